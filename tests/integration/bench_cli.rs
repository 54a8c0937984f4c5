//! `hooke bench` end to end on cloth-10: the JSON and CSV schema, and the errors of the records
//! recomputed here, independently of the library, from the OBJ frames the command writes
//! (x_n, y, x* and each solver's x) and the scene's springs and masses.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use hooke_cli::bench::COLUMNS;
use serde_json::Value;

/// Solver settings of the run: one PD, two Newton and one linearised run.
const SOLVERS: &[&str] = &["pd:1,3", "newton:2", "linearized-cg"];
const RUNS: &[(&str, &str)] = &[
    ("pd", "1"),
    ("pd", "3"),
    ("newton", "2"),
    ("linearized-cg", "default"),
];

/// Run `hooke bench cloth-10` into `dir` (report.json, report.csv, frames/).
fn bench_into(dir: &Path) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hooke"));
    cmd.args(["bench", "cloth-10", "--repeats", "1", "--no-cache", "-q"]);
    for s in SOLVERS {
        cmd.args(["--solver", s]);
    }
    cmd.arg("--json")
        .arg(dir.join("report.json"))
        .arg("--csv")
        .arg(dir.join("report.csv"))
        .arg("--frames")
        .arg(dir.join("frames"));
    let out = cmd.output().expect("run hooke");
    assert!(
        out.status.success(),
        "hooke bench failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = String::from_utf8_lossy(&out.stdout);
    for (solver, setting) in RUNS {
        assert!(
            table
                .lines()
                .any(|l| l.split_whitespace().take(2).eq([*solver, *setting])),
            "no table line for {solver} {setting} in:\n{table}"
        );
    }
}

fn records(dir: &Path) -> Vec<serde_json::Map<String, Value>> {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    let json: Value = serde_json::from_str(&text).unwrap();
    json.as_array()
        .expect("a JSON array")
        .iter()
        .map(|r| r.as_object().expect("records are objects").clone())
        .collect()
}

#[test]
fn json_and_csv_records_have_exactly_the_documented_keys_and_types() {
    let dir = tempfile::tempdir().unwrap();
    bench_into(dir.path());
    let records = records(dir.path());
    assert_eq!(records.len(), RUNS.len());
    let expected: BTreeSet<&str> = [
        "scene",
        "solver",
        "setting",
        "iterations",
        "wall_time_s",
        "factor_time_s",
        "objective_error",
        "position_error",
        "residual",
    ]
    .into_iter()
    .collect();
    assert_eq!(COLUMNS.iter().copied().collect::<BTreeSet<_>>(), expected);
    for (r, (solver, setting)) in records.iter().zip(RUNS) {
        let keys: BTreeSet<&str> = r.keys().map(String::as_str).collect();
        assert_eq!(keys, expected, "keys of {r:?}");
        assert_eq!(r["scene"], "cloth-10");
        assert_eq!(r["solver"], *solver);
        assert_eq!(r["setting"], *setting);
        assert!(r["iterations"].is_u64(), "iterations of {solver}: {r:?}");
        for key in [
            "wall_time_s",
            "objective_error",
            "position_error",
            "residual",
        ] {
            assert!(r[key].is_f64(), "{key} of {solver} {setting}: {:?}", r[key]);
        }
        assert!(r["wall_time_s"].as_f64().unwrap() > 0.0);
        // PD and Newton report a factorisation time; the linearised step factors nothing: null.
        if *solver == "linearized-cg" {
            assert!(r["factor_time_s"].is_null(), "{r:?}");
        } else {
            assert!(r["factor_time_s"].as_f64().unwrap() > 0.0, "{r:?}");
        }
    }
    assert_eq!(records[0]["iterations"], 1);
    assert_eq!(records[1]["iterations"], 3);
    assert_eq!(records[2]["iterations"], 2);

    // The CSV holds the same values, in the same column order as COLUMNS.
    let csv = std::fs::read_to_string(dir.path().join("report.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), COLUMNS.join(","));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), records.len());
    for (row, r) in rows.iter().zip(&records) {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields.len(), COLUMNS.len(), "{row}");
        for (field, key) in fields.iter().zip(COLUMNS) {
            match &r[key] {
                Value::Null => assert_eq!(*field, "", "{key} in {row}"),
                Value::String(s) => assert_eq!(field, s, "{key}"),
                // serde_json's default float parser may be off by one unit in the last place
                // (exact parsing is its `float_roundtrip` feature): compare to 2 ulp.
                Value::Number(n) => {
                    let (a, b) = (field.parse::<f64>().unwrap(), n.as_f64().unwrap());
                    assert!(
                        (a - b).abs() <= 2.0 * f64::EPSILON * b.abs(),
                        "{key} in {row}: the CSV ({a:e}) and the JSON ({b:e}) must hold the same number"
                    )
                }
                other => panic!("unexpected JSON value {other:?}"),
            }
        }
    }
}

/// Vertex positions of an OBJ file, parsed here (not by the library).
fn read_vertices(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|v| v.parse().unwrap()).collect();
            [c[0], c[1], c[2]]
        })
        .collect()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Φ, the force residual and the free vertices of cloth-10's step, written out from
/// docs/model.md §6.4.
struct Step {
    masses: Vec<f64>,
    springs: Vec<(usize, usize, f64, f64)>,
    free: Vec<usize>,
    h: f64,
    y: Vec<[f64; 3]>,
}

impl Step {
    /// Φ(x) = ½ Σ_free m |x − y|² + h² Σ ½ k (|r| − l)².
    fn phi(&self, x: &[[f64; 3]]) -> f64 {
        let inertia: f64 = self
            .free
            .iter()
            .map(|&v| 0.5 * self.masses[v] * norm(sub(x[v], self.y[v])).powi(2))
            .sum();
        let elastic: f64 = self
            .springs
            .iter()
            .map(|&(i, j, k, l)| 0.5 * k * (norm(sub(x[i], x[j])) - l).powi(2))
            .sum();
        inertia + self.h * self.h * elastic
    }

    /// |M(x − y) − h² f(x)| over the free DOFs.
    fn residual(&self, x: &[[f64; 3]]) -> f64 {
        let mut f = vec![[0.0; 3]; x.len()];
        for &(i, j, k, l) in &self.springs {
            let r = sub(x[i], x[j]);
            let len = norm(r);
            for a in 0..3 {
                let fi = -k * (len - l) * r[a] / len;
                f[i][a] += fi;
                f[j][a] -= fi;
            }
        }
        self.free
            .iter()
            .map(|&v| {
                let g: Vec<f64> = (0..3)
                    .map(|a| self.masses[v] * (x[v][a] - self.y[v][a]) - self.h * self.h * f[v][a])
                    .collect();
                g.iter().map(|c| c * c).sum::<f64>()
            })
            .sum::<f64>()
            .sqrt()
    }
}

#[test]
fn errors_in_the_records_match_errors_recomputed_from_the_frames() {
    let dir = tempfile::tempdir().unwrap();
    bench_into(dir.path());
    let frames = dir.path().join("frames");
    let x_n = read_vertices(&frames.join("x_n.obj"));
    let y = read_vertices(&frames.join("y.obj"));
    let x_star = read_vertices(&frames.join("x_star.obj"));
    assert_eq!(x_n.len(), 100);

    let setup = hooke::sim::scenes::cloth(10, false).unwrap();
    let mesh = setup.scene.mesh();
    let pinned = [0usize, 9];
    let step = Step {
        masses: mesh.masses().to_vec(),
        springs: mesh
            .springs()
            .iter()
            .map(|s| (s.i as usize, s.j as usize, s.stiffness, s.rest_length))
            .collect(),
        free: (0..100).filter(|v| !pinned.contains(v)).collect(),
        h: setup.scene.time_step(),
        y: y.clone(),
    };
    // The reference solves the step: its residual is at Newton's 1e-10 (relative) or below.
    let r0 = step.residual(&y);
    assert!(
        step.residual(&x_star) <= 1e-9 * r0,
        "x* is not the solution: residual {:e} of {r0:e}",
        step.residual(&x_star)
    );
    let phi_star = step.phi(&x_star);
    let gap = step.phi(&y) - phi_star;
    assert!(gap > 0.0, "Φ(y) − Φ* = {gap:e}");
    let step_length = step
        .free
        .iter()
        .map(|&v| norm(sub(x_star[v], x_n[v])).powi(2))
        .sum::<f64>()
        .sqrt();

    for r in records(dir.path()) {
        let name = format!(
            "{}-{}.obj",
            r["solver"].as_str().unwrap(),
            r["setting"].as_str().unwrap()
        );
        let x = read_vertices(&frames.join(&name));
        for &p in &pinned {
            assert_eq!(x[p], x_n[p], "{name}: pinned vertex {p} moved");
        }
        let position = step
            .free
            .iter()
            .map(|&v| norm(sub(x[v], x_star[v])).powi(2))
            .sum::<f64>()
            .sqrt()
            / step_length;
        // Φ(x) − Φ* by plain subtraction: its round-off is ~ε Φ / (Φ(y) − Φ*), far below the
        // tolerance for cloth-10.
        let objective = (step.phi(&x) - phi_star) / gap;
        let residual = step.residual(&x) / r0;
        for (key, mine) in [
            ("position_error", position),
            ("objective_error", objective),
            ("residual", residual),
        ] {
            let reported = r[key].as_f64().unwrap();
            assert!(
                (reported - mine).abs() <= 1e-9 + 1e-7 * mine.abs(),
                "{name}: {key} reported {reported:e}, recomputed {mine:e}"
            );
        }
    }
}

#[test]
fn bad_arguments_exit_1_with_a_message() {
    for (args, needle) in [
        (
            &["bench", "cloth-10", "--solver", "pd:0"][..],
            "iteration count",
        ),
        (
            &["bench", "cloth-10", "--solver", "qr:3"][..],
            "unknown solver",
        ),
        (&["bench", "no-such-scene"][..], "unknown scene"),
        (&["bench", "--sweep", "M=3"][..], "invalid --sweep"),
        (&["bench", "seed-2d"][..], "2D mesh"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
            .args(args)
            .args(["--no-cache", "-q"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
}

#[test]
fn bench_help_names_every_solver_spec() {
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(["bench", "--help"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for kind in hooke_cli::bench::SolverKind::ALL {
        let name = kind.name();
        // As a spec (`name:` or `name,`/`.` when it takes no values), not as a prefix of another.
        assert!(
            [":", ",", "."]
                .iter()
                .any(|end| help.contains(&format!(" {name}{end}"))),
            "`hooke bench --help` does not name {name}:\n{help}"
        );
    }
}

/// `--export-system DIR` writes every file of the step's systems and runs no solver (the files'
/// contents are checked against the in-memory matrices in hooke-cli's unit test).
#[test]
fn export_system_writes_the_step_systems() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("cloth-10");
    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(["bench", "cloth-10", "--export-system"])
        .arg(&target)
        .args(["--no-cache", "-q"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in hooke_cli::bench::EXPORT_FILES {
        assert!(target.join(name).is_file(), "{name} missing");
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("cloth-10: 294 unknowns"), "{stdout}");
    assert!(!stdout.contains("step ms"), "no solver runs: {stdout}");
    let readme: Value =
        serde_json::from_str(&std::fs::read_to_string(target.join("README.json")).unwrap())
            .unwrap();
    assert_eq!(readme["unknowns"], 294);
}
