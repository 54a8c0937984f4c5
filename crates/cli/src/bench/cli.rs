//! The `hooke bench` command: its arguments and what it does with them.

use std::path::PathBuf;
use std::time::Instant;

use crate::bench::{
    format_hard_cases, format_sweep_table, format_table, hard_cases, load_setup, plot_pareto,
    plot_sweep, run_spec, sweep, write_csv, write_frames, write_json, BenchError, BenchProblem,
    ErrorMeter, HardCaseOptions, PrepareOptions, Record, SolverSpec, StartState, SweepOptions,
    TimingOptions, HARD_CASES, HARD_INTEGRATORS, HARD_OPT_IN_SCENES, HARD_SCENES,
};
use crate::bench::{format_time_error, read_csv, time_error, TimeErrorOptions};

/// Arguments of `hooke bench`.
#[derive(clap::Args, Clone, Debug)]
#[command(after_help = BENCH_HELP)]
pub struct BenchArgs {
    /// A built-in scene (e.g. cloth-40, beam-4) or a scene file; not used with --sweep or
    /// --hard-cases. The help lists the built-in scenes by name.
    #[arg(default_value = "cloth-40", help = crate::scene_arg::bench_scene_help())]
    pub scene: String,
    /// Solver and settings, repeatable: `NAME` or `NAME:V1,V2,…` (one run per value), e.g.
    /// pd:1,2,5 or newton-tol:1e-4; the help lists every [`SolverKind`](crate::bench::SolverKind) with its values. A name
    /// alone takes its default settings.
    #[arg(long = "solver", value_name = "SPEC", help = crate::scene_arg::bench_solver_help())]
    pub solvers: Vec<String>,
    /// Write the records as a JSON array.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write the records as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Write the positions of the step as OBJ files into this directory: x_n.obj, y.obj,
    /// x_star.obj and SOLVER-SETTING.obj for each run (not with --sweep or --hard-cases).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["sweep", "hard_cases"])]
    pub frames: Option<PathBuf>,
    /// Overlay records from another implementation on the plot, repeatable: a CSV with this
    /// bench's columns (`--csv` writes them); its records for this scene become series of their
    /// own, named FILE-STEM:SOLVER.
    #[arg(long, value_name = "FILE.csv", conflicts_with_all = ["sweep", "hard_cases", "time_error"])]
    pub compare: Vec<PathBuf>,
    /// Plot error against time (or, with --sweep, time against vertices) on log axes as a PNG.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Time one step per solver on cloth-N for each N, e.g. N=10,20,40,80,160,320.
    #[arg(long, value_name = "N=…", conflicts_with = "hard_cases")]
    pub sweep: Option<String>,
    /// With --sweep: also compute the reference for each size and report the errors.
    #[arg(long, requires = "sweep")]
    pub errors: bool,
    /// With --sweep: time the step from the speed-vs-error state (10 exact steps first, cached)
    /// instead of the first step from rest.
    #[arg(long, requires = "sweep")]
    pub from_state: bool,
    /// Run every integrator on every hard case (the cloth cases, then the implicit integrators on
    /// bunny-drop, cloth-drape-40 and cloth-fall-40; cloth-twist-40 only when named with
    /// --hard-case) and print a matrix and one line per run.
    #[arg(long)]
    pub hard_cases: bool,
    /// Run every integrator on the scene for 1 s at its step h and report the position error at
    /// the end against backward Euler at h/64 and symplectic Euler at its stable step (the
    /// time-discretisation error of docs/model.md §9.3); --json writes the report.
    #[arg(long, conflicts_with_all = ["sweep", "hard_cases", "frames"])]
    pub time_error: bool,
    /// With --time-error: the simulated time (s).
    #[arg(long, default_value_t = 1.0, requires = "time_error")]
    pub duration: f64,
    /// With --hard-cases: frames per run of the cloth cases.
    #[arg(long, default_value_t = 30, requires = "hard_cases")]
    pub hard_frames: usize,
    /// With --hard-cases: frames per run of the scene cases (bunny-drop, cloth-drape-40,
    /// cloth-fall-40, cloth-twist-40); default: each one's own (10, 60, 30, 120).
    #[arg(long, value_name = "N", requires = "hard_cases")]
    pub hard_scene_frames: Option<usize>,
    /// With --hard-cases: run only this case (repeatable; default: every cloth case, then every
    /// scene case but cloth-twist-40; the help lists them).
    #[arg(long = "hard-case", value_name = "NAME", requires = "hard_cases", help = crate::scene_arg::hard_case_help())]
    pub hard_case_names: Vec<String>,
    /// With --hard-cases: run only this integrator (repeatable; default: every one of the
    /// matrix; the help lists them).
    #[arg(long = "hard-integrator", value_name = "NAME", requires = "hard_cases", help = crate::scene_arg::hard_integrator_help())]
    pub hard_integrators: Vec<String>,
    /// Timed repeats of each step after one warm-up run; the median is reported. Steps longer than
    /// 2 s are timed once.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Directory for the cached speed-vs-error states and references.
    #[arg(long, value_name = "DIR", default_value = "out/bench-cache")]
    pub cache_dir: PathBuf,
    /// Neither read nor write the cache.
    #[arg(long)]
    pub no_cache: bool,
    /// The fluid instead: time a 2D WCSPH step for each particle count, comma separated (e.g.
    /// 1e4,1e5), with the fluid's phase split, as a table (--json FILE, --plot FILE.png; --repeats
    /// timed steps per count); an entry naming a built-in fluid scene (dam-break-2d; the help
    /// lists them) runs that scene whole as `hooke run` does and reports its wall time and
    /// particle-steps per second.
    #[arg(long, value_name = "COUNTS", conflicts_with_all = ["sweep", "hard_cases", "time_error", "frames", "compare", "csv"], help = crate::scene_arg::bench_sph_help())]
    pub sph: Option<String>,
    /// With --sph: number the column's fluid particles in a fixed random order, as a long run's
    /// mixing leaves them (the column is built row by row, which is nearly the grid's order).
    #[arg(long, requires = "sph")]
    pub sph_shuffle: bool,
    /// Write the step's linear systems at x = y (Newton's clamped and exact Hessians, the
    /// gradient, PD's matrix, the free vertices and their positions) as MatrixMarket files with a
    /// README.json into this directory, and run no solver.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["sweep", "hard_cases", "time_error", "sph"])]
    pub export_system: Option<PathBuf>,
    /// Self-contact instead: time the contact work of one Newton iteration (broad phase and
    /// pairs within d̂, barrier value, gradient, PSD-projected Hessian, CCD step) on the surface
    /// of A.obj moving to B.obj (same triangles), as a table (--json FILE; --repeats timed runs
    /// per stage).
    #[arg(long, num_args = 2, value_names = ["A.obj", "B.obj"], conflicts_with_all = ["sweep", "hard_cases", "time_error", "frames", "compare", "csv", "sph", "export_system", "plot"])]
    pub contact: Option<Vec<PathBuf>>,
    /// With --contact: the barrier's reach d̂ (m).
    #[arg(
        long,
        default_value_t = 1e-3,
        requires = "contact",
        allow_negative_numbers = true
    )]
    pub dhat: f64,
    /// No progress lines on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The solvers `--sweep` times when no `--solver` is given.
pub(crate) const SWEEP_DEFAULT_SOLVERS: &[&str] = &["pd:10", "newton-tol:1e-8", "linearized-cg"];

const BENCH_HELP: &str = "\
Measures, for one backward Euler step from the speed-vs-error state (10 exact steps from rest;
docs/scenes.md §8) and the initial guess x0 = y, each solver's wall time (median of repeats;
PD's one-off factorisation reported apart as factor ms) and its errors against x* (Newton to a
relative gradient of 1e-10): objective error (Phi(x) - Phi*)/(Phi(y) - Phi*), position error
|x - x*|/|x* - x_n|, and the force residual |M(x - y) - h^2 f(x)| relative to its value at y
(docs/model.md §9).

Examples:
  hooke bench cloth-40 --json out/cloth-40.json --plot out/cloth-40.png
  hooke bench beam-4 --solver pd:1,10,100 --solver newton:1,2,3
  hooke bench --sweep N=10,20,40,80,160 --solver pd:10 --solver newton-tol:1e-8
  hooke bench --hard-cases
  hooke bench --sph 1e4,1e5,dam-break-2d --json out/sph.json --plot out/sph.png
  hooke bench --contact A.obj B.obj --dhat 1e-3
  hooke bench cloth-40 --time-error --json out/cloth-40-time-error.json";

/// Run `hooke bench` with `args`: print the table on stdout and write the files asked for.
///
/// # Errors
/// A [`BenchError`] for a bad spec or scene, a failed setup, or a file that cannot be written.
pub fn run_command(args: &BenchArgs) -> Result<(), BenchError> {
    if args.sph.is_some() {
        // The command runs the fluid's benchmark itself, with its typed error; here it comes as text.
        return crate::sph::bench::run(&crate::sph::bench::SphBenchOptions::from_args(args))
            .map_err(|e| BenchError::Scene(e.to_string()));
    }
    if let Some(files) = &args.contact {
        crate::output::remove_leftovers_of(
            &args.json.iter().map(PathBuf::as_path).collect::<Vec<_>>(),
        )
        .map_err(leftover_error)?;
        let timings = crate::bench::contact_kernels(&files[0], &files[1], args.dhat, args.repeats)?;
        print!("{}", crate::bench::format_contact(&timings));
        if let Some(path) = &args.json {
            crate::bench::output::write_serialized(path, &timings)?;
        }
        return Ok(());
    }
    // What a killed earlier run left of the files this one writes (the shared cache aside: another
    // run may be writing there).
    let outputs: Vec<&std::path::Path> = [&args.json, &args.csv, &args.plot]
        .into_iter()
        .flatten()
        .map(PathBuf::as_path)
        .collect();
    crate::output::remove_leftovers_of(&outputs).map_err(leftover_error)?;
    if let Some(dir) = &args.frames {
        crate::output::remove_leftovers(&[dir]).map_err(leftover_error)?;
    }
    let begin = Instant::now();
    let quiet = args.quiet;
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("[{:7.1} s] {line}", begin.elapsed().as_secs_f64());
        }
    };
    let timing = TimingOptions {
        repeats: args.repeats,
        ..TimingOptions::default()
    };
    let cache_dir = (!args.no_cache).then(|| args.cache_dir.clone());
    let specs = if args.solvers.is_empty() {
        None
    } else {
        Some(
            args.solvers
                .iter()
                .map(|s| s.parse::<SolverSpec>())
                .collect::<Result<Vec<_>, _>>()?,
        )
    };

    if args.hard_cases {
        let chosen: Vec<&str> = args.hard_integrators.iter().map(String::as_str).collect();
        let cases: Vec<&str> = if args.hard_case_names.is_empty() {
            HARD_CASES
                .iter()
                .chain(HARD_SCENES)
                .filter(|c| !HARD_OPT_IN_SCENES.contains(c))
                .copied()
                .collect()
        } else {
            args.hard_case_names.iter().map(String::as_str).collect()
        };
        let results = hard_cases(
            &cases,
            if chosen.is_empty() {
                HARD_INTEGRATORS
            } else {
                &chosen
            },
            HardCaseOptions {
                frames: args.hard_frames,
                scene_frames: args.hard_scene_frames,
                ..HardCaseOptions::default()
            },
            &mut progress,
        )?;
        print!("{}", format_hard_cases(&results));
        return Ok(());
    }

    if args.time_error {
        let setup = load_setup(&args.scene)?;
        let options = TimeErrorOptions {
            duration: args.duration,
            ..TimeErrorOptions::default()
        };
        let report = time_error(&setup, &options, &mut progress)?;
        print!("{}", format_time_error(&report));
        if let Some(path) = &args.json {
            crate::bench::output::write_serialized(path, &report)?;
        }
        return Ok(());
    }

    if let Some(text) = &args.sweep {
        let sizes = SweepOptions::parse_sizes(text)?;
        let specs = match specs {
            Some(s) => s,
            None => SWEEP_DEFAULT_SOLVERS
                .iter()
                .map(|s| s.parse())
                .collect::<Result<Vec<_>, _>>()?,
        };
        let options = SweepOptions {
            sizes,
            errors: args.errors,
            start: if args.from_state {
                StartState::SpeedVsError
            } else {
                StartState::Rest
            },
            timing,
            cache_dir,
        };
        let rows = sweep(&specs, &options, &mut progress)?;
        println!(
            "one step per solver on cloth-N ({}); peak MB is the whole process's peak resident memory so far (VmHWM)",
            if args.from_state {
                "from the speed-vs-error state"
            } else {
                "the first step, from rest"
            }
        );
        print!("{}", format_sweep_table(&rows));
        let records: Vec<Record> = rows.iter().map(|r| r.outcome.record.clone()).collect();
        write_outputs(args, &records)?;
        if let Some(path) = &args.plot {
            plot_sweep(path, &rows, "time per step against size, cloth-N")?;
        }
        return Ok(());
    }

    // Every input is read before the work starts: a missing or malformed file fails at once.
    let compared = read_compared(&args.compare)?;

    if let Some(dir) = &args.export_system {
        let setup = load_setup(&args.scene)?;
        let options = PrepareOptions {
            start: StartState::SpeedVsError,
            reference: false,
            cache_dir,
        };
        let problem = BenchProblem::prepare(&setup, &options, &mut progress)?;
        let systems = crate::bench::export_system(&problem, dir)?;
        println!(
            "{}: {} unknowns written to {}",
            problem.name,
            systems.gradient.len(),
            dir.display()
        );
        return Ok(());
    }

    let specs = specs.unwrap_or_else(SolverSpec::defaults);
    let setup = load_setup(&args.scene)?;
    let problem = BenchProblem::prepare(
        &setup,
        &PrepareOptions {
            start: StartState::SpeedVsError,
            reference: true,
            cache_dir,
        },
        &mut progress,
    )?;
    let mut meter = ErrorMeter::new(&problem);
    let mut outcomes = Vec::new();
    for spec in &specs {
        outcomes.extend(run_spec(&problem, &mut meter, spec, timing, &mut progress)?);
    }
    let mesh = problem.scene.mesh();
    let reference = problem
        .reference
        .as_ref()
        .map(|(_, info)| {
            format!(
                "reference x*: Newton, {} iterations, relative gradient {:.1e}, {:.3} s",
                info.iterations, info.gradient, info.wall_time_s
            )
        })
        .unwrap_or_default();
    println!(
        "{}: {} vertices, {} springs, h = {:.4} s; step {} from the speed-vs-error state; {reference}",
        problem.name,
        mesh.vertex_count(),
        mesh.springs().len(),
        problem.scene.time_step(),
        crate::bench::STATE_STEPS + 1,
    );
    println!(
        "step ms: median wall time of the step; factor ms: PD's one-off factorisation (not in step \
         ms) or Newton's factorisations (in step ms); residual: |M(x-y) - h^2 f(x)| / |h^2 f(y)|"
    );
    print!("{}", format_table(&outcomes));
    let records: Vec<Record> = outcomes.iter().map(|o| o.record.clone()).collect();
    write_outputs(args, &records)?;
    if let Some(dir) = &args.frames {
        write_frames(dir, &problem, &outcomes)?;
    }
    let mut plotted = records;
    for (file, records) in compared {
        let label = file
            .file_stem()
            .map_or("compare".into(), |s| s.to_string_lossy().into_owned());
        let theirs: Vec<Record> = records
            .into_iter()
            .filter(|r| r.scene == problem.name)
            .map(|r| Record {
                solver: format!("{label}:{}", r.solver),
                ..r
            })
            .collect();
        if theirs.is_empty() {
            eprintln!(
                "warning: {} has no record for {}; nothing to compare",
                file.display(),
                problem.name
            );
        } else {
            println!(
                "compared with {} record(s) of {} (series {label}:…)",
                theirs.len(),
                file.display()
            );
        }
        plotted.extend(theirs);
    }
    if let Some(path) = &args.plot {
        plot_pareto(path, &plotted, &problem.name)?;
    }
    Ok(())
}

/// The records of every `--compare` file, read and checked before any benchmark runs.
fn read_compared(files: &[PathBuf]) -> Result<Vec<(&PathBuf, Vec<Record>)>, BenchError> {
    files
        .iter()
        .map(|file| Ok((file, read_csv(file)?)))
        .collect()
}

/// A failure to remove a leftover temporary file, as the output error it is.
fn leftover_error(e: crate::output::OutputError) -> BenchError {
    match e {
        crate::output::OutputError::Io { path, source } => BenchError::Output {
            path,
            reason: source.to_string(),
        },
        e => BenchError::Output {
            path: PathBuf::new(),
            reason: e.to_string(),
        },
    }
}

fn write_outputs(args: &BenchArgs, records: &[Record]) -> Result<(), BenchError> {
    if let Some(path) = &args.json {
        write_json(path, records)?;
    }
    if let Some(path) = &args.csv {
        write_csv(path, records)?;
    }
    Ok(())
}
