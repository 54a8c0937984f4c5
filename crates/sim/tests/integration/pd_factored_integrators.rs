//! L-BFGS, Newton-CG and Chebyshev PD as integrators (docs/model.md §6.6–§6.9). The first two
//! minimise the same backward Euler objective Φ as Newton, so with every force, damping and pin
//! method they must land where Newton lands; Chebyshev PD must get closer to backward Euler than
//! plain PD with the same budget, report its ρ, and refuse what PD refuses.

use hooke_sim::{
    scenes, Damping, Integrator, PinMethod, PinPath, Pins, RateSource, Settings, SimError,
    Simulation, State,
};
use hooke_solvers::Convergence;
use hooke_solvers::{LbfgsParams, NewtonCgParams, NewtonParams};
use nalgebra::Vector3;

/// Relative gradient every minimiser is run to here. Its position error is about κ(∇²Φ) times
/// this; at h = 1/30 s on cloth-10 the inertia dominates (κ ≲ 10³), so 1e-11 leaves the
/// positions within ~1e-8 of the motion.
const TIGHT: f64 = 1e-11;

/// The same scene stepped `frames` times with `settings`.
fn run(setup: &scenes::Setup<3>, settings: Settings, frames: usize) -> State<3> {
    let mut sim = Simulation::new(setup.scene.clone(), setup.initial.clone(), settings)
        .unwrap_or_else(|e| panic!("{}: {e}", settings.integrator));
    for frame in 0..frames {
        let report = sim
            .step()
            .unwrap_or_else(|e| panic!("{} frame {frame}: {e}", settings.integrator));
        if let Some(converged) = report.converged {
            assert!(
                converged
                    || !matches!(
                        settings.integrator,
                        Integrator::Lbfgs | Integrator::NewtonCg
                    ),
                "{} did not converge in frame {frame}: {report:?}",
                settings.integrator
            );
        }
    }
    sim.state().clone()
}

/// |a − b| / |b − x₀| over all vertices.
fn distance(a: &State<3>, b: &State<3>, start: &State<3>) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for ((p, q), s) in a.positions.iter().zip(&b.positions).zip(&start.positions) {
        num += (p - q).norm_squared();
        den += (q - s).norm_squared();
    }
    (num / den).sqrt()
}

fn tight(integrator: Integrator, pins: PinMethod) -> Settings {
    Settings {
        integrator,
        pins,
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: TIGHT,
            ..NewtonParams::default()
        },
        lbfgs: LbfgsParams {
            convergence: Convergence::RelativeGradient,
            tolerance: TIGHT,
            max_iterations: 2000,
            ..LbfgsParams::default()
        },
        newton_cg: NewtonCgParams {
            convergence: Convergence::RelativeGradient,
            tolerance: TIGHT,
            ..NewtonCgParams::default()
        },
        ..Settings::default()
    }
}

/// Every minimiser against Newton on `setup`, with both pin methods.
fn agree_with_newton(setup: &scenes::Setup<3>, frames: usize, what: &str) {
    let newton = run(
        setup,
        tight(Integrator::Newton, PinMethod::Reduction),
        frames,
    );
    for integrator in [Integrator::Lbfgs, Integrator::NewtonCg] {
        for pins in PinMethod::ALL.iter().copied() {
            let state = run(setup, tight(integrator, pins), frames);
            let d = distance(&state, &newton, &setup.initial);
            // Both stop at a relative gradient of 1e-11 (see TIGHT): 1e-7 of the motion is a
            // margin of 10 over the expected ~1e-8.
            assert!(
                d <= 1e-7,
                "{what}: {integrator} ({pins:?}) is {d:.2e} of the motion from Newton"
            );
        }
    }
}

#[test]
fn lbfgs_and_newton_cg_land_where_newton_does_on_cloth_10() {
    let setup = scenes::cloth(10, false).unwrap();
    agree_with_newton(&setup, 5, "cloth-10");
}

#[test]
fn lbfgs_and_newton_cg_take_dashpot_damping_and_moving_pins() {
    let mut setup = scenes::cloth(10, false).unwrap();
    let n = 10u32;
    setup.scene = setup
        .scene
        .clone()
        .with_damping(Damping {
            drag: 0.0,
            viscous: 0.05,
            dashpot: 2.0,
        })
        .unwrap()
        .with_pin_path(
            Pins::Vertices(vec![n * n - 1]),
            PinPath::ConstantVelocity {
                velocity: Vector3::new(0.3, 0.0, 0.1),
            },
        )
        .unwrap();
    agree_with_newton(
        &setup,
        5,
        "cloth-10 with dashpot, viscous damping and a moving pin",
    );
}

#[test]
fn chebyshev_pd_beats_plain_pd_with_the_same_budget_and_reports_its_rate() {
    let setup = scenes::cloth(10, false).unwrap();
    let frames = 5;
    let newton = run(
        &setup,
        tight(Integrator::Newton, PinMethod::Reduction),
        frames,
    );
    let budget = |integrator| {
        let mut s = Settings {
            integrator,
            ..Settings::default()
        };
        s.pd.max_iterations = 30;
        s.chebyshev.max_iterations = 30;
        s
    };
    let plain = run(&setup, budget(Integrator::ProjectiveDynamics), frames);
    let mut sim = Simulation::new(
        setup.scene.clone(),
        setup.initial.clone(),
        budget(Integrator::ChebyshevPd),
    )
    .unwrap();
    assert_eq!(sim.chebyshev_rate(), None, "estimated on the first step");
    for _ in 0..frames {
        sim.step().unwrap();
    }
    let rate = sim.chebyshev_rate().expect("reported after the first step");
    assert!(
        matches!(rate, RateSource::Estimated(_) | RateSource::Fallback(_)),
        "{rate:?}"
    );
    assert!(rate.rate() > 0.0 && rate.rate() < 1.0, "{rate:?}");
    let (e_plain, e_cheb) = (
        distance(&plain, &newton, &setup.initial),
        distance(sim.state(), &newton, &setup.initial),
    );
    assert!(
        e_cheb < e_plain,
        "Chebyshev PD {e_cheb:.2e} is not closer to backward Euler than plain PD {e_plain:.2e}"
    );
}

#[test]
fn chebyshev_pd_with_a_given_rate_uses_it_and_refuses_what_pd_refuses() {
    let setup = scenes::cloth(10, false).unwrap();
    let mut settings = Settings {
        integrator: Integrator::ChebyshevPd,
        chebyshev_estimate: None,
        ..Settings::default()
    };
    settings.chebyshev.rate = 0.9;
    let mut sim = Simulation::new(setup.scene.clone(), setup.initial.clone(), settings).unwrap();
    sim.step().unwrap();
    assert_eq!(sim.chebyshev_rate(), Some(RateSource::Given(0.9)));

    let damped = setup
        .scene
        .clone()
        .with_damping(Damping {
            drag: 0.0,
            viscous: 0.0,
            dashpot: 1.0,
        })
        .unwrap();
    let refused = Simulation::new(damped, setup.initial.clone(), settings).unwrap_err();
    assert!(
        matches!(&refused, SimError::Unsupported { integrator, .. } if integrator == "pd-chebyshev"),
        "{refused}"
    );
    let bad = Settings {
        chebyshev_estimate: Some(2),
        ..settings
    };
    assert!(Simulation::new(setup.scene.clone(), setup.initial.clone(), bad).is_err());
}
