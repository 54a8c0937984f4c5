//! `hooke bench --time-error` through the library on a small cloth: a row per integrator, the
//! backward Euler minimisers (Newton, L-BFGS, Newton-CG) on the same trajectory, and the
//! reference differences of a method that is not backward Euler.

use hooke::sim::{scenes, Integrator};
use hooke_cli::bench::{format_time_error, time_error, TimeErrorOptions};

#[test]
fn every_integrator_gets_a_row_and_the_backward_euler_minimisers_agree() {
    let mut setup = scenes::cloth(5, false).unwrap();
    // Tight tolerances: the three minimisers then land on the same states (see below).
    setup.settings.newton.tolerance = 1e-11;
    setup.settings.lbfgs.tolerance = 1e-11;
    setup.settings.lbfgs.max_iterations = 2000;
    setup.settings.newton_cg.tolerance = 1e-11;
    let options = TimeErrorOptions {
        duration: 0.2,
        divisor: 8,
        ..TimeErrorOptions::default()
    };
    let report = time_error(&setup, &options, &mut |_| {}).unwrap();
    assert_eq!(report.rows.len(), Integrator::ALL.len());
    let row = |name: &str| {
        report
            .rows
            .iter()
            .find(|r| r.integrator == name)
            .unwrap_or_else(|| panic!("no row for {name}"))
    };
    let newton = row("newton")
        .error_vs_backward_euler
        .expect("newton finishes");
    // Backward Euler at h against h/8 over 6 steps: a first-order method differs by O(h) of the
    // motion, neither nothing nor everything.
    assert!(newton > 1e-4 && newton < 1.0, "newton: {newton:e}");
    for name in ["lbfgs", "newton-cg"] {
        let e = row(name).error_vs_backward_euler.expect("finishes");
        // Both minimise the same Φ to a relative gradient of 1e-11: their states agree with
        // Newton's to ~1e-8 of the motion, so the errors agree to that over `newton`.
        assert!(
            (e - newton).abs() <= 1e-6 * newton.max(1e-3),
            "{name}: {e:e} against newton's {newton:e}"
        );
    }
    // Every implicit integrator finishes cloth-5 and gets a finite error against both references
    // (symplectic Euler's reference runs: cloth-5 needs few substeps).
    for name in ["linearized", "pd", "pd-chebyshev"] {
        let r = row(name);
        assert_eq!(r.outcome, "ok", "{name}");
        assert!(
            r.error_vs_backward_euler.is_some_and(f64::is_finite),
            "{r:?}"
        );
        assert!(r.error_vs_symplectic.is_some_and(f64::is_finite), "{r:?}");
    }
    // The symplectic Euler row takes the fewest substeps under its safe bound, which is the
    // reference's step: the same computation, so no difference at all.
    assert_eq!(row("symplectic-euler").error_vs_symplectic, Some(0.0));
    let table = format_time_error(&report);
    for r in &report.rows {
        assert!(table.contains(&r.integrator), "{table}");
    }
}

#[test]
fn a_bad_duration_is_an_error_not_a_panic() {
    let setup = scenes::cloth(4, false).unwrap();
    for duration in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let options = TimeErrorOptions {
            duration,
            ..TimeErrorOptions::default()
        };
        assert!(
            time_error(&setup, &options, &mut |_| {}).is_err(),
            "{duration}"
        );
    }
}
