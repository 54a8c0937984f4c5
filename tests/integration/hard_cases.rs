//! The hard cases of docs/scenes.md §6 (numerical stability), every integrator on every case.
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
//! - projective dynamics, Chebyshev PD and L-BFGS (which run to an iteration budget) must finish;
//! - backward Euler by Newton (with and without the opt-in relaxation) and by Newton-CG must finish on
//!   every case, every step converged. On the crushed and stretched starts they do so by
//!   halving the steps they cannot finish (the `implicit` module of hooke-sim); the matrix shows the
//!   most pieces a frame took.
//!
//! "Bounded energy": none of these scenes has an energy source (no damping, wind or moving pins),
//! so the exact flow keeps the total energy E (kinetic + elastic + gravity) at E₀. Each integrator
//! may raise the largest E(t) over E₀ by at most a fraction of the scene's energy scale
//! |E₀| + E_g (E_g = M |g| L: total mass, gravity, diagonal of the initial bounding box; 13.9 J for
//! cloth-40), the fraction being what the method is known to do ([`gain_bound`]):
//! - the backward Euler minimisers run to convergence (Newton, Newton-CG) dissipate: 1e-6 (round-off
//!   of the energy's sum, with room), on every case; L-BFGS, which runs to its budget, measured
//!   dissipating on every case (its smallest loss −3.6e-3 of the scale in 3 frames): 1e-6 as well;
//! - projective dynamics stops after 10 iterations, before the minimiser, and gains energy on stiff
//!   springs at large steps (measured in 3 frames: +0.17 on `stiff h=1/30`, +0.63 on `stiff h=1/5`,
//!   +0.14 on `k 1e1..1e7`; bounds 0.2, 0.75, 0.2); on the other cases it dissipates (1e-6);
//! - Chebyshev PD restarts to plain PD when Φ would rise, so it gains only where PD does, and less
//!   (measured +0.016, +0.13, +0.070 on those three; bounds 0.02, 0.15, 0.1), 1e-6 elsewhere;
//! - the linearised step dissipates where it finishes (measured; 1e-6): where it would not, the
//!   energy watchdog stops it;
//! - symplectic Euler keeps E within an O(h) oscillation (1e-3), except on the zero-length spring,
//!   where its substeps resolve the short spring's fast oscillation only roughly (measured +0.035;
//!   bound 0.05);
//! - explicit Euler gains energy on every spring scene: it is held only by the watchdog's default
//!   limit (1: an energy error as large as the scene's own energy is an explosion).

use std::time::Instant;

use hooke::sim::{Scene, SimError, Simulation, State};
use hooke_cli::bench::{energy_scale, hard_case, hard_case_settings, HARD_CASES, HARD_INTEGRATORS};

const N: usize = 40;
/// Frames per run: three for the methods that cost milliseconds a frame here, fewer for the
/// Newton methods, whose iterations on these cases take seconds a frame in the dev profile (the
/// full 30-frame matrix is `hooke bench --hard-cases`).
fn frames(integrator: &str) -> usize {
    match integrator {
        "newton" => 2,
        "newton-relaxed" | "newton-cg" => 1,
        _ => 3,
    }
}
/// Explicit methods take at most this many substeps a frame; above, they must refuse.
const MAX_SUBSTEPS: usize = 1000;

/// The hard case `name` on cloth-40, built by the library (`hooke_cli::bench::hard_case`, shared with
/// `hooke bench --hard-cases`), with the two properties docs/scenes.md §6 states checked here.
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
    for frame in 1..=frames(integrator) {
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

/// The integrators that solve backward Euler to convergence and halve what they do not finish:
/// each must finish every case with every step converged, and dissipate.
const NEWTON_METHODS: &[&str] = &["newton", "newton-relaxed", "newton-cg"];

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

/// The most the largest energy over a run may exceed E₀, as a fraction of |E₀| + E_g (the module
/// documentation gives the measurements behind each figure).
fn gain_bound(integrator: &str, case: &str) -> f64 {
    match (integrator, case) {
        ("pd", "stiff h=1/30") => 0.2,
        ("pd", "stiff h=1/5") => 0.75,
        ("pd", "k 1e1..1e7") => 0.2,
        ("pd-chebyshev", "stiff h=1/30") => 0.02,
        ("pd-chebyshev", "stiff h=1/5") => 0.15,
        ("pd-chebyshev", "k 1e1..1e7") => 0.1,
        ("symplectic-euler", "zero-length spring") => 0.05,
        ("symplectic-euler", _) => 1e-3,
        ("explicit-euler", _) => 1.0,
        _ => 1e-6,
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
                    if NEWTON_METHODS.contains(&i) && *unconverged > 0 {
                        failures.push(format!(
                            "{c}, {i}: {unconverged} step(s) stopped at the iteration limit"
                        ));
                    }
                    let bound = gain_bound(i, c);
                    if e_max.is_nan() || *e_max > e0 + bound * (e0.abs() + scale) {
                        failures.push(format!(
                            "{c}, {i}: energy rose from {e0:.4e} J to {e_max:.4e} J, more than \
                             {bound:e} of the scale {:.4e} J",
                            e0.abs() + scale
                        ));
                    }
                    let mark = if *unconverged > 0 { "*" } else { "" };
                    let gain = (e_max - e0) / (e0.abs() + scale);
                    format!("ok{mark} E {e0:.2e}→{e_max:.2e} ({gain:+.1e}) ×{pieces}")
                }
                Outcome::Stopped { frame, error } => {
                    if !allowed(i, error) {
                        failures.push(format!("{c}, {i}: frame {frame}: {error}"));
                    }
                    format!("{} @{frame}", error_kind(error))
                }
            };
            eprintln!("{c}, {i}: {cell} {seconds:.1}s");
            table += &format!(" | {:<28}", format!("{cell} {seconds:.1}s"));
        }
        table += "\n";
    }
    eprintln!("{table}");
    failures
}

#[test]
fn every_integrator_but_the_newton_methods_on_every_hard_case() {
    let integrators: Vec<&str> = HARD_INTEGRATORS
        .iter()
        .copied()
        .filter(|&i| !NEWTON_METHODS.contains(&i))
        .collect();
    let failures = matrix(HARD_CASES, &integrators);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn newton_finishes_every_hard_case() {
    let failures = matrix(HARD_CASES, &["newton"]);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn newton_with_relaxation_finishes_every_hard_case() {
    let failures = matrix(HARD_CASES, &["newton-relaxed"]);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn newton_cg_finishes_every_hard_case() {
    let failures = matrix(HARD_CASES, &["newton-cg"]);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
