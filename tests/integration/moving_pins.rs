//! Pinned vertices on a prescribed path (docs/model.md §5.4: the pinned positions change, the
//! system matrix does not), through every integrator.

use hooke::mesh::generators;
use hooke::sim::{ExternalForce, Integrator, Keyframe, PinPath, Pins, Scene, Settings, Simulation};
use hooke::solvers::{NewtonParams, PdParams};
use nalgebra::Vector3;

const N: usize = 10;

fn settings(integrator: Integrator) -> Settings {
    Settings {
        integrator,
        // Explicit methods take their automatic substeps (forward Euler needs ~10³ a frame here).
        // The step-size criterion (m/s): a rigid translation starts at the solution, where a
        // gradient relative to its start (round-off) could never meet a relative tolerance.
        newton: NewtonParams {
            tolerance: 1e-8,
            max_iterations: 200,
            ..NewtonParams::default()
        },
        pd: PdParams {
            max_iterations: 20,
            ..PdParams::default()
        },
        ..Settings::default()
    }
}

/// cloth-10 with k = 10 N/m (soft enough for forward Euler's substeps) and its edge i = 0
/// (vertices 0..N) on `path`.
fn cloth_with_moving_edge(path: PinPath<3>, gravity: bool) -> Scene<3> {
    let mesh = generators::cloth(N, 10.0).unwrap();
    let edge: Vec<u32> = (0..N as u32).collect();
    let mut scene = Scene::new(mesh, 1.0 / 30.0)
        .unwrap()
        .with_pin_path(Pins::Vertices(edge), path)
        .unwrap();
    if gravity {
        scene = scene
            .with_forces(vec![ExternalForce::Gravity {
                acceleration: Vector3::new(0.0, -9.81, 0.0),
            }])
            .unwrap();
    }
    scene
}

#[test]
fn a_cloth_moving_with_its_pinned_edge_follows_it_exactly() {
    // No gravity, the whole cloth starts with the edge's velocity: the exact motion is a rigid
    // translation, x(t) = x(0) + u t, which every integrator reproduces up to round-off (no spring
    // is stretched, so every force and every solver correction is zero).
    let u = Vector3::new(0.5, 0.0, 0.0);
    for integrator in Integrator::ALL.iter().copied() {
        if integrator == Integrator::Newton {
            continue; // covered by newton_follows_a_rigid_translation (a tighter check)
        }
        let scene = cloth_with_moving_edge(PinPath::ConstantVelocity { velocity: u }, false);
        let mut state = scene.initial_state();
        let start = state.positions.clone();
        state.velocities.iter_mut().for_each(|v| *v = u);
        let mut sim = Simulation::new(scene, state, settings(integrator)).unwrap();
        for step in 1..=15 {
            sim.step()
                .unwrap_or_else(|e| panic!("{integrator}, step {step}: {e}"));
            let t = sim.state().time;
            for (v, (x, x0)) in sim.state().positions.iter().zip(&start).enumerate() {
                let error = (x - (x0 + u * t)).norm();
                assert!(
                    error <= 1e-12,
                    "{integrator}, step {step}: vertex {v} is {error:e} m off the translation"
                );
            }
        }
    }
}

#[test]

fn newton_follows_a_rigid_translation() {
    let u = Vector3::new(0.5, 0.0, 0.0);
    let scene = cloth_with_moving_edge(PinPath::ConstantVelocity { velocity: u }, false);
    let mut state = scene.initial_state();
    let start = state.positions.clone();
    state.velocities.iter_mut().for_each(|v| *v = u);
    let mut sim = Simulation::new(scene, state, settings(Integrator::Newton)).unwrap();
    for step in 1..=15 {
        sim.step()
            .unwrap_or_else(|e| panic!("newton, step {step}: {e}"));
        let t = sim.state().time;
        for (v, (x, x0)) in sim.state().positions.iter().zip(&start).enumerate() {
            let error = (x - (x0 + u * t)).norm();
            assert!(
                error <= 1e-12,
                "newton, step {step}: vertex {v} is {error:e} m off"
            );
        }
    }
}

#[test]
fn pinned_edge_follows_its_path_under_every_integrator_and_pd_keeps_its_factor() {
    // From rest, with gravity: the edge slides sideways at 0.3 m/s for 0.5 s, then stops
    // (keyframes). Pinned vertices are exactly on the path at every frame; the free cloth is dragged
    // along (its mean x ends further along +x than with the edge held still).
    let path = PinPath::Keyframes(vec![
        Keyframe {
            time: 0.0,
            offset: Vector3::zeros(),
            rotation: None,
        },
        Keyframe {
            time: 0.5,
            offset: Vector3::new(0.15, 0.0, 0.0),
            rotation: None,
        },
    ]);
    for integrator in Integrator::ALL.iter().copied() {
        let scene = cloth_with_moving_edge(path.clone(), true);
        let state = scene.initial_state();
        let start = state.positions.clone();
        let mut sim = Simulation::new(scene, state, settings(integrator)).unwrap();
        let factor_time = sim.factorization_time();
        // The methods that hold PD's prefactored matrix (PD itself, and those that use it as a
        // preconditioner or initial Hessian) report its factorisation time.
        assert_eq!(
            factor_time.is_some(),
            matches!(
                integrator,
                Integrator::ProjectiveDynamics
                    | Integrator::ChebyshevPd
                    | Integrator::Lbfgs
                    | Integrator::NewtonCg
            ),
            "{integrator}"
        );
        for step in 1..=24 {
            sim.step()
                .unwrap_or_else(|e| panic!("{integrator}, step {step}: {e}"));
            let t = sim.state().time;
            let offset = path.offset(t);
            for (v, (x, x0)) in sim.state().positions.iter().zip(&start).take(N).enumerate() {
                let error = (x - (x0 + offset)).norm();
                assert!(
                    error <= 1e-12,
                    "{integrator}, step {step}: pinned vertex {v} is {error:e} m off its path"
                );
            }
            // PD factored K (M + h² L) Kᵀ once; moving pins change only its right-hand side.
            assert_eq!(
                sim.factorization_time(),
                factor_time,
                "{integrator}, step {step}: the factorisation was redone"
            );
        }
        let mean_x = |p: &[Vector3<f64>]| p.iter().map(|x| x.x).sum::<f64>() / p.len() as f64;
        let still = {
            let edge: Vec<u32> = (0..N as u32).collect();
            let scene = cloth_with_moving_edge(path.clone(), true)
                .with_pins(Pins::Vertices(edge))
                .unwrap();
            let state = scene.initial_state();
            let mut sim = Simulation::new(scene, state, settings(integrator)).unwrap();
            for _ in 0..24 {
                sim.step().unwrap();
            }
            mean_x(&sim.state().positions)
        };
        let state = sim.state();
        let mean_dx = mean_x(&state.positions) - still;
        assert!(
            state
                .positions
                .iter()
                .chain(&state.velocities)
                .all(|p| p.iter().all(|c| c.is_finite())),
            "{integrator}: finite"
        );
        assert!(
            mean_dx > 0.03,
            "{integrator}: the cloth is dragged along the edge's 0.15 m, mean Δx = {mean_dx} m \
             against the still edge"
        );
        // After the path stops, the pins are at rest.
        for v in 0..N {
            assert!(
                state.velocities[v].norm() <= 1e-9,
                "{integrator}: vertex {v}"
            );
        }
    }
}
