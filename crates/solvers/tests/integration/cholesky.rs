//! The sparse Cholesky wrapper against a dense solve, in every configuration.

use faer::sparse::{SparseColMat, Triplet};
use faer::Mat;
use hooke_solvers::{CholeskyError, CholeskyParams, FactorKind, SparseCholesky, SPLIT_MIN_FACTOR};
use nalgebra::{DMatrix, DVector};

/// A grid graph Laplacian (4-neighbour, stiffness varying by edge) plus a mass diagonal: the scalar
/// matrix M + h²L of projective dynamics on an m × m cloth.
fn grid_system(m: usize, scale: f64) -> (SparseColMat<usize, f64>, DMatrix<f64>) {
    let n = m * m;
    let mut dense = DMatrix::zeros(n, n);
    for i in 0..m {
        for j in 0..m {
            let v = i * m + j;
            dense[(v, v)] += 1.0 + 0.1 * ((v % 7) as f64);
            for (di, dj) in [(1, 0), (0, 1), (1, 1)] {
                if i + di < m && j + dj < m {
                    let u = (i + di) * m + j + dj;
                    let k = scale * (1.0 + ((v + u) % 5) as f64);
                    dense[(v, v)] += k;
                    dense[(u, u)] += k;
                    dense[(v, u)] -= k;
                    dense[(u, v)] -= k;
                }
            }
        }
    }
    let mut triplets = Vec::new();
    for c in 0..n {
        for r in 0..n {
            if dense[(r, c)] != 0.0 {
                triplets.push(Triplet::new(r, c, dense[(r, c)]));
            }
        }
    }
    (
        SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap(),
        dense,
    )
}

fn rhs(n: usize, columns: usize) -> Mat<f64> {
    Mat::from_fn(n, columns, |i, j| ((i * 5 + j * 3) % 13) as f64 - 6.0)
}

#[test]
fn every_configuration_matches_the_dense_solve() {
    let (a, dense) = grid_system(20, 30.0);
    let n = a.nrows();
    let b = rhs(n, 3);
    let cholesky = dense.clone().cholesky().unwrap();
    let eigen = dense.symmetric_eigen().eigenvalues;
    let kappa = eigen.max() / eigen.min();
    for kind in [
        FactorKind::Auto,
        FactorKind::Simplicial,
        FactorKind::Supernodal,
    ] {
        for threads in [1, 2] {
            let params = CholeskyParams {
                kind,
                factor_threads: threads,
                solve_threads: threads,
                ..CholeskyParams::default()
            };
            let mut llt = SparseCholesky::analyze(a.symbolic(), params).unwrap();
            match kind {
                FactorKind::Simplicial => assert!(!llt.is_supernodal()),
                FactorKind::Supernodal => assert!(llt.is_supernodal()),
                FactorKind::Auto => {}
            }
            llt.factorize(a.as_ref()).unwrap();
            let mut x = b.clone();
            llt.solve_in_place(x.as_mut());
            for col in 0..3 {
                let expected = cholesky.solve(&DVector::from_fn(n, |i, _| b[(i, col)]));
                let error = (0..n)
                    .map(|i| (x[(i, col)] - expected[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                // Backward-stable solves: forward error ≤ c · κ · ε · ‖x‖ with a modest c.
                let bound = 100.0 * kappa * f64::EPSILON * expected.norm();
                assert!(
                    error <= bound,
                    "{kind:?}, {threads} thread(s), column {col}: error {error:e} > {bound:e}"
                );
            }
        }
    }
}

#[test]
fn refactorisation_equals_a_fresh_factorisation() {
    let (a1, _) = grid_system(15, 1.0);
    let (a2, _) = grid_system(15, 1e4);
    let b = rhs(a1.nrows(), 3);
    for kind in [FactorKind::Simplicial, FactorKind::Supernodal] {
        let params = CholeskyParams {
            kind,
            ..Default::default()
        };
        let mut reused = SparseCholesky::analyze(a1.symbolic(), params).unwrap();
        reused.factorize(a1.as_ref()).unwrap();
        reused.factorize(a2.as_ref()).unwrap();
        let mut fresh = SparseCholesky::analyze(a2.symbolic(), params).unwrap();
        fresh.factorize(a2.as_ref()).unwrap();
        let (mut x1, mut x2) = (b.clone(), b.clone());
        reused.solve_in_place(x1.as_mut());
        fresh.solve_in_place(x2.as_mut());
        assert!(
            x1 == x2,
            "{kind:?}: refactorised and fresh solutions differ"
        );
    }
}

#[test]
fn wide_right_hand_sides_are_solved_three_columns_at_a_time() {
    let (a, _) = grid_system(8, 2.0);
    let mut llt = SparseCholesky::analyze(a.symbolic(), CholeskyParams::default()).unwrap();
    llt.factorize(a.as_ref()).unwrap();
    let b = rhs(a.nrows(), 7);
    let mut wide = b.clone();
    llt.solve_in_place(wide.as_mut());
    for col in 0..7 {
        let mut one: Vec<f64> = (0..a.nrows()).map(|i| b[(i, col)]).collect();
        llt.solve_slice(&mut one);
        assert!(
            (0..a.nrows()).all(|i| one[i] == wide[(i, col)]),
            "column {col}"
        );
    }
}

#[test]
fn bad_matrices_are_reported() {
    let (a, dense) = grid_system(6, 1.0);
    let n = a.nrows();
    let mut llt = SparseCholesky::analyze(a.symbolic(), CholeskyParams::default()).unwrap();
    // Indefinite: flip the sign of the whole matrix.
    let mut triplets = Vec::new();
    for c in 0..n {
        for r in 0..n {
            if dense[(r, c)] != 0.0 {
                triplets.push(Triplet::new(r, c, -dense[(r, c)]));
            }
        }
    }
    let negative = SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap();
    assert!(matches!(
        llt.factorize(negative.as_ref()),
        Err(CholeskyError::NotPositiveDefinite { .. })
    ));
    // NaN.
    triplets[0].val = f64::NAN;
    let nan = SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap();
    assert_eq!(llt.factorize(nan.as_ref()), Err(CholeskyError::NonFinite));
    // Another pattern.
    let (other, _) = grid_system(7, 1.0);
    assert!(matches!(
        llt.factorize(other.as_ref()),
        Err(CholeskyError::PatternMismatch { .. })
    ));
    // The same size and number of entries, one symmetric pair moved elsewhere: the row indices
    // are checked, not only their count.
    let present = (0..n)
        .flat_map(|c| (c + 1..n).map(move |r| (r, c)))
        .find(|&(r, c)| dense[(r, c)] != 0.0)
        .unwrap();
    let absent = (0..n)
        .flat_map(|c| (c + 1..n).map(move |r| (r, c)))
        .find(|&(r, c)| dense[(r, c)] == 0.0)
        .unwrap();
    let mut moved = Vec::new();
    for c in 0..n {
        for r in 0..n {
            let (r2, c2) = if (r, c) == present {
                absent
            } else if (c, r) == present {
                (absent.1, absent.0)
            } else {
                (r, c)
            };
            if dense[(r, c)] != 0.0 {
                moved.push(Triplet::new(r2, c2, dense[(r, c)]));
            }
        }
    }
    let moved = SparseColMat::try_new_from_triplets(n, n, &moved).unwrap();
    assert_eq!(moved.compute_nnz(), a.compute_nnz());
    let expected_column = present.1.min(absent.1);
    match llt.factorize(moved.as_ref()) {
        Err(CholeskyError::PatternMismatch { column, .. }) => {
            assert_eq!(column, Some(expected_column))
        }
        other => panic!("expected a pattern mismatch, got {other:?}"),
    }
    // And it recovers on a good matrix.
    llt.factorize(a.as_ref()).unwrap();
}

#[test]
fn faer_matrices_are_operators_and_factors_are_preconditioners() {
    use hooke_solvers::{
        CgParams, ConjugateGradient, Identity, LinearOperator, StopReason, Symmetric,
    };
    let (a, dense) = grid_system(12, 50.0);
    let n = a.nrows();
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let expected = &dense * DVector::from_column_slice(&x);
    let (mut general, mut symmetric) = (vec![0.0; n], vec![0.0; n]);
    a.apply(&x, &mut general);
    Symmetric(a.as_ref()).apply(&x, &mut symmetric);
    for i in 0..n {
        // Sums of at most 7 products of O(100) values: round-off well under 1e-12 relative.
        assert!(
            (general[i] - expected[i]).abs() <= 1e-12 * expected.amax(),
            "row {i}"
        );
        assert!(
            (symmetric[i] - expected[i]).abs() <= 1e-12 * expected.amax(),
            "row {i}"
        );
    }
    let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64 - 2.0).collect();
    let params = CgParams {
        tolerance: 1e-10,
        max_iterations: 10 * n,
    };
    // Unpreconditioned CG needs many iterations on this stiff system ...
    let mut plain = vec![0.0; n];
    let unpreconditioned = ConjugateGradient::new(params)
        .solve(&Symmetric(a.as_ref()), &mut Identity, &b, &mut plain)
        .unwrap();
    // ... preconditioned by the Cholesky factor of a nearby matrix (stiffness halved), far fewer.
    let (nearby, _) = grid_system(12, 25.0);
    let mut llt = SparseCholesky::analyze(nearby.symbolic(), CholeskyParams::default()).unwrap();
    llt.factorize(nearby.as_ref()).unwrap();
    let mut x = vec![0.0; n];
    let report = ConjugateGradient::new(params)
        .solve(&Symmetric(a.as_ref()), &mut llt, &b, &mut x)
        .unwrap();
    assert_eq!(report.stop, StopReason::Converged);
    assert!(
        report.iterations * 3 < unpreconditioned.iterations,
        "Cholesky-preconditioned CG took {} iterations, plain CG {}",
        report.iterations,
        unpreconditioned.iterations
    );
}

#[test]
fn ldlt_reports_the_inertia_and_solves_indefinite_systems() {
    // M + h²L shifted down by σ between its eigenvalues: indefinite with a known number of negative
    // eigenvalues (σ chosen midway between two consecutive ones so no pivot is near zero).
    let (a, dense) = grid_system(12, 3.0);
    let n = a.nrows();
    let mut eigen: Vec<f64> = dense
        .clone()
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .copied()
        .collect();
    eigen.sort_by(f64::total_cmp);
    for negative in [0, 1, 7, n / 2] {
        let sigma = if negative == 0 {
            0.5 * eigen[0]
        } else {
            0.5 * (eigen[negative - 1] + eigen[negative])
        };
        let shifted_dense = &dense - DMatrix::identity(n, n) * sigma;
        let mut triplets = Vec::new();
        for c in 0..n {
            for r in 0..n {
                if dense[(r, c)] != 0.0 {
                    triplets.push(Triplet::new(r, c, shifted_dense[(r, c)]));
                }
            }
        }
        let shifted = SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap();
        let b = rhs(n, 2);
        let expected: Vec<DVector<f64>> = (0..2)
            .map(|col| {
                shifted_dense
                    .clone()
                    .lu()
                    .solve(&DVector::from_fn(n, |i, _| b[(i, col)]))
                    .unwrap()
            })
            .collect();
        // κ of the shifted matrix: its eigenvalues are λ − σ.
        let smallest = eigen
            .iter()
            .map(|l| (l - sigma).abs())
            .fold(f64::INFINITY, f64::min);
        let largest = eigen.iter().map(|l| (l - sigma).abs()).fold(0.0, f64::max);
        let kappa = largest / smallest;
        for kind in [FactorKind::Simplicial, FactorKind::Supernodal] {
            let params = CholeskyParams {
                kind,
                ..Default::default()
            };
            let mut ldlt = SparseCholesky::analyze(a.symbolic(), params).unwrap();
            let inertia = ldlt.factorize_ldlt(shifted.as_ref()).unwrap();
            assert_eq!(
                (inertia.negative, inertia.positive),
                (negative, n - negative),
                "{kind:?}: inertia of a matrix with {negative} negative eigenvalues"
            );
            assert_eq!(inertia.is_positive_definite(), negative == 0);
            let mut x = b.clone();
            ldlt.solve_in_place(x.as_mut());
            for (col, expected) in expected.iter().enumerate() {
                let error = (0..n)
                    .map(|i| (x[(i, col)] - expected[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                // LDLᵀ without pivoting is not backward stable in general, but on this mildly
                // indefinite, diagonally heavy matrix its growth is small: hold it to the same
                // c · κ · ε bound as the definite solves.
                let bound = 100.0 * kappa * f64::EPSILON * expected.norm();
                assert!(
                    error <= bound,
                    "{kind:?}, {negative} negative, column {col}: error {error:e} > {bound:e}"
                );
            }
        }
    }
}

#[test]
fn ldlt_reports_a_zero_pivot_as_singular() {
    // Pairs coupled as [[1, 1], [1, 1]]: whichever of a pair is eliminated first, the other's pivot
    // is 1 − 1·1 = 0 exactly, in any order.
    let n = 8;
    let mut triplets = Vec::new();
    for p in 0..n / 2 {
        let (a, b) = (2 * p, 2 * p + 1);
        for (r, c) in [(a, a), (a, b), (b, a), (b, b)] {
            triplets.push(Triplet::new(r, c, 1.0));
        }
    }
    let singular = SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap();
    let mut ldlt = SparseCholesky::analyze(singular.symbolic(), CholeskyParams::default()).unwrap();
    assert!(matches!(
        ldlt.factorize_ldlt(singular.as_ref()),
        Err(CholeskyError::Singular { .. })
    ));
}

/// A solve split over two threads (a factor above SPLIT_MIN_FACTOR) gives the bits of the serial
/// solve, for PD's matrix of cloth-160 and three right-hand sides.
#[test]
fn split_solves_give_the_serial_bits() {
    use hooke_assembly::{FreeDofs, LaplacianPattern};
    let n = 160;
    let mesh = hooke_mesh::generators::cloth(n, 1e3).unwrap();
    let free = FreeDofs::new(mesh.vertex_count(), &[0, n as u32 - 1]).unwrap();
    let pattern = LaplacianPattern::new(mesh.vertex_count(), mesh.springs(), Some(&free));
    let mut values = pattern.new_values();
    pattern.system_into(mesh.springs(), mesh.masses(), 1.0 / 30.0, &mut values);
    let size = pattern.size();
    let b = Mat::<f64>::from_fn(size, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
    let solve = |threads: usize| {
        let params = CholeskyParams {
            kind: FactorKind::Simplicial,
            solve_threads: threads,
            ..CholeskyParams::default()
        };
        let mut llt = SparseCholesky::analyze(pattern.symbolic(), params).unwrap();
        llt.factorize(pattern.matrix(&values)).unwrap();
        assert!(llt.factor_nnz() >= SPLIT_MIN_FACTOR, "{}", llt.factor_nnz());
        let mut x = b.clone();
        llt.solve_in_place(x.as_mut());
        x
    };
    let (serial, split) = (solve(1), solve(2));
    for j in 0..3 {
        for i in 0..size {
            assert_eq!(
                serial[(i, j)].to_bits(),
                split[(i, j)].to_bits(),
                "({i}, {j})"
            );
        }
    }
    assert!(serial.norm_l2() > 0.0);
}
