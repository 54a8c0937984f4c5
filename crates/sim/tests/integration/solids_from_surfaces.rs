//! The built-in solids from surfaces (docs/scenes.md §4) and the scene-file key
//! `fill = { spacing = … }`.

use hooke_sim::file::parse_scene;
use hooke_sim::scenes::{builtin, AnySetup, SOLID_DIAGONAL};

fn three(name: &str) -> hooke_sim::scenes::Setup<3> {
    match builtin(name).expect("a built-in scene").expect("builds") {
        AnySetup::Three(s) => s,
        AnySetup::Two(_) => panic!("{name} is 3D"),
    }
}

#[test]
fn bunny_drop_is_built_as_written() {
    let setup = three("bunny-drop");
    let positions = setup.scene.mesh().positions();
    let (mut lo, mut hi) = (positions[0], positions[0]);
    for p in positions {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    // The filled solid's box is the surface's, up to the bevelling of its extremes by less than a
    // lattice spacing (1/30 of the diagonal).
    let diagonal = (hi - lo).norm();
    assert!(
        (diagonal - SOLID_DIAGONAL).abs() < SOLID_DIAGONAL / 30.0,
        "diagonal {diagonal}"
    );
    assert!((lo.y - 0.2).abs() < 0.01, "lowest point at {}", lo.y);
    assert_eq!(setup.steps, 60);
    let mass: f64 = setup.scene.mesh().total_mass();
    assert!(
        mass > 0.5 && mass < 5.0,
        "a 0.3 m bunny of water weighs a few kg, not {mass}"
    );
}

#[test]
fn torus_hang_pins_a_few_top_vertices() {
    let setup = three("torus-hang");
    let positions = setup.scene.mesh().positions();
    let top = positions
        .iter()
        .map(|p| p.y)
        .fold(f64::NEG_INFINITY, f64::max);
    let pinned = setup.scene.pinned();
    assert!(
        !pinned.is_empty() && pinned.len() < positions.len() / 10,
        "{} pinned",
        pinned.len()
    );
    for &v in pinned {
        // Within 2 % of the height (0.3 m diagonal of a 3:1:3 box: about 0.21 m tall) of the top.
        assert!(
            top - positions[v as usize].y < 0.02 * 0.22,
            "vertex {v} pinned too low"
        );
    }
}

fn scene_with(mesh: &str) -> Result<hooke_sim::file::SceneFile, hooke_sim::file::SceneFileError> {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes");
    let text = format!(
        "[mesh]\n{mesh}\n[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n[run]\nsteps = 2\n"
    );
    parse_scene(&text, &dir.join("scene.toml"))
}

#[test]
fn fill_key_builds_a_solid_and_bad_values_are_refused() {
    let ok = scene_with("file = \"sphere_642.obj\"\nfill = { spacing = 0.2 }\nstiffness = 1e4\nmass = { density = 1000.0 }");
    match ok {
        Ok(file) => match file.setup {
            AnySetup::Three(s) => assert!(!s.scene.mesh().tetrahedra().is_empty()),
            AnySetup::Two(_) => panic!("3D"),
        },
        Err(e) => panic!("{e}"),
    }
    for bad in [
        "file = \"sphere_642.obj\"\nfill = { spacing = -1.0 }\nstiffness = 1e4\nmass = { density = 1000.0 }",
        "file = \"cloth_30x30.obj\"\nfill = { spacing = 0.1 }\nstiffness = 1e4\nmass = { density = 1000.0 }",
        "file = \"sphere_tet.msh\"\nfill = { spacing = 0.1 }\nstiffness = 1e4\nmass = { density = 1000.0 }",
    ] {
        match scene_with(bad) {
            Err(e) => assert!(e.to_string().contains("mesh.fill"), "{e}"),
            Ok(_) => panic!("accepted {bad:?}"),
        }
    }
}
