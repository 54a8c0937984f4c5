//! The editor's error type.

/// What the editor refuses.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EditorError {
    /// A parameter out of its range.
    #[error("invalid editor parameter {name} = {value}: must be {allowed}")]
    InvalidParameter {
        /// The field.
        name: &'static str,
        /// Its value, as text.
        value: String,
        /// The allowed range.
        allowed: &'static str,
    },
    /// An event position that is not finite or lies outside the unit box.
    #[error("event position ({x}, {y}) is outside the unit box [0, 1]²")]
    PositionOutsideBox {
        /// m.
        x: f64,
        /// m.
        y: f64,
    },
    /// A scene the editor cannot open.
    #[error("the editor cannot open this scene: {reason}")]
    UnsupportedScene {
        /// Why.
        reason: String,
    },
    /// The drawing surface could not be created.
    #[error("cannot draw a {size}×{size} frame (size must be 64 to 4096 pixels)")]
    FrameSize {
        /// Pixels per side.
        size: u32,
    },
    /// A frame could not be encoded or written.
    #[error("{path}: {reason}")]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        reason: String,
    },
    /// The scene file could not be read or built.
    #[error(transparent)]
    SceneFile(#[from] hooke_sim::file::SceneFileError),
}
