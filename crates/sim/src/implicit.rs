//! Backward Euler (SPEC §2.4–2.5): x⁺ minimises Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) over the free
//! vertices, with y = x_n + h v_n + h² M⁻¹ f_ext, then v⁺ = (x⁺ − x_n)/h. Solved by Newton (seed 003)
//! or by projective dynamics (Liu et al. 2013), both from x⁰ = y.
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
//! - contact: a projection of x⁺ and v⁺ after the solve (pinned vertices untouched);
//! - pins: removed from the unknowns (SPEC §3 reduction), held at their positions, or at the end of
//!   the step moved to where their prescribed path is at t + h (the right-hand side changes, the
//!   matrices do not: PD's factorisation and Newton's symbolic analysis are kept).

use hooke_assembly::FreeDofs;
use hooke_solvers::{
    BackwardEulerStep, Newton, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics,
    SolveSummary, StopReason,
};
use nalgebra::SVector;

use crate::forces::ExternalForce;
use crate::{Scene, SimError};

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
}

/// A backward Euler integrator bound to one scene (topology, pins, masses, h).
#[derive(Debug)]
pub(crate) struct BackwardEuler<const D: usize> {
    solver: Solver<D>,
    /// Effective masses A (kg, per vertex): see the module documentation.
    inertia: Vec<f64>,
    x_start: Vec<SVector<f64, D>>,
    /// The inertial target y of the current step, per vertex.
    y: Vec<SVector<f64, D>>,
}

/// Refuse scene terms the solver does not model (see the module documentation).
fn check_supported<const D: usize>(scene: &Scene<D>, name: &str) -> Result<(), SimError> {
    if name == "pd" && scene.damping().dashpot > 0.0 {
        return Err(SimError::Unsupported {
            integrator: name.to_string(),
            what: "dashpot damping (its Jacobian changes with the spring directions; projective \
                   dynamics factors one constant matrix: use newton or linearized)"
                .to_string(),
        });
    }
    Ok(())
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
    /// Newton's method on Φ.
    pub(crate) fn newton(scene: &Scene<D>, params: NewtonParams) -> Result<Self, SimError> {
        check_supported(scene, "newton")?;
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let inertia = effective_masses(scene);
        let objective = BackwardEulerStep::new(mesh.springs(), &inertia, free, scene.time_step());
        let newton = Newton::new(objective.pattern(), params).map_err(|e| SimError::Solver {
            message: e.to_string(),
        })?;
        let unknowns = vec![0.0; objective.dim()];
        Ok(BackwardEuler {
            solver: Solver::Newton {
                newton: Box::new(newton),
                objective: Box::new(objective),
                unknowns,
            },
            inertia,
            x_start: vec![SVector::zeros(); n],
            y: vec![SVector::zeros(); n],
        })
    }

    /// Time of projective dynamics' last factorisation (it factors once, in
    /// [`BackwardEuler::projective`]); `None` for Newton.
    pub(crate) fn factor_time(&self) -> Option<std::time::Duration> {
        match &self.solver {
            Solver::Projective { pd } => Some(pd.factor_time()),
            Solver::Newton { .. } => None,
        }
    }

    /// Projective dynamics on Φ (the matrix is factored here, once).
    pub(crate) fn projective(scene: &Scene<D>, params: PdParams) -> Result<Self, SimError> {
        check_supported(scene, "pd")?;
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let inertia = effective_masses(scene);
        let pd =
            ProjectiveDynamics::new(mesh.springs(), &inertia, &free, scene.time_step(), params)
                .map_err(|e| SimError::Solver {
                    message: e.to_string(),
                })?;
        Ok(BackwardEuler {
            solver: Solver::Projective { pd: Box::new(pd) },
            inertia,
            x_start: vec![SVector::zeros(); n],
            y: vec![SVector::zeros(); n],
        })
    }

    /// One step: positions and velocities of the free vertices are updated in place; pinned ones
    /// move to `next_pinned` (full numbering; free entries are not read) with the velocity of that
    /// move. Returns the solver's summary.
    pub(crate) fn step(
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
                objective.set_step(&self.y, positions, unknowns);
                objective.set_dashpot(scene.damping().dashpot, &self.x_start);
                let report = newton.minimize(objective.as_mut(), unknowns).map_err(|e| {
                    SimError::Solver {
                        message: e.to_string(),
                    }
                })?;
                positions.copy_from_slice(objective.positions(unknowns));
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.gradient(),
                    stop: report.stop,
                }
            }
            Solver::Projective { pd } => {
                for v in 0..positions.len() {
                    self.y[v] = target(v, &positions[v], &velocities[v]);
                }
                // x⁰ = y at free vertices; pinned vertices keep their positions (y = x there).
                positions.copy_from_slice(&self.y);
                let report = pd.solve(scene.mesh().springs(), &self.y, positions);
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.changes.last().copied().unwrap_or(0.0),
                    stop: report.stop,
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
            for contact in scene.contacts() {
                contact.project(&mut positions[v], &mut velocities[v]);
            }
        }
        debug_assert!(matches!(
            summary.stop,
            StopReason::Converged | StopReason::IterationLimit | StopReason::Stagnated
        ));
        Ok(summary)
    }
}
