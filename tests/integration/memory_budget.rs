//! `hooke run --memory-budget` (docs/solvers.md §2.5, §6.1): Newton and projective dynamics over
//! the budget run on their multilevel paths and summary.json records the budget; a budget that is
//! not one is refused naming the flag.

use crate::command::{fails_with, hooke, stderr};

#[test]
fn newton_and_pd_over_the_budget_run_on_their_multilevel_paths() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let out = hooke(&[
        "run",
        "cloth-10",
        "--integrator",
        "newton",
        "--memory-budget",
        "0",
        "--steps",
        "2",
        "--out",
        out_dir,
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["solver_settings"]["memory_budget"], 0);
    let steps = summary["steps"].as_array().unwrap();
    assert!(
        steps[1..].iter().all(|s| s["solver_converged"] == true),
        "{steps:?}"
    );
    let pd = hooke(&[
        "run",
        "cloth-10",
        "--integrator",
        "pd",
        "--memory-budget",
        "1K",
        "--steps",
        "2",
        "--out",
        out_dir,
        "-q",
    ]);
    assert!(pd.status.success(), "{}", stderr(&pd));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["solver_settings"]["memory_budget"], 1024);
    let steps = summary["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3, "{steps:?}");
    fails_with(
        &[
            "run",
            "cloth-10",
            "--memory-budget",
            "lots",
            "--out",
            out_dir,
            "-q",
        ],
        &["memory-budget", "not a memory budget"],
    );
}

/// `--pd-global-solve` picks how the PD-based integrators solve with their matrix (docs/solvers.md
/// §6.1), summary.json records it, and an integrator without a PD matrix or a bad name is refused
/// naming the flag.
#[test]
fn the_pd_global_solve_flag_reaches_pd_and_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    for kind in ["direct", "multilevel"] {
        let out = hooke(&[
            "run",
            "cloth-10",
            "--integrator",
            "pd",
            "--pd-global-solve",
            kind,
            "--steps",
            "2",
            "--out",
            out_dir,
            "-q",
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(summary["solver_settings"]["pd_global_solve"], kind);
        assert_eq!(summary["steps"].as_array().unwrap().len(), 3);
    }
    fails_with(
        &[
            "run",
            "cloth-10",
            "--integrator",
            "newton",
            "--pd-global-solve",
            "direct",
            "--out",
            out_dir,
            "-q",
        ],
        &["pd-global-solve", "pd-chebyshev"],
    );
    fails_with(
        &[
            "run",
            "cloth-10",
            "--integrator",
            "pd",
            "--pd-global-solve",
            "fast",
            "--out",
            out_dir,
            "-q",
        ],
        &["pd-global-solve", "not a global solve"],
    );
}
