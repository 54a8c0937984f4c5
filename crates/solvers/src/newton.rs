//! Newton's method for minimising a smooth objective Φ whose Hessian has a fixed sparsity pattern
//! (backward Euler: Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x), docs/model.md §6.4-§6.5).
//!
//! Each iteration factors the Newton matrix (faer, symbolic analysis done once in
//! [`Newton::new`]) and takes a backtracking (Armijo) line search along −H⁻¹∇Φ: as LLᵀ, which says
//! whether it is positive definite, or, under [`IndefinitePolicy::NewtonIfDescent`], which steps
//! along indefinite matrices, as LDLᵀ, which gives its inertia. The exact Hessian of a spring mesh
//! is indefinite where springs are compressed; what happens then is the [`IndefinitePolicy`]:
//! - [`IndefinitePolicy::ConvexBlend`] (the default): factor (1 − β) H + β H₊, H₊ the problem's
//!   convexified Hessian (for backward Euler the clamped one, H₊ ≥ M), which damps only the
//!   non-convex terms. β starts at 0 in every solve; after an indefinite factorisation the smallest
//!   definite weight on the ladder 1e-4 · 3ᵏ ([`NewtonParams::initial_shift`],
//!   [`NewtonParams::blend_factor`]) is found by trying the next step, then β = 1, then bisecting
//!   (definiteness only grows with β); a full step lowers β one step, a step shorter than ¼
//!   raises it one, so the last iterations are exact Newton steps;
//! - [`IndefinitePolicy::NewtonIfDescent`]: take the indefinite matrix's step when it descends,
//!   shift otherwise (converges to a stationary point of Φ);
//! - [`IndefinitePolicy::Shift`]: H + μD (D the masses), μ raised tenfold until positive definite;
//! - [`IndefinitePolicy::Projected`]: factor the problem's [`NewtonProblem::definite_hessian`],
//!   made positive definite term by term before the factorisation, so that each iteration factors
//!   once. For backward Euler this is the mass-split projection (docs/solvers.md §3.2): a share θ
//!   of every vertex's mass is split among the compressed springs at it in proportion to their
//!   negative curvature, each spring keeps its exact block where its share holds it and has its
//!   negative eigenvalue weighted down to what the share holds where it does not, and the mass
//!   left over, (1 − θ) M, is the margin of definiteness. Exact Newton wherever the masses hold
//!   the compression, without a failed factorisation; a fallback shift (counted) only if rounding
//!   defeats the proof. The masses hold little on cloth, so it converges linearly there;
//! - [`IndefinitePolicy::ProjectedThenExact`]: the same, with the exact Hessian after full steps
//!   (a failed try counted, then a doubling pause). Both are options, not the default: measured
//!   slower than the blend on cloth-160 and most hard cases (`benches/results/newton-definite.md`).
//!
//! With the defaults ([`NewtonParams::default`]) a solve is: from x⁰, up to 100 iterations, each
//! one LLᵀ factorisation of the convex blend above (β = 0, the exact Hessian, whenever it is
//! positive definite), the step −H⁻¹∇Φ shortened by halving (up to 40 times) until Φ falls by at
//! least 1e-4 of what the linear model predicts (Armijo), until a step's size is at most
//! [`DEFAULT_STEP_TOLERANCE`] ([`Convergence::StepSize`]; for backward Euler 1e-5 m/s). These
//! defaults were chosen on a table of scenes (cloth-10 to cloth-160, beam-4, beam-8
//! and the eight hard cases; `benches/results/issue15-newton-default.md`), on
//! which this plain Newton is as fast as or faster than every variant tried except on the crushed
//! cloth. One addition, chosen on the same table with the contact scenes
//! (`benches/results/bunny-drop-speed.md`): before factoring, a system is tried by up to 4
//! iterations of CG preconditioned with the factor held from an earlier matrix, to a relative
//! residual of 1e-6 ([`FactorReuse`]); where the matrix has hardly changed (free fall, rest, the
//! last iterations of a solve) this replaces the factorisation: half the time of a dropped solid,
//! the same answers, and no change on cloth.
//!
//! Opt-in, after every accepted step the problem may relax the iterate ([`NewtonProblem::relax`],
//! [`Relaxation::BUCKLING`]): for backward Euler, Gauss–Seidel sweeps of per-vertex Newton
//! steps, focused sweeps over the hottest vertices, and a nonlinear elimination that solves the
//! patches of a fixed cover holding a fold; skipped after an exact full step whose decrease of Φ
//! its quadratic model predicted within 2 % ([`Relaxation::trusted_model`]). It pays on crushed
//! and buckling cloth, where the error sits in a few folds, and costs more than it saves
//! elsewhere.
//!
//! The line search compares Φ(x + αΔ) − Φ(x) computed by [`NewtonProblem::objective_change`],
//! which problems implement without the cancellation of subtracting two values of Φ.
//!
//! # Stops
//! A solve converged if and only if it stops with [`StopReason::Converged`]
//! ([`StopReason::is_converged`]): its criterion ([`NewtonParams::convergence`]) holds.
//! - [`Convergence::StepSize`] (the default): a Newton step Δ of a matrix without the mass shift
//!   has [`NewtonProblem::step_size`] ≤ `tolerance` (the step is taken if the line search accepts
//!   it), or the gradient is exactly zero. Its quantity is in the problem's unit (backward Euler:
//!   m/s) and does not vanish with the gradient's scale.
//! - [`Convergence::RelativeGradient`]: ‖∇Φ‖ ≤ `tolerance` · ‖∇Φ(x⁰)‖.
//!
//! Every other stop is not converged: a line search that finds no decrease along a descent
//! direction while the gradient is at its proven rounding floor,
//! ‖∇Φ‖ ≤ [`NewtonProblem::gradient_round_off`], is [`StopReason::RoundOff`] (the criterion asked
//! for is below what the arithmetic resolves); a shortened step that lowers Φ by no more than its
//! round-off is [`StopReason::RoundOff`] at that floor and [`StopReason::Stagnated`] above it; the
//! iteration limit is [`StopReason::IterationLimit`]; a non-finite Φ or gradient
//! [`NewtonError::NonFinite`] with [`StopReason::NonFinite`] in its report.
//! [`NewtonReport::residual`] is the criterion's own quantity, so the flag and the number agree.
//!
//! Every line search starts at the longest step the problem allows
//! ([`NewtonProblem::max_step_length`]), so that an iterate never crosses a contact barrier.
//!
//! # Parameters
//! [`NewtonParams::validate`] checks every field (and the nested [`Relaxation`] and
//! [`CholeskyParams`]); [`Newton::new`] and [`Newton::minimize`] refuse invalid settings with
//! [`NewtonError::InvalidParameter`]. The report's history grows as iterations go (it reserves a
//! fixed number of records, not the iteration limit).
//!
//! The crushed-to-1 % start of the hard cases (docs/scenes.md §6) stays hard for every policy
//! (every local model is valid in a tiny region); the simulation halves such steps (`hooke-sim`'s
//! backward Euler).

use std::time::{Duration, Instant};

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use crate::cg::{CgParams, ConjugateGradient};
use crate::cholesky::{CholeskyError, CholeskyParams, Inertia};
use crate::multilevel::{LinearSolver, MultilevelSolve};
use crate::operator::{dot, Symmetric};
use crate::params::{self, ParamError, HISTORY_RESERVE};
use crate::report::{Report, StopReason};

/// The most steps of the shift (or blend weight) ladder from [`NewtonParams::initial_shift`] to
/// [`NewtonParams::max_shift`]: the defaults take 16 (shift) and 34 (blend); a factor so close to 1
/// that the ladder would be longer is refused, since every step may cost a factorisation.
pub const MAX_SHIFT_STEPS: f64 = 200.0;

/// The largest count accepted for the relaxation's sweeps and iteration limits (each unit may
/// cost a pass over the mesh): far above any useful setting, low enough that a typo does not hang.
pub const MAX_RELAXATION_COUNT: usize = 10_000;

/// The largest number of rings of neighbours accepted by [`Relaxation`].
pub const MAX_RINGS: usize = 1_000;

/// The largest number of covers accepted by [`Relaxation::patch_covers`].
pub const MAX_PATCH_COVERS: usize = 16;

/// The most step halvings of the line search: 2⁻¹⁰⁷⁴ is the smallest positive double, so more
/// would only try α = 0 again.
pub const MAX_LINE_SEARCH_HALVINGS: usize = 1074;

/// A line-searched step that lowers Φ by at most this many units of round-off (ε|Φ|) counts as no
/// progress: the iterate is at the resolution floor of Φ and its gradient.
const STAGNATION_ULPS: f64 = 8.0;

/// The objective Newton minimises. The Hessian's pattern is fixed: [`NewtonProblem::hessian`]
/// refills the values of [`NewtonProblem::pattern`] and returns the matrix (full symmetric storage).
pub trait NewtonProblem {
    /// Number of unknowns.
    fn dim(&self) -> usize;
    /// Φ(x).
    fn objective(&mut self, x: &[f64]) -> f64;
    /// Φ(trial) − Φ(x). Override it to compute the difference without subtracting two rounded values
    /// of Φ (e.g. term by term, with |a|−|b| written as (a−b)·(a+b)/(|a|+|b|)): the line search then
    /// resolves decreases far below ε·|Φ|, which it needs for tight tolerances.
    fn objective_change(&mut self, x: &[f64], trial: &[f64]) -> f64 {
        self.objective(trial) - self.objective(x)
    }
    /// g = ∇Φ(x).
    fn gradient(&mut self, x: &[f64], g: &mut [f64]);
    /// The size of the rounding error of [`NewtonProblem::gradient`] at x, in the gradient's norm: a
    /// gradient this small is noise, and a line search along a direction made from it may find no
    /// decrease. Newton then reports [`StopReason::Stagnated`] instead of an error. Default 0 (no
    /// estimate: every failed line search is an error).
    fn gradient_round_off(&mut self, _x: &[f64]) -> f64 {
        0.0
    }
    /// The size of a step Δ of the unknowns in the problem's own unit, which
    /// [`Convergence::StepSize`] compares with the tolerance. Backward Euler: the largest vertex
    /// displacement |Δ_v| divided by h (m/s). Default: the largest |Δ_i|, in the unknowns' unit.
    fn step_size(&self, step: &[f64]) -> f64 {
        step.iter().fold(0.0, |m: f64, s| m.max(s.abs()))
    }
    /// The longest step length α ∈ (0, 1] along `step` from `x` that the problem allows: every
    /// line search starts there. A problem whose Φ is +∞ beyond a surface (backward Euler with
    /// contact barriers) returns a share of the first α at which a vertex would reach an
    /// obstacle, so that no trial point crosses one. Default 1.
    fn max_step_length(&mut self, _x: &[f64], _step: &[f64]) -> f64 {
        1.0
    }
    /// The Hessian's sparsity pattern (every diagonal entry must be stored). It changes only in
    /// [`NewtonProblem::update_pattern`].
    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize>;
    /// Make [`NewtonProblem::pattern`] hold every entry of the Hessians at x (those of terms that
    /// couple unknowns only where they are close, such as self-contact pairs), growing it where it
    /// does not, and say whether it changed: Newton then analyses the new pattern (one symbolic
    /// analysis per pattern) and forgets its held factor. Called before every Hessian. The default
    /// keeps the pattern and returns `false`.
    fn update_pattern(&mut self, _x: &[f64]) -> bool {
        false
    }
    /// Refill the Hessian's values at x and return it.
    fn hessian(&mut self, x: &[f64]) -> SparseColMatRef<'_, usize, f64>;
    /// The positive diagonal D of the shift H + μ D, one entry per unknown (the masses for backward
    /// Euler, which makes μ dimensionless: μ = 1 doubles the inertia).
    fn shift_diagonal(&self) -> &[f64];
    /// Whether [`NewtonProblem::convexified_hessian`] gives a matrix. Default `false`.
    fn has_convexified_hessian(&self) -> bool {
        false
    }
    /// A convexified Hessian at x in the same pattern: positive definite wherever Φ's convex part
    /// makes it so (for backward Euler the clamped spring Hessian plus the masses), and equal to the
    /// Hessian where Φ is convex. [`IndefinitePolicy::ConvexBlend`] factors blends of the two;
    /// problems without one (the default, `None`) are solved as under
    /// [`IndefinitePolicy::NewtonIfDescent`].
    fn convexified_hessian(&mut self, _x: &[f64]) -> Option<SparseColMatRef<'_, usize, f64>> {
        None
    }
    /// The block size of the unknowns and a near-nullspace of the Hessian (column-major, dim × k,
    /// 1 ≤ k ≤ [`crate::AMG_MAX_BLOCK`]), for the multilevel path's AMG set-up (docs/solvers.md
    /// §2.5); backward Euler in 3D: 3 and the rigid-body modes at x. Default `None`: scalar
    /// blocks and the constant vector.
    fn near_nullspace(&self, _x: &[f64]) -> Option<(usize, Vec<f64>)> {
        None
    }
    /// Whether [`NewtonProblem::definite_hessian`] gives a matrix. Default `false`.
    fn has_definite_hessian(&self) -> bool {
        false
    }
    /// The Hessian at x in the same pattern made positive definite term by term, before any
    /// factorisation: each term's exact Hessian where it keeps the sum definite, a projection of
    /// it where it may not (for backward Euler the mass-split projection of the compressed
    /// springs, docs/solvers.md §3.2). [`IndefinitePolicy::Projected`] factors it; problems
    /// without one (the default, `None`) are solved as under [`IndefinitePolicy::ConvexBlend`].
    fn definite_hessian(&mut self, _x: &[f64]) -> Option<SparseColMatRef<'_, usize, f64>> {
        None
    }
    /// Lower Φ from `x`, in place, by the nonlinear relaxation `relaxation` describes (block
    /// coordinate descent that never raises Φ), and say how much was done. The default does
    /// nothing and returns `None`.
    fn relax(&mut self, _x: &mut [f64], _relaxation: Relaxation) -> Option<RelaxationWork> {
        None
    }
    /// Called after every accepted step that does not end the solve (after the relaxation, before Φ
    /// and its gradient at the new iterate `x`): the problem may change its own parameters there,
    /// as backward Euler's adaptive barrier stiffness does. Returns whether Φ changed; the solvers
    /// then judge progress on the new Φ only. The default changes nothing and returns `false`.
    fn after_iterate(&mut self, _x: &[f64]) -> bool {
        false
    }
    /// Get ready to [`NewtonProblem::relax`] with `relaxation`: build once what it needs (for
    /// backward Euler, the elimination's patches and their symbolic analyses), so that relaxing
    /// allocates nothing. [`Newton::minimize`] calls it before its first iteration. The default
    /// does nothing.
    fn prepare_relaxation(&mut self, _relaxation: Relaxation) {}
}

/// Nonlinear relaxation between Newton steps ([`NewtonProblem::relax`]): Gauss–Seidel sweeps of block
/// coordinate descent, each block (a vertex, for backward Euler) moved by line-searched Newton steps
/// on Φ with the rest held fixed. It removes the local, high-frequency part of the error that the
/// quadratic model of the whole problem cannot follow far (buckling cloth), so that the Newton steps
/// are left with the smooth part.
///
/// After the sweeps over all blocks come focused sweeps: the share [`Relaxation::focus_share`] of
/// the blocks with the largest gradients, with [`Relaxation::focus_rings`] rings of neighbours,
/// is swept again, up to [`Relaxation::focus_sweeps`] times and until none of those blocks has a
/// gradient larger than the largest one left outside the selection. Where a buckling step stalls,
/// the gradient sits in a few folds (on cloth-160's speed-vs-error step, 100 of 25,600 vertices
/// carry 40–95 % of ‖∇Φ‖² for most of the solve); a uniform sweep spends almost all its work
/// elsewhere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relaxation {
    /// Sweeps over all blocks after every accepted Newton step (0: none). Default 10.
    pub sweeps: usize,
    /// Newton steps per block and sweep (each stops early once the block no longer moves).
    /// Default 3.
    pub block_iterations: usize,
    /// The share of the blocks, those with the largest gradient norms, that the focused sweeps
    /// start from, finite and ≥ 0 (rounded up to a whole block; 0: no focused sweeps; above 1 the
    /// same as 1). Default 1/256 (100 of
    /// cloth-160's 25,598 free vertices, 7 of cloth-40's 1,598).
    pub focus_share: f64,
    /// Rings of neighbouring blocks added around the selected ones. Default 2.
    pub focus_rings: usize,
    /// The most focused sweeps after every accepted Newton step (0: none). Default 50.
    pub focus_sweeps: usize,
    /// Skip the relaxation after a Newton step of the exact Hessian (no blend or shift) taken in
    /// full whose decrease of Φ agrees with its quadratic model's, ½ gᵀΔ, within this relative
    /// tolerance: the model is trusted there, and Newton converges quadratically without help
    /// (0: never skip). Default 0.02. A solid that does not buckle (beam-4) then never relaxes.
    pub trusted_model: f64,
    /// Nonlinear elimination after the sweeps: the share of the blocks with the largest
    /// gradients, finite and ≥ 0 (rounded up to a whole block; 0: none; above 1 the same as 1),
    /// selects patches
    /// of a fixed cover of the blocks, and each selected patch is solved as one problem,
    /// everything else held, by an inner [`Newton`] with the relaxation [`Relaxation::inner`] (no
    /// elimination of its own). A fold is a collective mode of many vertices that single-vertex
    /// sweeps move only slowly; solving its patches removes it, and the outer Newton steps are
    /// left with the smooth part. The patches are cells of [`Relaxation::patch_share`] of the
    /// blocks with [`Relaxation::region_rings`] rings of neighbours, built with their symbolic
    /// factorisations once per problem ([`NewtonProblem::prepare_relaxation`]), so an elimination
    /// allocates nothing. Default 1/64 (400 of cloth-160's 25,598 free vertices).
    pub region_share: f64,
    /// The size of the cover's cells, as a share of the blocks, finite and ≥ 0 (rounded up to a
    /// whole block; 0 or above 1: one cell of all blocks). Each patch keeps its own problem and
    /// factorisation, so the memory grows with the patches' total size, overlaps included (about
    /// twice the mesh's with the defaults on cloth-160). Default 1/32 (800 of cloth-160's free vertices, about 1,500 with their
    /// rings).
    pub patch_share: f64,
    /// How many covers of cells the patches come from: the seeds of each next cover are the
    /// points farthest from those of the covers before (the corners of their cells), so that a
    /// fold at a corner of one cover's cells lies inside a cell of another. Each block is in one
    /// cell of every cover. Default 2.
    pub patch_covers: usize,
    /// Rings of neighbouring blocks added around each cell to make its patch (its overlap with
    /// the neighbouring patches). Default 3.
    pub region_rings: usize,
    /// The patches are solved, the one whose cell holds the most of the selected blocks' ‖∇Φ‖²
    /// that no solved patch holds first, until the cells' heat counted at each choice reaches
    /// this share of it. Default 0.7.
    pub region_coverage: f64,
    /// Eliminate only where the error is concentrated: when the selected blocks carry at least
    /// this share of ‖∇Φ‖². Default 0.5. Measured: on cloth-160's buckling
    /// step they carry 55–98 %, the fold the elimination is for; on cloth-40 stiff (k = 1e5 N/m)
    /// at h = 1/5 s 11–57 %, mostly below 40 %, where the error is spread over the sheet and the
    /// region solves cost 4× the rest of the solve without saving iterations.
    pub region_concentration: f64,
    /// The inner Newton's tolerance on a patch's gradient, relative to the patch's gradient at the
    /// start of its solve. Default 1e-6.
    pub region_tolerance: f64,
    /// The inner Newton's iteration limit. Default 30.
    pub region_iterations: usize,
    /// Sweeps over a patch's blocks in the inner Newton's own relaxation (its other settings
    /// are these). Default 10.
    pub region_sweeps: usize,
}

impl Default for Relaxation {
    /// [`Relaxation::NONE`]: Newton's default is plain Newton (see [`Relaxation::BUCKLING`] for the
    /// preset, and the module documentation for why it is not the default).
    fn default() -> Self {
        Relaxation::NONE
    }
}

impl Relaxation {
    /// The relaxation stack tuned for buckling cloth (every field's documentation gives its value
    /// here): sweeps, focused sweeps and the nonlinear elimination over patches. Opt-in: it pays
    /// where a step's error sits in a fold of a crushed or buckling sheet (the hard cases' crushed
    /// cloth-40 at 3 frames: 5.4 s against 24.7 s for plain Newton, release build; a cloth-160 run
    /// of 11 frames: 168 s against 337 s), and costs more than it saves elsewhere (cloth-80's
    /// speed-vs-error step 1.30 s against 0.77 s, a cloth-20 run 1.6× and a cloth-80 run 1.1×
    /// slower; beams and the other seven hard cases are as fast or faster without it). Its patches
    /// are built the first time the elimination runs, not before.
    pub const BUCKLING: Relaxation = Relaxation {
        sweeps: 10,
        block_iterations: 3,
        focus_share: 1.0 / 256.0,
        focus_rings: 2,
        focus_sweeps: 50,
        trusted_model: 0.02,
        region_share: 1.0 / 64.0,
        patch_share: 1.0 / 32.0,
        patch_covers: 2,
        region_rings: 3,
        region_coverage: 0.7,
        region_concentration: 0.5,
        region_tolerance: 1e-6,
        region_iterations: 30,
        region_sweeps: 10,
    };
}

impl Relaxation {
    /// Check every field against its allowed range (stated in [`ParamError`]'s message): the
    /// shares, the coverage, the concentration and the tolerances finite and ≥ 0 (a share above 1
    /// counts as 1, a concentration above 1 never eliminates); the
    /// counts at most [`MAX_RELAXATION_COUNT`], the rings at most [`MAX_RINGS`], the covers at
    /// most [`MAX_PATCH_COVERS`] (and at least 1 when the elimination is on); with the elimination
    /// on, the inner solves' settings ([`Relaxation::inner_params`]) too.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        // Shares above 1 mean all of them, a concentration above 1 never eliminating.
        let unit = |field, value: f64| params::non_negative(field, value);
        let count =
            |field, value| params::count_in(field, value, 0, MAX_RELAXATION_COUNT, "at most 10000");
        let rings = |field, value| params::count_in(field, value, 0, MAX_RINGS, "at most 1000");
        count("Relaxation::sweeps", self.sweeps)?;
        count("Relaxation::block_iterations", self.block_iterations)?;
        unit("Relaxation::focus_share", self.focus_share)?;
        rings("Relaxation::focus_rings", self.focus_rings)?;
        count("Relaxation::focus_sweeps", self.focus_sweeps)?;
        params::non_negative("Relaxation::trusted_model", self.trusted_model)?;
        unit("Relaxation::region_share", self.region_share)?;
        unit("Relaxation::patch_share", self.patch_share)?;
        let covers_min = usize::from(self.region_blocks(1) > 0);
        params::count_in(
            "Relaxation::patch_covers",
            self.patch_covers,
            covers_min,
            MAX_PATCH_COVERS,
            if covers_min == 1 {
                "in 1..=16 when the elimination is on"
            } else {
                "at most 16"
            },
        )?;
        rings("Relaxation::region_rings", self.region_rings)?;
        unit("Relaxation::region_coverage", self.region_coverage)?;
        unit(
            "Relaxation::region_concentration",
            self.region_concentration,
        )?;
        params::non_negative("Relaxation::region_tolerance", self.region_tolerance)?;
        count("Relaxation::region_iterations", self.region_iterations)?;
        count("Relaxation::region_sweeps", self.region_sweeps)?;
        if self.region_blocks(1) > 0 {
            // The elimination's inner solves are set up from these fields: checked here, where the
            // relaxation enters, so that no patch solve is refused for its settings mid-step.
            self.inner_params().validate()?;
        }
        Ok(())
    }

    /// The settings of the elimination's inner [`Newton`] on a patch: tolerance
    /// [`Relaxation::region_tolerance`] (a solve raises it to the patch's round-off floor, never
    /// lowers it), [`Relaxation::region_iterations`] iterations, the relaxation
    /// [`Relaxation::inner`], no factor reuse, and the defaults otherwise. Valid whenever this relaxation is, with
    /// the elimination on ([`Relaxation::validate`] checks them).
    pub fn inner_params(&self) -> NewtonParams {
        NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: self.region_tolerance,
            max_iterations: self.region_iterations,
            relaxation: self.inner(),
            // A patch's factor is small: a factorisation costs about what a CG iteration does.
            factor_reuse: FactorReuse::OFF,
            ..NewtonParams::default()
        }
    }

    /// No relaxation: plain Newton.
    pub const NONE: Relaxation = Relaxation {
        sweeps: 0,
        block_iterations: 0,
        focus_share: 0.0,
        focus_rings: 0,
        focus_sweeps: 0,
        trusted_model: 0.0,
        region_share: 0.0,
        patch_share: 0.0,
        patch_covers: 0,
        region_rings: 0,
        region_coverage: 0.0,
        region_concentration: 0.0,
        region_tolerance: 0.0,
        region_iterations: 0,
        region_sweeps: 0,
    };

    /// Whether this relaxes at all.
    pub fn is_none(&self) -> bool {
        (self.block_iterations == 0 || (self.sweeps == 0 && self.focused_blocks(1) == 0))
            && self.region_blocks(1) == 0
    }

    /// How many of `blocks` blocks the nonlinear elimination selects (the hottest ones):
    /// ⌈share · blocks⌉, at most `blocks`, and 0 if there is no elimination.
    pub fn region_blocks(&self, blocks: usize) -> usize {
        share_of(self.region_share, self.region_iterations > 0, blocks)
    }

    /// This relaxation without the nonlinear elimination.
    pub fn without_region(self) -> Relaxation {
        Relaxation {
            region_share: 0.0,
            ..self
        }
    }

    /// The relaxation an inner solve of the elimination uses: this one with
    /// [`Relaxation::region_sweeps`] sweeps and without an elimination.
    pub fn inner(self) -> Relaxation {
        Relaxation {
            sweeps: self.region_sweeps,
            ..self.without_region()
        }
    }

    /// How many of `blocks` blocks a cell of the elimination's cover holds: ⌈share · blocks⌉, at
    /// most `blocks` (0 for a share that is not positive, which means one cell of all of them).
    pub fn patch_blocks(&self, blocks: usize) -> usize {
        share_of(self.patch_share, true, blocks)
    }

    /// How many of `blocks` blocks the focused sweeps select: ⌈share · blocks⌉, at most `blocks`,
    /// and 0 if there are no focused sweeps.
    pub fn focused_blocks(&self, blocks: usize) -> usize {
        share_of(self.focus_share, self.focus_sweeps > 0, blocks)
    }
}

/// ⌈share · blocks⌉ blocks, at most `blocks`; 0 if not `enabled` or the share is not positive
/// (NaN included).
fn share_of(share: f64, enabled: bool, blocks: usize) -> usize {
    if !enabled || share.is_nan() || share <= 0.0 {
        return 0;
    }
    ((share.min(1.0) * blocks as f64).ceil() as usize).min(blocks)
}

/// What one call of [`NewtonProblem::relax`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RelaxationWork {
    /// Sweeps over all blocks.
    pub sweeps: usize,
    /// Focused sweeps ([`Relaxation::focus_share`]).
    pub focused_sweeps: usize,
    /// Block visits in all (each one up to [`Relaxation::block_iterations`] Newton steps): the
    /// work, in units of one block's relaxation.
    pub block_visits: usize,
    /// Patches solved by the nonlinear elimination ([`Relaxation::region_share`]).
    pub region_solves: usize,
    /// Eliminations skipped because the error was not concentrated
    /// ([`Relaxation::region_concentration`]), and patches selected but not solved because their
    /// gradient was round-off.
    pub skipped_regions: usize,
    /// Patches selected but not solved because the inner solves' settings
    /// ([`Relaxation::inner_params`]) were refused. Always 0 under [`Newton`], which validates the
    /// relaxation before it relaxes; only a direct [`NewtonProblem::relax`] call with settings
    /// that fail [`Relaxation::validate`] can meet it.
    pub refused_regions: usize,
    /// Blocks in the patches solved (with their rings), summed over the patches.
    pub region_blocks: usize,
    /// The inner Newton's iterations.
    pub region_iterations: usize,
    /// The inner Newton's numeric factorisations.
    pub region_factorizations: usize,
}

/// Settings of [`Newton`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// What `tolerance` bounds. Default [`Convergence::StepSize`].
    pub convergence: Convergence,
    /// The tolerance of [`NewtonParams::convergence`], in its unit: for [`Convergence::StepSize`]
    /// the problem's step measure ([`NewtonProblem::step_size`]; backward Euler: m/s), default
    /// [`DEFAULT_STEP_TOLERANCE`]; for [`Convergence::RelativeGradient`] dimensionless (1e-8 is
    /// usual, 1e-10 for reference solutions).
    pub tolerance: f64,
    /// Iteration limit. Default 100 (cloth-40 from rest needs up to 51 in one step where it buckles).
    pub max_iterations: usize,
    /// Armijo constant c in Φ(x + αΔ) ≤ Φ(x) + c α ∇Φᵀ Δ. Default 1e-4.
    pub armijo: f64,
    /// Step halvings before the line search gives up. Default 40.
    pub max_halvings: usize,
    /// The first non-zero shift μ (or blend weight β) tried after a failed factorisation. Default
    /// 1e-4.
    pub initial_shift: f64,
    /// The factor by which the shift μ is raised after a failed attempt or a short step, and
    /// lowered after a full step. Default 10.
    pub shift_factor: f64,
    /// The same for the blend weight β of [`IndefinitePolicy::ConvexBlend`]. Default 3 (10 was
    /// measured slower: see the module documentation).
    pub blend_factor: f64,
    /// Above this shift the solve gives up (the problem is not convex enough to fix). Default 1e12.
    pub max_shift: f64,
    /// What to do when the unshifted matrix is indefinite. Default
    /// [`IndefinitePolicy::ConvexBlend`].
    pub indefinite: IndefinitePolicy,
    /// Nonlinear relaxation after every accepted step, where the problem supports it. Default
    /// [`Relaxation::NONE`] (plain Newton); [`Relaxation::BUCKLING`] is the preset for buckling
    /// and crushed cloth.
    pub relaxation: Relaxation,
    /// Factorisation settings.
    pub cholesky: CholeskyParams,
    /// Solving a Newton system by CG preconditioned with the factor held from an earlier
    /// iteration, before factoring it. Default [`FactorReuse::DEFAULT`].
    pub factor_reuse: FactorReuse,
    /// Take the multilevel path (docs/solvers.md §2.5) when the Cholesky factor would hold more
    /// than this many times the matrix' stored entries (the factor's lower triangle against the
    /// matrix' full pattern), decided after the symbolic analysis, before the factor is
    /// allocated; even within the memory budget, if the problem has a convexified Hessian (for
    /// one without, the factor is used). Default [`MULTILEVEL_FILL`]; `f64::INFINITY`: only above
    /// the memory budget.
    pub multilevel_fill: f64,
}

/// The default [`NewtonParams::multilevel_fill`]: 20. Measured on this project's 2-core machine
/// (docs/solvers.md §2.5): a solid's factor fills far more than a cloth's, and the multilevel
/// path is the faster one from a fill of about 20 on (the dropped cube filled at 0.067 m, fill
/// 25: 3×; at 0.05 m, fill 38: 8×), the direct one below it (bunny-drop, fill 11: 1.7×;
/// cloth-40 and cloth-80, fill 4–5: 3×).
pub const MULTILEVEL_FILL: f64 = 20.0;

/// Solving a Newton system H Δ = −∇Φ by conjugate gradients preconditioned with the factor held
/// from an earlier Newton matrix (of this solve or of an earlier one on the same pattern), instead
/// of factoring H. Where H has hardly changed since (a body in free fall or at rest, the last
/// iterations of a solve), CG converges in one to a few iterations, each one solve with the held
/// factor: far cheaper than a factorisation of a dense factor. CG gives up as soon as its residual
/// falls behind the geometric rate that would reach [`FactorReuse::tolerance`] within
/// [`FactorReuse::max_iterations`] (so a matrix far from the factor's costs one or two solves),
/// or on a direction of non-positive curvature; the matrix is then factored as without reuse.
/// After a refused attempt the next 1, 2, 4, … 16 chances are passed over (the pause doubles with
/// each refusal in a row and ends with a success), so a scene whose matrices keep changing, such
/// as a swinging cloth, rarely pays for an attempt. Tried only on the exact matrix (no blend or
/// shift), whose factor is held as LLᵀ. Not used under [`IndefinitePolicy::NewtonIfDescent`],
/// which needs each matrix's inertia.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FactorReuse {
    /// CG iterations allowed before the matrix is factored after all; 0 turns reuse off.
    pub max_iterations: usize,
    /// The relative residual ‖H Δ + ∇Φ‖ / ‖∇Φ‖ at which CG's Δ is taken as the Newton step
    /// (dimensionless, in (0, 1)).
    pub tolerance: f64,
}

impl FactorReuse {
    /// No reuse: every Newton iteration factors its matrix.
    pub const OFF: FactorReuse = FactorReuse {
        max_iterations: 0,
        tolerance: 1e-6,
    };

    /// The default: up to 4 CG iterations to a relative residual of 1e-6.
    pub const DEFAULT: FactorReuse = FactorReuse {
        max_iterations: 4,
        tolerance: 1e-6,
    };

    /// Whether reuse is on (`max_iterations` > 0).
    pub fn is_on(&self) -> bool {
        self.max_iterations > 0
    }

    /// Check the fields: `tolerance` in (0, 1); `max_iterations` at most
    /// [`MAX_RELAXATION_COUNT`].
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::real(
            "FactorReuse::tolerance",
            self.tolerance,
            self.tolerance > 0.0 && self.tolerance < 1.0,
            "in (0, 1)",
        )?;
        params::count_in(
            "FactorReuse::max_iterations",
            self.max_iterations,
            0,
            MAX_RELAXATION_COUNT,
            "at most 10000",
        )
    }
}

impl Default for FactorReuse {
    fn default() -> Self {
        FactorReuse::DEFAULT
    }
}

/// The default tolerance of [`Convergence::StepSize`]: 1e-5 in the problem's step measure, for
/// backward Euler m/s (a Newton step that moves no vertex by more than 1e-5 m/s · h; the step is
/// then taken, so what is left is smaller still). The loosest value measured that leaves every
/// scene of the table (cloth-40, cloth-40-stiff, cloth-80, beam-4, bunny-drop) at the answer of a
/// tighter solve; a buckling cloth amplifies what a looser one leaves (docs/contact.md).
pub const DEFAULT_STEP_TOLERANCE: f64 = 1e-5;

/// When a Newton solve has converged (see the module documentation's "Stops").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Convergence {
    /// The Newton step is small: [`NewtonProblem::step_size`] of Δ = −H⁻¹∇Φ is at most the
    /// tolerance. For backward Euler the step size is the largest vertex displacement of the step
    /// divided by h (m/s): a scale that does not vanish with the gradient (a body in free fall has
    /// no gradient at its inertial target, and a gradient relative to it means nothing). Tested
    /// only on steps whose matrix is not shifted by the masses (the exact Hessian, or a blend with
    /// the convexified one, β ≤ 1), where Δ estimates the distance to the solution; the step is
    /// then still taken when the line search accepts it.
    #[default]
    StepSize,
    /// ‖∇Φ(x)‖ ≤ tolerance · ‖∇Φ(x⁰)‖ (dimensionless), also met by ∇Φ(x⁰) = 0: the speed-vs-error
    /// measurements' setting, comparable across solvers; not a physical scale.
    RelativeGradient,
}

impl Convergence {
    /// A short name for reports: `step-size` or `relative-gradient`.
    pub fn name(self) -> &'static str {
        match self {
            Convergence::StepSize => "step-size",
            Convergence::RelativeGradient => "relative-gradient",
        }
    }
}

/// How Newton treats an indefinite Hessian (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum IndefinitePolicy {
    /// Factor (1 − β) H + β H₊, H₊ the problem's [`NewtonProblem::convexified_hessian`], with the
    /// blend weight β ∈ [0, 1] adapted like a Levenberg–Marquardt parameter until the matrix is
    /// positive definite (beyond β = 1, μ = β − 1 times D is added as well). Only the
    /// non-convex terms are damped. For a problem without a convexified Hessian: as
    /// [`IndefinitePolicy::NewtonIfDescent`].
    #[default]
    ConvexBlend,
    /// Take the Newton step of the indefinite matrix when it descends and the line search accepts
    /// it; shift otherwise. Converges to a stationary point of Φ.
    NewtonIfDescent,
    /// Always shift until the matrix is positive definite: every step minimises a convex model, at
    /// the price of linear convergence wherever the shift stays on.
    Shift,
    /// Factor the problem's [`NewtonProblem::definite_hessian`], made positive definite term by
    /// term before the factorisation (for backward Euler: exact spring blocks wherever a share of
    /// the masses holds them, projected where it does not), so that each iteration factors once.
    /// Should that matrix still fail to factor (rounding), H + μD with μ raised tenfold from
    /// [`NewtonParams::initial_shift`] until it does, each failure counted
    /// ([`NewtonReport::failed_factorizations`]); μ is lowered one step after every full step. For
    /// a problem without a definite Hessian: as [`IndefinitePolicy::ConvexBlend`].
    Projected,
    /// [`IndefinitePolicy::Projected`], switching to the exact Hessian near convergence (a
    /// progressive projection): after a step taken in full, the next iteration factors the exact
    /// Hessian; if that is not positive definite (one failed factorisation, counted), the
    /// definite one, and the next 1, 2, 4, … 16 chances to go exact are passed over (the pause
    /// doubles with each failure in a row and ends with a success). The first iteration of a solve
    /// and every iteration after a shortened step factor the definite Hessian. Where the exact
    /// Hessian is definite near the solution (the usual case), the last iterations are exact
    /// Newton steps and converge quadratically.
    ProjectedThenExact,
    /// Factor the problem's [`NewtonProblem::definite_hessian`] once per iteration (shifted only
    /// where rounding defeats it, as under [`IndefinitePolicy::Projected`]) and solve the exact
    /// Newton system H Δ = −∇Φ by CG preconditioned with that factor, from 0, to the relative
    /// residual min(0.1, ‖∇Φ‖/‖∇Φ₀‖) in at most [`PRECONDITIONED_CG_ITERATIONS`] iterations,
    /// stopped at the first direction of non-positive curvature of H (the iterate so far, or
    /// before the first iteration the definite matrix's own Newton step, which descends). One
    /// factorisation per iteration and never a failed one from indefiniteness; where H is
    /// definite and close to its definite part, the step is H's Newton step and convergence
    /// quadratic.
    ProjectedPreconditioned,
}

/// The CG iterations [`IndefinitePolicy::ProjectedPreconditioned`] allows per Newton iteration.
pub const PRECONDITIONED_CG_ITERATIONS: usize = 20;

impl IndefinitePolicy {
    /// Every policy, in the order of their documentation.
    pub const ALL: [IndefinitePolicy; 6] = [
        IndefinitePolicy::ConvexBlend,
        IndefinitePolicy::NewtonIfDescent,
        IndefinitePolicy::Shift,
        IndefinitePolicy::Projected,
        IndefinitePolicy::ProjectedThenExact,
        IndefinitePolicy::ProjectedPreconditioned,
    ];

    /// Whether the policy factors the problem's [`NewtonProblem::definite_hessian`].
    pub fn is_projected(self) -> bool {
        matches!(
            self,
            IndefinitePolicy::Projected
                | IndefinitePolicy::ProjectedThenExact
                | IndefinitePolicy::ProjectedPreconditioned
        )
    }

    /// A short name for reports and options: `blend`, `descent`, `shift`, `projected` or
    /// `projected-exact`.
    pub fn name(self) -> &'static str {
        match self {
            IndefinitePolicy::ConvexBlend => "blend",
            IndefinitePolicy::NewtonIfDescent => "descent",
            IndefinitePolicy::Shift => "shift",
            IndefinitePolicy::Projected => "projected",
            IndefinitePolicy::ProjectedThenExact => "projected-exact",
            IndefinitePolicy::ProjectedPreconditioned => "projected-pcg",
        }
    }
}

impl NewtonParams {
    /// Check every field against its allowed range: `tolerance` finite and ≥ 0 (relative);
    /// `max_iterations` ≥ 1; `armijo` in (0, 1); `max_halvings` at most
    /// [`MAX_LINE_SEARCH_HALVINGS`]; `initial_shift` finite and > 0; `shift_factor` and
    /// `blend_factor` finite and > 1; `max_shift` finite, ≥ `initial_shift`, and reached from it
    /// within [`MAX_SHIFT_STEPS`] steps of either factor; and the nested [`Relaxation::validate`],
    /// [`FactorReuse::validate`] and [`CholeskyParams::validate`].
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("NewtonParams::tolerance", self.tolerance)?;
        params::at_least(
            "NewtonParams::max_iterations",
            self.max_iterations,
            1,
            "at least 1",
        )?;
        params::real(
            "NewtonParams::armijo",
            self.armijo,
            self.armijo > 0.0 && self.armijo < 1.0,
            "in (0, 1)",
        )?;
        params::count_in(
            "NewtonParams::max_halvings",
            self.max_halvings,
            0,
            MAX_LINE_SEARCH_HALVINGS,
            "at most 1074",
        )?;
        params::positive("NewtonParams::initial_shift", self.initial_shift)?;
        for (field, factor) in [
            ("NewtonParams::shift_factor", self.shift_factor),
            ("NewtonParams::blend_factor", self.blend_factor),
        ] {
            params::real(
                field,
                factor,
                factor > 1.0 && factor.is_finite(),
                "finite and > 1",
            )?;
        }
        params::real(
            "NewtonParams::max_shift",
            self.max_shift,
            self.max_shift.is_finite() && self.max_shift >= self.initial_shift,
            "finite and >= initial_shift",
        )?;
        let ratio = (self.max_shift / self.initial_shift).ln();
        for (field, factor) in [
            ("NewtonParams::shift_factor", self.shift_factor),
            ("NewtonParams::blend_factor", self.blend_factor),
        ] {
            params::real(
                field,
                factor,
                ratio / factor.ln() <= MAX_SHIFT_STEPS,
                "large enough to reach max_shift from initial_shift in at most 200 steps",
            )?;
        }
        self.relaxation.validate()?;
        self.factor_reuse.validate()?;
        params::real(
            "NewtonParams::multilevel_fill",
            self.multilevel_fill,
            self.multilevel_fill > 0.0,
            "positive (+∞: only above the memory budget)",
        )?;
        self.cholesky.validate()
    }
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            convergence: Convergence::StepSize,
            tolerance: DEFAULT_STEP_TOLERANCE,
            max_iterations: 100,
            armijo: 1e-4,
            max_halvings: 40,
            initial_shift: 1e-4,
            shift_factor: 10.0,
            blend_factor: 3.0,
            max_shift: 1e12,
            indefinite: IndefinitePolicy::ConvexBlend,
            relaxation: Relaxation::NONE,
            cholesky: CholeskyParams::default(),
            factor_reuse: FactorReuse::DEFAULT,
            multilevel_fill: MULTILEVEL_FILL,
        }
    }
}

/// One Newton iteration's record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonIteration {
    /// Relative gradient norm ‖∇Φ‖ / ‖∇Φ(x⁰)‖ after the iteration.
    pub gradient: f64,
    /// Φ after the iteration.
    pub objective: f64,
    /// The shift μ of the accepted step, or under [`IndefinitePolicy::ConvexBlend`] its blend weight
    /// β (0: the exact Hessian; 1: the convexified one).
    pub shift: f64,
    /// Failed attempts before the step was found: factorisations that were not positive definite
    /// (under [`IndefinitePolicy::Shift`]), singular, or gave an ascent direction, and line searches
    /// that failed on an indefinite step.
    pub failed_factorizations: usize,
    /// Negative eigenvalues of the factored matrix of the accepted step (0: positive definite).
    pub negative_eigenvalues: usize,
    /// Line-search step length α.
    pub step_length: f64,
    /// [`NewtonProblem::step_size`] of the full step Δ (before the line search).
    pub step_size: f64,
}

/// The account of a Newton solve.
#[derive(Clone, Debug, PartialEq)]
pub struct NewtonReport {
    /// Iterations (accepted steps).
    pub iterations: usize,
    /// Relative gradient norm before the first iteration.
    pub initial_gradient: f64,
    /// Φ before the first iteration.
    pub initial_objective: f64,
    /// One record per iteration.
    pub history: Vec<NewtonIteration>,
    /// Iterations that used a non-zero shift.
    pub shifted_steps: usize,
    /// Iterations whose accepted step came from an indefinite matrix.
    pub indefinite_steps: usize,
    /// Failed attempts in all (each one raised the shift).
    pub failed_factorizations: usize,
    /// Numeric factorisations in all (accepted and failed attempts).
    pub factorizations: usize,
    /// Iterations whose step was solved by CG with the factor held from an earlier matrix
    /// ([`NewtonParams::factor_reuse`]) instead of a factorisation.
    pub reused_factors: usize,
    /// CG attempts on a held factor that did not converge (the matrix was then factored).
    pub refused_reuses: usize,
    /// CG iterations on held factors in all (each one solve with the factor), converged or not.
    pub reuse_iterations: usize,
    /// CG iterations on the exact Newton systems under
    /// [`IndefinitePolicy::ProjectedPreconditioned`], in all (each one solve with the definite
    /// Hessian's factor and one product with the exact Hessian).
    pub exact_cg_iterations: usize,
    /// Relaxation sweeps over all blocks, in all ([`NewtonParams::relaxation`]).
    pub relaxation_sweeps: usize,
    /// Relaxations skipped after a trusted exact Newton step ([`Relaxation::trusted_model`]).
    pub skipped_relaxations: usize,
    /// Focused relaxation sweeps in all ([`Relaxation::focus_share`]).
    pub focused_sweeps: usize,
    /// Block visits of the relaxation in all, full and focused sweeps together.
    pub relaxed_blocks: usize,
    /// Patches solved by the nonlinear elimination ([`Relaxation::region_share`]), in all.
    pub region_solves: usize,
    /// Eliminations and patches skipped (see [`RelaxationWork::skipped_regions`]), in all.
    pub skipped_regions: usize,
    /// Blocks in the patches solved, summed over the solves.
    pub region_blocks: usize,
    /// Iterations of the inner Newton solves of the patches, in all (not counted in
    /// [`NewtonReport::iterations`]).
    pub region_iterations: usize,
    /// Numeric factorisations of the inner solves (not counted in
    /// [`NewtonReport::factorizations`]).
    pub region_factorizations: usize,
    /// Time in relaxation.
    pub relaxation_time: Duration,
    /// Why it stopped.
    pub stop: StopReason,
    /// The criterion the solve was run to ([`NewtonParams::convergence`]).
    pub convergence: Convergence,
    /// [`NewtonProblem::step_size`] of the last Newton step computed (its full length Δ, whether
    /// or not it was taken); 0 if the solve started at a stationary point, ∞ before any step.
    pub step_size: f64,
    /// Wall time, and the part spent in numeric factorisations.
    pub wall_time: Duration,
    /// Time in numeric factorisations.
    pub factor_time: Duration,
}

impl NewtonReport {
    /// An empty report whose history has room for `iterations` records, at most
    /// a fixed reserve (the history grows beyond it as iterations go: no allocation is sized by a
    /// user's limit).
    pub(crate) fn with_capacity(iterations: usize) -> Self {
        NewtonReport {
            iterations: 0,
            initial_gradient: 1.0,
            initial_objective: 0.0,
            history: Vec::with_capacity(iterations.min(HISTORY_RESERVE)),
            shifted_steps: 0,
            indefinite_steps: 0,
            failed_factorizations: 0,
            factorizations: 0,
            reused_factors: 0,
            refused_reuses: 0,
            reuse_iterations: 0,
            exact_cg_iterations: 0,
            relaxation_sweeps: 0,
            skipped_relaxations: 0,
            focused_sweeps: 0,
            relaxed_blocks: 0,
            region_solves: 0,
            skipped_regions: 0,
            region_blocks: 0,
            region_iterations: 0,
            region_factorizations: 0,
            relaxation_time: Duration::ZERO,
            stop: StopReason::IterationLimit,
            convergence: Convergence::StepSize,
            step_size: f64::INFINITY,
            wall_time: Duration::ZERO,
            factor_time: Duration::ZERO,
        }
    }

    /// Empty this report for a solve starting at Φ = `objective`, keeping the history's capacity.
    fn reset(&mut self, objective: f64) {
        let mut history = std::mem::take(&mut self.history);
        history.clear();
        *self = NewtonReport {
            initial_objective: objective,
            history,
            ..NewtonReport::with_capacity(0)
        };
    }

    /// The last relative gradient norm.
    pub fn gradient(&self) -> f64 {
        self.history
            .last()
            .map_or(self.initial_gradient, |h| h.gradient)
    }

    /// The criterion's own quantity at the end of the solve ([`NewtonReport::convergence`]): the
    /// last step size ([`NewtonReport::step_size`], e.g. m/s) or the relative gradient
    /// ([`NewtonReport::gradient`]). The solve converged if and only if it stopped with
    /// [`StopReason::Converged`], and then this is at most the tolerance.
    pub fn residual(&self) -> f64 {
        match self.convergence {
            Convergence::StepSize => self.step_size,
            Convergence::RelativeGradient => self.gradient(),
        }
    }
}

/// Why Newton failed; each variant keeps the report so far.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NewtonError {
    /// No step along the Newton direction decreased Φ enough.
    #[error("the line search failed at iteration {} (relative gradient {:e})", report.iterations, report.gradient())]
    LineSearchFailed {
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// Even the largest shift did not give a factorisable matrix.
    #[error("the Hessian could not be made positive definite (shift above {max_shift:e}) at iteration {}", report.iterations)]
    NotPositiveDefinite {
        /// The limit that was passed.
        max_shift: f64,
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// Φ or its gradient is NaN or infinite.
    #[error("non-finite objective or gradient at iteration {}", report.iterations)]
    NonFinite {
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// The Hessian does not have the analysed pattern, or its analysis failed.
    #[error(transparent)]
    Factorization(#[from] CholeskyError),
    /// A parameter is out of its range ([`NewtonParams::validate`]); nothing was computed.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
}

impl NewtonError {
    /// The report up to the failure, for the variants that carry one.
    pub fn report(&self) -> Option<&NewtonReport> {
        match self {
            NewtonError::LineSearchFailed { report }
            | NewtonError::NotPositiveDefinite { report, .. }
            | NewtonError::NonFinite { report } => Some(report),
            NewtonError::Factorization(_) | NewtonError::InvalidParameter(_) => None,
        }
    }
}

/// Why [`Newton::minimize_into`] failed; [`NewtonError`] without the report.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    LineSearchFailed,
    NotPositiveDefinite { max_shift: f64 },
    NonFinite,
    Factorization(CholeskyError),
    InvalidParameter(ParamError),
}

impl Failure {
    /// The error, carrying `report`.
    fn with_report(self, report: NewtonReport) -> NewtonError {
        let report = Box::new(report);
        match self {
            Failure::LineSearchFailed => NewtonError::LineSearchFailed { report },
            Failure::NotPositiveDefinite { max_shift } => {
                NewtonError::NotPositiveDefinite { max_shift, report }
            }
            Failure::NonFinite => NewtonError::NonFinite { report },
            Failure::Factorization(e) => NewtonError::Factorization(e),
            Failure::InvalidParameter(e) => NewtonError::InvalidParameter(e),
        }
    }
}

/// Newton's method with its workspace (factorisation, vectors, the Hessian and shifted value
/// buffers), reused across solves on the same pattern: the symbolic analysis is done once.
#[derive(Debug)]
pub struct Newton {
    /// The settings.
    pub params: NewtonParams,
    /// The Cholesky factor, or above the memory budget or the fill bound the multilevel solve
    /// (docs/solvers.md §2.5).
    cholesky: LinearSolver,
    diagonal_slots: Vec<usize>,
    hessian: Vec<f64>,
    /// The problem's convexified Hessian at the current iterate, fetched once per iterate
    /// whatever the number of blends factored there; `convex_current` says whether it is.
    convex: Vec<f64>,
    convex_current: bool,
    shifted: Vec<f64>,
    g: Vec<f64>,
    step: Vec<f64>,
    trial: Vec<f64>,
    shift: f64,
    /// −∇Φ, the right-hand side of CG on a held factor.
    rhs: Vec<f64>,
    cg: ConjugateGradient,
    cg_report: Report,
    /// Chances to reuse the held factor still to be passed over after refused attempts, and the
    /// length of the last such pause (see [`FactorReuse`]).
    reuse_pause: u32,
    reuse_backoff: u32,
    /// Whether the held factor may precondition a later system (see
    /// [`Newton::forget_held_factor`]).
    reusable: bool,
    /// Under [`IndefinitePolicy::ProjectedThenExact`]: whether the next iteration factors the exact
    /// Hessian, and the chances to go exact still to be passed over after failed attempts, with
    /// the length of the last such pause.
    exact_next: bool,
    exact_pause: u32,
    exact_backoff: u32,
}

/// The position of every diagonal entry in the value array of `pattern`.
///
/// # Panics
/// If a diagonal entry is not stored.
#[track_caller]
fn diagonal_slots(pattern: SymbolicSparseColMatRef<'_, usize>) -> Vec<usize> {
    (0..pattern.ncols())
        .map(|j| {
            let start = pattern.col_ptr()[j];
            let k = pattern
                .row_idx_of_col_raw(j)
                .iter()
                .position(|&i| i == j)
                .expect("every diagonal entry is stored");
            start + k
        })
        .collect()
}

/// The longest pause, in chances passed over, after consecutive refused reuses.
const MAX_REUSE_BACKOFF: u32 = 16;

/// An accepted step: its length α and Φ(x + αΔ) − Φ(x).
struct Accepted {
    alpha: f64,
    change: f64,
    /// The longest step length the problem allowed ([`NewtonProblem::max_step_length`]).
    longest: f64,
}

impl Newton {
    /// Analyse the problem's Hessian pattern once. A Cholesky factor above
    /// [`CholeskyParams::memory_budget`], or filling more than [`NewtonParams::multilevel_fill`]
    /// times the matrix, is not allocated: the Newton systems are then solved on the multilevel
    /// path ([`Newton::multilevel`], docs/solvers.md §2.5; for the fill, only for a problem with a
    /// convexified Hessian: another falls back to the factor at its first solve).
    ///
    /// # Errors
    /// [`NewtonError::InvalidParameter`] if `params` does not pass [`NewtonParams::validate`];
    /// [`NewtonError::Factorization`] if the symbolic analysis fails.
    ///
    /// # Panics
    /// If the pattern lacks a diagonal entry.
    #[track_caller]
    pub fn new(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: NewtonParams,
    ) -> Result<Self, NewtonError> {
        params.validate()?;
        let n = pattern.ncols();
        let diagonal_slots = diagonal_slots(pattern);
        let nnz = pattern.compute_nnz();
        Ok(Newton {
            cholesky: LinearSolver::analyze(pattern, params.cholesky, params.multilevel_fill)?,
            diagonal_slots,
            hessian: vec![0.0; nnz],
            convex: Vec::new(),
            convex_current: false,
            shifted: vec![0.0; nnz],
            g: vec![0.0; n],
            step: vec![0.0; n],
            trial: vec![0.0; n],
            shift: 0.0,
            rhs: vec![0.0; n],
            cg: ConjugateGradient::new(CgParams::default()),
            cg_report: Report::start(MAX_RELAXATION_COUNT),
            reuse_pause: 0,
            reuse_backoff: 0,
            reusable: false,
            exact_next: false,
            exact_pause: 0,
            exact_backoff: 0,
            params,
        })
    }

    /// Analyse a new pattern of `problem` (after [`NewtonProblem::update_pattern`] changed it): the
    /// factor's symbolic analysis and the buffers as in [`Newton::new`], the held factor forgotten,
    /// and the multilevel path prepared again at `x` where it is taken.
    fn adopt_pattern(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
    ) -> Result<(), Failure> {
        let pattern = problem.pattern();
        self.diagonal_slots = diagonal_slots(pattern);
        let nnz = pattern.compute_nnz();
        self.hessian.resize(nnz, 0.0);
        self.convex_current = false;
        self.shifted.resize(nnz, 0.0);
        self.cholesky =
            LinearSolver::analyze(pattern, self.params.cholesky, self.params.multilevel_fill)
                .map_err(Failure::Factorization)?;
        self.forget_held_factor();
        if !problem.has_convexified_hessian() {
            self.cholesky
                .fall_back_to_direct(problem.pattern(), self.params.cholesky)
                .map_err(Failure::Factorization)?;
        }
        if let Some(multilevel) = self.cholesky.multilevel_mut() {
            multilevel
                .prepare(problem, x)
                .map_err(Failure::Factorization)?;
        }
        Ok(())
    }

    /// The multilevel solve standing in for a Cholesky factor above the memory budget
    /// ([`CholeskyParams::memory_budget`]) or the fill bound ([`NewtonParams::multilevel_fill`];
    /// docs/solvers.md §2.5); `None` on the direct path.
    pub fn multilevel(&self) -> Option<&MultilevelSolve> {
        self.cholesky.multilevel()
    }

    /// The factor between successive shifts (or blend weights) under `policy`.
    fn shift_factor(&self, policy: IndefinitePolicy) -> f64 {
        match policy {
            IndefinitePolicy::ConvexBlend => self.params.blend_factor,
            _ => self.params.shift_factor,
        }
    }

    /// The next larger shift.
    fn raise_shift(&self, policy: IndefinitePolicy) -> f64 {
        if self.shift == 0.0 {
            self.params.initial_shift
        } else {
            self.shift_factor(policy) * self.shift
        }
    }

    /// The next smaller shift (0 below the first one).
    fn lower_shift(&self, policy: IndefinitePolicy) -> f64 {
        if self.shift <= self.params.initial_shift {
            0.0
        } else {
            self.shift / self.shift_factor(policy)
        }
    }

    /// Factor the matrix of the current shift (see [`Newton::regularize`]), counting it in `report`.
    /// Only [`IndefinitePolicy::NewtonIfDescent`] steps along an indefinite matrix and needs its
    /// LDLᵀ factor and inertia; the other policies need to know only whether the matrix is positive
    /// definite, which LLᵀ tells faster (8–18 % on cloth-40 and cloth-160's Newton matrix) and, when
    /// it is not, at the first non-positive pivot ([`CholeskyError::NotPositiveDefinite`]).
    fn factor_at_shift(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        policy: IndefinitePolicy,
        report: &mut NewtonReport,
    ) -> Result<Inertia, CholeskyError> {
        self.regularize(problem, x, policy);
        let matrix = SparseColMatRef::new(problem.pattern(), &self.shifted);
        let factored = if policy == IndefinitePolicy::NewtonIfDescent {
            self.cholesky.factorize_ldlt(matrix)
        } else {
            self.cholesky.factorize(matrix, &self.g).map(|()| Inertia {
                positive: self.g.len(),
                negative: 0,
            })
        };
        report.factor_time += self.cholesky.factor_time();
        report.factorizations += 1;
        self.reusable = factored.is_ok() && self.cholesky.has_llt_factor();
        factored
    }

    /// Forget what this solver carries from one solve to the next: the held factor is not reused
    /// (the next iteration factors its matrix) and the pause after refused reuses ends. A solve
    /// after this call takes the same steps as the first solve of a new [`Newton`]: a simulation
    /// calls it where it writes a checkpoint, so that a run resumed from the checkpoint and the
    /// run that wrote it compute the same bits.
    pub fn forget_held_factor(&mut self) {
        self.reusable = false;
        self.reuse_pause = 0;
        self.reuse_backoff = 0;
    }

    /// Solve `self.shifted` Δ = −∇Φ (the matrix on `pattern`) into `self.step` by CG from zero,
    /// preconditioned with the held factor, to a relative residual of `tolerance` in at most
    /// `max_iterations`, giving up where `give_up(k, residual)` says so. Returns the iterations
    /// made and whether CG converged; `self.cg_report` keeps its history either way, so that the
    /// next solve allocates nothing.
    fn cg_on_held_factor(
        &mut self,
        pattern: SymbolicSparseColMatRef<'_, usize>,
        tolerance: f64,
        max_iterations: usize,
        give_up: impl Fn(usize, f64) -> bool,
    ) -> (usize, bool) {
        for (b, g) in self.rhs.iter_mut().zip(&self.g) {
            *b = -g;
        }
        self.step.fill(0.0);
        self.cg.params = CgParams {
            tolerance,
            max_iterations,
        };
        let matrix = Symmetric(SparseColMatRef::new(pattern, &self.shifted));
        let solved = self.cg.solve_into(
            &matrix,
            &mut self.cholesky,
            &self.rhs,
            &mut self.step,
            &mut self.cg_report,
            give_up,
        );
        match solved {
            Ok(()) => (
                self.cg_report.iterations,
                self.cg_report.stop.is_converged(),
            ),
            Err(e) => match e.into_report() {
                // The history moved into the error: take it back.
                Some(failed) => {
                    let iterations = failed.iterations;
                    self.cg_report = failed;
                    (iterations, false)
                }
                None => (0, false),
            },
        }
    }

    /// Solve the Newton system of the current shift (see [`Newton::regularize`]) into `step` by CG
    /// preconditioned with the held LLᵀ factor ([`NewtonParams::factor_reuse`]), counting it in
    /// `report`. `true` if CG converged; otherwise `step` is garbage and the matrix must be
    /// factored.
    fn solve_by_held_factor(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        policy: IndefinitePolicy,
        report: &mut NewtonReport,
    ) -> bool {
        let reuse = self.params.factor_reuse;
        if !(self.reusable && self.cholesky.has_llt_factor()) {
            return false;
        }
        if self.reuse_pause > 0 {
            self.reuse_pause -= 1;
            return false;
        }
        self.regularize(problem, x, policy);
        // Off the geometric track that reaches the tolerance within the allowed iterations: the
        // matrix has moved too far from the factor's, and further solves with it would be wasted.
        let track = |k: usize, residual: f64| {
            residual > reuse.tolerance.powf(k as f64 / reuse.max_iterations as f64)
        };
        let (iterations, converged) = self.cg_on_held_factor(
            problem.pattern(),
            reuse.tolerance,
            reuse.max_iterations,
            track,
        );
        report.reuse_iterations += iterations;
        if converged {
            report.reused_factors += 1;
            self.reuse_backoff = 0;
        } else {
            report.refused_reuses += 1;
            self.reuse_backoff = (2 * self.reuse_backoff).clamp(1, MAX_REUSE_BACKOFF);
            self.reuse_pause = self.reuse_backoff;
        }
        converged
    }

    /// Under [`IndefinitePolicy::ConvexBlend`], after the blend of the current weight failed to be
    /// positive definite: find the smallest weight above it on the ladder of
    /// [`NewtonParams::blend_factor`] steps whose blend is, by trying the next step, then the whole
    /// blend (β = 1), then doubling jumps, and bisecting between the last failure and the first
    /// success. The blend H + β (H₊ − H) only gains definiteness as β grows (H₊ − H is
    /// positive semidefinite, and beyond β = 1 a positive multiple of D is added), so this finds the
    /// weight that climbing one step at a time would find, and so the same iterate, with
    /// O(log) instead of O(steps) factorisations. Returns `Some(true)` with that weight set and its
    /// factor held; `Some(false)` with a weight set whose factorisation should be retried (rounding
    /// broke the monotonicity); `None` if no weight up to [`NewtonParams::max_shift`] is definite.
    /// Failed factorisations are counted in `failed`.
    ///
    /// # Errors
    /// Factorisation errors other than a zero pivot.
    fn search_definite_shift(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        report: &mut NewtonReport,
        failed: &mut usize,
    ) -> Result<Option<bool>, Failure> {
        let policy = IndefinitePolicy::ConvexBlend;
        let (initial, factor, max_shift) = (
            self.params.initial_shift,
            self.params.blend_factor,
            self.params.max_shift,
        );
        let base = self.shift;
        // The j-th weight above `base`, multiplied up one step at a time exactly as a climb would.
        let ladder = |j: usize| {
            let mut shift = base;
            for _ in 0..j {
                shift = if shift == 0.0 {
                    initial
                } else {
                    factor * shift
                };
            }
            shift
        };
        let mut top = 0;
        while ladder(top + 1) <= max_shift {
            top += 1;
        }
        let mut definite_at = |this: &mut Self, report: &mut NewtonReport, j: usize| {
            this.shift = ladder(j);
            match this.factor_at_shift(problem, x, policy, report) {
                Ok(inertia) => Ok(inertia.is_positive_definite()),
                Err(CholeskyError::Singular { .. } | CholeskyError::NotPositiveDefinite { .. }) => {
                    Ok(false)
                }
                Err(e) => Err(Failure::Factorization(e)),
            }
        };
        // The first weight of at least 1: the convexified Hessian itself (plus D beyond), definite
        // for a problem whose convex part is.
        let mut whole = 1;
        while whole < top && ladder(whole) < 1.0 {
            whole += 1;
        }
        // Try the next step (the usual answer once a solve is under way), then the whole blend,
        // then double the jump beyond it: `bad` fails, `good` is definite.
        let mut bad = 0;
        let mut good = loop {
            if bad >= top {
                return Ok(None);
            }
            let j = if bad == 0 {
                1
            } else if bad < whole {
                whole
            } else {
                (bad + (bad - whole).max(1)).min(top)
            };
            if definite_at(self, report, j)? {
                break j;
            }
            *failed += 1;
            bad = j;
        };
        // Bisect between them; the factor held is the last one computed.
        let mut held_is_good = true;
        while good - bad > 1 {
            let middle = (bad + good) / 2;
            if definite_at(self, report, middle)? {
                good = middle;
                held_is_good = true;
            } else {
                *failed += 1;
                bad = middle;
                held_is_good = false;
            }
        }
        if held_is_good {
            self.shift = ladder(good);
            return Ok(Some(true));
        }
        let definite = definite_at(self, report, good)?;
        Ok(Some(definite))
    }

    /// Write the matrix to factor into `shifted`: H + μ D, or under [`IndefinitePolicy::ConvexBlend`]
    /// (1 − β) H + β H₊ (+ (β − 1) D beyond β = 1; H + μ D if the problem has no H₊).
    fn regularize(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        policy: IndefinitePolicy,
    ) {
        self.shifted.copy_from_slice(&self.hessian);
        let mut shift = self.shift;
        if policy == IndefinitePolicy::ConvexBlend && shift > 0.0 {
            if !self.convex_current {
                if let Some(convex) = problem.convexified_hessian(x) {
                    self.convex.clear();
                    self.convex.extend_from_slice(convex.val());
                    self.convex_current = true;
                }
            }
            if self.convex_current {
                let beta = shift.min(1.0);
                for (s, c) in self.shifted.iter_mut().zip(&self.convex) {
                    *s += beta * (c - *s);
                }
                shift = (shift - 1.0).max(0.0);
            }
        }
        if shift > 0.0 {
            let d = problem.shift_diagonal();
            for (j, &slot) in self.diagonal_slots.iter().enumerate() {
                self.shifted[slot] += shift * d[j];
            }
        }
    }

    /// One step of [`IndefinitePolicy::ProjectedPreconditioned`] from `x` (`gradient`: the relative
    /// ‖∇Φ‖): the definite Hessian factored, the exact Newton system solved by truncated CG
    /// preconditioned with that factor, and the line search along its step, or along the
    /// definite matrix's own Newton step should that one be refused. `None` if the line search
    /// refused both.
    fn preconditioned_step(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        p: &NewtonParams,
        gradient: f64,
        report: &mut NewtonReport,
    ) -> Result<Option<(Accepted, f64)>, Failure> {
        let h = problem
            .definite_hessian(x)
            .expect("has_definite_hessian promised a matrix");
        self.hessian.copy_from_slice(h.val());
        self.convex_current = false;
        self.shift = 0.0;
        let mut failed = 0;
        loop {
            match self.factor_at_shift(problem, x, IndefinitePolicy::Projected, report) {
                Ok(_) => break,
                Err(CholeskyError::Singular { .. } | CholeskyError::NotPositiveDefinite { .. }) => {
                    failed += 1;
                    self.shift = self.raise_shift(IndefinitePolicy::Projected);
                    if self.shift > p.max_shift {
                        report.failed_factorizations += failed;
                        return Err(Failure::NotPositiveDefinite {
                            max_shift: p.max_shift,
                        });
                    }
                }
                Err(e) => return Err(Failure::Factorization(e)),
            }
        }
        report.failed_factorizations += failed;
        self.shifted.copy_from_slice(problem.hessian(x).val());
        let (iterations, _) = self.cg_on_held_factor(
            problem.pattern(),
            gradient.clamp(1e-12, 0.1),
            PRECONDITIONED_CG_ITERATIONS,
            |_, _| false,
        );
        report.exact_cg_iterations += iterations;
        for attempt in 0..2 {
            if attempt == 1 || iterations == 0 {
                // The definite matrix's own Newton step.
                self.step.copy_from_slice(&self.rhs);
                self.cholesky.solve_slice(&mut self.step);
            }
            report.step_size = problem.step_size(&self.step);
            let slope = dot(&self.g, &self.step);
            if slope < 0.0 {
                if let Some(accepted) = self.line_search(problem, x, slope) {
                    return Ok(Some((accepted, slope)));
                }
            }
            if iterations == 0 {
                break;
            }
        }
        Ok(None)
    }

    /// Why a solve stops when the line search refused a descent direction of a convex model at
    /// `x`: no step lowers Φ, so either the gradient is round-off ([`StopReason::RoundOff`]: the
    /// tolerance is below what the arithmetic resolves) or objective and gradient disagree
    /// ([`StopReason::LineSearchFailed`]).
    fn refused_search_stop(&self, problem: &mut impl NewtonProblem, x: &[f64]) -> StopReason {
        let noise = problem.gradient_round_off(x);
        if dot(&self.g, &self.g).sqrt() <= noise {
            StopReason::RoundOff
        } else {
            StopReason::LineSearchFailed
        }
    }

    /// Backtracking line search from `x` along the current step, with slope gᵀΔ < 0.
    fn line_search(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        slope: f64,
    ) -> Option<Accepted> {
        let p = self.params;
        let longest = problem.max_step_length(x, &self.step).min(1.0);
        if longest.is_nan() || longest <= 0.0 {
            return None;
        }
        let mut alpha = longest;
        for _ in 0..=p.max_halvings {
            for ((t, x), s) in self.trial.iter_mut().zip(x).zip(&self.step) {
                *t = x + alpha * s;
            }
            let change = problem.objective_change(x, &self.trial);
            if change.is_finite() && change <= p.armijo * alpha * slope {
                return Some(Accepted {
                    alpha,
                    change,
                    longest,
                });
            }
            alpha *= 0.5;
        }
        None
    }

    /// Minimise Φ from the guess in `x` (which holds the result on return).
    ///
    /// # Errors
    /// [`NewtonError`], carrying the report so far; [`NewtonError::InvalidParameter`] (before
    /// anything is computed) if [`Newton::params`] was set to values [`NewtonParams::validate`]
    /// refuses.
    ///
    /// # Panics
    /// If `x` or the problem's pattern does not match the analysed dimension.
    #[track_caller]
    pub fn minimize(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &mut [f64],
    ) -> Result<NewtonReport, NewtonError> {
        let mut report = NewtonReport::with_capacity(self.params.max_iterations);
        match self.minimize_into(problem, x, &mut report) {
            Ok(()) => Ok(report),
            Err(failure) => Err(failure.with_report(report)),
        }
    }

    /// [`Newton::minimize`] into `report`, which is reset first and whose history keeps its
    /// capacity: with a report made once (of capacity [`NewtonParams::max_iterations`]), a solve
    /// allocates nothing. For the inner solves of the relaxation's elimination; on failure the
    /// report holds the account so far.
    #[track_caller]
    pub(crate) fn minimize_into(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &mut [f64],
        report: &mut NewtonReport,
    ) -> Result<(), Failure> {
        if problem.update_pattern(x) {
            self.adopt_pattern(problem, x)?;
        }
        if !problem.has_convexified_hessian() {
            // Chosen for its fill, the multilevel path gives way to the factor (which fits the
            // budget) for a problem it cannot solve.
            self.cholesky
                .fall_back_to_direct(problem.pattern(), self.params.cholesky)
                .map_err(Failure::Factorization)?;
        }
        if let Some(multilevel) = self.cholesky.multilevel_mut() {
            // The multilevel path gives no inertia: it blends towards the convexified Hessian
            // where CG meets negative curvature (docs/solvers.md §2.5).
            multilevel
                .prepare(problem, x)
                .map_err(Failure::Factorization)?;
            if self.params.indefinite == IndefinitePolicy::NewtonIfDescent {
                self.params.indefinite = IndefinitePolicy::ConvexBlend;
                let result = self.minimize_iterations(problem, x, report);
                self.params.indefinite = IndefinitePolicy::NewtonIfDescent;
                return result;
            }
        }
        self.minimize_iterations(problem, x, report)
    }

    /// [`Newton::minimize_into`] with the linear solver as it is.
    #[track_caller]
    fn minimize_iterations(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &mut [f64],
        report: &mut NewtonReport,
    ) -> Result<(), Failure> {
        let n = problem.dim();
        assert_eq!(x.len(), n, "unknowns");
        assert_eq!(
            self.g.len(),
            n,
            "the problem's dimension changed since the analysis"
        );
        let start = Instant::now();
        let mut p = self.params;
        p.validate().map_err(Failure::InvalidParameter)?;
        if p.indefinite.is_projected() && !problem.has_definite_hessian() {
            p.indefinite = IndefinitePolicy::ConvexBlend;
        }
        if p.indefinite == IndefinitePolicy::ProjectedPreconditioned
            && self.cholesky.multilevel().is_some()
        {
            // No factor to precondition with on the multilevel path.
            p.indefinite = IndefinitePolicy::Projected;
        }
        if p.indefinite == IndefinitePolicy::ConvexBlend && !problem.has_convexified_hessian() {
            p.indefinite = IndefinitePolicy::NewtonIfDescent;
        }
        let mut phi = problem.objective(x);
        problem.gradient(x, &mut self.g);
        let g0 = dot(&self.g, &self.g).sqrt();
        let scale = if g0 > 0.0 { 1.0 / g0 } else { 1.0 };
        report.reset(phi);
        report.convergence = p.convergence;
        let step_test = p.convergence == Convergence::StepSize;
        // Every solve starts from the exact Hessian: a shift earned in an earlier solve says nothing
        // about this one.
        self.shift = 0.0;
        self.exact_next = false;
        self.exact_pause = 0;
        self.exact_backoff = 0;
        let finish = |r: &mut NewtonReport, stop| {
            r.stop = stop;
            r.wall_time = start.elapsed();
        };
        let mut gradient = g0 * scale;
        // Solve by the held factor (with pauses after refused attempts), except after a reused
        // step the line search refused, until the next full step.
        let reuse_on = p.factor_reuse.is_on() && p.indefinite != IndefinitePolicy::NewtonIfDescent;
        let mut reuse = reuse_on;
        loop {
            if !(phi.is_finite() && gradient.is_finite()) {
                finish(report, StopReason::NonFinite);
                return Err(Failure::NonFinite);
            }
            if gradient == 0.0 || g0 == 0.0 {
                // A stationary point exactly: the Newton step is zero.
                report.step_size = 0.0;
                finish(report, StopReason::Converged);
                return Ok(());
            }
            if !step_test && gradient <= p.tolerance {
                finish(report, StopReason::Converged);
                return Ok(());
            }
            if report.iterations >= p.max_iterations {
                finish(report, StopReason::IterationLimit);
                return Ok(());
            }
            if report.iterations > 0 && problem.update_pattern(x) {
                self.adopt_pattern(problem, x)?;
            }
            // Whether this iteration tries the exact Hessian under ProjectedThenExact.
            let mut exact_try = p.indefinite == IndefinitePolicy::ProjectedThenExact
                && self.exact_next
                && self.shift == 0.0;
            let mut failed = 0;
            let (accepted, negative, step_slope, small) = if p.indefinite
                == IndefinitePolicy::ProjectedPreconditioned
            {
                match self.preconditioned_step(problem, x, &p, gradient, report)? {
                    Some((accepted, slope)) => {
                        let small =
                            step_test && self.shift == 0.0 && report.step_size <= p.tolerance;
                        (accepted, 0, slope, small)
                    }
                    None => {
                        let stop = self.refused_search_stop(problem, x);
                        finish(report, stop);
                        return match stop {
                            StopReason::RoundOff => Ok(()),
                            _ => Err(Failure::LineSearchFailed),
                        };
                    }
                }
            } else {
                {
                    let h = if p.indefinite.is_projected() && !exact_try {
                        problem
                            .definite_hessian(x)
                            .expect("has_definite_hessian promised a matrix")
                    } else {
                        problem.hessian(x)
                    };
                    assert_eq!(
                        h.val().len(),
                        self.hessian.len(),
                        "the Hessian's pattern changed"
                    );
                    self.hessian.copy_from_slice(h.val());
                    self.convex_current = false;
                }
                // Factor H + μD and search along its Newton step; raise μ until a step is accepted.
                // Set when a search below has left the positive definite factor of the current
                // shift.
                let mut held_definite = false;
                // The accepted step, the negative eigenvalues of its matrix, its slope gᵀΔ, and
                // whether it met the step-size criterion.
                loop {
                    let mut reused = false;
                    let negative = if held_definite {
                        held_definite = false;
                        Some(0)
                    } else if reuse
                        && failed == 0
                        && self.shift == 0.0
                        && self.solve_by_held_factor(problem, x, p.indefinite, report)
                    {
                        reused = true;
                        Some(0)
                    } else {
                        match self.factor_at_shift(problem, x, p.indefinite, report) {
                            Ok(inertia) if inertia.is_positive_definite() => Some(0),
                            Ok(inertia) if p.indefinite == IndefinitePolicy::NewtonIfDescent => {
                                Some(inertia.negative)
                            }
                            Ok(_)
                            | Err(
                                CholeskyError::Singular { .. }
                                | CholeskyError::NotPositiveDefinite { .. },
                            ) => None,
                            Err(e) => return Err(Failure::Factorization(e)),
                        }
                    };
                    if let Some(negative) = negative {
                        if !reused {
                            // Δ = −(H + μD)⁻¹ g
                            for (s, g) in self.step.iter_mut().zip(&self.g) {
                                *s = -g;
                            }
                            self.cholesky.solve_slice(&mut self.step);
                        }
                        let slope = dot(&self.g, &self.step);
                        let size = problem.step_size(&self.step);
                        // Only a step of a matrix without the mass shift estimates the distance to
                        // the solution (a shift shortens it at will).
                        let unshifted = negative == 0
                            && match p.indefinite {
                                IndefinitePolicy::ConvexBlend => self.shift <= 1.0,
                                _ => self.shift == 0.0,
                            };
                        let small = step_test && unshifted && size <= p.tolerance;
                        report.step_size = size;
                        if slope < 0.0 {
                            if let Some(accepted) = self.line_search(problem, x, slope) {
                                break (accepted, negative, slope, small);
                            }
                            if small {
                                // The criterion holds at x: what is left is below the tolerance (and,
                                // as no step of it lowers Φ, at the resolution of Φ).
                                report.failed_factorizations += failed;
                                finish(report, StopReason::Converged);
                                return Ok(());
                            }
                            if reused {
                                // Judge the matrix by its own factor before giving up.
                                reuse = false;
                                continue;
                            }
                            if negative == 0 {
                                report.failed_factorizations += failed;
                                let stop = self.refused_search_stop(problem, x);
                                finish(report, stop);
                                return match stop {
                                    StopReason::RoundOff => Ok(()),
                                    _ => Err(Failure::LineSearchFailed),
                                };
                            }
                        }
                        if reused {
                            // An ascent direction from CG (only with rounding): factor instead.
                            reuse = false;
                            continue;
                        }
                    }
                    failed += 1;
                    if exact_try {
                        // The exact Hessian is not definite here: factor the definite one, and pause
                        // before the next try.
                        exact_try = false;
                        self.exact_next = false;
                        self.exact_backoff = (2 * self.exact_backoff).clamp(1, MAX_REUSE_BACKOFF);
                        self.exact_pause = self.exact_backoff;
                        let h = problem
                            .definite_hessian(x)
                            .expect("has_definite_hessian promised a matrix");
                        self.hessian.copy_from_slice(h.val());
                        self.convex_current = false;
                        continue;
                    }
                    let exhausted = if p.indefinite == IndefinitePolicy::ConvexBlend {
                        match self.search_definite_shift(problem, x, report, &mut failed)? {
                            Some(held) => {
                                held_definite = held;
                                false
                            }
                            None => true,
                        }
                    } else {
                        self.shift = self.raise_shift(p.indefinite);
                        self.shift > p.max_shift
                    };
                    if exhausted {
                        report.failed_factorizations += failed;
                        finish(report, StopReason::NotPositiveDefinite);
                        return Err(Failure::NotPositiveDefinite {
                            max_shift: p.max_shift,
                        });
                    }
                }
            };
            report.failed_factorizations += failed;
            let Accepted {
                alpha,
                change,
                longest,
            } = accepted;
            x.copy_from_slice(&self.trial);
            // The quadratic model of an exact, positive definite Newton step predicts the change
            // ½ gᵀΔ; agreement within the tolerance means Newton is in its quadratic regime.
            let trusted = p.relaxation.trusted_model > 0.0
                && self.shift == 0.0
                && negative == 0
                && alpha == 1.0
                && (change / (0.5 * step_slope) - 1.0).abs() <= p.relaxation.trusted_model;
            if trusted && !p.relaxation.is_none() {
                report.skipped_relaxations += 1;
            } else if !p.relaxation.is_none() {
                let relaxing = Instant::now();
                if let Some(work) = problem.relax(x, p.relaxation) {
                    report.relaxation_sweeps += work.sweeps;
                    report.focused_sweeps += work.focused_sweeps;
                    report.relaxed_blocks += work.block_visits;
                    report.region_solves += work.region_solves;
                    report.skipped_regions += work.skipped_regions;
                    report.region_blocks += work.region_blocks;
                    report.region_iterations += work.region_iterations;
                    report.region_factorizations += work.region_factorizations;
                    report.relaxation_time += relaxing.elapsed();
                }
            }
            // A shortened step that lowers Φ by no more than its round-off: further iterations
            // would only inflate the shift. Stop; converged only if the gradient is at its proven
            // rounding floor (checked below, at the new iterate), stagnated otherwise.
            let stagnated = alpha < 1.0 && -change <= STAGNATION_ULPS * f64::EPSILON * phi.abs();
            // A problem that changed Φ (a stiffer barrier) has a new minimum to go to: no stop
            // for stagnation on the old one.
            let adapted = !small && problem.after_iterate(x);
            let stagnated = stagnated && !adapted;
            phi = problem.objective(x);
            problem.gradient(x, &mut self.g);
            gradient = dot(&self.g, &self.g).sqrt() * scale;
            report.iterations += 1;
            if self.shift > 0.0 {
                report.shifted_steps += 1;
            }
            if negative > 0 {
                report.indefinite_steps += 1;
            }
            report.history.push(NewtonIteration {
                gradient,
                objective: phi,
                shift: self.shift,
                failed_factorizations: failed,
                negative_eigenvalues: negative,
                step_length: alpha,
                step_size: report.step_size,
            });
            if small {
                finish(report, StopReason::Converged);
                return Ok(());
            }
            if stagnated {
                let floor = problem.gradient_round_off(x);
                let norm = dot(&self.g, &self.g).sqrt();
                let stop = if !step_test && gradient <= p.tolerance {
                    StopReason::Converged
                } else if norm <= floor {
                    StopReason::RoundOff
                } else {
                    StopReason::Stagnated
                };
                finish(report, stop);
                return Ok(());
            }
            // A full step means the model is trusted: relax the shift. A short one: stiffen it.
            // (Full and short relative to the longest step the problem allowed: a step cut short
            // by an obstacle says nothing about the model.)
            if alpha == 1.0 {
                reuse = reuse_on;
            }
            if exact_try {
                // An exact matrix factored: the pause after failures ends.
                self.exact_backoff = 0;
            }
            if p.indefinite == IndefinitePolicy::ProjectedThenExact {
                // Go exact after a full step, unless pausing after failed tries.
                self.exact_next = alpha == longest && self.exact_pause == 0;
                if alpha == longest && self.exact_pause > 0 {
                    self.exact_pause -= 1;
                }
            }
            if alpha == longest {
                self.shift = self.lower_shift(p.indefinite);
            } else if alpha < 0.25 * longest && !p.indefinite.is_projected() {
                // (The projected matrix is shifted only where it failed to factor.)
                self.shift = self.raise_shift(p.indefinite).min(p.max_shift);
            }
        }
    }
}
