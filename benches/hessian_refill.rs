//! Refilling the values of the backward Euler Hessian M + h² ∇²E of cloth-320 (102,400 vertices,
//! 611,202 springs, pins 0 and 319) in its fixed pattern, against the memory limit: a plain streaming
//! write of a value array of the same length, measured in the same run.
//!
//! The target is refill ≤ 2 × stream, single-threaded. Also measured: the 2-thread refill (rayon's
//! global pool) and, reported apart, building the pattern and scatter map once.
//!
//! Run: `cargo bench --bench hessian_refill` (a benchmark of the root package). Divide a refill
//! time by the spring count printed at start-up for ns per spring.

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hooke_assembly::{Definiteness, FreeDofs, HessianParams, HessianPattern};
use hooke_mesh::generators::cloth;
use nalgebra::Vector3;

fn refill(c: &mut Criterion) {
    let mesh = cloth(320, 1e3).expect("cloth-320");
    let n = mesh.vertex_count();
    let springs = mesh.springs();
    // A state away from rest, so every spring has a generic direction and stretch.
    let x: Vec<Vector3<f64>> = mesh
        .positions()
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let k = k as f64;
            p + Vector3::new((k * 0.37).sin(), (k * 1.11).cos(), (k * 2.3).sin()) * 1e-3
        })
        .collect();
    let free = FreeDofs::new(n, &[0, 319]).expect("pins in range");
    let pattern = HessianPattern::<3>::new(n, springs, Some(&free));
    let mut values = pattern.new_values();
    let mut workspace = pattern.workspace();
    eprintln!(
        "cloth-320: {n} vertices, {} springs, {} DOFs, {} stored values ({:.1} MB)",
        springs.len(),
        pattern.dof_count(),
        pattern.nnz(),
        pattern.nnz() as f64 * 8e-6
    );

    interleaved(
        &pattern,
        springs,
        &x,
        mesh.masses(),
        &mut workspace,
        &mut values,
    );

    let mut group = c.benchmark_group("hessian_refill_cloth320");
    group.sample_size(20);
    group.throughput(Throughput::Elements(springs.len() as u64));
    group.bench_function("stream_write", |b| {
        b.iter(|| {
            let fill = black_box(1.5);
            for v in values.iter_mut() {
                *v = fill;
            }
            black_box(&mut values);
        })
    });
    for (name, parallel) in [("refill_1_thread", false), ("refill_parallel", true)] {
        let params = HessianParams {
            definiteness: Definiteness::Exact,
            parallel,
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                pattern.assemble_into(
                    springs,
                    &x,
                    mesh.masses(),
                    1e-2,
                    params,
                    &mut workspace,
                    &mut values,
                );
                black_box(&mut values);
            })
        });
    }
    group.finish();

    let mut group = c.benchmark_group("hessian_pattern_cloth320");
    group.sample_size(10);
    group.bench_function("build_pattern", |b| {
        b.iter(|| black_box(HessianPattern::<3>::new(n, springs, Some(&free))))
    });
    group.finish();
}

/// On a machine shared with other work, criterion's benchmarks run one after the other and see
/// different loads. This measures the three in alternation, round after round, and reports the
/// minimum and median of each and the ratios of the minima (the least disturbed runs): a check on
/// criterion's ratio, printed before it.
fn interleaved(
    pattern: &HessianPattern<3>,
    springs: &[hooke_mesh::Spring],
    x: &[Vector3<f64>],
    masses: &[f64],
    workspace: &mut hooke_assembly::HessianWorkspace<3>,
    values: &mut [f64],
) {
    const ROUNDS: usize = 40;
    let mut times = [[0.0f64; ROUNDS]; 3];
    // `round` indexes three series (stream, 1 thread, 2 threads) filled in one interleaved pass.
    #[allow(clippy::needless_range_loop)]
    for round in 0..ROUNDS {
        let start = Instant::now();
        let fill = black_box(1.5);
        for v in values.iter_mut() {
            *v = fill;
        }
        black_box(&mut *values);
        times[0][round] = start.elapsed().as_secs_f64();
        for (k, parallel) in [(1, false), (2, true)] {
            let params = HessianParams {
                definiteness: Definiteness::Exact,
                parallel,
            };
            let start = Instant::now();
            pattern.assemble_into(springs, x, masses, 1e-2, params, workspace, values);
            black_box(&mut *values);
            times[k][round] = start.elapsed().as_secs_f64();
        }
    }
    let mut summary = [(0.0, 0.0); 3];
    for (t, s) in times.iter_mut().zip(&mut summary) {
        t.sort_by(f64::total_cmp);
        *s = (t[0], t[ROUNDS / 2]);
    }
    let names = ["stream_write", "refill_1_thread", "refill_parallel"];
    for (name, (min, median)) in names.iter().zip(summary) {
        eprintln!(
            "interleaved {name}: min {:.2} ms, median {:.2} ms, {:.1} ns/spring (min)",
            min * 1e3,
            median * 1e3,
            min * 1e9 / springs.len() as f64
        );
    }
    eprintln!(
        "interleaved ratios of minima: refill/stream {:.2}, 1 thread/parallel {:.2}",
        summary[1].0 / summary[0].0,
        summary[1].0 / summary[2].0
    );
}

criterion_group!(benches, refill);
criterion_main!(benches);
