//! `hooke bench --sweep` on small sizes (timing is not asserted): one record per size and solver
//! setting, errors null unless asked for, the peak memory reported, and the files written.

use std::process::Command;

use hooke_cli::bench::{sweep, SolverSpec, StartState, SweepOptions, TimingOptions};

fn specs() -> Vec<SolverSpec> {
    ["pd:2", "newton-tol:1e-6", "linearized-cg"]
        .iter()
        .map(|s| s.parse().unwrap())
        .collect()
}

fn options(errors: bool) -> SweepOptions {
    SweepOptions {
        sizes: vec![10, 20],
        errors,
        start: StartState::Rest,
        timing: TimingOptions {
            repeats: 1,
            ..TimingOptions::default()
        },
        cache_dir: None,
    }
}

#[test]
fn sweep_gives_one_record_per_size_and_setting_with_errors_only_when_asked() {
    let rows = sweep(&specs(), &options(false), &mut |_| {}).unwrap();
    assert_eq!(rows.len(), 6);
    for (row, (scene, vertices)) in rows.iter().zip(
        [("cloth-10", 100), ("cloth-20", 400)]
            .iter()
            .flat_map(|s| [*s; 3]),
    ) {
        let r = &row.outcome.record;
        assert_eq!(r.scene, scene);
        assert_eq!(row.vertices, vertices);
        assert!(r.wall_time_s.is_some_and(|t| t > 0.0), "{r:?}");
        assert!(r.residual.is_some_and(f64::is_finite), "{r:?}");
        assert_eq!((r.objective_error, r.position_error), (None, None), "{r:?}");
        assert!(
            row.outcome.positions.is_empty(),
            "a sweep keeps no positions"
        );
        if cfg!(target_os = "linux") {
            assert!(row.peak_memory_bytes.is_some_and(|b| b > 0));
        }
    }
    // Peak memory is the process's high-water mark: it never decreases.
    let peaks: Vec<u64> = rows.iter().filter_map(|r| r.peak_memory_bytes).collect();
    assert!(peaks.windows(2).all(|w| w[0] <= w[1]), "{peaks:?}");

    let rows = sweep(&specs(), &options(true), &mut |_| {}).unwrap();
    for row in &rows {
        let r = &row.outcome.record;
        let (Some(objective), Some(position)) = (r.objective_error, r.position_error) else {
            panic!("errors asked for but missing: {r:?}");
        };
        assert!(objective.is_finite() && position.is_finite(), "{r:?}");
        if r.solver == "newton-tol" {
            // Newton to a relative gradient of 1e-6 from y is close to x* (Newton to 1e-10).
            assert!(position < 1e-4 && objective.abs() < 1e-8, "{r:?}");
            assert!(r.residual.unwrap() <= 1e-6, "{r:?}");
        }
    }
}

#[test]
fn sweep_command_writes_json_csv_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let (json, csv, png) = (
        dir.path().join("sweep.json"),
        dir.path().join("sweep.csv"),
        dir.path().join("plots/sweep.png"),
    );
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args([
            "bench",
            "--sweep",
            "N=10,20",
            "--solver",
            "pd:5",
            "--repeats",
            "1",
        ])
        .args(["--no-cache", "-q", "--json"])
        .arg(&json)
        .arg("--csv")
        .arg(&csv)
        .arg("--plot")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("peak MB"), "{stdout}");
    let records: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let records = records.as_array().unwrap();
    assert_eq!(records.len(), 2);
    for (r, scene) in records.iter().zip(["cloth-10", "cloth-20"]) {
        assert_eq!(r["scene"], scene);
        assert_eq!(r["solver"], "pd");
        assert_eq!(r["setting"], "5");
        assert_eq!(r["iterations"], 5);
        assert!(r["objective_error"].is_null() && r["position_error"].is_null());
        assert!(r["residual"].is_f64());
    }
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 3);
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
}

#[test]
fn a_cached_reference_does_not_bring_errors_into_a_sweep_without_errors() {
    let dir = tempfile::tempdir().unwrap();
    let setup = hooke_cli::bench::load_setup("cloth-10").unwrap();
    let prepare = hooke_cli::bench::PrepareOptions {
        start: StartState::Rest,
        reference: true,
        cache_dir: Some(dir.path().to_path_buf()),
    };
    hooke_cli::bench::BenchProblem::prepare(&setup, &prepare, &mut |_| {}).unwrap();
    let options = SweepOptions {
        sizes: vec![10],
        cache_dir: Some(dir.path().to_path_buf()),
        ..options(false)
    };
    let mut log = Vec::new();
    let rows = sweep(&specs()[..1], &options, &mut |l| log.push(l.to_string())).unwrap();
    assert!(log.iter().any(|l| l.contains("read from")), "{log:?}");
    let r = &rows[0].outcome.record;
    assert_eq!((r.objective_error, r.position_error), (None, None), "{r:?}");
}
