//! A backward Euler step from rest whose inertial target carries a transverse wave, the shared
//! set-up of the quasi-Newton and inexact Newton tests.

use hooke_assembly::FreeDofs;
use hooke_mesh::SpringMesh;
use hooke_solvers::Convergence;
use hooke_solvers::{
    BackwardEulerStep, Newton, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics,
    StopReason,
};
use nalgebra::Vector3;

use crate::common::inertial_target;

type V = Vector3<f64>;

/// A backward Euler step on `mesh` with `pinned` held, from rest, whose inertial target is gravity's
/// h² g plus a transverse wave of `amplitude` (m): a deformed step with compressed springs, not the
/// trivial one from rest.
pub struct Step {
    pub problem: BackwardEulerStep<3>,
    pub pd: ProjectiveDynamics<3>,
    /// The start x⁰ = y on the free DOFs.
    pub start: Vec<f64>,
}

pub fn step(mesh: &SpringMesh<3>, pinned: &[u32], h: f64, amplitude: f64) -> Step {
    let x_n = mesh.positions().to_vec();
    let g = V::new(0.0, -9.81, 0.0);
    let y = inertial_target(&x_n, pinned, |_, p| {
        g * (h * h) + V::new(0.0, amplitude * (7.0 * p.x + 3.0 * p.z).sin(), 0.0)
    });
    let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
    let pd =
        ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, PdParams::default())
            .unwrap();
    let mut problem = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let mut start = vec![0.0; problem.dim()];
    problem.set_step(&y, &x_n, &mut start);
    Step { problem, pd, start }
}

/// Newton's minimiser x* to a relative gradient of 1e-12 (or its round-off floor).
pub fn newton_solution(s: &mut Step) -> Vec<f64> {
    let mut x = s.start.clone();
    let params = NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-12,
        ..Default::default()
    };
    let report = Newton::new(s.problem.pattern(), params)
        .unwrap()
        .minimize(&mut s.problem, &mut x)
        .unwrap();
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::RoundOff),
        "reference Newton: {:?}",
        report.stop
    );
    x
}

/// (Φ(x) − Φ*) / (Φ(x⁰) − Φ*), each difference computed without cancellation.
pub fn objective_error(s: &mut Step, x: &[f64], solution: &[f64]) -> f64 {
    let start = s.start.clone();
    s.problem.objective_change(solution, x) / s.problem.objective_change(solution, &start)
}

/// beam-R's clamped vertices (x = 0), as docs/scenes.md §3 pins them.
pub fn clamped(mesh: &SpringMesh<3>) -> Vec<u32> {
    mesh.positions()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.x == 0.0)
        .map(|(v, _)| v as u32)
        .collect()
}
