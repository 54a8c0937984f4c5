//! A run gives the same bytes on any number of threads: frames, summary.json and the preview of
//! `hooke run` with `RAYON_NUM_THREADS=1` and `=2` (timings.json, which holds wall times, aside),
//! for every implicit integrator, an explicit one, obstacles, self-contact and the fluid. The
//! parallel loops sum in a fixed order (docs/model.md §1), and the factorisations' parallel
//! paths (the split triangular solve of a factor above 32,768 values: cloth-80's PD factor) give
//! the serial bits.

use crate::command::hooke;
use crate::resume::files;

use std::process::{Command, Stdio};

/// Runs `hooke run args --quiet --out DIR` on `threads` rayon threads; returns DIR.
fn run_on(threads: usize, args: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .arg("run")
        .args(args)
        .args(["--quiet", "--out", dir.path().to_str().unwrap()])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RAYON_NUM_THREADS", threads.to_string())
        .stdin(Stdio::null())
        .output()
        .expect("the hooke binary runs");
    assert!(
        out.status.success(),
        "{args:?} on {threads} thread(s):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

#[test]
fn one_thread_and_two_write_the_same_bytes() {
    // The command itself runs (the helper is shared with the other command tests).
    assert!(hooke(&["scenes"]).status.success());
    let runs: &[&[&str]] = &[
        &["cloth-10", "--integrator", "newton", "--steps", "8"],
        &["cloth-10", "--integrator", "pd", "--steps", "8"],
        &["cloth-10", "--integrator", "pd-chebyshev", "--steps", "8"],
        &["cloth-10", "--integrator", "lbfgs", "--steps", "8"],
        &["cloth-10", "--integrator", "newton-cg", "--steps", "8"],
        &["cloth-10", "--integrator", "linearized", "--steps", "8"],
        &[
            "cloth-10",
            "--integrator",
            "symplectic-euler",
            "--steps",
            "4",
        ],
        &["cloth-80", "--integrator", "pd", "--steps", "2"],
        &["cloth-fall-10", "--steps", "12"],
        &["bunny-drop", "--steps", "4"],
        &["dam-break-2d", "--steps", "2"],
    ];
    for args in runs {
        let one = files(run_on(1, args).path());
        let two = files(run_on(2, args).path());
        assert!(one.keys().any(|k| k.starts_with("frames")), "{args:?}");
        assert_eq!(
            one.keys().collect::<Vec<_>>(),
            two.keys().collect::<Vec<_>>(),
            "{args:?}"
        );
        for (name, bytes) in &one {
            assert!(
                two[name] == *bytes,
                "{args:?}: {name} differs between 1 and 2 threads"
            );
        }
    }
}
