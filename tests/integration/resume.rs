//! `hooke run --checkpoint-every K` and `hooke run --resume DIR`: a run stopped after frame 12 of 20
//! and resumed from its checkpoint leaves the same files, byte for byte, as a run that was never
//! stopped (`timings.json`, which holds wall times, aside).
//!
//! The stop is the hidden `--stop-after N` flag, which ends the process right after frame N (no
//! final summary, no preview). The kill tests kill a real process at a chosen point: the test hook
//! `HOOKE_TEST_HALT` (crates/cli/src/test_hook.rs) halts the run there, in the middle of a frame's
//! write or right after a frame, and the test kills it once it says so, so nothing races.
//!
//! `--resume DIR --steps N` extends a finished or interrupted run to N frames: the files are then
//! those of a run of N frames from the start.

use crate::command::hooke;

use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every file under `dir` (relative path → contents), except the wall times.
pub(crate) fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
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

    same_files(whole.path(), stopped.path());
    let a = files(whole.path());
    assert!(a.contains_key("summary.json") && a.contains_key("preview.png"));
    assert!(a.keys().filter(|k| k.starts_with("frames")).count() == 21);
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
    // Settings come from the checkpoint: other flags (but --steps) are refused.
    let out = hooke(&["run", "--resume", d, "--dt", "0.01"]);
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

/// The arguments of a 40-frame Newton run of cloth-10 into `dir` with a checkpoint every 3 frames.
fn kill_test_args(dir: &Path) -> Vec<String> {
    let dir = dir.to_str().unwrap();
    [
        "run",
        "cloth-10",
        "--integrator",
        "newton",
        "--steps",
        "40",
        "--checkpoint-every",
        "3",
        "--quiet",
        "--out",
        dir,
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

/// The run of [`kill_test_args`] in a new directory, uninterrupted.
fn uninterrupted_kill_test_run() -> tempfile::TempDir {
    let whole = tempfile::tempdir().unwrap();
    let args = kill_test_args(whole.path());
    ok(&hooke(&args.iter().map(String::as_str).collect::<Vec<_>>()));
    whole
}

/// Runs [`kill_test_args`] into `dir` with the test hook halting it at `halt`, and kills the
/// process (SIGKILL on Unix) once it reports that it has halted there.
fn run_and_kill_at(dir: &Path, halt: &str) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(kill_test_args(dir))
        .env("HOOKE_TEST_HALT", halt)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut said = Vec::new();
    let marker = format!("halted at {halt}");
    for line in stderr.lines() {
        let line = line.unwrap();
        let halted = line == marker;
        said.push(line);
        if halted {
            break;
        }
    }
    // The halted process waits on its standard input (kept open here) until it is killed.
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(
        said.last().map(String::as_str),
        Some(marker.as_str()),
        "the run did not halt at {halt}: {said:#?}"
    );
}

/// Resumes the run in `killed` and asserts that it then holds the files of the run in `whole`.
fn resume_and_compare(whole: &Path, killed: &Path) {
    ok(&hooke(&[
        "run",
        "--resume",
        killed.to_str().unwrap(),
        "--quiet",
    ]));
    same_files(whole, killed);
}

/// The names of the files in `dir` (which has no subdirectories), in order.
fn names(dir: &Path) -> Vec<String> {
    files(dir).into_keys().collect()
}

#[test]
fn a_run_killed_while_writing_a_frame_resumes() {
    let whole = uninterrupted_kill_test_run();
    let killed = tempfile::tempdir().unwrap();

    // Killed halfway through frame 7's temporary file, after the checkpoint at frame 6.
    run_and_kill_at(killed.path(), "in-frame:7");
    let frames = names(&killed.path().join("frames"));
    let leftovers: Vec<&String> = frames.iter().filter(|n| n.starts_with('.')).collect();
    assert_eq!(leftovers.len(), 1, "{frames:?}");
    assert!(
        leftovers[0].starts_with(".frame_0007.obj.") && leftovers[0].ends_with(".tmp"),
        "{frames:?}"
    );
    let partial = std::fs::metadata(killed.path().join("frames").join(leftovers[0])).unwrap();
    assert!(partial.len() > 0, "half a frame was written");
    assert!(frames.contains(&"frame_0006.obj".to_string()));
    assert!(
        !frames.contains(&"frame_0007.obj".to_string()),
        "{frames:?}"
    );
    assert!(killed.path().join("checkpoint.json").is_file());

    // The resumption removes the leftover and ends with the uninterrupted run's files.
    resume_and_compare(whole.path(), killed.path());
}

#[test]
fn a_run_killed_after_a_frame_resumes() {
    let whole = uninterrupted_kill_test_run();
    let killed = tempfile::tempdir().unwrap();

    // Killed after frame 10, a frame past the checkpoint at 9: frame 10 is written again.
    run_and_kill_at(killed.path(), "after-frame:10");
    let frames = names(&killed.path().join("frames"));
    assert_eq!(frames.len(), 11, "{frames:?}");
    assert_eq!(frames.last().map(String::as_str), Some("frame_0010.obj"));
    // A temporary file a kill left elsewhere (here: while the summary was written) goes too.
    std::fs::write(killed.path().join(".summary.json.AbC123.tmp"), b"{").unwrap();
    resume_and_compare(whole.path(), killed.path());
}

#[test]
fn a_halted_run_whose_input_closes_exits_as_if_killed() {
    // Without a process to kill it (standard input empty), the hook exits at the point, running
    // nothing more: the frame's temporary file stays, as after a kill.
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(kill_test_args(dir.path()))
        .env("HOOKE_TEST_HALT", "in-frame:2")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(70), "{out:?}");
    let frames = names(&dir.path().join("frames"));
    assert_eq!(frames.len(), 3, "{frames:?}");
    assert!(frames[0].starts_with(".frame_0002.obj."), "{frames:?}");
    // A wrong value is an error that names the variable, before anything is written.
    let other = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(kill_test_args(other.path()))
        .env("HOOKE_TEST_HALT", "in-frame")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("HOOKE_TEST_HALT"), "{stderr}");
    assert!(!other.path().join("frames/frame_0000.obj").exists());
}

/// The files of `hooke run cloth-10 --steps {steps} --checkpoint-every 4` into a new directory.
fn fresh_run(steps: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    ok(&hooke(&[
        "run",
        "cloth-10",
        "--steps",
        steps,
        "--checkpoint-every",
        "4",
        "--quiet",
        "--out",
        dir.path().to_str().unwrap(),
    ]));
    dir
}

/// Asserts that `a` and `b` hold the same files (`timings.json` aside), byte for byte.
fn same_files(a: &Path, b: &Path) {
    let (a, b) = (files(a), files(b));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs");
    }
}

#[test]
fn resume_with_steps_extends_a_finished_or_interrupted_run() {
    let thirty = fresh_run("30");
    let resume_to = |dir: &Path, steps: &str| {
        hooke(&[
            "run",
            "--resume",
            dir.to_str().unwrap(),
            "--steps",
            steps,
            "--quiet",
        ])
    };

    // A finished run of 20 frames (checkpoint at 20) extended to 30.
    let finished = fresh_run("20");
    ok(&resume_to(finished.path(), "30"));
    same_files(thirty.path(), finished.path());
    let timings = std::fs::read_to_string(finished.path().join("timings.json")).unwrap();
    let timings: serde_json::Value = serde_json::from_str(&timings).unwrap();
    assert_eq!(timings["resumed_after"], serde_json::json!([20]));

    // An interrupted one (stopped after 13, checkpoint at 12) extended to 30.
    let stopped = tempfile::tempdir().unwrap();
    let out = hooke(&[
        "run",
        "cloth-10",
        "--steps",
        "20",
        "--checkpoint-every",
        "4",
        "--stop-after",
        "13",
        "--quiet",
        "--out",
        stopped.path().to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    ok(&resume_to(stopped.path(), "30"));
    same_files(thirty.path(), stopped.path());

    // Extended to 22: no checkpoint falls after 20, so the one at 20 is rewritten with the new
    // length, as a run of 22 frames writes it; and a plain --resume of it then keeps 22 frames.
    let twenty_two = fresh_run("22");
    let short = fresh_run("20");
    ok(&resume_to(short.path(), "22"));
    same_files(twenty_two.path(), short.path());
    ok(&hooke(&[
        "run",
        "--resume",
        short.path().to_str().unwrap(),
        "--quiet",
    ]));
    same_files(twenty_two.path(), short.path());

    // Before the checkpoint: refused, and nothing is removed.
    let out = resume_to(short.path(), "10");
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--steps") && stderr.contains("checkpoint's frame 20"),
        "{stderr}"
    );
    same_files(twenty_two.path(), short.path());
}

#[test]
fn the_summary_is_written_during_a_run_and_long_runs_are_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    // Stopped after frame 150 of 250: summary.json holds the records up to frame 100.
    let out = hooke(&[
        "run",
        "cloth-10",
        "--steps",
        "250",
        "--stop-after",
        "150",
        "--out",
        d,
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("warning: 250 frames"), "{stderr}");
    let summary = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&summary).unwrap();
    let steps = summary["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 101);
    assert_eq!(steps[100]["step"], 100);

    // A billion frames: warned of before the first step.
    let out = hooke(&[
        "run",
        "cloth-10",
        "--steps",
        "1000000000",
        "--stop-after",
        "1",
        "--out",
        d,
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    let warning = stderr
        .find("warning: 1000000000 frames")
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(stderr[warning..].contains(" TB to "), "{stderr}");
    assert!(
        warning < stderr.find("stopped after frame 1").unwrap(),
        "{stderr}"
    );
}

/// Self-contact friction resumes bit for bit: its lag is taken from each step's start positions
/// alone. A 4×4 sheet lying 0.9 d̂ above a pinned 6×6 sheet (an OBJ file of both), sliding at
/// 0.5 m/s with μ = 0.3 under gravity, stopped after frame 12 and resumed from the checkpoint
/// at frame 12.
#[test]
fn self_contact_friction_resumes_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    let mut grid = |n: usize, size: f64, origin: [f64; 3], first: usize| {
        let s = size / (n - 1) as f64;
        for j in 0..n {
            for i in 0..n {
                let p = [
                    origin[0] + i as f64 * s,
                    origin[1],
                    origin[2] + j as f64 * s,
                ];
                obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
            }
        }
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (a, b) = (first + j * n + i + 1, first + j * n + i + 2);
                let (c, d) = (a + n, b + n);
                obj.push_str(&format!("f {a} {c} {b}\nf {b} {c} {d}\n"));
            }
        }
    };
    grid(6, 1.0, [0.0, 0.0, 0.0], 0);
    grid(4, 0.3, [0.2667, 1.8e-3, 0.4167], 36);
    std::fs::write(dir.path().join("sheets.obj"), obj).unwrap();
    let scene = dir.path().join("sliding.toml");
    std::fs::write(
        &scene,
        r#"
[mesh]
file = "sheets.obj"
mass = { total = 5.2 }
stiffness = 1000.0
[pins]
region = { min = [-1.0, -1.0, -1.0], max = [2.0, 1e-4, 2.0] }
[forces]
gravity = [0.0, -9.81, 0.0]
[initial]
velocity = [0.5, 0.0, 0.0]
[self_contact]
dhat = 2e-3
friction = 0.3
[integrator]
method = "newton"
time_step = 0.016666666666666666
[run]
steps = 20
"#,
    )
    .unwrap();
    stop_resume_compare(&[scene.to_str().unwrap()], 4);
}

/// The adaptive barrier stiffness resumes bit for bit: its scale starts afresh at every step from
/// that step's state. cloth-fall-10 has it on (with self-contact and the ground): the scale is
/// 2.15 in frame 4, where the cloth lands, and 1.003 from frame 7 on, as it rests on the ground.
#[test]
fn the_adaptive_stiffness_resumes_bit_for_bit() {
    stop_resume_compare(&["cloth-fall-10"], 4);
}
