//! Smoothed-aggregation AMG (docs/solvers.md §2.4): the V-cycle is a symmetric positive definite
//! preconditioner, PCG with it reaches the direct solve's answer, a refresh equals a fresh set-up
//! bit for bit, the result does not depend on the thread count, and bad input is a typed error.

use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use hooke_mesh::{generators, SpringMesh};
use hooke_solvers::{
    Amg, AmgError, AmgParams, AmgSmoother, BlockJacobi, CgParams, CholeskyParams,
    ConjugateGradient, Convergence, NewtonCg, NewtonCgParams, NewtonProblem, Preconditioner,
    SparseCholesky, StopReason, Symmetric,
};

use crate::common::on_threads;
use crate::waved_step;
use waved_step::{clamped, newton_solution, objective_error, step};

/// The clamped Hessian at y of a waved step on `mesh` (compressed and stretched springs: an SPD
/// matrix with the anisotropy of a real Newton system) and the free vertices' positions y.
fn hessian(
    mesh: &SpringMesh<3>,
    pinned: &[u32],
    amplitude: f64,
) -> (SparseColMat<usize, f64>, Vec<f64>) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, amplitude);
    let x = s.start.clone();
    let h = s.problem.convexified_hessian(&x).expect("clamped Hessian");
    let owned = SparseColMat::new(h.symbolic().to_owned().unwrap(), h.val().to_vec());
    (owned, x)
}

fn cloth(n: usize) -> (SparseColMat<usize, f64>, Vec<f64>) {
    hessian(
        &generators::cloth(n, 1e3).unwrap(),
        &[0, n as u32 - 1],
        0.05,
    )
}

fn beam() -> (SparseColMat<usize, f64>, Vec<f64>) {
    let mesh = generators::beam(2).unwrap();
    hessian(&mesh, &clamped(&mesh), 0.05)
}

/// Settings that give several levels on these small matrices (the default stops at 1000 unknowns).
fn small_coarse() -> AmgParams {
    AmgParams {
        max_coarse: 40,
        ..AmgParams::default()
    }
}

/// Deterministic pseudo-random values in [−1, 1).
fn random(n: usize, seed: u64) -> Vec<f64> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

fn symmetric_positive_definite(a: SparseColMatRef<'_, usize, f64>, positions: &[f64]) {
    for smoother in [AmgSmoother::GaussSeidel, AmgSmoother::SymmetricGaussSeidel] {
        let params = AmgParams {
            smoother,
            ..small_coarse()
        };
        symmetric_positive_definite_with(a, positions, params);
    }
}

fn symmetric_positive_definite_with(
    a: SparseColMatRef<'_, usize, f64>,
    positions: &[f64],
    params: AmgParams,
) {
    let modes = Amg::rigid_body_modes(positions);
    let mut amg = Amg::new(a, 3, &modes, params).unwrap();
    assert!(amg.level_count() >= 2, "levels {:?}", amg.level_sizes());
    let n = a.nrows();
    for seed in 0..5 {
        let (x, y) = (random(n, 2 * seed), random(n, 2 * seed + 1));
        let (mut bx, mut by) = (vec![0.0; n], vec![0.0; n]);
        amg.apply(&x, &mut bx);
        amg.apply(&y, &mut by);
        let (xby, ybx) = (dot(&x, &by), dot(&y, &bx));
        // Round-off of two dot products of n terms and the cycle's own sums: a few hundred ε of
        // the terms' scale ‖x‖‖By‖ (an asymmetric cycle, e.g. forward sweeps only, is off by
        // percents).
        let scale = norm(&x) * norm(&by) + norm(&y) * norm(&bx);
        assert!(
            (xby - ybx).abs() <= 1e-13 * scale,
            "⟨x, By⟩ = {xby:e}, ⟨y, Bx⟩ = {ybx:e}"
        );
        let xbx = dot(&x, &bx);
        assert!(xbx > 0.0, "⟨x, Bx⟩ = {xbx:e}");
    }
}

#[test]
fn the_v_cycle_is_symmetric_positive_definite_on_cloth_10() {
    let (a, x) = cloth(10);
    symmetric_positive_definite(a.as_ref(), &x);
}

#[test]
fn the_v_cycle_is_symmetric_positive_definite_on_beam_2() {
    let (a, x) = beam();
    symmetric_positive_definite(a.as_ref(), &x);
}

/// PCG with the V-cycle to a relative residual of 1e-10, against the Cholesky solution; returns
/// the iterations.
fn reaches_the_direct_solution(
    a: SparseColMatRef<'_, usize, f64>,
    positions: &[f64],
    params: AmgParams,
) -> usize {
    let n = a.nrows();
    let b = random(n, 7);
    let mut chol = SparseCholesky::analyze(a.symbolic(), CholeskyParams::default()).unwrap();
    chol.factorize(a).unwrap();
    let mut direct = b.clone();
    chol.solve_slice(&mut direct);

    let modes = Amg::rigid_body_modes(positions);
    let mut amg = Amg::new(a, 3, &modes, params).unwrap();
    let tolerance = 1e-10;
    let mut cg = ConjugateGradient::new(CgParams {
        tolerance,
        max_iterations: 500,
    });
    let mut x = vec![0.0; n];
    let report = cg.solve(&Symmetric(a), &mut amg, &b, &mut x).unwrap();
    assert_eq!(report.stop, StopReason::Converged);
    // The difference measured in the residual it makes: ‖A(x − x_direct)‖ ≤ ‖b − Ax‖ +
    // ‖b − A x_direct‖, the tolerance plus the direct solve's round-off (CG's recursive residual
    // may drift from the true one by round-off too: twice the tolerance covers both).
    let difference: Vec<f64> = x.iter().zip(&direct).map(|(p, q)| p - q).collect();
    let mut ad = vec![0.0; n];
    hooke_solvers::LinearOperator::apply(&Symmetric(a), &difference, &mut ad);
    assert!(
        norm(&ad) <= 2.0 * tolerance * norm(&b),
        "‖A(x − x_direct)‖/‖b‖ = {:e}",
        norm(&ad) / norm(&b)
    );

    // Block Jacobi for comparison: AMG must need far fewer iterations.
    let blocks = (0..n / 3).map(|k| {
        nalgebra::Matrix3::from_fn(|i, j| {
            let col = 3 * k + j;
            let rows = a.row_idx_of_col_raw(col);
            rows.iter()
                .position(|&r| r == 3 * k + i)
                .map_or(0.0, |p| a.val_of_col(col)[p])
        })
    });
    let mut jacobi = BlockJacobi::<3>::from_blocks(blocks).unwrap();
    let mut xj = vec![0.0; n];
    let jacobi_report = cg.solve(&Symmetric(a), &mut jacobi, &b, &mut xj).unwrap();
    eprintln!(
        "n = {n}: AMG {:?} ({} levels), block Jacobi {} PCG iterations",
        report.iterations,
        amg.level_count(),
        jacobi_report.iterations
    );
    assert!(
        2 * report.iterations < jacobi_report.iterations,
        "AMG {} vs block Jacobi {} iterations",
        report.iterations,
        jacobi_report.iterations
    );
    report.iterations
}

#[test]
fn pcg_with_amg_reaches_the_cholesky_solution() {
    let (a, x) = cloth(10);
    reaches_the_direct_solution(a.as_ref(), &x, small_coarse());
    let (a, x) = cloth(20);
    reaches_the_direct_solution(a.as_ref(), &x, small_coarse());
    let (a, x) = beam();
    reaches_the_direct_solution(a.as_ref(), &x, small_coarse());
}

/// A hierarchy refreshed with new values (same pattern) applies the same bits as one set up on
/// them from scratch.
#[test]
fn refresh_equals_a_fresh_set_up_bit_for_bit() {
    let mesh = generators::cloth(20, 1e3).unwrap();
    let (a1, x1) = hessian(&mesh, &[0, 19], 0.05);
    let (a2, _) = hessian(&mesh, &[0, 19], 0.12);
    assert_eq!(a1.symbolic().row_idx(), a2.symbolic().row_idx());
    assert_ne!(a1.val(), a2.val(), "the values differ");
    let modes = Amg::rigid_body_modes(&x1);
    let mut refreshed = Amg::new(a1.as_ref(), 3, &modes, small_coarse()).unwrap();
    refreshed.refresh(a2.as_ref()).unwrap();
    let mut fresh = Amg::new(a2.as_ref(), 3, &modes, small_coarse()).unwrap();
    let r = random(a1.nrows(), 3);
    let (mut z1, mut z2) = (vec![0.0; r.len()], vec![0.0; r.len()]);
    refreshed.apply(&r, &mut z1);
    fresh.apply(&r, &mut z2);
    assert!(z1.iter().zip(&z2).all(|(p, q)| p.to_bits() == q.to_bits()));
    // And a refresh back to the first values reproduces the first hierarchy.
    let mut first = Amg::new(a1.as_ref(), 3, &modes, small_coarse()).unwrap();
    refreshed.refresh(a1.as_ref()).unwrap();
    first.apply(&r, &mut z1);
    refreshed.apply(&r, &mut z2);
    assert!(z1.iter().zip(&z2).all(|(p, q)| p.to_bits() == q.to_bits()));
}

/// Set-up, V-cycles and PCG on a 1-thread and a 2-thread rayon pool give the same bits (cloth-40:
/// above the size where the products run in parallel).
#[test]
fn the_same_bits_on_one_and_two_threads() {
    let (a, x) = cloth(40);
    let run = |threads: usize| {
        on_threads(threads, || {
            let modes = Amg::rigid_body_modes(&x);
            let mut amg = Amg::new(a.as_ref(), 3, &modes, AmgParams::default()).unwrap();
            let b = random(a.nrows(), 11);
            let mut z = vec![0.0; b.len()];
            amg.apply(&b, &mut z);
            let mut cg = ConjugateGradient::new(CgParams {
                tolerance: 1e-8,
                max_iterations: 200,
            });
            let mut s = vec![0.0; b.len()];
            cg.solve(&Symmetric(a.as_ref()), &mut amg, &b, &mut s)
                .unwrap();
            (z, s)
        })
    };
    let (z1, s1) = run(1);
    let (z2, s2) = run(2);
    assert!(z1.iter().zip(&z2).all(|(p, q)| p.to_bits() == q.to_bits()));
    assert!(s1.iter().zip(&s2).all(|(p, q)| p.to_bits() == q.to_bits()));
}

/// The scalar PD matrix M + h²L with a constant near-nullspace, block size 1.
#[test]
fn scalar_systems_with_a_constant_near_nullspace() {
    let mesh = generators::cloth(20, 1e3).unwrap();
    let free = hooke_assembly::FreeDofs::new(mesh.vertex_count(), &[0, 19]).unwrap();
    let pattern =
        hooke_assembly::LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
    let mut values = pattern.new_values();
    pattern.system_into(mesh.springs(), mesh.masses(), 1.0 / 30.0, &mut values);
    let a = pattern.to_sparse_col_mat(&values);
    let ones = vec![1.0; a.nrows()];
    let mut amg = Amg::new(a.as_ref(), 1, &ones, small_coarse()).unwrap();
    assert!(amg.level_count() >= 2);
    let b = random(a.nrows(), 5);
    let mut x = vec![0.0; b.len()];
    let report = ConjugateGradient::new(CgParams {
        tolerance: 1e-10,
        max_iterations: 100,
    })
    .solve(&Symmetric(a.as_ref()), &mut amg, &b, &mut x)
    .unwrap();
    assert_eq!(report.stop, StopReason::Converged);
    assert!(report.iterations <= 20, "{} iterations", report.iterations);
}

#[test]
fn bad_input_is_a_typed_error() {
    let (a, x) = cloth(10);
    let modes = Amg::rigid_body_modes(&x);
    let n = a.nrows();
    // Not square.
    let rect = SparseColMat::<usize, f64>::try_new_from_triplets(
        6,
        3,
        &[Triplet::new(0, 0, 1.0), Triplet::new(4, 2, 1.0)],
    )
    .unwrap();
    assert!(matches!(
        Amg::new(rect.as_ref(), 3, &[1.0; 18], AmgParams::default()),
        Err(AmgError::NotSquare { rows: 6, cols: 3 })
    ));
    // Block sizes that do not divide the dimension, zero, or too large.
    for block in [0, 4, 9] {
        assert!(
            matches!(
                Amg::new(a.as_ref(), block, &modes, AmgParams::default()),
                Err(AmgError::BlockSize { .. })
            ),
            "block {block}"
        );
    }
    // A near-nullspace of the wrong length.
    assert!(matches!(
        Amg::new(
            a.as_ref(),
            3,
            &modes[..modes.len() - 1],
            AmgParams::default()
        ),
        Err(AmgError::NearNullspace { .. })
    ));
    // NaN in the matrix, at set-up and at a refresh.
    let mut values = a.val().to_vec();
    values[5] = f64::NAN;
    let nan = SparseColMat::new(a.symbolic().to_owned().unwrap(), values);
    assert!(matches!(
        Amg::new(nan.as_ref(), 3, &modes, AmgParams::default()),
        Err(AmgError::NonFinite)
    ));
    let mut amg = Amg::new(a.as_ref(), 3, &modes, small_coarse()).unwrap();
    assert!(matches!(
        amg.refresh(nan.as_ref()),
        Err(AmgError::NonFinite)
    ));
    // NaN in the near-nullspace.
    let mut bad_modes = modes.clone();
    bad_modes[3] = f64::NAN;
    assert!(matches!(
        Amg::new(a.as_ref(), 3, &bad_modes, AmgParams::default()),
        Err(AmgError::NonFinite)
    ));
    // A refresh with another pattern.
    let (other, _) = cloth(11);
    assert!(matches!(
        amg.refresh(other.as_ref()),
        Err(AmgError::PatternMismatch)
    ));
    // Not positive definite: −A.
    let negative = SparseColMat::new(
        a.symbolic().to_owned().unwrap(),
        a.val().iter().map(|v| -v).collect(),
    );
    assert!(matches!(
        Amg::new(negative.as_ref(), 3, &modes, AmgParams::default()),
        Err(AmgError::NotPositiveDefinite { level: 0, .. })
    ));
    // Parameters out of range.
    for params in [
        AmgParams {
            strength_threshold: f64::NAN,
            ..AmgParams::default()
        },
        AmgParams {
            prolongator_damping: 2.0,
            ..AmgParams::default()
        },
        AmgParams {
            smoother_sweeps: 0,
            ..AmgParams::default()
        },
    ] {
        assert!(matches!(
            Amg::new(a.as_ref(), 3, &modes, params),
            Err(AmgError::InvalidParameter(_))
        ));
    }
    assert_eq!(n % 3, 0);
}

/// Newton-CG preconditioned by AMG, set up once on the clamped Hessian at the initial guess y
/// (and not refreshed: a fixed SPD preconditioner for every Newton iteration), reaches Newton's
/// minimiser to the objective error docs/model.md §9.2 holds solvers to.
fn newton_cg_with_amg_reaches_newton(mesh: &SpringMesh<3>, pinned: &[u32]) {
    let mut s = step(mesh, pinned, 1.0 / 30.0, 0.05);
    let solution = newton_solution(&mut s);
    let mut x = s.start.clone();
    let h = s.problem.convexified_hessian(&x).expect("clamped Hessian");
    let h = SparseColMat::new(h.symbolic().to_owned().unwrap(), h.val().to_vec());
    let modes = Amg::rigid_body_modes(&x);
    let mut amg = Amg::new(h.as_ref(), 3, &modes, AmgParams::default()).unwrap();
    let params = NewtonCgParams {
        convergence: Convergence::RelativeGradient,
        tolerance: 1e-11,
        ..Default::default()
    };
    let report = NewtonCg::new(s.problem.dim(), params)
        .unwrap()
        .minimize(&mut s.problem, &mut amg, &mut x)
        .unwrap();
    let error = objective_error(&mut s, &x, &solution);
    eprintln!(
        "Newton-CG with AMG: {} iterations, {} CG iterations, objective error {error:e}",
        report.iterations, report.cg_iterations
    );
    assert!(
        matches!(report.stop, StopReason::Converged | StopReason::RoundOff),
        "{:?}",
        report.stop
    );
    assert!(error.abs() <= 1e-10, "objective error {error:e}");
}

#[test]
fn newton_cg_with_amg_reaches_newtons_solution_on_cloth_10() {
    newton_cg_with_amg_reaches_newton(&generators::cloth(10, 1e3).unwrap(), &[0, 9]);
}

#[test]
fn newton_cg_with_amg_reaches_newtons_solution_on_beam_2() {
    let mesh = generators::beam(2).unwrap();
    newton_cg_with_amg_reaches_newton(&mesh, &clamped(&mesh));
}

/// D right-hand sides at once: each column's V-cycle is the one-value cycle on that column (to the
/// rounding of the coarsest solve, whose multi-column triangular solves may sum in another order:
/// 1e-12 relative, far below the cycle's own contraction), and the column product is the
/// one-value product bit for bit; on one thread and two the same bits.
#[test]
fn columns_are_the_one_value_cycle_on_each_column() {
    let (a, x) = cloth(20);
    let modes = Amg::rigid_body_modes(&x);
    let n = a.nrows();
    let columns: Vec<Vec<f64>> = (0..3).map(|c| random(n, 20 + c)).collect();
    let r: Vec<nalgebra::Vector3<f64>> = (0..n)
        .map(|i| nalgebra::Vector3::new(columns[0][i], columns[1][i], columns[2][i]))
        .collect();
    let run = |threads: usize| {
        on_threads(threads, || {
            let mut amg = Amg::new(a.as_ref(), 3, &modes, small_coarse()).unwrap();
            assert!(amg.level_count() >= 3, "{:?}", amg.level_sizes());
            let mut work = amg.columns_workspace::<3>();
            let mut z = vec![nalgebra::Vector3::zeros(); n];
            amg.apply_columns(&mut work, &r, &mut z);
            let mut product = vec![nalgebra::Vector3::zeros(); n];
            amg.product_columns(&r, &mut product);
            (amg, z, product)
        })
    };
    let (mut amg, z, product) = run(1);
    let (_, z2, product2) = run(2);
    let bits = |v: &[nalgebra::Vector3<f64>]| -> Vec<u64> {
        v.iter()
            .flat_map(|p| p.iter().map(|c| c.to_bits()))
            .collect()
    };
    assert_eq!(bits(&z), bits(&z2));
    assert_eq!(bits(&product), bits(&product2));
    for (c, column) in columns.iter().enumerate() {
        let mut one = vec![0.0; n];
        amg.apply(column, &mut one);
        let scale = norm(&one);
        let apart = (0..n).map(|i| (z[i][c] - one[i]).abs()).fold(0.0, f64::max);
        assert!(apart <= 1e-12 * scale, "column {c}: {apart:e} of {scale:e}");
        let mut ax = vec![0.0; n];
        hooke_solvers::LinearOperator::apply(&amg, column, &mut ax);
        assert!((0..n).all(|i| product[i][c].to_bits() == ax[i].to_bits()));
    }
}

/// The sweeps split into parts (hybrid Gauss–Seidel) on cloth-56's Hessian (9,402 rows: its
/// finest level is split): the cycle stays symmetric positive definite, PCG with it reaches the
/// direct solution in about the plain sweeps' iterations, and the bits do not depend on the
/// thread count.
#[test]
fn sweeps_split_into_parts_stay_symmetric_and_thread_count_free() {
    let (a, x) = cloth(56);
    assert!(a.nrows() >= hooke_solvers::AMG_PARTS_MIN_ROWS);
    let serial = AmgParams {
        smoother_parts: 1,
        ..AmgParams::default()
    };
    let plain = reaches_the_direct_solution(a.as_ref(), &x, serial);
    for parts in [2, 3] {
        let params = AmgParams {
            smoother_parts: parts,
            ..AmgParams::default()
        };
        symmetric_positive_definite_with(a.as_ref(), &x, params);
        let split = reaches_the_direct_solution(a.as_ref(), &x, params);
        assert!(
            split <= plain + plain / 2,
            "{parts} parts: {split} PCG iterations, {plain} with plain sweeps"
        );
        let run = |threads: usize| {
            on_threads(threads, || {
                let modes = Amg::rigid_body_modes(&x);
                let mut amg = Amg::new(a.as_ref(), 3, &modes, params).unwrap();
                let b = random(a.nrows(), 13);
                let mut z = vec![0.0; b.len()];
                amg.apply(&b, &mut z);
                z
            })
        };
        let (one, two) = (run(1), run(2));
        assert!(one
            .iter()
            .zip(&two)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
        // The split sweeps are another smoother: not the plain sweeps' bits.
        let modes = Amg::rigid_body_modes(&x);
        let mut plain_amg = Amg::new(a.as_ref(), 3, &modes, serial).unwrap();
        let b = random(a.nrows(), 13);
        let mut z = vec![0.0; b.len()];
        plain_amg.apply(&b, &mut z);
        assert!(
            z.iter().zip(&one).any(|(p, q)| p != q),
            "{parts} parts: the plain sweeps' result"
        );
    }
}
