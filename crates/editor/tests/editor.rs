//! The editor's behaviour: event handling, pins, clearing, every integrator on a recorded script,
//! failures that pause instead of panicking, and save/open round trips.

use hooke_editor::{
    Editor, EditorParams, Event, IntegratorChoice, Key, Script, Vec2, DASHPOT_FLOOR, DRAG_FLOOR,
};
use proptest::prelude::*;

fn click(x: f64, y: f64) -> Event {
    Event::Click {
        x,
        y,
        shift: false,
        pin: false,
    }
}

fn key(key: Key) -> Event {
    Event::Key { key, shift: false }
}

fn script(name: &str) -> Script {
    let path = format!("{}/tests/scripts/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let script: Script = serde_json::from_str(&text).unwrap();
    script.validated().unwrap()
}

fn inside_and_finite(editor: &Editor) -> Result<(), String> {
    for (v, p) in editor.positions().iter().enumerate() {
        if !(p.iter().all(|c| c.is_finite())
            && (0.0..=1.0).contains(&p.x)
            && (0.0..=1.0).contains(&p.y))
        {
            return Err(format!("particle {v} at {:?}", p));
        }
    }
    if !editor
        .velocities()
        .iter()
        .all(|v| v.iter().all(|c| c.is_finite()))
    {
        return Err("a velocity is not finite".into());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// A click joins the new particle to exactly the particles closer than the connection radius
    /// (brute force over every earlier particle), each spring with the default rest length.
    #[test]
    fn a_click_joins_exactly_the_particles_within_the_radius(
        points in prop::collection::vec((0.0..=1.0f64, 0.0..=1.0f64), 1..40),
    ) {
        let mut editor = Editor::new(EditorParams::default()).unwrap();
        for (k, &(x, y)) in points.iter().enumerate() {
            let before = editor.springs().len();
            editor.handle(click(x, y)).unwrap();
            let new: Vec<u32> = editor.springs()[before..]
                .iter()
                .map(|s| {
                    prop_assert_eq!(s.j as usize, k);
                    prop_assert_eq!(s.rest_length, 0.1);
                    Ok(s.i)
                })
                .collect::<Result<_, _>>()?;
            let expected: Vec<u32> = points[..k]
                .iter()
                .enumerate()
                .filter(|(_, &(px, py))| (Vec2::new(px, py) - Vec2::new(x, y)).norm() < 0.15)
                .map(|(i, _)| i as u32)
                .collect();
            prop_assert_eq!(new, expected);
        }
        prop_assert_eq!(editor.particle_count(), points.len());
    }
}

#[test]
fn clear_empties_the_model_and_the_editor_keeps_running() {
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    assert_eq!((editor.particle_count(), editor.springs().len()), (3, 3));
    editor.handle(key(Key::C)).unwrap();
    assert_eq!((editor.particle_count(), editor.springs().len()), (0, 0));
    editor.advance();
    assert!(editor.failure().is_none());
    // A lone particle has no spring: it falls ballistically and the floor stops it.
    editor.handle(click(0.5, 0.5)).unwrap();
    for _ in 0..100 {
        editor.advance();
    }
    assert_eq!(editor.positions()[0].y, 0.0, "the floor holds the particle");
    assert_eq!(editor.positions()[0].x, 0.5, "nothing pushes it sideways");
}

#[test]
fn pins_hold_and_the_pin_key_toggles_them() {
    let mut editor = Editor::new(EditorParams::default()).unwrap();
    editor
        .handle(Event::Click {
            x: 0.5,
            y: 0.8,
            shift: true,
            pin: false,
        })
        .unwrap();
    editor.handle(click(0.45, 0.72)).unwrap();
    editor.handle(click(0.55, 0.72)).unwrap();
    assert_eq!(editor.pinned(), &[true, false, false]);
    for choice in IntegratorChoice::ALL {
        editor.set_integrator(*choice);
        for _ in 0..20 {
            editor.advance();
        }
        assert!(
            editor.failure().is_none(),
            "{choice:?}: {:?}",
            editor.failure()
        );
        assert_eq!(
            editor.positions()[0],
            Vec2::new(0.5, 0.8),
            "{choice:?} moved the pin"
        );
    }
    // The hanging particles stay below the pin, held by their springs.
    assert!(editor.positions()[1].y < 0.8 && editor.positions()[1].y > 0.55);
    // Unpin it: the whole structure falls to the floor.
    editor
        .handle(Event::Click {
            x: 0.5,
            y: 0.8,
            shift: false,
            pin: true,
        })
        .unwrap();
    assert_eq!(editor.particle_count(), 3, "a pin click adds nothing");
    assert_eq!(editor.pinned(), &[false, false, false]);
    editor.set_integrator(IntegratorChoice::SymplecticEuler);
    for _ in 0..200 {
        editor.advance();
    }
    let lowest = editor.positions().iter().map(|p| p.y).fold(1.0, f64::min);
    assert_eq!(lowest, 0.0, "the unpinned structure lies on the floor");
}

#[test]
fn keys_change_the_settings_by_ten_per_cent() {
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    editor.handle(key(Key::Y)).unwrap();
    editor
        .handle(Event::Key {
            key: Key::D,
            shift: true,
        })
        .unwrap();
    editor.handle(key(Key::X)).unwrap();
    // One multiplication or division by 1.1: exact to rounding.
    assert!((editor.young() - 1100.0).abs() < 1e-9);
    assert!((editor.drag() - 1.0 / 1.1).abs() < 1e-12);
    assert!((editor.dashpot() - 110.0).abs() < 1e-9);
    let start = editor.integrator();
    for _ in 0..IntegratorChoice::ALL.len() {
        editor.handle(key(Key::I)).unwrap();
    }
    assert_eq!(
        editor.integrator(),
        start,
        "the integrator key cycles through all"
    );
    editor
        .handle(Event::Key {
            key: Key::I,
            shift: true,
        })
        .unwrap();
    assert_eq!(
        editor.integrator(),
        *IntegratorChoice::ALL.last().unwrap(),
        "shift + the integrator key cycles backwards"
    );
    editor.handle(key(Key::BracketRight)).unwrap();
    assert_eq!(editor.substeps(), 20);
    editor.handle(key(Key::Space)).unwrap();
    assert!(editor.is_paused());
    let before = editor.positions().to_vec();
    editor.advance();
    assert_eq!(editor.positions(), &before[..], "paused: nothing moves");
}

/// Drag and dashpot start from 0 (a scene without damping, or lowered to 0): the key raises them
/// to their floor, then by ten per cent; lowering below the floor gives 0 again.
#[test]
fn drag_and_dashpot_step_up_from_zero_and_back_to_zero() {
    let params = EditorParams {
        drag: 0.0,
        dashpot: 0.0,
        ..EditorParams::default()
    };
    let mut editor = Editor::seed(params).unwrap();
    let shifted = |key| Event::Key { key, shift: true };
    editor.handle(key(Key::D)).unwrap();
    editor.handle(key(Key::X)).unwrap();
    assert_eq!(
        (editor.drag(), editor.dashpot()),
        (DRAG_FLOOR, DASHPOT_FLOOR)
    );
    editor.handle(key(Key::D)).unwrap();
    editor.handle(key(Key::X)).unwrap();
    assert_eq!(editor.drag(), DRAG_FLOOR * 1.1);
    assert_eq!(editor.dashpot(), DASHPOT_FLOOR * 1.1);
    for _ in 0..2 {
        editor.handle(shifted(Key::D)).unwrap();
        editor.handle(shifted(Key::X)).unwrap();
    }
    assert_eq!((editor.drag(), editor.dashpot()), (0.0, 0.0));
    // Lowering 0 keeps 0; the editor runs undamped and damped without failing.
    editor.handle(shifted(Key::D)).unwrap();
    assert_eq!(editor.drag(), 0.0);
    for _ in 0..20 {
        editor.advance();
    }
    editor.handle(key(Key::D)).unwrap();
    editor.handle(key(Key::X)).unwrap();
    for _ in 0..20 {
        editor.advance();
    }
    assert!(editor.failure().is_none(), "{:?}", editor.failure());
    // From the default 1/s, 49 presses down reach 0 (1.1^-48 > 0.01 > 1.1^-49).
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    for press in 1..=49 {
        editor.handle(shifted(Key::D)).unwrap();
        assert_eq!(
            editor.drag() == 0.0,
            press == 49,
            "press {press}: {}",
            editor.drag()
        );
    }
}

#[test]
fn bad_positions_are_refused_and_change_nothing() {
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    for (x, y) in [
        (f64::NAN, 0.5),
        (0.5, 1.5),
        (-0.1, 0.2),
        (0.5, f64::INFINITY),
    ] {
        assert!(editor.handle(click(x, y)).is_err(), "({x}, {y})");
        assert!(editor.handle(Event::RightPress { x, y }).is_err());
    }
    assert_eq!(editor.particle_count(), 3);
    assert!(EditorParams {
        substeps: 0,
        ..EditorParams::default()
    }
    .validate()
    .is_err());
    let err = EditorParams {
        connection_radius: -1.0,
        ..EditorParams::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(err.contains("connection_radius"), "{err}");
}

/// The recorded script (building, pulling, dragging, pin toggle, stiffness and dashpot keys) under
/// every integrator: inside the box and finite at every frame, and no integrator fails on it.
#[test]
fn every_integrator_keeps_the_replay_inside_the_box_and_finite() {
    let script = script("build_and_pull.json");
    for choice in IntegratorChoice::ALL {
        let mut editor = Editor::seed(EditorParams::default()).unwrap();
        editor.set_integrator(*choice);
        script
            .replay(&mut editor, |frame, editor, _| {
                inside_and_finite(editor)
                    .unwrap_or_else(|e| panic!("{choice:?}, frame {frame}: {e}"));
                Ok(())
            })
            .unwrap();
        assert!(
            editor.failure().is_none(),
            "{choice:?}: {:?}",
            editor.failure()
        );
        assert_eq!(editor.particle_count(), 8);
        assert!(editor.is_paused(), "the script ends with space");
    }
}

#[test]
fn a_replay_is_deterministic() {
    let script = script("build_and_pull.json");
    let run = || {
        let mut editor = Editor::seed(EditorParams::default()).unwrap();
        editor.set_integrator(IntegratorChoice::Newton);
        script.replay(&mut editor, |_, _, _| Ok(())).unwrap();
        editor.positions().to_vec()
    };
    assert_eq!(run(), run());
}

/// Dense particles under symplectic Euler go past the explicit stability bound: the library
/// refuses the step, the editor shows it and pauses; switching to backward Euler and resuming
/// continues from the state before the refused frame.
#[test]
fn an_integrator_failure_pauses_and_a_retry_resumes() {
    let mut editor = Editor::new(EditorParams::default()).unwrap();
    for i in 0..6 {
        for j in 0..6 {
            editor
                .handle(click(0.3 + 0.03 * i as f64, 0.3 + 0.03 * j as f64))
                .unwrap();
        }
    }
    let before = editor.positions().to_vec();
    editor.advance();
    let failure = editor
        .failure()
        .expect("symplectic Euler refuses this step")
        .to_string();
    assert!(
        failure.contains("stability bound") && failure.contains("symplectic-euler"),
        "{failure}"
    );
    assert!(editor.is_paused());
    assert_eq!(
        editor.positions(),
        &before[..],
        "the refused frame changed nothing"
    );
    editor.set_integrator(IntegratorChoice::Newton);
    editor.handle(key(Key::Space)).unwrap();
    for _ in 0..30 {
        editor.advance();
    }
    assert!(editor.failure().is_none(), "{:?}", editor.failure());
    assert!(!editor.is_paused());
    inside_and_finite(&editor).unwrap();
    assert!(editor.stats().iterations > 0);
}

#[test]
fn a_saved_scene_opens_again_and_runs_under_hooke_run() {
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    editor
        .handle(Event::Click {
            x: 0.6,
            y: 0.9,
            shift: true,
            pin: false,
        })
        .unwrap();
    editor.handle(click(0.55, 0.8)).unwrap();
    editor.handle(key(Key::Y)).unwrap();
    editor.set_integrator(IntegratorChoice::LinearizedJacobi);
    for _ in 0..10 {
        editor.advance();
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("edited.toml");
    editor.save_scene(&path).unwrap();
    let opened = Editor::open(EditorParams::default(), &path).unwrap();
    assert_eq!(
        opened.positions(),
        editor.positions(),
        "positions round-trip exactly"
    );
    assert_eq!(opened.pinned(), editor.pinned());
    assert_eq!(opened.springs(), editor.springs());
    assert_eq!(opened.integrator(), IntegratorChoice::LinearizedJacobi);
    // k = Y/l written as decimal text and multiplied back by l: a few ulps.
    assert!((opened.young() - editor.young()).abs() < 1e-9 * editor.young());
    assert_eq!(
        (opened.drag(), opened.dashpot()),
        (editor.drag(), editor.dashpot())
    );
    // `hooke run` reads the same file and steps it.
    let file = hooke_sim::file::load_scene(&path).unwrap();
    let hooke_sim::scenes::AnySetup::Two(setup) = file.setup else {
        panic!("a 2D scene");
    };
    let mut sim = hooke_sim::Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
    for _ in 0..20 {
        sim.step().unwrap();
    }
}
