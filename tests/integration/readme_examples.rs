//! The README's library examples are the examples' own code, not copies that drift: each
//! example's lines between `// README: begin` and `// README: end` are one of README.md's code
//! blocks, verbatim (the examples compile and run under `cargo test`, so the README's blocks do:
//! they are not doc tests as well). The README's scene-file example is loaded and run as it stands.

/// The code blocks of `markdown` (the lines between a fence line starting with ``` and the next).
fn code_blocks(markdown: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut current: Option<Vec<&str>> = None;
    for line in markdown.lines() {
        match (&mut current, line.starts_with("```")) {
            (None, true) => current = Some(Vec::new()),
            (Some(lines), true) => {
                blocks.push(lines.join("\n"));
                current = None;
            }
            (Some(lines), false) => lines.push(line),
            (None, false) => {}
        }
    }
    blocks
}

#[test]
fn the_readme_shows_each_example_verbatim() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let blocks = code_blocks(&readme);
    for example in [
        "hanging_cloth",
        "cloth_newton",
        "solid_from_surface",
        "finite_difference_user_energy",
        "fluid_dam_break",
    ] {
        let path = root.join(format!("examples/{example}.rs"));
        let text = std::fs::read_to_string(&path).unwrap();
        let shown: Vec<&str> = text
            .lines()
            .skip_while(|l| *l != "// README: begin")
            .skip(1)
            .take_while(|l| *l != "// README: end")
            .collect();
        assert!(shown.len() > 10, "{}: no README part", path.display());
        let shown = shown.join("\n");
        assert!(
            blocks.contains(&shown),
            "README.md has no code block equal to the README part of {}:\n{shown}",
            path.display()
        );
        assert!(
            readme.contains(&format!("examples/{example}.rs")),
            "README.md names examples/{example}.rs"
        );
    }
}

/// The README's scene-file example ("## Scene files"), verbatim: its first code block after that
/// heading.
fn readme_scene_file() -> String {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let section = &readme[readme
        .find("\n## Scene files\n")
        .expect("README.md has a section \"## Scene files\"")..];
    let block = code_blocks(section).into_iter().next().unwrap();
    assert!(
        block.starts_with("name = "),
        "the first block of \"## Scene files\" is not the scene file:\n{block}"
    );
    block
}

/// The README's scene-file example runs wherever it is saved: written alone into a fresh
/// directory (no mesh file beside it), it loads, has self-contact on under Newton, and its first
/// frames step with the surface free of self-intersections (3 frames instead of its 60, so that
/// the test stays short in the dev profile). It shows every section of a scene file, active or
/// commented.
#[test]
fn the_readme_scene_file_runs_anywhere_with_self_contact() {
    use hooke::mesh::intersection::intersecting_triangle_pairs;
    use hooke::sim::file::load_scene;
    use hooke::sim::scenes::AnySetup;
    use hooke::sim::{Integrator, Simulation};

    let text = readme_scene_file();
    for section in [
        "[mesh]",
        "[pins]",
        "[forces]",
        "[damping]",
        "[[contact]]",
        "[barrier]",
        "[self_contact]",
        "[initial]",
        "[integrator]",
        "[run]",
        "[output]",
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start_matches("# ").starts_with(section)),
            "the README's scene file does not show {section}:\n{text}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("my-cloth.toml");
    std::fs::write(&path, &text).unwrap();
    let file = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
    let AnySetup::Three(setup) = file.setup else {
        panic!("the README's scene is 3D");
    };
    assert!(setup.scene.self_contact().is_some(), "self-contact is off");
    assert!(
        setup.settings.integrator.uses_contact_barrier(),
        "{} does not model self-contact",
        setup.settings.integrator
    );
    assert_eq!(setup.settings.integrator, Integrator::Newton);
    assert!(setup.steps >= 3, "{} steps", setup.steps);
    let triangles = setup.scene.surface_triangles();
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    for frame in 1..=3 {
        let report = sim.step().unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        assert_eq!(report.converged, Some(true), "frame {frame}");
        assert!(
            sim.self_contact_state().is_some(),
            "frame {frame}: no self-contact state"
        );
        let pairs = intersecting_triangle_pairs(&sim.state().positions, &triangles).unwrap();
        assert!(pairs.is_empty(), "frame {frame}: {pairs:?} intersect");
    }
}
