//! `--time-error`: the time-discretisation error of docs/model.md §9.3, reported apart from the
//! error of one solve.
//!
//! Every integrator runs the scene for `duration` (1 s) at the scene's step h with its settings;
//! its positions at the end are compared with two references run over the same time:
//! - backward Euler at h/`divisor` (h/64), by Newton to the library's tolerance: what the implicit
//!   integrators converge to as h shrinks, so it measures their time-discretisation error alone;
//! - symplectic Euler at its safe stable step: a second-order-accurate path for these scenes' smooth
//!   motion (no contact), closer to the continuous dynamics than any step of size h.
//!
//! The error is |x − x_ref| / |x_ref − x₀| over all vertices (pinned ones agree in every run): the
//! position error of docs/model.md §9.2 with the start of the run in place of x_n.

use std::time::Instant;

use serde::Serialize;

use crate::bench::BenchError;
use crate::sim::scenes::Setup;
use crate::sim::{stability_bound, Integrator, Settings, Simulation};

/// How [`time_error`] runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeErrorOptions {
    /// Simulated time (s). Default 1.
    pub duration: f64,
    /// The backward Euler reference's step is h / `divisor`. Default 64.
    pub divisor: usize,
    /// The most substeps any run may take in total (explicit methods at tiny stable steps are
    /// reported as skipped beyond it). Default 10⁷.
    pub max_substeps: usize,
}

impl Default for TimeErrorOptions {
    fn default() -> Self {
        TimeErrorOptions {
            duration: 1.0,
            divisor: 64,
            max_substeps: 10_000_000,
        }
    }
}

/// One integrator's run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeErrorRow {
    /// The integrator's name.
    pub integrator: String,
    /// Steps of h taken.
    pub steps: usize,
    /// Substeps per step (explicit methods), 1 otherwise.
    pub substeps: usize,
    /// Wall time of the run (s).
    pub wall_time_s: f64,
    /// |x − x_BE(h/divisor)| / |x_BE(h/divisor) − x₀| at the end (absent if the run did not finish).
    pub error_vs_backward_euler: Option<f64>,
    /// |x − x_SE| / |x_SE − x₀| at the end, x_SE symplectic Euler at its stable step (absent if
    /// that reference or the run did not finish).
    pub error_vs_symplectic: Option<f64>,
    /// `ok`, or why the run did not finish (refused at set-up, or its error).
    pub outcome: String,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeErrorReport {
    /// The scene.
    pub scene: String,
    /// Its time step h (s).
    pub time_step: f64,
    /// Simulated time (s): `steps` · h.
    pub duration: f64,
    /// The backward Euler reference's step (s).
    pub backward_euler_step: f64,
    /// The symplectic Euler reference's substep (s), if it ran.
    pub symplectic_step: Option<f64>,
    /// One row per integrator.
    pub rows: Vec<TimeErrorRow>,
}

/// Positions after `steps` steps of `settings` on `setup`'s scene with step `h`, the substeps
/// per step, and the wall time; `Err` with the reason if the run is refused or fails.
fn run(
    setup: &Setup<3>,
    h: f64,
    steps: usize,
    settings: Settings,
) -> Result<(Vec<nalgebra::Vector3<f64>>, usize, f64), String> {
    let scene = setup
        .scene
        .clone()
        .with_time_step(h)
        .map_err(|e| e.to_string())?;
    let start = Instant::now();
    let mut sim =
        Simulation::new(scene, setup.initial.clone(), settings).map_err(|e| e.to_string())?;
    for _ in 0..steps {
        sim.step().map_err(|e| e.to_string())?;
    }
    Ok((
        sim.state().positions.clone(),
        sim.substeps(),
        start.elapsed().as_secs_f64(),
    ))
}

/// |x − r| / |r − x₀|; `None` if the reference did not move.
fn relative_error(
    x: &[nalgebra::Vector3<f64>],
    reference: &[nalgebra::Vector3<f64>],
    start: &[nalgebra::Vector3<f64>],
) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for ((a, r), s) in x.iter().zip(reference).zip(start) {
        num += (a - r).norm_squared();
        den += (r - s).norm_squared();
    }
    (den > 0.0).then(|| (num / den).sqrt())
}

/// Run every integrator of [`Integrator::ALL`] on `setup` for `options.duration` and measure its
/// time-discretisation error against both references (see the module documentation).
///
/// # Errors
/// [`BenchError::Scene`] if the duration or divisor is invalid or the backward Euler reference
/// fails (without it nothing can be measured).
pub fn time_error(
    setup: &Setup<3>,
    options: &TimeErrorOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<TimeErrorReport, BenchError> {
    let h = setup.scene.time_step();
    if !(options.duration > 0.0 && options.duration.is_finite()) || options.divisor == 0 {
        return Err(BenchError::Scene(format!(
            "--time-error needs a finite duration > 0 and a divisor ≥ 1 (got {} s and {})",
            options.duration, options.divisor
        )));
    }
    let steps = (options.duration / h).round().max(1.0) as usize;
    let start = &setup.initial.positions;
    let newton = Settings {
        integrator: Integrator::Newton,
        ..setup.settings
    };
    let fine = h / options.divisor as f64;
    progress(&format!(
        "reference: backward Euler at h/{} = {fine:.3e} s, {} steps",
        options.divisor,
        steps * options.divisor
    ));
    let (backward, _, seconds) = run(setup, fine, steps * options.divisor, newton)
        .map_err(|e| BenchError::Scene(format!("the backward Euler reference failed: {e}")))?;
    progress(&format!("reference done in {seconds:.1} s"));

    // Symplectic Euler at the safe step of its stability bound.
    let bound = stability_bound(&setup.scene);
    let (safe, _) = bound.for_integrator(Integrator::SymplecticEuler, h);
    let substeps = (h / safe).ceil().max(1.0) as usize;
    let symplectic = if substeps.saturating_mul(steps) <= options.max_substeps {
        let settings = Settings {
            integrator: Integrator::SymplecticEuler,
            substeps: Some(substeps),
            ..setup.settings
        };
        progress(&format!(
            "reference: symplectic Euler at {:.3e} s ({substeps} substeps per step)",
            h / substeps as f64
        ));
        run(setup, h, steps, settings).ok().map(|(x, _, _)| x)
    } else {
        None
    };

    let mut rows = Vec::new();
    for &integrator in Integrator::ALL {
        let settings = Settings {
            integrator,
            substeps: None,
            ..setup.settings
        };
        progress(&format!("{integrator}: {steps} steps of {h:.4} s"));
        let row = match run(setup, h, steps, settings) {
            Ok((x, substeps, wall)) => TimeErrorRow {
                integrator: integrator.name().to_string(),
                steps,
                substeps,
                wall_time_s: wall,
                error_vs_backward_euler: relative_error(&x, &backward, start),
                error_vs_symplectic: symplectic
                    .as_ref()
                    .and_then(|r| relative_error(&x, r, start)),
                outcome: "ok".to_string(),
            },
            Err(reason) => TimeErrorRow {
                integrator: integrator.name().to_string(),
                steps,
                substeps: 0,
                wall_time_s: 0.0,
                error_vs_backward_euler: None,
                error_vs_symplectic: None,
                outcome: reason,
            },
        };
        rows.push(row);
    }
    Ok(TimeErrorReport {
        scene: setup.name.clone(),
        time_step: h,
        duration: steps as f64 * h,
        backward_euler_step: fine,
        symplectic_step: symplectic.as_ref().map(|_| h / substeps as f64),
        rows,
    })
}

/// The report as a table.
pub fn format_time_error(report: &TimeErrorReport) -> String {
    let sci = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2e}"));
    let mut out = format!(
        "{}: time-discretisation error after {:.3} s at h = {:.4} s; references: backward Euler \
         at {:.3e} s, symplectic Euler at {}\n",
        report.scene,
        report.duration,
        report.time_step,
        report.backward_euler_step,
        report
            .symplectic_step
            .map_or("- (not run: too many substeps)".to_string(), |s| format!(
                "{s:.3e} s"
            )),
    );
    out += &format!(
        "{:<18} {:>6} {:>9} {:>10} {:>12} {:>12}  outcome\n",
        "integrator", "steps", "substeps", "wall s", "vs BE(h/k)", "vs SE"
    );
    for r in &report.rows {
        out += &format!(
            "{:<18} {:>6} {:>9} {:>10.3} {:>12} {:>12}  {}\n",
            r.integrator,
            r.steps,
            r.substeps,
            r.wall_time_s,
            sci(r.error_vs_backward_euler),
            sci(r.error_vs_symplectic),
            r.outcome
        );
    }
    out
}
