//! The `hooke` command guides its user: help texts list what the parsers accept, a mesh file or a
//! fluid scene given where a spring scene is expected is refused with what to do instead, messages
//! name flags and scene keys (never the library's Rust types), the energy watchdog's advice fits
//! the integrator, and input files are checked before any work. Each test runs in about a second.

use crate::command::{fails_with, hooke, stderr, stdout};

use std::path::Path;

use hooke::sim::Integrator;
use hooke_cli::bench::{
    SolverKind, HARD_CASES, HARD_CASE_OVERRIDES, HARD_INTEGRATORS, HARD_SCENES,
};

/// The scene names `hooke scenes` lists, in its order.
fn listed_scenes() -> Vec<String> {
    let out = hooke(&["scenes"]);
    assert!(out.status.success());
    stdout(&out)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect()
}

/// A user-facing message must not show the library's Rust paths (`NewtonParams::max_iterations`).
fn assert_no_rust_names(text: &str) {
    for leak in ["::", "Params", "Settings", "Options"] {
        assert!(!text.contains(leak), "{leak:?} leaks into:\n{text}");
    }
}

#[test]
fn help_texts_list_what_the_parsers_accept() {
    let scenes = listed_scenes();
    assert!(scenes.len() >= 20, "{scenes:?}");
    let run = stdout(&hooke(&["run", "--help"]));
    for integrator in Integrator::ALL {
        assert!(
            run.contains(integrator.name()),
            "`hooke run --help` lists {integrator}:\n{run}"
        );
        // Every name the help shows is one the parser accepts.
        assert_eq!(
            integrator.name().parse::<Integrator>().ok(),
            Some(*integrator)
        );
    }
    for integrator in hooke::sph::Integrator::ALL {
        assert!(
            run.contains(integrator.name()),
            "{}:\n{run}",
            integrator.name()
        );
    }
    for scene in &scenes {
        assert!(
            run.contains(scene.as_str()),
            "`hooke run --help` lists {scene}:\n{run}"
        );
    }
    let bench = stdout(&hooke(&["bench", "--help"]));
    for kind in SolverKind::ALL {
        assert!(
            bench.contains(&format!("{} (", kind.name()))
                || bench.contains(&format!("{}:", kind.name())),
            "`hooke bench --help` lists the spec {}:\n{bench}",
            kind.name()
        );
    }
    for name in HARD_INTEGRATORS.iter().chain(HARD_CASES).chain(HARD_SCENES) {
        assert!(
            bench.contains(name),
            "`hooke bench --help` lists {name}:\n{bench}"
        );
    }
    // Every built-in scene is named by bench's help: as a scene it measures, or where it goes.
    for scene in &scenes {
        assert!(
            bench.contains(scene.as_str()),
            "`hooke bench --help` names {scene}:\n{bench}"
        );
    }
}

#[test]
fn the_hard_case_settings_name_only_flags_that_exist() {
    let help = stdout(&hooke(&["run", "--help"])) + &stdout(&hooke(&["bench", "--help"]));
    let flags: Vec<&str> = HARD_CASE_OVERRIDES
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
        .filter(|w| w.starts_with("--"))
        .collect();
    for flag in &flags {
        assert!(
            help.contains(&format!("{flag} ")),
            "{flag} is not a flag of run or bench"
        );
    }
    assert_no_rust_names(HARD_CASE_OVERRIDES);
}

#[test]
fn a_mesh_file_given_as_a_scene_says_what_to_do() {
    for mesh in [
        "data/meshes/bunny.obj",
        "data/meshes/sphere_tet.msh",
        "data/meshes/armadillo_4k.node",
    ] {
        let quoted = format!("file = \"{mesh}\"");
        for command in [&["run", mesh][..], &["bench", mesh], &["edit", mesh]] {
            let text = fails_with(
                command,
                &["is a mesh file, not a scene", "hooke mesh", &quoted],
            );
            assert!(
                !text.contains("TOML") && !text.contains("expected `=`"),
                "{text}"
            );
        }
    }
    fails_with(
        &["run", "data/meshes/bunny.obj"],
        &["hooke mesh tetrahedralize"],
    );
    fails_with(
        &["run", "data/meshes/sphere_tet.msh"],
        &["hooke mesh quality"],
    );
}

#[test]
fn every_listed_scene_is_taken_or_refused_with_the_reason() {
    let fluid: Vec<&str> = hooke::sph::scenes::BUILTIN.iter().map(|s| s.0).collect();
    for scene in listed_scenes() {
        let out = hooke(&[
            "edit",
            &scene,
            "--replay",
            "/nonexistent/events.json",
            "--frames",
            "/nonexistent",
        ]);
        let text = stderr(&out);
        assert!(
            !out.status.success() && !text.contains("panicked"),
            "{scene}: {text}"
        );
        if scene == "seed-2d" {
            // Opened: what fails is the missing event script.
            assert!(text.contains("events.json"), "{scene}: {text}");
        } else if fluid.contains(&scene.as_str()) {
            assert!(
                text.contains("is a fluid scene") && text.contains("hooke run"),
                "{text}"
            );
        } else {
            assert!(
                text.contains("is a built-in 3D scene") && text.contains("2D"),
                "{text}"
            );
        }
        assert!(!text.contains("not a built-in scene"), "{scene}: {text}");
    }
    for scene in &fluid {
        fails_with(
            &["bench", scene],
            &["is a fluid scene", &format!("hooke bench --sph {scene}")],
        );
    }
    fails_with(&["bench", "seed-2d"], &["seed-2d", "3D"]);
    fails_with(&["bench", "cloth-drape-20"], &["cannot measure", "contact"]);
}

#[test]
fn solver_messages_name_flags_and_keys_not_rust_fields() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (args, flag) in [
        (
            &["--integrator", "newton", "--iterations", "0"][..],
            "--iterations",
        ),
        (&["--integrator", "pd", "--iterations", "0"], "--iterations"),
        (&["--integrator", "pd", "--tolerance", "-1"], "--tolerance"),
        (
            &["--integrator", "lbfgs", "--tolerance", "NaN"],
            "--tolerance",
        ),
        (
            &["--integrator", "newton-cg", "--iterations", "0"],
            "--iterations",
        ),
        (
            &["--integrator", "pd-chebyshev", "--iterations", "0"],
            "--iterations",
        ),
    ] {
        let mut command = vec!["run", "cloth-10", "--steps", "1", "--out", out];
        command.extend_from_slice(args);
        let text = fails_with(&command, &[flag]);
        assert_no_rust_names(&text);
    }
    // A scene file's key is named as the file has it.
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        "[mesh]\ngenerator = \"cloth\"\nn = 4\nstiffness = 1e3\n\n[integrator]\nmethod = \"newton\"\n\
         time_step = 0.01\niterations = 0\n\n[run]\nsteps = 1\n",
    )
    .unwrap();
    let text = fails_with(
        &["run", scene.to_str().unwrap(), "--out", out],
        &["integrator.iterations"],
    );
    assert_no_rust_names(&text);
}

#[test]
fn the_energy_watchdog_advises_what_helps_the_integrator() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    // With a limit of 0 any rise of the energy stops the run: symplectic Euler's oscillating energy
    // does within a second of cloth-10, and so does PD with a single iteration per step.
    let explicit = fails_with(
        &[
            "run",
            "cloth-10",
            "--integrator",
            "symplectic-euler",
            "--energy-limit",
            "0",
            "--steps",
            "30",
            "--out",
            out,
            "-q",
        ],
        &["unstable", "--substeps", "--integrator newton"],
    );
    assert!(!explicit.contains("--iterations"), "{explicit}");
    let pd = fails_with(
        &[
            "run",
            "cloth-10",
            "--integrator",
            "pd",
            "--iterations",
            "1",
            "--energy-limit",
            "0",
            "--steps",
            "30",
            "--out",
            out,
            "-q",
        ],
        &["unstable", "--iterations", "--dt"],
    );
    assert!(!pd.contains("--substeps"), "{pd}");
    assert!(!pd.contains("--integrator pd"), "{pd}");
}

#[test]
fn a_bad_compare_file_fails_before_the_benchmark_runs() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("report.json");
    let malformed = dir.path().join("theirs.csv");
    std::fs::write(&malformed, "scene,solver\ncloth-10,pd\n").unwrap();
    let missing = dir.path().join("missing.csv");
    for (compare, needle) in [(&missing, "missing.csv"), (&malformed, "theirs.csv")] {
        let start = std::time::Instant::now();
        let out = hooke(&[
            "bench",
            "cloth-10",
            "--solver",
            "pd:1",
            "--repeats",
            "1",
            "--no-cache",
            "--json",
            json.to_str().unwrap(),
            "--compare",
            compare.to_str().unwrap(),
        ]);
        let text = stderr(&out);
        assert!(!out.status.success(), "{text}");
        assert!(text.contains(needle), "{text}");
        // Nothing was measured: no table, no progress line of the state's steps, no records.
        assert!(stdout(&out).is_empty(), "{}", stdout(&out));
        assert!(!text.contains("speed-vs-error"), "{text}");
        assert!(!Path::new(&json).exists());
        eprintln!(
            "{}: refused after {:.2} s",
            compare.display(),
            start.elapsed().as_secs_f64()
        );
    }
}
