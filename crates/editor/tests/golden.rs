//! Replays of recorded event scripts against golden frames.
//!
//! A frame matches its golden PNG when at most [`MAX_DIFFERING_PIXELS`] pixels differ by more than
//! [`CHANNEL_TOLERANCE`] in some channel. Why these numbers: the simulation is deterministic, so on
//! one build every pixel is identical; what may differ is tiny-skia's anti-aliasing (its SIMD
//! paths, a future patch release; the version is pinned to =0.12.0) and ab_glyph's coverage,
//! both of which change edge pixels by a few levels of 255 and never move a shape. A particle moved
//! by one pixel changes more than 20 pixels by more than 24 levels at 256 px, so it fails.
//! `HOOKE_BLESS_GOLDEN=1 cargo test -p hooke-editor --test golden` rewrites the goldens.

use std::path::PathBuf;

use hooke_editor::{Editor, EditorParams, IntegratorChoice, Renderer, Script};
use tiny_skia::Pixmap;

const CHANNEL_TOLERANCE: u8 = 24;
const MAX_DIFFERING_PIXELS: usize = 16;
const SIZE: u32 = 256;

fn dir(sub: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join(sub)
}

/// Pixels that differ, in rows `first_row..` (0: the whole frame).
fn differing_pixels(a: &Pixmap, b: &Pixmap, first_row: u32) -> usize {
    let skip = (first_row * a.width()) as usize;
    a.pixels()[skip..]
        .iter()
        .zip(&b.pixels()[skip..])
        .filter(|(p, q)| {
            p.red().abs_diff(q.red()) > CHANNEL_TOLERANCE
                || p.green().abs_diff(q.green()) > CHANNEL_TOLERANCE
                || p.blue().abs_diff(q.blue()) > CHANNEL_TOLERANCE
        })
        .count()
}

fn check(script_name: &str, integrator: IntegratorChoice, frames: &[usize]) {
    let text = std::fs::read_to_string(dir("scripts").join(format!("{script_name}.json"))).unwrap();
    let script: Script = serde_json::from_str::<Script>(&text)
        .unwrap()
        .validated()
        .unwrap();
    let bless = std::env::var_os("HOOKE_BLESS_GOLDEN").is_some();
    let mut editor = Editor::seed(EditorParams::default()).unwrap();
    editor.set_integrator(integrator);
    let mut renderer = Renderer::new(SIZE).unwrap();
    let mut compared = 0;
    script
        .replay(&mut editor, |frame, editor, _| {
            if !frames.contains(&frame) {
                return Ok(());
            }
            renderer.render(editor, None);
            let path = dir("golden").join(format!(
                "{script_name}_{}_{frame:04}.png",
                integrator.name()
            ));
            if bless {
                renderer.save_png(&path)?;
                return Ok(());
            }
            let golden = Pixmap::load_png(&path).unwrap_or_else(|e| {
                panic!("{}: {e} (bless with HOOKE_BLESS_GOLDEN=1)", path.display())
            });
            let differing = differing_pixels(renderer.pixmap(), &golden, 0);
            assert!(
                differing <= MAX_DIFFERING_PIXELS,
                "{}: {differing} pixels differ by more than {CHANNEL_TOLERANCE} (at most \
                 {MAX_DIFFERING_PIXELS} may)",
                path.display()
            );
            compared += 1;
            Ok(())
        })
        .unwrap();
    if !bless {
        assert_eq!(compared, frames.len());
    }
}

#[test]
fn the_issue_example_matches_its_golden_frames() {
    check(
        "issue_example",
        IntegratorChoice::SymplecticEuler,
        &[0, 45, 75, 119],
    );
}

#[test]
fn building_pulling_and_dragging_match_their_golden_frames() {
    check(
        "build_and_pull",
        IntegratorChoice::SymplecticEuler,
        &[20, 50, 90, 119],
    );
    check(
        "build_and_pull",
        IntegratorChoice::ProjectiveDynamics,
        &[50, 119],
    );
}

/// The comparison itself: a frame differs from a copy with a particle moved.
#[test]
fn the_comparison_catches_a_moved_particle() {
    let mut renderer = Renderer::new(SIZE).unwrap();
    let editor = Editor::seed(EditorParams::default()).unwrap();
    let reference = renderer.render(&editor, None).clone();
    assert_eq!(differing_pixels(&reference, &reference, 0), 0);
    let mut moved = Editor::new(EditorParams::default()).unwrap();
    // The same three particles, the first one pixel (1/256) to the right.
    for (x, y) in [(0.3 + 1.0 / 256.0, 0.3), (0.3, 0.4), (0.4, 0.4)] {
        moved
            .handle(hooke_editor::Event::Click {
                x,
                y,
                shift: false,
                pin: false,
            })
            .unwrap();
    }
    let other = renderer.render(&moved, None);
    // Below the overlay (whose energy line changes too), so that the particle alone must fail it.
    assert!(differing_pixels(&reference, other, SIZE / 2) > MAX_DIFFERING_PIXELS);
}
