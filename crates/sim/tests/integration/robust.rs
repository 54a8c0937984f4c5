//! Robustness: settings validated where they enter, the state after a failed step, typed solver
//! errors, `Settings::parallel` honoured bit for bit, and a per-frame converged flag.

use hooke_sim::{scenes, Integrator, SimError, Simulation, SolverFailure, State};
use hooke_solvers::{NewtonError, NewtonParams, PdParams, StopReason};

fn settings_for(integrator: Integrator) -> hooke_sim::Settings {
    hooke_sim::Settings {
        integrator,
        ..hooke_sim::Settings::default()
    }
}

/// cloth-10 thrown at `speed` m/s along x.
fn thrown(speed: f64) -> scenes::Setup<3> {
    let mut setup = scenes::cloth(10, false).unwrap();
    for v in &mut setup.initial.velocities {
        v.x = speed;
    }
    setup
}

fn same_state(a: &State<3>, b: &State<3>) -> bool {
    a.time.to_bits() == b.time.to_bits()
        && a.positions.len() == b.positions.len()
        && a.positions
            .iter()
            .zip(&b.positions)
            .chain(a.velocities.iter().zip(&b.velocities))
            .all(|(p, q)| {
                p.iter()
                    .zip(q.iter())
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            })
}

#[test]
fn after_a_failed_step_the_state_is_the_one_before_it_for_every_integrator() {
    // 1e9 m/s: one frame carries every vertex 3e7 m away, beyond the divergence limit
    // (1e6 × (1 m + the scene's extent)), whatever the integrator does with the springs.
    for &integrator in Integrator::ALL {
        let setup = thrown(1e9);
        let initial = setup.initial.clone();
        // The explicit methods would refuse cloth-10's stiff bound (over 10⁵ substeps) before any
        // step: run them forced, with few substeps, so that the step itself fails.
        let explicit = matches!(
            integrator,
            Integrator::ExplicitEuler | Integrator::SymplecticEuler
        );
        let settings = hooke_sim::Settings {
            substeps: explicit.then_some(10),
            allow_unstable: explicit,
            ..settings_for(integrator)
        };
        let mut sim = Simulation::new(setup.scene, setup.initial, settings)
            .unwrap_or_else(|e| panic!("{integrator}: {e}"));
        let error = sim.step().expect_err(integrator.name());
        assert!(
            matches!(
                error,
                SimError::Diverged { step: 1, .. } | SimError::NonFinite { step: 1, .. }
            ),
            "{integrator}: {error}"
        );
        assert!(
            same_state(sim.state(), &initial),
            "{integrator}: state changed"
        );
        assert_eq!(sim.steps_taken(), 0, "{integrator}");
        // Failing again from there gives the same error and leaves the same state.
        let again = sim.step().expect_err(integrator.name());
        assert_eq!(again.to_string(), error.to_string(), "{integrator}");
        assert!(same_state(sim.state(), &initial), "{integrator}");
    }
}

#[test]
fn a_solver_failure_is_typed_with_its_report_and_step_and_the_state_is_restored() {
    // 1e200 m/s overflows Φ (½ m |x − y|² with |x − y| = h · 1e200): Newton stops on a non-finite
    // objective, in every halved piece too, and says so with its own error and report.
    let setup = thrown(1e200);
    let initial = setup.initial.clone();
    let mut sim =
        Simulation::new(setup.scene, setup.initial, settings_for(Integrator::Newton)).unwrap();
    match sim.step() {
        Err(SimError::Solver {
            step: 1,
            source: SolverFailure::Newton(NewtonError::NonFinite { report }),
        }) => {
            assert_eq!(report.stop, StopReason::NonFinite, "{report:?}");
            assert_eq!(report.iterations, 0);
        }
        other => panic!("expected Newton's NonFinite at step 1, got {other:?}"),
    }
    assert!(same_state(sim.state(), &initial));
    assert_eq!(sim.steps_taken(), 0);
}

#[test]
fn invalid_solver_settings_are_refused_by_the_simulation_with_the_field() {
    let setup = scenes::cloth(4, false).unwrap();
    for (settings, field) in [
        (
            hooke_sim::Settings {
                newton: NewtonParams {
                    blend_factor: 1.0,
                    ..NewtonParams::default()
                },
                ..settings_for(Integrator::Newton)
            },
            "NewtonParams::blend_factor",
        ),
        (
            // Refused whichever integrator runs: a scene file may switch to it.
            hooke_sim::Settings {
                newton: NewtonParams {
                    max_iterations: 0,
                    ..NewtonParams::default()
                },
                ..settings_for(Integrator::SymplecticEuler)
            },
            "NewtonParams::max_iterations",
        ),
        (
            hooke_sim::Settings {
                pd: PdParams {
                    tolerance: f64::NAN,
                    ..PdParams::default()
                },
                ..settings_for(Integrator::ProjectiveDynamics)
            },
            "PdParams::tolerance",
        ),
    ] {
        let error =
            Simulation::new(setup.scene.clone(), setup.initial.clone(), settings).expect_err(field);
        match &error {
            SimError::SolverParameter(e) => assert_eq!(e.field(), field, "{error}"),
            other => panic!("{field}: {other:?}"),
        }
        assert!(error.to_string().contains(field), "{error}");
    }
}

#[test]
fn serial_and_parallel_runs_are_bit_identical_on_cloth_40() {
    // Three frames of cloth-40 (9,322 springs: above the 8,192 at which the Hessian's assembly
    // and the spring sums go parallel) for Newton and projective dynamics.
    let frames = 3;
    for integrator in [Integrator::Newton, Integrator::ProjectiveDynamics] {
        let run = |parallel: bool| {
            let setup = scenes::cloth(40, false).unwrap();
            assert!(setup.scene.mesh().springs().len() > 8192);
            let settings = hooke_sim::Settings {
                parallel,
                ..settings_for(integrator)
            };
            let mut sim = Simulation::new(setup.scene, setup.initial, settings).unwrap();
            let mut iterations = Vec::new();
            for _ in 0..frames {
                let report = sim.step().unwrap();
                iterations.push(report.solver.map(|s| s.iterations));
                assert_eq!(
                    report.converged,
                    report.solver.map(|s| s.stop.is_converged())
                );
            }
            (sim.state().clone(), iterations)
        };
        let (serial, serial_iterations) = run(false);
        let (parallel, parallel_iterations) = run(true);
        assert_eq!(serial_iterations, parallel_iterations, "{integrator}");
        assert!(
            same_state(&serial, &parallel),
            "{integrator}: serial and parallel runs differ"
        );
    }
}

#[test]
fn the_step_report_says_whether_the_solver_converged() {
    let setup = scenes::cloth(6, false).unwrap();
    // Newton to its tolerance: converged. PD's fixed budget (tolerance 0): not converged.
    // Symplectic Euler solves nothing: no flag.
    for (integrator, expected) in [
        (Integrator::Newton, Some(true)),
        (Integrator::ProjectiveDynamics, Some(false)),
        (Integrator::SymplecticEuler, None),
    ] {
        let mut sim = Simulation::new(
            setup.scene.clone(),
            setup.initial.clone(),
            settings_for(integrator),
        )
        .unwrap();
        let report = sim.step().unwrap();
        assert_eq!(report.converged, expected, "{integrator}: {report:?}");
    }
}
