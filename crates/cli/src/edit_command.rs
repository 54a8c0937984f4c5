//! `hooke edit`: the interactive 2D editor in a window (`--record EVENTS.json` records the
//! session), or replayed headless from an event script (`--replay EVENTS.json --frames DIR`),
//! which is what tests and CI use. Keys and formats: docs/editor.md.

use std::path::{Path, PathBuf};

use hooke_editor::{Editor, EditorError, EditorParams, Renderer, Script, StateRecord};

/// `hooke edit` arguments.
#[derive(clap::Args, Debug)]
pub struct EditArgs {
    /// A 2D scene file to open (as `hooke run` reads it; `s` in the editor saves one), or the
    /// built-in 2D scene seed-2d. Without it the editor starts with three particles
    /// (docs/editor.md).
    pub file: Option<PathBuf>,
    /// Replay this event script headless instead of opening a window:
    /// {"frames": N, "events": [{"frame": 0, "kind": "click", "x": 0.3, "y": 0.5}, ..]}.
    #[arg(long, value_name = "EVENTS.json", requires = "frames")]
    pub replay: Option<PathBuf>,
    /// With --replay: write DIR/frame_NNNN.png (created if missing).
    #[arg(long, value_name = "DIR", requires = "replay")]
    pub frames: Option<PathBuf>,
    /// With --replay: write every K-th frame (frames 0, K, 2K, ..).
    #[arg(long, value_name = "K", default_value_t = 1, requires = "replay")]
    pub every: usize,
    /// Frame (and window) side in pixels, 64 to 4096.
    #[arg(long, value_name = "PIXELS", default_value_t = 512)]
    pub size: u32,
    /// With --replay: write the final state (particles, pins, springs, settings) as JSON.
    #[arg(long, value_name = "STATE.json", requires = "replay")]
    pub state_out: Option<PathBuf>,
    /// Where `s` saves the scene (window), or where a script's `s` saves it (replay).
    #[arg(long, value_name = "FILE.toml", default_value = "edited.toml")]
    pub save: PathBuf,
    /// With the window: record the session's events to this file as an event script that
    /// `--replay` reads (from the same FILE, or none), written every 300 frames and on closing.
    #[arg(long, value_name = "EVENTS.json", conflicts_with = "replay")]
    pub record: Option<PathBuf>,
}

/// What `hooke edit` can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EditError {
    /// The editor refused something (a scene, an event, a frame size, a write).
    #[error(transparent)]
    Editor(#[from] EditorError),
    /// A file could not be read or a directory made.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The event script is not valid JSON of the expected shape.
    #[error("{}: {source}", path.display())]
    Script {
        /// The script.
        path: PathBuf,
        /// The parser's message (line, column, field).
        source: serde_json::Error,
    },
    /// An argument out of range.
    #[error("invalid --{name}: {reason}")]
    Argument {
        /// The flag.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// The scene argument names something the editor does not open (a mesh file, a 3D or fluid
    /// scene): why, and what to use.
    #[error("{0}")]
    NotAnEditableScene(String),
    /// The window could not run.
    #[error(transparent)]
    Window(#[from] hooke_editor::window::WindowError),
}

/// Run `hooke edit`.
///
/// # Errors
/// [`EditError`].
pub fn run(args: &EditArgs) -> Result<(), EditError> {
    let params = EditorParams::default();
    let mut editor = match &args.file {
        Some(path) => open(params, path)?,
        None => Editor::seed(params)?,
    };
    match (&args.replay, &args.frames) {
        (Some(script), Some(frames)) => replay(args, &mut editor, script, frames),
        _ => {
            // What a killed session left beside the files this one writes.
            for path in args.record.iter().chain([&args.save]) {
                hooke_mesh::io::remove_temporaries_of(path).map_err(|e| EditorError::Write {
                    path: path.clone(),
                    reason: e.to_string(),
                })?;
            }
            let settings = hooke_editor::window::WindowSettings {
                size: args.size,
                save_path: args.save.clone(),
                record_path: args.record.clone(),
                ..Default::default()
            };
            hooke_editor::window::run(&mut editor, &settings)?;
            Ok(())
        }
    }
}

/// The editor on the scene `path` names: a 2D scene file, or the built-in seed-2d; the other
/// built-in scenes, fluid scenes and mesh files are refused with what to use instead.
fn open(params: EditorParams, path: &Path) -> Result<Editor, EditError> {
    let text = path.to_string_lossy();
    let refusal = crate::scene_arg::mesh_file_hint(&text).or_else(|| {
        crate::scene_arg::fluid_scene_hint(&text, "the editor edits 2D mass-spring scenes")
    });
    if let Some(reason) = refusal {
        return Err(EditError::NotAnEditableScene(reason));
    }
    if path.exists() {
        return Ok(Editor::open(params, path)?);
    }
    match crate::sim::scenes::builtin(&text) {
        Some(Ok(crate::sim::scenes::AnySetup::Two(setup))) => {
            Ok(Editor::from_setup(params, &setup)?)
        }
        Some(Ok(crate::sim::scenes::AnySetup::Three(_))) => {
            Err(EditError::NotAnEditableScene(format!(
                "{text} is a built-in 3D scene (`hooke run {text}` runs it); the editor edits 2D \
                 scenes: seed-2d or a 2D scene file"
            )))
        }
        Some(Err(e)) => Err(EditError::NotAnEditableScene(format!("{text}: {e}"))),
        None => Ok(Editor::open(params, path)?),
    }
}

fn replay(
    args: &EditArgs,
    editor: &mut Editor,
    script_path: &Path,
    frames: &Path,
) -> Result<(), EditError> {
    if args.every == 0 {
        return Err(EditError::Argument {
            name: "every",
            reason: "must be at least 1".into(),
        });
    }
    let text = std::fs::read_to_string(script_path).map_err(|source| EditError::Io {
        path: script_path.to_path_buf(),
        source,
    })?;
    let script: Script = serde_json::from_str(&text).map_err(|source| EditError::Script {
        path: script_path.to_path_buf(),
        source,
    })?;
    let script = script.validated()?;
    let mut renderer = Renderer::new(args.size)?;
    std::fs::create_dir_all(frames).map_err(|source| EditError::Io {
        path: frames.to_path_buf(),
        source,
    })?;
    script.replay(editor, |frame, editor, save| {
        if save {
            editor.save_scene(&args.save)?;
        }
        if frame % args.every == 0 {
            renderer.render(editor, None);
            renderer.save_png(&frames.join(format!("frame_{frame:04}.png")))?;
        }
        Ok(())
    })?;
    if let Some(path) = &args.state_out {
        let record = StateRecord::of(editor);
        let json = serde_json::to_string_pretty(&record).expect("a state record serialises");
        hooke_editor::write_atomically(path, json.as_bytes())?;
    }
    if let Some(failure) = editor.failure() {
        eprintln!("note: the replay ended paused on a failure: {failure}");
    }
    Ok(())
}
