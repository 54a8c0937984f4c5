//! The canonical scenes of docs/scenes.md, built exactly as written there, by name.

use hooke_mesh::generators::{self, SEED_2D_REST_LENGTH};
use nalgebra::{SVector, Vector2, Vector3};

use crate::contact_model::{AdaptiveStiffness, BarrierSettings, Contact, SelfContact, Shape};
use crate::damping::Damping;
use crate::forces::ExternalForce;
use crate::integrator::{Integrator, Settings};
use crate::scene::{Keyframe, PinPath, Pins, Rotation, Scene, State};
use crate::SimError;

/// Gravity of the 3D scenes, m/s² (docs/scenes.md).
pub const GRAVITY: f64 = 9.81;
/// Gravity of the 2D sketch scene seed-2d, m/s² (the sketch's 9.8, docs/scenes.md §5).
pub const SEED_2D_GRAVITY: f64 = 9.8;
/// cloth-N soft stiffness, N/m.
pub const CLOTH_SOFT_STIFFNESS: f64 = 1e3;
/// cloth-N stiff stiffness, N/m.
pub const CLOTH_STIFF_STIFFNESS: f64 = 1e5;
/// Frame time step of cloth and beam, s.
pub const FRAME_TIME_STEP: f64 = 1.0 / 30.0;

/// A scene ready to run: the scene, its initial state, how many frames, and how to integrate.
#[derive(Clone, Debug, PartialEq)]
pub struct Setup<const D: usize> {
    /// The scene's name (e.g. `cloth-40`).
    pub name: String,
    /// The scene.
    pub scene: Scene<D>,
    /// The state at time 0.
    pub initial: State<D>,
    /// Number of frames to run.
    pub steps: usize,
    /// The integration settings.
    pub settings: Settings,
}

impl<const D: usize> Setup<D> {
    fn new(name: String, scene: Scene<D>, steps: usize, settings: Settings) -> Self {
        Setup {
            name,
            initial: scene.initial_state(),
            scene,
            steps,
            settings,
        }
    }
}

/// A setup in 2D or 3D.
#[derive(Clone, Debug, PartialEq)]
pub enum AnySetup {
    /// A 2D scene (seed-2d).
    Two(Setup<2>),
    /// A 3D scene (cloth, beam, meshes from files).
    Three(Setup<3>),
}

impl AnySetup {
    /// The scene's name.
    pub fn name(&self) -> &str {
        match self {
            AnySetup::Two(s) => &s.name,
            AnySetup::Three(s) => &s.name,
        }
    }
}

/// One line of `hooke scenes`: a name and what it is.
pub fn builtin_scenes() -> Vec<(String, String)> {
    let mut list = Vec::new();
    for n in [10, 20, 40, 80, 160, 320] {
        list.push((
            format!("cloth-{n}"),
            format!("{n}×{n} cloth, k = 1e3 N/m, pinned at two corners, 30 frames of 1/30 s"),
        ));
        list.push((
            format!("cloth-{n}-stiff"),
            format!("{n}×{n} cloth, k = 1e5 N/m"),
        ));
    }
    for n in [20, 40, 80] {
        list.push((
            format!("cloth-drape-{n}"),
            format!("{n}×{n} cloth, k = 1e3 N/m, no pins, released at y = 0.3 m over a sphere (centre (0.5, 0, 0.5), radius 0.25 m) and the ground y = −0.3, friction 0.1, 60 frames of 1/30 s"),
        ));
        list.push((
            format!("cloth-fall-{n}"),
            format!("{n}×{n} cloth, k = 1e3 N/m, no pins, thrown down at 5 m/s from y = 0.5 m onto the ground y = 0, friction 0.3, 30 frames of 1/30 s"),
        ));
        list.push((
            format!("cloth-twist-{n}"),
            format!("{n}×{n} cloth, k = 1e3 N/m, held at two opposite edges, one turned two full turns (720°) about the cloth's middle line in 4 s, gravity, 120 frames of 1/30 s: wrung into dense self-contact"),
        ));
    }
    for r in [2, 4, 8, 16] {
        list.push((
            format!("beam-{r}"),
            format!("4×1×1 m tetrahedral beam, {}×{r}×{r} cubes, k = 1e4 N/m, 1000 kg/m³, clamped at x = 0", 4 * r),
        ));
    }
    list.push((
        "bunny-drop".into(),
        "Stanford bunny (diagonal 0.3 m) filled with tetrahedra, k = 1e4 N/m, 1000 kg/m³, dropped from 0.2 m onto the ground y = 0 (frictionless), 60 frames of 1/60 s".into(),
    ));
    list.push((
        "torus-hang".into(),
        "torus (diagonal 0.3 m) filled with tetrahedra, k = 1e4 N/m, 1000 kg/m³, hanging from its top 2 %, 60 frames of 1/60 s".into(),
    ));
    list.push((
        "seed-2d".into(),
        "the 2D sketch's particles in a unit box: three particles fall, springs hold, walls stop them".into(),
    ));
    list
}

/// Build a built-in scene by name: `cloth-N`, `cloth-N-stiff`, `cloth-drape-N`, `cloth-fall-N` (any
/// N ≥ 2), `cloth-twist-N` (any N ≥ 3), `beam-R` (any R ≥ 1), `bunny-drop`, `torus-hang` or
/// `seed-2d`. Returns `None` for an unknown name.
///
/// # Errors
/// A [`SimError`] if the parameters are out of range (e.g. `cloth-1`).
pub fn builtin(name: &str) -> Option<Result<AnySetup, SimError>> {
    if name == "seed-2d" {
        return Some(seed_2d().map(AnySetup::Two));
    }
    if let Some(size) = name.strip_prefix("cloth-drape-") {
        let n: usize = size.parse().ok()?;
        return Some(cloth_drape(n).map(AnySetup::Three));
    }
    if let Some(size) = name.strip_prefix("cloth-fall-") {
        let n: usize = size.parse().ok()?;
        return Some(cloth_fall(n).map(AnySetup::Three));
    }
    if let Some(size) = name.strip_prefix("cloth-twist-") {
        let n: usize = size.parse().ok()?;
        return Some(cloth_twist(n).map(AnySetup::Three));
    }
    if let Some(rest) = name.strip_prefix("cloth-") {
        let (size, stiff) = match rest.strip_suffix("-stiff") {
            Some(size) => (size, true),
            None => (rest, false),
        };
        let n: usize = size.parse().ok()?;
        return Some(cloth(n, stiff).map(AnySetup::Three));
    }
    if name == "bunny-drop" {
        return Some(bunny_drop().map(AnySetup::Three));
    }
    if name == "torus-hang" {
        return Some(torus_hang().map(AnySetup::Three));
    }
    if let Some(size) = name.strip_prefix("beam-") {
        let r: usize = size.parse().ok()?;
        return Some(beam(r).map(AnySetup::Three));
    }
    None
}

/// Whether the built-in scene `name` has obstacles: `cloth-drape-N`, `cloth-fall-N`,
/// `bunny-drop` and `seed-2d` (its box). Answered from the name alone, without building the scene
/// (help texts list the scenes by it); `false` for an unknown name.
pub fn builtin_has_contact(name: &str) -> bool {
    name.starts_with("cloth-drape-")
        || name.starts_with("cloth-fall-")
        || name == "bunny-drop"
        || name == "seed-2d"
}

/// Whether the built-in scene `name` moves pins along a path (`cloth-twist-N`), from the name
/// alone like [`builtin_has_contact`]; `false` for an unknown name.
pub fn builtin_has_pin_path(name: &str) -> bool {
    name.starts_with("cloth-twist-")
}

fn gravity_3d() -> ExternalForce<3> {
    ExternalForce::Gravity {
        acceleration: Vector3::new(0.0, -GRAVITY, 0.0),
    }
}

/// cloth-N (docs/scenes.md §1): soft (k = 1e3 N/m) or stiff (k = 1e5 N/m); vertices 0 and N−1
/// pinned; gravity; h = 1/30 s; 30 frames; symplectic Euler with automatic substeps.
///
/// # Errors
/// [`SimError::Mesh`] if `n < 2`.
pub fn cloth(n: usize, stiff: bool) -> Result<Setup<3>, SimError> {
    let k = if stiff {
        CLOTH_STIFF_STIFFNESS
    } else {
        CLOTH_SOFT_STIFFNESS
    };
    let mesh = generators::cloth(n, k)?;
    let scene = Scene::new(mesh, FRAME_TIME_STEP)?
        .with_pins(Pins::Vertices(vec![0, n as u32 - 1]))?
        .with_forces(vec![gravity_3d()])?;
    let name = if stiff {
        format!("cloth-{n}-stiff")
    } else {
        format!("cloth-{n}")
    };
    // Backward Euler by Newton at the frame step: unconditionally stable, no substeps (the
    // default; the explicit integrators need ~100 substeps a frame here).
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    Ok(Setup::new(name, scene, 30, settings))
}

/// Height (m) cloth-drape-N's cloth is released at.
pub const DRAPE_HEIGHT: f64 = 0.3;
/// Centre (m) of cloth-drape-N's sphere: under the middle of the cloth.
pub const DRAPE_SPHERE_CENTER: [f64; 3] = [0.5, 0.0, 0.5];
/// Radius (m) of cloth-drape-N's sphere.
pub const DRAPE_SPHERE_RADIUS: f64 = 0.25;
/// Height (m) of cloth-drape-N's ground plane.
pub const DRAPE_GROUND: f64 = -0.3;
/// Friction coefficient of cloth-drape-N's sphere and ground.
pub const DRAPE_FRICTION: f64 = 0.1;
/// Height (m) cloth-fall-N's cloth starts at; its ground is y = 0.
pub const FALL_HEIGHT: f64 = 0.5;
/// Downward speed (m/s) every vertex of cloth-fall-N starts with.
pub const FALL_SPEED: f64 = 5.0;
/// Friction coefficient of cloth-fall-N's ground.
pub const FALL_FRICTION: f64 = 0.3;

/// cloth-N's mesh (k = 1e3 N/m, 1 kg) moved up to height `y` (m); rest lengths unchanged.
fn lifted_cloth(n: usize, y: f64) -> Result<hooke_mesh::SpringMesh3, SimError> {
    let mesh = generators::cloth(n, CLOTH_SOFT_STIFFNESS)?;
    let up = Vector3::new(0.0, y, 0.0);
    let positions = mesh.positions().iter().map(|p| p + up).collect();
    Ok(
        hooke_mesh::SpringMesh::new(positions, mesh.masses().to_vec(), mesh.springs().to_vec())?
            .with_triangles(mesh.triangles().to_vec())?,
    )
}

/// The barrier of the scenes with self-contact: the defaults with IPC's adaptive stiffness
/// (docs/contact.md), which needs fewer Newton iterations on every one of them. The library's
/// default keeps the stiffness fixed: its energy guarantee on convex obstacles needs that.
fn adaptive_barrier() -> BarrierSettings {
    BarrierSettings {
        adaptive_stiffness: Some(AdaptiveStiffness::default()),
        ..BarrierSettings::default()
    }
}

/// A ground plane y = `height` (m), normal +y, with friction `friction`.
fn ground(height: f64, friction: f64) -> Contact<3> {
    Contact {
        shape: Shape::Plane {
            point: Vector3::new(0.0, height, 0.0),
            normal: Vector3::y(),
        },
        friction,
    }
}

/// cloth-drape-N: cloth-N's cloth (N×N vertices on the unit square, k = 1e3 N/m, 1 kg) with no
/// pins, released from rest at y = [`DRAPE_HEIGHT`] over a sphere of centre
/// [`DRAPE_SPHERE_CENTER`] and radius [`DRAPE_SPHERE_RADIUS`] and a ground plane y =
/// [`DRAPE_GROUND`], both with friction [`DRAPE_FRICTION`]; gravity; 60 frames of h = 1/30 s by
/// backward Euler (Newton). The cloth falls onto the sphere and its sides fold down over it.
///
/// # Errors
/// [`SimError::Mesh`] if `n < 2`.
pub fn cloth_drape(n: usize) -> Result<Setup<3>, SimError> {
    let scene = Scene::new(lifted_cloth(n, DRAPE_HEIGHT)?, FRAME_TIME_STEP)?
        .with_forces(vec![gravity_3d()])?
        .with_contacts(vec![
            Contact {
                shape: Shape::Sphere {
                    center: Vector3::from(DRAPE_SPHERE_CENTER),
                    radius: DRAPE_SPHERE_RADIUS,
                },
                friction: DRAPE_FRICTION,
            },
            ground(DRAPE_GROUND, DRAPE_FRICTION),
        ])?
        .with_self_contact(Some(SelfContact::default()))?
        .with_barrier(adaptive_barrier())?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    Ok(Setup::new(format!("cloth-drape-{n}"), scene, 60, settings))
}

/// cloth-fall-N: cloth-N's cloth with no pins at y = [`FALL_HEIGHT`], every vertex moving down at
/// [`FALL_SPEED`], onto the ground plane y = 0 with friction [`FALL_FRICTION`]; gravity; 30 frames
/// of h = 1/30 s by backward Euler (Newton). The cloth hits the ground flat after about 0.09 s.
///
/// # Errors
/// [`SimError::Mesh`] if `n < 2`.
pub fn cloth_fall(n: usize) -> Result<Setup<3>, SimError> {
    let scene = Scene::new(lifted_cloth(n, FALL_HEIGHT)?, FRAME_TIME_STEP)?
        .with_forces(vec![gravity_3d()])?
        .with_contacts(vec![ground(0.0, FALL_FRICTION)])?
        .with_self_contact(Some(SelfContact::default()))?
        .with_barrier(adaptive_barrier())?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    let mut setup = Setup::new(format!("cloth-fall-{n}"), scene, 30, settings);
    for v in &mut setup.initial.velocities {
        *v = Vector3::new(0.0, -FALL_SPEED, 0.0);
    }
    Ok(setup)
}

/// The angle (degrees) cloth-twist-N's turning edge turns through: two full turns.
pub const TWIST_DEGREES: f64 = 720.0;
/// The time (s) over which cloth-twist-N's edge turns [`TWIST_DEGREES`], at constant angular
/// speed (180°/s); the scene runs exactly this long.
pub const TWIST_DURATION: f64 = 4.0;

/// cloth-twist-N: cloth-N's cloth (N×N vertices on the unit square in the x–z plane at y = 0,
/// k = 1e3 N/m, 1 kg) held by its two edges across x: the edge x = 0 (vertices 0..N) fixed, the
/// edge x = 1 (vertices N(N−1)..N²) turned right-handed about the x axis through the cloth's centre
/// (0.5, 0, 0.5) by [`TWIST_DEGREES`] over [`TWIST_DURATION`] at constant angular speed; gravity;
/// 120 frames of h = 1/30 s by backward Euler (Newton). The twist wrings the cloth into a rope, its
/// layers pressed through one another: a stress test of self-contact (docs/scenes.md).
///
/// # Errors
/// [`SimError::Mesh`] if `n < 2`; [`SimError::EverythingPinned`] for `n = 2` (both edges are the
/// whole cloth).
pub fn cloth_twist(n: usize) -> Result<Setup<3>, SimError> {
    let mesh = generators::cloth(n, CLOTH_SOFT_STIFFNESS)?;
    // The generator refuses n > 65,535, so n² fits a u32.
    let n32 = n as u32;
    let fixed: Vec<u32> = (0..n32).collect();
    let turning: Vec<u32> = ((n32 - 1) * n32..n32 * n32).collect();
    let turn = |time: f64, degrees: f64| Keyframe {
        time,
        offset: Vector3::zeros(),
        rotation: Some(Rotation {
            axis: Vector3::x(),
            point: Vector3::new(0.5, 0.0, 0.5),
            degrees,
        }),
    };
    let path = PinPath::Keyframes(vec![turn(0.0, 0.0), turn(TWIST_DURATION, TWIST_DEGREES)]);
    let scene = Scene::new(mesh, FRAME_TIME_STEP)?
        .with_pins(Pins::Vertices(fixed))?
        .with_pin_path(Pins::Vertices(turning), path)?
        .with_forces(vec![gravity_3d()])?
        .with_self_contact(Some(SelfContact::default()))?
        .with_barrier(adaptive_barrier())?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    let frames = (TWIST_DURATION / FRAME_TIME_STEP).round() as usize;
    Ok(Setup::new(
        format!("cloth-twist-{n}"),
        scene,
        frames,
        settings,
    ))
}

/// beam-R (docs/scenes.md §3): vertices with x = 0 pinned; gravity; h = 1/30 s; 30 frames.
///
/// # Errors
/// [`SimError::Mesh`] if `r == 0`.
pub fn beam(r: usize) -> Result<Setup<3>, SimError> {
    let mesh = generators::beam(r)?;
    let clamped: Vec<u32> = mesh
        .positions()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.x == 0.0)
        .map(|(v, _)| v as u32)
        .collect();
    let scene = Scene::new(mesh, FRAME_TIME_STEP)?
        .with_pins(Pins::Vertices(clamped))?
        .with_forces(vec![gravity_3d()])?;
    Ok(Setup::new(
        format!("beam-{r}"),
        scene,
        30,
        Settings::default(),
    ))
}

/// seed-2d (docs/scenes.md §5, the 2D sketch scene): unit box walls, particle mass 1 kg, frames of
/// 10 substeps of 1e-3 s, spring k = Y/l = 1e4 N/m, drag 1/s, dashpot 100 N·s/m, gravity 9.8 m/s²;
/// 300 frames (3 s).
///
/// # Errors
/// Never for the fixed parameters; the `Result` is for uniformity.
pub fn seed_2d() -> Result<Setup<2>, SimError> {
    let mesh = generators::seed_2d()?;
    debug_assert_eq!(mesh.springs()[0].rest_length, SEED_2D_REST_LENGTH);
    let scene = Scene::new(mesh, 1e-2)?
        .with_forces(vec![ExternalForce::Gravity {
            acceleration: Vector2::new(0.0, -SEED_2D_GRAVITY),
        }])?
        .with_damping(Damping {
            drag: 1.0,
            viscous: 0.0,
            dashpot: 100.0,
        })?
        .with_contacts(vec![Contact::new(Shape::Box {
            min: SVector::zeros(),
            max: Vector2::new(1.0, 1.0),
        })])?;
    let settings = Settings {
        integrator: Integrator::SymplecticEuler,
        substeps: Some(10),
        ..Settings::default()
    };
    Ok(Setup::new("seed-2d".into(), scene, 300, settings))
}

/// Bounding-box diagonal of the solids from surfaces (docs/scenes.md §4), m.
pub const SOLID_DIAGONAL: f64 = 0.3;
/// Lattice spacing of the solids from surfaces, as a fraction of their diagonal.
pub const SOLID_SPACING_FRACTION: f64 = 1.0 / 30.0;
/// Spring stiffness of the solids from surfaces, N/m.
pub const SOLID_STIFFNESS: f64 = 1e4;
/// Density of the solids from surfaces, kg/m³ (lumped: a quarter of each tetrahedron's mass to each
/// of its vertices).
pub const SOLID_DENSITY: f64 = 1000.0;
/// Frame time step of the solids from surfaces, s.
pub const SOLID_FRAME_TIME_STEP: f64 = 1.0 / 60.0;

/// The OBJ text of `data/meshes/bunny.obj`, built in so that the scene runs from any directory.
const BUNNY_OBJ: &str = include_str!("../../../data/meshes/bunny.obj");
/// The OBJ text of `data/meshes/torus.obj`.
const TORUS_OBJ: &str = include_str!("../../../data/meshes/torus.obj");

/// A built-in surface, turned by `orient`, scaled to a bounding-box diagonal of [`SOLID_DIAGONAL`]
/// and translated by `place` (given its box `[min, max]` after scaling), then filled with tetrahedra
/// at a spacing of [`SOLID_SPACING_FRACTION`] of the diagonal; springs on the edges, lumped masses.
fn solid_from_surface(
    obj: &str,
    file: &str,
    orient: impl Fn(Vector3<f64>) -> Vector3<f64>,
    place: impl Fn([Vector3<f64>; 2]) -> Vector3<f64>,
) -> Result<hooke_mesh::SpringMesh3, SimError> {
    let surface = hooke_mesh::io::parse_obj(obj.as_bytes(), std::path::Path::new(file))?;
    let turned: Vec<Vector3<f64>> = surface.positions().iter().map(|p| orient(*p)).collect();
    let (mut lo, mut hi) = (turned[0], turned[0]);
    for p in &turned {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let scale = SOLID_DIAGONAL / (hi - lo).norm();
    let shift = place([lo * scale, hi * scale]);
    let positions = turned.iter().map(|p| p * scale + shift).collect();
    let surface = hooke_mesh::TriMesh::new(positions, surface.triangles().to_vec())?;
    let stuffed =
        hooke_mesh::stuffing::fill_surface(&surface, SOLID_SPACING_FRACTION * SOLID_DIAGONAL)
            .map_err(|e| SimError::InvalidParameter {
                name: "mesh".into(),
                value: file.into(),
                reason: e.to_string(),
            })?;
    Ok(hooke_mesh::SpringMesh::from_tetrahedra(
        &stuffed.mesh,
        SOLID_STIFFNESS,
        hooke_mesh::MassModel::Density {
            density: SOLID_DENSITY,
            thickness: 1.0,
        },
    )?)
}

/// bunny-drop (docs/scenes.md §4): `data/meshes/bunny.obj` (z up in the file, turned
/// y up) scaled to a diagonal of 0.3 m, filled at a spacing of 0.01 m, k = 1e4 N/m, 1000 kg/m³
/// lumped, its lowest point 0.2 m above the frictionless ground plane y = 0; gravity; 60 frames of 1/60 s, by
/// backward Euler (Newton), the ground a barrier inside Newton's objective (docs/contact.md).
///
/// # Errors
/// Never for the built-in data; the `Result` is for uniformity.
pub fn bunny_drop() -> Result<Setup<3>, SimError> {
    let mesh = solid_from_surface(
        BUNNY_OBJ,
        "bunny.obj",
        |p| Vector3::new(p.x, p.z, -p.y),
        |[lo, hi]| Vector3::new(-0.5 * (lo.x + hi.x), 0.2 - lo.y, -0.5 * (lo.z + hi.z)),
    )?;
    let scene = Scene::new(mesh, SOLID_FRAME_TIME_STEP)?
        .with_forces(vec![gravity_3d()])?
        .with_contacts(vec![Contact::new(Shape::Plane {
            point: Vector3::zeros(),
            normal: Vector3::y(),
        })])?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    Ok(Setup::new("bunny-drop".into(), scene, 60, settings))
}

/// torus-hang (docs/scenes.md §4): `data/meshes/torus.obj` (axis y in the file, turned to z so that
/// the ring stands upright) filled as bunny-drop, the vertices within 2 % of the height of the top
/// pinned; gravity; 60 frames of 1/60 s by backward Euler (Newton).
///
/// # Errors
/// Never for the built-in data; the `Result` is for uniformity.
pub fn torus_hang() -> Result<Setup<3>, SimError> {
    let mesh = solid_from_surface(
        TORUS_OBJ,
        "torus.obj",
        |p| Vector3::new(p.x, -p.z, p.y),
        |[lo, hi]| -0.5 * (lo + hi),
    )?;
    let (low, top) = mesh
        .positions()
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, t), p| {
            (l.min(p.y), t.max(p.y))
        });
    let cut = top - 0.02 * (top - low);
    let pinned: Vec<u32> = mesh
        .positions()
        .iter()
        .enumerate()
        .filter(|(_, p)| p.y >= cut)
        .map(|(v, _)| v as u32)
        .collect();
    let scene = Scene::new(mesh, SOLID_FRAME_TIME_STEP)?
        .with_pins(Pins::Vertices(pinned))?
        .with_forces(vec![gravity_3d()])?;
    let settings = Settings {
        integrator: Integrator::Newton,
        ..Settings::default()
    };
    Ok(Setup::new("torus-hang".into(), scene, 60, settings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Simulation;

    /// cloth-twist-N pins its two edges across x, the far one on a path about the cloth's middle
    /// line; by name it builds for any N ≥ 3 and is listed for 20, 40 and 80.
    #[test]
    fn cloth_twist_pins_its_two_edges_and_turns_one() {
        let setup = cloth_twist(5).unwrap();
        assert_eq!(setup.name, "cloth-twist-5");
        assert_eq!((setup.steps, setup.scene.time_step()), (120, 1.0 / 30.0));
        assert_eq!(setup.settings.integrator, Integrator::Newton);
        let positions = setup.scene.mesh().positions();
        let pinned = setup.scene.pinned();
        assert_eq!(pinned, [0, 1, 2, 3, 4, 20, 21, 22, 23, 24]);
        for &v in pinned {
            let x = positions[v as usize].x;
            assert!(x == 0.0 || x == 1.0, "vertex {v} at x = {x}");
        }
        let paths = setup.scene.pin_paths();
        assert_eq!(paths.len(), 1);
        assert_eq!(paths[0].vertices, [20, 21, 22, 23, 24]);
        assert!(positions[20..].iter().all(|p| p.x == 1.0));
        // Constant angular speed: 180°/s, 720° at the end, held after.
        for (t, degrees) in [
            (0.0, 0.0),
            (1.0, 180.0),
            (2.0, 360.0),
            (4.0, 720.0),
            (5.0, 720.0),
        ] {
            assert!((paths[0].path.angle_degrees(t) - degrees).abs() < 1e-12);
        }
        assert_eq!(
            setup.scene.forces().gravity(),
            Some(Vector3::new(0.0, -GRAVITY, 0.0))
        );
        assert!(setup.scene.contacts().is_empty());
        assert!(builtin_has_pin_path("cloth-twist-40") && !builtin_has_contact("cloth-twist-40"));
        let listed: Vec<String> = builtin_scenes().into_iter().map(|(n, _)| n).collect();
        for n in [20, 40, 80] {
            assert!(listed.contains(&format!("cloth-twist-{n}")));
        }
        let Some(Ok(AnySetup::Three(by_name))) = builtin("cloth-twist-40") else {
            panic!("cloth-twist-40 builds by name")
        };
        assert_eq!(by_name.scene.mesh().vertex_count(), 1600);
        assert!(matches!(
            builtin("cloth-twist-2"),
            Some(Err(SimError::EverythingPinned { .. }))
        ));
        assert!(matches!(builtin("cloth-twist-1"), Some(Err(_))));
        assert!(builtin("cloth-twist-x").is_none());
    }

    /// After 1 s (30 frames) the turning edge has turned 180° about the line y = 0, z = 0.5: a
    /// vertex at (1, 0, z) is at (1, 0, 1 − z), to round-off of the 1 m cloth; the fixed edge has
    /// not moved.
    #[test]
    fn cloth_twist_edge_is_half_a_turn_round_after_one_second() {
        let setup = cloth_twist(6).unwrap();
        let start = setup.initial.positions.clone();
        let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
        for _ in 0..30 {
            sim.step().unwrap();
        }
        assert!((sim.state().time - 1.0).abs() < 1e-12);
        let (positions, velocities) = (&sim.state().positions, &sim.state().velocities);
        // Their velocity is the path's mean over the last step: the chord from 29/30 s to 1 s.
        let path = &sim.scene().pin_paths()[0].path;
        let h = 1.0 / 30.0;
        for (v, x0) in start.iter().enumerate().skip(30) {
            let expected = Vector3::new(1.0, 0.0, 1.0 - x0.z);
            let error = (positions[v] - expected).norm();
            assert!(error < 1e-12, "vertex {v}: {error:e} m off");
            let chord = (path.position(x0, 1.0) - path.position(x0, 1.0 - h)) / h;
            let error = (velocities[v] - chord).norm();
            assert!(error < 1e-9, "vertex {v}: velocity {error:e} m/s off");
        }
        assert_eq!(positions[..6], start[..6], "the fixed edge");
        // The free middle of the cloth is not where it started (it sags and twists).
        assert!((positions[15] - start[15]).norm() > 1e-3);
    }
}
