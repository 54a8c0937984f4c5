//! Smoothed-aggregation algebraic multigrid (docs/solvers.md §2.4) for symmetric positive definite
//! systems of B × B vertex blocks (B = 3: Newton's clamped Hessian; B = 1: projective dynamics'
//! M + h²L), used as a preconditioner of [`crate::ConjugateGradient`]: one V-cycle per application.
//!
//! Set-up, per level: the vertex graph of the matrix (every stored off-diagonal block is a strong
//! connection with the default threshold 0, so the aggregates depend on the pattern alone), greedy
//! standard aggregation, a tentative prolongator T from the near-nullspace (for 3D, the 6
//! rigid-body modes of [`Amg::rigid_body_modes`]) orthonormalised per aggregate by Gram–Schmidt
//! with a rank test, the smoothed prolongator P = (I − ω D⁻¹A) T with ω = (4/3)/ρ(D⁻¹A) (D the
//! block diagonal, ρ estimated by a fixed number of power iterations), and the Galerkin coarse
//! matrix Pᵀ A P, symmetrised. The patterns of P, Pᵀ, A P and Pᵀ A P are computed once;
//! [`Amg::refresh`] refills their values from new values of A on the same pattern (no symbolic
//! work), giving the same bits as a fresh set-up with the same near-nullspace. The coarsest level
//! is factored by [`crate::SparseCholesky`]. Memory: 32-bit column indices, and A T (as large as
//! P) never stored whole (docs/solvers.md §2.4).
//!
//! The V-cycle smooths with symmetric block Gauss–Seidel by default (a forward then a backward
//! sweep, before and after the coarse correction; [`AmgSmoother`]), the sweeps after being the
//! adjoints of those before, so the preconditioner is symmetric positive definite, as CG needs.
//! A level of at least [`AMG_PARTS_MIN_ROWS`] rows is swept in [`AmgParams::smoother_parts`]
//! contiguous parts in parallel (hybrid Gauss–Seidel: the other parts' values from the sweep's
//! start); the residual products and the refill's sparse products run row-parallel on rayon, each
//! row summed in a fixed order. The parts depend on the matrix and the setting only, so the result
//! has the same bits whatever the thread count. Every buffer of the cycle is allocated at set-up.

use std::ops::{AddAssign, Mul, SubAssign};

use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::MatMut;
use nalgebra::SVector;
use rayon::prelude::*;

use crate::cholesky::{CholeskyError, CholeskyParams, FactorKind, SparseCholesky};
use crate::operator::{LinearOperator, Preconditioner};
use crate::params::{self, ParamError};

/// What one unknown carries through a V-cycle: one value (`f64`, [`Amg`] as a [`Preconditioner`])
/// or the D values of D right-hand sides at once (`SVector<f64, D>`, [`Amg::apply_columns`]: the
/// columns of (A ⊗ I_D), as projective dynamics' D coordinates, so that each level's matrix is
/// read once for all of them). Every operation is per column, so a column's values are those of
/// the one-value cycle on that column.
trait Lane: Copy + Send + Sync + AddAssign + SubAssign + Mul<f64, Output = Self> {
    /// The zero value.
    fn zero() -> Self;

    /// Solve the coarsest level in place with its factor; `scratch` is the column-major buffer
    /// of a multi-column solve.
    fn solve_coarse(factor: &mut SparseCholesky, x: &mut [Self], scratch: &mut Vec<f64>);
}

impl Lane for f64 {
    fn zero() -> Self {
        0.0
    }

    fn solve_coarse(factor: &mut SparseCholesky, x: &mut [f64], _: &mut Vec<f64>) {
        factor.solve_slice(x);
    }
}

impl<const D: usize> Lane for SVector<f64, D> {
    fn zero() -> Self {
        SVector::zeros()
    }

    fn solve_coarse(factor: &mut SparseCholesky, x: &mut [Self], scratch: &mut Vec<f64>) {
        let n = x.len();
        scratch.resize(n * D, 0.0);
        for (i, v) in x.iter().enumerate() {
            for a in 0..D {
                scratch[a * n + i] = v[a];
            }
        }
        factor.solve_in_place(MatMut::from_column_major_slice_mut(scratch, n, D));
        for (i, v) in x.iter_mut().enumerate() {
            for a in 0..D {
                v[a] = scratch[a * n + i];
            }
        }
    }
}

/// The vectors of a V-cycle on one level: right-hand side, solution, residual.
#[derive(Clone, Debug)]
struct Cycle<T> {
    b: Vec<T>,
    x: Vec<T>,
    r: Vec<T>,
}

impl<T: Lane> Cycle<T> {
    fn new(n: usize) -> Self {
        Cycle {
            b: vec![T::zero(); n],
            x: vec![T::zero(); n],
            r: vec![T::zero(); n],
        }
    }
}

/// The buffers of [`Amg::apply_columns`] for D right-hand sides, made by
/// [`Amg::columns_workspace`] for one hierarchy (every allocation of the column cycle is here).
#[derive(Clone, Debug)]
pub struct AmgColumns<const D: usize> {
    cycle: Vec<Cycle<SVector<f64, D>>>,
    /// Column-major right-hand sides of the coarsest solve.
    coarse: Vec<f64>,
}

/// The fewest rows of a level whose sweeps are split into [`AmgParams::smoother_parts`] parts:
/// below it a fork costs more than the part of the sweep it moves.
pub const AMG_PARTS_MIN_ROWS: usize = 8192;

/// The largest vertex block (fine block size, or near-nullspace vectors, which become the coarse
/// blocks): the diagonal blocks are inverted in fixed-size stack arrays.
pub const AMG_MAX_BLOCK: usize = 8;

/// The V-cycle's smoother. Both make the cycle a symmetric operator: the sweeps after the coarse
/// correction are the adjoints of those before, in reverse order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AmgSmoother {
    /// Block Gauss–Seidel: forward sweeps before the coarse correction, backward sweeps after
    /// (half the smoothing work of the symmetric sweeps per cycle, more CG iterations: 12 against 9
    /// on cloth-80's Hessian, 13 against 10 on cloth-160's; benches/results/amg.md).
    GaussSeidel,
    /// Symmetric block Gauss–Seidel: a forward and a backward sweep per sweep, before and after.
    #[default]
    SymmetricGaussSeidel,
}

/// Settings of [`Amg`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmgParams {
    /// Strength of connection: blocks i ≠ j are connected when ‖A_ij‖_F ≥ θ √(‖A_ii‖_F ‖A_jj‖_F).
    /// Default 0: every stored block (the aggregates then depend on the pattern only, which is
    /// what makes [`Amg::refresh`] equal to a fresh set-up).
    pub strength_threshold: f64,
    /// Stop coarsening at or below this many unknowns; the coarsest level is factored. Default 1000.
    pub max_coarse: usize,
    /// The most levels, the finest included. Default 10.
    pub max_levels: usize,
    /// The smoother of every level but the coarsest.
    pub smoother: AmgSmoother,
    /// Smoother sweeps before and after the coarse correction (see [`AmgSmoother`]). Default 1.
    pub smoother_sweeps: usize,
    /// Split the rows of every level with at least [`AMG_PARTS_MIN_ROWS`] rows into this many
    /// contiguous parts of about equal stored entries, swept in parallel: Gauss–Seidel within a
    /// part, the other parts' values taken from the sweep's start (hybrid Gauss–Seidel; the
    /// forward and backward sweeps stay adjoint, so the cycle stays symmetric). The split depends
    /// on this number and the matrix only, so the bits do not depend on the thread count.
    /// Default 2, for two cores: on PD's matrix the same CG iterations as plain Gauss–Seidel
    /// and a 1.25–1.3× faster PD step on cloth-320 and cloth-640; the same iterations on a cloth
    /// Hessian; on Newton's multilevel path for filled solids the same Newton iterations and
    /// 1.1–1.2× faster runs (docs/solvers.md §2.4). 1: plain Gauss–Seidel, serial.
    pub smoother_parts: usize,
    /// ω ρ(D⁻¹A) of the prolongator smoothing. Default 4/3.
    pub prolongator_damping: f64,
    /// Power iterations for the spectral radius ρ(D⁻¹A). Default 15.
    pub spectral_radius_iterations: usize,
}

impl Default for AmgParams {
    fn default() -> Self {
        AmgParams {
            strength_threshold: 0.0,
            max_coarse: 1000,
            max_levels: 10,
            smoother: AmgSmoother::default(),
            smoother_sweeps: 1,
            smoother_parts: 2,
            prolongator_damping: 4.0 / 3.0,
            spectral_radius_iterations: 15,
        }
    }
}

impl AmgParams {
    /// Check the fields: threshold finite in [0, 1], `max_coarse` ≥ 1, `max_levels` in 1..=64,
    /// sweeps in 1..=100, damping in (0, 2), power iterations in 1..=1000.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::real(
            "AmgParams::strength_threshold",
            self.strength_threshold,
            (0.0..=1.0).contains(&self.strength_threshold),
            "in [0, 1]",
        )?;
        params::at_least("AmgParams::max_coarse", self.max_coarse, 1, "at least 1")?;
        params::count_in("AmgParams::max_levels", self.max_levels, 1, 64, "in 1..=64")?;
        params::count_in(
            "AmgParams::smoother_sweeps",
            self.smoother_sweeps,
            1,
            100,
            "in 1..=100",
        )?;
        params::count_in(
            "AmgParams::smoother_parts",
            self.smoother_parts,
            1,
            64,
            "in 1..=64",
        )?;
        params::real(
            "AmgParams::prolongator_damping",
            self.prolongator_damping,
            self.prolongator_damping > 0.0 && self.prolongator_damping < 2.0,
            "in (0, 2)",
        )?;
        params::count_in(
            "AmgParams::spectral_radius_iterations",
            self.spectral_radius_iterations,
            1,
            1000,
            "in 1..=1000",
        )
    }
}

/// Why [`Amg`] could not be set up or refreshed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AmgError {
    /// The matrix is not square.
    #[error("the matrix is {rows}×{cols}, not square")]
    NotSquare {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
    },
    /// The block size is 0, above [`AMG_MAX_BLOCK`], or does not divide the dimension.
    #[error("block size {block} does not fit a {dim}×{dim} matrix (it must divide it and be in 1..={AMG_MAX_BLOCK})")]
    BlockSize {
        /// The dimension.
        dim: usize,
        /// The block size.
        block: usize,
    },
    /// The near-nullspace is not a whole number of columns of the matrix' dimension, has none, or
    /// more than [`AMG_MAX_BLOCK`].
    #[error("the near-nullspace has {len} values, not 1 to {AMG_MAX_BLOCK} columns of {dim}")]
    NearNullspace {
        /// Values given.
        len: usize,
        /// The dimension.
        dim: usize,
    },
    /// The dimension is above `u32::MAX`, the largest the hierarchy's 32-bit indices hold.
    #[error(
        "the matrix is {dim}×{dim}, above the largest dimension the hierarchy indexes (u32::MAX)"
    )]
    TooLarge {
        /// The dimension.
        dim: usize,
    },
    /// A column's row indices are not strictly increasing.
    #[error("the row indices of column {column} are not sorted and unique")]
    UnsortedPattern {
        /// The column.
        column: usize,
    },
    /// The matrix (or the near-nullspace) holds NaN or infinite values.
    #[error("the matrix or the near-nullspace holds non-finite values")]
    NonFinite,
    /// [`Amg::refresh`] got a matrix of another pattern.
    #[error("the matrix does not have the pattern the hierarchy was built for")]
    PatternMismatch,
    /// A diagonal block is not positive definite (the matrix is not SPD).
    #[error("diagonal block {block} of level {level} is not positive definite")]
    NotPositiveDefinite {
        /// The level (0: the given matrix).
        level: usize,
        /// The block (vertex or aggregate).
        block: usize,
    },
    /// The coarsest level's factorisation failed.
    #[error("coarsest level: {0}")]
    Coarse(#[from] CholeskyError),
    /// A parameter is out of its range ([`AmgParams::validate`]).
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
}

/// A sparse matrix in compressed rows with sorted columns (symmetric matrices: the same arrays as
/// compressed columns). Column indices are 32-bit, half the index memory of the largest
/// hierarchies ([`Amg::new`] refuses a dimension above `u32::MAX`).
#[derive(Clone, Debug, Default)]
struct Csr {
    n_rows: usize,
    n_cols: usize,
    ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

impl Csr {
    fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.ptr[i]..self.ptr[i + 1]
    }

    /// The K rows from row `lo`, all with row `lo`'s columns, side by side over the first `width`
    /// of them: v_r − Σ_c a_rc x_c (`SUBTRACT`) or v_r + Σ_c a_rc x_c, x_c from `read`. Each x_c
    /// and column index is read once for the K sums, and each sum adds its terms in the order of
    /// the row walk, as one row at a time does: the same bits, K independent chains of additions
    /// instead of one.
    #[inline(always)]
    fn rows_side_by_side<const K: usize, const SUBTRACT: bool, T: Lane>(
        &self,
        lo: usize,
        width: usize,
        read: impl Fn(usize) -> T,
        mut v: [T; K],
    ) -> [T; K] {
        let first = self.ptr[lo];
        let row_len = self.ptr[lo + 1] - first;
        let cols = &self.col[first..first + width];
        let rows: [&[f64]; K] = std::array::from_fn(|r| {
            let start = first + r * row_len;
            debug_assert_eq!(self.ptr[lo + r], start, "rows of one pattern");
            &self.val[start..start + width]
        });
        for (t, &c) in cols.iter().enumerate() {
            let xc = read(c as usize);
            for r in 0..K {
                if SUBTRACT {
                    v[r] -= xc * rows[r][t];
                } else {
                    v[r] += xc * rows[r][t];
                }
            }
        }
        v
    }

    /// [`Csr::rows_side_by_side`] for the `out.len()` rows from row `lo` (of one pattern) into
    /// `out`, from `init(r)` for row `lo + r`: `true` for a block of 3 or 6 rows, `false` (nothing
    /// written) for another size.
    #[inline(always)]
    fn block_side_by_side<const SUBTRACT: bool, T: Lane>(
        &self,
        lo: usize,
        width: usize,
        read: impl Fn(usize) -> T,
        init: impl Fn(usize) -> T,
        out: &mut [T],
    ) -> bool {
        match out.len() {
            3 => out.copy_from_slice(&self.rows_side_by_side::<3, SUBTRACT, T>(
                lo,
                width,
                read,
                std::array::from_fn(init),
            )),
            6 => out.copy_from_slice(&self.rows_side_by_side::<6, SUBTRACT, T>(
                lo,
                width,
                read,
                std::array::from_fn(init),
            )),
            _ => return false,
        }
        true
    }

    /// `out = b − A x` (`SUBTRACT`) or `out = A x` (`b` unused) over the row blocks `blocks`
    /// (bounds), blocks of 3 or 6 rows side by side when `uniform` (every block's rows have one
    /// pattern); halves of many blocks in parallel. Each row a serial sum in
    /// the row's order: the same bits whatever the pool.
    fn apply_blocks<const SUBTRACT: bool, T: Lane>(
        &self,
        blocks: &[usize],
        uniform: bool,
        b: &[T],
        x: &[T],
        out: &mut [T],
    ) {
        const SERIAL_BLOCKS: usize = 1024;
        let count = blocks.len() - 1;
        if count > SERIAL_BLOCKS && out.len() >= 4096 {
            let mid = count / 2;
            let (low, high) = out.split_at_mut(blocks[mid] - blocks[0]);
            rayon::join(
                || self.apply_blocks::<SUBTRACT, T>(&blocks[..=mid], uniform, b, x, low),
                || self.apply_blocks::<SUBTRACT, T>(&blocks[mid..], uniform, b, x, high),
            );
            return;
        }
        let base = blocks[0];
        let init = |i: usize| if SUBTRACT { b[i] } else { T::zero() };
        let read = |c: usize| x[c];
        for w in blocks.windows(2) {
            let (lo, hi) = (w[0], w[1]);
            let width = self.ptr[lo + 1] - self.ptr[lo];
            let out = &mut out[lo - base..hi - base];
            if uniform
                && self.block_side_by_side::<SUBTRACT, T>(lo, width, read, |r| init(lo + r), out)
            {
                continue;
            }
            for (i, o) in (lo..hi).zip(out.iter_mut()) {
                let mut v = init(i);
                for e in self.row(i) {
                    if SUBTRACT {
                        v -= x[self.col[e] as usize] * self.val[e];
                    } else {
                        v += x[self.col[e] as usize] * self.val[e];
                    }
                }
                *o = v;
            }
        }
    }
}

/// The symbolic set-up of the next coarser level below `level` (near-nullspace `nullspace`,
/// column-major, `k` columns): its transfer operators' patterns, the coarse level (its matrix'
/// pattern) and the coarse near-nullspace; `None` when aggregation does not coarsen.
fn coarsen(
    level: &Level,
    nullspace: &[f64],
    k: usize,
    strength_threshold: f64,
) -> Option<(Transfer, Level, Vec<f64>)> {
    let size = level.a.n_rows;
    let aggregates = aggregate(&level.a, &level.block_ptr, strength_threshold);
    let (t, coarse_ptr, coarse_nullspace) = tentative(&aggregates, &level.block_ptr, nullspace, k);
    let coarse_size = *coarse_ptr.last().expect("non-empty");
    if coarse_size >= size || coarse_size == 0 {
        return None;
    }
    let p = smoothed_pattern(&level.a, &t, &level.block_ptr);
    let r = transpose_pattern(&p);
    let ap = product_pattern(&level.a, &p);
    let coarse_a = product_pattern(&r, &ap);
    let p_uniform = uniform_rows(&p, &level.block_ptr);
    let r_uniform = uniform_rows(&r, &coarse_ptr);
    let transfer = Transfer {
        t,
        p,
        r,
        p_uniform,
        r_uniform,
        ap,
        next: vec![0; coarse_size],
        // Allocated by the first fill that needs them (the finest level's come from its ρ
        // computed beside this set-up).
        power: [Vec::new(), Vec::new()],
    };
    Some((transfer, Level::new(coarse_a, coarse_ptr), coarse_nullspace))
}

/// Whether the rows of each block (bounds `block_ptr`) of `a` have one pattern.
fn uniform_rows(a: &Csr, block_ptr: &[usize]) -> bool {
    block_ptr.windows(2).all(|w| {
        let first = &a.col[a.row(w[0])];
        (w[0] + 1..w[1]).all(|i| &a.col[a.row(i)] == first)
    })
}

/// The pattern of C = A B (sorted rows). A row of A with the same pattern as the row before it
/// (the rows of one vertex block, the coarse unknowns of one aggregate) has the same row in C,
/// which is copied instead of formed again; and a column of A whose row of B has the pattern of
/// the row before it, met right after that row's column, adds nothing new and is passed over.
fn product_pattern(a: &Csr, b: &Csr) -> Csr {
    let same_as_previous: Vec<bool> = (0..b.n_rows)
        .map(|i| i > 0 && b.col[b.row(i)] == b.col[b.row(i - 1)])
        .collect();
    let mut mark = vec![usize::MAX; b.n_cols];
    let mut ptr = Vec::with_capacity(a.n_rows + 1);
    ptr.push(0);
    let mut col = Vec::new();
    for i in 0..a.n_rows {
        let start = col.len();
        if i > 0 && a.col[a.row(i)] == a.col[a.row(i - 1)] {
            col.extend_from_within(ptr[i - 1]..start);
            ptr.push(col.len());
            continue;
        }
        let mut previous = usize::MAX;
        for e in a.row(i) {
            let c = a.col[e] as usize;
            let repeat = same_as_previous[c] && previous == c - 1;
            previous = c;
            if repeat {
                continue;
            }
            for f in b.row(c) {
                let j = b.col[f];
                if mark[j as usize] != i {
                    mark[j as usize] = i;
                    col.push(j);
                }
            }
        }
        col[start..].sort_unstable();
        ptr.push(col.len());
    }
    let nnz = col.len();
    Csr {
        n_rows: a.n_rows,
        n_cols: b.n_cols,
        ptr,
        col,
        val: vec![0.0; nnz],
    }
}

/// The values of C = A B into C's pattern (from [`product_pattern`]). A's rows are taken by the
/// blocks `blocks` (row bounds): a block whose rows have one pattern (`uniform`) is multiplied
/// side by side, each row of B read once for the block's k rows, accumulated in a scratch vector
/// interleaved by row (column j of row r at j k + r); each entry of C is still summed in the order
/// of its row's walk, so the bits are those of one row at a time. The blocks are split into one
/// contiguous chunk per scratch vector of `dense` (each zeroed, of at least C's column count
/// times the largest block, and zeroed again on return), the chunks in parallel: the bits do not
/// depend on the split.
fn product_values(
    a: &Csr,
    blocks: &[usize],
    uniform: bool,
    b: &Csr,
    c: &mut Csr,
    dense: &mut [Vec<f64>],
) {
    let Csr { ptr, col, val, .. } = c;
    let (ptr, col) = (&*ptr, &*col);
    for_each_chunk(
        blocks.len() - 1,
        |u| ptr[blocks[u]],
        val,
        dense,
        |first, last, values, dense| {
            let base = ptr[blocks[first]];
            for w in blocks[first..=last].windows(2) {
                let (lo, hi) = (w[0], w[1]);
                // The block's rows side by side, or (rows of several patterns) one at a time.
                let k = if uniform { hi - lo } else { 1 };
                let mut row = lo;
                while row < hi {
                    let a_first = a.ptr[row];
                    let width = a.ptr[row + 1] - a_first;
                    let mut av = [0.0; AMG_MAX_BLOCK];
                    for t in 0..width {
                        for (r, v) in av[..k].iter_mut().enumerate() {
                            *v = a.val[a.ptr[row + r] + t];
                        }
                        for f in b.row(a.col[a_first + t] as usize) {
                            let (j, bv) = (b.col[f] as usize, b.val[f]);
                            let slot = &mut dense[j * k..j * k + k];
                            for (d, v) in slot.iter_mut().zip(&av[..k]) {
                                *d += v * bv;
                            }
                        }
                    }
                    let cols = &col[ptr[row]..ptr[row + 1]];
                    for r in 0..k {
                        // Rows of A of one pattern have one pattern in C (product_pattern).
                        debug_assert_eq!(ptr[row + r + 1] - ptr[row + r], cols.len());
                        let out = &mut values[ptr[row + r] - base..ptr[row + r + 1] - base];
                        for (o, &j) in out.iter_mut().zip(cols) {
                            let d = &mut dense[j as usize * k + r];
                            *o = *d;
                            *d = 0.0;
                        }
                    }
                    row += k;
                }
            }
        },
    );
}

/// Run `work(first, last, values, scratch)` over `units` units (rows or blocks) split into one
/// contiguous chunk per scratch vector of `dense`, the chunks in parallel: each chunk gets its
/// units' values, `values[offset(first)..offset(last)]` (`offset(u)`: the index of unit u's first
/// value, non-decreasing, `offset(units)` = the end), and a scratch vector of its own.
fn for_each_chunk(
    units: usize,
    offset: impl Fn(usize) -> usize,
    values: &mut [f64],
    dense: &mut [Vec<f64>],
    work: impl Fn(usize, usize, &mut [f64], &mut Vec<f64>) + Sync,
) {
    let chunks = dense.len().clamp(1, units.max(1));
    let chunk_units = units.div_ceil(chunks).max(1);
    let mut pieces: Vec<(usize, usize, &mut [f64])> = Vec::new();
    let mut rest = values;
    let mut consumed = offset(0);
    let mut first = 0;
    while first < units {
        let last = (first + chunk_units).min(units);
        let end = offset(last);
        let (piece, tail) = std::mem::take(&mut rest).split_at_mut(end - consumed);
        consumed = end;
        pieces.push((first, last, piece));
        rest = tail;
        first = last;
    }
    let run = |((first, last, values), scratch): ((usize, usize, &mut [f64]), &mut Vec<f64>)| {
        work(first, last, values, scratch)
    };
    if pieces.len() > 1 {
        pieces
            .into_par_iter()
            .zip(dense.par_iter_mut())
            .for_each(run);
    } else {
        pieces.into_iter().zip(dense.iter_mut()).for_each(run);
    }
}

/// The pattern of Aᵀ. Its entries are laid out in the order of a walk over A's rows, each
/// entry (i, j) of A to the next free place of row j of Aᵀ: [`Amg::fill`] moves values by the
/// same walk.
fn transpose_pattern(a: &Csr) -> Csr {
    let mut count = vec![0usize; a.n_cols + 1];
    for &j in &a.col {
        count[j as usize + 1] += 1;
    }
    for j in 0..a.n_cols {
        count[j + 1] += count[j];
    }
    let ptr = count.clone();
    let mut next = count;
    let mut col = vec![0; a.col.len()];
    for i in 0..a.n_rows {
        for e in a.row(i) {
            let j = a.col[e] as usize;
            col[next[j]] = i as u32;
            next[j] += 1;
        }
    }
    let nnz = col.len();
    Csr {
        n_rows: a.n_cols,
        n_cols: a.n_rows,
        ptr,
        col,
        val: vec![0.0; nnz],
    }
}

/// Invert the symmetric positive definite k × k block `m` (row-major, k ≤ [`AMG_MAX_BLOCK`]) in
/// place by Gauss–Jordan without pivoting (valid for SPD blocks). `false` if a pivot is not
/// positive and finite.
fn invert_spd_block(m: &mut [f64], k: usize) -> bool {
    let mut inv = [0.0; AMG_MAX_BLOCK * AMG_MAX_BLOCK];
    let mut a = [0.0; AMG_MAX_BLOCK * AMG_MAX_BLOCK];
    a[..k * k].copy_from_slice(&m[..k * k]);
    for i in 0..k {
        inv[i * k + i] = 1.0;
    }
    for p in 0..k {
        let pivot = a[p * k + p];
        if !(pivot > 0.0 && pivot.is_finite()) {
            return false;
        }
        let scale = 1.0 / pivot;
        for c in 0..k {
            a[p * k + c] *= scale;
            inv[p * k + c] *= scale;
        }
        for r in 0..k {
            if r != p {
                let f = a[r * k + p];
                if f != 0.0 {
                    for c in 0..k {
                        a[r * k + c] -= f * a[p * k + c];
                        inv[r * k + c] -= f * inv[p * k + c];
                    }
                }
            }
        }
    }
    // Symmetrise: the inverse of a symmetric block is symmetric; rounding may differ by an ulp.
    for r in 0..k {
        for c in 0..r {
            let v = 0.5 * (inv[r * k + c] + inv[c * k + r]);
            inv[r * k + c] = v;
            inv[c * k + r] = v;
        }
    }
    m[..k * k].copy_from_slice(&inv[..k * k]);
    m[..k * k].iter().all(|v| v.is_finite())
}

/// One level: its matrix, its vertex blocks (block b holds unknowns `block_ptr[b]..block_ptr[b+1]`),
/// the inverted diagonal blocks, and (above the coarsest) the prolongator to it from the next
/// coarser level with the products that refill the next level's matrix.
#[derive(Clone, Debug)]
struct Level {
    a: Csr,
    block_ptr: Vec<usize>,
    /// Per block, the offset of its inverted diagonal block (row-major k × k) in `diag_inv`.
    diag_offset: Vec<usize>,
    diag_inv: Vec<f64>,
    /// Per block, the indices in `a.val` of its diagonal block's entries (row-major k × k;
    /// usize::MAX where not stored).
    diag_entries: Vec<usize>,
    /// Whether the rows of every block have the same columns (a vertex block matrix stored in
    /// full, as Newton's Hessian and every Galerkin level of it): the smoother then walks a
    /// block's rows side by side.
    uniform_rows: bool,
    transfer: Option<Transfer>,
    /// The blocks' split into the smoother's parts: part p holds blocks
    /// `parts[p]..parts[p + 1]` (one part: the plain sweep).
    parts: Vec<usize>,
}

/// One Gauss–Seidel sweep's order over the blocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sweep {
    Forward,
    Backward,
    /// Forward from x = 0 (the pre-smoothing's first sweep): each block reads only the columns
    /// before its own, the others being still zero.
    ForwardFromZero,
}

/// The operators between a level and the next coarser one.
#[derive(Clone, Debug)]
struct Transfer {
    /// The tentative prolongator (fixed).
    t: Csr,
    /// P = T − ω D⁻¹ A T (A T is formed block by block in [`smooth_values`], never stored).
    p: Csr,
    /// R = Pᵀ.
    r: Csr,
    /// Whether P's rows have one pattern per fine block and R's per coarse block
    /// ([`uniform_rows`]).
    p_uniform: bool,
    r_uniform: bool,
    /// A P.
    ap: Csr,
    /// Per coarse unknown, the next entry of its row: scratch of the transpositions in
    /// [`Amg::fill`] (P's values into R, the coarse matrix' symmetrisation).
    next: Vec<usize>,
    /// Scratch for the spectral radius: two vectors of the level's size (empty until the first
    /// fill).
    power: [Vec<f64>; 2],
}

/// A smoothed-aggregation AMG hierarchy (see the module docs), a [`Preconditioner`] applying one
/// V-cycle.
#[derive(Debug)]
pub struct Amg {
    params: AmgParams,
    levels: Vec<Level>,
    /// The one-value cycle's vectors, per level.
    cycle: Vec<Cycle<f64>>,
    coarse: SparseCholesky,
    /// The coarsest matrix' pattern with faer's index type, for its factorisations.
    coarse_pattern: SymbolicSparseColMat<usize>,
    /// Scratch of the product numerics, one per rayon thread (grown when the pool is larger than
    /// at the last fill), each `largest × widest` long.
    dense: Vec<Vec<f64>>,
    /// The largest column count of the products (the largest coarse level) and the largest block:
    /// the scratch length is their product.
    largest: usize,
    widest: usize,
    /// The given matrix' stored entries (its pattern check in [`Amg::refresh`]).
    fine_nnz: usize,
}

impl Amg {
    /// The 6 rigid-body modes of 3D vertices at `positions` (m, x y z per vertex): 3 translations
    /// and 3 rotations about the centroid, as a 3n × 6 column-major array (the near-nullspace of
    /// [`Amg::new`] with block size 3). The rotations are in metres (position differences).
    pub fn rigid_body_modes(positions: &[f64]) -> Vec<f64> {
        let n = positions.len() / 3;
        let mut centroid = [0.0; 3];
        for p in positions.chunks_exact(3) {
            for a in 0..3 {
                centroid[a] += p[a];
            }
        }
        for c in &mut centroid {
            *c /= n.max(1) as f64;
        }
        let dim = 3 * n;
        let mut modes = vec![0.0; 6 * dim];
        for (v, p) in positions.chunks_exact(3).enumerate() {
            let (x, y, z) = (p[0] - centroid[0], p[1] - centroid[1], p[2] - centroid[2]);
            for a in 0..3 {
                modes[a * dim + 3 * v + a] = 1.0;
            }
            // Rotations about x, y, z: ω × r.
            let rot = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]];
            for (c, r) in rot.iter().enumerate() {
                for a in 0..3 {
                    modes[(3 + c) * dim + 3 * v + a] = r[a];
                }
            }
        }
        modes
    }

    /// Build the hierarchy for the symmetric positive definite matrix `a` (full storage, sorted
    /// columns) of `block_size` × `block_size` vertex blocks, with the near-nullspace
    /// `near_nullspace` (column-major, dim × k, 1 ≤ k ≤ [`AMG_MAX_BLOCK`]; for 3D vertices
    /// [`Amg::rigid_body_modes`], for a scalar matrix a column of ones).
    ///
    /// # Errors
    /// [`AmgError`] for a non-square matrix, a block size or near-nullspace that does not fit,
    /// unsorted columns, non-finite values, a diagonal block that is not positive definite, a
    /// failed coarsest factorisation, or invalid `params`.
    pub fn new(
        a: SparseColMatRef<'_, usize, f64>,
        block_size: usize,
        near_nullspace: &[f64],
        params: AmgParams,
    ) -> Result<Self, AmgError> {
        params.validate()?;
        let n = a.nrows();
        if a.ncols() != n {
            return Err(AmgError::NotSquare {
                rows: n,
                cols: a.ncols(),
            });
        }
        if block_size == 0 || block_size > AMG_MAX_BLOCK || n % block_size != 0 {
            return Err(AmgError::BlockSize {
                dim: n,
                block: block_size,
            });
        }
        let k = near_nullspace.len().checked_div(n).unwrap_or(0);
        if n == 0 || k == 0 || k > AMG_MAX_BLOCK || near_nullspace.len() != k * n {
            return Err(AmgError::NearNullspace {
                len: near_nullspace.len(),
                dim: n,
            });
        }
        if near_nullspace.iter().any(|v| !v.is_finite()) {
            return Err(AmgError::NonFinite);
        }
        if u32::try_from(n).is_err() {
            return Err(AmgError::TooLarge { dim: n });
        }
        let fine = csr_of(a)?;
        let fine_nnz = fine.col.len();
        let block_ptr: Vec<usize> = (0..=n / block_size).map(|b| b * block_size).collect();
        let mut finest = Level::new(fine, block_ptr);
        finest.invert_diagonal(0)?;
        let coarsens = |level: &Level, depth: usize| {
            level.a.n_rows > params.max_coarse && depth < params.max_levels
        };
        // The finest level's ρ(D⁻¹A) needs no aggregate: it is computed beside the finest level's
        // symbolic set-up (on another thread of the pool, when it has one).
        let (finest_rho, first) = if coarsens(&finest, 1) {
            let mut power = [vec![0.0; n], vec![0.0; n]];
            let (rho, first) = rayon::join(
                || spectral_radius(&finest, &mut power, params.spectral_radius_iterations),
                || coarsen(&finest, near_nullspace, k, params.strength_threshold),
            );
            (Some((rho, power)), first)
        } else {
            (None, None)
        };
        let mut levels = vec![finest];
        let mut next = first;
        while let Some((transfer, coarse, nullspace)) = next.take() {
            levels.last_mut().expect("one level at least").transfer = Some(transfer);
            levels.push(coarse);
            let depth = levels.len();
            let level = levels.last().expect("pushed");
            if coarsens(level, depth) {
                let k = nullspace.len() / level.a.n_rows;
                next = coarsen(level, &nullspace, k, params.strength_threshold);
            }
        }
        // The products' right factors (T, P, A P) have a coarse level's columns; their left
        // factors' row blocks are any level's blocks.
        let largest = levels[1..].iter().map(|l| l.a.n_rows).max().unwrap_or(0);
        let widest = levels
            .iter()
            .flat_map(|l| l.block_ptr.windows(2).map(|w| w[1] - w[0]))
            .max()
            .unwrap_or(1);
        let last = &levels.last().expect("one level at least").a;
        let coarse_pattern = SymbolicSparseColMat::new_checked(
            last.n_rows,
            last.n_cols,
            last.ptr.clone(),
            None,
            last.col.iter().map(|&c| c as usize).collect(),
        );
        let coarse = SparseCholesky::analyze(
            coarse_pattern.as_ref(),
            CholeskyParams {
                kind: FactorKind::Auto,
                ..CholeskyParams::default()
            },
        )?;
        for level in &mut levels {
            level.split(params.smoother_parts);
        }
        let cycle = levels.iter().map(|l| Cycle::new(l.a.n_rows)).collect();
        let mut amg = Amg {
            params,
            levels,
            cycle,
            coarse,
            coarse_pattern,
            dense: Vec::new(),
            largest,
            widest,
            fine_nnz,
        };
        if let (Some((rho, power)), Some(tr)) = (finest_rho, amg.levels[0].transfer.as_mut()) {
            tr.power = power;
            amg.fill(Some(rho))?;
        } else {
            amg.fill(None)?;
        }
        Ok(amg)
    }

    /// Refill every level from new values of the matrix, on the pattern the hierarchy was built for
    /// (the aggregates and the near-nullspace stay): no symbolic work (the only allocations are a
    /// list of row chunks per product, a block's rows of A T per chunk of the prolongator's
    /// smoothing, and a scratch vector when the rayon pool has grown); the
    /// same bits as [`Amg::new`] on `a` with the same near-nullspace, whatever the thread count.
    ///
    /// # Errors
    /// [`AmgError::PatternMismatch`] if `a` has another size or pattern, [`AmgError::NonFinite`],
    /// [`AmgError::NotPositiveDefinite`], [`AmgError::Coarse`]. After an error the hierarchy must
    /// be refreshed successfully before it is applied.
    pub fn refresh(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<(), AmgError> {
        self.params.validate()?;
        let fine = &mut self.levels[0].a;
        if a.nrows() != fine.n_rows || a.ncols() != fine.n_cols || a.compute_nnz() != self.fine_nnz
        {
            return Err(AmgError::PatternMismatch);
        }
        for j in 0..a.ncols() {
            let rows = a.row_idx_of_col_raw(j);
            let range = fine.row(j);
            let cols = &fine.col[range.clone()];
            if rows.len() != cols.len() || rows.iter().zip(cols).any(|(&r, &c)| r != c as usize) {
                return Err(AmgError::PatternMismatch);
            }
            fine.val[range].copy_from_slice(a.val_of_col(j));
        }
        self.fill(None)
    }

    /// The number of levels, the finest included.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// The unknowns of each level, finest first.
    pub fn level_sizes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.a.n_rows).collect()
    }

    /// Operator complexity: stored entries of all levels' matrices over the finest's.
    pub fn operator_complexity(&self) -> f64 {
        let total: usize = self.levels.iter().map(|l| l.a.col.len()).sum();
        total as f64 / self.levels[0].a.col.len().max(1) as f64
    }

    /// The numeric set-up from the finest matrix' values down; `finest_rho`: the finest level's
    /// ρ(D⁻¹A) when it is known, its diagonal blocks already inverted.
    fn fill(&mut self, finest_rho: Option<f64>) -> Result<(), AmgError> {
        if self.levels[0].a.val.iter().any(|v| !v.is_finite()) {
            return Err(AmgError::NonFinite);
        }
        let threads = rayon::current_num_threads().max(1);
        while self.dense.len() < threads {
            self.dense.push(vec![0.0; self.largest * self.widest]);
        }
        let dense = &mut self.dense[..threads];
        let omega_scale = self.params.prolongator_damping;
        let iterations = self.params.spectral_radius_iterations;
        for depth in 0..self.levels.len() {
            let (upper, lower) = self.levels.split_at_mut(depth + 1);
            let level = &mut upper[depth];
            let known_rho = finest_rho.filter(|_| depth == 0);
            if known_rho.is_none() {
                level.invert_diagonal(depth)?;
            }
            let Some(tr) = level.transfer.as_mut() else {
                continue;
            };
            let mut power = std::mem::take(&mut tr.power);
            for v in &mut power {
                v.resize(level.a.n_rows, 0.0);
            }
            let rho = known_rho.unwrap_or_else(|| spectral_radius(level, &mut power, iterations));
            let omega = omega_scale / rho;
            let tr = level.transfer.as_mut().expect("checked");
            tr.power = power;
            smooth_values(
                &level.a,
                tr,
                &level.block_ptr,
                &level.diag_offset,
                &level.diag_inv,
                omega,
                dense,
            );
            // R = Pᵀ: P's entries, walked by rows, to their places in R (as transpose_pattern
            // laid them out).
            let Transfer {
                p,
                r,
                ap,
                next,
                r_uniform,
                ..
            } = tr;
            next.copy_from_slice(&r.ptr[..r.n_rows]);
            for i in 0..p.n_rows {
                for e in p.row(i) {
                    let j = p.col[e] as usize;
                    r.val[next[j]] = p.val[e];
                    next[j] += 1;
                }
            }
            product_values(&level.a, &level.block_ptr, level.uniform_rows, p, ap, dense);
            let coarse = &mut lower[0];
            product_values(r, &coarse.block_ptr, *r_uniform, ap, &mut coarse.a, dense);
            let coarse = &mut coarse.a;
            // Exact symmetry: the mean of each entry and its transpose. The pattern Pᵀ A P is
            // symmetric, so walking the rows in order meets the entries (i, j) of column j in
            // the order of row j's entries (j, i).
            next.copy_from_slice(&coarse.ptr[..coarse.n_rows]);
            for i in 0..coarse.n_rows {
                for e in coarse.row(i) {
                    let j = coarse.col[e] as usize;
                    let t = next[j];
                    next[j] += 1;
                    debug_assert_eq!(coarse.col[t] as usize, i, "the coarse pattern is symmetric");
                    if e < t {
                        let v = 0.5 * (coarse.val[e] + coarse.val[t]);
                        coarse.val[e] = v;
                        coarse.val[t] = v;
                    }
                }
            }
        }
        let last = &self.levels.last().expect("one level").a;
        let view = SparseColMatRef::new(self.coarse_pattern.as_ref(), &last.val);
        self.coarse.factorize(view)?;
        Ok(())
    }

    /// One V-cycle, z ≈ A⁻¹ r, on the lanes of `cycle` (one [`Cycle`] per level; `scratch` for a
    /// multi-column coarsest solve).
    fn vcycle<T: Lane>(
        &mut self,
        cycle: &mut [Cycle<T>],
        scratch: &mut Vec<f64>,
        r: &[T],
        z: &mut [T],
    ) {
        let sweeps = self.params.smoother_sweeps;
        let symmetric_each_side = self.params.smoother == AmgSmoother::SymmetricGaussSeidel;
        cycle[0].b.copy_from_slice(r);
        let depth = self.levels.len();
        for (l, level) in self.levels[..depth - 1].iter().enumerate() {
            let (upper, lower) = cycle.split_at_mut(l + 1);
            let v = &mut upper[l];
            v.x.fill(T::zero());
            for sweep in 0..sweeps {
                let first = if sweep == 0 {
                    Sweep::ForwardFromZero
                } else {
                    Sweep::Forward
                };
                level.sweep(&v.b, &mut v.x, &mut v.r, first);
                if symmetric_each_side {
                    level.sweep(&v.b, &mut v.x, &mut v.r, Sweep::Backward);
                }
            }
            level.residual(&v.b, &v.x, &mut v.r);
            let tr = level.transfer.as_ref().expect("above the coarsest");
            let coarse_blocks = &self.levels[l + 1].block_ptr;
            tr.r.apply_blocks::<false, T>(coarse_blocks, tr.r_uniform, &[], &v.r, &mut lower[0].b);
        }
        {
            let last = &mut cycle[depth - 1];
            last.x.copy_from_slice(&last.b);
            T::solve_coarse(&mut self.coarse, &mut last.x, scratch);
        }
        for (l, level) in self.levels[..depth - 1].iter().enumerate().rev() {
            let (upper, lower) = cycle.split_at_mut(l + 1);
            let v = &mut upper[l];
            let tr = level.transfer.as_ref().expect("above the coarsest");
            tr.p.apply_blocks::<false, T>(
                &level.block_ptr,
                tr.p_uniform,
                &[],
                &lower[0].x,
                &mut v.r,
            );
            for (x, c) in v.x.iter_mut().zip(&v.r) {
                *x += *c;
            }
            for _ in 0..sweeps {
                if symmetric_each_side {
                    level.sweep(&v.b, &mut v.x, &mut v.r, Sweep::Forward);
                }
                level.sweep(&v.b, &mut v.x, &mut v.r, Sweep::Backward);
            }
        }
        z.copy_from_slice(&cycle[0].x);
    }

    /// Buffers for [`Amg::apply_columns`] with D right-hand sides.
    pub fn columns_workspace<const D: usize>(&self) -> AmgColumns<D> {
        AmgColumns {
            cycle: self.levels.iter().map(|l| Cycle::new(l.a.n_rows)).collect(),
            coarse: Vec::with_capacity(D * self.levels.last().map_or(0, |l| l.a.n_rows)),
        }
    }

    /// One V-cycle for each of D right-hand sides at once: z_a ≈ A⁻¹ r_a for every column
    /// a (entry i of `r` holds unknown i of the D right-hand sides), with each level's matrix read
    /// once for all D. Column a's values are those of [`Preconditioner::apply`] on column a, but
    /// for the coarsest solve's rounding (faer's multi-column triangular solves). Allocates
    /// nothing.
    ///
    /// # Panics
    /// If `r` or `z` is not of the matrix' dimension, or `work` was made for another hierarchy.
    #[track_caller]
    pub fn apply_columns<const D: usize>(
        &mut self,
        work: &mut AmgColumns<D>,
        r: &[SVector<f64, D>],
        z: &mut [SVector<f64, D>],
    ) {
        let n = self.levels[0].a.n_rows;
        assert!(r.len() == n && z.len() == n, "vector lengths");
        assert!(
            work.cycle.len() == self.levels.len()
                && work
                    .cycle
                    .iter()
                    .zip(&self.levels)
                    .all(|(c, l)| c.b.len() == l.a.n_rows),
            "the workspace of another hierarchy"
        );
        let AmgColumns { cycle, coarse } = work;
        self.vcycle(cycle, coarse, r, z);
    }

    /// y = A x for D columns at once with the finest matrix (row-parallel above a size; the same
    /// bits whatever the thread count).
    ///
    /// # Panics
    /// If `x` or `y` is not of the matrix' dimension.
    #[track_caller]
    pub fn product_columns<const D: usize>(
        &self,
        x: &[SVector<f64, D>],
        y: &mut [SVector<f64, D>],
    ) {
        let a = &self.levels[0].a;
        assert!(x.len() == a.n_cols && y.len() == a.n_rows, "vector lengths");
        self.levels[0].apply(x, y);
    }
}

impl Preconditioner for Amg {
    /// One V-cycle.
    ///
    /// # Panics
    /// If `r` or `z` is not of the matrix' dimension.
    #[track_caller]
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        let n = self.levels[0].a.n_rows;
        assert!(r.len() == n && z.len() == n, "vector lengths");
        let mut cycle = std::mem::take(&mut self.cycle);
        self.vcycle(&mut cycle, &mut Vec::new(), r, z);
        self.cycle = cycle;
    }
}

/// The level's matrix as a linear operator (for tests and measurements on the same data).
impl LinearOperator for Amg {
    fn dim(&self) -> usize {
        self.levels[0].a.n_rows
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.levels[0].apply(x, y)
    }
}

impl Level {
    fn new(a: Csr, block_ptr: Vec<usize>) -> Self {
        let blocks = block_ptr.len() - 1;
        let mut diag_offset = Vec::with_capacity(blocks + 1);
        let mut total = 0;
        for b in 0..blocks {
            diag_offset.push(total);
            let k = block_ptr[b + 1] - block_ptr[b];
            total += k * k;
        }
        diag_offset.push(total);
        let mut diag_entries = vec![usize::MAX; total];
        for b in 0..blocks {
            let (lo, hi) = (block_ptr[b], block_ptr[b + 1]);
            let k = hi - lo;
            for i in lo..hi {
                for e in a.row(i) {
                    let j = a.col[e] as usize;
                    if (lo..hi).contains(&j) {
                        diag_entries[diag_offset[b] + (i - lo) * k + (j - lo)] = e;
                    }
                }
            }
        }
        let uniform_rows = uniform_rows(&a, &block_ptr);
        Level {
            a,
            block_ptr,
            diag_offset,
            diag_inv: vec![0.0; total],
            diag_entries,
            uniform_rows,
            transfer: None,
            parts: vec![0, blocks],
        }
    }

    /// y = A x.
    fn apply<T: Lane>(&self, x: &[T], y: &mut [T]) {
        self.a
            .apply_blocks::<false, T>(&self.block_ptr, self.uniform_rows, &[], x, y);
    }

    /// r = b − A x.
    fn residual<T: Lane>(&self, b: &[T], x: &[T], r: &mut [T]) {
        self.a
            .apply_blocks::<true, T>(&self.block_ptr, self.uniform_rows, b, x, r);
    }

    /// x_b = D_b⁻¹ y_b for the blocks `first..last`, `x` holding their rows (from the first
    /// block's first row), `y` the whole level's; halves of many blocks in parallel (each block
    /// solved alone: the same bits on any pool).
    fn solve_diagonal(&self, first: usize, last: usize, y: &[f64], x: &mut [f64]) {
        const SERIAL_BLOCKS: usize = 2048;
        if last - first > SERIAL_BLOCKS {
            let mid = first + (last - first) / 2;
            let (low, high) = x.split_at_mut(self.block_ptr[mid] - self.block_ptr[first]);
            rayon::join(
                || self.solve_diagonal(first, mid, y, low),
                || self.solve_diagonal(mid, last, y, high),
            );
            return;
        }
        let base = self.block_ptr[first];
        for b in first..last {
            let (lo, hi) = (self.block_ptr[b], self.block_ptr[b + 1]);
            let k = hi - lo;
            let inv = &self.diag_inv[self.diag_offset[b]..][..k * k];
            for i in 0..k {
                let mut sum = 0.0;
                for j in 0..k {
                    sum += inv[i * k + j] * y[lo + j];
                }
                x[lo + i - base] = sum;
            }
        }
    }

    fn invert_diagonal(&mut self, level: usize) -> Result<(), AmgError> {
        for b in 0..self.block_ptr.len() - 1 {
            let k = self.block_ptr[b + 1] - self.block_ptr[b];
            let o = self.diag_offset[b];
            let block = &mut self.diag_inv[o..o + k * k];
            for (v, &e) in block.iter_mut().zip(&self.diag_entries[o..o + k * k]) {
                *v = if e == usize::MAX { 0.0 } else { self.a.val[e] };
            }
            if !invert_spd_block(block, k) {
                return Err(AmgError::NotPositiveDefinite { level, block: b });
            }
        }
        Ok(())
    }

    /// Split the blocks into `parts` contiguous parts of about equal stored entries (one part
    /// below [`AMG_PARTS_MIN_ROWS`] rows).
    fn split(&mut self, parts: usize) {
        let blocks = self.block_ptr.len() - 1;
        self.parts = vec![0];
        if parts > 1 && self.a.n_rows >= AMG_PARTS_MIN_ROWS {
            let total = self.a.col.len();
            let entries_before = |blk: usize| self.a.ptr[self.block_ptr[blk]];
            let mut blk = 0;
            for p in 1..parts {
                let goal = total * p / parts;
                while blk < blocks && entries_before(blk) < goal {
                    blk += 1;
                }
                if blk > *self.parts.last().expect("starts at 0") && blk < blocks {
                    self.parts.push(blk);
                }
            }
        }
        self.parts.push(blocks);
    }

    /// s_r = b_r − Σ_c a_rc x_c for the rows `lo..hi` of one block, one row after the other, x_c
    /// from `read`; under `from_zero` only the columns before the block's (the others are still
    /// zero: their terms are exact zeros).
    fn rows_one_by_one<T: Lane>(
        &self,
        lo: usize,
        hi: usize,
        b: &[T],
        read: impl Fn(usize) -> T,
        from_zero: bool,
        s: &mut [T; AMG_MAX_BLOCK],
    ) {
        for i in lo..hi {
            let mut v = b[i];
            let mut entries = self.a.row(i);
            if from_zero {
                let cols = &self.a.col[entries.clone()];
                entries.end = entries.start + cols.partition_point(|&c| (c as usize) < lo);
            }
            for e in entries {
                v -= read(self.a.col[e] as usize) * self.a.val[e];
            }
            s[i - lo] = v;
        }
    }

    /// One block Gauss–Seidel sweep on A x = b, forward or backward over the blocks: over the
    /// whole level, or (several parts) over each part in parallel with the other parts' values
    /// from `start`, a scratch vector of the level's size that receives x at the sweep's start.
    fn sweep<T: Lane>(&self, b: &[T], x: &mut [T], start: &mut [T], sweep: Sweep) {
        if self.parts.len() <= 2 {
            self.sweep_part(b, x, 0, &[], 0..self.block_ptr.len() - 1, sweep);
        } else {
            start.copy_from_slice(x);
            self.sweep_parts(b, x, 0, &self.parts, start, sweep);
        }
    }

    /// Sweep the parts `parts` (block bounds) whose rows start at row `offset` (`x` holds their
    /// rows), halving the list into two forks until one part is left.
    fn sweep_parts<T: Lane>(
        &self,
        b: &[T],
        x: &mut [T],
        offset: usize,
        parts: &[usize],
        start: &[T],
        sweep: Sweep,
    ) {
        if parts.len() == 2 {
            self.sweep_part(b, x, offset, start, parts[0]..parts[1], sweep);
            return;
        }
        let mid = parts.len() / 2;
        let split = self.block_ptr[parts[mid]] - offset;
        let (left, right) = x.split_at_mut(split);
        rayon::join(
            || self.sweep_parts(b, left, offset, &parts[..=mid], start, sweep),
            || self.sweep_parts(b, right, offset + split, &parts[mid..], start, sweep),
        );
    }

    /// Gauss–Seidel over `blocks`, whose rows are `x` from row `offset` on; a column outside them
    /// is read from `outside` (never, when `x` holds every row).
    fn sweep_part<T: Lane>(
        &self,
        b: &[T],
        x: &mut [T],
        offset: usize,
        outside: &[T],
        blocks: std::ops::Range<usize>,
        sweep: Sweep,
    ) {
        let rows = x.len();
        let forward = sweep != Sweep::Backward;
        let from_zero = sweep == Sweep::ForwardFromZero;
        let mut s = [T::zero(); AMG_MAX_BLOCK];
        let count = blocks.len();
        for step in 0..count {
            let blk = if forward {
                blocks.start + step
            } else {
                blocks.end - 1 - step
            };
            let (lo, hi) = (self.block_ptr[blk], self.block_ptr[blk + 1]);
            let k = hi - lo;
            let read = |c: usize| {
                let local = c.wrapping_sub(offset);
                if local < rows {
                    x[local]
                } else {
                    outside[c]
                }
            };
            let width = || {
                let cols = &self.a.col[self.a.row(lo)];
                if from_zero {
                    cols.partition_point(|&c| (c as usize) < lo)
                } else {
                    cols.len()
                }
            };
            let side_by_side = self.uniform_rows
                && self.a.block_side_by_side::<true, T>(
                    lo,
                    width(),
                    read,
                    |r| b[lo + r],
                    &mut s[..k],
                );
            if !side_by_side {
                self.rows_one_by_one(lo, hi, b, read, from_zero, &mut s);
            }
            let inv = &self.diag_inv[self.diag_offset[blk]..self.diag_offset[blk] + k * k];
            for i in 0..k {
                let mut d = T::zero();
                for j in 0..k {
                    d += s[j] * inv[i * k + j];
                }
                x[lo - offset + i] += d;
            }
        }
    }
}

/// ρ(D⁻¹A) of a level by power iteration from a fixed start, as the Rayleigh quotient
/// xᵀAx / xᵀDx of the last iterate (D⁻¹A is similar to a symmetric matrix; the quotient converges
/// from below). `power` holds two scratch vectors of the level's size. The products, sums and
/// block solves run in parallel on large levels, the sums in a fixed order (the same bits on any
/// pool).
fn spectral_radius(level: &Level, power: &mut [Vec<f64>; 2], iterations: usize) -> f64 {
    let [x, y] = power;
    // A fixed, sign-varying start (a hash of the index), so that no eigenvector is missed.
    for (i, v) in x.iter_mut().enumerate() {
        let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
        *v = (h as f64) / (1u64 << 24) as f64 - 0.5;
    }
    let a = &level.a;
    let blocks = level.block_ptr.len() - 1;
    let mut rho = 1.0;
    for _ in 0..iterations {
        level.apply(x, y);
        let xax = crate::operator::dot(x, y);
        let xdx = hooke_assembly::deterministic_sum(blocks, true, |b| {
            let (lo, hi) = (level.block_ptr[b], level.block_ptr[b + 1]);
            let k = hi - lo;
            let entries = &level.diag_entries[level.diag_offset[b]..][..k * k];
            let mut sum = 0.0;
            for i in 0..k {
                for j in 0..k {
                    let e = entries[i * k + j];
                    if e != usize::MAX {
                        sum += x[lo + i] * a.val[e] * x[lo + j];
                    }
                }
            }
            sum
        });
        if xdx > 0.0 && xax.is_finite() {
            rho = xax / xdx;
        }
        level.solve_diagonal(0, blocks, y, x);
        let norm = crate::operator::dot(x, x).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            break;
        }
        x.par_iter_mut().with_min_len(4096).for_each(|v| *v /= norm);
    }
    rho.max(f64::MIN_POSITIVE)
}

/// Copy a faer CSC matrix (symmetric: its CSC arrays are its CSR arrays) into a [`Csr`], checking
/// sorted columns and finite values.
fn csr_of(a: SparseColMatRef<'_, usize, f64>) -> Result<Csr, AmgError> {
    let n = a.nrows();
    let mut ptr = Vec::with_capacity(n + 1);
    ptr.push(0);
    let mut col = Vec::with_capacity(a.compute_nnz());
    let mut val = Vec::with_capacity(a.compute_nnz());
    for j in 0..a.ncols() {
        let rows = a.row_idx_of_col_raw(j);
        if rows.windows(2).any(|w| w[0] >= w[1]) {
            return Err(AmgError::UnsortedPattern { column: j });
        }
        // Every row index is below n ≤ u32::MAX (checked by the caller).
        col.extend(rows.iter().map(|&i| i as u32));
        val.extend_from_slice(a.val_of_col(j));
        ptr.push(col.len());
    }
    if val.iter().any(|v| !v.is_finite()) {
        return Err(AmgError::NonFinite);
    }
    Ok(Csr {
        n_rows: n,
        n_cols: n,
        ptr,
        col,
        val,
    })
}

/// Greedy standard aggregation of the blocks (pyamg's three passes): 1. a block whose strong
/// neighbours are all free starts an aggregate with them; 2. a left-over block joins the
/// aggregate of its first aggregated strong neighbour; 3. any block still left starts an aggregate
/// with its free strong neighbours. Returns the aggregate of each block.
fn aggregate(a: &Csr, block_ptr: &[usize], theta: f64) -> Vec<usize> {
    let blocks = block_ptr.len() - 1;
    let mut block_of = vec![0usize; a.n_rows];
    for b in 0..blocks {
        block_of[block_ptr[b]..block_ptr[b + 1]].fill(b);
    }
    // Squared Frobenius norms of the diagonal blocks, then the strong neighbours of each block,
    // sorted, in one flat list (block b's at strong_col[strong_ptr[b]..strong_ptr[b + 1]]): a
    // list per block would be one allocation per vertex.
    let mut diag = vec![0.0; blocks];
    for b in 0..blocks {
        for i in block_ptr[b]..block_ptr[b + 1] {
            for e in a.row(i) {
                if block_of[a.col[e] as usize] == b {
                    diag[b] += a.val[e] * a.val[e];
                }
            }
        }
    }
    let mut strong_ptr = Vec::with_capacity(blocks + 1);
    strong_ptr.push(0);
    let mut strong_col: Vec<u32> = Vec::with_capacity(a.col.len() / block_ptr[1].max(1));
    // Per block, its slot in the current block's neighbour list (valid when `owner` is b).
    let mut slot = vec![0usize; blocks];
    let mut owner = vec![usize::MAX; blocks];
    let mut list: Vec<(usize, f64)> = Vec::new();
    for b in 0..blocks {
        list.clear();
        for i in block_ptr[b]..block_ptr[b + 1] {
            for e in a.row(i) {
                let c = block_of[a.col[e] as usize];
                let v = a.val[e] * a.val[e];
                if c == b {
                    continue;
                } else if owner[c] == b {
                    list[slot[c]].1 += v;
                } else {
                    owner[c] = b;
                    slot[c] = list.len();
                    list.push((c, v));
                }
            }
        }
        list.sort_unstable_by_key(|&(n, _)| n);
        strong_col.extend(
            list.iter()
                .filter(|&&(c, v)| {
                    theta == 0.0 || v.sqrt() >= theta * (diag[b] * diag[c]).sqrt().sqrt()
                })
                .map(|&(c, _)| c as u32),
        );
        strong_ptr.push(strong_col.len());
    }
    let strong = |b: usize| {
        strong_col[strong_ptr[b]..strong_ptr[b + 1]]
            .iter()
            .map(|&c| c as usize)
    };
    const FREE: usize = usize::MAX;
    let mut agg = vec![FREE; blocks];
    let mut count = 0;
    for b in 0..blocks {
        if agg[b] == FREE && strong(b).all(|c| agg[c] == FREE) {
            agg[b] = count;
            for c in strong(b) {
                agg[c] = count;
            }
            count += 1;
        }
    }
    let first_pass = agg.clone();
    for (b, a) in agg.iter_mut().enumerate() {
        if *a == FREE {
            if let Some(c) = strong(b).find(|&c| first_pass[c] != FREE) {
                *a = first_pass[c];
            }
        }
    }
    for b in 0..blocks {
        if agg[b] == FREE {
            agg[b] = count;
            for c in strong(b) {
                if agg[c] == FREE {
                    agg[c] = count;
                }
            }
            count += 1;
        }
    }
    agg
}

/// The tentative prolongator: per aggregate, the near-nullspace rows of its unknowns
/// orthonormalised by modified Gram–Schmidt, dropping columns that are (numerically) dependent on
/// the earlier ones; the kept columns become the aggregate's coarse unknowns, and the Gram–Schmidt
/// coefficients (R of B_agg = Q R, the kept rows) its coarse near-nullspace. Returns T, the coarse
/// block pointer and the coarse near-nullspace (column-major, coarse size × k).
fn tentative(
    aggregates: &[usize],
    block_ptr: &[usize],
    nullspace: &[f64],
    k: usize,
) -> (Csr, Vec<usize>, Vec<f64>) {
    let n = *block_ptr.last().expect("non-empty");
    let count = aggregates.iter().map(|&a| a + 1).max().unwrap_or(0);
    // The blocks of each aggregate, in block order (a counting sort).
    let mut member_ptr = vec![0usize; count + 1];
    for &a in aggregates {
        member_ptr[a + 1] += 1;
    }
    for a in 0..count {
        member_ptr[a + 1] += member_ptr[a];
    }
    let mut members = vec![0usize; aggregates.len()];
    let mut next = member_ptr.clone();
    for (b, &a) in aggregates.iter().enumerate() {
        members[next[a]] = b;
        next[a] += 1;
    }
    // Per fine unknown, its aggregate's first coarse column, its aggregate's Q (row-major
    // m × kept, the unknown's row at `q_row`) and the kept count.
    let mut q_of = vec![(0usize, 0usize, 0usize); n];
    let mut q_all: Vec<f64> = Vec::with_capacity(n * k);
    let mut coarse_ptr = Vec::with_capacity(count + 1);
    coarse_ptr.push(0);
    let mut coarse_r: Vec<f64> = Vec::new(); // per coarse unknown, its row of R (k values)
    let (mut dofs, mut v, mut q, mut coefficients) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for a in 0..count {
        dofs.clear();
        dofs.extend(
            members[member_ptr[a]..member_ptr[a + 1]]
                .iter()
                .flat_map(|&b| block_ptr[b]..block_ptr[b + 1]),
        );
        let m = dofs.len();
        if m == 0 {
            coarse_ptr.push(*coarse_ptr.last().expect("non-empty"));
            continue;
        }
        // The kept columns of Q, column after column (m values each).
        q.clear();
        let first_r = coarse_r.len();
        let mut kept = 0;
        for c in 0..k {
            v.clear();
            v.extend(dofs.iter().map(|&d| nullspace[c * n + d]));
            let original = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            coefficients.clear();
            for qj in q.chunks_exact(m) {
                let proj: f64 = qj.iter().zip(&v).map(|(a, b)| a * b).sum();
                coefficients.push(proj);
                for (vi, qi) in v.iter_mut().zip(qj) {
                    *vi -= proj * qi;
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for (j, &p) in coefficients.iter().enumerate() {
                coarse_r[first_r + j * k + c] = p;
            }
            if kept < m && norm > 1e-10 * original && norm > 0.0 {
                q.extend(v.iter().map(|vi| vi / norm));
                coarse_r.extend(std::iter::repeat_n(0.0, k));
                coarse_r[first_r + kept * k + c] = norm;
                kept += 1;
            }
        }
        let base = *coarse_ptr.last().expect("non-empty");
        let q_start = q_all.len();
        // Row-major per unknown: unknown i's kept values side by side.
        for i in 0..m {
            q_all.extend((0..kept).map(|j| q[j * m + i]));
        }
        for (i, &d) in dofs.iter().enumerate() {
            q_of[d] = (base, q_start + i * kept, kept);
        }
        coarse_ptr.push(base + kept);
    }
    let coarse_n = *coarse_ptr.last().expect("non-empty");
    let mut ptr = Vec::with_capacity(n + 1);
    ptr.push(0);
    let mut col = Vec::with_capacity(n * k);
    let mut val = Vec::with_capacity(n * k);
    for &(base, q_row, kept) in &q_of {
        for (j, &value) in q_all[q_row..q_row + kept].iter().enumerate() {
            if value != 0.0 {
                // A coarse index is below the fine dimension, itself ≤ u32::MAX.
                col.push((base + j) as u32);
                val.push(value);
            }
        }
        ptr.push(col.len());
    }
    let mut coarse_nullspace = vec![0.0; coarse_n * k];
    for (i, row) in coarse_r.chunks_exact(k).enumerate() {
        for c in 0..k {
            coarse_nullspace[c * coarse_n + i] = row[c];
        }
    }
    (
        Csr {
            n_rows: n,
            n_cols: coarse_n,
            ptr,
            col,
            val,
        },
        coarse_ptr,
        coarse_nullspace,
    )
}

/// The pattern of P = T − ω D⁻¹ A T: per block, the union of its rows' patterns in T and A T (D⁻¹
/// mixes the rows of a block), A T's taken from A's and T's patterns without forming it. A row of
/// A with the pattern of the block's row before it, and a row of T with the pattern of the row
/// before it met right after it, add nothing new and are passed over.
fn smoothed_pattern(a: &Csr, t: &Csr, block_ptr: &[usize]) -> Csr {
    let t_same_as_previous: Vec<bool> = (0..t.n_rows)
        .map(|i| i > 0 && t.col[t.row(i)] == t.col[t.row(i - 1)])
        .collect();
    let mut mark = vec![usize::MAX; t.n_cols];
    let mut ptr = vec![0];
    let mut col = Vec::new();
    let mut block_cols = Vec::new();
    for b in 0..block_ptr.len() - 1 {
        block_cols.clear();
        let mut add = |j: u32| {
            if mark[j as usize] != b {
                mark[j as usize] = b;
                block_cols.push(j);
            }
        };
        for i in block_ptr[b]..block_ptr[b + 1] {
            t.row(i).for_each(|f| add(t.col[f]));
            if i > block_ptr[b] && a.col[a.row(i)] == a.col[a.row(i - 1)] {
                continue;
            }
            let mut previous = usize::MAX;
            for e in a.row(i) {
                let c = a.col[e] as usize;
                let repeat = t_same_as_previous[c] && previous == c - 1;
                previous = c;
                if !repeat {
                    t.row(c).for_each(|f| add(t.col[f]));
                }
            }
        }
        block_cols.sort_unstable();
        for _ in block_ptr[b]..block_ptr[b + 1] {
            col.extend_from_slice(&block_cols);
            ptr.push(col.len());
        }
    }
    let nnz = col.len();
    Csr {
        n_rows: t.n_rows,
        n_cols: t.n_cols,
        ptr,
        col,
        val: vec![0.0; nnz],
    }
}

/// P's values: T − ω D⁻¹ (A T), block by block (every row of a block has the block's pattern).
/// A block's rows of A T are formed in a scratch vector of `dense` and kept only while the block
/// is smoothed, so A T is never stored (on a 3D solid it is as large as P). The blocks are split
/// into one contiguous chunk per scratch vector (each zeroed, of at least T's column count, and
/// zeroed again on return), the chunks in parallel; each value is summed in a fixed order by one
/// thread, so the bits do not depend on the split.
fn smooth_values(
    a: &Csr,
    tr: &mut Transfer,
    block_ptr: &[usize],
    diag_offset: &[usize],
    diag_inv: &[f64],
    omega: f64,
    dense: &mut [Vec<f64>],
) {
    let Transfer { t, p, .. } = tr;
    let Csr { ptr, col, val, .. } = p;
    let (ptr, col) = (&*ptr, &*col);
    let blocks = block_ptr.len() - 1;
    let offset = |b: usize| ptr[block_ptr[b]];
    for_each_chunk(blocks, offset, val, dense, |first, last, values, dense| {
        let base = offset(first);
        // The block's rows of A T on its pattern, row after row.
        let mut at_rows: Vec<f64> = Vec::new();
        for b in first..last {
            let (lo, hi) = (block_ptr[b], block_ptr[b + 1]);
            let k = hi - lo;
            let cols = &col[ptr[lo]..ptr[lo + 1]];
            let width = cols.len();
            at_rows.clear();
            at_rows.resize(k * width, 0.0);
            for s in lo..hi {
                for e in a.row(s) {
                    let av = a.val[e];
                    for f in t.row(a.col[e] as usize) {
                        dense[t.col[f] as usize] += av * t.val[f];
                    }
                }
                let row = &mut at_rows[(s - lo) * width..(s - lo + 1) * width];
                for (v, &j) in row.iter_mut().zip(cols) {
                    *v = dense[j as usize];
                    dense[j as usize] = 0.0;
                }
            }
            let inv = &diag_inv[diag_offset[b]..diag_offset[b] + k * k];
            for i in lo..hi {
                let vals = &mut values[ptr[i] - base..ptr[i + 1] - base];
                vals.fill(0.0);
                // T's row i, merged into P's sorted row.
                let mut pos = 0;
                for f in t.row(i) {
                    while cols[pos] != t.col[f] {
                        pos += 1;
                    }
                    vals[pos] += t.val[f];
                }
                for s in lo..hi {
                    let w = inv[(i - lo) * k + (s - lo)];
                    if w != 0.0 {
                        let scale = -omega * w;
                        let row = &at_rows[(s - lo) * width..(s - lo + 1) * width];
                        for (v, &r) in vals.iter_mut().zip(row) {
                            *v += scale * r;
                        }
                    }
                }
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_inverse_of_an_spd_block() {
        let mut m = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let a = m;
        assert!(invert_spd_block(&mut m, 3));
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|l| a[i * 3 + l] * m[l * 3 + j]).sum();
                assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14);
            }
        }
        let mut bad = [1.0, 2.0, 2.0, 1.0];
        assert!(!invert_spd_block(&mut bad, 2));
    }

    /// A symmetric block-tridiagonal matrix of `sizes` blocks (each block row one pattern),
    /// strongly diagonally dominant, with sign-varying values from a fixed hash.
    fn block_tridiagonal(sizes: &[usize]) -> (Csr, Vec<usize>) {
        let mut block_ptr = vec![0];
        for &k in sizes {
            block_ptr.push(block_ptr.last().unwrap() + k);
        }
        let n = *block_ptr.last().unwrap();
        let value = |i: usize, j: usize| {
            let (lo, hi) = (i.min(j) as u64, i.max(j) as u64);
            let h = (lo * 7919 + hi * 104_729).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            let v = h as f64 / (1u64 << 24) as f64 - 0.5;
            if i == j {
                v + 20.0
            } else {
                v
            }
        };
        let (mut ptr, mut col, mut val) = (vec![0], Vec::new(), Vec::new());
        for b in 0..sizes.len() {
            let cols = block_ptr[b.saturating_sub(1)]..block_ptr[(b + 2).min(sizes.len())];
            for i in block_ptr[b]..block_ptr[b + 1] {
                for j in cols.clone() {
                    col.push(j as u32);
                    val.push(value(i, j));
                }
                ptr.push(col.len());
            }
        }
        let a = Csr {
            n_rows: n,
            n_cols: n,
            ptr,
            col,
            val,
        };
        (a, block_ptr)
    }

    /// The rows side by side (blocks of 3 and 6) give the bits of one row at a time, in the
    /// products, the residuals and every kind of sweep, serial and split in parts.
    #[test]
    fn rows_side_by_side_are_the_bits_of_one_row_at_a_time() {
        // Above AMG_PARTS_MIN_ROWS, so that two parts are two.
        let mut sizes = vec![3; 2000];
        sizes.extend([6; 500]);
        sizes.extend([2, 5, 3, 1, 6]);
        let (a, block_ptr) = block_tridiagonal(&sizes);
        assert!(uniform_rows(&a, &block_ptr));
        let n = a.n_rows;
        let x: Vec<f64> = (0..n)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0)
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|i| ((i * 53 % 97) as f64 - 48.0) / 3.0)
            .collect();
        for parts in [1, 2] {
            let mut level = Level::new(a.clone(), block_ptr.clone());
            level.invert_diagonal(0).expect("diagonally dominant");
            level.split(parts);
            assert_eq!(level.parts.len(), parts + 1);
            let mut results = Vec::new();
            for uniform in [true, false] {
                level.uniform_rows = uniform;
                let (mut y, mut r) = (vec![0.0; n], vec![0.0; n]);
                level.apply(&x, &mut y);
                level.residual(&b, &x, &mut r);
                let mut sweeps = Vec::new();
                for sweep in [Sweep::ForwardFromZero, Sweep::Forward, Sweep::Backward] {
                    let mut z = if sweep == Sweep::ForwardFromZero {
                        vec![0.0; n]
                    } else {
                        x.clone()
                    };
                    let mut start = vec![0.0; n];
                    level.sweep(&b, &mut z, &mut start, sweep);
                    sweeps.push(z);
                }
                results.push((y, r, sweeps));
            }
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let (side, single) = (&results[0], &results[1]);
            assert_eq!(bits(&side.0), bits(&single.0), "A x, {parts} part(s)");
            assert_eq!(bits(&side.1), bits(&single.1), "b - A x, {parts} part(s)");
            for (s, o) in side.2.iter().zip(&single.2) {
                assert_eq!(bits(s), bits(o), "sweep, {parts} part(s)");
            }
        }
    }

    /// The patterns that pass over repeated rows are the plain products' patterns.
    #[test]
    fn patterns_passing_over_repeated_rows_are_the_plain_ones() {
        let (a, block_ptr) = block_tridiagonal(&[3, 3, 1, 3, 2, 3, 3, 3, 6, 6, 3, 1, 3]);
        let blocks = block_ptr.len() - 1;
        let aggregates: Vec<usize> = (0..blocks).map(|b| b / 3).collect();
        let modes: Vec<f64> = (0..2 * a.n_rows)
            .map(|i| if i < a.n_rows { 1.0 } else { i as f64 })
            .collect();
        let (t, _, _) = tentative(&aggregates, &block_ptr, &modes, 2);
        let rows = |m: &Csr| -> Vec<Vec<u32>> {
            (0..m.n_rows).map(|i| m.col[m.row(i)].to_vec()).collect()
        };
        let plain = |a: &Csr, b: &Csr| -> Vec<Vec<u32>> {
            (0..a.n_rows)
                .map(|i| {
                    let set: std::collections::BTreeSet<u32> = a.col[a.row(i)]
                        .iter()
                        .flat_map(|&c| b.col[b.row(c as usize)].iter().copied())
                        .collect();
                    set.into_iter().collect()
                })
                .collect()
        };
        assert_eq!(rows(&product_pattern(&a, &a)), plain(&a, &a));
        assert_eq!(rows(&product_pattern(&a, &t)), plain(&a, &t));
        let p = smoothed_pattern(&a, &t, &block_ptr);
        let at = plain(&a, &t);
        for (b, w) in block_ptr.windows(2).enumerate() {
            let union: std::collections::BTreeSet<u32> = (w[0]..w[1])
                .flat_map(|i| t.col[t.row(i)].iter().chain(&at[i]).copied())
                .collect();
            for i in w[0]..w[1] {
                assert_eq!(
                    p.col[p.row(i)].to_vec(),
                    union.iter().copied().collect::<Vec<_>>(),
                    "block {b}"
                );
            }
        }
        let r = transpose_pattern(&p);
        assert_eq!(rows(&product_pattern(&r, &a)), plain(&r, &a));
    }

    /// A forward sweep from zero that skips the columns at and after each block's is the full
    /// forward sweep from zero.
    #[test]
    fn a_sweep_from_zero_is_the_full_sweep_from_zero() {
        let (a, block_ptr) = block_tridiagonal(&[3; 40]);
        let n = a.n_rows;
        let mut level = Level::new(a, block_ptr);
        level.invert_diagonal(0).expect("diagonally dominant");
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        for uniform in [true, false] {
            level.uniform_rows = uniform;
            let (mut skipped, mut full, mut start) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            level.sweep(&b, &mut skipped, &mut start, Sweep::ForwardFromZero);
            level.sweep(&b, &mut full, &mut start, Sweep::Forward);
            assert_eq!(skipped, full);
        }
    }
}
