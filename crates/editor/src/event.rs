//! What the editor reacts to: mouse and key events in unit-box coordinates (y up), and their JSON
//! form (docs/editor.md): `{"kind": "click", "x": 0.3, "y": 0.5}`, each kind with exactly its own
//! fields; any other field is refused, naming it.

use serde::{Deserialize, Deserializer, Serialize};

/// A key the editor knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
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
///
/// As JSON (docs/editor.md) the `kind` names the variant in snake case and the other fields are the
/// variant's: `{"kind": "right_release"}`, `{"kind": "key", "key": "d", "shift": true}`. `shift`
/// and `pin` may be left out (false) and are not written when false. A field the kind does not
/// take, `null` for a field, or a missing coordinate is refused with a message naming the field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", try_from = "EventFields")]
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
        #[serde(skip_serializing_if = "is_false")]
        shift: bool,
        /// The pin key held.
        #[serde(skip_serializing_if = "is_false")]
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
        #[serde(skip_serializing_if = "is_false")]
        shift: bool,
    },
}

fn is_false(flag: &bool) -> bool {
    !*flag
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

/// An event's `kind`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Kind {
    Click,
    Move,
    RightPress,
    RightRelease,
    MiddlePress,
    MiddleRelease,
    Key,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Click => "click",
            Kind::Move => "move",
            Kind::RightPress => "right_press",
            Kind::RightRelease => "right_release",
            Kind::MiddlePress => "middle_press",
            Kind::MiddleRelease => "middle_release",
            Kind::Key => "key",
        }
    }

    /// The fields besides `kind` that an event of this kind takes.
    fn fields(self) -> &'static [&'static str] {
        match self {
            Kind::Click => &["x", "y", "shift", "pin"],
            Kind::Move | Kind::RightPress | Kind::MiddlePress => &["x", "y"],
            Kind::RightRelease | Kind::MiddleRelease => &[],
            Kind::Key => &["key", "shift"],
        }
    }
}

/// Every field an event, or a script's event (with its `frame`), may have. The events are read
/// through this flat record rather than serde's internally tagged enums because those let a unit
/// variant (`right_release`) take any stray field, and `deny_unknown_fields` does not reach
/// through `#[serde(flatten)]`; which fields a kind takes is checked in [`EventFields::event`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EventFields {
    #[serde(default, deserialize_with = "present")]
    pub(crate) frame: Option<usize>,
    kind: Kind,
    #[serde(default, deserialize_with = "present")]
    x: Option<f64>,
    #[serde(default, deserialize_with = "present")]
    y: Option<f64>,
    #[serde(default, deserialize_with = "present")]
    shift: Option<bool>,
    #[serde(default, deserialize_with = "present")]
    pin: Option<bool>,
    #[serde(default, deserialize_with = "present")]
    key: Option<Key>,
}

/// A field that is there: `Some` of its value (`null` is refused as not a value of the type,
/// where `Option`'s own deserializer would read it as absent).
fn present<'de, D, T>(deserializer: D) -> Result<Option<T>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    T::deserialize(deserializer).map(Some)
}

/// Why event fields do not make an event (serde shows it with the position in the file).
#[derive(Debug)]
pub(crate) struct FieldError(pub(crate) String);

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl EventFields {
    /// The event these fields describe, `frame` aside.
    ///
    /// # Errors
    /// A field the kind does not take, or one it needs missing, named.
    pub(crate) fn event(&self) -> Result<Event, FieldError> {
        let kind = self.kind;
        let takes = kind.fields();
        let given = [
            ("x", self.x.is_some()),
            ("y", self.y.is_some()),
            ("shift", self.shift.is_some()),
            ("pin", self.pin.is_some()),
            ("key", self.key.is_some()),
        ];
        if let Some((field, _)) = given
            .iter()
            .find(|&&(field, there)| there && !takes.contains(&field))
        {
            let allowed = if takes.is_empty() {
                "no field but `kind`".to_string()
            } else {
                let names: Vec<String> = takes.iter().map(|f| format!("`{f}`")).collect();
                names.join(", ")
            };
            return Err(FieldError(format!(
                "unknown field `{field}`: an event of kind `{}` takes {allowed}",
                kind.name()
            )));
        }
        let need = |value: Option<f64>, field: &str| {
            value.ok_or_else(|| {
                FieldError(format!(
                    "missing field `{field}` for an event of kind `{}`",
                    kind.name()
                ))
            })
        };
        let shift = self.shift.unwrap_or(false);
        Ok(match kind {
            Kind::Click => Event::Click {
                x: need(self.x, "x")?,
                y: need(self.y, "y")?,
                shift,
                pin: self.pin.unwrap_or(false),
            },
            Kind::Move => Event::Move {
                x: need(self.x, "x")?,
                y: need(self.y, "y")?,
            },
            Kind::RightPress => Event::RightPress {
                x: need(self.x, "x")?,
                y: need(self.y, "y")?,
            },
            Kind::RightRelease => Event::RightRelease,
            Kind::MiddlePress => Event::MiddlePress {
                x: need(self.x, "x")?,
                y: need(self.y, "y")?,
            },
            Kind::MiddleRelease => Event::MiddleRelease,
            Kind::Key => Event::Key {
                key: self.key.ok_or_else(|| {
                    FieldError("missing field `key` for an event of kind `key`".into())
                })?,
                shift,
            },
        })
    }
}

impl TryFrom<EventFields> for Event {
    type Error = FieldError;

    fn try_from(fields: EventFields) -> Result<Self, FieldError> {
        if fields.frame.is_some() {
            return Err(FieldError(
                "unknown field `frame`: an event alone has none (a script's events do)".into(),
            ));
        }
        fields.event()
    }
}
