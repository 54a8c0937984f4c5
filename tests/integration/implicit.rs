//! Backward Euler by Newton and by projective dynamics, through the simulation API.

use hooke::sim::scenes::{self, AnySetup};
use hooke::sim::{Integrator, Pins, Scene, Settings, SimError, Simulation, State};
use hooke::solvers::{NewtonParams, PdParams};
use hooke_solvers::Convergence;
use nalgebra::Vector3;

fn settings(integrator: Integrator) -> Settings {
    Settings {
        integrator,
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-10,
            ..Default::default()
        },
        pd: PdParams {
            max_iterations: 20_000,
            tolerance: 1e-10,
            ..Default::default()
        },
        ..Settings::default()
    }
}

#[test]
fn backward_euler_dissipates_the_energy_of_a_free_stretched_cloth() {
    // cloth-10 with no pins and no gravity, released from 30 % stretch: an undamped free scene.
    let mesh = hooke::mesh::generators::cloth(10, 1e3).unwrap();
    let scene = Scene::new(mesh, 1.0 / 30.0).unwrap();
    let mut state = scene.initial_state();
    for p in &mut state.positions {
        *p = Vector3::new(
            p.x * 1.3,
            0.02 * (7.0 * p.x).sin() * (5.0 * p.z).cos(),
            p.z * 1.3,
        );
    }
    // Newton's adaptive shift is slow where the cloth buckles (an open robustness target):
    // give it room, and report what it used.
    let mut s = settings(Integrator::Newton);
    s.newton.max_iterations = 1000;
    let mut sim = Simulation::new(scene, state, s).unwrap();
    let e0 = sim.energy().total;
    let mut iterations = Vec::new();
    let mut previous = e0;
    for frame in 1..=20 {
        let report = sim.step().unwrap();
        let solver = report.solver.expect("Newton reports");
        iterations.push(solver.iterations);
        assert!(solver.stop.is_converged(), "frame {frame}: {solver:?}");
        let e = sim.energy().total;
        // Newton's tolerance (1e-10 of the gradient) leaves an energy error far below 1e-9 of e0.
        assert!(
            e <= previous + 1e-9 * e0,
            "frame {frame}: energy rose from {previous} to {e} J"
        );
        previous = e;
    }
    eprintln!("Newton iterations per frame: {iterations:?}");
    assert!(
        previous < 0.9 * e0,
        "backward Euler dissipates: {e0} J → {previous} J"
    );
}

#[test]
fn projective_dynamics_to_convergence_follows_the_newton_trajectory() {
    let run = |integrator| {
        let setup = scenes::cloth(8, false).unwrap();
        let mut sim = Simulation::new(setup.scene, setup.initial, settings(integrator)).unwrap();
        for _ in 0..3 {
            sim.step().unwrap();
        }
        sim.state().clone()
    };
    let (newton, pd): (State<3>, State<3>) =
        (run(Integrator::Newton), run(Integrator::ProjectiveDynamics));
    let start = scenes::cloth(8, false).unwrap().initial.positions;
    let motion = newton
        .positions
        .iter()
        .zip(&start)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    let difference = newton
        .positions
        .iter()
        .zip(&pd.positions)
        .map(|(a, b)| (a - b).norm_squared())
        .sum::<f64>()
        .sqrt();
    // Both solve each step to ~1e-10; over three steps the trajectories agree to far better than
    // 1e-6 of the motion (measured: see the assertion message if it fails).
    assert!(
        difference <= 1e-6 * motion,
        "PD and Newton trajectories differ by {difference:e} m (motion {motion:e} m)"
    );
}

#[test]
fn implicit_integrators_run_the_canonical_cloth_and_beam() {
    for name in ["cloth-10", "cloth-10-stiff", "beam-2"] {
        for integrator in [Integrator::Newton, Integrator::ProjectiveDynamics] {
            let AnySetup::Three(setup) = scenes::builtin(name).unwrap().unwrap() else {
                unreachable!()
            };
            let s = Settings {
                integrator,
                ..Settings::default()
            };
            let mut sim = Simulation::new(setup.scene, setup.initial, s).unwrap();
            for frame in 1..=5 {
                let report = sim
                    .step()
                    .unwrap_or_else(|e| panic!("{name}, {integrator}, frame {frame}: {e}"));
                assert_eq!(report.substeps, 1);
                assert!(
                    report.solver.is_some(),
                    "implicit steps report their solver"
                );
            }
            let state = sim.state();
            assert!(state
                .positions
                .iter()
                .chain(&state.velocities)
                .all(|v| v.iter().all(|c| c.is_finite())));
        }
    }
}

#[test]
fn terms_the_implicit_solve_does_not_model_are_refused() {
    let AnySetup::Two(setup) = scenes::builtin("seed-2d").unwrap().unwrap() else {
        unreachable!()
    };
    // seed-2d has dashpot damping: Newton takes it as a dissipation potential, projective dynamics
    // (one constant matrix) refuses it.
    let mut s = setup.settings;
    s.integrator = Integrator::ProjectiveDynamics;
    match Simulation::new(setup.scene.clone(), setup.initial.clone(), s) {
        Err(SimError::Unsupported { what, .. }) => assert!(what.starts_with("dashpot damping")),
        other => panic!("pd: expected Unsupported, got {other:?}"),
    }
    s.integrator = Integrator::Newton;
    let mut sim = Simulation::new(setup.scene.clone(), setup.initial.clone(), s).unwrap();
    sim.step().unwrap();
    // Pins are fine.
    let mesh = hooke::mesh::generators::cloth(4, 10.0).unwrap();
    let scene = Scene::new(mesh, 0.1)
        .unwrap()
        .with_pins(Pins::Vertices(vec![0]))
        .unwrap();
    let state = scene.initial_state();
    assert!(Simulation::new(scene, state, settings(Integrator::Newton)).is_ok());
}
