//! The numeric factorisation of Newton's matrix on cloth-N in several organisations, to choose
//! Newton's factor settings: faer's AMD on the 3n × 3n pattern against AMD on the vertex graph
//! expanded to each vertex's three DOFs (dense 3 × 3 blocks stay together, so supernodes are at
//! least three columns wide), each simplicial and supernodal; LDLᵀ and LLᵀ. The matrix is the
//! Hessian of Φ at y for a step from a cloth swung by one symplectic step (its values do not
//! change the cost of a factorisation without pivoting). Also the time of one solve with the LLᵀ
//! factor for one right-hand side (what each CG iteration preconditioned by a held factor costs).
//!
//! `cargo run --release -p hooke-solvers --example newton_factor_variants -- [N=40] [repeats=7] [threads=1]`

use std::time::Instant;

use dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::linalg::{amd, SupernodalThreshold};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};
use hooke_assembly::FreeDofs;
use hooke_mesh::generators;
use hooke_solvers::{BackwardEulerStep, NewtonProblem};
use nalgebra::Vector3;

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(Ok(40), |s| s.parse())?;
    let repeats: usize = args.get(2).map_or(Ok(7), |s| s.parse())?;
    let threads: usize = args.get(3).map_or(Ok(1), |s| s.parse())?;
    let par = if threads > 1 {
        Par::rayon(threads)
    } else {
        Par::Seq
    };
    let mesh = generators::cloth(n, 1e3)?;
    let pinned = [0u32, n as u32 - 1];
    let h = 1.0 / 30.0;
    let free = FreeDofs::new(mesh.vertex_count(), &pinned)?;
    let mut step = BackwardEulerStep::<3>::new(mesh.springs(), mesh.masses(), free, h);
    let x = mesh.positions().to_vec();
    let y: Vec<_> = x
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let wave = Vector3::new(0.0, 0.05 * (7.0 * p.x).sin() * (5.0 * p.z).cos(), 0.0);
            if pinned.contains(&(i as u32)) {
                *p
            } else {
                p + wave
            }
        })
        .collect();
    let mut unknowns = vec![0.0; step.dim()];
    step.set_step(&y, &x, &mut unknowns);
    let dim = step.dim();
    let pattern = step.pattern().to_owned()?;
    let values = step.hessian(&unknowns).val().to_vec();
    let a = SparseColMatRef::new(pattern.as_ref(), &values);
    println!("cloth-{n}: {dim} unknowns, {} stored entries", values.len());

    // The vertex graph (DOFs 3v, 3v+1, 3v+2 of free vertex v), ordered by AMD and expanded.
    let vertices = dim / 3;
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for v in 0..vertices {
        let mut rows: Vec<usize> = pattern.row_idx_of_col(3 * v).map(|r| r / 3).collect();
        rows.dedup();
        row_idx.extend(rows);
        col_ptr.push(row_idx.len());
    }
    let graph = SymbolicSparseColMat::new_checked(vertices, vertices, col_ptr, None, row_idx);
    let mut vperm = vec![0usize; vertices];
    let mut vperm_inv = vec![0usize; vertices];
    let mut mem = MemBuffer::new(amd::order_scratch::<usize>(vertices, graph.compute_nnz()));
    amd::order(
        &mut vperm,
        &mut vperm_inv,
        graph.as_ref(),
        amd::Control::default(),
        MemStack::new(&mut mem),
    )?;
    let perm: Vec<usize> = vperm
        .iter()
        .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
        .collect();
    let mut perm_inv = vec![0usize; dim];
    for (new, &old) in perm.iter().enumerate() {
        perm_inv[old] = new;
    }
    let block = PermRef::new_checked(&perm, &perm_inv, dim);

    println!("ordering  kind         L values   LDLt ms    LLt ms  solve ms   analysis ms");
    for (order_name, ordering) in [("amd-3n", None), ("amd-vertex", Some(block))] {
        for (kind_name, threshold) in [
            ("auto", SupernodalThreshold::AUTO),
            ("simplicial", SupernodalThreshold::FORCE_SIMPLICIAL),
            ("supernodal", SupernodalThreshold::FORCE_SUPERNODAL),
        ] {
            let start = Instant::now();
            let symbolic: SymbolicCholesky<usize> = factorize_symbolic_cholesky(
                pattern.as_ref(),
                Side::Lower,
                match ordering {
                    None => SymmetricOrdering::Amd,
                    Some(p) => SymmetricOrdering::Custom(p),
                },
                CholeskySymbolicParams {
                    supernodal_flop_ratio_threshold: threshold,
                    ..Default::default()
                },
            )
            .map_err(|e| format!("{e:?}"))?;
            let analysis = start.elapsed().as_secs_f64() * 1e3;
            let mut l = vec![0.0; symbolic.len_val()];
            let mut mem = MemBuffer::new(StackReq::any_of(&[
                symbolic.factorize_numeric_ldlt_scratch::<f64>(par, Default::default()),
                symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
                symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
            ]));
            let mut rhs = vec![0.0; dim];
            let mut solve = Vec::new();
            let mut ldlt = Vec::new();
            let mut llt = Vec::new();
            for _ in 0..repeats {
                let start = Instant::now();
                symbolic
                    .factorize_numeric_ldlt(
                        &mut l,
                        a,
                        Side::Lower,
                        LdltRegularization::default(),
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .map_err(|e| format!("{e:?}"))?;
                ldlt.push(start.elapsed().as_secs_f64() * 1e3);
                let start = Instant::now();
                let ok = symbolic
                    .factorize_numeric_llt(
                        &mut l,
                        a,
                        Side::Lower,
                        LltRegularization::default(),
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .is_ok();
                llt.push(if ok {
                    start.elapsed().as_secs_f64() * 1e3
                } else {
                    f64::NAN
                });
                if ok {
                    rhs.fill(1.0);
                    let start = Instant::now();
                    LltRef::new(&symbolic, &l).solve_in_place_with_conj(
                        Conj::No,
                        MatMut::from_column_major_slice_mut(&mut rhs, dim, 1),
                        Par::Seq,
                        MemStack::new(&mut mem),
                    );
                    solve.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            println!(
                "{order_name:<10}{kind_name:<11}{:>10}{:>10.2}{:>10.2}{:>10.3}{:>13.2}",
                symbolic.len_val(),
                median(ldlt),
                median(llt),
                if solve.is_empty() {
                    f64::NAN
                } else {
                    median(solve)
                },
                analysis
            );
        }
    }
    Ok(())
}
