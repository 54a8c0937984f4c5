//! How the factor of projective dynamics' matrix K(M + h²L)Kᵀ is stored decides the speed of its
//! three-column solve (memory traffic over the factor). Times factorisation and solve on cloth-N for
//! simplicial and supernodal factors, serial and 2-thread solves.
//!
//! `cargo run --release -p hooke-solvers --example pd_factor_storage -- [N=160] [repeats=20]`

use std::time::{Duration, Instant};

use faer::Mat;
use hooke_assembly::{FreeDofs, LaplacianPattern};
use hooke_mesh::generators;
use hooke_solvers::{CholeskyParams, FactorKind, SparseCholesky};

fn median(mut t: Vec<Duration>) -> Duration {
    t.sort();
    t[t.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(Ok(160), |s| s.parse())?;
    let repeats: usize = args.get(2).map_or(Ok(20), |s| s.parse())?;
    let mesh = generators::cloth(n, 1e3)?;
    let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1])?;
    let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
    let mut values = pattern.new_values();
    pattern.system_into(mesh.springs(), mesh.masses(), 1.0 / 30.0, &mut values);
    let matrix = pattern.matrix(&values);
    let size = pattern.size();
    println!(
        "cloth-{n}: {size} unknowns, {} stored entries",
        pattern.nnz()
    );
    for kind in [FactorKind::Simplicial, FactorKind::Supernodal] {
        for threads in [1, 2] {
            let params = CholeskyParams {
                kind,
                factor_threads: threads,
                solve_threads: threads,
                ..CholeskyParams::default()
            };
            let mut llt = SparseCholesky::analyze(pattern.symbolic(), params)?;
            let factor = median(
                (0..repeats.min(5))
                    .map(|_| {
                        llt.factorize(matrix).unwrap();
                        llt.factor_time()
                    })
                    .collect(),
            );
            let mut rhs = Mat::<f64>::from_fn(size, 3, |i, j| ((i * 3 + j) % 7) as f64);
            let solve = median(
                (0..repeats)
                    .map(|_| {
                        let start = Instant::now();
                        llt.solve_in_place(rhs.as_mut());
                        start.elapsed()
                    })
                    .collect(),
            );
            println!(
                "{kind:?}, {threads} thread(s): factor nnz {}, analysis {:.1?}, factor {:.2?}, \
                 3-column solve {:.2?} ({:.2} GB/s over the factor's values)",
                llt.factor_nnz(),
                llt.analysis_time(),
                factor,
                solve,
                // Forward and backward sweeps each read every stored value once.
                2.0 * llt.factor_nnz() as f64 * 8.0 / solve.as_secs_f64() / 1e9
            );
        }
    }
    Ok(())
}
