//! The canonical scenes, scene files and explicit integration, end to end.

use std::path::Path;

use hooke::sim::file::{load_scene, parse_scene, SceneFileError};
use hooke::sim::scenes::{self, AnySetup, Setup};
use hooke::sim::{Contact, Integrator, Shape, SimError, Simulation};
use nalgebra::Vector3;

fn run<const D: usize>(setup: Setup<D>, frames: usize) -> Result<Simulation<D>, SimError> {
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings)?;
    for _ in 0..frames {
        sim.step()?;
    }
    Ok(sim)
}

fn all_finite<const D: usize>(sim: &Simulation<D>) -> bool {
    let s = sim.state();
    s.positions
        .iter()
        .chain(&s.velocities)
        .all(|v| v.iter().all(|c| c.is_finite()))
}

#[test]
fn every_canonical_scene_runs_a_few_frames_without_nan() {
    for name in [
        "cloth-10",
        "cloth-10-stiff",
        "cloth-20",
        "beam-2",
        "seed-2d",
    ] {
        for integrator in [Integrator::SymplecticEuler, Integrator::ExplicitEuler] {
            let setup = scenes::builtin(name)
                .expect("a built-in name")
                .expect("builds");
            // Symplectic Euler must run; forward Euler may refuse up front (it is unstable for
            // undamped springs and would need too many substeps), but must not blow up.
            let may_refuse = integrator == Integrator::ExplicitEuler;
            let outcome = match setup {
                AnySetup::Two(mut s) => {
                    s.settings.integrator = integrator;
                    run(s, 3).map(|sim| (all_finite(&sim), sim.energy().total))
                }
                AnySetup::Three(mut s) => {
                    s.settings.integrator = integrator;
                    run(s, 3).map(|sim| (all_finite(&sim), sim.energy().total))
                }
            };
            match outcome {
                Ok((finite, energy)) => {
                    assert!(finite, "{name} with {integrator}: non-finite state");
                    assert!(
                        energy.is_finite(),
                        "{name} with {integrator}: energy {energy}"
                    );
                }
                Err(SimError::InvalidParameter {
                    name: parameter, ..
                }) if may_refuse && parameter == "substeps" => {}
                Err(e) => panic!("{name} with {integrator}: {e}"),
            }
        }
    }
}

#[test]
fn symplectic_euler_keeps_the_energy_of_an_undamped_run() {
    // cloth-10 soft, undamped, gravity only: total energy (kinetic + elastic + gravity) is conserved by
    // the exact flow. Symplectic Euler conserves a modified energy that differs from it by O(h ω E);
    // at 4× the automatic substeps (h ω ≈ 0.5 on the stiffest mode) the deviation stays within 0.5 % of
    // the largest kinetic energy of the run (measured: 0.06 %; the margin covers other platforms'
    // rounding, not a different behaviour), and it does not drift.
    let mut setup = scenes::cloth(10, false).unwrap();
    setup.settings.integrator = Integrator::SymplecticEuler;
    let auto = Simulation::new(setup.scene.clone(), setup.initial.clone(), setup.settings)
        .unwrap()
        .substeps();
    setup.settings.substeps = Some(4 * auto);
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    let e0 = sim.energy().total;
    let mut deviations = Vec::new();
    let mut max_kinetic: f64 = 0.0;
    for _ in 1..=30 {
        sim.step().unwrap();
        let e = sim.energy();
        deviations.push((e.total - e0).abs());
        max_kinetic = max_kinetic.max(e.kinetic);
    }
    assert!(
        max_kinetic > 1e-3,
        "the cloth should have swung: kinetic energy {max_kinetic} J"
    );
    // The run's energy scale is the largest kinetic energy it reaches (the potential energy that
    // gravity released).
    let (frame, worst) = deviations
        .iter()
        .copied()
        .enumerate()
        .fold(
            (0, 0.0f64),
            |a, (k, d)| if d > a.1 { (k + 1, d) } else { a },
        );
    assert!(
        worst <= 0.005 * max_kinetic,
        "frame {frame}: total energy moved {worst} J from {e0} J (largest kinetic energy {max_kinetic} J)"
    );
    eprintln!(
        "largest energy deviation {worst:.3e} J (frame {frame}) = {:.3} % of the largest kinetic energy",
        100.0 * worst / max_kinetic
    );
}

#[test]
fn pinned_vertices_stay_and_the_cloth_falls() {
    let setup = scenes::cloth(10, false).unwrap();
    let start = setup.initial.positions.clone();
    let sim = run(setup, 10).unwrap();
    let x = &sim.state().positions;
    assert_eq!(x[0], start[0], "vertex 0 is pinned");
    assert_eq!(x[9], start[9], "vertex N−1 is pinned");
    let lowest = x.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    assert!(
        lowest < -0.3,
        "after 1/3 s the free edge should have fallen: lowest y = {lowest}"
    );
    assert!(
        (sim.state().time - 10.0 / 30.0).abs() < 1e-15,
        "frame times are exact multiples of h"
    );
}

#[test]
fn seed_2d_particles_fall_springs_hold_walls_stop_them() {
    let file = load_scene(Path::new("data/scenes/seed-2d.toml")).unwrap();
    let AnySetup::Two(setup) = file.setup else {
        panic!("seed-2d is 2D")
    };
    let scene = setup.scene.clone();
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    let y0: f64 = sim.state().positions.iter().map(|p| p.y).sum::<f64>() / 3.0;
    for frame in 1..=300 {
        sim.step().unwrap();
        for (v, p) in sim.state().positions.iter().enumerate() {
            assert!(
                (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y),
                "frame {frame}: particle {v} left the box at {p:?}"
            );
        }
        let stretch = scene.max_stretch(sim.state());
        assert!(
            stretch < 2.0,
            "frame {frame}: a spring stretched {stretch}× its rest length"
        );
    }
    let y: f64 = sim.state().positions.iter().map(|p| p.y).sum::<f64>() / 3.0;
    assert!(y < y0 - 0.2, "the particles fell: mean height {y0} → {y}");
    let lowest = sim
        .state()
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f64::INFINITY, f64::min);
    assert!(
        lowest.abs() < 1e-12,
        "resting on the floor: lowest y = {lowest}"
    );
    let speed = sim
        .state()
        .velocities
        .iter()
        .map(|v| v.norm())
        .fold(0.0, f64::max);
    assert!(
        speed < 0.05,
        "drag and dashpot bring them to rest: fastest {speed} m/s after 3 s"
    );
}

#[test]
fn scene_files_equal_the_built_in_scenes() {
    for name in ["cloth-40", "cloth-40-stiff", "beam-4", "seed-2d"] {
        let path = format!("data/scenes/{name}.toml");
        let from_file = load_scene(Path::new(&path))
            .unwrap_or_else(|e| panic!("{e}"))
            .setup;
        let built_in = scenes::builtin(name).unwrap().unwrap();
        assert!(
            from_file == built_in,
            "{path} differs from the built-in {name}"
        );
    }
}

fn file_error(text: &str) -> String {
    match parse_scene(text, Path::new("bad.toml")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            let message = e.to_string();
            assert!(
                message.contains("bad.toml"),
                "the error names the file: {message}"
            );
            message
        }
    }
}

const GOOD: &str = r#"
[mesh]
generator = "cloth"
n = 5
stiffness = 100.0
[pins]
vertices = [0, 4]
[forces]
gravity = [0.0, -9.81, 0.0]
[integrator]
method = "symplectic-euler"
time_step = 0.01
[run]
steps = 2
"#;

#[test]
fn bad_scene_files_name_the_key_and_the_reason() {
    assert!(parse_scene(GOOD, Path::new("good.toml")).is_ok());
    let cases: &[(&str, &str, &str)] = &[
        ("stiffness = 100.0", "stiffness = -5.0", "stiffness"),
        (
            "stiffness = 100.0",
            "stiffness = 100.0\ncolour = 3",
            "colour",
        ),
        ("n = 5", "n = \"five\"", "n"),
        (
            "gravity = [0.0, -9.81, 0.0]",
            "gravity = [0.0, -9.81]",
            "forces.gravity",
        ),
        ("vertices = [0, 4]", "vertices = [0, 99]", "pins.vertices"),
        (
            "vertices = [0, 4]",
            "region = { min = [-1.0, -1.0, -1.0], max = [2.0, 2.0, 2.0] }",
            "pins.region",
        ),
        (
            "time_step = 0.01",
            "time_step = 0.0",
            "integrator.time_step",
        ),
        (
            "time_step = 0.01",
            "time_step = nan",
            "integrator.time_step",
        ),
        (
            "method = \"symplectic-euler\"",
            "method = \"runge-kutta\"",
            "integrator.method",
        ),
        (
            "generator = \"cloth\"",
            "generator = \"torus\"",
            "mesh.generator",
        ),
        ("steps = 2", "steps = 0", "run.steps"),
    ];
    for (from, to, key) in cases {
        assert!(GOOD.contains(from), "test case {from:?}");
        let message = file_error(&GOOD.replace(from, to));
        assert!(
            message.contains(key),
            "error for {to:?} should name {key:?}: {message}"
        );
    }
    // Everything pinned is refused with its own message.
    let message = file_error(&GOOD.replace(
        "vertices = [0, 4]",
        "region = { min = [-1.0, -1.0, -1.0], max = [2.0, 2.0, 2.0] }",
    ));
    assert!(message.contains("all 25 vertices are pinned"), "{message}");
    // A missing file is an I/O error naming it.
    assert!(matches!(
        load_scene(Path::new("no/such/scene.toml")),
        Err(SceneFileError::Io { .. })
    ));
}

#[test]
fn scene_files_read_meshes_relative_to_themselves() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/meshes");
    let text = format!(
        r#"
[mesh]
file = "{}/cloth_30x30.obj"
stiffness = 500.0
bending = "interior-edges"
mass = {{ total = 0.5 }}
[pins]
region = {{ min = [-0.01, -1.0, -0.51], max = [0.01, 1.0, 0.51] }}
[forces]
gravity = [0.0, -9.81, 0.0]
wind = {{ velocity = [0.0, 0.0, 2.0], coefficient = 0.001 }}
[damping]
viscous = 0.0005
[[contact]]
shape = "sphere"
center = [0.5, -0.6, 0.0]
radius = 0.3
friction = 0.2
[integrator]
method = "symplectic-euler"
time_step = 0.01
[run]
steps = 3
"#,
        meshes.display()
    );
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let AnySetup::Three(setup) = load_scene(&path).unwrap_or_else(|e| panic!("{e}")).setup else {
        panic!("a 3D scene")
    };
    assert_eq!(setup.scene.mesh().vertex_count(), 961);
    assert!((setup.scene.mesh().total_mass() - 0.5).abs() < 1e-12);
    assert!(!setup.scene.pinned().is_empty());
    let sim = run(setup, 3).unwrap();
    assert!(all_finite(&sim));
}

#[test]
fn explicit_steps_above_the_bound_are_refused_unless_forced() {
    let mut setup = scenes::cloth(10, true).unwrap();
    setup.settings.integrator = Integrator::SymplecticEuler;
    setup.settings.substeps = Some(1);
    match Simulation::new(setup.scene.clone(), setup.initial.clone(), setup.settings) {
        Err(SimError::UnstableStep {
            suggested_substeps, ..
        }) => assert!(suggested_substeps > 1),
        other => panic!("expected UnstableStep, got {other:?}"),
    }
    // Forced, it blows up, and says so instead of returning huge numbers or NaN.
    setup.settings.allow_unstable = true;
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    let mut outcome = Ok(());
    for _ in 0..200 {
        if let Err(e) = sim.step() {
            outcome = Err(e);
            break;
        }
    }
    assert!(
        matches!(
            outcome,
            Err(SimError::Diverged { .. } | SimError::NonFinite { .. })
        ),
        "an unstable explicit run must end in a Diverged error, got {outcome:?}"
    );
}

#[test]
fn contact_keeps_the_cloth_out_of_the_ground_and_the_sphere() {
    // Symplectic Euler with substeps, each vertex projected on its own after every substep; the
    // implicit integrators' projection of the whole mesh is tested below.
    let mut setup = scenes::cloth(12, false).unwrap();
    setup.settings.integrator = Integrator::SymplecticEuler;
    let ground = -0.5;
    let scene = setup
        .scene
        .with_contacts(vec![
            Contact::new(Shape::Plane {
                point: Vector3::new(0.0, ground, 0.0),
                normal: Vector3::y(),
            }),
            Contact::new(Shape::Sphere {
                center: Vector3::new(0.6, -0.35, 0.5),
                radius: 0.15,
            }),
        ])
        .unwrap();
    let mut sim = Simulation::new(scene, setup.initial, setup.settings).unwrap();
    for frame in 1..=45 {
        sim.step().unwrap();
        for (v, p) in sim.state().positions.iter().enumerate() {
            assert!(
                p.y >= ground,
                "frame {frame}: vertex {v} below the ground at {p:?}"
            );
            let d = (p - Vector3::new(0.6, -0.35, 0.5)).norm();
            assert!(
                d >= 0.15 * (1.0 - 1e-12),
                "frame {frame}: vertex {v} inside the sphere ({d} m from its centre)"
            );
        }
    }
}

#[test]
fn newton_on_a_contact_scene_keeps_the_energy_bounded() {
    // cloth-12 swinging onto a sphere and the ground under Newton (the default) at h = 1/30 s: a
    // frame moves vertices up to 0.1 m into the sphere of radius 0.15 m. Projecting each vertex on
    // its own stored that much stretch in its springs (measured: +15.6 J at frame 7, +105.5 J at
    // frame 8, from E₀ = 0 J). Projecting the mesh (the `contact` module) keeps the energy within
    // 1.57 J of E₀ (frame 8, measured; the linearisation of the contact-constrained step about the
    // unconstrained one). The bound is 0.15 M|g|L = 2.08 J, 15 % of the energy scale of the
    // watchdog (M = 1 kg, |g| = 9.81 m/s², L = √2 m), 50 times below what the per-vertex projection
    // gained. The run must also end below E₀ (backward Euler and inelastic contact dissipate).
    let setup = scenes::cloth(12, false).unwrap();
    assert_eq!(setup.settings.integrator, Integrator::Newton);
    let ground = -0.5;
    let center = Vector3::new(0.6, -0.35, 0.5);
    let radius = 0.15;
    let scene = setup
        .scene
        .with_contacts(vec![
            Contact::new(Shape::Plane {
                point: Vector3::new(0.0, ground, 0.0),
                normal: Vector3::y(),
            }),
            Contact::new(Shape::Sphere { center, radius }),
        ])
        .unwrap();
    let pinned: Vec<usize> = scene.pinned().iter().map(|&v| v as usize).collect();
    let pins_at_start: Vec<_> = pinned.iter().map(|&v| setup.initial.positions[v]).collect();
    let mut sim = Simulation::new(scene, setup.initial, setup.settings).unwrap();
    let initial = sim.energy().total;
    let bound = 0.15 * 1.0 * 9.81 * 2f64.sqrt();
    let mut touched_sphere = false;
    let mut highest = f64::NEG_INFINITY;
    for frame in 1..=45 {
        sim.step()
            .unwrap_or_else(|e| panic!("frame {frame}: the contact run failed: {e}"));
        let energy = sim.energy().total;
        highest = highest.max(energy - initial);
        assert!(
            energy <= initial + bound,
            "frame {frame}: energy {energy:.4} J, more than {bound:.2} J above the initial \
             {initial:.4} J"
        );
        let positions = &sim.state().positions;
        for (v, p) in positions.iter().enumerate() {
            let d = (p - center).norm();
            assert!(
                p.y >= ground && d >= radius * (1.0 - 1e-12),
                "frame {frame}: vertex {v} inside an obstacle at {p:?} ({d} m from the centre)"
            );
            // Vertices in contact end on the sphere's tangent planes, just outside it.
            touched_sphere |= d < radius + 0.005;
        }
        for (&v, start) in pinned.iter().zip(&pins_at_start) {
            assert_eq!(
                positions[v], *start,
                "frame {frame}: pinned vertex {v} moved"
            );
        }
    }
    assert!(touched_sphere, "the cloth never reached the sphere");
    let last = sim.energy().total;
    assert!(
        last < initial,
        "the run ends at {last:.4} J, not below the initial {initial:.4} J (highest gain \
         {highest:.3} J)"
    );
}

#[test]
fn parallel_and_serial_runs_are_identical() {
    // cloth-70 has 29,202 springs, above the parallel threshold.
    let a = scenes::cloth(70, false).unwrap();
    let mut b = a.clone();
    b.settings.parallel = false;
    let (a, b) = (run(a, 1).unwrap(), run(b, 1).unwrap());
    assert!(a.state() == b.state(), "parallel and serial states differ");
}

/// The ready-made files of cloth-drape-40 and cloth-fall-40 (which place the cloth with
/// `mesh.transform` and, for the fall, start it with `initial.velocity`) build the built-in scenes:
/// positions, velocities, contacts, frames and h, and then the whole setup.
#[test]
fn drape_and_fall_files_build_the_built_in_scenes() {
    for name in ["cloth-drape-40", "cloth-fall-40"] {
        let path = format!("data/scenes/{name}.toml");
        let AnySetup::Three(file) = load_scene(Path::new(&path))
            .unwrap_or_else(|e| panic!("{e}"))
            .setup
        else {
            panic!("{path}: a 3D scene")
        };
        let Some(Ok(AnySetup::Three(built_in))) = scenes::builtin(name) else {
            panic!("{name} is built in")
        };
        assert_eq!(file.initial.positions, built_in.initial.positions, "{path}");
        assert_eq!(
            file.initial.velocities, built_in.initial.velocities,
            "{path}"
        );
        assert_eq!(file.scene.contacts(), built_in.scene.contacts(), "{path}");
        assert_eq!(file.steps, built_in.steps, "{path}");
        assert_eq!(file.scene.time_step(), built_in.scene.time_step(), "{path}");
        assert!(file.scene.pinned().is_empty(), "{path} pins nothing");
        assert!(file == built_in, "{path} differs from the built-in {name}");
    }
}

/// The drape and fall scenes are as their documentation defines them.
#[test]
fn drape_and_fall_scenes_are_as_defined() {
    let drape = scenes::cloth_drape(20).unwrap();
    let mesh = drape.scene.mesh();
    assert_eq!(mesh.vertex_count(), 400);
    // Vertex (i, j) at x = i/(N−1), z = j/(N−1), lifted to y = 0.3.
    assert_eq!(mesh.positions()[19], Vector3::new(0.0, 0.3, 1.0));
    assert_eq!(mesh.positions()[20], Vector3::new(1.0 / 19.0, 0.3, 0.0));
    assert!((mesh.total_mass() - 1.0).abs() < 1e-12);
    assert!(mesh.springs().iter().all(|s| s.stiffness == 1e3));
    assert!(drape.scene.pinned().is_empty());
    assert!(drape
        .initial
        .velocities
        .iter()
        .all(|v| *v == Vector3::zeros()));
    assert_eq!(
        drape.scene.contacts(),
        &[
            Contact {
                shape: Shape::Sphere {
                    center: Vector3::new(0.5, 0.0, 0.5),
                    radius: 0.25
                },
                friction: 0.1
            },
            Contact {
                shape: Shape::Plane {
                    point: Vector3::new(0.0, -0.3, 0.0),
                    normal: Vector3::y()
                },
                friction: 0.1
            },
        ]
    );
    assert_eq!(
        drape.scene.forces().gravity(),
        Some(Vector3::new(0.0, -9.81, 0.0))
    );
    assert_eq!((drape.steps, drape.scene.time_step()), (60, 1.0 / 30.0));
    assert_eq!(drape.settings.integrator, Integrator::Newton);

    let fall = scenes::cloth_fall(20).unwrap();
    assert!(fall.scene.mesh().positions().iter().all(|p| p.y == 0.5));
    assert!(fall.scene.pinned().is_empty());
    assert!(fall
        .initial
        .velocities
        .iter()
        .all(|v| *v == Vector3::new(0.0, -5.0, 0.0)));
    assert_eq!(
        fall.scene.contacts(),
        &[Contact {
            shape: Shape::Plane {
                point: Vector3::zeros(),
                normal: Vector3::y()
            },
            friction: 0.3
        }]
    );
    assert_eq!((fall.steps, fall.scene.time_step()), (30, 1.0 / 30.0));
    assert_eq!(fall.settings.integrator, Integrator::Newton);

    // By name, any N ≥ 2 like cloth-N.
    for (name, vertices) in [("cloth-drape-3", 9), ("cloth-fall-5", 25)] {
        let Some(Ok(AnySetup::Three(s))) = scenes::builtin(name) else {
            panic!("{name}")
        };
        assert_eq!(
            (s.name.as_str(), s.scene.mesh().vertex_count()),
            (name, vertices)
        );
    }
    assert!(matches!(scenes::builtin("cloth-drape-1"), Some(Err(_))));
    assert!(scenes::builtin("cloth-drape-x").is_none());
    let listed: Vec<String> = scenes::builtin_scenes()
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    for n in [20, 40, 80] {
        for kind in ["drape", "fall"] {
            let name = format!("cloth-{kind}-{n}");
            assert!(listed.contains(&name), "{name} is listed");
            assert!(scenes::builtin(&name).is_some(), "{name} builds by name");
        }
    }
}

/// `scenes::builtin_has_contact`, which help texts use to tell the contact scenes apart without
/// building them, agrees with every listed scene as built.
#[test]
fn builtin_has_contact_agrees_with_the_built_scenes() {
    for (name, _) in scenes::builtin_scenes() {
        let has_contact = match scenes::builtin(&name).expect("listed").expect("builds") {
            scenes::AnySetup::Two(s) => !s.scene.contacts().is_empty(),
            scenes::AnySetup::Three(s) => !s.scene.contacts().is_empty(),
        };
        assert_eq!(scenes::builtin_has_contact(&name), has_contact, "{name}");
    }
}

/// A file mesh is placed by `mesh.transform` before springs, masses and pins are made: the
/// 30×30 cloth file scaled by 2 about the origin and lifted by 1 m keeps its spring count, has
/// springs twice as long, and its pin region is found where the transform put it.
#[test]
fn a_file_mesh_is_placed_by_its_transform() {
    let meshes = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/meshes");
    let text = |transform: &str, region: &str| {
        format!(
            "[mesh]\nfile = \"{}/cloth_30x30.obj\"\nstiffness = 500.0\nmass = {{ total = 0.5 }}\n\
             {transform}\n[pins]\nregion = {region}\n[integrator]\nmethod = \"newton\"\n\
             time_step = 0.01\n[run]\nsteps = 1\n",
            meshes.display()
        )
    };
    let load = |text: String| match parse_scene(&text, Path::new("placed.toml")) {
        Ok(file) => match file.setup {
            AnySetup::Three(s) => Ok(s),
            AnySetup::Two(_) => panic!("a 3D scene"),
        },
        Err(e) => Err(e.to_string()),
    };
    let edge = "{ min = [-0.01, -1.0, -0.51], max = [0.01, 1.0, 0.51] }";
    let plain = load(text("", edge)).unwrap();
    let placed = load(text(
        "transform = { scale = 2.0, translate = [0.0, 1.0, 0.0] }",
        "{ min = [-0.01, 0.0, -1.01], max = [0.01, 2.0, 1.01] }",
    ))
    .unwrap();
    let (a, b) = (plain.scene.mesh(), placed.scene.mesh());
    assert_eq!(a.springs().len(), b.springs().len());
    for (s, t) in a.springs().iter().zip(b.springs()) {
        assert!((2.0 * s.rest_length - t.rest_length).abs() < 1e-12);
    }
    for (p, q) in a.positions().iter().zip(b.positions()) {
        assert!((2.0 * p + Vector3::new(0.0, 1.0, 0.0) - q).norm() < 1e-12);
    }
    assert_eq!(plain.scene.pinned(), placed.scene.pinned());
    // The old region no longer holds anything once the mesh is lifted.
    let err = load(text("transform = { translate = [0.0, 5.0, 0.0] }", edge)).unwrap_err();
    assert!(err.contains("pins.region"), "{err}");
    let err = load(text("transform = { scale = 0.0 }", edge)).unwrap_err();
    assert!(err.contains("mesh.transform.scale"), "{err}");
}
