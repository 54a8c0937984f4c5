//! Proptest strategies that build valid meshes, spring meshes and states by construction (feature
//! `proptest-support`), for this crate's tests and for users' test suites.
//!
//! Every strategy here yields values that pass validation; none of them filters (so no case is ever
//! rejected). Sizes are bounded by the arguments, so keep them small for fast tests. Shrinking goes
//! toward fewer cells, no jitter and the identity transform.
//!
//! ```
//! use hooke_mesh::proptest_support::{pinned_set, tri_mesh};
//! use proptest::prelude::*;
//!
//! proptest! {
//!     #![proptest_config(ProptestConfig::with_cases(8))]
//!     fn areas_are_positive(mesh in tri_mesh(4)) {
//!         prop_assert!(mesh.areas().iter().all(|&a| a > 0.0));
//!     }
//! }
//! # areas_are_positive();
//! ```

use std::ops::RangeInclusive;

use nalgebra::{Rotation3, SVector};
use proptest::prelude::*;

use crate::generators::cloth;
use crate::{Bending, MassModel, SpringMesh, TetMesh, TriMesh, Vec3};

/// Grid sizes (vertices per side) in `range`, raised to at least 2 (the smallest grid).
pub fn grid_size(range: RangeInclusive<usize>) -> impl Strategy<Value = usize> {
    let low = (*range.start()).max(2);
    let high = (*range.end()).max(low);
    low..=high
}

/// cloth-N spring meshes ([`cloth`]) with N from [`grid_size`]`(n_range)` and one stiffness (N/m)
/// drawn from `stiffness_range`.
///
/// # Panics
/// When the strategy is built, if the stiffness range is empty or not within (0, ∞).
pub fn cloth_mesh(
    n_range: RangeInclusive<usize>,
    stiffness_range: RangeInclusive<f64>,
) -> impl Strategy<Value = SpringMesh<3>> {
    assert!(
        *stiffness_range.start() > 0.0
            && stiffness_range.end().is_finite()
            && stiffness_range.start() <= stiffness_range.end(),
        "cloth_mesh: the stiffness range must be positive and finite"
    );
    (grid_size(n_range), stiffness_range)
        .prop_map(|(n, k)| cloth(n, k).expect("cloth-N with N ≥ 2 and k > 0 is valid"))
}

/// A similarity transform: rotation, uniform scale, translation.
#[derive(Clone, Debug)]
struct Transform {
    rotation: Rotation3<f64>,
    scale: f64,
    translation: Vec3,
}

impl Transform {
    fn apply(&self, p: Vec3) -> Vec3 {
        self.rotation * p * self.scale + self.translation
    }
}

/// Random rotation (Euler angles), scale in [0.01, 100] (log-uniform) and translation in [−10, 10]³.
/// Shrinks toward the identity.
fn transform() -> impl Strategy<Value = Transform> {
    use std::f64::consts::PI;
    (
        prop_oneof![Just(0.0), -PI..PI],
        prop_oneof![Just(0.0), -PI / 2.0..PI / 2.0],
        prop_oneof![Just(0.0), -PI..PI],
        prop_oneof![Just(0.0), -2.0f64..2.0],
        prop_oneof![
            Just([0.0; 3]),
            [-10.0f64..10.0, -10.0f64..10.0, -10.0f64..10.0]
        ],
    )
        .prop_map(|(roll, pitch, yaw, log_scale, t)| Transform {
            rotation: Rotation3::from_euler_angles(roll, pitch, yaw),
            scale: 10f64.powf(log_scale),
            translation: Vec3::from(t),
        })
}

/// A jitter of norm at most 1 in `N` dimensions (a point of the unit ball's bounding cube, scaled
/// into the ball), shrinking toward zero.
fn unit_jitter<const N: usize>() -> impl Strategy<Value = SVector<f64, N>> {
    proptest::collection::vec(-1.0f64..=1.0, N).prop_map(|v| {
        let v = SVector::<f64, N>::from_iterator(v);
        let norm = v.norm();
        if norm > 1.0 {
            v / norm
        } else {
            v
        }
    })
}

/// Triangle meshes: a jittered grid of 1..=`max_cells` cells per side (2..=`max_cells` + 1 vertices),
/// cells of aspect ratio in [0.5, 2], each cell split along a random diagonal, every vertex moved in
/// the plane by at most 0.25 of the shorter spacing (which keeps every triangle's smallest altitude
/// above a quarter of the unjittered one, so none degenerates or flips), then rotated, scaled by
/// [0.01, 100] and translated. Vertex (i, j) has index i·(cells_y + 1) + j.
///
/// # Panics
/// When the strategy is built, if `max_cells == 0`.
pub fn tri_mesh(max_cells: usize) -> impl Strategy<Value = TriMesh> {
    assert!(max_cells >= 1, "tri_mesh: max_cells must be at least 1");
    (1..=max_cells, 1..=max_cells, 0.5f64..=2.0, transform())
        .prop_flat_map(|(cx, cy, aspect, transform)| {
            let vertices = (cx + 1) * (cy + 1);
            (
                Just((cx, cy, aspect, transform)),
                proptest::collection::vec(unit_jitter::<2>(), vertices),
                proptest::collection::vec(any::<bool>(), cx * cy),
            )
        })
        .prop_map(|((cx, cy, aspect, transform), jitter, flips)| {
            let (hx, hy): (f64, f64) = (1.0, aspect);
            let amplitude = 0.25 * hx.min(hy);
            let index = |i: usize, j: usize| (i * (cy + 1) + j) as u32;
            let mut positions = Vec::with_capacity(jitter.len());
            for i in 0..=cx {
                for j in 0..=cy {
                    let d = jitter[index(i, j) as usize] * amplitude;
                    let p = Vec3::new(i as f64 * hx + d.x, j as f64 * hy + d.y, 0.0);
                    positions.push(transform.apply(p));
                }
            }
            let mut triangles = Vec::with_capacity(2 * cx * cy);
            for i in 0..cx {
                for j in 0..cy {
                    let (a, b, c, d) = (
                        index(i, j),
                        index(i + 1, j),
                        index(i + 1, j + 1),
                        index(i, j + 1),
                    );
                    if flips[i * cy + j] {
                        triangles.extend([[a, b, d], [b, c, d]]);
                    } else {
                        triangles.extend([[a, b, c], [a, c, d]]);
                    }
                }
            }
            TriMesh::new(positions, triangles).expect("a jittered grid triangulation is valid")
        })
}

/// Tetrahedral meshes: a box of 1..=`max_cells` cubes per axis (random per axis), each cube split
/// into 6 tetrahedra around its main diagonal as in [`crate::generators::beam_tet_mesh`] (same vertex
/// numbering and orientation), every vertex moved by at most 0.15 of the spacing, then rotated, scaled
/// by [0.01, 100] and translated. All tetrahedra stay positively oriented: for a corner jitter of
/// radius r·h, 6·volume/h³ of the path tetrahedron is at least about 0.41 at r = 0.15 (numerical
/// minimum over the jitter spheres), against 1 unjittered.
///
/// # Panics
/// When the strategy is built, if `max_cells == 0`.
pub fn tet_mesh(max_cells: usize) -> impl Strategy<Value = TetMesh> {
    assert!(max_cells >= 1, "tet_mesh: max_cells must be at least 1");
    (1..=max_cells, 1..=max_cells, 1..=max_cells, transform())
        .prop_flat_map(|(ca, cb, cc, transform)| {
            let vertices = (ca + 1) * (cb + 1) * (cc + 1);
            (
                Just(([ca, cb, cc], transform)),
                proptest::collection::vec(unit_jitter::<3>(), vertices),
            )
        })
        .prop_map(|((cells, transform), jitter)| {
            let mesh = jittered_box(cells, &jitter, 0.15, &transform);
            debug_assert!(mesh.tetrahedra().iter().all(|t| {
                let [a, b, c, d] = t.map(|v| mesh.positions()[v as usize]);
                crate::tetrahedron_signed_volume(&a, &b, &c, &d) > 0.0
            }));
            mesh
        })
}

/// The Freudenthal (Kuhn) split of a box of unit cubes, jittered by `amplitude` × `jitter` and
/// transformed.
fn jittered_box(
    cells: [usize; 3],
    jitter: &[Vec3],
    amplitude: f64,
    transform: &Transform,
) -> TetMesh {
    let dims = cells.map(|c| c + 1);
    crate::generators::lattice_tet_mesh(cells, |[a, b, c]| {
        let k = (a * dims[1] + b) * dims[2] + c;
        transform.apply(Vec3::new(a as f64, b as f64, c as f64) + jitter[k] * amplitude)
    })
    .expect("a jittered Freudenthal box is valid")
}

/// Mass models: uniform with a total in [0.1, 100] kg, or by density in [1, 10⁴] kg/m³ with a
/// thickness in [10⁻⁴, 0.1] m.
pub fn mass_model() -> impl Strategy<Value = MassModel> {
    prop_oneof![
        (0.1f64..=100.0).prop_map(|total| MassModel::Uniform { total }),
        (1.0f64..=1e4, 1e-4f64..=0.1)
            .prop_map(|(density, thickness)| MassModel::Density { density, thickness }),
    ]
}

/// 3D spring meshes: either a [`tri_mesh`] (springs on its edges, with or without bending springs) or
/// a [`tet_mesh`] (springs on its edges), with one stiffness in [1, 10⁶] N/m (log-uniform) and a
/// [`mass_model`].
///
/// # Panics
/// When the strategy is built, if `max_cells == 0`.
pub fn spring_mesh_3d(max_cells: usize) -> impl Strategy<Value = SpringMesh<3>> {
    let stiffness = (0.0f64..=6.0).prop_map(|e| 10f64.powf(e));
    let bending = prop_oneof![Just(Bending::None), Just(Bending::InteriorEdges)];
    prop_oneof![
        (
            tri_mesh(max_cells),
            stiffness.clone(),
            bending,
            mass_model()
        )
            .prop_map(|(mesh, k, bending, mass)| SpringMesh::from_triangles(
                &mesh, k, bending, mass
            )
            .expect("springs on a valid triangle mesh are valid")),
        (tet_mesh(max_cells), stiffness, mass_model()).prop_map(|(mesh, k, mass)| {
            SpringMesh::from_tetrahedra(&mesh, k, mass)
                .expect("springs on a valid tetrahedral mesh are valid")
        }),
    ]
}

/// A random subset of the vertices `0..n`, sorted, as `u32` indices: possibly empty, never all of
/// them (a mesh with every vertex pinned cannot move). Each vertex is pinned with probability 0.2.
///
/// # Panics
/// When the strategy is built, if `n` exceeds the `u32` index range.
pub fn pinned_set(n: usize) -> impl Strategy<Value = Vec<u32>> {
    assert!(
        u32::try_from(n).is_ok(),
        "pinned_set: {n} vertices exceed the u32 index range"
    );
    (
        proptest::collection::vec(proptest::bool::weighted(0.2), n),
        0..n.max(1),
    )
        .prop_map(move |(mut pinned, free)| {
            if n > 0 && pinned.iter().all(|&p| p) {
                pinned[free] = false;
            }
            pinned
                .iter()
                .enumerate()
                .filter(|(_, &p)| p)
                .map(|(i, _)| i as u32)
                .collect()
        })
}

/// `positions` with every coordinate moved by a uniform random amount in [−`amplitude`, `amplitude`]
/// (m): a bounded perturbation of a state, e.g. to test forces away from rest.
///
/// # Panics
/// When the strategy is built, if `amplitude` is negative or not finite.
pub fn perturbed_positions<const D: usize>(
    positions: Vec<SVector<f64, D>>,
    amplitude: f64,
) -> impl Strategy<Value = Vec<SVector<f64, D>>> {
    assert!(
        amplitude >= 0.0 && amplitude.is_finite(),
        "perturbed_positions: the amplitude must be non-negative and finite"
    );
    let n = positions.len();
    proptest::collection::vec(-amplitude..=amplitude, n * D).prop_map(move |offsets| {
        positions
            .iter()
            .zip(offsets.chunks_exact(D))
            .map(|(p, d)| p + SVector::<f64, D>::from_column_slice(d))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::test_runner::TestRunner;

    #[test]
    fn meshes_are_valid_and_oriented() {
        let mut runner = TestRunner::deterministic();
        runner
            .run(&(tri_mesh(5), tet_mesh(3)), |(tri, tet)| {
                for t in tri.triangles() {
                    let [a, b, c] = t.map(|v| tri.positions()[v as usize]);
                    let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
                    // A quarter of the right-triangle altitude survives the jitter.
                    prop_assert!(crate::triangle_area(&a, &b, &c) > 1e-3 * longest * longest);
                }
                for t in tet.tetrahedra() {
                    let [a, b, c, d] = t.map(|v| tet.positions()[v as usize]);
                    let v = crate::tetrahedron_signed_volume(&a, &b, &c, &d);
                    let longest = [(a, b), (a, c), (a, d), (b, c), (b, d), (c, d)]
                        .iter()
                        .map(|(p, q)| (p - q).norm())
                        .fold(0.0, f64::max);
                    prop_assert!(v > 1e-3 * longest.powi(3), "volume {v}");
                }
                Ok(())
            })
            .unwrap();
    }

    #[test]
    fn pinned_sets_are_sorted_proper_subsets() {
        let mut runner = TestRunner::deterministic();
        runner
            .run(
                &(0usize..6).prop_flat_map(|n| (Just(n), pinned_set(n))),
                |(n, pins)| {
                    prop_assert!(pins.windows(2).all(|w| w[0] < w[1]));
                    prop_assert!(pins.iter().all(|&p| (p as usize) < n));
                    prop_assert!(n == 0 || pins.len() < n);
                    Ok(())
                },
            )
            .unwrap();
    }

    #[test]
    fn perturbation_is_bounded() {
        let p = vec![nalgebra::Vector2::new(1.0, 2.0); 5];
        let mut runner = TestRunner::deterministic();
        runner
            .run(&perturbed_positions(p.clone(), 0.5), |q| {
                prop_assert_eq!(q.len(), 5);
                for (a, b) in p.iter().zip(&q) {
                    prop_assert!((a - b).amax() <= 0.5);
                }
                Ok(())
            })
            .unwrap();
    }
}
