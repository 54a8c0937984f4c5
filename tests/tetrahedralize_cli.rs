//! `hooke mesh tetrahedralize` and `hooke mesh quality`, end to end.

use std::process::Command;

fn hooke(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the hooke binary runs")
}

#[test]
fn tetrahedralize_writes_every_format_and_the_json_report() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("report.json");
    for name in ["sphere.vtk", "sphere.node", "sphere.msh"] {
        let out = dir.path().join(name);
        let run = hooke(&[
            "mesh",
            "tetrahedralize",
            "data/meshes/sphere_642.obj",
            "--spacing",
            "0.2",
            "--out",
            out.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        for key in [
            "tets",
            "vertices",
            "min_dihedral_deg",
            "max_dihedral_deg",
            "min_radius_ratio",
            "volume",
            "surface_volume",
            "hausdorff",
            "seconds",
        ] {
            assert!(report.get(key).is_some(), "{key} missing from {report}");
        }
        assert!(report["min_dihedral_deg"].as_f64().unwrap() >= 10.7);
        assert!(report["max_dihedral_deg"].as_f64().unwrap() <= 164.8);
        // The written mesh reads back with the same numbers.
        let quality = hooke(&[
            "mesh",
            "quality",
            out.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(
            quality.status.success(),
            "{}",
            String::from_utf8_lossy(&quality.stderr)
        );
        let again: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(again["tets"], report["tets"]);
        assert_eq!(again["vertices"], report["vertices"]);
    }
    assert!(dir.path().join("sphere.ele").exists());
}

#[test]
fn open_surface_and_bad_spacing_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.vtk");
    let open = hooke(&[
        "mesh",
        "tetrahedralize",
        "data/meshes/cloth_30x30.obj",
        "--spacing",
        "0.1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!open.status.success());
    let text = String::from_utf8_lossy(&open.stderr);
    assert!(text.contains("open") && text.contains("edge"), "{text}");
    let bad = hooke(&[
        "mesh",
        "tetrahedralize",
        "data/meshes/sphere_642.obj",
        "--spacing",
        "-1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("spacing"));
    assert!(!out.exists(), "no output on failure");
}
