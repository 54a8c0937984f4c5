//! `hooke run` and `hooke scenes`, and the dispatch of every subcommand.

use crate::checkpoint::{self, Checkpoint, CheckpointError};
use crate::output;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::str::FromStr;
use std::time::Instant;

use crate::mesh::io::{write_obj, write_vtk_with_data, Frame, FrameData};
use crate::mesh::MeshError;
use crate::sim::file::{load_scene, FrameFormat, SceneFileError};
use crate::sim::scenes::{self, AnySetup, Setup};
use crate::sim::{
    parse_energy_limit, Integrator, LinearSolver, PinMethod, RelaxationPreset, SimError,
    Simulation, SolverOptions,
};
use crate::solvers::{GlobalSolveKind, MemoryBudget};
use crate::test_hook::Halt;
use clap::{Parser, Subcommand, ValueEnum};

use output::{
    progress_bar, remove_leftovers, render_preview, write_atomically, write_summary, write_timings,
    OutputError, ResidualRecord, RunSummary, RunTimings, ScenePreview, SelfContactRecord,
    SolverSettingsRecord, StepRecord, StepTiming,
};

/// The scene `hooke run` uses without an argument.
const DEFAULT_SCENE: &str = "cloth-40";

/// `summary.json` is written after every this many frames during a run, besides at its end, so
/// that a long run can be followed and a killed one leaves its records up to at most this many
/// frames before the kill. The summary of n frames is about [`SUMMARY_RECORD_BYTES`]·n bytes, so
/// rewriting it every K frames costs about 400·n/K bytes a frame: with K = 100, less than a
/// cloth-10 OBJ frame (about 8 kB) up to n ≈ 2,000 and less than a cloth-40 frame (about 140 kB)
/// up to n ≈ 35,000. The built-in scenes run 30 to 300 frames, at up to a few hundred a second, so
/// their summary lags by a second of computation at most. Beyond [`WARN_FRAMES`] the run is warned
/// of.
const SUMMARY_EVERY: usize = 100;

/// About how many bytes a frame's record takes in `summary.json` (pretty-printed; 380 for Newton's
/// records of cloth-10, which carry the solver's fields).
const SUMMARY_RECORD_BYTES: u64 = 400;

/// A run of more frames than this is warned of before it starts: more than 30 times the longest
/// built-in scene (300 frames), and from there on the periodic `summary.json` (4 MB and more)
/// costs about as much as the frames of a small scene.
const WARN_FRAMES: usize = 10_000;

/// A run whose frames are estimated (from the size of a frame already written) to take more than
/// this many bytes is warned of before it starts: 1 GB.
const WARN_BYTES: u64 = 1_000_000_000;

#[derive(Parser)]
#[command(
    name = "hooke",
    version,
    about = "Mass-spring simulation with implicit solvers"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in scenes.
    Scenes,
    /// Run a scene and write frames, summary.json and preview.png.
    Run(RunArgs),
    /// Speed against error: time solvers on one backward Euler step and measure their errors.
    Bench(crate::bench::BenchArgs),
    /// The interactive 2D mass-spring editor, in a window (which can record the session) or
    /// replayed headless from an event script (docs/editor.md).
    Edit(crate::edit_command::EditArgs),
    /// Tetrahedral meshes: fill a closed surface (tetrahedralize), report a mesh's quality.
    Mesh(crate::mesh_command::MeshArgs),
}

/// The arguments of `hooke run`; a checkpoint records them (see [`RunArgs::for_checkpoint`]).
#[derive(clap::Args, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct RunArgs {
    /// A built-in scene name (see `hooke scenes`) or a scene file (.toml); the help lists the
    /// names (from the lists `hooke scenes` prints).
    #[arg(default_value = DEFAULT_SCENE, help = crate::scene_arg::run_scene_help())]
    scene: String,
    /// Time integrator, by name; the help lists every one the parser accepts (from
    /// `Integrator::ALL`). Default: the scene's.
    #[arg(long, value_name = "NAME", help = crate::scene_arg::run_integrator_help())]
    integrator: Option<String>,
    /// β of the linearized integrator, in [0, 1]: 0 explicit, 0.5 midpoint-like, 1 linearised
    /// backward Euler (default 1).
    #[arg(long, value_name = "B", allow_negative_numbers = true)]
    beta: Option<f64>,
    /// Linear solver of the linearized integrator: jacobi or cg (conjugate gradient with a
    /// block-Jacobi preconditioner; default).
    #[arg(long, value_name = "NAME")]
    linear_solver: Option<String>,
    /// Solver iterations: the linear solver's limit (linearized, default 1000), Newton's iteration
    /// limit (newton, default 100), iterations per step (pd, default 10).
    #[arg(long, value_name = "K")]
    iterations: Option<usize>,
    /// Tolerance: the linear solver's relative residual (linearized, > 0, default 1e-8); for
    /// newton, newton-cg and lbfgs the step size in m/s, the largest vertex displacement of a
    /// Newton step divided by h (≥ 0, default 1e-5); for pd and pd-chebyshev the largest position
    /// change of an iteration divided by h, in m/s (≥ 0, default 0: run all iterations).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    tolerance: Option<f64>,
    /// Newton's relaxation between its steps (newton only): none (plain Newton, the default) or
    /// buckling (block sweeps and the elimination of folds; faster on crushed cloth and large
    /// buckling cloth, 2x on a cloth-160 run; slower on small cloth). Default: the scene file's,
    /// else none.
    #[arg(long, value_name = "none|buckling")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    relaxation: Option<String>,
    /// Newton's factor reuse (newton only): how many CG iterations a Newton system may take on the
    /// factor held from an earlier Newton matrix before the matrix is factored; 0 factors every
    /// Newton matrix. Default: the scene file's, else 4 (2x faster on bunny-drop, the same on
    /// cloth).
    #[arg(long, value_name = "N")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    factor_reuse: Option<usize>,
    /// The most memory a sparse Cholesky factor may take (newton, pd, pd-chebyshev, lbfgs,
    /// newton-cg): bytes with an optional unit K, M, G or T (powers of 1024), e.g. 4G; machine
    /// (half the physical memory); or unlimited. Above it Newton solves its systems by CG with
    /// the AMG preconditioner instead of factoring them, and the PD-based integrators solve their
    /// global step by CG with AMG (docs/solvers.md §2.5, §6.1). Default: the scene file's, else
    /// machine.
    #[arg(long, value_name = "BYTES|machine|unlimited")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    memory_budget: Option<String>,
    /// How pd, pd-chebyshev, lbfgs and newton-cg solve with the PD matrix: direct (its Cholesky
    /// factor), multilevel (CG with a multigrid V-cycle, no factor) or auto (multilevel above
    /// 50,000 free vertices or the memory budget; docs/solvers.md §6.1). Default: the scene
    /// file's, else auto.
    #[arg(long, value_name = "auto|direct|multilevel")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pd_global_solve: Option<String>,
    /// Number of frames to run (default: the scene's; fluid scenes: 50 to t = 1 s for the dam
    /// breaks, 40 to 2 s for hydrostatic-2d).
    #[arg(long)]
    steps: Option<usize>,
    /// Fluid scenes only: the lattice spacing Δx in metres (default: the scene's, 0.02 in 2D and
    /// 0.04 in 3D, or the scene file's dx).
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dx: Option<f64>,
    /// Frame time step in seconds (default: the scene's; fluid scenes: the simulated time between
    /// frames, 0.02 s for the dam breaks and 0.05 s for hydrostatic-2d, the fluid taking its own
    /// stable steps in between).
    #[arg(long, allow_negative_numbers = true)]
    dt: Option<f64>,
    /// Substeps per frame for explicit integrators (default: from the stability bound).
    #[arg(long)]
    substeps: Option<usize>,
    /// Run an explicit integrator even above its stability bound.
    #[arg(long)]
    force: bool,
    /// Energy watchdog: stop with an error when the total energy rises above
    /// E₀ + FACTOR·(|E₀| + M|g|L) (E₀ the initial energy, M the total mass, L the diagonal of the
    /// initial bounding box), a gain no scene without energy sources can make except by instability.
    /// A factor >= 0, or `off` to disable the watchdog. Default: the scene file's, else 1. Not
    /// checked for scenes with wind or moving pins, nor with --force.
    #[arg(long, value_name = "FACTOR|off", allow_negative_numbers = true)]
    energy_limit: Option<String>,
    /// How the implicit integrators hold pinned vertices: reduction (pinned DOFs removed from the
    /// unknowns; default) or counter-force (every DOF kept, the force on a pinned vertex cancelled
    /// with its Jacobian). Both give the same steps up to round-off; pd supports only reduction.
    /// Default: the scene file's, else reduction.
    #[arg(long, value_name = "reduction|counter-force")]
    pin_method: Option<String>,
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Frame file format (default: the scene file's, else obj).
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// No progress bar.
    #[arg(long, short)]
    #[serde(skip)]
    quiet: bool,
    /// Write a checkpoint, DIR/checkpoint.json, after every K-th frame (replacing the previous
    /// one, atomically), from which `hooke run --resume DIR` continues the run.
    #[arg(long, value_name = "K")]
    checkpoint_every: Option<usize>,
    /// Continue the run in DIR from its last checkpoint, with the checkpoint's scene and settings
    /// (no other argument but --quiet and --steps may be given): its frames and summary.json are
    /// then those of a run that was never stopped. With --steps N the run goes on to frame N
    /// instead: a finished or interrupted run is extended to N frames (N at least the checkpoint's
    /// frame), leaving what a run started with --steps N leaves.
    #[arg(long, value_name = "DIR", conflicts_with_all = [
        "scene", "integrator", "beta", "linear_solver", "iterations", "tolerance", "relaxation",
        "factor_reuse", "memory_budget", "pd_global_solve",
        "dx", "dt",
        "substeps", "force", "energy_limit", "pin_method", "out", "format", "checkpoint_every",
    ])]
    #[serde(skip)]
    resume: Option<PathBuf>,
    /// For tests: stop like a killed run right after frame N is written (no summary, no
    /// preview), with an error.
    #[arg(long, value_name = "N", hide = true)]
    #[serde(skip)]
    stop_after: Option<usize>,
}

impl RunArgs {
    /// The scene argument: a built-in scene's name or a scene file's path.
    pub(crate) fn scene(&self) -> &str {
        &self.scene
    }

    /// The arguments a checkpoint records: the scene file by its absolute path, and nothing that
    /// only concerns this process (output directory, progress bar, resumption, test hook).
    pub(crate) fn for_checkpoint(&self) -> RunArgs {
        RunArgs {
            scene: checkpoint::absolute_scene(&self.scene),
            integrator: self.integrator.clone(),
            beta: self.beta,
            linear_solver: self.linear_solver.clone(),
            iterations: self.iterations,
            tolerance: self.tolerance,
            relaxation: self.relaxation.clone(),
            factor_reuse: self.factor_reuse,
            memory_budget: self.memory_budget.clone(),
            pd_global_solve: self.pd_global_solve.clone(),
            steps: self.steps,
            dx: self.dx,
            dt: self.dt,
            substeps: self.substeps,
            force: self.force,
            energy_limit: self.energy_limit.clone(),
            pin_method: self.pin_method.clone(),
            out: PathBuf::new(),
            format: self.format,
            quiet: false,
            checkpoint_every: self.checkpoint_every,
            resume: None,
            stop_after: None,
        }
    }
}

#[derive(Clone, Copy, ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
enum Format {
    Obj,
    Vtk,
}

/// Everything the command can fail with.
#[derive(Debug, thiserror::Error)]
enum CliError {
    #[error("unknown scene {0:?}: not a built-in scene (see `hooke scenes`) and not a file")]
    UnknownScene(String),
    /// The scene argument names something else than a scene (a mesh file): why, and what to do.
    #[error("{0}")]
    NotAScene(String),
    #[error(transparent)]
    SceneFile(#[from] SceneFileError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("invalid --{name}: {reason}")]
    Argument { name: &'static str, reason: String },
    #[error(transparent)]
    Bench(#[from] crate::bench::BenchError),
    #[error(transparent)]
    Edit(#[from] crate::edit_command::EditError),
    #[error(transparent)]
    MeshCommand(#[from] crate::mesh_command::MeshCommandError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("stopped after frame {0} (--stop-after)")]
    Stopped(usize),
    #[error("invalid HOOKE_TEST_HALT (a test hook): {0}")]
    TestHook(String),
    #[error(transparent)]
    Sph(#[from] crate::sph::SphCliError),
}

/// Parses the command line, runs the command and reports any error on standard error.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Scenes) => {
            for (name, description) in scenes::builtin_scenes() {
                println!("{name:<18} {description}");
            }
            for (name, description) in crate::sph::builtin_scenes() {
                println!("{name:<18} {description}");
            }
            Ok(())
        }
        Some(Command::Run(args)) => run(&args),
        Some(Command::Bench(args)) if args.sph.is_some() => {
            crate::sph::bench::run(&crate::sph::bench::SphBenchOptions::from_args(&args))
                .map_err(CliError::from)
        }
        Some(Command::Bench(args)) => crate::bench::run_command(&args).map_err(CliError::from),
        Some(Command::Edit(args)) => crate::edit_command::run(&args).map_err(CliError::from),
        Some(Command::Mesh(args)) => crate::mesh_command::run(&args).map_err(CliError::from),
        None => run(&RunArgs {
            scene: DEFAULT_SCENE.into(),
            out: "out".into(),
            ..RunArgs::default()
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let mut shown = e.to_string();
            eprintln!("error: {shown}");
            let mut source = std::error::Error::source(&e);
            while let Some(s) = source {
                // Most messages already end with their cause: print each cause once.
                let cause = s.to_string();
                if !shown.contains(&cause) {
                    eprintln!("  caused by: {cause}");
                    shown = cause;
                }
                source = s.source();
            }
            ExitCode::FAILURE
        }
    }
}

fn run(args: &RunArgs) -> Result<(), CliError> {
    // A resumed run takes its arguments from the checkpoint.
    let (resumed_args, resume) = match &args.resume {
        Some(dir) => {
            let point = Checkpoint::read(dir)?;
            let recorded = point.args.for_checkpoint();
            let resumed = RunArgs {
                out: dir.clone(),
                quiet: args.quiet,
                stop_after: args.stop_after,
                // --steps extends (or shortens, down to the checkpoint) the run.
                steps: args.steps.or(recorded.steps),
                ..recorded
            };
            (Some(resumed), Some(point))
        }
        None => (None, None),
    };
    let args = resumed_args.as_ref().unwrap_or(args);
    let path = Path::new(&args.scene);
    if crate::sph::is_builtin(&args.scene) || (path.is_file() && crate::sph::is_fluid_file(path)) {
        return run_fluid(args);
    }
    if let Some(hint) = crate::scene_arg::mesh_file_hint(&args.scene) {
        return Err(CliError::NotAScene(hint));
    }
    if args.dx.is_some() {
        return Err(CliError::Argument {
            name: "dx",
            reason: "is for fluid scenes (see `hooke scenes`) only".into(),
        });
    }
    let (setup, file_format) = if path.extension().is_some_and(|e| e == "toml") || path.is_file() {
        let file = load_scene(path)?;
        (file.setup, file.format)
    } else {
        let setup = scenes::builtin(&args.scene)
            .ok_or_else(|| CliError::UnknownScene(args.scene.clone()))??;
        (setup, FrameFormat::Obj)
    };
    let format = match args.format {
        Some(Format::Obj) => FrameFormat::Obj,
        Some(Format::Vtk) => FrameFormat::Vtk,
        None => file_format,
    };
    match setup {
        AnySetup::Two(s) => run_setup(s, args, format, resume),
        AnySetup::Three(s) => run_setup(s, args, format, resume),
    }
}

fn run_setup<const D: usize>(
    mut setup: Setup<D>,
    args: &RunArgs,
    format: FrameFormat,
    resume: Option<Checkpoint>,
) -> Result<(), CliError> {
    if let Some(integrator) = parse_flag::<Integrator>(&args.integrator, "integrator")? {
        setup.settings.integrator = integrator;
    }
    let linear_solver = parse_flag::<LinearSolver>(&args.linear_solver, "linear-solver")?;
    let relaxation = parse_flag::<RelaxationPreset>(&args.relaxation, "relaxation")?;
    let pd_global_solve = parse_flag::<GlobalSolveKind>(&args.pd_global_solve, "pd-global-solve")?;
    let memory_budget = match &args.memory_budget {
        Some(text) => Some(
            MemoryBudget::parse(text).map_err(|reason| CliError::Argument {
                name: "memory-budget",
                reason,
            })?,
        ),
        None => None,
    };
    // One flag at a time, so that an error names its flag.
    for (name, options) in [
        (
            "beta",
            SolverOptions {
                beta: args.beta,
                ..SolverOptions::default()
            },
        ),
        (
            "linear-solver",
            SolverOptions {
                linear_solver,
                ..SolverOptions::default()
            },
        ),
        (
            "iterations",
            SolverOptions {
                iterations: args.iterations,
                ..SolverOptions::default()
            },
        ),
        (
            "tolerance",
            SolverOptions {
                tolerance: args.tolerance,
                ..SolverOptions::default()
            },
        ),
        (
            "relaxation",
            SolverOptions {
                relaxation,
                ..SolverOptions::default()
            },
        ),
        (
            "factor-reuse",
            SolverOptions {
                factor_reuse: args.factor_reuse,
                ..SolverOptions::default()
            },
        ),
        (
            "memory-budget",
            SolverOptions {
                memory_budget,
                ..SolverOptions::default()
            },
        ),
        (
            "pd-global-solve",
            SolverOptions {
                pd_global_solve,
                ..SolverOptions::default()
            },
        ),
    ] {
        setup
            .settings
            .apply_options(&options)
            .map_err(|e| CliError::Argument {
                name,
                reason: flag_reason(e),
            })?;
    }
    if let Some(pins) = parse_flag::<PinMethod>(&args.pin_method, "pin-method")? {
        setup.settings.pins = pins;
    }
    if let Some(dt) = args.dt {
        setup.scene = setup.scene.with_time_step(dt)?;
    }
    if let Some(steps) = args.steps {
        if steps == 0 {
            return Err(CliError::Argument {
                name: "steps",
                reason: "must be at least 1".into(),
            });
        }
        setup.steps = steps;
    }
    if args.checkpoint_every == Some(0) {
        return Err(CliError::Argument {
            name: "checkpoint-every",
            reason: "must be at least 1".into(),
        });
    }
    if args.substeps.is_some() {
        setup.settings.substeps = args.substeps;
    }
    setup.settings.allow_unstable |= args.force;
    if let Some(text) = &args.energy_limit {
        parse_energy_limit(text)
            .and_then(|limit| setup.settings.set_energy_limit(limit))
            .map_err(|e| CliError::Argument {
                name: "energy-limit",
                reason: flag_reason(e),
            })?;
    }

    let frames_dir = args.out.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(|source| CliError::Io {
        path: frames_dir.clone(),
        source,
    })?;

    // The temporary files of a killed writer (a new run's directory may be a killed run's too).
    remove_leftovers(&[&args.out, &frames_dir])?;
    let halt = Halt::from_env().map_err(CliError::TestHook)?;

    let name = setup.name.clone();
    let steps = setup.steps;
    let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings)?;
    let (resumed, recorded_steps) = match resume {
        Some(point) => {
            let recorded_steps = point.args.steps;
            (Some(point.restore(&args.out, &mut sim)?), recorded_steps)
        }
        None => (None, None),
    };
    if let Some(resumed) = &resumed {
        if resumed.frame > steps {
            return Err(CliError::Argument {
                name: "steps",
                reason: format!(
                    "{steps} is before the checkpoint's frame {}: a resumed run goes on from its \
                     checkpoint",
                    resumed.frame
                ),
            });
        }
        if recorded_steps != args.steps {
            // The checkpoint records the new length at once: the same file as a run started with
            // it writes there, and a resumption of this run (if it is stopped too) keeps the length.
            Checkpoint::new(args, resumed.frame, &sim, &resumed.steps)?.write(&args.out)?;
        }
    }
    // Frames after the checkpoint (or, for a new run, every frame) are an earlier process's.
    remove_stale_frames(&frames_dir, resumed.as_ref().map(|r| r.frame))?;
    let mesh = sim.scene().mesh().clone();
    let lines: Vec<[u32; 2]> = if mesh.triangles().is_empty() {
        mesh.springs().iter().map(|s| [s.i, s.j]).collect()
    } else {
        Vec::new()
    };
    let pinned_flags = sim.scene().is_pinned().to_vec();
    let extension = match format {
        FrameFormat::Obj => "obj",
        FrameFormat::Vtk => "vtk",
    };
    let frame_path = |index: usize| frames_dir.join(format!("frame_{index:04}.{extension}"));
    let write_frame = |index: usize, state: &crate::sim::State<D>| -> Result<(), CliError> {
        let frame = Frame {
            positions: &state.positions,
            triangles: mesh.triangles(),
            tetrahedra: mesh.tetrahedra(),
            lines: &lines,
        };
        // The lines, where there are any, are the springs in order.
        let strain: Vec<f64> = if lines.is_empty() || matches!(format, FrameFormat::Obj) {
            Vec::new()
        } else {
            mesh.springs()
                .iter()
                .map(|s| {
                    let r = state.positions[s.i as usize] - state.positions[s.j as usize];
                    r.norm() / s.rest_length - 1.0
                })
                .collect()
        };
        let data = FrameData {
            velocities: Some(&state.velocities),
            pinned: Some(&pinned_flags),
            line_strain: (!lines.is_empty()).then_some(&strain[..]),
        };
        let write = |mut out: &mut dyn std::io::Write| match format {
            FrameFormat::Obj => write_obj(&frame, &mut out),
            FrameFormat::Vtk => write_vtk_with_data(&frame, &data, &mut out),
        };
        write_atomically(&frame_path(index), |out| {
            if halt == Some(Halt::InFrame(index)) {
                let mut bytes = Vec::new();
                write(&mut bytes)?;
                std::io::Write::write_all(out, &bytes[..bytes.len() / 2])?;
                std::io::Write::flush(out)?;
                out.get_ref().sync_all()?;
                Halt::InFrame(index).halt();
            }
            write(out)
        })?;
        Ok(())
    };

    let settings = sim.settings();
    let mut summary = RunSummary {
        scene: name.clone(),
        integrator: settings.integrator.name().into(),
        dimension: D,
        vertices: mesh.vertex_count(),
        springs: mesh.springs().len(),
        time_step: sim.scene().time_step(),
        substeps: sim.substeps(),
        solver_settings: {
            let o = settings.solver_options();
            (o != SolverOptions::default()).then(|| SolverSettingsRecord {
                beta: o.beta,
                linear_solver: o.linear_solver.map(|s| s.name().to_string()),
                iterations: o.iterations,
                tolerance: o.tolerance,
                relaxation: o.relaxation.map(|r| r.name().to_string()),
                factor_reuse: o.factor_reuse,
                memory_budget: o.memory_budget.map(MemoryBudget::bytes),
                pd_global_solve: o.pd_global_solve.map(|k| k.name().to_string()),
            })
        },
        pin_method: Some(settings.pins.name().into()),
        solver_residual: settings
            .integrator
            .solver_residual()
            .map(|(quantity, unit)| ResidualRecord {
                quantity: quantity.into(),
                unit: unit.into(),
            }),
        chebyshev_rate: None,
        // Reserved up to a fixed size: the frame count is the user's.
        steps: Vec::with_capacity(steps.saturating_add(1).min(1 << 12)),
    };
    let record = |step: usize, sim: &Simulation<D>, report: Option<crate::sim::StepReport>| {
        let energy = sim.energy();
        StepRecord {
            step,
            time: sim.state().time,
            kinetic_energy: energy.kinetic,
            potential_energy: energy.potential,
            contact_energy: (sim.settings().integrator.uses_contact_barrier()
                && (!sim.scene().contacts().is_empty() || sim.self_contact_state().is_some()))
            .then_some(energy.contact),
            total_energy: energy.total,
            contact_distance: (!sim.scene().contacts().is_empty())
                .then(|| sim.smallest_contact_distance()),
            self_contact: sim.self_contact_state().map(|c| SelfContactRecord {
                smallest_distance: c
                    .smallest_distance
                    .is_finite()
                    .then_some(c.smallest_distance),
                point_triangle_pairs: c.point_triangle_pairs,
                edge_edge_pairs: c.edge_edge_pairs,
                stiffness: c.stiffness,
            }),
            barrier_stiffness_scale: sim.barrier_stiffness_scale(),
            inverted_tetrahedra: (!sim.scene().mesh().tetrahedra().is_empty())
                .then(|| sim.scene().inverted_tetrahedra(&sim.state().positions)),
            max_stretch: sim.scene().max_stretch(sim.state()),
            solver_iterations: report.and_then(|r| r.solver).map(|s| s.iterations),
            solver_residual: report.and_then(|r| r.solver).map(|s| s.residual),
            solver_stop: report
                .and_then(|r| r.solver)
                .map(|s| s.stop.name().to_string()),
            solver_converged: report.and_then(|r| r.converged),
            clamped_hessian: report.is_some_and(|r| r.clamped_hessian),
            halved_into: report
                .and_then(|r| r.solver)
                .map(|s| s.substeps)
                .filter(|&pieces| pieces > 1),
        }
    };
    let timing = |step: usize, report: Option<crate::sim::StepReport>| StepTiming {
        step,
        wall_time_s: report.map_or(0.0, |r| r.wall_time.as_secs_f64()),
    };
    eprintln!(
        "{name}: {} vertices, {} springs, {} with {} substep(s) of {:.3e} s (explicit bound ≈ {:.3e} s), {steps} frames",
        mesh.vertex_count(),
        mesh.springs().len(),
        settings.integrator,
        sim.substeps(),
        sim.scene().time_step() / sim.substeps() as f64,
        sim.stability_bound().estimated_step,
    );
    let start = Instant::now();
    let mut timings = RunTimings::default();
    let first = match resumed {
        Some(resumed) => {
            summary.steps = resumed.steps;
            timings.steps = resumed.timings;
            timings.resumed_after.push(resumed.frame);
            resumed.frame + 1
        }
        None => {
            write_frame(0, sim.state())?;
            summary.steps.push(record(0, &sim, None));
            timings.steps.push(timing(0, None));
            1
        }
    };
    warn_of_large_output(steps, &frame_path(first - 1), &args.out);
    let progress = progress_bar(steps as u64, args.quiet);
    progress.inc(first as u64 - 1);
    let mut failure = None;
    for step in first..=steps {
        match sim.step() {
            Ok(report) => {
                summary.steps.push(record(step, &sim, Some(report)));
                if summary.chebyshev_rate.is_none() {
                    summary.chebyshev_rate = sim.chebyshev_rate().map(rate_record);
                }
                timings.steps.push(timing(step, Some(report)));
                write_frame(step, sim.state())?;
                let checkpoint = args.checkpoint_every.is_some_and(|k| step % k == 0);
                let periodic_summary = step % SUMMARY_EVERY == 0 && step < steps;
                if checkpoint || periodic_summary {
                    // Timings first: a resumed run reads those up to its checkpoint back.
                    write_timings(&args.out.join("timings.json"), &timings)?;
                }
                if periodic_summary {
                    write_summary(&args.out.join("summary.json"), &summary)?;
                }
                if checkpoint {
                    Checkpoint::new(args, step, &sim, &summary.steps)?.write(&args.out)?;
                    // A run resumed from here starts without the solver's history: so does this one.
                    sim.forget_solver_history();
                }
                progress.inc(1);
                if args.stop_after == Some(step) {
                    progress.finish_and_clear();
                    return Err(CliError::Stopped(step));
                }
                if halt == Some(Halt::AfterFrame(step)) {
                    Halt::AfterFrame(step).halt();
                }
            }
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    progress.finish_and_clear();
    let unconverged = summary
        .steps
        .iter()
        .filter(|r| r.solver_converged == Some(false))
        .count();
    // PD and Chebyshev PD run a budget of iterations by design: not reaching a tolerance is their
    // normal stop.
    let budgeted = matches!(
        settings.integrator,
        Integrator::ProjectiveDynamics | Integrator::ChebyshevPd
    );
    if unconverged > 0 && !budgeted {
        eprintln!(
            "warning: the solver did not converge (stopped short of its tolerance) in \
             {unconverged} step(s) (see solver_converged and solver_stop in summary.json)"
        );
    }
    let clamped = summary.steps.iter().filter(|r| r.clamped_hessian).count();
    if clamped > 0 {
        eprintln!(
            "note: {clamped} step(s) used the clamped spring Hessian: the exact one gave a system \
             that is not positive definite"
        );
    }
    // The summary is written even after a failure, so that the steps before it can be inspected.
    write_summary(&args.out.join("summary.json"), &summary)?;
    write_timings(&args.out.join("timings.json"), &timings)?;
    if let Some(e) = failure {
        return Err(e.into());
    }
    let state = sim.state();
    let preview = ScenePreview::of(
        &name,
        sim.scene(),
        &state.positions,
        steps,
        state.time,
        settings.integrator,
    );
    render_preview(&args.out.join("preview.png"), &preview.input())?;
    let first = summary.steps.first().map_or(0.0, |r| r.total_energy);
    let last = summary.steps.last().map_or(0.0, |r| r.total_energy);
    eprintln!(
        "done in {:.2} s: energy {first:.6e} J → {last:.6e} J; wrote {}/frames ({} files), summary.json, timings.json, preview.png",
        start.elapsed().as_secs_f64(),
        args.out.display(),
        steps + 1
    );
    Ok(())
}

/// Warns on standard error, before a run of `steps` frames into `out` steps, when it is long
/// ([`WARN_FRAMES`]) or its frames are estimated to be large ([`WARN_BYTES`]): `frame` is a frame
/// file already written, whose size stands for every frame's.
fn warn_of_large_output(steps: usize, frame: &Path, out: &Path) {
    // Without the frame's size (an unreadable file), the frame count alone decides.
    let frame_bytes = std::fs::metadata(frame).map_or(0, |m| m.len());
    let total = frame_bytes.saturating_mul(steps as u64 + 1);
    if steps > WARN_FRAMES || total > WARN_BYTES {
        eprintln!(
            "warning: {steps} frames of about {} each will write about {} to {}/frames, and \
             summary.json (rewritten every {SUMMARY_EVERY} frames) grows to about {}",
            human_bytes(frame_bytes),
            human_bytes(total),
            out.display(),
            human_bytes(SUMMARY_RECORD_BYTES.saturating_mul(steps as u64 + 1)),
        );
    }
}

/// `bytes` with a decimal unit, to three significant digits: `512 B`, `1.23 MB`, `45.6 TB`.
fn human_bytes(bytes: u64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 999.5 && unit + 1 < units.len() {
        value /= 1000.0;
        unit += 1;
    }
    let decimals = match value {
        _ if unit == 0 => 0,
        v if v < 9.995 => 2,
        v if v < 99.95 => 1,
        _ => 0,
    };
    format!("{value:.decimals$} {}", units[unit])
}

/// The value of an optional flag parsed as `T`, or a [`CliError::Argument`] naming the flag.
fn parse_flag<T: FromStr>(value: &Option<String>, name: &'static str) -> Result<Option<T>, CliError>
where
    T::Err: std::fmt::Display,
{
    value
        .as_deref()
        .map(|text| {
            text.parse::<T>().map_err(|e| CliError::Argument {
                name,
                reason: e.to_string(),
            })
        })
        .transpose()
}

/// Why a flag's value was refused, in the flag's words: the library names the option it set
/// (`invalid iterations = 0: must be at least 1 for newton`), which the flag's name already says,
/// so only the value and the rule are kept (`0: must be at least 1 for newton`).
fn flag_reason(error: SimError) -> String {
    match error {
        SimError::InvalidParameter { value, reason, .. } => format!("{value}: {reason}"),
        other => other.to_string(),
    }
}

/// `hooke run` of a fluid scene: the spring integrators' options are refused.
fn run_fluid(args: &RunArgs) -> Result<(), CliError> {
    let not_for_fluid = [
        ("beta", args.beta.is_some()),
        ("linear-solver", args.linear_solver.is_some()),
        ("iterations", args.iterations.is_some()),
        ("tolerance", args.tolerance.is_some()),
        ("relaxation", args.relaxation.is_some()),
        ("factor-reuse", args.factor_reuse.is_some()),
        ("memory-budget", args.memory_budget.is_some()),
        ("pd-global-solve", args.pd_global_solve.is_some()),
        ("substeps", args.substeps.is_some()),
        ("force", args.force),
        ("energy-limit", args.energy_limit.is_some()),
        ("pin-method", args.pin_method.is_some()),
        ("checkpoint-every", args.checkpoint_every.is_some()),
        ("resume", args.resume.is_some()),
        ("stop-after", args.stop_after.is_some()),
        ("format", matches!(args.format, Some(Format::Obj))),
    ];
    if let Some((name, _)) = not_for_fluid.iter().find(|(_, given)| *given) {
        let reason = if *name == "format" {
            "fluid scenes always write VTK frames".to_string()
        } else {
            format!("is not an option of fluid scenes such as {}", args.scene)
        };
        return Err(CliError::Argument { name, reason });
    }
    crate::sph::run::run(&crate::sph::run::FluidRunOptions {
        scene: &args.scene,
        dx: args.dx,
        frames: args.steps,
        frame_interval: args.dt,
        integrator: args.integrator.as_deref(),
        out: &args.out,
        quiet: args.quiet,
    })
    .map_err(CliError::from)
}

/// Remove frame files of an earlier run (those after frame `keep_through`, when a run resumes
/// from its checkpoint there), so that the directory holds exactly this run's frames.
fn remove_stale_frames(dir: &Path, keep_through: Option<usize>) -> Result<(), CliError> {
    let io = |source| CliError::Io {
        path: dir.to_path_buf(),
        source,
    };
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let Some(index) = name
            .strip_prefix("frame_")
            .and_then(|rest| rest.strip_suffix(".obj").or(rest.strip_suffix(".vtk")))
        else {
            continue;
        };
        let kept = keep_through
            .is_some_and(|last| index.parse::<usize>().is_ok_and(|index| index <= last));
        if !kept {
            std::fs::remove_file(&path).map_err(|source| CliError::Io {
                path: path.clone(),
                source,
            })?;
        }
    }
    Ok(())
}

/// summary.json's record of Chebyshev PD's ρ.
fn rate_record(rate: crate::sim::RateSource) -> output::RateRecord {
    use crate::sim::RateSource;
    let source = match rate {
        RateSource::Given(_) => "given",
        RateSource::Estimated(_) => "estimated",
        RateSource::Fallback(_) => "fallback",
    };
    output::RateRecord {
        rate: rate.rate(),
        source: source.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_counts_read_with_three_digits() {
        assert_eq!(human_bytes(0), "0 B");
        assert_eq!(human_bytes(999), "999 B");
        assert_eq!(human_bytes(1_000), "1.00 kB");
        assert_eq!(human_bytes(5_286), "5.29 kB");
        assert_eq!(human_bytes(45_600_000), "45.6 MB");
        assert_eq!(human_bytes(500_000_000_000), "500 GB");
        assert_eq!(human_bytes(999_600_000), "1.00 GB");
        assert_eq!(human_bytes(u64::MAX), "18.4 EB");
    }
}
