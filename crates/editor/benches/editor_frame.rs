//! One editor frame (10 substeps and the drawing at 512 px) with 1,000 particles, per integrator.
//!
//! Two models of 1,000 particles, both built by the editor's own click rule:
//! - `net-1000`: a 40 × 25 net of spacing 0.02 m, clicks joined within 0.021 m (its four lattice
//!   neighbours, 1,935 springs) at rest length 0.02 m, the top corners pinned: the sparse case,
//!   inside symplectic Euler's stability bound at the default 1 ms substep (k = Y/l = 5e4 N/m);
//! - `dense-1000`: 1,000 clicks on a 32 × 32 grid over the box with the editor's rule (0.15 m,
//!   rest 0.1 m): about 70 neighbours each, ~32,000 springs. Symplectic and forward Euler refuse
//!   it (far past their stability bound); the implicit integrators run it.
//!
//! `cargo bench -p hooke-editor --bench editor_frame` (release).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use hooke_editor::{Editor, EditorParams, Event, IntegratorChoice, Renderer};

fn click(editor: &mut Editor, x: f64, y: f64, shift: bool) {
    editor
        .handle(Event::Click {
            x,
            y,
            shift,
            pin: false,
        })
        .expect("inside the box");
}

fn net() -> Editor {
    let params = EditorParams {
        connection_radius: 0.021,
        rest_length: 0.02,
        max_particles: 1000,
        ..EditorParams::default()
    };
    let mut editor = Editor::new(params).unwrap();
    for row in 0..25 {
        for column in 0..40 {
            let pinned = row == 0 && (column == 0 || column == 39);
            click(
                &mut editor,
                0.1 + 0.02 * column as f64,
                0.9 - 0.02 * row as f64,
                pinned,
            );
        }
    }
    editor
}

fn dense() -> Editor {
    let params = EditorParams {
        max_particles: 1000,
        ..EditorParams::default()
    };
    let mut editor = Editor::new(params).unwrap();
    'grid: for row in 0..32 {
        for column in 0..32 {
            if editor.particle_count() == 1000 {
                break 'grid;
            }
            click(
                &mut editor,
                0.02 + 0.03 * column as f64,
                0.95 - 0.03 * row as f64,
                false,
            );
        }
    }
    editor
}

/// Each model under each integrator: the frame (advance + render), and its two parts apart
/// (`editor_step`: advance only; `editor_draw`: render only, of the model as the frames left it),
/// so that a change is seen where it lands.
fn frames(c: &mut Criterion) {
    let mut frame_group = c.benchmark_group("editor_frame");
    configure(&mut frame_group);
    let mut prepared = Vec::new();
    for (name, build) in [("net-1000", net as fn() -> Editor), ("dense-1000", dense)] {
        for &choice in IntegratorChoice::ALL {
            let mut editor = build();
            editor.set_integrator(choice);
            // The first frame builds the simulation (PD factors here); the frames measured step it.
            editor.advance();
            if let Some(failure) = editor.failure() {
                eprintln!("{name}/{}: refused: {failure}", choice.name());
                continue;
            }
            eprintln!(
                "{name}/{}: {} particles, {} springs",
                choice.name(),
                editor.particle_count(),
                editor.springs().len()
            );
            let mut renderer = Renderer::new(512).unwrap();
            frame_group.bench_function(format!("{name}/{}", choice.name()), |b| {
                b.iter(|| {
                    editor.advance();
                    black_box(renderer.render(&editor, None));
                })
            });
            if let Some(failure) = editor.failure() {
                eprintln!("{name}/{}: failed while measured: {failure}", choice.name());
            }
            prepared.push((format!("{name}/{}", choice.name()), editor, renderer));
        }
    }
    frame_group.finish();
    let mut step_group = c.benchmark_group("editor_step");
    configure(&mut step_group);
    for (id, editor, _) in &mut prepared {
        step_group.bench_function(id.as_str(), |b| b.iter(|| editor.advance()));
    }
    step_group.finish();
    let mut draw_group = c.benchmark_group("editor_draw");
    configure(&mut draw_group);
    for (id, editor, renderer) in &mut prepared {
        draw_group.bench_function(id.as_str(), |b| {
            b.iter(|| black_box(renderer.render(editor, None).width()))
        });
    }
    draw_group.finish();
}

fn configure(group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
}

criterion_group!(benches, frames);
criterion_main!(benches);
