//! The broad phase on two 160×160 sheets of 1 m, 0.5 mm apart (51,200 vertices), reach 1 mm:
//! static boxes, and boxes swept along a motion of up to 1 mm per vertex, on rayon's global pool.
//! `SHEET_HEIGHT` (m) lifts both sheets (default 0, where the lower sheet lies on a cell boundary
//! of the grid, so swept boxes straddle two layers of cells).
//!
//! Run: `cargo bench -p hooke-collision --bench broad_phase`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use hooke_collision::broad_phase::{BroadPhase, CandidatePairs, SurfaceTopology};
use nalgebra::Vector3;

type V = Vector3<f64>;

/// An n×n grid of spacing h in the plane z = `height`, vertex ids from `first`.
fn grid(n: usize, h: f64, height: f64, first: u32) -> (Vec<V>, Vec<[u32; 3]>) {
    let x = (0..n * n)
        .map(|k| V::new((k % n) as f64 * h, (k / n) as f64 * h, height))
        .collect();
    let id = |i: usize, j: usize| first + (j * n + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (x, triangles)
}

fn two_sheets(c: &mut Criterion) {
    let n = 160;
    let h = 1.0 / (n - 1) as f64;
    let height = std::env::var("SHEET_HEIGHT")
        .ok()
        .and_then(|z| z.parse().ok())
        .unwrap_or(0.0);
    let (mut x, mut triangles) = grid(n, h, height, 0);
    let (upper, upper_triangles) = grid(n, h, height + 0.0005, (n * n) as u32);
    x.extend(upper);
    triangles.extend(upper_triangles);
    // A fixed pseudo-random motion (an LCG: the same on every run).
    let mut state: u64 = 99;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let motion: Vec<V> = (0..x.len())
        .map(|_| V::new(next(), next(), next()) * 0.002)
        .collect();
    let topology = SurfaceTopology::new(x.len(), &triangles);
    let mut broad = BroadPhase::new();
    let mut out = CandidatePairs::new();
    for (name, m) in [("static", None), ("swept", Some(&motion[..]))] {
        broad.find(&topology, &x, m, 1e-3, &mut out);
        eprintln!(
            "{name}: {} point–triangle, {} edge–edge pairs",
            out.point_triangle.len(),
            out.edge_edge.len()
        );
        c.bench_function(&format!("broad phase, two 160² sheets, {name}"), |b| {
            b.iter(|| broad.find(&topology, black_box(&x), m, 1e-3, &mut out))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = two_sheets
}
criterion_main!(benches);
