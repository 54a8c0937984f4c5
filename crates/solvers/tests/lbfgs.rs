//! L-BFGS with projective dynamics' matrix as its initial Hessian, on backward Euler steps: it must
//! reach Newton's minimiser and never raise Φ.

use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::Convergence;
use hooke_solvers::{Lbfgs, LbfgsParams, NewtonProblem, StopReason};
use proptest::prelude::*;

mod common;
mod waved_step;
use waved_step::{clamped, newton_solution, objective_error, step};

fn reaches_newton(mesh: &SpringMesh<3>, pinned: &[u32], amplitude: f64) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, amplitude);
    let solution = newton_solution(&mut s);
    let params = LbfgsParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-11,
        max_iterations: 2000,
        ..Default::default()
    };
    let mut lbfgs = Lbfgs::new(s.problem.dim(), params).unwrap();
    let mut x = s.start.clone();
    let report = lbfgs.minimize(&mut s.problem, &mut s.pd, &mut x).unwrap();
    let error = objective_error(&mut s, &x, &solution);
    eprintln!(
        "L-BFGS: {} iterations, relative gradient {:e}, objective error {error:e}, {} pairs skipped, {} restarts, {} trials",
        report.iterations,
        report.gradient(),
        report.skipped_pairs,
        report.restarts,
        report.line_search_trials
    );
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::RoundOff),
        "{:?} after {} iterations",
        report.stop,
        report.iterations
    );
    // docs/model.md §9.2's objective error; both solvers stop near round-off, so 1e-10 (the bound
    // these tests hold solvers to) has orders of magnitude of margin over the 1e-11 gradient.
    assert!(
        error.abs() <= 1e-10,
        "objective error {error:e} against Newton's x*"
    );
}

#[test]
fn lbfgs_reaches_newtons_solution_on_cloth_10() {
    reaches_newton(&generators::cloth(10, 1e3).unwrap(), &[0, 9], 0.05);
}

#[test]
fn lbfgs_reaches_newtons_solution_on_beam_2() {
    let mesh = generators::beam(2).unwrap();
    reaches_newton(&mesh, &clamped(&mesh), 0.05);
}

#[test]
fn invalid_settings_are_refused_with_the_field_named() {
    let cases = [
        LbfgsParams {
            max_iterations: 0,
            ..Default::default()
        },
        LbfgsParams {
            convergence: Convergence::RelativeGradient,
            tolerance: f64::NAN,
            ..Default::default()
        },
        LbfgsParams {
            history: 0,
            ..Default::default()
        },
        LbfgsParams {
            armijo: 1.0,
            ..Default::default()
        },
        LbfgsParams {
            max_iterations: usize::MAX,
            ..Default::default()
        },
    ];
    let fields = [
        "max_iterations",
        "tolerance",
        "history",
        "armijo",
        "max_iterations",
    ];
    for (params, field) in cases.iter().zip(fields) {
        let error = Lbfgs::new(3, *params).unwrap_err();
        assert_eq!(error.field(), format!("LbfgsParams::{field}"), "{params:?}");
        assert!(error.to_string().contains(field));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Φ never increases along L-BFGS: the k-th iterate is the result of a run limited to k
    /// iterations (the solver is deterministic), and its Φ is compared with the (k−1)-th's by the
    /// problem's own exact change and by plain differences of Φ.
    #[test]
    fn lbfgs_never_raises_the_objective(
        n in 4usize..9,
        stiffness in prop::sample::select(vec![1e2, 1e3, 1e5]),
        h in prop::sample::select(vec![1.0 / 120.0, 1.0 / 30.0, 1.0 / 5.0]),
        amplitude in 0.0f64..0.2,
        history in 1usize..8,
    ) {
        let mesh = generators::cloth(n, stiffness).unwrap();
        let mut s = step(&mesh, &[0, n as u32 - 1], h, amplitude);
        let mut previous = s.start.clone();
        for k in 1..=12 {
            let params = LbfgsParams { max_iterations: k, tolerance: 0.0, history, ..Default::default() };
            let mut x = s.start.clone();
            let report = Lbfgs::new(s.problem.dim(), params)
                .unwrap()
                .minimize(&mut s.problem, &mut s.pd, &mut x);
            let Ok(report) = report else {
                // A failed search must not have moved x above the start either.
                prop_assert!(s.problem.objective_change(&s.start.clone(), &x) <= 0.0);
                break;
            };
            let change = s.problem.objective_change(&previous, &x);
            prop_assert!(change <= 0.0, "iteration {k}: Φ rose by {change:e}");
            // The report's sum of accepted changes is the change from the start.
            let total = s.problem.objective_change(&s.start.clone(), &x);
            prop_assert!(
                (report.objective_change - total).abs() <= 1e-9 * total.abs().max(f64::MIN_POSITIVE),
                "reported {:e}, measured {:e}", report.objective_change, total
            );
            if report.iterations < k {
                break; // converged or stagnated
            }
            previous = x;
        }
    }
}
