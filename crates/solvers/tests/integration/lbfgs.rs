//! L-BFGS with projective dynamics' matrix as its initial Hessian, on backward Euler steps: it must
//! reach Newton's minimiser and never raise Φ.

use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::Convergence;
use hooke_solvers::{Lbfgs, LbfgsParams, NewtonProblem, StopReason};
use proptest::prelude::*;

use crate::waved_step;
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

/// One free point x ∈ ℝ² on a spring of stiffness k and rest length 1 to the origin, with the
/// inertia ½ m |x − y|²: Φ is not convex where the spring is compressed (|x| < 1), so a curvature
/// pair measured there can have sᵀt ≤ 0. Records every point its gradient is taken at.
struct CompressedSpring {
    k: f64,
    m: f64,
    y: [f64; 2],
    visited: Vec<[f64; 2]>,
}

impl CompressedSpring {
    fn gradient_at(&self, x: &[f64]) -> [f64; 2] {
        let r = x[0].hypot(x[1]);
        let pull = self.k * (r - 1.0) / r;
        [
            self.m * (x[0] - self.y[0]) + pull * x[0],
            self.m * (x[1] - self.y[1]) + pull * x[1],
        ]
    }
}

impl NewtonProblem for CompressedSpring {
    fn dim(&self) -> usize {
        2
    }
    fn objective(&mut self, x: &[f64]) -> f64 {
        let r = x[0].hypot(x[1]);
        let inertia = (x[0] - self.y[0]).powi(2) + (x[1] - self.y[1]).powi(2);
        0.5 * self.m * inertia + 0.5 * self.k * (r - 1.0).powi(2)
    }
    fn gradient(&mut self, x: &[f64], g: &mut [f64]) {
        self.visited.push([x[0], x[1]]);
        g.copy_from_slice(&self.gradient_at(x));
    }
    fn pattern(&self) -> faer::sparse::SymbolicSparseColMatRef<'_, usize> {
        unreachable!("L-BFGS never asks for the Hessian")
    }
    fn hessian(&mut self, _x: &[f64]) -> faer::sparse::SparseColMatRef<'_, usize, f64> {
        unreachable!("L-BFGS never asks for the Hessian")
    }
    fn shift_diagonal(&self) -> &[f64] {
        unreachable!("L-BFGS never asks for a shift")
    }
}

/// L-BFGS with one pair and H₀ = I, written out plainly: the points its gradient is taken at.
/// A pair is kept only if sᵀt > ε |s| |t|; a rejected pair leaves the kept one in use.
fn reference_lbfgs_history_1(
    problem: &mut CompressedSpring,
    start: [f64; 2],
    params: LbfgsParams,
) -> Vec<[f64; 2]> {
    let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
    let mut x = start;
    let mut g = problem.gradient_at(&x);
    let mut visited = vec![x];
    let mut pair: Option<([f64; 2], [f64; 2], f64)> = None;
    for _ in 0..params.max_iterations {
        let accepted = loop {
            let mut d = [-g[0], -g[1]];
            if let Some((s, t, rho)) = pair {
                let a = rho * dot(s, g);
                let q = [g[0] - a * t[0], g[1] - a * t[1]];
                let b = rho * dot(t, q);
                d = [-(q[0] + (a - b) * s[0]), -(q[1] + (a - b) * s[1])];
            }
            let slope = dot(g, d);
            let mut alpha = 1.0;
            let mut found = None;
            if slope < 0.0 {
                for _ in 0..=params.max_halvings {
                    let trial = [x[0] + alpha * d[0], x[1] + alpha * d[1]];
                    let change = problem.objective(&trial) - problem.objective(&x);
                    if change <= params.armijo * alpha * slope {
                        found = Some([alpha * d[0], alpha * d[1]]);
                        break;
                    }
                    alpha *= 0.5;
                }
            }
            if found.is_some() || pair.is_none() {
                break found;
            }
            pair = None; // the retry along −H₀ g
        };
        let Some(s) = accepted else { break };
        x = [x[0] + s[0], x[1] + s[1]];
        let g_new = problem.gradient_at(&x);
        visited.push(x);
        let t = [g_new[0] - g[0], g_new[1] - g[1]];
        g = g_new;
        let curvature = dot(s, t);
        if curvature > f64::EPSILON * dot(s, s).sqrt() * dot(t, t).sqrt() {
            pair = Some((s, t, 1.0 / curvature));
        }
    }
    visited
}

/// A curvature pair that fails its test must not displace the stored one: with a history of one
/// pair, on a compressed spring whose Φ is not convex, L-BFGS takes exactly the steps of the plain
/// algorithm above (the same iterates to round-off of the two-loop's arithmetic), and skips pairs.
#[test]
fn a_rejected_pair_leaves_the_stored_pair_in_use() {
    let params = LbfgsParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-8,
        max_iterations: 40,
        history: 1,
        ..Default::default()
    };
    let make = || CompressedSpring {
        k: 5.0,
        m: 1.0,
        y: [-0.5, 0.2],
        visited: Vec::new(),
    };
    let start = [0.3, -0.2];
    let mut problem = make();
    let mut x = start.to_vec();
    let mut lbfgs = Lbfgs::new(2, params).unwrap();
    let report = lbfgs
        .minimize(&mut problem, &mut hooke_solvers::Identity, &mut x)
        .unwrap();
    let expected = reference_lbfgs_history_1(&mut make(), start, params);
    assert!(
        report.skipped_pairs >= 1,
        "the case must reject a pair: {report:?}"
    );
    // The first rejection must be followed by further steps, or the stored pair is never used.
    assert!(
        problem.visited.len() >= 3 + report.skipped_pairs,
        "{report:?}"
    );
    let compared = problem.visited.len().min(expected.len());
    assert!(
        compared >= 4,
        "{} and {} iterates",
        problem.visited.len(),
        expected.len()
    );
    for (k, (got, want)) in problem
        .visited
        .iter()
        .zip(&expected)
        .take(compared)
        .enumerate()
    {
        // Both follow the same arithmetic up to the order of a few products: 1e-12 of the
        // problem's length scale (the spring's rest length, 1 m) is far below any step here.
        let gap = (got[0] - want[0]).hypot(got[1] - want[1]);
        assert!(gap <= 1e-12, "iterate {k}: {got:?} against {want:?}");
    }
}
