//! The `hooke` command end to end: it runs scenes and leaves frames, a summary and a preview.

use std::path::Path;
use std::process::Command;

fn hooke(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the hooke binary runs")
}

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
    assert_eq!(sorted, ["frames", "preview.png", "summary.json"]);

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
        (&["run", "cloth-10", "--substeps", "1"], "stability bound"),
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
    }
}
