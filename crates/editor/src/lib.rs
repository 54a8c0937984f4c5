//! # hooke-editor
//!
//! The interactive 2D mass-spring editor (docs/editor.md: keys, event and state formats) as a
//! deterministic state machine, drawn into a pixel buffer, shown in a window or replayed headless.
//!
//! - [`Editor`]: the model (particles, pins, springs, Young's modulus, drag, dashpot, integrator)
//!   and the simulation built from it. [`Editor::handle`] applies an [`Event`];
//!   [`Editor::advance`] simulates one frame of fixed substeps. There is no clock inside, so a
//!   replay of the same events gives the same frames bit for bit.
//! - [`Renderer`]: draws an editor with tiny-skia (walls, springs coloured by strain, particles,
//!   pinned ones marked, a text overlay) and writes PNG frames.
//! - [`Script`]: a recorded event script (`EVENTS.json`) and its headless replay; [`StateRecord`]
//!   is what `--state-out` writes. Both, and [`Event`], refuse unknown fields.
//! - [`Session`]: the window's frames without the window (mouse and keys to events, the save key,
//!   a recording of the events as a [`Script`], one advance), so that what the window does is
//!   tested headless.
//! - `window` (cargo feature `window`): the minifb window that feeds the editor its events.
//!
//! ```
//! use hooke_editor::{Editor, EditorParams, Event, Key, Renderer};
//!
//! let mut editor = Editor::seed(EditorParams::default())?;
//! editor.handle(Event::Key { key: Key::I, shift: false })?; // explicit Euler next
//! editor.advance();
//! let mut renderer = Renderer::new(128)?;
//! let frame = renderer.render(&editor, None);
//! assert_eq!(frame.width(), 128);
//! # Ok::<(), hooke_editor::EditorError>(())
//! ```
#![deny(missing_docs)]

mod draw;
mod editor;
mod error;
mod event;
mod params;
mod replay;
pub mod scene_file;
mod session;
mod setup;
#[cfg(feature = "window")]
pub mod window;

pub use draw::{to_0rgb, Renderer, FRAME_SIZES, FULL_STRAIN};
pub use editor::{Editor, FrameStats, ModelSpring, Outcome, Vec2};
pub use error::EditorError;
pub use event::{Event, Key};
pub use params::{
    EditorParams, IntegratorChoice, DASHPOT_FLOOR, DRAG_FLOOR, MAX_PARTICLES, MAX_SUBSTEPS,
};
pub use replay::{Script, ScriptEvent, StateRecord, MAX_SCRIPT_FRAMES};
pub use session::{FrameInput, Session, RECORD_EVERY_FRAMES};

use std::path::Path;

/// Write `bytes` to `path` atomically, through [`hooke_mesh::io::write_atomically`] (a temporary
/// file of its own beside `path`, synced and renamed onto it, the directory synced): the file is
/// either the old one or complete.
///
/// # Errors
/// [`EditorError::Write`] naming the file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), EditorError> {
    use std::io::Write;
    hooke_mesh::io::write_atomically(path, |out| out.write_all(bytes)).map_err(|e| {
        let reason = match e {
            // The path is named by the editor's error already.
            hooke_mesh::MeshError::Io { source, .. } => source.to_string(),
            e => e.to_string(),
        };
        EditorError::Write {
            path: path.to_path_buf(),
            reason,
        }
    })
}
