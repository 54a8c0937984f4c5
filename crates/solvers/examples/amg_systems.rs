//! PCG with the smoothed-aggregation AMG preconditioner (docs/solvers.md §2.4) on systems written
//! by `hooke bench SCENE --export-system DIR`: Newton's clamped Hessian with the right-hand side
//! −∇Φ(y) and the 6 rigid-body modes of the exported positions, and PD's scalar matrix M + h²L
//! with a constant near-nullspace and a random right-hand side. Prints the hierarchy, the set-up,
//! refresh and solve times, the PCG iterations to the tolerance and the true relative residual
//! (benches/results/amg.md). PCG multiplies by the hierarchy's finest matrix, as the library's
//! multilevel Newton solve does.
//!
//! `cargo run -p hooke-solvers --example amg_systems -- DIR [tolerance=1e-6] [sweeps=1] [symmetric|gs] [power iterations] [smoother parts]`
//! (RAYON_NUM_THREADS=1 for one thread).

use std::path::Path;
use std::time::Instant;

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use hooke_solvers::{Amg, AmgParams, AmgSmoother, LinearOperator, Preconditioner, Symmetric};

fn read_sparse(path: &Path) -> SparseColMat<usize, f64> {
    let t: sprs::TriMat<f64> =
        sprs::io::read_matrix_market(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let m: sprs::CsMat<f64> = t.to_csc();
    let (n, c) = m.shape();
    let (ptr, idx, val) = m.into_raw_storage();
    SparseColMat::new(SymbolicSparseColMat::new_checked(n, c, ptr, None, idx), val)
}

/// A dense MatrixMarket array (column-major values).
fn read_dense(path: &Path) -> (usize, usize, Vec<f64>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines().filter(|l| !l.starts_with('%'));
    let size: Vec<usize> = lines
        .next()
        .expect("size line")
        .split_whitespace()
        .map(|s| s.parse().expect("size"))
        .collect();
    let values = lines.map(|l| l.trim().parse().expect("value")).collect();
    (size[0], size[1], values)
}

/// CPU time of the whole process so far (every thread's run time from /proc/self/task/*/schedstat),
/// s; the wall clock of a loaded machine overstates the work.
fn cpu_time() -> f64 {
    let mut ns = 0u64;
    if let Ok(tasks) = std::fs::read_dir("/proc/self/task") {
        for task in tasks.flatten() {
            if let Ok(text) = std::fs::read_to_string(task.path().join("schedstat")) {
                ns += text
                    .split_whitespace()
                    .next()
                    .and_then(|v| v.parse::<u64>().ok())
                    .unwrap_or(0);
            }
        }
    }
    ns as f64 * 1e-9
}

/// Wall and CPU seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64, f64) {
    let (wall, cpu) = (Instant::now(), cpu_time());
    let value = f();
    (value, wall.elapsed().as_secs_f64(), cpu_time() - cpu)
}

/// PCG from x = 0 to ‖b − A x‖ ≤ `tolerance` ‖b‖, one V-cycle per iteration, the product with A
/// by the hierarchy's finest level (as the library's multilevel Newton solve does); the
/// iterations, or `None` after 1000.
fn pcg(amg: &mut Amg, b: &[f64], x: &mut [f64], tolerance: f64) -> Option<usize> {
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(p, q)| p * q).sum::<f64>();
    let n = b.len();
    let (mut r, mut z, mut q) = (b.to_vec(), vec![0.0; n], vec![0.0; n]);
    x.fill(0.0);
    let target = tolerance * norm(b);
    Preconditioner::apply(amg, &r, &mut z);
    let mut d = z.clone();
    let mut rz = dot(&r, &z);
    for k in 1..=1000 {
        LinearOperator::apply(&*amg, &d, &mut q);
        let alpha = rz / dot(&d, &q);
        for i in 0..n {
            x[i] += alpha * d[i];
            r[i] -= alpha * q[i];
        }
        if norm(&r) <= target {
            return Some(k);
        }
        Preconditioner::apply(amg, &r, &mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for (d, z) in d.iter_mut().zip(&z) {
            *d = z + beta * *d;
        }
    }
    None
}

fn norm(a: &[f64]) -> f64 {
    a.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn run(
    name: &str,
    a: &SparseColMat<usize, f64>,
    block: usize,
    nullspace: &[f64],
    b: &[f64],
    tolerance: f64,
    params: AmgParams,
) {
    let n = a.nrows();
    let (amg, setup_wall, setup) =
        timed(|| Amg::new(a.as_ref(), block, nullspace, params).expect("set-up"));
    let mut amg = amg;
    let ((), _, refresh) = timed(|| amg.refresh(a.as_ref()).expect("refresh"));
    let mut x = vec![0.0; n];
    let (iterations, solve_wall, solve) = timed(|| pcg(&mut amg, b, &mut x, tolerance));
    let mut ax = vec![0.0; n];
    Symmetric(a.as_ref()).apply(&x, &mut ax);
    let r: Vec<f64> = b.iter().zip(&ax).map(|(p, q)| p - q).collect();
    println!(
        "{name}: n = {n}, nnz = {}, levels {:?}, operator complexity {:.3}; CPU s (wall s): set-up {:.3} ({:.3}), \
         refresh {:.3}; PCG to {tolerance:e}: {} iterations, {:.3} ({:.3}), {:.1} ms per \
         iteration; set-up + solve {:.3} ({:.3}); true relative residual {:.2e}",
        a.compute_nnz(),
        amg.level_sizes(),
        amg.operator_complexity(),
        setup,
        setup_wall,
        refresh,
        iterations.map_or("no convergence in 1000".to_string(), |k| k.to_string()),
        solve,
        solve_wall,
        1e3 * solve / iterations.unwrap_or(1000).max(1) as f64,
        setup + solve,
        setup_wall + solve_wall,
        norm(&r) / norm(b)
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = Path::new(
        args.first()
            .expect("usage: amg_systems DIR [tolerance] [sweeps]"),
    );
    let tolerance: f64 = args.get(1).map_or(1e-6, |s| s.parse().expect("tolerance"));
    let sweeps: usize = args.get(2).map_or(1, |s| s.parse().expect("sweeps"));
    let smoother = match args.get(3).map(String::as_str) {
        Some("gs") => AmgSmoother::GaussSeidel,
        _ => AmgSmoother::SymmetricGaussSeidel,
    };
    let params = AmgParams {
        smoother,
        smoother_sweeps: sweeps,
        spectral_radius_iterations: args
            .get(4)
            .map_or(AmgParams::default().spectral_radius_iterations, |s| {
                s.parse().expect("power iterations")
            }),
        smoother_parts: args
            .get(5)
            .map_or(AmgParams::default().smoother_parts, |s| {
                s.parse().expect("smoother parts")
            }),
        ..AmgParams::default()
    };
    println!(
        "{}: rayon threads {}",
        dir.display(),
        rayon::current_num_threads()
    );
    let h = read_sparse(&dir.join("hessian_clamped.mtx"));
    let (_, _, g) = read_dense(&dir.join("gradient.mtx"));
    let (nv, _, p) = read_dense(&dir.join("positions.mtx"));
    let positions: Vec<f64> = (0..nv)
        .flat_map(|f| (0..3).map(move |a| (f, a)))
        .map(|(f, a)| p[a * nv + f])
        .collect();
    let rhs: Vec<f64> = g.iter().map(|v| -v).collect();
    let modes = Amg::rigid_body_modes(&positions);
    run("Hessian (clamped)", &h, 3, &modes, &rhs, tolerance, params);
    let a = read_sparse(&dir.join("pd_matrix.mtx"));
    let ones = vec![1.0; a.nrows()];
    // PD's right-hand side differs per iteration; a fixed pseudo-random one stands for it.
    let b: Vec<f64> = (0..a.nrows())
        .map(|i| ((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f64 / 16777216.0 - 0.5)
        .collect();
    run("PD matrix M + h²L", &a, 1, &ones, &b, tolerance, params);
}
