//! `hooke run --checkpoint-every K` and `hooke run --resume DIR`: a run stopped after frame 12 of 20
//! and resumed from its checkpoint leaves the same files, byte for byte, as a run that was never
//! stopped (`timings.json`, which holds wall times, aside).
//!
//! The stop is the hidden `--stop-after N` flag, which ends the process right after frame N as a
//! kill would (no summary, no preview); `a_killed_run_resumes` also kills a real process.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

fn hooke(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the hooke binary runs")
}

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every file under `dir` (relative path → contents), except the wall times.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let name = path
                .strip_prefix(dir)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            if name != "timings.json" {
                out.insert(name, std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

/// Runs `run_args` for 20 frames with a checkpoint every `every` frames: once through, and once
/// stopped after frame 12 and resumed; asserts that the two leave the same files.
fn stop_resume_compare(run_args: &[&str], every: usize) {
    let whole = tempfile::tempdir().unwrap();
    let stopped = tempfile::tempdir().unwrap();
    let every = every.to_string();
    let with = |dir: &Path, extra: &[&str]| {
        let mut args = vec!["run"];
        args.extend_from_slice(run_args);
        args.extend_from_slice(&["--steps", "20", "--checkpoint-every", &every, "--quiet"]);
        args.extend_from_slice(&["--out", dir.to_str().unwrap()]);
        args.extend_from_slice(extra);
        hooke(&args)
    };
    ok(&with(whole.path(), &[]));

    let out = with(stopped.path(), &["--stop-after", "12"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("stopped after frame 12"), "{stderr}");
    assert!(
        stopped.path().join("frames/frame_0012.obj").is_file()
            || stopped.path().join("frames/frame_0012.vtk").is_file()
    );
    assert!(!stopped.path().join("summary.json").exists());
    assert!(stopped.path().join("checkpoint.json").is_file());

    let resumed = hooke(&[
        "run",
        "--resume",
        stopped.path().to_str().unwrap(),
        "--quiet",
    ]);
    ok(&resumed);

    let a = files(whole.path());
    let b = files(stopped.path());
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the same files"
    );
    assert!(a.contains_key("summary.json") && a.contains_key("preview.png"));
    assert!(a.keys().filter(|k| k.starts_with("frames")).count() == 21);
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs after the resumption");
    }
    // The timings of the resumed run say where it was resumed and cover every step.
    let timings = std::fs::read_to_string(stopped.path().join("timings.json")).unwrap();
    let timings: serde_json::Value = serde_json::from_str(&timings).unwrap();
    let expected_resume = 12 / every.parse::<usize>().unwrap() * every.parse::<usize>().unwrap();
    assert_eq!(
        timings["resumed_after"],
        serde_json::json!([expected_resume])
    );
    assert_eq!(timings["steps"].as_array().unwrap().len(), 21, "{timings}");
}

#[test]
fn newton_resumes_bit_for_bit_from_a_checkpoint_at_the_stop() {
    // Newton on a cloth pinned at two corners; the last checkpoint is at the stop (12 = 3 × 4).
    stop_resume_compare(&["cloth-20", "--integrator", "newton"], 4);
}

#[test]
fn runs_resume_from_a_checkpoint_before_the_stop() {
    // Checkpoints at 5 and 10: frames 11 and 12 of the stopped run are written again. Symplectic
    // Euler (substeps), projective dynamics and the linearised integrator, VTK frames with data.
    stop_resume_compare(&["data/scenes/seed-2d.toml", "--format", "vtk"], 5);
    stop_resume_compare(&["cloth-10", "--integrator", "pd", "--format", "vtk"], 5);
    stop_resume_compare(&["cloth-10", "--integrator", "linearized"], 5);
}

#[test]
fn resume_refuses_other_arguments_and_missing_or_damaged_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    // Nothing to resume.
    let out = hooke(&["run", "--resume", d]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("checkpoint.json"), "{stderr}");
    // Settings come from the checkpoint: other flags are refused.
    let out = hooke(&["run", "--resume", d, "--steps", "3"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
    // A damaged checkpoint.
    std::fs::write(dir.path().join("checkpoint.json"), b"{\"format\": 1").unwrap();
    let out = hooke(&["run", "--resume", d]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("not a valid checkpoint"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    // K = 0.
    let out = hooke(&["run", "cloth-10", "--checkpoint-every", "0", "--out", d]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--checkpoint-every"));
}

#[test]
fn a_changed_scene_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("chain.toml");
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/scenes/seed-2d.toml"),
    )
    .unwrap();
    std::fs::write(&scene, &text).unwrap();
    let out_dir = dir.path().join("out");
    let out = hooke(&[
        "run",
        scene.to_str().unwrap(),
        "--steps",
        "6",
        "--checkpoint-every",
        "2",
        "--stop-after",
        "3",
        "--quiet",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    std::fs::write(&scene, format!("{text}\n# edited\n")).unwrap();
    let out = hooke(&["run", "--resume", out_dir.to_str().unwrap(), "--quiet"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("scene file changed"), "{stderr}");
}

#[test]
fn a_killed_run_resumes() {
    // A real kill at whatever moment after the first checkpoint: the resumed run still ends with
    // the files of an uninterrupted one.
    let whole = tempfile::tempdir().unwrap();
    let killed = tempfile::tempdir().unwrap();
    let args = |dir: &Path| -> Vec<String> {
        [
            "run",
            "cloth-10",
            "--integrator",
            "newton",
            "--steps",
            "40",
            "--checkpoint-every",
            "3",
        ]
        .iter()
        .map(|s| s.to_string())
        .chain([
            "--quiet".into(),
            "--out".into(),
            dir.to_str().unwrap().into(),
        ])
        .collect()
    };
    ok(&hooke(
        &args(whole.path())
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    ));
    let mut child = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args(killed.path()))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let checkpoint = killed.path().join("checkpoint.json");
    while !checkpoint.exists() {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    child.kill().ok();
    child.wait().unwrap();
    ok(&hooke(&[
        "run",
        "--resume",
        killed.path().to_str().unwrap(),
        "--quiet",
    ]));
    let (a, b) = (files(whole.path()), files(killed.path()));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{name} differs after the kill and resumption"
        );
    }
}
