//! Newton-CG (truncated Newton, PCG on the exact Hessian preconditioned by projective dynamics'
//! factor): it reaches Newton's minimiser, never raises Φ, and converges superlinearly near x*.

use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::Convergence;
use hooke_solvers::{NewtonCg, NewtonCgParams, NewtonProblem, StopReason};
use proptest::prelude::*;

use crate::waved_step;
use waved_step::{clamped, newton_solution, objective_error, step};

fn solve(
    mesh: &SpringMesh<3>,
    pinned: &[u32],
    amplitude: f64,
    params: NewtonCgParams,
) -> (f64, hooke_solvers::NewtonCgReport) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, amplitude);
    let solution = newton_solution(&mut s);
    let mut x = s.start.clone();
    let report = NewtonCg::new(s.problem.dim(), params)
        .unwrap()
        .minimize(&mut s.problem, &mut s.pd, &mut x)
        .unwrap();
    let error = objective_error(&mut s, &x, &solution);
    eprintln!(
        "Newton-CG: {} iterations, {} CG iterations ({} truncated at negative curvature), relative gradients {:?}, objective error {error:e}",
        report.iterations, report.cg_iterations, report.negative_curvature, report.gradients
    );
    (error, report)
}

fn reaches_newton(mesh: &SpringMesh<3>, pinned: &[u32]) {
    let params = NewtonCgParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-11,
        ..Default::default()
    };
    let (error, report) = solve(mesh, pinned, 0.05, params);
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::RoundOff),
        "{:?}",
        report.stop
    );
    // docs/model.md §9.2's objective error; the bound these tests hold solvers to, far above the
    // 1e-11 gradient's.
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

#[test]
fn newton_cg_reaches_newtons_solution_on_cloth_10() {
    reaches_newton(&generators::cloth(10, 1e3).unwrap(), &[0, 9]);
}

#[test]
fn newton_cg_reaches_newtons_solution_on_beam_2() {
    let mesh = generators::beam(2).unwrap();
    reaches_newton(&mesh, &clamped(&mesh));
}

/// On the beam (a stiff solid, convex near its solution) the gradient's ratio from one iteration to
/// the next falls towards 0: superlinear, where a fixed forcing term would give a constant ratio.
#[test]
fn newton_cg_converges_superlinearly_on_a_smooth_case() {
    let mesh = generators::beam(2).unwrap();
    let params = NewtonCgParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-12,
        ..Default::default()
    };
    let (_, report) = solve(&mesh, &clamped(&mesh), 0.05, params);
    let g = &report.gradients;
    let ratios: Vec<f64> = g.windows(2).map(|w| w[1] / w[0]).collect();
    assert!(ratios.len() >= 3, "too few iterations to see a rate: {g:?}");
    let tail = &ratios[ratios.len() - 3..];
    assert!(
        tail[2] < tail[0] && tail[1] < tail[0],
        "the last ratios do not fall: {ratios:?}"
    );
    assert!(
        tail[2] < 0.05,
        "the last ratio {} is not superlinear",
        tail[2]
    );
}

#[test]
fn invalid_settings_are_refused_with_the_field_named() {
    let defaults = NewtonCgParams::default();
    for (params, field) in [
        (
            NewtonCgParams {
                max_iterations: 0,
                ..defaults
            },
            "max_iterations",
        ),
        (
            NewtonCgParams {
                max_cg_iterations: usize::MAX,
                ..defaults
            },
            "max_cg_iterations",
        ),
        (
            NewtonCgParams {
                convergence: Convergence::RelativeGradient,
                tolerance: f64::INFINITY,
                ..defaults
            },
            "tolerance",
        ),
        (
            NewtonCgParams {
                forcing_max: 1.0,
                ..defaults
            },
            "forcing_max",
        ),
        (
            NewtonCgParams {
                forcing_alpha: 1.0,
                ..defaults
            },
            "forcing_alpha",
        ),
        (
            NewtonCgParams {
                armijo: 0.0,
                ..defaults
            },
            "armijo",
        ),
    ] {
        assert_eq!(
            NewtonCg::new(3, params).unwrap_err().field(),
            format!("NewtonCgParams::{field}")
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Φ never rises: the k-th iterate (a run limited to k iterations; the solver is deterministic)
    /// is not above the (k−1)-th by backward Euler's exact change of Φ, on waved cloth with
    /// compressed springs (negative curvature) and stiff springs at large steps.
    #[test]
    fn newton_cg_never_raises_the_objective(
        n in 4usize..9,
        stiffness in prop::sample::select(vec![1e2, 1e3, 1e5]),
        h in prop::sample::select(vec![1.0 / 120.0, 1.0 / 30.0, 1.0 / 5.0]),
        amplitude in 0.0f64..0.2,
    ) {
        let mesh = generators::cloth(n, stiffness).unwrap();
        let mut s = step(&mesh, &[0, n as u32 - 1], h, amplitude);
        let mut previous = s.start.clone();
        for k in 1..=8 {
            let params = NewtonCgParams { max_iterations: k, tolerance: 0.0, ..Default::default() };
            let mut x = s.start.clone();
            let result = NewtonCg::new(s.problem.dim(), params)
                .unwrap()
                .minimize(&mut s.problem, &mut s.pd, &mut x);
            let change = s.problem.objective_change(&previous, &x);
            prop_assert!(change <= 0.0, "iteration {}: Φ rose by {:e}", k, change);
            match result {
                Ok(report) if report.iterations == k => previous = x,
                _ => break, // converged, stagnated or failed: x is the last accepted iterate
            }
        }
    }
}
