//! One editing session's frames as the window runs them, without the window: what the window read
//! from the mouse and keyboard ([`FrameInput`]) becomes [`Event`]s, which the editor handles and a
//! recording keeps; one [`Editor::advance`] follows (then the save the save key asked for). The
//! window only polls its devices and draws, so a test drives this same code with made-up input.
//!
//! A recording is a [`Script`] (docs/editor.md): each event under the index of the frame it was
//! handled before, and the number of frames run. The editor has no clock, so replaying it on the
//! editor the session started from gives the same state bit for bit.

use std::path::PathBuf;

use crate::{
    Editor, EditorError, Event, Key, Outcome, Script, ScriptEvent, FRAME_SIZES, MAX_SCRIPT_FRAMES,
};

/// Frames between two writes of a recording while the session runs (5 s at the window's 60 frames
/// a second), so that a crash loses at most that much; the session's end writes it too.
pub const RECORD_EVERY_FRAMES: usize = 300;

/// What the window read from its devices for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameInput {
    /// The cursor in window pixels from the top-left corner (x right, y down), `None` when the
    /// window does not know it. Positions outside the window are clamped to its edge.
    pub mouse: Option<(f32, f32)>,
    /// The left button is down.
    pub left: bool,
    /// The right button is down.
    pub right: bool,
    /// The middle button is down.
    pub middle: bool,
    /// A shift key is down.
    pub shift: bool,
    /// The pin key (P) is down.
    pub pin: bool,
    /// The editor's keys pressed since the last frame, in order (no repeats of a held key).
    pub keys: Vec<Key>,
}

/// Mouse buttons as they were last frame, to turn levels into press and release edges.
#[derive(Clone, Copy, Debug, Default)]
struct Buttons {
    left: bool,
    right: bool,
    middle: bool,
}

/// The events of one session kept for a recording, and where it is written.
#[derive(Debug)]
struct Recorder {
    path: PathBuf,
    every: usize,
    script: Script,
    /// Frames in the recording when it was last written.
    written: Option<usize>,
}

impl Recorder {
    fn write(&mut self) -> Result<(), EditorError> {
        let text = self.script.to_json().map_err(|e| EditorError::Write {
            path: self.path.clone(),
            reason: e.to_string(),
        })?;
        crate::write_atomically(&self.path, text.as_bytes())?;
        self.written = Some(self.script.frames);
        Ok(())
    }

    /// Full: a longer script would be refused on replay.
    fn full(&self) -> bool {
        self.script.frames >= MAX_SCRIPT_FRAMES
    }
}

/// An editing session: turns each frame's [`FrameInput`] into events for an [`Editor`], saves the
/// scene when asked, records the events if told to, and advances the editor one frame.
///
/// ```
/// use hooke_editor::{Editor, EditorParams, FrameInput, Session};
///
/// let mut editor = Editor::new(EditorParams::default())?;
/// let mut session = Session::new(256, "edited.toml".into())?;
/// // A left click at the window's centre adds a particle at (0.5, 0.5).
/// let click = FrameInput { mouse: Some((128.0, 128.0)), left: true, ..FrameInput::default() };
/// session.frame(&mut editor, &click);
/// assert_eq!(editor.particle_count(), 1);
/// assert_eq!(session.frames(), 1);
/// # Ok::<(), hooke_editor::EditorError>(())
/// ```
#[derive(Debug)]
pub struct Session {
    size: u32,
    save_path: PathBuf,
    buttons: Buttons,
    last_position: Option<(f64, f64)>,
    frames: usize,
    recorder: Option<Recorder>,
}

impl Session {
    /// A session in a window of `size` × `size` pixels (the unit box) whose save key writes
    /// `save_path`.
    ///
    /// # Errors
    /// [`EditorError::FrameSize`] for a size outside [`FRAME_SIZES`].
    pub fn new(size: u32, save_path: PathBuf) -> Result<Self, EditorError> {
        if !FRAME_SIZES.contains(&size) {
            return Err(EditorError::FrameSize { size });
        }
        Ok(Session {
            size,
            save_path,
            buttons: Buttons::default(),
            last_position: None,
            frames: 0,
            recorder: None,
        })
    }

    /// Record the session's events to `path` (a [`Script`] as JSON), written atomically after the
    /// first frame, every `every` frames after that, and by [`Session::finish`]. A write that
    /// fails while the session runs is shown as the editor's notice and tried again `every`
    /// frames later. The recording stops at [`MAX_SCRIPT_FRAMES`] frames, the most a script
    /// replays, with a notice.
    ///
    /// # Errors
    /// [`EditorError::InvalidParameter`] for `every` = 0.
    pub fn recording_to(mut self, path: PathBuf, every: usize) -> Result<Self, EditorError> {
        if every == 0 {
            return Err(EditorError::InvalidParameter {
                name: "record every",
                value: "0".into(),
                allowed: "at least 1 frame",
            });
        }
        self.recorder = Some(Recorder {
            path,
            every,
            script: Script {
                frames: 0,
                events: Vec::new(),
            },
            written: None,
        });
        Ok(self)
    }

    /// The events `input` stands for, given the last frame's: a move when the cursor's unit-box
    /// position changed, a click on the left button's press, presses and releases of the right
    /// and middle buttons, then the keys. Updates the remembered buttons and cursor.
    pub fn events(&mut self, input: &FrameInput) -> Vec<Event> {
        let mut events = Vec::new();
        if let Some((mx, my)) = input.mouse {
            let size = f64::from(self.size);
            // A non-finite pixel position (no such thing from a window) clamps to a corner rather
            // than making an event the editor refuses.
            let unit = |v: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
            let x = unit(f64::from(mx) / size);
            let y = unit(1.0 - f64::from(my) / size);
            if self.last_position != Some((x, y)) {
                events.push(Event::Move { x, y });
                self.last_position = Some((x, y));
            }
            if input.left && !self.buttons.left {
                events.push(Event::Click {
                    x,
                    y,
                    shift: input.shift,
                    pin: input.pin,
                });
            }
            match (input.right, self.buttons.right) {
                (true, false) => events.push(Event::RightPress { x, y }),
                (false, true) => events.push(Event::RightRelease),
                _ => {}
            }
            match (input.middle, self.buttons.middle) {
                (true, false) => events.push(Event::MiddlePress { x, y }),
                (false, true) => events.push(Event::MiddleRelease),
                _ => {}
            }
            self.buttons = Buttons {
                left: input.left,
                right: input.right,
                middle: input.middle,
            };
        }
        for &key in &input.keys {
            events.push(Event::Key {
                key,
                shift: input.shift,
            });
        }
        events
    }

    /// One frame: the events of `input` handled in order and recorded, one [`Editor::advance`],
    /// then, if the save key was pressed, the scene written to the save path (its outcome shown as
    /// a notice), and the recording written if it is due. The save follows the frame, as in
    /// [`Script::replay`], so that a replayed recording saves the same file.
    pub fn frame(&mut self, editor: &mut Editor, input: &FrameInput) {
        let mut save = false;
        for event in self.events(input) {
            // Only events the editor took are recorded: a replay would stop at a refused one.
            // Events made from window input lie inside the box, so none is refused.
            let Ok(outcome) = editor.handle(event) else {
                continue;
            };
            save |= outcome == Outcome::SaveRequested;
            if let Some(recorder) = self.recorder.as_mut().filter(|r| !r.full()) {
                recorder.script.events.push(ScriptEvent {
                    frame: recorder.script.frames,
                    event,
                });
            }
        }
        editor.advance();
        self.frames += 1;
        if save {
            let notice = match editor.save_scene(&self.save_path) {
                Ok(()) => format!("saved {}", self.save_path.display()),
                Err(e) => format!("not saved: {e}"),
            };
            editor.set_notice(notice);
        }
        let Some(recorder) = self.recorder.as_mut() else {
            return;
        };
        if recorder.full() {
            return;
        }
        recorder.script.frames += 1;
        let due = recorder
            .written
            .is_none_or(|w| recorder.script.frames - w >= recorder.every);
        let full = recorder.full();
        if due || full {
            if let Err(e) = recorder.write() {
                editor.set_notice(format!("recording not written: {e}"));
                // Try again after another interval rather than every frame.
                recorder.written = Some(recorder.script.frames);
            } else if full {
                editor.set_notice(format!(
                    "recording stopped at {MAX_SCRIPT_FRAMES} frames, the most a script replays"
                ));
            }
        }
    }

    /// Frames run so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The recording so far, if the session records.
    pub fn recording(&self) -> Option<&Script> {
        self.recorder.as_ref().map(|r| &r.script)
    }

    /// End the session: write the recording, if any, one last time (nothing when no frame ran, as
    /// a script has at least one).
    ///
    /// # Errors
    /// [`EditorError::Write`] naming the recording's file.
    pub fn finish(self) -> Result<(), EditorError> {
        match self.recorder {
            Some(mut recorder) if recorder.script.frames > 0 => recorder.write(),
            _ => Ok(()),
        }
    }
}
