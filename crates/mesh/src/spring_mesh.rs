//! The spring graph that every simulation runs on: positions, lumped masses, springs, and the
//! surface or volume elements kept for output.

use nalgebra::SVector;

use crate::elements::{check_indices, check_positions, TetMesh, TriMesh};
use crate::{ElementKind, MeshError};

/// One spring between vertices `i` and `j`, stored in that order.
///
/// Energy ½ k (|x_i − x_j| − l)² with `stiffness` k in N/m and `rest_length` l in m.
/// 24 bytes, so that a sweep over 600,000 springs reads 14 MB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// First vertex.
    pub i: u32,
    /// Second vertex.
    pub j: u32,
    /// Stiffness k (N/m), positive.
    pub stiffness: f64,
    /// Rest length l (m), positive.
    pub rest_length: f64,
}

impl Spring {
    /// The two vertex indices as `usize`.
    #[inline]
    pub fn ends(&self) -> (usize, usize) {
        (self.i as usize, self.j as usize)
    }
}

/// How vertex masses are lumped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MassModel {
    /// The total mass (kg) split evenly over the vertices.
    Uniform {
        /// Total mass, kg.
        total: f64,
    },
    /// Triangle meshes: density (kg/m³) × area × thickness (m), a third to each vertex of a triangle.
    /// Tetrahedral meshes: density × volume, a quarter to each vertex; `thickness` is ignored.
    Density {
        /// Density, kg/m³.
        density: f64,
        /// Sheet thickness for triangle meshes, m.
        thickness: f64,
    },
}

/// Which springs a triangle mesh gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Bending {
    /// Only the triangle edges.
    #[default]
    None,
    /// Also one spring across every interior edge, between the two opposite vertices.
    InteriorEdges,
}

/// A mass-spring system in dimension `D` (2 or 3): initial positions (m), lumped masses (kg),
/// springs, and the triangles and tetrahedra kept for output (they carry no physics).
///
/// Invariants, checked by [`SpringMesh::new`]: at least one vertex; finite coordinates; every mass
/// positive and finite; at least one spring; every spring joins two distinct existing vertices with a
/// positive finite stiffness and rest length; element indices in range. A spring may be far from its
/// rest length (or of zero current length): that is a state, not a defect of the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringMesh<const D: usize> {
    positions: Vec<SVector<f64, D>>,
    masses: Vec<f64>,
    springs: Vec<Spring>,
    triangles: Vec<[u32; 3]>,
    tetrahedra: Vec<[u32; 4]>,
}

/// A 3D spring mesh (cloth, solids).
pub type SpringMesh3 = SpringMesh<3>;
/// A 2D spring mesh (the seed-2d scene).
pub type SpringMesh2 = SpringMesh<2>;

impl<const D: usize> SpringMesh<D> {
    const DIMENSION_IS_2_OR_3: () = assert!(D == 2 || D == 3, "hooke meshes are 2D or 3D");

    /// Build and validate a spring mesh with no output elements.
    ///
    /// # Errors
    /// The first violated invariant (see the type), naming the vertex or spring.
    pub fn new(
        positions: Vec<SVector<f64, D>>,
        masses: Vec<f64>,
        springs: Vec<Spring>,
    ) -> Result<Self, MeshError> {
        #[allow(clippy::let_unit_value)]
        let () = Self::DIMENSION_IS_2_OR_3;
        check_positions(&positions)?;
        if masses.len() != positions.len() {
            return Err(MeshError::LengthMismatch {
                what: "masses (one per vertex)",
                expected: positions.len(),
                actual: masses.len(),
            });
        }
        for (vertex, &mass) in masses.iter().enumerate() {
            if !(mass > 0.0 && mass.is_finite()) {
                return Err(MeshError::InvalidMass { vertex, mass });
            }
        }
        if springs.is_empty() {
            return Err(MeshError::NoElements {
                kind: ElementKind::Spring,
            });
        }
        for (index, s) in springs.iter().enumerate() {
            check_indices(ElementKind::Spring, index, &[s.i, s.j], positions.len())?;
            let (i, j) = s.ends();
            if !(s.stiffness > 0.0 && s.stiffness.is_finite()) {
                return Err(MeshError::InvalidStiffness {
                    spring: index,
                    i,
                    j,
                    stiffness: s.stiffness,
                });
            }
            if !(s.rest_length > 0.0 && s.rest_length.is_finite()) {
                return Err(MeshError::InvalidRestLength {
                    spring: index,
                    i,
                    j,
                    rest_length: s.rest_length,
                });
            }
        }
        Ok(SpringMesh {
            positions,
            masses,
            springs,
            triangles: Vec::new(),
            tetrahedra: Vec::new(),
        })
    }

    /// Springs on the given vertex pairs with one stiffness and rest length = current distance.
    ///
    /// # Errors
    /// As [`SpringMesh::new`]; a pair of coincident vertices gives [`MeshError::InvalidRestLength`].
    pub fn from_pairs(
        positions: Vec<SVector<f64, D>>,
        masses: Vec<f64>,
        pairs: &[[u32; 2]],
        stiffness: f64,
    ) -> Result<Self, MeshError> {
        check_positions(&positions)?;
        for (index, pair) in pairs.iter().enumerate() {
            check_indices(ElementKind::Spring, index, pair, positions.len())?;
        }
        let springs = springs_at_rest(&positions, pairs, stiffness);
        Self::new(positions, masses, springs)
    }

    /// Attach triangles for output (surface rendering). They must index existing vertices.
    ///
    /// # Errors
    /// [`MeshError::IndexOutOfRange`] or [`MeshError::RepeatedVertex`].
    pub fn with_triangles(mut self, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        for (element, t) in triangles.iter().enumerate() {
            check_indices(ElementKind::Triangle, element, t, self.positions.len())?;
        }
        self.triangles = triangles;
        Ok(self)
    }

    /// Attach tetrahedra for output (volume rendering). They must index existing vertices.
    ///
    /// # Errors
    /// [`MeshError::IndexOutOfRange`] or [`MeshError::RepeatedVertex`].
    pub fn with_tetrahedra(mut self, tetrahedra: Vec<[u32; 4]>) -> Result<Self, MeshError> {
        for (element, t) in tetrahedra.iter().enumerate() {
            check_indices(ElementKind::Tetrahedron, element, t, self.positions.len())?;
        }
        self.tetrahedra = tetrahedra;
        Ok(self)
    }

    /// Replace every spring's stiffness by `stiffness(index, spring)` (N/m), validating the result.
    ///
    /// # Errors
    /// [`MeshError::InvalidStiffness`] for the first non-positive or non-finite value.
    pub fn map_stiffness(
        mut self,
        mut stiffness: impl FnMut(usize, &Spring) -> f64,
    ) -> Result<Self, MeshError> {
        for (index, s) in self.springs.iter_mut().enumerate() {
            let k = stiffness(index, s);
            if !(k > 0.0 && k.is_finite()) {
                let (i, j) = s.ends();
                return Err(MeshError::InvalidStiffness {
                    spring: index,
                    i,
                    j,
                    stiffness: k,
                });
            }
            s.stiffness = k;
        }
        Ok(self)
    }

    /// Replace every vertex mass by `mass(vertex, old_mass)` (kg), validating the result.
    ///
    /// # Errors
    /// [`MeshError::InvalidMass`] for the first non-positive or non-finite value.
    pub fn map_masses(
        mut self,
        mut mass: impl FnMut(usize, f64) -> f64,
    ) -> Result<Self, MeshError> {
        for (vertex, m) in self.masses.iter_mut().enumerate() {
            let new = mass(vertex, *m);
            if !(new > 0.0 && new.is_finite()) {
                return Err(MeshError::InvalidMass { vertex, mass: new });
            }
            *m = new;
        }
        Ok(self)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Initial vertex positions (m).
    pub fn positions(&self) -> &[SVector<f64, D>] {
        &self.positions
    }

    /// Lumped vertex masses (kg), all positive.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.masses.iter().sum()
    }

    /// The springs, in generation order.
    pub fn springs(&self) -> &[Spring] {
        &self.springs
    }

    /// Triangles kept for output (may be empty).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Tetrahedra kept for output (may be empty).
    pub fn tetrahedra(&self) -> &[[u32; 4]] {
        &self.tetrahedra
    }
}

impl SpringMesh<3> {
    /// Springs on the edges of a triangle mesh (and, with [`Bending::InteriorEdges`], across its
    /// interior edges), rest length = initial distance, masses by `mass`; the triangles are kept for
    /// output. Springs come sorted by `[min, max]` vertex index, edges first, then bending springs.
    ///
    /// # Errors
    /// [`MeshError::InvalidStiffness`], an invalid mass model ([`MeshError::InvalidParameter`]), or a
    /// bending pair of coincident vertices ([`MeshError::InvalidRestLength`]).
    pub fn from_triangles(
        mesh: &TriMesh,
        stiffness: f64,
        bending: Bending,
        mass: MassModel,
    ) -> Result<Self, MeshError> {
        let mut pairs = mesh.edges();
        if bending == Bending::InteriorEdges {
            pairs.extend(mesh.bending_pairs());
        }
        let masses = match mass {
            MassModel::Uniform { total } => uniform_masses(mesh.positions().len(), total)?,
            MassModel::Density { density, thickness } => {
                check_positive("density", density)?;
                check_positive("thickness", thickness)?;
                lumped_masses(
                    mesh.positions().len(),
                    mesh.triangles()
                        .iter()
                        .zip(mesh.areas())
                        .map(|(t, area)| (&t[..], density * thickness * area)),
                )
            }
        };
        Self::from_pairs(mesh.positions().to_vec(), masses, &pairs, stiffness)?
            .with_triangles(mesh.triangles().to_vec())
    }

    /// Springs on the unique edges of a tetrahedral mesh, rest length = initial distance, masses by
    /// `mass` (for [`MassModel::Density`] a quarter of each tetrahedron's mass to each vertex; the
    /// thickness is ignored); the tetrahedra and the boundary surface are kept for output.
    ///
    /// # Errors
    /// As [`SpringMesh::from_triangles`].
    pub fn from_tetrahedra(
        mesh: &TetMesh,
        stiffness: f64,
        mass: MassModel,
    ) -> Result<Self, MeshError> {
        let masses = match mass {
            MassModel::Uniform { total } => uniform_masses(mesh.positions().len(), total)?,
            MassModel::Density { density, .. } => {
                check_positive("density", density)?;
                lumped_masses(
                    mesh.positions().len(),
                    mesh.tetrahedra()
                        .iter()
                        .zip(mesh.volumes())
                        .map(|(t, volume)| (&t[..], density * volume)),
                )
            }
        };
        Self::from_pairs(mesh.positions().to_vec(), masses, &mesh.edges(), stiffness)?
            .with_triangles(mesh.boundary_faces())?
            .with_tetrahedra(mesh.tetrahedra().to_vec())
    }
}

pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<(), MeshError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(MeshError::InvalidParameter {
            name,
            value: value.to_string(),
            reason: "must be positive and finite",
        })
    }
}

/// `total / n` for each of `n` vertices.
pub(crate) fn uniform_masses(n: usize, total: f64) -> Result<Vec<f64>, MeshError> {
    check_positive("total mass", total)?;
    Ok(vec![total / n as f64; n])
}

/// Each element gives an equal share of its mass to each of its vertices. A vertex in no element
/// would get zero mass, which [`SpringMesh::new`] then rejects by name.
fn lumped_masses<'a>(n: usize, elements: impl Iterator<Item = (&'a [u32], f64)>) -> Vec<f64> {
    let mut masses = vec![0.0; n];
    for (vertices, mass) in elements {
        let share = mass / vertices.len() as f64;
        for &v in vertices {
            masses[v as usize] += share;
        }
    }
    masses
}

/// Springs on `pairs` (indices already checked) with rest length = current distance.
pub(crate) fn springs_at_rest<const D: usize>(
    positions: &[SVector<f64, D>],
    pairs: &[[u32; 2]],
    stiffness: f64,
) -> Vec<Spring> {
    pairs
        .iter()
        .map(|&[i, j]| Spring {
            i,
            j,
            stiffness,
            rest_length: (positions[i as usize] - positions[j as usize]).norm(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;
    use nalgebra::Vector2;

    #[test]
    fn validation_names_the_offender() {
        let p = vec![Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.0)];
        let s = |k, l| {
            vec![Spring {
                i: 0,
                j: 1,
                stiffness: k,
                rest_length: l,
            }]
        };
        assert!(SpringMesh::new(p.clone(), vec![1.0, 1.0], s(1.0, 1.0)).is_ok());
        assert!(matches!(
            SpringMesh::new(p.clone(), vec![1.0, 0.0], s(1.0, 1.0)),
            Err(MeshError::InvalidMass { vertex: 1, .. })
        ));
        assert!(matches!(
            SpringMesh::new(p.clone(), vec![1.0, 1.0], s(-1.0, 1.0)),
            Err(MeshError::InvalidStiffness { spring: 0, .. })
        ));
        assert!(matches!(
            SpringMesh::new(p.clone(), vec![1.0, 1.0], s(1.0, 0.0)),
            Err(MeshError::InvalidRestLength { spring: 0, .. })
        ));
        assert!(matches!(
            SpringMesh::new(p.clone(), vec![1.0], s(1.0, 1.0)),
            Err(MeshError::LengthMismatch { .. })
        ));
        assert!(matches!(
            SpringMesh::from_pairs(p, vec![1.0, 1.0], &[[0, 0]], 1.0),
            Err(MeshError::RepeatedVertex { .. })
        ));
    }

    #[test]
    fn tet_masses_are_a_quarter_of_the_volume() {
        let tet = TetMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        let m = SpringMesh::from_tetrahedra(
            &tet,
            10.0,
            MassModel::Density {
                density: 600.0,
                thickness: 0.0,
            },
        )
        .unwrap();
        for &mass in m.masses() {
            assert!((mass - 600.0 / 6.0 / 4.0).abs() < 1e-12);
        }
        assert_eq!(m.springs().len(), 6);
        assert_eq!(m.triangles().len(), 4);
    }
}
