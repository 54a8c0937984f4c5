//! Anderson-accelerated projective dynamics: it reaches Newton's minimiser, its energy guard refuses
//! Anderson points above the plain PD iterate and keeps Φ from rising, its tolerance bounds the
//! distance to the solution as PD's does, and it beats plain PD per iteration.

use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::{
    AndersonParams, AndersonPd, AndersonReport, NewtonProblem, PdParams, StopReason,
};

use crate::chebyshev::{distance, step, Step, V};

impl Step {
    /// Anderson PD from y with `params`.
    fn solve_anderson(&mut self, params: AndersonParams) -> (Vec<V>, AndersonReport) {
        let mut x = self.y.clone();
        let mut solver = AndersonPd::<3>::new(self.mesh.vertex_count(), params).unwrap();
        let report = solver
            .solve(&mut self.pd, self.mesh.springs(), &self.y, &mut x)
            .unwrap();
        (x, report)
    }
}

/// A step from rest that Anderson solves to the bench's stop.
fn reaches_newton(mesh: SpringMesh<3>, pinned: &[u32]) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, 0.05);
    let params = AndersonParams {
        max_iterations: 3000,
        tolerance: 1e-10,
        ..Default::default()
    };
    let (x, report) = s.solve_anderson(params);
    let error = s.objective_error(&x);
    eprintln!(
        "{} iterations ({} accepted, {} refused), {:?}, objective error {error:e}",
        report.iterations, report.accepted, report.rejected, report.stop
    );
    assert_eq!(report.stop, StopReason::Converged);
    assert!(report.accepted > 0, "no Anderson point was accepted");
    // docs/model.md §9.2's objective error; the bound these tests hold solvers to.
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

#[test]
fn anderson_pd_reaches_newtons_solution_on_cloth_10() {
    reaches_newton(generators::cloth(10, 1e3).unwrap(), &[0, 9]);
}

#[test]
fn anderson_pd_reaches_newtons_solution_on_beam_2() {
    let mesh = generators::beam(2).unwrap();
    let clamped: Vec<u32> = mesh
        .positions()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.x == 0.0)
        .map(|(v, _)| v as u32)
        .collect();
    reaches_newton(mesh, &clamped);
}

#[test]
fn anderson_beats_plain_pd_at_the_same_iterations() {
    let mut s = step(
        generators::cloth(10, 1e3).unwrap(),
        &[0, 9],
        1.0 / 30.0,
        0.05,
    );
    let (x_fast, report) = s.solve_anderson(AndersonParams {
        max_iterations: 100,
        ..Default::default()
    });
    let (x_plain, _) = s.solve_plain(PdParams {
        max_iterations: 100,
        ..PdParams::default()
    });
    let (fast, slow) = (s.objective_error(&x_fast), s.objective_error(&x_plain));
    eprintln!(
        "100 iterations: Anderson {fast:e} ({} accepted, {} refused), plain PD {slow:e}",
        report.accepted, report.rejected
    );
    assert!(
        fast < 0.1 * slow,
        "Anderson {fast:e} is not 10× below plain PD's {slow:e}"
    );
}

/// The tolerance T bounds the distance to the solution per h (m/s) as PD's does
/// (`FixedPointError` on the changes of the accepted points), on the cloth-10 step where the last
/// change alone is a poor measure (tests/chebyshev.rs shows that for PD): within 2 T, the bound
/// PD and Chebyshev PD are held to there.
#[test]
fn the_tolerance_bounds_the_distance_to_the_solution() {
    let h = 1.0 / 30.0;
    let mut s = step(generators::cloth(10, 1e3).unwrap(), &[0, 9], h, 0.05);
    let x_star = s.newton_positions();
    for tolerance in [1e-2, 1e-4, 1e-6] {
        let (x, report) = s.solve_anderson(AndersonParams {
            max_iterations: 8000,
            tolerance,
            ..Default::default()
        });
        assert_eq!(report.stop, StopReason::Converged);
        let d = distance(&x, &x_star) / h;
        eprintln!(
            "T = {tolerance:e} m/s: {} iterations, {d:e} m/s from x*",
            report.iterations
        );
        assert!(d <= 2.0 * tolerance, "Anderson stopped {d:e} m/s away");
    }
}

/// cloth-40 stiff (k = 1e5 N/m) at h = 1/5 s, waved (the case where Chebyshev's unguarded
/// extrapolation gains energy, tests/chebyshev.rs): Anderson's secant model of G is poor there and
/// the guard refuses some of its points. Φ, recorded after every iteration, never rises, and the
/// record agrees with backward Euler's own exact change of Φ over the solve.
#[test]
fn the_energy_guard_refuses_points_above_the_plain_iterate_and_phi_never_rises() {
    let mut s = step(generators::cloth(40, 1e5).unwrap(), &[0, 39], 0.2, 0.1);
    let (x, report) = s.solve_anderson(AndersonParams {
        max_iterations: 60,
        record_objective: true,
        ..Default::default()
    });
    eprintln!(
        "{} accepted, {} refused; Φ from {:e} to {:e}",
        report.accepted,
        report.rejected,
        report.objectives[0],
        report.objectives.last().unwrap()
    );
    assert!(
        report.rejected > 0,
        "the guard never fired: the case does not test it"
    );
    assert!(report.accepted > 0, "no Anderson point was accepted");
    assert_eq!(report.objectives.len(), report.iterations + 1);
    for (k, w) in report.objectives.windows(2).enumerate() {
        assert!(
            w[1] <= w[0],
            "iteration {k}: Φ rose from {} to {}",
            w[0],
            w[1]
        );
    }
    let (y, end) = (s.y.clone(), s.reduced(&x));
    let start = s.reduced(&y);
    let total = s.problem.objective_change(&start, &end);
    let reported = report.objectives.last().unwrap() - report.objectives[0];
    // The record sums 60 exactly computed changes: it agrees to the rounding of that sum.
    assert!(
        total < 0.0 && (reported - total).abs() <= 1e-9 * total.abs(),
        "reported change {reported:e}, measured {total:e}"
    );
}

/// The same input gives the same bits (serial sums in a fixed order; PD's parallel parts are
/// deterministic), also from a solver object that has run another step before.
#[test]
fn the_solve_is_deterministic() {
    let mut s = step(
        generators::cloth(12, 1e3).unwrap(),
        &[0, 11],
        1.0 / 30.0,
        0.05,
    );
    let params = AndersonParams {
        max_iterations: 40,
        window: 3,
        ..Default::default()
    };
    let (a, _) = s.solve_anderson(params);
    let mut solver = AndersonPd::<3>::new(s.mesh.vertex_count(), params).unwrap();
    let springs = s.mesh.springs().to_vec();
    let mut other = s.y.clone();
    for v in other.iter_mut().skip(1) {
        v.y += 0.01;
    }
    solver.solve(&mut s.pd, &springs, &s.y, &mut other).unwrap();
    let mut b = s.y.clone();
    solver.solve(&mut s.pd, &springs, &s.y, &mut b).unwrap();
    assert_eq!(a, b);
}

#[test]
fn invalid_settings_are_refused_with_the_field_named() {
    for (params, field) in [
        (
            AndersonParams {
                max_iterations: 0,
                ..Default::default()
            },
            "max_iterations",
        ),
        (
            AndersonParams {
                window: 0,
                ..Default::default()
            },
            "window",
        ),
        (
            AndersonParams {
                window: hooke_solvers::ANDERSON_MAX_WINDOW + 1,
                ..Default::default()
            },
            "window",
        ),
        (
            AndersonParams {
                tolerance: f64::NAN,
                ..Default::default()
            },
            "tolerance",
        ),
    ] {
        assert_eq!(
            AndersonPd::<3>::new(4, params).unwrap_err().field(),
            format!("AndersonParams::{field}")
        );
    }
}
