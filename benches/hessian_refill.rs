//! Refilling the values of the backward Euler Hessian M + h² ∇²E of cloth-320 (102,400 vertices,
//! 611,202 springs, pins 0 and 319) in its fixed pattern, against the memory limit: a plain streaming
//! write of a value array of the same length, measured in the same run.
//!
//! Issue 3 asks for refill ≤ 2 × stream, single-threaded. Also measured: the 2-thread refill (rayon's
//! global pool) and, reported apart, building the pattern and scatter map once.
//!
//! Run: `cargo bench -p hooke-assembly --bench hessian_refill`. Divide a refill time by the spring
//! count printed at start-up for ns per spring.

use std::hint::black_box;

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

criterion_group!(benches, refill);
criterion_main!(benches);
