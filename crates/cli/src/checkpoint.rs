//! Checkpoints of `hooke run`: `--checkpoint-every K` writes `DIR/checkpoint.json` after every K-th
//! frame, and `hooke run --resume DIR` continues the run from it.
//!
//! A checkpoint holds what the run needs to go on as if it had never stopped: the run's arguments
//! (the scene file by its absolute path, with a hash of its contents), the last frame written, the
//! simulation's [`Snapshot`] (state, frames taken, Newton's halving memory, the energy watchdog's
//! reference) and the summary's records so far. The resumed run rebuilds the simulation from the
//! same scene and arguments, restores the snapshot, removes any frame written after the checkpoint
//! and steps on: its frames, `summary.json`, `preview.png` and checkpoints are those of an
//! uninterrupted run, byte for byte. Only `timings.json` differs, which is why wall times are in
//! neither the summary nor the checkpoint: `timings.json` is written just before each checkpoint,
//! and a resumed run takes the wall times of the frames up to its checkpoint from there.
//!
//! Numbers are stored with `serde_json`'s default formatting, the shortest decimal that reads back
//! to the same `f64`, so positions and velocities come back bit for bit (tested); a state is
//! finite, so JSON's lack of NaN and infinity never matters. The file is replaced atomically (a
//! temporary file in the same directory, then a rename): an interruption while it is written
//! leaves the previous checkpoint.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::command::RunArgs;
use crate::output::{read_timings, write_json_atomically, OutputError, StepRecord, StepTiming};
use crate::sim::{SimError, Simulation, Snapshot};

/// The checkpoint's file name in the output directory.
pub(crate) const FILE_NAME: &str = "checkpoint.json";

/// The `format` field that marks a checkpoint file.
const FORMAT: &str = "hooke-checkpoint";

/// The layout version; a checkpoint of another version is refused rather than misread.
const VERSION: u32 = 1;

/// A checkpoint could not be written, read or used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub(crate) enum CheckpointError {
    /// Reading the file failed (e.g. the directory holds no checkpoint).
    #[error("{}: cannot read the checkpoint: {source}", path.display())]
    Io {
        /// The checkpoint file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a checkpoint this version of hooke wrote, or it is damaged.
    #[error("{}: not a valid checkpoint: {reason}", path.display())]
    Invalid {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The scene file changed since the checkpoint was written: the run cannot go on as it was.
    #[error(
        "{}: the scene file changed since the checkpoint was written (its contents hash to \
         {found:016x}, the checkpoint's to {expected:016x})",
        scene.display()
    )]
    SceneChanged {
        /// The scene file.
        scene: PathBuf,
        /// Hash of the contents when the checkpoint was written.
        expected: u64,
        /// Hash of the contents now.
        found: u64,
    },
    /// The simulation refused the snapshot (another scene, state or settings).
    #[error("{}: the checkpoint does not fit the rebuilt simulation: {source}", path.display())]
    Snapshot {
        /// The checkpoint file.
        path: PathBuf,
        /// The simulation's error.
        #[source]
        source: SimError,
    },
    /// Writing the checkpoint failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// What `DIR/checkpoint.json` holds.
#[derive(Serialize, Deserialize)]
pub(crate) struct Checkpoint {
    /// Always [`FORMAT`].
    format: String,
    /// Always [`VERSION`].
    version: u32,
    /// The version of hooke that wrote it.
    hooke_version: String,
    /// The run's arguments; `out`, `resume`, `quiet` and the test hook are not recorded.
    pub(crate) args: RunArgs,
    /// FNV-1a hash of the scene file's contents, for a scene given as a file.
    scene_hash: Option<u64>,
    /// The last frame written and stepped to.
    frame: usize,
    /// The spatial dimension of `snapshot`: 2 or 3.
    dimension: usize,
    /// The simulation's [`Snapshot`] after `frame`.
    snapshot: serde_json::Value,
    /// The summary's records of frames 0 to `frame`.
    steps: Vec<StepRecord>,
}

/// Where a resumed run starts.
pub(crate) struct Resumed {
    /// The frame the checkpoint was written after; the run goes on with the next.
    pub frame: usize,
    /// The summary's records of frames 0 to `frame`.
    pub steps: Vec<StepRecord>,
    /// Their wall times, as far as `timings.json` still holds them (none if it is missing or
    /// unreadable: they are a record, not something the run depends on).
    pub timings: Vec<StepTiming>,
}

/// The checkpoint file of output directory `dir`.
pub(crate) fn path_in(dir: &Path) -> PathBuf {
    dir.join(FILE_NAME)
}

/// FNV-1a (64-bit) of `bytes`: a fingerprint of a scene file's contents, not a defence against
/// tampering.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| {
        (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The hash of a scene file's contents; `None` for a built-in scene.
fn scene_hash(scene: &str) -> Result<Option<u64>, CheckpointError> {
    let path = Path::new(scene);
    if !path.is_file() {
        return Ok(None);
    }
    std::fs::read(path)
        .map(|bytes| Some(fnv1a(&bytes)))
        .map_err(|source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        })
}

impl Checkpoint {
    /// The checkpoint after `frame` of a run with `args` (whose scene, if a file, is given by an
    /// absolute path: see [`absolute_scene`]).
    pub(crate) fn new<const D: usize>(
        args: &RunArgs,
        frame: usize,
        sim: &Simulation<D>,
        steps: &[StepRecord],
    ) -> Result<Self, CheckpointError> {
        let path = Path::new("checkpoint");
        let snapshot =
            serde_json::to_value(sim.snapshot()).map_err(|e| CheckpointError::Invalid {
                path: path.to_path_buf(),
                reason: e.to_string(),
            })?;
        Ok(Checkpoint {
            format: FORMAT.into(),
            version: VERSION,
            hooke_version: env!("CARGO_PKG_VERSION").into(),
            args: args.for_checkpoint(),
            scene_hash: scene_hash(args.scene())?,
            frame,
            dimension: D,
            snapshot,
            steps: steps.to_vec(),
        })
    }

    /// Write it to `dir`'s checkpoint file, atomically.
    pub(crate) fn write(&self, dir: &Path) -> Result<(), CheckpointError> {
        Ok(write_json_atomically(&path_in(dir), self, false)?)
    }

    /// Read the checkpoint of output directory `dir`, and check that it is one and that its scene
    /// file (if any) has not changed.
    pub(crate) fn read(dir: &Path) -> Result<Self, CheckpointError> {
        let path = path_in(dir);
        let text = std::fs::read(&path).map_err(|source| CheckpointError::Io {
            path: path.clone(),
            source,
        })?;
        let invalid = |reason: String| CheckpointError::Invalid {
            path: path.clone(),
            reason,
        };
        let checkpoint: Checkpoint =
            serde_json::from_slice(&text).map_err(|e| invalid(e.to_string()))?;
        if checkpoint.format != FORMAT || checkpoint.version != VERSION {
            return Err(invalid(format!(
                "format {:?} version {}, expected {FORMAT:?} version {VERSION}",
                checkpoint.format, checkpoint.version
            )));
        }
        if checkpoint.hooke_version != env!("CARGO_PKG_VERSION") {
            return Err(invalid(format!(
                "written by hooke {}, this is {}: a run continues with the code that began it",
                checkpoint.hooke_version,
                env!("CARGO_PKG_VERSION")
            )));
        }
        let records = checkpoint.steps.len();
        if records != checkpoint.frame + 1
            || checkpoint
                .steps
                .iter()
                .enumerate()
                .any(|(i, r)| r.step != i)
        {
            return Err(invalid(format!(
                "{records} summary records for frames 0 to {}",
                checkpoint.frame
            )));
        }
        let found = scene_hash(checkpoint.args.scene())?;
        if let (Some(expected), Some(found)) = (checkpoint.scene_hash, found) {
            if expected != found {
                return Err(CheckpointError::SceneChanged {
                    scene: PathBuf::from(checkpoint.args.scene()),
                    expected,
                    found,
                });
            }
        }
        if checkpoint.scene_hash.is_some() != found.is_some() {
            return Err(invalid(format!(
                "the scene {:?} was {} when the checkpoint was written and is {} now",
                checkpoint.args.scene(),
                if checkpoint.scene_hash.is_some() {
                    "a file"
                } else {
                    "built in"
                },
                if found.is_some() { "a file" } else { "not" }
            )));
        }
        Ok(checkpoint)
    }

    /// Put the checkpoint's snapshot into `sim`, rebuilt from the checkpoint's arguments, and
    /// return where the run goes on.
    pub(crate) fn restore<const D: usize>(
        self,
        dir: &Path,
        sim: &mut Simulation<D>,
    ) -> Result<Resumed, CheckpointError> {
        let path = path_in(dir);
        if self.dimension != D {
            return Err(CheckpointError::Invalid {
                path,
                reason: format!("a {}D snapshot for a {D}D scene", self.dimension),
            });
        }
        let snapshot: Snapshot<D> =
            serde_json::from_value(self.snapshot).map_err(|e| CheckpointError::Invalid {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        if snapshot.steps_taken != self.frame {
            return Err(CheckpointError::Invalid {
                path,
                reason: format!(
                    "the snapshot is after {} steps, the checkpoint after frame {}",
                    snapshot.steps_taken, self.frame
                ),
            });
        }
        sim.restore(&snapshot)
            .map_err(|source| CheckpointError::Snapshot { path, source })?;
        let mut timings = read_timings(&dir.join("timings.json"))
            .map(|t| t.steps)
            .unwrap_or_default();
        timings.retain(|t| t.step <= self.frame);
        Ok(Resumed {
            frame: self.frame,
            steps: self.steps,
            timings,
        })
    }
}

/// `scene` as the checkpoint records it: a file by its absolute path (so that `--resume` works
/// from any directory), a built-in scene by its name.
pub(crate) fn absolute_scene(scene: &str) -> String {
    let path = Path::new(scene);
    if path.is_file() {
        if let Ok(absolute) = std::path::absolute(path) {
            if let Some(text) = absolute.to_str() {
                return text.to_string();
            }
        }
    }
    scene.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_reference_values() {
        // The FNV-1a test vectors of the reference implementation (Fowler, Noll, Vo).
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn json_numbers_round_trip_bit_for_bit() {
        // serde_json's default formatting (ryu) is the shortest round-trip decimal; check the hard
        // cases a state can hold: signed zero, subnormals, extremes, values near powers of two.
        let mut values = vec![
            0.0,
            -0.0,
            5e-324,
            -f64::from_bits(0x000f_ffff_ffff_ffff), // the largest subnormal
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            1.0 / 3.0,
            0.1 + 0.2,
            f64::EPSILON,
            1.0 - f64::EPSILON / 2.0,
        ];
        // A deterministic spread of bit patterns over every exponent.
        let mut bits = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..20_000 {
            bits ^= bits << 13;
            bits ^= bits >> 7;
            bits ^= bits << 17;
            let x = f64::from_bits(bits);
            if x.is_finite() {
                values.push(x);
            }
        }
        let text = serde_json::to_string(&values).unwrap();
        let back: Vec<f64> = serde_json::from_str(&text).unwrap();
        assert_eq!(back.len(), values.len());
        for (a, b) in values.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits(), "{a:e} came back as {b:e}");
        }
    }
}
