//! The hard cases of SCENES.md (numerical stability), every integrator on every case.
//!
//! Each run takes a few frames and must either finish with finite values and bounded energy, or
//! stop with a clear typed error of a kind its method may give:
//! - explicit Euler and symplectic Euler may refuse the step ([`SimError::UnstableStep`], or too
//!   many substeps as [`SimError::InvalidParameter`]), or stop when the state runs away
//!   ([`SimError::EnergyGrowth`], [`SimError::Diverged`], [`SimError::NonFinite`]: the
//!   simulation's own checks);
//! - the linearised integrator may report that its linear solver failed ([`SimError::LinearSolve`]:
//!   Jacobi diverging, CG meeting a matrix that is not positive definite even after the clamped
//!   fallback), or stop on [`SimError::EnergyGrowth`] (one Newton step without line search
//!   overshoots on stiff springs at large steps) or the divergence checks;
//! - projective dynamics has no failure mode: it must finish;
//! - backward Euler by Newton must finish on every case, every step converged (issue 5). On the
//!   crushed and stretched starts it does so by halving the steps it cannot finish (the `implicit`
//!   module of hooke-sim); the matrix shows the most pieces a frame took.
//!
//! "Bounded energy": none of these scenes has an energy source (no damping, wind or moving pins),
//! so the exact flow keeps the total energy E (kinetic + elastic + gravity) at E₀. A finished run
//! must keep E(t) ≤ E₀ + (|E₀| + E_g), E_g = M |g| L the scene's gravitational energy scale (total
//! mass, gravity, diagonal of the initial bounding box: 13.9 J for cloth-40): an energy error
//! as large as the scene's own energy is an explosion, not accuracy. (This is the default limit of
//! the simulation's energy watchdog, which stops such runs with [`SimError::EnergyGrowth`].)
//! Backward Euler by Newton dissipates, and must keep E(t) ≤ E₀ + 1e-6 (|E₀| + E_g).

use std::time::Instant;

use hooke::sim::{Scene, SimError, Simulation, State};
use hooke_cli::bench::{energy_scale, hard_case, hard_case_settings, HARD_CASES, HARD_INTEGRATORS};

const N: usize = 40;
/// Frames per run.
const FRAMES: usize = 3;
/// Frames per Newton run: its iterations on these cases take seconds a frame in the dev profile.
const NEWTON_FRAMES: usize = 2;
/// Explicit methods take at most this many substeps a frame; above, they must refuse.
const MAX_SUBSTEPS: usize = 1000;

/// The hard case `name` on cloth-40, built by the library (`hooke_cli::bench::hard_case`, shared with
/// `hooke bench --hard-cases`), with the two properties SCENES.md states checked here.
fn case(name: &str) -> (Scene<3>, State<3>) {
    let (scene, state) = hard_case(name, N).unwrap();
    match name {
        "mass ratio 1e4" => {
            let masses = scene.mesh().masses();
            let ratio = masses.iter().cloned().fold(0.0, f64::max)
                / masses.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!((ratio / 1e4 - 1.0).abs() < 1e-12, "mass ratio {ratio}");
        }
        "zero-length spring" => {
            let zero = scene
                .mesh()
                .springs()
                .iter()
                .filter(|s| {
                    (state.positions[s.i as usize] - state.positions[s.j as usize]).norm() == 0.0
                })
                .count();
            assert_eq!(zero, 1, "exactly one spring of zero length");
        }
        "free-floating" => assert!(scene.pinned().is_empty(), "no pins"),
        _ => {}
    }
    (scene, state)
}

/// How a run ended.
#[derive(Debug)]
enum Outcome {
    /// Every frame finished: the energy before and the largest after.
    Finished {
        e0: f64,
        e_max: f64,
        scale: f64,
        /// Steps whose solver stopped at its iteration limit.
        unconverged: usize,
        /// The most pieces one frame was split into (explicit substeps, or Newton's halving).
        pieces: usize,
    },
    /// Stopped with this error (at `frame`, 0 for the setup).
    Stopped { frame: usize, error: SimError },
}

fn run(case_name: &str, integrator: &str) -> Outcome {
    let (scene, state) = case(case_name);
    let settings = hard_case_settings(integrator, &scene, MAX_SUBSTEPS).unwrap();
    let mut sim = match Simulation::new(scene, state, settings) {
        Ok(sim) => sim,
        Err(error) => return Outcome::Stopped { frame: 0, error },
    };
    let e0 = sim.energy().total;
    let scale = energy_scale(sim.scene(), &sim.state().positions);
    let mut e_max = f64::NEG_INFINITY;
    let mut unconverged = 0;
    let mut pieces = 0;
    let frames = if integrator == "newton" {
        NEWTON_FRAMES
    } else {
        FRAMES
    };
    for frame in 1..=frames {
        match sim.step() {
            Err(error) => return Outcome::Stopped { frame, error },
            Ok(report) => {
                pieces = pieces.max(report.substeps);
                if report.converged == Some(false) {
                    unconverged += 1;
                }
            }
        }
        let state = sim.state();
        assert!(
            state
                .positions
                .iter()
                .chain(&state.velocities)
                .all(|p| p.iter().all(|c| c.is_finite())),
            "{case_name}, {integrator}, frame {frame}: a step returned Ok with non-finite values"
        );
        e_max = e_max.max(sim.energy().total);
    }
    Outcome::Finished {
        e0,
        e_max,
        scale,
        unconverged,
        pieces,
    }
}

fn error_kind(e: &SimError) -> &'static str {
    match e {
        SimError::UnstableStep { .. } => "UnstableStep",
        SimError::InvalidParameter { .. } => "InvalidParameter",
        SimError::Diverged { .. } => "Diverged",
        SimError::NonFinite { .. } => "NonFinite",
        SimError::LinearSolve { .. } => "LinearSolve",
        SimError::EnergyGrowth { .. } => "EnergyGrowth",
        SimError::Solver { .. } => "Solver",
        _ => "other",
    }
}

/// The errors each integrator may stop with (see the module docs).
fn allowed(integrator: &str, e: &SimError) -> bool {
    match integrator {
        "explicit-euler" | "symplectic-euler" => {
            matches!(
                e,
                SimError::UnstableStep { .. }
                    | SimError::EnergyGrowth { .. }
                    | SimError::Diverged { .. }
                    | SimError::NonFinite { .. }
            ) || matches!(e, SimError::InvalidParameter { name, .. } if name == "substeps")
        }
        "linearized-cg" | "linearized-jacobi" => matches!(
            e,
            SimError::LinearSolve { .. }
                | SimError::EnergyGrowth { .. }
                | SimError::Diverged { .. }
                | SimError::NonFinite { .. }
        ),
        _ => false,
    }
}

fn energy_slack(integrator: &str, e0: f64, scale: f64) -> f64 {
    let scale = e0.abs() + scale;
    match integrator {
        "newton" => 1e-6 * scale,
        _ => scale,
    }
}

/// Run every case with every integrator in `integrators`, print the matrix, and return the
/// failures (a message per case that broke its contract).
/// A cell "ok E a→b" finished (E at the start → the largest after; "ok*" if some step's solver
/// stopped at its iteration limit); otherwise the error and the frame it stopped at (0: refused at
/// the start).
fn matrix(cases: &[&str], integrators: &[&str]) -> Vec<String> {
    let mut failures = Vec::new();
    let mut table = format!("{:<20}", "case");
    for i in integrators {
        table += &format!(" | {i:<28}");
    }
    table += "\n";
    for &c in cases {
        table += &format!("{c:<20}");
        for &i in integrators {
            let start = Instant::now();
            let outcome = run(c, i);
            let seconds = start.elapsed().as_secs_f64();
            let cell = match &outcome {
                Outcome::Finished {
                    e0,
                    e_max,
                    scale,
                    unconverged,
                    pieces,
                } => {
                    // Newton must converge; the others report their iteration limits (PD runs a
                    // fixed number of iterations by design).
                    if i == "newton" && *unconverged > 0 {
                        failures.push(format!(
                            "{c}, {i}: {unconverged} step(s) stopped at the iteration limit"
                        ));
                    }
                    if e_max.is_nan() || *e_max > e0 + energy_slack(i, *e0, *scale) {
                        failures.push(format!(
                            "{c}, {i}: energy rose from {e0:.4e} J to {e_max:.4e} J"
                        ));
                    }
                    let mark = if *unconverged > 0 { "*" } else { "" };
                    format!("ok{mark} E {e0:.2e}→{e_max:.2e} ×{pieces}")
                }
                Outcome::Stopped { frame, error } => {
                    if !allowed(i, error) {
                        failures.push(format!("{c}, {i}: frame {frame}: {error}"));
                    }
                    format!("{} @{frame}", error_kind(error))
                }
            };
            table += &format!(" | {:<28}", format!("{cell} {seconds:.1}s"));
        }
        table += "\n";
    }
    eprintln!("{table}");
    failures
}

#[test]
fn every_integrator_but_newton_on_every_hard_case() {
    let integrators: Vec<&str> = HARD_INTEGRATORS
        .iter()
        .copied()
        .filter(|&i| i != "newton")
        .collect();
    let failures = matrix(HARD_CASES, &integrators);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn newton_finishes_every_hard_case() {
    let failures = matrix(HARD_CASES, &["newton"]);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
