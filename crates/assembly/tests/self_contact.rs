//! The self-contact barrier summed over a surface (hooke_assembly::self_contact) on two sheets a
//! fraction of d̂ apart, with generated offsets and jitter: its gradient against central
//! differences of its energy, its exact Hessian against central differences of its gradient, the
//! projected Hessian positive semidefinite, the in-place assembly equal to the block-by-block one,
//! and parallel equal to serial bit for bit.

use hooke_assembly::self_contact::{SelfContactBarrier, SelfContactModel};
use hooke_assembly::{Definiteness, HessianPattern};
use nalgebra::{DMatrix, DVector, Vector3};
use proptest::prelude::*;

#[path = "common/sheets.rs"]
mod sheets;
use sheets::two_sheets;

/// Reach d̂ (m) and stiffness κ (N/m) of every case.
const D_HAT: f64 = 1e-3;
const KAPPA: f64 = 1e3;

fn barrier(positions: &[Vector3<f64>], triangles: &[[u32; 3]]) -> SelfContactBarrier {
    let model = SelfContactModel {
        triangles: triangles.to_vec(),
        rest_positions: positions.to_vec(),
        distance: D_HAT,
        stiffness: KAPPA,
        friction: 0.0,
        friction_velocity: 1e-3,
    };
    SelfContactBarrier::new(model, vec![true; positions.len()])
}

fn gradient(b: &mut SelfContactBarrier, x: &[Vector3<f64>]) -> DVector<f64> {
    let mut g = vec![Vector3::zeros(); x.len()];
    b.add_gradient(x, 1.0, &mut g);
    DVector::from_iterator(3 * x.len(), g.iter().flat_map(|v| v.iter().copied()))
}

fn dense_hessian(
    b: &mut SelfContactBarrier,
    x: &[Vector3<f64>],
    definiteness: Definiteness,
) -> DMatrix<f64> {
    let n = 3 * x.len();
    let mut h = DMatrix::zeros(n, n);
    b.for_each_hessian_block(x, 1.0, definiteness, |i, j, block| {
        let mut view = h.fixed_view_mut::<3, 3>(3 * i, 3 * j);
        view += block;
    });
    h
}

fn moved(x: &[Vector3<f64>], k: usize, step: f64) -> Vec<Vector3<f64>> {
    let mut y = x.to_vec();
    y[k / 3][k % 3] += step;
    y
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    #[test]
    fn derivatives_match_differences_and_parallel_matches_serial(
        gap in 2e-4..8e-4f64,
        // Offsets and jitter keep the points off the triangles' edges and the edges off exact
        // alignment: where two closest-feature regions meet, the Hessian jumps and a central
        // difference across the seam measures neither side.
        sx in 0.05..0.95f64,
        sz in 0.05..0.95f64,
        jitter in 1e-6..5e-5f64,
    ) {
        let (x, triangles) = two_sheets(5, gap, sx, sz, jitter);
        let mut b = barrier(&x, &triangles);
        let energy = b.energy(&x);
        let (point_triangle, edge_edge) = b.active_counts(&x);
        prop_assert!(energy > 0.0 && point_triangle + edge_edge > 0, "the sheets are within d̂");
        let g = gradient(&mut b, &x);

        // Central differences with a step of 1e-7 m: the barrier's derivatives change on the
        // scale of the gap d ≥ 2e-4 m, so the truncation error relative to the gradient (and of
        // the gradient's differences to the Hessian) is about (step/d)² ≤ 2.5e-7; rounding adds
        // ε·E/step, far less (E ≈ κ d̂² = 1e-3 J against |∇E| ≈ κ d̂ = 1 N).
        let step = 1e-7;
        let mut fd = DVector::zeros(g.len());
        for k in 0..g.len() {
            fd[k] = (b.energy(&moved(&x, k, step)) - b.energy(&moved(&x, k, -step))) / (2.0 * step);
        }
        let scale = g.norm();
        prop_assert!((&fd - &g).norm() <= 1e-6 * scale, "gradient: |fd − g| = {:e}, |g| = {scale:e}", (&fd - &g).norm());

        let h = dense_hessian(&mut b, &x, Definiteness::Exact);
        let mut fd_h = DMatrix::zeros(g.len(), g.len());
        for k in 0..g.len() {
            let column = (gradient(&mut b, &moved(&x, k, step)) - gradient(&mut b, &moved(&x, k, -step))) / (2.0 * step);
            fd_h.set_column(k, &column);
        }
        let h_scale = h.norm();
        prop_assert!((&fd_h - &h).norm() <= 1e-6 * h_scale, "Hessian: |fd − H| = {:e}, |H| = {h_scale:e}", (&fd_h - &h).norm());
        prop_assert_eq!(&h, &h.transpose(), "the exact Hessian is exactly symmetric");

        // The projection is positive semidefinite up to rounding of its entries.
        let clamped = dense_hessian(&mut b, &x, Definiteness::Clamped);
        let smallest = clamped.clone().symmetric_eigen().eigenvalues.min();
        prop_assert!(smallest >= -1e-12 * clamped.norm(), "smallest eigenvalue {smallest:e}");

        // In place into a pattern: the same values as block by block.
        let mut links = Vec::new();
        b.links(&x, &mut links);
        let pattern = HessianPattern::<3>::with_links(x.len(), &[], &links, None);
        let mut values = pattern.new_values();
        prop_assert!(b.add_hessian_into(&x, 1.0, Definiteness::Exact, &pattern, Some, &mut values));
        let assembled = pattern.to_sparse_col_mat(&values).to_dense();
        for c in 0..h.ncols() {
            for r in 0..h.nrows() {
                prop_assert_eq!(assembled[(r, c)], h[(r, c)]);
            }
        }

        // Serial gives the parallel bits.
        let mut serial = barrier(&x, &triangles);
        serial.set_parallel(false);
        prop_assert_eq!(serial.energy(&x).to_bits(), energy.to_bits());
        prop_assert_eq!(gradient(&mut serial, &x), g);
        prop_assert_eq!(dense_hessian(&mut serial, &x, Definiteness::Exact), h);
    }
}

/// The energy change of a move has the same bits whether the candidates were searched for this
/// move alone or are a larger set kept from an earlier search (which reuses them while its boxes
/// cover the move): only terms within d̂ at one end of the move count, in pair order.
#[test]
fn the_energy_change_does_not_depend_on_earlier_searches() {
    // 9×9 sheets 0.6 d̂ apart, the upper one with a wobble: dozens of pairs within d̂, and more
    // candidates within the search's reach.
    let (x, triangles) = two_sheets(9, 0.6 * D_HAT, 0.3, 0.4, 0.05 * D_HAT);
    let delta: Vec<Vector3<f64>> = (0..x.len())
        .map(|k| {
            let k = k as f64;
            Vector3::new((k * 0.7).sin(), (k * 1.3).cos(), (k * 0.9).sin()) * (0.05 * D_HAT)
        })
        .collect();
    let mut fresh = barrier(&x, &triangles);
    let change = fresh.energy_change(&x, &delta);
    assert!(change.is_finite() && change != 0.0, "{change:e}");
    // An earlier search along a move that also slides the upper sheet by 0.3 m finds a
    // superset, whose boxes then cover the move.
    let mut seasoned = barrier(&x, &triangles);
    let upper = x.len() / 2;
    let long_move: Vec<Vector3<f64>> = delta
        .iter()
        .enumerate()
        .map(|(k, d)| d + Vector3::new(if k >= upper { 0.3 } else { 0.0 }, 0.0, 0.0))
        .collect();
    seasoned.pairs_near_move(&x, &long_move);
    let superset = seasoned.pairs_near(&x).len();
    let exact = fresh.pairs_near_move(&x, &delta).len();
    assert!(
        superset > exact,
        "{superset} candidates kept, {exact} found afresh"
    );
    for parallel in [false, true] {
        seasoned.set_parallel(parallel);
        assert_eq!(
            seasoned.energy_change(&x, &delta).to_bits(),
            change.to_bits()
        );
    }
}
