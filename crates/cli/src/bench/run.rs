//! Timing one step per solver setting and measuring its result.

use std::time::{Duration, Instant};

use hooke_solvers::{
    Amg, AmgParams, AndersonParams, AndersonPd, BackwardEulerStep, ChebyshevParams, ChebyshevPd,
    Convergence, GlobalSolveKind, IndefinitePolicy, Lbfgs, LbfgsParams, Newton, NewtonCg,
    NewtonCgParams, NewtonCgReport, NewtonParams, NewtonProblem, PdParams, ProjectiveDynamics,
    Relaxation, StopReason,
};
use nalgebra::Vector3;
use serde::Serialize;

use crate::bench::{BenchError, BenchProblem, ErrorMeter, Setting, SolverKind, SolverSpec};
use crate::sim::{Integrator, LinearSolver, LinearizedParams, Settings, Simulation};

/// Iteration limit of the tolerance-driven PD, CG and Jacobi runs.
const TOLERANCE_RUN_LIMIT: usize = 10_000;
/// Newton's iteration limit for `newton-tol` and `newton-cg-tol`.
const NEWTON_TOLERANCE_LIMIT: usize = 500;
/// Plain PD iterations from which `chebyshev` estimates ρ, once per scene.
const CHEBYSHEV_RATE_ITERATIONS: usize = 20;

/// One line of the report: what `--json` and `--csv` write, with exactly these fields (`null` /
/// empty where a value was not computed).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Record {
    /// The scene's name, e.g. `cloth-40`.
    pub scene: String,
    /// The solver family ([`SolverKind::name`]).
    pub solver: String,
    /// Its setting: an iteration count, a tolerance or `default`.
    pub setting: String,
    /// Iterations the solver took: PD and Newton iterations, or the linear solver's iterations for
    /// the linearised integrator.
    pub iterations: Option<usize>,
    /// Wall time of the step, s: the median of the timed repeats (see [`TimingOptions`]). Excludes
    /// work done once per scene and reused by every step (PD's factorisation, Newton's symbolic
    /// analysis); for the linearised integrator it is its whole step (Hessian assembly and solve).
    pub wall_time_s: Option<f64>,
    /// Factorisation time, s. PD: its one numeric factorisation of K(M + h²L)Kᵀ, done once per scene
    /// and amortised over all steps: *not* part of `wall_time_s`. Newton: the time in numeric
    /// factorisations within the step (median over repeats): part of `wall_time_s`. Null for the
    /// linearised integrator (it factors nothing).
    pub factor_time_s: Option<f64>,
    /// (Φ(x) − Φ*) / (Φ(y) − Φ*) (docs/model.md §9.2).
    pub objective_error: Option<f64>,
    /// |x − x*| / |x* − x_n| over the free DOFs (docs/model.md §9.2).
    pub position_error: Option<f64>,
    /// ‖M(x − y) − h² f(x)‖ / ‖M(y − y) − h² f(y)‖ = ‖∇Φ(x)‖ / ‖∇Φ(y)‖, the force residual relative
    /// to its value at the initial guess y.
    pub residual: Option<f64>,
}

/// A record with what the JSON does not hold: a note (why a run failed, a stop short of its
/// tolerance) and the positions x it produced (empty if it failed).
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The record.
    pub record: Record,
    /// Failure or remark, if any.
    pub note: Option<String>,
    /// x after the step, per vertex (full numbering); empty if the run failed.
    pub positions: Vec<Vector3<f64>>,
}

/// How steps are timed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimingOptions {
    /// Timed repeats after one untimed warm-up run (which also provides x): the reported time is
    /// their median. Default 5.
    pub repeats: usize,
    /// A warm-up run longer than this (s) is timed once, by itself: caches hardly matter at that
    /// length and repeats would take minutes. Default 2 s.
    pub single_run_above: f64,
}

impl Default for TimingOptions {
    fn default() -> Self {
        TimingOptions {
            repeats: 5,
            single_run_above: 2.0,
        }
    }
}

/// What one run returns: the positions, iterations, wall time, factorisation time (if any), a note.
struct RunResult {
    positions: Vec<Vector3<f64>>,
    iterations: usize,
    wall: Duration,
    factor: Option<Duration>,
    note: Option<String>,
}

/// Run every setting of `spec` on `problem`, time it and measure it with `meter` (which must be
/// built for the same problem). A run that fails gives a record with nulls and the error in its
/// note; only an error of the setup itself is returned as `Err`.
///
/// # Errors
/// [`BenchError::Solver`] if the solver cannot be set up for the scene (e.g. PD's matrix does not
/// factor).
pub fn run_spec(
    problem: &BenchProblem,
    meter: &mut ErrorMeter,
    spec: &SolverSpec,
    timing: TimingOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<Outcome>, BenchError> {
    let mut runner = Runner::new(problem, spec.kind)?;
    let mut outcomes = Vec::with_capacity(spec.settings.len());
    for &setting in &spec.settings {
        let begin = Instant::now();
        let outcome = match timed(timing, || runner.run(problem, setting)) {
            Ok(r) => {
                let m = meter.measure(&r.positions);
                Outcome {
                    record: Record {
                        scene: problem.name.clone(),
                        solver: spec.kind.name().into(),
                        setting: setting.to_string(),
                        iterations: Some(r.iterations),
                        wall_time_s: Some(r.wall.as_secs_f64()),
                        factor_time_s: r.factor.map(|d| d.as_secs_f64()),
                        objective_error: m.objective_error,
                        position_error: m.position_error,
                        residual: Some(m.residual),
                    },
                    note: r.note,
                    positions: r.positions,
                }
            }
            Err(message) => Outcome {
                record: Record {
                    scene: problem.name.clone(),
                    solver: spec.kind.name().into(),
                    setting: setting.to_string(),
                    iterations: None,
                    wall_time_s: None,
                    factor_time_s: None,
                    objective_error: None,
                    position_error: None,
                    residual: None,
                },
                note: Some(format!("failed: {message}")),
                positions: Vec::new(),
            },
        };
        progress(&format!(
            "{} {}:{} done in {:.1} s",
            problem.name,
            spec.kind,
            setting,
            begin.elapsed().as_secs_f64()
        ));
        outcomes.push(outcome);
    }
    Ok(outcomes)
}

/// Run once untimed (the result), then `repeats` more if short; median times.
fn timed(
    timing: TimingOptions,
    mut run: impl FnMut() -> Result<RunResult, String>,
) -> Result<RunResult, String> {
    let mut first = run()?;
    if timing.repeats == 0 || first.wall.as_secs_f64() > timing.single_run_above {
        return Ok(first);
    }
    let mut walls = Vec::with_capacity(timing.repeats);
    let mut factors = Vec::with_capacity(timing.repeats);
    for _ in 0..timing.repeats {
        let r = run()?;
        walls.push(r.wall);
        factors.extend(r.factor);
    }
    first.wall = median(&mut walls);
    if first.factor.is_some() && !factors.is_empty() {
        first.factor = Some(median(&mut factors));
    }
    Ok(first)
}

/// The median (the mean of the two middle values for an even count).
fn median(values: &mut [Duration]) -> Duration {
    values.sort();
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2
    }
}

/// A solver set up once per scene (PD's factorisation, Newton's symbolic analysis).
enum Runner {
    Pd {
        pd: Box<ProjectiveDynamics<3>>,
        x: Vec<Vector3<f64>>,
    },
    Newton {
        newton: Box<Newton>,
        objective: Box<BackwardEulerStep<3>>,
        unknowns: Vec<f64>,
    },
    Linearized {
        solver: LinearSolver,
    },
    /// L-BFGS or Newton-CG: the objective, and PD's factor as initial Hessian / preconditioner.
    QuasiNewton {
        kind: SolverKind,
        pd: Box<ProjectiveDynamics<3>>,
        objective: Box<BackwardEulerStep<3>>,
        unknowns: Vec<f64>,
    },
    Chebyshev {
        pd: Box<ProjectiveDynamics<3>>,
        rate: f64,
        x: Vec<Vector3<f64>>,
    },
    Anderson {
        pd: Box<ProjectiveDynamics<3>>,
        x: Vec<Vector3<f64>>,
    },
}

impl Runner {
    fn new(problem: &BenchProblem, kind: SolverKind) -> Result<Self, BenchError> {
        let mesh = problem.scene.mesh();
        let h = problem.scene.time_step();
        let solver_error = |e: String| BenchError::Solver {
            scene: problem.name.clone(),
            solver: kind.name().into(),
            reason: e,
        };
        let pd_with = |global_solve| {
            ProjectiveDynamics::new(
                mesh.springs(),
                mesh.masses(),
                &problem.free(),
                h,
                PdParams {
                    global_solve,
                    ..PdParams::default()
                },
            )
            .map(Box::new)
            .map_err(|e| solver_error(e.to_string()))
        };
        let pd = || pd_with(GlobalSolveKind::Auto);
        Ok(match kind {
            SolverKind::Pd | SolverKind::PdTol | SolverKind::PdAmg => Runner::Pd {
                pd: pd_with(if kind == SolverKind::PdAmg {
                    GlobalSolveKind::Multilevel
                } else {
                    GlobalSolveKind::Auto
                })?,
                x: problem.y.clone(),
            },
            SolverKind::Lbfgs
            | SolverKind::LbfgsTol
            | SolverKind::NewtonCg
            | SolverKind::NewtonCgTol
            | SolverKind::NewtonCgAmg
            | SolverKind::NewtonCgAmgTol => {
                let objective =
                    BackwardEulerStep::new(mesh.springs(), mesh.masses(), problem.free(), h);
                Runner::QuasiNewton {
                    kind,
                    pd: pd()?,
                    unknowns: vec![0.0; objective.dim()],
                    objective: Box::new(objective),
                }
            }
            SolverKind::Chebyshev => {
                let mut pd = pd()?;
                // ρ of plain PD on this scene; 0.99 if PD converges too fast to tell.
                let rate = pd
                    .estimate_rate(
                        mesh.springs(),
                        &problem.y,
                        &problem.y,
                        CHEBYSHEV_RATE_ITERATIONS,
                    )
                    .unwrap_or(ChebyshevParams::default().rate);
                Runner::Chebyshev {
                    pd,
                    rate,
                    x: problem.y.clone(),
                }
            }
            SolverKind::Anderson => Runner::Anderson {
                pd: pd()?,
                x: problem.y.clone(),
            },
            SolverKind::Newton
            | SolverKind::NewtonTol
            | SolverKind::NewtonRelaxed
            | SolverKind::NewtonRelaxedTol
            | SolverKind::NewtonProjected
            | SolverKind::NewtonProjectedTol
            | SolverKind::NewtonProjectedExact
            | SolverKind::NewtonProjectedExactTol
            | SolverKind::NewtonProjectedPcg
            | SolverKind::NewtonProjectedPcgTol => {
                let objective =
                    BackwardEulerStep::new(mesh.springs(), mesh.masses(), problem.free(), h);
                let relaxed = matches!(
                    kind,
                    SolverKind::NewtonRelaxed | SolverKind::NewtonRelaxedTol
                );
                let params = NewtonParams {
                    relaxation: if relaxed {
                        Relaxation::BUCKLING
                    } else {
                        Relaxation::NONE
                    },
                    indefinite: match kind {
                        SolverKind::NewtonProjected | SolverKind::NewtonProjectedTol => {
                            IndefinitePolicy::Projected
                        }
                        SolverKind::NewtonProjectedExact | SolverKind::NewtonProjectedExactTol => {
                            IndefinitePolicy::ProjectedThenExact
                        }
                        SolverKind::NewtonProjectedPcg | SolverKind::NewtonProjectedPcgTol => {
                            IndefinitePolicy::ProjectedPreconditioned
                        }
                        _ => NewtonParams::default().indefinite,
                    },
                    ..NewtonParams::default()
                };
                let newton = Newton::new(objective.pattern(), params)
                    .map_err(|e| solver_error(e.to_string()))?;
                Runner::Newton {
                    unknowns: vec![0.0; objective.dim()],
                    newton: Box::new(newton),
                    objective: Box::new(objective),
                }
            }
            SolverKind::Cg | SolverKind::CgTol | SolverKind::LinearizedCg => Runner::Linearized {
                solver: LinearSolver::ConjugateGradient,
            },
            SolverKind::Jacobi | SolverKind::JacobiTol | SolverKind::LinearizedJacobi => {
                Runner::Linearized {
                    solver: LinearSolver::Jacobi,
                }
            }
        })
    }

    /// (iteration limit, tolerance) of a setting: a count runs exactly that many iterations (no
    /// tolerance), a tolerance runs up to `tolerance_limit` iterations, `Default` is `default`.
    fn limits(setting: Setting, tolerance_limit: usize, default: (usize, f64)) -> (usize, f64) {
        match setting {
            Setting::Iterations(k) => (k, 0.0),
            Setting::Tolerance(t) => (tolerance_limit, t),
            Setting::Default => default,
        }
    }

    fn run(&mut self, problem: &BenchProblem, setting: Setting) -> Result<RunResult, String> {
        let springs = problem.scene.mesh().springs();
        match self {
            Runner::Pd { pd, x } => {
                let defaults = PdParams::default();
                let (max_iterations, tolerance) = Self::limits(
                    setting,
                    TOLERANCE_RUN_LIMIT,
                    (defaults.max_iterations, defaults.tolerance),
                );
                pd.params.max_iterations = max_iterations;
                pd.params.tolerance = tolerance;
                x.copy_from_slice(&problem.y);
                let start = Instant::now();
                let report = pd
                    .solve(springs, &problem.y, x)
                    .map_err(|e| e.to_string())?;
                let wall = start.elapsed();
                let note = (matches!(setting, Setting::Tolerance(_))
                    && report.stop != StopReason::Converged)
                    .then(|| format!("stopped at {TOLERANCE_RUN_LIMIT} iterations"));
                Ok(RunResult {
                    positions: x.clone(),
                    iterations: report.iterations,
                    wall,
                    factor: Some(pd.factor_time()),
                    note,
                })
            }
            Runner::Newton {
                newton,
                objective,
                unknowns,
            } => {
                let (max_iterations, tolerance) = Self::limits(setting, NEWTON_TOLERANCE_LIMIT, {
                    let d = NewtonParams::default();
                    (d.max_iterations, d.tolerance)
                });
                newton.params.max_iterations = max_iterations;
                newton.params.tolerance = tolerance;
                // newton-tol:T and newton:K keep the relative gradient's meaning (comparable
                // across solvers); the default row is the library's default criterion.
                newton.params.convergence = match setting {
                    Setting::Default => NewtonParams::default().convergence,
                    _ => Convergence::RelativeGradient,
                };
                objective.set_step(&problem.y, &problem.start.positions, unknowns);
                // Each run is a first solve: the factor held from an earlier run of this same
                // step (the warm-up, a repeat, another setting) would precondition its first
                // iterations with a matrix no simulation has at that point.
                newton.forget_held_factor();
                let report = newton
                    .minimize(objective.as_mut(), unknowns)
                    .map_err(|e| e.to_string())?;
                let note = match (setting, report.stop) {
                    (_, StopReason::RoundOff) => Some(format!(
                        "at the round-off floor, relative gradient {:.1e}",
                        report.gradient()
                    )),
                    (_, StopReason::Stagnated) => Some(format!(
                        "stagnated above the round-off floor (not converged), relative gradient \
                         {:.1e}",
                        report.gradient()
                    )),
                    (Setting::Tolerance(_), StopReason::IterationLimit) => {
                        Some(format!("stopped at {NEWTON_TOLERANCE_LIMIT} iterations"))
                    }
                    _ => None,
                };
                let shifted =
                    (report.shifted_steps > 0 || report.failed_factorizations > 0).then(|| {
                        format!(
                            "{} shifted step(s), {} failed factorisation(s)",
                            report.shifted_steps, report.failed_factorizations
                        )
                    });
                let regions = (report.region_solves > 0).then(|| {
                    format!(
                        "{} patch solve(s): {} inner iterations, {} factorisations",
                        report.region_solves,
                        report.region_iterations,
                        report.region_factorizations
                    )
                });
                let reuse = (report.reuse_iterations > 0).then(|| {
                    format!(
                        "{} CG iteration(s) on a held factor",
                        report.reuse_iterations
                    )
                });
                let exact_cg = (report.exact_cg_iterations > 0).then(|| {
                    format!(
                        "{} CG iteration(s) on the definite factor",
                        report.exact_cg_iterations
                    )
                });
                let note = [note, shifted, reuse, exact_cg, regions]
                    .into_iter()
                    .flatten()
                    .reduce(|a, b| format!("{a}; {b}"));
                Ok(RunResult {
                    positions: objective.positions(unknowns).to_vec(),
                    iterations: report.iterations,
                    wall: report.wall_time,
                    factor: Some(report.factor_time),
                    note,
                })
            }
            Runner::QuasiNewton {
                kind,
                pd,
                objective,
                unknowns,
            } => {
                objective.set_step(&problem.y, &problem.start.positions, unknowns);
                let (iterations, wall, stop, gradient, detail) =
                    if matches!(kind, SolverKind::Lbfgs | SolverKind::LbfgsTol) {
                        let defaults = LbfgsParams::default();
                        let (max_iterations, tolerance) = Self::limits(
                            setting,
                            TOLERANCE_RUN_LIMIT,
                            (defaults.max_iterations, defaults.tolerance),
                        );
                        let params = LbfgsParams {
                            max_iterations,
                            tolerance,
                            convergence: match setting {
                                Setting::Default => defaults.convergence,
                                _ => Convergence::RelativeGradient,
                            },
                            ..defaults
                        };
                        let mut lbfgs =
                            Lbfgs::new(unknowns.len(), params).map_err(|e| e.to_string())?;
                        let r = lbfgs
                            .minimize(objective.as_mut(), pd.as_mut(), unknowns)
                            .map_err(|e| e.to_string())?;
                        let detail = (r.skipped_pairs > 0 || r.restarts > 0).then(|| {
                            format!(
                                "{} curvature pair(s) skipped, {} restart(s)",
                                r.skipped_pairs, r.restarts
                            )
                        });
                        (r.iterations, r.wall_time, r.stop, r.gradient(), detail)
                    } else {
                        let defaults = NewtonCgParams::default();
                        let (max_iterations, tolerance) = Self::limits(
                            setting,
                            NEWTON_TOLERANCE_LIMIT,
                            (defaults.max_iterations, defaults.tolerance),
                        );
                        let params = NewtonCgParams {
                            max_iterations,
                            tolerance,
                            convergence: match setting {
                                Setting::Default => defaults.convergence,
                                _ => Convergence::RelativeGradient,
                            },
                            ..defaults
                        };
                        let mut solver =
                            NewtonCg::new(unknowns.len(), params).map_err(|e| e.to_string())?;
                        let amg_kind =
                            matches!(kind, SolverKind::NewtonCgAmg | SolverKind::NewtonCgAmgTol);
                        let (r, amg_setup) = if amg_kind {
                            // AMG on the clamped Hessian at y, set up inside the timed step.
                            let start = Instant::now();
                            let hessian = objective
                                .convexified_hessian(unknowns)
                                .ok_or("no clamped Hessian")?;
                            let modes = Amg::rigid_body_modes(unknowns);
                            let mut amg = Amg::new(hessian, 3, &modes, AmgParams::default())
                                .map_err(|e| e.to_string())?;
                            let setup = start.elapsed();
                            let r = solver
                                .minimize(objective.as_mut(), &mut amg, unknowns)
                                .map_err(|e| e.to_string())?;
                            (r, Some(setup))
                        } else {
                            let r = solver
                                .minimize(objective.as_mut(), pd.as_mut(), unknowns)
                                .map_err(|e| e.to_string())?;
                            (r, None)
                        };
                        let mut detail = format!("{} CG iterations", r.cg_iterations);
                        if let Some(setup) = amg_setup {
                            detail += &format!(
                                ", AMG set-up {:.1} ms (in step ms)",
                                setup.as_secs_f64() * 1e3
                            );
                        }
                        let r = NewtonCgReport {
                            wall_time: r.wall_time + amg_setup.unwrap_or_default(),
                            ..r
                        };
                        if r.negative_curvature > 0 {
                            detail += &format!(", {} at negative curvature", r.negative_curvature);
                        }
                        if r.cg_limit_hits > 0 {
                            detail += &format!(", {} at the CG limit", r.cg_limit_hits);
                        }
                        (
                            r.iterations,
                            r.wall_time,
                            r.stop,
                            r.gradient(),
                            Some(detail),
                        )
                    };
                let stop_note = match (setting, stop) {
                    (_, StopReason::RoundOff) => Some(format!(
                        "at the round-off floor, relative gradient {gradient:.1e}"
                    )),
                    (Setting::Tolerance(_), StopReason::IterationLimit) => {
                        Some("stopped at its iteration limit".to_string())
                    }
                    _ => None,
                };
                Ok(RunResult {
                    positions: objective.positions(unknowns).to_vec(),
                    iterations,
                    wall,
                    factor: (!matches!(kind, SolverKind::NewtonCgAmg | SolverKind::NewtonCgAmgTol))
                        .then(|| pd.factor_time()),
                    note: [stop_note, detail]
                        .into_iter()
                        .flatten()
                        .reduce(|a, b| format!("{a}; {b}")),
                })
            }
            Runner::Chebyshev { pd, rate, x } => {
                let (max_iterations, _) = Self::limits(setting, TOLERANCE_RUN_LIMIT, (10, 0.0));
                let params = ChebyshevParams {
                    max_iterations,
                    rate: *rate,
                    ..ChebyshevParams::default()
                };
                let mut solver =
                    ChebyshevPd::<3>::new(x.len(), params).map_err(|e| e.to_string())?;
                x.copy_from_slice(&problem.y);
                let report = solver
                    .solve(pd, springs, &problem.y, x)
                    .map_err(|e| e.to_string())?;
                let mut note = format!("ρ = {rate:.4}");
                if report.restarts > 0 {
                    note += &format!(", {} restart(s)", report.restarts);
                }
                if report.rollbacks > 0 {
                    note += &format!(" ({} rolled back)", report.rollbacks);
                }
                if report.stop == StopReason::Stagnated {
                    note += ", stopped where even plain PD raised Φ (its rounding floor; not converged)";
                }
                Ok(RunResult {
                    positions: x.clone(),
                    iterations: report.iterations,
                    wall: report.wall_time,
                    factor: Some(pd.factor_time()),
                    note: Some(note),
                })
            }
            Runner::Anderson { pd, x } => {
                let (max_iterations, _) = Self::limits(setting, TOLERANCE_RUN_LIMIT, (10, 0.0));
                let params = AndersonParams {
                    max_iterations,
                    ..AndersonParams::default()
                };
                let mut solver =
                    AndersonPd::<3>::new(x.len(), params).map_err(|e| e.to_string())?;
                x.copy_from_slice(&problem.y);
                let report = solver
                    .solve(pd, springs, &problem.y, x)
                    .map_err(|e| e.to_string())?;
                Ok(RunResult {
                    positions: x.clone(),
                    iterations: report.iterations,
                    wall: report.wall_time,
                    factor: Some(pd.factor_time()),
                    note: Some(format!(
                        "window {}, {} Anderson point(s) accepted, {} refused by the energy guard",
                        params.window, report.accepted, report.rejected
                    )),
                })
            }
            Runner::Linearized { solver } => {
                let defaults = LinearizedParams::default();
                let (max_iterations, tolerance) = match setting {
                    Setting::Iterations(k) => (k, f64::MIN_POSITIVE),
                    Setting::Tolerance(t) => (TOLERANCE_RUN_LIMIT, t),
                    Setting::Default => (defaults.max_iterations, defaults.tolerance),
                };
                let settings = Settings {
                    integrator: Integrator::Linearized,
                    linearized: LinearizedParams {
                        beta: 1.0,
                        solver: *solver,
                        tolerance,
                        max_iterations,
                        ..defaults
                    },
                    ..Settings::default()
                };
                let mut sim =
                    Simulation::new(problem.scene.clone(), problem.start.clone(), settings)
                        .map_err(|e| e.to_string())?;
                let report = sim.step().map_err(|e| e.to_string())?;
                let summary = report
                    .solver
                    .ok_or("the linearised step reported no solve")?;
                let mut notes = Vec::new();
                if report.clamped_hessian {
                    notes.push("clamped Hessian (the exact one was not positive definite)".into());
                }
                if !matches!(setting, Setting::Iterations(_))
                    && summary.stop == StopReason::IterationLimit
                {
                    notes.push(format!(
                        "linear solve stopped at its iteration limit, residual {:.1e}",
                        summary.residual
                    ));
                }
                Ok(RunResult {
                    positions: sim.state().positions.clone(),
                    iterations: summary.iterations,
                    wall: report.wall_time,
                    factor: None,
                    note: (!notes.is_empty()).then(|| notes.join("; ")),
                })
            }
        }
    }
}
