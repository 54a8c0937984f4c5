//! The editor in a window (cargo feature `window`): minifb shows the renderer's pixels and the loop
//! turns its mouse and keys into [`Event`]s. minifb loads X11 at run time, so building needs no
//! display; running needs one (`DISPLAY`).

use std::path::PathBuf;
use std::time::Instant;

use minifb::{KeyRepeat, MouseButton, MouseMode, Window, WindowOptions};

use crate::{to_0rgb, Editor, EditorError, Event, Key, Outcome, Renderer};

/// How the window runs.
#[derive(Clone, Debug, PartialEq)]
pub struct WindowSettings {
    /// Pixels per side (the unit box fills the window).
    pub size: u32,
    /// Where `s` saves the scene file.
    pub save_path: PathBuf,
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
    /// The renderer refused the size.
    #[error(transparent)]
    Editor(#[from] EditorError),
}

/// Mouse buttons as they were last frame, to turn levels into press/release edges.
#[derive(Default)]
struct Buttons {
    left: bool,
    right: bool,
    middle: bool,
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

/// Run `editor` in a window until it is closed, Escape is pressed, or `settings.max_frames` frames
/// have been shown. Returns the number of frames shown. Each frame: events, one
/// [`Editor::advance`], the drawing, with the last frame's wall time (advance + draw) in the
/// overlay. Saving (`s`) writes `settings.save_path`; its outcome is shown as a notice.
///
/// # Errors
/// [`WindowError::Window`] if the window cannot be opened or updated.
pub fn run(editor: &mut Editor, settings: &WindowSettings) -> Result<u64, WindowError> {
    let mut renderer = Renderer::new(settings.size)?;
    let size = settings.size as usize;
    let mut window = Window::new("hooke edit", size, size, WindowOptions::default())
        .map_err(|e| WindowError::Window(e.to_string()))?;
    window.set_target_fps(settings.target_fps);
    let mut buffer = Vec::with_capacity(size * size);
    let mut buttons = Buttons::default();
    let mut last_position = None;
    let mut frame_time = None;
    let mut shown = 0u64;
    while window.is_open() && !window.is_key_down(minifb::Key::Escape) {
        if settings.max_frames.is_some_and(|m| shown >= m) {
            break;
        }
        let start = Instant::now();
        let shift = window.is_key_down(minifb::Key::LeftShift)
            || window.is_key_down(minifb::Key::RightShift);
        let pin = window.is_key_down(minifb::Key::P);
        let mut events = Vec::new();
        if let Some((mx, my)) = window.get_mouse_pos(MouseMode::Clamp) {
            let x = (f64::from(mx) / size as f64).clamp(0.0, 1.0);
            let y = (1.0 - f64::from(my) / size as f64).clamp(0.0, 1.0);
            if last_position != Some((x, y)) {
                events.push(Event::Move { x, y });
                last_position = Some((x, y));
            }
            let left = window.get_mouse_down(MouseButton::Left);
            let right = window.get_mouse_down(MouseButton::Right);
            let middle = window.get_mouse_down(MouseButton::Middle);
            if left && !buttons.left {
                events.push(Event::Click { x, y, shift, pin });
            }
            match (right, buttons.right) {
                (true, false) => events.push(Event::RightPress { x, y }),
                (false, true) => events.push(Event::RightRelease),
                _ => {}
            }
            match (middle, buttons.middle) {
                (true, false) => events.push(Event::MiddlePress { x, y }),
                (false, true) => events.push(Event::MiddleRelease),
                _ => {}
            }
            buttons = Buttons {
                left,
                right,
                middle,
            };
        }
        for key in window.get_keys_pressed(KeyRepeat::No) {
            if let Some(key) = key_of(key) {
                events.push(Event::Key { key, shift });
            }
        }
        for event in events {
            // The window only produces positions inside the box, so nothing is refused here.
            if let Ok(Outcome::SaveRequested) = editor.handle(event) {
                let notice = match editor.save_scene(&settings.save_path) {
                    Ok(()) => format!("saved {}", settings.save_path.display()),
                    Err(e) => format!("not saved: {e}"),
                };
                editor.set_notice(notice);
            }
        }
        editor.advance();
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
