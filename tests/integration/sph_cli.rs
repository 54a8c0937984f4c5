//! The `hooke` command on the fluid: `hooke run` of the fluid scenes (docs/scenes.md §7) and of a
//! `[fluid]` scene file writes VTK frames with velocity, density and pressure, a summary with the
//! documented keys and a preview; bad input is an error with a message, never a panic;
//! `hooke bench --sph` prints a row and writes JSON. Coarse spacings and short runs keep each test
//! to about a second in the dev profile.

use crate::command::{fails_with, hooke, stderr};

use std::path::Path;
use std::process::Command;

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

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The number of points of a legacy VTK frame, and whether it has each point-data array.
fn check_frame(path: &Path, points: usize) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.starts_with("# vtk DataFile Version"),
        "{}",
        path.display()
    );
    assert!(
        text.contains(&format!("POINTS {points} double")),
        "{}",
        path.display()
    );
    assert!(text.contains(&format!("POINT_DATA {points}")));
    for array in [
        "VECTORS velocity double",
        "SCALARS density double",
        "SCALARS pressure double",
    ] {
        assert!(text.contains(array), "{}: no {array}", path.display());
    }
}

#[test]
fn scenes_lists_the_fluid_scenes() {
    let out = hooke(&["scenes"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for name in ["dam-break-2d", "hydrostatic-2d", "dam-break-3d", "cloth-40"] {
        assert!(
            text.lines().any(|l| l.starts_with(name)),
            "`hooke scenes` lists {name}:\n{text}"
        );
    }
}

#[test]
fn dam_break_writes_frames_summary_and_preview() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().to_str().unwrap();
    // Δx = 0.05: 20 × 40 = 800 fluid particles; 10 frames of 0.02 s.
    let out = hooke(&[
        "run",
        "dam-break-2d",
        "--dx",
        "0.05",
        "--steps",
        "10",
        "--out",
        out_dir,
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let frames: Vec<_> = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .collect();
    assert_eq!(frames.len(), 11, "frames 0..=10");
    for k in [0, 5, 10] {
        check_frame(&dir.path().join(format!("frames/frame_{k:04}.vtk")), 800);
    }
    assert!(dir.path().join("walls.vtk").is_file());
    assert_eq!(png_size(&dir.path().join("preview.png")), (800, 600));

    let summary = read_json(&dir.path().join("summary.json"));
    for key in [
        "scene",
        "model",
        "dimension",
        "fluid_particles",
        "boundary_particles",
        "particle_mass",
        "dx",
        "smoothing_length",
        "sound_speed",
        "rest_density",
        "integrator",
        "density_method",
        "kernel",
        "frame_interval",
        "column_width",
        "column_height",
        "dam_break",
        "frames",
    ] {
        assert!(summary.get(key).is_some(), "summary has {key}");
    }
    assert_eq!(summary["scene"], "dam-break-2d");
    assert_eq!(summary["fluid_particles"], 800);
    assert_eq!(summary["frame_interval"], 0.02);
    let frames = summary["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 11);
    let first_mass = frames[0]["total_mass"].as_f64().unwrap();
    assert!((first_mass - 800.0 * 1000.0 * 0.05 * 0.05).abs() < 1e-9);
    let mut last_front = 0.0;
    for (k, f) in frames.iter().enumerate() {
        for key in [
            "frame",
            "time",
            "steps",
            "frame_steps",
            "min_dt",
            "max_dt",
            "max_density_error",
            "kinetic_energy",
            "max_speed",
            "particles",
            "total_mass",
            "front_x",
            "Z",
            "T",
        ] {
            assert!(f.get(key).is_some(), "frame {k} has {key}: {f}");
        }
        assert_eq!(f["frame"], k);
        assert!((f["time"].as_f64().unwrap() - 0.02 * k as f64).abs() < 1e-12);
        assert_eq!(f["particles"], 800, "particle count constant");
        assert_eq!(f["total_mass"].as_f64().unwrap(), first_mass, "mass exact");
        let front = f["front_x"].as_f64().unwrap();
        assert!(
            front >= last_front,
            "frame {k}: front {front} < {last_front}"
        );
        last_front = front;
        assert_eq!(f["Z"].as_f64().unwrap(), front / 1.0);
        let t_scaled = 0.02 * k as f64 * (2.0f64 * 9.81).sqrt();
        assert!((f["T"].as_f64().unwrap() - t_scaled).abs() < 1e-9);
        assert!(f["max_density_error"].as_f64().unwrap() < 0.05);
        if k > 0 {
            let (lo, hi) = (f["min_dt"].as_f64().unwrap(), f["max_dt"].as_f64().unwrap());
            assert!(0.0 < lo && lo <= hi && hi < 0.02, "{lo} {hi}");
            assert!(f["frame_steps"].as_u64().unwrap() > 0);
            assert!(f["kinetic_energy"].as_f64().unwrap() > 0.0);
        }
    }
    let start = frames[0]["front_x"].as_f64().unwrap();
    assert!(
        last_front > start + 0.2,
        "the front moves: {start} → {last_front}"
    );
}

#[test]
fn scene_file_runs_and_hydrostatic_has_no_front() {
    let dir = tempfile::tempdir().unwrap();
    let small = dir.path().join("small");
    let out = hooke(&[
        "run",
        "data/scenes/dam-break-small.toml",
        "--steps",
        "5",
        "--out",
        small.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    check_frame(&small.join("frames/frame_0005.vtk"), 200);
    let summary = read_json(&small.join("summary.json"));
    assert_eq!(summary["scene"], "dam-break-small");
    assert_eq!(summary["frames"].as_array().unwrap().len(), 6);
    assert!(summary["frames"][5]["front_x"].as_f64().unwrap() > 0.25);
    assert!(small.join("preview.png").is_file());

    let still = dir.path().join("still");
    let out = hooke(&[
        "run",
        "hydrostatic-2d",
        "--dx",
        "0.1",
        "--steps",
        "2",
        "--out",
        still.to_str().unwrap(),
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = read_json(&still.join("summary.json"));
    assert_eq!(summary["dam_break"], false);
    let last = &summary["frames"][2];
    assert!(last.get("front_x").is_none(), "{last}");
    assert!((last["time"].as_f64().unwrap() - 0.1).abs() < 1e-12);
}

#[test]
fn three_d_dam_break_runs() {
    let dir = tempfile::tempdir().unwrap();
    let out = hooke(&[
        "run",
        "dam-break-3d",
        "--dx",
        "0.125",
        "--steps",
        "1",
        "--dt",
        "0.01",
        "--out",
        dir.path().to_str().unwrap(),
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary = read_json(&dir.path().join("summary.json"));
    assert_eq!(summary["dimension"], 3);
    let n = summary["fluid_particles"].as_u64().unwrap() as usize;
    check_frame(&dir.path().join("frames/frame_0001.vtk"), n);
}

#[test]
fn bad_input_is_an_error_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out_dir = out_dir.to_str().unwrap();
    fails_with(
        &["run", "dam-break-2d", "--dx", "0", "--out", out_dir],
        &["--dx", "> 0"],
    );
    fails_with(
        &["run", "dam-break-2d", "--dx", "-0.02", "--out", out_dir],
        &["--dx"],
    );
    fails_with(
        &["run", "dam-break-2d", "--dx", "3", "--out", out_dir],
        &["--dx", "coarse"],
    );
    fails_with(&["run", "dam-break-2d", "--dx", "fine"], &["--dx"]);
    fails_with(
        &["run", "dam-break-2d", "--beta", "0.5", "--out", out_dir],
        &["--beta", "fluid"],
    );
    fails_with(
        &["run", "cloth-10", "--dx", "0.1", "--out", out_dir],
        &["--dx", "fluid"],
    );

    let base = "[fluid]\ntank = [1.0, 1.0]\ncolumn = [0.25, 0.5]\ndx = 0.05\n";
    let cases = [
        ("unknown", format!("{base}viscosity = 0.1\n"), "viscosity"),
        ("dx", base.replace("dx = 0.05", "dx = -0.05"), "fluid.dx"),
        ("type", base.replace("dx = 0.05", "dx = \"fine\""), "dx"),
        ("cfl", format!("{base}cfl = 2.0\n"), "fluid.cfl"),
        (
            "column",
            base.replace("[0.25, 0.5]", "[0.25]"),
            "fluid.column",
        ),
        ("frames", format!("{base}[run]\nframes = 0\n"), "run.frames"),
        ("syntax", format!("{base}dx = \n"), "malformed.toml"),
    ];
    for (what, text, needle) in cases {
        let path = dir.path().join("malformed.toml");
        std::fs::write(&path, text).unwrap();
        let out = hooke(&["run", path.to_str().unwrap(), "--out", out_dir]);
        let message = stderr(&out);
        assert!(!out.status.success(), "{what}: should fail");
        assert!(!message.contains("panicked"), "{what}: {message}");
        assert!(
            message.contains(needle),
            "{what}: {needle:?} not in {message}"
        );
    }
}

#[test]
fn a_failing_step_is_a_typed_error_after_the_summary() {
    // Gravity upwards (30 m/s²) throws the column out of the open top.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("up.toml");
    std::fs::write(
        &path,
        "[fluid]\ntank = [1.0, 1.0]\ncolumn = [0.25, 0.5]\ndx = 0.05\ngravity = 30.0\n\
         [run]\nduration = 0.5\nframes = 5\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    fails_with(
        &[
            "run",
            path.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
            "-q",
        ],
        &["up: frame", "out of the domain"],
    );
    let summary = read_json(&out_dir.join("summary.json"));
    assert!(!summary["frames"].as_array().unwrap().is_empty());
    assert!(!out_dir.join("preview.png").exists());
}

#[test]
fn bench_sph_prints_a_row_and_writes_json() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("sph.json");
    let plot = dir.path().join("sph.png");
    let out = hooke(&[
        "bench",
        "--sph",
        "2000",
        "--repeats",
        "1",
        "--json",
        json.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
        "-q",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    // round(√2000)² = 2025 particles.
    assert!(
        text.lines().any(|l| l.trim_start().starts_with("2025 ")),
        "{text}"
    );
    let records = read_json(&json);
    let records = records.as_array().unwrap();
    assert_eq!(records.len(), 1);
    for key in [
        "requested",
        "fluid_particles",
        "boundary_particles",
        "steps",
        "threads",
        "ms_per_step",
        "particle_steps_per_s",
        "neighbour_search_ms",
        "density_ms",
        "forces_ms",
        "integration_ms",
    ] {
        assert!(records[0].get(key).is_some(), "record has {key}");
    }
    assert_eq!(records[0]["fluid_particles"], 2025);
    assert!(records[0]["ms_per_step"].as_f64().unwrap() > 0.0);
    assert_eq!(png_size(&plot), (900, 600));

    fails_with(&["bench", "--sph", "1e4,lots"], &["--sph", "lots"]);
}

#[test]
fn a_fluid_run_writes_its_summary_during_the_run() {
    // Halted right after frame 20 (a kill there), the run leaves summary.json with frames 0..=20:
    // it is rewritten every 10 frames, as a spring run's is every 100. dx = 0.2 m: 50 particles.
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args([
            "run",
            "dam-break-2d",
            "--dx",
            "0.2",
            "--steps",
            "25",
            "-q",
            "--out",
        ])
        .arg(dir.path())
        .env("HOOKE_TEST_HALT", "after-frame:20")
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(70), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("halted at after-frame:20"),
        "{}",
        stderr(&out)
    );
    let summary = read_json(&dir.path().join("summary.json"));
    let frames = summary["frames"].as_array().unwrap();
    let numbers: Vec<u64> = frames
        .iter()
        .map(|f| f["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(numbers, (0..=20).collect::<Vec<u64>>());
    assert!(
        !dir.path().join("preview.png").exists(),
        "the run did not finish"
    );
    // Halted at frame 9, before the first rewrite, it leaves no summary at all.
    let early = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args([
            "run",
            "dam-break-2d",
            "--dx",
            "0.2",
            "--steps",
            "25",
            "-q",
            "--out",
        ])
        .arg(early.path())
        .env("HOOKE_TEST_HALT", "after-frame:9")
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(70), "{}", stderr(&out));
    assert!(!early.path().join("summary.json").exists());
}
