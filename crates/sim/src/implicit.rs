//! Backward Euler (docs/model.md §6.4–§6.9): x⁺ minimises Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x)
//! over the free vertices, with y = x_n + h v_n + h² M⁻¹ f_ext, then v⁺ = (x⁺ − x_n)/h. Solved by
//! Newton (docs/model.md §6.5) or by projective dynamics (Liu et al. 2013), both from x⁰ = y.
//!
//! Terms of a scene and how they enter. Every force that is linear in x or in v = (x − x_n)/h adds
//! a quadratic ½ a_v |x_v − c_v|² per vertex to Φ, which folds exactly into the inertia term: M and y
//! become the effective masses A = M + Σ a and the target ỹ = A⁻¹ (M y + Σ a c). Both solvers then run
//! unchanged (projective dynamics factors A + h² L once).
//! - gravity f = m g: in y (a = 0);
//! - viscous damping f = −c v: a = h c, centre x_n (implicit in v, unconditionally stable);
//! - wind f = c (w − v): a = h c, centre x_n + h w (drag toward the moving air, implicit);
//! - the attractor f = −s m (x − p): a = h² s m, centre p (implicit in x);
//! - buoyancy, a step in height: evaluated at x_n and folded into y (explicit; its force is bounded);
//! - dashpot damping along springs: for Newton the dissipation potential of
//!   [`BackwardEulerStep::set_dashpot`] (implicit in v, direction frozen at x_n); projective dynamics
//!   keeps one constant matrix, which a direction-dependent Jacobian cannot enter, so it refuses a
//!   dashpot with [`SimError::Unsupported`];
//! - drag: v⁺ ← v⁺ e^(−h c_drag) after the solve (as in the explicit integrators);
//! - contact: for Newton, Newton-CG and L-BFGS part of Φ (a barrier per free vertex and obstacle,
//!   and friction lagged at x_n: [`BackwardEulerStep::set_contact`], docs/contact.md), with a
//!   start x⁰ on the way from x_n to y that keeps every vertex outside and line searches that never
//!   cross an obstacle; for projective dynamics and Chebyshev PD collision constraints in their
//!   iterations ([`hooke_solvers::ProjectiveDynamics::set_contact`], every iterate kept outside
//!   the obstacles); only the linearised integrator projects the whole mesh after its step (the
//!   `contact` module);
//! - pins: removed from the unknowns (docs/model.md §5.2, [`PinMethod::Reduction`]), held at their
//!   positions, or at the end of the step moved to where their prescribed path is at t + h (the
//!   right-hand side changes, the matrices do not: PD's factorisation and Newton's symbolic
//!   analysis are kept). With [`PinMethod::CounterForce`] Newton keeps every vertex an unknown
//!   ([`BackwardEulerStep::with_counter_forces`]): the pinned vertices are placed where their path
//!   is at t + h before the solve, and the counter-forces' rows hold them there; the step is the
//!   reduction's up to round-off. Projective dynamics refuses counter-forces with
//!   [`SimError::Unsupported`]: its global matrix M + h² L never holds the spring forces'
//!   Jacobian, so a counter-force has nothing to cancel there, and the matrix with pinned rows and
//!   columns replaced by the masses would only add decoupled rows to the reduced system (the same
//!   positions at a higher cost).
//!
//! A Newton (or Newton-CG) step that does not converge is redone as smaller steps (adaptive
//! halving, see `MAX_HALVINGS`): backward Euler by Newton finishes even from the hard cases'
//! crushed and stretched starts, at the price of more steps, which the step's summary reports.
//! L-BFGS, like projective dynamics, runs to its iteration budget and keeps the last iterate.

use hooke_assembly::FreeDofs;
use hooke_solvers::backward_euler::SelfContactState;
use hooke_solvers::{
    BackwardEulerStep, ChebyshevParams, ChebyshevPd, Lbfgs, LbfgsParams, Newton, NewtonCg,
    NewtonCgParams, NewtonParams, NewtonProblem, PdParams, Preconditioner, ProjectiveDynamics,
    SolveSummary,
};
use nalgebra::SVector;

use crate::forces::ExternalForce;
use crate::simulation::HalvingMemory;
use crate::{PinMethod, Scene, SimError};

/// Which solver, with its state kept across steps.
#[derive(Debug)]
enum Solver<const D: usize> {
    Newton {
        newton: Box<Newton>,
        objective: Box<BackwardEulerStep<D>>,
        unknowns: Vec<f64>,
    },
    Projective {
        pd: Box<ProjectiveDynamics<D>>,
    },
    /// L-BFGS or Newton-CG on Newton's objective, with PD's prefactored matrix as the initial
    /// inverse Hessian or preconditioner.
    PreconditionedByPd {
        method: PdPreconditioned,
        objective: Box<BackwardEulerStep<D>>,
        pd: Box<ProjectiveDynamics<D>>,
        /// Counter-force pins only: the preconditioner's map between the full and reduced layouts.
        layout: Option<Box<FullLayout>>,
        unknowns: Vec<f64>,
    },
    /// Chebyshev-accelerated PD; ρ is estimated on the first step unless given.
    Chebyshev {
        pd: Box<ProjectiveDynamics<D>>,
        chebyshev: Box<ChebyshevPd<D>>,
        /// Plain PD iterations of the first step's estimate of ρ, until it is made.
        estimate: Option<usize>,
        /// The ρ in use: estimated, or given, or the fallback when the estimate did not form.
        rate: RateSource,
    },
}

/// The minimiser of Φ that a step of backward Euler uses, with its settings: what a half-step
/// integrator is rebuilt from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Minimizer {
    /// Newton with a factorisation per iteration.
    Newton(NewtonParams),
    /// L-BFGS, H₀ the PD matrix (`PdParams` for its factorisation).
    Lbfgs(LbfgsParams, PdParams),
    /// Newton-CG preconditioned by the PD matrix.
    NewtonCg(NewtonCgParams, PdParams),
}

impl Minimizer {
    /// Whether a step this minimiser does not finish is redone in halves. Newton and Newton-CG
    /// converge fast once Φ is nearly convex, so halving finishes their steps; L-BFGS converges
    /// linearly, and on stiff scenes at the default limit it would halve a frame into hundreds of
    /// pieces (cloth-40-stiff: 950): like projective dynamics it runs to its iteration budget and
    /// takes the last iterate (Φ never rose), reported as not converged.
    fn halves(&self) -> bool {
        !matches!(self, Minimizer::Lbfgs(..))
    }
}

/// The PD-preconditioned method and its state.
#[derive(Debug)]
enum PdPreconditioned {
    Lbfgs(Box<Lbfgs>),
    NewtonCg(Box<NewtonCg>),
}

impl PdPreconditioned {
    /// Minimise Φ from `unknowns` with `preconditioner` (H₀ for L-BFGS): (iterations, relative
    /// gradient, stop).
    fn minimize<const D: usize>(
        &mut self,
        objective: &mut BackwardEulerStep<D>,
        preconditioner: &mut impl Preconditioner,
        unknowns: &mut [f64],
    ) -> Result<(usize, f64, hooke_solvers::StopReason), SimError> {
        Ok(match self {
            PdPreconditioned::Lbfgs(lbfgs) => {
                let r = lbfgs
                    .minimize(objective, preconditioner, unknowns)
                    .map_err(SimError::solver)?;
                (r.iterations, r.residual(), r.stop)
            }
            PdPreconditioned::NewtonCg(solver) => {
                let r = solver
                    .minimize(objective, preconditioner, unknowns)
                    .map_err(SimError::solver)?;
                (r.iterations, r.residual(), r.stop)
            }
        })
    }
}

/// Where Chebyshev PD's ρ comes from, for the step report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RateSource {
    /// Given in the settings ([`hooke_solvers::ChebyshevParams::rate`]).
    Given(f64),
    /// Estimated from plain PD iterations on the first step
    /// ([`hooke_solvers::ProjectiveDynamics::estimate_rate`]).
    Estimated(f64),
    /// The estimate did not form (PD converged to round-off first, or the ratio was not in
    /// (0, 1)): the settings' ρ is used.
    Fallback(f64),
}

impl RateSource {
    /// The ρ in use.
    pub fn rate(&self) -> f64 {
        match *self {
            RateSource::Given(r) | RateSource::Estimated(r) | RateSource::Fallback(r) => r,
        }
    }
}

/// Counter-force pins keep every vertex an unknown (D per vertex); the PD factor is over the free
/// vertices (D per free vertex). The preconditioner gathers the free rows, applies the factor and
/// scatters back; a pinned row's Hessian is A_p I, so its entry is divided by A_p.
#[derive(Debug)]
struct FullLayout {
    /// Per free vertex (in PD's order), its vertex.
    free_vertices: Vec<u32>,
    /// Per vertex, whether it is pinned, and its effective mass (kg).
    pinned: Vec<bool>,
    inertia: Vec<f64>,
    reduced_r: Vec<f64>,
    reduced_z: Vec<f64>,
}

/// [`FullLayout`] applied with PD's factor.
struct FullLayoutPreconditioner<'a, const D: usize> {
    layout: &'a mut FullLayout,
    pd: &'a mut ProjectiveDynamics<D>,
}

impl<const D: usize> Preconditioner for FullLayoutPreconditioner<'_, D> {
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        let l = &mut *self.layout;
        for (f, &v) in l.free_vertices.iter().enumerate() {
            let v = v as usize;
            l.reduced_r[D * f..D * f + D].copy_from_slice(&r[D * v..D * v + D]);
        }
        self.pd.apply(&l.reduced_r, &mut l.reduced_z);
        for (v, (&pinned, &a)) in l.pinned.iter().zip(&l.inertia).enumerate() {
            if pinned {
                for k in D * v..D * v + D {
                    z[k] = r[k] / a;
                }
            }
        }
        for (f, &v) in l.free_vertices.iter().enumerate() {
            let v = v as usize;
            z[D * v..D * v + D].copy_from_slice(&l.reduced_z[D * f..D * f + D]);
        }
    }
}

/// A backward Euler integrator bound to one scene (topology, pins, masses, h).
#[derive(Debug)]
pub(crate) struct BackwardEuler<const D: usize> {
    solver: Solver<D>,
    /// The minimiser and its settings, for the half-step integrator; `None` for PD and Chebyshev
    /// PD, which do not halve.
    minimizer: Option<Minimizer>,
    /// How pins are held (Newton builds its half-step integrator the same way).
    pins: PinMethod,
    /// Newton only: whether the objective's per-spring loops run in parallel (the half-step
    /// integrator inherits it).
    parallel: bool,
    /// Effective masses A (kg, per vertex): see the module documentation.
    inertia: Vec<f64>,
    x_start: Vec<SVector<f64, D>>,
    /// The inertial target y of the current step, per vertex.
    y: Vec<SVector<f64, D>>,
    /// Newton only: the integrator for h/2, built the first time a step has to be halved.
    half: Option<Box<Half<D>>>,
    /// Newton only: the state at the start of the step, restored before a step is halved.
    saved_positions: Vec<SVector<f64, D>>,
    saved_velocities: Vec<SVector<f64, D>>,
    /// Newton only: calls at this step size that go straight to halves, and the failures of the
    /// whole step in a row that set it (see [`BackwardEuler::step`]).
    skip_whole: u32,
    failure_streak: u32,
}

/// Where a (possibly halved) step lies in the frame: its start, s after the frame's, and where the
/// moving pins are at a given time into the frame.
#[derive(Clone, Copy)]
struct Pieces<'a, const D: usize> {
    pins_at: &'a dyn Fn(f64, &mut [SVector<f64, D>]),
    start: f64,
}

/// Two steps of h/2 in place of a step of h that Newton did not finish.
#[derive(Debug)]
struct Half<const D: usize> {
    scene: Scene<D>,
    integrator: BackwardEuler<D>,
    /// Where the pins are halfway through the step (full numbering).
    pins_halfway: Vec<SVector<f64, D>>,
}

/// Adaptive halving of Newton's steps. A step that Newton does not finish (iteration limit, or a
/// solver error such as a failed line search) is redone from the same state as two steps of h/2,
/// each of which may be halved again, down to h/2^MAX_HALVINGS (12: 4096 pieces). Halving works
/// because the inertia term A/h² grows fourfold per halving while the spring Hessian does not: below
/// [`convex_step`] Φ is convex and Newton converges from any start. The result is still backward
/// Euler, on a finer grid of steps; `SolveSummary::substeps` counts the pieces and `iterations`
/// includes the given-up attempts.
///
/// Cost control, measured on the crushed-to-1 % hard case of cloth-40 (docs/scenes.md §6; Newton
/// limit 200, release build): a failed whole step jumps straight to the depth where h is
/// 2^CONVEXITY_SLACK times the convexity bound at x_n instead of failing once per level (2 frames:
/// 36 s against 76 s; slack 0, 4 and 6 cost more iterations than 2), and a step size that failed is
/// not tried again for the next 1, 2, 4, … 16 calls at that size (frames 1–4: 1212, 776, 496 and
/// 283 iterations in 19, 12, 7 and 3 pieces, against 1382, 1017, 735 and 418 without).
const MAX_HALVINGS: u32 = 12;

/// Refuse scene terms the solver does not model (see the module documentation).
fn check_supported<const D: usize>(scene: &Scene<D>, name: &str) -> Result<(), SimError> {
    if (name == "pd" || name == "pd-chebyshev") && scene.self_contact().is_some() {
        return Err(SimError::Unsupported {
            integrator: name.to_string(),
            what: "self-contact (its barrier and the collision detection that caps every line \
                   search live in the objective that newton, newton-cg and lbfgs minimise: use \
                   one of those)"
                .to_string(),
        });
    }
    if (name == "pd" || name == "pd-chebyshev") && scene.damping().dashpot > 0.0 {
        return Err(SimError::Unsupported {
            integrator: name.to_string(),
            what: "dashpot damping (its Jacobian changes with the spring directions; projective \
                   dynamics factors one constant matrix: use newton or linearized)"
                .to_string(),
        });
    }
    Ok(())
}

/// How many halvings short of [`convex_step`] a failed step jumps to: Newton copes with a Φ that
/// is mildly non-convex (cloth buckles at h = 1/30 s, far above the bound), so the bound's step
/// times 2^CONVEXITY_SLACK is tried first.
const CONVEXITY_SLACK: f64 = 2.0;

/// A time step (s) below which Φ is convex at `positions`: the compressed springs' negative
/// curvature −k(l/|r| − 1) across them adds to the Hessian a weighted graph Laplacian ⊗ I whose
/// quadratic form is at most 2 Σ_v |x_v|² w_v, w_v = Σ_{s∋v} k_s (l_s/|r_s| − 1)⁺, so
/// A_v ≥ 2 h² w_v at every free vertex makes A + h² ∇²E positive semidefinite. Zero if a spring has
/// zero length, infinite if none is compressed.
fn convex_step<const D: usize>(
    scene: &Scene<D>,
    inertia: &[f64],
    positions: &[SVector<f64, D>],
) -> f64 {
    let mut weight = vec![0.0; positions.len()];
    for s in scene.mesh().springs() {
        let (i, j) = s.ends();
        let length = (positions[i] - positions[j]).norm();
        let w = s.stiffness * (s.rest_length / length - 1.0).max(0.0);
        weight[i] += w;
        weight[j] += w;
    }
    let pinned = scene.is_pinned();
    weight
        .iter()
        .zip(inertia)
        .enumerate()
        .filter(|&(v, _)| !pinned[v])
        .map(|(_, (&w, &a))| (a / (2.0 * w)).sqrt())
        .fold(f64::INFINITY, f64::min)
}

/// Per vertex, the effective mass A_v = m_v + Σ a_v (kg) of the terms folded into the inertia.
fn effective_masses<const D: usize>(scene: &Scene<D>) -> Vec<f64> {
    let h = scene.time_step();
    let viscous = scene.damping().viscous;
    scene
        .mesh()
        .masses()
        .iter()
        .map(|&m| {
            let mut a = m + h * viscous;
            for f in scene.forces().as_slice() {
                match f {
                    ExternalForce::Wind { coefficient, .. } => a += h * coefficient,
                    ExternalForce::Attractor { strength, .. } => a += h * h * strength * m,
                    ExternalForce::Gravity { .. } | ExternalForce::Buoyancy { .. } => {}
                }
            }
            a
        })
        .collect()
}

/// ỹ_v = A_v⁻¹ (m_v y_v + Σ a c) for a free vertex at `x` (x_n) moving at `v`.
fn inertial_target<const D: usize>(
    scene: &Scene<D>,
    mass: f64,
    effective_mass: f64,
    x: &SVector<f64, D>,
    v: &SVector<f64, D>,
) -> SVector<f64, D> {
    let h = scene.time_step();
    let forces = scene.forces();
    let gravity = forces.gravity().unwrap_or_else(SVector::zeros);
    let mut sum = (x + v * h + gravity * (h * h)) * mass
        + x * (h * scene.damping().viscous)
        + forces.buoyancy_force(mass, x) * (h * h);
    for f in forces.as_slice() {
        match f {
            ExternalForce::Wind {
                velocity,
                coefficient,
            } => sum += (x + velocity * h) * (h * coefficient),
            ExternalForce::Attractor { point, strength } => {
                sum += point * (h * h * strength * mass)
            }
            ExternalForce::Gravity { .. } | ExternalForce::Buoyancy { .. } => {}
        }
    }
    sum / effective_mass
}

impl<const D: usize> BackwardEuler<D> {
    /// Newton's method on Φ, pins held by `pins`, the objective's loops parallel if `parallel`
    /// (the same bits either way).
    #[cfg(test)]
    pub(crate) fn newton(
        scene: &Scene<D>,
        params: NewtonParams,
        pins: PinMethod,
        parallel: bool,
    ) -> Result<Self, SimError> {
        Self::minimizer(scene, Minimizer::Newton(params), pins, parallel)
    }

    /// Backward Euler by `minimizer` on Φ (Newton, L-BFGS or Newton-CG), pins held by `pins`,
    /// the objective's loops parallel if `parallel` (the same bits either way). L-BFGS and
    /// Newton-CG factor PD's matrix K(A + h²L)Kᵀ here, once.
    pub(crate) fn minimizer(
        scene: &Scene<D>,
        minimizer: Minimizer,
        pins: PinMethod,
        parallel: bool,
    ) -> Result<Self, SimError> {
        check_supported(scene, "newton")?;
        if let Minimizer::Newton(params) = minimizer {
            if !params.relaxation.is_none() && !scene.contacts().is_empty() {
                return Err(SimError::Unsupported {
                    integrator: "newton".to_string(),
                    what: "the buckling relaxation on a scene with contact (its per-vertex sweeps \
                           and patch solves do not see the obstacles): use relaxation none"
                        .to_string(),
                });
            }
        }
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let inertia = effective_masses(scene);
        let mut objective = match pins {
            PinMethod::Reduction => {
                BackwardEulerStep::new(mesh.springs(), &inertia, free.clone(), scene.time_step())
            }
            PinMethod::CounterForce => BackwardEulerStep::with_counter_forces(
                mesh.springs(),
                &inertia,
                free.clone(),
                scene.time_step(),
            ),
        };
        objective.set_parallel(parallel);
        objective.set_contact(scene.contact_model(), mesh.masses());
        objective
            .set_contact_surface(scene.surface_triangles())
            .map_err(SimError::SolverParameter)?;
        objective
            .set_self_contact(scene.self_contact_model())
            .map_err(SimError::SolverParameter)?;
        objective
            .set_adaptive_stiffness(scene.barrier().adaptive_stiffness)
            .map_err(SimError::SolverParameter)?;
        let unknowns = vec![0.0; objective.dim()];
        let pd_factor = |pd_params: PdParams| {
            let pd_params = PdParams {
                parallel,
                ..pd_params
            };
            ProjectiveDynamics::new(
                mesh.springs(),
                &inertia,
                &free,
                scene.time_step(),
                pd_params,
            )
            .map(Box::new)
            .map_err(SimError::solver)
        };
        let layout = (pins == PinMethod::CounterForce).then(|| {
            let free_dofs = free.free_count() * D;
            Box::new(FullLayout {
                free_vertices: free.free_vertices().to_vec(),
                pinned: scene.is_pinned().to_vec(),
                inertia: inertia.clone(),
                reduced_r: vec![0.0; free_dofs],
                reduced_z: vec![0.0; free_dofs],
            })
        });
        let solver = match minimizer {
            Minimizer::Newton(params) => Solver::Newton {
                newton: Box::new(
                    Newton::new(objective.pattern(), params).map_err(SimError::solver)?,
                ),
                objective: Box::new(objective),
                unknowns,
            },
            Minimizer::Lbfgs(params, pd_params) => Solver::PreconditionedByPd {
                method: PdPreconditioned::Lbfgs(Box::new(
                    Lbfgs::new(unknowns.len(), params).map_err(SimError::SolverParameter)?,
                )),
                objective: Box::new(objective),
                pd: pd_factor(pd_params)?,
                layout,
                unknowns,
            },
            Minimizer::NewtonCg(params, pd_params) => Solver::PreconditionedByPd {
                method: PdPreconditioned::NewtonCg(Box::new(
                    NewtonCg::new(unknowns.len(), params).map_err(SimError::SolverParameter)?,
                )),
                objective: Box::new(objective),
                pd: pd_factor(pd_params)?,
                layout,
                unknowns,
            },
        };
        Ok(BackwardEuler {
            solver,
            minimizer: Some(minimizer),
            pins,
            parallel,
            inertia,
            x_start: vec![SVector::zeros(); n],
            y: vec![SVector::zeros(); n],
            half: None,
            saved_positions: vec![SVector::zeros(); n],
            saved_velocities: vec![SVector::zeros(); n],
            skip_whole: 0,
            failure_streak: 0,
        })
    }

    /// Chebyshev PD's ρ and where it came from; `None` for the other solvers, and before the first
    /// step when ρ is to be estimated.
    pub(crate) fn chebyshev_rate(&self) -> Option<RateSource> {
        match &self.solver {
            Solver::Chebyshev {
                estimate: None,
                rate,
                ..
            } => Some(*rate),
            _ => None,
        }
    }

    /// Time of the PD matrix's factorisation (PD, Chebyshev PD, and the PD preconditioner of
    /// L-BFGS and Newton-CG factor it once, when built); `None` for Newton.
    pub(crate) fn factor_time(&self) -> Option<std::time::Duration> {
        match &self.solver {
            Solver::Projective { pd }
            | Solver::Chebyshev { pd, .. }
            | Solver::PreconditionedByPd { pd, .. } => Some(pd.factor_time()),
            Solver::Newton { .. } => None,
        }
    }

    /// What self-contact does at `positions` (`None` without it, or for a solver without the
    /// barrier objective).
    pub(crate) fn self_contact_state(
        &mut self,
        positions: &[SVector<f64, D>],
    ) -> Option<SelfContactState> {
        match &mut self.solver {
            Solver::Newton { objective, .. } | Solver::PreconditionedByPd { objective, .. } => {
                objective.self_contact_state(positions)
            }
            _ => None,
        }
    }

    /// The scale the barriers' stiffnesses carry at the end of the last step under IPC's adaptive
    /// stiffness (`None` when it is off, or for a solver without the barrier objective).
    pub(crate) fn barrier_stiffness_scale(&self) -> Option<f64> {
        match &self.solver {
            Solver::Newton { objective, .. } | Solver::PreconditionedByPd { objective, .. } => {
                objective
                    .adaptive_stiffness()
                    .map(|_| objective.stiffness_scale())
            }
            _ => None,
        }
    }

    /// Forget the solver's history between steps (Newton's held factor: see
    /// [`hooke_solvers::Newton::forget_held_factor`]); the other solvers carry none that a
    /// checkpoint does not hold.
    pub(crate) fn forget_solver_history(&mut self) {
        if let Solver::Newton { newton, .. } = &mut self.solver {
            newton.forget_held_factor();
        }
    }

    /// Projective dynamics on Φ (the matrix is factored here, once). Pins by reduction only: see
    /// the module documentation.
    pub(crate) fn projective(
        scene: &Scene<D>,
        params: PdParams,
        pins: PinMethod,
    ) -> Result<Self, SimError> {
        Self::projective_with(scene, params, pins, None)
    }

    /// Chebyshev-accelerated projective dynamics: `params` for the factorisation, `chebyshev` for
    /// the acceleration; with `estimate = Some(k)` its ρ is estimated from k plain iterations on
    /// the first step (the given ρ is the fallback), with `None` the given ρ is used.
    pub(crate) fn chebyshev(
        scene: &Scene<D>,
        params: PdParams,
        chebyshev: ChebyshevParams,
        estimate: Option<usize>,
        pins: PinMethod,
    ) -> Result<Self, SimError> {
        Self::projective_with(scene, params, pins, Some((chebyshev, estimate)))
    }

    fn projective_with(
        scene: &Scene<D>,
        params: PdParams,
        pins: PinMethod,
        chebyshev: Option<(ChebyshevParams, Option<usize>)>,
    ) -> Result<Self, SimError> {
        let name = if chebyshev.is_some() {
            "pd-chebyshev"
        } else {
            "pd"
        };
        check_supported(scene, name)?;
        if pins == PinMethod::CounterForce && !scene.pinned().is_empty() {
            return Err(SimError::Unsupported {
                integrator: name.to_string(),
                what: "pins by counter-force (its global matrix M + h² L never holds the force \
                       Jacobian a counter-force cancels, and pinned rows replaced by the masses \
                       would only add decoupled rows to the same solve: use pin method \
                       reduction)"
                    .to_string(),
            });
        }
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let inertia = effective_masses(scene);
        let mut pd =
            ProjectiveDynamics::new(mesh.springs(), &inertia, &free, scene.time_step(), params)
                .map_err(SimError::solver)?;
        pd.set_contact(mesh.springs(), scene.pd_contact_model())
            .map_err(SimError::solver)?;
        let pd = Box::new(pd);
        let solver = match chebyshev {
            None => Solver::Projective { pd },
            Some((chebyshev, estimate)) => Solver::Chebyshev {
                pd,
                chebyshev: Box::new(
                    ChebyshevPd::new(n, chebyshev).map_err(SimError::SolverParameter)?,
                ),
                estimate,
                rate: RateSource::Given(chebyshev.rate),
            },
        };
        Ok(BackwardEuler {
            solver,
            minimizer: None,
            pins,
            parallel: params.parallel,
            inertia,
            x_start: vec![SVector::zeros(); n],
            y: vec![SVector::zeros(); n],
            half: None,
            saved_positions: Vec::new(),
            saved_velocities: Vec::new(),
            skip_whole: 0,
            failure_streak: 0,
        })
    }

    /// One step: positions and velocities of the free vertices are updated in place; pinned ones
    /// move to `next_pinned` (full numbering; free entries are not read) with the velocity of that
    /// move. If Newton halves the step, `pins_at(t, targets)` writes where the moving pins are t
    /// seconds into the step (the others keep the positions they have in `targets`). Returns the
    /// solver's summary.
    pub(crate) fn step(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        next_pinned: &[SVector<f64, D>],
        pins_at: &dyn Fn(f64, &mut [SVector<f64, D>]),
    ) -> Result<SolveSummary, SimError> {
        let pieces = Pieces {
            pins_at,
            start: 0.0,
        };
        self.step_halving(scene, positions, velocities, next_pinned, pieces, 0, 0)
    }

    /// [`BackwardEuler::step`], halved (Newton only) when the solve stops at its iteration limit or
    /// fails, `depth` halvings deep already; below depth `skip_to` the whole step is not tried.
    #[allow(clippy::too_many_arguments)] // the state, the pins, and where in the recursion
    fn step_halving(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        next_pinned: &[SVector<f64, D>],
        pieces: Pieces<'_, D>,
        depth: u32,
        skip_to: u32,
    ) -> Result<SolveSummary, SimError> {
        let params = match self.minimizer {
            Some(minimizer) if depth < MAX_HALVINGS && minimizer.halves() => minimizer,
            _ => return self.step_once(scene, positions, velocities, next_pinned),
        };
        let (whole, first_depth) = if depth < skip_to {
            (Ok(None), skip_to)
        } else if self.skip_whole > 0 {
            // This step size failed recently: halve without trying it again yet.
            self.skip_whole -= 1;
            (Ok(None), depth + 1)
        } else {
            self.saved_positions.copy_from_slice(positions);
            self.saved_velocities.copy_from_slice(velocities);
            let whole = self.step_once(scene, positions, velocities, next_pinned);
            // Not converged (the iteration limit, or a stall above the rounding floor) or an error
            // of the solver: redo the step in halves.
            let failed = match &whole {
                Ok(summary) => !summary.stop.is_converged(),
                Err(SimError::Solver { .. }) => true,
                Err(_) => false,
            };
            if !failed {
                self.failure_streak = 0;
                return whole;
            }
            // Back off: skip the whole step for the next 1, 2, 4, … 16 calls at this size.
            self.skip_whole = 1 << self.failure_streak.min(4);
            self.failure_streak += 1;
            positions.copy_from_slice(&self.saved_positions);
            velocities.copy_from_slice(&self.saved_velocities);
            // Go straight to the depth at which Φ is convex, or nearly (see `convex_step`):
            // halving one level at a time would spend a whole failed solve per level.
            let convex = convex_step(scene, &self.inertia, positions);
            let levels = (scene.time_step() / convex).log2().ceil() - CONVEXITY_SLACK;
            // ∞ (a spring of zero length) saturates at the deepest level; NaN cannot occur (h > 0).
            let target = depth + levels.clamp(1.0, f64::from(MAX_HALVINGS)) as u32;
            (whole.map(Some), target.min(MAX_HALVINGS))
        };
        let half = self.half_integrator(scene, params, positions)?;
        // Fixed pins stay put; moving ones are where their path is halfway through the step.
        half.pins_halfway.copy_from_slice(positions);
        let halfway = pieces.start + 0.5 * scene.time_step();
        (pieces.pins_at)(halfway, &mut half.pins_halfway);
        let Half {
            scene: half_scene,
            integrator,
            pins_halfway,
            ..
        } = half;
        let first = integrator.step_halving(
            half_scene,
            positions,
            velocities,
            pins_halfway,
            pieces,
            depth + 1,
            first_depth,
        )?;
        let second = integrator.step_halving(
            half_scene,
            positions,
            velocities,
            next_pinned,
            Pieces {
                start: halfway,
                ..pieces
            },
            depth + 1,
            0,
        )?;
        let given_up = match whole {
            Ok(Some(s)) => s.iterations,
            _ => 0,
        };
        Ok(SolveSummary {
            iterations: given_up + first.iterations + second.iterations,
            residual: first.residual.max(second.residual),
            // The first piece that did not converge, if any, says why.
            stop: if first.stop.is_converged() {
                second.stop
            } else {
                first.stop
            },
            substeps: first.substeps + second.substeps,
        })
    }

    /// The integrator for h/2, built the first time it is needed (`positions` only sizes its
    /// buffer).
    fn half_integrator(
        &mut self,
        scene: &Scene<D>,
        minimizer: Minimizer,
        positions: &[SVector<f64, D>],
    ) -> Result<&mut Half<D>, SimError> {
        if self.half.is_none() {
            let half_scene = scene.clone().with_time_step(0.5 * scene.time_step())?;
            let integrator =
                BackwardEuler::minimizer(&half_scene, minimizer, self.pins, self.parallel)?;
            self.half = Some(Box::new(Half {
                scene: half_scene,
                integrator,
                pins_halfway: positions.to_vec(),
            }));
        }
        Ok(self.half.as_mut().expect("built above"))
    }

    /// The halving back-off at this step size and at every half size built so far (outermost
    /// first); empty for projective dynamics, which does not halve.
    pub(crate) fn halving_memory(&self) -> Vec<HalvingMemory> {
        let mut memory = Vec::new();
        let mut level = Some(self);
        while let Some(integrator) = level {
            if integrator.minimizer.is_none() {
                break;
            }
            memory.push(HalvingMemory::new(
                integrator.skip_whole,
                integrator.failure_streak,
            ));
            level = integrator.half.as_ref().map(|h| &h.integrator);
        }
        memory
    }

    /// Put back what [`BackwardEuler::halving_memory`] returned, building the half-step
    /// integrators it reaches down to. Nothing changes if it fails.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] if the memory is deeper than the halving goes or is given to
    /// projective dynamics; the errors of building a half-step integrator.
    pub(crate) fn restore_halving_memory(
        &mut self,
        scene: &Scene<D>,
        memory: &[HalvingMemory],
        positions: &[SVector<f64, D>],
    ) -> Result<(), SimError> {
        let deepest = MAX_HALVINGS as usize + 1;
        let params = match self.minimizer {
            Some(minimizer) if memory.len() <= deepest => minimizer,
            Some(_) => {
                return Err(SimError::invalid(
                    "snapshot.halving",
                    format!("{} entries", memory.len()),
                    format!("backward Euler halves at most {MAX_HALVINGS} times"),
                ))
            }
            None if memory.is_empty() => return Ok(()),
            None => {
                return Err(SimError::invalid(
                    "snapshot.halving",
                    format!("{} entries", memory.len()),
                    "projective dynamics does not halve steps",
                ))
            }
        };
        // Build every level first, so that a failure leaves the counts as they were (a built but
        // unused half-step integrator changes no result: it is the one a halving would build).
        let mut level = &mut *self;
        let mut scene = scene.clone();
        for _ in 1..memory.len() {
            level.half_integrator(&scene, params, positions)?;
            let half = level.half.as_mut().expect("built above");
            scene = half.scene.clone();
            level = &mut half.integrator;
        }
        let mut level = Some(self);
        for m in memory {
            let integrator = level.expect("built above");
            integrator.skip_whole = m.skip_whole;
            integrator.failure_streak = m.failure_streak;
            level = integrator.half.as_deref_mut().map(|h| &mut h.integrator);
        }
        Ok(())
    }

    /// One step of the scene's h, without halving.
    fn step_once(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        next_pinned: &[SVector<f64, D>],
    ) -> Result<SolveSummary, SimError> {
        let h = scene.time_step();
        let pinned = scene.is_pinned();
        self.x_start.copy_from_slice(positions);
        for &v in scene.pinned() {
            positions[v as usize] = next_pinned[v as usize];
        }
        let masses = scene.mesh().masses();
        let inertia = &self.inertia;
        let target = |v: usize, x: &SVector<f64, D>, vel: &SVector<f64, D>| {
            if pinned[v] {
                *x
            } else {
                inertial_target(scene, masses[v], inertia[v], x, vel)
            }
        };
        let summary = match &mut self.solver {
            Solver::Newton {
                newton,
                objective,
                unknowns,
            } => {
                for v in 0..positions.len() {
                    self.y[v] = target(v, &positions[v], &velocities[v]);
                }
                objective.set_step_with_velocities(&self.y, positions, Some(velocities), unknowns);
                objective.set_dashpot(scene.damping().dashpot, &self.x_start);
                let report = newton
                    .minimize(objective.as_mut(), unknowns)
                    .map_err(SimError::solver)?;
                positions.copy_from_slice(objective.positions(unknowns));
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.residual(),
                    stop: report.stop,
                    substeps: 1,
                }
            }
            Solver::PreconditionedByPd {
                method,
                objective,
                pd,
                layout,
                unknowns,
            } => {
                for v in 0..positions.len() {
                    self.y[v] = target(v, &positions[v], &velocities[v]);
                }
                objective.set_step_with_velocities(&self.y, positions, Some(velocities), unknowns);
                objective.set_dashpot(scene.damping().dashpot, &self.x_start);
                let (iterations, residual, stop) = match layout {
                    None => method.minimize(objective.as_mut(), pd.as_mut(), unknowns)?,
                    Some(layout) => {
                        let mut full = FullLayoutPreconditioner {
                            layout,
                            pd: pd.as_mut(),
                        };
                        method.minimize(objective.as_mut(), &mut full, unknowns)?
                    }
                };
                positions.copy_from_slice(objective.positions(unknowns));
                SolveSummary {
                    iterations,
                    residual,
                    stop,
                    substeps: 1,
                }
            }
            Solver::Chebyshev {
                pd,
                chebyshev,
                estimate,
                rate,
            } => {
                for v in 0..positions.len() {
                    self.y[v] = target(v, &positions[v], &velocities[v]);
                }
                // Without contact x⁰ = y; with contact PD starts from x_n (its own initial guess).
                if !pd.has_contact() {
                    positions.copy_from_slice(&self.y);
                }
                let springs = scene.mesh().springs();
                if let Some(iterations) = estimate.take() {
                    let given = rate.rate();
                    *rate = match pd.estimate_rate(springs, &self.y, positions, iterations) {
                        Some(r) => RateSource::Estimated(r),
                        None => RateSource::Fallback(given),
                    };
                    chebyshev
                        .set_rate(rate.rate())
                        .map_err(SimError::SolverParameter)?;
                }
                let report = chebyshev
                    .solve(pd, springs, &self.y, positions)
                    .map_err(SimError::solver)?;
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.changes.last().copied().unwrap_or(0.0) / h,
                    stop: report.stop,
                    substeps: 1,
                }
            }
            Solver::Projective { pd } => {
                for v in 0..positions.len() {
                    self.y[v] = target(v, &positions[v], &velocities[v]);
                }
                // x⁰ = y at free vertices; pinned vertices keep their positions (y = x there).
                // With contact PD starts from x_n (its own initial guess).
                if !pd.has_contact() {
                    positions.copy_from_slice(&self.y);
                }
                let report = pd
                    .solve(scene.mesh().springs(), &self.y, positions)
                    .map_err(SimError::solver)?;
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.changes.last().copied().unwrap_or(0.0) / h,
                    stop: report.stop,
                    substeps: 1,
                }
            }
        };
        let drag = (-h * scene.damping().drag).exp();
        for v in 0..positions.len() {
            if pinned[v] {
                velocities[v] = (positions[v] - self.x_start[v]) / h;
                continue;
            }
            velocities[v] = (positions[v] - self.x_start[v]) / h * drag;
        }
        Ok(summary)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pins;
    use hooke_mesh::generators;
    use nalgebra::DMatrix;

    /// Smallest eigenvalue of ∇²Φ over the free DOFs at `x` for the scene's h, relative to the
    /// largest effective mass (so that −1e-12 is round-off).
    fn smallest_eigenvalue(scene: &Scene<3>, x: &[SVector<f64, 3>]) -> f64 {
        let inertia = effective_masses(scene);
        let free = FreeDofs::new(x.len(), scene.pinned()).unwrap();
        let mut step =
            BackwardEulerStep::new(scene.mesh().springs(), &inertia, free, scene.time_step());
        let mut unknowns = vec![0.0; step.dim()];
        step.set_step(x, x, &mut unknowns);
        let h = step.hessian(&unknowns);
        let n = h.ncols();
        let mut dense = DMatrix::zeros(n, n);
        for j in 0..n {
            for (&i, &v) in h.row_idx_of_col_raw(j).iter().zip(h.val_of_col(j)) {
                dense[(i, j)] = v;
            }
        }
        let largest = inertia.iter().cloned().fold(0.0, f64::max);
        dense.symmetric_eigen().eigenvalues.min() / largest
    }

    #[test]
    fn a_halved_step_moves_the_pins_along_their_path() {
        // cloth-8 crushed to 1 % with one pin moving at constant velocity: Newton does not finish
        // the whole step within 8 iterations (it needs 20 with the default relaxation) and halves it.
        let n = 8;
        let mesh = generators::cloth(n, 1e3).unwrap();
        let h = 1.0 / 30.0;
        let scene = Scene::new(mesh, h)
            .unwrap()
            .with_pins(Pins::Vertices(vec![0, n as u32 - 1]))
            .unwrap();
        let mut positions: Vec<_> = scene.mesh().positions().iter().map(|p| p * 0.01).collect();
        let mut velocities = vec![SVector::zeros(); positions.len()];
        let moving = n - 1;
        let start = positions[moving];
        let shift = SVector::<f64, 3>::new(0.0, 0.05, 0.0);
        let mut next_pinned = positions.clone();
        next_pinned[moving] = start + shift;
        let asked = std::cell::RefCell::new(Vec::new());
        let pins_at = |t: f64, targets: &mut [SVector<f64, 3>]| {
            asked.borrow_mut().push(t);
            targets[moving] = start + shift * (t / h);
        };
        let params = NewtonParams {
            max_iterations: 8,
            ..NewtonParams::default()
        };
        let mut integrator =
            BackwardEuler::newton(&scene, params, Default::default(), true).unwrap();
        let summary = integrator
            .step(
                &scene,
                &mut positions,
                &mut velocities,
                &next_pinned,
                &pins_at,
            )
            .unwrap();
        let asked = asked.into_inner();
        assert!(summary.substeps > 1, "not halved: {summary:?}");
        assert_eq!(
            summary.stop,
            hooke_solvers::StopReason::Converged,
            "{summary:?}"
        );
        assert_eq!(
            asked[0],
            0.5 * h,
            "the first halving asks for the middle: {asked:?}"
        );
        assert!(asked.iter().all(|&t| t > 0.0 && t < h), "{asked:?}");
        // At the end the pins are where they were told to be, and the moving one has the velocity
        // of its path (its last piece moved it along the path: linear, so shift / h exactly up to
        // round-off of the pieces' lengths).
        assert_eq!(positions[moving], start + shift);
        assert_eq!(positions[0], next_pinned[0]);
        let expected = shift / h;
        assert!(
            (velocities[moving] - expected).norm() <= 1e-9 * expected.norm(),
            "{:?} against {expected:?}",
            velocities[moving]
        );
    }

    #[test]
    fn below_the_convex_step_the_newton_matrix_is_positive_semidefinite() {
        let mesh = generators::cloth(5, 1e3).unwrap();
        let mut rest = mesh.positions().to_vec();
        // Crushed to 1 % (the hard case), and a wavy compression of 30 % in x only.
        let crushed: Vec<_> = rest.iter().map(|p| p * 0.01).collect();
        for p in &mut rest {
            p.x *= 0.7;
            p.y = 0.01 * (7.0 * p.x).sin();
        }
        for x in [crushed, rest] {
            let scene = Scene::new(mesh.clone(), 1.0 / 30.0)
                .unwrap()
                .with_pins(Pins::Vertices(vec![0, 4]))
                .unwrap();
            let bound = convex_step(&scene, &effective_masses(&scene), &x);
            assert!(bound > 0.0 && bound < scene.time_step(), "bound {bound}");
            // At the bound: positive semidefinite up to round-off.
            let at_bound = scene.clone().with_time_step(bound).unwrap();
            let smallest = smallest_eigenvalue(&at_bound, &x);
            assert!(
                smallest >= -1e-12,
                "λ_min/A_max = {smallest:e} at h = {bound:e}"
            );
            // The bound is not vacuous: 1/30 s, far above it, is indefinite here.
            let smallest = smallest_eigenvalue(&scene, &x);
            assert!(smallest < 0.0, "λ_min/A_max = {smallest:e} at h = 1/30 s");
        }
    }
}
