//! The editor in a window (cargo feature `window`): minifb shows the renderer's pixels, and the
//! loop hands its mouse and keys to a [`Session`], which makes the editor's events of them. minifb
//! loads X11 at run time, so building needs no display; running needs one (`DISPLAY`).

use std::path::PathBuf;
use std::time::Instant;

use minifb::{KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};

use crate::{
    to_0rgb, Editor, EditorError, FrameInput, Key, Renderer, Session, RECORD_EVERY_FRAMES,
};

/// How the window runs.
#[derive(Clone, Debug, PartialEq)]
pub struct WindowSettings {
    /// Pixels per side (the unit box fills the window).
    pub size: u32,
    /// Where `s` saves the scene file.
    pub save_path: PathBuf,
    /// Record the session's events here as a replayable event script (docs/editor.md), written
    /// atomically every [`RECORD_EVERY_FRAMES`] frames and when the window closes.
    pub record_path: Option<PathBuf>,
    /// Stop after this many frames (tests); `None` runs until the window closes or Escape.
    pub max_frames: Option<u64>,
    /// Frames per second the loop aims at (minifb sleeps the rest of each frame).
    pub target_fps: usize,
}

impl Default for WindowSettings {
    fn default() -> Self {
        WindowSettings {
            size: 512,
            save_path: PathBuf::from("edited.toml"),
            record_path: None,
            max_frames: None,
            target_fps: 60,
        }
    }
}

/// Why the window could not run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WindowError {
    /// The window could not be opened (no display, no X11 library) or updated.
    #[error("the window failed: {0} (is DISPLAY set and an X server running?)")]
    Window(String),
    /// The renderer refused the size, or the recording could not be written.
    #[error(transparent)]
    Editor(#[from] EditorError),
}

fn key_of(key: minifb::Key) -> Option<Key> {
    Some(match key {
        minifb::Key::Space => Key::Space,
        minifb::Key::C => Key::C,
        minifb::Key::Y => Key::Y,
        minifb::Key::D => Key::D,
        minifb::Key::X => Key::X,
        minifb::Key::I => Key::I,
        minifb::Key::S => Key::S,
        minifb::Key::LeftBracket => Key::BracketLeft,
        minifb::Key::RightBracket => Key::BracketRight,
        _ => return None,
    })
}

/// What the window's mouse and keyboard say this frame.
fn read_input(window: &Window) -> FrameInput {
    FrameInput {
        mouse: window.get_mouse_pos(MouseMode::Clamp),
        left: window.get_mouse_down(MouseButton::Left),
        right: window.get_mouse_down(MouseButton::Right),
        middle: window.get_mouse_down(MouseButton::Middle),
        shift: window.is_key_down(minifb::Key::LeftShift)
            || window.is_key_down(minifb::Key::RightShift),
        pin: window.is_key_down(minifb::Key::P),
        keys: window
            .get_keys_pressed(KeyRepeat::No)
            .into_iter()
            .filter_map(key_of)
            .collect(),
    }
}

/// Run `editor` in a window until it is closed, Escape is pressed, or `settings.max_frames` frames
/// have been shown. Returns the number of frames shown. Each frame is a [`Session::frame`] of what
/// the mouse and keyboard say (events, one [`Editor::advance`]), then the drawing, with the last
/// frame's wall time (advance + draw) in the overlay. Saving (`s`) writes `settings.save_path`
/// at the end of that frame; its outcome is shown as a notice. With `settings.record_path` the session's events are recorded
/// there, and written however the loop ends (closed, Escape, the frame limit, or a window error).
///
/// # Errors
/// [`WindowError::Window`] if the window cannot be opened or updated; [`WindowError::Editor`] if
/// the size is refused or the recording's last write fails.
pub fn run(editor: &mut Editor, settings: &WindowSettings) -> Result<u64, WindowError> {
    let mut renderer = Renderer::new(settings.size)?;
    let mut session = Session::new(settings.size, settings.save_path.clone())?;
    if let Some(path) = &settings.record_path {
        session = session.recording_to(path.clone(), RECORD_EVERY_FRAMES)?;
    }
    let shown = show(editor, settings, &mut renderer, &mut session);
    // The recording is written before any error of the window is returned.
    let finished = session.finish();
    let shown = shown?;
    finished?;
    Ok(shown)
}

/// The window's loop.
fn show(
    editor: &mut Editor,
    settings: &WindowSettings,
    renderer: &mut Renderer,
    session: &mut Session,
) -> Result<u64, WindowError> {
    let size = settings.size as usize;
    let mut window = Window::new("hooke edit", size, size, WindowOptions::default())
        .map_err(|e| WindowError::Window(e.to_string()))?;
    window.set_target_fps(settings.target_fps);
    let mut buffer = Vec::with_capacity(size * size);
    let mut frame_time = None;
    let mut shown = 0u64;
    while window.is_open() && !window.is_key_down(minifb::Key::Escape) {
        if settings.max_frames.is_some_and(|m| shown >= m) {
            break;
        }
        let start = Instant::now();
        session.frame(editor, &read_input(&window));
        let pixmap = renderer.render(editor, frame_time);
        to_0rgb(pixmap, &mut buffer);
        frame_time = Some(start.elapsed());
        window
            .update_with_buffer(&buffer, size, size)
            .map_err(|e| WindowError::Window(e.to_string()))?;
        shown += 1;
    }
    Ok(shown)
}
