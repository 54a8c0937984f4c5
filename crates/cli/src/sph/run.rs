//! `hooke run` of a fluid scene, and what it writes in `--out DIR`:
//!
//! - `frames/frame_NNNN.vtk`: the fluid particles of frame N (0 the initial state) as a legacy
//!   ASCII VTK unstructured grid of vertex cells, 2D with z = 0, with the point data `velocity`
//!   (vectors, m/s), `density` (kg/m³) and `pressure` (Pa): a 2D fluid is a slice of unit depth
//!   (docs/sph.md, "Units");
//! - `walls.vtk`: the boundary particles (fixed), as vertices without data;
//! - `summary.json`: [`FluidSummary`], one [`FluidFrameRecord`] per frame, rewritten (atomically)
//!   every [`SUMMARY_EVERY`] frames during the run and at its end, so that a long run can be
//!   followed and a killed one leaves its records up to the last multiple;
//! - `preview.png`: the last frame, particles coloured by speed, walls drawn ([`super::preview`]).
//!
//! Frames are `--dt` apart (default: the scene's end time over its frame count, 0.02 s for the dam
//! breaks and 0.05 s for hydrostatic-2d); `--steps N` sets the number of frames after the initial
//! one (default the scene's: 50 for the dam breaks to t = 1 s, 40 for hydrostatic-2d to 2 s). Between
//! frames the fluid takes its own stable steps (CFL and force conditions), the last one shortened to
//! land on the frame's time.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use hooke_sph::scenes::{self, FluidScene};
use hooke_sph::{Evaluated, Fluid, Integrator};
use nalgebra::SVector;
use serde::{Deserialize, Serialize};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};

use super::{file, preview, SphCliError};
use crate::output::progress_bar;

/// `summary.json` is rewritten after every this many frames during a fluid run. A fluid frame's
/// record is about 400 bytes and its VTK file about 100 bytes a particle, so rewriting the summary
/// of n frames every K frames costs 400·n/K bytes a frame, less than the frame itself (0.5 MB at
/// the default 5,000 particles) up to n ≈ 10,000 with K = 10; a default frame takes about a second
/// of computation, so the summary lags the run by some ten seconds at most.
pub(crate) const SUMMARY_EVERY: usize = 10;

/// A fluid scene in 2D or 3D.
#[derive(Debug, Clone)]
pub(crate) enum AnyScene {
    /// A 2D scene.
    Two(FluidScene<2>),
    /// A 3D scene.
    Three(FluidScene<3>),
}

/// What `hooke run` asks of a fluid run.
#[derive(Debug, Clone)]
pub(crate) struct FluidRunOptions<'a> {
    /// A built-in fluid scene's name or a scene file with a `[fluid]` table.
    pub scene: &'a str,
    /// `--dx`: the lattice spacing instead of the scene's (m).
    pub dx: Option<f64>,
    /// `--steps`: frames after the initial one.
    pub frames: Option<usize>,
    /// `--dt`: simulated time between frames (s).
    pub frame_interval: Option<f64>,
    /// `--integrator`: symplectic-euler or leapfrog.
    pub integrator: Option<&'a str>,
    /// `--out`.
    pub out: &'a Path,
    /// `--quiet`: no progress bar.
    pub quiet: bool,
}

/// `summary.json` of a fluid run. Units are SI; a 2D fluid is a slice of unit depth, so its
/// densities are kg/m³ and pressures Pa as in 3D, while masses are per metre of depth (kg/m) and
/// energies J/m (docs/sph.md, "Units").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FluidSummary {
    /// The scene, e.g. `dam-break-2d`.
    pub scene: String,
    /// Always `sph` (a spring run's summary has `vertices` and `springs` instead).
    pub model: String,
    /// 2 or 3.
    pub dimension: usize,
    /// Fluid particles (constant over the run).
    pub fluid_particles: usize,
    /// Boundary (wall) particles, fixed.
    pub boundary_particles: usize,
    /// Mass of each particle, ρ₀Δx^D (kg; kg/m in 2D).
    pub particle_mass: f64,
    /// Lattice spacing Δx (m).
    pub dx: f64,
    /// Smoothing length h (m); the kernel's support is 2h.
    pub smoothing_length: f64,
    /// Speed of sound c₀ (m/s).
    pub sound_speed: f64,
    /// Rest density ρ₀ (kg/m³).
    pub rest_density: f64,
    /// `symplectic-euler` or `leapfrog`.
    pub integrator: String,
    /// `continuity` or `summation`.
    pub density_method: String,
    /// `cubic-spline` or `wendland-quintic`.
    pub kernel: String,
    /// Simulated time between frames (s).
    pub frame_interval: f64,
    /// The column's width L (m), the front's scale.
    pub column_width: f64,
    /// The column's height H (m).
    pub column_height: f64,
    /// Whether frames report the dam-break front (`front_x`, `Z`, `T`).
    pub dam_break: bool,
    /// One record per frame written, from frame 0 (the initial state).
    pub frames: Vec<FluidFrameRecord>,
}

/// The fluid at one frame, and the steps that led to it from the previous frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FluidFrameRecord {
    /// Frame number (0 the initial state).
    pub frame: usize,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken since the start.
    pub steps: u64,
    /// Steps taken since the previous frame.
    pub frame_steps: u64,
    /// Smallest step Δt since the previous frame (s), not counting a last step shortened to land
    /// on the frame's time; `null` for frame 0.
    pub min_dt: Option<f64>,
    /// Largest step Δt since the previous frame (s); `null` for frame 0.
    pub max_dt: Option<f64>,
    /// Largest density error maxᵢ |ρᵢ/ρ₀ − 1| over fluid particles (dimensionless).
    pub max_density_error: f64,
    /// Kinetic energy ½ m Σ |vᵢ|² of the fluid (J, J/m in 2D).
    pub kinetic_energy: f64,
    /// Largest fluid speed (m/s).
    pub max_speed: f64,
    /// Fluid particles.
    pub particles: usize,
    /// Total fluid mass (kg, kg/m in 2D): the particles' masses are fixed, so it is constant.
    pub total_mass: f64,
    /// Dam breaks only: the front, the largest x over fluid particles with at least 3 fluid
    /// neighbours within the support (m); `null` when no particle has 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub front_x: Option<f64>,
    /// Dam breaks only: Z = front_x / L.
    #[serde(rename = "Z", default, skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    /// Dam breaks only: T = t·√(2g/L), the time of Koshizuka and Oka's data.
    #[serde(rename = "T", default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
}

/// Builds the scene `options` name: a built-in scene at `--dx` (or its spacing in
/// docs/scenes.md §7), or a scene file (its `dx` replaced by `--dx`).
fn load_scene(options: &FluidRunOptions) -> Result<AnyScene, SphCliError> {
    if let Some(dx) = options.dx {
        if !(dx.is_finite() && dx > 0.0) {
            return Err(SphCliError::Argument {
                name: "dx",
                reason: format!("{dx} is out of range: must be finite and > 0 (m)"),
            });
        }
    }
    let path = Path::new(options.scene);
    let scene = if super::is_builtin(options.scene) {
        let default_dx = scenes::BUILTIN
            .iter()
            .find(|(n, _, _)| *n == options.scene)
            .map_or(0.02, |&(_, dx, _)| dx);
        let dx = options.dx.unwrap_or(default_dx);
        let built = match options.scene {
            "dam-break-3d" => scenes::dam_break_3d(dx).map(AnyScene::Three),
            "hydrostatic-2d" => scenes::hydrostatic_2d(dx).map(AnyScene::Two),
            _ => scenes::dam_break_2d(dx).map(AnyScene::Two),
        };
        built.map_err(|e| match options.dx {
            Some(_) => SphCliError::Argument {
                name: "dx",
                reason: e.to_string(),
            },
            None => SphCliError::fluid(options.scene, "setup", e),
        })?
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| SphCliError::io(path, e))?;
        let text = match options.dx {
            Some(dx) => override_dx(&text, path, dx)?,
            None => text,
        };
        file::parse(&text, path)?
    };
    // At least two particles across the column.
    let (dx, width, height) = match &scene {
        AnyScene::Two(s) => (s.dx, s.column_width, s.column_height),
        AnyScene::Three(s) => (s.dx, s.column_width, s.column_height),
    };
    if options.dx.is_some() && dx > width.min(height) / 2.0 {
        return Err(SphCliError::Argument {
            name: "dx",
            reason: format!(
                "{dx} is too coarse: at most half the column's smaller side, {} m",
                width.min(height)
            ),
        });
    }
    Ok(scene)
}

/// The scene file's text with `fluid.dx` set to `dx`.
fn override_dx(text: &str, path: &Path, dx: f64) -> Result<String, SphCliError> {
    let mut table: toml::Table = text.parse().map_err(|source| SphCliError::Syntax {
        path: path.to_path_buf(),
        source: Box::new(source),
    })?;
    if let Some(toml::Value::Table(fluid)) = table.get_mut("fluid") {
        fluid.insert("dx".into(), toml::Value::Float(dx));
    }
    Ok(table.to_string())
}

/// Runs a fluid scene and writes its frames, summary and preview (see the [module](self)).
///
/// # Errors
/// [`SphCliError`]: a bad scene, file or option; a failed step (after the summary of the frames
/// before it is written); an output file that cannot be written.
pub(crate) fn run(options: &FluidRunOptions) -> Result<(), SphCliError> {
    run_timed(options, true).map(|_| ())
}

/// Where the wall time of a fluid run went.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RunTimes {
    /// Fluid particles.
    pub fluid_particles: usize,
    /// Boundary particles.
    pub boundary_particles: usize,
    /// Steps taken.
    pub steps: u64,
    /// From the fluid's construction to the last file written.
    pub wall: Duration,
    /// In [`Fluid::advance_to`] and the evaluation of each frame's state.
    pub stepping: Duration,
    /// Each frame's record (front, energies) and VTK file, the summary and the preview.
    pub output: Duration,
}

/// As [`run`], returning where the time went; `announce` prints the scene's header line and the
/// closing line on stderr (the benchmark prints its own).
pub(crate) fn run_timed(
    options: &FluidRunOptions,
    announce: bool,
) -> Result<RunTimes, SphCliError> {
    match load_scene(options)? {
        AnyScene::Two(s) => run_scene(s, options, announce),
        AnyScene::Three(s) => run_scene(s, options, announce),
    }
}

fn run_scene<const D: usize>(
    mut scene: FluidScene<D>,
    options: &FluidRunOptions,
    announce: bool,
) -> Result<RunTimes, SphCliError> {
    let name = scene.name.clone();
    if let Some(text) = options.integrator {
        scene.setup.params.integrator =
            text.parse::<Integrator>()
                .map_err(|e| SphCliError::Argument {
                    name: "integrator",
                    reason: e.to_string(),
                })?;
    }
    let frames = options.frames.unwrap_or(scene.frames);
    if frames == 0 {
        return Err(SphCliError::Argument {
            name: "steps",
            reason: "must be at least 1".into(),
        });
    }
    let interval = match options.frame_interval {
        Some(dt) if dt.is_finite() && dt > 0.0 => dt,
        Some(dt) => {
            return Err(SphCliError::Argument {
                name: "dt",
                reason: format!("{dt} is out of range: must be finite and > 0 (s)"),
            })
        }
        None => scene.end_time / scene.frames.max(1) as f64,
    };
    let begin = Instant::now();
    let mut fluid =
        Fluid::new(scene.setup.clone()).map_err(|e| SphCliError::fluid(&name, "setup", e))?;

    let frames_dir = options.out.join("frames");
    std::fs::create_dir_all(&frames_dir).map_err(|e| SphCliError::io(&frames_dir, e))?;
    remove_stale_frames(&frames_dir)?;
    crate::output::remove_leftovers(&[options.out, &frames_dir])?;
    write_particles(
        &options.out.join("walls.vtk"),
        fluid.boundary_positions(),
        None,
    )?;

    let params = *fluid.params();
    let gravity = -params.gravity[1];
    let width = scene.column_width;
    let mut summary = FluidSummary {
        scene: name.clone(),
        model: "sph".into(),
        dimension: D,
        fluid_particles: fluid.fluid_count(),
        boundary_particles: fluid.boundary_count(),
        particle_mass: fluid.particle_mass(),
        dx: scene.dx,
        smoothing_length: params.smoothing_length,
        sound_speed: params.sound_speed,
        rest_density: params.rest_density,
        integrator: params.integrator.name().into(),
        density_method: params.density.name().into(),
        kernel: params.kernel.name().into(),
        frame_interval: interval,
        column_width: width,
        column_height: scene.column_height,
        dam_break: scene.dam_break,
        frames: Vec::with_capacity(frames.saturating_add(1).min(1 << 12)),
    };
    let dam_break = scene.dam_break;
    let record = |frame: usize, fluid: &mut Fluid<D>, report: Option<hooke_sph::AdvanceReport>| {
        let front_x = if dam_break { fluid.front(0, 3) } else { None };
        let e = fluid.evaluated();
        let fluid = e.fluid();
        let time = fluid.time();
        FluidFrameRecord {
            frame,
            time,
            steps: fluid.steps(),
            frame_steps: report.map_or(0, |r| r.steps),
            min_dt: report.map(|r| r.min_dt).filter(|d| d.is_finite()),
            max_dt: report.map(|r| r.max_dt).filter(|&d| d > 0.0),
            max_density_error: e.max_density_error(),
            kinetic_energy: fluid.kinetic_energy(),
            max_speed: fluid.max_speed(),
            particles: fluid.fluid_count(),
            total_mass: fluid.total_mass(),
            front_x,
            z: front_x.map(|x| x / width),
            t: dam_break.then(|| time * (2.0 * gravity.abs() / width).sqrt()),
        }
    };
    let write_frame = |index: usize, e: Evaluated<D>| {
        write_particles(
            &frames_dir.join(format!("frame_{index:04}.vtk")),
            e.positions(),
            Some(ParticleData {
                velocities: e.velocities(),
                densities: e.densities(),
                pressures: e.pressures(),
            }),
        )
    };
    if announce {
        eprintln!(
            "{name}: {} fluid and {} wall particles, dx = {} m, h = {:.4} m, c0 = {:.2} m/s, {}; \
         {frames} frames of {interval} s (acoustic step {:.3e} s)",
            fluid.fluid_count(),
            fluid.boundary_count(),
            scene.dx,
            params.smoothing_length,
            params.sound_speed,
            params.integrator.name(),
            fluid.acoustic_step(),
        );
    }
    let start = Instant::now();
    // Stepping: the steps and each frame's evaluation (which the next step reuses); output:
    // the rest of each frame.
    let mut stepping = Duration::ZERO;
    let mut output = Duration::ZERO;
    fluid.evaluated();
    stepping += start.elapsed();
    let written = Instant::now();
    summary.frames.push(record(0, &mut fluid, None));
    write_frame(0, fluid.evaluated())?;
    output += written.elapsed();
    let halt = crate::test_hook::Halt::from_env().map_err(SphCliError::TestHook)?;
    let progress = progress_bar(frames as u64, options.quiet);
    let mut failure = None;
    for frame in 1..=frames {
        let t = frame as f64 * interval;
        let stepped = Instant::now();
        match fluid.advance_to(t) {
            Ok(report) => {
                fluid.evaluated();
                stepping += stepped.elapsed();
                let written = Instant::now();
                summary.frames.push(record(frame, &mut fluid, Some(report)));
                write_frame(frame, fluid.evaluated())?;
                if frame % SUMMARY_EVERY == 0 && frame < frames {
                    crate::output::write_json_atomically(
                        &options.out.join("summary.json"),
                        &summary,
                        true,
                    )?;
                }
                output += written.elapsed();
                progress.set_message(format!("t = {:.3} s", fluid.time()));
                progress.inc(1);
                if halt == Some(crate::test_hook::Halt::AfterFrame(frame)) {
                    crate::test_hook::Halt::AfterFrame(frame).halt();
                }
            }
            Err(e) => {
                failure = Some(SphCliError::fluid(
                    &name,
                    format!("frame {frame} (t = {t} s)"),
                    e,
                ));
                break;
            }
        }
    }
    progress.finish_and_clear();
    let written = Instant::now();
    // The summary is written even after a failure, so that the frames before it can be inspected.
    crate::output::write_json_atomically(&options.out.join("summary.json"), &summary, true)?;
    if let Some(e) = failure {
        return Err(e);
    }
    let speeds: Vec<f64> = fluid.velocities().iter().map(|v| v.norm()).collect();
    let shown = summary.frames.last().map_or(0, |r| r.frame);
    let title = format!(
        "{name} · frame {shown} · t = {:.3} s  ({} particles, dx = {} m)",
        fluid.time(),
        fluid.fluid_count(),
        scene.dx
    );
    preview::render(
        &options.out.join("preview.png"),
        &preview::Input {
            title: &title,
            positions: fluid.positions(),
            speeds: &speeds,
            speed_scale: (2.0 * gravity.abs() * scene.column_height).sqrt(),
            walls: fluid.boundary_positions(),
            tank_min: scene.tank_min,
            tank_max: scene.tank_max,
            lid: scene.walls[1][1],
        },
    )?;
    let last = summary.frames.last().cloned();
    let front = last
        .as_ref()
        .and_then(|r| r.front_x)
        .map(|x| format!(", front x = {x:.3} m (Z = {:.3})", x / width))
        .unwrap_or_default();
    let max_error = summary
        .frames
        .iter()
        .map(|r| r.max_density_error)
        .fold(0.0, f64::max);
    output += written.elapsed();
    let times = RunTimes {
        fluid_particles: fluid.fluid_count(),
        boundary_particles: fluid.boundary_count(),
        steps: fluid.steps(),
        wall: begin.elapsed(),
        stepping,
        output,
    };
    if announce {
        let rate = fluid.fluid_count() as f64 * fluid.steps() as f64 / stepping.as_secs_f64();
        eprintln!(
            "done in {:.2} s: {} steps, largest density error {:.2} %{front}; stepping {:.2} s \
             ({:.2e} fluid particle-steps/s), output {:.2} s; wrote {}/frames ({} files), \
             walls.vtk, summary.json, preview.png",
            start.elapsed().as_secs_f64(),
            fluid.steps(),
            100.0 * max_error,
            stepping.as_secs_f64(),
            rate,
            output.as_secs_f64(),
            options.out.display(),
            frames + 1
        );
    }
    Ok(times)
}

/// Removes the frame files of an earlier run, so that the directory holds exactly this run's.
fn remove_stale_frames(dir: &Path) -> Result<(), SphCliError> {
    for entry in std::fs::read_dir(dir).map_err(|e| SphCliError::io(dir, e))? {
        let path: PathBuf = entry.map_err(|e| SphCliError::io(dir, e))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with("frame_") && (name.ends_with(".vtk") || name.ends_with(".obj")) {
            std::fs::remove_file(&path).map_err(|e| SphCliError::io(&path, e))?;
        }
    }
    Ok(())
}

/// Per-particle data of a frame.
struct ParticleData<'a, const D: usize> {
    velocities: &'a [SVector<f64, D>],
    densities: &'a [f64],
    pressures: &'a [f64],
}

fn xyz<const D: usize>(p: &SVector<f64, D>) -> [f64; 3] {
    std::array::from_fn(|a| if a < D { p[a] } else { 0.0 })
}

/// Writes `positions` as vertex cells of a legacy ASCII VTK unstructured grid, atomically, with
/// `data` as point data.
fn write_particles<const D: usize>(
    path: &Path,
    positions: &[SVector<f64, D>],
    data: Option<ParticleData<D>>,
) -> Result<(), SphCliError> {
    let n = positions.len();
    let count = u32::try_from(n).map_err(|_| {
        SphCliError::io(
            path,
            std::io::Error::other("more particles than a legacy VTK file can count"),
        )
    })?;
    let points: Vec<f64> = positions.iter().flat_map(xyz).collect();
    let mut vertices = Vec::with_capacity(2 * n);
    for i in 0..count {
        vertices.push(1);
        vertices.push(i);
    }
    let mut attributes = Attributes::new();
    if let Some(d) = data {
        let velocity: Vec<f64> = d.velocities.iter().flat_map(xyz).collect();
        attributes
            .point
            .push(Attribute::vectors("velocity").with_data(velocity));
        attributes
            .point
            .push(Attribute::scalars("density", 1).with_data(d.densities.to_vec()));
        attributes
            .point
            .push(Attribute::scalars("pressure", 1).with_data(d.pressures.to_vec()));
    }
    let vtk = Vtk {
        version: Version::new_legacy(4, 2),
        title: "hooke sph".to_string(),
        byte_order: ByteOrder::BigEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: points.into(),
            cells: Cells {
                cell_verts: VertexNumbers::Legacy {
                    num_cells: count,
                    vertices,
                },
                types: vec![CellType::Vertex; n],
            },
            data: attributes,
        }),
    };
    let mut text = String::new();
    vtk.write_legacy_ascii(&mut text)
        .map_err(|e| SphCliError::io(path, std::io::Error::other(format!("vtkio: {e}"))))?;
    Ok(crate::output::write_atomically(path, |out| {
        out.write_all(text.as_bytes())
    })?)
}
