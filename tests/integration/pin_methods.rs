//! Pinned vertices by reduction (the default) and by counter-forces (docs/model.md §5.2, §5.3): the
//! two methods solve the same system for the free vertices, so Newton and the linearised integrator
//! must give the same trajectories with either, and hold every pinned vertex exactly where it is
//! prescribed.

use hooke::mesh::generators;
use hooke::sim::{
    ExternalForce, Integrator, LinearSolver, LinearizedParams, PinMethod, PinPath, Pins, Scene,
    Settings, SimError, Simulation,
};
use hooke::solvers::NewtonParams;
use hooke_solvers::Convergence;
use nalgebra::Vector3;

type V = Vector3<f64>;

const N: usize = 10;
const STEPS: usize = 12;

/// cloth-10 (k = 1000 N/m, 1 kg, 1 m) under gravity with its corners 0 and N − 1 pinned; with
/// `moving`, corner N − 1 follows a path at 0.6 m/s (x) and 0.3 m/s (z) instead of staying.
fn cloth(moving: bool) -> Scene<3> {
    let mesh = generators::cloth(N, 1e3).unwrap();
    let scene = Scene::new(mesh, 1.0 / 30.0)
        .unwrap()
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: V::new(0.0, -9.81, 0.0),
        }])
        .unwrap();
    if moving {
        scene
            .with_pins(Pins::Vertices(vec![0]))
            .unwrap()
            .with_pin_path(
                Pins::Vertices(vec![N as u32 - 1]),
                PinPath::ConstantVelocity {
                    velocity: V::new(0.6, 0.0, 0.3),
                },
            )
            .unwrap()
    } else {
        scene
            .with_pins(Pins::Vertices(vec![0, N as u32 - 1]))
            .unwrap()
    }
}

fn settings(integrator: Integrator, pins: PinMethod) -> Settings {
    Settings {
        integrator,
        pins,
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-10,
            ..NewtonParams::default()
        },
        linearized: LinearizedParams {
            solver: LinearSolver::ConjugateGradient,
            tolerance: 1e-12,
            ..LinearizedParams::default()
        },
        ..Settings::default()
    }
}

/// The positions after each of `STEPS` steps, and the time of each.
fn run(scene: &Scene<3>, settings: Settings) -> Vec<(f64, Vec<V>)> {
    let mut sim = Simulation::new(scene.clone(), scene.initial_state(), settings).unwrap();
    (1..=STEPS)
        .map(|step| {
            sim.step().unwrap_or_else(|e| {
                panic!(
                    "{} with {}, step {step}: {e}",
                    settings.integrator, settings.pins
                )
            });
            (sim.state().time, sim.state().positions.clone())
        })
        .collect()
}

fn compare(integrator: Integrator, moving: bool) {
    let scene = cloth(moving);
    let start = scene.initial_state().positions;
    let reduced = run(&scene, settings(integrator, PinMethod::Reduction));
    let counter = run(&scene, settings(integrator, PinMethod::CounterForce));
    // The displacement scale: the largest motion of any vertex over the run.
    let scale = reduced
        .iter()
        .flat_map(|(_, x)| x.iter().zip(&start).map(|(a, b)| (a - b).norm()))
        .fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    for (step, ((t, r), (t_c, c))) in reduced.iter().zip(&counter).enumerate() {
        assert_eq!(t, t_c);
        for &p in scene.pinned() {
            let p = p as usize;
            // Exactly where prescribed: the start, or the path at t (anchor + offset(t)).
            let prescribed = if moving && p == N - 1 {
                start[p] + V::new(0.6, 0.0, 0.3) * *t
            } else {
                start[p]
            };
            assert_eq!(c[p], prescribed, "{integrator}, step {}: pin {p}", step + 1);
            assert_eq!(r[p], prescribed, "{integrator}, step {}: pin {p}", step + 1);
        }
        for (a, b) in r.iter().zip(c) {
            worst = worst.max((a - b).norm());
        }
    }
    eprintln!(
        "{integrator}, {}: counter-force vs reduction {worst:e} m over {STEPS} steps, motion {scale:e} m",
        if moving { "moving pin" } else { "two pins" }
    );
    assert!(scale > 0.05, "the cloth moves ({scale} m)");
    assert!(
        worst <= TOLERANCE * scale,
        "{integrator}: the trajectories differ by {worst:e} m (motion {scale:e} m)"
    );
}

/// The two methods give the free rows the same system, so their trajectories differ only by
/// round-off: the full-DOF assembly sums the same spring blocks (possibly in another order) and the
/// solvers' dot products see the pinned entries as extra exact zeros. A relative perturbation ε of
/// the data moves a step's solution by about κ ε, κ the condition number of M + h² ∇²E; for this
/// cloth (vertex mass 0.01 kg, h² k ≈ 1.1 N/m·s², about 8 springs a vertex) κ ≲ 1e3, so ≈ 2e-13 of
/// the motion per step and a few 1e-12 over 12 steps (backward Euler damps rather than amplifies
/// earlier differences). 1e-10 of the motion leaves a margin of 30 over that; measured: at most
/// 7.2e-16 m in 0.96 m (Newton) and bit-identical trajectories (linearised, CG). A difference of the
/// size of the solvers' tolerances (Newton 1e-10 relative gradient, CG 1e-12 residual, times κ)
/// would mean the two systems differ, and fails this.
const TOLERANCE: f64 = 1e-10;

#[test]
fn newton_with_counter_forces_follows_the_reduction() {
    compare(Integrator::Newton, false);
    compare(Integrator::Newton, true);
}

#[test]
fn linearized_with_counter_forces_follows_the_reduction() {
    compare(Integrator::Linearized, false);
    compare(Integrator::Linearized, true);
}

#[test]
fn projective_dynamics_refuses_counter_forces() {
    let scene = cloth(false);
    match Simulation::new(
        scene.clone(),
        scene.initial_state(),
        settings(Integrator::ProjectiveDynamics, PinMethod::CounterForce),
    ) {
        Err(SimError::Unsupported { integrator, what }) => {
            assert_eq!(integrator, "pd");
            assert!(
                what.contains("counter-force") && what.contains("reduction"),
                "{what}"
            );
        }
        other => panic!("expected Unsupported, got {other:?}"),
    }
}

#[test]
fn newton_halving_keeps_the_counter_forces() {
    // Newton limited to 4 iterations cannot finish the buckling steps of this cloth at 1/30 s, so
    // the implicit integrator halves them (building its h/2 integrator with the same pin method);
    // the halved trajectory is the reduction's too.
    let scene = cloth(true);
    let limited = |pins| Settings {
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-10,
            max_iterations: 4,
            ..NewtonParams::default()
        },
        ..settings(Integrator::Newton, pins)
    };
    let mut runs = [PinMethod::Reduction, PinMethod::CounterForce]
        .map(|pins| Simulation::new(scene.clone(), scene.initial_state(), limited(pins)).unwrap());
    let start = scene.initial_state().positions;
    let (mut pieces, mut worst, mut scale) = (0, 0.0f64, 0.0f64);
    for step in 1..=6 {
        let [a, b] = runs
            .each_mut()
            .map(|sim| sim.step().unwrap().solver.unwrap());
        assert_eq!(a.substeps, b.substeps, "step {step}: the same halving");
        pieces = pieces.max(b.substeps);
        let [r, c] = runs.each_ref().map(|sim| sim.state().positions.clone());
        assert_eq!(c[0], start[0]);
        assert_eq!(c[N - 1], r[N - 1]);
        for ((x, y), x0) in r.iter().zip(&c).zip(&start) {
            worst = worst.max((x - y).norm());
            scale = scale.max((x - x0).norm());
        }
    }
    eprintln!("halving: up to {pieces} pieces a step, difference {worst:e} m, motion {scale:e} m");
    assert!(pieces > 1, "the limit of 4 iterations forces halving");
    assert!(
        worst <= TOLERANCE * scale,
        "{worst:e} m (motion {scale:e} m)"
    );
}
