//! The measures of docs/model.md §9.2 for an approximate solution x of one backward Euler step,
//! over the free DOFs:
//!
//! - objective error (Φ(x) − Φ*) / (Φ(x⁰) − Φ*), x⁰ = y, Φ* = Φ(x*): both differences computed by
//!   [`NewtonProblem::objective_change`] term by term, without subtracting two rounded values of Φ
//!   (Φ(x) − Φ* of an accurate solver is far below ε·Φ). 1 means no better than the initial guess
//!   y; it can exceed 1 for a solver that does not start from y (the linearised integrator starts
//!   from x_n);
//! - position error |x − x*| / |x* − x_n| (Euclidean norms over the free DOFs);
//! - residual: the force residual relative to its value at x⁰ = y,
//!   |M(x − y) − h² f(x)| / |M(y − y) − h² f(y)| = ‖∇Φ(x)‖ / ‖∇Φ(y)‖ (Euclidean norms over the free
//!   DOFs), the quantity Newton's tolerance bounds.

use hooke_solvers::{BackwardEulerStep, NewtonProblem};
use nalgebra::Vector3;

use crate::bench::BenchProblem;

/// The three measures of one approximate solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measures {
    /// (Φ(x) − Φ*) / (Φ(y) − Φ*); `None` without a reference.
    pub objective_error: Option<f64>,
    /// |x − x*| / |x* − x_n|; `None` without a reference.
    pub position_error: Option<f64>,
    /// ‖∇Φ(x)‖ / ‖∇Φ(y)‖.
    pub residual: f64,
}

/// Measures approximate solutions of one step against its reference.
#[derive(Debug)]
pub struct ErrorMeter {
    objective: BackwardEulerStep<3>,
    free_vertices: Vec<u32>,
    /// Free unknowns of x* (if any).
    x_star: Option<Vec<f64>>,
    /// Φ(y) − Φ*.
    initial_gap: f64,
    /// |x* − x_n|.
    step_length: f64,
    /// ‖∇Φ(y)‖.
    initial_gradient: f64,
    x: Vec<f64>,
    g: Vec<f64>,
}

impl ErrorMeter {
    /// A meter for `problem`'s step (errors against x* only if the problem has a reference).
    pub fn new(problem: &BenchProblem) -> Self {
        let mesh = problem.scene.mesh();
        let free = problem.free();
        let free_vertices = free.free_vertices().to_vec();
        let mut objective = BackwardEulerStep::new(
            mesh.springs(),
            mesh.masses(),
            free,
            problem.scene.time_step(),
        );
        let mut y = vec![0.0; objective.dim()];
        objective.set_step(&problem.y, &problem.start.positions, &mut y);
        let gather = |full: &[Vector3<f64>]| -> Vec<f64> {
            free_vertices
                .iter()
                .flat_map(|&v| full[v as usize].iter().copied())
                .collect()
        };
        let x_n = gather(&problem.start.positions);
        let x_star = problem.x_star().map(gather);
        let mut g = vec![0.0; y.len()];
        objective.gradient(&y, &mut g);
        let initial_gradient = norm(&g);
        let (initial_gap, step_length) = match &x_star {
            Some(xs) => (objective.objective_change(xs, &y), distance(xs, &x_n)),
            None => (f64::NAN, f64::NAN),
        };
        ErrorMeter {
            x: vec![0.0; y.len()],
            objective,
            free_vertices,
            x_star,
            initial_gap,
            step_length,
            initial_gradient,
            g,
        }
    }

    /// The measures of `positions` (full numbering; pinned entries are not read).
    pub fn measure(&mut self, positions: &[Vector3<f64>]) -> Measures {
        for (f, &v) in self.free_vertices.iter().enumerate() {
            self.x[3 * f..3 * f + 3].copy_from_slice(positions[v as usize].as_slice());
        }
        self.objective.gradient(&self.x, &mut self.g);
        let residual = norm(&self.g) / self.initial_gradient;
        let (objective_error, position_error) = match &self.x_star {
            Some(xs) => (
                Some(self.objective.objective_change(xs, &self.x) / self.initial_gap),
                Some(distance(&self.x, xs) / self.step_length),
            ),
            None => (None, None),
        };
        Measures {
            objective_error,
            position_error,
            residual,
        }
    }

    /// |x* − x_n| over the free DOFs (m).
    pub fn step_length(&self) -> f64 {
        self.step_length
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt()
}
