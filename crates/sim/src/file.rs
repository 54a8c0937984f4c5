//! Scene files: TOML documents that describe a scene completely (mesh source, material, pins,
//! forces, damping, contact, integrator, number of frames, output format).
//!
//! ```toml
//! name = "cloth-40"
//!
//! [mesh]
//! generator = "cloth"      # "cloth" (n), "beam" (r), "seed-2d" or "particles"; or file = "path" (OBJ, STL, MSH, TetGen)
//! n = 40
//! stiffness = 1000.0       # N/m
//! # bending = "interior-edges"              (triangle files only)
//! # mass = { total = 1.0 }                  (kg, spread evenly), or
//! # mass = { density = 1000.0, thickness = 0.001 }   (kg/m³, m)
//! # "particles" (what `hooke edit` saves) lists the graph itself, in 2D or 3D:
//! # positions = [[0.3, 0.3], [0.3, 0.4]]   # m
//! # springs = [[0, 1]]                     # particle pairs
//! # rest_lengths = [0.1]                   # m, one per spring (stiffness applies to every spring)
//! # particle_mass = 1.0                    # kg, every particle
//! # fill = { spacing = 0.01 }              (closed surface files: fill with tetrahedra, lattice spacing m)
//! # transform = { scale = 2.0, rotate = { axis = [0.0, 1.0, 0.0], degrees = 90.0 }, translate = [0.0, 0.3, 0.0] }
//! #                        # scale (> 0, about the origin), then rotate (degrees, right-handed
//! #                        # about the axis through the origin), then translate (m); every part
//! #                        # optional. 2D meshes: rotate = { degrees = .. } only, counter-clockwise
//! #                        # about the origin; translate = [x, y]
//!
//! [pins]
//! vertices = [0, 39]       # and/or region = { min = [..], max = [..] }
//! # [[pins.path]]          # pinned vertices that follow a prescribed path (repeatable)
//! # vertices = [0, 39]     # or region = { min = [..], max = [..] }
//! # velocity = [0.5, 0.0, 0.0]              # m/s, constant; or keyframes of the displacement (m),
//! # keyframes = [{ time = 0.0, offset = [0.0, 0.0, 0.0] }, { time = 1.0, offset = [0.5, 0.0, 0.0] }]
//! #                        # a keyframe may also turn: rotate = { axis = [0.0, 0.0, 1.0], point = [0.5, 0.0, 0.0], degrees = 90.0 }
//! #                        # (degrees right-handed about the axis through the point, m; interpolated
//! #                        # linearly, so 720 is two turns; one axis and point per path; 2D: no axis,
//! #                        # counter-clockwise about the point)
//!
//! [forces]
//! gravity = [0.0, -9.81, 0.0]                           # m/s²
//! # wind = { velocity = [1.0, 0.0, 0.0], coefficient = 0.01 }
//! # buoyancy = { fluid_density = 1000.0, body_density = 500.0, surface = 0.0 }
//! # attractor = { point = [0.5, 0.5, 0.5], strength = 100.0 }
//!
//! [damping]                # all default to 0
//! # drag = 1.0             # 1/s
//! # viscous = 0.0          # N·s/m
//! # dashpot = 100.0        # N·s/m
//!
//! # [[contact]]
//! # shape = "plane"        # or "box" (min, max) or "sphere" (center, radius)
//! # point = [0.0, -1.0, 0.0]
//! # normal = [0.0, 1.0, 0.0]
//! # friction = 0.0
//!
//! # [barrier]              # how newton, newton-cg and lbfgs model contact (docs/contact.md)
//! # distance = 0.001       # d̂, m: the barrier's reach; default 1e-3 of the mesh's bounding-box diagonal
//! # stiffness = 1e7        # κ̂, 1/s² per unit of vertex mass; default 1000 · 9.80665 / d̂
//! # friction_velocity = 0.001  # ε_v, m/s: friction's smoothing velocity
//!
//! # [self_contact]         # the surface never passes through itself (newton, newton-cg, lbfgs)
//! # enabled = true         # default true when the section is given
//! # dhat = 0.001           # d̂, m: the self-contact barrier's reach; default the [barrier]'s distance
//! # friction = 0.0         # μ between parts of the surface, ≥ 0 (lagged Coulomb friction)
//!
//! # [initial]              # the state at time 0; default: at rest
//! # velocity = [0.0, -5.0, 0.0]   # m/s, every vertex but the pinned ones
//!
//! [integrator]
//! method = "symplectic-euler"  # or "explicit-euler", "linearized", "newton", "pd"
//! time_step = 0.03333333333333333   # s, one frame
//! # substeps = 10          # explicit methods; default: automatic, from the stability bound
//! # allow_unstable = false # explicit methods
//! # energy_limit = 1.0     # energy watchdog: stop when E > E₀ + factor·(|E₀| + M|g|L); "off" disables
//! # beta = 1.0             # linearized: β in [0, 1]
//! # linear_solver = "cg"   # linearized: "cg" or "jacobi"
//! # iterations = 1000      # linearized: linear solver limit; newton: iteration limit; pd: iterations
//! # tolerance = 1e-5       # linearized: relative residual; newton, newton-cg, lbfgs: step size, m/s; pd, pd-chebyshev: estimated distance to the solution / h, m/s
//! # pin_method = "reduction"  # or "counter-force" (linearized, newton; pd refuses it)
//! # relaxation = "none"    # newton: or "buckling" (sweeps and fold elimination between steps)
//! # factor_reuse = 4       # newton: CG iterations on an earlier matrix's factor before factoring; 0: off
//! # memory_budget = "4G"   # newton, pd, pd-chebyshev, lbfgs, newton-cg: the most a Cholesky factor may take ("machine": half the RAM; "unlimited"; or bytes)
//! # pd_global_solve = "auto"  # pd, pd-chebyshev, lbfgs, newton-cg: "direct" (the factor), "multilevel" (CG with AMG), "auto" (multilevel above 50,000 free vertices or the budget)
//!
//! [run]
//! steps = 30
//!
//! # [output]
//! # format = "obj"         # or "vtk"
//! ```
//!
//! Generators pin nothing: a scene file's pins are those of `[pins]` (`vertices = []` pins none).
//!
//! `mesh.transform` places the mesh before anything else reads it: a file's vertices are moved
//! before a closed surface is filled with tetrahedra and before springs and masses are made from
//! them (so masses from a density follow the scaled size); a generator's mesh is moved after it is
//! generated, its rest lengths scaled with it (it stays at rest) and its masses unchanged. `[pins]`
//! regions, `[[pins.path]]` regions and the initial state all see the placed positions. A zero or
//! non-finite axis, a scale ≤ 0, non-finite numbers, or an axis on a 2D mesh are errors naming
//! the key.
//!
//! `initial.velocity` is given to every vertex; vertices pinned in place keep zero velocity, and
//! vertices pinned on a path start with it too (from the first step on, theirs is the path's).
//!
//! Unknown keys are errors. Every error names the file and the key (and, for syntax and type
//! errors, the line and column).

use std::path::{Path, PathBuf};

use hooke_mesh::io::{read_mesh, Mesh};
use hooke_mesh::{generators, Bending, MassModel, SpringMesh};
use hooke_solvers::{GlobalSolveKind, MemoryBudget};
use nalgebra::{SMatrix, SVector};
use serde::Deserialize;

use crate::contact_model::{AdaptiveStiffness, BarrierSettings, Contact, SelfContact, Shape};
use crate::damping::Damping;
use crate::forces::ExternalForce;
use crate::integrator::{
    parse_energy_limit, Integrator, LinearSolver, PinMethod, RelaxationPreset, Settings,
    SolverOptions,
};
use crate::scene::{Keyframe, PinPath, Pins, Rotation, Scene};
use crate::scenes::{AnySetup, Setup};
use crate::SimError;

/// What went wrong with a scene file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneFileError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key, or a value of the wrong type (the message gives line, column
    /// and key).
    #[error("{}: {source}", path.display())]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// The parser's error.
        #[source]
        source: Box<toml::de::Error>,
    },
    /// A key whose value is not acceptable.
    #[error("{}: [{key}]: {reason}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The key, as a dotted path (e.g. `mesh.stiffness`).
        key: String,
        /// Why.
        reason: String,
    },
}

/// Output frame format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameFormat {
    /// Wavefront OBJ (surfaces, or lines for spring graphs).
    #[default]
    Obj,
    /// Legacy VTK unstructured grid (ParaView).
    Vtk,
}

/// A scene file's content: the setup, and the output format it asks for.
#[derive(Clone, Debug)]
pub struct SceneFile {
    /// The scene, initial state, frames and settings.
    pub setup: AnySetup,
    /// The frame format the file asks for (OBJ by default).
    pub format: FrameFormat,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Document {
    name: Option<String>,
    mesh: MeshSection,
    pins: Option<PinsSection>,
    #[serde(default)]
    forces: ForcesSection,
    #[serde(default)]
    damping: Damping0,
    #[serde(default)]
    contact: Vec<ContactSection>,
    barrier: Option<BarrierSection>,
    self_contact: Option<SelfContactSection>,
    initial: Option<InitialSection>,
    integrator: IntegratorSection,
    run: RunSection,
    #[serde(default)]
    output: OutputSection,
}

/// The most vertices a scene file may ask a generator for: 2^24 (cloth n = 4096, beam r = 160),
/// already tens of GB with springs and a solver's matrices. The file is input, and a size in it
/// must not decide how much the process tries to allocate; programs that want more call
/// [`generators`] directly. A `fill` is bounded the same way: its lattice (about
/// 2·(bounding box)/spacing³ vertices) may have at most this many vertices, checked before the
/// mesher allocates anything.
pub const MAX_GENERATED_VERTICES: usize = 1 << 24;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshSection {
    generator: Option<String>,
    file: Option<PathBuf>,
    n: Option<usize>,
    r: Option<usize>,
    stiffness: Option<f64>,
    bending: Option<String>,
    mass: Option<MassSection>,
    positions: Option<Vec<Vec<f64>>>,
    springs: Option<Vec<[u32; 2]>>,
    rest_lengths: Option<Vec<f64>>,
    particle_mass: Option<f64>,
    fill: Option<FillSection>,
    transform: Option<TransformSection>,
}

/// `transform = { scale = s, rotate = { axis = [..], degrees = θ }, translate = [..] }`: scale
/// about the origin, then rotate about the origin, then translate; every part optional.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformSection {
    scale: Option<f64>,
    rotate: Option<RotateSection>,
    translate: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RotateSection {
    axis: Option<Vec<f64>>,
    degrees: f64,
}

/// `[barrier]`: the contact barrier's settings ([`BarrierSettings`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BarrierSection {
    distance: Option<f64>,
    stiffness: Option<f64>,
    friction_velocity: Option<f64>,
    adaptive_stiffness: Option<bool>,
    max_stiffness_ratio: Option<f64>,
    stiffness_gap_share: Option<f64>,
}

/// `[self_contact]`: self-contact of the mesh's surface ([`SelfContact`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SelfContactSection {
    enabled: Option<bool>,
    dhat: Option<f64>,
    friction: Option<f64>,
}

/// `[initial]`: the state at time 0 beyond the mesh's positions.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InitialSection {
    velocity: Option<Vec<f64>>,
}

/// `fill = { spacing = h }`: fill a closed surface file with tetrahedra (isosurface stuffing).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FillSection {
    spacing: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, untagged)]
enum MassSection {
    Uniform {
        total: f64,
    },
    Density {
        density: f64,
        thickness: Option<f64>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PinsSection {
    #[serde(default)]
    vertices: Vec<u32>,
    region: Option<RegionSection>,
    #[serde(default)]
    path: Vec<PathSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathSection {
    #[serde(default)]
    vertices: Vec<u32>,
    region: Option<RegionSection>,
    velocity: Option<Vec<f64>>,
    keyframes: Option<Vec<KeyframeSection>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeSection {
    time: f64,
    offset: Vec<f64>,
    rotate: Option<PathRotateSection>,
}

/// A keyframe's `rotate = { axis = [..], point = [..], degrees = θ }` (no axis in 2D).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathRotateSection {
    axis: Option<Vec<f64>>,
    point: Option<Vec<f64>>,
    degrees: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionSection {
    min: Vec<f64>,
    max: Vec<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ForcesSection {
    gravity: Option<Vec<f64>>,
    wind: Option<WindSection>,
    buoyancy: Option<BuoyancySection>,
    attractor: Option<AttractorSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WindSection {
    velocity: Vec<f64>,
    coefficient: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BuoyancySection {
    fluid_density: f64,
    body_density: f64,
    surface: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AttractorSection {
    point: Vec<f64>,
    strength: f64,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Damping0 {
    #[serde(default)]
    drag: f64,
    #[serde(default)]
    viscous: f64,
    #[serde(default)]
    dashpot: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, tag = "shape", rename_all = "lowercase")]
enum ContactSection {
    Box {
        min: Vec<f64>,
        max: Vec<f64>,
        #[serde(default)]
        friction: f64,
    },
    Plane {
        point: Vec<f64>,
        normal: Vec<f64>,
        #[serde(default)]
        friction: f64,
    },
    Sphere {
        center: Vec<f64>,
        radius: f64,
        #[serde(default)]
        friction: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IntegratorSection {
    method: String,
    time_step: f64,
    substeps: Option<usize>,
    #[serde(default)]
    allow_unstable: bool,
    beta: Option<f64>,
    linear_solver: Option<String>,
    iterations: Option<usize>,
    tolerance: Option<f64>,
    energy_limit: Option<EnergyLimitValue>,
    pin_method: Option<String>,
    relaxation: Option<String>,
    factor_reuse: Option<usize>,
    memory_budget: Option<MemoryBudgetValue>,
    pd_global_solve: Option<String>,
}

/// `integrator.memory_budget`: a size in bytes, or text ("4G", "machine", "unlimited").
#[derive(Deserialize)]
#[serde(untagged)]
enum MemoryBudgetValue {
    Bytes(u64),
    Text(String),
}

/// `integrator.energy_limit`: a factor, or "off".
#[derive(Deserialize)]
#[serde(untagged)]
enum EnergyLimitValue {
    Factor(f64),
    Word(String),
    Flag(bool),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunSection {
    steps: usize,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct OutputSection {
    #[serde(default)]
    format: FrameFormat,
}

/// Read and build a scene file. Relative mesh paths are resolved against the file's directory.
///
/// # Errors
/// [`SceneFileError`], naming the file and the key.
pub fn load_scene(path: &Path) -> Result<SceneFile, SceneFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_scene(&text, path)
}

/// Build a scene from TOML text; `path` names the file in errors and anchors relative mesh paths.
///
/// # Errors
/// As [`load_scene`].
pub fn parse_scene(text: &str, path: &Path) -> Result<SceneFile, SceneFileError> {
    let doc: Document = toml::from_str(text).map_err(|source| SceneFileError::Syntax {
        path: path.to_path_buf(),
        source: Box::new(source),
    })?;
    let ctx = Context { path };
    let name = doc.name.clone().unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into())
    });
    let setup = match ctx.mesh(&doc.mesh)? {
        AnyMesh::Two(mesh) => AnySetup::Two(ctx.setup(name, mesh, &doc)?),
        AnyMesh::Three(mesh) => AnySetup::Three(ctx.setup(name, mesh, &doc)?),
    };
    Ok(SceneFile {
        setup,
        format: doc.output.format,
    })
}

/// A checked `mesh.transform`: x ↦ R (s x) + t.
struct Placement<const D: usize> {
    /// s, > 0.
    scale: f64,
    /// R, a rotation about the origin.
    rotation: SMatrix<f64, D, D>,
    /// t, m.
    translation: SVector<f64, D>,
}

impl<const D: usize> Placement<D> {
    fn apply(&self, p: &SVector<f64, D>) -> SVector<f64, D> {
        self.rotation * (p * self.scale) + self.translation
    }
}

enum AnyMesh {
    Two(SpringMesh<2>),
    Three(SpringMesh<3>),
}

struct Context<'a> {
    path: &'a Path,
}

impl Context<'_> {
    fn invalid(&self, key: &str, reason: impl ToString) -> SceneFileError {
        SceneFileError::Invalid {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            reason: reason.to_string(),
        }
    }

    fn vector<const D: usize>(
        &self,
        key: &str,
        values: &[f64],
    ) -> Result<SVector<f64, D>, SceneFileError> {
        if values.len() != D {
            return Err(self.invalid(
                key,
                format!(
                    "expected {D} components (the scene is {D}D), got {}",
                    values.len()
                ),
            ));
        }
        Ok(SVector::from_column_slice(values))
    }

    fn stiffness(&self, mesh: &MeshSection) -> Result<f64, SceneFileError> {
        mesh.stiffness
            .ok_or_else(|| self.invalid("mesh.stiffness", "missing: the spring stiffness in N/m"))
    }

    fn mesh(&self, m: &MeshSection) -> Result<AnyMesh, SceneFileError> {
        let mesh_err = |key: &str, e: hooke_mesh::MeshError| self.invalid(key, e);
        match (&m.generator, &m.file) {
            (Some(_), Some(_)) => {
                Err(self.invalid("mesh", "give either `generator` or `file`, not both"))
            }
            (None, None) => Err(self.invalid("mesh", "missing `generator` or `file`")),
            (Some(generator), None) => {
                if m.bending.is_some() || m.mass.is_some() || m.fill.is_some() {
                    return Err(self.invalid(
                        "mesh",
                        "`bending`, `mass` and `fill` apply to mesh files; generators build the scene as docs/scenes.md defines it",
                    ));
                }
                let graph_keys = m.positions.is_some()
                    || m.springs.is_some()
                    || m.rest_lengths.is_some()
                    || m.particle_mass.is_some();
                if graph_keys && generator != "particles" {
                    return Err(self.invalid(
                        "mesh",
                        "`positions`, `springs`, `rest_lengths` and `particle_mass` apply to generator \"particles\"",
                    ));
                }
                let mesh = match generator.as_str() {
                    "particles" => self.particles(m),
                    "cloth" => {
                        let n = m.n.ok_or_else(|| self.invalid("mesh.n", "missing: cloth needs n (vertices per side)"))?;
                        if n.checked_mul(n).is_none_or(|v| v > MAX_GENERATED_VERTICES) {
                            return Err(self.invalid(
                                "mesh.n",
                                format!("{n}: a scene file's cloth has at most {MAX_GENERATED_VERTICES} vertices (n ≤ 4096)"),
                            ));
                        }
                        generators::cloth(n, self.stiffness(m)?)
                            .map(AnyMesh::Three)
                            .map_err(|e| mesh_err("mesh", e))
                    }
                    "beam" => {
                        let r = m.r.ok_or_else(|| self.invalid("mesh.r", "missing: beam needs r (cubes across)"))?;
                        if r > 160 {
                            return Err(self.invalid(
                                "mesh.r",
                                format!("{r}: a scene file's beam has at most {MAX_GENERATED_VERTICES} vertices (r ≤ 160)"),
                            ));
                        }
                        let mesh = generators::beam(r).map_err(|e| mesh_err("mesh.r", e))?;
                        let k = self.stiffness(m)?;
                        mesh.map_stiffness(|_, _| k)
                            .map(AnyMesh::Three)
                            .map_err(|e| mesh_err("mesh.stiffness", e))
                    }
                    "seed-2d" => {
                        let mesh = generators::seed_2d().map_err(|e| mesh_err("mesh", e))?;
                        match m.stiffness {
                            Some(k) => mesh.map_stiffness(|_, _| k).map_err(|e| mesh_err("mesh.stiffness", e)),
                            None => Ok(mesh),
                        }
                        .map(AnyMesh::Two)
                    }
                    other => Err(self.invalid(
                        "mesh.generator",
                        format!("unknown generator {other:?}; expected \"cloth\", \"beam\", \"seed-2d\" or \"particles\""),
                    )),
                }?;
                match mesh {
                    AnyMesh::Two(mesh) => self.place_generated(mesh, m).map(AnyMesh::Two),
                    AnyMesh::Three(mesh) => self.place_generated(mesh, m).map(AnyMesh::Three),
                }
            }
            (None, Some(file)) => {
                let file = self.path.parent().unwrap_or(Path::new("")).join(file);
                let stiffness = self.stiffness(m)?;
                let mass = match &m.mass {
                    None => {
                        return Err(self.invalid(
                            "mesh.mass",
                            "missing: { total = kg } or { density = kg/m³, thickness = m }",
                        ))
                    }
                    Some(MassSection::Uniform { total }) => MassModel::Uniform { total: *total },
                    Some(MassSection::Density { density, thickness }) => MassModel::Density {
                        density: *density,
                        thickness: thickness.unwrap_or(1.0),
                    },
                };
                let bending = match m.bending.as_deref() {
                    None | Some("none") => Bending::None,
                    Some("interior-edges") => Bending::InteriorEdges,
                    Some(other) => {
                        return Err(self.invalid(
                            "mesh.bending",
                            format!(
                                "unknown value {other:?}; expected \"none\" or \"interior-edges\""
                            ),
                        ))
                    }
                };
                let loaded = read_mesh(&file).map_err(|e| mesh_err("mesh.file", e))?;
                // The transform moves the file's vertices before anything is built from them: the
                // lattice of `fill`, the springs' rest lengths and the masses follow the placed mesh.
                let loaded = match self.placement::<3>(m.transform.as_ref())? {
                    None => loaded,
                    Some(placement) => {
                        let place = |points: &[SVector<f64, 3>]| -> Vec<SVector<f64, 3>> {
                            points.iter().map(|p| placement.apply(p)).collect()
                        };
                        match loaded {
                            Mesh::Surface(tri) => hooke_mesh::TriMesh::new(
                                place(tri.positions()),
                                tri.triangles().to_vec(),
                            )
                            .map(Mesh::Surface),
                            Mesh::Volume(tet) => hooke_mesh::TetMesh::new(
                                place(tet.positions()),
                                tet.tetrahedra().to_vec(),
                            )
                            .map(Mesh::Volume),
                        }
                        .map_err(|e| mesh_err("mesh.transform", e))?
                    }
                };
                match loaded {
                    Mesh::Surface(tri) if m.fill.is_some() => {
                        if bending != Bending::None {
                            return Err(self.invalid("mesh.bending", "bending springs apply to triangle meshes only, not to a filled solid"));
                        }
                        let spacing = m.fill.as_ref().map_or(0.0, |f| f.spacing);
                        // The lattice is bounded as a generator's mesh is: refused before the
                        // mesher allocates it.
                        let options = hooke_mesh::stuffing::StuffingOptions {
                            max_lattice_vertices: MAX_GENERATED_VERTICES as u64,
                            ..hooke_mesh::stuffing::StuffingOptions::new(spacing)
                                .map_err(|e| self.invalid("mesh.fill", e))?
                        };
                        let surface = hooke_mesh::stuffing::ClosedSurface::new(&tri)
                            .map_err(|e| self.invalid("mesh.fill", e))?;
                        let stuffed = hooke_mesh::stuffing::tetrahedralize(&surface, &options)
                            .map_err(|e| self.invalid("mesh.fill", e))?;
                        SpringMesh::from_tetrahedra(&stuffed.mesh, stiffness, mass)
                    }
                    Mesh::Surface(tri) => {
                        if matches!(mass, MassModel::Density { .. }) && m.mass.as_ref().is_some_and(|s| matches!(s, MassSection::Density { thickness: None, .. })) {
                            return Err(self.invalid("mesh.mass.thickness", "missing: a surface mesh needs a thickness (m) to turn density into mass"));
                        }
                        SpringMesh::from_triangles(&tri, stiffness, bending, mass)
                    }
                    Mesh::Volume(_) if m.fill.is_some() => {
                        return Err(self.invalid("mesh.fill", "fill applies to closed surface files (.obj, .stl); this file is already tetrahedral"));
                    }
                    Mesh::Volume(tet) => {
                        if bending != Bending::None {
                            return Err(self.invalid("mesh.bending", "bending springs apply to triangle meshes only"));
                        }
                        SpringMesh::from_tetrahedra(&tet, stiffness, mass)
                    }
                }
                .map(AnyMesh::Three)
                .map_err(|e| mesh_err("mesh", e))
            }
        }
    }

    /// `mesh.transform`, checked, for a `D`-dimensional mesh; `None` when absent.
    fn placement<const D: usize>(
        &self,
        transform: Option<&TransformSection>,
    ) -> Result<Option<Placement<D>>, SceneFileError> {
        let Some(t) = transform else {
            return Ok(None);
        };
        let scale = match t.scale {
            None => 1.0,
            Some(s) if s.is_finite() && s > 0.0 => s,
            Some(s) => {
                return Err(self.invalid(
                    "mesh.transform.scale",
                    format!("{s}: must be a finite number > 0"),
                ))
            }
        };
        let rotation =
            match &t.rotate {
                None => SMatrix::<f64, D, D>::identity(),
                Some(r) => {
                    if !r.degrees.is_finite() {
                        return Err(self.invalid(
                            "mesh.transform.rotate.degrees",
                            format!("{}: must be finite", r.degrees),
                        ));
                    }
                    let (sin, cos) = r.degrees.to_radians().sin_cos();
                    match (D, &r.axis) {
                        (2, None) => SMatrix::from_fn(|i, j| match (i, j) {
                            (0, 0) | (1, 1) => cos,
                            (0, 1) => -sin,
                            _ => sin,
                        }),
                        (2, Some(_)) => return Err(self.invalid(
                            "mesh.transform.rotate.axis",
                            "a 2D mesh turns in its plane about the origin: give `degrees` only",
                        )),
                        (_, None) => {
                            return Err(self.invalid(
                                "mesh.transform.rotate.axis",
                                "missing: the axis [x, y, z] to turn about (right-handed)",
                            ))
                        }
                        (_, Some(axis)) => {
                            let key = "mesh.transform.rotate.axis";
                            let k = self.vector::<D>(key, axis)?;
                            let length = k.norm();
                            if !length.is_finite() || length == 0.0 {
                                return Err(self.invalid(
                                    key,
                                    format!("{:?}: must be finite and non-zero", k.as_slice()),
                                ));
                            }
                            let k = k / length;
                            // Rodrigues: R = cos θ I + sin θ [k]× + (1 − cos θ) k kᵀ.
                            SMatrix::from_fn(|i, j| {
                                let identity = if i == j { 1.0 } else { 0.0 };
                                let cross = match (i, j) {
                                    (0, 1) => -k[2],
                                    (0, 2) => k[1],
                                    (1, 0) => k[2],
                                    (1, 2) => -k[0],
                                    (2, 0) => -k[1],
                                    (2, 1) => k[0],
                                    _ => 0.0,
                                };
                                cos * identity + sin * cross + (1.0 - cos) * k[i] * k[j]
                            })
                        }
                    }
                }
            };
        let translation = match &t.translate {
            None => SVector::zeros(),
            Some(values) => {
                let key = "mesh.transform.translate";
                let v = self.vector::<D>(key, values)?;
                if !v.iter().all(|c| c.is_finite()) {
                    return Err(self.invalid(key, format!("{values:?}: must be finite")));
                }
                v
            }
        };
        Ok(Some(Placement {
            scale,
            rotation,
            translation,
        }))
    }

    /// A generator's mesh moved by `mesh.transform` (if any): positions placed, rest lengths
    /// scaled with them (the mesh stays at rest), masses and elements unchanged.
    fn place_generated<const D: usize>(
        &self,
        mesh: SpringMesh<D>,
        m: &MeshSection,
    ) -> Result<SpringMesh<D>, SceneFileError> {
        let Some(placement) = self.placement::<D>(m.transform.as_ref())? else {
            return Ok(mesh);
        };
        let positions = mesh
            .positions()
            .iter()
            .map(|p| placement.apply(p))
            .collect();
        let springs = mesh
            .springs()
            .iter()
            .map(|s| hooke_mesh::Spring {
                rest_length: s.rest_length * placement.scale,
                ..*s
            })
            .collect();
        SpringMesh::new(positions, mesh.masses().to_vec(), springs)
            .and_then(|placed| placed.with_triangles(mesh.triangles().to_vec()))
            .and_then(|placed| placed.with_tetrahedra(mesh.tetrahedra().to_vec()))
            .map_err(|e| self.invalid("mesh.transform", e))
    }

    /// The "particles" generator: the graph as listed (2D or 3D, by the positions' length).
    fn particles(&self, m: &MeshSection) -> Result<AnyMesh, SceneFileError> {
        let missing = |key: &str, what: &str| self.invalid(key, format!("missing: {what}"));
        let positions = m
            .positions
            .as_ref()
            .ok_or_else(|| missing("mesh.positions", "[[x, y], ..] in m"))?;
        let pairs = m
            .springs
            .as_ref()
            .ok_or_else(|| missing("mesh.springs", "[[i, j], ..]"))?;
        let rest = m
            .rest_lengths
            .as_ref()
            .ok_or_else(|| missing("mesh.rest_lengths", "one rest length (m) per spring"))?;
        let mass = m
            .particle_mass
            .ok_or_else(|| missing("mesh.particle_mass", "the mass of every particle, kg"))?;
        let stiffness = self.stiffness(m)?;
        if rest.len() != pairs.len() {
            return Err(self.invalid(
                "mesh.rest_lengths",
                format!("{} rest lengths for {} springs", rest.len(), pairs.len()),
            ));
        }
        let springs: Vec<hooke_mesh::Spring> = pairs
            .iter()
            .zip(rest)
            .map(|(&[i, j], &rest_length)| hooke_mesh::Spring {
                i,
                j,
                stiffness,
                rest_length,
            })
            .collect();
        let dimension = positions.first().map_or(0, Vec::len);
        let mesh_err = |e: hooke_mesh::MeshError| self.invalid("mesh", e);
        match dimension {
            2 => {
                let points = self.points::<2>(positions)?;
                SpringMesh::new(points.clone(), vec![mass; points.len()], springs)
                    .map(AnyMesh::Two)
                    .map_err(mesh_err)
            }
            3 => {
                let points = self.points::<3>(positions)?;
                SpringMesh::new(points.clone(), vec![mass; points.len()], springs)
                    .map(AnyMesh::Three)
                    .map_err(mesh_err)
            }
            other => Err(self.invalid(
                "mesh.positions",
                format!("positions need 2 or 3 coordinates each, the first has {other}"),
            )),
        }
    }

    fn points<const D: usize>(
        &self,
        positions: &[Vec<f64>],
    ) -> Result<Vec<SVector<f64, D>>, SceneFileError> {
        positions
            .iter()
            .enumerate()
            .map(|(v, p)| self.vector::<D>(&format!("mesh.positions[{v}]"), p))
            .collect()
    }

    /// A pin path keyframe's `rotate` table, `key` naming it. The values' own checks (finite,
    /// non-zero axis, one axis per path) are [`PinPath::validate`]'s.
    fn path_rotation<const D: usize>(
        &self,
        key: &str,
        r: &PathRotateSection,
    ) -> Result<Rotation<D>, SceneFileError> {
        let axis = match (D, &r.axis) {
            (2, None) => nalgebra::Vector3::z(),
            (2, Some(_)) => {
                return Err(self.invalid(
                    &format!("{key}.axis"),
                    "a 2D path turns in its plane, counter-clockwise: give `point` and \
                     `degrees` only",
                ))
            }
            (_, None) => {
                return Err(self.invalid(
                    &format!("{key}.axis"),
                    "missing: the axis [x, y, z] to turn about (right-handed)",
                ))
            }
            (_, Some(axis)) => self.vector::<3>(&format!("{key}.axis"), axis)?,
        };
        let point = match &r.point {
            Some(point) => self.vector::<D>(&format!("{key}.point"), point)?,
            None => {
                return Err(
                    self.invalid(&format!("{key}.point"), "missing: a point of the axis (m)")
                )
            }
        };
        Ok(Rotation {
            axis,
            point,
            degrees: r.degrees,
        })
    }

    fn setup<const D: usize>(
        &self,
        name: String,
        mesh: SpringMesh<D>,
        doc: &Document,
    ) -> Result<Setup<D>, SceneFileError> {
        let sim = |key: &'static str| move |e: SimError| self.invalid(key, e);
        let i = &doc.integrator;
        let mut scene = Scene::new(mesh, i.time_step).map_err(sim("integrator.time_step"))?;
        if let Some(p) = &doc.pins {
            if !p.vertices.is_empty() {
                scene = scene
                    .with_pins(Pins::Vertices(p.vertices.clone()))
                    .map_err(sim("pins.vertices"))?;
            }
            if let Some(region) = &p.region {
                let min = self.vector::<D>("pins.region.min", &region.min)?;
                let max = self.vector::<D>("pins.region.max", &region.max)?;
                let mut pins: Vec<u32> = scene.pinned().to_vec();
                let in_region = scene
                    .clone()
                    .with_pins(Pins::Region { min, max })
                    .map_err(sim("pins.region"))?;
                pins.extend_from_slice(in_region.pinned());
                scene = scene.with_pins(Pins::Vertices(pins)).map_err(sim("pins"))?;
            }
            for (index, path) in p.path.iter().enumerate() {
                let key = |field: &str| format!("pins.path[{index}]{field}");
                let invalid = |field: &str, e: SimError| self.invalid(&key(field), e);
                let pins = match (&path.region, path.vertices.is_empty()) {
                    (None, true) => {
                        return Err(self.invalid(&key(""), "give `vertices` or `region`"))
                    }
                    (Some(_), false) => {
                        return Err(
                            self.invalid(&key(""), "give either `vertices` or `region`, not both")
                        )
                    }
                    (None, false) => Pins::Vertices(path.vertices.clone()),
                    (Some(region), true) => Pins::Region {
                        min: self.vector::<D>(&key(".region.min"), &region.min)?,
                        max: self.vector::<D>(&key(".region.max"), &region.max)?,
                    },
                };
                let motion = match (&path.velocity, &path.keyframes) {
                    (Some(velocity), None) => PinPath::ConstantVelocity {
                        velocity: self.vector(&key(".velocity"), velocity)?,
                    },
                    (None, Some(keys)) => PinPath::Keyframes(
                        keys.iter()
                            .enumerate()
                            .map(|(k, f)| {
                                Ok(Keyframe {
                                    time: f.time,
                                    offset: self.vector(
                                        &key(&format!(".keyframes[{k}].offset")),
                                        &f.offset,
                                    )?,
                                    rotation: f
                                        .rotate
                                        .as_ref()
                                        .map(|r| {
                                            self.path_rotation::<D>(
                                                &key(&format!(".keyframes[{k}].rotate")),
                                                r,
                                            )
                                        })
                                        .transpose()?,
                                })
                            })
                            .collect::<Result<_, SceneFileError>>()?,
                    ),
                    _ => {
                        return Err(self.invalid(
                            &key(""),
                            "give exactly one of `velocity` (m/s) or `keyframes` \
                             ([{ time = s, offset = [m, ..] }, ..])",
                        ))
                    }
                };
                scene = scene.with_pin_path(pins, motion).map_err(|e| match e {
                    // The path's own checks name its fields: name them as the file's keys.
                    SimError::InvalidParameter {
                        name,
                        value,
                        reason,
                    } if name.starts_with("pin path ") => self.invalid(
                        &key(&format!(
                            ".{}",
                            name["pin path ".len()..].replace(".rotation", ".rotate")
                        )),
                        format!("{value}: {reason}"),
                    ),
                    e => invalid("", e),
                })?;
            }
        }
        let f = &doc.forces;
        let mut forces = Vec::new();
        if let Some(g) = &f.gravity {
            forces.push(ExternalForce::Gravity {
                acceleration: self.vector("forces.gravity", g)?,
            });
        }
        if let Some(w) = &f.wind {
            forces.push(ExternalForce::Wind {
                velocity: self.vector("forces.wind.velocity", &w.velocity)?,
                coefficient: w.coefficient,
            });
        }
        if let Some(b) = &f.buoyancy {
            forces.push(ExternalForce::Buoyancy {
                fluid_density: b.fluid_density,
                body_density: b.body_density,
                surface: b.surface,
            });
        }
        if let Some(a) = &f.attractor {
            forces.push(ExternalForce::Attractor {
                point: self.vector("forces.attractor.point", &a.point)?,
                strength: a.strength,
            });
        }
        scene = scene.with_forces(forces).map_err(sim("forces"))?;
        let d = &doc.damping;
        scene = scene
            .with_damping(Damping {
                drag: d.drag,
                viscous: d.viscous,
                dashpot: d.dashpot,
            })
            .map_err(sim("damping"))?;
        let mut contacts = Vec::new();
        for (index, c) in doc.contact.iter().enumerate() {
            let key = |field: &str| format!("contact[{index}].{field}");
            let contact = match c {
                ContactSection::Box { min, max, friction } => Contact {
                    shape: Shape::Box {
                        min: self.vector(&key("min"), min)?,
                        max: self.vector(&key("max"), max)?,
                    },
                    friction: *friction,
                },
                ContactSection::Plane {
                    point,
                    normal,
                    friction,
                } => Contact {
                    shape: Shape::Plane {
                        point: self.vector(&key("point"), point)?,
                        normal: self.vector(&key("normal"), normal)?,
                    },
                    friction: *friction,
                },
                ContactSection::Sphere {
                    center,
                    radius,
                    friction,
                } => Contact {
                    shape: Shape::Sphere {
                        center: self.vector(&key("center"), center)?,
                        radius: *radius,
                    },
                    friction: *friction,
                },
            };
            contacts.push(
                contact
                    .validated()
                    .map_err(|e| self.invalid(&format!("contact[{index}]"), e))?,
            );
        }
        scene = scene.with_contacts(contacts).map_err(sim("contact"))?;
        let self_contact_on = doc
            .self_contact
            .as_ref()
            .is_some_and(|c| c.enabled.unwrap_or(true));
        if let Some(b) = &doc.barrier {
            if doc.contact.is_empty() && !self_contact_on {
                return Err(self.invalid(
                    "barrier",
                    "the scene has no [[contact]] obstacle and no [self_contact] for the barrier \
                     to act on",
                ));
            }
            let defaults = BarrierSettings::default();
            let adaptive_given = b.max_stiffness_ratio.is_some() || b.stiffness_gap_share.is_some();
            let adaptive_on = b
                .adaptive_stiffness
                .unwrap_or(defaults.adaptive_stiffness.is_some());
            if adaptive_given && !adaptive_on {
                return Err(self.invalid(
                    "barrier.adaptive_stiffness",
                    "max_stiffness_ratio and stiffness_gap_share set the adaptive stiffness, which \
                     is off: set adaptive_stiffness = true or leave them out",
                ));
            }
            let adaptive_defaults = defaults.adaptive_stiffness.unwrap_or_default();
            let barrier = BarrierSettings {
                distance: b.distance,
                stiffness: b.stiffness,
                friction_velocity: b.friction_velocity.unwrap_or(defaults.friction_velocity),
                adaptive_stiffness: adaptive_on.then(|| AdaptiveStiffness {
                    max_ratio: b.max_stiffness_ratio.unwrap_or(adaptive_defaults.max_ratio),
                    gap_share: b.stiffness_gap_share.unwrap_or(adaptive_defaults.gap_share),
                }),
            };
            scene = scene.with_barrier(barrier).map_err(sim("barrier"))?;
        }
        if let Some(c) = &doc.self_contact {
            let friction = c.friction.unwrap_or(0.0);
            if !(friction.is_finite() && friction >= 0.0) {
                return Err(self.invalid(
                    "self_contact.friction",
                    format!("{friction} must be finite and ≥ 0"),
                ));
            }
            if self_contact_on {
                let settings = SelfContact {
                    distance: c.dhat,
                    friction,
                };
                scene = scene
                    .with_self_contact(Some(settings))
                    .map_err(sim("self_contact"))?;
            }
        }
        let integrator: Integrator = i
            .method
            .parse()
            .map_err(|e| self.invalid("integrator.method", e))?;
        if i.substeps == Some(0) {
            return Err(self.invalid("integrator.substeps", "must be at least 1"));
        }
        if doc.run.steps == 0 {
            return Err(self.invalid("run.steps", "must be at least 1"));
        }
        let mut settings = Settings {
            integrator,
            substeps: i.substeps,
            allow_unstable: i.allow_unstable,
            ..Settings::default()
        };
        if let Some(value) = &i.energy_limit {
            let limit = match value {
                EnergyLimitValue::Factor(factor) => Ok(Some(*factor)),
                EnergyLimitValue::Word(word) => parse_energy_limit(word),
                EnergyLimitValue::Flag(flag) => Err(SimError::invalid(
                    "energy limit",
                    flag,
                    "expected a factor (a number >= 0) or \"off\"",
                )),
            };
            limit
                .and_then(|limit| settings.set_energy_limit(limit))
                .map_err(|e| self.invalid("integrator.energy_limit", e))?;
        }
        if let Some(name) = &i.pin_method {
            settings.pins = name
                .parse::<PinMethod>()
                .map_err(|e| self.invalid("integrator.pin_method", e))?;
        }
        let linear_solver = match &i.linear_solver {
            Some(name) => Some(
                name.parse::<LinearSolver>()
                    .map_err(|e| self.invalid("integrator.linear_solver", e))?,
            ),
            None => None,
        };
        let relaxation = match &i.relaxation {
            Some(name) => Some(
                name.parse::<RelaxationPreset>()
                    .map_err(|e| self.invalid("integrator.relaxation", e))?,
            ),
            None => None,
        };
        let memory_budget = match &i.memory_budget {
            Some(MemoryBudgetValue::Bytes(bytes)) => Some(MemoryBudget::Bytes(*bytes)),
            Some(MemoryBudgetValue::Text(text)) => Some(
                MemoryBudget::parse(text)
                    .map_err(|e| self.invalid("integrator.memory_budget", e))?,
            ),
            None => None,
        };
        let pd_global_solve = match &i.pd_global_solve {
            Some(name) => Some(
                name.parse::<GlobalSolveKind>()
                    .map_err(|e| self.invalid("integrator.pd_global_solve", e))?,
            ),
            None => None,
        };
        // One option at a time, so that an error names its key.
        for (key, options) in [
            (
                "integrator.beta",
                SolverOptions {
                    beta: i.beta,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.linear_solver",
                SolverOptions {
                    linear_solver,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.iterations",
                SolverOptions {
                    iterations: i.iterations,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.tolerance",
                SolverOptions {
                    tolerance: i.tolerance,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.relaxation",
                SolverOptions {
                    relaxation,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.factor_reuse",
                SolverOptions {
                    factor_reuse: i.factor_reuse,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.memory_budget",
                SolverOptions {
                    memory_budget,
                    ..SolverOptions::default()
                },
            ),
            (
                "integrator.pd_global_solve",
                SolverOptions {
                    pd_global_solve,
                    ..SolverOptions::default()
                },
            ),
        ] {
            settings
                .apply_options(&options)
                .map_err(|e| self.invalid(key, e))?;
        }
        let mut initial = scene.initial_state();
        if let Some(velocity) = doc.initial.as_ref().and_then(|i| i.velocity.as_ref()) {
            let key = "initial.velocity";
            let v = self.vector::<D>(key, velocity)?;
            if !v.iter().all(|c| c.is_finite()) {
                return Err(self.invalid(key, format!("{velocity:?}: must be finite")));
            }
            // Pinned vertices stay at rest; those on a path start with the velocity too (after
            // the first step, theirs is the path's).
            let mut moves = scene.is_pinned().iter().map(|&p| !p).collect::<Vec<_>>();
            for group in scene.pin_paths() {
                for &vertex in &group.vertices {
                    moves[vertex as usize] = true;
                }
            }
            for (velocity, _) in initial
                .velocities
                .iter_mut()
                .zip(&moves)
                .filter(|(_, &m)| m)
            {
                *velocity = v;
            }
        }
        Ok(Setup {
            name,
            initial,
            scene,
            steps: doc.run.steps,
            settings,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::{LinearSolver, SolverOptions};
    use hooke_solvers::Relaxation;

    const BASE: &str = r#"
[mesh]
generator = "cloth"
n = 4
stiffness = 100.0
[pins]
vertices = [0, 3]
[run]
steps = 2
"#;

    fn parse(extra: &str) -> Result<Setup<3>, SceneFileError> {
        let text = format!("{BASE}{extra}");
        match parse_scene(&text, Path::new("test.toml"))?.setup {
            AnySetup::Three(s) => Ok(s),
            AnySetup::Two(_) => unreachable!(),
        }
    }

    #[test]
    fn the_particles_generator_reads_a_2d_graph_and_names_bad_keys() {
        let text = r#"
[mesh]
generator = "particles"
positions = [[0.3, 0.3], [0.3, 0.4], [0.4, 0.4]]
springs = [[0, 1], [0, 2], [1, 2]]
rest_lengths = [0.1, 0.1, 0.12]
particle_mass = 2.0
stiffness = 1e4
[pins]
vertices = [2]
[integrator]
method = "pd"
time_step = 0.001
[run]
steps = 3
"#;
        let AnySetup::Two(setup) = parse_scene(text, Path::new("p.toml")).unwrap().setup else {
            panic!("a 2D graph gives a 2D scene");
        };
        let mesh = setup.scene.mesh();
        assert_eq!(mesh.positions()[1], SVector::<f64, 2>::new(0.3, 0.4));
        assert_eq!(mesh.masses(), &[2.0, 2.0, 2.0]);
        assert_eq!(mesh.springs()[2].rest_length, 0.12);
        assert!(mesh.springs().iter().all(|s| s.stiffness == 1e4));
        assert_eq!(setup.scene.pinned(), &[2]);
        for (change, key) in [
            ("rest_lengths = [0.1, 0.1, 0.12]", "mesh.rest_lengths"),
            (
                "positions = [[0.3, 0.3], [0.3, 0.4], [0.4, 0.4]]",
                "mesh.positions",
            ),
        ] {
            let broken = text.replace(
                change,
                match key {
                    "mesh.rest_lengths" => "rest_lengths = [0.1]",
                    _ => "positions = [[0.3], [0.3], [0.4]]",
                },
            );
            let err = parse_scene(&broken, Path::new("p.toml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(key), "{err}");
        }
        let stray = BASE.replace("n = 4", "n = 4\nparticle_mass = 1.0");
        let err = parse_scene(
            &format!("{stray}[integrator]\nmethod = \"newton\"\ntime_step = 0.1\n"),
            Path::new("c.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("particles"), "{err}");
    }

    #[test]
    fn integrator_keys_give_the_settings_the_options_give() {
        let setup = parse(
            r#"
[integrator]
method = "linearized"
time_step = 0.01
beta = 0.25
linear_solver = "jacobi"
iterations = 123
tolerance = 1e-9
"#,
        )
        .unwrap();
        let mut expected = Settings {
            integrator: Integrator::Linearized,
            ..Settings::default()
        };
        expected
            .apply_options(&SolverOptions {
                beta: Some(0.25),
                linear_solver: Some(LinearSolver::Jacobi),
                iterations: Some(123),
                tolerance: Some(1e-9),
                relaxation: None,
                factor_reuse: None,
                memory_budget: None,
                pd_global_solve: None,
            })
            .unwrap();
        assert_eq!(setup.settings, expected);
        let newton = parse(
            "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\niterations = 9\ntolerance = 1e-10\n",
        )
        .unwrap();
        assert_eq!(newton.settings.newton.max_iterations, 9);
        assert_eq!(newton.settings.newton.tolerance, 1e-10);
    }

    /// `relaxation` opts Newton into the buckling preset; it names its key when misspelt or given
    /// to another integrator.
    #[test]
    fn relaxation_key_chooses_newtons_preset() {
        let parse = |method: &str, relaxation: &str| {
            parse(&format!(
                "[integrator]\nmethod = \"{method}\"\ntime_step = 0.01\n{relaxation}"
            ))
        };
        let plain = parse("newton", "").unwrap();
        assert_eq!(plain.settings.newton.relaxation, Relaxation::NONE);
        let relaxed = parse("newton", "relaxation = \"buckling\"\n").unwrap();
        assert_eq!(relaxed.settings.newton.relaxation, Relaxation::BUCKLING);
        assert_eq!(
            relaxed.settings.solver_options().relaxation,
            Some(RelaxationPreset::Buckling)
        );
        let none = parse("newton", "relaxation = \"none\"\n").unwrap();
        assert_eq!(none.settings.newton.relaxation, Relaxation::NONE);
        for (method, line, expected) in [
            (
                "newton",
                "relaxation = \"sweeps\"\n",
                "unknown relaxation \"sweeps\"",
            ),
            (
                "pd",
                "relaxation = \"buckling\"\n",
                "applies only to the newton integrator",
            ),
        ] {
            let err = parse(method, line).err().unwrap().to_string();
            assert!(
                err.contains("integrator.relaxation") && err.contains(expected),
                "{method} {line}: {err}"
            );
        }
    }

    /// `memory_budget` bounds Newton's factor (newton) or PD's (the PD-based integrators), as
    /// bytes or text; bad text and an integrator that factors nothing are refused, naming the key.
    #[test]
    fn memory_budget_key_reaches_the_factor() {
        let parse = |method: &str, line: &str| {
            parse(&format!(
                "[integrator]\nmethod = \"{method}\"\ntime_step = 0.01\n{line}"
            ))
        };
        let default = parse("newton", "").unwrap();
        assert_eq!(
            default.settings.newton.cholesky.memory_budget,
            MemoryBudget::Machine
        );
        let newton = parse("newton", "memory_budget = \"1.5G\"\n").unwrap();
        assert_eq!(
            newton.settings.newton.cholesky.memory_budget,
            MemoryBudget::Bytes(3 << 29)
        );
        let pd = parse("pd", "memory_budget = 4096\n").unwrap();
        assert_eq!(
            pd.settings.pd.cholesky.memory_budget,
            MemoryBudget::Bytes(4096)
        );
        assert_eq!(
            pd.settings.solver_options().memory_budget,
            Some(MemoryBudget::Bytes(4096))
        );
        for (method, line, expected) in [
            (
                "newton",
                "memory_budget = \"lots\"\n",
                "not a memory budget",
            ),
            (
                "symplectic-euler",
                "memory_budget = \"1G\"\n",
                "factors nothing",
            ),
        ] {
            let err = parse(method, line).unwrap_err().to_string();
            assert!(
                err.contains("integrator.memory_budget") && err.contains(expected),
                "{err}"
            );
        }
    }

    /// `pd_global_solve` sets how the PD-based integrators solve with their matrix; bad text and
    /// an integrator without a PD matrix are refused, naming the key.
    #[test]
    fn pd_global_solve_key_reaches_the_pd_matrix() {
        let parse = |method: &str, line: &str| {
            parse(&format!(
                "[integrator]\nmethod = \"{method}\"\ntime_step = 0.01\n{line}"
            ))
        };
        let default = parse("pd", "").unwrap();
        assert_eq!(default.settings.pd.global_solve, GlobalSolveKind::Auto);
        for method in ["pd", "pd-chebyshev", "lbfgs", "newton-cg"] {
            let set = parse(method, "pd_global_solve = \"multilevel\"\n").unwrap();
            assert_eq!(set.settings.pd.global_solve, GlobalSolveKind::Multilevel);
            assert_eq!(
                set.settings.solver_options().pd_global_solve,
                Some(GlobalSolveKind::Multilevel)
            );
        }
        for (method, line, expected) in [
            ("pd", "pd_global_solve = \"fast\"\n", "not a global solve"),
            ("newton", "pd_global_solve = \"direct\"\n", "pd-chebyshev"),
        ] {
            let err = parse(method, line).unwrap_err().to_string();
            assert!(
                err.contains("integrator.pd_global_solve") && err.contains(expected),
                "{err}"
            );
        }
    }

    /// `factor_reuse` sets Newton's CG iterations on a held factor (0: off); it is refused for
    /// another integrator and out of range, naming its key.
    #[test]
    fn factor_reuse_key_reaches_newton() {
        let parse = |method: &str, line: &str| {
            parse(&format!(
                "[integrator]\nmethod = \"{method}\"\ntime_step = 0.01\n{line}"
            ))
        };
        let default = parse("newton", "").unwrap();
        assert_eq!(
            default.settings.newton.factor_reuse,
            hooke_solvers::FactorReuse::DEFAULT
        );
        for n in [0, 9] {
            let set = parse("newton", &format!("factor_reuse = {n}\n")).unwrap();
            assert_eq!(set.settings.newton.factor_reuse.max_iterations, n);
            assert_eq!(set.settings.solver_options().factor_reuse, Some(n));
        }
        for (method, line, expected) in [
            (
                "pd",
                "factor_reuse = 2\n",
                "applies only to the newton integrator",
            ),
            // Named by the key, not by the solver's field (FactorReuse::max_iterations).
            ("newton", "factor_reuse = 20000\n", "factor reuse = 20000"),
            ("newton", "factor_reuse = -1\n", "factor_reuse"),
        ] {
            let err = parse(method, line).err().unwrap().to_string();
            assert!(
                err.contains("factor_reuse") && err.contains(expected),
                "{method} {line}: {err}"
            );
            assert!(!err.contains("::"), "{method} {line}: {err}");
        }
    }

    /// A size in a file must not decide how much the process allocates: a cloth or beam above
    /// MAX_GENERATED_VERTICES is refused before anything is built, naming the key.
    #[test]
    fn generated_meshes_are_bounded_by_the_file_limit() {
        let mesh = |section: &str| {
            let text = format!(
                "[mesh]\n{section}\nstiffness = 100.0\n[integrator]\nmethod = \"pd\"\n\
                 time_step = 0.01\n[run]\nsteps = 1\n"
            );
            parse_scene(&text, Path::new("big.toml")).map(|_| ())
        };
        for (section, key) in [
            ("generator = \"cloth\"\nn = 4097", "mesh.n"),
            ("generator = \"cloth\"\nn = 65535", "mesh.n"),
            ("generator = \"cloth\"\nn = 18446744073709551615", "mesh.n"),
            ("generator = \"beam\"\nr = 161", "mesh.r"),
            ("generator = \"beam\"\nr = 18446744073709551615", "mesh.r"),
        ] {
            let err = mesh(section).unwrap_err().to_string();
            assert!(
                err.contains(key) && err.contains("at most"),
                "{section}: {err}"
            );
        }
        // The limits themselves are sizes a file may ask for (not built here: 2^24 vertices).
        assert_eq!(4096 * 4096, MAX_GENERATED_VERTICES);
        assert!(generators::beam_vertex_count(160) <= MAX_GENERATED_VERTICES);
        assert!(generators::beam_vertex_count(161) > MAX_GENERATED_VERTICES);
    }

    #[test]
    fn bad_integrator_keys_name_the_key() {
        for (section, expected) in [
            ("method = \"linearized\"\nbeta = 2.0", "[integrator.beta]"),
            (
                "method = \"linearized\"\ntolerance = 0.0",
                "[integrator.tolerance]",
            ),
            ("method = \"pd\"\niterations = 0", "[integrator.iterations]"),
            (
                "method = \"linearized\"\nlinear_solver = \"lu\"",
                "[integrator.linear_solver]",
            ),
            (
                "method = \"newton\"\nbeta = 0.5",
                "applies only to the linearized",
            ),
            ("method = \"linearized\"\nbetta = 0.5", "betta"),
        ] {
            let err = parse(&format!("[integrator]\ntime_step = 0.01\n{section}\n"))
                .unwrap_err()
                .to_string();
            assert!(err.contains("test.toml"), "{err}");
            assert!(err.contains(expected), "{section}: {err}");
        }
    }

    #[test]
    fn the_energy_limit_key_sets_the_watchdog_and_bad_values_name_the_key() {
        let integrator = "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n";
        let limit = |value: &str| {
            parse(&format!("{integrator}energy_limit = {value}\n")).map(|s| s.settings.energy_limit)
        };
        assert_eq!(
            parse(integrator).unwrap().settings.energy_limit,
            Settings::default().energy_limit,
            "absent: the default"
        );
        assert_eq!(limit("2.5").unwrap(), Some(2.5));
        assert_eq!(limit("3").unwrap(), Some(3.0), "a TOML integer is a factor");
        assert_eq!(limit("0.0").unwrap(), Some(0.0));
        assert_eq!(limit("\"off\"").unwrap(), None);
        assert_eq!(limit("\"0.5\"").unwrap(), Some(0.5));
        for bad in ["-1.0", "nan", "inf", "\"sometimes\"", "true"] {
            match limit(bad) {
                Err(SceneFileError::Invalid { key, reason, .. }) => {
                    assert_eq!(key, "integrator.energy_limit", "{bad}");
                    assert!(reason.contains("energy limit"), "{bad}: {reason}");
                }
                other => panic!("energy_limit = {bad}: expected Invalid, got {other:?}"),
            }
        }
    }

    #[test]
    fn the_pin_method_key_sets_the_method_and_bad_values_name_the_key() {
        let integrator = "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n";
        let method = |value: &str| {
            parse(&format!("{integrator}pin_method = {value}\n")).map(|s| s.settings.pins)
        };
        assert_eq!(
            parse(integrator).unwrap().settings.pins,
            PinMethod::Reduction,
            "absent: the default"
        );
        assert_eq!(method("\"reduction\"").unwrap(), PinMethod::Reduction);
        assert_eq!(
            method("\"counter-force\"").unwrap(),
            PinMethod::CounterForce
        );
        for bad in ["\"penalty\"", "\"\"", "1", "true"] {
            let err = method(bad).unwrap_err();
            let text = err.to_string();
            assert!(text.contains("test.toml"), "{bad}: {text}");
            match err {
                SceneFileError::Invalid { key, reason, .. } => {
                    assert_eq!(key, "integrator.pin_method", "{bad}");
                    assert!(reason.contains("counter-force"), "{bad}: {reason}");
                }
                // A value of the wrong TOML type is a type error naming the key.
                other => assert!(
                    (bad == "1" || bad == "true") && text.contains("pin_method"),
                    "pin_method = {bad}: expected Invalid, got {other:?}"
                ),
            }
        }
    }

    #[test]
    fn pin_paths_are_read_and_checked() {
        let integrator = "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n";
        let setup = parse(&format!(
            "{integrator}[[pins.path]]\nvertices = [0, 3]\nvelocity = [0.5, 0.0, 0.0]\n\
             [[pins.path]]\nvertices = [15]\n\
             keyframes = [{{ time = 0.0, offset = [0.0, 0.0, 0.0] }}, {{ time = 1.0, offset = [0.0, 1.0, 0.0] }}]\n"
        ))
        .unwrap();
        let paths = setup.scene.pin_paths();
        assert_eq!(paths.len(), 2);
        assert_eq!(paths[0].vertices, [0, 3]);
        assert_eq!(setup.scene.pinned(), [0, 3, 15]);
        assert_eq!(
            paths[1].path.offset(0.5),
            nalgebra::Vector3::new(0.0, 0.5, 0.0)
        );
        assert_eq!(
            paths[1].path.offset(2.0),
            nalgebra::Vector3::new(0.0, 1.0, 0.0)
        );
        for (path, expected) in [
            ("vertices = [1]", "exactly one of `velocity`"),
            ("vertices = [1]\nvelocity = [1.0, 0.0]", "pins.path[0].velocity"),
            ("velocity = [1.0, 0.0, 0.0]", "give `vertices` or `region`"),
            (
                "vertices = [1]\nkeyframes = [{ time = 1.0, offset = [0.0, 0.0, 0.0] }, { time = 1.0, offset = [1.0, 0.0, 0.0] }]",
                "strictly increasing",
            ),
            ("vertices = [99]\nvelocity = [1.0, 0.0, 0.0]", "does not exist"),
            ("vertices = [1]\nspeed = 1.0", "speed"),
        ] {
            let err = parse(&format!("{integrator}[[pins.path]]\n{path}\n"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(expected), "{path}: {err}");
        }
    }

    /// A keyframe's `rotate` table gives the path the same rotation as built in code, and the
    /// vertex follows it through a run; bad values are refused naming the file's key.
    #[test]
    fn pin_path_rotations_are_read_and_bad_ones_name_the_key() {
        let integrator = "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n";
        let setup = parse(&format!(
            "{integrator}[[pins.path]]\nvertices = [15]\nkeyframes = [\
             {{ time = 0.0, offset = [0.0, 0.0, 0.0] }}, \
             {{ time = 0.1, offset = [0.0, 0.0, 0.5], rotate = {{ axis = [0.0, 2.0, 0.0], point = [0.5, 0.0, 0.5], degrees = 90.0 }} }}]\n"
        ))
        .unwrap();
        let turn = |degrees| {
            Some(Rotation {
                axis: nalgebra::Vector3::new(0.0, 2.0, 0.0),
                point: nalgebra::Vector3::new(0.5, 0.0, 0.5),
                degrees,
            })
        };
        let expected = PinPath::Keyframes(vec![
            Keyframe {
                time: 0.0,
                offset: nalgebra::Vector3::zeros(),
                rotation: None,
            },
            Keyframe {
                time: 0.1,
                offset: nalgebra::Vector3::new(0.0, 0.0, 0.5),
                rotation: turn(90.0),
            },
        ]);
        assert_eq!(setup.scene.pin_paths()[0].path, expected);
        // Vertex 15 of the 4×4 cloth is its corner (1, 0, 1): a quarter turn about y through the
        // centre takes it to (1, 0, 0), and the displacement to (1, 0, 0.5).
        let start = setup.initial.positions[15];
        assert_eq!(start, nalgebra::Vector3::new(1.0, 0.0, 1.0));
        let mut sim = crate::Simulation::new(setup.scene, setup.initial, setup.settings).unwrap();
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let error = (sim.state().positions[15] - nalgebra::Vector3::new(1.0, 0.0, 0.5)).norm();
        assert!(error < 1e-12, "{error:e} m off");

        let keyframes = |rotate: &str| {
            format!(
                "{integrator}[[pins.path]]\nvertices = [15]\nkeyframes = [\
                 {{ time = 0.0, offset = [0.0, 0.0, 0.0] }}, \
                 {{ time = 1.0, offset = [0.0, 0.0, 0.0], rotate = {rotate} }}]\n"
            )
        };
        let key = "pins.path[0].keyframes[1].rotate";
        for (rotate, expected) in [
            (
                "{ axis = [0.0, 0.0, 0.0], point = [0.0, 0.0, 0.0], degrees = 90.0 }",
                format!("[{key}.axis]"),
            ),
            (
                "{ axis = [0.0, nan, 1.0], point = [0.0, 0.0, 0.0], degrees = 90.0 }",
                format!("[{key}.axis]"),
            ),
            (
                "{ axis = [0.0, 1.0], point = [0.0, 0.0, 0.0], degrees = 90.0 }",
                format!("[{key}.axis]"),
            ),
            (
                "{ point = [0.0, 0.0, 0.0], degrees = 90.0 }",
                format!("[{key}.axis]: missing"),
            ),
            (
                "{ axis = [0.0, 1.0, 0.0], degrees = 90.0 }",
                format!("[{key}.point]: missing"),
            ),
            (
                "{ axis = [0.0, 1.0, 0.0], point = [0.0, inf, 0.0], degrees = 90.0 }",
                format!("[{key}.point]"),
            ),
            (
                "{ axis = [0.0, 1.0, 0.0], point = [0.0, 0.0, 0.0], degrees = nan }",
                format!("[{key}.degrees]"),
            ),
            (
                "{ axis = [0.0, 1.0, 0.0], point = [0.0, 0.0, 0.0] }",
                "degrees".to_string(),
            ),
            (
                "{ axis = [0.0, 1.0, 0.0], point = [0.0, 0.0, 0.0], degrees = 90.0, speed = 1.0 }",
                "speed".to_string(),
            ),
        ] {
            let err = parse(&keyframes(rotate)).unwrap_err().to_string();
            assert!(err.contains(&expected), "{rotate}: {err}");
        }
        // Two keyframes turning about different axes.
        let err = parse(&format!(
            "{integrator}[[pins.path]]\nvertices = [15]\nkeyframes = [\
             {{ time = 0.0, offset = [0.0, 0.0, 0.0], rotate = {{ axis = [0.0, 1.0, 0.0], point = [0.0, 0.0, 0.0], degrees = 0.0 }} }}, \
             {{ time = 1.0, offset = [0.0, 0.0, 0.0], rotate = {{ axis = [1.0, 0.0, 0.0], point = [0.0, 0.0, 0.0], degrees = 90.0 }} }}]\n"
        ))
        .unwrap_err()
        .to_string();
        assert!(
            err.contains(&format!("[{key}.axis]")) && err.contains("one axis"),
            "{err}"
        );
    }

    /// In 2D a keyframe turns in the plane about `point`, counter-clockwise; an axis is refused.
    #[test]
    fn a_2d_pin_path_turns_in_the_plane() {
        let text = |rotate: &str| {
            format!(
                "[mesh]\ngenerator = \"particles\"\nstiffness = 100.0\npositions = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]\n\
                 springs = [[0, 1], [1, 2]]\nrest_lengths = [1.0, 1.0]\nparticle_mass = 1.0\n\
                 [[pins.path]]\nvertices = [2]\nkeyframes = [{{ time = 0.0, offset = [0.0, 0.0] }}, \
                 {{ time = 1.0, offset = [0.0, 0.0], rotate = {rotate} }}]\n\
                 [integrator]\nmethod = \"newton\"\ntime_step = 0.01\n[run]\nsteps = 1\n"
            )
        };
        let file = parse_scene(
            &text("{ point = [1.0, 0.0], degrees = 90.0 }"),
            Path::new("flat.toml"),
        )
        .unwrap();
        let AnySetup::Two(setup) = file.setup else {
            panic!("a 2D scene")
        };
        let path = &setup.scene.pin_paths()[0].path;
        let turned = path.position(&nalgebra::Vector2::new(2.0, 0.0), 1.0);
        assert!((turned - nalgebra::Vector2::new(1.0, 1.0)).norm() < 1e-15);
        let err = parse_scene(
            &text("{ axis = [0.0, 0.0, 1.0], point = [1.0, 0.0], degrees = 90.0 }"),
            Path::new("flat.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("[pins.path[0].keyframes[1].rotate.axis]") && err.contains("in its plane"),
            "{err}"
        );
    }

    const NEWTON: &str = "[integrator]\nmethod = \"newton\"\ntime_step = 0.01\n";

    /// A one-spring graph whose first particle is at `point`, placed by `transform`.
    fn placed(point: [f64; 3], transform: &str) -> Result<Setup<3>, SceneFileError> {
        let text = format!(
            "[mesh]\ngenerator = \"particles\"\npositions = [[{}, {}, {}], [0.0, 0.0, 0.0]]\n\
             springs = [[0, 1]]\nrest_lengths = [0.5]\nparticle_mass = 1.0\nstiffness = 10.0\n\
             transform = {transform}\n{NEWTON}[run]\nsteps = 1\n",
            point[0], point[1], point[2]
        );
        match parse_scene(&text, Path::new("t.toml"))?.setup {
            AnySetup::Three(s) => Ok(s),
            AnySetup::Two(_) => unreachable!(),
        }
    }

    /// Scale about the origin, then rotate about the origin, then translate: (1, 0, 0) scaled by 2
    /// is (2, 0, 0), turned 90° about +y is (0, 0, −2), moved by (1, 2, 3) is (1, 2, 1). Any other
    /// order gives another point. Rest lengths scale with the mesh; masses do not change.
    #[test]
    fn the_transform_scales_then_rotates_then_translates() {
        let setup = placed(
            [1.0, 0.0, 0.0],
            "{ scale = 2.0, rotate = { axis = [0.0, 3.0, 0.0], degrees = 90.0 }, translate = [1.0, 2.0, 3.0] }",
        )
        .unwrap();
        let mesh = setup.scene.mesh();
        let expected = [
            SVector::<f64, 3>::new(1.0, 2.0, 1.0),
            SVector::<f64, 3>::new(1.0, 2.0, 3.0),
        ];
        for (p, e) in mesh.positions().iter().zip(&expected) {
            assert!((p - e).norm() < 1e-12, "{p:?} != {e:?}");
        }
        assert_eq!(mesh.springs()[0].rest_length, 1.0);
        assert_eq!(mesh.masses(), &[1.0, 1.0]);
        assert_eq!(setup.initial.positions, mesh.positions());
        // Every part is optional.
        let moved = placed([1.0, 0.0, 0.0], "{ translate = [0.0, 0.5, 0.0] }").unwrap();
        assert_eq!(
            moved.scene.mesh().positions()[0],
            SVector::<f64, 3>::new(1.0, 0.5, 0.0)
        );
        assert_eq!(moved.scene.mesh().springs()[0].rest_length, 0.5);
        let turned = placed(
            [1.0, 0.0, 0.0],
            "{ rotate = { axis = [0.0, 0.0, 1.0], degrees = 90.0 } }",
        )
        .unwrap();
        assert!(
            (turned.scene.mesh().positions()[0] - SVector::<f64, 3>::new(0.0, 1.0, 0.0)).norm()
                < 1e-12
        );
        assert!(placed([1.0, 0.0, 0.0], "{}").is_ok());
    }

    #[test]
    fn bad_transforms_name_the_key() {
        for (transform, key) in [
            ("{ scale = 0.0 }", "mesh.transform.scale"),
            ("{ scale = -1.0 }", "mesh.transform.scale"),
            ("{ scale = nan }", "mesh.transform.scale"),
            ("{ scale = inf }", "mesh.transform.scale"),
            (
                "{ rotate = { axis = [0.0, 0.0, 0.0], degrees = 10.0 } }",
                "mesh.transform.rotate.axis",
            ),
            (
                "{ rotate = { axis = [0.0, nan, 1.0], degrees = 10.0 } }",
                "mesh.transform.rotate.axis",
            ),
            (
                "{ rotate = { axis = [0.0, 1.0], degrees = 10.0 } }",
                "mesh.transform.rotate.axis",
            ),
            (
                "{ rotate = { degrees = 10.0 } }",
                "mesh.transform.rotate.axis",
            ),
            (
                "{ rotate = { axis = [0.0, 1.0, 0.0], degrees = inf } }",
                "mesh.transform.rotate.degrees",
            ),
            ("{ translate = [0.0, 1.0] }", "mesh.transform.translate"),
            (
                "{ translate = [0.0, nan, 1.0] }",
                "mesh.transform.translate",
            ),
            ("{ shear = 1.0 }", "shear"),
        ] {
            let err = placed([1.0, 0.0, 0.0], transform).unwrap_err().to_string();
            assert!(
                err.contains("t.toml") && err.contains(key),
                "{transform}: {err}"
            );
        }
    }

    /// In 2D, rotate takes degrees only (counter-clockwise about the origin) and refuses an axis.
    #[test]
    fn a_2d_transform_turns_in_the_plane() {
        let text = |transform: &str| {
            format!(
                "[mesh]\ngenerator = \"particles\"\npositions = [[1.0, 0.0], [0.0, 0.0]]\n\
                 springs = [[0, 1]]\nrest_lengths = [1.0]\nparticle_mass = 1.0\nstiffness = 10.0\n\
                 transform = {transform}\n{NEWTON}[run]\nsteps = 1\n"
            )
        };
        let parsed = parse_scene(
            &text("{ scale = 2.0, rotate = { degrees = 90.0 }, translate = [0.5, 0.0] }"),
            Path::new("t.toml"),
        )
        .unwrap();
        let AnySetup::Two(setup) = parsed.setup else {
            panic!("a 2D graph gives a 2D scene")
        };
        let p = setup.scene.mesh().positions()[0];
        assert!(
            (p - SVector::<f64, 2>::new(0.5, 2.0)).norm() < 1e-12,
            "{p:?}"
        );
        let err = parse_scene(
            &text("{ rotate = { axis = [0.0, 0.0, 1.0], degrees = 90.0 } }"),
            Path::new("t.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("mesh.transform.rotate.axis"), "{err}");
    }

    /// `[pins]` regions are matched against the placed mesh: the cloth's edge x = 0, moved up by
    /// 1 m, is found at y = 1 and not at y = 0.
    #[test]
    fn pin_regions_are_matched_after_the_transform() {
        let cloth = |transform: &str, region: &str| {
            let text = format!(
                "[mesh]\ngenerator = \"cloth\"\nn = 4\nstiffness = 100.0\ntransform = {transform}\n\
                 [pins]\nregion = {region}\n{NEWTON}[run]\nsteps = 1\n"
            );
            parse_scene(&text, Path::new("t.toml")).map(|f| match f.setup {
                AnySetup::Three(s) => s,
                AnySetup::Two(_) => unreachable!(),
            })
        };
        let lifted = "{ translate = [0.0, 1.0, 0.0] }";
        let setup = cloth(lifted, "{ min = [-0.1, 0.9, -0.1], max = [0.1, 1.1, 1.1] }").unwrap();
        assert_eq!(setup.scene.pinned(), &[0, 1, 2, 3]);
        let err = cloth(
            lifted,
            "{ min = [-0.1, -0.1, -0.1], max = [0.1, 0.1, 1.1] }",
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("pins.region"), "{err}");
        // Turned 90° about z, vertex (i, j) at (i/3, 0, j/3) goes to (0, i/3, j/3): only (3, 0),
        // vertex 12, is near (0, 1, 0).
        let turned = cloth(
            "{ rotate = { axis = [0.0, 0.0, 1.0], degrees = 90.0 } }",
            "{ min = [-0.1, 0.9, -0.1], max = [0.1, 1.1, 0.1] }",
        )
        .unwrap();
        assert_eq!(turned.scene.pinned(), &[12]);
    }

    /// Generators pin nothing; `[pins] vertices = []` is valid and pins nothing either.
    #[test]
    fn generators_pin_nothing() {
        for pins in ["", "[pins]\nvertices = []\n"] {
            let text = format!(
                "[mesh]\ngenerator = \"cloth\"\nn = 4\nstiffness = 100.0\n{pins}{NEWTON}[run]\nsteps = 1\n"
            );
            let AnySetup::Three(setup) = parse_scene(&text, Path::new("t.toml")).unwrap().setup
            else {
                unreachable!()
            };
            assert!(setup.scene.pinned().is_empty(), "{pins:?}");
        }
    }

    /// `initial.velocity` is given to every free vertex and to vertices on a pin path; vertices
    /// pinned in place start at rest.
    #[test]
    fn the_initial_velocity_moves_the_free_vertices() {
        let setup = parse(&format!(
            "{NEWTON}[initial]\nvelocity = [0.0, -5.0, 0.0]\n\
             [[pins.path]]\nvertices = [15]\nvelocity = [1.0, 0.0, 0.0]\n"
        ))
        .unwrap();
        let down = SVector::<f64, 3>::new(0.0, -5.0, 0.0);
        for (v, velocity) in setup.initial.velocities.iter().enumerate() {
            let expected = if v == 0 || v == 3 {
                SVector::zeros()
            } else {
                down
            };
            assert_eq!(*velocity, expected, "vertex {v}");
        }
        assert_eq!(
            parse(NEWTON).unwrap().initial,
            parse(NEWTON).unwrap().scene.initial_state()
        );
        for (initial, expected) in [
            ("velocity = [0.0, -5.0]", "initial.velocity"),
            ("velocity = [0.0, nan, 0.0]", "initial.velocity"),
            ("speed = 1.0", "speed"),
        ] {
            let err = parse(&format!("{NEWTON}[initial]\n{initial}\n"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(expected), "{initial}: {err}");
        }
    }

    #[test]
    fn the_barrier_section_sets_the_contact_model_and_names_bad_keys() {
        let ground =
            "[[contact]]\nshape = \"plane\"\npoint = [0.0, -1.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n";
        let setup = parse(&format!(
            "{NEWTON}{ground}[barrier]\ndistance = 0.002\nstiffness = 5e6\nfriction_velocity = 0.01\n"
        ))
        .unwrap();
        let model = setup.scene.contact_model().unwrap();
        assert_eq!(
            (model.distance, model.stiffness, model.friction_velocity),
            (0.002, 5e6, 0.01)
        );
        // Defaults: d̂ = 1e-3 of the cloth's diagonal (√2 m), κ̂ = 1000 g₀ / d̂.
        let model = parse(&format!("{NEWTON}{ground}"))
            .unwrap()
            .scene
            .contact_model()
            .unwrap();
        assert!((model.distance - 1e-3 * 2f64.sqrt()).abs() < 1e-15);
        assert!((model.stiffness - 1000.0 * 9.80665 / model.distance).abs() < 1e-6);
        for (barrier, expected) in [
            ("distance = 0.0", "barrier.distance"),
            ("stiffness = -1.0", "barrier.stiffness"),
            ("friction_velocity = nan", "barrier.friction_velocity"),
            ("reach = 1.0", "reach"),
        ] {
            let err = parse(&format!("{NEWTON}{ground}[barrier]\n{barrier}\n"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(expected), "{barrier}: {err}");
        }
        let err = parse(&format!("{NEWTON}[barrier]\ndistance = 0.01\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("no [[contact]]"), "{err}");
    }
}
