//! The Hessian of the backward Euler objective Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x)
//! (docs/model.md §6.4),
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
//! Damping (docs/model.md §4) adds to the same values: [`HessianPattern::add_dashpot_into`] the
//! velocity Jacobian of the dashpot along the springs, scaled (h for backward Euler), and
//! [`HessianPattern::add_vertex_diagonal`] a per-vertex multiple of the identity (viscous damping
//! h·c, or masses).
//!
//! Pinned vertices (docs/model.md §5.2) are removed by assembling directly on the free vertices:
//! their rows and columns never exist, a spring from a free vertex to a pinned one adds to the free
//! vertex's diagonal block only. The result is K (M + h² ∇²E) Kᵀ, bit for bit equal to the full
//! matrix with the pinned rows and columns deleted.

use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use hooke_mesh::Spring;
use std::ops::Range;

use nalgebra::{SMatrix, SVector};

use crate::forces::PARALLEL_THRESHOLD;
use crate::graph::{block_pattern_with_links, matrix_owned, matrix_ref, BlockGraph, Contribution};
use crate::schedule::{Gather, RefillSchedule};
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
    schedule: RefillSchedule,
    symbolic: SymbolicSparseColMat<usize>,
    /// The off-diagonal blocks no spring writes (those of [`HessianPattern::with_links`]), as
    /// (block column, slot): zeroed by every refill.
    link_blocks: Vec<(u32, u32)>,
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
        Self::with_links(vertex_count, springs, &[], free)
    }

    /// [`HessianPattern::new`] with a block for every pair of free vertices in `links` (vertex
    /// indices of the full mesh) as well, for terms that couple vertices no spring joins
    /// (self-contact pairs), which add their blocks with [`HessianPattern::add_block`]. Links with
    /// a pinned end, repeated links and links along springs add no block. A refill writes zeros
    /// into the blocks no spring writes, so they hold only what is added after it.
    ///
    /// # Panics
    /// As [`HessianPattern::new`], and if a link has an end ≥ `vertex_count`.
    #[track_caller]
    pub fn with_links(
        vertex_count: usize,
        springs: &[Spring],
        links: &[[u32; 2]],
        free: Option<&FreeDofs>,
    ) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::DIMENSION_IS_1_TO_3;
        let (graph, symbolic) = block_pattern_with_links::<D>(vertex_count, springs, links, free);
        let schedule = RefillSchedule::new::<D>(&graph);
        let mut link_blocks = Vec::new();
        if !links.is_empty() {
            let mut written = Vec::new();
            for column in 0..graph.columns() {
                written.clear();
                written.resize(graph.column_blocks(column).len(), false);
                written[graph.diagonal_slot(column)] = true;
                for c in graph.contributions(column) {
                    if c.slot != Contribution::PINNED_OTHER {
                        written[c.slot as usize] = true;
                    }
                }
                link_blocks.extend(
                    (0..written.len())
                        .filter(|&slot| !written[slot])
                        .map(|slot| (column as u32, slot as u32)),
                );
            }
        }
        HessianPattern {
            graph,
            schedule,
            symbolic,
            link_blocks,
        }
    }

    /// Whether the pattern stores the block (`row`, `column`) of block columns (free vertex
    /// numbers in [`FreeDofs`], or vertex indices for a pattern on all vertices).
    pub fn has_block(&self, row: usize, column: usize) -> bool {
        column < self.graph.columns()
            && self
                .graph
                .block_rows(column)
                .binary_search(&(row as u32))
                .is_ok()
    }

    /// Add `block` to the block (`row`, `column`) (block column numbers as in
    /// [`HessianPattern::has_block`]); `false`, adding nothing, if the pattern does not store it.
    /// Only this block is touched: add the transpose to (`column`, `row`) to keep `values`
    /// symmetric (a symmetric term adding both in the same order keeps it exactly symmetric).
    ///
    /// # Panics
    /// If `column` is out of range or `values` does not have one entry per stored entry.
    #[track_caller]
    pub fn add_block(
        &self,
        row: usize,
        column: usize,
        block: &SMatrix<f64, D, D>,
        values: &mut [f64],
    ) -> bool {
        assert_eq!(
            values.len(),
            self.nnz(),
            "add_block: one value per stored entry"
        );
        let graph = &self.graph;
        let Ok(slot) = graph.block_rows(column).binary_search(&(row as u32)) else {
            return false;
        };
        let blocks = graph.column_blocks(column);
        let column_len = D * blocks.len();
        let at = D * D * blocks.start + D * slot;
        for b in 0..D {
            for a in 0..D {
                values[at + b * column_len + a] += block[(a, b)];
            }
        }
        true
    }

    /// Add `scale` times an element's Hessian `hessian` over K vertices (a (K·D) × (K·D) matrix in
    /// column-major order, K = `columns.len()`) into the blocks of the block columns `columns`
    /// (`None` for a vertex that is not a column, whose rows and columns are skipped), block
    /// column by block column: the same additions, in the same order, as
    /// [`HessianPattern::add_block`] called for every pair (a, b) with b outer. `false`, adding
    /// nothing more from that point, if the pattern lacks one of the blocks.
    ///
    /// # Panics
    /// If a column is out of range, `hessian` is not (K·D)² long, or `values` does not have one
    /// entry per stored entry.
    #[track_caller]
    pub fn add_element(
        &self,
        columns: &[Option<usize>],
        hessian: &[f64],
        scale: f64,
        values: &mut [f64],
    ) -> bool {
        let size = D * columns.len();
        assert_eq!(hessian.len(), size * size, "add_element: a (K·D)² Hessian");
        assert_eq!(
            values.len(),
            self.nnz(),
            "add_element: one value per stored entry"
        );
        let graph = &self.graph;
        for (b, column) in columns.iter().enumerate() {
            let Some(column) = *column else { continue };
            let rows = graph.block_rows(column);
            let blocks = graph.column_blocks(column);
            let column_len = D * blocks.len();
            for (a, row) in columns.iter().enumerate() {
                let Some(row) = *row else { continue };
                let Ok(slot) = rows.binary_search(&(row as u32)) else {
                    return false;
                };
                let at = D * D * blocks.start + D * slot;
                for c in 0..D {
                    let source = &hessian[(D * b + c) * size + D * a..][..D];
                    let target = &mut values[at + c * column_len..][..D];
                    for (t, h) in target.iter_mut().zip(source) {
                        *t += scale * h;
                    }
                }
            }
        }
        true
    }

    /// Zero the blocks no spring writes ([`HessianPattern::with_links`]).
    fn zero_link_blocks(&self, values: &mut [f64]) {
        for &(column, slot) in &self.link_blocks {
            let blocks = self.graph.column_blocks(column as usize);
            let column_len = D * blocks.len();
            let at = D * D * blocks.start + D * slot as usize;
            for b in 0..D {
                values[at + b * column_len..at + b * column_len + D].fill(0.0);
            }
        }
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

    /// The block structure (for the other assembly modules).
    pub(crate) fn graph(&self) -> &BlockGraph {
        &self.graph
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
        matrix_ref(&self.symbolic, values, "HessianPattern::matrix")
    }

    /// An owned copy of the matrix with the values `values` (allocates; for one-off use).
    ///
    /// # Panics
    /// If `values.len()` is not [`HessianPattern::nnz`].
    #[track_caller]
    pub fn to_sparse_col_mat(&self, values: &[f64]) -> SparseColMat<usize, f64> {
        matrix_owned(&self.symbolic, values, "HessianPattern::to_sparse_col_mat")
    }

    /// A workspace for [`HessianPattern::assemble_into`]: the ring buffers where spring blocks wait
    /// for their second end (48 bytes a block; a few thousand blocks per parallel task on meshes
    /// with a banded numbering, at most one per spring). Allocate it once and reuse it for every
    /// refill.
    pub fn workspace(&self) -> HessianWorkspace<D> {
        HessianWorkspace {
            ring: vec![[0.0; PACKED]; self.schedule.ring_len()],
        }
    }

    /// Refill `values` with M + h² ∇²E at `positions` (kg): diagonal block of free vertex v:
    /// m_v I + h² Σ H_s over the springs at v (pinned other end included); block of free vertices
    /// v ≠ w: −h² Σ H_s over the springs joining them; H_s is
    /// [`hessian_block`](crate::spring::hessian_block) of the spring with `params.definiteness`.
    ///
    /// No allocation. Each block column gathers the blocks of its springs in increasing spring
    /// order and writes its values, in column order (the writes stream through the value array, and
    /// on x86-64 arrays of 16 MiB or more are prefetched a few columns ahead of them);
    /// a spring's block −h² H_s is computed once, by its first free end, a few springs at a time
    /// (vectorised), and kept in a small ring buffer in `workspace` for the second (computed again
    /// only where the two ends fall in different parallel tasks; see the `schedule` module). Every
    /// stored value is thus a sum in a fixed order, the same for (v, w) and (w, v): the matrix is
    /// exactly symmetric, and serial and parallel refills give the same bits.
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
        let mode = match params.definiteness {
            Definiteness::Exact => EXACT,
            Definiteness::Clamped => CLAMPED,
        };
        self.refill(
            springs,
            positions,
            masses,
            h,
            (mode, &[]),
            params.parallel,
            workspace,
            values,
        );
    }

    /// [`HessianPattern::assemble_into`] with the transverse eigenvalue of every compressed spring
    /// multiplied by its weight in `scales` (one per spring, in [0, 1]): spring s's block is
    /// k [c' I + (1 − c') r̂r̂ᵀ] with c' = σ_s (1 − l/|r|) where 1 − l/|r| < 0 and σ_s < 1, and the
    /// exact block (the same bits as [`Definiteness::Exact`]) everywhere else; σ_s = 0 gives the
    /// clamped block. The longitudinal eigenvalue k is kept. With the weights of
    /// [`HessianPattern::definite_scales`] the result is positive definite (see there). The same
    /// refill as `assemble_into` otherwise: no allocation, the same bits serial or parallel.
    ///
    /// # Panics
    /// As [`HessianPattern::assemble_into`], and if `scales` does not have one entry per spring.
    #[allow(clippy::too_many_arguments)] // the state (springs, positions, masses, h, weights) and the buffers
    #[track_caller]
    pub fn assemble_scaled_into(
        &self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        scales: &[f64],
        parallel: bool,
        workspace: &mut HessianWorkspace<D>,
        values: &mut [f64],
    ) {
        assert_eq!(
            scales.len(),
            springs.len(),
            "assemble_scaled_into: one weight per spring"
        );
        self.refill(
            springs,
            positions,
            masses,
            h,
            (SCALED, scales),
            parallel,
            workspace,
            values,
        );
    }

    /// The refill of [`HessianPattern::assemble_into`] and [`HessianPattern::assemble_scaled_into`]
    /// (`mode`: [`EXACT`], [`CLAMPED`] or [`SCALED`] with its weights), checks included.
    #[allow(clippy::too_many_arguments)]
    #[track_caller]
    fn refill(
        &self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        (mode, scales): (u8, &[f64]),
        parallel: bool,
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
            workspace.ring.len(),
            self.schedule.ring_len(),
            "assemble_into: the workspace was made for another pattern"
        );
        assert_eq!(
            values.len(),
            self.nnz(),
            "assemble_into: one value per stored entry"
        );
        let parallel = parallel && springs.len() >= PARALLEL_THRESHOLD;
        let refill = Refill {
            graph: &self.graph,
            schedule: &self.schedule,
            springs,
            positions,
            masses,
            scales,
            h2: h * h,
            prefetch: values.len() >= PREFETCH_MIN_VALUES,
        };
        let ring_offsets = Some(self.schedule.ring_offsets());
        let ring = &mut workspace.ring;
        // One copy of the loop per variant, so that the choice is not made per spring.
        match mode {
            EXACT => {
                let fill = |columns, values: &mut [f64], ring: &mut [[f64; PACKED]]| {
                    refill.leaf::<EXACT>(columns, values, ring)
                };
                self.graph
                    .for_each_leaf::<D, _, _>(values, ring, ring_offsets, parallel, &fill);
            }
            CLAMPED => {
                let fill = |columns, values: &mut [f64], ring: &mut [[f64; PACKED]]| {
                    refill.leaf::<CLAMPED>(columns, values, ring)
                };
                self.graph
                    .for_each_leaf::<D, _, _>(values, ring, ring_offsets, parallel, &fill);
            }
            _ => {
                let fill = |columns, values: &mut [f64], ring: &mut [[f64; PACKED]]| {
                    refill.leaf::<SCALED>(columns, values, ring)
                };
                self.graph
                    .for_each_leaf::<D, _, _>(values, ring, ring_offsets, parallel, &fill);
            }
        }
        self.zero_link_blocks(values);
    }

    /// Add the velocity Jacobian of the dashpot damping along every spring, scaled: for each spring
    /// s = (i, j) with B_s = `scale` · c · r̂r̂ᵀ (r = x_i − x_j at `positions`, m), add B_s to the
    /// diagonal blocks of i and j and −B_s to the blocks (i, j) and (j, i). This is
    /// −`scale` · ∂f_dashpot/∂v with f_i = −c ((v_i − v_j)·r̂) r̂ (docs/model.md §4, see
    /// [`dashpot_velocity_block`](crate::spring::dashpot_velocity_block)): positive semidefinite for
    /// `scale` · c ≥ 0. Backward Euler uses `scale` = h: in positions, g(x) = M (x − y) −
    /// h² f(x, (x − x_n)/h) has the Jacobian M − h² ∂f/∂x − h ∂f/∂v, and the velocity form
    /// M − h ∂f/∂v − h² ∂f/∂x has the same damping term.
    ///
    /// Units: `coefficient` c in N·s/m, `scale` in s to add to a matrix in kg (N·s²/m), or 1 for the
    /// damping matrix itself (N·s/m).
    ///
    /// Only the free DOFs are touched: a spring from a free vertex to a pinned one adds B_s to the
    /// free vertex's diagonal block (its velocity derivative with respect to the free end), and
    /// nothing else, so the result is K (A + `scale` · C) Kᵀ for the full damping matrix C, as for
    /// [`HessianPattern::assemble_into`]. A spring of zero length has no direction and adds nothing
    /// (as [`dashpot_force`](crate::spring::dashpot_force) is zero there).
    ///
    /// Invariants kept: the sums are in increasing spring order per block, the same for (v, w) and
    /// (w, v), so an exactly symmetric `values` stays exactly symmetric, and serial and parallel
    /// runs (chosen by size, as in `assemble_into`) give the same bits. No allocation.
    ///
    /// # Panics
    /// If the number of springs, positions (one per vertex of the full mesh) or values does not
    /// match the pattern (in debug builds also if a spring's ends changed).
    #[track_caller]
    pub fn add_dashpot_into(
        &self,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        coefficient: f64,
        scale: f64,
        values: &mut [f64],
    ) {
        let free = self.graph.free();
        assert_eq!(
            springs.len(),
            self.graph.spring_count(),
            "add_dashpot_into: the springs are not those of the pattern"
        );
        assert_eq!(
            positions.len(),
            free.vertex_count(),
            "add_dashpot_into: one position per vertex"
        );
        assert_eq!(
            values.len(),
            self.nnz(),
            "add_dashpot_into: one value per stored entry"
        );
        let factor = scale * coefficient;
        let graph = &self.graph;
        let fill = |column: usize, out: &mut [f64]| {
            let column_len = D * graph.column_blocks(column).len();
            let mut sum = [0.0; PACKED];
            for c in graph.contributions(column) {
                let spring = &springs[c.spring as usize];
                let (i, j) = spring.ends();
                debug_assert!(
                    {
                        let vertex = free.free_vertices()[column] as usize;
                        i == vertex || j == vertex
                    },
                    "spring {} moved",
                    c.spring
                );
                // The block is computed by each end (no workspace): the same bits both times.
                let packed = dashpot_block::<D>(&(positions[i] - positions[j]), factor);
                for (acc, v) in sum.iter_mut().zip(&packed).take(PACKED_LEN[D]) {
                    *acc += v;
                }
                if c.slot != Contribution::PINNED_OTHER {
                    let at = D * c.slot as usize;
                    for b in 0..D {
                        let dst = &mut out[b * column_len + at..][..D];
                        for (a, d) in dst.iter_mut().enumerate() {
                            *d -= packed[packed_index::<D>(a, b)];
                        }
                    }
                }
            }
            let at = D * graph.diagonal_slot(column);
            for b in 0..D {
                let dst = &mut out[b * column_len + at..][..D];
                for (a, d) in dst.iter_mut().enumerate() {
                    *d += sum[packed_index::<D>(a, b)];
                }
            }
        };
        let parallel = springs.len() >= PARALLEL_THRESHOLD;
        graph.for_each_column::<D, _>(values, parallel, &fill);
    }

    /// The D×D diagonal block of every free vertex, in free-vertex order, read from `values` (this
    /// pattern's value array): what a block-Jacobi preconditioner inverts. No allocation.
    ///
    /// # Panics
    /// If `values` does not have one entry per stored entry.
    #[track_caller]
    pub fn diagonal_blocks<'a>(
        &'a self,
        values: &'a [f64],
    ) -> impl ExactSizeIterator<Item = SMatrix<f64, D, D>> + 'a {
        assert_eq!(
            values.len(),
            self.nnz(),
            "diagonal_blocks: one value per stored entry"
        );
        let graph = &self.graph;
        (0..graph.columns()).map(move |column| {
            // Block column `column` holds D scalar columns of `column_len` values each, from
            // D² × (its first block); the diagonal block starts D × its slot down each of them.
            let blocks = graph.column_blocks(column);
            let column_len = D * blocks.len();
            let at = D * D * blocks.start + D * graph.diagonal_slot(column);
            SMatrix::from_fn(|a, b| values[at + b * column_len + a])
        })
    }

    /// Add `block` to the diagonal block of block column `column` (the free vertex numbered
    /// `column` in [`FreeDofs`], or vertex `column` for a pattern on all vertices). `block` should
    /// be symmetric; only its values are copied, entry by entry, so a symmetric block keeps
    /// `values` exactly symmetric. For per-vertex terms such as contact barriers against static
    /// obstacles.
    ///
    /// # Panics
    /// If `column` is out of range or `values` does not have one entry per stored entry.
    #[track_caller]
    pub fn add_diagonal_block(
        &self,
        column: usize,
        block: &SMatrix<f64, D, D>,
        values: &mut [f64],
    ) {
        assert_eq!(
            values.len(),
            self.nnz(),
            "add_diagonal_block: one value per stored entry"
        );
        let graph = &self.graph;
        let blocks = graph.column_blocks(column);
        let column_len = D * blocks.len();
        let at = D * D * blocks.start + D * graph.diagonal_slot(column);
        for b in 0..D {
            for a in 0..D {
                values[at + b * column_len + a] += block[(a, b)];
            }
        }
    }

    /// Add `per_vertex[v]` · I_D to the diagonal block of every free vertex v (`per_vertex` is
    /// indexed by full vertex index; the entries of pinned vertices are not read). For viscous
    /// damping f = −c v this adds `scale` · c per vertex (c in N·s/m, e.g. h · c in kg for backward
    /// Euler in positions), and for lumped masses m_v (kg). A diagonal added to an exactly
    /// symmetric `values` keeps it exactly symmetric; no allocation; the same bits serial or
    /// parallel (one addition per entry).
    ///
    /// # Panics
    /// If `per_vertex` does not have one entry per vertex of the full mesh, or `values` one per
    /// stored entry.
    #[track_caller]
    pub fn add_vertex_diagonal(&self, per_vertex: &[f64], values: &mut [f64]) {
        let free = self.graph.free();
        assert_eq!(
            per_vertex.len(),
            free.vertex_count(),
            "add_vertex_diagonal: one value per vertex"
        );
        assert_eq!(
            values.len(),
            self.nnz(),
            "add_vertex_diagonal: one value per stored entry"
        );
        let graph = &self.graph;
        let fill = |column: usize, out: &mut [f64]| {
            let column_len = D * graph.column_blocks(column).len();
            let at = D * graph.diagonal_slot(column);
            let add = per_vertex[free.free_vertices()[column] as usize];
            for b in 0..D {
                out[b * column_len + at + b] += add;
            }
        };
        // One cache line per scalar column is touched, spread over the whole array: worth two
        // threads on large meshes.
        let parallel = graph.spring_count().max(graph.columns()) >= PARALLEL_THRESHOLD;
        graph.for_each_column::<D, _>(values, parallel, &fill);
    }
}

/// `factor` · r̂r̂ᵀ (packed upper triangle), zero where r has no direction.
#[inline]
fn dashpot_block<const D: usize>(r: &SVector<f64, D>, factor: f64) -> [f64; PACKED] {
    let mut packed = [0.0; PACKED];
    if let Some((unit, _)) = crate::spring::direction(r) {
        for b in 0..D {
            for a in 0..=b {
                packed[packed_index::<D>(a, b)] = factor * (unit[a] * unit[b]);
            }
        }
    }
    packed
}

/// Scratch memory of [`HessianPattern::assemble_into`]: ring buffers of spring blocks −h² H_s
/// (packed upper triangle), one per parallel task, where the first end of a spring keeps its block
/// for the second. Made by [`HessianPattern::workspace`]; its contents between calls mean nothing.
#[derive(Clone, Debug)]
pub struct HessianWorkspace<const D: usize> {
    ring: Vec<[f64; PACKED]>,
}

/// The state of one refill, shared by the parallel tasks.
struct Refill<'a, const D: usize> {
    graph: &'a BlockGraph,
    schedule: &'a RefillSchedule,
    springs: &'a [Spring],
    positions: &'a [SVector<f64, D>],
    masses: &'a [f64],
    /// The weights of [`SCALED`] (empty otherwise).
    scales: &'a [f64],
    h2: f64,
    /// Whether to prefetch the value array ahead of the writes (large arrays only).
    prefetch: bool,
}

impl<const D: usize> Refill<'_, D> {
    /// Fill the values of the leaf `columns` (see [`RefillSchedule`]): spring blocks are computed
    /// [`BATCH`] at a time, up to `BATCH − 1` computes ahead of the column that needs them (the ring
    /// has that much slack), then each column gathers its blocks from the ring.
    fn leaf<const MODE: u8>(
        &self,
        columns: Range<usize>,
        values: &mut [f64],
        ring: &mut [[f64; PACKED]],
    ) {
        let schedule = self.schedule;
        let computes = schedule.computes(columns.clone());
        let plans = schedule.plans(columns.clone());
        let mut gathers = match (columns.start, columns.end.checked_sub(1)) {
            (first, Some(last)) if first <= last => schedule.gathers(
                self.graph.contribution_range(first).start..self.graph.contribution_range(last).end,
            ),
            _ => &[],
        };
        // Computes done so far in this leaf; compute k writes ring slot k mod R, and R is a
        // multiple of BATCH, so a batch starting at a multiple of BATCH writes consecutive slots.
        let (mut done, mut slot) = (0, 0);
        let mut rest = values;
        for (column, plan) in columns.zip(plans) {
            debug_assert!(
                schedule.computes(column..column + 1).iter().all(|&s| {
                    let (i, j) = self.springs[s as usize].ends();
                    let vertex = plan.vertex as usize;
                    i == vertex || j == vertex
                }),
                "a spring at column {column} moved"
            );
            let needed = plan.computes_end as usize;
            while done < needed {
                if let Some(batch) = computes.get(done..done + BATCH) {
                    let batch: &[u32; BATCH] = batch.try_into().expect("BATCH springs");
                    let out: &mut [[f64; PACKED]; BATCH] = (&mut ring[slot..slot + BATCH])
                        .try_into()
                        .expect("BATCH slots");
                    self.blocks::<BATCH, MODE>(batch, out);
                    done += BATCH;
                    slot += BATCH;
                } else {
                    // The last few computes of the leaf.
                    let out: &mut [[f64; PACKED]; 1] =
                        (&mut ring[slot..slot + 1]).try_into().expect("one slot");
                    self.blocks::<1, MODE>(&[computes[done]], out);
                    done += 1;
                    slot += 1;
                }
                if slot == ring.len() {
                    slot = 0;
                }
            }
            let len = plan.len as usize;
            let (out, tail) = std::mem::take(&mut rest).split_at_mut(D * len);
            rest = tail;
            if self.prefetch {
                prefetch_ahead(rest, D * len);
            }
            let (mine, others) = gathers.split_at(plan.gathers as usize);
            gathers = others;
            let mass = self.masses[plan.vertex as usize];
            let diagonal = plan.diagonal as usize;
            self.gather(mine, plan.simple, len, diagonal, mass, ring, out);
        }
    }

    /// Write the values of one block column (`len` values per scalar column, diagonal block at
    /// `diagonal`) from the blocks in `ring` its `gathers` name, adding `mass` on the diagonal.
    /// `simple`: every gather has a target and is the first to write it.
    #[allow(clippy::too_many_arguments)] // the column's plan, unpacked, and the buffers
    #[inline(always)]
    fn gather(
        &self,
        gathers: &[Gather],
        simple: bool,
        len: usize,
        diagonal: usize,
        mass: f64,
        ring: &[[f64; PACKED]],
        out: &mut [f64],
    ) {
        // Σ (−h² H_s) over the springs at this vertex, in increasing spring order (packed: each
        // entry once, so the diagonal block is exactly symmetric).
        let mut sum = [0.0; PACKED];
        if simple {
            // Every gather has a target and is the first to it (the common case): no tests.
            for g in gathers {
                let packed = &ring[g.ring as usize];
                for (acc, v) in sum.iter_mut().zip(packed).take(PACKED_LEN[D]) {
                    *acc += v;
                }
                let at = (g.target & !Gather::FIRST) as usize;
                // One bounds check for the D scalar columns of the block.
                let window = &mut out[at..at + (D - 1) * len + D];
                for b in 0..D {
                    let dst = &mut window[b * len..b * len + D];
                    for (a, d) in dst.iter_mut().enumerate() {
                        *d = packed[packed_index::<D>(a, b)];
                    }
                }
            }
        } else {
            for g in gathers {
                let packed = &ring[g.ring as usize];
                for (acc, v) in sum.iter_mut().zip(packed).take(PACKED_LEN[D]) {
                    *acc += v;
                }
                if g.target != Gather::NO_TARGET {
                    let at = (g.target & !Gather::FIRST) as usize;
                    let first = g.target & Gather::FIRST != 0;
                    let window = &mut out[at..at + (D - 1) * len + D];
                    for b in 0..D {
                        let dst = &mut window[b * len..b * len + D];
                        if first {
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
        }
        let window = &mut out[diagonal..diagonal + (D - 1) * len + D];
        for b in 0..D {
            let dst = &mut window[b * len..b * len + D];
            for (a, d) in dst.iter_mut().enumerate() {
                *d = -sum[packed_index::<D>(a, b)];
            }
            dst[b] += mass;
        }
    }

    /// −h² H_s of the springs `indices` into `out` (packed upper triangles): the arithmetic of
    /// [`HessianTerms`], lane by lane over the N springs without branches so that it vectorises
    /// (square roots and divisions included). Where a spring may have no direction or an
    /// overflowing block (`HessianTerms` then substitutes its stand-in), the N springs are redone
    /// one by one through `HessianTerms`. The same bits as one spring at a time.
    #[inline(always)]
    fn blocks<const N: usize, const MODE: u8>(
        &self,
        indices: &[u32; N],
        out: &mut [[f64; PACKED]; N],
    ) {
        // Structure of arrays, one operation over the N lanes at a time, so that each vectorises.
        let mut r = [[0.0; N]; D];
        let mut stiffness = [0.0; N];
        let mut rest_length = [0.0; N];
        for n in 0..N {
            let s = &self.springs[indices[n] as usize];
            let (i, j) = s.ends();
            let (xi, xj) = (&self.positions[i], &self.positions[j]);
            for a in 0..D {
                r[a][n] = xi[a] - xj[a];
            }
            stiffness[n] = s.stiffness;
            rest_length[n] = s.rest_length;
        }
        // |r|² summed in nalgebra's order (0 + x² + y² + z², and 0 + x² = x²).
        let mut length_squared = [0.0; N];
        for (a, ra) in r.iter().enumerate() {
            for n in 0..N {
                length_squared[n] = if a == 0 {
                    ra[n] * ra[n]
                } else {
                    length_squared[n] + ra[n] * ra[n]
                };
            }
        }
        let mut inverse_length = [0.0; N];
        for n in 0..N {
            inverse_length[n] = 1.0 / length_squared[n].sqrt();
        }
        let (mut p, mut q) = ([0.0; N], [0.0; N]);
        // Per lane, |r|² + 1/|r| + along + across: finite (in absolute value) only if all four
        // are, and 1/|r| is finite only if |r|² > 0, so a finite check means the lane is on the
        // fast path of `HessianTerms` (|r|² positive and finite, along and across finite); a finite
        // sum that overflows only makes the test cautious.
        let mut check = [0.0; N];
        let mut sigma = [1.0; N];
        if MODE == SCALED {
            for n in 0..N {
                sigma[n] = self.scales[indices[n] as usize];
            }
        }
        for n in 0..N {
            let ratio = rest_length[n] * inverse_length[n];
            let clamp = MODE == CLAMPED && ratio > 1.0;
            let across = if clamp { 0.0 } else { 1.0 - ratio };
            let along = if clamp { 1.0 } else { ratio };
            let (mut along, mut across) = (stiffness[n] * along, stiffness[n] * across);
            if MODE == SCALED {
                // As `HessianTerms::with_across_scale`, without a branch.
                let scaled = across < 0.0 && sigma[n] < 1.0;
                let weighted = sigma[n] * across;
                along = if scaled {
                    stiffness[n] - weighted
                } else {
                    along
                };
                across = if scaled { weighted } else { across };
            }
            check[n] = length_squared[n] + inverse_length[n] + along + across;
            p[n] = -self.h2 * along;
            q[n] = -self.h2 * across;
        }
        let fast = check
            .iter()
            .fold(true, |fast, c| fast & (c.abs() < f64::INFINITY));
        let mut unit = [[0.0; N]; D];
        for a in 0..D {
            for n in 0..N {
                unit[a][n] = r[a][n] * inverse_length[n];
            }
        }
        let mut packed = [[0.0; N]; PACKED];
        for b in 0..D {
            for a in 0..=b {
                for n in 0..N {
                    packed[packed_index::<D>(a, b)][n] = p[n] * (unit[a][n] * unit[b][n]);
                }
            }
            for n in 0..N {
                packed[packed_index::<D>(b, b)][n] += q[n];
            }
        }
        for n in 0..N {
            for k in 0..PACKED_LEN[D] {
                out[n][k] = packed[k][n];
            }
        }
        if !fast {
            let definiteness = if MODE == CLAMPED {
                Definiteness::Clamped
            } else {
                Definiteness::Exact
            };
            for n in 0..N {
                let s = &self.springs[indices[n] as usize];
                let (i, j) = s.ends();
                let r = self.positions[i] - self.positions[j];
                let mut t = HessianTerms::new(s.stiffness, s.rest_length, &r, definiteness);
                if MODE == SCALED {
                    t = t.with_across_scale(s.stiffness, sigma[n]);
                }
                let (p, q) = (-self.h2 * t.along, -self.h2 * t.across);
                for b in 0..D {
                    for a in 0..=b {
                        out[n][packed_index::<D>(a, b)] = p * (t.unit[a] * t.unit[b]);
                    }
                    out[n][packed_index::<D>(b, b)] += q;
                }
            }
        }
    }
}

/// How far ahead of the column being written a refill prefetches the value array, in values
/// (8 KiB: several columns of a cloth, enough to cover the memory latency).
const PREFETCH_AHEAD: usize = 1024;
/// Value arrays of at least this many values (16 MiB) are prefetched ahead of the writes: on
/// arrays that stay in cache the prefetches cost more than they save.
const PREFETCH_MIN_VALUES: usize = 1 << 21;

/// Ask for the cache lines of the `len` values `PREFETCH_AHEAD` values into `rest` (the part of
/// the value array after the column being written), so that the writes a few columns later find
/// their lines in cache instead of stalling on them; called once per column, this covers the
/// array line by line. A hint only: no effect on the values, and none off x86-64.
#[inline(always)]
fn prefetch_ahead(rest: &[f64], len: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let mut at = rest.as_ptr().wrapping_add(PREFETCH_AHEAD);
        let end = at.wrapping_add(len);
        while at < end {
            // SAFETY: a prefetch is a hint that reads and writes nothing and never faults, whatever
            // the address (past the end of the array included, reached by wrapping arithmetic).
            unsafe { _mm_prefetch::<_MM_HINT_T0>(at.cast()) };
            at = at.wrapping_add(8);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (rest, len);
}

/// The refill's spring blocks: exact ([`Definiteness::Exact`]).
const EXACT: u8 = 0;
/// Clamped ([`Definiteness::Clamped`]).
const CLAMPED: u8 = 1;
/// Exact with the compressed springs' transverse eigenvalues weighted
/// ([`HessianPattern::assemble_scaled_into`]).
const SCALED: u8 = 2;

/// Springs whose blocks a refill computes together.
pub(crate) const BATCH: usize = 4;

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

    /// ∇²E on the free DOFs (the spring part alone, N/m) by central differences of the force
    /// (dense).
    fn finite_difference_spring_hessian(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        free: &FreeDofs,
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
        -jac
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

    /// The assembled matrix against finite differences, in two parts, so that neither hides in
    /// the other: the spring part ∇²E (assembled with zero masses and h = 1) against central
    /// differences of the force, relative to the spring part's own largest entry (with the
    /// masses in, M dominates M + h²∇²E at small h: beam-1 at h = 1e-3 would let a 2 % error in
    /// the springs pass); then the matrix with the masses and `h` against M + h² times that
    /// spring part, which checks where the masses go and the h² scaling.
    fn check_against_finite_differences(
        mesh: &SpringMesh<3>,
        x: &[Vector3<f64>],
        pinned: &[u32],
        h: f64,
    ) {
        let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
        let no_masses = vec![0.0; mesh.vertex_count()];
        let (pattern, values) =
            assemble(mesh, x, Some(&free), &no_masses, 1.0, Definiteness::Exact);
        let springs = dense(pattern.matrix(&values));
        let reference = finite_difference_spring_hessian(mesh, x, &free);
        // Central differences with a step of 1e-5 × the shortest spring: each entry is off by
        // ~1e-10 of the largest entry (see `fd`); 1e-6 of the largest entry leaves room for sums
        // over neighbours and is still far below a 2 % error in any spring's block.
        let scale = springs.amax();
        let error = (&springs - &reference).amax();
        assert!(
            error <= 1e-6 * scale,
            "assembled ∇²E differs from finite differences by {error} (largest entry {scale})"
        );
        assert_exactly_symmetric(&springs);

        let (pattern, values) =
            assemble(mesh, x, Some(&free), mesh.masses(), h, Definiteness::Exact);
        let a = dense(pattern.matrix(&values));
        let mut expected = &springs * (h * h);
        let mut largest_mass: f64 = 0.0;
        for (f, &v) in free.free_vertices().iter().enumerate() {
            let m = mesh.masses()[v as usize];
            largest_mass = largest_mass.max(m);
            for c in 0..3 {
                expected[(3 * f + c, 3 * f + c)] += m;
            }
        }
        // The same products summed with h² inside or outside the sum, and one addition of the
        // mass: round-off only, a few ulps per summed term (at most ~30 neighbours per block row
        // here), so 64 ε of the larger part. The spring part's accuracy was checked above.
        let error = (&a - &expected).amax();
        let round_off = 64.0 * f64::EPSILON * (largest_mass + h * h * scale);
        assert!(
            error <= round_off,
            "M + h²∇²E differs from M + h² (∇²E at h = 1) by {error} (round-off {round_off})"
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
        fn diagonal_blocks_are_the_matrix_diagonal_blocks((mesh, x, pinned) in mesh_state_pins()) {
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            let (pattern, values) = assemble(&mesh, &x, Some(&free), mesh.masses(), 0.05, Definiteness::Exact);
            let matrix = dense(pattern.matrix(&values));
            let blocks = pattern.diagonal_blocks(&values);
            prop_assert_eq!(blocks.len(), free.free_count());
            for (f, block) in blocks.enumerate() {
                prop_assert_eq!(block, matrix.fixed_view::<3, 3>(3 * f, 3 * f).into_owned());
            }
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

    /// The full (3n × 3n) damping matrix C = −∂f_dashpot/∂v built densely from the per-spring
    /// blocks [`dashpot_velocity_block`](crate::spring::dashpot_velocity_block), in spring order.
    fn dense_dashpot_matrix(mesh: &SpringMesh<3>, x: &[Vector3<f64>], c: f64) -> DMatrix<f64> {
        let n = mesh.vertex_count();
        let mut out = DMatrix::zeros(3 * n, 3 * n);
        for s in mesh.springs() {
            let (i, j) = s.ends();
            // ∂f_i/∂v_i = −c r̂r̂ᵀ, ∂f_i/∂v_j = +c r̂r̂ᵀ; C is minus those.
            let block = crate::spring::dashpot_velocity_block(c, &(x[i] - x[j]));
            for (r, col, sign) in [(i, i, -1.0), (j, j, -1.0), (i, j, 1.0), (j, i, 1.0)] {
                for b in 0..3 {
                    for a in 0..3 {
                        out[(3 * r + a, 3 * col + b)] += sign * block[(a, b)];
                    }
                }
            }
        }
        out
    }

    /// The rows and columns of the free vertices of a full per-DOF matrix.
    fn free_part(full: &DMatrix<f64>, free: &FreeDofs) -> DMatrix<f64> {
        let nf = free.free_count();
        DMatrix::from_fn(3 * nf, 3 * nf, |r, c| {
            let (v, w) = (
                free.free_vertices()[r / 3] as usize,
                free.free_vertices()[c / 3] as usize,
            );
            full[(3 * v + r % 3, 3 * w + c % 3)]
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        #[test]
        fn dashpot_jacobian_is_the_sum_of_the_spring_blocks(
            (mesh, x, pinned) in mesh_state_pins(),
            c in 1e-3f64..1e3,
        ) {
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
            let mut values = pattern.new_values();
            pattern.add_dashpot_into(mesh.springs(), &x, c, 1.0, &mut values);
            let assembled = dense(pattern.matrix(&values));
            // Same products, summed from zero in the same (spring) order: equal, not merely close.
            // (Pinned rows and columns are absent from the pattern: `free_part` drops them.)
            let reference = free_part(&dense_dashpot_matrix(&mesh, &x, c), &free);
            prop_assert_eq!(&assembled, &reference);
            assert_exactly_symmetric(&assembled);
            // Positive semidefinite: the eigenvalues of the symmetric matrix are computed to a few ε
            // times its norm, so none may be below −1e-12 ‖C‖.
            let norm = assembled.amax() * assembled.nrows() as f64;
            let smallest = assembled.clone().symmetric_eigen().eigenvalues.min();
            prop_assert!(smallest >= -1e-12 * norm.max(f64::MIN_POSITIVE), "λ_min = {} (‖C‖ ≤ {})", smallest, norm);
        }

        #[test]
        fn dashpot_jacobian_adds_to_the_hessian_scaled(
            (mesh, x, pinned) in mesh_state_pins(),
            scale in 1e-3f64..1.0,
        ) {
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            let (pattern, mut values) = assemble(&mesh, &x, Some(&free), mesh.masses(), 0.05, Definiteness::Exact);
            let before = dense(pattern.matrix(&values));
            let c = 2.5;
            pattern.add_dashpot_into(mesh.springs(), &x, c, scale, &mut values);
            let after = dense(pattern.matrix(&values));
            assert_exactly_symmetric(&after);
            let damping = free_part(&dense_dashpot_matrix(&mesh, &x, c), &free) * scale;
            // The same terms summed in another association: a few ε of the largest term per entry.
            let bound = 1e-14 * (before.amax() + damping.amax());
            let error = (&after - &before - &damping).amax();
            prop_assert!(error <= bound, "off by {} (bound {})", error, bound);
        }
    }

    #[test]
    fn dashpot_jacobian_matches_finite_differences_of_the_dashpot_force() {
        // −∂/∂v of the summed dashpot force (through `SpringForces`, the simulation's force path) on
        // the free DOFs, pinned velocities held, on a cloth with two pins and a tetrahedral beam.
        for (mesh, pinned) in [
            (cloth(6, 50.0).unwrap(), vec![0, 5]),
            (beam(1).unwrap(), vec![0, 1, 2, 3]),
        ] {
            let n = mesh.vertex_count();
            let x = wobble(mesh.positions(), 0.3 * min_rest_length(&mesh));
            let v: Vec<Vector3<f64>> = wobble(&vec![Vector3::zeros(); n], 1.0);
            let free = FreeDofs::new(n, &pinned).unwrap();
            let pattern = HessianPattern::<3>::new(n, mesh.springs(), Some(&free));
            let c = 0.7;
            let mut values = pattern.new_values();
            pattern.add_dashpot_into(mesh.springs(), &x, c, 1.0, &mut values);
            let assembled = dense(pattern.matrix(&values));
            let mut flat = Vec::new();
            for &w in free.free_vertices() {
                flat.extend_from_slice(v[w as usize].as_slice());
            }
            let forces = SpringForces::new(n, mesh.springs());
            let jac = fd::jacobian(
                |u, out| {
                    let mut full = v.clone();
                    let moved: Vec<_> = u.chunks_exact(3).map(Vector3::from_column_slice).collect();
                    free.expand_vector(&moved, &mut full);
                    let mut f = vec![Vector3::zeros(); n];
                    let dashpot = Some(crate::Dashpot {
                        coefficient: c,
                        velocities: &full,
                    });
                    forces
                        .clone()
                        .compute(mesh.springs(), &x, dashpot, &mut f, false);
                    let mut reduced = vec![Vector3::zeros(); free.free_count()];
                    free.reduce_vector(&f, &mut reduced);
                    for (o, r) in out.chunks_exact_mut(3).zip(&reduced) {
                        o.copy_from_slice(r.as_slice());
                    }
                },
                &flat,
                flat.len(),
                1e-3,
            );
            // The force is linear in v: central differences are exact but for round-off, about
            // ε · |f| / step with |f| ≲ (spring force + c · |v| · degree) ~ 1e2: ~1e-11. The
            // tolerance, 1e-8 of the largest entry c, is far above that and far below any real error.
            let error = (&assembled + &jac).amax();
            assert!(
                error <= 1e-8 * assembled.amax(),
                "C differs from −∂f/∂v by {error} (largest entry {})",
                assembled.amax()
            );
        }
    }

    #[test]
    fn dashpot_and_diagonal_are_the_same_bits_on_one_and_two_threads() {
        // cloth-100 (58,806 springs) is above the parallel threshold.
        let mesh = cloth(100, 1e3).unwrap();
        let x = wobble(mesh.positions(), 0.002);
        let free = FreeDofs::new(mesh.vertex_count(), &[0, 99]).unwrap();
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut values = pattern.new_values();
                pattern.assemble_into(
                    mesh.springs(),
                    &x,
                    mesh.masses(),
                    0.01,
                    HessianParams::default(),
                    &mut pattern.workspace(),
                    &mut values,
                );
                pattern.add_dashpot_into(mesh.springs(), &x, 0.3, 0.01, &mut values);
                pattern.add_vertex_diagonal(mesh.masses(), &mut values);
                values
            })
        };
        let (one, two) = (run(1), run(2));
        assert!(one
            .iter()
            .zip(&two)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn vertex_diagonal_adds_to_free_diagonal_blocks_only() {
        let mesh = beam(1).unwrap();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, &[1, 4]).unwrap();
        let pattern = HessianPattern::<3>::new(n, mesh.springs(), Some(&free));
        let per_vertex: Vec<f64> = (0..n).map(|v| 1.0 + v as f64).collect();
        let mut values = pattern.new_values();
        pattern.add_vertex_diagonal(&per_vertex, &mut values);
        let got = dense(pattern.matrix(&values));
        let want = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            3 * free.free_count(),
            free.free_vertices()
                .iter()
                .flat_map(|&v| [per_vertex[v as usize]; 3]),
        ));
        assert_eq!(got, want);
        // Added, not written: a second call doubles the diagonal.
        pattern.add_vertex_diagonal(&per_vertex, &mut values);
        assert_eq!(dense(pattern.matrix(&values)), want * 2.0);
    }

    /// −h² (along · ûûᵀ + across · I), packed upper triangle.
    #[inline(always)]
    fn expand<const D: usize>(t: &HessianTerms<D>, h2: f64) -> [f64; PACKED] {
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

    /// −h² H_s of one spring, packed: the definition, one spring at a time.
    fn spring_block<const D: usize>(
        s: &Spring,
        positions: &[SVector<f64, D>],
        definiteness: Definiteness,
        h2: f64,
    ) -> [f64; PACKED] {
        let (i, j) = s.ends();
        let r = positions[i] - positions[j];
        expand(
            &HessianTerms::new(s.stiffness, s.rest_length, &r, definiteness),
            h2,
        )
    }

    /// The refill written the plain way, each column computing the blocks of all its springs
    /// afresh: the definition the scheduled refill must reproduce bit for bit.
    fn reference_values<const D: usize>(
        pattern: &HessianPattern<D>,
        springs: &[Spring],
        positions: &[SVector<f64, D>],
        masses: &[f64],
        h: f64,
        definiteness: Definiteness,
    ) -> Vec<f64> {
        let graph = &pattern.graph;
        let mut values = pattern.new_values();
        let fill = |column: usize, out: &mut [f64]| {
            let column_len = D * graph.column_blocks(column).len();
            let mut sum = [0.0; PACKED];
            for c in graph.contributions(column) {
                let packed =
                    spring_block(&springs[c.spring as usize], positions, definiteness, h * h);
                for (acc, v) in sum.iter_mut().zip(&packed).take(PACKED_LEN[D]) {
                    *acc += v;
                }
                if c.slot != Contribution::PINNED_OTHER {
                    for b in 0..D {
                        for a in 0..D {
                            let d = &mut out[b * column_len + D * c.slot as usize + a];
                            let v = packed[packed_index::<D>(a, b)];
                            *d = if c.first { v } else { *d + v };
                        }
                    }
                }
            }
            let at = D * graph.diagonal_slot(column);
            let vertex = graph.free().free_vertices()[column] as usize;
            for b in 0..D {
                for a in 0..D {
                    out[b * column_len + at + a] = -sum[packed_index::<D>(a, b)];
                }
                out[b * column_len + at + b] += masses[vertex];
            }
        };
        graph.for_each_column::<D, _>(&mut values, false, &fill);
        values
    }

    #[test]
    fn scheduled_refill_equals_the_plain_refill_bit_for_bit() {
        // cloth-100 with pins (16 leaves: blocks kept within a leaf, recomputed across leaves and
        // at pinned ends), a beam, duplicate springs, and the 2D seed scene.
        let check = |name: &str, values: &[f64], reference: &[f64]| {
            assert!(
                values
                    .iter()
                    .zip(reference)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}: the refill differs from the plain definition"
            );
        };
        for (mesh, pinned) in [
            (cloth(100, 1e3).unwrap(), vec![0, 99, 5000]),
            (beam(2).unwrap(), vec![3]),
            (cloth(5, 1.0).unwrap(), vec![]),
        ] {
            let x = wobble(mesh.positions(), 0.002);
            let free = FreeDofs::new(mesh.vertex_count(), &pinned).unwrap();
            let mut springs = mesh.springs().to_vec();
            springs.extend_from_slice(&mesh.springs()[..3]); // parallel springs
            let pattern = HessianPattern::<3>::new(mesh.vertex_count(), &springs, Some(&free));
            let mut workspace = pattern.workspace();
            for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
                for parallel in [false, true] {
                    let mut values = vec![f64::NAN; pattern.nnz()];
                    let params = HessianParams {
                        definiteness,
                        parallel,
                    };
                    pattern.assemble_into(
                        &springs,
                        &x,
                        mesh.masses(),
                        0.01,
                        params,
                        &mut workspace,
                        &mut values,
                    );
                    let reference =
                        reference_values(&pattern, &springs, &x, mesh.masses(), 0.01, definiteness);
                    check(
                        &format!(
                            "{} vertices, {definiteness:?}, parallel {parallel}",
                            mesh.vertex_count()
                        ),
                        &values,
                        &reference,
                    );
                }
            }
        }
        let mesh = hooke_mesh::generators::seed_2d().unwrap();
        let free = FreeDofs::new(mesh.vertex_count(), &[0]).unwrap();
        let pattern = HessianPattern::<2>::new(mesh.vertex_count(), mesh.springs(), Some(&free));
        let mut values = pattern.new_values();
        let params = HessianParams::default();
        pattern.assemble_into(
            mesh.springs(),
            mesh.positions(),
            mesh.masses(),
            0.01,
            params,
            &mut pattern.workspace(),
            &mut values,
        );
        let reference = reference_values(
            &pattern,
            mesh.springs(),
            mesh.positions(),
            mesh.masses(),
            0.01,
            Definiteness::Exact,
        );
        check("seed-2d", &values, &reference);
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
        let assembled = |masses: &[f64], h: f64| {
            let mut values = pattern.new_values();
            pattern.assemble_into(
                mesh.springs(),
                &x,
                masses,
                h,
                HessianParams::default(),
                &mut pattern.workspace(),
                &mut values,
            );
            dense(pattern.matrix(&values))
        };
        // The spring part alone (zero masses, h = 1), as in 3D: with the masses in, M would
        // dominate the scale of the comparison.
        let springs = assembled(&vec![0.0; n], 1.0);
        assert_exactly_symmetric(&springs);
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
        // As in 3D: ~1e-10 of the largest entry per finite difference, 1e-6 leaves room.
        let scale = springs.amax();
        let error = (&springs + &jac).amax();
        assert!(
            error <= 1e-6 * scale,
            "2D ∇²E off by {error} (largest entry {scale})"
        );
        // With the masses and h = 0.01: M + h² times that spring part, to round-off (as in 3D).
        let h = 0.01;
        let a = assembled(mesh.masses(), h);
        assert_exactly_symmetric(&a);
        let mut expected = &springs * (h * h);
        for (f, &v) in free.free_vertices().iter().enumerate() {
            for c in 0..2 {
                expected[(2 * f + c, 2 * f + c)] += mesh.masses()[v as usize];
            }
        }
        let largest_mass = mesh.masses().iter().cloned().fold(0.0, f64::max);
        let round_off = 64.0 * f64::EPSILON * (largest_mass + h * h * scale);
        let error = (&a - &expected).amax();
        assert!(
            error <= round_off,
            "2D M + h²∇²E off by {error} (round-off {round_off})"
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
    fn scheduled_refill_equals_the_plain_refill_on_degenerate_springs() {
        // Springs where `HessianTerms` takes its stand-in or is at the edge of it, mixed in batches
        // with ordinary springs: the batched fast-path test must send each such batch to the
        // one-by-one path (or compute the same bits), in both variants.
        let mesh = cloth(6, 100.0).unwrap();
        let l = mesh.springs()[0].rest_length;
        let mut x = mesh.positions().to_vec();
        x[1] = x[0]; // zero length (1/|r| infinite; clamped: along and across finite)
        x[8] = x[7] + Vector3::new(1e-300, 0.0, 0.0); // |r|² underflows to 0
        x[9] = x[10] + Vector3::new(3e-160, 0.0, 0.0); // |r|² subnormal but positive
        x[20] += Vector3::new(1e200, 0.0, 0.0); // |r|² overflows
        x[27] += Vector3::new(1e3 * l, -2e3 * l, 0.0); // very long
        let mut springs = mesh.springs().to_vec();
        springs[5].stiffness = 1e308; // along or across overflows
        springs[6].rest_length = 0.0;
        springs[7].stiffness = f64::INFINITY;
        springs[11].rest_length = 1e300;
        let pattern = HessianPattern::<3>::new(mesh.vertex_count(), &springs, None);
        let mut workspace = pattern.workspace();
        for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
            let mut values = vec![f64::NAN; pattern.nnz()];
            let params = HessianParams {
                definiteness,
                parallel: false,
            };
            pattern.assemble_into(
                &springs,
                &x,
                mesh.masses(),
                0.01,
                params,
                &mut workspace,
                &mut values,
            );
            let reference =
                reference_values(&pattern, &springs, &x, mesh.masses(), 0.01, definiteness);
            assert!(
                values
                    .iter()
                    .zip(&reference)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{definiteness:?}: the refill differs from the plain definition"
            );
        }
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
