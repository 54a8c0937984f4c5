//! Speed against error (docs/model.md §9): the library behind `hooke bench`.
//!
//! One backward Euler step is solved by every solver and setting asked for, from the same state and
//! the same initial guess x⁰ = y; each result x is timed and measured against the exact solution x*.
//!
//! - [`BenchProblem::prepare`] builds the step: the speed-vs-error state (docs/scenes.md §8; 10
//!   steps of exact backward Euler from rest, Newton to a relative gradient of 1e-10), its inertial
//!   target y = x_n + h v_n + h² g, and the reference x* (Newton to 1e-10 from y), cached in a file
//!   keyed by the scene because large scenes take minutes;
//! - [`SolverSpec`] parses `pd:1,2,5`, `newton:1,2,3`, `newton-tol:1e-4`, `cg-tol:1e-2`,
//!   `jacobi:10`, `linearized-cg`, …;
//! - [`run_spec`] times each setting (median of repeats, factorisations reported apart) and measures
//!   it with an [`ErrorMeter`] ([`Measures`]: objective error, position error, relative force
//!   residual);
//! - [`write_json`], [`write_csv`], [`format_table`], [`plot_pareto`] report [`Record`]s;
//! - [`sweep`] times one step on cloth-N for several N; [`hard_cases`] runs every integrator on the
//!   hard cases of docs/scenes.md §6; [`contact_kernels`] times the self-contact work of one
//!   Newton iteration on two OBJ files; [`time_error`] runs every integrator for 1 s and reports its
//!   time-discretisation error against small-step references.
//!
//! ```no_run
//! use hooke_cli::bench::{BenchProblem, ErrorMeter, PrepareOptions, SolverSpec, TimingOptions};
//!
//! let setup = hooke_cli::bench::load_setup("cloth-10")?;
//! let options = PrepareOptions { reference: true, ..PrepareOptions::default() };
//! let problem = BenchProblem::prepare(&setup, &options, &mut |line| eprintln!("{line}"))?;
//! let mut meter = ErrorMeter::new(&problem);
//! let spec: SolverSpec = "pd:10".parse()?;
//! let outcomes =
//!     hooke_cli::bench::run_spec(&problem, &mut meter, &spec, TimingOptions::default(), &mut |_| {})?;
//! println!("{:?}", outcomes[0].record);
//! # Ok::<(), hooke_cli::bench::BenchError>(())
//! ```

pub(crate) mod cli;
mod export;
mod hard;
mod measure;
mod output;
mod plot;
mod run;
mod self_contact_kernels;
mod spec;
mod state;
mod sweep;
mod time_error;

use std::path::PathBuf;

pub use cli::{run_command, BenchArgs};
pub use export::{export_system, StepSystems, EXPORT_FILES};
pub use hard::{
    deepest_penetration, energy_scale, hard_case, hard_case_settings, hard_cases, hard_scene,
    run_hard_case, HardCaseOptions, HardOutcome, HardResult, RunStats, BUNNY_DROP_FRAMES,
    HARD_CASES, HARD_CASE_OVERRIDES, HARD_INTEGRATORS, HARD_OPT_IN_INTEGRATORS, HARD_OPT_IN_SCENES,
    HARD_SCENES,
};
pub use measure::{ErrorMeter, Measures};
pub use output::{
    format_hard_cases, format_sweep_table, format_table, frame_file_name, read_csv, write_csv,
    write_frames, write_json, COLUMNS,
};
pub(crate) use plot::{fitted_log_range, log_axis, log_tick_label};
pub use plot::{plot_fronts, plot_pareto, plot_sweep};
pub use run::{run_spec, Outcome, Record, TimingOptions};
pub use self_contact_kernels::{contact_kernels, format_contact, ContactTimings};
pub use spec::{Setting, SolverKind, SolverSpec};
pub use state::{
    inertial_target, load_setup, BenchProblem, PrepareOptions, ReferenceInfo, StartState,
    REFERENCE_MAX_ITERATIONS, REFERENCE_TOLERANCE, STATE_STEPS,
};
pub use sweep::{peak_memory_bytes, sweep, SweepOptions, SweepRow};
pub use time_error::{
    format_time_error, time_error, TimeErrorOptions, TimeErrorReport, TimeErrorRow,
};

/// Everything `hooke bench` can fail with. Bad specifications and scenes are errors, never panics.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BenchError {
    /// The scene name is neither a built-in scene nor a file.
    #[error("unknown scene {0:?}: not a built-in scene (see `hooke scenes`) and not a file")]
    UnknownScene(String),
    /// The scene could not be built or read.
    #[error("scene: {0}")]
    Scene(String),
    /// The scene argument names a mesh file or a fluid scene, which the benchmark does not
    /// measure: why, and the command that takes it.
    #[error("{0}")]
    NotASpringScene(String),
    /// The scene has a term the backward Euler objective of the benchmark does not model.
    #[error("{scene}: the benchmark cannot measure this scene: it has {what}")]
    Unsupported {
        /// The scene.
        scene: String,
        /// What it has.
        what: String,
    },
    /// A `--solver` spec names no known solver.
    #[error(
        "unknown solver in {spec:?}: {name:?}; expected one of: {}",
        SolverKind::ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
    )]
    UnknownSolver {
        /// The whole spec.
        spec: String,
        /// The name part.
        name: String,
    },
    /// A value in a `--solver` spec is not valid for that solver.
    #[error("invalid value {value:?} in solver spec {spec:?}: {reason}")]
    BadSetting {
        /// The whole spec.
        spec: String,
        /// The offending value.
        value: String,
        /// What was expected.
        reason: String,
    },
    /// A `--sweep` argument is not `N=n1,n2,…`.
    #[error("invalid --sweep {0:?}: expected N=10,20,40 (cloth sizes, each at least 2)")]
    BadSweep(String),
    /// A step of the exact run to the speed-vs-error state failed.
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    /// The reference solve did not reach its tolerance.
    #[error("{scene}: the reference solve failed: {reason}")]
    Reference {
        /// The scene.
        scene: String,
        /// What happened.
        reason: String,
    },
    /// A solver could not be set up for the scene.
    #[error("{scene}: {solver} could not be set up: {reason}")]
    Solver {
        /// The scene.
        scene: String,
        /// The solver.
        solver: String,
        /// Why.
        reason: String,
    },
    /// The state cache could not be written.
    #[error("bench cache {}: {reason}", path.display())]
    Cache {
        /// The cache file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// An output file could not be written.
    #[error("{}: {reason}", path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
}
