//! What the editor takes from a library scene it opens (a scene file's setup), and what it refuses.
//!
//! The editor models one kind of scene: particles of one mass in the unit box, held by its walls,
//! joined by springs of one Young's modulus, under vertical gravity, with drag and dashpot damping,
//! stepped in frames of fixed substeps. A scene is opened when it is of that kind, and its values
//! become the editor's: particles, velocities, pins, springs, the mass, gravity, drag, dashpot, the
//! time step and the integrator. Anything the editor would otherwise drop (another force, viscous
//! damping, pins on a path, another obstacle, friction, several masses) refuses the scene with
//! [`EditorError::UnsupportedScene`] naming it; what the editor runs differently without changing
//! the physics (the file's solver settings, a scene without walls, a substep count beyond the
//! editor's) opens with a notice that says so.

use hooke_sim::scenes::Setup;
use hooke_sim::{stability_bound, ExternalForce, Integrator, Settings, Shape};

use crate::params::{IntegratorChoice, MAX_SUBSTEPS};
use crate::{EditorError, EditorParams};

/// A scene the editor can open: its parameters (time step, mass, gravity, drag and dashpot as the
/// scene has them), its Young's modulus, its integrator, and what the overlay should say about it.
#[derive(Debug)]
pub(crate) struct Opened {
    pub params: EditorParams,
    pub young: f64,
    pub integrator: IntegratorChoice,
    pub notice: Option<String>,
}

fn unsupported(reason: String) -> EditorError {
    EditorError::UnsupportedScene { reason }
}

/// Check `setup` against what the editor models and take its values over `params`'s.
///
/// # Errors
/// [`EditorError::UnsupportedScene`] naming the first part of the scene the editor cannot model.
pub(crate) fn open(params: EditorParams, setup: &Setup<2>) -> Result<Opened, EditorError> {
    let scene = &setup.scene;
    let mesh = scene.mesh();
    let n = mesh.vertex_count();
    if n > params.max_particles {
        return Err(unsupported(format!(
            "{n} particles, more than the editor's {}",
            params.max_particles
        )));
    }
    for (v, p) in setup.initial.positions.iter().enumerate() {
        if !(0.0..=1.0).contains(&p.x) || !(0.0..=1.0).contains(&p.y) {
            return Err(unsupported(format!(
                "particle {v} at ({}, {}) is outside the unit box",
                p.x, p.y
            )));
        }
    }
    let mut params = params;
    let masses = mesh.masses();
    if let Some(&mass) = masses.first() {
        if let Some((v, &other)) = masses.iter().enumerate().find(|&(_, &m)| m != mass) {
            return Err(unsupported(format!(
                "particle {v} has mass {other} kg, particle 0 has {mass} kg; the editor gives \
                 every particle one mass"
            )));
        }
        params.particle_mass = mass;
    }
    let young = match mesh.springs().first() {
        Some(first) => {
            let young = first.stiffness * first.rest_length;
            for (index, s) in mesh.springs().iter().enumerate() {
                let y = s.stiffness * s.rest_length;
                // Scene files store k = Y / l; a round trip through decimal text changes k·l by a
                // few ulps, nothing more.
                if (y - young).abs() > 1e-9 * young {
                    return Err(unsupported(format!(
                        "spring {index} has k·l = {y} N, spring 0 has {young} N; the editor keeps \
                         one Young's modulus"
                    )));
                }
            }
            young
        }
        None => params.young,
    };
    params.gravity = gravity(setup)?;
    let damping = scene.damping();
    if damping.viscous != 0.0 {
        return Err(unsupported(format!(
            "viscous damping {} N·s/m; the editor models drag and dashpot damping only",
            damping.viscous
        )));
    }
    params.drag = damping.drag;
    params.dashpot = damping.dashpot;
    if let Some(group) = scene.pin_paths().first() {
        return Err(unsupported(format!(
            "{} particles are pinned to a moving path; the editor's pins stay where they are",
            group.vertices.len()
        )));
    }
    let mut notices = Vec::new();
    let walls = walls(setup)?;
    if !walls {
        notices.push("the scene has no walls: the editor adds the unit box's".to_string());
    }
    let settings = &setup.settings;
    let integrator = IntegratorChoice::from_settings(settings);
    let (frame_time, substeps) = frame(&params, setup, &mut notices);
    params.frame_time = frame_time;
    params.substeps = substeps;
    let ignored = ignored_settings(settings, integrator);
    if !ignored.is_empty() {
        notices.push(format!(
            "not taken from the file: {} (the editor runs its own)",
            ignored.join(", ")
        ));
    }
    params.validate()?;
    Ok(Opened {
        params,
        young,
        integrator,
        notice: (!notices.is_empty()).then(|| notices.join("; ")),
    })
}

/// The magnitude of the scene's gravity (m/s²), which must point down (−y) or be absent.
fn gravity(setup: &Setup<2>) -> Result<f64, EditorError> {
    for force in setup.scene.forces().as_slice() {
        if !matches!(force, ExternalForce::Gravity { .. }) {
            return Err(unsupported(format!(
                "the force {force:?}; the editor models gravity only"
            )));
        }
    }
    let g = setup.scene.forces().gravity().unwrap_or_default();
    if g.x != 0.0 || g.y > 0.0 {
        return Err(unsupported(format!(
            "gravity ({}, {}) m/s²; the editor's gravity points down (0, −g)",
            g.x, g.y
        )));
    }
    Ok(-g.y)
}

/// Whether the scene has the editor's walls (the unit box, frictionless); refuses any other
/// obstacle.
fn walls(setup: &Setup<2>) -> Result<bool, EditorError> {
    let contacts = setup.scene.contacts();
    for (index, contact) in contacts.iter().enumerate() {
        let unit_box = matches!(contact.shape, Shape::Box { min, max }
            if min.x == 0.0 && min.y == 0.0 && max.x == 1.0 && max.y == 1.0);
        if !unit_box {
            return Err(unsupported(format!(
                "contact {index} is {:?}; the editor's only obstacle is the unit box's walls",
                contact.shape
            )));
        }
        if contact.friction != 0.0 {
            return Err(unsupported(format!(
                "contact {index} has friction {}; the editor's walls are frictionless",
                contact.friction
            )));
        }
    }
    Ok(!contacts.is_empty())
}

/// The frame (s) and substeps of the scene's time step h. An explicit integrator's h is a frame of
/// its substeps (the file's, or as many as the library's automatic choice: the fewest under the
/// safe stability bound); an implicit integrator steps h once, so h is the editor's substep and a
/// frame holds as many as come closest to the editor's frame time. Substeps beyond
/// [`MAX_SUBSTEPS`] are cut to it, with a notice (the editor then refuses the step as too long,
/// and says so, until another integrator is chosen).
fn frame(params: &EditorParams, setup: &Setup<2>, notices: &mut Vec<String>) -> (f64, usize) {
    let h = setup.scene.time_step();
    let settings = &setup.settings;
    if !settings.integrator.is_explicit() {
        let substeps = (params.frame_time / h)
            .round()
            .clamp(1.0, MAX_SUBSTEPS as f64) as usize;
        return (h * substeps as f64, substeps);
    }
    let wanted = settings.substeps.map_or_else(
        || {
            let (safe_step, _) =
                stability_bound(&setup.scene).for_integrator(settings.integrator, h);
            (h / safe_step).ceil().max(1.0)
        },
        |s| s as f64,
    );
    if wanted > MAX_SUBSTEPS as f64 {
        notices.push(format!(
            "{} needs {wanted:.0} substeps per frame; the editor runs at most {MAX_SUBSTEPS}",
            settings.integrator.name()
        ));
    }
    (h, wanted.min(MAX_SUBSTEPS as f64) as usize)
}

/// The file's settings that differ from what the editor runs for `choice`.
fn ignored_settings(settings: &Settings, choice: IntegratorChoice) -> Vec<&'static str> {
    let editor = choice.settings();
    let mut ignored = Vec::new();
    match settings.integrator {
        Integrator::Newton if settings.newton != editor.newton => ignored.push("newton settings"),
        Integrator::ProjectiveDynamics
            if hooke_solvers::PdParams {
                parallel: editor.pd.parallel,
                ..settings.pd
            } != editor.pd =>
        {
            ignored.push("pd settings")
        }
        Integrator::Linearized if settings.linearized != editor.linearized => {
            ignored.push("linearized settings")
        }
        _ => {}
    }
    if settings.pins != editor.pins {
        ignored.push("pin_method");
    }
    if settings.allow_unstable {
        ignored.push("allow_unstable");
    }
    ignored
}
