//! Time integrators and their settings.
//!
//! [`Settings`] holds the method and every solver's parameters. [`SolverOptions`] is the
//! method-independent way to set them (β, the linear solver, an iteration count, a tolerance): the
//! scene file's `[integrator]` section and `hooke run`'s flags both go through
//! [`Settings::apply_options`], so the same words give the same settings.

use std::fmt;
use std::str::FromStr;

use hooke_assembly::Definiteness;

use crate::SimError;
use hooke_solvers::ParamError;

/// A time integration method (docs/model.md §6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Integrator {
    /// Forward Euler: v⁺ = v + h M⁻¹ f(x, v), x⁺ = x + h v. Unstable for undamped springs at any
    /// step (its amplification factor exceeds 1): it gains energy, slowly at small steps.
    ExplicitEuler,
    /// Symplectic (semi-implicit) Euler, in the 2D sketch's order (docs/model.md §6.2):
    /// v⁺ = v + h M⁻¹ f(x, v), drag, x⁺ = x + h v⁺, contact. Stable below the step bound; energy oscillates
    /// but does not drift.
    SymplecticEuler,
    /// Linearised implicit Euler of the β family (docs/model.md §6.3):
    /// [M − β h² ∂f/∂x(x)] v⁺ = M v + h f(x), x⁺ = x + h v⁺, one sparse linear solve per step by
    /// Jacobi or conjugate gradient, with [`Settings::linearized`]'s parameters. β = 1 is one Newton
    /// step of backward Euler from x_n. See the `linearized` module docs for how each scene term
    /// enters.
    Linearized,
    /// Backward Euler solved by Newton's method (docs/model.md §6.5) to [`Settings::newton`]'s
    /// tolerance. Unconditionally stable; dissipates energy.
    Newton,
    /// Backward Euler solved approximately by projective dynamics (Liu et al. 2013) with
    /// [`Settings::pd`]'s iteration budget; converges to the Newton solution as iterations grow.
    ProjectiveDynamics,
    /// Backward Euler solved by L-BFGS (Liu, Bouaziz and Kavan 2017) to [`Settings::lbfgs`]'s
    /// tolerance: the same Φ as Newton (every force, damping and pin method), the prefactored PD
    /// matrix K(A + h²L)Kᵀ as the initial inverse Hessian (one solve per iteration, no
    /// factorisation per step), a line search that never accepts a rise of Φ. Like projective
    /// dynamics it runs to a budget: a step that reaches the iteration limit keeps its last iterate
    /// and is reported as not converged (halving, as Newton does, would split a stiff frame into
    /// hundreds of pieces at L-BFGS's linear rate).
    Lbfgs,
    /// Backward Euler solved by truncated Newton ([`Settings::newton_cg`]): conjugate gradient on
    /// the exact Hessian, preconditioned by the PD factor, with Eisenstat–Walker forcing terms and
    /// truncation at negative curvature (no factorisation per iteration). Every force, damping and
    /// pin method Newton supports; halved as Newton's.
    NewtonCg,
    /// Projective dynamics with Chebyshev acceleration (Wang 2015, [`Settings::chebyshev`]): ρ
    /// estimated from plain PD on the first step ([`Settings::chebyshev_estimate`]), and a restart
    /// to the plain PD iterate whenever Φ would rise, so that it never gains energy where plain PD
    /// does not. The same terms as [`Integrator::ProjectiveDynamics`].
    ChebyshevPd,
}

impl Integrator {
    /// Every integrator, in the order the command lists them.
    pub const ALL: &'static [Integrator] = &[
        Integrator::ExplicitEuler,
        Integrator::SymplecticEuler,
        Integrator::Linearized,
        Integrator::Newton,
        Integrator::ProjectiveDynamics,
        Integrator::Lbfgs,
        Integrator::NewtonCg,
        Integrator::ChebyshevPd,
    ];

    /// The name used in scene files and on the command line (`explicit-euler`, `symplectic-euler`,
    /// `linearized`, `newton`, `pd`, `lbfgs`, `newton-cg`, `pd-chebyshev`).
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::ExplicitEuler => "explicit-euler",
            Integrator::SymplecticEuler => "symplectic-euler",
            Integrator::Linearized => "linearized",
            Integrator::Newton => "newton",
            Integrator::ProjectiveDynamics => "pd",
            Integrator::Lbfgs => "lbfgs",
            Integrator::NewtonCg => "newton-cg",
            Integrator::ChebyshevPd => "pd-chebyshev",
        }
    }

    /// What the residual in this integrator's [`hooke_solvers::SolveSummary::residual`] is, and
    /// its unit: (quantity, unit), `None` for the explicit methods, which solve nothing.
    /// - `newton`, `lbfgs`, `newton-cg`: their convergence criterion's quantity, by default the
    ///   step size, the largest vertex displacement of the last (quasi-)Newton step divided by h
    ///   (m/s; the largest over the pieces of a halved step);
    /// - `pd`, `pd-chebyshev`: the largest change of a position coordinate in the last iteration
    ///   (m);
    /// - `linearized`: the relative linear residual ‖b − A v‖ / ‖b‖ (dimensionless).
    pub fn solver_residual(&self) -> Option<(&'static str, &'static str)> {
        match self {
            Integrator::Newton | Integrator::Lbfgs | Integrator::NewtonCg => Some((
                "step size: the largest vertex displacement of the last Newton step / h",
                "m/s",
            )),
            Integrator::ProjectiveDynamics | Integrator::ChebyshevPd => {
                Some(("largest position change in the last iteration / h", "m/s"))
            }
            Integrator::Linearized => Some(("relative linear residual |b - A v| / |b|", "1")),
            Integrator::ExplicitEuler | Integrator::SymplecticEuler => None,
        }
    }

    /// True for the integrators whose contact is part of the minimised objective Φ (newton,
    /// newton-cg, lbfgs): a barrier per vertex and obstacle, with lagged friction, and line
    /// searches that never cross an obstacle (docs/contact.md). The others project vertices
    /// after their steps or substeps.
    pub fn uses_contact_barrier(&self) -> bool {
        matches!(
            self,
            Integrator::Newton | Integrator::NewtonCg | Integrator::Lbfgs
        )
    }

    /// True for the integrators that handle contact inside their solve: the barrier ones
    /// ([`Integrator::uses_contact_barrier`]) and projective dynamics with Chebyshev's
    /// acceleration or without (contact targets in the global step, every iterate kept outside
    /// the obstacles: docs/contact.md). The explicit and linearised integrators project vertices
    /// after their steps or substeps.
    pub fn contact_in_solve(&self) -> bool {
        self.uses_contact_barrier()
            || matches!(
                self,
                Integrator::ProjectiveDynamics | Integrator::ChebyshevPd
            )
    }

    /// True for the explicit methods, which have a step-size limit and take substeps.
    pub fn is_explicit(&self) -> bool {
        matches!(
            self,
            Integrator::ExplicitEuler | Integrator::SymplecticEuler
        )
    }
}

impl fmt::Display for Integrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown integrator name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown integrator {name:?}; expected one of: {}", Integrator::ALL.iter().map(|i| i.name()).collect::<Vec<_>>().join(", "))]
pub struct UnknownIntegrator {
    /// The name that was given.
    pub name: String,
}

impl FromStr for Integrator {
    type Err = UnknownIntegrator;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "explicit-euler" | "forward-euler" => Ok(Integrator::ExplicitEuler),
            "symplectic-euler" | "semi-implicit-euler" => Ok(Integrator::SymplecticEuler),
            "linearized" | "linearised" | "linearized-euler" => Ok(Integrator::Linearized),
            "newton" | "backward-euler" => Ok(Integrator::Newton),
            "pd" | "projective-dynamics" => Ok(Integrator::ProjectiveDynamics),
            "lbfgs" | "l-bfgs" | "quasi-newton" => Ok(Integrator::Lbfgs),
            "newton-cg" | "truncated-newton" => Ok(Integrator::NewtonCg),
            "pd-chebyshev" | "chebyshev" => Ok(Integrator::ChebyshevPd),
            other => Err(UnknownIntegrator {
                name: other.to_string(),
            }),
        }
    }
}

/// The linear solver of the linearised integrator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum LinearSolver {
    /// Block Jacobi (3×3 blocks in 3D, docs/solvers.md §2.2): cheap iterations, but converges only
    /// when the system is block diagonally dominant enough (small β h² k / m); otherwise it reports
    /// divergence.
    Jacobi,
    /// Conjugate gradient with the block-Jacobi preconditioner (the default): converges for every
    /// symmetric positive definite system.
    #[default]
    ConjugateGradient,
}

impl LinearSolver {
    /// Every linear solver, in the order the command lists them.
    pub const ALL: &'static [LinearSolver] =
        &[LinearSolver::Jacobi, LinearSolver::ConjugateGradient];

    /// The name used in scene files and on the command line (`jacobi`, `cg`).
    pub fn name(&self) -> &'static str {
        match self {
            LinearSolver::Jacobi => "jacobi",
            LinearSolver::ConjugateGradient => "cg",
        }
    }
}

impl fmt::Display for LinearSolver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Newton's nonlinear relaxation between its steps, by preset ([`hooke_solvers::Relaxation`]):
/// the `relaxation` key of a scene file's `[integrator]` section and `hooke run --relaxation`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum RelaxationPreset {
    /// Plain Newton, the default ([`hooke_solvers::Relaxation::NONE`]).
    #[default]
    None,
    /// Block sweeps and the nonlinear elimination of folds
    /// ([`hooke_solvers::Relaxation::BUCKLING`]): faster on crushed cloth and large buckling
    /// steps, slower on most other scenes (`benches/results/issue15-newton-default.md`).
    Buckling,
}

impl RelaxationPreset {
    /// Every preset, in the order the command lists them.
    pub const ALL: &'static [RelaxationPreset] =
        &[RelaxationPreset::None, RelaxationPreset::Buckling];

    /// The name used in scene files and on the command line (`none`, `buckling`).
    pub fn name(&self) -> &'static str {
        match self {
            RelaxationPreset::None => "none",
            RelaxationPreset::Buckling => "buckling",
        }
    }

    /// The solver's settings of this preset.
    pub fn relaxation(&self) -> hooke_solvers::Relaxation {
        match self {
            RelaxationPreset::None => hooke_solvers::Relaxation::NONE,
            RelaxationPreset::Buckling => hooke_solvers::Relaxation::BUCKLING,
        }
    }

    /// The preset whose settings these are, if any (a caller may set others by hand).
    pub fn of(relaxation: &hooke_solvers::Relaxation) -> Option<RelaxationPreset> {
        Self::ALL
            .iter()
            .copied()
            .find(|preset| preset.relaxation() == *relaxation)
    }
}

impl fmt::Display for RelaxationPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown relaxation preset name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown relaxation {name:?}; expected \"none\" or \"buckling\"")]
pub struct UnknownRelaxation {
    /// The name that was given.
    pub name: String,
}

impl FromStr for RelaxationPreset {
    type Err = UnknownRelaxation;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "none" => Ok(RelaxationPreset::None),
            "buckling" => Ok(RelaxationPreset::Buckling),
            _ => Err(UnknownRelaxation { name: s.into() }),
        }
    }
}

/// An unknown linear solver name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown linear solver {name:?}; expected \"jacobi\" or \"cg\"")]
pub struct UnknownLinearSolver {
    /// The name that was given.
    pub name: String,
}

impl FromStr for LinearSolver {
    type Err = UnknownLinearSolver;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "jacobi" => Ok(LinearSolver::Jacobi),
            "cg" | "conjugate-gradient" => Ok(LinearSolver::ConjugateGradient),
            other => Err(UnknownLinearSolver {
                name: other.to_string(),
            }),
        }
    }
}

/// How the implicit integrators hold pinned vertices (docs/model.md §5).
///
/// Both methods solve the same system for the free vertices and give the same steps up to
/// round-off (see [`hooke_assembly::CounterForce`]); a pinned vertex is at its prescribed position
/// after every step either way. The explicit integrators solve no system and hold pinned vertices
/// the same way under both settings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum PinMethod {
    /// Remove the pinned DOFs from the unknowns (docs/model.md §5.2, the default): the
    /// smallest system.
    #[default]
    Reduction,
    /// Keep every DOF an unknown and cancel the force on each pinned vertex by a counter-force,
    /// with its derivative in the Jacobian (docs/model.md §5.3): the pinned rows and columns
    /// of the system become m_p I. Supported by `newton` and `linearized`; `pd` refuses it with
    /// [`SimError::Unsupported`] (its one constant matrix would only gain decoupled rows: the
    /// counter-force has no Jacobian to enter a matrix that never holds the force's).
    CounterForce,
}

impl PinMethod {
    /// Both methods, in the order the command lists them.
    pub const ALL: &'static [PinMethod] = &[PinMethod::Reduction, PinMethod::CounterForce];

    /// The name used in scene files and on the command line (`reduction`, `counter-force`).
    pub fn name(&self) -> &'static str {
        match self {
            PinMethod::Reduction => "reduction",
            PinMethod::CounterForce => "counter-force",
        }
    }
}

impl fmt::Display for PinMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown pin method name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown pin method {name:?}; expected \"reduction\" or \"counter-force\"")]
pub struct UnknownPinMethod {
    /// The name that was given.
    pub name: String,
}

impl FromStr for PinMethod {
    type Err = UnknownPinMethod;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "reduction" => Ok(PinMethod::Reduction),
            "counter-force" | "counter-forces" => Ok(PinMethod::CounterForce),
            other => Err(UnknownPinMethod {
                name: other.to_string(),
            }),
        }
    }
}

/// Settings of the linearised integrator ([`Integrator::Linearized`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearizedParams {
    /// β in [0, 1] (dimensionless): 0 is explicit (the matrix is M plus the damping terms), ½ the
    /// midpoint-like rule, 1 linearised backward Euler. Default 1, the unconditionally stable member
    /// for linear springs.
    pub beta: f64,
    /// Jacobi or conjugate gradient. Default conjugate gradient (converges on any SPD system).
    pub solver: LinearSolver,
    /// Stop the linear solve at ‖b − A v‖ ≤ `tolerance` · ‖b‖ (relative residual). Default 1e-8:
    /// far below the linearisation error of the step itself.
    pub tolerance: f64,
    /// Iteration limit of the linear solve. Default 1000. A solve that reaches it is kept, and
    /// reported with [`hooke_solvers::StopReason::IterationLimit`] in the step's report (never as
    /// converged).
    pub max_iterations: usize,
    /// The spring Hessian in ∂f/∂x: exact (default; then β = 1 is exactly one Newton step) or
    /// clamped (always positive semidefinite, see [`Definiteness`]).
    pub definiteness: Definiteness,
    /// With the exact Hessian, when the system is found not to be positive definite (CG meets
    /// pᵀAp ≤ 0, or Jacobi diverges; compressed springs at large β h² k / m), refill it with the
    /// clamped Hessian and solve again, counting it in
    /// [`StepReport::clamped_hessian`](crate::StepReport::clamped_hessian). Default true; false
    /// turns that case into [`SimError::LinearSolve`].
    pub clamp_on_failure: bool,
}

impl Default for LinearizedParams {
    fn default() -> Self {
        LinearizedParams {
            beta: 1.0,
            solver: LinearSolver::ConjugateGradient,
            tolerance: 1e-8,
            max_iterations: 1000,
            definiteness: Definiteness::Exact,
            clamp_on_failure: true,
        }
    }
}

impl LinearizedParams {
    /// Check β ∈ [0, 1], a finite positive tolerance and at least one iteration.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the parameter.
    pub fn validate(&self) -> Result<(), SimError> {
        check_beta(self.beta)?;
        check_tolerance(self.tolerance)?;
        check_iterations(self.max_iterations)?;
        Ok(())
    }
}

fn check_beta(beta: f64) -> Result<f64, SimError> {
    if (0.0..=1.0).contains(&beta) {
        Ok(beta)
    } else {
        Err(SimError::invalid("beta", beta, "must be in [0, 1]"))
    }
}

fn check_tolerance(tolerance: f64) -> Result<f64, SimError> {
    if tolerance > 0.0 && tolerance.is_finite() {
        Ok(tolerance)
    } else {
        Err(SimError::invalid(
            "tolerance",
            tolerance,
            "must be finite and positive",
        ))
    }
}

fn check_iterations(iterations: usize) -> Result<usize, SimError> {
    if iterations >= 1 {
        Ok(iterations)
    } else {
        Err(SimError::invalid("iterations", 0, "must be at least 1"))
    }
}

/// How a simulation integrates time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// The method.
    pub integrator: Integrator,
    /// Substeps per frame for explicit methods; `None` picks the fewest that keep each substep under
    /// the safe stability bound.
    pub substeps: Option<usize>,
    /// Let an explicit method run with a step above its estimated stability bound (it will likely
    /// blow up, and then stop with [`crate::SimError::NonFinite`]).
    pub allow_unstable: bool,
    /// Use rayon for the per-spring and per-vertex loops, in every integrator (results are
    /// identical either way). It overrides [`hooke_solvers::PdParams::parallel`] and sets
    /// Newton's objective's loops ([`hooke_solvers::BackwardEulerStep::set_parallel`]).
    pub parallel: bool,
    /// Energy watchdog (dimensionless factor; default 1): stop with
    /// [`SimError::EnergyGrowth`] when the total energy exceeds E₀ + `energy_limit` · (|E₀| + E_g),
    /// E₀ the energy at the start and E_g = M |g| L the scene's gravitational energy scale (total
    /// mass, gravity, diagonal of the initial bounding box). Without energy sources the exact
    /// motion keeps E = E₀ and damping and contact only lower it, so a run that gains more than the
    /// scene's own energy scale is an instability (explicit methods past their bound, the
    /// linearised step overshooting), not physics. Only checked for scenes without energy sources
    /// (no wind, no pins on a path), and not when [`Settings::allow_unstable`] forces the run (the
    /// divergence checks still stop an explosion); `None` turns it off. Set from text by
    /// `hooke run --energy-limit FACTOR|off` and the scene file key `integrator.energy_limit` (see
    /// [`parse_energy_limit`]); a factor that is negative or not finite is refused by
    /// [`Settings::set_energy_limit`] and by [`crate::Simulation::new`].
    pub energy_limit: Option<f64>,
    /// How the implicit integrators hold pinned vertices (default: [`PinMethod::Reduction`]). Set
    /// from text by `hooke run --pin-method` and the scene file key `integrator.pin_method`.
    pub pins: PinMethod,
    /// The linearised integrator's settings (default: β = 1, CG to 1e-8).
    pub linearized: LinearizedParams,
    /// Newton's settings (default: step size 1e-5 m/s, [`hooke_solvers::DEFAULT_STEP_TOLERANCE`]).
    pub newton: hooke_solvers::NewtonParams,
    /// Projective dynamics' settings (default: 10 iterations). Its factorisation settings also
    /// serve the PD matrix of `lbfgs`, `newton-cg` and `pd-chebyshev`.
    pub pd: hooke_solvers::PdParams,
    /// L-BFGS's settings (default: step size 1e-5 m/s, 100 iterations, history 5).
    pub lbfgs: hooke_solvers::LbfgsParams,
    /// Newton-CG's settings (default: step size 1e-5 m/s, 100 iterations).
    pub newton_cg: hooke_solvers::NewtonCgParams,
    /// Chebyshev PD's settings (default: 10 iterations; its `rate` is the fallback when the
    /// estimate does not form, or the ρ used when [`Settings::chebyshev_estimate`] is `None`).
    pub chebyshev: hooke_solvers::ChebyshevParams,
    /// Plain PD iterations from which Chebyshev PD estimates ρ on its first step
    /// ([`hooke_solvers::ProjectiveDynamics::estimate_rate`]), in 4..=[`MAX_RATE_ESTIMATE`];
    /// `None` uses [`Settings::chebyshev`]'s `rate` as given. Default `Some(20)`.
    pub chebyshev_estimate: Option<usize>,
}

/// The most plain PD iterations [`Settings::chebyshev_estimate`] may ask for.
pub const MAX_RATE_ESTIMATE: usize = 10_000;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            integrator: Integrator::SymplecticEuler,
            substeps: None,
            allow_unstable: false,
            parallel: true,
            energy_limit: Some(1.0),
            pins: PinMethod::Reduction,
            linearized: LinearizedParams::default(),
            newton: hooke_solvers::NewtonParams::default(),
            pd: hooke_solvers::PdParams::default(),
            lbfgs: hooke_solvers::LbfgsParams::default(),
            newton_cg: hooke_solvers::NewtonCgParams::default(),
            chebyshev: hooke_solvers::ChebyshevParams::default(),
            chebyshev_estimate: Some(20),
        }
    }
}

/// The energy watchdog's setting ([`Settings::energy_limit`]) as `hooke run --energy-limit` and a
/// scene file's `integrator.energy_limit` write it: a factor (a finite number ≥ 0,
/// dimensionless), or `off` (also `none`) to turn the watchdog off.
///
/// # Errors
/// [`SimError::InvalidParameter`] (name "energy limit") for anything else, including a negative,
/// infinite or NaN factor.
pub fn parse_energy_limit(text: &str) -> Result<Option<f64>, SimError> {
    let text = text.trim();
    if text.eq_ignore_ascii_case("off") || text.eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(factor) => check_energy_limit(factor).map(Some),
        Err(_) => Err(SimError::invalid(
            "energy limit",
            text,
            "expected a factor (a number >= 0) or \"off\"",
        )),
    }
}

fn check_energy_limit(factor: f64) -> Result<f64, SimError> {
    if factor >= 0.0 && factor.is_finite() {
        Ok(factor)
    } else {
        Err(SimError::invalid(
            "energy limit",
            factor,
            "the factor must be finite and >= 0 (use \"off\" to turn the watchdog off)",
        ))
    }
}

/// Solver settings given by name, as a scene file's `[integrator]` section and `hooke run`'s flags
/// give them. `None` keeps the current value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolverOptions {
    /// β of the linearised integrator, in [0, 1].
    pub beta: Option<f64>,
    /// The linearised integrator's linear solver.
    pub linear_solver: Option<LinearSolver>,
    /// Iterations: the linear solver's limit (linearized), Newton's iteration limit (newton), the
    /// iterations per step (pd). At least 1.
    pub iterations: Option<usize>,
    /// Tolerance: the linear solver's relative residual (linearized, dimensionless); the step
    /// size of newton, newton-cg and lbfgs (m/s); PD's and Chebyshev PD's position change per
    /// iteration divided by h (m/s). Finite; > 0 for the linearised integrator, ≥ 0 for the others
    /// (0: Newton stops only at its iteration limit, PD always runs its iterations).
    pub tolerance: Option<f64>,
    /// Newton's relaxation preset (newton only).
    pub relaxation: Option<RelaxationPreset>,
    /// Newton's factor reuse (newton only): the CG iterations allowed on the factor held from an
    /// earlier Newton matrix before the matrix is factored ([`hooke_solvers::FactorReuse`]);
    /// 0 factors every Newton matrix.
    pub factor_reuse: Option<usize>,
    /// The memory a sparse Cholesky factor may take ([`hooke_solvers::CholeskyParams::memory_budget`],
    /// docs/solvers.md §2.5): Newton's (above it Newton takes the multilevel path) and the PD
    /// matrix's of pd, pd-chebyshev, lbfgs and newton-cg (above it, under the automatic global
    /// solve, their multilevel global step, docs/solvers.md §6.1). Implicit integrators that
    /// factor a matrix only.
    pub memory_budget: Option<hooke_solvers::MemoryBudget>,
    /// How the PD matrix is solved ([`hooke_solvers::PdParams::global_solve`], docs/solvers.md
    /// §6.1): pd, pd-chebyshev, lbfgs and newton-cg only.
    pub pd_global_solve: Option<hooke_solvers::GlobalSolveKind>,
}

impl Settings {
    /// Check every setting, whichever integrator is chosen (a scene file or a caller may switch
    /// integrators later): `substeps` at least 1 if given; `energy_limit` finite and ≥ 0 if on;
    /// [`LinearizedParams::validate`], [`hooke_solvers::NewtonParams::validate`] and
    /// [`hooke_solvers::PdParams::validate`]. [`crate::Simulation::new`] calls it.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for the simulation's own settings,
    /// [`SimError::SolverParameter`] (naming the solver's field and its range) for the solvers'.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.substeps == Some(0) {
            return Err(SimError::invalid("substeps", 0, "must be at least 1"));
        }
        if let Some(factor) = self.energy_limit {
            check_energy_limit(factor)?;
        }
        self.linearized.validate()?;
        self.newton.validate()?;
        self.pd.validate()?;
        self.lbfgs.validate()?;
        self.newton_cg.validate()?;
        self.chebyshev.validate()?;
        if let Some(k) = self.chebyshev_estimate {
            if !(4..=MAX_RATE_ESTIMATE).contains(&k) {
                return Err(SimError::invalid(
                    "chebyshev_estimate",
                    k,
                    format!("must be in 4..={MAX_RATE_ESTIMATE} plain PD iterations"),
                ));
            }
        }
        Ok(())
    }

    /// Apply `options` to the solver of `self.integrator` (set the integrator first). The values
    /// are checked by that solver's own `validate` ([`LinearizedParams::validate`],
    /// [`hooke_solvers::NewtonParams::validate`], [`hooke_solvers::PdParams::validate`], and
    /// likewise L-BFGS's, Newton-CG's and Chebyshev PD's), the one
    /// rule for each: PD and Newton accept a tolerance of 0 (PD then always runs its iterations),
    /// the linearised integrator's linear solvers need a positive one. On an error the settings
    /// are unchanged.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for β or a linear solver for another integrator than
    /// `linearized`, iterations or a tolerance for an explicit integrator (which solves nothing),
    /// and every value out of its solver's range, named as the option is (`iterations`,
    /// `tolerance`, `factor reuse`) with the allowed range.
    pub fn apply_options(&mut self, options: &SolverOptions) -> Result<(), SimError> {
        let mut candidate = *self;
        candidate.apply_unchecked(options)?;
        // The linearised integrator's checks name the options already.
        if self.integrator == Integrator::Linearized {
            candidate.linearized.validate()?;
        }
        let checked = match self.integrator {
            Integrator::Newton => candidate.newton.validate(),
            Integrator::ProjectiveDynamics => candidate.pd.validate(),
            Integrator::Lbfgs => candidate.lbfgs.validate(),
            Integrator::NewtonCg => candidate.newton_cg.validate(),
            Integrator::ChebyshevPd => candidate.chebyshev.validate(),
            _ => Ok(()),
        };
        checked.map_err(|e| option_error(self.integrator, e))?;
        *self = candidate;
        Ok(())
    }

    /// [`Settings::apply_options`] without the solvers' range checks: only whether each option
    /// applies to the integrator.
    fn apply_unchecked(&mut self, options: &SolverOptions) -> Result<(), SimError> {
        let integrator = self.integrator;
        let only_linearized = |name: &str, value: String| {
            SimError::invalid(
                name,
                value,
                format!("applies only to the linearized integrator (this run uses {integrator})"),
            )
        };
        if let Some(beta) = options.beta {
            if integrator != Integrator::Linearized {
                return Err(only_linearized("beta", beta.to_string()));
            }
            self.linearized.beta = beta;
        }
        if let Some(solver) = options.linear_solver {
            if integrator != Integrator::Linearized {
                return Err(only_linearized("linear solver", solver.to_string()));
            }
            self.linearized.solver = solver;
        }
        let no_solver = |name: &str, value: String| {
            SimError::invalid(
                name,
                value,
                format!(
                    "{integrator} is explicit and solves no system; iterations and tolerance apply \
                     to the implicit integrators (linearized, newton, pd, lbfgs, newton-cg, \
                     pd-chebyshev)"
                ),
            )
        };
        if let Some(iterations) = options.iterations {
            match integrator {
                Integrator::Linearized => self.linearized.max_iterations = iterations,
                Integrator::Newton => self.newton.max_iterations = iterations,
                Integrator::ProjectiveDynamics => self.pd.max_iterations = iterations,
                Integrator::Lbfgs => self.lbfgs.max_iterations = iterations,
                Integrator::NewtonCg => self.newton_cg.max_iterations = iterations,
                Integrator::ChebyshevPd => self.chebyshev.max_iterations = iterations,
                _ => return Err(no_solver("iterations", iterations.to_string())),
            }
        }
        if let Some(preset) = options.relaxation {
            if integrator != Integrator::Newton {
                return Err(SimError::invalid(
                    "relaxation",
                    preset,
                    format!("applies only to the newton integrator (this run uses {integrator})"),
                ));
            }
            self.newton.relaxation = preset.relaxation();
        }
        if let Some(iterations) = options.factor_reuse {
            if integrator != Integrator::Newton {
                return Err(SimError::invalid(
                    "factor reuse",
                    iterations,
                    format!("applies only to the newton integrator (this run uses {integrator})"),
                ));
            }
            self.newton.factor_reuse.max_iterations = iterations;
        }
        if let Some(budget) = options.memory_budget {
            match integrator {
                Integrator::Newton => self.newton.cholesky.memory_budget = budget,
                Integrator::ProjectiveDynamics
                | Integrator::Lbfgs
                | Integrator::NewtonCg
                | Integrator::ChebyshevPd => self.pd.cholesky.memory_budget = budget,
                _ => {
                    return Err(SimError::invalid(
                        "memory budget",
                        budget,
                        format!(
                            "bounds a sparse Cholesky factor: it applies to newton, pd, \
                             pd-chebyshev, lbfgs and newton-cg (this run uses {integrator}, \
                             which factors nothing)"
                        ),
                    ))
                }
            }
        }
        if let Some(kind) = options.pd_global_solve {
            match integrator {
                Integrator::ProjectiveDynamics
                | Integrator::Lbfgs
                | Integrator::NewtonCg
                | Integrator::ChebyshevPd => self.pd.global_solve = kind,
                _ => {
                    return Err(SimError::invalid(
                        "PD global solve",
                        kind,
                        format!(
                            "applies to the integrators that solve with the PD matrix: pd, \
                             pd-chebyshev, lbfgs and newton-cg (this run uses {integrator})"
                        ),
                    ))
                }
            }
        }
        if let Some(tolerance) = options.tolerance {
            match integrator {
                Integrator::Linearized => self.linearized.tolerance = tolerance,
                Integrator::Newton => self.newton.tolerance = tolerance,
                Integrator::ProjectiveDynamics => self.pd.tolerance = tolerance,
                Integrator::Lbfgs => self.lbfgs.tolerance = tolerance,
                Integrator::NewtonCg => self.newton_cg.tolerance = tolerance,
                Integrator::ChebyshevPd => self.chebyshev.tolerance = tolerance,
                _ => return Err(no_solver("tolerance", tolerance.to_string())),
            }
        }
        Ok(())
    }

    /// Set the energy watchdog ([`Settings::energy_limit`]): `Some(factor)` (dimensionless, finite,
    /// ≥ 0) or `None` (off).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a negative, infinite or NaN factor (the settings are then
    /// unchanged).
    pub fn set_energy_limit(&mut self, limit: Option<f64>) -> Result<(), SimError> {
        if let Some(factor) = limit {
            check_energy_limit(factor)?;
        }
        self.energy_limit = limit;
        Ok(())
    }

    /// The settings of the chosen integrator's solver, by name, for reports: (β, linear solver,
    /// iterations, tolerance), each `None` where the integrator has no such setting.
    pub fn solver_options(&self) -> SolverOptions {
        match self.integrator {
            Integrator::Linearized => SolverOptions {
                beta: Some(self.linearized.beta),
                linear_solver: Some(self.linearized.solver),
                iterations: Some(self.linearized.max_iterations),
                tolerance: Some(self.linearized.tolerance),
                relaxation: None,
                factor_reuse: None,
                memory_budget: None,
                pd_global_solve: None,
            },
            Integrator::Newton => SolverOptions {
                iterations: Some(self.newton.max_iterations),
                tolerance: Some(self.newton.tolerance),
                relaxation: RelaxationPreset::of(&self.newton.relaxation),
                factor_reuse: Some(self.newton.factor_reuse.max_iterations),
                memory_budget: Some(self.newton.cholesky.memory_budget),
                ..SolverOptions::default()
            },
            Integrator::ProjectiveDynamics => SolverOptions {
                iterations: Some(self.pd.max_iterations),
                tolerance: Some(self.pd.tolerance),
                memory_budget: Some(self.pd.cholesky.memory_budget),
                pd_global_solve: Some(self.pd.global_solve),
                ..SolverOptions::default()
            },
            Integrator::Lbfgs => SolverOptions {
                iterations: Some(self.lbfgs.max_iterations),
                tolerance: Some(self.lbfgs.tolerance),
                memory_budget: Some(self.pd.cholesky.memory_budget),
                pd_global_solve: Some(self.pd.global_solve),
                ..SolverOptions::default()
            },
            Integrator::NewtonCg => SolverOptions {
                iterations: Some(self.newton_cg.max_iterations),
                tolerance: Some(self.newton_cg.tolerance),
                memory_budget: Some(self.pd.cholesky.memory_budget),
                pd_global_solve: Some(self.pd.global_solve),
                ..SolverOptions::default()
            },
            Integrator::ChebyshevPd => SolverOptions {
                iterations: Some(self.chebyshev.max_iterations),
                tolerance: Some(self.chebyshev.tolerance),
                memory_budget: Some(self.pd.cholesky.memory_budget),
                pd_global_solve: Some(self.pd.global_solve),
                ..SolverOptions::default()
            },
            _ => SolverOptions::default(),
        }
    }
}

/// A solver's range error about a field that a [`SolverOptions`] option sets, in the option's
/// words (`iterations`, `tolerance`, `factor reuse`: the names of the scene file's keys and the
/// command's flags, docs/formats.md §1.8) instead of the solver's field (`NewtonParams::max_iterations`),
/// which the user of the options never named. Other fields keep the solver's error.
fn option_error(integrator: Integrator, error: ParamError) -> SimError {
    let field = error.field();
    let option = if field == "FactorReuse::max_iterations" {
        "factor reuse"
    } else if field.starts_with("FactorReuse::") || field.contains('.') {
        return SimError::SolverParameter(error);
    } else if field.ends_with("::max_iterations") {
        "iterations"
    } else if field.ends_with("::tolerance") {
        "tolerance"
    } else {
        return SimError::SolverParameter(error);
    };
    let (value, allowed) = match error {
        ParamError::Real { value, allowed, .. } => (value.to_string(), allowed),
        ParamError::Count { value, allowed, .. } => (value.to_string(), allowed),
        _ => return SimError::SolverParameter(error),
    };
    SimError::invalid(option, value, format!("must be {allowed} for {integrator}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for i in Integrator::ALL {
            assert_eq!(i.name().parse::<Integrator>().unwrap(), *i);
        }
        for s in LinearSolver::ALL {
            assert_eq!(s.name().parse::<LinearSolver>().unwrap(), *s);
        }
        for r in RelaxationPreset::ALL {
            assert_eq!(r.name().parse::<RelaxationPreset>().unwrap(), *r);
            assert_eq!(RelaxationPreset::of(&r.relaxation()), Some(*r));
        }
        for p in PinMethod::ALL {
            assert_eq!(p.name().parse::<PinMethod>().unwrap(), *p);
        }
        assert_eq!(PinMethod::default(), PinMethod::Reduction);
        let err = "penalty".parse::<PinMethod>().unwrap_err().to_string();
        assert!(
            err.contains("\"penalty\"") && err.contains("counter-force"),
            "{err}"
        );
        assert!("rk4".parse::<Integrator>().is_err());
        assert!("gmres".parse::<LinearSolver>().is_err());
    }

    #[test]
    fn energy_limits_parse_and_bad_ones_are_refused() {
        for (text, expected) in [
            ("1", Some(1.0)),
            ("0.25", Some(0.25)),
            ("0", Some(0.0)),
            (" 1e3 ", Some(1e3)),
            ("off", None),
            ("OFF", None),
            ("none", None),
        ] {
            assert_eq!(parse_energy_limit(text).unwrap(), expected, "{text:?}");
        }
        for text in ["-1", "NaN", "inf", "", "twice", "1 J"] {
            match parse_energy_limit(text) {
                Err(SimError::InvalidParameter { name, .. }) => assert_eq!(name, "energy limit"),
                other => panic!("{text:?}: expected InvalidParameter, got {other:?}"),
            }
        }
        let mut s = Settings::default();
        assert_eq!(s.energy_limit, Some(1.0));
        s.set_energy_limit(None).unwrap();
        assert_eq!(s.energy_limit, None);
        s.set_energy_limit(Some(3.0)).unwrap();
        assert_eq!(s.energy_limit, Some(3.0));
        for bad in [-0.5, f64::NAN, f64::INFINITY] {
            assert!(s.set_energy_limit(Some(bad)).is_err(), "{bad}");
            assert_eq!(
                s.energy_limit,
                Some(3.0),
                "a refused value leaves the setting"
            );
        }
    }

    #[test]
    fn options_reach_the_chosen_solver_and_bad_values_are_refused() {
        let mut s = Settings {
            integrator: Integrator::Linearized,
            ..Settings::default()
        };
        s.apply_options(&SolverOptions {
            beta: Some(0.5),
            linear_solver: Some(LinearSolver::Jacobi),
            iterations: Some(7),
            tolerance: Some(1e-6),
            relaxation: None,
            factor_reuse: None,
            memory_budget: None,
            pd_global_solve: None,
        })
        .unwrap();
        assert_eq!(s.linearized.beta, 0.5);
        assert_eq!(s.linearized.solver, LinearSolver::Jacobi);
        assert_eq!(s.linearized.max_iterations, 7);
        assert_eq!(s.linearized.tolerance, 1e-6);
        let mut n = Settings {
            integrator: Integrator::Newton,
            ..Settings::default()
        };
        n.apply_options(&SolverOptions {
            iterations: Some(9),
            tolerance: Some(1e-10),
            ..Default::default()
        })
        .unwrap();
        assert_eq!((n.newton.max_iterations, n.newton.tolerance), (9, 1e-10));
        for (options, integrator, expected) in [
            (
                SolverOptions {
                    beta: Some(1.5),
                    ..Default::default()
                },
                Integrator::Linearized,
                "beta",
            ),
            (
                SolverOptions {
                    beta: Some(-0.1),
                    ..Default::default()
                },
                Integrator::Linearized,
                "beta",
            ),
            (
                SolverOptions {
                    beta: Some(f64::NAN),
                    ..Default::default()
                },
                Integrator::Linearized,
                "beta",
            ),
            (
                SolverOptions {
                    tolerance: Some(-1e-12),
                    ..Default::default()
                },
                Integrator::Newton,
                "tolerance",
            ),
            (
                SolverOptions {
                    tolerance: Some(0.0),
                    ..Default::default()
                },
                Integrator::Linearized,
                "tolerance",
            ),
            (
                SolverOptions {
                    tolerance: Some(-1.0),
                    ..Default::default()
                },
                Integrator::Linearized,
                "tolerance",
            ),
            (
                SolverOptions {
                    iterations: Some(0),
                    ..Default::default()
                },
                Integrator::ProjectiveDynamics,
                "iterations",
            ),
            (
                SolverOptions {
                    beta: Some(0.5),
                    ..Default::default()
                },
                Integrator::Newton,
                "only to the linearized",
            ),
            (
                SolverOptions {
                    iterations: Some(5),
                    ..Default::default()
                },
                Integrator::SymplecticEuler,
                "explicit",
            ),
        ] {
            let mut s = Settings {
                integrator,
                ..Settings::default()
            };
            let before = s;
            let err = s.apply_options(&options).unwrap_err().to_string();
            assert!(err.contains(expected), "{options:?} on {integrator}: {err}");
            assert_eq!(s, before, "a refused option leaves the settings unchanged");
        }
    }

    /// One rule: an iteration count or a tolerance given by name is accepted exactly when the
    /// chosen solver's own `validate` accepts it in its params (PD and Newton take a tolerance of 0,
    /// PD's default), whatever the value.
    #[test]
    fn options_are_accepted_exactly_when_the_solvers_validate_accepts_them() {
        let tolerances = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            1e-8,
            1.0,
            1e300,
            -1e-12,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for integrator in [
            Integrator::Linearized,
            Integrator::Newton,
            Integrator::ProjectiveDynamics,
        ] {
            for &tolerance in &tolerances {
                let mut s = Settings {
                    integrator,
                    ..Settings::default()
                };
                let mut direct = s;
                let valid = match integrator {
                    Integrator::Linearized => {
                        direct.linearized.tolerance = tolerance;
                        direct.linearized.validate().is_ok()
                    }
                    Integrator::Newton => {
                        direct.newton.tolerance = tolerance;
                        direct.newton.validate().is_ok()
                    }
                    _ => {
                        direct.pd.tolerance = tolerance;
                        direct.pd.validate().is_ok()
                    }
                };
                let applied = s.apply_options(&SolverOptions {
                    tolerance: Some(tolerance),
                    ..Default::default()
                });
                assert_eq!(
                    applied.is_ok(),
                    valid,
                    "{integrator}, tolerance {tolerance}"
                );
                if valid {
                    assert_eq!(s, direct);
                }
            }
            for iterations in [0, 1, 7, usize::MAX] {
                let mut s = Settings {
                    integrator,
                    ..Settings::default()
                };
                let mut direct = s;
                let valid = match integrator {
                    Integrator::Linearized => {
                        direct.linearized.max_iterations = iterations;
                        direct.linearized.validate().is_ok()
                    }
                    Integrator::Newton => {
                        direct.newton.max_iterations = iterations;
                        direct.newton.validate().is_ok()
                    }
                    _ => {
                        direct.pd.max_iterations = iterations;
                        direct.pd.validate().is_ok()
                    }
                };
                let applied = s.apply_options(&SolverOptions {
                    iterations: Some(iterations),
                    ..Default::default()
                });
                assert_eq!(
                    applied.is_ok(),
                    valid,
                    "{integrator}, iterations {iterations}"
                );
            }
        }
        // The case that disagreed before: PD with a tolerance of 0, its own default.
        let mut pd = Settings {
            integrator: Integrator::ProjectiveDynamics,
            ..Settings::default()
        };
        pd.apply_options(&SolverOptions {
            tolerance: Some(0.0),
            ..Default::default()
        })
        .unwrap();
        assert_eq!(pd.pd.tolerance, 0.0);
    }
}
