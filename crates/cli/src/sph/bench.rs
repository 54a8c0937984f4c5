//! `hooke bench --sph COUNTS`: the cost of a 2D WCSPH step against particle count, split by phase.
//!
//! The set-up ([`step_cost_column`]): for each count N, a square column of
//! about N particles (side 1 m, Δx = 1/round(√N)) in the corner of a 2 m × 1.5 m tank with open top
//! and three layers of wall particles, the parameters of docs/scenes.md §7 otherwise (h = 1.3 Δx,
//! c₀ = 10·√(2gH), α = 0.1, symplectic Euler, continuity density). Two steps are taken to warm up,
//! then `--repeats` steps are timed: wall time per step, fluid particle-steps per second, and the
//! fluid's own phase timings per step (neighbour search, density, forces, integration).
//!
//! An entry may instead name a built-in fluid scene (`hooke bench --sph 1e4,dam-break-2d`): the
//! scene is then run as `hooke run SCENE` runs it, frames and summary written (to a temporary
//! directory, removed afterwards), and reported with the wall time, the part spent stepping and
//! the part spent writing, and its fluid particle-steps per second: the rate a user meets, which
//! a step of the column above only bounds (docs/sph.md, "Speed").

use std::path::Path;
use std::time::Instant;

use hooke_sph::scenes::{ColumnInTank, WALL_LAYERS};
use hooke_sph::{Fluid, FluidParams};
use nalgebra::SVector;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};

use super::SphCliError;
use crate::output::OutputError;

/// Fewest and most particles a count may ask for.
const COUNT_RANGE: (f64, f64) = (16.0, 1e8);

/// One count's measurement; also the keys of `--json`'s records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphBenchRecord {
    /// The count asked for.
    pub requested: usize,
    /// Fluid particles (the nearest square of the count).
    pub fluid_particles: usize,
    /// Wall particles.
    pub boundary_particles: usize,
    /// Timed steps.
    pub steps: u32,
    /// Threads of the rayon pool.
    pub threads: usize,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Fluid particles × steps per second of wall time.
    pub particle_steps_per_s: f64,
    /// Neighbour search (sorting by cell, gathering) per step (ms).
    pub neighbour_search_ms: f64,
    /// Density (summation) and equation of state per step (ms).
    pub density_ms: f64,
    /// Pressure, viscosity and gravity forces per step (ms).
    pub forces_ms: f64,
    /// Step size, checks and updates per step (ms).
    pub integration_ms: f64,
}

/// One entry of `--sph`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Entry {
    /// A column of about this many fluid particles, a few steps timed.
    Count(usize),
    /// A built-in fluid scene, run whole as `hooke run` runs it.
    Scene(String),
}

/// A built-in scene's run as a user meets it; also the keys of its `--json` record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SphSceneRecord {
    /// The scene, e.g. `dam-break-2d`.
    pub scene: String,
    /// Fluid particles.
    pub fluid_particles: usize,
    /// Wall particles.
    pub boundary_particles: usize,
    /// Steps taken over the run.
    pub steps: u64,
    /// Threads of the rayon pool.
    pub threads: usize,
    /// Wall time of the run, from the fluid's construction to the last file written (s).
    pub wall_s: f64,
    /// Of which stepping (s).
    pub stepping_s: f64,
    /// Of which the frames' records and files, the summary and the preview (s).
    pub output_s: f64,
    /// Fluid particles × steps per second of the whole run's wall time.
    pub particle_steps_per_s: f64,
    /// Fluid particles × steps per second of stepping.
    pub stepping_particle_steps_per_s: f64,
}

/// Parses `--sph`'s entries: comma separated, each a particle count such as `2000` or `1e5` (a
/// leading `N=` is allowed) or a built-in fluid scene's name.
pub(crate) fn parse_entries(text: &str) -> Result<Vec<Entry>, SphCliError> {
    let bad = |reason: String| SphCliError::Argument {
        name: "sph",
        reason,
    };
    let body = text.trim().strip_prefix("N=").unwrap_or(text.trim());
    let mut counts = Vec::new();
    for part in body.split(',') {
        let part = part.trim();
        if super::is_builtin(part) {
            counts.push(Entry::Scene(part.to_string()));
            continue;
        }
        let value: f64 = part.parse().map_err(|_| {
            bad(format!(
                "{part:?} is neither a number nor a built-in fluid scene: expected particle \
                 counts such as 1e4,1e5 or a scene such as dam-break-2d"
            ))
        })?;
        if !(value.is_finite() && value >= COUNT_RANGE.0 && value <= COUNT_RANGE.1) {
            return Err(bad(format!(
                "{part} is out of range: each count must be in [{}, {:e}]",
                COUNT_RANGE.0, COUNT_RANGE.1
            )));
        }
        counts.push(Entry::Count(value.round() as usize));
    }
    Ok(counts)
}

/// Runs the built-in scene `name` as `hooke run` does, into a temporary directory.
pub(crate) fn measure_scene(name: &str) -> Result<SphSceneRecord, SphCliError> {
    let dir = tempfile::Builder::new()
        .prefix("hooke-bench-sph-")
        .tempdir()
        .map_err(|e| SphCliError::io(&std::env::temp_dir(), e))?;
    let times = super::run::run_timed(
        &super::run::FluidRunOptions {
            scene: name,
            dx: None,
            frames: None,
            frame_interval: None,
            integrator: None,
            out: dir.path(),
            quiet: true,
        },
        false,
    )?;
    let work = times.fluid_particles as f64 * times.steps as f64;
    Ok(SphSceneRecord {
        scene: name.to_string(),
        fluid_particles: times.fluid_particles,
        boundary_particles: times.boundary_particles,
        steps: times.steps,
        threads: rayon_threads(),
        wall_s: times.wall.as_secs_f64(),
        stepping_s: times.stepping.as_secs_f64(),
        output_s: times.output.as_secs_f64(),
        particle_steps_per_s: work / times.wall.as_secs_f64(),
        stepping_particle_steps_per_s: work / times.stepping.as_secs_f64(),
    })
}

/// The scenes' table `hooke bench --sph` prints.
pub(crate) fn format_scene_table(records: &[SphSceneRecord]) -> String {
    let mut s = format!(
        "{:>16} {:>7} {:>6} {:>7} {:>8} {:>10} {:>8} {:>14} {:>14}\n",
        "scene",
        "fluid",
        "walls",
        "steps",
        "wall s",
        "stepping s",
        "output s",
        "particle-st/s",
        "stepping p-s/s"
    );
    for r in records {
        s.push_str(&format!(
            "{:>16} {:>7} {:>6} {:>7} {:>8.2} {:>10.2} {:>8.2} {:>14.4e} {:>14.4e}\n",
            r.scene,
            r.fluid_particles,
            r.boundary_particles,
            r.steps,
            r.wall_s,
            r.stepping_s,
            r.output_s,
            r.particle_steps_per_s,
            r.stepping_particle_steps_per_s
        ));
    }
    s
}

/// A `--json` record: a count's or a scene's, in the order of `--sph`.
#[derive(Serialize)]
#[serde(untagged)]
enum JsonRecord {
    Count(SphBenchRecord),
    Scene(SphSceneRecord),
}

/// The step-cost benchmark's fluid: the dam break's
/// parameters on a 1 m square column of about `particles` fluid particles (Δx = 1/round(√particles),
/// at least 2 across) in a 2 × 1.5 m tank walled at the sides and bottom, with `WALL_LAYERS` layers
/// of boundary particles and the sound speed from the column's height.
fn step_cost_column(particles: usize) -> ColumnInTank<2> {
    let side = (particles as f64).sqrt().round().max(2.0);
    ColumnInTank::<2> {
        tank_min: SVector::zeros(),
        tank_max: SVector::<f64, 2>::new(2.0, 1.5),
        walls: [[true, true], [true, false]],
        column_max: SVector::<f64, 2>::new(1.0, 1.0),
        dx: 1.0 / side,
        layers: WALL_LAYERS,
        params: FluidParams {
            sound_speed: 0.0,
            ..FluidParams::default()
        },
    }
}

/// Measures one count (see the [module](self)).
///
/// With `shuffle`, the fluid particles are numbered in a fixed pseudo-random order (a Fisher-Yates
/// shuffle driven by a fixed linear congruential generator: the same order every run), as a long
/// run's mixing leaves them.
pub(crate) fn measure(
    count: usize,
    steps: u32,
    shuffle: bool,
) -> Result<SphBenchRecord, SphCliError> {
    let spec = step_cost_column(count);
    let name = format!("bench N={count}");
    let fail = |what: &str, e| SphCliError::fluid(&name, what, e);
    let mut setup = spec.build().map_err(|e| fail("setup", e))?;
    if shuffle {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for i in (1..setup.fluid_positions.len()).rev() {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let j = ((state >> 33) % (i as u64 + 1)) as usize;
            setup.fluid_positions.swap(i, j);
            if !setup.fluid_velocities.is_empty() {
                setup.fluid_velocities.swap(i, j);
            }
            if !setup.fluid_densities.is_empty() {
                setup.fluid_densities.swap(i, j);
            }
        }
    }
    let mut fluid = Fluid::new(setup).map_err(|e| fail("setup", e))?;
    for _ in 0..2 {
        fluid.step().map_err(|e| fail("warm-up step", e))?;
    }
    fluid.reset_timings();
    let start = Instant::now();
    for _ in 0..steps {
        fluid.step().map_err(|e| fail("timed step", e))?;
    }
    let per = start.elapsed().as_secs_f64() / f64::from(steps);
    let t = fluid.timings();
    let ms = |d: std::time::Duration| 1e3 * d.as_secs_f64() / f64::from(steps);
    Ok(SphBenchRecord {
        requested: count,
        fluid_particles: fluid.fluid_count(),
        boundary_particles: fluid.boundary_count(),
        steps,
        threads: rayon_threads(),
        ms_per_step: 1e3 * per,
        particle_steps_per_s: fluid.fluid_count() as f64 / per,
        neighbour_search_ms: ms(t.neighbour_search),
        density_ms: ms(t.density),
        forces_ms: ms(t.forces),
        integration_ms: ms(t.integration),
    })
}

/// The threads the fluid's parallel loops use (rayon's global pool).
fn rayon_threads() -> usize {
    rayon::current_num_threads()
}

/// The table `hooke bench --sph` prints.
pub(crate) fn format_table(records: &[SphBenchRecord]) -> String {
    let mut s = format!(
        "{:>10} {:>9} {:>11} {:>14} {:>10} {:>10} {:>10} {:>10}\n",
        "N",
        "walls",
        "ms/step",
        "particle-st/s",
        "search ms",
        "density ms",
        "forces ms",
        "update ms"
    );
    for r in records {
        s.push_str(&format!(
            "{:>10} {:>9} {:>11.3} {:>14.4e} {:>10.3} {:>10.3} {:>10.3} {:>10.3}\n",
            r.fluid_particles,
            r.boundary_particles,
            r.ms_per_step,
            r.particle_steps_per_s,
            r.neighbour_search_ms,
            r.density_ms,
            r.forces_ms,
            r.integration_ms
        ));
    }
    s
}

/// What `hooke bench --sph` asks for.
pub(crate) struct SphBenchOptions<'a> {
    /// `--sph`'s text.
    pub counts: &'a str,
    /// `--repeats`: timed steps per count.
    pub steps: usize,
    /// `--json FILE`.
    pub json: Option<&'a Path>,
    /// `--plot FILE.png`.
    pub plot: Option<&'a Path>,
    /// `--quiet`.
    pub quiet: bool,
    /// `--sph-shuffle`: the fluid particles numbered in a random order (see [`measure`]).
    pub shuffle: bool,
}

impl<'a> SphBenchOptions<'a> {
    /// The options of `hooke bench --sph` (the counts are empty without `--sph`).
    pub(crate) fn from_args(args: &'a crate::bench::BenchArgs) -> Self {
        SphBenchOptions {
            counts: args.sph.as_deref().unwrap_or(""),
            steps: args.repeats,
            json: args.json.as_deref(),
            plot: args.plot.as_deref(),
            quiet: args.quiet,
            shuffle: args.sph_shuffle,
        }
    }
}

/// Runs `hooke bench --sph`: measures every count and scene, prints the tables, writes the files
/// asked for (`--json`: one record per entry, in order; `--plot`: the counts).
pub(crate) fn run(options: &SphBenchOptions) -> Result<(), SphCliError> {
    // What a killed earlier run left of the files this one writes.
    let outputs: Vec<&Path> = [options.json, options.plot].into_iter().flatten().collect();
    crate::output::remove_leftovers_of(&outputs)?;
    let entries = parse_entries(options.counts)?;
    let steps = u32::try_from(options.steps)
        .ok()
        .filter(|&s| s >= 1)
        .ok_or_else(|| SphCliError::Argument {
            name: "repeats",
            reason: "with --sph: the timed steps per count, at least 1".into(),
        })?;
    let begin = Instant::now();
    let mut measured = Vec::new();
    for entry in entries {
        let at = begin.elapsed().as_secs_f64();
        match entry {
            Entry::Count(count) => {
                if !options.quiet {
                    eprintln!("[{at:7.1} s] sph N={count}: {steps} timed steps");
                }
                measured.push(JsonRecord::Count(measure(count, steps, options.shuffle)?));
            }
            Entry::Scene(name) => {
                if !options.quiet {
                    eprintln!("[{at:7.1} s] sph {name}: the whole scene, as hooke run runs it");
                }
                measured.push(JsonRecord::Scene(measure_scene(&name)?));
            }
        }
    }
    let records: Vec<SphBenchRecord> = measured
        .iter()
        .filter_map(|m| match m {
            JsonRecord::Count(r) => Some(r.clone()),
            JsonRecord::Scene(_) => None,
        })
        .collect();
    let scenes: Vec<SphSceneRecord> = measured
        .iter()
        .filter_map(|m| match m {
            JsonRecord::Scene(r) => Some(r.clone()),
            JsonRecord::Count(_) => None,
        })
        .collect();
    if !records.is_empty() {
        println!(
            "2D WCSPH step cost (column in a tank, the dam break's parameters (docs/sph.md)){}, {} thread(s), {steps} timed step(s) after 2 warm-up steps; phases as the fluid times them",
            if options.shuffle {
                ", particles numbered at random"
            } else {
                ""
            },
            rayon_threads()
        );
        print!("{}", format_table(&records));
    }
    if !scenes.is_empty() {
        println!(
            "Fluid scenes run as `hooke run` runs them (frames written), {} thread(s)",
            rayon_threads()
        );
        print!("{}", format_scene_table(&scenes));
    }
    if let Some(path) = options.json {
        create_parent(path)?;
        crate::output::write_json_atomically(path, &measured, true)?;
    }
    if let (Some(path), false) = (options.plot, records.is_empty()) {
        create_parent(path)?;
        plot(path, &records)?;
    }
    Ok(())
}

fn create_parent(path: &Path) -> Result<(), SphCliError> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).map_err(|e| SphCliError::io(dir, e))
        }
        _ => Ok(()),
    }
}

const FONT: &str = "sans-serif";

fn plot_error(path: &Path, e: impl std::fmt::Display) -> SphCliError {
    SphCliError::Output(OutputError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Time per step and per phase against fluid particles, on log axes, as a PNG written
/// atomically.
fn plot(path: &Path, records: &[SphBenchRecord]) -> Result<(), SphCliError> {
    // Registers the embedded font (shared with the preview).
    let text = super::preview::font_ready();
    const SIZE: (u32, u32) = (900, 600);
    let mut pixels = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    type Column = fn(&SphBenchRecord) -> f64;
    let series: [(&str, Column, RGBColor); 5] = [
        ("step", |r| r.ms_per_step, RGBColor(30, 32, 36)),
        (
            "neighbour search",
            |r| r.neighbour_search_ms,
            RGBColor(31, 119, 180),
        ),
        ("density", |r| r.density_ms, RGBColor(44, 160, 44)),
        ("forces", |r| r.forces_ms, RGBColor(214, 39, 40)),
        ("integration", |r| r.integration_ms, RGBColor(255, 127, 14)),
    ];
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let xs: Vec<f64> = records.iter().map(|r| r.fluid_particles as f64).collect();
    let ys: Vec<f64> = records
        .iter()
        .flat_map(|r| series.iter().map(move |(_, f, _)| f(r)))
        .filter(|&v| positive(v))
        .collect();
    // Axes fitted to the data, not widened to whole decades.
    let range = |values: &[f64]| crate::bench::fitted_log_range(values.iter().copied());
    let mut draw = || -> Result<(), String> {
        let area = BitMapBackend::with_buffer(&mut pixels, SIZE).into_drawing_area();
        area.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut builder = ChartBuilder::on(&area);
        builder
            .margin(12)
            .x_label_area_size(if text { 45 } else { 5 })
            .y_label_area_size(if text { 70 } else { 5 });
        if text {
            builder.caption(
                format!(
                    "2D WCSPH: time per step against particles ({} threads)",
                    rayon_threads()
                ),
                (FONT, 20),
            );
        }
        let mut chart = builder
            .build_cartesian_2d(
                crate::bench::log_axis(range(&xs)),
                crate::bench::log_axis(range(&ys)),
            )
            .map_err(|e| e.to_string())?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc("fluid particles")
                .y_desc("wall time per step (ms)")
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 15))
                .x_label_formatter(&|v| crate::bench::log_tick_label(*v))
                .y_label_formatter(&|v| crate::bench::log_tick_label(*v));
        } else {
            mesh.disable_x_mesh().disable_y_mesh();
        }
        mesh.draw().map_err(|e| e.to_string())?;
        for (name, column, color) in series {
            let points: Vec<(f64, f64)> = records
                .iter()
                .map(|r| (r.fluid_particles as f64, column(r)))
                .filter(|&(_, y)| positive(y))
                .collect();
            let line = chart
                .draw_series(LineSeries::new(
                    points.iter().copied(),
                    color.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?;
            if text {
                line.label(name).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            }
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(|e| e.to_string())?;
        }
        if text {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .label_font((FONT, 13))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())?;
        }
        area.present().map_err(|e| e.to_string())
    };
    draw().map_err(|e| plot_error(path, e))?;
    Ok(crate::output::write_png(path, &pixels, SIZE.0, SIZE.1)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_parse() {
        assert_eq!(
            parse_entries("1e4,1e5").unwrap(),
            vec![Entry::Count(10_000), Entry::Count(100_000)]
        );
        assert_eq!(parse_entries("N=2000").unwrap(), vec![Entry::Count(2000)]);
        assert_eq!(
            parse_entries("400, dam-break-2d").unwrap(),
            vec![Entry::Count(400), Entry::Scene("dam-break-2d".into())]
        );
        for bad in ["", "abc", "1e9", "5", "1e4,-3", "nan", "dam-break-4d"] {
            let e = parse_entries(bad).unwrap_err().to_string();
            assert!(e.contains("--sph"), "{bad}: {e}");
        }
    }

    #[test]
    fn a_small_count_measures() {
        let r = measure(400, 1, false).unwrap();
        assert_eq!(r.fluid_particles, 400);
        assert!(r.ms_per_step > 0.0 && r.particle_steps_per_s > 0.0);
        let walls = r.boundary_particles;
        assert!(format_table(&[r]).lines().count() == 2);
        // Shuffled: the same particles, measured alike.
        let shuffled = measure(400, 1, true).unwrap();
        assert_eq!(shuffled.fluid_particles, 400);
        assert_eq!(shuffled.boundary_particles, walls);
        assert!(shuffled.ms_per_step > 0.0);
    }
}
