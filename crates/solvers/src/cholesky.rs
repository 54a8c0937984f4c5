//! Sparse Cholesky (LLᵀ) on faer's low-level API: symbolic analysis (AMD ordering) once per sparsity
//! pattern, numeric refactorisation into a reused value buffer, in-place solves of several right-hand
//! sides with caller-owned scratch memory. Nothing is allocated after [`SparseCholesky::analyze`].
//!
//! The same symbolic analysis also serves an LDLᵀ factorisation without pivoting
//! ([`SparseCholesky::factorize_ldlt`]) for matrices that may be indefinite: it reports the inertia
//! (the signs of D, which by Sylvester's law are the signs of the eigenvalues) and fails only on an
//! exactly zero pivot. Without pivoting it is not backward stable for every indefinite matrix; its
//! users (Newton's method) check what they get, e.g. that a step descends.
//!
//! The matrix is given in full symmetric storage (both triangles, as hooke's assembly produces);
//! only its lower triangle is read.
//!
//! A factor is allocated only within [`CholeskyParams::memory_budget`] (docs/solvers.md §2.5): the
//! symbolic analysis, whose memory grows with the matrix, not with the factor, says how many
//! values the factor will hold, and a factor (with its numeric scratch) above the budget is refused
//! with [`CholeskyError::OverBudget`] before its values are allocated, instead of aborting the
//! process when the allocation fails.

use std::sync::Arc;
use std::time::{Duration, Instant};

use dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::{LdltError, LdltRegularization};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw,
    SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::params::{self, ParamError, MAX_THREADS};

pub use crate::multilevel::MemoryBudget;

/// How the factor is organised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FactorKind {
    /// Let faer choose from the flop count per nonzero of the factor (its default rule).
    #[default]
    Auto,
    /// Column by column: fastest solves on small factors.
    Simplicial,
    /// Dense supernodes: much faster numeric factorisation on large factors (measured 6–20× from
    /// cloth-160 up).
    Supernodal,
}

/// The smallest factor (stored values) whose solves [`CholeskyParams::solve_threads`] splits over
/// two threads. Below it the fork costs more than the second thread saves: PD's three-column
/// solve split 2 + 1 is 5.8× slower on cloth-10 (1,406 values), 1.6× on cloth-40 (61,169), even on
/// cloth-80 (371,164), and 1.15× faster on cloth-160 (1.87 M; `examples/pd_solve_variants`).
pub const SPLIT_MIN_FACTOR: usize = 500_000;

/// Settings of [`SparseCholesky`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CholeskyParams {
    /// Simplicial, supernodal or automatic.
    pub kind: FactorKind,
    /// Threads for the numeric factorisation (1: serial). Default 1.
    pub factor_threads: usize,
    /// Threads for the triangular solves: with 2 or more, a solve of several right-hand sides
    /// splits its columns over two threads, each block solved serially (the same bits as one
    /// thread; one column, and a factor of fewer than [`SPLIT_MIN_FACTOR`] stored values, always
    /// on one). Default 1. faer's own parallel solve was
    /// measured slower than the serial one on 2 cores; the split three-column solve of projective
    /// dynamics 1.15× faster on cloth-160 and 1.28× on cloth-320 (`examples/pd_solve_variants`).
    pub solve_threads: usize,
    /// The most memory the factor's values and its numeric scratch may take (bytes, once
    /// resolved: [`MemoryBudget::bytes`]). Default [`MemoryBudget::Machine`], half the machine's
    /// physical memory. Checked after the symbolic analysis, before the factor is allocated.
    pub memory_budget: MemoryBudget,
}

impl Default for CholeskyParams {
    fn default() -> Self {
        CholeskyParams {
            kind: FactorKind::Auto,
            factor_threads: 1,
            solve_threads: 1,
            memory_budget: MemoryBudget::Machine,
        }
    }
}

impl CholeskyParams {
    /// Check the thread counts: each in 1..=[`MAX_THREADS`].
    ///
    /// # Errors
    /// [`ParamError`] naming the field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        for (field, threads) in [
            ("CholeskyParams::factor_threads", self.factor_threads),
            ("CholeskyParams::solve_threads", self.solve_threads),
        ] {
            params::count_in(field, threads, 1, MAX_THREADS, "in 1..=1024")?;
        }
        Ok(())
    }
}

fn par(threads: usize) -> Par {
    if threads <= 1 {
        Par::Seq
    } else {
        Par::rayon(threads)
    }
}

/// Why a factorisation failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CholeskyError {
    /// The matrix is not positive definite: a pivot was not positive.
    #[error("the matrix is not positive definite (non-positive pivot in column {column} of the permuted matrix)")]
    NotPositiveDefinite {
        /// Index of the failing pivot in the fill-reducing order.
        column: usize,
    },
    /// The matrix does not match the analysed pattern: its size, its number of stored entries, or
    /// the row indices stored in a column differ.
    #[error("the matrix ({rows}×{cols}, {nnz} stored entries) does not match the analysed pattern ({n}×{n}, {expected_nnz}){}", column.map_or(String::new(), |c| format!(": the row indices of column {c} differ")))]
    PatternMismatch {
        /// Rows of the given matrix.
        rows: usize,
        /// Columns of the given matrix.
        cols: usize,
        /// Its stored entries.
        nnz: usize,
        /// The analysed size.
        n: usize,
        /// The analysed number of stored entries.
        expected_nnz: usize,
        /// The first column whose row indices differ, if the sizes agree.
        column: Option<usize>,
    },
    /// An LDLᵀ pivot was exactly zero (or not finite): the matrix is singular in the analysed order.
    #[error("the matrix is singular (zero pivot in column {column} of the permuted matrix)")]
    Singular {
        /// Index of the failing pivot in the fill-reducing order.
        column: usize,
    },
    /// The matrix holds NaN or infinite values.
    #[error("the matrix holds non-finite values")]
    NonFinite,
    /// faer could not complete the symbolic analysis (e.g. out of memory, or an index overflow).
    #[error("symbolic analysis failed: {0}")]
    Symbolic(String),
    /// A parameter is out of its range ([`CholeskyParams::validate`]).
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
    /// The factor (its values and the numeric factorisation's scratch) would take more memory
    /// than [`CholeskyParams::memory_budget`] allows; nothing was allocated for it.
    #[error("the sparse Cholesky factor of this {dim}×{dim} matrix needs {} of memory, above the memory budget of {} (raise the budget, or use a solver with a multilevel path: docs/solvers.md §2.5)", crate::multilevel::human_bytes(*needed), crate::multilevel::human_bytes(*budget))]
    OverBudget {
        /// The matrix' dimension.
        dim: usize,
        /// Bytes the factor needs: 8 per stored value plus the numeric scratch.
        needed: u64,
        /// The budget in bytes.
        budget: u64,
    },
    /// The multilevel solve that stands in for a factor over the budget failed (its set-up,
    /// or a problem it cannot serve); docs/solvers.md §2.5.
    #[error("multilevel solve: {0}")]
    Multilevel(String),
}

/// The inertia of a symmetric matrix, read off the pivots of its LDLᵀ factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Inertia {
    /// Positive eigenvalues.
    pub positive: usize,
    /// Negative eigenvalues.
    pub negative: usize,
}

impl Inertia {
    /// True if every eigenvalue is positive.
    pub fn is_positive_definite(&self) -> bool {
        self.negative == 0
    }
}

/// Which factorisation the stored values hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stored {
    None,
    Llt,
    Ldlt,
}

/// A sparse LLᵀ factorisation whose symbolic part is computed once and shared, and whose numeric
/// part is recomputed in place for new values on the same pattern.
pub struct SparseCholesky {
    symbolic: Arc<SymbolicCholesky<usize>>,
    factor: Vec<f64>,
    scratch: MemBuffer,
    /// Scratch of the second thread's column in a split solve (see
    /// [`CholeskyParams::solve_threads`]).
    column_scratch: MemBuffer,
    params: CholeskyParams,
    n: usize,
    /// The analysed pattern, compact CSC.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    factored: Stored,
    analysis_time: Duration,
    factor_time: Duration,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("n", &self.n)
            .field("factor_nnz", &self.factor.len())
            .field("supernodal", &self.is_supernodal())
            .field("params", &self.params)
            .field("factored", &self.factored)
            .finish_non_exhaustive()
    }
}

impl SparseCholesky {
    /// Analyse a symmetric sparsity pattern (full storage, both triangles): fill-reducing AMD ordering
    /// and the symbolic factor. Do this once per pattern; then [`SparseCholesky::factorize`] for each
    /// new set of values.
    ///
    /// # Errors
    /// [`CholeskyError::InvalidParameter`] if `params` does not pass [`CholeskyParams::validate`];
    /// [`CholeskyError::Symbolic`] if faer's analysis fails; [`CholeskyError::OverBudget`] if the
    /// factor would exceed [`CholeskyParams::memory_budget`] (nothing allocated for it).
    ///
    /// # Panics
    /// If the pattern is not square.
    #[track_caller]
    pub fn analyze(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: CholeskyParams,
    ) -> Result<Self, CholeskyError> {
        assert_eq!(
            pattern.nrows(),
            pattern.ncols(),
            "a Cholesky factorisation needs a square matrix"
        );
        let (symbolic, analysis_time) = Self::symbolic_analysis(pattern, params)?;
        Self::with_symbolic(symbolic, pattern, params, analysis_time)
    }

    /// The symbolic analysis of [`SparseCholesky::analyze`] alone (no factor allocated), and its
    /// time.
    pub(crate) fn symbolic_analysis(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: CholeskyParams,
    ) -> Result<(Arc<SymbolicCholesky<usize>>, Duration), CholeskyError> {
        params.validate()?;
        let start = Instant::now();
        let threshold = match params.kind {
            FactorKind::Auto => SupernodalThreshold::AUTO,
            FactorKind::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
            FactorKind::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
        };
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: threshold,
                ..Default::default()
            },
        )
        .map_err(|e| CholeskyError::Symbolic(format!("{e:?}")))?;
        Ok((Arc::new(symbolic), start.elapsed()))
    }

    /// Reuse an existing symbolic analysis (shared, e.g. by several solvers on the same pattern),
    /// made for `pattern`, which every matrix factored later must have.
    ///
    /// # Errors
    /// [`CholeskyError::InvalidParameter`] if `params` does not pass [`CholeskyParams::validate`];
    /// [`CholeskyError::Symbolic`] if the factor or the scratch memory cannot be had;
    /// [`CholeskyError::OverBudget`] (before allocating the factor) if they would exceed
    /// [`CholeskyParams::memory_budget`].
    ///
    /// # Panics
    /// If `pattern` is not of the analysis' size.
    #[track_caller]
    pub fn with_symbolic(
        symbolic: Arc<SymbolicCholesky<usize>>,
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: CholeskyParams,
        analysis_time: Duration,
    ) -> Result<Self, CholeskyError> {
        params.validate()?;
        let n = symbolic.nrows();
        assert!(
            pattern.nrows() == n && pattern.ncols() == n,
            "the pattern is not of the analysis' size"
        );
        // A compact copy of the pattern, so that each factorisation can check it in O(nnz).
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(pattern.compute_nnz());
        col_ptr.push(0);
        for j in 0..n {
            row_idx.extend_from_slice(pattern.row_idx_of_col_raw(j));
            col_ptr.push(row_idx.len());
        }
        let (needed, scratch_req) = Self::memory_needed(&symbolic, params);
        let budget = params.memory_budget.bytes();
        if needed > budget {
            return Err(CholeskyError::OverBudget {
                dim: n,
                needed,
                budget,
            });
        }
        // Fallible, so that a factor within the budget that the machine cannot hold after all is
        // an error, not an abort.
        let mut factor = Vec::new();
        factor
            .try_reserve_exact(symbolic.len_val())
            .map_err(|_| CholeskyError::Symbolic(format!("factor memory: {needed} bytes")))?;
        factor.resize(symbolic.len_val(), 0.0);
        let scratch = MemBuffer::try_new(scratch_req)
            .map_err(|e| CholeskyError::Symbolic(format!("scratch memory: {e:?}")))?;
        let column_scratch = MemBuffer::try_new(if params.solve_threads > 1 {
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq)
        } else {
            StackReq::EMPTY
        })
        .map_err(|e| CholeskyError::Symbolic(format!("scratch memory: {e:?}")))?;
        Ok(SparseCholesky {
            factor,
            symbolic,
            scratch,
            column_scratch,
            params,
            n,
            col_ptr,
            row_idx,
            factored: Stored::None,
            analysis_time,
            factor_time: Duration::ZERO,
        })
    }

    /// The memory a factor of `symbolic` takes with `params` (bytes: 8 per stored value plus the
    /// numeric factorisation's or a three-column solve's scratch, whichever is larger, plus a
    /// split solve's column scratch), which [`CholeskyParams::memory_budget`] bounds, and the
    /// scratch requirement itself. Saturates instead of overflowing.
    pub fn memory_needed(
        symbolic: &SymbolicCholesky<usize>,
        params: CholeskyParams,
    ) -> (u64, StackReq) {
        let factor_req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(
                par(params.factor_threads),
                Default::default(),
            ),
            symbolic.factorize_numeric_ldlt_scratch::<f64>(
                par(params.factor_threads),
                Default::default(),
            ),
        ]);
        // Three right-hand sides (the x, y, z coordinates) is the widest solve hooke makes.
        let solve_req = symbolic.solve_in_place_scratch::<f64>(3, Par::Seq);
        let scratch_req = StackReq::any_of(&[factor_req, solve_req]);
        let column = if params.solve_threads > 1 {
            symbolic
                .solve_in_place_scratch::<f64>(1, Par::Seq)
                .size_bytes()
        } else {
            0
        };
        // An overflowed requirement has no alignment: it is larger than any memory.
        let scratch_bytes = if scratch_req.align_bytes() == 0 {
            u64::MAX
        } else {
            scratch_req.size_bytes() as u64
        };
        let needed = (symbolic.len_val() as u64)
            .saturating_mul(std::mem::size_of::<f64>() as u64)
            .saturating_add(scratch_bytes)
            .saturating_add(column as u64);
        (needed, scratch_req)
    }

    /// The settings it was made with.
    pub fn params(&self) -> &CholeskyParams {
        &self.params
    }

    /// The shared symbolic analysis.
    pub fn symbolic(&self) -> &Arc<SymbolicCholesky<usize>> {
        &self.symbolic
    }

    /// The dimension n.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Stored values of the factor L (its nnz, supernodal blocks counted in full).
    pub fn factor_nnz(&self) -> usize {
        self.factor.len()
    }

    /// True if the factor is supernodal.
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// Wall time of the symbolic analysis.
    pub fn analysis_time(&self) -> Duration {
        self.analysis_time
    }

    /// Wall time of the last numeric factorisation.
    pub fn factor_time(&self) -> Duration {
        self.factor_time
    }

    /// Factor `a` (same pattern as analysed) into the reused buffer.
    ///
    /// # Errors
    /// [`CholeskyError::PatternMismatch`], [`CholeskyError::NonFinite`], or
    /// [`CholeskyError::NotPositiveDefinite`]; after an error the previous factor is invalid and
    /// [`SparseCholesky::solve_in_place`] panics until a factorisation succeeds.
    pub fn factorize(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<(), CholeskyError> {
        self.check(a)?;
        let start = Instant::now();
        let stack = MemStack::new(&mut self.scratch);
        let result = self.symbolic.factorize_numeric_llt::<f64>(
            &mut self.factor,
            a,
            Side::Lower,
            LltRegularization::default(),
            par(self.params.factor_threads),
            stack,
            Default::default(),
        );
        self.factor_time = start.elapsed();
        match result {
            Ok(_) => {
                self.factored = Stored::Llt;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => {
                Err(CholeskyError::NotPositiveDefinite { column: index })
            }
        }
    }

    /// Factor `a` (same pattern as analysed, possibly indefinite) as LDLᵀ without pivoting, in the
    /// fill-reducing order of the analysis, and return its inertia. Solves then use this factor.
    ///
    /// # Errors
    /// [`CholeskyError::PatternMismatch`], [`CholeskyError::NonFinite`], or
    /// [`CholeskyError::Singular`] on a zero pivot; after an error no factor is held.
    pub fn factorize_ldlt(
        &mut self,
        a: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Inertia, CholeskyError> {
        self.check(a)?;
        let start = Instant::now();
        let stack = MemStack::new(&mut self.scratch);
        let result = self.symbolic.factorize_numeric_ldlt::<f64>(
            &mut self.factor,
            a,
            Side::Lower,
            LdltRegularization::default(),
            par(self.params.factor_threads),
            stack,
            Default::default(),
        );
        self.factor_time = start.elapsed();
        match result {
            Ok(_) => {
                let mut inertia = Inertia::default();
                let mut count = |d: f64| {
                    if d > 0.0 {
                        inertia.positive += 1;
                    } else if d < 0.0 {
                        inertia.negative += 1;
                    }
                };
                match self.symbolic.raw() {
                    SymbolicCholeskyRaw::Simplicial(s) => {
                        // Each column of L starts with its diagonal, which holds D.
                        for &start in &s.col_ptr()[..self.n] {
                            count(self.factor[start]);
                        }
                    }
                    SymbolicCholeskyRaw::Supernodal(s) => {
                        // Supernode blocks are column-major, their leading square holds D.
                        for k in 0..s.n_supernodes() {
                            let cols = s.supernode_end()[k] - s.supernode_begin()[k];
                            let rows = cols + s.nnz_per_super()[k];
                            let base = s.col_ptr_for_val()[k];
                            for c in 0..cols {
                                count(self.factor[base + c * rows + c]);
                            }
                        }
                    }
                }
                if inertia.positive + inertia.negative != self.n {
                    return Err(CholeskyError::NonFinite);
                }
                self.factored = Stored::Ldlt;
                Ok(inertia)
            }
            Err(LdltError::ZeroPivot { index }) => Err(CholeskyError::Singular { column: index }),
        }
    }

    /// Check `a` against the analysed pattern and for finite values; forget the previous factor.
    fn check(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<(), CholeskyError> {
        self.factored = Stored::None;
        let nnz = a.compute_nnz();
        let mismatch = |column| CholeskyError::PatternMismatch {
            rows: a.nrows(),
            cols: a.ncols(),
            nnz,
            n: self.n,
            expected_nnz: self.row_idx.len(),
            column,
        };
        if a.nrows() != self.n || a.ncols() != self.n || nnz != self.row_idx.len() {
            return Err(mismatch(None));
        }
        // O(nnz), a few per cent of even the cheapest numeric factorisation.
        if let Some(j) = (0..self.n).find(|&j| {
            a.row_idx_of_col_raw(j) != &self.row_idx[self.col_ptr[j]..self.col_ptr[j + 1]]
        }) {
            return Err(mismatch(Some(j)));
        }
        if (0..self.n).any(|j| a.val_of_col(j).iter().any(|v| !v.is_finite())) {
            return Err(CholeskyError::NonFinite);
        }
        Ok(())
    }

    /// The LLᵀ factor laid out for the split solve of interleaved right-hand sides
    /// ([`crate::forest_solve`]); `None` for a supernodal factor or without an LLᵀ factorisation.
    pub(crate) fn forest_solve<const D: usize>(
        &self,
    ) -> Option<crate::forest_solve::ForestSolve<D>> {
        if self.factored != Stored::Llt {
            return None;
        }
        crate::forest_solve::ForestSolve::new(&self.symbolic, &self.factor)
    }

    /// Whether an LLᵀ factor is held (the last factorisation was [`SparseCholesky::factorize`] and
    /// succeeded).
    pub fn has_llt_factor(&self) -> bool {
        self.factored == Stored::Llt
    }

    /// The stored values of the LLᵀ factor (faer's storage for the analysed pattern), or `None`
    /// without an LLᵀ factorisation.
    pub(crate) fn llt_values(&self) -> Option<&[f64]> {
        (self.factored == Stored::Llt).then_some(&self.factor[..])
    }

    /// Solve A X = B in place for the columns of `rhs` (n × k, k ≤ 3 without allocating; wider
    /// right-hand sides are solved three columns at a time).
    ///
    /// # Panics
    /// If no factorisation has succeeded, or `rhs` does not have n rows.
    #[track_caller]
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        assert!(
            self.factored != Stored::None,
            "solve_in_place needs a successful factorisation first"
        );
        assert_eq!(rhs.nrows(), self.n, "right-hand side rows");
        let split = self.params.solve_threads > 1 && self.factor.len() >= SPLIT_MIN_FACTOR;
        let k = rhs.ncols();
        let mut start = 0;
        while start < k {
            let width = (k - start).min(3);
            let columns = rhs.rb_mut().subcols_mut(start, width);
            let (symbolic, factor, llt) = (
                &*self.symbolic,
                &self.factor[..],
                self.factored == Stored::Llt,
            );
            if split && width > 1 {
                let (left, right) = columns.split_at_col_mut(width - 1);
                let (a, b) = (&mut self.scratch, &mut self.column_scratch);
                rayon::join(
                    || solve_serial(symbolic, factor, llt, left, a),
                    || solve_serial(symbolic, factor, llt, right, b),
                );
            } else {
                solve_serial(symbolic, factor, llt, columns, &mut self.scratch);
            }
            start += width;
        }
    }

    /// Solve A x = b in place for one right-hand side stored in a slice of length n.
    ///
    /// # Panics
    /// As [`SparseCholesky::solve_in_place`].
    #[track_caller]
    pub fn solve_slice(&mut self, b: &mut [f64]) {
        let n = b.len();
        self.solve_in_place(MatMut::from_column_major_slice_mut(b, n, 1));
    }
}

use faer::reborrow::ReborrowMut;

/// Solve in place with the factor `factor` of `symbolic` (LLᵀ if `llt`, else LDLᵀ), on this thread.
fn solve_serial(
    symbolic: &SymbolicCholesky<usize>,
    factor: &[f64],
    llt: bool,
    columns: MatMut<'_, f64>,
    scratch: &mut MemBuffer,
) {
    let stack = MemStack::new(scratch);
    if llt {
        faer::sparse::linalg::cholesky::LltRef::new(symbolic, factor).solve_in_place_with_conj(
            Conj::No,
            columns,
            Par::Seq,
            stack,
        );
    } else {
        faer::sparse::linalg::cholesky::LdltRef::new(symbolic, factor).solve_in_place_with_conj(
            Conj::No,
            columns,
            Par::Seq,
            stack,
        );
    }
}
