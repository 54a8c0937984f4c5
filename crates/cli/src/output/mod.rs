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

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

pub use preview::{
    detail_line, render_preview, PreviewInput, PreviewObstacle, PreviewPositions, ScenePreview,
};
pub use progress::progress_bar;
pub use summary::{
    write_summary, RateRecord, ResidualRecord, RunSummary, SelfContactRecord, SolverSettingsRecord,
    StepRecord,
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

    /// The [`OutputError::Io`] of a file operation of the mesh crate about `path` (which reports
    /// nothing but I/O errors, each naming its file).
    fn from_mesh(path: &Path, e: crate::mesh::MeshError) -> Self {
        match e {
            crate::mesh::MeshError::Io { path, source } => OutputError::Io { path, source },
            e => OutputError::io(path, std::io::Error::other(e.to_string())),
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

/// Writes `path` through `write`, atomically, by [`crate::mesh::io::write_atomically`] (the
/// workspace's one implementation: a temporary file of this writer's own beside `path`, synced,
/// renamed onto it, the directory synced); on any error the temporary file is removed and `path`
/// is left as it was.
pub(crate) fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), OutputError> {
    crate::mesh::io::write_atomically(path, write).map_err(|e| OutputError::from_mesh(path, e))
}

/// Removes the temporary files that [`write_atomically`] left in `dirs` when a process writing there
/// was killed (see [`crate::mesh::io::remove_temporaries`]): a command calls it on the directories
/// it owns when it starts, so that they then hold complete files only.
pub(crate) fn remove_leftovers(dirs: &[&Path]) -> Result<(), OutputError> {
    for dir in dirs {
        crate::mesh::io::remove_temporaries(dir).map_err(|e| OutputError::from_mesh(dir, e))?;
    }
    Ok(())
}

/// Removes the temporary files that [`write_atomically`] left beside each of `paths` when a process
/// writing it was killed (see [`crate::mesh::io::remove_temporaries_of`]): for a command that
/// writes a few named files into directories it does not own, when it starts. A path whose
/// directory does not exist has none.
pub(crate) fn remove_leftovers_of(paths: &[&Path]) -> Result<(), OutputError> {
    for path in paths {
        crate::mesh::io::remove_temporaries_of(path)
            .map_err(|e| OutputError::from_mesh(path, e))?;
    }
    Ok(())
}

/// Writes `value` to `path` as JSON (pretty-printed or compact) and a final newline, atomically
/// (see [`write_atomically`]).
pub(crate) fn write_json_atomically(
    path: &Path,
    value: &impl serde::Serialize,
    pretty: bool,
) -> Result<(), OutputError> {
    // serde_json's error is kept aside so that it is reported as JSON, not as I/O.
    let mut json_error = None;
    let written = write_atomically(path, |out| {
        let json = if pretty {
            serde_json::to_writer_pretty(&mut *out, value)
        } else {
            serde_json::to_writer(&mut *out, value)
        };
        match json {
            Ok(()) => out.write_all(b"\n"),
            Err(e) if e.is_io() => Err(e.into()),
            Err(e) => {
                json_error = Some(e);
                Err(std::io::Error::other("cannot serialise"))
            }
        }
    });
    match json_error {
        Some(source) => Err(OutputError::Json {
            path: path.to_path_buf(),
            source,
        }),
        None => written,
    }
}

/// Writes `pixels` (RGB, 8 bits a channel, row-major, `width` × `height`) to `path` as a PNG,
/// atomically (see [`write_atomically`]). The encoder and its settings are those plotters uses to
/// save a bitmap, so the bytes are the same as its own file's.
pub(crate) fn write_png(
    path: &Path,
    pixels: &[u8],
    width: u32,
    height: u32,
) -> Result<(), OutputError> {
    use image::ImageEncoder;
    let mut encoding_error = None;
    let written = write_atomically(path, |out| {
        image::codecs::png::PngEncoder::new(out)
            .write_image(pixels, width, height, image::ColorType::Rgb8)
            .map_err(|e| match e {
                image::ImageError::IoError(e) => e,
                e => {
                    encoding_error = Some(e.to_string());
                    std::io::Error::other("cannot encode")
                }
            })
    });
    match encoding_error {
        Some(message) => Err(OutputError::plot(path, message)),
        None => written,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plotters::prelude::*;

    #[test]
    fn png_bytes_are_those_plotters_saves() {
        let dir = tempfile::tempdir().unwrap();
        let (width, height) = (7u32, 5u32);
        let pixels: Vec<u8> = (0..width * height * 3)
            .map(|i| (i * 37 % 256) as u8)
            .collect();
        let ours = dir.path().join("ours.png");
        write_png(&ours, &pixels, width, height).unwrap();
        let theirs = dir.path().join("theirs.png");
        {
            let mut backend = BitMapBackend::new(&theirs, (width, height));
            backend
                .blit_bitmap((0, 0), (width, height), &pixels)
                .unwrap();
            backend.present().unwrap();
        }
        assert_eq!(
            std::fs::read(&ours).unwrap(),
            std::fs::read(&theirs).unwrap()
        );
    }

    #[test]
    fn a_value_json_cannot_hold_is_a_json_error_and_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        std::fs::write(&path, b"old").unwrap();
        // JSON object keys must be strings.
        let value = std::collections::BTreeMap::from([((1, 2), 3)]);
        let e = write_json_atomically(&path, &value, true).unwrap_err();
        assert!(matches!(e, OutputError::Json { .. }), "{e:?}");
        assert!(e.to_string().contains("summary.json"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        // No temporary file is left beside it.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn leftovers_of_a_directory_or_of_named_files_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for name in ["a.json", ".a.json.AbC123.tmp", ".b.png.XyZ789.tmp"] {
            std::fs::write(d.join(name), b"x").unwrap();
        }
        let present = |name: &str| d.join(name).exists();
        remove_leftovers_of(&[&d.join("a.json"), &d.join("missing/c.csv")]).unwrap();
        assert!(!present(".a.json.AbC123.tmp"));
        assert!(present(".b.png.XyZ789.tmp") && present("a.json"));
        remove_leftovers(&[d]).unwrap();
        assert!(!present(".b.png.XyZ789.tmp") && present("a.json"));
    }
}
