//! `--hard-cases`: every integrator on every hard case of docs/scenes.md §6 (numerical
//! stability).
//!
//! The cases are built on cloth-N (N = 40 by default) as docs/scenes.md §6 states them, with the
//! same seeds and vertices as the project's `tests/integration/hard_cases.rs`:
//! - `stiff h=1/30`, `stiff h=1/5`: cloth-N-stiff (k = 1e5 N/m) at both steps;
//! - `stretched x3`: the initial state scaled by 3 in x and z; `crushed to 1%`: scaled by 0.01;
//! - `k 1e1..1e7`: stiffness log-uniform over 6 orders of magnitude (SplitMix64, seed 2024);
//! - `mass ratio 1e4`: masses log-uniform over 4 orders of magnitude (seed 7), with the extremes
//!   exactly 1e4 apart;
//! - `zero-length spring`: vertex (N/2, N/2) moved onto (N/2, N/2 + 1);
//! - `free-floating`: no pins, spinning at 2 rad/s about the vertical axis through the centre.
//!
//! The scene cases ([`HARD_SCENES`]) are built-in scenes with obstacles, run as they are defined
//! (their own frames unless [`HardCaseOptions::scene_frames`] says otherwise) by the implicit
//! integrators of the suite only (an explicit method would need hundreds of substeps a frame):
//! - `bunny-drop`: the filled bunny dropped onto the frictionless ground, 10 frames of 1/60 s;
//! - `cloth-drape-40`: the unpinned cloth falling onto a sphere over the ground, 60 frames;
//! - `cloth-fall-40`: the unpinned cloth thrown down onto the ground at 5 m/s, 30 frames;
//! - `cloth-twist-40`: the cloth held at two opposite edges, one turning 720° in 4 s, wringing
//!   itself into a rope, 120 frames (about 3 minutes under newton in a release build, quiet).
//!
//! cloth-drape-40, cloth-fall-40 and cloth-twist-40 have self-contact on, which only newton,
//! newton-cg and lbfgs model (newton-relaxed too: it is newton, whose relaxation does nothing on a
//! scene with self-contact); the other implicit integrators refuse them as `unsupported`.
//!
//! Each run takes `frames` frames and ends `ok` (with the energy drift and the largest stretch),
//! `unsupported` (the integrator refuses a term of the scene by design: [`SimError::Unsupported`]),
//! `refused` (the simulation would not start otherwise: an explicit method above its stability
//! bound, or needing more than `max_substeps` substeps), or `failed` (an error during the run: a
//! linear solve that failed, the energy watchdog, divergence). Every run also reports [`RunStats`]
//! over the frames it finished: how many converged, the largest energy gain of one frame and the
//! total change (J), the deepest penetration of a free vertex into an obstacle (m), and on a scene
//! with self-contact or a sphere the exact checks of the surface after every frame: frames in which
//! it intersects itself ([`intersecting_triangle_pairs`]) or has a point inside a sphere
//! ([`triangles_inside_sphere`]), the smallest self-contact distance and the most pairs within d̂.

use std::time::Instant;

use nalgebra::Vector3;

use crate::bench::BenchError;
use crate::mesh::intersection::{intersecting_triangle_pairs, triangles_inside_sphere};
use crate::sim::{
    scenes, stability_bound, Integrator, LinearSolver, LinearizedParams, Pins, Scene, Settings,
    Shape, SimError, Simulation, State,
};
use crate::solvers::NewtonParams;

/// The hard cases, in the order of docs/scenes.md §6.
pub const HARD_CASES: &[&str] = &[
    "stiff h=1/30",
    "stiff h=1/5",
    "stretched x3",
    "crushed to 1%",
    "k 1e1..1e7",
    "mass ratio 1e4",
    "zero-length spring",
    "free-floating",
];

/// The scene cases, run after [`HARD_CASES`] by the implicit integrators of [`HARD_INTEGRATORS`].
/// All but bunny-drop have self-contact on (`unsupported` but for the newton methods and lbfgs).
pub const HARD_SCENES: &[&str] = &[
    "bunny-drop",
    "cloth-drape-40",
    "cloth-fall-40",
    "cloth-twist-40",
];

/// The scene cases run only when named (`--hard-case NAME`): cloth-twist-40's 120 frames take
/// about three minutes under Newton (quiet machine) and did not end within 81 minutes under L-BFGS, so a default
/// run of the suite stays within minutes.
pub const HARD_OPT_IN_SCENES: &[&str] = &["cloth-twist-40"];

/// Frames bunny-drop runs in the suite (a sixth of the scene's 60: the fall and the first contact).
pub const BUNNY_DROP_FRAMES: usize = 10;

/// The integrators run on each case.
pub const HARD_INTEGRATORS: &[&str] = &[
    "explicit-euler",
    "symplectic-euler",
    "linearized-cg",
    "linearized-jacobi",
    "newton",
    "newton-relaxed",
    "pd",
    "lbfgs",
    "newton-cg",
    "pd-chebyshev",
];

/// Integrators [`hard_case_settings`] also accepts, by `--hard-integrator NAME` only (not in the
/// default matrix): Newton under the projected indefinite policies (docs/solvers.md §3.2).
pub const HARD_OPT_IN_INTEGRATORS: &[&str] = &[
    "newton-projected",
    "newton-projected-exact",
    "newton-projected-pcg",
];

/// The settings [`hard_case_settings`] changes from the library's defaults ([`Settings::default`]
/// with the integrator chosen), printed with the matrix ([`crate::bench::format_hard_cases`]).
pub const HARD_CASE_OVERRIDES: &str = "settings: the library's defaults, except: explicit \
     methods take the substeps their stability bound asks for (at most 1000 per frame, above \
     which the run is refused); newton-relaxed is newton with the opt-in buckling relaxation \
     (`hooke run --relaxation buckling`); newton-projected (by name only) is newton factoring \
     the Hessian made positive definite spring by spring (docs/solvers.md §3.2), \
     newton-projected-exact the same with the exact Hessian after full steps, \
     newton-projected-pcg the exact system by CG on the definite Hessian's factor";

/// How [`hard_cases`] runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HardCaseOptions {
    /// Cloth size N. Default 40 (docs/scenes.md §6).
    pub n: usize,
    /// Frames per run. Default 30 (1 s at h = 1/30).
    pub frames: usize,
    /// Explicit methods take the substeps their stability bound asks for, up to this many per
    /// frame; above it they are refused. Default 1000.
    pub max_substeps: usize,
    /// Frames per run of a scene case ([`HARD_SCENES`]); `None` (the default): each one's own
    /// ([`hard_scene`]).
    pub scene_frames: Option<usize>,
}

impl Default for HardCaseOptions {
    fn default() -> Self {
        HardCaseOptions {
            n: 40,
            frames: 30,
            max_substeps: 1000,
            scene_frames: None,
        }
    }
}

/// What one run measured over the frames it finished (all of them for an `ok` run, those before
/// the failing one for a failed run, none for a refused one).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct RunStats {
    /// Frames that finished.
    pub frames: usize,
    /// Frames whose solver converged ([`crate::sim::StepReport::converged`] not `Some(false)`;
    /// the explicit methods, which solve nothing, count every frame). At most `frames`.
    pub converged: usize,
    /// The largest energy change of one frame, max over n of E(n+1) − E(n) (J, total energy);
    /// positive when some frame gained energy. `None` if no frame finished.
    pub max_energy_step: Option<f64>,
    /// E(last frame) − E(0) (J); 0 if no frame finished.
    pub energy_change: f64,
    /// The most negative [`crate::sim::Contact::signed_distance`] (m) of a free vertex from any
    /// obstacle over the frames: ≤ 0, and 0 when nothing went inside (or the scene has no obstacle).
    pub deepest_penetration: f64,
    /// Frames after which the scene's surface ([`Scene::surface_triangles`]) intersected itself,
    /// by the exact test [`intersecting_triangle_pairs`] (any pair of triangles meeting off their
    /// shared vertices and edge). `Some` (0 until a frame finishes) on a scene with self-contact,
    /// where the barrier promises 0; `None` without self-contact.
    pub self_intersecting_frames: Option<usize>,
    /// The smallest `smallest_distance` of [`Simulation::self_contact_state`] over the frames (m):
    /// how close two primitives of the surface came, over the candidate pairs of self-contact's
    /// broad phase (every pair within 1.5 d̂ is one; pairs farther apart may be too, so a value
    /// above d̂ says only that no pair came within it; ∞ when there was no candidate). Below d̂
    /// exactly when some pair was within the barrier's reach. `None` until a frame reports a
    /// self-contact state (no self-contact, or no frame finished).
    pub smallest_self_distance: Option<f64>,
    /// The self-contact barrier's reach d̂ of the scene (m), to read
    /// [`RunStats::smallest_self_distance`] against; `None` without self-contact.
    pub self_contact_reach: Option<f64>,
    /// The most point–triangle pairs within d̂ after one frame; `None` as
    /// [`RunStats::smallest_self_distance`].
    pub most_point_triangle_pairs: Option<usize>,
    /// The most edge–edge pairs within d̂ after one frame; `None` as
    /// [`RunStats::smallest_self_distance`].
    pub most_edge_edge_pairs: Option<usize>,
    /// Frames after which some triangle of the surface had a point strictly inside a sphere
    /// obstacle ([`triangles_inside_sphere`] at the sphere's own radius). `Some` (0 until a frame
    /// finishes) on a scene with a sphere; `None` without one.
    pub frames_inside_sphere: Option<usize>,
}

impl RunStats {
    /// Add one finished frame: `energy` its total energy (J), `previous` the one before (J).
    fn frame(&mut self, converged: bool, previous: f64, energy: f64, e0: f64, penetration: f64) {
        self.frames += 1;
        self.converged += usize::from(converged);
        let step = energy - previous;
        self.max_energy_step = Some(self.max_energy_step.map_or(step, |m| m.max(step)));
        self.energy_change = energy - e0;
        self.deepest_penetration = self.deepest_penetration.min(penetration);
    }
}

/// The exact checks of a scene's surface after every frame ([`RunStats`]): self-intersection on a
/// scene with self-contact, triangles inside each sphere obstacle.
struct SurfaceChecks {
    /// The surface ([`Scene::surface_triangles`]).
    triangles: Vec<[u32; 3]>,
    /// Whether the scene has self-contact.
    self_contact: bool,
    /// The sphere obstacles: centre (m), radius (m).
    spheres: Vec<(Vector3<f64>, f64)>,
}

impl SurfaceChecks {
    /// The checks `scene` asks for, with the counts they fill in `stats` set to 0.
    fn new(scene: &Scene<3>, stats: &mut RunStats) -> Self {
        let spheres: Vec<(Vector3<f64>, f64)> = scene
            .contacts()
            .iter()
            .filter_map(|c| match c.shape {
                Shape::Sphere { center, radius } => Some((center, radius)),
                _ => None,
            })
            .collect();
        let self_contact = scene.self_contact().is_some();
        if self_contact {
            stats.self_intersecting_frames = Some(0);
            stats.self_contact_reach = scene.self_contact_model().map(|m| m.distance);
        }
        if !spheres.is_empty() {
            stats.frames_inside_sphere = Some(0);
        }
        let triangles = if self_contact || !spheres.is_empty() {
            scene.surface_triangles()
        } else {
            Vec::new()
        };
        SurfaceChecks {
            triangles,
            self_contact,
            spheres,
        }
    }

    /// Check the frame just finished by `sim` and count it in `stats`.
    fn frame(&self, sim: &Simulation<3>, stats: &mut RunStats) {
        let positions = &sim.state().positions;
        if self.self_contact {
            // An error (a non-finite coordinate, which the simulation itself refuses) leaves the
            // frame unproven: counted as intersecting.
            let intersects = intersecting_triangle_pairs(positions, &self.triangles)
                .map_or(true, |pairs| !pairs.is_empty());
            if let Some(count) = &mut stats.self_intersecting_frames {
                *count += usize::from(intersects);
            }
        }
        if let Some(state) = sim.self_contact_state() {
            let smallest = stats.smallest_self_distance.unwrap_or(f64::INFINITY);
            stats.smallest_self_distance = Some(smallest.min(state.smallest_distance));
            let most = |m: Option<usize>, n: usize| Some(m.unwrap_or(0).max(n));
            stats.most_point_triangle_pairs =
                most(stats.most_point_triangle_pairs, state.point_triangle_pairs);
            stats.most_edge_edge_pairs = most(stats.most_edge_edge_pairs, state.edge_edge_pairs);
        }
        if !self.spheres.is_empty() {
            let inside = self.spheres.iter().any(|(center, radius)| {
                triangles_inside_sphere(positions, &self.triangles, center, *radius)
                    .map_or(true, |inside| !inside.is_empty())
            });
            if let Some(count) = &mut stats.frames_inside_sphere {
                *count += usize::from(inside);
            }
        }
    }
}

/// The most negative signed distance (m) of a free vertex of `state` from the obstacles of
/// `scene`, or 0 if none is inside (or there are no obstacles).
pub fn deepest_penetration(scene: &Scene<3>, state: &State<3>) -> f64 {
    let mut deepest = 0.0f64;
    for contact in scene.contacts() {
        for (x, &pinned) in state.positions.iter().zip(scene.is_pinned()) {
            if !pinned {
                deepest = deepest.min(contact.signed_distance(x));
            }
        }
    }
    deepest
}

/// How one run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum HardOutcome {
    /// Every frame finished.
    Ok {
        /// (E_end − E₀) / (|E₀| + E_g): the change of total energy over the run relative to the
        /// scene's energy scale (E_g = M |g| L: total mass, gravity, diagonal of the initial
        /// bounding box). Backward Euler dissipates (negative); a positive drift is energy gained.
        energy_drift: f64,
        /// Largest spring stretch |r|/l over all frames (1 at rest).
        max_stretch: f64,
        /// Frames whose solver did not converge ([`crate::sim::StepReport::converged`]: the
        /// iteration limit, or a stall above the rounding floor; projective dynamics runs a fixed
        /// number of iterations by design and counts here).
        unconverged: usize,
        /// The most pieces one frame was split into: explicit substeps, or the halves of a step
        /// that Newton did not finish (1: never split).
        max_pieces: usize,
    },
    /// The integrator does not model a term of the scene and refused to start
    /// ([`SimError::Unsupported`]: self-contact under an integrator other than newton, newton-cg
    /// and lbfgs; the buckling relaxation with obstacles): a combination it refuses by design, not
    /// a failure.
    Unsupported {
        /// The error's message.
        error: String,
    },
    /// The simulation refused to start (for another reason than [`HardOutcome::Unsupported`]).
    Refused {
        /// The error's message.
        error: String,
    },
    /// An error during the run.
    Failed {
        /// The frame (1-based) that failed.
        frame: usize,
        /// The error's message.
        error: String,
        /// Largest stretch over the frames before it.
        max_stretch: f64,
    },
}

/// One cell of the matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct HardResult {
    /// The case ([`HARD_CASES`]).
    pub case: String,
    /// The integrator ([`HARD_INTEGRATORS`]).
    pub integrator: String,
    /// How it ended.
    pub outcome: HardOutcome,
    /// What it measured over the frames it finished.
    pub stats: RunStats,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
}

/// Run every integrator of `integrators` on every case of `cases` ([`HARD_CASES`] and
/// [`HARD_SCENES`]); the scene cases only with the implicit ones (an explicit integrator gives no
/// cell there).
///
/// # Errors
/// [`BenchError::Scene`] for an unknown case or integrator name, or a size below 4.
pub fn hard_cases(
    cases: &[&str],
    integrators: &[&str],
    options: HardCaseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<HardResult>, BenchError> {
    if options.n < 4 && cases.iter().any(|c| !HARD_SCENES.contains(c)) {
        return Err(BenchError::Scene(format!(
            "hard cases need cloth-N with N ≥ 4, got {}",
            options.n
        )));
    }
    let mut results = Vec::new();
    for &case_name in cases {
        let is_scene = HARD_SCENES.contains(&case_name);
        for &integrator in integrators {
            let (scene, state, frames) = if is_scene {
                let (scene, state, frames) = hard_scene(case_name)?;
                (scene, state, options.scene_frames.unwrap_or(frames))
            } else {
                let (scene, state) = hard_case(case_name, options.n)?;
                (scene, state, options.frames)
            };
            let settings = hard_case_settings(integrator, &scene, options.max_substeps)?;
            if is_scene && settings.integrator.is_explicit() {
                continue;
            }
            let result = run_hard_case(case_name, integrator, scene, state, settings, frames);
            progress(&format!(
                "{case_name}, {integrator}: {} in {:.1} s",
                result.outcome.label(),
                result.wall_time_s
            ));
            results.push(result);
        }
    }
    Ok(results)
}

impl HardOutcome {
    /// The outcome's name in the report: `ok`, `unsupported`, `refused` or `failed`.
    pub fn label(&self) -> &'static str {
        match self {
            HardOutcome::Ok { .. } => "ok",
            HardOutcome::Unsupported { .. } => "unsupported",
            HardOutcome::Refused { .. } => "refused",
            HardOutcome::Failed { .. } => "failed",
        }
    }
}

/// Run one cell of the matrix as [`hard_cases`] does: `settings` on `scene` from `state` for
/// `frames` frames, measured after every frame ([`RunStats`]) and timed as a whole; `case` and
/// `integrator` only name the result. For a scene of the caller's own (a small self-contact scene
/// in a test) as for the suite's.
pub fn run_hard_case(
    case: &str,
    integrator: &str,
    scene: Scene<3>,
    state: State<3>,
    settings: Settings,
    frames: usize,
) -> HardResult {
    let start = Instant::now();
    let (outcome, stats) = run(scene, state, settings, frames);
    HardResult {
        case: case.into(),
        integrator: integrator.into(),
        outcome,
        stats,
        wall_time_s: start.elapsed().as_secs_f64(),
    }
}

fn run(
    scene: Scene<3>,
    state: State<3>,
    settings: Settings,
    frames: usize,
) -> (HardOutcome, RunStats) {
    let scale = energy_scale(&scene, &state.positions);
    let mut stats = RunStats::default();
    let checks = SurfaceChecks::new(&scene, &mut stats);
    let mut sim = match Simulation::new(scene, state, settings) {
        Ok(sim) => sim,
        Err(e @ SimError::Unsupported { .. }) => {
            let error = e.to_string();
            return (HardOutcome::Unsupported { error }, stats);
        }
        Err(e) => {
            let error = e.to_string();
            return (HardOutcome::Refused { error }, stats);
        }
    };
    let e0 = sim.energy().total;
    let mut previous = e0;
    let mut max_stretch = sim.scene().max_stretch(sim.state());
    let (mut unconverged, mut max_pieces) = (0, 1);
    for frame in 1..=frames {
        let report = match sim.step() {
            Ok(report) => report,
            Err(e) => {
                let outcome = match e {
                    SimError::UnstableStep { .. } => HardOutcome::Refused {
                        error: e.to_string(),
                    },
                    e => HardOutcome::Failed {
                        frame,
                        error: e.to_string(),
                        max_stretch,
                    },
                };
                return (outcome, stats);
            }
        };
        let converged = report.converged != Some(false);
        if !converged {
            unconverged += 1;
        }
        max_pieces = max_pieces.max(report.substeps);
        max_stretch = max_stretch.max(sim.scene().max_stretch(sim.state()));
        let energy = sim.energy().total;
        let penetration = deepest_penetration(sim.scene(), sim.state());
        stats.frame(converged, previous, energy, e0, penetration);
        checks.frame(&sim, &mut stats);
        previous = energy;
    }
    let outcome = HardOutcome::Ok {
        energy_drift: (sim.energy().total - e0) / (e0.abs() + scale),
        max_stretch,
        unconverged,
        max_pieces,
    };
    (outcome, stats)
}

/// E_g = M |g| L (J): total mass, gravity, diagonal of the bounding box of `positions` — the
/// scene's own energy scale, against which energy drift is judged.
pub fn energy_scale(scene: &Scene<3>, positions: &[Vector3<f64>]) -> f64 {
    let (mut min, mut max) = (positions[0], positions[0]);
    for p in positions {
        min = min.inf(p);
        max = max.sup(p);
    }
    let g = scene.forces().gravity().map_or(0.0, |g| g.norm());
    scene.mesh().total_mass() * g * (max - min).norm()
}

/// The settings the hard cases run `name` (one of [`HARD_INTEGRATORS`]) with on `scene`: explicit
/// methods with the substeps their safe stability bound needs, at most `max_substeps`; Newton with
/// 200 iterations; the others with their defaults.
///
/// # Errors
/// [`BenchError::Scene`] for an unknown integrator name.
pub fn hard_case_settings(
    name: &str,
    scene: &Scene<3>,
    max_substeps: usize,
) -> Result<Settings, BenchError> {
    let explicit = |integrator| {
        let bound = stability_bound(scene);
        let (safe, _) = bound.for_integrator(integrator, scene.time_step());
        let needed = (scene.time_step() / safe).ceil();
        Settings {
            integrator,
            substeps: Some((needed as usize).clamp(1, max_substeps)),
            ..Settings::default()
        }
    };
    let linearized = |solver| Settings {
        integrator: Integrator::Linearized,
        linearized: LinearizedParams {
            solver,
            ..LinearizedParams::default()
        },
        ..Settings::default()
    };
    Ok(match name {
        "explicit-euler" => explicit(Integrator::ExplicitEuler),
        "symplectic-euler" => explicit(Integrator::SymplecticEuler),
        "linearized-cg" => linearized(LinearSolver::ConjugateGradient),
        "linearized-jacobi" => linearized(LinearSolver::Jacobi),
        "newton" => Settings {
            integrator: Integrator::Newton,
            ..Settings::default()
        },
        "newton-relaxed" => Settings {
            integrator: Integrator::Newton,
            newton: NewtonParams {
                relaxation: crate::solvers::Relaxation::BUCKLING,
                ..NewtonParams::default()
            },
            ..Settings::default()
        },
        name @ ("newton-projected" | "newton-projected-exact" | "newton-projected-pcg") => {
            Settings {
                integrator: Integrator::Newton,
                newton: NewtonParams {
                    indefinite: match name {
                        "newton-projected" => crate::solvers::IndefinitePolicy::Projected,
                        "newton-projected-exact" => {
                            crate::solvers::IndefinitePolicy::ProjectedThenExact
                        }
                        _ => crate::solvers::IndefinitePolicy::ProjectedPreconditioned,
                    },
                    ..NewtonParams::default()
                },
                ..Settings::default()
            }
        }
        "pd" => Settings {
            integrator: Integrator::ProjectiveDynamics,
            ..Settings::default()
        },
        "lbfgs" => Settings {
            integrator: Integrator::Lbfgs,
            ..Settings::default()
        },
        "newton-cg" => Settings {
            integrator: Integrator::NewtonCg,
            ..Settings::default()
        },
        "pd-chebyshev" => Settings {
            integrator: Integrator::ChebyshevPd,
            ..Settings::default()
        },
        other => {
            return Err(BenchError::Scene(format!(
                "unknown integrator {other:?} for the hard cases; expected one of: {}",
                HARD_INTEGRATORS
                    .iter()
                    .chain(HARD_OPT_IN_INTEGRATORS)
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", ")
            )))
        }
    })
}

/// SplitMix64: a small seeded generator, so the random cases are the same on every machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The scene case `name` (one of [`HARD_SCENES`]): the built-in scene's scene and initial state,
/// and the frames the suite runs it for ([`BUNNY_DROP_FRAMES`] for bunny-drop, the scene's own
/// for the others: 60, 30 and 120).
///
/// # Errors
/// [`BenchError::Scene`] for an unknown name or a scene that cannot be built.
pub fn hard_scene(name: &str) -> Result<(Scene<3>, State<3>, usize), BenchError> {
    let scene_error = |e: SimError| BenchError::Scene(format!("hard case {name:?}: {e}"));
    let setup = match name {
        "bunny-drop" => scenes::bunny_drop().map(|s| (s, BUNNY_DROP_FRAMES)),
        "cloth-drape-40" => scenes::cloth_drape(40).map(|s| {
            let frames = s.steps;
            (s, frames)
        }),
        "cloth-fall-40" => scenes::cloth_fall(40).map(|s| {
            let frames = s.steps;
            (s, frames)
        }),
        "cloth-twist-40" => scenes::cloth_twist(40).map(|s| {
            let frames = s.steps;
            (s, frames)
        }),
        other => return Err(unknown_case(other)),
    };
    let (setup, frames) = setup.map_err(scene_error)?;
    Ok((setup.scene, setup.initial, frames))
}

/// The hard case `name` (one of [`HARD_CASES`]) on cloth-`n`: the scene and its initial state, as
/// the module documentation describes them.
///
/// # Errors
/// [`BenchError::Scene`] for an unknown case or a scene that cannot be built.
pub fn hard_case(name: &str, n: usize) -> Result<(Scene<3>, State<3>), BenchError> {
    let scene_error = |e: SimError| BenchError::Scene(format!("hard case {name:?}: {e}"));
    let cloth = |stiff| -> Result<(Scene<3>, State<3>), BenchError> {
        let setup = scenes::cloth(n, stiff).map_err(scene_error)?;
        Ok((setup.scene, setup.initial))
    };
    let rebuild = |scene: &Scene<3>, mesh| -> Result<Scene<3>, BenchError> {
        Scene::new(mesh, scene.time_step())
            .and_then(|s| s.with_pins(Pins::Vertices(scene.pinned().to_vec())))
            .and_then(|s| s.with_forces(scene.forces().as_slice().to_vec()))
            .map_err(scene_error)
    };
    Ok(match name {
        "stiff h=1/30" => cloth(true)?,
        "stiff h=1/5" => {
            let (scene, state) = cloth(true)?;
            (scene.with_time_step(0.2).map_err(scene_error)?, state)
        }
        "stretched x3" => {
            let (scene, mut state) = cloth(false)?;
            for p in &mut state.positions {
                p.x *= 3.0;
                p.z *= 3.0;
            }
            (scene, state)
        }
        "crushed to 1%" => {
            let (scene, mut state) = cloth(false)?;
            for p in &mut state.positions {
                *p *= 0.01;
            }
            (scene, state)
        }
        "k 1e1..1e7" => {
            let (scene, state) = cloth(false)?;
            let mut rng = Rng(2024);
            let mesh = scene
                .mesh()
                .clone()
                .map_stiffness(|_, _| 10f64.powf(1.0 + 6.0 * rng.next()))
                .map_err(|e| scene_error(e.into()))?;
            (rebuild(&scene, mesh)?, state)
        }
        "mass ratio 1e4" => {
            let (scene, state) = cloth(false)?;
            let mut rng = Rng(7);
            let count = scene.mesh().vertex_count();
            let mesh = scene
                .mesh()
                .clone()
                .map_masses(|v, m| match v {
                    _ if v == count / 2 => m * 100.0,
                    _ if v == count / 2 + 1 => m / 100.0,
                    _ => m * 10f64.powf(-2.0 + 4.0 * rng.next()),
                })
                .map_err(|e| scene_error(e.into()))?;
            (rebuild(&scene, mesh)?, state)
        }
        "zero-length spring" => {
            let (scene, mut state) = cloth(false)?;
            let half = n / 2;
            let (a, b) = (half * n + half, half * n + half + 1);
            state.positions[a] = state.positions[b];
            (scene, state)
        }
        "free-floating" => {
            let (scene, mut state) = cloth(false)?;
            let scene = Scene::new(scene.mesh().clone(), scene.time_step())
                .and_then(|s| s.with_forces(scene.forces().as_slice().to_vec()))
                .map_err(scene_error)?;
            let centre = Vector3::new(0.5, 0.0, 0.5);
            for (p, v) in state.positions.iter().zip(&mut state.velocities) {
                *v = Vector3::new(0.0, 2.0, 0.0).cross(&(p - centre));
            }
            (scene, state)
        }
        other => return Err(unknown_case(other)),
    })
}

/// The error for a hard case of that name that does not exist, listing those that do.
fn unknown_case(name: &str) -> BenchError {
    BenchError::Scene(format!(
        "unknown hard case {name:?}; expected one of: {}",
        HARD_CASES
            .iter()
            .chain(HARD_SCENES)
            .copied()
            .collect::<Vec<_>>()
            .join(", ")
    ))
}
