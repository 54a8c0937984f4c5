//! `hooke edit --replay`: frames, the state record, refused input, and a session recorded as the
//! window records it (`--record`) replayed to the same state.

use std::path::PathBuf;

use clap::Parser;
use hooke_cli::edit_command::{run, EditArgs};
use hooke_editor::{Editor, EditorParams, FrameInput, Key, Session, StateRecord};

/// `hooke edit`'s arguments as the command line gives them.
#[derive(Parser)]
struct Edit {
    #[command(flatten)]
    args: EditArgs,
}

fn args(replay: PathBuf, frames: PathBuf) -> EditArgs {
    EditArgs {
        file: None,
        replay: Some(replay),
        frames: Some(frames),
        every: 10,
        size: 128,
        state_out: None,
        save: PathBuf::from("unused.toml"),
        record: None,
    }
}

#[test]
fn a_replay_writes_every_kth_frame_and_the_state() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("events.json");
    // The example script of docs/editor.md, with a save at frame 20.
    std::fs::write(
        &script,
        r#"{"frames": 100, "events": [{"frame": 0, "kind": "click", "x": 0.3, "y": 0.5, "shift": false},
            {"frame": 20, "kind": "key", "key": "s"},
            {"frame": 40, "kind": "key", "key": "space"}, {"frame": 60, "kind": "right_press", "x": 0.5, "y": 0.5},
            {"frame": 90, "kind": "right_release"}]}"#,
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let state = dir.path().join("state.json");
    let mut a = args(script, frames.clone());
    a.state_out = Some(state.clone());
    a.save = dir.path().join("saved.toml");
    run(&a).unwrap();
    let mut written: Vec<String> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    let expected: Vec<String> = (0..100)
        .step_by(10)
        .map(|f| format!("frame_{f:04}.png"))
        .collect();
    assert_eq!(written, expected);
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&state).unwrap()).unwrap();
    assert_eq!(
        record["particles"].as_array().unwrap().len(),
        4,
        "seed's three and the click"
    );
    // (0.3, 0.5) is 0.1 from (0.3, 0.4) and 0.141 from (0.4, 0.4), both within 0.15: 3 + 2 springs.
    assert_eq!(record["springs"].as_array().unwrap().len(), 5);
    assert_eq!(record["pinned"].as_array().unwrap().len(), 0);
    assert_eq!(record["integrator"], "symplectic-euler");
    assert_eq!(record["stiffness"], 1000.0);
    assert_eq!(record["frame"], 100);
    let saved = hooke_sim::file::load_scene(&dir.path().join("saved.toml")).unwrap();
    assert_eq!(saved.setup.name(), "saved");
}

#[test]
fn bad_scripts_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    for (text, expected) in [
        (
            r#"{"frames": 10, "events": [{"frame": 12, "kind": "key", "key": "c"}]}"#,
            "frame",
        ),
        (r#"{"frames": 0}"#, "frames"),
        (
            r#"{"frames": 5, "events": [{"frame": 1, "kind": "click", "x": 2.0, "y": 0.5}]}"#,
            "outside the unit box",
        ),
        (
            r#"{"frames": 5, "events": [{"frame": 1, "kind": "jump"}]}"#,
            "jump",
        ),
        (
            r#"{"frames": 5, "events": [{"frame": 1, "kind": "key", "key": "q"}]}"#,
            "q",
        ),
        (r#"{"frames": 5"#, "EOF"),
    ] {
        let script = dir.path().join("bad.json");
        std::fs::write(&script, text).unwrap();
        let err = run(&args(script, dir.path().join("f")))
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{text}: {err}");
    }
    let script = dir.path().join("ok.json");
    std::fs::write(&script, r#"{"frames": 1}"#).unwrap();
    let mut a = args(script, dir.path().join("f"));
    a.every = 0;
    assert!(run(&a).unwrap_err().to_string().contains("--every"));
    a.every = 1;
    a.size = 10;
    assert!(run(&a).unwrap_err().to_string().contains("64 to 4096"));
}

#[test]
fn record_is_a_window_flag() {
    let parsed = Edit::try_parse_from(["edit", "scene.toml", "--record", "events.json"]).unwrap();
    assert_eq!(parsed.args.record, Some(PathBuf::from("events.json")));
    assert_eq!(parsed.args.file, Some(PathBuf::from("scene.toml")));
    let message = Edit::try_parse_from([
        "edit",
        "--replay",
        "events.json",
        "--frames",
        "out",
        "--record",
        "again.json",
    ])
    .err()
    .expect("--record with --replay is refused")
    .to_string();
    assert!(message.contains("--record"), "{message}");
}

/// A session driven through the window's code path (`Session`, as `hooke edit --record` runs it)
/// writes a recording; `hooke edit --replay` of it writes the state the session ended in.
#[test]
fn a_recorded_session_replays_through_hooke_edit_to_the_same_state() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("recorded.json");
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    let mut session = Session::new(128, dir.path().join("window.toml"))
        .unwrap()
        .recording_to(recording.clone(), 1000)
        .unwrap();
    let at = |x: f32, y: f32| FrameInput {
        mouse: Some((x, y)),
        ..FrameInput::default()
    };
    let mut inputs = vec![at(60.3, 30.7); 3];
    inputs[1].left = true;
    inputs.push(FrameInput {
        keys: vec![Key::X, Key::I],
        ..at(60.3, 30.7)
    });
    for k in 0..30 {
        let mut pull = at(20.0 + 2.9 * k as f32, 90.1);
        pull.right = true;
        inputs.push(pull);
    }
    inputs.extend(vec![at(100.0, 100.0); 20]);
    for input in &inputs {
        session.frame(&mut editor, input);
    }
    session.finish().unwrap();
    let frames = dir.path().join("frames");
    let state = dir.path().join("state.json");
    let mut a = args(recording, frames);
    a.every = 1000;
    a.state_out = Some(state.clone());
    run(&a).unwrap();
    let replayed: StateRecord =
        serde_json::from_str(&std::fs::read_to_string(&state).unwrap()).unwrap();
    assert_eq!(replayed, StateRecord::of(&editor));
    assert_eq!(replayed.frame, inputs.len() as u64);
    assert_eq!(
        replayed.particles.len(),
        4,
        "the seed's three and the click"
    );
}
