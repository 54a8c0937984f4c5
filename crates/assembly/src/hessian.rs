//! The Hessian of the backward Euler objective Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) (SPEC §2.4),
//! M + h² ∇²E, as a sparse symmetric matrix in faer's CSC format over the free degrees of freedom.
//!
//! [`HessianPattern`] is built once per topology (springs and pinned vertices): the symbolic CSC
//! structure, with both triangles stored, sorted row indices and dense D×D blocks, and the map
//! telling which springs contribute to each block. [`HessianPattern::assemble_into`] then refills
//! the value array in place for every new state, without allocating, in parallel or not, with the
//! same bits either way. [`HessianPattern::matrix`] views the pattern and a value array as a faer
//! [`SparseColMatRef`] without copying, ready for `faer`'s sparse Cholesky (whose symbolic analysis
//! can therefore be reused across refills).
//!
//! Pinned vertices (SPEC §3) are removed by assembling directly on the free vertices: their rows and
//! columns never exist, a spring from a free vertex to a pinned one adds to the free vertex's
//! diagonal block only. The result is K (M + h² ∇²E) Kᵀ, bit for bit equal to the full matrix with
//! the pinned rows and columns deleted.

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use hooke_mesh::Spring;
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::SVector;

use crate::forces::PARALLEL_THRESHOLD;
use crate::graph::{BlockGraph, Contribution, Reuse};
use crate::spring::{Definiteness, HessianTerms};
use crate::FreeDofs;

/// Options of [`HessianPattern::assemble_into`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HessianParams {
    /// Exact spring Hessians (the default: Newton's quadratic convergence) or the clamped, positive
    /// semidefinite variant (see [`Definiteness`]).
    pub definiteness: Definiteness,
    /// Fill the block columns in parallel with rayon (default `true`). Ignored below 8,192 springs,
    /// where thread start-up costs more than the work. The result is the same bit for bit.
    pub parallel: bool,
}

impl Default for HessianParams {
    fn default() -> Self {
        HessianParams {
            definiteness: Definiteness::Exact,
            parallel: true,
        }
    }
}

/// The fixed sparsity pattern of M + h² ∇²E over the free DOFs of a spring mesh in dimension D, and
/// the map from springs to stored values.
///
/// The matrix is (D·n_free) × (D·n_free), DOF `D·f + a` being component `a` of free vertex `f`
/// (numbering of [`FreeDofs`]). Stored: every D×D block (f, g) with f = g or f, g joined by at least
/// one spring, dense, in both triangles; row indices sorted within each column.
#[derive(Clone, Debug)]
pub struct HessianPattern<const D: usize> {
    graph: BlockGraph,
    symbolic: SymbolicSparseColMat<usize>,
}

impl<const D: usize> HessianPattern<D> {
    const DIMENSION_IS_1_TO_3: () =
        assert!(D >= 1 && D <= 3, "HessianPattern supports D = 1, 2, 3");

    /// The pattern for `springs` over `vertex_count` vertices, on the free vertices of `free` (all
    /// vertices if `None`). O(s log d) time for s springs of largest vertex degree d, O(nnz) memory.
    ///
    /// # Panics
    /// If a spring has an end ≥ `vertex_count` or joins a vertex to itself (a validated
    /// `SpringMesh` never does), or `free` was built for another vertex count.
    #[track_caller]
    pub fn new(vertex_count: usize, springs: &[Spring], free: Option<&FreeDofs>) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::DIMENSION_IS_1_TO_3;
        let all;
        let free = match free {
            Some(free) => free,
            None => {
                all = FreeDofs::all_free(vertex_count);
                &all
            }
        };
        let graph = BlockGraph::new(vertex_count, springs, free);
        let symbolic = graph.symbolic::<D>();
        HessianPattern { graph, symbolic }
    }

    /// The free-DOF map the pattern was built on.
    pub fn free_dofs(&self) -> &FreeDofs {
        self.graph.free()
    }

    /// Number of rows (= columns): D × the number of free vertices.
    pub fn dof_count(&self) -> usize {
        D * self.graph.columns()
    }

    /// Number of stored values (both triangles).
    pub fn nnz(&self) -> usize {
        D * D * self.graph.blocks()
    }

    /// Number of springs the pattern was built for.
    pub fn spring_count(&self) -> usize {
        self.graph.spring_count()
    }

    /// The symbolic CSC structure (for a reusable symbolic Cholesky factorisation).
    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.symbolic.as_ref()
    }

    /// A zeroed value array of the right length, to be filled by [`HessianPattern::assemble_into`].
    pub fn new_values(&self) -> Vec<f64> {
        vec![0.0; self.nnz()]
    }

    /// The matrix with this pattern and the values `values`, as a borrowed faer matrix (no copy).
    ///
    /// # Panics
    /// If `values.len()` is not [`HessianPattern::nnz`].
    #[track_caller]
    pub fn matrix<'a>(&'a self, values: &'a [f64]) -> SparseColMatRef<'a, usize, f64> {
        assert_eq!(
            values.len(),
            self.nnz(),
            "HessianPattern::matrix: one value per stored entry"
        );
        SparseColMatRef::new(self.symbolic.as_ref(), values)
    }

    /// An owned copy of the matrix with the values `values` (allocates; for one-off use).
    ///
    /// # Panics
    /// If `values.len()` is not [`HessianPattern::nnz`].
    #[track_caller]
    pub fn to_sparse_col_mat(&self, values: &[f64]) -> SparseColMat<usize, f64> {
        assert_eq!(
            values.len(),
            self.nnz(),
            "HessianPattern::to_sparse_col_mat: one value per stored entry"
        );
        SparseColMat::new(self.symbolic.clone(), values.to_vec())
    }

    /// A workspace for [`HessianPattern::assemble_into`] (one packed symmetric block per spring,
    /// 48 bytes). Allocate it once and reuse it for every refill.
    pub fn workspace(&self) -> HessianWorkspace<D> {
        HessianWorkspace {
            blocks: (0..self.graph.spring_count())
                .map(|_| Default::default())
                .collect(),
        }
    }

    /// Refill `values` with M + h² ∇²E at `positions` (kg): diagonal block of free vertex v:
    /// m_v I + h² Σ H_s over the springs at v (pinned other end included); block of free vertices
    /// v ≠ w: −h² Σ H_s over the springs joining them; H_s is
    /// [`hessian_block`](crate::spring::hessian_block) of the spring with `params.definiteness`.
    ///
    /// No allocation. Each block column gathers the blocks of its springs in increasing spring
    /// order and writes its values; a spring's block −h² H_s is computed once, by its first free end,
    /// and kept in `workspace` for the second (computed again only where the two ends fall in
    /// different parallel tasks). Every stored value is thus a sum in a fixed order, the same for (v, w) and
    /// (w, v): the matrix is exactly symmetric, and serial and parallel refills give the same bits.
    ///
    /// `springs` must be those the pattern was built with (same ends, in the same order; stiffness
    /// and rest length may change). `positions` and `masses` (kg, ≥ 0; those of pinned vertices are
    /// not read) are per vertex of the full mesh. `h` is the time step (s); with `h = 1` and zero
    /// masses the result is the elastic Hessian ∇²E alone.
    ///
    /// # Panics
    /// If the number of springs, positions, masses or values does not match the pattern, or the
    /// workspace was made for another pattern (in debug builds also if a spring's ends changed).
    #[allow(clippy::too_many_arguments)] // the state (springs, positions, masses, h) and the buffers
    #[track_caller]
    pub fn assemble_into(
        &self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        params: HessianParams,
        workspace: &mut HessianWorkspace<D>,
        values: &mut [f64],
    ) {
        let free = self.graph.free();
        assert_eq!(
            springs.len(),
            self.graph.spring_count(),
            "assemble_into: the springs are not those of the pattern"
        );
        assert_eq!(
            positions.len(),
            free.vertex_count(),
            "assemble_into: one position per vertex"
        );
        assert_eq!(
            masses.len(),
            free.vertex_count(),
            "assemble_into: one mass per vertex"
        );
        assert_eq!(
            workspace.blocks.len(),
            springs.len(),
            "assemble_into: the workspace was made for another pattern"
        );
        assert_eq!(
            values.len(),
            self.nnz(),
            "assemble_into: one value per stored entry"
        );
        let parallel = params.parallel && springs.len() >= PARALLEL_THRESHOLD;
        let definiteness = params.definiteness;
        let h2 = h * h;
        let kept = &workspace.blocks[..];
        let graph = &self.graph;
        let fill = |column: usize, out: &mut [f64]| {
            let column_len = D * graph.column_blocks(column).len();
            let vertex = free.free_vertices()[column] as usize;
            // Σ (−h² H_s) over the springs at this vertex.
            let mut sum = [0.0; PACKED];
            for c in graph.contributions(column) {
                let spring = &springs[c.spring as usize];
                debug_assert!(
                    {
                        let (i, j) = spring.ends();
                        i == vertex || j == vertex
                    },
                    "spring {} moved",
                    c.spring
                );
                let slot = &kept[c.spring as usize];
                let packed = if c.reuse == Reuse::Kept {
                    std::array::from_fn(|e| f64::from_bits(slot[e].load(Ordering::Relaxed)))
                } else {
                    let packed = spring_block(spring, positions, definiteness, h2);
                    if c.reuse == Reuse::ComputeAndKeep {
                        for (k, v) in slot.iter().zip(&packed) {
                            k.store(v.to_bits(), Ordering::Relaxed);
                        }
                    }
                    packed
                };
                for (acc, v) in sum.iter_mut().zip(&packed).take(PACKED_LEN[D]) {
                    *acc += v;
                }
                if c.slot != Contribution::PINNED_OTHER {
                    let at = D * c.slot as usize;
                    for b in 0..D {
                        let dst = &mut out[b * column_len + at..][..D];
                        if c.first {
                            for (a, d) in dst.iter_mut().enumerate() {
                                *d = packed[packed_index::<D>(a, b)];
                            }
                        } else {
                            for (a, d) in dst.iter_mut().enumerate() {
                                *d += packed[packed_index::<D>(a, b)];
                            }
                        }
                    }
                }
            }
            let at = D * graph.diagonal_slot(column);
            let mass = masses[vertex];
            for b in 0..D {
                let dst = &mut out[b * column_len + at..][..D];
                for (a, d) in dst.iter_mut().enumerate() {
                    *d = -sum[packed_index::<D>(a, b)];
                }
                dst[b] += mass;
            }
        };
        graph.for_each_column::<D, _>(values, parallel, &fill);
    }
}

/// Scratch memory of [`HessianPattern::assemble_into`]: room for −h² H_s of every spring (packed
/// upper triangle), where the first end of a spring keeps its block for the second. Made by
/// [`HessianPattern::workspace`]; its contents between calls mean nothing. (The entries are atomics
/// only so that parallel tasks can share the buffer without `unsafe`: each entry is written and read
/// by one task, with relaxed ordering, which costs the same as plain loads and stores.)
#[derive(Debug)]
pub struct HessianWorkspace<const D: usize> {
    blocks: Vec<[AtomicU64; PACKED]>,
}

/// −h² H_s of one spring, packed upper triangle.
#[inline]
fn spring_block<const D: usize>(
    s: &Spring,
    positions: &[SVector<f64, D>],
    definiteness: Definiteness,
    h2: f64,
) -> [f64; PACKED] {
    let (i, j) = s.ends();
    let t = HessianTerms::new(
        s.stiffness,
        s.rest_length,
        &(positions[i] - positions[j]),
        definiteness,
    );
    let (p, q) = (-h2 * t.along, -h2 * t.across);
    let mut packed = [0.0; PACKED];
    for b in 0..D {
        for a in 0..=b {
            packed[packed_index::<D>(a, b)] = p * (t.unit[a] * t.unit[b]);
        }
        packed[packed_index::<D>(b, b)] += q;
    }
    packed
}

/// Length of a packed symmetric block: D (D + 1) / 2 ≤ 6 for D ≤ 3.
const PACKED: usize = 6;
/// Used length of a packed block by dimension.
const PACKED_LEN: [usize; 4] = [0, 1, 3, 6];

/// Position of entry (a, b) (either order) of a symmetric D×D block in its packed upper triangle
/// (column by column: (0,0), (0,1), (1,1), (0,2), (1,2), (2,2)).
#[inline(always)]
fn packed_index<const D: usize>(a: usize, b: usize) -> usize {
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    b * (b + 1) / 2 + a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spring::hessian_block;
    use crate::{fd, SpringForces};
    use hooke_mesh::generators::{beam, cloth};
    use hooke_mesh::proptest_support::{pinned_set, spring_mesh_3d};
    use hooke_mesh::SpringMesh;
    use nalgebra::{DMatrix, Vector3};
    use proptest::prelude::*;

    fn dense(m: SparseColMatRef<'_, usize, f64>) -> DMatrix<f64> {
        let mut out = DMatrix::zeros(m.nrows(), m.ncols());
        for t in m.triplet_iter() {
            out[(t.row, t.col)] += *t.val;
        }
        out
    }

    /// Positions moved deterministically by up to `amplitude` (m) per coordinate.
    fn wobble(p: &[Vector3<f64>], amplitude: f64) -> Vec<Vector3<f64>> {
        p.iter()
            .enumerate()
            .map(|(k, x)| {
                let k = k as f64;
                x + Vector3::new((k * 0.37).sin(), (k * 1.11).cos(), (k * 2.3).sin()) * amplitude
            })
            .collect()
    }

    fn min_rest_length(mesh: &SpringMesh<3>) -> f64 {
        mesh.springs()
            .iter()
            .map(|s| s.rest_length)
            .fold(f64::INFINITY, f64::min)
    }

    /// M + h² ∇²E on the free DOFs by central differences of the force (dense).
    fn finite_difference_hessian(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        free: &FreeDofs,
        h: f64,
    ) -> DMatrix<f64> {
        let n = mesh.vertex_count();
        let nf = free.free_count();
        let mut flat = Vec::with_capacity(3 * nf);
        for &v in free.free_vertices() {
            flat.extend_from_slice(x[v as usize].as_slice());
        }
        let shortest = mesh
            .springs()
            .iter()
            .map(|s| (x[s.i as usize] - x[s.j as usize]).norm())
            .fold(f64::INFINITY, f64::min);
        let jac = fd::jacobian(
            |y, out| {
                let mut full = x.to_vec();
                let free_positions: Vec<Vector3<f64>> =
                    y.chunks_exact(3).map(Vector3::from_column_slice).collect();
                free.expand_vector(&free_positions, &mut full);
                let mut forces = SpringForces::new(n, mesh.springs());
                let mut f = vec![Vector3::zeros(); n];
                forces.compute(mesh.springs(), &full, None, &mut f, false);
                let mut reduced = vec![Vector3::zeros(); nf];
                free.reduce_vector(&f, &mut reduced);
                for (o, v) in out.chunks_exact_mut(3).zip(&reduced) {
                    o.copy_from_slice(v.as_slice());
                }
            },
            &flat,
            3 * nf,
            fd::suggested_step(shortest),
        );
        let mut reference = -jac * (h * h);
        for (f, &v) in free.free_vertices().iter().enumerate() {
            for a in 0..3 {
                reference[(3 * f + a, 3 * f + a)] += mesh.masses()[v as usize];
            }
        }
        reference
    }

    fn assemble(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        free: Option<&FreeDofs>,
        masses: &[f64],
        h: f64,
        definiteness: Definiteness,
    ) -> (HessianPattern<3>, Vec<f64>) {
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), free);
        let mut values = pattern.new_values();
        let params = HessianParams {
            definiteness,
            parallel: true,
        };
        let mut workspace = pattern.workspace();
        pattern.assemble_into(
            mesh.springs(),
            x,
            masses,
            h,
            params,
            &mut workspace,
            &mut values,
        );
        (pattern, values)
    }

    fn assert_exactly_symmetric(a: &DMatrix<f64>) {
        for r in 0..a.nrows() {
            for c in 0..r {
                assert_eq!(
                    a[(r, c)].to_bits(),
                    a[(c, r)].to_bits(),
                    "entry ({r}, {c}) differs from ({c}, {r})"
                );
            }
        }
    }

    fn check_against_finite_differences(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        pinned: &[u32],
        h: f64,
    ) {
        let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
        let (pattern, values) =
            assemble(mesh, x, Some(&free), mesh.masses(), h, Definiteness::Exact);
        let a = dense(pattern.matrix(&values));
        let reference = finite_difference_hessian(mesh, x, &free, h);
        // Central differences with h = 1e-5 × the shortest spring: each entry is off by ~1e-10 of the
        // largest entry (see `fd`); 1e-6 of the largest entry leaves room for sums over neighbours.
        let scale = a.amax();
        let error = (&a - &reference).amax();
        assert!(
            error <= 1e-6 * scale,
            "assembled Hessian differs from finite differences by {error} (largest entry {scale})"
        );
        assert_exactly_symmetric(&a);
    }

    #[test]
    fn cloth_and_beam_hessians_match_finite_differences() {
        let mesh = cloth(6, 50.0).unwrap();
        let x = wobble(mesh.positions(), 0.3 * min_rest_length(&mesh));
        check_against_finite_differences(&mesh, &x, &[], 0.01);
        check_against_finite_differences(&mesh, &x, &[0, 5], 0.01);
        let mesh = beam(1).unwrap();
        let x = wobble(mesh.positions(), 0.3 * min_rest_length(&mesh));
        check_against_finite_differences(&mesh, &x, &[0, 1, 2, 3], 1e-3);
    }

    fn mesh_state_pins() -> impl Strategy<Value = (SpringMesh<3>, Vec<Vector3<f64>>, Vec<u32>)> {
        spring_mesh_3d(3).prop_flat_map(|mesh| {
            let n = mesh.vertex_count();
            let amplitude = 0.3 * min_rest_length(&mesh);
            (
                Just(mesh.clone()),
                hooke_mesh::proptest_support::perturbed_positions(
                    mesh.positions().to_vec(),
                    amplitude,
                ),
                pinned_set(n),
            )
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        #[test]
        fn random_mesh_hessians_match_finite_differences((mesh, x, pinned) in mesh_state_pins()) {
            check_against_finite_differences(&mesh, &x, &pinned, 0.02);
        }

        #[test]
        fn reduced_matrix_is_the_full_one_without_pinned_rows((mesh, x, pinned) in mesh_state_pins()) {
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
                let (full_pattern, full_values) = assemble(&mesh, &x, None, mesh.masses(), 0.05, definiteness);
                let (pattern, values) = assemble(&mesh, &x, Some(&free), mesh.masses(), 0.05, definiteness);
                let full = dense(full_pattern.matrix(&full_values));
                let reduced = dense(pattern.matrix(&values));
                let mut kept = 0;
                for (g, &w) in free.free_vertices().iter().enumerate() {
                    for (f, &v) in free.free_vertices().iter().enumerate() {
                        for b in 0..3 {
                            for a in 0..3 {
                                let (r, c) = (3 * f + a, 3 * g + b);
                                let full_entry = full[(3 * v as usize + a, 3 * w as usize + b)];
                                prop_assert_eq!(reduced[(r, c)].to_bits(), full_entry.to_bits());
                            }
                        }
                        if full_pattern.matrix(&full_values).get(3 * v as usize, 3 * w as usize).is_some() {
                            kept += 9;
                        }
                    }
                }
                // No stored entry of the reduced pattern outside the full one, none missing.
                prop_assert_eq!(pattern.nnz(), kept);
            }
        }

        #[test]
        fn clamped_hessian_is_positive_semidefinite(
            (mesh, x, _pinned) in mesh_state_pins(),
            seed in proptest::collection::vec(-1.0f64..1.0, 64),
        ) {
            let zero = vec![0.0; mesh.vertex_count()];
            let (pattern, values) = assemble(&mesh, &x, None, &zero, 1.0, Definiteness::Clamped);
            let a = pattern.matrix(&values);
            let v: Vec<f64> = (0..pattern.dof_count()).map(|k| seed[k % seed.len()] * (1.0 + k as f64).sqrt().sin()).collect();
            let (mut quad, mut bound) = (0.0, 0.0);
            for t in a.triplet_iter() {
                quad += v[t.row] * t.val * v[t.col];
                bound += (v[t.row] * t.val * v[t.col]).abs();
            }
            // vᵀHv is a sum of non-negative per-spring terms; round-off is a few ε of Σ|terms|.
            prop_assert!(quad >= -1e-12 * bound, "vᵀHv = {} (Σ|terms| = {})", quad, bound);
        }

        #[test]
        fn elastic_hessian_annihilates_translations(
            (mesh, x, _pinned) in mesh_state_pins(),
            t in [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
        ) {
            let zero = vec![0.0; mesh.vertex_count()];
            let (pattern, values) = assemble(&mesh, &x, None, &zero, 1.0, Definiteness::Exact);
            let mut product = vec![0.0; pattern.dof_count()];
            let mut bound = vec![0.0; pattern.dof_count()];
            for e in pattern.matrix(&values).triplet_iter() {
                product[e.row] += e.val * t[e.col % 3];
                bound[e.row] += (e.val * t[e.col % 3]).abs();
            }
            for (p, b) in product.iter().zip(&bound) {
                // Exact cancellation up to round-off of the sum: ε times the sum of |terms| per row.
                prop_assert!(p.abs() <= 1e-13 * b.max(f64::MIN_POSITIVE), "H(1⊗t) = {} (Σ|terms| {})", p, b);
            }
        }
    }

    #[test]
    fn serial_and_parallel_assembly_agree_bit_for_bit() {
        // cloth-100: 58,806 springs, above the parallel threshold, and 9,998 free vertices in 16
        // leaves, so that blocks kept across columns and blocks recomputed across leaves both occur.
        let mesh = cloth(100, 1e3).unwrap();
        let x = wobble(mesh.positions(), 0.002);
        let free = FreeDofs::new(mesh.vertex_count(), &[0, 99]).unwrap();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let mut workspace = pattern.workspace();
        let mut serial = pattern.new_values();
        let mut parallel = pattern.new_values();
        for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
            let params = |parallel| HessianParams {
                definiteness,
                parallel,
            };
            pattern.assemble_into(
                mesh.springs(),
                &x,
                mesh.masses(),
                0.01,
                params(false),
                &mut workspace,
                &mut serial,
            );
            pattern.assemble_into(
                mesh.springs(),
                &x,
                mesh.masses(),
                0.01,
                params(true),
                &mut workspace,
                &mut parallel,
            );
            assert!(
                serial
                    .iter()
                    .zip(&parallel)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{definiteness:?}: serial and parallel values differ"
            );
        }
        // Every off-diagonal block is −h² H_s of its spring (cloth-100 has no parallel springs), also
        // after a refill at other positions with the same workspace (no stale kept block is read).
        let moved = wobble(&x, 0.01);
        let params = HessianParams::default();
        for state in [&moved, &x] {
            pattern.assemble_into(
                mesh.springs(),
                state,
                mesh.masses(),
                0.01,
                params,
                &mut workspace,
                &mut parallel,
            );
            let a = pattern.matrix(&parallel);
            for s in mesh.springs() {
                let (i, j) = s.ends();
                let (Some(fi), Some(fj)) = (free.free_index(i), free.free_index(j)) else {
                    continue;
                };
                let block = hessian_block(
                    s.stiffness,
                    s.rest_length,
                    &(state[i] - state[j]),
                    Definiteness::Exact,
                ) * -1e-4;
                for (r, c) in [(fi, fj), (fj, fi)] {
                    for b in 0..3 {
                        for q in 0..3 {
                            let got = *a.get(3 * r + q, 3 * c + b).expect("stored block");
                            // Same terms, rounded in another order: a few ε of the block's size.
                            assert!(
                                (got - block[(q, b)]).abs() <= 1e-14 * block.amax(),
                                "spring ({i}, {j})"
                            );
                        }
                    }
                }
            }
        }
        // Refilling into a dirty buffer gives the same values: nothing depends on the old contents.
        let mut dirty = vec![f64::NAN; pattern.nnz()];
        pattern.assemble_into(
            mesh.springs(),
            &x,
            mesh.masses(),
            0.01,
            params,
            &mut workspace,
            &mut dirty,
        );
        assert!(dirty
            .iter()
            .zip(&parallel)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn two_dimensional_hessian_matches_finite_differences() {
        // The seed-2d scene (radius graph, fixed rest length 0.1 m: springs start stretched or
        // compressed), one pin, through the D = 2 code path.
        let mesh = hooke_mesh::generators::seed_2d().unwrap();
        let n = mesh.vertex_count();
        let x: Vec<nalgebra::Vector2<f64>> = mesh
            .positions()
            .iter()
            .enumerate()
            .map(|(k, p)| {
                p + nalgebra::Vector2::new((k as f64).sin(), (k as f64 * 0.7).cos()) * 0.01
            })
            .collect();
        let free = FreeDofs::new(n, &[0]).unwrap();
        let pattern = HessianPattern::<2>::new(n, mesh.springs(), Some(&free));
        let mut values = pattern.new_values();
        let h = 0.01;
        let params = HessianParams::default();
        pattern.assemble_into(
            mesh.springs(),
            &x,
            mesh.masses(),
            h,
            params,
            &mut pattern.workspace(),
            &mut values,
        );
        let a = dense(pattern.matrix(&values));
        assert_exactly_symmetric(&a);
        let mut flat = Vec::new();
        for &v in free.free_vertices() {
            flat.extend_from_slice(x[v as usize].as_slice());
        }
        let shortest = mesh
            .springs()
            .iter()
            .map(|s| (x[s.i as usize] - x[s.j as usize]).norm())
            .fold(f64::INFINITY, f64::min);
        let jac = fd::jacobian(
            |y, out| {
                let mut full = x.clone();
                let moved: Vec<_> = y
                    .chunks_exact(2)
                    .map(nalgebra::Vector2::from_column_slice)
                    .collect();
                free.expand_vector(&moved, &mut full);
                let mut f = vec![nalgebra::Vector2::zeros(); n];
                SpringForces::new(n, mesh.springs()).compute(
                    mesh.springs(),
                    &full,
                    None,
                    &mut f,
                    false,
                );
                let mut reduced = vec![nalgebra::Vector2::zeros(); free.free_count()];
                free.reduce_vector(&f, &mut reduced);
                for (o, v) in out.chunks_exact_mut(2).zip(&reduced) {
                    o.copy_from_slice(v.as_slice());
                }
            },
            &flat,
            flat.len(),
            fd::suggested_step(shortest),
        );
        let mut reference = -jac * (h * h);
        for (f, &v) in free.free_vertices().iter().enumerate() {
            for c in 0..2 {
                reference[(2 * f + c, 2 * f + c)] += mesh.masses()[v as usize];
            }
        }
        // As in 3D: ~1e-10 of the largest entry per finite difference, 1e-6 leaves room.
        let error = (&a - &reference).amax();
        assert!(
            error <= 1e-6 * a.amax(),
            "2D Hessian off by {error} (largest entry {})",
            a.amax()
        );
    }

    #[test]
    fn pattern_is_sorted_and_exactly_symmetric_on_cloth() {
        let mesh = cloth(7, 20.0).unwrap();
        let x = wobble(mesh.positions(), 0.01);
        let (pattern, values) = assemble(&mesh, &x, None, mesh.masses(), 0.01, Definiteness::Exact);
        // faer's checked constructor already verified sorted, unique row indices; count the blocks:
        // one per vertex and two per distinct neighbour pair (cloth springs are all distinct).
        assert_eq!(
            pattern.nnz(),
            9 * (mesh.vertex_count() + 2 * mesh.springs().len())
        );
        assert_exactly_symmetric(&dense(pattern.matrix(&values)));
    }

    #[test]
    fn duplicate_springs_are_summed() {
        let p = vec![Vector3::zeros(), Vector3::x(), Vector3::x() * 2.0];
        let s = |i, j, k| Spring {
            i,
            j,
            stiffness: k,
            rest_length: 0.5,
        };
        let springs = vec![s(0, 1, 2.0), s(1, 2, 1.0), s(1, 0, 3.0)];
        let merged = vec![s(0, 1, 5.0), s(1, 2, 1.0)];
        let zero = [0.0; 3];
        let params = HessianParams::default();
        let build = |springs: &[Spring]| {
            let pattern = HessianPattern::<3>::new(3, springs, None);
            let mut v = pattern.new_values();
            pattern.assemble_into(
                springs,
                &p,
                &zero,
                1.0,
                params,
                &mut pattern.workspace(),
                &mut v,
            );
            dense(pattern.matrix(&v))
        };
        // Integer-valued: the sums of blocks of parallel springs are the block of their stiffness sum.
        assert_eq!(build(&springs), build(&merged));
    }

    #[test]
    fn degenerate_springs_give_finite_values() {
        let mesh = cloth(4, 100.0).unwrap();
        let l = mesh.springs()[0].rest_length;
        let mut x = mesh.positions().to_vec();
        x[1] = x[0]; // zero length
        x[5] = x[4] + Vector3::new(1e-6 * l, 0.0, 0.0); // very short
        x[15] += Vector3::new(1e3 * l, -2e3 * l, 0.0); // very long
        for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
            let (_, values) = assemble(&mesh, &x, None, mesh.masses(), 0.01, definiteness);
            assert!(
                values.iter().all(|v| v.is_finite()),
                "{definiteness:?}: non-finite value"
            );
        }
    }

    #[test]
    #[should_panic(expected = "one value per stored entry")]
    fn wrong_value_length_panics() {
        let mesh = cloth(3, 1.0).unwrap();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), None);
        let mut workspace = pattern.workspace();
        let mut values = vec![0.0; pattern.nnz() - 1];
        pattern.assemble_into(
            mesh.springs(),
            mesh.positions(),
            mesh.masses(),
            0.1,
            HessianParams::default(),
            &mut workspace,
            &mut values,
        );
    }
}
