//! The floor of projective dynamics' iteration is its three-column solve with the prefactored
//! K(M + h²L)Kᵀ, which streams the factor from memory once per column block. This times the ways
//! of making that stream cheaper (benches/results/issue15-pd-speed.md) on cloth-N's matrix, each on
//! the same simplicial factor order (faer's AMD):
//! - `f64/usize`: the storage PD uses (the baseline);
//! - `f64/u32`: 32-bit row indices (12 bytes per stored entry instead of 16);
//! - `f32/u32`, `f32/usize`: single-precision values as well (8 or 12 bytes), whose solve would
//!   drive PD in correction form (x ← x + A₃₂⁻¹ (b − A x), with A and the residual in f64, so that
//!   the fixed point stays the f64 one);
//! - `f64/usize 2 threads`: the three columns split two and one over two threads (each thread has
//!   its own scratch), against faer's own 2-thread solve.
//!
//! It also prints, for the f32 solve, the relative error of one solve and of one refinement step.
//!
//! `cargo run --release -p hooke-solvers --example pd_solve_variants -- [N=160] [repeats=30]`

use std::time::{Duration, Instant};

use dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Index, Mat, MatMut, Par, Side};
use hooke_assembly::{FreeDofs, LaplacianPattern};
use hooke_mesh::generators;

fn median(mut t: Vec<Duration>) -> Duration {
    t.sort();
    t[t.len() / 2]
}

/// A factor of one storage: its symbolic analysis, values and solve scratch.
struct Factor<I: Index, T: faer::traits::RealField> {
    symbolic: SymbolicCholesky<I>,
    values: Vec<T>,
}

fn factor<I: Index, T: faer::traits::RealField + Copy>(
    a: SparseColMatRef<'_, I, T>,
) -> Factor<I, T> {
    let symbolic = factorize_symbolic_cholesky(
        a.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        },
    )
    .expect("symbolic");
    let mut values = vec![T::zero_impl(); symbolic.len_val()];
    let mut scratch =
        MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<T>(Par::Seq, Default::default()));
    symbolic
        .factorize_numeric_llt::<T>(
            &mut values,
            a,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut scratch),
            Default::default(),
        )
        .expect("positive definite");
    Factor { symbolic, values }
}

fn solve<I: Index, T: faer::traits::RealField + Copy>(
    f: &Factor<I, T>,
    rhs: MatMut<'_, T>,
    par: Par,
    scratch: &mut MemBuffer,
) {
    LltRef::new(&f.symbolic, &f.values).solve_in_place_with_conj(
        Conj::No,
        rhs,
        par,
        MemStack::new(scratch),
    );
}

fn time<I: Index, T: faer::traits::RealField + Copy>(
    f: &Factor<I, T>,
    rhs0: &Mat<T>,
    par: Par,
    repeats: usize,
) -> Duration {
    let mut scratch = MemBuffer::new(f.symbolic.solve_in_place_scratch::<T>(3, par));
    let mut rhs = rhs0.clone();
    median(
        (0..repeats)
            .map(|_| {
                rhs.copy_from(rhs0);
                let start = Instant::now();
                solve(f, rhs.as_mut(), par, &mut scratch);
                start.elapsed()
            })
            .collect(),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(Ok(160), |s| s.parse())?;
    let repeats: usize = args.get(2).map_or(Ok(30), |s| s.parse())?;
    let mesh = generators::cloth(n, 1e3)?;
    let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1])?;
    let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
    let mut values = pattern.new_values();
    pattern.system_into(mesh.springs(), mesh.masses(), 1.0 / 30.0, &mut values);
    let a64 = pattern.matrix(&values);
    let size = pattern.size();

    let col_ptr32: Vec<u32> = a64.symbolic().col_ptr().iter().map(|&c| c as u32).collect();
    let row_idx32: Vec<u32> = a64.symbolic().row_idx().iter().map(|&r| r as u32).collect();
    let values32: Vec<f32> = a64.val().iter().map(|&v| v as f32).collect();
    let sym32 = SymbolicSparseColMatRef::new_checked(size, size, &col_ptr32, None, &row_idx32);
    let a64_u32 = SparseColMatRef::<u32, f64>::new(sym32, a64.val());
    let a32_u32 = SparseColMatRef::<u32, f32>::new(sym32, &values32);
    let a32_usize = SparseColMatRef::<usize, f32>::new(a64.symbolic(), &values32);

    let f64_usize = factor(a64);
    let f64_u32 = factor(a64_u32);
    let f32_u32 = factor(a32_u32);
    let f32_usize = factor(a32_usize);
    println!(
        "cloth-{n}: {size} unknowns, {} stored entries of A, {} of L; median of {repeats} solves of 3 columns",
        a64.compute_nnz(),
        f64_usize.values.len()
    );

    let b64 = Mat::<f64>::from_fn(size, 3, |i, j| (((i * 3 + j) % 7) as f64) - 3.0);
    let b32 = Mat::<f32>::from_fn(size, 3, |i, j| b64[(i, j)] as f32);
    let rows = [
        ("f64/usize", time(&f64_usize, &b64, Par::Seq, repeats)),
        ("f64/u32", time(&f64_u32, &b64, Par::Seq, repeats)),
        ("f32/usize", time(&f32_usize, &b32, Par::Seq, repeats)),
        ("f32/u32", time(&f32_u32, &b32, Par::Seq, repeats)),
        (
            "f64/usize faer 2 threads",
            time(&f64_usize, &b64, Par::rayon(2), repeats),
        ),
    ];
    // Two columns on one thread, one on the other, each with its own scratch.
    let mut scratch_a = MemBuffer::new(
        f64_usize
            .symbolic
            .solve_in_place_scratch::<f64>(2, Par::Seq),
    );
    let mut scratch_b = MemBuffer::new(
        f64_usize
            .symbolic
            .solve_in_place_scratch::<f64>(1, Par::Seq),
    );
    let mut rhs = b64.clone();
    let split = median(
        (0..repeats)
            .map(|_| {
                rhs.copy_from(&b64);
                let start = Instant::now();
                let (left, right) = rhs.as_mut().split_at_col_mut(2);
                rayon::join(
                    || solve(&f64_usize, left, Par::Seq, &mut scratch_a),
                    || solve(&f64_usize, right, Par::Seq, &mut scratch_b),
                );
                start.elapsed()
            })
            .collect(),
    );
    let base = rows[0].1.as_secs_f64();
    for (name, t) in rows
        .iter()
        .copied()
        .chain([("f64/usize split 2+1 on 2 threads", split)])
    {
        println!(
            "{name:<34} {:>8.3} ms  {:>5.2}x",
            t.as_secs_f64() * 1e3,
            base / t.as_secs_f64()
        );
    }

    // Accuracy of the f32 solve, and of one f64 refinement step with it.
    let mut exact = b64.clone();
    let mut scratch = MemBuffer::new(
        f64_usize
            .symbolic
            .solve_in_place_scratch::<f64>(3, Par::Seq),
    );
    solve(&f64_usize, exact.as_mut(), Par::Seq, &mut scratch);
    let mut x32 = b32.clone();
    let mut scratch32 = MemBuffer::new(f32_u32.symbolic.solve_in_place_scratch::<f32>(3, Par::Seq));
    solve(&f32_u32, x32.as_mut(), Par::Seq, &mut scratch32);
    let mut x = Mat::<f64>::from_fn(size, 3, |i, j| x32[(i, j)] as f64);
    let error = |x: &Mat<f64>| (x - &exact).norm_l2() / exact.norm_l2();
    println!("f32 solve: relative error {:.2e}", error(&x));
    // r = b − A x in f64 (A is stored in full; the factorisations read its lower triangle).
    let mut r = b64.clone();
    for j in 0..size {
        for (i, &v) in a64.row_idx_of_col(j).zip(a64.val_of_col(j)) {
            for c in 0..3 {
                r[(i, c)] -= v * x[(j, c)];
            }
        }
    }
    let mut d32 = Mat::<f32>::from_fn(size, 3, |i, j| r[(i, j)] as f32);
    solve(&f32_u32, d32.as_mut(), Par::Seq, &mut scratch32);
    x += Mat::<f64>::from_fn(size, 3, |i, j| d32[(i, j)] as f64);
    println!(
        "after one f64 refinement step: relative error {:.2e}",
        error(&x)
    );
    Ok(())
}
