//! Triangle and tetrahedral meshes (geometry and connectivity only), with validation.

use nalgebra::Vector3;

use crate::{ElementKind, MeshError};

/// A point or vector in 3D, in metres.
pub type Vec3 = Vector3<f64>;

/// Relative threshold below which an element counts as degenerate: its area (volume) compared with
/// the square (cube) of its longest edge. Chosen far above round-off (~1e-16) so that only elements that
/// are flat for all practical purposes are rejected, and scale-free so that units do not matter.
pub const DEGENERACY_TOLERANCE: f64 = 1e-12;

/// A triangle surface mesh: vertex positions (m) and triangles as triples of vertex indices.
///
/// Invariants, checked by [`TriMesh::new`]: at least one vertex and one triangle, finite coordinates,
/// indices in range, no triangle that repeats a vertex or has zero area.
#[derive(Clone, Debug, PartialEq)]
pub struct TriMesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// A tetrahedral volume mesh: vertex positions (m) and tetrahedra as quadruples of vertex indices.
///
/// Invariants, checked by [`TetMesh::new`]: at least one vertex and one tetrahedron, finite coordinates,
/// indices in range, no tetrahedron that repeats a vertex or has zero volume. Orientation is not
/// required (volumes are taken unsigned).
#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    positions: Vec<Vec3>,
    tetrahedra: Vec<[u32; 4]>,
}

pub(crate) fn check_positions<const D: usize>(
    positions: &[nalgebra::SVector<f64, D>],
) -> Result<(), MeshError> {
    if positions.is_empty() {
        return Err(MeshError::Empty);
    }
    if positions.len() > u32::MAX as usize {
        return Err(MeshError::TooManyVertices {
            count: positions.len(),
        });
    }
    check_finite(positions)
}

/// [`MeshError::NonFiniteCoordinate`] for the first NaN or infinite coordinate.
pub(crate) fn check_finite<const D: usize>(
    positions: &[nalgebra::SVector<f64, D>],
) -> Result<(), MeshError> {
    for (vertex, p) in positions.iter().enumerate() {
        for (axis, &value) in p.iter().enumerate() {
            if !value.is_finite() {
                return Err(MeshError::NonFiniteCoordinate {
                    vertex,
                    axis,
                    value,
                });
            }
        }
    }
    Ok(())
}

pub(crate) fn check_indices<const K: usize>(
    kind: ElementKind,
    element: usize,
    indices: &[u32; K],
    vertex_count: usize,
) -> Result<(), MeshError> {
    for (a, &index) in indices.iter().enumerate() {
        if index as usize >= vertex_count {
            return Err(MeshError::IndexOutOfRange {
                kind,
                element,
                index: index as usize,
                vertex_count,
            });
        }
        if indices[..a].contains(&index) {
            return Err(MeshError::RepeatedVertex {
                kind,
                element,
                vertex: index as usize,
            });
        }
    }
    Ok(())
}

/// Area of a triangle (m²).
pub fn triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> f64 {
    0.5 * (b - a).cross(&(c - a)).norm()
}

/// Signed volume of a tetrahedron (m³): positive when (b − a, c − a, d − a) is right-handed.
pub fn tetrahedron_signed_volume(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

fn longest_edge<const K: usize>(points: [&Vec3; K]) -> f64 {
    let mut longest: f64 = 0.0;
    for a in 0..K {
        for b in a + 1..K {
            longest = longest.max((points[a] - points[b]).norm());
        }
    }
    longest
}

impl TriMesh {
    /// Build a triangle mesh, validating it (see the type's invariants).
    ///
    /// # Errors
    /// [`MeshError::Empty`], [`MeshError::NoElements`], [`MeshError::NonFiniteCoordinate`],
    /// [`MeshError::IndexOutOfRange`], [`MeshError::RepeatedVertex`] or [`MeshError::Degenerate`],
    /// naming the first offending vertex or triangle.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        check_positions(&positions)?;
        if triangles.is_empty() {
            return Err(MeshError::NoElements {
                kind: ElementKind::Triangle,
            });
        }
        for (element, t) in triangles.iter().enumerate() {
            check_indices(ElementKind::Triangle, element, t, positions.len())?;
            let [a, b, c] = t.map(|v| &positions[v as usize]);
            let measure = triangle_area(a, b, c);
            let scale = longest_edge([a, b, c]).powi(2);
            if measure.is_nan() || measure <= DEGENERACY_TOLERANCE * scale {
                return Err(MeshError::Degenerate {
                    kind: ElementKind::Triangle,
                    element,
                    measure,
                    scale,
                });
            }
        }
        Ok(TriMesh {
            positions,
            triangles,
        })
    }

    /// Vertex positions (m).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles as vertex index triples.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Area of each triangle (m²), in triangle order.
    pub fn areas(&self) -> Vec<f64> {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| &self.positions[v as usize]);
                triangle_area(a, b, c)
            })
            .collect()
    }

    /// The unique undirected edges, each as `[min, max]`, sorted.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        unique_edges(
            self.triangles
                .iter()
                .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]]),
        )
    }

    /// For every interior edge (shared by exactly two triangles), the two vertices opposite it, as
    /// `[min, max]`, sorted and without duplicates: the end points of the cloth bending springs. Edges
    /// shared by more than two triangles (non-manifold) get no bending spring.
    pub fn bending_pairs(&self) -> Vec<[u32; 2]> {
        // (edge key, opposite vertex), sorted by edge so that each edge's triangles are adjacent.
        let mut half: Vec<(u64, u32)> = Vec::with_capacity(3 * self.triangles.len());
        for &[a, b, c] in &self.triangles {
            for (p, q, opposite) in [(a, b, c), (b, c, a), (c, a, b)] {
                half.push((edge_key(p, q), opposite));
            }
        }
        half.sort_unstable();
        let mut pairs = Vec::new();
        let mut start = 0;
        while start < half.len() {
            let mut end = start + 1;
            while end < half.len() && half[end].0 == half[start].0 {
                end += 1;
            }
            if end - start == 2 {
                let (o1, o2) = (half[start].1, half[start + 1].1);
                if o1 != o2 {
                    pairs.push([o1.min(o2), o1.max(o2)]);
                }
            }
            start = end;
        }
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }
}

impl TetMesh {
    /// Build a tetrahedral mesh, validating it (see the type's invariants).
    ///
    /// # Errors
    /// As [`TriMesh::new`], for tetrahedra.
    pub fn new(positions: Vec<Vec3>, tetrahedra: Vec<[u32; 4]>) -> Result<Self, MeshError> {
        check_positions(&positions)?;
        if tetrahedra.is_empty() {
            return Err(MeshError::NoElements {
                kind: ElementKind::Tetrahedron,
            });
        }
        for (element, t) in tetrahedra.iter().enumerate() {
            check_indices(ElementKind::Tetrahedron, element, t, positions.len())?;
            let [a, b, c, d] = t.map(|v| &positions[v as usize]);
            let measure = tetrahedron_signed_volume(a, b, c, d).abs();
            let scale = longest_edge([a, b, c, d]).powi(3);
            if measure.is_nan() || measure <= DEGENERACY_TOLERANCE * scale {
                return Err(MeshError::Degenerate {
                    kind: ElementKind::Tetrahedron,
                    element,
                    measure,
                    scale,
                });
            }
        }
        Ok(TetMesh {
            positions,
            tetrahedra,
        })
    }

    /// Vertex positions (m).
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Tetrahedra as vertex index quadruples.
    pub fn tetrahedra(&self) -> &[[u32; 4]] {
        &self.tetrahedra
    }

    /// Unsigned volume of each tetrahedron (m³), in element order.
    pub fn volumes(&self) -> Vec<f64> {
        self.tetrahedra
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.map(|v| &self.positions[v as usize]);
                tetrahedron_signed_volume(a, b, c, d).abs()
            })
            .collect()
    }

    /// The unique undirected edges, each as `[min, max]`, sorted.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        unique_edges(
            self.tetrahedra
                .iter()
                .flat_map(|&[a, b, c, d]| [[a, b], [a, c], [a, d], [b, c], [b, d], [c, d]]),
        )
    }

    /// The boundary surface: faces that belong to exactly one tetrahedron, oriented outward when the
    /// tetrahedra are positively oriented. Sorted by their sorted vertex triple.
    pub fn boundary_faces(&self) -> Vec<[u32; 3]> {
        let mut faces: Vec<([u32; 3], [u32; 3])> = Vec::with_capacity(4 * self.tetrahedra.len());
        for &[a, b, c, d] in &self.tetrahedra {
            // Faces opposite d, c, b, a, wound outward for a positively oriented tetrahedron.
            for face in [[a, c, b], [a, b, d], [a, d, c], [b, c, d]] {
                let mut key = face;
                key.sort_unstable();
                faces.push((key, face));
            }
        }
        faces.sort_unstable_by_key(|f| f.0);
        let mut boundary = Vec::new();
        let mut start = 0;
        while start < faces.len() {
            let mut end = start + 1;
            while end < faces.len() && faces[end].0 == faces[start].0 {
                end += 1;
            }
            if end - start == 1 {
                boundary.push(faces[start].1);
            }
            start = end;
        }
        boundary
    }
}

pub(crate) fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    ((lo as u64) << 32) | hi as u64
}

/// Unique undirected edges as `[min, max]`, sorted; O(E log E), no hashing.
pub(crate) fn unique_edges(edges: impl Iterator<Item = [u32; 2]>) -> Vec<[u32; 2]> {
    let mut keys: Vec<u64> = edges.map(|[a, b]| edge_key(a, b)).collect();
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter()
        .map(|k| [(k >> 32) as u32, k as u32])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TriMesh {
        TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn square_edges_and_bending() {
        let m = square();
        assert_eq!(m.edges(), vec![[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]);
        assert_eq!(m.bending_pairs(), vec![[1, 3]]);
        assert_eq!(m.areas(), vec![0.5, 0.5]);
    }

    #[test]
    fn rejects_bad_triangles() {
        let p = square().positions().to_vec();
        assert!(matches!(
            TriMesh::new(p.clone(), vec![[0, 1, 7]]),
            Err(MeshError::IndexOutOfRange { index: 7, .. })
        ));
        assert!(matches!(
            TriMesh::new(p.clone(), vec![[0, 1, 2], [1, 1, 2]]),
            Err(MeshError::RepeatedVertex {
                element: 1,
                vertex: 1,
                ..
            })
        ));
        let mut flat = p.clone();
        flat[2] = Vec3::new(2.0, 0.0, 0.0);
        assert!(matches!(
            TriMesh::new(flat, vec![[0, 1, 2]]),
            Err(MeshError::Degenerate { element: 0, .. })
        ));
        let mut nan = p.clone();
        nan[3].y = f64::NAN;
        assert!(matches!(
            TriMesh::new(nan, vec![[0, 1, 2]]),
            Err(MeshError::NonFiniteCoordinate {
                vertex: 3,
                axis: 1,
                ..
            })
        ));
        assert!(matches!(
            TriMesh::new(vec![], vec![]),
            Err(MeshError::Empty)
        ));
        assert!(matches!(
            TriMesh::new(p, vec![]),
            Err(MeshError::NoElements { .. })
        ));
    }

    #[test]
    fn unit_tet_volume_edges_boundary() {
        let m = TetMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        assert!((m.volumes()[0] - 1.0 / 6.0).abs() < 1e-15);
        assert_eq!(m.edges().len(), 6);
        let faces = m.boundary_faces();
        assert_eq!(faces.len(), 4);
        // Outward: each face normal points away from the opposite vertex (centroid test).
        let centroid = Vec3::new(0.25, 0.25, 0.25);
        for f in faces {
            let [a, b, c] = f.map(|v| m.positions()[v as usize]);
            let n = (b - a).cross(&(c - a));
            assert!(n.dot(&(a - centroid)) > 0.0, "face {f:?} points inward");
        }
    }
}
