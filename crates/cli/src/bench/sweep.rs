//! `--sweep N=…`: one step per solver setting on cloth-N for several N, and peak memory.

use std::path::PathBuf;

use crate::bench::{
    load_setup, run_spec, BenchError, BenchProblem, ErrorMeter, Outcome, PrepareOptions,
    SolverSpec, StartState, TimingOptions,
};

/// How [`sweep`] runs.
#[derive(Clone, Debug)]
pub struct SweepOptions {
    /// Cloth sizes N (N×N vertices).
    pub sizes: Vec<usize>,
    /// Also compute x* for each size and report the objective and position errors (otherwise
    /// null; the residual needs no reference and is always reported).
    pub errors: bool,
    /// Where the timed step starts. Default [`StartState::Rest`]: the first step of each scene, so
    /// that a large N does not need 10 exact steps first; [`StartState::SpeedVsError`] measures the
    /// same step as the error report (and caches it).
    pub start: StartState,
    /// How steps are timed.
    pub timing: TimingOptions,
    /// Cache directory for states and references.
    pub cache_dir: Option<PathBuf>,
}

impl SweepOptions {
    /// Parse `N=10,20,40` into sizes.
    ///
    /// # Errors
    /// [`BenchError::BadSweep`] for anything else, or a size below 2.
    pub fn parse_sizes(text: &str) -> Result<Vec<usize>, BenchError> {
        let bad = || BenchError::BadSweep(text.to_string());
        let list = text.trim().strip_prefix("N=").ok_or_else(bad)?;
        list.split(',')
            .map(|v| match v.trim().parse::<usize>() {
                Ok(n) if n >= 2 => Ok(n),
                _ => Err(bad()),
            })
            .collect()
    }
}

/// One record of a sweep, with the vertex count and the process's peak memory after it.
#[derive(Clone, Debug)]
pub struct SweepRow {
    /// Vertices of the scene (N²).
    pub vertices: usize,
    /// The record and note (positions dropped).
    pub outcome: Outcome,
    /// Peak resident memory of the whole process so far (bytes; `VmHWM` of /proc/self/status on
    /// Linux, `None` elsewhere). Process-wide and monotone: it includes the scenes and solvers of
    /// earlier rows, so with sizes in increasing order it is dominated by the current size.
    pub peak_memory_bytes: Option<u64>,
}

/// Time one step of every setting of `specs` on cloth-N for each N of `options.sizes`.
///
/// # Errors
/// As [`BenchProblem::prepare`] and [`run_spec`].
pub fn sweep(
    specs: &[SolverSpec],
    options: &SweepOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<SweepRow>, BenchError> {
    let mut rows = Vec::new();
    for &n in &options.sizes {
        let setup = load_setup(&format!("cloth-{n}"))?;
        let vertices = setup.scene.mesh().vertex_count();
        let mut problem = BenchProblem::prepare(
            &setup,
            &PrepareOptions {
                start: options.start,
                reference: options.errors,
                cache_dir: options.cache_dir.clone(),
            },
            progress,
        )?;
        if !options.errors {
            // A reference read from the cache is not used either: errors only when asked for.
            problem.reference = None;
        }
        let mut meter = ErrorMeter::new(&problem);
        for spec in specs {
            for mut outcome in run_spec(&problem, &mut meter, spec, options.timing, progress)? {
                outcome.positions = Vec::new();
                // The peak so far: Linux reads VmHWM from approximate per-CPU counters, so
                // two readings in a busy multithreaded process can step back a few pages.
                let earlier = rows.last().and_then(|r: &SweepRow| r.peak_memory_bytes);
                let peak = match (peak_memory_bytes(), earlier) {
                    (Some(now), Some(before)) => Some(now.max(before)),
                    (now, before) => now.or(before),
                };
                rows.push(SweepRow {
                    vertices,
                    outcome,
                    peak_memory_bytes: peak,
                });
            }
        }
    }
    Ok(rows)
}

/// Peak resident set size of this process in bytes (`VmHWM` in /proc/self/status), on Linux;
/// `None` where that file does not exist.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line
        .trim_start_matches("VmHWM:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}
