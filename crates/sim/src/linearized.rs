//! Linearised implicit Euler of the β family (docs/model.md §6.3):
//!
//! [M − β h² ∂f/∂x(x) − h ∂f/∂v] v⁺ = M v + h f(x, v) − h (∂f/∂v) v,   x⁺ = x + h v⁺,
//!
//! over the free vertices (pins by reduction, docs/model.md §5.2), solved by block Jacobi or by
//! conjugate gradient with the block-Jacobi preconditioner. Without velocity-dependent forces this
//! is [M − β h² ∂f/∂x] v⁺ = M v + h f(x). β = 0 is symplectic Euler, ½ the midpoint-like rule, 1
//! linearised backward Euler: one Newton step of backward Euler started from x⁰ = x_n (not from y,
//! where [`crate::Integrator::Newton`] starts).
//!
//! The matrix is assembled by [`HessianPattern::assemble_into`], which fills D + h'² ∇²E for a
//! per-vertex diagonal D (the masses, plus the attractor below); with h' = h√β and ∇²E = −∂f/∂x
//! (springs) that is the spring part. [`HessianPattern::add_vertex_diagonal`] adds the viscous and
//! wind terms and [`HessianPattern::add_dashpot_into`] the dashpot's, each only when the scene has
//! them. The symbolic pattern is built once per scene and the values are refilled in place every
//! step, as are the inverted diagonal blocks ([`BlockJacobi::refill`]: Jacobi's splitting and CG's
//! preconditioner); a step allocates only the linear solver's report. How each term of a scene
//! enters:
//!
//! - springs: f(x) on the right-hand side; their exact Hessian (or the clamped one, see
//!   [`LinearizedParams::definiteness`]), scaled by β h², in the matrix;
//! - gravity and buoyancy: in f(x) on the right-hand side (their x-derivative is zero; buoyancy's
//!   jump at the surface is not linearised);
//! - the attractor f = −s m (x − p): f(x) on the right-hand side and its Jacobian −s m I in the
//!   matrix, as + β h² s m on the vertex's diagonal (so β = 1 treats it exactly as backward Euler);
//! - wind f = c (w − v): implicit in v, like viscous damping: + h c on the diagonal, and only its
//!   constant part h c w on the right-hand side;
//! - viscous damping f = −c v: implicit in v: h c added on the diagonal (the −h c v of f and
//!   the h c v of −h (∂f/∂v) v cancel on the right-hand side);
//! - dashpot damping f_i = −c_d ((v_i − v_j)·r̂) r̂: implicit in v through its velocity
//!   Jacobian, blocks h c_d r̂r̂ᵀ added (r̂ at x_n; its dependence on x is not linearised), nothing
//!   on the right-hand side;
//! - drag: v⁺ ← v⁺ e^(−h c_drag) after the solve, before x⁺ = x + h v⁺ (the order of the
//!   symplectic integrator, so that β = 0 is symplectic Euler exactly);
//! - contact: a projection of x⁺ and v⁺ after the step, for the whole mesh, done by
//!   [`crate::Simulation`] (see [`crate::barrier`]; pinned vertices untouched);
//! - pins: removed from the unknowns; a pinned vertex moves to its prescribed position at the end
//!   of the step with velocity (x_pin(t + h) − x)/h, and that known velocity enters the free rows'
//!   right-hand side through the coupling blocks (β h² H_s + h c_d r̂r̂ᵀ) v_pin of the springs to it.
//!   With [`PinMethod::CounterForce`] every vertex keeps its D unknowns instead: the matrix is
//!   assembled on all vertices and [`CounterForce::apply_to_matrix`] replaces the pinned rows and
//!   columns by m_p I (the diagonal above), the counter-force cancelling the force on the pinned
//!   vertex together with its Jacobian. The pinned unknowns are the velocity change relative to the
//!   prescribed v_pin, zero: their right-hand side and initial guess are zero, so Jacobi and CG never
//!   move them (zero residual in a decoupled row), and the known v_pin enters the free rows as
//!   above (the zeroed columns carried it). The free rows are the reduced system's, solved with the
//!   pinned entries as extra zeros; the step equals the reduction's up to round-off.
//!
//! Damping and wind are thus treated by backward Euler in v whatever β (β scales only the position
//! linearisation), which makes them unconditionally stable.

use hooke_assembly::spring::{dashpot_velocity_block, hessian_block};
use hooke_assembly::{
    CounterForce, Definiteness, FreeDofs, HessianParams, HessianPattern, HessianWorkspace,
    SpringForces,
};
use hooke_solvers::{
    BlockJacobi, CgParams, ConjugateGradient, Jacobi, JacobiParams, Report, SolveError,
    SolveSummary, Symmetric,
};
use nalgebra::{SMatrix, SVector};

use crate::forces::ExternalForce;
use crate::integrator::{LinearSolver, LinearizedParams, PinMethod};
use crate::{Scene, SimError};

/// What one linearised step did.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LinearizedStep {
    pub summary: SolveSummary,
    /// The exact Hessian was not positive definite and the step was solved with the clamped one.
    pub clamped: bool,
}

/// The linearised integrator bound to one scene (topology, pins, masses, h, damping).
#[derive(Debug)]
pub(crate) struct Linearized<const D: usize> {
    params: LinearizedParams,
    free: FreeDofs,
    pattern: HessianPattern<D>,
    /// Pins by counter-force: every vertex has unknowns, the pinned rows and columns replaced.
    counter: Option<CounterForce<D>>,
    workspace: HessianWorkspace<D>,
    values: Vec<f64>,
    /// Per vertex (full numbering): m (1 + β h² s), s the attractor strength.
    diagonal: Vec<f64>,
    /// Per vertex: h (c_viscous + c_wind); empty when zero.
    damping_diagonal: Vec<f64>,
    /// Dashpot coefficient c_d (N·s/m).
    dashpot: f64,
    forces: SpringForces<D>,
    force: Vec<SVector<f64, D>>,
    rhs: Vec<f64>,
    unknowns: Vec<f64>,
    /// Velocity of each pinned vertex over the step (full numbering; free entries unused).
    pin_velocity: Vec<SVector<f64, D>>,
    /// Springs with exactly one pinned end.
    boundary: Vec<u32>,
    /// Σ c_wind (N·s/m) over the wind terms.
    wind_coefficient: f64,
    /// The inverted diagonal blocks of the matrix, refilled in place every solve: Jacobi's
    /// splitting and CG's preconditioner.
    preconditioner: BlockJacobi<D>,
    cg: ConjugateGradient,
    jacobi: Jacobi,
}

impl<const D: usize> Linearized<D> {
    /// The integrator for `scene` with `params`, pins held by `pins`.
    pub(crate) fn new(
        scene: &Scene<D>,
        params: LinearizedParams,
        pins: PinMethod,
    ) -> Result<Self, SimError> {
        params.validate()?;
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let (pattern, counter) = match pins {
            PinMethod::Reduction => (HessianPattern::new(n, mesh.springs(), Some(&free)), None),
            PinMethod::CounterForce => {
                let pattern = HessianPattern::new(n, mesh.springs(), None);
                let counter = CounterForce::new(&pattern, &free);
                (pattern, Some(counter))
            }
        };
        // Vertices with unknowns: vertex v's at D·v with counter-forces, free vertex f's at D·f.
        let unknown_vertices = if counter.is_some() {
            n
        } else {
            free.free_count()
        };
        let h = scene.time_step();
        let mut attractor = 0.0;
        let mut wind_coefficient = 0.0;
        for f in scene.forces().as_slice() {
            match f {
                ExternalForce::Attractor { strength, .. } => attractor += strength,
                ExternalForce::Wind { coefficient, .. } => wind_coefficient += coefficient,
                _ => {}
            }
        }
        let damping = scene.damping();
        let diagonal = mesh
            .masses()
            .iter()
            .map(|&m| m * (1.0 + params.beta * h * h * attractor))
            .collect();
        let damping_rate = h * (damping.viscous + wind_coefficient);
        let damping_diagonal = if damping_rate > 0.0 {
            vec![damping_rate; n]
        } else {
            Vec::new()
        };
        let is_pinned = scene.is_pinned();
        let boundary = mesh
            .springs()
            .iter()
            .enumerate()
            .filter(|(_, s)| is_pinned[s.i as usize] != is_pinned[s.j as usize])
            .map(|(k, _)| k as u32)
            .collect();
        let dim = D * unknown_vertices;
        Ok(Linearized {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            diagonal,
            damping_diagonal,
            dashpot: damping.dashpot,
            forces: SpringForces::new(n, mesh.springs()),
            force: vec![SVector::zeros(); n],
            rhs: vec![0.0; dim],
            unknowns: vec![0.0; dim],
            pin_velocity: vec![SVector::zeros(); n],
            boundary,
            wind_coefficient,
            preconditioner: BlockJacobi::identity(unknown_vertices),
            cg: ConjugateGradient::new(CgParams {
                tolerance: params.tolerance,
                max_iterations: params.max_iterations,
            }),
            jacobi: Jacobi::new(JacobiParams {
                tolerance: params.tolerance,
                max_iterations: params.max_iterations,
                ..JacobiParams::default()
            }),
            params,
            free,
            pattern,
            counter,
        })
    }

    /// The first unknown of vertex `v`, free vertex number `f`.
    #[inline]
    fn offset(&self, f: usize, v: usize) -> usize {
        D * if self.counter.is_some() { v } else { f }
    }

    /// One step from `positions`, `velocities` (updated in place); pinned vertices end at
    /// `next_pinned` (full numbering; free entries are not read). `step` numbers errors.
    pub(crate) fn step(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        next_pinned: &[SVector<f64, D>],
        step: usize,
        parallel: bool,
    ) -> Result<LinearizedStep, SimError> {
        let h = scene.time_step();
        let mesh = scene.mesh();
        for &v in scene.pinned() {
            let v = v as usize;
            self.pin_velocity[v] = (next_pinned[v] - positions[v]) / h;
        }
        self.forces
            .compute(mesh.springs(), positions, None, &mut self.force, parallel);
        let mut definiteness = self.params.definiteness;
        let mut clamped = false;
        let report = loop {
            self.assemble(scene, positions, velocities, definiteness, parallel);
            match self.solve() {
                Ok(report) => break report,
                Err(SolveError::NotPositiveDefinite { .. } | SolveError::Diverged { .. })
                    if definiteness == Definiteness::Exact
                        && self.params.clamp_on_failure
                        && self.params.beta > 0.0 =>
                {
                    definiteness = Definiteness::Clamped;
                    clamped = true;
                }
                Err(source) => {
                    return Err(SimError::LinearSolve {
                        step,
                        solver: self.params.solver.name(),
                        source,
                    })
                }
            }
        };
        let drag = (-h * scene.damping().drag).exp();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let o = self.offset(f, v);
            let vel = SVector::<f64, D>::from_column_slice(&self.unknowns[o..o + D]) * drag;
            velocities[v] = vel;
            positions[v] += vel * h;
        }
        for &v in scene.pinned() {
            let v = v as usize;
            positions[v] = next_pinned[v];
            velocities[v] = self.pin_velocity[v];
        }
        Ok(LinearizedStep {
            summary: report.summary(),
            clamped,
        })
    }

    /// Fill the matrix values, the right-hand side and the initial guess (v).
    fn assemble(
        &mut self,
        scene: &Scene<D>,
        positions: &[SVector<f64, D>],
        velocities: &[SVector<f64, D>],
        definiteness: Definiteness,
        parallel: bool,
    ) {
        let h = scene.time_step();
        let beta = self.params.beta;
        let mesh = scene.mesh();
        let masses = mesh.masses();
        let forces = scene.forces();
        self.pattern.assemble_into(
            mesh.springs(),
            positions,
            &self.diagonal,
            h * beta.sqrt(),
            HessianParams {
                definiteness,
                parallel,
            },
            &mut self.workspace,
            &mut self.values,
        );
        if !self.damping_diagonal.is_empty() {
            self.pattern
                .add_vertex_diagonal(&self.damping_diagonal, &mut self.values);
        }
        if self.dashpot > 0.0 {
            self.pattern.add_dashpot_into(
                mesh.springs(),
                positions,
                self.dashpot,
                h,
                &mut self.values,
            );
        }
        if let Some(counter) = &self.counter {
            // Pinned rows and columns: the diagonal's m_p I, zero elsewhere. Their unknowns (the
            // velocity change from the prescribed one) and right-hand side are zero.
            counter.apply_to_matrix(&self.diagonal, &mut self.values);
            for &p in self.free.pinned() {
                let o = D * p as usize;
                self.rhs[o..o + D].fill(0.0);
                self.unknowns[o..o + D].fill(0.0);
            }
        }
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let o = self.offset(f, v);
            let (m, x, vel) = (masses[v], &positions[v], &velocities[v]);
            // External forces at (x, v), with wind's −c v moved into the matrix.
            let mut external = SVector::<f64, D>::zeros();
            if !forces.is_empty() {
                external = forces.force(m, x, vel) + vel * self.wind_coefficient;
            }
            let b = vel * m + (self.force[v] + external) * h;
            self.rhs[o..o + D].copy_from_slice(b.as_slice());
            self.unknowns[o..o + D].copy_from_slice(vel.as_slice());
        }
        // Known velocities of moving pins: −A_ij v_j to the free row i.
        let dashpot = self.dashpot;
        for &s in &self.boundary {
            let spring = &mesh.springs()[s as usize];
            let (i, j) = spring.ends();
            let (free_end, pinned_end) = if self.free.is_pinned(j) {
                (i, j)
            } else {
                (j, i)
            };
            let vp = self.pin_velocity[pinned_end];
            if vp.iter().all(|&c| c == 0.0) {
                continue;
            }
            let r = positions[i] - positions[j];
            let mut coupling: SMatrix<f64, D, D> = SMatrix::zeros();
            if beta > 0.0 {
                coupling += hessian_block(spring.stiffness, spring.rest_length, &r, definiteness)
                    * (beta * h * h);
            }
            if dashpot > 0.0 {
                coupling -= dashpot_velocity_block(dashpot, &r) * h;
            }
            let f = self
                .free
                .free_index(free_end)
                .expect("one end of a boundary spring is free");
            let o = self.offset(f, free_end);
            let add = coupling * vp;
            for a in 0..D {
                self.rhs[o + a] += add[a];
            }
        }
    }

    fn solve(&mut self) -> Result<Report, SolveError> {
        let values = &self.values;
        self.preconditioner
            .refill(self.pattern.diagonal_blocks(values))?;
        let a = Symmetric(self.pattern.matrix(values));
        match self.params.solver {
            LinearSolver::ConjugateGradient => {
                self.cg
                    .solve(&a, &mut self.preconditioner, &self.rhs, &mut self.unknowns)
            }
            LinearSolver::Jacobi => {
                self.jacobi
                    .solve(&a, &self.preconditioner, &self.rhs, &mut self.unknowns)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pins;
    use hooke_mesh::generators;

    /// With counter-forces every vertex has unknowns, and the pinned ones (the velocity change from
    /// the prescribed velocity) stay exactly zero through the solve.
    #[test]
    fn counter_forces_keep_every_vertex_an_unknown_and_the_pinned_ones_at_zero() {
        let mesh = generators::cloth(6, 1e3).unwrap();
        let n = mesh.vertex_count();
        let scene = Scene::new(mesh, 1.0 / 30.0)
            .unwrap()
            .with_pins(Pins::Vertices(vec![0, 5]))
            .unwrap();
        let mut positions = scene.initial_state().positions;
        // A deformed start, so that every free velocity changes.
        for (v, x) in positions.iter_mut().enumerate() {
            x.y += 0.01 * (v as f64).sin();
        }
        let velocities = vec![SVector::zeros(); n];
        let next_pinned = positions.clone();
        for (pins, dim) in [
            (PinMethod::Reduction, 3 * (n - 2)),
            (PinMethod::CounterForce, 3 * n),
        ] {
            let mut integrator =
                Linearized::<3>::new(&scene, LinearizedParams::default(), pins).unwrap();
            assert_eq!(integrator.unknowns.len(), dim, "{pins}");
            let (mut x, mut v) = (positions.clone(), velocities.clone());
            integrator
                .step(&scene, &mut x, &mut v, &next_pinned, 1, false)
                .unwrap();
            if pins == PinMethod::CounterForce {
                for p in [0, 5] {
                    assert_eq!(&integrator.unknowns[3 * p..3 * p + 3], &[0.0; 3]);
                    assert_eq!(x[p], positions[p]);
                }
            }
            assert!(v.iter().any(|v| v.norm() > 1e-3), "{pins}: the cloth moves");
        }
    }
}
