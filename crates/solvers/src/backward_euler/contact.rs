//! Contact inside backward Euler's objective (docs/contact.md): for every free vertex v and
//! obstacle o, h² κ_v b(d_o(x_v)) with IPC's log barrier b (zero beyond d̂, +∞ at the surface), and
//! h² times the lagged friction potential of the contacts active at the step's start.

use hooke_assembly::contact::{self, LaggedFriction, Obstacle};
use hooke_assembly::Definiteness;
use nalgebra::{SMatrix, SVector};

/// The share of the time of impact a line search may go: after a step of this share of the way
/// to an obstacle, a vertex keeps a tenth of its distance, so no iterate reaches a surface.
pub const TIME_OF_IMPACT_SHARE: f64 = 0.9;

/// The contact model of a backward Euler step: obstacles with their friction coefficients, and the
/// barrier's and friction's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactModel<const D: usize> {
    /// The obstacles (static), each with its friction coefficient μ ≥ 0 (0: frictionless).
    pub obstacles: Vec<(Obstacle<D>, f64)>,
    /// The barrier's reach d̂ (m, > 0): a vertex farther than d̂ from an obstacle feels nothing.
    pub distance: f64,
    /// The barrier's stiffness per unit of vertex mass, κ̂ (1/s², > 0): vertex v's barrier is
    /// κ_v b(d) with κ_v = κ̂ m_v (N/m), m_v the mass given with the model (kg).
    pub stiffness: f64,
    /// IPC's friction smoothing velocity ε_v (m/s, > 0): below this tangential speed friction
    /// acts as a stiff spring towards sticking, above it as Coulomb's μ λ.
    pub friction_velocity: f64,
}

/// The contact terms of [`super::BackwardEulerStep`], with the friction lagged at the step's start.
#[derive(Debug)]
pub(crate) struct StepContact<const D: usize> {
    pub(crate) model: ContactModel<D>,
    /// κ_v per vertex (N/m).
    stiffness: Vec<f64>,
    /// The lagged frictional contacts of this step: (vertex, contact).
    friction: Vec<(u32, LaggedFriction<D>)>,
    /// ε_v h (m).
    friction_length: f64,
}

impl<const D: usize> StepContact<D> {
    pub(crate) fn new(model: ContactModel<D>, masses: &[f64], h: f64) -> Self {
        let stiffness = masses.iter().map(|&m| model.stiffness * m).collect();
        let friction_length = model.friction_velocity * h;
        StepContact {
            stiffness,
            friction: Vec::new(),
            friction_length,
            model,
        }
    }

    /// Lag the friction at the step's start `start` (free vertices `free`): every vertex within d̂
    /// of an obstacle with μ > 0 gets that contact's normal force and tangent plane.
    pub(crate) fn lag_friction(&mut self, free: &[u32], start: &[SVector<f64, D>]) {
        self.friction.clear();
        for &v in free {
            let x = &start[v as usize];
            for &(obstacle, mu) in &self.model.obstacles {
                if mu <= 0.0 {
                    continue;
                }
                if let Some(lagged) = contact::lagged_friction(
                    &obstacle,
                    x,
                    self.model.distance,
                    self.stiffness[v as usize],
                    mu,
                ) {
                    self.friction.push((v, lagged));
                }
            }
        }
    }

    /// The smallest distance (m) of any free vertex from any obstacle at `x` (∞ without obstacles).
    pub(crate) fn smallest_distance(&self, free: &[u32], x: &[SVector<f64, D>]) -> f64 {
        let mut smallest = f64::INFINITY;
        for &v in free {
            for (obstacle, _) in &self.model.obstacles {
                smallest = smallest.min(obstacle.distance(&x[v as usize]));
            }
        }
        smallest
    }

    /// The barrier and friction energy at `x` (J; +∞ if a vertex is on or inside an obstacle),
    /// summed in vertex order.
    pub(crate) fn energy(&self, free: &[u32], x: &[SVector<f64, D>]) -> f64 {
        let d_hat = self.model.distance;
        let mut sum = 0.0;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                let d = obstacle.distance(&x[v]);
                if d < d_hat {
                    sum += self.stiffness[v] * contact::barrier(d, d_hat);
                }
            }
        }
        for (v, lagged) in &self.friction {
            sum += lagged.terms(&x[*v as usize], self.friction_length).energy;
        }
        sum
    }

    /// The change of [`StepContact::energy`] from `x` to `x + delta` (J), term by term without
    /// subtracting two rounded energies.
    pub(crate) fn energy_change(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        let d_hat = self.model.distance;
        let mut sum = 0.0;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                let d = obstacle.distance(&x[v]);
                let change = obstacle.distance_change(&x[v], &delta[v]);
                if d < d_hat || d + change < d_hat {
                    sum += self.stiffness[v] * contact::barrier_change(d, change, d_hat);
                }
            }
        }
        for (v, lagged) in &self.friction {
            let v = *v as usize;
            sum += lagged.energy_change(&x[v], &delta[v], self.friction_length);
        }
        sum
    }

    /// Add the contact forces' negative, ∇(energy) · `scale`, into `gradient` per vertex
    /// (`out[v] += scale ∇_v`), and their magnitudes into `magnitude` if given (for the gradient's
    /// rounding bound).
    pub(crate) fn add_gradient(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) {
        let d_hat = self.model.distance;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(terms) = contact::vertex_barrier(
                    obstacle,
                    &x[v],
                    d_hat,
                    self.stiffness[v],
                    Definiteness::Clamped,
                ) {
                    out[v] += terms.gradient * scale;
                }
            }
        }
        for (v, lagged) in &self.friction {
            let v = *v as usize;
            out[v] += lagged.terms(&x[v], self.friction_length).gradient * scale;
        }
    }

    /// Call `add(v, block)` with `scale` times every vertex's contact Hessian block (barrier with
    /// `definiteness`, and friction, which is positive semidefinite).
    pub(crate) fn for_each_hessian_block(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        mut add: impl FnMut(usize, SMatrix<f64, D, D>),
    ) {
        let d_hat = self.model.distance;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(terms) =
                    contact::vertex_barrier(obstacle, &x[v], d_hat, self.stiffness[v], definiteness)
                {
                    add(v, terms.hessian * scale);
                }
            }
        }
        for (v, lagged) in &self.friction {
            let v = *v as usize;
            add(v, lagged.terms(&x[v], self.friction_length).hessian * scale);
        }
    }

    /// The longest share α ≤ 1 of the move `delta` (per vertex) from `x` that keeps every free
    /// vertex off every obstacle: [`TIME_OF_IMPACT_SHARE`] of the first time of impact.
    pub(crate) fn max_step(
        &self,
        free: &[u32],
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        let mut first = f64::INFINITY;
        for &v in free {
            let v = v as usize;
            for (obstacle, _) in &self.model.obstacles {
                if let Some(t) = obstacle.time_of_impact(&x[v], &delta[v]) {
                    first = first.min(t);
                }
            }
        }
        (TIME_OF_IMPACT_SHARE * first).min(1.0)
    }
}
