//! The scene argument of the commands that take one (`hooke run`, `hooke bench`, `hooke edit`):
//! what an argument names when it is not what the command runs (a mesh file, a fluid scene, a
//! scene of the wrong dimension), and the lists their help texts show, made from the same
//! constants the commands parse (so that a new integrator, scene or solver appears in the help).

use std::path::Path;

use crate::sim::{scenes, Integrator};

/// Triangle surfaces the library reads (docs/formats.md §8).
const SURFACE_EXTENSIONS: &[&str] = &["obj", "stl"];

/// Tetrahedral meshes the library reads (docs/formats.md §8).
const TETRAHEDRA_EXTENSIONS: &[&str] = &["msh", "node", "ele", "vtk"];

/// If `scene` is a mesh file's name (by its extension), why it is not a scene and what to do with
/// it: `hooke mesh` for the mesh itself, or a scene file whose `[mesh]` table names it.
pub(crate) fn mesh_file_hint(scene: &str) -> Option<String> {
    let extension = Path::new(scene).extension()?.to_str()?.to_ascii_lowercase();
    let what = if SURFACE_EXTENSIONS.contains(&extension.as_str()) {
        format!(
            "a triangle surface (fill a closed one with tetrahedra by `hooke mesh tetrahedralize \
             {scene} --spacing S --out MESH.vtk`)"
        )
    } else if TETRAHEDRA_EXTENSIONS.contains(&extension.as_str()) {
        format!("a tetrahedral mesh (`hooke mesh quality {scene}` reports its quality)")
    } else {
        return None;
    };
    Some(format!(
        "{scene} is a mesh file, not a scene: {what}; to simulate it, write a scene file (.toml) \
         whose [mesh] table names it, file = \"{scene}\" (relative to the scene file), with its \
         stiffness and mass (docs/formats.md §1.2)"
    ))
}

/// If `scene` is a built-in fluid scene's name, or a scene file with a `[fluid]` table, the
/// command that runs or times it, for a command that does not (`what` says what this one does).
pub(crate) fn fluid_scene_hint(scene: &str, what: &str) -> Option<String> {
    let path = Path::new(scene);
    let fluid =
        crate::sph::is_builtin(scene) || (path.is_file() && crate::sph::is_fluid_file(path));
    fluid.then(|| {
        format!(
            "{scene} is a fluid scene (docs/sph.md) and {what}: run it with `hooke run {scene}`, \
             time it with `hooke bench --sph {scene}`"
        )
    })
}

/// The built-in scenes' names, spring scenes then fluid scenes, as `hooke scenes` lists them.
pub(crate) fn builtin_scene_names() -> Vec<String> {
    scenes::builtin_scenes()
        .into_iter()
        .map(|(name, _)| name)
        .chain(crate::sph::builtin_scenes().map(|(name, _)| name.to_string()))
        .collect()
}

/// The fluid integrators' names, comma separated.
pub(crate) fn fluid_integrator_names() -> String {
    hooke_sph::Integrator::ALL
        .iter()
        .map(|i| i.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// What an integrator is, in a few words, for the help: every one of [`Integrator::ALL`] is
/// listed, this adds the words.
fn integrator_words(integrator: Integrator) -> &'static str {
    match integrator {
        Integrator::ExplicitEuler => "forward Euler",
        Integrator::SymplecticEuler => "semi-implicit Euler",
        Integrator::Linearized => "linearised implicit Euler, β family",
        Integrator::Newton => "backward Euler by Newton",
        Integrator::ProjectiveDynamics => "backward Euler by projective dynamics",
        Integrator::Lbfgs => "backward Euler by L-BFGS on PD's factor",
        Integrator::NewtonCg => "backward Euler by inexact Newton, PCG",
        Integrator::ChebyshevPd => "projective dynamics with Chebyshev acceleration",
        _ => "",
    }
}

/// `hooke run`'s help of the scene argument: every built-in scene by name.
pub(crate) fn run_scene_help() -> String {
    format!(
        "A built-in scene ({}; `hooke scenes` describes them) or a scene file (.toml, \
         docs/formats.md §1)",
        builtin_scene_names().join(", ")
    )
}

/// `hooke run`'s help of `--integrator`: every spring integrator, and the fluid's.
pub(crate) fn run_integrator_help() -> String {
    let springs: Vec<String> = Integrator::ALL
        .iter()
        .map(|&i| match integrator_words(i) {
            "" => i.name().to_string(),
            words => format!("{} ({words})", i.name()),
        })
        .collect();
    format!(
        "Time integrator: {}. Default: the scene's. Fluid scenes: {}",
        springs.join(", "),
        fluid_integrator_names()
    )
}

/// `hooke bench`'s help of the scene argument: the scenes it measures, and where the others go.
pub(crate) fn bench_scene_help() -> String {
    let (contact, rest): (Vec<String>, Vec<String>) = scenes::builtin_scenes()
        .into_iter()
        .map(|(name, _)| name)
        .filter(|name| name != "seed-2d")
        .partition(|name| scenes::builtin_has_contact(name));
    let (moving, measured): (Vec<String>, Vec<String>) = rest
        .into_iter()
        .partition(|name| scenes::builtin_has_pin_path(name));
    let fluid: Vec<&str> = crate::sph::builtin_scenes().map(|(name, _)| name).collect();
    format!(
        "A built-in 3D spring scene without obstacles ({}) or such a scene file; not used with \
         --sweep or --hard-cases. The scenes with obstacles ({}) or moving pins ({}) are refused \
         here, since the measured step's objective has no contact term and holds pins still; \
         --hard-cases runs {}. The 2D seed-2d is not measured; the fluid scenes ({}) are timed by \
         --sph NAME",
        measured.join(", "),
        contact.join(", "),
        moving.join(", "),
        crate::bench::HARD_SCENES.join(", "),
        fluid.join(", ")
    )
}

/// `hooke bench`'s help of `--solver`: every spec kind with its values.
pub(crate) fn bench_solver_help() -> String {
    let kinds: Vec<String> = crate::bench::SolverKind::ALL
        .iter()
        .map(|k| k.usage())
        .collect();
    let defaults: Vec<String> = crate::bench::SolverSpec::defaults()
        .iter()
        .map(|s| s.kind.name().to_string())
        .collect();
    format!(
        "Solver and settings, repeatable: {}. A name alone takes its default settings. Default: \
         {} (with --sweep: {})",
        kinds.join("; "),
        defaults.join(", "),
        crate::bench::cli::SWEEP_DEFAULT_SOLVERS.join(", ")
    )
}

/// `hooke bench`'s help of `--hard-case`: every case by name.
pub(crate) fn hard_case_help() -> String {
    let names: Vec<&str> = crate::bench::HARD_CASES
        .iter()
        .chain(crate::bench::HARD_SCENES)
        .copied()
        .collect();
    format!(
        "With --hard-cases: run only this case (repeatable; default: every one, in this order: {})",
        names.join(", ")
    )
}

/// `hooke bench`'s help of `--hard-integrator`: every integrator of the matrix.
pub(crate) fn hard_integrator_help() -> String {
    format!(
        "With --hard-cases: run only this integrator (repeatable; default: every one of the \
         matrix: {}; also, by name only: {})",
        crate::bench::HARD_INTEGRATORS.join(", "),
        crate::bench::HARD_OPT_IN_INTEGRATORS.join(", ")
    )
}

/// `hooke bench`'s help of `--sph`: the built-in fluid scenes it runs whole.
pub(crate) fn bench_sph_help() -> String {
    let fluid: Vec<&str> = crate::sph::builtin_scenes().map(|(name, _)| name).collect();
    format!(
        "The fluid instead: time a 2D WCSPH step for each particle count, comma separated (e.g. \
         1e4,1e5), with the fluid's phase split, as a table (--json FILE, --plot FILE.png; \
         --repeats timed steps per count); an entry naming a built-in fluid scene ({}) runs that \
         scene whole as `hooke run` does and reports its wall time and particle-steps per second",
        fluid.join(", ")
    )
}
