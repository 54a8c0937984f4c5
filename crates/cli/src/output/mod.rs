//! What a run leaves on disk and on the terminal: the PNG preview of its last frame
//! ([`render_preview`]), the per-step `summary.json` ([`write_summary`]) and the progress bar
//! ([`progress_bar`]), the wall times of the steps (`timings.json`, [`write_timings`]).
//!
//! Files are written atomically: each is written to a temporary file in the destination's
//! directory and renamed onto the destination only once it is complete, so a reader never sees a
//! half-written file and a failed write leaves nothing behind.

mod preview;
mod progress;
mod summary;
mod timings;

use std::path::{Path, PathBuf};

pub use preview::{render_preview, PreviewInput, PreviewObstacle, PreviewPositions};
pub use progress::progress_bar;
pub use summary::{
    write_summary, RateRecord, ResidualRecord, RunSummary, SolverSettingsRecord, StepRecord,
};
pub use timings::{read_timings, write_timings, RunTimings, StepTiming};

// Extras the binary may not need (other image sizes, reading a summary back): for tests and tools.
#[allow(unused_imports)]
pub use preview::{render_preview_sized, PREVIEW_HEIGHT, PREVIEW_WIDTH};
#[allow(unused_imports)]
pub use summary::read_summary;

/// An output file could not be produced.
///
/// Every variant names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// Creating, writing, syncing or renaming a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file (or, when the temporary file could not be created, its directory).
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Drawing or encoding the preview image failed.
    #[error("{}: cannot render the preview: {message}", path.display())]
    Plot {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Serialising or parsing JSON failed.
    #[error("{}: {source}", path.display())]
    Json {
        /// The JSON file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: serde_json::Error,
    },
}

impl OutputError {
    /// An [`OutputError::Io`] about `path`.
    fn io(path: &Path, source: std::io::Error) -> Self {
        OutputError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// An [`OutputError::Plot`] about `path`.
    fn plot(path: &Path, message: impl std::fmt::Display) -> Self {
        OutputError::Plot {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}

/// Writes `value` to `path` as JSON (pretty-printed or compact), atomically: to a temporary file in
/// `path`'s directory, flushed, synced and renamed onto `path`; on any error the temporary file is
/// removed and `path` is left as it was.
pub(crate) fn write_json_atomically(
    path: &Path,
    value: &impl serde::Serialize,
    pretty: bool,
) -> Result<(), OutputError> {
    use std::io::Write;
    let tmp = temp_file_beside(path, ".hooke-", ".json.tmp")?;
    {
        let mut writer = std::io::BufWriter::new(tmp.as_file());
        let json = if pretty {
            serde_json::to_writer_pretty(&mut writer, value)
        } else {
            serde_json::to_writer(&mut writer, value)
        };
        json.map_err(|source| OutputError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        writer
            .write_all(b"\n")
            .and_then(|()| writer.flush())
            .map_err(|e| OutputError::io(path, e))?;
    }
    tmp.as_file()
        .sync_all()
        .map_err(|e| OutputError::io(path, e))?;
    tmp.persist(path)
        .map_err(|e| OutputError::io(path, e.error))?;
    Ok(())
}

/// A new temporary file in `path`'s directory, named `{prefix}…{suffix}`, with the permissions an
/// ordinary new file gets (0o666 less the umask on Unix, not tempfile's private 0o600), since it
/// becomes `path` once complete.
fn temp_file_beside(
    path: &Path,
    prefix: &str,
    suffix: &str,
) -> Result<tempfile::NamedTempFile, OutputError> {
    let dir = parent_dir(path);
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix).suffix(suffix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder
        .tempfile_in(dir)
        .map_err(|e| OutputError::io(dir, e))
}

/// The directory a temporary file for `path` goes in: `path`'s parent, or the current directory
/// when `path` is a bare file name.
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}
