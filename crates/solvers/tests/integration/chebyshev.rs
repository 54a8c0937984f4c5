//! Chebyshev-accelerated projective dynamics: it reaches Newton's minimiser, its restart keeps Φ from
//! rising where the unguarded extrapolation gains energy, and it beats plain PD per iteration.

use hooke_assembly::FreeDofs;
use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::{
    BackwardEulerStep, ChebyshevParams, ChebyshevPd, Newton, NewtonParams, NewtonProblem, PdParams,
    ProjectiveDynamics, StopReason,
};
use nalgebra::Vector3;
use proptest::prelude::*;

use crate::common;
use common::inertial_target;

pub(crate) type V = Vector3<f64>;

pub(crate) struct Step {
    pub(crate) mesh: SpringMesh<3>,
    pub(crate) pd: ProjectiveDynamics<3>,
    pub(crate) problem: BackwardEulerStep<3>,
    pub(crate) x_n: Vec<V>,
    pub(crate) y: Vec<V>,
}

/// (Shared with the Anderson tests.) A backward Euler step from rest whose inertial target is gravity's h² g plus a transverse wave
/// of `amplitude` (m).
pub(crate) fn step(mesh: SpringMesh<3>, pinned: &[u32], h: f64, amplitude: f64) -> Step {
    let x_n = mesh.positions().to_vec();
    let g = V::new(0.0, -9.81, 0.0);
    let y = inertial_target(&x_n, pinned, |_, p| {
        g * (h * h) + V::new(0.0, amplitude * (7.0 * p.x + 3.0 * p.z).sin(), 0.0)
    });
    let free = FreeDofs::new(mesh.vertex_count(), pinned).unwrap();
    let pd =
        ProjectiveDynamics::<3>::new(mesh.springs(), mesh.masses(), &free, h, PdParams::default())
            .unwrap();
    let problem = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    Step {
        mesh,
        pd,
        problem,
        x_n,
        y,
    }
}

impl Step {
    /// Reduced unknowns of per-vertex positions.
    pub(crate) fn reduced(&mut self, x: &[V]) -> Vec<f64> {
        let mut xf = vec![0.0; self.problem.dim()];
        self.problem.set_step(&self.y, x, &mut xf);
        // set_step writes y's free part; overwrite it with x's.
        let free: Vec<u32> = self.problem.free().free_vertices().to_vec();
        for (f, v) in free.iter().enumerate() {
            xf[3 * f..3 * f + 3].copy_from_slice(x[*v as usize].as_slice());
        }
        xf
    }

    /// (Φ(x) − Φ*) / (Φ(y) − Φ*) against Newton's x* (to a relative gradient of 1e-12).
    pub(crate) fn objective_error(&mut self, x: &[V]) -> f64 {
        let mut solution = vec![0.0; self.problem.dim()];
        let (y, x_n) = (self.y.clone(), self.x_n.clone());
        self.problem.set_step(&y, &x_n, &mut solution);
        let start = solution.clone();
        let params = NewtonParams {
            tolerance: 1e-12,
            ..Default::default()
        };
        let report = Newton::new(self.problem.pattern(), params)
            .unwrap()
            .minimize(&mut self.problem, &mut solution)
            .unwrap();
        assert!(matches!(
            report.stop,
            StopReason::Converged | StopReason::Stagnated
        ));
        let xf = self.reduced(x);
        self.problem.objective_change(&solution, &xf)
            / self.problem.objective_change(&solution, &start)
    }

    /// Newton's minimiser x* (to a relative gradient of 1e-12), per vertex.
    pub(crate) fn newton_positions(&mut self) -> Vec<V> {
        let mut solution = vec![0.0; self.problem.dim()];
        let (y, x_n) = (self.y.clone(), self.x_n.clone());
        self.problem.set_step(&y, &x_n, &mut solution);
        let params = NewtonParams {
            tolerance: 1e-12,
            ..Default::default()
        };
        let report = Newton::new(self.problem.pattern(), params)
            .unwrap()
            .minimize(&mut self.problem, &mut solution)
            .unwrap();
        assert!(report.stop.is_at_resolution(), "{:?}", report.stop);
        self.problem.positions(&solution).to_vec()
    }

    /// Plain PD from y with `params`.
    pub(crate) fn solve_plain(&mut self, params: PdParams) -> (Vec<V>, hooke_solvers::PdReport) {
        let mut x = self.y.clone();
        self.pd.params = params;
        let report = self.pd.solve(self.mesh.springs(), &self.y, &mut x).unwrap();
        (x, report)
    }

    fn solve(&mut self, params: ChebyshevParams) -> (Vec<V>, hooke_solvers::ChebyshevReport) {
        let mut x = self.y.clone();
        let mut solver = ChebyshevPd::<3>::new(self.mesh.vertex_count(), params).unwrap();
        let report = solver
            .solve(&mut self.pd, self.mesh.springs(), &self.y, &mut x)
            .unwrap();
        (x, report)
    }
}

fn reaches_newton(mesh: SpringMesh<3>, pinned: &[u32]) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, 0.05);
    let (y, springs) = (s.y.clone(), s.mesh.springs().to_vec());
    let rate = s.pd.estimate_rate(&springs, &y, &y, 40).unwrap();
    let params = ChebyshevParams {
        max_iterations: 3000,
        rate,
        tolerance: 1e-10,
        ..Default::default()
    };
    let (x, report) = s.solve(params);
    let error = s.objective_error(&x);
    eprintln!(
        "ρ = {rate}: {} iterations, {} restarts, {:?}, objective error {error:e}",
        report.iterations, report.restarts, report.stop
    );
    // Converged by the position change, or stopped at PD's rounding floor (even the plain iterate
    // raised Φ), which must then be within the bound below.
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::Stagnated),
        "{:?}",
        report.stop
    );
    // docs/model.md §9.2's objective error; the bound these tests hold solvers to.
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

#[test]
fn chebyshev_pd_reaches_newtons_solution_on_cloth_10() {
    reaches_newton(generators::cloth(10, 1e3).unwrap(), &[0, 9]);
}

#[test]
fn chebyshev_pd_reaches_newtons_solution_on_beam_2() {
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
fn chebyshev_beats_plain_pd_at_the_same_iterations() {
    let mut s = step(
        generators::cloth(10, 1e3).unwrap(),
        &[0, 9],
        1.0 / 30.0,
        0.05,
    );
    let (y, springs) = (s.y.clone(), s.mesh.springs().to_vec());
    let rate = s.pd.estimate_rate(&springs, &y, &y, 40).unwrap();
    let accelerated = ChebyshevParams {
        max_iterations: 100,
        rate,
        ..Default::default()
    };
    let plain = ChebyshevParams {
        delay: usize::MAX,
        ..accelerated
    };
    let (x_fast, _) = s.solve(accelerated);
    let (x_plain, _) = s.solve(plain);
    let (fast, slow) = (s.objective_error(&x_fast), s.objective_error(&x_plain));
    eprintln!("100 iterations: Chebyshev {fast:e}, plain PD {slow:e}");
    assert!(
        fast < 0.1 * slow,
        "Chebyshev {fast:e} is not 10× below plain PD's {slow:e}"
    );
}

/// Largest |x − x*| over the coordinates (m), the measure PD's tolerance is stated in.
pub(crate) fn distance(x: &[V], x_star: &[V]) -> f64 {
    x.iter()
        .zip(x_star)
        .map(|(a, b)| (a - b).amax())
        .fold(0.0, f64::max)
}

/// PD's and Chebyshev PD's tolerance T bounds the distance to the solution (per h, m/s), as
/// Newton's step-size tolerance does, and not only the last change: on cloth-10 (ρ ≈ 0.9986),
/// stopping when the last change is below T h leaves a distance several times T h, which
/// this test shows first (so that it tells the two rules apart: 59 T after 8 iterations). The
/// estimate ρ/(1 − ρ)·c is exact once one mode dominates; before that the ratio of changes still
/// rises towards the slowest mode's rate and the estimate runs low (1.25 T and 1.28 T measured
/// here), so the bound is 2 T.
#[test]
fn the_tolerance_bounds_the_distance_to_the_solution() {
    let h = 1.0 / 30.0;
    let mut s = step(generators::cloth(10, 1e3).unwrap(), &[0, 9], h, 0.05);
    let x_star = s.newton_positions();
    // PD's rate on this step is about 0.9986 (from the changes of a long run): the distance left
    // is about 700 times the last change.
    let tolerance = 1e-2; // m/s
                          // The old rule: the first iteration whose change is at most T h.
    let (_, long) = s.solve_plain(PdParams {
        max_iterations: 8000,
        ..PdParams::default()
    });
    let first_small = 1 + long
        .changes
        .iter()
        .position(|&c| c <= tolerance * h)
        .expect("PD reaches a change of T h within 8000 iterations");
    let (x_old, _) = s.solve_plain(PdParams {
        max_iterations: first_small,
        ..PdParams::default()
    });
    let old = distance(&x_old, &x_star) / h;
    assert!(
        old > 2.0 * tolerance,
        "the last change is not a poor measure here ({old:e} m/s): the case tells nothing"
    );
    let (x, report) = s.solve_plain(PdParams {
        max_iterations: 8000,
        tolerance,
        ..PdParams::default()
    });
    assert_eq!(report.stop, StopReason::Converged);
    let plain = distance(&x, &x_star) / h;
    eprintln!(
        "T = {tolerance:e} m/s: last-change rule at {first_small} iterations leaves {old:e} m/s, \
         the estimate stops at {} iterations with {plain:e} m/s",
        report.iterations
    );
    assert!(plain <= 2.0 * tolerance, "PD stopped {plain:e} m/s away");

    let (y, springs) = (s.y.clone(), s.mesh.springs().to_vec());
    let rate = s.pd.estimate_rate(&springs, &y, &y, 40).unwrap();
    let (x, report) = s.solve(ChebyshevParams {
        max_iterations: 8000,
        rate,
        tolerance,
        ..Default::default()
    });
    assert_eq!(report.stop, StopReason::Converged);
    let accelerated = distance(&x, &x_star) / h;
    eprintln!(
        "Chebyshev: {} iterations, {accelerated:e} m/s",
        report.iterations
    );
    assert!(
        accelerated <= 2.0 * tolerance,
        "Chebyshev PD stopped {accelerated:e} m/s away"
    );
}

/// cloth-40 stiff (k = 1e5 N/m) at h = 1/5 s, waved: the unguarded extrapolation raises Φ at some
/// iteration; with the restart Φ never rises.
#[test]
fn the_restart_keeps_phi_from_rising_where_the_extrapolation_gains_energy() {
    let mut s = step(generators::cloth(40, 1e5).unwrap(), &[0, 39], 0.2, 0.1);
    let params = ChebyshevParams {
        max_iterations: 60,
        rate: 0.999,
        delay: 1,
        ..Default::default()
    };
    let (_, unguarded) = s.solve(ChebyshevParams {
        restart: false,
        ..params
    });
    let rises = unguarded
        .objectives
        .windows(2)
        .filter(|w| w[1] > w[0])
        .count();
    assert!(
        rises > 0,
        "the unguarded method never raised Φ: the case does not test the restart"
    );
    let (_, guarded) = s.solve(params);
    assert!(guarded.restarts > 0);
    for (k, w) in guarded.objectives.windows(2).enumerate() {
        assert!(
            w[1] <= w[0],
            "iteration {k}: Φ rose from {} to {}",
            w[0],
            w[1]
        );
    }
}

/// The guard checks Φ every k iterations: with ρ set above plain PD's rate the extrapolation
/// overshoots, stretches of k iterations raise Φ (5 of them are rolled back to the last checked
/// point here, k = 6), and the solve still reaches Newton's minimiser, with Φ never rising from
/// one check to the next.
#[test]
fn a_rolled_back_stretch_still_reaches_newtons_solution() {
    let mut s = step(
        generators::cloth(10, 1e3).unwrap(),
        &[0, 9],
        1.0 / 30.0,
        0.05,
    );
    // Above PD's rate on this step (about 0.9986): the extrapolation overshoots.
    let rate = 0.99995;
    let params = ChebyshevParams {
        max_iterations: 20000,
        rate,
        delay: 1,
        check_interval: 6,
        tolerance: 1e-10,
        ..Default::default()
    };
    let (x, report) = s.solve(params);
    let error = s.objective_error(&x);
    eprintln!(
        "ρ = {rate}: {} iterations, {} restarts, {} rollbacks, {:?}, objective error {error:e}",
        report.iterations, report.restarts, report.rollbacks, report.stop
    );
    assert!(
        report.rollbacks > 0,
        "no stretch was rolled back: the case does not test the rollback"
    );
    for (k, w) in report.objectives.windows(2).enumerate() {
        assert!(w[1] <= w[0], "check {k}: Φ rose from {} to {}", w[0], w[1]);
    }
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::Stagnated),
        "{:?}",
        report.stop
    );
    // docs/model.md §9.2's objective error; the bound these tests hold solvers to.
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// With the restart, Φ never rises, whatever the rate, delay and under-relaxation.
    #[test]
    fn phi_never_rises_with_the_restart(
        n in 4usize..10,
        stiffness in prop::sample::select(vec![1e2, 1e3, 1e5]),
        h in prop::sample::select(vec![1.0 / 120.0, 1.0 / 30.0, 1.0 / 5.0]),
        amplitude in 0.0f64..0.2,
        rate in 0.5f64..0.9999,
        delay in 0usize..5,
        under_relaxation in 0.5f64..=1.0,
        check_interval in 1usize..8,
    ) {
        let mut s = step(generators::cloth(n, stiffness).unwrap(), &[0, n as u32 - 1], h, amplitude);
        let params = ChebyshevParams {
            max_iterations: 40, rate, delay, under_relaxation, check_interval, ..Default::default()
        };
        let (x, report) = s.solve(params);
        prop_assert!(x.iter().all(|p| p.iter().all(|c| c.is_finite())));
        for (k, w) in report.objectives.windows(2).enumerate() {
            prop_assert!(w[1] <= w[0], "iteration {}: Φ rose from {} to {}", k, w[0], w[1]);
        }
        // Independently, by backward Euler's own exact change of Φ: the end is not above the start,
        // and the report's accumulated change agrees with it to the rounding of the sum of 40
        // changes (1e-9 of the total, with a floor at the smallest normal number).
        let (y, end) = (s.y.clone(), s.reduced(&x));
        let start = s.reduced(&y);
        let total = s.problem.objective_change(&start, &end);
        prop_assert!(total <= 0.0, "Φ rose by {:e} over the solve", total);
        let reported = report.objectives.last().unwrap() - report.objectives[0];
        prop_assert!(
            (reported - total).abs() <= 1e-9 * total.abs().max(f64::MIN_POSITIVE),
            "reported change {:e}, measured {:e}", reported, total
        );
    }
}

#[test]
fn invalid_settings_are_refused_with_the_field_named() {
    for (params, field) in [
        (
            ChebyshevParams {
                max_iterations: 0,
                ..Default::default()
            },
            "max_iterations",
        ),
        (
            ChebyshevParams {
                rate: 1.0,
                ..Default::default()
            },
            "rate",
        ),
        (
            ChebyshevParams {
                rate: f64::NAN,
                ..Default::default()
            },
            "rate",
        ),
        (
            ChebyshevParams {
                under_relaxation: 0.0,
                ..Default::default()
            },
            "under_relaxation",
        ),
        (
            ChebyshevParams {
                tolerance: -1.0,
                ..Default::default()
            },
            "tolerance",
        ),
        (
            ChebyshevParams {
                check_interval: 0,
                ..Default::default()
            },
            "check_interval",
        ),
    ] {
        assert_eq!(
            ChebyshevPd::<3>::new(4, params).unwrap_err().field(),
            format!("ChebyshevParams::{field}")
        );
    }
}
