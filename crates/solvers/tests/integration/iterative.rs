//! Iterative solvers against a direct (dense Cholesky) solve, and their stop reasons.

use hooke_solvers::{
    BlockJacobi, CgParams, ConjugateGradient, Identity, Jacobi, JacobiParams, SolveError,
    StopReason,
};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;

/// A random SPD matrix XᵀX + I of size 3m (whole 3×3 blocks), with X entries in [−1, 1].
fn spd() -> impl Strategy<Value = DMatrix<f64>> {
    (1usize..=8).prop_flat_map(|m| {
        let n = 3 * m;
        proptest::collection::vec(-1.0f64..1.0, n * n).prop_map(move |v| {
            let x = DMatrix::from_vec(n, n, v);
            x.transpose() * &x + DMatrix::identity(n, n)
        })
    })
}

/// A weighted graph Laplacian of a random graph on m vertices, ⊗ I₃, plus a positive diagonal shift:
/// symmetric, strictly block diagonally dominant, hence SPD and a system Jacobi converges on.
fn laplacian_like() -> impl Strategy<Value = DMatrix<f64>> {
    (2usize..=10).prop_flat_map(|m| {
        (
            proptest::collection::vec((0..m, 0..m, 0.1f64..10.0), 1..3 * m),
            proptest::collection::vec(0.01f64..1.0, m),
        )
            .prop_map(move |(edges, shift)| {
                let mut a = DMatrix::zeros(3 * m, 3 * m);
                for (i, j, k) in edges {
                    if i == j {
                        continue;
                    }
                    for d in 0..3 {
                        a[(3 * i + d, 3 * i + d)] += k;
                        a[(3 * j + d, 3 * j + d)] += k;
                        a[(3 * i + d, 3 * j + d)] -= k;
                        a[(3 * j + d, 3 * i + d)] -= k;
                    }
                }
                for (v, s) in shift.into_iter().enumerate() {
                    for d in 0..3 {
                        a[(3 * v + d, 3 * v + d)] += s;
                    }
                }
                a
            })
    })
}

fn rhs(n: usize) -> DVector<f64> {
    DVector::from_fn(n, |k, _| ((k * 7 + 3) % 11) as f64 - 5.0)
}

/// Check ‖x − x*‖ ≤ κ(A) · (relative residual reached) · ‖x*‖ · 10: the standard bound
/// ‖e‖/‖x*‖ ≤ κ ‖r‖/‖b‖, with a factor 10 for round-off in forming the residual.
fn assert_close_to_direct(a: &DMatrix<f64>, b: &DVector<f64>, x: &[f64], residual: f64) {
    let direct = a.clone().cholesky().expect("SPD").solve(b);
    let eigen = a.clone().symmetric_eigen().eigenvalues;
    let kappa = eigen.max() / eigen.min();
    let error = (DVector::from_column_slice(x) - &direct).norm();
    let bound = 10.0 * kappa * residual.max(f64::EPSILON) * direct.norm();
    assert!(
        error <= bound,
        "error {error:e} above the bound {bound:e} (κ = {kappa:e})"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn cg_matches_the_direct_solve(a in prop_oneof![spd(), laplacian_like()]) {
        let n = a.nrows();
        let b = rhs(n);
        let params = CgParams { tolerance: 1e-10, max_iterations: 10 * n };
        for preconditioned in [false, true] {
            let mut x = vec![0.0; n];
            let mut cg = ConjugateGradient::new(params);
            let report = if preconditioned {
                cg.solve(&a, &mut BlockJacobi::<3>::from_dense(&a).unwrap(), b.as_slice(), &mut x)
            } else {
                cg.solve(&a, &mut Identity, b.as_slice(), &mut x)
            }
            .unwrap();
            prop_assert_eq!(report.stop, StopReason::Converged);
            prop_assert_eq!(report.residuals.len(), report.iterations + 1);
            assert_close_to_direct(&a, &b, &x, report.residual());
        }
    }

    #[test]
    fn jacobi_matches_the_direct_solve_on_dominant_systems(a in laplacian_like()) {
        let n = a.nrows();
        let b = rhs(n);
        let mut x = vec![0.0; n];
        // Strict dominance can be weak (shift ≥ 0.01 against weights up to 10 × 30 edges), so the
        // contraction can be slow: allow many iterations of this cheap method.
        let params = JacobiParams { tolerance: 1e-10, max_iterations: 200_000, ..Default::default() };
        let report = Jacobi::new(params)
            .solve(&a, &BlockJacobi::<3>::from_dense(&a).unwrap(), b.as_slice(), &mut x)
            .unwrap();
        prop_assert_eq!(report.stop, StopReason::Converged);
        assert_close_to_direct(&a, &b, &x, report.residual());
    }

    #[test]
    fn the_iteration_limit_is_reported(a in spd()) {
        let n = a.nrows();
        prop_assume!(n >= 6);
        let b = rhs(n);
        let mut x = vec![0.0; n];
        let params = CgParams { tolerance: 1e-14, max_iterations: 2 };
        let report = ConjugateGradient::new(params).solve(&a, &mut Identity, b.as_slice(), &mut x).unwrap();
        prop_assert_eq!(report.stop, StopReason::IterationLimit);
        prop_assert_eq!(report.iterations, 2);
        let jacobi = JacobiParams { tolerance: 1e-14, max_iterations: 2, divergence_factor: f64::INFINITY, ..Default::default() };
        let mut x = vec![0.0; n];
        match Jacobi::new(jacobi).solve(&a, &BlockJacobi::<3>::from_dense(&a).unwrap(), b.as_slice(), &mut x) {
            Ok(report) => {
                prop_assert_eq!(report.stop, StopReason::IterationLimit);
                prop_assert_eq!(report.iterations, 2);
            }
            Err(e) => prop_assert!(matches!(e, SolveError::NonFinite { .. }), "{e}"),
        }
    }
}

#[test]
fn cg_reports_an_indefinite_system() {
    let a = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, -1.0, 2.0]));
    let mut x = vec![0.0; 3];
    match ConjugateGradient::default().solve(&a, &mut Identity, &[1.0, 1.0, 1.0], &mut x) {
        Err(SolveError::NotPositiveDefinite { curvature, report }) => {
            assert!(curvature <= 0.0);
            assert_eq!(report.stop, StopReason::NotPositiveDefinite);
            assert_eq!(report.residuals.len(), report.iterations + 1);
        }
        other => panic!("expected NotPositiveDefinite, got {other:?}"),
    }
}

#[test]
fn jacobi_reports_divergence_on_a_non_dominant_system() {
    // Spectral radius of D⁻¹(L + U) is 2: the error doubles every iteration.
    let a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
    let diagonal = BlockJacobi::<1>::from_dense(&a).unwrap();
    let mut x = vec![0.0; 2];
    match Jacobi::default().solve(&a, &diagonal, &[1.0, 0.0], &mut x) {
        Err(SolveError::Diverged { report }) => {
            assert!(
                report.iterations < 20,
                "stopped early, after {} iterations",
                report.iterations
            );
            assert!(report.residual() > 1e3 * report.residuals[0]);
            assert_eq!(report.stop, StopReason::Diverged);
        }
        other => panic!("expected Diverged, got {other:?}"),
    }
}

#[test]
fn a_singular_block_is_named() {
    let mut a = DMatrix::identity(6, 6);
    a[(4, 4)] = 0.0;
    assert_eq!(
        BlockJacobi::<3>::from_dense(&a).unwrap_err(),
        SolveError::SingularBlock { block: 1 }
    );
}

#[test]
fn refilled_blocks_equal_freshly_built_ones() {
    // Two different matrices on the same block structure: refilling the first one's inverses with
    // the second's blocks gives exactly (bit for bit: the same inversion) a fresh build.
    let first = DMatrix::from_fn(9, 9, |i, j| if i == j { 5.0 } else { 0.5 });
    let second = DMatrix::from_fn(9, 9, |i, j| {
        if i == j {
            3.0 + i as f64
        } else {
            0.25 * ((i + 2 * j) % 5) as f64
        }
    });
    let mut blocks = BlockJacobi::<3>::identity(3);
    assert_eq!(blocks.dim(), 9);
    assert_eq!(blocks.block_count(), 3);
    let block = |a: &DMatrix<f64>, k: usize| a.fixed_view::<3, 3>(3 * k, 3 * k).into_owned();
    blocks.refill((0..3).map(|k| block(&first, k))).unwrap();
    assert_eq!(blocks, BlockJacobi::<3>::from_dense(&first).unwrap());
    blocks.refill((0..3).map(|k| block(&second, k))).unwrap();
    assert_eq!(blocks, BlockJacobi::<3>::from_dense(&second).unwrap());
    // Each inverse times its block is the identity, to round-off of entries O(10).
    for (k, inverse) in blocks.inverses().iter().enumerate() {
        let error = (inverse * block(&second, k) - nalgebra::Matrix3::identity()).amax();
        assert!(error < 1e-14, "block {k}: |A⁻¹A − I| = {error:e}");
    }
    // A singular block is named, as by `from_blocks`.
    let mut singular = second.clone();
    singular[(7, 7)] = 0.0;
    singular[(7, 6)] = 0.0;
    singular[(7, 8)] = 0.0;
    assert_eq!(
        blocks.refill((0..3).map(|k| block(&singular, k))),
        Err(SolveError::SingularBlock { block: 2 })
    );
}

#[test]
#[should_panic(expected = "2 blocks given for 3")]
fn refilling_with_too_few_blocks_is_a_contract_violation() {
    let mut blocks = BlockJacobi::<3>::identity(3);
    let _ = blocks.refill(std::iter::repeat_n(nalgebra::Matrix3::identity(), 2));
}

#[test]
#[should_panic(expected = "more than 3 blocks given")]
fn refilling_with_too_many_blocks_is_a_contract_violation() {
    let mut blocks = BlockJacobi::<3>::identity(3);
    let _ = blocks.refill(std::iter::repeat_n(nalgebra::Matrix3::identity(), 4));
}

#[test]
fn solving_again_reuses_the_workspace_and_gives_the_same_bits() {
    let a = DMatrix::from_fn(9, 9, |i, j| {
        if i == j {
            4.0
        } else {
            1.0 / (1.0 + (i + j) as f64)
        }
    });
    let b = rhs(9);
    let mut cg = ConjugateGradient::default();
    let mut x1 = vec![0.0; 9];
    let mut x2 = vec![0.0; 9];
    cg.solve(&a, &mut Identity, b.as_slice(), &mut x1).unwrap();
    cg.solve(&a, &mut Identity, b.as_slice(), &mut x2).unwrap();
    assert_eq!(x1, x2);
}
