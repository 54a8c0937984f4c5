//! `DIR/timings.json`: the wall time of every step of a run.
//!
//! Wall times differ from one run to the next, so they are kept out of `summary.json`, which then
//! holds only results: two runs of the same scene and settings (or a run and its resumption from a
//! checkpoint) write the same `summary.json`, byte for byte.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{write_json_atomically, OutputError};

/// The wall times of a run, one per recorded step, in step order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RunTimings {
    /// Wall-clock time of each step, in seconds (s); step 0, the initial state, costs 0.
    pub steps: Vec<StepTiming>,
    /// The steps from which the run was continued after an interruption (`hooke run --resume`),
    /// in order: the steps up to each such point were timed by an earlier process. Empty for a
    /// run that went through in one go.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed_after: Vec<usize>,
}

/// The wall time of one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepTiming {
    /// Step number, as in `summary.json`.
    pub step: usize,
    /// Wall-clock time spent on the step, in seconds (s).
    pub wall_time_s: f64,
}

/// Writes `timings` to `path` as pretty-printed JSON, atomically (as [`super::write_summary`]).
pub fn write_timings(path: &Path, timings: &RunTimings) -> Result<(), OutputError> {
    write_json_atomically(path, timings, true)
}

/// Reads timings written by [`write_timings`].
pub fn read_timings(path: &Path) -> Result<RunTimings, OutputError> {
    let file = std::fs::File::open(path).map_err(|e| OutputError::io(path, e))?;
    serde_json::from_reader(std::io::BufReader::new(file)).map_err(|source| OutputError::Json {
        path: path.to_path_buf(),
        source,
    })
}
