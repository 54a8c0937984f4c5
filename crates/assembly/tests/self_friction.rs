//! Self-contact friction (hooke_assembly::self_friction): the lag of one pair (closest points,
//! normal force, tangent basis) and its potential's gradient and Hessian against central
//! differences, for point–triangle pairs over a face and near an edge, crossing edges and nearly
//! parallel edges, with generated configurations and moves in both of f₀'s regimes; the Hessian
//! exactly symmetric and positive semidefinite; the force within Coulomb's bound μλ. Over two
//! sheets: the summed gradient against differences of the summed potential, the change against
//! the difference of potentials, the in-place assembly equal to the block-by-block one, and
//! parallel equal to serial bit for bit.

use hooke_assembly::barrier::barrier_derivative;
use hooke_assembly::self_contact::{SelfContactBarrier, SelfContactModel, SurfacePair};
use hooke_assembly::self_friction::{lag_pair_friction, PairFriction, SelfContactFriction};
use hooke_assembly::surface_barrier::{edge_edge_distance, point_triangle_distance};
use hooke_assembly::HessianPattern;
use hooke_collision::distance::{
    edge_edge_case, edge_edge_cross_squared, edge_edge_mollifier_threshold, mollifier,
    point_triangle_case, EdgeEdgeCase, PointTriangleCase,
};
use nalgebra::{DMatrix, DVector, SMatrix, SVector, Vector3};
use proptest::prelude::*;

#[path = "common/sheets.rs"]
mod sheets;
use sheets::two_sheets;

type Vec3 = Vector3<f64>;

/// Reach d̂ (m), stiffness κ (N/m), friction μ and smoothing length ε = ε_v h (m) of every case:
/// ε_v = 1e-3 m/s and h = 1/30 s would give 3.3e-5 m; 1e-4 m keeps the numbers round.
const D_HAT: f64 = 1e-2;
const KAPPA: f64 = 1e3;
const MU: f64 = 0.4;
const EPS: f64 = 1e-4;

fn vec3() -> impl Strategy<Value = Vec3> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(a, b, c)| Vec3::new(a, b, c))
}

/// Relative error of `a` against `b`, measured on the scale of `b`'s largest entry.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// A point at a height in (0.15, 0.85)·d̂ above a spot of a unit-sized triangle: over its face
/// where `(u, v)` is inside, beyond an edge or a corner where it is not.
fn point_triangle_config() -> impl Strategy<Value = [Vec3; 4]> {
    (
        vec3(),
        vec3(),
        vec3(),
        -0.2..1.2f64,
        -0.2..1.2f64,
        0.15..0.85f64,
    )
        .prop_filter_map("a well-shaped triangle", |(t0, t1, t2, u, v, height)| {
            let n = (t1 - t0).cross(&(t2 - t0));
            if n.norm() < 0.2 {
                return None;
            }
            let spot = t0 + (t1 - t0) * u + (t2 - t0) * v * (1.0 - u).max(0.0);
            let p = spot + n.normalize() * (height * D_HAT);
            let d = point_triangle_distance(&[p, t0, t1, t2]);
            (d > 0.1 * D_HAT && d < 0.9 * D_HAT).then_some([p, t0, t1, t2])
        })
}

/// A point just beyond an edge of a triangle (inside the triangle's plane's slab of d̂), so that
/// its closest feature is the edge: the case "near an edge".
fn point_near_edge_config() -> impl Strategy<Value = [Vec3; 4]> {
    (
        vec3(),
        vec3(),
        vec3(),
        0.1..0.9f64,
        0.1..0.7f64,
        -0.7..0.7f64,
    )
        .prop_filter_map("a well-shaped triangle", |(t0, t1, t2, s, out, up)| {
            let n = (t1 - t0).cross(&(t2 - t0));
            if n.norm() < 0.2 {
                return None;
            }
            let n = n.normalize();
            let e = t1 - t0;
            // Outward in the plane, across edge t0–t1 (away from t2).
            let inward = n.cross(&e).normalize();
            let outward = if inward.dot(&(t2 - t0)) > 0.0 {
                -inward
            } else {
                inward
            };
            let p = t0 + e * s + (outward * out + n * up) * D_HAT;
            let x = [p, t0, t1, t2];
            let d = point_triangle_distance(&x);
            (d > 0.1 * D_HAT && d < 0.9 * D_HAT).then_some(x)
        })
}

/// Edge b crossing over edge a at height·d̂, turned by an angle (near 0 with `parallel`: nearly
/// parallel, where the mollifier acts, sin θ ≥ 1e-3).
fn edge_edge_config(parallel: bool) -> impl Strategy<Value = [Vec3; 4]> {
    (
        vec3(),
        vec3(),
        0.01..0.3f64,
        any::<bool>(),
        0.2..0.8f64,
        0.2..0.8f64,
        -0.3..0.3f64,
    )
        .prop_filter_map(
            "edges within reach",
            move |(a0, a1, tilt, flip, u, height, slide)| {
                let ea = a1 - a0;
                if ea.norm() < 0.3 {
                    return None;
                }
                let normal = ea.cross(&Vec3::new(0.3, -0.5, 0.8));
                if normal.norm() < 0.1 {
                    return None;
                }
                let normal = normal.normalize();
                let across = normal.cross(&ea).normalize();
                let sign = if flip { -1.0 } else { 1.0 };
                let angle = sign * if parallel { tilt * 1e-1 } else { 0.5 + tilt };
                let dir = ea.normalize() * angle.cos() + across * angle.sin();
                let mid = a0 + ea * u + normal * (height * D_HAT) + ea.normalize() * slide * 0.1;
                let x = [a0, a1, mid - dir * 0.4, mid + dir * 0.4];
                let d = edge_edge_distance(&x);
                (d > 0.15 * D_HAT && d < 0.85 * D_HAT).then_some(x)
            },
        )
}

/// A move of every vertex: a shared tangential slide of length up to 3ε (so both regimes of f₀,
/// the smoothed one below ε and Coulomb's beyond) plus a smaller independent part per vertex.
fn moves() -> impl Strategy<Value = [Vec3; 4]> {
    (vec3(), vec3(), vec3(), vec3(), vec3(), 0.0..3.0f64).prop_map(|(s, a, b, c, d, length)| {
        let slide = s * (length * EPS);
        let own = 0.3 * EPS;
        [a * own + slide, b * own, c * own, d * own]
    })
}

fn add(x: &[Vec3; 4], m: &[Vec3; 4]) -> [Vec3; 4] {
    [x[0] + m[0], x[1] + m[1], x[2] + m[2], x[3] + m[3]]
}

fn nudged(x: &[Vec3; 4], k: usize, step: f64) -> [Vec3; 4] {
    let mut y = *x;
    y[k / 3][k % 3] += step;
    y
}

/// Checks of one lagged pair at the lag point `start` and a moved configuration `x`:
/// - the lag: weights summing to 0 whose Σ wᵢ xᵢ has the pair's distance as length (so they are
///   the closest points) and lies along the normal; an orthonormal tangent basis orthogonal to
///   the normal; λ = −κ m b'(d);
/// - a rigid translation of the pair gives u = 0;
/// - the gradient against central differences of the energy, the Hessian against central
///   differences of the gradient, the Hessian exactly symmetric and positive semidefinite;
/// - the force within μλ, and at μλ once the slide exceeds ε;
/// - the change against the difference of energies.
fn check_pair(pair: &SurfacePair, start: &[Vec3; 4], x: &[Vec3; 4]) -> Result<(), TestCaseError> {
    let friction = lag_pair_friction(pair, start, D_HAT, KAPPA, MU).expect("within reach");
    let (d, m) = match pair {
        SurfacePair::PointTriangle(_) => (point_triangle_distance(start), 1.0),
        SurfacePair::EdgeEdge(_, eps_x) => {
            let c = edge_edge_cross_squared(&start[0], &start[1], &start[2], &start[3]);
            (edge_edge_distance(start), mollifier(c, *eps_x))
        }
    };
    let w = friction.weights;
    prop_assert!((w.iter().sum::<f64>()).abs() < 1e-15);
    let gap = start[0] * w[0] + start[1] * w[1] + start[2] * w[2] + start[3] * w[3];
    // The closest points' distance to the pair's distance: both computed from coordinates of
    // order 1, so they agree to ~1e-15 m, 1e-12 of d ≥ 1.5e-3 m.
    prop_assert!(
        (gap.norm() - d).abs() <= 1e-12,
        "|Σ w x| = {:e}, d = {d:e}",
        gap.norm()
    );
    prop_assert!((gap.dot(&friction.normal).abs() - d).abs() <= 1e-12);
    let [t0, t1] = friction.tangents;
    for (a, b, expected) in [
        (t0, t0, 1.0),
        (t1, t1, 1.0),
        (t0, t1, 0.0),
        (t0, friction.normal, 0.0),
        (t1, friction.normal, 0.0),
    ] {
        prop_assert!((a.dot(&b) - expected).abs() < 1e-14);
    }
    let lambda = -KAPPA * m * barrier_derivative(d, D_HAT);
    prop_assert!((friction.normal_force - lambda).abs() <= 1e-13 * lambda);
    let shift = Vec3::new(0.3, -0.2, 0.7) * EPS;
    let translated = start.map(|p| p + shift);
    prop_assert!(friction.tangential(&translated, start).norm() < 1e-15);

    // Central differences with a step of 1e-4 ε. The potential's third derivatives in u are of
    // the order of μλ/ε² below ε (f₀'s cubic) and μλ/y² beyond, so the truncation error of a
    // difference relative to the gradient (μλ f₁ ≥ μλ·2y/ε·½) is at most ~step²/(ε y) below ε
    // and (step/y)² beyond; skipping slides |u| < 0.02 ε bounds it by 5e-7. Moves within 10 steps
    // of |u| = ε are skipped too: f₀'s third derivative jumps there, and a difference across the
    // jump errs by ~step/ε. Rounding (coordinates of order 1, ~1e-16 m, over the step of 1e-8 m)
    // adds ~1e-8.
    let step = 1e-4 * EPS;
    let y = friction.tangential(x, start).norm();
    prop_assume!(y > 0.02 * EPS && (y - EPS).abs() > 10.0 * step);
    let terms = friction.terms(x, start, EPS, true);
    let mut fd = SVector::<f64, 12>::zeros();
    let mut fd_h = SMatrix::<f64, 12, 12>::zeros();
    for k in 0..12 {
        let (plus, minus) = (nudged(x, k, step), nudged(x, k, -step));
        fd[k] = (friction.energy(&plus, start, EPS) - friction.energy(&minus, start, EPS))
            / (2.0 * step);
        let column = (friction.terms(&plus, start, EPS, false).gradient
            - friction.terms(&minus, start, EPS, false).gradient)
            / (2.0 * step);
        fd_h.set_column(k, &column);
    }
    prop_assert!(
        relative(terms.gradient.as_slice(), fd.as_slice()) < 1e-5,
        "gradient: {:e}",
        relative(terms.gradient.as_slice(), fd.as_slice())
    );
    prop_assert!(
        relative(terms.hessian.as_slice(), fd_h.as_slice()) < 1e-5,
        "Hessian: {:e}",
        relative(terms.hessian.as_slice(), fd_h.as_slice())
    );
    prop_assert_eq!(terms.hessian, terms.hessian.transpose());
    let scale = terms.hessian.amax();
    let smallest = terms.hessian.symmetric_eigenvalues().min();
    prop_assert!(
        smallest >= -1e-12 * scale,
        "smallest eigenvalue {smallest:e}"
    );
    prop_assert!((terms.energy - friction.energy(x, start, EPS)).abs() <= 1e-15 * terms.energy);

    // Coulomb's bound, and the gradient is the force mapped back by wᵢ T.
    let bound = MU * friction.normal_force;
    let force = friction.force(x, start, EPS);
    prop_assert!(force.norm() <= bound * (1.0 + 1e-14));
    if y > EPS {
        prop_assert!((force.norm() - bound).abs() <= 1e-14 * bound);
    }
    let g3 = -(t0 * force[0] + t1 * force[1]);
    for (i, wi) in w.iter().enumerate() {
        let block = terms.gradient.fixed_rows::<3>(3 * i);
        prop_assert!((block - g3 * *wi).amax() <= 1e-14 * bound);
    }

    // The change without cancellation against the difference of energies for a move of 0.1 ε
    // (that difference is accurate to ~1e-15 μλε/ (0.1 μλε) = 1e-14 of it).
    let delta = [
        Vec3::new(0.1, -0.3, 0.2),
        Vec3::new(-0.2, 0.1, 0.0),
        Vec3::new(0.3, 0.2, -0.1),
        Vec3::new(0.0, -0.1, 0.3),
    ]
    .map(|v| v * EPS);
    let change = friction.energy_change(x, start, &delta, EPS);
    let direct = friction.energy(&add(x, &delta), start, EPS) - friction.energy(x, start, EPS);
    prop_assert!(
        (change - direct).abs() <= 1e-9 * bound * EPS,
        "{change:e} vs {direct:e}"
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn point_over_a_face(start in point_triangle_config(), m in moves()) {
        let case = point_triangle_case(&start[0], &start[1], &start[2], &start[3]);
        prop_assume!(case == PointTriangleCase::Face);
        check_pair(&SurfacePair::PointTriangle([0, 1, 2, 3]), &start, &add(&start, &m))?;
        // Over the face the normal is the triangle's.
        let friction = lag_pair_friction(&SurfacePair::PointTriangle([0, 1, 2, 3]), &start, D_HAT, KAPPA, MU).unwrap();
        let n = (start[2] - start[1]).cross(&(start[3] - start[1])).normalize();
        prop_assert!((friction.normal.dot(&n).abs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn point_near_an_edge(start in point_near_edge_config(), m in moves()) {
        let case = point_triangle_case(&start[0], &start[1], &start[2], &start[3]);
        prop_assume!(matches!(case, PointTriangleCase::Edge(_)));
        check_pair(&SurfacePair::PointTriangle([0, 1, 2, 3]), &start, &add(&start, &m))?;
    }

    #[test]
    fn crossing_edges(start in edge_edge_config(false), m in moves()) {
        prop_assume!(edge_edge_case(&start[0], &start[1], &start[2], &start[3]) == EdgeEdgeCase::LineLine);
        let eps_x = edge_edge_mollifier_threshold(&start[0], &start[1], &start[2], &start[3]);
        check_pair(&SurfacePair::EdgeEdge([0, 1, 2, 3], eps_x), &start, &add(&start, &m))?;
    }

    #[test]
    fn nearly_parallel_edges(start in edge_edge_config(true), m in moves()) {
        let eps_x = edge_edge_mollifier_threshold(&start[0], &start[1], &start[2], &start[3]);
        let c = edge_edge_cross_squared(&start[0], &start[1], &start[2], &start[3]);
        prop_assert!(c < eps_x, "the mollifier acts on these edges");
        check_pair(&SurfacePair::EdgeEdge([0, 1, 2, 3], eps_x), &start, &add(&start, &m))?;
    }
}

/// Parallel edges a tiny distance apart (1e-9 d̂, below the share where the closest points'
/// difference gives the normal), and a point on a triangle's plane 1e-9 d̂ away: the normal falls
/// back to the edges' offset and the triangle's normal, a unit vector orthogonal to the tangents.
#[test]
fn the_normal_falls_back_to_the_shape_when_the_gap_is_tiny() {
    let tiny = 1e-9 * D_HAT;
    let edges = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.2, tiny, 0.0),
        Vec3::new(0.8, tiny, 0.0),
    ];
    let pair = SurfacePair::EdgeEdge([0, 1, 2, 3], 1e-3);
    // Exactly parallel: the mollifier vanishes, and so does the normal force.
    assert!(lag_pair_friction(&pair, &edges, D_HAT, KAPPA, MU).is_none());
    let mut tilted = edges;
    tilted[3].z += 1e-2;
    let f = lag_pair_friction(&pair, &tilted, D_HAT, KAPPA, MU).unwrap();
    assert!((f.normal.norm() - 1.0).abs() < 1e-15);
    assert!(f.tangents.iter().all(|t| t.dot(&f.normal).abs() < 1e-15));
    let triangle = [
        Vec3::new(0.3, 0.3, tiny),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let f = lag_pair_friction(
        &SurfacePair::PointTriangle([0, 1, 2, 3]),
        &triangle,
        D_HAT,
        KAPPA,
        MU,
    )
    .unwrap();
    assert!((f.normal.z.abs() - 1.0).abs() < 1e-15, "{:?}", f.normal);
}

fn surface(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    start: &[Vec3],
    parallel: bool,
) -> SelfContactFriction {
    let d_hat = 1e-3;
    let model = SelfContactModel {
        triangles: triangles.to_vec(),
        rest_positions: positions.to_vec(),
        distance: d_hat,
        stiffness: KAPPA,
        friction: MU,
        friction_velocity: 1e-3,
    };
    let free = vec![true; positions.len()];
    let mut barrier = SelfContactBarrier::new(model, free.clone());
    barrier.set_parallel(parallel);
    let mut friction = SelfContactFriction::new(MU, 1e-3, free);
    friction.set_parallel(parallel);
    // h = 0.1 s: ε = 1e-4 m.
    friction.lag(&mut barrier, start, 0.1);
    friction
}

fn gradient(f: &mut SelfContactFriction, x: &[Vec3]) -> DVector<f64> {
    let mut g = vec![Vec3::zeros(); x.len()];
    f.add_gradient(x, 1.0, &mut g);
    DVector::from_iterator(3 * x.len(), g.iter().flat_map(|v| v.iter().copied()))
}

fn dense_hessian(f: &mut SelfContactFriction, x: &[Vec3]) -> DMatrix<f64> {
    let n = 3 * x.len();
    let mut h = DMatrix::zeros(n, n);
    f.for_each_hessian_block(x, 1.0, |i, j, block| {
        let mut view = h.fixed_view_mut::<3, 3>(3 * i, 3 * j);
        view += block;
    });
    h
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// The summed friction of two sheets a fraction of d̂ apart, lagged there, after the upper
    /// sheet slides by up to 3ε (with jitter per vertex).
    #[test]
    fn summed_friction_matches_differences_and_parallel_matches_serial(
        gap in 2e-4..8e-4f64,
        sx in 0.05..0.95f64,
        sz in 0.05..0.95f64,
        jitter in 1e-6..5e-5f64,
        slide in (-3.0..3.0f64, -3.0..3.0f64),
    ) {
        let (x0, triangles) = two_sheets(5, gap, sx, sz, jitter);
        let mut f = surface(&x0, &triangles, &x0, true);
        prop_assert!(!f.pairs().is_empty(), "the sheets are within d̂");
        let eps = f.smoothing_length();
        prop_assert!((eps - 1e-4).abs() < 1e-18);
        let half = x0.len() / 2;
        let x: Vec<Vec3> = x0
            .iter()
            .enumerate()
            .map(|(v, p)| {
                let k = v as f64;
                let wobble = Vec3::new((k * 0.7).cos(), (k * 1.3).cos(), (k * 0.9).cos()) * (0.2 * eps);
                let sliding = if v >= half { Vec3::new(slide.0, 0.0, slide.1) * eps } else { Vec3::zeros() };
                p + wobble + sliding
            })
            .collect();
        let energy = f.energy(&x);
        let g = gradient(&mut f, &x);
        // Central differences with a step of 1e-3 ε, as for a single pair; with many pairs some
        // may sit within a few steps of |u| = 0 or ε, where a difference errs by ~step/ε per
        // pair: 1e-4 of the gradient's norm leaves room for that and none for a wrong term (a
        // wrong weight or tangent changes the gradient by its own size).
        let step = 1e-3 * eps;
        let moved = |k: usize, s: f64| {
            let mut y = x.clone();
            y[k / 3][k % 3] += s;
            y
        };
        let mut fd = DVector::zeros(g.len());
        for k in 0..g.len() {
            fd[k] = (f.energy(&moved(k, step)) - f.energy(&moved(k, -step))) / (2.0 * step);
        }
        prop_assert!((&fd - &g).norm() <= 1e-4 * g.norm(), "gradient: |fd − g| = {:e}, |g| = {:e}", (&fd - &g).norm(), g.norm());
        let h = dense_hessian(&mut f, &x);
        let mut fd_h = DMatrix::zeros(g.len(), g.len());
        for k in 0..g.len() {
            fd_h.set_column(k, &((gradient(&mut f, &moved(k, step)) - gradient(&mut f, &moved(k, -step))) / (2.0 * step)));
        }
        prop_assert!((&fd_h - &h).norm() <= 1e-4 * h.norm(), "Hessian: |fd − H| = {:e}, |H| = {:e}", (&fd_h - &h).norm(), h.norm());
        prop_assert_eq!(&h, &h.transpose());
        let smallest = h.clone().symmetric_eigen().eigenvalues.min();
        prop_assert!(smallest >= -1e-12 * h.norm(), "smallest eigenvalue {smallest:e}");

        // The change against the difference of potentials, for a move of 0.1 ε.
        let delta: Vec<Vec3> = (0..x.len()).map(|v| Vec3::new((v as f64).sin(), 0.3, (v as f64 * 2.0).cos()) * (0.1 * eps)).collect();
        let end: Vec<Vec3> = x.iter().zip(&delta).map(|(a, b)| a + b).collect();
        let change = f.energy_change(&x, &delta);
        let direct = f.energy(&end) - energy;
        prop_assert!((change - direct).abs() <= 1e-9 * energy, "{change:e} vs {direct:e}");

        // In place into a pattern made of its links: the block-by-block values.
        let mut links = Vec::new();
        f.links(&mut links);
        let pattern = HessianPattern::<3>::with_links(x.len(), &[], &links, None);
        let mut values = pattern.new_values();
        prop_assert!(f.add_hessian_into(&x, 1.0, &pattern, Some, &mut values));
        let assembled = pattern.to_sparse_col_mat(&values).to_dense();
        for c in 0..h.ncols() {
            for r in 0..h.nrows() {
                prop_assert_eq!(assembled[(r, c)], h[(r, c)]);
            }
        }

        // Serial gives the parallel bits, lag included.
        let mut serial = surface(&x0, &triangles, &x0, false);
        prop_assert_eq!(serial.pairs(), f.pairs());
        prop_assert_eq!(serial.energy(&x).to_bits(), energy.to_bits());
        prop_assert_eq!(serial.energy_change(&x, &delta).to_bits(), change.to_bits());
        prop_assert_eq!(gradient(&mut serial, &x), g);
        prop_assert_eq!(dense_hessian(&mut serial, &x), h);
    }
}

/// The lag depends on the start positions alone: a barrier whose candidates were found from
/// elsewhere (another configuration, then the start) lags the same pairs in the same order.
#[test]
fn the_lag_does_not_depend_on_the_barriers_history() {
    let (x0, triangles) = two_sheets(5, 5e-4, 0.3, 0.6, 2e-5);
    let model = SelfContactModel {
        triangles: triangles.clone(),
        rest_positions: x0.clone(),
        distance: 1e-3,
        stiffness: KAPPA,
        friction: MU,
        friction_velocity: 1e-3,
    };
    let free = vec![true; x0.len()];
    let mut fresh = SelfContactBarrier::new(model.clone(), free.clone());
    let mut a = SelfContactFriction::new(MU, 1e-3, free.clone());
    a.lag(&mut fresh, &x0, 0.1);
    let mut used = SelfContactBarrier::new(model, free.clone());
    // Candidates found for a move of the upper sheet (a different broad-phase order).
    let delta: Vec<Vec3> = (0..x0.len())
        .map(|v| {
            if v >= x0.len() / 2 {
                Vec3::new(0.02, 0.0, -0.03)
            } else {
                Vec3::zeros()
            }
        })
        .collect();
    used.pairs_near_move(&x0, &delta);
    let mut b = SelfContactFriction::new(MU, 1e-3, free);
    b.lag(&mut used, &x0, 0.1);
    assert!(!a.pairs().is_empty());
    assert_eq!(a.pairs(), b.pairs());
    let pairs: &[PairFriction] = a.pairs();
    assert!(pairs
        .windows(2)
        .all(|w| (!w[0].point_triangle, w[0].vertices) < (!w[1].point_triangle, w[1].vertices)));
}

/// Scaling the normal forces scales the potential and its gradient by the same factor.
#[test]
fn scaled_normal_forces_scale_the_terms() {
    let (x0, triangles) = two_sheets(5, 5e-4, 0.3, 0.6, 2e-5);
    let mut f = surface(&x0, &triangles, &x0, false);
    let x: Vec<Vec3> = x0.iter().map(|p| p + Vec3::new(2e-4, 0.0, -1e-4)).collect();
    let (energy, g) = (f.energy(&x), gradient(&mut f, &x));
    f.scale_normal_forces(4.0);
    assert!((f.energy(&x) - 4.0 * energy).abs() <= 1e-14 * energy);
    assert!((gradient(&mut f, &x) - &g * 4.0).amax() <= 1e-14 * g.amax());
}

/// μ = 0 lags nothing: no terms, no links.
#[test]
fn no_friction_lags_nothing() {
    let (x0, triangles) = two_sheets(5, 5e-4, 0.3, 0.6, 2e-5);
    let model = SelfContactModel {
        triangles,
        rest_positions: x0.clone(),
        distance: 1e-3,
        stiffness: KAPPA,
        friction: 0.0,
        friction_velocity: 1e-3,
    };
    let free = vec![true; x0.len()];
    let mut barrier = SelfContactBarrier::new(model, free.clone());
    let mut f = SelfContactFriction::new(0.0, 1e-3, free);
    f.lag(&mut barrier, &x0, 0.1);
    assert!(f.pairs().is_empty());
    let mut links = Vec::new();
    f.links(&mut links);
    assert!(links.is_empty());
    assert_eq!(f.energy(&x0), 0.0);
}
