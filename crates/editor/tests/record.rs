//! The event, script and state formats refuse what they do not know, and a session recorded
//! through the window's own code path (without a window) replays to the same state bit for bit.

use std::path::Path;

use hooke_editor::{
    Editor, EditorParams, Event, FrameInput, Key, Script, ScriptEvent, Session, StateRecord,
};

/// Everything of the editor's state a replay must reproduce, f64s as bits (so 0.0 and −0.0, or
/// values one ulp apart, differ).
fn state(editor: &Editor) -> String {
    let bits = |v: &[hooke_editor::Vec2]| -> Vec<[u64; 2]> {
        v.iter().map(|p| [p.x.to_bits(), p.y.to_bits()]).collect()
    };
    let (cursor, attracting) = editor.cursor();
    format!(
        "positions {:?}\nvelocities {:?}\npinned {:?}\nsprings {:?}\nyoung {} drag {} dashpot {} \
         substeps {} integrator {:?} paused {} frames {} failure {:?} cursor {:?} attracting {} \
         dragging {:?}",
        bits(editor.positions()),
        bits(editor.velocities()),
        editor.pinned(),
        editor.springs(),
        editor.young().to_bits(),
        editor.drag().to_bits(),
        editor.dashpot().to_bits(),
        editor.substeps(),
        editor.integrator(),
        editor.is_paused(),
        editor.frames(),
        editor.failure(),
        [cursor.x.to_bits(), cursor.y.to_bits()],
        attracting,
        editor.dragging(),
    )
}

fn read_script(path: &Path) -> Script {
    let text = std::fs::read_to_string(path).unwrap();
    serde_json::from_str::<Script>(&text)
        .unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display()))
        .validated()
        .unwrap()
}

fn refused<T: serde::de::DeserializeOwned + std::fmt::Debug>(text: &str) -> String {
    match serde_json::from_str::<T>(text) {
        Ok(value) => panic!("{text} was read as {value:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn every_event_kind_refuses_a_stray_field_naming_it() {
    // The unit variants first: serde's internally tagged enums would take these silently.
    for (text, field) in [
        (r#"{"kind": "right_release", "x": 0.3}"#, "x"),
        (r#"{"kind": "middle_release", "shift": true}"#, "shift"),
        (r#"{"kind": "right_release", "colour": "red"}"#, "colour"),
        (r#"{"kind": "middle_release", "key": "d"}"#, "key"),
        (r#"{"kind": "click", "x": 0.3, "y": 0.5, "z": 0.1}"#, "z"),
        (
            r#"{"kind": "click", "x": 0.3, "y": 0.5, "key": "c"}"#,
            "key",
        ),
        (
            r#"{"kind": "move", "x": 0.3, "y": 0.5, "shift": true}"#,
            "shift",
        ),
        (
            r#"{"kind": "right_press", "x": 0.3, "y": 0.5, "pin": true}"#,
            "pin",
        ),
        (
            r#"{"kind": "middle_press", "x": 0.3, "y": 0.5, "button": 2}"#,
            "button",
        ),
        (r#"{"kind": "key", "key": "d", "x": 0.3}"#, "x"),
        (r#"{"kind": "key", "key": "d", "pin": false}"#, "pin"),
    ] {
        let message = refused::<Event>(text);
        assert!(message.contains(&format!("`{field}`")), "{text}: {message}");
        // The same inside a script, where the event's fields sit beside `frame`.
        let in_script = text.replacen('{', r#"{"frame": 0, "#, 1);
        let message = refused::<ScriptEvent>(&in_script);
        assert!(
            message.contains(&format!("`{field}`")),
            "{in_script}: {message}"
        );
        let script = format!(r#"{{"frames": 2, "events": [{in_script}]}}"#);
        let message = refused::<Script>(&script);
        assert!(
            message.contains(&format!("`{field}`")),
            "{script}: {message}"
        );
    }
}

#[test]
fn events_missing_a_field_or_with_null_are_refused_naming_it() {
    for (text, expected) in [
        (r#"{"kind": "click", "x": 0.3}"#, "missing field `y`"),
        (r#"{"kind": "move", "y": 0.3}"#, "missing field `x`"),
        (r#"{"kind": "key", "shift": true}"#, "missing field `key`"),
        (r#"{"x": 0.3, "y": 0.3}"#, "missing field `kind`"),
        (r#"{"kind": "click", "x": null, "y": 0.5}"#, "null"),
        (r#"{"kind": "right_release", "x": null}"#, "null"),
        (r#"{"kind": "jump"}"#, "unknown variant `jump`"),
        (r#"{"kind": "key", "key": "q"}"#, "unknown variant `q`"),
        (
            r#"{"kind": "move", "x": 0.3, "x": 0.4, "y": 0.5}"#,
            "duplicate field `x`",
        ),
        // An event alone has no frame; a script's event needs one.
        (
            r#"{"frame": 1, "kind": "right_release"}"#,
            "unknown field `frame`",
        ),
    ] {
        let message = refused::<Event>(text);
        assert!(message.contains(expected), "{text}: {message}");
    }
    let message = refused::<ScriptEvent>(r#"{"kind": "right_release"}"#);
    assert!(message.contains("missing field `frame`"), "{message}");
}

#[test]
fn scripts_and_state_records_refuse_unknown_fields() {
    let message = refused::<Script>(r#"{"frames": 2, "events": [], "fps": 60}"#);
    assert!(message.contains("unknown field `fps`"), "{message}");
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    editor.advance();
    let record = StateRecord::of(&editor);
    let mut json: serde_json::Value = serde_json::to_value(&record).unwrap();
    assert_eq!(
        serde_json::from_value::<StateRecord>(json.clone()).unwrap(),
        record,
        "a record reads back"
    );
    json["velocities"] = serde_json::json!([]);
    let message = serde_json::from_value::<StateRecord>(json)
        .unwrap_err()
        .to_string();
    assert!(message.contains("unknown field `velocities`"), "{message}");
}

/// The editor reads scene files through the library's reader, which refuses unknown keys too.
#[test]
fn a_saved_scene_with_a_stray_key_is_refused_naming_it() {
    let editor = Editor::seed(EditorParams::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("edited.toml");
    let text = editor.scene_file_text("edited").unwrap();
    let text = text.replacen("[damping]\n", "[damping]\nsquish = 2.0\n", 1);
    assert!(text.contains("squish"), "the damping table is there");
    std::fs::write(&path, text).unwrap();
    let message = Editor::open(EditorParams::default(), &path)
        .unwrap_err()
        .to_string();
    assert!(message.contains("squish"), "{message}");
}

#[test]
fn every_event_reads_back_as_it_is_written() {
    let events = [
        Event::Click {
            x: 0.1,
            y: 1.0 / 3.0,
            shift: false,
            pin: false,
        },
        Event::Click {
            x: 0.0,
            y: 1.0,
            shift: true,
            pin: true,
        },
        Event::Move {
            x: 0.123_456_789_012_345_67,
            y: f64::EPSILON,
        },
        Event::RightPress { x: 0.5, y: 0.25 },
        Event::RightRelease,
        Event::MiddlePress { x: 0.75, y: 0.5 },
        Event::MiddleRelease,
        Event::Key {
            key: Key::BracketLeft,
            shift: true,
        },
        Event::Key {
            key: Key::Space,
            shift: false,
        },
    ];
    for (frame, event) in events.into_iter().enumerate() {
        let text = serde_json::to_string(&event).unwrap();
        assert_eq!(
            serde_json::from_str::<Event>(&text).unwrap(),
            event,
            "{text}"
        );
        let scripted = ScriptEvent { frame, event };
        let text = serde_json::to_string(&scripted).unwrap();
        assert_eq!(
            serde_json::from_str::<ScriptEvent>(&text).unwrap(),
            scripted,
            "{text}"
        );
    }
    // False flags are left out, as a hand-written script would.
    let text = serde_json::to_string(&Event::Click {
        x: 0.5,
        y: 0.5,
        shift: false,
        pin: false,
    })
    .unwrap();
    assert_eq!(text, r#"{"kind":"click","x":0.5,"y":0.5}"#);
}

const SIZE: u32 = 256;

fn at(x: f32, y: f32) -> FrameInput {
    FrameInput {
        mouse: Some((x, y)),
        ..FrameInput::default()
    }
}

fn with_keys(mut input: FrameInput, keys: &[Key], shift: bool) -> FrameInput {
    input.keys = keys.to_vec();
    input.shift = shift;
    input
}

/// A session as a person would make it in the window, in window pixels (y down): a pinned
/// particle and a hanging structure, stiffness, drag from 0 and dashpot keys, a right-button pull
/// steered by the mouse, a middle-button drag, a pin toggle, a save, the integrator and substep
/// keys, a pause. Fractional pixels give coordinates with every bit of an f64 in use.
fn session_inputs() -> Vec<FrameInput> {
    let mut inputs = Vec::new();
    let mut hold = |input: FrameInput, frames: usize| {
        for _ in 0..frames {
            inputs.push(input.clone());
        }
    };
    hold(at(0.0, 0.0), 2);
    let mut pinned = at(128.3, 51.7);
    pinned.left = true;
    pinned.shift = true;
    hold(pinned, 2);
    hold(at(128.3, 51.7), 1);
    for (x, y) in [(115.1, 72.9), (141.6, 72.2), (127.9, 92.4), (153.3, 97.05)] {
        let mut click = at(x, y);
        click.left = true;
        hold(click, 1);
        hold(at(x, y), 3);
    }
    hold(with_keys(at(153.3, 97.05), &[Key::Y], false), 1);
    hold(with_keys(at(153.3, 97.05), &[Key::D, Key::D], false), 1);
    hold(with_keys(at(153.3, 97.05), &[Key::X], false), 1);
    hold(at(153.3, 97.05), 10);
    let mut pull = at(204.8, 153.6);
    pull.right = true;
    hold(pull.clone(), 5);
    for k in 0..15 {
        pull.mouse = Some((204.8 - 3.1 * k as f32, 153.6 + 1.7 * k as f32));
        hold(pull.clone(), 1);
    }
    hold(at(160.0, 180.0), 10);
    // The middle button moves the pinned particle, which stays where it is let go; the pin key
    // and a click there then unpin it.
    let mut grab = at(128.3, 51.7);
    grab.middle = true;
    hold(grab.clone(), 3);
    for k in 0..10 {
        grab.mouse = Some((128.3 - 4.3 * k as f32, 51.7 + 2.2 * k as f32));
        hold(grab.clone(), 1);
    }
    grab.middle = false;
    hold(grab.clone(), 10);
    let mut toggle = grab;
    toggle.left = true;
    toggle.pin = true;
    hold(toggle, 1);
    hold(at(160.0, 180.0), 10);
    hold(with_keys(at(128.3, 51.7), &[Key::S], false), 1);
    hold(with_keys(at(128.3, 51.7), &[Key::I, Key::I], false), 1);
    hold(with_keys(at(128.3, 51.7), &[Key::I], true), 1);
    hold(with_keys(at(128.3, 51.7), &[Key::BracketRight], false), 1);
    hold(at(300.0, -20.0), 20); // Outside the window: clamped to its edge.
    hold(with_keys(at(300.0, -20.0), &[Key::Space], false), 1);
    hold(at(10.0, 10.0), 5);
    inputs
}

#[test]
fn a_recorded_session_replays_to_the_same_state_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("events.json");
    let params = EditorParams {
        drag: 0.0,
        ..EditorParams::default()
    };
    let mut editor = Editor::seed(params).unwrap();
    let mut session = Session::new(SIZE, dir.path().join("saved.toml"))
        .unwrap()
        .recording_to(recording.clone(), 25)
        .unwrap();
    let inputs = session_inputs();
    let (mut pulled, mut dragged) = (false, false);
    for (k, input) in inputs.iter().enumerate() {
        session.frame(&mut editor, input);
        pulled |= editor.cursor().1;
        dragged |= editor.dragging().is_some();
        // Written after the first frame and every 25 frames after, so a crash loses little.
        if k == 0 || (k + 1) % 25 == 1 {
            assert_eq!(read_script(&recording).frames, k + 1, "frame {k}");
        }
    }
    assert_eq!(
        editor.notice(),
        Some(&*format!(
            "saved {}",
            dir.path().join("saved.toml").display()
        ))
    );
    assert!(
        pulled && dragged,
        "the right button pulled, the middle one dragged"
    );
    assert!(editor.failure().is_none(), "{:?}", editor.failure());
    assert!(editor.drag() > 0.0, "D raised the drag from 0");
    assert_eq!(
        editor.particle_count(),
        8,
        "the seed's three and five clicks"
    );
    assert!(editor.is_paused(), "the session ends paused");
    assert_eq!(
        editor.pinned().iter().filter(|&&p| p).count(),
        0,
        "the pin was toggled off"
    );
    let recorded = session.recording().unwrap().clone();
    session.finish().unwrap();
    let script = read_script(&recording);
    assert_eq!(script, recorded, "the file holds the whole recording");
    assert_eq!(script.frames, inputs.len());
    let kinds: Vec<&str> = [
        "click",
        "move",
        "right_press",
        "right_release",
        "middle_press",
    ]
    .into_iter()
    .chain(["middle_release", "key"])
    .collect();
    let text = std::fs::read_to_string(&recording).unwrap();
    for kind in kinds {
        assert!(
            text.contains(&format!(r#""kind":"{kind}""#)),
            "{kind} recorded"
        );
    }
    let mut replayed = Editor::seed(params).unwrap();
    let mut saves = 0;
    let replay_dir = tempfile::tempdir().unwrap();
    let replay_saved = replay_dir.path().join("saved.toml");
    script
        .replay(&mut replayed, |_, editor, save| {
            if save {
                saves += 1;
                editor.save_scene(&replay_saved)?;
            }
            Ok(())
        })
        .unwrap();
    assert_eq!(saves, 1);
    // The save key wrote the same scene in the session and in the replay.
    assert_eq!(
        std::fs::read_to_string(&replay_saved).unwrap(),
        std::fs::read_to_string(dir.path().join("saved.toml")).unwrap()
    );
    assert_eq!(state(&replayed), state(&editor));
    assert_eq!(StateRecord::of(&replayed), StateRecord::of(&editor));
    // The comparison sees one ulp: the pull's target moved by that gives another state.
    let mut nudged = script.clone();
    let press = nudged
        .events
        .iter_mut()
        .find(|e| matches!(e.event, Event::RightPress { .. }))
        .unwrap();
    let Event::RightPress { x, y } = press.event else {
        unreachable!()
    };
    press.event = Event::RightPress {
        x: f64::from_bits(x.to_bits() + 1),
        y,
    };
    let mut other = Editor::seed(params).unwrap();
    nudged.replay(&mut other, |_, _, _| Ok(())).unwrap();
    assert_ne!(state(&other), state(&editor));
}

#[test]
fn a_session_checks_its_settings_and_reports_a_recording_it_cannot_write() {
    assert!(Session::new(0, "s.toml".into()).is_err());
    let message = Session::new(SIZE, "s.toml".into())
        .unwrap()
        .recording_to("r.json".into(), 0)
        .unwrap_err()
        .to_string();
    assert!(message.contains("record every"), "{message}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing").join("events.json");
    let mut editor = Editor::new(EditorParams::default()).unwrap();
    let mut session = Session::new(SIZE, dir.path().join("s.toml"))
        .unwrap()
        .recording_to(path.clone(), 10)
        .unwrap();
    session.frame(&mut editor, &at(10.0, 10.0));
    let notice = editor.notice().unwrap_or_default().to_string();
    assert!(notice.starts_with("recording not written"), "{notice}");
    // The editor goes on; the session's end reports the failure, naming the file.
    session.frame(&mut editor, &at(20.0, 10.0));
    assert_eq!(editor.frames(), 2);
    let message = session.finish().unwrap_err().to_string();
    assert!(message.contains("events.json"), "{message}");
    // A session that ran no frame writes nothing: a script has at least one.
    let empty = dir.path().join("empty.json");
    Session::new(SIZE, dir.path().join("s.toml"))
        .unwrap()
        .recording_to(empty.clone(), 10)
        .unwrap()
        .finish()
        .unwrap();
    assert!(!empty.exists());
}
