//! The fluid (hooke-sph's weakly compressible SPH, docs/sph.md) behind the command: `hooke run`
//! of `dam-break-2d`, `hydrostatic-2d` and `dam-break-3d` (docs/scenes.md §7) or of a scene file with a
//! `[fluid]` table ([`file`]), what such a run writes ([`run`], [`preview`]), and
//! `hooke bench --sph COUNTS` ([`bench`]).
//!
//! Only the fluid's public API is used: `hooke_sph::{Fluid, FluidParams, scenes::*, SphError}`.

pub(crate) mod bench;
pub(crate) mod file;
pub(crate) mod preview;
pub(crate) mod run;

use std::path::{Path, PathBuf};

use hooke_sph::SphError;

use crate::output::OutputError;

/// The built-in fluid scenes, as `hooke scenes` lists them: name and description.
pub(crate) fn builtin_scenes() -> impl Iterator<Item = (&'static str, &'static str)> {
    hooke_sph::scenes::BUILTIN
        .iter()
        .map(|&(name, _, description)| (name, description))
}

/// Whether `name` is a built-in fluid scene.
pub(crate) fn is_builtin(name: &str) -> bool {
    builtin_scenes().any(|(n, _)| n == name)
}

/// Whether the scene file at `path` has a `[fluid]` table (and so is run by the fluid). A file
/// that cannot be read or is not TOML is not: the spring scene parser then reports its error.
pub(crate) fn is_fluid_file(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| text.parse::<toml::Table>().ok())
        .is_some_and(|table| table.contains_key("fluid"))
}

/// Everything a fluid run or benchmark can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SphCliError {
    /// The fluid refused its input or a step failed (a particle would leave the domain, a value
    /// would become non-finite, the step collapsed).
    #[error("{scene}: {context}: {source}")]
    Fluid {
        /// The scene.
        scene: String,
        /// Where: `setup`, or `frame N (t = …)`.
        context: String,
        /// The fluid's error.
        #[source]
        source: Box<SphError>,
    },
    /// The scene file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The scene file is not TOML, has an unknown key or a value of the wrong type (the message
    /// names the key, line and column).
    #[error("{}: {source}", path.display())]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// The parser's error.
        #[source]
        source: Box<toml::de::Error>,
    },
    /// A scene file's key has a value that is not acceptable.
    #[error("{}: [{key}]: {reason}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The key, dotted (e.g. `fluid.dx`).
        key: String,
        /// Why.
        reason: String,
    },
    /// A command-line option is not valid for a fluid run or benchmark.
    #[error("invalid --{name}: {reason}")]
    Argument {
        /// The option, without its dashes.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// An output file could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The test hook `HOOKE_TEST_HALT` has a value that is not a halting point.
    #[error("invalid HOOKE_TEST_HALT (a test hook): {0}")]
    TestHook(String),
}

impl SphCliError {
    /// An [`SphCliError::Fluid`] of `scene` at `context`.
    pub(crate) fn fluid(scene: &str, context: impl Into<String>, source: SphError) -> Self {
        SphCliError::Fluid {
            scene: scene.to_string(),
            context: context.into(),
            source: Box::new(source),
        }
    }

    /// An [`SphCliError::Io`] about `path`.
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        SphCliError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
