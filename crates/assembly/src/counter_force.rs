//! Pinned vertices by counter-forces (docs/model.md §5.3): keep every DOF, and hold a pinned vertex
//! in place by a force that cancels the force on it, with that force's derivative in the Jacobian. The alternative to the reduction of [`FreeDofs`] (docs/model.md §5.2, the
//! default), and tested to give the same steps.
//!
//! # The method
//! Newton on g(x) = M (x − y) − h² f(x) (docs/model.md §6.4) with a counter-force f_c on every
//! pinned vertex p equal to minus the force on it: g_p = M_p (x_p − y_p) − h² (f_p + f_c,p)
//! = M_p (x_p − y_p), zero for a vertex held where it is (x_p = y_p: the counter-force also cancels
//! gravity and the other external forces; a pin that moves is placed on its path before the step).
//! The derivative of f_c,p is −∂f_p/∂x, so row p of ∇g is M_p in its diagonal block and zero
//! elsewhere, and the Newton step keeps Δx_p = 0. Column p of the free rows, ∂g_f/∂x_p, then
//! multiplies Δx_p = 0: it is zeroed too, which changes no step and keeps the matrix symmetric (for
//! Cholesky and CG).
//!
//! # Relation to the reduction
//! With K the identity with the pinned rows removed and P the identity with the free rows removed,
//! [`CounterForce`] turns the full-DOF H and g into
//!
//! Ĥ = KᵀK H KᵀK + Pᵀ M_pinned P,   ĝ = KᵀK g.
//!
//! Up to a permutation Ĥ is block diagonal, diag(K H Kᵀ, M_pinned), so Ĥ Δx = −ĝ gives
//! K Δx = −(K H Kᵀ)⁻¹ K g, the step of the reduced system K H Kᵀ Δx_f = −K g, and P Δx = 0.
//! Ĥ is positive definite exactly when K H Kᵀ is (pinned masses are positive). The cost is the
//! pinned DOFs kept in the system and the full-DOF pattern; the gain is one numbering for every
//! vector and a pattern independent of which vertices are pinned.

use std::ops::Range;

use crate::{FreeDofs, HessianPattern};

/// The positions, in a full-DOF [`HessianPattern`]'s value array, of the rows and columns of the
/// pinned vertices, built once per pattern and set of pins; [`CounterForce::apply`] then applies the
/// counter-forces to a refilled matrix and gradient in O(pinned vertices × their degree), without
/// allocating.
///
/// Invariants: the pattern it was built for has every vertex free; `columns` and `row_blocks` index
/// that pattern's value array.
#[derive(Clone, Debug)]
pub struct CounterForce<const D: usize> {
    pinned: Vec<u32>,
    vertex_count: usize,
    nnz: usize,
    /// Per pinned vertex: its block column's values, and where its diagonal block starts with the
    /// stride between its scalar columns.
    columns: Vec<PinnedColumn>,
    /// The blocks (p, w) of pinned rows p in the columns of other vertices w: first value, stride.
    row_blocks: Vec<(usize, usize)>,
}

#[derive(Clone, Debug)]
struct PinnedColumn {
    values: Range<usize>,
    diagonal: usize,
    stride: usize,
}

impl<const D: usize> CounterForce<D> {
    /// The counter-forces holding the pinned vertices of `pins` in a matrix with the pattern
    /// `pattern`, which must keep every DOF (built with `free = None`). O(Σ degree log degree) over
    /// the pinned vertices.
    ///
    /// # Panics
    /// If `pattern` has pinned vertices removed, or `pins` was built for another vertex count.
    #[track_caller]
    pub fn new(pattern: &HessianPattern<D>, pins: &FreeDofs) -> Self {
        let graph = pattern.graph();
        let vertex_count = graph.free().vertex_count();
        assert_eq!(
            graph.free().free_count(),
            vertex_count,
            "CounterForce::new: the pattern must keep every DOF (build it with free = None)"
        );
        assert_eq!(
            pins.vertex_count(),
            vertex_count,
            "CounterForce::new: the pins were made for another vertex count"
        );
        // With every vertex free, free index = vertex index.
        let value_start = |column: usize| D * D * graph.column_blocks(column).start;
        let stride = |column: usize| D * graph.column_blocks(column).len();
        let mut columns = Vec::with_capacity(pins.pinned().len());
        let mut row_blocks = Vec::new();
        for &p in pins.pinned() {
            let p = p as usize;
            let start = value_start(p);
            columns.push(PinnedColumn {
                values: start..start + D * D * graph.column_blocks(p).len(),
                diagonal: start + D * graph.diagonal_slot(p),
                stride: stride(p),
            });
            for &w in graph.block_rows(p) {
                let w = w as usize;
                if w == p {
                    continue;
                }
                // The pattern is structurally symmetric: block (p, w) exists because (w, p) does.
                let slot = graph
                    .block_rows(w)
                    .binary_search(&(p as u32))
                    .expect("the block pattern is symmetric");
                row_blocks.push((value_start(w) + D * slot, stride(w)));
            }
        }
        CounterForce {
            pinned: pins.pinned().to_vec(),
            vertex_count,
            nnz: pattern.nnz(),
            columns,
            row_blocks,
        }
    }

    /// The pinned vertices, strictly increasing.
    pub fn pinned(&self) -> &[u32] {
        &self.pinned
    }

    /// Apply the counter-forces to a full-DOF matrix (`values`, refilled by
    /// [`HessianPattern::assemble_into`], possibly with damping added) and its gradient: see
    /// [`CounterForce::apply_to_matrix`] and [`CounterForce::apply_to_gradient`].
    ///
    /// # Panics
    /// As those two.
    #[track_caller]
    pub fn apply(&self, masses: &[f64], values: &mut [f64], gradient: &mut [f64]) {
        self.apply_to_matrix(masses, values);
        self.apply_to_gradient(gradient);
    }

    /// The matrix part: zero the rows and columns of the pinned DOFs and put m_p I_D (`masses`, kg,
    /// per vertex) in each pinned vertex's diagonal block. An exactly symmetric matrix stays exactly
    /// symmetric. With every pinned mass positive, the result is positive definite exactly when the
    /// matrix restricted to the free DOFs is.
    ///
    /// # Panics
    /// If `masses` does not have one entry per vertex or `values` one per stored entry of the
    /// pattern this was built for.
    #[track_caller]
    pub fn apply_to_matrix(&self, masses: &[f64], values: &mut [f64]) {
        assert_eq!(
            masses.len(),
            self.vertex_count,
            "CounterForce::apply_to_matrix: one mass per vertex"
        );
        assert_eq!(
            values.len(),
            self.nnz,
            "CounterForce::apply_to_matrix: one value per stored entry"
        );
        for &(start, stride) in &self.row_blocks {
            for b in 0..D {
                values[start + b * stride..][..D].fill(0.0);
            }
        }
        for (column, &p) in self.columns.iter().zip(&self.pinned) {
            values[column.values.clone()].fill(0.0);
            for b in 0..D {
                values[column.diagonal + b * column.stride + b] = masses[p as usize];
            }
        }
    }

    /// The right-hand side part: zero the pinned entries of the gradient g (one value per DOF,
    /// DOF D·v + a being component a of vertex v), the counter-force cancelling every force on a
    /// pinned vertex held in place.
    ///
    /// # Panics
    /// If `gradient` does not have D values per vertex.
    #[track_caller]
    pub fn apply_to_gradient(&self, gradient: &mut [f64]) {
        assert_eq!(
            gradient.len(),
            D * self.vertex_count,
            "CounterForce::apply_to_gradient: D values per vertex"
        );
        for &p in &self.pinned {
            gradient[D * p as usize..][..D].fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spring::Definiteness;
    use crate::{HessianParams, SpringForces};
    use hooke_mesh::proptest_support::{perturbed_positions, pinned_set, spring_mesh_3d};
    use hooke_mesh::SpringMesh;
    use nalgebra::{DMatrix, DVector, Vector3};
    use proptest::prelude::*;

    fn dense(m: faer::sparse::SparseColMatRef<'_, usize, f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(m.nrows(), m.ncols());
        for t in m.triplet_iter() {
            out[(t.row, t.col)] += *t.val;
        }
        out
    }

    /// M + h² ∇²E on `free` (all vertices if `None`), dense.
    fn hessian(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        free: Option<&FreeDofs>,
        h: f64,
        definiteness: Definiteness,
    ) -> (HessianPattern<3>, Vec<f64>) {
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), free);
        let mut values = pattern.new_values();
        let params = HessianParams {
            definiteness,
            parallel: false,
        };
        pattern.assemble_into(
            mesh.springs(),
            x,
            mesh.masses(),
            h,
            params,
            &mut pattern.workspace(),
            &mut values,
        );
        (pattern, values)
    }

    fn min_rest_length(mesh: &SpringMesh<3>) -> f64 {
        mesh.springs()
            .iter()
            .map(|s| s.rest_length)
            .fold(f64::INFINITY, f64::min)
    }

    /// A mesh, a state x away from rest, an inertial target y, and pins (at least one free vertex).
    #[allow(clippy::type_complexity)]
    fn case() -> impl Strategy<
        Value = (
            SpringMesh<3>,
            Vec<Vector3<f64>>,
            Vec<Vector3<f64>>,
            Vec<u32>,
        ),
    > {
        spring_mesh_3d(3).prop_flat_map(|mesh| {
            let n = mesh.vertex_count();
            let amplitude = 0.3 * min_rest_length(&mesh);
            let x = perturbed_positions(mesh.positions().to_vec(), amplitude);
            let y = perturbed_positions(mesh.positions().to_vec(), amplitude);
            (Just(mesh), x, y, pinned_set(n))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        #[test]
        fn counter_force_step_is_the_reduced_step(
            (mesh, x, y, pinned) in case(),
            h in 1e-3f64..0.1,
            exact in any::<bool>(),
        ) {
            let n = mesh.vertex_count();
            let definiteness = if exact { Definiteness::Exact } else { Definiteness::Clamped };
            let pins = FreeDofs::new(n, &pinned).unwrap();
            // The full gradient g = M (x − y) − h² f(x), one value per DOF.
            let mut f = vec![Vector3::zeros(); n];
            SpringForces::new(n, mesh.springs()).compute(mesh.springs(), &x, None, &mut f, false);
            let g: Vec<f64> = (0..n)
                .flat_map(|v| ((x[v] - y[v]) * mesh.masses()[v] - f[v] * (h * h)).data.0[0])
                .collect();

            // Counter-force: full DOFs.
            let (full_pattern, mut full_values) = hessian(&mesh, &x, None, h, definiteness);
            let counter = CounterForce::new(&full_pattern, &pins);
            let mut g_full = g.clone();
            counter.apply(mesh.masses(), &mut full_values, &mut g_full);
            let a_full = dense(full_pattern.matrix(&full_values));
            prop_assert_eq!(&a_full, &a_full.transpose(), "counter-forced matrix not symmetric");

            // Reduction: free DOFs only.
            let (pattern, values) = hessian(&mesh, &x, Some(&pins), h, definiteness);
            let a = dense(pattern.matrix(&values));
            let g_free: Vec<f64> = pins
                .free_vertices()
                .iter()
                .flat_map(|&v| g[3 * v as usize..][..3].to_vec())
                .collect();

            // The step's accuracy is set by the conditioning of the free system: skip the (rare)
            // nearly singular exact Hessians of strongly compressed meshes.
            let sv = a.clone().singular_values();
            let kappa = sv.max() / sv.min();
            prop_assume!(kappa < 1e10, "κ = {}", kappa);

            let step_full = a_full.lu().solve(&-DVector::from_vec(g_full)).expect("nonsingular");
            let step_free = a.lu().solve(&-DVector::from_vec(g_free)).expect("nonsingular");

            for &p in pins.pinned() {
                for c in 0..3 {
                    // Row p reads m_p Δx_p = 0 and is decoupled: exactly zero, not small.
                    prop_assert_eq!(step_full[3 * p as usize + c], 0.0);
                }
            }
            // Both are backward-stable solves (LU with partial pivoting) of the same free system,
            // so each is within ~dim · ε · κ of the exact step, relative to its size; 10 dim ε κ
            // bounds their difference with margin for the pivot growth of a symmetric matrix.
            let dim = step_full.len() as f64;
            let tolerance = 10.0 * dim * f64::EPSILON * kappa * step_free.amax();
            for (f, &v) in pins.free_vertices().iter().enumerate() {
                for c in 0..3 {
                    let (full, reduced) = (step_full[3 * v as usize + c], step_free[3 * f + c]);
                    prop_assert!(
                        (full - reduced).abs() <= tolerance,
                        "vertex {} axis {}: counter-force step {} vs reduced step {} (tolerance {}, κ {})",
                        v, c, full, reduced, tolerance, kappa
                    );
                }
            }
        }
    }

    #[test]
    fn pinned_rows_and_columns_become_mass_times_identity() {
        let mesh = hooke_mesh::generators::cloth(4, 10.0).unwrap();
        let n = mesh.vertex_count();
        let pins = FreeDofs::new(n, &[0, 5, 15]).unwrap();
        let (pattern, mut values) =
            hessian(&mesh, mesh.positions(), None, 0.1, Definiteness::Exact);
        let before = dense(pattern.matrix(&values));
        let counter = CounterForce::new(&pattern, &pins);
        let mut g = vec![1.0; 3 * n];
        counter.apply(mesh.masses(), &mut values, &mut g);
        let after = dense(pattern.matrix(&values));
        for r in 0..3 * n {
            let pinned_r = pins.is_pinned(r / 3);
            assert_eq!(g[r], if pinned_r { 0.0 } else { 1.0 });
            for c in 0..3 * n {
                let pinned_c = pins.is_pinned(c / 3);
                let want = if r == c && pinned_r {
                    mesh.masses()[r / 3]
                } else if pinned_r || pinned_c {
                    0.0
                } else {
                    before[(r, c)]
                };
                assert_eq!(after[(r, c)], want, "entry ({r}, {c})");
            }
        }
    }

    #[test]
    #[should_panic(expected = "must keep every DOF")]
    fn a_reduced_pattern_is_refused() {
        let mesh = hooke_mesh::generators::cloth(3, 1.0).unwrap();
        let pins = FreeDofs::new(mesh.vertex_count(), &[0]).unwrap();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&pins));
        CounterForce::new(&pattern, &pins);
    }
}
