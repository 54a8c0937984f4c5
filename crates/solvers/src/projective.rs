//! Projective dynamics / fast mass-spring (Liu, Bargteil, O'Brien, Kavan 2013; docs/model.md §6.8)
//! for one backward Euler step: minimise Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) by alternating
//! - the local step d_s = l_s r̂_s (parallel over springs), and
//! - the global step K (M + h² L) Kᵀ x_f = K (h² J d + M y − (M + h² L) b),
//!
//! with the scalar matrix K (M + h² L) Kᵀ factored once (Kronecker structure: the D coordinates are D
//! right-hand sides of one n_free × n_free system). Each iteration does not increase Φ (it is a
//! block coordinate descent on the spring-projection form of Φ), so PD converges monotonically, if
//! only linearly, to the backward Euler solution.

use std::time::{Duration, Instant};

use hooke_assembly::pd::{local_step, LaplacianPattern};
use hooke_assembly::{spring_energy, FreeDofs};
use hooke_mesh::Spring;
use nalgebra::SVector;

mod collision_constraints;
mod global;

pub use collision_constraints::{PdContactModel, DEFAULT_CONTACT_WEIGHT};
pub(crate) use global::GlobalSolve;
use global::{DirectSolve, MultilevelSolve};
pub use global::{GlobalSolveKind, PdMultilevelParams, MULTILEVEL_PD_FILL, MULTILEVEL_PD_UNKNOWNS};

use crate::amg::AmgError;
use crate::backward_euler::spring_energy_change;
use crate::cholesky::{CholeskyError, CholeskyParams, FactorKind, SparseCholesky};
use crate::operator::Preconditioner;
use crate::params::{self, ParamError, HISTORY_RESERVE};
use crate::report::StopReason;
use collision_constraints::PdContact;

/// Why projective dynamics could not be set up or run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PdError {
    /// A parameter is out of its range ([`PdParams::validate`]), or the time step is not finite
    /// and positive; nothing was computed.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
    /// The global matrix did not factor (e.g. a free component with zero mass and no pin, or
    /// non-finite values).
    #[error(transparent)]
    Factorization(#[from] CholeskyError),
    /// The multilevel global step's hierarchy could not be built or refilled (e.g. a free
    /// component with zero mass and no pin, or non-finite values).
    #[error("the multilevel global step: {0}")]
    Multilevel(#[from] AmgError),
}

/// The most iterations [`PdParams::max_iterations`] may ask for: a budget that ends (with no
/// tolerance, PD runs every iteration of it), the same bound as Chebyshev PD's.
pub const PD_MAX_ITERATIONS: usize = 1 << 24;

impl PdParams {
    /// Check the fields: `max_iterations` in 1..=[`PD_MAX_ITERATIONS`], `tolerance` finite and ≥ 0 (m/s),
    /// [`PdMultilevelParams::validate`] and [`CholeskyParams::validate`].
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::count_in(
            "PdParams::max_iterations",
            self.max_iterations,
            1,
            PD_MAX_ITERATIONS,
            "in 1 ..= 2^24",
        )?;
        params::non_negative("PdParams::tolerance", self.tolerance)?;
        params::real(
            "PdParams::multilevel_fill",
            self.multilevel_fill,
            self.multilevel_fill > 0.0,
            "positive (+∞: by size and memory budget only)",
        )?;
        self.multilevel.validate()?;
        self.cholesky.validate()
    }
}

/// Settings of [`ProjectiveDynamics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdParams {
    /// Iterations per step (the method's usual fixed budget). Default 10.
    pub max_iterations: usize,
    /// Also stop when the estimated distance to the solution, divided by h, is at most `tolerance`
    /// (m/s: Newton's step-size criterion, [`crate::Convergence::StepSize`], in the same unit and
    /// with the same meaning). PD converges linearly, so that distance is the last change times
    /// ρ/(1 − ρ) for its rate ρ, not the last change: [`FixedPointError`] estimates it from the
    /// ratios of successive changes. Default 0: always run `max_iterations`.
    pub tolerance: f64,
    /// Evaluate Φ after every iteration (one extra pass over springs and vertices) for the report.
    /// Default false: benchmarks measure the bare iteration.
    pub record_objective: bool,
    /// Run the local step, the Φ evaluation and the solve on two threads (same bits either way; the
    /// right-hand side always goes parallel above 8,192 springs, with the same result). A
    /// simplicial factor (up to 50,000 unknowns, [`ProjectiveDynamics::factor_kind_for`]) is solved
    /// for all D coordinates in one pass, split along its elimination tree into two halves that run
    /// on two threads when it has at least 32,768 stored values; a supernodal one by faer, its
    /// columns split over [`CholeskyParams::solve_threads`]. The multilevel path's products and
    /// sums run on rayon above a size whatever this flag (the same bits on any thread count).
    /// Default true.
    pub parallel: bool,
    /// How the global step is solved: by the prefactored matrix or on the multilevel path.
    /// Default [`GlobalSolveKind::Auto`] ([`ProjectiveDynamics::global_solve_for`]).
    pub global_solve: GlobalSolveKind,
    /// Under [`GlobalSolveKind::Auto`], take the multilevel path also when the factor of the
    /// global matrix would hold more than this many times the matrix' stored entries (the
    /// factor's lower triangle against the matrix' full pattern), decided after the symbolic
    /// analysis, before the factor is allocated. Default [`MULTILEVEL_PD_FILL`]; `f64::INFINITY`:
    /// by size and memory budget only.
    pub multilevel_fill: f64,
    /// The multilevel path's settings.
    pub multilevel: PdMultilevelParams,
    /// Factorisation settings of the direct path. [`FactorKind::Auto`] picks by size for the
    /// solve ([`ProjectiveDynamics::factor_kind_for`]).
    pub cholesky: CholeskyParams,
}

impl Default for PdParams {
    fn default() -> Self {
        PdParams {
            max_iterations: 10,
            tolerance: 0.0,
            record_objective: false,
            parallel: true,
            global_solve: GlobalSolveKind::Auto,
            multilevel_fill: MULTILEVEL_PD_FILL,
            multilevel: PdMultilevelParams::default(),
            // A supernodal factor's columns split over two threads (the same bits as serial;
            // 1.28× on cloth-320's solve): `parallel: false` solves them on one.
            cholesky: CholeskyParams {
                solve_threads: 2,
                ..CholeskyParams::default()
            },
        }
    }
}

/// The account of one projective dynamics solve.
#[derive(Clone, Debug, PartialEq)]
pub struct PdReport {
    /// Iterations performed.
    pub iterations: usize,
    /// Largest position change (m) in each iteration.
    pub changes: Vec<f64>,
    /// Φ before the first iteration and after each one (J), if recorded.
    pub objectives: Vec<f64>,
    /// Conjugate gradient iterations of the multilevel global steps, summed over the
    /// iterations (0 on the direct path).
    pub linear_iterations: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// Wall time of the solve (the factorisation is done once, apart: see
    /// [`ProjectiveDynamics::factor_time`]).
    pub wall_time: Duration,
}

/// Projective dynamics for one mesh, pin set, mass vector and time step, with the factorisation and
/// every buffer kept across steps.
#[derive(Debug)]
pub struct ProjectiveDynamics<const D: usize> {
    /// The settings.
    pub params: PdParams,
    pattern: LaplacianPattern,
    global: GlobalSolve<D>,
    values: Vec<f64>,
    masses: Vec<f64>,
    h: f64,
    d: Vec<SVector<f64, D>>,
    rhs: Vec<SVector<f64, D>>,
    /// Contact with obstacles, if set ([`ProjectiveDynamics::set_contact`]).
    contact: Option<Box<PdContact<D>>>,
}

impl<const D: usize> ProjectiveDynamics<D> {
    /// Assemble and factor K (M + h² L) Kᵀ for `springs` over the free vertices of `free`, with
    /// masses (kg, per vertex of the full mesh) and time step `h` (s).
    ///
    /// # Errors
    /// [`PdError::InvalidParameter`] if `params` does not pass [`PdParams::validate`] or `h` is
    /// not finite and positive; [`PdError::Factorization`] if the matrix does not factor (e.g. a
    /// free component with zero mass and no pin) or holds non-finite values.
    pub fn new(
        springs: &[Spring],
        masses: &[f64],
        free: &FreeDofs,
        h: f64,
        params: PdParams,
    ) -> Result<Self, PdError> {
        params.validate()?;
        params::positive("ProjectiveDynamics::new: h", h)?;
        let pattern = LaplacianPattern::new(free.vertex_count(), springs, Some(free));
        let cholesky_params = CholeskyParams {
            kind: match params.cholesky.kind {
                FactorKind::Auto => Self::factor_kind_for(pattern.size()),
                kind => kind,
            },
            solve_threads: if params.parallel {
                params.cholesky.solve_threads
            } else {
                1
            },
            ..params.cholesky
        };
        let n_free = free.free_count();
        let multilevel = || GlobalSolve::Multilevel(Box::new(MultilevelSolve::new(n_free)));
        let kind = match params.global_solve {
            GlobalSolveKind::Auto => Self::global_solve_for(n_free),
            kind => kind,
        };
        let global = match kind {
            GlobalSolveKind::Multilevel => multilevel(),
            _ => match SparseCholesky::analyze(pattern.symbolic(), cholesky_params) {
                // A filled solid's factor: the multilevel path is the faster one.
                Ok(cholesky)
                    if params.global_solve == GlobalSolveKind::Auto
                        && cholesky.factor_nnz() as f64
                            > params.multilevel_fill * pattern.symbolic().compute_nnz() as f64 =>
                {
                    multilevel()
                }
                Ok(cholesky) => GlobalSolve::Direct(Box::new(DirectSolve::new(cholesky))),
                // Over the memory budget, Auto takes the path that needs no factor.
                Err(CholeskyError::OverBudget { .. })
                    if params.global_solve == GlobalSolveKind::Auto =>
                {
                    multilevel()
                }
                Err(e) => return Err(e.into()),
            },
        };
        let mut pd = ProjectiveDynamics {
            params,
            values: pattern.new_values(),
            pattern,
            global,
            masses: masses.to_vec(),
            h,
            d: springs
                .iter()
                .map(|s| {
                    let mut e = SVector::zeros();
                    e[0] = s.rest_length;
                    e
                })
                .collect(),
            rhs: vec![SVector::zeros(); n_free],
            contact: None,
        };
        pd.refactor(springs, masses, h)?;
        Ok(pd)
    }

    /// The global solve [`GlobalSolveKind::Auto`] takes for `unknowns` free vertices (if the
    /// factor fits in the memory budget and fills at most [`PdParams::multilevel_fill`] times the
    /// matrix): [`GlobalSolveKind::Multilevel`] above [`MULTILEVEL_PD_UNKNOWNS`],
    /// [`GlobalSolveKind::Direct`] otherwise.
    pub fn global_solve_for(unknowns: usize) -> GlobalSolveKind {
        if unknowns > MULTILEVEL_PD_UNKNOWNS {
            GlobalSolveKind::Multilevel
        } else {
            GlobalSolveKind::Direct
        }
    }

    /// The global solve this system takes ([`GlobalSolveKind::Direct`] or
    /// [`GlobalSolveKind::Multilevel`]).
    pub fn global_solve(&self) -> GlobalSolveKind {
        match self.global {
            GlobalSolve::Direct(_) => GlobalSolveKind::Direct,
            GlobalSolve::Multilevel(_) => GlobalSolveKind::Multilevel,
        }
    }

    /// The factor organisation [`FactorKind::Auto`] means here. The matrix is factored once and solved
    /// every iteration, so the solve decides: measured on this project's 2-core machine
    /// (`examples/pd_factor_storage`, serial solves of three columns), the simplicial factor solves
    /// cloth-160 (25,598 unknowns) in 9.7 ms against 13.6 ms supernodal, while from cloth-320
    /// (102,398) the supernodal one wins (48 ms against 54 ms) and factors 18× faster (0.23 s
    /// against 4.1 s). The crossover is taken at 50,000 unknowns.
    pub fn factor_kind_for(unknowns: usize) -> FactorKind {
        if unknowns <= 50_000 {
            FactorKind::Simplicial
        } else {
            FactorKind::Supernodal
        }
    }

    /// Refill and refactor the system after h, the stiffnesses or the masses changed (same springs
    /// and pins). The symbolic analysis is kept.
    ///
    /// # Errors
    /// As [`ProjectiveDynamics::new`].
    pub fn refactor(&mut self, springs: &[Spring], masses: &[f64], h: f64) -> Result<(), PdError> {
        self.masses.copy_from_slice(masses);
        self.h = h;
        self.pattern
            .system_into(springs, masses, h, &mut self.values);
        self.global
            .factor(self.pattern.matrix(&self.values), &self.params.multilevel)?;
        if let Some(contact) = &mut self.contact {
            contact.rebuild(&self.pattern, springs, masses, h);
        }
        Ok(())
    }

    /// Whether the split solve runs its two bins on two threads: in parallel mode, for factors
    /// large enough to pay for the fork ([`crate::forest_solve::SPLIT_MIN_VALUES`]).
    fn split_threads(&self) -> bool {
        self.params.parallel && self.params.cholesky.solve_threads > 1 && self.global.is_large()
    }

    /// Time of the last numeric factorisation, or on the multilevel path of the hierarchy's
    /// set-up or refill (amortised over every step until the next refactor).
    pub fn factor_time(&self) -> Duration {
        self.global.prepare_time()
    }

    /// Stored values of the Cholesky factor (0 on the multilevel path, which stores none).
    pub fn factor_nnz(&self) -> usize {
        self.global.cholesky().map_or(0, SparseCholesky::factor_nnz)
    }

    /// Φ(x) = ½ Σ m_v |x_v − y_v|² + h² E(x) over all vertices, in kg·m² (J·s²). Pinned vertices add a
    /// constant (their x does not change), so differences of Φ are those of the reduced objective.
    pub fn objective(
        &self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &[SVector<f64, D>],
    ) -> f64 {
        let inertia: f64 = self
            .masses
            .iter()
            .zip(x.iter().zip(y))
            .map(|(m, (x, y))| 0.5 * m * (x - y).norm_squared())
            .sum();
        inertia + self.h * self.h * spring_energy(springs, x, self.params.parallel)
    }

    /// Φ(trial) − Φ(x) without subtracting two rounded values of Φ: term by term, each spring's
    /// through |r_t| − |r| = Δr·(2r + Δr)/(|r_t| + |r|), so that changes far below ε·Φ are resolved
    /// (as [`crate::NewtonProblem::objective_change`] for backward Euler). Pinned vertices must be at
    /// the same place in both.
    pub fn objective_change(
        &self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &[SVector<f64, D>],
        trial: &[SVector<f64, D>],
    ) -> f64 {
        let inertia: f64 = self
            .masses
            .iter()
            .zip(x.iter().zip(trial).zip(y))
            .map(|(m, ((x, t), y))| {
                let delta = t - x;
                0.5 * m * delta.dot(&((x - y) * 2.0 + delta))
            })
            .sum();
        let energy = hooke_assembly::deterministic_sum(springs.len(), self.params.parallel, |s| {
            let (i, j) = springs[s].ends();
            let r = x[i] - x[j];
            spring_energy_change(
                springs[s].stiffness,
                springs[s].rest_length,
                &r,
                &(trial[i] - trial[j] - r),
            )
        });
        inertia + self.h * self.h * energy
    }

    /// The time step h (s) the matrix was built for.
    pub fn time_step(&self) -> f64 {
        self.h
    }

    /// Run projective dynamics for the step with inertial target `y` (per vertex, m). `x` holds the
    /// initial guess (usually y) with the pinned vertices at their prescribed positions, and the
    /// result on return (pinned vertices untouched). The report's stop is
    /// [`StopReason::Converged`] when the tolerance was met, [`StopReason::IterationLimit`] after
    /// the iteration budget (the method's usual stop, not converged), and
    /// [`StopReason::NonFinite`] as soon as a position change is NaN or infinite.
    ///
    /// # Errors
    /// [`PdError::InvalidParameter`] (before anything is computed) if [`ProjectiveDynamics::params`]
    /// was set to values [`PdParams::validate`] refuses.
    ///
    /// # Panics
    /// If the lengths of `springs`, `y` or `x` do not match the system, or after a
    /// [`ProjectiveDynamics::refactor`] that failed (no factor or hierarchy to solve with).
    #[track_caller]
    pub fn solve(
        &mut self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
    ) -> Result<PdReport, PdError> {
        self.params.validate()?;
        let start = Instant::now();
        let p = self.params;
        let mut report = PdReport {
            iterations: 0,
            // Reserved up to a fixed size, never by the user's limit: beyond it they grow.
            changes: Vec::with_capacity(p.max_iterations.min(HISTORY_RESERVE)),
            objectives: Vec::with_capacity(if p.record_objective {
                p.max_iterations.saturating_add(1).min(HISTORY_RESERVE)
            } else {
                0
            }),
            linear_iterations: 0,
            stop: StopReason::IterationLimit,
            wall_time: Duration::ZERO,
        };
        self.begin_step(springs, y, x)?;
        if p.record_objective {
            report.objectives.push(self.objective(springs, y, x));
        }
        let mut largest_displacement: f64 = 0.0;
        let mut error = FixedPointError::default();
        while report.iterations < p.max_iterations {
            let change = self.iteration(springs, y, x, &mut largest_displacement);
            report.iterations += 1;
            report.linear_iterations += self.last_linear_iterations();
            report.changes.push(change);
            if p.record_objective {
                report.objectives.push(self.objective(springs, y, x));
            }
            if !change.is_finite() {
                report.stop = StopReason::NonFinite;
                break;
            }
            if error.after(change) <= p.tolerance * self.h {
                report.stop = StopReason::Converged;
                break;
            }
        }
        report.wall_time = start.elapsed();
        Ok(report)
    }

    /// One iteration (local step, right-hand side, D-column solve) from `x`, written into `x`:
    /// returns the largest change of a position (m) and raises `largest_displacement` to the
    /// largest distance of a new position from y (m).
    pub(crate) fn iteration(
        &mut self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
        largest_displacement: &mut f64,
    ) -> f64 {
        local_step(springs, x, &mut self.d, self.params.parallel);
        self.pattern
            .rhs_into(springs, &self.d, y, x, &self.masses, self.h, &mut self.rhs);
        let threads = self.split_threads();
        let free_vertices = self.pattern.free_dofs().free_vertices();
        // The multilevel path starts from the current iterate, which makes its step a descent.
        self.global.guess(|f| x[free_vertices[f] as usize]);
        let mut change: f64 = 0.0;
        let mut update = |x: &mut [SVector<f64, D>], vertex: usize, new: SVector<f64, D>| {
            change = change.max((new - x[vertex]).amax());
            x[vertex] = new;
            *largest_displacement = largest_displacement.max((new - y[vertex]).amax());
        };
        match &mut self.contact {
            Some(contact) => {
                contact.global_step(
                    &mut self.global,
                    &self.rhs,
                    free_vertices,
                    x,
                    threads,
                    &self.params.multilevel,
                );
                for (f, &vertex) in free_vertices.iter().enumerate() {
                    let vertex = vertex as usize;
                    let new = contact.feasible_move(&x[vertex], &contact.solution()[f]);
                    update(x, vertex, new);
                }
            }
            None => self
                .global
                .solve(&self.rhs, threads, &self.params.multilevel, |f, new| {
                    update(x, free_vertices[f] as usize, new);
                }),
        }
        change
    }

    /// CG iterations of the last global step (0 on the direct path).
    pub(crate) fn last_linear_iterations(&self) -> usize {
        match &self.contact {
            Some(contact) if contact.active_count() > 0 => contact.last_linear_iterations(),
            _ => self.global.last_iterations(),
        }
    }

    /// With contact, begin a step: `x` holds the step's start (outside every obstacle) and
    /// receives the initial guess (see [`ProjectiveDynamics::set_contact`]); the active set is
    /// chosen and the weighted matrix refactored if it changed. Without contact, nothing.
    pub(crate) fn begin_step(
        &mut self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
    ) -> Result<(), PdError> {
        if let Some(contact) = &mut self.contact {
            contact.begin_step(&self.pattern, springs, y, x, &self.params.multilevel)?;
        }
        Ok(())
    }

    /// With contact, limit each free vertex's move from `from` to `x` so that it stays outside
    /// every obstacle (see [`ProjectiveDynamics::set_contact`]). Without contact, nothing.
    pub(crate) fn limit_moves(&self, from: &[SVector<f64, D>], x: &mut [SVector<f64, D>]) {
        if let Some(contact) = &self.contact {
            contact.limit_moves(self.pattern.free_dofs().free_vertices(), from, x);
        }
    }

    /// Set contact with static obstacles (`Some`), or remove it (`None`). With contact, the `x`
    /// given to [`ProjectiveDynamics::solve`] (and [`crate::ChebyshevPd::solve`]) is the step's
    /// start x_n, which must be outside every obstacle, not an initial guess: the solve starts
    /// from y where a vertex's way there is clear, and short of the first obstacle otherwise.
    /// Every iterate, and the result, is outside every obstacle (signed distance ≥ 0 as
    /// [`Obstacle::distance`](hooke_collision::obstacle::Obstacle::distance) computes it); see
    /// [`PdContactModel`] and docs/contact.md for the contact solve and its friction. `springs`
    /// are the system's.
    ///
    /// # Errors
    /// [`PdError::InvalidParameter`] if the model does not pass [`PdContactModel::validate`];
    /// [`PdError::Factorization`] if the scratch memory of a second factor cannot be had.
    pub fn set_contact(
        &mut self,
        springs: &[Spring],
        model: Option<PdContactModel<D>>,
    ) -> Result<(), PdError> {
        let Some(model) = model else {
            self.contact = None;
            return Ok(());
        };
        model.validate()?;
        let weighted = match self.global.cholesky() {
            Some(cholesky) => {
                GlobalSolve::Direct(Box::new(DirectSolve::new(SparseCholesky::with_symbolic(
                    cholesky.symbolic().clone(),
                    self.pattern.symbolic(),
                    *cholesky.params(),
                    cholesky.analysis_time(),
                )?)))
            }
            None => GlobalSolve::Multilevel(Box::new(MultilevelSolve::new(self.pattern.size()))),
        };
        self.contact = Some(Box::new(PdContact::new(
            model,
            weighted,
            &self.pattern,
            springs,
            &self.masses,
            self.h,
        )));
        Ok(())
    }

    pub(crate) fn take_contact(&mut self) -> Option<Box<PdContact<D>>> {
        self.contact.take()
    }

    pub(crate) fn restore_contact(&mut self, contact: Option<Box<PdContact<D>>>) {
        self.contact = contact;
    }

    /// Whether contact is set ([`ProjectiveDynamics::set_contact`]).
    pub fn has_contact(&self) -> bool {
        self.contact.is_some()
    }

    /// Free vertices active in the last step's contact solve (0 without contact).
    pub fn contact_vertices(&self) -> usize {
        self.contact.as_ref().map_or(0, |c| c.active_count())
    }

    /// Factorisations of the contact solve's weighted matrix so far (one per new active set).
    pub fn contact_factorizations(&self) -> usize {
        self.contact.as_ref().map_or(0, |c| c.factorizations)
    }

    /// The free vertices, in the order of the reduced unknowns.
    pub(crate) fn free_vertices(&self) -> &[u32] {
        self.pattern.free_dofs().free_vertices()
    }
}

/// z = (K (M + h² L) Kᵀ ⊗ I_D)⁻¹ r with the prefactored matrix, or on the multilevel path
/// z ≈ that by one V-cycle (a fixed symmetric positive definite operator): the initial inverse
/// Hessian of [`Lbfgs`](crate::Lbfgs) for a backward Euler step (one D-column solve). `r` and `z` are in the
/// layout of [`BackwardEulerStep`](crate::BackwardEulerStep)'s reduced unknowns: coordinate a of the
/// f-th free vertex at D·f + a.
impl<const D: usize> Preconditioner for ProjectiveDynamics<D> {
    #[track_caller]
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        let n_free = self.pattern.free_dofs().free_count();
        assert_eq!(r.len(), D * n_free, "one value per free DOF");
        assert_eq!(z.len(), D * n_free, "one value per free DOF");
        let threads = self.split_threads();
        for (f, r) in self.rhs.iter_mut().zip(r.chunks_exact(D)) {
            *f = SVector::from_column_slice(r);
        }
        self.global.precondition(&self.rhs, threads, |f, o| {
            z[D * f..D * f + D].copy_from_slice(o.as_slice());
        });
    }
}

/// The distance from a linearly converging fixed-point iteration's iterate to its fixed point,
/// estimated from the position changes of its iterations: a change c_k at a rate ρ leaves about
/// c_k ρ/(1 − ρ) to go. ρ is estimated as the larger of the last two ratios c_k / c_(k−1) (one
/// ratio can be small by accident of the first iterations); until three changes are known, or
/// while that ratio is at least 1, the estimate is infinite: the iteration is not known to
/// converge. Used by projective dynamics and its Chebyshev acceleration, so that their tolerance
/// means what Newton's step-size tolerance means (a distance to the solution per h, m/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FixedPointError {
    /// The last change (m), if any.
    last_change: Option<f64>,
    /// The last ratio of successive changes, if any.
    last_ratio: Option<f64>,
}

impl FixedPointError {
    /// Record `change` (m; the largest change of a position coordinate in the iteration just
    /// made) and return the estimated distance to the fixed point (m): 0 when `change` is 0 (the
    /// iterate is the fixed point), infinite while ρ is not yet known to be below 1.
    pub fn after(&mut self, change: f64) -> f64 {
        if change == 0.0 {
            return 0.0;
        }
        let Some(previous) = self.last_change.replace(change) else {
            return f64::INFINITY;
        };
        let ratio = change / previous;
        let Some(earlier) = self.last_ratio.replace(ratio) else {
            return f64::INFINITY;
        };
        let rate = ratio.max(earlier);
        if rate < 1.0 {
            change * rate / (1.0 - rate)
        } else {
            f64::INFINITY
        }
    }
}
