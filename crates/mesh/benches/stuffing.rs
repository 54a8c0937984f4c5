//! Isosurface stuffing of the Stanford bunny at spacings from 1/20 to 1/120 of its diagonal (up
//! to about 10⁶ tetrahedra): time per mesh, tetrahedra per second (criterion's throughput) and the
//! process's peak resident memory after each spacing; then the graded variant at the same surface
//! spacings, with its tetrahedron count against the uniform mesh's.
//!
//! `cargo bench -p hooke-mesh --bench stuffing`; results in `benches/results/mesher-*`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hooke_mesh::io::read_obj;
use hooke_mesh::stuffing::{tetrahedralize, tetrahedralize_graded, ClosedSurface, StuffingOptions};

/// Peak resident set size of this process (kB), from /proc (Linux); 0 elsewhere.
fn peak_rss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse().ok()))
        })
        .unwrap_or(0)
}

fn bunny(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes/bunny.obj");
    let surface = ClosedSurface::new(&read_obj(&path).expect("bunny.obj")).expect("closed bunny");
    let [lo, hi] = surface.bounds();
    let diagonal = (hi - lo).norm();
    let mut group = c.benchmark_group("stuffing/bunny");
    group.sample_size(10);
    group.warm_up_time(std::time::Duration::from_secs(1));
    group.measurement_time(std::time::Duration::from_secs(5));
    for divisions in [20u32, 40, 80, 100, 120] {
        let options = StuffingOptions::new(diagonal / divisions as f64).expect("spacing");
        let once = tetrahedralize(&surface, &options).expect("stuffed bunny");
        eprintln!(
            "bunny diagonal/{divisions}: {} tetrahedra, {} vertices, {:.3} s ({:.0} tets/s), dihedral {:.2}°..{:.2}°, volume {:+.3} %, peak RSS {} MB",
            once.report.tets,
            once.report.vertices,
            once.report.seconds,
            once.report.tets as f64 / once.report.seconds,
            once.report.min_dihedral_deg,
            once.report.max_dihedral_deg,
            100.0 * (once.report.volume / surface.enclosed_volume() - 1.0),
            peak_rss_kb() / 1024,
        );
        group.throughput(Throughput::Elements(once.report.tets as u64));
        group.bench_function(format!("diagonal-over-{divisions}"), |b| {
            b.iter(|| tetrahedralize(&surface, &options).expect("stuffed bunny"))
        });
    }
    group.finish();
}

fn bunny_graded(c: &mut Criterion) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/meshes/bunny.obj");
    let surface = ClosedSurface::new(&read_obj(&path).expect("bunny.obj")).expect("closed bunny");
    let [lo, hi] = surface.bounds();
    let diagonal = (hi - lo).norm();
    let mut group = c.benchmark_group("stuffing/bunny-graded");
    group.sample_size(10);
    group.warm_up_time(std::time::Duration::from_secs(1));
    group.measurement_time(std::time::Duration::from_secs(5));
    for divisions in [20u32, 40, 60, 80, 120] {
        let options = StuffingOptions::new(diagonal / divisions as f64).expect("spacing");
        let graded = tetrahedralize_graded(&surface, &options).expect("graded bunny");
        let uniform = tetrahedralize(&surface, &options).expect("stuffed bunny");
        eprintln!(
            "bunny diagonal/{divisions} graded: {} tetrahedra ({:.2}× fewer than uniform's {}), {} vertices, {:.3} s against {:.3} s, dihedral {:.2}°..{:.2}°, peak RSS {} MB",
            graded.report.tets,
            uniform.report.tets as f64 / graded.report.tets as f64,
            uniform.report.tets,
            graded.report.vertices,
            graded.report.seconds,
            uniform.report.seconds,
            graded.report.min_dihedral_deg,
            graded.report.max_dihedral_deg,
            peak_rss_kb() / 1024,
        );
        group.throughput(Throughput::Elements(graded.report.tets as u64));
        group.bench_function(format!("diagonal-over-{divisions}"), |b| {
            b.iter(|| tetrahedralize_graded(&surface, &options).expect("graded bunny"))
        });
    }
    group.finish();
}

criterion_group!(benches, bunny, bunny_graded);
criterion_main!(benches);
