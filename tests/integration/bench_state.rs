//! The speed-vs-error state and its reference (docs/scenes.md §8, docs/model.md §9) through the
//! library: the cache returns the state bit for bit and survives a corrupt file; the meter's
//! measures are exact at their ends (y gives objective error and residual 1, x* gives 0); PD's
//! error falls with its iterations.

use hooke_cli::bench::{
    load_setup, run_spec, BenchProblem, ErrorMeter, PrepareOptions, StartState, TimingOptions,
    STATE_STEPS,
};

fn options(cache: Option<&std::path::Path>) -> PrepareOptions {
    PrepareOptions {
        start: StartState::SpeedVsError,
        reference: true,
        cache_dir: cache.map(|p| p.to_path_buf()),
    }
}

#[test]
fn the_cache_returns_the_state_and_reference_bit_for_bit() {
    let setup = load_setup("cloth-10").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut log = Vec::new();
    let fresh = BenchProblem::prepare(&setup, &options(Some(dir.path())), &mut |l| {
        log.push(l.to_string())
    })
    .unwrap();
    assert_eq!(
        log.iter().filter(|l| l.contains("exact step")).count(),
        STATE_STEPS
    );
    let h = setup.scene.time_step();
    assert!((fresh.start.time - STATE_STEPS as f64 * h).abs() < 1e-12);

    let mut log = Vec::new();
    let cached = BenchProblem::prepare(&setup, &options(Some(dir.path())), &mut |l| {
        log.push(l.to_string())
    })
    .unwrap();
    assert!(log.iter().any(|l| l.contains("read from")), "{log:?}");
    assert!(!log.iter().any(|l| l.contains("exact step")), "{log:?}");
    assert_eq!(cached.start, fresh.start);
    assert_eq!(cached.y, fresh.y);
    assert_eq!(cached.x_star(), fresh.x_star());

    // A damaged file is reported and recomputed, not trusted.
    let file = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "bin"))
        .expect("a cache file");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    let mut log = Vec::new();
    let again = BenchProblem::prepare(&setup, &options(Some(dir.path())), &mut |l| {
        log.push(l.to_string())
    })
    .unwrap();
    assert!(
        log.iter().any(|l| l.contains("ignoring cache file")),
        "{log:?}"
    );
    assert_eq!(again.x_star(), fresh.x_star());
    // ... and rewritten: the next run reads it.
    let mut log = Vec::new();
    BenchProblem::prepare(&setup, &options(Some(dir.path())), &mut |l| {
        log.push(l.to_string())
    })
    .unwrap();
    assert!(log.iter().any(|l| l.contains("read from")), "{log:?}");
}

#[test]
fn measures_are_exact_at_y_and_x_star_and_pd_improves_with_iterations() {
    let setup = load_setup("beam-2").unwrap();
    let problem = BenchProblem::prepare(&setup, &options(None), &mut |_| {}).unwrap();
    let mut meter = ErrorMeter::new(&problem);
    let at_y = meter.measure(&problem.y);
    assert_eq!(at_y.objective_error, Some(1.0));
    assert_eq!(at_y.residual, 1.0);
    let x_star = problem.x_star().unwrap().to_vec();
    let at_star = meter.measure(&x_star);
    assert_eq!(at_star.objective_error, Some(0.0));
    assert_eq!(at_star.position_error, Some(0.0));
    assert!(at_star.residual <= 1e-10, "{at_star:?}");

    let spec = "pd:1,10,100".parse().unwrap();
    let timing = TimingOptions {
        repeats: 1,
        ..TimingOptions::default()
    };
    let outcomes = run_spec(&problem, &mut meter, &spec, timing, &mut |_| {}).unwrap();
    let errors: Vec<f64> = outcomes
        .iter()
        .map(|o| o.record.objective_error.unwrap())
        .collect();
    assert!(
        errors.windows(2).all(|w| w[1] < w[0]) && errors[0] < 1.0,
        "PD's objective error must fall with its iterations: {errors:?}"
    );
    // Each record's measures are those of its positions.
    for o in &outcomes {
        let m = meter.measure(&o.positions);
        assert_eq!(m.objective_error, o.record.objective_error);
        assert_eq!(m.position_error, o.record.position_error);
        assert_eq!(Some(m.residual), o.record.residual);
    }
}
