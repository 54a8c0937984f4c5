//! The `hooke` command end to end: it runs scenes and leaves frames, a summary and a preview.

use crate::command::hooke;

use std::path::Path;

fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is a PNG",
        path.display()
    );
    let be = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn scenes_lists_the_canonical_scenes() {
    let out = hooke(&["scenes"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for name in [
        "cloth-40",
        "cloth-40-stiff",
        "cloth-320",
        "beam-4",
        "seed-2d",
        "bunny-drop",
        "cloth-drape-20",
        "cloth-drape-40",
        "cloth-drape-80",
        "cloth-fall-20",
        "cloth-fall-40",
        "cloth-fall-80",
        "cloth-twist-20",
        "cloth-twist-40",
        "cloth-twist-80",
    ] {
        assert!(
            text.lines().any(|l| l.starts_with(name)),
            "`hooke scenes` lists {name}:\n{text}"
        );
    }
}

#[test]
fn run_writes_frames_summary_and_preview() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let out = hooke(&[
        "run",
        "data/scenes/seed-2d.toml",
        "--steps",
        "20",
        "--out",
        out_dir,
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let frames: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .collect();
    assert_eq!(frames.len(), 21, "frames 0..=20");
    let frame = std::fs::read_to_string(dir.path().join("frames/frame_0000.obj")).unwrap();
    assert_eq!(frame.lines().filter(|l| l.starts_with("v ")).count(), 3);
    assert_eq!(
        frame.lines().filter(|l| l.starts_with("l ")).count(),
        3,
        "springs as lines"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    let steps = summary["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 21);
    assert_eq!(summary["scene"], "seed-2d");
    assert_eq!(summary["substeps"], 10);
    for (k, step) in steps.iter().enumerate() {
        assert_eq!(step["step"], k);
        for key in [
            "time",
            "kinetic_energy",
            "potential_energy",
            "total_energy",
            "max_stretch",
        ] {
            assert!(
                step[key].as_f64().is_some_and(f64::is_finite),
                "step {k}: {key} = {}",
                step[key]
            );
        }
    }
    assert_eq!(png_size(&dir.path().join("preview.png")), (800, 600));
    // Only the finished files remain: no temporary files beside them.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(
        sorted,
        ["frames", "preview.png", "summary.json", "timings.json"]
    );

    // A shorter second run into the same directory leaves exactly its own frames.
    let out = hooke(&[
        "run", "cloth-10", "--steps", "2", "--out", out_dir, "--format", "vtk", "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut frames: Vec<String> = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    frames.sort();
    assert_eq!(
        frames,
        ["frame_0000.vtk", "frame_0001.vtk", "frame_0002.vtk"]
    );
}

/// cloth-twist-N runs by name: two frames of the 10×10 twist, the turning edge 12° round after
/// 2/30 s (180°/s): its corner (1, 0, 1), 0.5 m from the axis y = 0, z = 0.5, is at
/// (1, −0.5 sin 12°, 0.5 + 0.5 cos 12°) in the last frame (which keeps every digit), to
/// round-off of the 1 m cloth.
#[test]
fn run_turns_the_twisted_cloth() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let out = hooke(&[
        "run",
        "cloth-twist-10",
        "--steps",
        "2",
        "--out",
        out_dir,
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["scene"], "cloth-twist-10");
    let frame = std::fs::read_to_string(dir.path().join("frames/frame_0002.obj")).unwrap();
    let corner: Vec<f64> = frame
        .lines()
        .filter(|l| l.starts_with("v "))
        .nth(99)
        .unwrap()
        .split_whitespace()
        .skip(1)
        .map(|c| c.parse().unwrap())
        .collect();
    let angle = 12f64.to_radians();
    let expected = [1.0, -0.5 * angle.sin(), 0.5 + 0.5 * angle.cos()];
    for (axis, (got, want)) in corner.iter().zip(expected).enumerate() {
        assert!(
            (got - want).abs() < 1e-12,
            "axis {axis}: {got} against {want}"
        );
    }
}

#[test]
fn errors_are_clear_and_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["run", "cloth-nine"], "unknown scene"),
        (&["run", "no/such/file.toml"], "no/such/file.toml"),
        (&["run", "cloth-10", "--dt", "-1"], "time step"),
        (&["run", "cloth-10", "--dt", "0"], "time step"),
        (
            &["run", "cloth-10", "--integrator", "rk4"],
            "unknown integrator",
        ),
        (
            &[
                "run",
                "cloth-10",
                "--integrator",
                "symplectic-euler",
                "--substeps",
                "1",
            ],
            "stability bound",
        ),
    ];
    for (args, expected) in cases {
        let mut all = args.to_vec();
        all.extend(["--out", out_dir, "--quiet"]);
        let out = hooke(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        assert!(
            stderr.contains(expected),
            "{args:?}: expected {expected:?} in {stderr}"
        );
        // Each cause is printed once, not again as a "caused by" line of its own.
        for line in stderr
            .lines()
            .filter_map(|l| l.strip_prefix("  caused by: "))
        {
            assert_eq!(stderr.matches(line).count(), 1, "{args:?}: {stderr}");
        }
    }
    let missing = hooke(&["run", "no/such/file.toml", "--out", out_dir, "--quiet"]);
    let stderr = String::from_utf8_lossy(&missing.stderr);
    assert_eq!(
        stderr.matches("No such file").count(),
        1,
        "the cause is printed once: {stderr}"
    );
}

#[test]
fn linearized_flags_reach_the_solver_and_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let out = hooke(&[
        "run",
        "cloth-10",
        "--integrator",
        "linearized",
        "--beta",
        "0.5",
        "--linear-solver",
        "jacobi",
        "--iterations",
        "300",
        "--tolerance",
        "1e-6",
        "--steps",
        "3",
        "--out",
        out_dir,
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["integrator"], "linearized");
    let s = &summary["solver_settings"];
    assert_eq!(s["beta"], 0.5);
    assert_eq!(s["linear_solver"], "jacobi");
    assert_eq!(s["iterations"], 300);
    assert_eq!(s["tolerance"], 1e-6);
    for step in &summary["steps"].as_array().unwrap()[1..] {
        let iterations = step["solver_iterations"].as_u64().unwrap();
        assert!((1..=300).contains(&iterations), "{step}");
        assert!(step["solver_residual"].as_f64().is_some(), "{step}");
        assert!(step["solver_stop"].is_string(), "{step}");
    }
    // Newton and PD take --iterations and --tolerance too.
    for integrator in ["newton", "pd"] {
        let out = hooke(&[
            "run",
            "cloth-10",
            "--integrator",
            integrator,
            "--iterations",
            "7",
            "--tolerance",
            "1e-5",
            "--steps",
            "1",
            "--out",
            out_dir,
            "--quiet",
        ]);
        assert!(
            out.status.success(),
            "{integrator}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(summary["solver_settings"]["iterations"], 7, "{integrator}");
        assert_eq!(
            summary["solver_settings"]["tolerance"], 1e-5,
            "{integrator}"
        );
        assert!(summary["solver_settings"].get("beta").is_none());
    }
}

#[test]
fn a_scene_file_and_the_flags_give_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("cloth.toml");
    std::fs::write(
        &scene,
        r#"
name = "cloth-10"
[mesh]
generator = "cloth"
n = 10
stiffness = 1000.0
[pins]
vertices = [0, 9]
[forces]
gravity = [0.0, -9.81, 0.0]
[integrator]
method = "linearized"
time_step = 0.03333333333333333
beta = 0.75
linear_solver = "jacobi"
iterations = 400
tolerance = 1e-7
[run]
steps = 4
"#,
    )
    .unwrap();
    let from_file = dir.path().join("file");
    let from_flags = dir.path().join("flags");
    let file_run = hooke(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        from_file.to_str().unwrap(),
        "--quiet",
    ]);
    let flag_run = hooke(&[
        "run",
        "cloth-10",
        "--integrator",
        "linearized",
        "--beta",
        "0.75",
        "--linear-solver",
        "jacobi",
        "--iterations",
        "400",
        "--tolerance",
        "1e-7",
        "--steps",
        "4",
        "--out",
        from_flags.to_str().unwrap(),
        "--quiet",
    ]);
    for run in [&file_run, &flag_run] {
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let read = |dir: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
    };
    let (a, b) = (read(&from_file), read(&from_flags));
    assert_eq!(a["solver_settings"], b["solver_settings"]);
    assert_eq!(a["solver_settings"]["beta"], 0.75);
    assert_eq!(a["integrator"], b["integrator"]);
    // Same settings, same run: the last frames are identical, byte for byte.
    let last = |dir: &Path| std::fs::read(dir.join("frames/frame_0004.obj")).unwrap();
    assert_eq!(last(&from_file), last(&from_flags));
}

#[test]
fn bad_solver_flags_are_clear_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let linearized = ["run", "cloth-10", "--integrator", "linearized"];
    let cases: &[(&[&str], &str)] = &[
        (&["--beta", "1.5"], "invalid --beta"),
        (&["--beta", "-0.1"], "must be in [0, 1]"),
        (&["--beta", "nan"], "must be in [0, 1]"),
        (&["--tolerance", "0"], "invalid --tolerance"),
        (&["--tolerance", "-1"], "must be finite and positive"),
        (&["--tolerance=-1e-6"], "must be finite and positive"),
        (&["--iterations", "0"], "invalid --iterations"),
        (&["--linear-solver", "gmres"], "unknown linear solver"),
    ];
    let mismatched: &[(&[&str], &str)] = &[
        (
            &["run", "cloth-10", "--integrator", "newton", "--beta", "0.5"],
            "applies only to the linearized integrator",
        ),
        (
            &[
                "run",
                "cloth-10",
                "--integrator",
                "symplectic-euler",
                "--tolerance",
                "1e-6",
            ],
            "solves no system",
        ),
    ];
    let all = cases
        .iter()
        .map(|(flags, expected)| {
            let mut args = linearized.to_vec();
            args.extend_from_slice(flags);
            (args, *expected)
        })
        .chain(mismatched.iter().map(|(a, e)| (a.to_vec(), *e)));
    for (mut args, expected) in all {
        args.extend(["--steps", "1", "--out", out_dir, "--quiet"]);
        let out = hooke(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        assert!(
            stderr.contains(expected),
            "{args:?}: expected {expected:?} in {stderr}"
        );
    }
}

#[test]
fn the_energy_limit_flag_sets_and_disables_the_watchdog() {
    // Linearised Euler with β = 0 is symplectic Euler with one step of 1/30 s, 16 times cloth-10's
    // explicit bound: it is unstable, and after 2 frames its energy is 40.8 J (measured) from
    // E₀ = 0. The watchdog's scale is M |g| L = 1 kg · 9.81 m/s² · √2 m = 13.9 J, so its limit is
    // 13.9 J at the default factor 1 (tripped), 27.7 J at 2 (tripped), 139 J at 10 (not), and
    // `off` never stops the run: margins of 1.5× and more on every side.
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    let unstable = [
        "run",
        "cloth-10",
        "--integrator",
        "linearized",
        "--beta",
        "0",
        "--steps",
        "2",
        "--out",
        out_dir,
        "--quiet",
    ];
    let run = |extra: &[&str]| {
        let mut args = unstable.to_vec();
        args.extend_from_slice(extra);
        let out = hooke(&args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!stderr.contains("panicked"), "{extra:?} panicked: {stderr}");
        (out.status.success(), stderr)
    };
    for (extra, limit) in [
        (&[][..], "1.387e1 J"),
        (&["--energy-limit", "2"][..], "2.775e1 J"),
    ] {
        let (ok, stderr) = run(extra);
        assert!(!ok, "{extra:?}: the watchdog should stop the run");
        assert!(
            stderr.contains("step 2: the total energy rose") && stderr.contains(limit),
            "{extra:?}: expected the energy error with limit {limit}: {stderr}"
        );
    }
    for extra in [
        &["--energy-limit", "10"][..],
        &["--energy-limit", "off"][..],
    ] {
        let (ok, stderr) = run(extra);
        assert!(ok, "{extra:?}: the run should finish: {stderr}");
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("summary.json")).unwrap(),
        )
        .unwrap();
        let last = summary["steps"][2]["total_energy"].as_f64().unwrap();
        assert!(
            last > 27.7,
            "{extra:?}: the run gained {last} J, past the default limit"
        );
    }
    // The scene file's key, and the flag overriding it.
    let scene = dir.path().join("unstable.toml");
    std::fs::write(
        &scene,
        r#"
[mesh]
generator = "cloth"
n = 10
stiffness = 1000.0
[pins]
vertices = [0, 9]
[forces]
gravity = [0.0, -9.81, 0.0]
[integrator]
method = "linearized"
time_step = 0.03333333333333333
beta = 0.0
energy_limit = "off"
[run]
steps = 2
"#,
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    let from_file = |extra: &[&str]| {
        let mut args = vec!["run", scene, "--out", out_dir, "--quiet"];
        args.extend_from_slice(extra);
        let out = hooke(&args);
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (ok, stderr) = from_file(&[]);
    assert!(ok, "energy_limit = \"off\" in the file: {stderr}");
    let (ok, stderr) = from_file(&["--energy-limit", "1"]);
    assert!(
        !ok && stderr.contains("the total energy rose"),
        "the flag overrides the file: {stderr}"
    );
    // Bad values are typed errors naming the flag.
    for (value, expected) in [
        ("--energy-limit=-1", "finite and >= 0"),
        ("--energy-limit=nan", "finite and >= 0"),
        ("--energy-limit=inf", "finite and >= 0"),
        ("--energy-limit=lots", "a factor (a number >= 0) or \"off\""),
    ] {
        let (ok, stderr) = run(&[value]);
        assert!(!ok, "{value} should fail");
        assert!(
            stderr.contains("invalid --energy-limit") && stderr.contains(expected),
            "{value}: expected {expected:?} in {stderr}"
        );
    }
}

#[test]
fn run_help_lists_every_integrator_and_solver_flag() {
    let out = hooke(&["run", "--help"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for word in [
        "--integrator",
        "explicit-euler",
        "symplectic-euler",
        "linearized",
        "newton",
        "pd",
        "--beta",
        "--linear-solver",
        "jacobi",
        "cg",
        "--iterations",
        "--tolerance",
        "--energy-limit",
        "--pin-method",
        "counter-force",
        "--relaxation",
        "buckling",
    ] {
        assert!(
            text.contains(word),
            "`hooke run --help` mentions {word}:\n{text}"
        );
    }
}

#[test]
fn the_relaxation_flag_opts_newton_into_the_buckling_preset() {
    // cloth-10 by Newton with the buckling preset: the run finishes and its summary records the
    // preset; plain Newton records "none"; other integrators and unknown names are refused.
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        let out_dir = dir.path().join(extra.join("_"));
        let out_dir = out_dir.to_str().unwrap().to_string();
        let mut args = vec![
            "run", "cloth-10", "--steps", "2", "--out", &out_dir, "--quiet",
        ];
        args.extend_from_slice(extra);
        let out = hooke(&args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        let summary = std::fs::read_to_string(Path::new(&out_dir).join("summary.json"))
            .ok()
            .map(|text| serde_json::from_str::<serde_json::Value>(&text).unwrap());
        (out.status.success(), stderr, summary)
    };
    for (preset, flags) in [
        (
            "buckling",
            &["--integrator", "newton", "--relaxation", "buckling"][..],
        ),
        ("none", &["--integrator", "newton"][..]),
    ] {
        let (ok, stderr, summary) = run(flags);
        assert!(ok, "{flags:?}: {stderr}");
        assert_eq!(summary.unwrap()["solver_settings"]["relaxation"], preset);
    }
    for (flags, expected) in [
        (
            &["--integrator", "pd", "--relaxation", "buckling"][..],
            "applies only to the newton integrator",
        ),
        (
            &["--integrator", "newton", "--relaxation", "sweeps"][..],
            "invalid --relaxation: unknown relaxation \"sweeps\"",
        ),
    ] {
        let (ok, stderr, _) = run(flags);
        assert!(!ok, "{flags:?} should fail");
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
    }
}

#[test]
fn the_pin_method_flag_and_key_choose_how_pins_are_held() {
    // cloth-10 (corners pinned) by Newton, 3 frames, with each pin method: both runs finish, the
    // summary records the method, and the runs agree to round-off (the two methods solve the same
    // system for the free vertices; tests/integration/pin_methods.rs bounds the position difference at 1e-10
    // of the motion; here the summaries' total energies are compared).
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str]| {
        let out_dir = dir.path().join(extra.join("_").replace('-', ""));
        let out_dir = out_dir.to_str().unwrap().to_string();
        let mut args = vec![
            "run", "cloth-10", "--steps", "3", "--out", &out_dir, "--quiet",
        ];
        args.extend_from_slice(extra);
        let out = hooke(&args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!stderr.contains("panicked"), "{extra:?} panicked: {stderr}");
        let summary = std::fs::read_to_string(Path::new(&out_dir).join("summary.json"))
            .ok()
            .map(|text| serde_json::from_str::<serde_json::Value>(&text).unwrap());
        (out.status.success(), stderr, summary)
    };
    let (ok, stderr, default) = run(&["--integrator", "newton"]);
    assert!(ok, "{stderr}");
    let default = default.unwrap();
    assert_eq!(default["pin_method"], "reduction", "the default");
    let (ok, stderr, counter) = run(&["--integrator", "newton", "--pin-method", "counter-force"]);
    assert!(ok, "{stderr}");
    let counter = counter.unwrap();
    assert_eq!(counter["pin_method"], "counter-force");
    for step in 1..=3 {
        let [a, b] =
            [&default, &counter].map(|s| s["steps"][step]["total_energy"].as_f64().unwrap());
        // Energies of order 1 J; round-off-level trajectories give round-off-level energies.
        assert!(
            (a - b).abs() <= 1e-9 * a.abs().max(1.0),
            "step {step}: {a} J vs {b} J"
        );
    }
    // Bad values name the flag and the choices; pd refuses counter-forces.
    for (extra, expected) in [
        (
            &["--integrator", "newton", "--pin-method", "penalty"][..],
            "invalid --pin-method: unknown pin method \"penalty\"",
        ),
        (
            &["--integrator", "newton", "--pin-method", ""][..],
            "expected \"reduction\" or \"counter-force\"",
        ),
        (
            &["--pin-method", "counter-force", "--integrator", "pd"][..],
            "does not support pins by counter-force",
        ),
    ] {
        let (ok, stderr, _) = run(extra);
        assert!(!ok, "{extra:?} should fail");
        assert!(
            stderr.contains(expected),
            "{extra:?}: expected {expected:?} in {stderr}"
        );
    }
    // The scene file's key, and the flag overriding it.
    let scene = dir.path().join("pins.toml");
    std::fs::write(
        &scene,
        r#"
[mesh]
generator = "cloth"
n = 10
stiffness = 1000.0
[pins]
vertices = [0, 9]
[integrator]
method = "newton"
time_step = 0.03333333333333333
pin_method = "counter-force"
[run]
steps = 1
"#,
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    let from_file = |extra: &[&str]| {
        let out_dir = dir.path().join("file");
        let mut args = vec!["run", scene, "--out", out_dir.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        let out = hooke(&args);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{extra:?}: {stderr}");
        let text = std::fs::read_to_string(out_dir.join("summary.json")).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()["pin_method"].clone()
    };
    assert_eq!(from_file(&[]), "counter-force");
    assert_eq!(from_file(&["--pin-method", "reduction"]), "reduction");
}
