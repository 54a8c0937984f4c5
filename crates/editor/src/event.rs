//! What the editor reacts to: mouse and key events in unit-box coordinates (y up).

use serde::Deserialize;

/// A key the editor knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Key {
    /// Pause or resume (resuming after a failure retries with the current settings).
    Space,
    /// Clear every particle and spring.
    C,
    /// Young's modulus ×1.1 (shift: ÷1.1).
    Y,
    /// Drag ×1.1 (shift: ÷1.1); from 0 it steps to [`crate::DRAG_FLOOR`], and below that to 0.
    D,
    /// Dashpot ×1.1 (shift: ÷1.1); from 0 it steps to [`crate::DASHPOT_FLOOR`], and below that
    /// to 0.
    X,
    /// Next integrator (shift: previous).
    I,
    /// Save the scene (the front end writes the file).
    S,
    /// Halve the substeps per frame.
    #[serde(rename = "[")]
    BracketLeft,
    /// Double the substeps per frame.
    #[serde(rename = "]")]
    BracketRight,
}

/// One input event. Coordinates are in the unit box, y up, and must be finite and inside
/// [0, 1]² (the window is the box).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
#[non_exhaustive]
pub enum Event {
    /// Left click: add a particle joined to every particle within the connection radius
    /// (`shift`: pinned). With `pin` (the pin key, P, held) it toggles the pin of the particle
    /// under the cursor instead, and adds nothing.
    Click {
        /// m.
        x: f64,
        /// m.
        y: f64,
        /// Shift held.
        #[serde(default)]
        shift: bool,
        /// The pin key held.
        #[serde(default)]
        pin: bool,
    },
    /// The cursor moved (it steers the pull and the drag).
    Move {
        /// m.
        x: f64,
        /// m.
        y: f64,
    },
    /// Right button pressed: pull every particle toward the cursor while held.
    RightPress {
        /// m.
        x: f64,
        /// m.
        y: f64,
    },
    /// Right button released.
    RightRelease,
    /// Middle button pressed: grab the particle under the cursor (held at the cursor while
    /// dragged).
    MiddlePress {
        /// m.
        x: f64,
        /// m.
        y: f64,
    },
    /// Middle button released: let the particle go.
    MiddleRelease,
    /// A key press.
    Key {
        /// Which key.
        key: Key,
        /// Shift held.
        #[serde(default)]
        shift: bool,
    },
}

impl Event {
    /// The event's cursor position, if it has one.
    pub fn position(&self) -> Option<(f64, f64)> {
        match *self {
            Event::Click { x, y, .. }
            | Event::Move { x, y }
            | Event::RightPress { x, y }
            | Event::MiddlePress { x, y } => Some((x, y)),
            _ => None,
        }
    }
}
