//! `hooke mesh tetrahedralize` and `hooke mesh quality`, end to end.

use crate::command::hooke;

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
        // The paper's proven bounds for the thresholds in use (Table 1, "minimum dihedral, safe").
        assert!(report["min_dihedral_deg"].as_f64().unwrap() >= 9.3171);
        assert!(report["max_dihedral_deg"].as_f64().unwrap() <= 161.6432);
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

/// Two cubes sharing a corner, and two overlapping cubes: each refused with a message that names
/// the defect, not as a feature thinner than the spacing.
#[test]
fn bowtie_and_self_intersecting_surfaces_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.vtk");
    let cube = |shift: f64| -> String {
        let mut text = String::new();
        for c in 0..8 {
            text += &format!(
                "v {} {} {}\n",
                (c & 1) as f64 + shift,
                ((c >> 1) & 1) as f64 + shift,
                (c >> 2) as f64 + shift
            );
        }
        text
    };
    let faces = |base: usize| -> String {
        [
            [1, 3, 2],
            [2, 3, 4],
            [5, 6, 7],
            [6, 8, 7],
            [1, 2, 5],
            [2, 6, 5],
            [3, 7, 4],
            [4, 7, 8],
            [1, 5, 3],
            [3, 5, 7],
            [2, 4, 6],
            [4, 8, 6],
        ]
        .iter()
        .map(|f| format!("f {} {} {}\n", f[0] + base, f[1] + base, f[2] + base))
        .collect()
    };
    for (name, shift, defect) in [
        ("bowtie.obj", 1.0, "non-manifold vertex"),
        ("overlap.obj", 0.5, "self-intersecting"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, cube(0.0) + &cube(shift) + &faces(0) + &faces(8)).unwrap();
        let run = hooke(&[
            "mesh",
            "tetrahedralize",
            path.to_str().unwrap(),
            "--spacing",
            "0.1",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!run.status.success());
        let text = String::from_utf8_lossy(&run.stderr);
        assert!(text.contains(defect), "{name}: {text}");
        assert!(!text.contains("thinner"), "{name}: {text}");
    }
}
