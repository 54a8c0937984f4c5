//! The report as text: the table on stdout, JSON and CSV files (written atomically).

use std::io::Write;
use std::path::Path;

use crate::bench::{BenchError, BenchProblem, HardOutcome, HardResult, Outcome, Record, SweepRow};
use crate::mesh::io::{save_obj, Frame};

/// The column names of the JSON records and the CSV header, in order.
pub const COLUMNS: [&str; 9] = [
    "scene",
    "solver",
    "setting",
    "iterations",
    "wall_time_s",
    "factor_time_s",
    "objective_error",
    "position_error",
    "residual",
];

fn output_error(path: &Path, e: impl std::fmt::Display) -> BenchError {
    BenchError::Output {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// Create the directory `path` will be written in, if missing.
pub(crate) fn create_parent(path: &Path) -> Result<(), BenchError> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).map_err(|e| output_error(path, e))
        }
        _ => Ok(()),
    }
}

/// [`hooke_mesh::io::write_atomically`] into a created directory, with its error as an output
/// error.
fn write_file(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), BenchError> {
    create_parent(path)?;
    hooke_mesh::io::write_atomically(path, write).map_err(|e| match e {
        hooke_mesh::MeshError::Io { source, .. } => output_error(path, source),
        e => output_error(path, e),
    })
}

/// Write `records` as a JSON array (keys as [`Record`]'s fields, `null` where not computed; a
/// non-finite number is written as `null` too).
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn write_json(path: &Path, records: &[Record]) -> Result<(), BenchError> {
    write_serialized(path, records)
}

/// Write any report as pretty JSON, atomically.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub(crate) fn write_serialized(
    path: &Path,
    value: &(impl serde::Serialize + ?Sized),
) -> Result<(), BenchError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| output_error(path, e))?;
    write_file(path, |out| writeln!(out, "{text}"))
}

/// Write `records` as CSV: a header with the JSON keys, one line per record, empty fields where
/// not computed, numbers in Rust's shortest round-trip form.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn write_csv(path: &Path, records: &[Record]) -> Result<(), BenchError> {
    let number = |v: Option<f64>| match v {
        Some(v) if v.is_finite() => format!("{v:?}"),
        _ => String::new(),
    };
    write_file(path, |out| {
        let mut writer = csv::Writer::from_writer(out);
        writer.write_record(COLUMNS)?;
        for r in records {
            writer.write_record([
                r.scene.clone(),
                r.solver.clone(),
                r.setting.clone(),
                r.iterations.map(|k| k.to_string()).unwrap_or_default(),
                number(r.wall_time_s),
                number(r.factor_time_s),
                number(r.objective_error),
                number(r.position_error),
                number(r.residual),
            ])?;
        }
        writer.flush()
    })
}

/// Read records written by [`write_csv`] (by this bench or by another implementation writing the
/// same columns, [`COLUMNS`], in any order; empty fields are absent values).
///
/// # Errors
/// [`BenchError::Output`] naming the file if it cannot be read, lacks a column, or has a field
/// that is not of its column's type.
pub fn read_csv(path: &Path) -> Result<Vec<Record>, BenchError> {
    let mut reader = csv::Reader::from_path(path).map_err(|e| output_error(path, e))?;
    let header = reader.headers().map_err(|e| output_error(path, e))?.clone();
    if let Some(missing) = COLUMNS.iter().find(|c| !header.iter().any(|h| h == **c)) {
        return Err(output_error(
            path,
            format!(
                "no column {missing:?} (the bench's CSV columns are {})",
                COLUMNS.join(",")
            ),
        ));
    }
    reader
        .deserialize()
        .collect::<Result<Vec<Record>, _>>()
        .map_err(|e| output_error(path, e))
}

fn sci(v: Option<f64>) -> String {
    match v {
        Some(v) => format!("{v:.2e}"),
        None => "-".into(),
    }
}

fn ms(v: Option<f64>) -> String {
    match v {
        Some(v) => format!("{:.3}", v * 1e3),
        None => "-".into(),
    }
}

/// The report table: one line per outcome, with a note column for failures and remarks.
pub fn format_table(outcomes: &[Outcome]) -> String {
    let mut s = format!(
        "{:<18} {:>8} {:>6} {:>11} {:>11} {:>10} {:>10} {:>10}  note\n",
        "solver", "setting", "iters", "step ms", "factor ms", "obj. err", "pos. err", "residual"
    );
    for o in outcomes {
        let r = &o.record;
        s += &format!(
            "{:<18} {:>8} {:>6} {:>11} {:>11} {:>10} {:>10} {:>10}  {}\n",
            r.solver,
            r.setting,
            r.iterations.map_or("-".into(), |k| k.to_string()),
            ms(r.wall_time_s),
            ms(r.factor_time_s),
            sci(r.objective_error),
            sci(r.position_error),
            sci(r.residual),
            o.note.as_deref().unwrap_or("")
        );
    }
    s
}

/// The sweep table: one line per size and solver setting, with the process's peak memory after
/// that size.
pub fn format_sweep_table(rows: &[SweepRow]) -> String {
    let mut s = format!(
        "{:<12} {:>9} {:>18} {:>8} {:>6} {:>11} {:>11} {:>10} {:>10} {:>10} {:>9}  note\n",
        "scene",
        "vertices",
        "solver",
        "setting",
        "iters",
        "step ms",
        "factor ms",
        "obj. err",
        "pos. err",
        "residual",
        "peak MB"
    );
    for row in rows {
        let r = &row.outcome.record;
        s += &format!(
            "{:<12} {:>9} {:>18} {:>8} {:>6} {:>11} {:>11} {:>10} {:>10} {:>10} {:>9}  {}\n",
            r.scene,
            row.vertices,
            r.solver,
            r.setting,
            r.iterations.map_or("-".into(), |k| k.to_string()),
            ms(r.wall_time_s),
            ms(r.factor_time_s),
            sci(r.objective_error),
            sci(r.position_error),
            sci(r.residual),
            row.peak_memory_bytes
                .map_or("-".into(), |b| format!("{:.0}", b as f64 / 1e6)),
            row.outcome.note.as_deref().unwrap_or("")
        );
    }
    s
}

/// The hard-case matrix (cases down, integrators across; `-` where a pair was not run), then one
/// line per run with its [`RunStats`](crate::bench::RunStats), then (if any case has self-contact
/// or a sphere) one line per run of such a case with the exact surface checks, then one line per
/// run that did not finish, with its error.
pub fn format_hard_cases(results: &[HardResult]) -> String {
    let mut integrators: Vec<&str> = Vec::new();
    let mut cases: Vec<&str> = Vec::new();
    for r in results {
        if !integrators.contains(&r.integrator.as_str()) {
            integrators.push(&r.integrator);
        }
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    const W: usize = 30;
    let mut s = format!("{}\n", crate::bench::HARD_CASE_OVERRIDES);
    s += &format!("{:<20}", "case");
    for i in &integrators {
        s += &format!(" | {i:<W$}");
    }
    s += "\n";
    let mut details = String::new();
    for c in &cases {
        s += &format!("{c:<20}");
        for i in &integrators {
            let cell = match results.iter().find(|r| r.case == *c && r.integrator == *i) {
                Some(r) => {
                    let cell = match &r.outcome {
                        HardOutcome::Ok {
                            energy_drift,
                            max_stretch,
                            unconverged,
                            max_pieces,
                        } => {
                            let mark = if *unconverged > 0 { "*" } else { " " };
                            let pieces = if *max_pieces > 1 {
                                format!(" x{max_pieces}")
                            } else {
                                String::new()
                            };
                            format!("ok{mark} dE {energy_drift:+.1e} s {max_stretch:.2}{pieces}")
                        }
                        HardOutcome::Unsupported { error } => {
                            details += &format!("{c}, {i}: unsupported: {error}\n");
                            "unsupported".to_string()
                        }
                        HardOutcome::Refused { error } => {
                            details += &format!("{c}, {i}: refused: {error}\n");
                            "refused".to_string()
                        }
                        HardOutcome::Failed {
                            frame,
                            error,
                            max_stretch,
                        } => {
                            details += &format!("{c}, {i}: failed at frame {frame}: {error}\n");
                            format!("FAILED @{frame} s {max_stretch:.2}")
                        }
                    };
                    format!("{cell} {:.1}s", r.wall_time_s)
                }
                None => "-".into(),
            };
            s += &format!(" | {cell:<W$}");
        }
        s += "\n";
    }
    s += &format_run_stats(results);
    s += &format_surface_checks(results);
    if !details.is_empty() {
        s += "\n";
        s += &details;
    }
    s
}

/// One line per run of [`RunStats`](crate::bench::RunStats): frames converged of frames
/// finished, the largest energy change of one frame and the total change (J), and the deepest
/// penetration into an obstacle (m, ≤ 0; 0 when nothing went inside). `-` where no frame finished.
fn format_run_stats(results: &[HardResult]) -> String {
    let mut s = format!(
        "\n{:<20} | {:<18} | {:<11} | {:>9} | {:>13} | {:>13} | {:>14}\n",
        "case",
        "integrator",
        "outcome",
        "converged",
        "max dE/frame J",
        "dE total J",
        "penetration m"
    );
    for r in results {
        let st = &r.stats;
        let (step, total) = match st.max_energy_step {
            Some(step) => (format!("{step:+.3e}"), format!("{:+.3e}", st.energy_change)),
            None => ("-".into(), "-".into()),
        };
        s += &format!(
            "{:<20} | {:<18} | {:<11} | {:>9} | {step:>13} | {total:>13} | {:>14.3e}\n",
            r.case,
            r.integrator,
            r.outcome.label(),
            format!("{}/{}", st.converged, st.frames),
            st.deepest_penetration
        );
    }
    s
}

/// One line per run of a case with self-contact or a sphere obstacle: the frames in which the
/// surface intersected itself and in which a triangle had a point inside a sphere (each of the
/// frames finished; both must be 0), the smallest self-contact distance over the run and the
/// scene's d̂ (m; `inf` when no pair was a candidate, [`RunStats`](crate::bench::RunStats)), and
/// the most point–triangle and edge–edge pairs within d̂ in one frame. `-` where the check does not
/// apply or no frame finished. Empty if no run has such a case.
fn format_surface_checks(results: &[HardResult]) -> String {
    let checked: Vec<&HardResult> = results
        .iter()
        .filter(|r| {
            r.stats.self_intersecting_frames.is_some() || r.stats.frames_inside_sphere.is_some()
        })
        .collect();
    if checked.is_empty() {
        return String::new();
    }
    let mut s = format!(
        "\n{:<20} | {:<18} | {:<11} | {:>8} | {:>11} | {:>11} | {:>12} | {:>10} | {:>8} | {:>8}\n",
        "case",
        "integrator",
        "outcome",
        "frames",
        "self-isect",
        "in sphere",
        "min dist m",
        "dhat m",
        "max pt",
        "max ee"
    );
    for r in checked {
        let st = &r.stats;
        let finished = st.frames > 0;
        let count = |v: Option<usize>| match v {
            Some(v) if finished => v.to_string(),
            _ => "-".into(),
        };
        let length = |v: Option<f64>| match v {
            Some(v) => format!("{v:.3e}"),
            None => "-".into(),
        };
        s += &format!(
            "{:<20} | {:<18} | {:<11} | {:>8} | {:>11} | {:>11} | {:>12} | {:>10} | {:>8} | {:>8}\n",
            r.case,
            r.integrator,
            r.outcome.label(),
            st.frames,
            count(st.self_intersecting_frames),
            count(st.frames_inside_sphere),
            length(st.smallest_self_distance),
            length(st.self_contact_reach),
            count(st.most_point_triangle_pairs),
            count(st.most_edge_edge_pairs)
        );
    }
    s
}

/// The OBJ file name of an outcome's positions in [`write_frames`]: `SOLVER-SETTING.obj`.
pub fn frame_file_name(record: &Record) -> String {
    format!("{}-{}.obj", record.solver, record.setting)
}

/// Write the step's positions as OBJ frames (vertex order of the scene, coordinates written so
/// that they read back bit for bit) into `dir`: `x_n.obj` (the start state), `y.obj` (the inertial
/// target and initial guess), `x_star.obj` (the reference, if computed), and one
/// [`frame_file_name`] per outcome that produced positions.
///
/// # Errors
/// [`BenchError::Output`] naming the file.
pub fn write_frames(
    dir: &Path,
    problem: &BenchProblem,
    outcomes: &[Outcome],
) -> Result<(), BenchError> {
    std::fs::create_dir_all(dir).map_err(|e| output_error(dir, e))?;
    let triangles = problem.scene.mesh().triangles();
    let save = |name: &str, positions: &[nalgebra::Vector3<f64>]| {
        let path = dir.join(name);
        let frame = Frame {
            triangles,
            ..Frame::points(positions)
        };
        save_obj(&path, &frame).map_err(|e| output_error(&path, e))
    };
    save("x_n.obj", &problem.start.positions)?;
    save("y.obj", &problem.y)?;
    if let Some(x) = problem.x_star() {
        save("x_star.obj", x)?;
    }
    for o in outcomes.iter().filter(|o| !o.positions.is_empty()) {
        save(&frame_file_name(&o.record), &o.positions)?;
    }
    Ok(())
}
