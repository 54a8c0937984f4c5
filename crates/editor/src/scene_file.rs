//! Saving the editor's model as a scene file that `hooke run` accepts (the `particles` mesh
//! generator of [`hooke_sim::file`]), and opening one.

use std::path::Path;

use hooke_sim::file::load_scene;
use hooke_sim::scenes::AnySetup;
use serde::Serialize;

use crate::{Editor, EditorError, EditorParams};

#[derive(Serialize)]
struct Document {
    name: String,
    mesh: Mesh,
    pins: Pins,
    forces: Forces,
    damping: Damping,
    contact: Vec<Contact>,
    integrator: Integrator,
    run: Run,
}

#[derive(Serialize)]
struct Mesh {
    generator: &'static str,
    positions: Vec<[f64; 2]>,
    springs: Vec<[u32; 2]>,
    rest_lengths: Vec<f64>,
    particle_mass: f64,
    stiffness: f64,
}

#[derive(Serialize)]
struct Pins {
    vertices: Vec<u32>,
}

#[derive(Serialize)]
struct Forces {
    gravity: [f64; 2],
}

#[derive(Serialize)]
struct Damping {
    drag: f64,
    dashpot: f64,
}

#[derive(Serialize)]
struct Contact {
    shape: &'static str,
    min: [f64; 2],
    max: [f64; 2],
}

#[derive(Serialize)]
struct Integrator {
    method: &'static str,
    time_step: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    substeps: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    linear_solver: Option<&'static str>,
    energy_limit: &'static str,
}

#[derive(Serialize)]
struct Run {
    steps: usize,
}

/// Frames a saved scene runs for under `hooke run` (300 frames, 3 s at the default frame).
pub const SAVED_FRAMES: usize = 300;

impl Editor {
    /// The model as a scene file (TOML): the particles and springs (`generator = "particles"`,
    /// stiffness Y / l; the editor's springs share one rest length, or the file could not give them
    /// one stiffness), pins, gravity, drag, dashpot, the unit box, the integrator and the frame
    /// (explicit integrators: the frame time with the editor's substeps; implicit ones: the
    /// substep as their frame, as the editor steps them), 300 frames.
    ///
    /// # Errors
    /// [`EditorError::UnsupportedScene`] with no spring (a scene file's mesh needs one) or springs
    /// of different rest lengths (one stiffness per file).
    pub fn scene_file_text(&self, name: &str) -> Result<String, EditorError> {
        let unsupported = |reason: &str| EditorError::UnsupportedScene {
            reason: reason.to_string(),
        };
        let Some(first) = self.springs().first() else {
            return Err(unsupported("a scene file needs at least one spring"));
        };
        if self
            .springs()
            .iter()
            .any(|s| s.rest_length != first.rest_length)
        {
            return Err(unsupported(
                "the springs have different rest lengths, so no one stiffness k = Y/l fits them",
            ));
        }
        let settings = self.integrator().settings();
        let explicit = settings.integrator.is_explicit();
        let params = self.params();
        let document = Document {
            name: name.to_string(),
            mesh: Mesh {
                generator: "particles",
                positions: self.positions().iter().map(|p| [p.x, p.y]).collect(),
                springs: self.springs().iter().map(|s| [s.i, s.j]).collect(),
                rest_lengths: self.springs().iter().map(|s| s.rest_length).collect(),
                particle_mass: params.particle_mass,
                stiffness: self.young() / first.rest_length,
            },
            pins: Pins {
                vertices: self
                    .pinned()
                    .iter()
                    .enumerate()
                    .filter(|(_, &p)| p)
                    .map(|(v, _)| v as u32)
                    .collect(),
            },
            forces: Forces {
                gravity: [0.0, -params.gravity],
            },
            damping: Damping {
                drag: self.drag(),
                dashpot: self.dashpot(),
            },
            contact: vec![Contact {
                shape: "box",
                min: [0.0, 0.0],
                max: [1.0, 1.0],
            }],
            integrator: Integrator {
                method: settings.integrator.name(),
                time_step: if explicit {
                    params.frame_time
                } else {
                    self.substep()
                },
                substeps: explicit.then_some(self.substeps()),
                linear_solver: match settings.integrator {
                    hooke_sim::Integrator::Linearized => Some(settings.linearized.solver.name()),
                    _ => None,
                },
                energy_limit: "off",
            },
            run: Run {
                steps: if explicit {
                    SAVED_FRAMES
                } else {
                    SAVED_FRAMES * self.substeps()
                },
            },
        };
        toml::to_string(&document).map_err(|e| EditorError::Write {
            path: name.into(),
            reason: e.to_string(),
        })
    }

    /// Save [`Editor::scene_file_text`] to `path`, atomically.
    ///
    /// # Errors
    /// As [`Editor::scene_file_text`], and [`EditorError::Write`].
    pub fn save_scene(&self, path: &Path) -> Result<(), EditorError> {
        let name = path
            .file_stem()
            .map_or("edited".into(), |s| s.to_string_lossy().into_owned());
        crate::write_atomically(path, self.scene_file_text(&name)?.as_bytes())
    }

    /// Open a 2D scene file (as `hooke run` reads it) in the editor.
    ///
    /// # Errors
    /// [`EditorError::SceneFile`] if the file does not read, [`EditorError::UnsupportedScene`] for a
    /// 3D scene or one [`Editor::from_setup`] refuses.
    pub fn open(params: EditorParams, path: &Path) -> Result<Self, EditorError> {
        match load_scene(path)?.setup {
            AnySetup::Two(setup) => Editor::from_setup(params, &setup),
            AnySetup::Three(_) => Err(EditorError::UnsupportedScene {
                reason: "it is a 3D scene; the editor is 2D".into(),
            }),
        }
    }
}
