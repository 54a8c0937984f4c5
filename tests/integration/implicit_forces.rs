//! Wind, viscous damping, the attractor, buoyancy and dashpot damping inside the backward Euler
//! integrators (Newton and projective dynamics), through the simulation API.

use hooke::sim::{Damping, ExternalForce, Integrator, Scene, Settings, SimError, Simulation};
use hooke::solvers::{NewtonParams, PdParams};
use hooke_solvers::Convergence;
use nalgebra::Vector3;

type V = Vector3<f64>;

fn settings(integrator: Integrator) -> Settings {
    Settings {
        integrator,
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: 1e-12,
            max_iterations: 200,
            ..Default::default()
        },
        pd: PdParams {
            max_iterations: 50_000,
            tolerance: 1e-13,
            ..Default::default()
        },
        ..Settings::default()
    }
}

/// cloth-6, no pins, stretched and moving, with every term linear in x or v.
fn scene(damping: Damping) -> Scene<3> {
    let mesh = hooke::mesh::generators::cloth(6, 1e3).unwrap();
    Scene::new(mesh, 1.0 / 30.0)
        .unwrap()
        .with_forces(vec![
            ExternalForce::Gravity {
                acceleration: V::new(0.0, -9.81, 0.0),
            },
            ExternalForce::Wind {
                velocity: V::new(1.0, 0.0, -0.5),
                coefficient: 0.02,
            },
            ExternalForce::Attractor {
                point: V::new(0.5, -1.0, 0.5),
                strength: 4.0,
            },
        ])
        .unwrap()
        .with_damping(damping)
        .unwrap()
}

#[test]
fn newton_and_pd_solve_the_backward_euler_equation_with_wind_viscous_damping_and_the_attractor() {
    let damping = Damping {
        viscous: 0.01,
        ..Damping::default()
    };
    for integrator in [Integrator::Newton, Integrator::ProjectiveDynamics] {
        let scene = scene(damping);
        let mut state = scene.initial_state();
        for (k, (p, v)) in state
            .positions
            .iter_mut()
            .zip(&mut state.velocities)
            .enumerate()
        {
            *p *= 1.1;
            *v = V::new((k as f64).sin(), 0.3, (0.7 * k as f64).cos());
        }
        let (x_n, v_n) = (state.positions.clone(), state.velocities.clone());
        let mut sim = Simulation::new(scene.clone(), state, settings(integrator)).unwrap();
        sim.step().unwrap();
        let h = scene.time_step();
        let x = &sim.state().positions;
        let masses = scene.mesh().masses();
        // M (x − x_n − h v_n) = h² (f_spring(x) + f_ext(x, v⁺)), v⁺ = (x − x_n)/h: backward Euler
        // with every force at the end of the step.
        let mut force = vec![V::zeros(); x.len()];
        let mut largest = 0.0f64;
        for s in scene.mesh().springs() {
            let (i, j) = s.ends();
            let f = hooke::assembly::spring::force(s.stiffness, s.rest_length, &(x[i] - x[j]));
            force[i] += f;
            force[j] -= f;
            largest = largest.max(f.norm());
        }
        for v in 0..x.len() {
            let velocity = (x[v] - x_n[v]) / h;
            let external =
                scene.forces().force(masses[v], &x[v], &velocity) - velocity * damping.viscous;
            let residual =
                (x[v] - x_n[v] - v_n[v] * h) * masses[v] - (force[v] + external) * (h * h);
            // Both solvers converged far below 1e-9 of the largest h²-scaled force.
            assert!(
                residual.norm() <= 1e-9 * (largest + external.norm()) * h * h,
                "{integrator:?}, vertex {v}: residual {:e}",
                residual.norm()
            );
        }
    }
}

#[test]
fn viscous_and_dashpot_damping_remove_energy_inside_newton() {
    let run = |damping: Damping| {
        let mesh = hooke::mesh::generators::cloth(8, 1e3).unwrap();
        let scene = Scene::new(mesh, 1.0 / 30.0)
            .unwrap()
            .with_damping(damping)
            .unwrap();
        let mut state = scene.initial_state();
        for (k, v) in state.velocities.iter_mut().enumerate() {
            *v = V::new(0.0, (0.9 * k as f64).sin(), 0.0);
        }
        let mut sim = Simulation::new(scene, state, settings(Integrator::Newton)).unwrap();
        for _ in 0..5 {
            sim.step().unwrap();
        }
        sim.energy().total
    };
    let undamped = run(Damping::default());
    let viscous = run(Damping {
        viscous: 0.05,
        ..Damping::default()
    });
    let dashpot = run(Damping {
        dashpot: 0.5,
        ..Damping::default()
    });
    assert!(
        viscous < 0.9 * undamped,
        "viscous: {viscous} J vs undamped {undamped} J"
    );
    assert!(
        dashpot < 0.9 * undamped,
        "dashpot: {dashpot} J vs undamped {undamped} J"
    );
}

#[test]
fn projective_dynamics_refuses_a_dashpot_and_says_why() {
    let damping = Damping {
        dashpot: 1.0,
        ..Damping::default()
    };
    let scene = scene(damping);
    let state = scene.initial_state();
    match Simulation::new(scene, state, settings(Integrator::ProjectiveDynamics)) {
        Err(SimError::Unsupported { what, .. }) => assert!(what.contains("dashpot"), "{what}"),
        other => panic!("expected Unsupported, got {other:?}"),
    }
}

#[test]
fn buoyancy_lifts_a_submerged_cloth_in_newton_and_pd() {
    for integrator in [Integrator::Newton, Integrator::ProjectiveDynamics] {
        let mesh = hooke::mesh::generators::cloth(5, 1e3).unwrap();
        let forces = |fluid_density| {
            vec![
                ExternalForce::Gravity {
                    acceleration: V::new(0.0, -9.81, 0.0),
                },
                ExternalForce::Buoyancy {
                    fluid_density,
                    body_density: 500.0,
                    surface: 1.0,
                },
            ]
        };
        let fall = |fluid_density| {
            let scene = Scene::new(mesh.clone(), 1.0 / 30.0)
                .unwrap()
                .with_forces(forces(fluid_density))
                .unwrap();
            let state = scene.initial_state();
            let mut sim = Simulation::new(scene, state, settings(integrator)).unwrap();
            sim.step().unwrap();
            sim.state().positions[12].y
        };
        // Water twice as dense as the body: net force upward, m g (ρ_f/ρ_b − 1) = m g.
        let (dry, wet) = (fall(0.0), fall(1000.0));
        let h = 1.0 / 30.0;
        assert!(
            (dry + 9.81 * h * h).abs() < 1e-9 && (wet - 9.81 * h * h).abs() < 1e-9,
            "{integrator:?}: free fall {dry} m, buoyant rise {wet} m in one step"
        );
    }
}
