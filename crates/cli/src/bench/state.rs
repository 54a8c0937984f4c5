//! The step every solver is measured on (the speed-vs-error state, docs/scenes.md §8), its exact
//! solution x* (docs/model.md §9.1), and a cache of both keyed by the scene.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use hooke_assembly::FreeDofs;
use hooke_solvers::{BackwardEulerStep, Convergence, Newton, NewtonParams, NewtonProblem};
use nalgebra::Vector3;

use crate::bench::BenchError;
use crate::sim::file::load_scene;
use crate::sim::scenes::{self, AnySetup, Setup};
use crate::sim::{ExternalForce, Integrator, Scene, Settings, Simulation, State};

/// Steps of exact backward Euler from rest before the measured step (docs/scenes.md §8).
pub const STATE_STEPS: usize = 10;
/// Relative gradient ‖∇Φ(x)‖/‖∇Φ(y)‖ of the exact solves: the 10 steps to the state and the
/// reference x* (docs/model.md §9.1).
pub const REFERENCE_TOLERANCE: f64 = 1e-10;
/// Newton's iteration limit for the exact solves (cloth-160 needs about 100).
pub const REFERENCE_MAX_ITERATIONS: usize = 500;

/// Where the measured step starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum StartState {
    /// The speed-vs-error state (docs/scenes.md §8): after [`STATE_STEPS`] steps of exact backward
    /// Euler (Newton to [`REFERENCE_TOLERANCE`]) from rest.
    #[default]
    SpeedVsError,
    /// The scene's initial state (at rest for the canonical scenes): the first step.
    Rest,
}

/// Load a 3D scene by built-in name or scene file, checking that the backward Euler objective
/// models all of it (gravity is the only external force; no damping, contact or moving pins).
///
/// # Errors
/// [`BenchError::UnknownScene`], [`BenchError::Scene`], [`BenchError::Unsupported`],
/// [`BenchError::NotASpringScene`] (a mesh file or a fluid scene, with the command that takes it).
pub fn load_setup(name: &str) -> Result<Setup<3>, BenchError> {
    if let Some(hint) = crate::scene_arg::mesh_file_hint(name).or_else(|| {
        crate::scene_arg::fluid_scene_hint(
            name,
            "`hooke bench SCENE` measures a spring scene's backward Euler step",
        )
    }) {
        return Err(BenchError::NotASpringScene(hint));
    }
    let path = Path::new(name);
    let setup = if path.extension().is_some_and(|e| e == "toml") || path.is_file() {
        load_scene(path)
            .map_err(|e| BenchError::Scene(e.to_string()))?
            .setup
    } else {
        scenes::builtin(name)
            .ok_or_else(|| BenchError::UnknownScene(name.to_string()))?
            .map_err(|e| BenchError::Scene(e.to_string()))?
    };
    let setup = match setup {
        AnySetup::Three(s) => s,
        AnySetup::Two(s) => {
            return Err(BenchError::Unsupported {
                scene: s.name,
                what: "a 2D mesh (the benchmark measures 3D backward Euler steps)".into(),
            })
        }
    };
    check_supported(&setup.name, &setup.scene)?;
    Ok(setup)
}

/// Refuse scenes whose step the backward Euler objective Φ does not describe exactly.
fn check_supported(name: &str, scene: &Scene<3>) -> Result<(), BenchError> {
    let refuse = |what: &str| BenchError::Unsupported {
        scene: name.to_string(),
        what: what.to_string(),
    };
    for f in scene.forces().as_slice() {
        if !matches!(f, ExternalForce::Gravity { .. }) {
            return Err(refuse("an external force other than gravity"));
        }
    }
    let d = scene.damping();
    if d.drag > 0.0 || d.viscous > 0.0 || d.dashpot > 0.0 {
        return Err(refuse("damping"));
    }
    if !scene.contacts().is_empty() {
        return Err(refuse("contact"));
    }
    if !scene.pin_paths().is_empty() {
        return Err(refuse("pins on a path"));
    }
    Ok(())
}

/// The inertial target y = x_n + h v_n + h² g of the step from `state` (pinned vertices: y = x_n).
pub fn inertial_target(scene: &Scene<3>, state: &State<3>) -> Vec<Vector3<f64>> {
    let h = scene.time_step();
    let g = scene.forces().gravity().unwrap_or_else(Vector3::zeros);
    let pinned = scene.is_pinned();
    state
        .positions
        .iter()
        .zip(&state.velocities)
        .zip(pinned)
        .map(|((x, v), &p)| if p { *x } else { x + v * h + g * (h * h) })
        .collect()
}

/// How the reference x* was computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceInfo {
    /// Newton iterations.
    pub iterations: usize,
    /// The relative gradient reached (≤ [`REFERENCE_TOLERANCE`] unless Newton stagnated at the
    /// round-off floor first).
    pub gradient: f64,
    /// Wall time of the reference solve, s.
    pub wall_time_s: f64,
}

/// One backward Euler step to measure solvers on: the scene, the state x_n, v_n it starts from, its
/// inertial target y, and (if computed) its exact solution x*.
#[derive(Clone, Debug)]
pub struct BenchProblem {
    /// The scene's name.
    pub name: String,
    /// The scene.
    pub scene: Scene<3>,
    /// x_n, v_n.
    pub start: State<3>,
    /// y = x_n + h v_n + h² g (pinned vertices at x_n).
    pub y: Vec<Vector3<f64>>,
    /// x*, the step solved by Newton to [`REFERENCE_TOLERANCE`], with how it was computed.
    pub reference: Option<(Vec<Vector3<f64>>, ReferenceInfo)>,
}

/// How [`BenchProblem::prepare`] computes and caches.
#[derive(Clone, Debug, Default)]
pub struct PrepareOptions {
    /// Where the step starts.
    pub start: StartState,
    /// Compute the reference x*.
    pub reference: bool,
    /// A directory for the state and the reference (created if missing); `None`: no cache.
    pub cache_dir: Option<PathBuf>,
}

impl BenchProblem {
    /// Build the step for `setup`: run the exact steps to the start state, compute y and, if asked,
    /// x*; read both from `options.cache_dir` when a file for this exact scene is there, and write
    /// them there otherwise. `progress` receives one line per exact step.
    ///
    /// # Errors
    /// [`BenchError::Sim`] or [`BenchError::Reference`] if an exact step fails;
    /// [`BenchError::Cache`] if the cache cannot be written (an unreadable or stale cache file is
    /// recomputed, with a note to `progress`).
    pub fn prepare(
        setup: &Setup<3>,
        options: &PrepareOptions,
        progress: &mut dyn FnMut(&str),
    ) -> Result<Self, BenchError> {
        check_supported(&setup.name, &setup.scene)?;
        let scene = &setup.scene;
        let key = cache_key(setup, options.start);
        let cache_path = options.cache_dir.as_ref().map(|dir| {
            let safe: String = setup
                .name
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            dir.join(format!("{safe}-{key:016x}.bin"))
        });
        let n = scene.mesh().vertex_count();
        let mut cached = None;
        if let Some(path) = &cache_path {
            if path.exists() {
                match read_cache(path, key, n) {
                    Ok(c) => {
                        progress(&format!(
                            "{}: state read from {}",
                            setup.name,
                            path.display()
                        ));
                        cached = Some(c);
                    }
                    Err(e) => progress(&format!(
                        "{}: ignoring cache file {} ({e}); recomputing",
                        setup.name,
                        path.display()
                    )),
                }
            }
        }
        let (start, mut reference) = match cached {
            Some(c) => (c.start, c.reference),
            None => (start_state(setup, options.start, progress)?, None),
        };
        let y = inertial_target(scene, &start);
        let mut computed = false;
        if options.reference && reference.is_none() {
            let t = Instant::now();
            progress(&format!(
                "{}: reference x* (Newton to a relative gradient of {REFERENCE_TOLERANCE:e})…",
                setup.name
            ));
            let r = solve_reference(&setup.name, scene, &start, &y)?;
            progress(&format!(
                "{}: reference done, {} iterations, relative gradient {:.1e}, {:.1} s",
                setup.name,
                r.1.iterations,
                r.1.gradient,
                t.elapsed().as_secs_f64()
            ));
            reference = Some(r);
            computed = true;
        }
        if let Some(path) = &cache_path {
            if computed || !path.exists() {
                write_cache(path, key, &start, reference.as_ref())?;
            }
        }
        Ok(BenchProblem {
            name: setup.name.clone(),
            scene: scene.clone(),
            start,
            y,
            reference,
        })
    }

    /// The reference positions x*, if computed.
    pub fn x_star(&self) -> Option<&[Vector3<f64>]> {
        self.reference.as_ref().map(|(x, _)| x.as_slice())
    }

    /// The free-DOF map of the scene.
    pub fn free(&self) -> FreeDofs {
        FreeDofs::new(self.scene.mesh().vertex_count(), self.scene.pinned())
            .expect("a validated scene's pins are in range")
    }
}

/// Run the exact steps from the scene's initial state to `start`.
fn start_state(
    setup: &Setup<3>,
    start: StartState,
    progress: &mut dyn FnMut(&str),
) -> Result<State<3>, BenchError> {
    if start == StartState::Rest {
        return Ok(setup.initial.clone());
    }
    let settings = Settings {
        integrator: Integrator::Newton,
        newton: NewtonParams {
            convergence: Convergence::RelativeGradient,
            tolerance: REFERENCE_TOLERANCE,
            max_iterations: REFERENCE_MAX_ITERATIONS,
            ..NewtonParams::default()
        },
        ..Settings::default()
    };
    let mut sim = Simulation::new(setup.scene.clone(), setup.initial.clone(), settings)?;
    let begin = Instant::now();
    for step in 1..=STATE_STEPS {
        let report = sim.step()?;
        let summary = report.solver.expect("Newton reports a solve");
        progress(&format!(
            "{}: exact step {step}/{STATE_STEPS}: {} Newton iterations, relative gradient {:.1e}, {:.1} s ({:.0} s so far)",
            setup.name,
            summary.iterations,
            summary.residual,
            report.wall_time.as_secs_f64(),
            begin.elapsed().as_secs_f64()
        ));
        if !summary.stop.is_at_resolution() {
            return Err(BenchError::Reference {
                scene: setup.name.clone(),
                reason: format!(
                    "step {step} of the exact run did not converge ({}, at most \
                     {REFERENCE_MAX_ITERATIONS} Newton iterations) with relative gradient {:e}",
                    summary.stop.name(),
                    summary.residual
                ),
            });
        }
    }
    Ok(sim.state().clone())
}

/// x* of the step from `start` with target `y`: Newton to [`REFERENCE_TOLERANCE`] from y.
fn solve_reference(
    name: &str,
    scene: &Scene<3>,
    start: &State<3>,
    y: &[Vector3<f64>],
) -> Result<(Vec<Vector3<f64>>, ReferenceInfo), BenchError> {
    let mesh = scene.mesh();
    let free = FreeDofs::new(mesh.vertex_count(), scene.pinned())
        .expect("a validated scene's pins are in range");
    let mut objective =
        BackwardEulerStep::new(mesh.springs(), mesh.masses(), free, scene.time_step());
    let mut unknowns = vec![0.0; objective.dim()];
    objective.set_step(y, &start.positions, &mut unknowns);
    let params = NewtonParams {
        convergence: Convergence::RelativeGradient,
        tolerance: REFERENCE_TOLERANCE,
        max_iterations: REFERENCE_MAX_ITERATIONS,
        ..NewtonParams::default()
    };
    let fail = |reason: String| BenchError::Reference {
        scene: name.to_string(),
        reason,
    };
    let mut newton = Newton::new(objective.pattern(), params).map_err(|e| fail(e.to_string()))?;
    let report = newton
        .minimize(&mut objective, &mut unknowns)
        .map_err(|e| fail(e.to_string()))?;
    if !report.stop.is_at_resolution() {
        return Err(fail(format!(
            "Newton did not converge ({}, at most {REFERENCE_MAX_ITERATIONS} iterations) with \
             relative gradient {:e}",
            report.stop.name(),
            report.gradient()
        )));
    }
    let info = ReferenceInfo {
        iterations: report.iterations,
        gradient: report.gradient(),
        wall_time_s: report.wall_time.as_secs_f64(),
    };
    Ok((objective.positions(&unknowns).to_vec(), info))
}

// ---------------------------------------------------------------------------------------------
// The cache: one binary file per scene and start state, keyed by a hash of everything that
// determines the state and x* (mesh, masses, springs, pins, h, gravity, initial state, the exact
// solves' settings). Little-endian; f64 stored bit for bit, so a cached run equals a fresh one.
// The version in MAGIC stands for the exact solves' algorithm: a buckling step has more than one
// solution, and a changed Newton may pick another one, so it is bumped whenever Newton's default
// changes (03: convex blend and relaxation; 04: focused relaxation sweeps; 05: no relaxation after trusted exact steps;
// 06: nonlinear elimination of the hottest region; 07: the elimination over a fixed cover of
// patches; 08: Newton systems solved on a held factor).

const MAGIC: &[u8; 12] = b"HOOKEBENCH08";

/// FNV-1a, 64 bit.
struct Fnv(u64);

impl Fnv {
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01B3);
        }
    }
    fn f64(&mut self, v: f64) {
        self.bytes(&v.to_bits().to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
}

fn cache_key(setup: &Setup<3>, start: StartState) -> u64 {
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    h.bytes(MAGIC);
    h.bytes(setup.name.as_bytes());
    h.u64(match start {
        StartState::SpeedVsError => STATE_STEPS as u64,
        StartState::Rest => 0,
    });
    h.f64(REFERENCE_TOLERANCE);
    h.u64(REFERENCE_MAX_ITERATIONS as u64);
    let scene = &setup.scene;
    h.f64(scene.time_step());
    if let Some(g) = scene.forces().gravity() {
        g.iter().for_each(|&c| h.f64(c));
    }
    let mesh = scene.mesh();
    h.u64(mesh.vertex_count() as u64);
    mesh.masses().iter().for_each(|&m| h.f64(m));
    for s in mesh.springs() {
        h.u64(((s.i as u64) << 32) | s.j as u64);
        h.f64(s.stiffness);
        h.f64(s.rest_length);
    }
    scene.pinned().iter().for_each(|&p| h.u64(p as u64));
    for p in setup
        .initial
        .positions
        .iter()
        .chain(&setup.initial.velocities)
    {
        p.iter().for_each(|&c| h.f64(c));
    }
    h.f64(setup.initial.time);
    h.0
}

struct Cached {
    start: State<3>,
    reference: Option<(Vec<Vector3<f64>>, ReferenceInfo)>,
}

fn write_cache(
    path: &Path,
    key: u64,
    start: &State<3>,
    reference: Option<&(Vec<Vector3<f64>>, ReferenceInfo)>,
) -> Result<(), BenchError> {
    let cache_error = |e: String| BenchError::Cache {
        path: path.to_path_buf(),
        reason: e,
    };
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| cache_error(e.to_string()))?;
    }
    hooke_mesh::io::write_atomically(path, |out| {
        out.write_all(MAGIC)?;
        out.write_all(&key.to_le_bytes())?;
        out.write_all(&(start.positions.len() as u64).to_le_bytes())?;
        out.write_all(&start.time.to_le_bytes())?;
        let points = |out: &mut dyn Write, v: &[Vector3<f64>]| -> std::io::Result<()> {
            for p in v {
                for c in p.iter() {
                    out.write_all(&c.to_le_bytes())?;
                }
            }
            Ok(())
        };
        points(out, &start.positions)?;
        points(out, &start.velocities)?;
        match reference {
            Some((x, info)) => {
                out.write_all(&[1])?;
                out.write_all(&(info.iterations as u64).to_le_bytes())?;
                out.write_all(&info.gradient.to_le_bytes())?;
                out.write_all(&info.wall_time_s.to_le_bytes())?;
                points(out, x)?;
            }
            None => out.write_all(&[0])?,
        }
        Ok(())
    })
    .map_err(|e| cache_error(e.to_string()))
}

/// A cursor over the bytes of a cache file.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, len: usize) -> Result<&[u8], String> {
        let s = self
            .bytes
            .get(self.at..self.at + len)
            .ok_or_else(|| "the file is truncated".to_string())?;
        self.at += len;
        Ok(s)
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn points(&mut self, n: usize) -> Result<Vec<Vector3<f64>>, String> {
        (0..n)
            .map(|_| Ok(Vector3::new(self.f64()?, self.f64()?, self.f64()?)))
            .collect()
    }
}

fn read_cache(path: &Path, key: u64, n: usize) -> Result<Cached, String> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|e| e.to_string())?;
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
    };
    if r.take(MAGIC.len())? != MAGIC {
        return Err("not a hooke bench cache file of this version".into());
    }
    if r.u64()? != key {
        return Err("it was written for another scene or settings".into());
    }
    if r.u64()? != n as u64 {
        return Err("vertex count differs".into());
    }
    let time = r.f64()?;
    let positions = r.points(n)?;
    let velocities = r.points(n)?;
    let reference = match r.take(1)?[0] {
        0 => None,
        1 => {
            let iterations = r.u64()? as usize;
            let gradient = r.f64()?;
            let wall_time_s = r.f64()?;
            let x = r.points(n)?;
            Some((
                x,
                ReferenceInfo {
                    iterations,
                    gradient,
                    wall_time_s,
                },
            ))
        }
        _ => return Err("corrupt reference flag".into()),
    };
    if r.at != bytes.len() {
        return Err("trailing bytes".into());
    }
    let all_finite = positions
        .iter()
        .chain(&velocities)
        .chain(reference.iter().flat_map(|(x, _)| x))
        .all(|p| p.iter().all(|c| c.is_finite()));
    if !all_finite {
        return Err("non-finite values".into());
    }
    Ok(Cached {
        start: State {
            positions,
            velocities,
            time,
        },
        reference,
    })
}
