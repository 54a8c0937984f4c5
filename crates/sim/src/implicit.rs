//! Backward Euler (SPEC §2.4–2.5): x⁺ minimises Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) over the free
//! vertices, with y = x_n + h v_n + h² M⁻¹ f_ext, then v⁺ = (x⁺ − x_n)/h. Solved by Newton (seed 003)
//! or by projective dynamics (Liu et al. 2013), both from x⁰ = y.
//!
//! Terms of a scene and how they enter:
//! - gravity: a constant force, folded into y (exact for both solvers);
//! - drag: v⁺ ← v⁺ e^(−h c_drag) after the solve (as in the explicit integrators);
//! - contact: a projection of x⁺ and v⁺ after the solve (pinned vertices untouched);
//! - pins: removed from the unknowns (SPEC §3 reduction), held at their positions.
//!
//! Wind, buoyancy, the attractor and viscous or dashpot damping are not yet part of the implicit
//! solve; a scene that asks for them is refused with [`SimError::Unsupported`] rather than run with
//! the term silently missing.

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use hooke_assembly::{FreeDofs, HessianParams, HessianPattern, HessianWorkspace, SpringForces};
use hooke_mesh::Spring;
use hooke_solvers::{
    Newton, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics, SolveSummary, StopReason,
};
use nalgebra::SVector;

use crate::forces::ExternalForce;
use crate::{Scene, SimError};

/// Φ over the free DOFs of one step, for Newton.
#[derive(Debug)]
struct StepObjective<const D: usize> {
    free: FreeDofs,
    pattern: HessianPattern<D>,
    workspace: HessianWorkspace<D>,
    values: Vec<f64>,
    forces: SpringForces<D>,
    force: Vec<SVector<f64, D>>,
    masses: Vec<f64>,
    springs: Vec<Spring>,
    shift: Vec<f64>,
    h: f64,
    /// Inertial target per vertex.
    y: Vec<SVector<f64, D>>,
    /// The full positions: pinned vertices fixed, free ones overwritten from the unknowns.
    x: Vec<SVector<f64, D>>,
}

impl<const D: usize> StepObjective<D> {
    fn expand(&mut self, xf: &[f64]) {
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            self.x[v as usize] = SVector::from_column_slice(&xf[D * f..D * f + D]);
        }
    }
}

impl<const D: usize> NewtonProblem for StepObjective<D> {
    fn dim(&self) -> usize {
        D * self.free.free_count()
    }

    fn objective(&mut self, xf: &[f64]) -> f64 {
        self.expand(xf);
        let inertia: f64 = self
            .free
            .free_vertices()
            .iter()
            .map(|&v| {
                let v = v as usize;
                0.5 * self.masses[v] * (self.x[v] - self.y[v]).norm_squared()
            })
            .sum();
        inertia + self.h * self.h * hooke_assembly::spring_energy(&self.springs, &self.x, true)
    }

    fn gradient(&mut self, xf: &[f64], g: &mut [f64]) {
        self.expand(xf);
        self.forces
            .compute(&self.springs, &self.x, None, &mut self.force, true);
        let h2 = self.h * self.h;
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let gv = (self.x[v] - self.y[v]) * self.masses[v] - self.force[v] * h2;
            g[D * f..D * f + D].copy_from_slice(gv.as_slice());
        }
    }

    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.pattern.symbolic()
    }

    fn hessian(&mut self, xf: &[f64]) -> SparseColMatRef<'_, usize, f64> {
        self.expand(xf);
        self.pattern.assemble_into(
            &self.springs,
            &self.x,
            &self.masses,
            self.h,
            HessianParams::default(),
            &mut self.workspace,
            &mut self.values,
        );
        self.pattern.matrix(&self.values)
    }

    fn shift_diagonal(&self) -> &[f64] {
        &self.shift
    }
}

/// Which solver, with its state kept across steps.
#[derive(Debug)]
enum Solver<const D: usize> {
    Newton {
        newton: Box<Newton>,
        objective: Box<StepObjective<D>>,
        unknowns: Vec<f64>,
    },
    Projective {
        pd: Box<ProjectiveDynamics<D>>,
        y: Vec<SVector<f64, D>>,
    },
}

/// A backward Euler integrator bound to one scene (topology, pins, masses, h).
#[derive(Debug)]
pub(crate) struct BackwardEuler<const D: usize> {
    solver: Solver<D>,
    gravity: SVector<f64, D>,
    x_start: Vec<SVector<f64, D>>,
}

/// Refuse scene terms the implicit solve does not model yet.
fn check_supported<const D: usize>(scene: &Scene<D>, name: &str) -> Result<(), SimError> {
    let unsupported = |what: &str| SimError::Unsupported {
        integrator: name.to_string(),
        what: what.to_string(),
    };
    for f in scene.forces().as_slice() {
        match f {
            ExternalForce::Gravity { .. } => {}
            ExternalForce::Wind { .. } => return Err(unsupported("wind")),
            ExternalForce::Buoyancy { .. } => return Err(unsupported("buoyancy")),
            ExternalForce::Attractor { .. } => return Err(unsupported("the point attractor")),
        }
    }
    let damping = scene.damping();
    if damping.viscous > 0.0 {
        return Err(unsupported("viscous damping"));
    }
    if damping.dashpot > 0.0 {
        return Err(unsupported("dashpot damping"));
    }
    Ok(())
}

impl<const D: usize> BackwardEuler<D> {
    /// Newton's method on Φ.
    pub(crate) fn newton(scene: &Scene<D>, params: NewtonParams) -> Result<Self, SimError> {
        check_supported(scene, "newton")?;
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let pattern = HessianPattern::new(n, mesh.springs(), Some(&free));
        let newton = Newton::new(pattern.symbolic(), params).map_err(|e| SimError::Solver {
            message: e.to_string(),
        })?;
        let shift = free
            .free_vertices()
            .iter()
            .flat_map(|&v| [mesh.masses()[v as usize]; D])
            .collect();
        let objective = StepObjective {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            forces: SpringForces::new(n, mesh.springs()),
            force: vec![SVector::zeros(); n],
            masses: mesh.masses().to_vec(),
            springs: mesh.springs().to_vec(),
            shift,
            h: scene.time_step(),
            y: vec![SVector::zeros(); n],
            x: mesh.positions().to_vec(),
            free,
            pattern,
        };
        let unknowns = vec![0.0; objective.dim()];
        Ok(BackwardEuler {
            solver: Solver::Newton {
                newton: Box::new(newton),
                objective: Box::new(objective),
                unknowns,
            },
            gravity: scene.forces().gravity().unwrap_or_else(SVector::zeros),
            x_start: vec![SVector::zeros(); n],
        })
    }

    /// Projective dynamics on Φ (the matrix is factored here, once).
    pub(crate) fn projective(scene: &Scene<D>, params: PdParams) -> Result<Self, SimError> {
        check_supported(scene, "pd")?;
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let pd = ProjectiveDynamics::new(
            mesh.springs(),
            mesh.masses(),
            &free,
            scene.time_step(),
            params,
        )
        .map_err(|e| SimError::Solver {
            message: e.to_string(),
        })?;
        Ok(BackwardEuler {
            solver: Solver::Projective {
                pd: Box::new(pd),
                y: vec![SVector::zeros(); n],
            },
            gravity: scene.forces().gravity().unwrap_or_else(SVector::zeros),
            x_start: vec![SVector::zeros(); n],
        })
    }

    /// One step: positions and velocities of the free vertices are updated in place; pinned ones
    /// keep their positions and get zero velocity. Returns the solver's summary.
    pub(crate) fn step(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
    ) -> Result<SolveSummary, SimError> {
        let h = scene.time_step();
        let pinned = scene.is_pinned();
        self.x_start.copy_from_slice(positions);
        let target = |v: usize, x: &SVector<f64, D>, vel: &SVector<f64, D>| {
            if pinned[v] {
                *x
            } else {
                x + vel * h + self.gravity * (h * h)
            }
        };
        let summary = match &mut self.solver {
            Solver::Newton {
                newton,
                objective,
                unknowns,
            } => {
                for v in 0..positions.len() {
                    objective.y[v] = target(v, &positions[v], &velocities[v]);
                    objective.x[v] = positions[v];
                }
                for (f, &v) in objective.free.free_vertices().iter().enumerate() {
                    unknowns[D * f..D * f + D].copy_from_slice(objective.y[v as usize].as_slice());
                }
                let report = newton.minimize(objective.as_mut(), unknowns).map_err(|e| {
                    SimError::Solver {
                        message: e.to_string(),
                    }
                })?;
                objective.expand(unknowns);
                positions.copy_from_slice(&objective.x);
                SolveSummary {
                    iterations: report.iterations,
                    residual: report.gradient(),
                    stop: report.stop,
                }
            }
            Solver::Projective { pd, y } => {
                for v in 0..positions.len() {
                    y[v] = target(v, &positions[v], &velocities[v]);
                }
                // x⁰ = y at free vertices; pinned vertices keep their positions (y = x there).
                positions.copy_from_slice(y);
                let report = pd.solve(scene.mesh().springs(), y, positions);
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
                velocities[v] = SVector::zeros();
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
