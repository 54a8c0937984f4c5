//! `hooke bench --contact A.obj B.obj`: on two small sheets a fraction of d̂ apart, the pair
//! counts it reports equal a brute-force count over every point–triangle and edge–edge pair (no
//! broad phase), the smallest distance is the gap, a trial that passes one sheet through the other
//! gets a collision-free step short of the crossing, and bad input is a clear error.

use std::path::Path;
use std::process::Command;

use hooke::collision::distance::{edge_edge_distance_squared, point_triangle_distance_squared};
use nalgebra::Vector3;

const D_HAT: f64 = 1e-3;

/// Two n×n sheets on the unit square in the xz-plane, the upper `gap` (m) above the lower and
/// shifted by half a spacing, moved down by `down` (m) in the trial; as positions and triangles.
fn sheets(n: usize, gap: f64, down: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let s = 1.0 / (n - 1) as f64;
    let mut positions = Vec::new();
    for (dx, dy, dz) in [(0.0, 0.0, 0.0), (0.5 * s, gap - down, 0.5 * s)] {
        for j in 0..n {
            for i in 0..n {
                positions.push(Vector3::new(i as f64 * s + dx, dy, j as f64 * s + dz));
            }
        }
    }
    let mut triangles = Vec::new();
    for o in [0, (n * n) as u32] {
        for j in 0..n as u32 - 1 {
            for i in 0..n as u32 - 1 {
                let a = o + j * n as u32 + i;
                let (b, c) = (a + 1, a + n as u32);
                triangles.push([a, c, b]);
                triangles.push([b, c, c + 1]);
            }
        }
    }
    (positions, triangles)
}

fn write_obj(path: &Path, positions: &[Vector3<f64>], triangles: &[[u32; 3]]) {
    let mut text = String::new();
    for p in positions {
        text += &format!("v {:?} {:?} {:?}\n", p.x, p.y, p.z);
    }
    for t in triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

fn bench(a: &Path, b: &Path, json: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(["bench", "--contact"])
        .arg(a)
        .arg(b)
        .args(["--dhat", "1e-3", "--repeats", "1", "--json"])
        .arg(json)
        .output()
        .unwrap()
}

/// The record of a successful run.
fn bench_record(a: &Path, b: &Path, json: &Path) -> serde_json::Value {
    let out = bench(a, b, json);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

/// Point–triangle and edge–edge pairs sharing no vertex within d̂, by brute force.
fn brute_force_counts(x: &[Vector3<f64>], triangles: &[[u32; 3]]) -> (usize, usize) {
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let point_triangle = (0..x.len() as u32)
        .flat_map(|p| triangles.iter().map(move |t| (p, t)))
        .filter(|(p, t)| !t.contains(p))
        .filter(|(p, t)| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            point_triangle_distance_squared(&x[*p as usize], &a, &b, &c).sqrt() < D_HAT
        })
        .count();
    let mut edge_edge = 0;
    for (i, ea) in edges.iter().enumerate() {
        for eb in &edges[i + 1..] {
            if ea.iter().any(|v| eb.contains(v)) {
                continue;
            }
            let [a0, a1] = ea.map(|v| x[v as usize]);
            let [b0, b1] = eb.map(|v| x[v as usize]);
            if edge_edge_distance_squared(&a0, &a1, &b0, &b1).sqrt() < D_HAT {
                edge_edge += 1;
            }
        }
    }
    (point_triangle, edge_edge)
}

#[test]
fn pair_counts_match_brute_force_and_the_step_stops_short_of_a_crossing() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, crossing, json) = (
        dir.path().join("A.obj"),
        dir.path().join("B.obj"),
        dir.path().join("C.obj"),
        dir.path().join("out.json"),
    );
    let gap = 5e-4;
    let (x, triangles) = sheets(8, gap, 0.0);
    write_obj(&a, &x, &triangles);
    write_obj(&b, &sheets(8, gap, 4e-4).0, &triangles);
    // The upper sheet moved 1 mm down: through the lower one, 0.5 mm below it.
    write_obj(&crossing, &sheets(8, gap, 1e-3).0, &triangles);

    let record = bench_record(&a, &b, &json);
    let count = |key: &str| record[key].as_u64().unwrap() as usize;
    let (point_triangle, edge_edge) = brute_force_counts(&x, &triangles);
    assert!(point_triangle > 0 && edge_edge > 0);
    assert_eq!(count("point_triangle_pairs"), point_triangle);
    assert_eq!(count("edge_edge_pairs"), edge_edge);
    assert_eq!(count("vertices"), x.len());
    // The nearest primitives are a vertex of the upper sheet over the lower one's face: the gap
    // itself, up to the rounding of the coordinates (ε·|x|, x ≤ 1 m).
    let smallest = record["smallest_distance"].as_f64().unwrap();
    assert!(
        (smallest - gap).abs() <= 1e-14,
        "smallest distance {smallest}"
    );
    // Moving 0.4 mm of the 0.5 mm gap crosses nothing.
    assert_eq!(record["step"].as_f64(), Some(1.0));
    for stage in [
        "build_ms",
        "value_ms",
        "gradient_ms",
        "hessian_ms",
        "step_ms",
    ] {
        assert!(record[stage].as_f64().unwrap() > 0.0, "{stage}");
    }

    // Through the other sheet: the step ends before the sheets meet (at 0.5 of the move), and
    // keeps at least a tenth of the gap (the CCD's kept share).
    let record = bench_record(&a, &crossing, &json);
    let step = record["step"].as_f64().unwrap();
    assert!(step > 0.0 && step <= 0.9 * 0.5, "step {step}");
}

#[test]
fn a_trial_of_another_surface_and_a_bad_reach_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (a, other, json) = (
        dir.path().join("A.obj"),
        dir.path().join("other.obj"),
        dir.path().join("out.json"),
    );
    let (x, triangles) = sheets(4, 5e-4, 0.0);
    write_obj(&a, &x, &triangles);
    let (y, other_triangles) = sheets(5, 5e-4, 0.0);
    write_obj(&other, &y, &other_triangles);
    let out = bench(&a, &other, &json);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("not the same surface"), "{stderr}");
    assert!(!json.exists(), "no record is written");

    let out = Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(["bench", "--contact"])
        .arg(&a)
        .arg(&a)
        .args(["--dhat", "-1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--dhat"), "{stderr}");
}
