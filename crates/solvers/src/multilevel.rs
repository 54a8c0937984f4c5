//! The memory budget of sparse factorisations and Newton's multilevel path (docs/solvers.md §2.5).
//!
//! - [`MemoryBudget`]: how much memory a Cholesky factor may take
//!   ([`crate::CholeskyParams::memory_budget`]); by default half the machine's physical memory. A
//!   factor above it is refused after the symbolic analysis, before its values are allocated
//!   ([`CholeskyError::OverBudget`]).
//! - Newton's linear solver (`LinearSolver`, internal): the sparse Cholesky factor when it fits the
//!   budget and fills less than [`crate::NewtonParams::multilevel_fill`] times the matrix (a
//!   solid's factor fills far more than a cloth's); otherwise the multilevel path
//!   ([`MultilevelSolve`]), where each Newton system is solved by
//!   conjugate gradients preconditioned with one V-cycle of the smoothed-aggregation [`Amg`],
//!   whose hierarchy is built on the first Newton matrix of the pattern and refilled
//!   ([`Amg::refresh`]) for every later one: no symbolic work per matrix, and memory of the order
//!   of the matrix, not of its factor.
//!
//! CG needs a symmetric positive definite matrix, and the exact Hessian of a spring mesh is
//! indefinite where springs are compressed. Newton's "factorisation" on this path is the
//! hierarchy's refill followed by the CG solve of the Newton system H Δ = −∇Φ itself: a direction
//! of non-positive curvature met by CG counts as a failed factorisation
//! ([`CholeskyError::NotPositiveDefinite`]), so that Newton's indefinite policy blends towards the
//! problem's convexified Hessian exactly as on the direct path (docs/solvers.md §3.2; for backward
//! Euler the clamped spring Hessian plus the masses, positive definite). Where the exact Hessian is
//! positive definite Newton keeps its exact steps and their fast convergence. CG may miss the
//! negative curvature of an indefinite matrix; its step is then checked as every step is (it must
//! descend, and the line search must lower Φ). A problem without a convexified Hessian has no
//! multilevel path (no inertia is available to step along an indefinite matrix), and Newton
//! refuses it with the factor's size and the budget ([`CholeskyError::Multilevel`]). CG stops at
//! the relative residual [`MULTILEVEL_TOLERANCE`], or at [`MULTILEVEL_MAX_ITERATIONS`] keeping its
//! last iterate (a CG iterate from 0 on a positive definite system is a descent direction).

use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use crate::amg::{Amg, AmgError, AmgParams};
use crate::cholesky::{CholeskyError, CholeskyParams, Inertia, SparseCholesky};
use crate::newton::NewtonProblem;
use crate::operator::{dot, LinearOperator, Preconditioner};

/// The budget used where the machine's memory cannot be read (no `/proc/meminfo`): 4 GiB, half
/// of a modest 8 GiB machine.
pub const FALLBACK_BUDGET: u64 = 4 << 30;

/// How much memory a sparse Cholesky factor may take: its stored values (8 bytes each) and the
/// numeric factorisation's scratch ([`SparseCholesky::memory_needed`]). The symbolic analysis
/// itself is not counted: it is of the order of the matrix (its ordering and supernode
/// structure), not of the factor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MemoryBudget {
    /// Half the machine's physical memory (`MemTotal` of `/proc/meminfo` on Linux, read once per
    /// process), or [`FALLBACK_BUDGET`] where it cannot be read. The total, not the memory
    /// available at the moment, so that the same scene on the same machine takes the same path
    /// (and the same bits) whatever else runs.
    #[default]
    Machine,
    /// At most this many bytes (`u64::MAX`: no limit).
    Bytes(u64),
}

impl MemoryBudget {
    /// No limit.
    pub const UNLIMITED: MemoryBudget = MemoryBudget::Bytes(u64::MAX);

    /// The budget in bytes.
    pub fn bytes(self) -> u64 {
        match self {
            MemoryBudget::Machine => machine_budget(),
            MemoryBudget::Bytes(bytes) => bytes,
        }
    }

    /// Read a budget as a user writes it: `machine`, `unlimited`, or a size in bytes with an
    /// optional binary unit, `K`, `M`, `G` or `T` (each optionally followed by `iB` or `B`; all
    /// powers of 1024), e.g. `4G`, `512MiB`, `1.5 GiB`, `1000000`. The number must be finite and
    /// ≥ 0; the size is rounded down to whole bytes (saturating at `u64::MAX`).
    ///
    /// # Errors
    /// A message saying what is accepted.
    pub fn parse(text: &str) -> Result<MemoryBudget, String> {
        let t = text.trim();
        match t.to_ascii_lowercase().as_str() {
            "machine" => return Ok(MemoryBudget::Machine),
            "unlimited" => return Ok(MemoryBudget::UNLIMITED),
            _ => {}
        }
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == 'E' || c == '+'))
            .unwrap_or(t.len());
        let (number, unit) = t.split_at(split);
        let unit = unit.trim();
        let scale: f64 = match unit.to_ascii_lowercase().as_str() {
            "" | "b" => 1.0,
            "k" | "kb" | "kib" => 1024.0,
            "m" | "mb" | "mib" => 1024.0 * 1024.0,
            "g" | "gb" | "gib" => 1024.0 * 1024.0 * 1024.0,
            "t" | "tb" | "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
            _ => return Err(budget_syntax(text)),
        };
        let value: f64 = number.parse().map_err(|_| budget_syntax(text))?;
        if !(value.is_finite() && value >= 0.0) {
            return Err(budget_syntax(text));
        }
        // `as` saturates at u64::MAX.
        Ok(MemoryBudget::Bytes((value * scale) as u64))
    }
}

impl std::fmt::Display for MemoryBudget {
    /// `machine`, `unlimited`, or the number of bytes: what [`MemoryBudget::parse`] reads back.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            MemoryBudget::Machine => f.write_str("machine"),
            MemoryBudget::Bytes(u64::MAX) => f.write_str("unlimited"),
            MemoryBudget::Bytes(bytes) => write!(f, "{bytes}"),
        }
    }
}

fn budget_syntax(text: &str) -> String {
    format!(
        "{text:?} is not a memory budget: expected \"machine\", \"unlimited\", or a size in bytes \
         with an optional unit K, M, G or T (powers of 1024), e.g. \"4G\" or \"512MiB\""
    )
}

/// Half of `MemTotal` from `/proc/meminfo`, read once; [`FALLBACK_BUDGET`] where unreadable.
fn machine_budget() -> u64 {
    static BUDGET: OnceLock<u64> = OnceLock::new();
    *BUDGET.get_or_init(|| {
        std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|text| mem_total(&text))
            .map_or(FALLBACK_BUDGET, |total| total / 2)
    })
}

/// `MemTotal` in bytes from the text of `/proc/meminfo` (its line `MemTotal:   24576000 kB`).
fn mem_total(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut words = line["MemTotal:".len()..].split_whitespace();
    let value: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => value.checked_mul(1024),
        None => Some(value),
        Some(_) => None,
    }
}

/// A byte count for messages: `47.6 GiB (51100831080 bytes)`.
pub(crate) fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    if bytes == u64::MAX {
        return "an unlimited amount".to_string();
    }
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {} ({bytes} bytes)", UNITS[unit])
    }
}

/// The relative residual ‖H Δ + ∇Φ‖ / ‖∇Φ‖ at which CG's Δ is taken as the Newton step on the
/// multilevel path: as fine as the held-factor reuse of the direct path accepts
/// ([`crate::FactorReuse::DEFAULT`]), so that the steps, and the step-size test made on them,
/// are those of an exact solve to about six digits.
pub const MULTILEVEL_TOLERANCE: f64 = 1e-6;

/// The most CG iterations per Newton system on the multilevel path; a solve that reaches it
/// keeps its last iterate (still a descent direction) and is counted in
/// [`MultilevelStats::limit_hits`].
pub const MULTILEVEL_MAX_ITERATIONS: usize = 500;

/// What the multilevel path did, summed over its life.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MultilevelStats {
    /// Hierarchies built ([`Amg::new`]): one per pattern, unless a set-up failed.
    pub setups: usize,
    /// Hierarchies refilled for a new matrix ([`Amg::refresh`]).
    pub refreshes: usize,
    /// Newton systems solved by CG.
    pub solves: usize,
    /// CG iterations in all (each one product with the matrix and one V-cycle).
    pub iterations: usize,
    /// Solves stopped by a direction of non-positive curvature (each one a failed
    /// "factorisation": Newton then blends towards the convexified Hessian).
    pub negative_curvature: usize,
    /// Solves stopped by [`MULTILEVEL_MAX_ITERATIONS`].
    pub limit_hits: usize,
    /// Time in set-ups and refills.
    pub setup_time: Duration,
    /// Time in the CG solves.
    pub solve_time: Duration,
}

/// Newton's linear solves on the multilevel path: CG preconditioned with [`Amg`] (see the module
/// documentation), standing in for a Cholesky factor that would exceed the memory budget.
#[derive(Debug)]
pub struct MultilevelSolve {
    dim: usize,
    /// Bytes the Cholesky factor would have needed, and the budget (which it exceeded, unless
    /// the path was taken for the factor's fill).
    needed: u64,
    budget: u64,
    /// The symbolic analysis and its time, kept when the path was taken for the factor's fill
    /// (the factor fits the budget): the direct path for a problem the multilevel path cannot
    /// solve, without analysing the pattern again.
    fallback: Option<(Arc<SymbolicCholesky<usize>>, Duration)>,
    /// Block size and near-nullspace of the hierarchy's set-up (dropped once it is built).
    block: usize,
    near_nullspace: Vec<f64>,
    amg: Option<Amg>,
    /// Whether the hierarchy holds a successfully filled matrix.
    ready: bool,
    r: Vec<f64>,
    z: Vec<f64>,
    d: Vec<f64>,
    q: Vec<f64>,
    x: Vec<f64>,
    /// The right-hand side −∇Φ of the last Newton system solved with the set-up, whose solution
    /// `x` holds when `solved`.
    rhs: Vec<f64>,
    solved: bool,
    last_setup: Duration,
    stats: MultilevelStats,
}

impl MultilevelSolve {
    fn new(dim: usize, needed: u64, budget: u64) -> Self {
        MultilevelSolve {
            dim,
            needed,
            budget,
            fallback: None,
            block: 1,
            near_nullspace: Vec::new(),
            amg: None,
            ready: false,
            r: vec![0.0; dim],
            z: vec![0.0; dim],
            d: vec![0.0; dim],
            q: vec![0.0; dim],
            x: vec![0.0; dim],
            rhs: vec![0.0; dim],
            solved: false,
            last_setup: Duration::ZERO,
            stats: MultilevelStats::default(),
        }
    }

    /// Bytes the Cholesky factor would have needed ([`SparseCholesky::memory_needed`]).
    pub fn factor_bytes(&self) -> u64 {
        self.needed
    }

    /// The memory budget (bytes), which the factor exceeded unless the path was taken for its
    /// fill ([`MultilevelSolve::for_fill`]).
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// Whether the path was taken because the factor would fill more than
    /// [`crate::NewtonParams::multilevel_fill`] times the matrix while it fits the budget,
    /// rather than because it exceeds the budget.
    pub fn for_fill(&self) -> bool {
        self.fallback.is_some()
    }

    /// What it did so far.
    pub fn stats(&self) -> MultilevelStats {
        self.stats
    }

    /// The hierarchy's unknowns per level, finest first (empty before the first Newton matrix).
    pub fn level_sizes(&self) -> Vec<usize> {
        self.amg.as_ref().map_or_else(Vec::new, Amg::level_sizes)
    }

    /// Get ready to solve `problem`'s Newton systems from `x`: check that it has a convexified
    /// Hessian (the only matrices this path solves), and take its near-nullspace for the
    /// hierarchy's set-up if none is built yet.
    ///
    /// # Errors
    /// [`CholeskyError::Multilevel`] naming the factor's size and the budget if the problem has
    /// no convexified Hessian.
    pub(crate) fn prepare(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
    ) -> Result<(), CholeskyError> {
        if !problem.has_convexified_hessian() {
            return Err(CholeskyError::Multilevel(format!(
                "the Cholesky factor of this {n}×{n} Newton matrix needs {}, above the memory \
                 budget of {}, and the problem has no convexified (positive definite) Hessian \
                 for the multilevel path to solve with CG (docs/solvers.md §2.5)",
                human_bytes(self.needed),
                human_bytes(self.budget),
                n = self.dim,
            )));
        }
        if self.amg.is_none() && self.near_nullspace.is_empty() {
            match problem.near_nullspace(x) {
                Some((block, modes)) => {
                    self.block = block;
                    self.near_nullspace = modes;
                }
                None => {
                    self.block = 1;
                    self.near_nullspace = vec![1.0; self.dim];
                }
            }
        }
        Ok(())
    }

    /// Build the hierarchy on `a` (the first matrix) or refill it, then solve the Newton system
    /// a Δ = −`gradient` by CG, its solution kept for [`MultilevelSolve::solve`].
    ///
    /// # Errors
    /// [`CholeskyError::NotPositiveDefinite`] if CG meets a direction of non-positive curvature,
    /// or the set-up a diagonal block that is not positive definite; the set-up's other errors.
    fn factorize(
        &mut self,
        a: SparseColMatRef<'_, usize, f64>,
        gradient: &[f64],
    ) -> Result<(), CholeskyError> {
        self.set_up(a)?;
        for (b, g) in self.rhs.iter_mut().zip(gradient) {
            *b = -g;
        }
        let rhs = std::mem::take(&mut self.rhs);
        let end = self.pcg(&rhs);
        self.rhs = rhs;
        match end {
            CgEnd::NegativeCurvature => {
                self.stats.negative_curvature += 1;
                Err(CholeskyError::NotPositiveDefinite { column: 0 })
            }
            CgEnd::Converged | CgEnd::Limit => {
                self.solved = true;
                Ok(())
            }
        }
    }

    /// Build the hierarchy on `a` (the first matrix) or refill it.
    fn set_up(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<(), CholeskyError> {
        let start = Instant::now();
        self.ready = false;
        self.solved = false;
        let result = match &mut self.amg {
            Some(amg) => {
                self.stats.refreshes += 1;
                amg.refresh(a)
            }
            None => {
                if self.near_nullspace.is_empty() {
                    self.block = 1;
                    self.near_nullspace = vec![1.0; self.dim];
                }
                self.stats.setups += 1;
                Amg::new(a, self.block, &self.near_nullspace, AmgParams::default()).map(|amg| {
                    self.amg = Some(amg);
                    // Kept by the hierarchy's coarse levels; the fine copy is not needed again.
                    self.near_nullspace = Vec::new();
                })
            }
        };
        self.last_setup = start.elapsed();
        self.stats.setup_time += self.last_setup;
        match result {
            Ok(()) => {
                self.ready = true;
                Ok(())
            }
            Err(AmgError::NotPositiveDefinite { block, .. }) => {
                Err(CholeskyError::NotPositiveDefinite { column: block })
            }
            Err(AmgError::NonFinite) => Err(CholeskyError::NonFinite),
            Err(AmgError::Coarse(e)) => Err(e),
            Err(e) => Err(CholeskyError::Multilevel(e.to_string())),
        }
    }

    /// Solve A x = b in place: the solution of the last [`MultilevelSolve::factorize`] if `b` is
    /// its right-hand side (Newton's step), else by CG (truncated at non-positive curvature).
    fn solve(&mut self, b: &mut [f64]) {
        assert!(
            self.ready,
            "the multilevel solve needs a successful set-up first"
        );
        assert_eq!(b.len(), self.dim, "right-hand side length");
        if !(self.solved && b == &self.rhs[..]) {
            self.pcg(b);
        }
        b.copy_from_slice(&self.x);
    }

    /// CG preconditioned with one V-cycle per iteration on the hierarchy's finest matrix, from 0,
    /// to the relative residual [`MULTILEVEL_TOLERANCE`] of `b`; the iterate is left in `self.x`
    /// (at a direction of non-positive curvature: the step so far, or at the first iteration the
    /// preconditioned residual, a descent direction of the quadratic model since the V-cycle is
    /// positive definite).
    fn pcg(&mut self, b: &[f64]) -> CgEnd {
        let start = Instant::now();
        let amg = self.amg.as_mut().expect("ready");
        self.stats.solves += 1;
        self.r.copy_from_slice(b);
        self.x.fill(0.0);
        let target = MULTILEVEL_TOLERANCE * dot(b, b).sqrt();
        let mut end = CgEnd::Converged;
        if target > 0.0 {
            Preconditioner::apply(amg, &self.r, &mut self.z);
            self.d.copy_from_slice(&self.z);
            let mut rz = dot(&self.r, &self.z);
            let mut k = 0;
            loop {
                if k == MULTILEVEL_MAX_ITERATIONS {
                    self.stats.limit_hits += 1;
                    end = CgEnd::Limit;
                    break;
                }
                // The operator is the hierarchy's finest matrix: the matrix just set up.
                LinearOperator::apply(&*amg, &self.d, &mut self.q);
                k += 1;
                let curvature = dot(&self.d, &self.q);
                if !(curvature > 0.0 && curvature.is_finite() && rz > 0.0 && rz.is_finite()) {
                    end = CgEnd::NegativeCurvature;
                    if k == 1 && curvature.is_finite() && rz.is_finite() {
                        self.x.copy_from_slice(&self.d);
                    }
                    break;
                }
                let alpha = rz / curvature;
                for ((x, r), (d, q)) in self
                    .x
                    .iter_mut()
                    .zip(self.r.iter_mut())
                    .zip(self.d.iter().zip(&self.q))
                {
                    *x += alpha * d;
                    *r -= alpha * q;
                }
                if dot(&self.r, &self.r).sqrt() <= target {
                    break;
                }
                Preconditioner::apply(amg, &self.r, &mut self.z);
                let rz_next = dot(&self.r, &self.z);
                let beta = rz_next / rz;
                rz = rz_next;
                for (d, z) in self.d.iter_mut().zip(&self.z) {
                    *d = z + beta * *d;
                }
            }
            self.stats.iterations += k;
        }
        self.stats.solve_time += start.elapsed();
        end
    }
}

/// How a CG solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CgEnd {
    Converged,
    Limit,
    NegativeCurvature,
}

/// Newton's linear solver: the Cholesky factor within the memory budget, the multilevel solve
/// above it (see the module documentation). It offers the calls Newton makes on a factor.
// One per Newton solver; the factor stays inline (the common path), the rare multilevel solve boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub(crate) enum LinearSolver {
    /// A sparse Cholesky factor (LLᵀ or LDLᵀ).
    Direct(SparseCholesky),
    /// CG with the AMG preconditioner.
    Multilevel(Box<MultilevelSolve>),
}

impl LinearSolver {
    /// Analyse `pattern`: a Cholesky factor if it fits `params.memory_budget` and holds at most
    /// `fill_limit` times the pattern's stored entries, the multilevel solve otherwise.
    ///
    /// # Errors
    /// [`SparseCholesky::analyze`]'s errors other than [`CholeskyError::OverBudget`].
    #[track_caller]
    pub(crate) fn analyze(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: CholeskyParams,
        fill_limit: f64,
    ) -> Result<Self, CholeskyError> {
        let (symbolic, analysis_time) = SparseCholesky::symbolic_analysis(pattern, params)?;
        let fill = symbolic.len_val() as f64 / pattern.compute_nnz().max(1) as f64;
        if fill > fill_limit {
            // Decided before the factor is allocated.
            let (needed, _) = SparseCholesky::memory_needed(&symbolic, params);
            let budget = params.memory_budget.bytes();
            let mut multilevel = MultilevelSolve::new(pattern.nrows(), needed, budget);
            if needed <= budget {
                multilevel.fallback = Some((symbolic, analysis_time));
            }
            return Ok(LinearSolver::Multilevel(Box::new(multilevel)));
        }
        match SparseCholesky::with_symbolic(symbolic, pattern, params, analysis_time) {
            Ok(cholesky) => Ok(LinearSolver::Direct(cholesky)),
            Err(CholeskyError::OverBudget {
                dim,
                needed,
                budget,
            }) => Ok(LinearSolver::Multilevel(Box::new(MultilevelSolve::new(
                dim, needed, budget,
            )))),
            Err(e) => Err(e),
        }
    }

    /// On the multilevel path taken for the factor's fill, take the direct path (the factor fits
    /// the budget) with the kept symbolic analysis of `pattern`; otherwise nothing.
    ///
    /// # Errors
    /// [`SparseCholesky::with_symbolic`]'s.
    pub(crate) fn fall_back_to_direct(
        &mut self,
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: CholeskyParams,
    ) -> Result<(), CholeskyError> {
        if let LinearSolver::Multilevel(m) = self {
            if let Some((symbolic, analysis_time)) = m.fallback.take() {
                *self = LinearSolver::Direct(SparseCholesky::with_symbolic(
                    symbolic,
                    pattern,
                    params,
                    analysis_time,
                )?);
            }
        }
        Ok(())
    }

    /// The multilevel solve, if this is one.
    pub(crate) fn multilevel(&self) -> Option<&MultilevelSolve> {
        match self {
            LinearSolver::Multilevel(m) => Some(m),
            LinearSolver::Direct(_) => None,
        }
    }

    /// The multilevel solve, if this is one.
    pub(crate) fn multilevel_mut(&mut self) -> Option<&mut MultilevelSolve> {
        match self {
            LinearSolver::Multilevel(m) => Some(m),
            LinearSolver::Direct(_) => None,
        }
    }

    /// LLᵀ factorisation of `a`, or on the multilevel path the set-up and the CG solve of the
    /// Newton system a Δ = −`gradient` (positive definite matrices only: non-positive curvature
    /// is [`CholeskyError::NotPositiveDefinite`]).
    pub(crate) fn factorize(
        &mut self,
        a: SparseColMatRef<'_, usize, f64>,
        gradient: &[f64],
    ) -> Result<(), CholeskyError> {
        match self {
            LinearSolver::Direct(c) => c.factorize(a),
            LinearSolver::Multilevel(m) => m.factorize(a, gradient),
        }
    }

    /// LDLᵀ with inertia. The multilevel path gives no inertia: Newton never asks it for one
    /// (it replaces the policy that needs it there, see [`crate::Newton::minimize`]).
    pub(crate) fn factorize_ldlt(
        &mut self,
        a: SparseColMatRef<'_, usize, f64>,
    ) -> Result<Inertia, CholeskyError> {
        match self {
            LinearSolver::Direct(c) => c.factorize_ldlt(a),
            LinearSolver::Multilevel(_) => Err(CholeskyError::Multilevel(
                "the multilevel path gives no inertia (LDLᵀ)".to_string(),
            )),
        }
    }

    /// Wall time of the last factorisation or multilevel set-up (without its CG solve).
    pub(crate) fn factor_time(&self) -> Duration {
        match self {
            LinearSolver::Direct(c) => c.factor_time(),
            LinearSolver::Multilevel(m) => m.last_setup,
        }
    }

    /// Whether an LLᵀ factor is held (never on the multilevel path: no held-factor reuse there).
    pub(crate) fn has_llt_factor(&self) -> bool {
        match self {
            LinearSolver::Direct(c) => c.has_llt_factor(),
            LinearSolver::Multilevel(_) => false,
        }
    }

    /// Solve A x = b in place with the factor, or by the multilevel CG.
    #[track_caller]
    pub(crate) fn solve_slice(&mut self, b: &mut [f64]) {
        match self {
            LinearSolver::Direct(c) => c.solve_slice(b),
            LinearSolver::Multilevel(m) => m.solve(b),
        }
    }
}

impl Preconditioner for LinearSolver {
    #[track_caller]
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        match self {
            LinearSolver::Direct(c) => Preconditioner::apply(c, r, z),
            LinearSolver::Multilevel(m) => {
                let amg = m.amg.as_mut().expect("a multilevel set-up first");
                Preconditioner::apply(amg, r, z)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_parse_with_binary_units() {
        let cases = [
            ("machine", MemoryBudget::Machine),
            ("Unlimited", MemoryBudget::UNLIMITED),
            ("1000", MemoryBudget::Bytes(1000)),
            ("4G", MemoryBudget::Bytes(4 << 30)),
            ("4 GiB", MemoryBudget::Bytes(4 << 30)),
            ("512MiB", MemoryBudget::Bytes(512 << 20)),
            ("1.5g", MemoryBudget::Bytes(3 << 29)),
            ("2k", MemoryBudget::Bytes(2048)),
            ("0", MemoryBudget::Bytes(0)),
            ("1e30T", MemoryBudget::UNLIMITED),
        ];
        for (text, budget) in cases {
            assert_eq!(MemoryBudget::parse(text), Ok(budget), "{text}");
        }
        for text in ["", "G", "-1G", "4X", "NaN", "inf", "4 G B"] {
            let err = MemoryBudget::parse(text).unwrap_err();
            assert!(err.contains("not a memory budget"), "{text}: {err}");
        }
        // Display reads back.
        for budget in [
            MemoryBudget::Machine,
            MemoryBudget::UNLIMITED,
            MemoryBudget::Bytes(12345),
        ] {
            assert_eq!(MemoryBudget::parse(&budget.to_string()), Ok(budget));
        }
    }

    #[test]
    fn mem_total_is_read_in_bytes() {
        let text = "MemTotal:       24576000 kB\nMemFree:         1000 kB\n";
        assert_eq!(mem_total(text), Some(24_576_000 * 1024));
        assert_eq!(mem_total("MemFree: 1 kB\n"), None);
        assert_eq!(mem_total("MemTotal: x kB\n"), None);
        // The machine's budget is half of something positive.
        assert!(MemoryBudget::Machine.bytes() > 0);
    }

    #[test]
    fn byte_counts_read_as_people_write_them() {
        assert_eq!(human_bytes(512), "512 bytes");
        assert_eq!(human_bytes(51_100_831_080), "47.6 GiB (51100831080 bytes)");
        assert_eq!(human_bytes(u64::MAX), "an unlimited amount");
    }
}
