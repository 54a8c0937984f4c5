//! Self-contact friction (docs/contact.md, "Self-contact friction"), through the simulation API: a
//! small sheet lying on a larger pinned one and sliding across it slows at no more than μ g and
//! stops under μ > 0, and slides on under μ = 0; friction never adds energy; μ = 0 gives the
//! frames of a scene without the key, bit for bit; scene files take `[self_contact] friction`
//! and refuse a negative one naming the key.

use hooke::mesh::{Bending, MassModel, SpringMesh, TriMesh};
use hooke::sim::file::parse_scene;
use hooke::sim::scenes::AnySetup;
use hooke::sim::{
    ExternalForce, Integrator, Pins, Scene, SelfContact, Settings, Simulation, State,
};
use nalgebra::Vector3;
use std::path::Path;

/// Gravity (m/s²).
const G: f64 = 9.81;
/// The self-contact reach d̂ (m).
const D_HAT: f64 = 2e-3;
/// The upper sheet's initial sliding speed (m/s).
const SPEED: f64 = 0.5;
/// Frames of h = 1/60 s.
const H: f64 = 1.0 / 60.0;
/// Frames the upper sheet settles at rest before it slides.
const SETTLE_FRAMES: usize = 30;

/// A 6×6 sheet on the unit square of the xz-plane, pinned, and a 4×4 sheet of 0.3 m × 0.3 m
/// lying on it (let down from 0.9 d̂ above and settled for `SETTLE_FRAMES`, shifted off the lower
/// vertices by a third of a spacing), then sliding at `SPEED` along x; one mesh, k = 1e3 N/m, 0.1 kg per vertex, no bending springs; gravity;
/// self-contact with d̂ = `D_HAT` and friction `friction` (`None`: the default settings, no key).
fn sliding_sheet(friction: Option<f64>) -> (Scene<3>, State<3>, usize) {
    let grid = |n: usize, size: f64, origin: Vector3<f64>| {
        let s = size / (n - 1) as f64;
        let mut p = Vec::new();
        for j in 0..n {
            for i in 0..n {
                p.push(origin + Vector3::new(i as f64 * s, 0.0, j as f64 * s));
            }
        }
        let mut t = Vec::new();
        for j in 0..n as u32 - 1 {
            for i in 0..n as u32 - 1 {
                let (a, b) = (j * n as u32 + i, j * n as u32 + i + 1);
                let (c, d) = (a + n as u32, b + n as u32);
                t.push([a, c, b]);
                t.push([b, c, d]);
            }
        }
        (p, t)
    };
    let (mut positions, mut triangles) = grid(6, 1.0, Vector3::zeros());
    let lower = positions.len();
    let offset = 0.2 / 3.0;
    let (upper, upper_triangles) = grid(
        4,
        0.3,
        Vector3::new(0.2 + offset, 0.9 * D_HAT, 0.35 + offset),
    );
    positions.extend(upper);
    triangles.extend(upper_triangles.iter().map(|t| t.map(|v| v + lower as u32)));
    let count = positions.len();
    let surface = TriMesh::new(positions, triangles).unwrap();
    let mesh = SpringMesh::from_triangles(
        &surface,
        1e3,
        Bending::None,
        MassModel::Uniform {
            total: 0.1 * count as f64,
        },
    )
    .unwrap();
    let settings = match friction {
        Some(friction) => SelfContact {
            distance: Some(D_HAT),
            friction,
        },
        None => SelfContact {
            distance: Some(D_HAT),
            ..SelfContact::default()
        },
    };
    let scene = Scene::new(mesh, H)
        .unwrap()
        .with_pins(Pins::Vertices((0..lower as u32).collect()))
        .unwrap()
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector3::new(0.0, -G, 0.0),
        }])
        .unwrap()
        .with_self_contact(Some(settings))
        .unwrap();
    // Settle the upper sheet onto the barrier at rest (0.5 s: the weight is then carried by the
    // pairs' barrier forces, λ summing to the sheet's weight), then set it sliding.
    let mut settle = Simulation::new(scene.clone(), scene.initial_state(), newton()).unwrap();
    for _ in 0..SETTLE_FRAMES {
        settle.step().unwrap();
    }
    let mut state = settle.state().clone();
    for v in state.velocities.iter_mut().skip(lower) {
        *v = Vector3::new(SPEED, 0.0, 0.0);
    }
    (scene, state, lower)
}

fn newton() -> Settings {
    Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    }
}

/// Per frame (0 = the start): the upper sheet's mean x-velocity (m/s) and the total energy (J).
fn run(friction: Option<f64>, frames: usize) -> (Vec<f64>, Vec<f64>, Vec<Vec<Vector3<f64>>>) {
    let (scene, state, lower) = sliding_sheet(friction);
    let mut sim = Simulation::new(scene, state, newton()).unwrap();
    let mean_vx = |sim: &Simulation<3>| {
        let v = &sim.state().velocities[lower..];
        v.iter().map(|v| v.x).sum::<f64>() / v.len() as f64
    };
    let (mut speeds, mut energies, mut frames_out) =
        (vec![mean_vx(&sim)], vec![sim.energy().total], Vec::new());
    for frame in 1..=frames {
        sim.step().unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        speeds.push(mean_vx(&sim));
        energies.push(sim.energy().total);
        frames_out.push(sim.state().positions.clone());
    }
    (speeds, energies, frames_out)
}

/// Under μ = 0.3 the sheet decelerates by Coulomb friction against its weight: μ g = 2.94 m/s²,
/// so it stops after about 0.17 s (10 frames), and stays. Its deceleration over any frame is at
/// most μ g (each pair's friction is at most μ λ, and the settled sheet's normal forces λ carry
/// its weight), with 1% for what is left of its settling; while it slides fast (the first 0.1 s,
/// far above ε_v = 1 mm/s) friction is at its Coulomb bound, so the mean deceleration is at least
/// 0.98 μ g (measured: μ g to 4 digits). Without friction it keeps 99% of its speed (no other
/// horizontal force acts on it).
#[test]
fn a_sheet_sliding_on_a_sheet_slows_and_stops_under_friction_and_slides_on_without() {
    let mu = 0.3;
    let frames = 18;
    let (speeds, _, _) = run(Some(mu), frames);
    let bound = mu * G;
    for (k, w) in speeds.windows(2).enumerate() {
        let deceleration = (w[0] - w[1]) / H;
        assert!(
            deceleration <= 1.01 * bound,
            "frame {}: deceleration {deceleration} m/s² above μ g = {bound}",
            k + 1
        );
    }
    let early = (speeds[0] - speeds[6]) / (6.0 * H);
    assert!(
        early >= 0.98 * bound,
        "mean deceleration over 0.1 s {early} m/s², μ g = {bound}; speeds {speeds:?}"
    );
    let last = *speeds.last().unwrap();
    assert!(
        last.abs() < 0.01 * SPEED,
        "still sliding at {last} m/s: {speeds:?}"
    );

    let (free, _, _) = run(Some(0.0), frames);
    let last = *free.last().unwrap();
    assert!(
        last >= 0.99 * SPEED,
        "without friction it slowed to {last} m/s: {free:?}"
    );
}

/// Friction only removes energy: the total energy (kinetic, springs, gravity, barrier) with μ > 0
/// never rises from one frame to the next (by more than 1e-9 of the initial energy, for rounding;
/// measured: it falls every frame), nor more than the largest rise without friction (which the
/// slide over the lower sheet's pairs makes rise by up to 6.4e-4 J in a frame, 0.3% of it), and it
/// ends lower than without friction by at least half the kinetic energy of the slide.
#[test]
fn friction_never_adds_energy() {
    let frames = 18;
    let (_, with, _) = run(Some(0.3), frames);
    let (_, without, _) = run(Some(0.0), frames);
    let rise = |e: &[f64]| {
        e.windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let tolerance = 1e-9 * with[0].abs();
    assert!(
        rise(&with) <= tolerance && rise(&with) <= rise(&without).max(0.0) + tolerance,
        "largest rise with friction {:e} J, without {:e} J",
        rise(&with),
        rise(&without)
    );
    let kinetic = 0.5 * 16.0 * 0.1 * SPEED * SPEED;
    assert!(
        with[frames] <= without[frames] - 0.5 * kinetic,
        "final energy with friction {} J, without {} J",
        with[frames],
        without[frames]
    );
}

/// μ = 0 costs nothing and changes nothing: the frames of a scene with `friction: 0.0` are those
/// of the default settings, bit for bit.
#[test]
fn zero_friction_gives_the_frames_of_no_friction() {
    let (_, _, zero) = run(Some(0.0), 6);
    let (_, _, none) = run(None, 6);
    assert!(zero == none, "the frames differ");
}

/// Serial and parallel runs with friction give the same frames.
#[test]
fn serial_and_parallel_runs_with_friction_give_the_same_frames() {
    let frames = |parallel: bool| {
        let (scene, state, _) = sliding_sheet(Some(0.3));
        let settings = Settings {
            parallel,
            ..newton()
        };
        let mut sim = Simulation::new(scene, state, settings).unwrap();
        (0..6)
            .map(|_| {
                sim.step().unwrap();
                sim.state().positions.clone()
            })
            .collect::<Vec<_>>()
    };
    assert!(
        frames(true) == frames(false),
        "serial and parallel frames differ"
    );
}

/// A cloth scene over a sphere with self-contact, as a scene file.
fn scene_file(self_contact: &str) -> String {
    format!(
        r#"
[mesh]
generator = "cloth"
n = 5
stiffness = 300.0
[pins]
vertices = [0, 4]
[[contact]]
shape = "sphere"
center = [0.5, -0.3, 0.5]
radius = 0.25
friction = 0.2
{self_contact}
[integrator]
method = "newton"
time_step = 0.03333333333333333
[run]
steps = 4
"#
    )
}

fn setup(text: &str) -> hooke::sim::scenes::Setup<3> {
    match parse_scene(text, Path::new("friction.toml")).unwrap().setup {
        AnySetup::Three(s) => s,
        AnySetup::Two(_) => unreachable!(),
    }
}

fn frames_of(text: &str) -> Vec<Vec<Vector3<f64>>> {
    let setup = setup(text);
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    (0..setup.steps)
        .map(|_| {
            sim.step().unwrap();
            sim.state().positions.clone()
        })
        .collect()
}

#[test]
fn scene_files_take_self_contact_friction_and_refuse_a_negative_one() {
    let with = setup(&scene_file("[self_contact]\nfriction = 0.3\n"));
    assert_eq!(with.scene.self_contact().unwrap().friction, 0.3);
    assert_eq!(with.scene.self_contact_model().unwrap().friction, 0.3);
    let frames = frames_of(&scene_file("[self_contact]\nfriction = 0.3\n"));
    assert_eq!(frames.len(), 4);
    assert!(frames
        .iter()
        .flatten()
        .all(|p| p.iter().all(|c| c.is_finite())));

    // friction = 0 is the file without the key, frame for frame.
    assert!(
        frames_of(&scene_file("[self_contact]\nfriction = 0.0\n"))
            == frames_of(&scene_file("[self_contact]\n")),
        "friction = 0 changed the frames"
    );

    for bad in ["-1.0", "nan", "inf"] {
        let text = scene_file(&format!("[self_contact]\nfriction = {bad}\n"));
        let err = parse_scene(&text, Path::new("friction.toml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("self_contact.friction"), "{bad}: {err}");
    }
}
