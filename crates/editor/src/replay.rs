//! Recorded event scripts (`EVENTS.json`) and the state record `--state-out` writes.

use serde::{Deserialize, Serialize};

use crate::event::{EventFields, FieldError};
use crate::{Editor, EditorError, Event};

/// Most frames a script may ask for (10,000 s of simulated time at the default 10 ms frame).
pub const MAX_SCRIPT_FRAMES: usize = 1_000_000;

/// One event of a script and the frame before whose simulation it is handled. As JSON, the
/// event's fields with `frame` beside them: `{"frame": 0, "kind": "click", "x": 0.3, "y": 0.5}`;
/// any other field is refused, naming it (see [`Event`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "EventFields")]
pub struct ScriptEvent {
    /// Frame index, 0-based, below [`Script::frames`].
    pub frame: usize,
    /// The event.
    #[serde(flatten)]
    pub event: Event,
}

impl TryFrom<EventFields> for ScriptEvent {
    type Error = FieldError;

    fn try_from(fields: EventFields) -> Result<Self, FieldError> {
        let event = fields.event()?;
        let frame = fields
            .frame
            .ok_or_else(|| FieldError("missing field `frame` for a script's event".into()))?;
        Ok(ScriptEvent { frame, event })
    }
}

/// An event script: `{"frames": 300, "events": [{"frame": 0, "kind": "click", "x": 0.3, "y":
/// 0.5, "shift": false}, …]}`, coordinates in the unit box (y up); the format is in
/// docs/editor.md. Unknown fields are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Frames to simulate.
    pub frames: usize,
    /// Events, in any order; events of one frame are handled in the order given.
    #[serde(default)]
    pub events: Vec<ScriptEvent>,
}

impl Script {
    /// Check the frame count and that every event's frame is below it; sort the events by frame
    /// (stable).
    ///
    /// # Errors
    /// [`EditorError::InvalidParameter`] naming `frames` or `events[k].frame`.
    pub fn validated(mut self) -> Result<Self, EditorError> {
        if !(1..=MAX_SCRIPT_FRAMES).contains(&self.frames) {
            return Err(EditorError::InvalidParameter {
                name: "frames",
                value: self.frames.to_string(),
                allowed: "1 to 1000000",
            });
        }
        if let Some(bad) = self.events.iter().find(|e| e.frame >= self.frames) {
            return Err(EditorError::InvalidParameter {
                name: "events[].frame",
                value: bad.frame.to_string(),
                allowed: "below the script's frame count",
            });
        }
        self.events.sort_by_key(|e| e.frame);
        Ok(self)
    }

    /// The script as JSON in the form it is read, one event a line so that a recording reads and
    /// edits easily. Numbers are written in the shortest form that reads back to the same f64.
    ///
    /// # Errors
    /// The encoder's, which the editor's own event types do not produce.
    pub(crate) fn to_json(&self) -> Result<String, serde_json::Error> {
        let mut text = format!("{{\"frames\": {}, \"events\": [", self.frames);
        for (k, event) in self.events.iter().enumerate() {
            text.push_str(if k == 0 { "\n  " } else { ",\n  " });
            text.push_str(&serde_json::to_string(event)?);
        }
        text.push_str(if self.events.is_empty() {
            "]}\n"
        } else {
            "\n]}\n"
        });
        Ok(text)
    }

    /// Replay on `editor`: for each frame, handle its events, [`Editor::advance`], then call
    /// `after_frame(frame, editor, save_requested)`. The callback may fail (writing a frame), which
    /// stops the replay.
    ///
    /// # Errors
    /// The first event the editor refuses ([`EditorError::PositionOutsideBox`]), or the
    /// callback's error.
    pub fn replay<F>(&self, editor: &mut Editor, mut after_frame: F) -> Result<(), EditorError>
    where
        F: FnMut(usize, &Editor, bool) -> Result<(), EditorError>,
    {
        let mut next = 0;
        for frame in 0..self.frames {
            let mut save = false;
            while next < self.events.len() && self.events[next].frame == frame {
                let outcome = editor.handle(self.events[next].event)?;
                save |= outcome == crate::Outcome::SaveRequested;
                next += 1;
            }
            editor.advance();
            after_frame(frame, editor, save)?;
        }
        Ok(())
    }
}

/// The editor's state as `--state-out STATE.json` writes it (read back, unknown fields are
/// refused).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateRecord {
    /// [[x, y], …], m.
    pub particles: Vec<[f64; 2]>,
    /// Indices of the pinned particles, increasing.
    pub pinned: Vec<usize>,
    /// [[i, j], …].
    pub springs: Vec<[u32; 2]>,
    /// Young's modulus Y, N (a spring of rest length l has k = Y / l).
    pub stiffness: f64,
    /// Drag rate, 1/s.
    pub drag: f64,
    /// Dashpot coefficient, N·s/m.
    pub dashpot: f64,
    /// The integrator's name ([`crate::IntegratorChoice::name`]).
    pub integrator: String,
    /// Frames advanced ([`Editor::frames`]).
    pub frame: u64,
    /// The failure shown, if any.
    pub failure: Option<String>,
}

impl StateRecord {
    /// The record of `editor` now.
    pub fn of(editor: &Editor) -> Self {
        StateRecord {
            particles: editor.positions().iter().map(|p| [p.x, p.y]).collect(),
            pinned: editor
                .pinned()
                .iter()
                .enumerate()
                .filter(|(_, &p)| p)
                .map(|(v, _)| v)
                .collect(),
            springs: editor.springs().iter().map(|s| [s.i, s.j]).collect(),
            stiffness: editor.young(),
            drag: editor.drag(),
            dashpot: editor.dashpot(),
            integrator: editor.integrator().name().to_string(),
            frame: editor.frames(),
            failure: editor.failure().map(str::to_string),
        }
    }
}
