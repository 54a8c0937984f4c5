//! A running simulation: a scene, its state, and the workspaces of its integrator.

use std::time::{Duration, Instant};

use hooke_assembly::{Dashpot, SpringForces};
use hooke_solvers::SolveSummary;
use nalgebra::SVector;
use rayon::prelude::*;

use crate::implicit::{BackwardEuler, Minimizer};
use crate::integrator::{Integrator, Settings};
use crate::linearized::Linearized;
use crate::projection::StepProjection;
use crate::stability::{stability_bound, StabilityBound};
use crate::{Energy, Scene, SimError, State};
use hooke_solvers::backward_euler::SelfContactState;

mod snapshot;
pub use snapshot::{HalvingMemory, Snapshot};

/// Auto substepping never asks for more than this many substeps per frame: past it the scene
/// needs an implicit integrator, and saying so beats running for hours.
pub const MAX_AUTO_SUBSTEPS: usize = 100_000;

/// A coordinate beyond this many times the scene's size (plus 1 m) means the run exploded.
pub const DIVERGENCE_FACTOR: f64 = 1e6;

/// Vertex loops below this size run serially.
const PARALLEL_VERTICES: usize = 8 * 1024;

/// What one frame step did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Substeps taken: the explicit methods' substeps per frame; for implicit methods 1, unless
    /// backward Euler by Newton halved a step it could not finish (then the number of pieces).
    pub substeps: usize,
    /// The solver's summary, for integrators that solve a system.
    pub solver: Option<SolveSummary>,
    /// Whether the solver converged this frame ([`hooke_solvers::StopReason::is_converged`]: the
    /// tolerance, or the proven rounding floor, was reached in every piece of the step); `None`
    /// for the explicit integrators, which solve nothing. Projective dynamics with its default
    /// tolerance 0 runs a fixed budget and reports `Some(false)`.
    pub converged: Option<bool>,
    /// Wall time of the step.
    pub wall_time: Duration,
    /// The linearised integrator found the exact Hessian's system not positive definite and solved
    /// the step with the clamped Hessian (see
    /// [`LinearizedParams::clamp_on_failure`](crate::LinearizedParams::clamp_on_failure)); false for
    /// every other integrator.
    pub clamped_hessian: bool,
}

/// A scene being simulated. Buffers are allocated once in [`Simulation::new`]; a step allocates
/// only its solver's report (once per implicit step, whatever the iterations; nothing for the
/// explicit integrators), which `crates/sim/tests/allocations.rs` checks.
#[derive(Debug)]
pub struct Simulation<const D: usize> {
    scene: Scene<D>,
    state: State<D>,
    settings: Settings,
    substeps: usize,
    bound: StabilityBound,
    spring_forces: SpringForces<D>,
    force: Vec<SVector<f64, D>>,
    steps_taken: usize,
    start_time: f64,
    divergence_limit: f64,
    implicit: Option<BackwardEuler<D>>,
    linearized: Option<Linearized<D>>,
    /// Vertices on pin paths: (vertex, index into the scene's paths, reference position x₀ with
    /// x(t₀) = path position of x₀ at t₀, [`crate::PinPath::reference`]).
    moving: Vec<(usize, usize, SVector<f64, D>)>,
    /// Pinned positions at the end of the current step (full numbering; free entries unused).
    next_pinned: Vec<SVector<f64, D>>,
    /// The energy watchdog's limit (J), if it applies.
    energy_limit: Option<(f64, f64)>,
    /// Contact after an implicit step (scenes with contacts and an implicit integrator).
    projection: Option<StepProjection<D>>,
    /// The state at the start of the current step, restored if the step fails.
    before: State<D>,
    /// What self-contact does at the current state (scenes with self-contact).
    self_contact: Option<SelfContactState>,
}

impl<const D: usize> Simulation<D> {
    /// Start simulating `scene` from `state` with `settings`.
    ///
    /// # Errors
    /// - [`SimError::InvalidParameter`] or [`SimError::SolverParameter`] if `settings` does not
    ///   pass [`Settings::validate`], `state` does not match the mesh or holds non-finite values,
    ///   or an explicit method would need too many substeps;
    /// - [`SimError::Solver`] (step 0) if the solver cannot be set up (projective dynamics'
    ///   matrix does not factor);
    /// - [`SimError::UnstableStep`] if an explicit step is above the estimated stability bound and
    ///   `settings.allow_unstable` is false.
    pub fn new(scene: Scene<D>, state: State<D>, settings: Settings) -> Result<Self, SimError> {
        settings.validate()?;
        if scene.self_contact().is_some() && !settings.integrator.uses_contact_barrier() {
            return Err(SimError::Unsupported {
                integrator: settings.integrator.to_string(),
                what: "self-contact (its barrier and the collision detection that caps every \
                       line search live in the objective that newton, newton-cg and lbfgs \
                       minimise: use one of those)"
                    .to_string(),
            });
        }
        // Settings::parallel governs every integrator (PD's own flag included).
        let mut settings = settings;
        settings.pd.parallel = settings.parallel;
        let n = scene.mesh().vertex_count();
        for (what, len) in [
            ("positions", state.positions.len()),
            ("velocities", state.velocities.len()),
        ] {
            if len != n {
                return Err(SimError::invalid(
                    format!("initial {what}"),
                    format!("{len} entries"),
                    format!("the mesh has {n} vertices"),
                ));
            }
        }
        check_finite(&state, 0)?;
        let bound = stability_bound(&scene);
        let h = scene.time_step();
        let (safe_step, estimated_step) = bound.for_integrator(settings.integrator, h);
        let substeps = if settings.integrator.is_explicit() {
            let substeps = match settings.substeps {
                Some(0) => return Err(SimError::invalid("substeps", 0, "must be at least 1")),
                Some(s) => s,
                None => {
                    let needed = (h / safe_step).ceil();
                    if needed > MAX_AUTO_SUBSTEPS as f64 && !settings.allow_unstable {
                        return Err(SimError::invalid(
                            "substeps",
                            needed,
                            format!(
                                "{} would need {needed:.0} substeps per frame to stay stable \
                                 (more than {MAX_AUTO_SUBSTEPS}); use symplectic Euler or an \
                                 implicit integrator, or give the substeps and force the run",
                                settings.integrator
                            ),
                        ));
                    }
                    (needed as usize).clamp(1, MAX_AUTO_SUBSTEPS)
                }
            };
            let sub = h / substeps as f64;
            if sub > estimated_step && !settings.allow_unstable {
                return Err(SimError::UnstableStep {
                    step: sub,
                    bound: estimated_step,
                    vertex: bound.stiffest_vertex,
                    suggested_substeps: (h / safe_step).ceil() as usize,
                });
            }
            substeps
        } else {
            1
        };
        let mut implicit = match settings.integrator {
            Integrator::Newton | Integrator::Lbfgs | Integrator::NewtonCg => {
                let minimizer = match settings.integrator {
                    Integrator::Newton => Minimizer::Newton(settings.newton),
                    Integrator::Lbfgs => Minimizer::Lbfgs(settings.lbfgs, settings.pd),
                    _ => Minimizer::NewtonCg(settings.newton_cg, settings.pd),
                };
                Some(BackwardEuler::minimizer(
                    &scene,
                    minimizer,
                    settings.pins,
                    settings.parallel,
                )?)
            }
            Integrator::ProjectiveDynamics => Some(BackwardEuler::projective(
                &scene,
                settings.pd,
                settings.pins,
            )?),
            Integrator::ChebyshevPd => Some(BackwardEuler::chebyshev(
                &scene,
                settings.pd,
                settings.chebyshev,
                settings.chebyshev_estimate,
                settings.pins,
            )?),
            _ => None,
        };
        let linearized = match settings.integrator {
            Integrator::Linearized => {
                Some(Linearized::new(&scene, settings.linearized, settings.pins)?)
            }
            _ => None,
        };
        let barrier = settings.integrator.uses_contact_barrier() && !scene.contacts().is_empty();
        check_start(
            &scene,
            settings.integrator,
            &state.positions,
            "initial positions",
        )?;
        let projection = if !scene.contacts().is_empty()
            && !settings.integrator.is_explicit()
            && !settings.integrator.contact_in_solve()
        {
            Some(StepProjection::new(&scene)?)
        } else {
            None
        };
        let mut moving = Vec::new();
        for (index, group) in scene.pin_paths().iter().enumerate() {
            for &v in &group.vertices {
                let reference = group
                    .path
                    .reference(&state.positions[v as usize], state.time);
                moving.push((v as usize, index, reference));
            }
        }
        let spring_forces = SpringForces::new(n, scene.mesh().springs());
        let start_time = state.time;
        let extent = state
            .positions
            .iter()
            .flat_map(|p| p.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()));
        let divergence_limit = DIVERGENCE_FACTOR * (1.0 + extent);
        let has_sources = !scene.pin_paths().is_empty()
            || scene
                .forces()
                .as_slice()
                .iter()
                .any(|f| matches!(f, crate::ExternalForce::Wind { .. }));
        if let Some(factor) = settings.energy_limit {
            crate::error::non_negative("energy limit", factor)?;
        }
        let self_contact = implicit
            .as_mut()
            .and_then(|i| i.self_contact_state(&state.positions));
        let energy_limit = match settings.energy_limit {
            Some(factor) if !has_sources && !settings.allow_unstable => {
                let mut min = state.positions[0];
                let mut max = state.positions[0];
                for p in &state.positions {
                    min = min.inf(p);
                    max = max.sup(p);
                }
                let g = scene.forces().gravity().map_or(0.0, |g| g.norm());
                let scale = scene.mesh().total_mass() * g * (max - min).norm();
                let initial = scene.energy(&state).total
                    + if barrier {
                        scene.barrier_energy(&state.positions)
                    } else {
                        0.0
                    }
                    + self_contact.map_or(0.0, |c| c.energy);
                Some((initial, initial + factor * (initial.abs() + scale)))
            }
            _ => None,
        };
        Ok(Simulation {
            before: state.clone(),
            force: vec![SVector::zeros(); n],
            spring_forces,
            scene,
            state,
            settings,
            substeps,
            bound,
            steps_taken: 0,
            start_time,
            divergence_limit,
            implicit,
            linearized,
            moving,
            next_pinned: vec![SVector::zeros(); n],
            energy_limit,
            projection,
            self_contact,
        })
    }

    /// What self-contact does at the current state: its barrier energy, the smallest distance
    /// between two primitives of the surface, the pairs within d̂ and κ; `None` without it.
    pub fn self_contact_state(&self) -> Option<SelfContactState> {
        self.self_contact
    }

    /// The scale s (dimensionless, ≥ 1) that IPC's adaptive stiffness
    /// ([`crate::BarrierSettings::adaptive_stiffness`]) put on every barrier's stiffness in the
    /// last step, as it stood at the step's end; `None` when it is off or the integrator has no
    /// barrier in its objective.
    pub fn barrier_stiffness_scale(&self) -> Option<f64> {
        self.implicit
            .as_ref()
            .and_then(|i| i.barrier_stiffness_scale())
    }

    /// Recompute [`Simulation::self_contact_state`] for the current positions.
    fn refresh_self_contact(&mut self) {
        if let Some(implicit) = &mut self.implicit {
            self.self_contact = implicit.self_contact_state(&self.state.positions);
        }
    }

    /// The scene.
    pub fn scene(&self) -> &Scene<D> {
        &self.scene
    }

    /// The current state.
    pub fn state(&self) -> &State<D> {
        &self.state
    }

    /// The settings in use.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// Chebyshev PD's ρ and whether it was estimated, given, or the fallback; `None` for the other
    /// integrators, and before the first step when ρ is to be estimated.
    pub fn chebyshev_rate(&self) -> Option<crate::RateSource> {
        self.implicit.as_ref().and_then(|i| i.chebyshev_rate())
    }

    /// Substeps per frame (1 for implicit methods).
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// The scene's explicit stability bound.
    pub fn stability_bound(&self) -> StabilityBound {
        self.bound
    }

    /// Frames stepped so far.
    pub fn steps_taken(&self) -> usize {
        self.steps_taken
    }

    /// Wall time of the last factorisation of a system matrix that stays constant over the run
    /// (projective dynamics factors K (M + h² L) Kᵀ once, in [`Simulation::new`]; moving pins change
    /// only the right-hand side). `None` for the other integrators.
    pub fn factorization_time(&self) -> Option<Duration> {
        self.implicit.as_ref().and_then(|i| i.factor_time())
    }

    /// Forget what the solver carries from one step to the next beyond the state (Newton's factor
    /// held for reuse, [`hooke_solvers::FactorReuse`]): the next step is solved as the first step
    /// of a simulation built from this state would be. Call it where a checkpoint is written, so
    /// that a run resumed from the checkpoint and the run that wrote it take the same steps, bit
    /// for bit. Costs one factorisation more at the next step.
    pub fn forget_solver_history(&mut self) {
        if let Some(implicit) = &mut self.implicit {
            implicit.forget_solver_history();
        }
    }

    /// Replace the positions (m) and velocities (m/s) of every vertex between two steps, keeping the
    /// scene, the time and every factorisation and workspace: an interactive editor moves a particle
    /// or gives the particles an impulse (the 2D editor's right-button pull) without rebuilding its
    /// integrator. Static pinned vertices are held where `positions` puts them from then on;
    /// vertices on a pin path keep following their path. Copies; allocates nothing.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] if a slice's length is not the mesh's vertex count, and
    /// [`SimError::NonFinite`] naming the first NaN or infinite value; the state is then unchanged.
    pub fn set_motion(
        &mut self,
        positions: &[SVector<f64, D>],
        velocities: &[SVector<f64, D>],
    ) -> Result<(), SimError> {
        let n = self.state.positions.len();
        for (quantity, values) in [("position", positions), ("velocity", velocities)] {
            if values.len() != n {
                return Err(SimError::invalid(
                    format!("{quantity} count"),
                    values.len(),
                    format!("the mesh has {n} vertices"),
                ));
            }
            if let Some(vertex) = values.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                return Err(SimError::NonFinite {
                    step: self.steps_taken,
                    vertex,
                    quantity,
                });
            }
        }
        check_start(
            &self.scene,
            self.settings.integrator,
            positions,
            "positions",
        )?;
        self.state.positions.copy_from_slice(positions);
        self.state.velocities.copy_from_slice(velocities);
        Ok(())
    }

    /// Write the pinned positions at time `t` into `self.next_pinned` (static pins: where they are).
    fn pinned_targets(&mut self, t: f64) {
        for &v in self.scene.pinned() {
            self.next_pinned[v as usize] = self.state.positions[v as usize];
        }
        let paths = self.scene.pin_paths();
        for &(v, path, anchor) in &self.moving {
            self.next_pinned[v] = paths[path].path.position(&anchor, t);
        }
    }

    /// Energy of the current state (J).
    pub fn energy(&self) -> Energy {
        let mut energy = self.scene.energy(&self.state);
        if self.settings.integrator.uses_contact_barrier() {
            energy.contact = self.scene.barrier_energy(&self.state.positions)
                + self.self_contact.map_or(0.0, |c| c.energy);
            energy.total += energy.contact;
        }
        energy
    }

    /// Advance one frame of the scene's time step.
    ///
    /// After a failed step the simulation is as it was before that step: the same state (positions,
    /// velocities, time) and the same [`Simulation::steps_taken`], so the caller can inspect it,
    /// change the settings of a new simulation from it, or write it out. A step that finishes
    /// without converging is not a failure: its report says so ([`StepReport::converged`]).
    ///
    /// # Errors
    /// - [`SimError::NonFinite`] if the state became NaN or infinite, [`SimError::Diverged`] if it
    ///   ran far outside the scene, [`SimError::EnergyGrowth`] if the energy of a scene without
    ///   energy sources rose past [`Settings::energy_limit`]'s bound (the simulation is unstable);
    /// - [`SimError::LinearSolve`] if the linearised integrator's linear solve failed, and
    ///   [`SimError::Solver`] (with the step index and the solver's typed error and report) if
    ///   Newton, projective dynamics or the contact projection failed.
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        self.before.positions.copy_from_slice(&self.state.positions);
        self.before
            .velocities
            .copy_from_slice(&self.state.velocities);
        self.before.time = self.state.time;
        let steps_before = self.steps_taken;
        let result = self.try_step();
        if result.is_err() {
            self.state.positions.copy_from_slice(&self.before.positions);
            self.state
                .velocities
                .copy_from_slice(&self.before.velocities);
            self.state.time = self.before.time;
            self.steps_taken = steps_before;
            if self.self_contact.is_some() {
                self.refresh_self_contact();
            }
        }
        result.map_err(|e| e.at_step(steps_before + 1))
    }

    /// [`Simulation::step`] without the restore on failure.
    fn try_step(&mut self) -> Result<StepReport, SimError> {
        let start = Instant::now();
        let mut solver = None;
        let mut clamped_hessian = false;
        let end_time = self.start_time + (self.steps_taken + 1) as f64 * self.scene.time_step();
        if self.implicit.is_some() || self.linearized.is_some() {
            self.pinned_targets(end_time);
        }
        // The projecting implicit solvers step a scene without its contacts; the projection below
        // does the contact for the whole mesh (see the `contact` module). The minimising ones
        // keep them: their contact is part of Φ.
        let contacts = if self.projection.is_some() {
            self.scene.take_contacts()
        } else {
            Vec::new()
        };
        let h = self.scene.time_step();
        if let Some(implicit) = &mut self.implicit {
            let state = &mut self.state;
            // Where the moving pins are `offset` seconds after the frame's start, for a step that
            // Newton halves (pins that do not move stay where they are).
            let (paths, moving) = (self.scene.pin_paths(), &self.moving);
            let frame_start = self.start_time + self.steps_taken as f64 * h;
            let pins_at = |offset: f64, targets: &mut [SVector<f64, D>]| {
                for &(v, path, anchor) in moving {
                    targets[v] = paths[path].path.position(&anchor, frame_start + offset);
                }
            };
            let outcome = implicit.step(
                &self.scene,
                &mut state.positions,
                &mut state.velocities,
                &self.next_pinned,
                &pins_at,
            );
            if self.projection.is_some() {
                self.scene.restore_contacts(contacts);
            }
            solver = Some(outcome?);
            // Backward Euler sets v⁺ = (x⁺ − x_n)/h · e^(−h c_drag).
            self.project_contacts((-h * self.scene.damping().drag).exp())?;
        } else if let Some(linearized) = &mut self.linearized {
            let state = &mut self.state;
            let outcome = linearized.step(
                &self.scene,
                &mut state.positions,
                &mut state.velocities,
                &self.next_pinned,
                self.steps_taken + 1,
                self.settings.parallel,
            );
            if self.projection.is_some() {
                self.scene.restore_contacts(contacts);
            }
            let outcome = outcome?;
            solver = Some(outcome.summary);
            clamped_hessian = outcome.clamped;
            // The linearised step sets x⁺ = x_n + h v⁺, drag included in v⁺.
            self.project_contacts(1.0)?;
        } else {
            if self.projection.is_some() {
                self.scene.restore_contacts(contacts);
            }
            let h = self.scene.time_step() / self.substeps as f64;
            for _ in 0..self.substeps {
                self.explicit_substep(h);
            }
        }
        self.steps_taken += 1;
        // Frame times are exact multiples of h: summing substeps would drift by round-off.
        self.state.time = self.start_time + self.steps_taken as f64 * self.scene.time_step();
        check_finite(&self.state, self.steps_taken)?;
        self.check_bounded()?;
        if self.self_contact.is_some() {
            self.refresh_self_contact();
        }
        if let Some((initial, limit)) = self.energy_limit {
            let energy = self.energy().total;
            if energy.is_nan() || energy > limit {
                return Err(SimError::EnergyGrowth {
                    step: self.steps_taken,
                    integrator: self.settings.integrator.name(),
                    energy,
                    initial,
                    limit,
                });
            }
        }
        Ok(StepReport {
            // Backward Euler by Newton may halve a step it cannot finish (see `implicit`).
            substeps: solver.map_or(self.substeps, |s| s.substeps),
            solver,
            converged: solver.map(|s| s.stop.is_converged()),
            wall_time: start.elapsed(),
            clamped_hessian,
        })
    }

    /// The deepest penetration of a free vertex into an obstacle at the current state: the most
    /// negative signed distance (m), or the smallest distance if none is inside (∞ without
    /// obstacles).
    pub fn smallest_contact_distance(&self) -> f64 {
        smallest_distance(&self.scene, &self.state.positions).0
    }

    /// Contact after an implicit step (see [`StepProjection::apply`]).
    fn project_contacts(&mut self, velocity_scale: f64) -> Result<(), SimError> {
        if let Some(projection) = &mut self.projection {
            projection.apply(
                &self.scene,
                &mut self.state.positions,
                &mut self.state.velocities,
                velocity_scale,
                self.settings.parallel,
            )?;
        }
        Ok(())
    }

    /// Positions beyond the divergence limit, or velocities that would cross it within one frame,
    /// mean the run exploded (energies would overflow long before NaN appears).
    fn check_bounded(&self) -> Result<(), SimError> {
        let limit = self.divergence_limit;
        let velocity_limit = limit / self.scene.time_step();
        for (quantity, values, limit) in [
            ("position", &self.state.positions, limit),
            ("velocity", &self.state.velocities, velocity_limit),
        ] {
            for (vertex, p) in values.iter().enumerate() {
                let value = p.amax();
                if value > limit {
                    return Err(SimError::Diverged {
                        step: self.steps_taken,
                        vertex,
                        quantity,
                        value,
                        limit,
                    });
                }
            }
        }
        Ok(())
    }

    /// Total force (N) on every vertex at the current state into `self.force`.
    fn compute_forces(&mut self) {
        let damping = self.scene.damping();
        let dashpot = (damping.dashpot > 0.0).then_some(Dashpot {
            coefficient: damping.dashpot,
            velocities: &self.state.velocities,
        });
        self.spring_forces.compute(
            self.scene.mesh().springs(),
            &self.state.positions,
            dashpot,
            &mut self.force,
            self.settings.parallel,
        );
    }

    fn explicit_substep(&mut self, h: f64) {
        if !self.moving.is_empty() {
            self.pinned_targets(self.state.time + h);
        }
        self.compute_forces();
        let scene = &self.scene;
        let forces = scene.forces();
        let damping = scene.damping();
        let drag = (-h * damping.drag).exp();
        let symplectic = matches!(self.settings.integrator, Integrator::SymplecticEuler);
        let update = |(((x, v), f), (&m, &pinned)): VertexItem<'_, D>| {
            if pinned {
                *v = SVector::zeros();
                return;
            }
            let mut total = *f;
            if !forces.is_empty() {
                total += forces.force(m, x, v);
            }
            if damping.viscous > 0.0 {
                total -= *v * damping.viscous;
            }
            let v_old = *v;
            *v += total * (h / m);
            *v *= drag;
            *x += if symplectic { *v * h } else { v_old * h };
            for contact in scene.contacts() {
                contact.project(x, v);
            }
        };
        let masses = scene.mesh().masses();
        let pinned = scene.is_pinned();
        let state = &mut self.state;
        if self.settings.parallel && masses.len() >= PARALLEL_VERTICES {
            state
                .positions
                .par_iter_mut()
                .zip(state.velocities.par_iter_mut())
                .zip(self.force.par_iter())
                .zip(masses.par_iter().zip(pinned.par_iter()))
                .with_min_len(2048)
                .for_each(update);
        } else {
            state
                .positions
                .iter_mut()
                .zip(state.velocities.iter_mut())
                .zip(self.force.iter())
                .zip(masses.iter().zip(pinned.iter()))
                .for_each(update);
        }
        // Pins on a path move to where it is at the end of the substep (static ones stay, at rest).
        for &(v, _, _) in &self.moving {
            state.velocities[v] = (self.next_pinned[v] - state.positions[v]) / h;
            state.positions[v] = self.next_pinned[v];
        }
        state.time += h;
    }
}

/// One vertex's data in the update loop: ((position, velocity), force), (mass, pinned).
type VertexItem<'a, const D: usize> = (
    (
        (&'a mut SVector<f64, D>, &'a mut SVector<f64, D>),
        &'a SVector<f64, D>,
    ),
    (&'a f64, &'a bool),
);

fn check_finite<const D: usize>(state: &State<D>, step: usize) -> Result<(), SimError> {
    for (quantity, values) in [
        ("position", &state.positions),
        ("velocity", &state.velocities),
    ] {
        if let Some(vertex) = values.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(SimError::NonFinite {
                step,
                vertex,
                quantity,
            });
        }
    }
    Ok(())
}

/// The smallest signed distance (m) of a free vertex from an obstacle of `scene` at `positions`,
/// with the vertex and the obstacle's index (∞ without obstacles).
fn smallest_distance<const D: usize>(
    scene: &Scene<D>,
    positions: &[SVector<f64, D>],
) -> (f64, usize, usize) {
    let mut smallest = (f64::INFINITY, 0, 0);
    let pinned = scene.is_pinned();
    for (v, x) in positions.iter().enumerate() {
        if pinned[v] {
            continue;
        }
        for (k, contact) in scene.contacts().iter().enumerate() {
            let d = contact.signed_distance(x);
            if d < smallest.0 {
                smallest = (d, v, k);
            }
        }
    }
    smallest
}

/// Refuse `positions` (`what`: "initial positions" or "positions") that the integrator cannot
/// start from: with contact inside the solve, a free vertex on or inside an obstacle, and with the
/// barrier in 3D a triangle of the surface that reaches into a sphere (the barrier is infinite
/// there); with self-contact, a surface that intersects itself.
fn check_start<const D: usize>(
    scene: &Scene<D>,
    integrator: Integrator,
    positions: &[SVector<f64, D>],
    what: &str,
) -> Result<(), SimError> {
    if integrator.contact_in_solve() && !scene.contacts().is_empty() {
        check_outside_obstacles(scene, positions, what)?;
        if integrator.uses_contact_barrier() {
            check_triangles_outside_spheres(scene, positions, what)?;
        }
    }
    if scene.self_contact().is_some() {
        check_no_self_intersection(scene, positions, what)?;
    }
    Ok(())
}

/// In 3D the barrier holds the surface's triangles off the spheres as wholes: a triangle (with a
/// free vertex) that reaches on or into a sphere between its vertices is refused too.
fn check_triangles_outside_spheres<const D: usize>(
    scene: &Scene<D>,
    positions: &[SVector<f64, D>],
    what: &str,
) -> Result<(), SimError> {
    if D != 3 {
        return Ok(());
    }
    let v3 = |p: &SVector<f64, D>| nalgebra::Vector3::new(p[0], p[1], p[2]);
    let pinned = scene.is_pinned();
    let triangles = scene.surface_triangles();
    for (k, contact) in scene.contacts().iter().enumerate() {
        let crate::Shape::Sphere { center, radius } = contact.shape else {
            continue;
        };
        for (t, triangle) in triangles.iter().enumerate() {
            if triangle.iter().all(|&v| pinned[v as usize]) {
                continue;
            }
            let corners = triangle.map(|v| v3(&positions[v as usize]));
            let d = hooke_assembly::surface_barrier::triangle_sphere_distance(
                &corners,
                &v3(&center),
                radius,
            );
            if d <= 0.0 {
                return Err(SimError::invalid(
                    what,
                    format!(
                        "surface triangle {t} (vertices {triangle:?}) at distance {d:e} m from \
                         contact[{k}], a sphere"
                    ),
                    "every triangle must start strictly outside every sphere (the barrier holds \
                     triangles, not only vertices, off spheres): move the mesh or the sphere",
                ));
            }
        }
    }
    Ok(())
}

/// The contact barrier needs every free vertex strictly outside every obstacle at the start.
fn check_outside_obstacles<const D: usize>(
    scene: &Scene<D>,
    positions: &[SVector<f64, D>],
    what: &str,
) -> Result<(), SimError> {
    let (d, v, k) = smallest_distance(scene, positions);
    if d > 0.0 {
        return Ok(());
    }
    Err(SimError::invalid(
        what,
        format!("vertex {v} at signed distance {d:e} m from contact[{k}]"),
        "every free vertex must start strictly outside every obstacle (the contact barrier is \
         infinite on and inside a surface): move the mesh or the obstacle",
    ))
}

/// Refuse a start whose surface intersects itself (decided exactly): self-contact keeps a surface
/// free of intersections, it cannot undo one.
fn check_no_self_intersection<const D: usize>(
    scene: &Scene<D>,
    positions: &[SVector<f64, D>],
    what: &str,
) -> Result<(), SimError> {
    let points: Vec<nalgebra::Vector3<f64>> = positions
        .iter()
        .map(|p| nalgebra::Vector3::new(p[0], p[1], p[2]))
        .collect();
    let pairs =
        hooke_mesh::intersection::intersecting_triangle_pairs(&points, &scene.surface_triangles())
            .map_err(SimError::Mesh)?;
    match pairs.first() {
        Some([a, b]) => Err(SimError::invalid(
            what,
            format!("surface triangles {a} and {b} intersect"),
            "self-contact needs a surface free of intersections at the start",
        )),
        None => Ok(()),
    }
}
