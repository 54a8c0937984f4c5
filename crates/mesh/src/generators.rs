//! Generators for the canonical scenes of docs/scenes.md, built exactly as written there: vertex
//! order, spring order and counts are part of the contract, because benchmarks compare against
//! them.

use std::collections::HashMap;

use nalgebra::{SVector, Vector2};

use crate::elements::TetMesh;
use crate::spring_mesh::{check_positive, springs_at_rest};
use crate::{MassModel, MeshError, Spring, SpringMesh, Vec3};

/// Number of springs of cloth-N: 2N(N−1) structural + 2(N−1)² shear + 2N(N−2) bending.
pub fn cloth_spring_count(n: usize) -> usize {
    2 * n * (n - 1) + 2 * (n - 1) * (n - 1) + 2 * n * n.saturating_sub(2)
}

/// cloth-N: an N×N grid on the unit square in the x–z plane (y = 0), vertex (i, j) at
/// (i/(N−1), 0, j/(N−1)) with index i·N + j; total mass 1 kg spread evenly; structural, shear and
/// two-ring bending springs with one stiffness `stiffness` (N/m) and rest length = initial distance,
/// in the order of docs/scenes.md §1; the two triangles of each cell kept for output.
///
/// The pins (vertices 0 and N−1), gravity and time step of the scene are set by the simulation crate.
///
/// # Errors
/// [`MeshError::InvalidParameter`] if `n < 2`, or `stiffness` is not positive and finite.
pub fn cloth(n: usize, stiffness: f64) -> Result<SpringMesh<3>, MeshError> {
    if n < 2 {
        return Err(MeshError::InvalidParameter {
            name: "N",
            value: n.to_string(),
            reason: "a cloth needs at least 2×2 vertices",
        });
    }
    if n > 65_535 {
        return Err(MeshError::TooManyVertices { count: n * n });
    }
    check_positive("stiffness", stiffness)?;
    let spacing = 1.0 / (n - 1) as f64;
    let index = |i: usize, j: usize| (i * n + j) as u32;
    let positions: Vec<Vec3> = (0..n)
        .flat_map(|i| (0..n).map(move |j| Vec3::new(i as f64 * spacing, 0.0, j as f64 * spacing)))
        .collect();
    let mut pairs = Vec::with_capacity(cloth_spring_count(n));
    for i in 0..n {
        for j in 0..n {
            let (right, up, right2, up2) = (i + 1 < n, j + 1 < n, i + 2 < n, j + 2 < n);
            if right {
                pairs.push([index(i, j), index(i + 1, j)]);
            }
            if up {
                pairs.push([index(i, j), index(i, j + 1)]);
            }
            if right && up {
                pairs.push([index(i, j), index(i + 1, j + 1)]);
                pairs.push([index(i + 1, j), index(i, j + 1)]);
            }
            if right2 {
                pairs.push([index(i, j), index(i + 2, j)]);
            }
            if up2 {
                pairs.push([index(i, j), index(i, j + 2)]);
            }
        }
    }
    debug_assert_eq!(pairs.len(), cloth_spring_count(n));
    let mut triangles = Vec::with_capacity(2 * (n - 1) * (n - 1));
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            triangles.push([index(i, j), index(i + 1, j), index(i + 1, j + 1)]);
            triangles.push([index(i, j), index(i + 1, j + 1), index(i, j + 1)]);
        }
    }
    let masses = vec![1.0 / (n * n) as f64; n * n];
    SpringMesh::from_pairs(positions, masses, &pairs, stiffness)?.with_triangles(triangles)
}

/// Number of vertices of beam-R: (4R+1)(R+1)².
pub fn beam_vertex_count(r: usize) -> usize {
    (4 * r + 1) * (r + 1) * (r + 1)
}

/// Number of springs of beam-R: the unique edges of the 6-tetrahedra-per-cube split, i.e. for each of
/// the 7 lattice directions e ∈ {0,1}³ \ {0}, the product over axes of (cells) where e has a 1 and
/// (cells + 1) where it has a 0, with cells (4R, R, R).
pub fn beam_spring_count(r: usize) -> usize {
    let cells = [4 * r, r, r];
    (1..8usize)
        .map(|mask| {
            (0..3)
                .map(|axis| {
                    if mask >> axis & 1 == 1 {
                        cells[axis]
                    } else {
                        cells[axis] + 1
                    }
                })
                .product::<usize>()
        })
        .sum()
}

/// The tetrahedral mesh of beam-R: the box [0, 4] × [0, 1] × [0, 1] m split into 4R × R × R cubes,
/// each cube into 6 positively oriented tetrahedra around its main diagonal (from its lowest to its
/// highest corner), which conforms across faces. Vertex (a, b, c) (a along x, b along y, c along z)
/// has index (a·(R+1) + b)·(R+1) + c; cubes are visited in the same order, and each cube's tetrahedra
/// in the order of the axis permutations (x,y,z), (x,z,y), (y,x,z), (y,z,x), (z,x,y), (z,y,x).
///
/// # Errors
/// [`MeshError::InvalidParameter`] if `r == 0`.
pub fn beam_tet_mesh(r: usize) -> Result<TetMesh, MeshError> {
    if r == 0 {
        return Err(MeshError::InvalidParameter {
            name: "R",
            value: r.to_string(),
            reason: "a beam needs at least one cube across",
        });
    }
    let h = 1.0 / r as f64;
    lattice_tet_mesh([4 * r, r, r], |[a, b, c]| {
        Vec3::new(a as f64 * h, b as f64 * h, c as f64 * h)
    })
}

/// A box of `cells[0] × cells[1] × cells[2]` lattice cubes, each split into 6 tetrahedra around its
/// main diagonal (the Freudenthal/Kuhn split, conforming across faces), with lattice point (a, b, c)
/// placed at `position([a, b, c])` (m). Vertex (a, b, c) has index (a·(c₁+1) + b)·(c₂+1) + c; cubes are
/// visited in the same order, and each cube's tetrahedra in the order of the axis permutations
/// (x,y,z), (x,z,y), (y,x,z), (y,z,x), (z,x,y), (z,y,x), oriented positively for an orientation-
/// preserving `position`.
///
/// # Errors
/// [`MeshError::InvalidParameter`] for a zero cell count, [`MeshError::TooManyVertices`], or the
/// validation errors of [`TetMesh::new`] (e.g. a `position` that flattens a tetrahedron).
pub fn lattice_tet_mesh(
    cells: [usize; 3],
    mut position: impl FnMut([usize; 3]) -> Vec3,
) -> Result<TetMesh, MeshError> {
    if cells.contains(&0) {
        return Err(MeshError::InvalidParameter {
            name: "cells",
            value: format!("{cells:?}"),
            reason: "every axis needs at least one cell",
        });
    }
    let dims = cells.map(|c| c + 1);
    let count = dims
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .unwrap_or(usize::MAX);
    if count > u32::MAX as usize {
        return Err(MeshError::TooManyVertices { count });
    }
    let index = |p: [usize; 3]| ((p[0] * dims[1] + p[1]) * dims[2] + p[2]) as u32;
    let mut positions = Vec::with_capacity(count);
    for a in 0..dims[0] {
        for b in 0..dims[1] {
            for c in 0..dims[2] {
                positions.push(position([a, b, c]));
            }
        }
    }
    const PERMUTATIONS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut tetrahedra = Vec::with_capacity(6 * cells.iter().product::<usize>());
    for a in 0..cells[0] {
        for b in 0..cells[1] {
            for c in 0..cells[2] {
                for perm in PERMUTATIONS {
                    // Walk from the lowest corner to the highest, one axis at a time.
                    let mut corner = [a, b, c];
                    let mut tet = [index(corner), 0, 0, 0];
                    for (k, &axis) in perm.iter().enumerate() {
                        corner[axis] += 1;
                        tet[k + 1] = index(corner);
                    }
                    // Odd permutations give negative orientation: swap two vertices.
                    if matches!(perm, [0, 2, 1] | [1, 0, 2] | [2, 1, 0]) {
                        tet.swap(1, 2);
                    }
                    tetrahedra.push(tet);
                }
            }
        }
    }
    TetMesh::new(positions, tetrahedra)
}

/// beam-R: [`beam_tet_mesh`] with springs on the unique tet edges (sorted by `[min, max]`), stiffness
/// 1e4 N/m, rest length = initial distance, density 1000 kg/m³ lumped a quarter per tet vertex.
///
/// # Errors
/// As [`beam_tet_mesh`].
pub fn beam(r: usize) -> Result<SpringMesh<3>, MeshError> {
    SpringMesh::from_tetrahedra(
        &beam_tet_mesh(r)?,
        1e4,
        MassModel::Density {
            density: 1000.0,
            thickness: 1.0,
        },
    )
}

/// How the radius graph sets the rest length of a new spring.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RestLength {
    /// Every spring gets this rest length (m), as the 2D sketch scene does (0.1).
    Fixed(f64),
    /// Each spring's rest length is the distance at which it was created.
    Measured,
}

/// The particle graph of the 2D sketch (seed-2d, the editor), built one particle at a time: each
/// new particle is joined by a spring to every existing particle closer than `radius`. Neighbours
/// are found on a uniform grid of cell size `radius`, so adding a particle costs O(neighbours), not
/// O(particles).
#[derive(Clone, Debug)]
pub struct RadiusGraph<const D: usize> {
    radius: f64,
    rest_length: RestLength,
    stiffness: f64,
    positions: Vec<SVector<f64, D>>,
    pairs: Vec<[u32; 2]>,
    springs: Vec<Spring>,
    grid: HashMap<[i64; D], Vec<u32>>,
}

impl<const D: usize> RadiusGraph<D> {
    /// An empty graph: connection `radius` (m), spring `stiffness` k (N/m) and rest-length rule.
    ///
    /// # Errors
    /// [`MeshError::InvalidParameter`] for a non-positive radius, stiffness or fixed rest length.
    pub fn new(radius: f64, stiffness: f64, rest_length: RestLength) -> Result<Self, MeshError> {
        check_positive("radius", radius)?;
        check_positive("stiffness", stiffness)?;
        if let RestLength::Fixed(l) = rest_length {
            check_positive("rest length", l)?;
        }
        Ok(RadiusGraph {
            radius,
            rest_length,
            stiffness,
            positions: Vec::new(),
            pairs: Vec::new(),
            springs: Vec::new(),
            grid: HashMap::new(),
        })
    }

    fn cell(&self, p: &SVector<f64, D>) -> [i64; D] {
        std::array::from_fn(|a| (p[a] / self.radius).floor() as i64)
    }

    /// Add a particle at `position` (m); returns its index. Springs to earlier particles within the
    /// radius are appended as (earlier, new), earlier particles in increasing index order.
    ///
    /// # Errors
    /// [`MeshError::NonFiniteCoordinate`] for a NaN or infinite position;
    /// [`MeshError::InvalidRestLength`] with [`RestLength::Measured`] if the new particle coincides
    /// with a neighbour.
    pub fn add_particle(&mut self, position: SVector<f64, D>) -> Result<u32, MeshError> {
        let new = self.positions.len();
        for (axis, &value) in position.iter().enumerate() {
            if !value.is_finite() {
                return Err(MeshError::NonFiniteCoordinate {
                    vertex: new,
                    axis,
                    value,
                });
            }
        }
        let new = u32::try_from(new).map_err(|_| MeshError::TooManyVertices { count: new + 1 })?;
        let home = self.cell(&position);
        let mut neighbours = Vec::new();
        // The 3^D cells around the home cell hold every particle within one radius.
        for offset in 0..3usize.pow(D as u32) {
            let mut cell = home;
            let mut code = offset;
            for c in cell.iter_mut() {
                *c += (code % 3) as i64 - 1;
                code /= 3;
            }
            if let Some(list) = self.grid.get(&cell) {
                neighbours.extend(
                    list.iter()
                        .copied()
                        .filter(|&k| (self.positions[k as usize] - position).norm() < self.radius),
                );
            }
        }
        neighbours.sort_unstable();
        for k in neighbours {
            let rest_length = match self.rest_length {
                RestLength::Fixed(l) => l,
                RestLength::Measured => (self.positions[k as usize] - position).norm(),
            };
            if rest_length.is_nan() || rest_length <= 0.0 {
                return Err(MeshError::InvalidRestLength {
                    spring: self.springs.len(),
                    i: k as usize,
                    j: new as usize,
                    rest_length,
                });
            }
            self.pairs.push([k, new]);
            self.springs.push(Spring {
                i: k,
                j: new,
                stiffness: self.stiffness,
                rest_length,
            });
        }
        self.positions.push(position);
        self.grid.entry(home).or_default().push(new);
        Ok(new)
    }

    /// The springs so far.
    pub fn springs(&self) -> &[Spring] {
        &self.springs
    }

    /// The finished spring mesh, every particle with mass `mass` (kg).
    ///
    /// # Errors
    /// As [`SpringMesh::new`] (e.g. no springs yet, or a non-positive mass).
    pub fn build(self, mass: f64) -> Result<SpringMesh<D>, MeshError> {
        let masses = vec![mass; self.positions.len()];
        SpringMesh::new(self.positions, masses, self.springs)
    }
}

/// seed-2d: the 2D sketch's starting scene (docs/scenes.md §5). Particles at (0.3, 0.3),
/// (0.3, 0.4), (0.4, 0.4), mass 1 kg, joined within radius 0.15 m with rest length 0.1 m. The
/// sketch's force −Y(|r|/l − 1) r̂ with Young's modulus Y = 1000 N is a spring of stiffness
/// k = Y/l = 1e4 N/m. Springs: (0,1), (0,2), (1,2).
pub fn seed_2d() -> Result<SpringMesh<2>, MeshError> {
    let mut graph = RadiusGraph::new(
        0.15,
        SEED_2D_YOUNG / SEED_2D_REST_LENGTH,
        RestLength::Fixed(SEED_2D_REST_LENGTH),
    )?;
    for p in [[0.3, 0.3], [0.3, 0.4], [0.4, 0.4]] {
        graph.add_particle(Vector2::new(p[0], p[1]))?;
    }
    graph.build(1.0)
}

/// The 2D sketch's spring Young's modulus Y (N): its force is −Y(|r|/l − 1) r̂.
pub const SEED_2D_YOUNG: f64 = 1000.0;
/// The 2D sketch's rest length (m).
pub const SEED_2D_REST_LENGTH: f64 = 0.1;

/// Positions of a spring mesh as measured distances, for tests: rest lengths equal distances.
#[doc(hidden)]
pub fn rest_lengths_match_positions<const D: usize>(mesh: &SpringMesh<D>) -> bool {
    let pairs: Vec<[u32; 2]> = mesh.springs().iter().map(|s| [s.i, s.j]).collect();
    springs_at_rest(mesh.positions(), &pairs, 1.0)
        .iter()
        .zip(mesh.springs())
        .all(|(a, b)| (a.rest_length - b.rest_length).abs() <= 1e-12 * b.rest_length.max(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::unique_edges;

    #[test]
    fn cloth_counts_match_scenes_md() {
        for (n, springs) in [(10, 502), (20, 2202), (40, 9202), (80, 37602)] {
            assert_eq!(cloth_spring_count(n), springs);
            let c = cloth(n, 1e3).unwrap();
            assert_eq!(c.vertex_count(), n * n);
            assert_eq!(c.springs().len(), springs, "cloth-{n}");
            assert_eq!(c.triangles().len(), 2 * (n - 1) * (n - 1));
            assert!((c.total_mass() - 1.0).abs() < 1e-12);
            assert!(rest_lengths_match_positions(&c));
        }
        assert_eq!(cloth_spring_count(160), 152_002);
    }

    #[test]
    fn cloth_order_is_as_written() {
        let n = 4;
        let c = cloth(n, 1.0).unwrap();
        let p = c.positions();
        assert_eq!(p[n + 2], Vec3::new(1.0 / 3.0, 0.0, 2.0 / 3.0));
        let pairs: Vec<_> = c.springs().iter().take(6).map(|s| (s.i, s.j)).collect();
        // i = 0, j = 0: right (0,0)-(1,0) = 0-4, up 0-1, diagonal 0-5, anti-diagonal 4-1,
        // two-ring 0-8 and 0-2.
        assert_eq!(pairs, vec![(0, 4), (0, 1), (0, 5), (4, 1), (0, 8), (0, 2)]);
        let last = c.springs().last().unwrap();
        // The last vertex to emit anything is (N−1, N−2): its up spring.
        assert_eq!((last.i, last.j), (14, 15));
    }

    #[test]
    fn cloth_springs_are_unique() {
        let c = cloth(7, 1.0).unwrap();
        let edges = unique_edges(c.springs().iter().map(|s| [s.i, s.j]));
        assert_eq!(edges.len(), c.springs().len());
    }

    #[test]
    fn beam_counts_volume_and_mass() {
        for r in 1..=4 {
            let mesh = beam_tet_mesh(r).unwrap();
            assert_eq!(mesh.positions().len(), beam_vertex_count(r));
            assert_eq!(mesh.tetrahedra().len(), 24 * r * r * r);
            let volume: f64 = mesh.volumes().iter().sum();
            assert!((volume - 4.0).abs() < 1e-9, "R = {r}: volume {volume}");
            for t in mesh.tetrahedra() {
                let [a, b, c, d] = t.map(|v| mesh.positions()[v as usize]);
                assert!(crate::tetrahedron_signed_volume(&a, &b, &c, &d) > 0.0);
            }
            // Conforming: the boundary is exactly the box surface, 2 triangles per boundary square.
            let boundary = mesh.boundary_faces().len();
            assert_eq!(boundary, 2 * (2 * 4 * r * r + 2 * 4 * r * r + 2 * r * r));
            let b = beam(r).unwrap();
            assert_eq!(b.springs().len(), beam_spring_count(r), "R = {r}");
            assert!((b.total_mass() - 4000.0).abs() < 1e-8);
        }
    }

    #[test]
    fn seed_2d_matches_the_seed() {
        let s = seed_2d().unwrap();
        assert_eq!(s.vertex_count(), 3);
        let pairs: Vec<_> = s.springs().iter().map(|s| (s.i, s.j)).collect();
        assert_eq!(pairs, vec![(0, 1), (0, 2), (1, 2)]);
        for spring in s.springs() {
            assert_eq!(spring.rest_length, 0.1);
            assert!((spring.stiffness - 1e4).abs() < 1e-9);
        }
    }

    #[test]
    fn radius_graph_agrees_with_brute_force() {
        // A deterministic scatter of points; compare with the O(n²) definition.
        let mut g = RadiusGraph::<2>::new(0.15, 1.0, RestLength::Measured).unwrap();
        let mut points = Vec::new();
        let mut state = 12345u64;
        for _ in 0..200 {
            let mut next = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let p = Vector2::new(next() - 0.5, next() - 0.5);
            points.push(p);
            g.add_particle(p).unwrap();
        }
        let mut expected = Vec::new();
        for new in 0..points.len() {
            for old in 0..new {
                if (points[old] - points[new]).norm() < 0.15 {
                    expected.push((old as u32, new as u32));
                }
            }
        }
        let got: Vec<_> = g.springs().iter().map(|s| (s.i, s.j)).collect();
        assert_eq!(got, expected);
    }
}
