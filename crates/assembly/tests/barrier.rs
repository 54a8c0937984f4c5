//! Property tests of the contact terms (hooke_assembly::barrier): the barrier's and friction's
//! derivatives against central differences, definiteness, continuity at d̂ and ε, the
//! cancellation-free differences, and the time of impact's roots and feasibility guarantee, in 2D
//! and 3D.

#![allow(clippy::needless_range_loop)] // analytic and FD vectors are compared entry by entry

use hooke_assembly::barrier::*;
use hooke_assembly::{fd, Definiteness};
use nalgebra::{DMatrix, SMatrix, SVector};
use proptest::prelude::*;

const EPS: f64 = f64::EPSILON;

fn unit<const D: usize>(v: &[f64]) -> SVector<f64, D> {
    let mut u = SVector::<f64, D>::from_column_slice(v);
    if u.norm() < 1e-3 {
        u = SVector::zeros();
        u[0] = 1.0;
    }
    u.normalize()
}

/// A unit vector orthogonal to `n` (from the raw vector `v`).
fn orthogonal_unit<const D: usize>(n: &SVector<f64, D>, v: &[f64]) -> SVector<f64, D> {
    let mut t = SVector::<f64, D>::from_column_slice(v);
    t -= n * n.dot(&t);
    if t.norm() < 1e-3 {
        // Any axis not parallel to n.
        let axis = if n[0].abs() < 0.9 { 0 } else { 1 };
        t = SVector::zeros();
        t[axis] = 1.0;
        t -= n * n.dot(&t);
    }
    t.normalize()
}

fn eigenvalues<const D: usize>(m: &SMatrix<f64, D, D>) -> Vec<f64> {
    let mut e: Vec<f64> = DMatrix::from_column_slice(D, D, m.as_slice())
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .copied()
        .collect();
    e.sort_by(f64::total_cmp);
    e
}

fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo.log10()..=hi.log10()).prop_map(|e| 10f64.powf(e))
}

fn raw<const D: usize>() -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(-1.0f64..=1.0, D)
}

// ---------------------------------------------------------------------------------------------
// Barrier
// ---------------------------------------------------------------------------------------------

/// b''' = −(6 d̂ d + 2a²)/d³ and b'''' = (12 d̂ d − 4 a d + 6 a²)/d⁴ (a = d − d̂), for error bounds
/// and the Taylor reference.
fn barrier_third(d: f64, d_hat: f64) -> f64 {
    let a = d - d_hat;
    -(6.0 * d_hat * d + 2.0 * a * a) / (d * d * d)
}
fn barrier_fourth(d: f64, d_hat: f64) -> f64 {
    let a = d - d_hat;
    (12.0 * d_hat * d - 4.0 * a * d + 6.0 * a * a) / (d * d * d * d)
}

/// A vertex near an obstacle: d̂ ∈ [1e-4, 1e-1] m and κ ∈ [1, 1e6] N/m log-uniform, the distance
/// d = d̂·10^e with e uniform in [−6, log10(1 − 1e-4)] (the end points also drawn on their own), a
/// plane (point within d of the origin, so coordinates stay on the scale of d) or a sphere of
/// radius R ∈ [d̂, 100 d̂] (log-uniform) centred within R of the origin, and a random direction.
#[derive(Clone, Debug)]
struct Case<const D: usize> {
    obstacle: Obstacle<D>,
    x: SVector<f64, D>,
    d_hat: f64,
    stiffness: f64,
}

fn case<const D: usize>() -> impl Strategy<Value = Case<D>> {
    let top = (1.0f64 - 1e-4).log10();
    let exponent = prop_oneof![Just(-6.0), Just(top), -6.0f64..=top];
    (
        log_uniform(1e-4, 1e-1),
        log_uniform(1.0, 1e6),
        exponent,
        any::<bool>(),
        log_uniform(1.0, 100.0),
        raw::<D>(),
        raw::<D>(),
        raw::<D>(),
    )
        .prop_map(|(d_hat, stiffness, e, sphere, radius, a, b, c)| {
            let d = d_hat * 10f64.powf(e);
            let n = unit::<D>(&a);
            let t = orthogonal_unit(&n, &b);
            let offset = SVector::<f64, D>::from_column_slice(&c);
            if sphere {
                let radius = radius * d_hat;
                let center = offset * radius;
                let obstacle = Obstacle::sphere_outside(center, radius).unwrap();
                Case {
                    obstacle,
                    x: center + n * (radius + d),
                    d_hat,
                    stiffness,
                }
            } else {
                let point = offset * d;
                let obstacle = Obstacle::half_space(point, n).unwrap();
                Case {
                    obstacle,
                    x: point + n * d + t * (d * c[0]),
                    d_hat,
                    stiffness,
                }
            }
        })
}

/// The rounding error of the computed distance (m), a few ulps of the coordinates involved, and
/// the curvature length |x − c| (∞ for a plane).
fn distance_rounding<const D: usize>(obstacle: &Obstacle<D>, x: &SVector<f64, D>) -> (f64, f64) {
    match obstacle {
        Obstacle::HalfSpace { point, .. } => (4.0 * EPS * (x.norm() + point.norm()), f64::INFINITY),
        Obstacle::SphereOutside { center, radius } => (
            4.0 * EPS * (x.norm() + center.norm() + radius),
            (x - center).norm(),
        ),
    }
}

fn check_barrier_derivatives<const D: usize>(case: &Case<D>) {
    let Case {
        obstacle,
        x,
        d_hat,
        stiffness: k,
    } = case;
    let d = obstacle.distance(x);
    let exact = vertex_barrier(obstacle, x, *d_hat, *k, Definiteness::Exact).unwrap();
    let (e_d, curvature) = distance_rounding(obstacle, x);
    // The step resolves the shortest length on which the energy varies: d (the log), d̂ − d (b
    // vanishes like (d̂ − d)³ at d̂) and the sphere's radius of curvature |x − c|. With h = 1e-4 of
    // it, the truncation h²|E'''|/6 is ≈ 3e-9 of |∇E| (|E'''|/|E'| ≈ 2/L² for each of the three
    // scales), so 1e-6 relative is a safe, still sharp, bound. The rounding of E (ε|E| and the
    // distance's rounding e_d times |κ b'|) divided by h is added on top: it is what limits the
    // sphere cases where d ≪ R (the distance is only known to ε R).
    let h = 1e-4 * d.min(d_hat - d).min(curvature);
    let b1 = barrier_derivative(d, *d_hat).abs();
    let b2 = barrier_second_derivative(d, *d_hat);
    let energy = |p: &[f64]| {
        let x = SVector::<f64, D>::from_column_slice(p);
        vertex_barrier(obstacle, &x, *d_hat, *k, Definiteness::Exact).map_or(0.0, |t| t.energy)
    };
    let numeric = fd::gradient(energy, x.as_slice(), h);
    let tol = 1e-6 * exact.gradient.norm() + 4.0 * (k * b1 * e_d + 4.0 * EPS * exact.energy) / h;
    for a in 0..D {
        assert!(
            (numeric[a] - exact.gradient[a]).abs() <= tol,
            "gradient axis {a}: {} vs FD {} (tol {tol:e}, d {d:e}, d̂ {d_hat:e}, {obstacle:?})",
            exact.gradient[a],
            numeric[a]
        );
    }
    let jac = fd::jacobian(
        |p, out| {
            let x = SVector::<f64, D>::from_column_slice(p);
            let g = vertex_barrier(obstacle, &x, *d_hat, *k, Definiteness::Exact)
                .map_or(SVector::zeros(), |t| t.gradient);
            out.copy_from_slice(g.as_slice());
        },
        x.as_slice(),
        D,
        h,
    );
    // As above one order up (|E''''|/|E''| ≈ 6/L²); the gradient's rounding is κ(b'' e_d + |b'|
    // e_n) with the normal's rounding e_n ≈ 4ε + e_d/|x − c|.
    let e_n = 4.0 * EPS + e_d / curvature;
    let tol = 1e-6 * exact.hessian.amax() + 4.0 * k * (b2 * e_d + b1 * e_n) / h;
    for a in 0..D {
        for b in 0..D {
            assert!(
                (jac[(a, b)] - exact.hessian[(a, b)]).abs() <= tol,
                "Hessian ({a},{b}): {} vs FD {} (tol {tol:e}, d {d:e}, d̂ {d_hat:e}, {obstacle:?})",
                exact.hessian[(a, b)],
                jac[(a, b)]
            );
        }
    }
    assert_eq!(exact.hessian, exact.hessian.transpose());
}

fn check_clamped<const D: usize>(case: &Case<D>) {
    let Case {
        obstacle,
        x,
        d_hat,
        stiffness: k,
    } = case;
    let exact = vertex_barrier(obstacle, x, *d_hat, *k, Definiteness::Exact).unwrap();
    let clamped = vertex_barrier(obstacle, x, *d_hat, *k, Definiteness::Clamped).unwrap();
    assert_eq!(exact.energy, clamped.energy);
    assert_eq!(exact.gradient, clamped.gradient);
    assert_eq!(clamped.hessian, clamped.hessian.transpose());
    // Eigenvalues are computed to a few ε of the matrix norm.
    let e = eigenvalues(&clamped.hessian);
    assert!(e[0] >= -1e-13 * clamped.hessian.amax(), "not PSD: {e:?}");
    match obstacle {
        Obstacle::HalfSpace { .. } => assert_eq!(exact.hessian, clamped.hessian),
        Obstacle::SphereOutside { .. } => {
            // The projection: the exact block's eigenvalues with the negative ones set to 0.
            let mut projected: Vec<f64> = eigenvalues(&exact.hessian)
                .into_iter()
                .map(|v| v.max(0.0))
                .collect();
            projected.sort_by(f64::total_cmp);
            let scale = exact.hessian.amax();
            for (p, c) in projected.iter().zip(&e) {
                assert!((p - c).abs() <= 1e-12 * scale, "{projected:?} vs {e:?}");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn barrier_gradient_and_hessian_match_finite_differences_2d(c in case::<2>()) {
        check_barrier_derivatives(&c);
    }

    #[test]
    fn barrier_gradient_and_hessian_match_finite_differences_3d(c in case::<3>()) {
        check_barrier_derivatives(&c);
    }

    #[test]
    fn clamped_barrier_hessian_is_the_psd_projection_2d(c in case::<2>()) {
        check_clamped(&c);
    }

    #[test]
    fn clamped_barrier_hessian_is_the_psd_projection_3d(c in case::<3>()) {
        check_clamped(&c);
    }

    /// b' and b'' against central differences of b and b' in d alone, and b'' ≥ 0.
    #[test]
    fn barrier_derivatives_in_d(d_hat in log_uniform(1e-4, 1.0), e in -6.0f64..-1e-4) {
        let d = d_hat * 10f64.powf(e);
        // Step and tolerance as in the vertex tests: h = 1e-4 min(d, d̂ − d) makes the truncation
        // ≈ 3e-9 relative; rounding ε|b|/h is below 1e-10 relative over this range.
        let h = 1e-4 * d.min(d_hat - d);
        let b1 = barrier_derivative(d, d_hat);
        let b2 = barrier_second_derivative(d, d_hat);
        let fd1 = (barrier(d + h, d_hat) - barrier(d - h, d_hat)) / ((d + h) - (d - h));
        let fd2 = (barrier_derivative(d + h, d_hat) - barrier_derivative(d - h, d_hat))
            / ((d + h) - (d - h));
        prop_assert!((fd1 - b1).abs() <= 1e-6 * b1.abs(), "b' {b1} vs {fd1}");
        prop_assert!((fd2 - b2).abs() <= 1e-6 * b2.abs(), "b'' {b2} vs {fd2}");
        prop_assert!(b2 >= 0.0 && b1 < 0.0 && barrier(d, d_hat) > 0.0);
    }

    /// Where the direct difference is accurate (|δ| ≥ 1e-3 of the scale), the two agree to the
    /// direct difference's own rounding: a few ε of the larger value, plus what the rounding of
    /// its end point fl(d + δ) (up to ε/2 |d + δ|) moves b there, |b'| times that. Near d̂ the
    /// latter dominates: b vanishes as (d̂ − d)³, so |b'| d / b ≈ 3 d / (d̂ − d) is in the
    /// hundreds (the first case kept in contact.proptest-regressions: d = 0.98 d̂, 3.6 times the
    /// first term alone). The second kept case, δ = −0.9985 d, is the end near 0, where 1 + δ/d
    /// lost its digits before `barrier_change` took ln((d + δ)/d) there.
    #[test]
    fn barrier_change_agrees_with_the_direct_difference(
        d_hat in log_uniform(1e-4, 1.0),
        e in -6.0f64..0.0,
        s in prop_oneof![-0.999f64..-1e-3, 1e-3f64..2.0],
    ) {
        let d = d_hat * 10f64.powf(e);
        let delta = s * d;
        let end = d + delta;
        let (b0, b1) = (barrier(d, d_hat), barrier(end, d_hat));
        let change = barrier_change(d, delta, d_hat);
        let slope = barrier_derivative(end, d_hat).abs();
        let end_rounding = 0.5 * EPS * end.abs() * slope;
        prop_assert!(
            (change - (b1 - b0)).abs() <= 16.0 * EPS * b0.max(b1) + 2.0 * end_rounding,
            "{change} vs {} (b0 {b0}, b1 {b1})", b1 - b0
        );
    }

    /// For tiny δ (|δ| ≤ 1e-6 of the scale min(d, d̂ − d)) against the third-order Taylor
    /// polynomial, whose truncation |b''''| δ⁴/24 is added to the tolerance: the change is
    /// accurate to 1e-13 relative, where the direct difference has a relative error of about
    /// ε b / |b' δ| (up to 1 and more).
    #[test]
    fn barrier_change_is_accurate_for_tiny_steps(
        d_hat in log_uniform(1e-4, 1.0),
        e in -6.0f64..-1e-4,
        s in log_uniform(1e-15, 1e-6),
        negative in any::<bool>(),
    ) {
        let d = d_hat * 10f64.powf(e);
        let delta = if negative { -s } else { s } * d.min(d_hat - d);
        let reference = barrier_derivative(d, d_hat) * delta
            + barrier_second_derivative(d, d_hat) * delta * delta / 2.0
            + barrier_third(d, d_hat) * delta * delta * delta / 6.0;
        let truncation = 2.0 * barrier_fourth(d, d_hat).abs() * delta.powi(4) / 24.0;
        let change = barrier_change(d, delta, d_hat);
        prop_assert!(
            (change - reference).abs() <= 1e-13 * reference.abs() + truncation,
            "{change} vs {reference}"
        );
    }

    /// The sphere's distance change: against the direct difference for moderate steps (both within
    /// a few ε of the coordinates), and for tiny steps against the second-order expansion
    /// n·δ + (|δ|² − (n·δ)²)/(2|o|), with the formula's own rounding, a few ε |δ| (δ·(2o + δ) may
    /// cancel when δ ⟂ o), and the truncation |δ|³/|o|² as the tolerance.
    #[test]
    fn sphere_distance_change(
        c in case::<3>(),
        v in raw::<3>(),
        s in log_uniform(1e-14, 1.0),
    ) {
        let radius = 0.7;
        let sphere = Obstacle::sphere_outside(SVector::<f64, 3>::new(0.2, -0.1, 0.4), radius).unwrap();
        let o = c.x - SVector::<f64, 3>::new(0.2, -0.1, 0.4);
        let o = if o.norm() < 1e-3 { SVector::<f64, 3>::new(1.0, 0.0, 0.0) } else { o };
        let x = SVector::<f64, 3>::new(0.2, -0.1, 0.4) + o;
        let delta = SVector::<f64, 3>::from_column_slice(&v) * (s * o.norm());
        let change = sphere.distance_change(&x, &delta);
        let len = (x - SVector::<f64, 3>::new(0.2, -0.1, 0.4)).norm();
        if s > 1e-3 {
            let direct = sphere.distance(&(x + delta)) - sphere.distance(&x);
            prop_assert!((change - direct).abs() <= 16.0 * EPS * (len + delta.norm() + radius));
        } else {
            let n = sphere.normal(&x);
            let along = n.dot(&delta);
            let reference = along + (delta.norm_squared() - along * along) / (2.0 * len);
            let tol = 16.0 * EPS * delta.norm() + delta.norm().powi(3) / (len * len);
            prop_assert!((change - reference).abs() <= tol, "{change} vs {reference}");
        }
    }
}

#[test]
fn barrier_is_c2_at_d_hat_and_infinite_at_contact() {
    let d_hat = 1e-3;
    for scale in [1e-2, 1e-4, 1e-6, 1e-8] {
        let d = d_hat * (1.0 - scale);
        // b ≈ s³ d̂²... b' ≈ 3 s² d̂ and b'' ≈ 6 s with s = scale: each vanishes as d → d̂.
        assert!(barrier(d, d_hat) <= 2.0 * scale.powi(3) * d_hat * d_hat);
        assert!(barrier_derivative(d, d_hat).abs() <= 4.0 * scale * scale * d_hat);
        assert!(barrier_second_derivative(d, d_hat) <= 7.0 * scale);
    }
    for d in [d_hat, 2.0 * d_hat, f64::INFINITY] {
        assert_eq!(barrier(d, d_hat), 0.0);
        assert_eq!(barrier_derivative(d, d_hat), 0.0);
        assert_eq!(barrier_second_derivative(d, d_hat), 0.0);
    }
    for d in [0.0, -1e-3, f64::NEG_INFINITY] {
        assert_eq!(barrier(d, d_hat), f64::INFINITY);
        assert_eq!(barrier_derivative(d, d_hat), f64::NEG_INFINITY);
        assert_eq!(barrier_second_derivative(d, d_hat), f64::INFINITY);
    }
    assert!(barrier(f64::NAN, d_hat).is_nan());
    assert!(barrier_derivative(f64::NAN, d_hat).is_nan());
    assert!(barrier_second_derivative(f64::NAN, d_hat).is_nan());
}

#[test]
fn barrier_change_edge_cases_and_tiny_step_against_the_direct_difference() {
    let d_hat = 1e-3;
    let d = 0.3 * d_hat;
    assert_eq!(barrier_change(d, -d, d_hat), f64::INFINITY);
    assert_eq!(barrier_change(d, -2.0 * d, d_hat), f64::INFINITY);
    assert_eq!(barrier_change(-d, 2.0 * d, d_hat), f64::NEG_INFINITY);
    assert!(barrier_change(-d, 0.5 * d, d_hat).is_nan());
    assert!(barrier_change(f64::NAN, 0.5 * d, d_hat).is_nan());
    assert_eq!(barrier_change(2.0 * d_hat, d_hat, d_hat), 0.0);
    assert_eq!(
        barrier_change(2.0 * d_hat, -d_hat - d, d_hat),
        barrier(2.0 * d_hat + (-d_hat - d), d_hat)
    );
    assert_eq!(barrier_change(d, d_hat, d_hat), -barrier(d, d_hat));
    assert_eq!(barrier_change(d, 0.0, d_hat), 0.0);
    // δ = 1e-12 d: the change is b' δ to 1e-12 relative (the next term b''δ²/2 is 1e-12 of it).
    let delta = 1e-12 * d;
    let first_order = barrier_derivative(d, d_hat) * delta;
    let change = barrier_change(d, delta, d_hat);
    let direct = barrier(d + delta, d_hat) - barrier(d, d_hat);
    let ours = ((change - first_order) / first_order).abs();
    let theirs = ((direct - first_order) / first_order).abs();
    assert!(ours <= 1e-11, "{ours:e}");
    // The direct difference keeps about log10(b / (ε b)) − 12 ≈ 3 digits.
    assert!(
        theirs >= 1e3 * ours && theirs > 1e-7,
        "{theirs:e} vs {ours:e}"
    );
}

#[test]
fn vertex_barrier_outside_inside_and_nan() {
    let plane =
        Obstacle::half_space(SVector::<f64, 2>::zeros(), SVector::<f64, 2>::new(0.0, 2.0)).unwrap();
    let d_hat = 1e-2;
    assert!(vertex_barrier(
        &plane,
        &SVector::<f64, 2>::new(5.0, d_hat),
        d_hat,
        1e3,
        Definiteness::Exact
    )
    .is_none());
    let inside = vertex_barrier(
        &plane,
        &SVector::<f64, 2>::new(5.0, -1e-3),
        d_hat,
        1e3,
        Definiteness::Exact,
    )
    .unwrap();
    assert_eq!(inside.energy, f64::INFINITY);
    assert!(inside.gradient.iter().all(|v| v.is_nan()));
    let nan = vertex_barrier(
        &plane,
        &SVector::<f64, 2>::new(f64::NAN, 0.0),
        d_hat,
        1e3,
        Definiteness::Clamped,
    )
    .unwrap();
    assert!(nan.energy.is_nan());
    // Force pushes to the allowed side (+y), of magnitude −κ b'(d).
    let near = vertex_barrier(
        &plane,
        &SVector::<f64, 2>::new(5.0, 1e-3),
        d_hat,
        1e3,
        Definiteness::Exact,
    )
    .unwrap();
    assert_eq!(near.gradient[0], 0.0);
    assert_eq!(near.gradient[1], 1e3 * barrier_derivative(1e-3, d_hat));
    assert!(near.gradient[1] < 0.0);
}

#[test]
fn obstacle_constructors_and_sphere_centre() {
    let n = SVector::<f64, 3>::new(0.0, 3e-200, 4e-200);
    let Some(Obstacle::HalfSpace { normal, .. }) = Obstacle::half_space(SVector::zeros(), n) else {
        panic!("a tiny normal is a direction");
    };
    assert!((normal - SVector::<f64, 3>::new(0.0, 0.6, 0.8)).amax() <= 2.0 * EPS);
    let huge = SVector::<f64, 3>::new(1e300, 1e300, 0.0);
    assert!(Obstacle::half_space(SVector::zeros(), huge).is_some());
    assert!(Obstacle::half_space(SVector::zeros(), SVector::<f64, 3>::zeros()).is_none());
    assert!(Obstacle::half_space(SVector::zeros(), SVector::<f64, 3>::repeat(f64::NAN)).is_none());
    assert!(Obstacle::half_space(SVector::<f64, 3>::repeat(f64::INFINITY), n).is_none());
    assert!(Obstacle::sphere_outside(SVector::<f64, 3>::zeros(), 0.0).is_none());
    assert!(Obstacle::sphere_outside(SVector::<f64, 3>::zeros(), -1.0).is_none());
    assert!(Obstacle::sphere_outside(SVector::<f64, 3>::zeros(), f64::NAN).is_none());
    let sphere = Obstacle::sphere_outside(SVector::<f64, 3>::zeros(), 1.0).unwrap();
    let centre = SVector::<f64, 3>::zeros();
    assert_eq!(sphere.distance(&centre), -1.0);
    assert_eq!(sphere.normal(&centre), SVector::<f64, 3>::x());
    let h = sphere.distance_hessian(&centre);
    assert_eq!(h[(0, 0)], 0.0);
    assert_eq!(h[(1, 1)], f64::INFINITY);
    assert_eq!(h[(0, 1)], 0.0);
    assert_eq!(sphere.distance_change(&centre, &SVector::zeros()), 0.0);
    assert_eq!(
        sphere.distance_change(&centre, &SVector::<f64, 3>::y()),
        1.0
    );
}

// ---------------------------------------------------------------------------------------------
// Friction
// ---------------------------------------------------------------------------------------------

/// A lagged contact: μ ∈ [0.05, 1], λ ∈ [1e-3, 1e3] N and ε ∈ [1e-6, 1e-2] m log-uniform, a random
/// normal, and x with tangential displacement y = |u| = ε·10^e, e ∈ [−3, 3] but at least 1e-3 ε
/// from ε (where f₀''' jumps), plus a random normal offset of size ≤ y; start within y of the
/// origin, so coordinates stay on the scale of y.
fn friction_case<const D: usize>(
) -> impl Strategy<Value = (LaggedFriction<D>, SVector<f64, D>, f64)> {
    (
        0.05f64..=1.0,
        log_uniform(1e-3, 1e3),
        log_uniform(1e-6, 1e-2),
        prop_oneof![-3.0f64..-4.4e-4, 4.4e-4f64..3.0],
        raw::<D>(),
        raw::<D>(),
        raw::<D>(),
    )
        .prop_map(|(mu, lambda, eps, e, a, b, c)| {
            let y = eps * 10f64.powf(e);
            let normal = unit::<D>(&a);
            let t = orthogonal_unit(&normal, &b);
            let start = SVector::<f64, D>::from_column_slice(&c) * y;
            let friction = LaggedFriction {
                coefficient: mu,
                normal_force: lambda,
                normal,
                start,
            };
            (friction, start + t * y + normal * (y * c[0]), eps)
        })
}

fn check_friction<const D: usize>(f: &LaggedFriction<D>, x: &SVector<f64, D>, eps: f64) {
    let terms = f.terms(x, eps);
    let scale = f.coefficient * f.normal_force;
    let y = f.tangential(x).norm();
    // Energy ≥ μλε/3 > 0 and the Coulomb bound |∇E| = μλ f₁ ≤ μλ (to rounding).
    assert!(terms.energy >= 0.0);
    assert!(terms.gradient.norm() <= scale * (1.0 + 4.0 * EPS));
    // The gradient lies in the tangent plane.
    assert!(terms.gradient.dot(&f.normal).abs() <= 8.0 * EPS * terms.gradient.norm());
    // PSD and symmetric; eigenvalues to a few ε of the size of the terms μλ(f₁' + f₁/y), not of
    // the block, which vanishes in 2D beyond ε (P − ûûᵀ = 0 there, up to rounding).
    assert_eq!(terms.hessian, terms.hessian.transpose());
    let e = eigenvalues(&terms.hessian);
    let size = scale * (2.0 / eps + friction_f1(y, eps) / y);
    assert!(e[0] >= -1e-13 * size, "{e:?}");
    // FD step: 1e-4 of the shortest scale, y (|u| turns) and |y − ε| (the regime switch, where
    // f₀''' jumps); truncation ≈ 1e-8 relative, so 1e-6 relative with the rounding of E (ε E/h,
    // E carries the constant μλε/3) and of u (e_u, a few ulps of the coordinates) on top.
    let h = 1e-4 * y.min((y - eps).abs());
    let e_u = 4.0 * EPS * (x.norm() + f.start.norm());
    let numeric = fd::gradient(
        |p| {
            f.terms(&SVector::<f64, D>::from_column_slice(p), eps)
                .energy
        },
        x.as_slice(),
        h,
    );
    let tol = 1e-6 * terms.gradient.norm() + 4.0 * (8.0 * EPS * terms.energy + scale * e_u) / h;
    for a in 0..D {
        assert!(
            (numeric[a] - terms.gradient[a]).abs() <= tol,
            "gradient {a}: {} vs {} (y/ε {})",
            terms.gradient[a],
            numeric[a],
            y / eps
        );
    }
    let jac = fd::jacobian(
        |p, out| {
            let g = f
                .terms(&SVector::<f64, D>::from_column_slice(p), eps)
                .gradient;
            out.copy_from_slice(g.as_slice());
        },
        x.as_slice(),
        D,
        h,
    );
    // The gradient μλ (f₁/y) u is known to μλ(4ε + 2 e_u max(1/ε, 1/y)).
    let tol = 1e-6 * terms.hessian.amax()
        + 4.0 * scale * (4.0 * EPS + 2.0 * e_u * (1.0 / eps).max(1.0 / y)) / h;
    for a in 0..D {
        for b in 0..D {
            assert!(
                (jac[(a, b)] - terms.hessian[(a, b)]).abs() <= tol,
                "Hessian ({a},{b}): {} vs {} (y/ε {})",
                terms.hessian[(a, b)],
                jac[(a, b)],
                y / eps
            );
        }
    }
}

fn check_friction_energy_change<const D: usize>(
    f: &LaggedFriction<D>,
    x: &SVector<f64, D>,
    eps: f64,
    v: &[f64],
    s: f64,
) {
    let y = f.tangential(x).norm();
    let delta = SVector::<f64, D>::from_column_slice(v) * (s * y);
    let change = f.energy_change(x, &delta, eps);
    let terms = f.terms(x, eps);
    if s > 1e-3 {
        // Moderate steps: the direct difference is accurate to a few ε of the energies.
        let direct = f.terms(&(x + delta), eps).energy - terms.energy;
        let tol = 16.0 * EPS * (terms.energy + f.terms(&(x + delta), eps).energy);
        assert!((change - direct).abs() <= tol, "{change} vs {direct}");
    } else {
        // Tiny steps (|δ| ≤ 1e-3 y): against the quadratic model ∇E·δ + ½δᵀHδ, whose truncation
        // is bounded by |δ|³ times the third derivative, ≲ μλ(2/ε² + 3/y²)|δ|³, for steps that do
        // not cross y = ε (f₀''' jumps there; such steps are skipped); rounding a few ε of
        // |∇E||δ| and of the model's terms.
        if (y - eps).abs() <= 2.0 * delta.norm() {
            return;
        }
        let model = terms.gradient.dot(&delta) + 0.5 * delta.dot(&(terms.hessian * delta));
        let scale = f.coefficient * f.normal_force;
        let truncation = scale * (2.0 / (eps * eps) + 3.0 / (y * y)) * delta.norm().powi(3);
        let rounding = 64.0
            * EPS
            * (terms.gradient.norm() * delta.norm()
                + terms.hessian.amax() * delta.norm_squared() * D as f64);
        assert!(
            (change - model).abs() <= truncation + rounding,
            "{change} vs {model} (y/ε {})",
            y / eps
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn friction_derivatives_bounds_and_definiteness_2d((f, x, eps) in friction_case::<2>()) {
        check_friction(&f, &x, eps);
    }

    #[test]
    fn friction_derivatives_bounds_and_definiteness_3d((f, x, eps) in friction_case::<3>()) {
        check_friction(&f, &x, eps);
    }

    #[test]
    fn friction_energy_change_2d(
        (f, x, eps) in friction_case::<2>(),
        v in raw::<2>(),
        s in log_uniform(1e-12, 3.0),
    ) {
        check_friction_energy_change(&f, &x, eps, &v, s);
    }

    #[test]
    fn friction_energy_change_3d(
        (f, x, eps) in friction_case::<3>(),
        v in raw::<3>(),
        s in log_uniform(1e-12, 3.0),
    ) {
        check_friction_energy_change(&f, &x, eps, &v, s);
    }
}

#[test]
fn friction_f0_f1_are_continuous_at_eps_and_zero_at_rest() {
    let eps = 1e-4;
    for side in [1.0 - 1e-12, 1.0, 1.0 + 1e-12] {
        let y = eps * side;
        // Both sides within the O(1e-12) change of the argument.
        assert!((friction_f0(y, eps) - eps).abs() <= 2e-12 * eps);
        assert!((friction_f1(y, eps) - 1.0).abs() <= 2e-12);
    }
    assert_eq!(friction_f0(0.0, eps), eps / 3.0);
    assert_eq!(friction_f1(0.0, eps), 0.0);
    assert!(friction_f0(f64::NAN, eps).is_nan());
    assert!(friction_f1(f64::NAN, eps).is_nan());
    // At u = 0: zero gradient, Hessian the limit (2/ε) μλ P.
    let f = LaggedFriction {
        coefficient: 0.5,
        normal_force: 4.0,
        normal: SVector::<f64, 3>::z(),
        start: SVector::<f64, 3>::new(1.0, 2.0, 3.0),
    };
    let terms = f.terms(&SVector::<f64, 3>::new(1.0, 2.0, 7.0), eps);
    assert_eq!(terms.gradient, SVector::<f64, 3>::zeros());
    assert_eq!(terms.energy, 2.0 * eps / 3.0);
    let expected = SMatrix::<f64, 3, 3>::from_diagonal(&SVector::<f64, 3>::new(1.0, 1.0, 0.0))
        * (2.0 * 2.0 / eps);
    assert!((terms.hessian - expected).amax() <= 4.0 * EPS * expected.amax());
    // Sliding: the Coulomb force μλ against the displacement.
    let sliding = f.terms(&SVector::<f64, 3>::new(1.0 + 1e-2, 2.0, 3.0), eps);
    assert!((sliding.gradient - SVector::<f64, 3>::x() * 2.0).amax() <= 4.0 * EPS);
    assert!(f
        .terms(&SVector::<f64, 3>::repeat(f64::NAN), eps)
        .energy
        .is_nan());
}

#[test]
fn lagged_friction_takes_the_barrier_force_at_the_lag_point() {
    let normal = SVector::<f64, 2>::new(0.6, 0.8);
    let plane = Obstacle::half_space(SVector::<f64, 2>::new(1.0, 1.0), normal).unwrap();
    let (d_hat, k, mu) = (1e-2, 1e4, 0.3);
    let x = SVector::<f64, 2>::new(1.0, 1.0) + normal * 3e-3 + SVector::<f64, 2>::new(0.8, -0.6);
    let f = lagged_friction(&plane, &x, d_hat, k, mu).unwrap();
    let d = plane.distance(&x);
    assert_eq!(f.normal_force, -k * barrier_derivative(d, d_hat));
    assert!(f.normal_force > 0.0);
    // λ is the magnitude of the barrier's force there.
    let barrier_terms = vertex_barrier(&plane, &x, d_hat, k, Definiteness::Exact).unwrap();
    assert!((barrier_terms.gradient.norm() - f.normal_force).abs() <= 4.0 * EPS * f.normal_force);
    assert_eq!(f.normal, plane.normal(&x));
    assert!((f.normal - normal).amax() <= 2.0 * EPS);
    assert_eq!(f.start, x);
    assert_eq!(f.coefficient, mu);
    let far = x + normal * d_hat;
    assert!(lagged_friction(&plane, &far, d_hat, k, mu).is_none());
    let inside = x - normal * d_hat;
    assert!(lagged_friction(&plane, &inside, d_hat, k, mu).is_none());
    assert!(lagged_friction(&plane, &SVector::repeat(f64::NAN), d_hat, k, mu).is_none());
}

// ---------------------------------------------------------------------------------------------
// Time of impact
// ---------------------------------------------------------------------------------------------

/// The coordinates' scale for the guarantee's condition d(x) ≥ 1e-12 S(α).
fn coordinate_scale<const D: usize>(
    obstacle: &Obstacle<D>,
    x: &SVector<f64, D>,
    p: &SVector<f64, D>,
    alpha: f64,
) -> f64 {
    let (anchor, radius) = match obstacle {
        Obstacle::HalfSpace { point, .. } => (point.norm(), 0.0),
        Obstacle::SphereOutside { center, radius } => (center.norm(), *radius),
    };
    x.norm() + anchor + radius + alpha * p.norm()
}

/// Checks the documented guarantee at α (skipping α where its condition does not hold).
fn assert_feasible<const D: usize>(
    obstacle: &Obstacle<D>,
    x: &SVector<f64, D>,
    p: &SVector<f64, D>,
    alpha: f64,
) {
    let d0 = obstacle.distance(x);
    if d0 < 1e-12 * coordinate_scale(obstacle, x, p, alpha) {
        return;
    }
    let d = obstacle.distance(&(x + p * alpha));
    assert!(
        d >= 0.0,
        "distance {d:e} at α = {alpha:e} (toi {:?}, d0 {d0:e}, {obstacle:?}, x {x:?}, p {p:?})",
        obstacle.time_of_impact(x, p)
    );
}

fn check_guarantee<const D: usize>(
    obstacle: &Obstacle<D>,
    x: &SVector<f64, D>,
    p: &SVector<f64, D>,
) {
    if obstacle.distance(x).is_nan() || obstacle.distance(x) <= 0.0 {
        return;
    }
    match obstacle.time_of_impact(x, p) {
        Some(toi) => {
            assert!(toi >= 0.0 && toi.is_finite());
            for k in 0..=64 {
                assert_feasible(obstacle, x, p, 0.9 * toi * k as f64 / 64.0);
            }
        }
        None => {
            // Along the whole ray: its closest approach to the obstacle, and a geometric sweep
            // over the scales of the problem.
            let len = p.norm();
            let (reach, closest) = match obstacle {
                Obstacle::HalfSpace { point, .. } => ((x - point).norm() / len, 0.0),
                Obstacle::SphereOutside { center, radius } => {
                    let o = x - center;
                    (
                        (o.norm() + radius) / len,
                        (-o.dot(p) / (len * len)).max(0.0),
                    )
                }
            };
            for k in -40..=40 {
                let alpha = closest * (1.0 + k as f64 * 1e-3);
                if alpha >= 0.0 {
                    assert_feasible(obstacle, x, p, alpha);
                }
                assert_feasible(obstacle, x, p, reach * 10f64.powf(k as f64 / 4.0));
            }
        }
    }
}

/// A sphere of radius r ∈ [1e-3, 1e3] m centred within 10 r of the origin, and a straight line
/// that passes the centre at distance m = r(1 + η): η of every size from a clear hit (−0.9) through
/// grazing within a few ulps (±k ε) to a clear miss (+1); the vertex starts at distance L ∈
/// [1e-6 r, 1e3 r] before the line's closest point, or just beside the sphere (random direction).
fn sphere_line<const D: usize>(
) -> impl Strategy<Value = (Obstacle<D>, SVector<f64, D>, SVector<f64, D>)> {
    let eta = prop_oneof![
        -0.9f64..1.0,
        (-64i32..64).prop_map(|k| k as f64 * EPS),
        log_uniform(1e-15, 1e-3),
        log_uniform(1e-15, 1e-3).prop_map(|v| -v),
    ];
    (
        log_uniform(1e-3, 1e3),
        raw::<D>(),
        raw::<D>(),
        raw::<D>(),
        eta,
        log_uniform(1e-6, 1e3),
        log_uniform(1e-6, 1e6),
        any::<bool>(),
    )
        .prop_map(|(r, c, w, t, eta, along, speed, generic)| {
            let center = SVector::<f64, D>::from_column_slice(&c) * (10.0 * r);
            let sphere = Obstacle::sphere_outside(center, r).unwrap();
            let w = unit::<D>(&w);
            let t = orthogonal_unit(&w, &t);
            if generic {
                // A vertex at d = along·r (capped) in direction w, moving along t + (w scaled).
                let x = center + w * (r * (1.0 + along.min(10.0)));
                let p = (t + w * (eta * 2.0)) * speed;
                (sphere, x, p)
            } else {
                let closest = center + w * (r * (1.0 + eta));
                let x = closest - t * (along * r);
                (sphere, x, t * speed)
            }
        })
}

fn plane_line<const D: usize>(
) -> impl Strategy<Value = (Obstacle<D>, SVector<f64, D>, SVector<f64, D>)> {
    let slope = prop_oneof![
        -1.0f64..1.0,
        log_uniform(1e-16, 1e-2).prop_map(|v| -v),
        Just(0.0)
    ];
    (
        raw::<D>(),
        raw::<D>(),
        raw::<D>(),
        log_uniform(1e-3, 1e3),
        log_uniform(1e-12, 1e3),
        slope,
        log_uniform(1e-6, 1e6),
    )
        .prop_map(|(a, n, t, scale, d, slope, speed)| {
            let point = SVector::<f64, D>::from_column_slice(&a) * scale;
            let n = unit::<D>(&n);
            let t = orthogonal_unit(&n, &t);
            let plane = Obstacle::half_space(point, n).unwrap();
            let x = point + n * (d * scale) + t * scale;
            (plane, x, (t + n * slope) * speed)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn time_of_impact_keeps_a_capped_step_feasible_sphere_2d((s, x, p) in sphere_line::<2>()) {
        check_guarantee(&s, &x, &p);
    }

    #[test]
    fn time_of_impact_keeps_a_capped_step_feasible_sphere_3d((s, x, p) in sphere_line::<3>()) {
        check_guarantee(&s, &x, &p);
    }

    #[test]
    fn time_of_impact_keeps_a_capped_step_feasible_plane_2d((s, x, p) in plane_line::<2>()) {
        check_guarantee(&s, &x, &p);
    }

    #[test]
    fn time_of_impact_keeps_a_capped_step_feasible_plane_3d((s, x, p) in plane_line::<3>()) {
        check_guarantee(&s, &x, &p);
    }

    /// The plane's root is exact: the distance at x + toi·p is zero to the rounding of the
    /// coordinates there, a few ε of |x| + |point| + toi|p|.
    #[test]
    fn plane_time_of_impact_is_exact((plane, x, p) in plane_line::<3>()) {
        if let Some(toi) = plane.time_of_impact(&x, &p) {
            let d = plane.distance(&(x + p * toi));
            let tol = 8.0 * EPS * coordinate_scale(&plane, &x, &p, toi);
            prop_assert!(d.abs() <= tol, "{d:e} vs {tol:e}");
        } else {
            let Obstacle::HalfSpace { normal, .. } = plane else { unreachable!() };
            // Moving away or along, to the rounding of p·n.
            prop_assert!(p.dot(&normal) >= -4.0 * EPS * p.norm());
        }
    }

    /// The sphere's root: a line entering the sphere at a known point s = c + r ŵ at an angle
    /// (p̂·ŵ ≤ −0.1) from x = s − t p. The computed root is t to 1e-9 relative: the rounding of x
    /// (ε(|c| + r + t|p|)) moves the root by that over |p| cos θ ≥ 0.1 |p|, with t|p| ≥ 1e-3 r
    /// and |c| ≤ 10 r, ≈ 1e-11 t.
    #[test]
    fn sphere_time_of_impact_finds_the_entry_point(
        r in log_uniform(1e-3, 1e3),
        c in raw::<3>(),
        w in raw::<3>(),
        v in raw::<3>(),
        cosine in 0.1f64..=1.0,
        travel in log_uniform(1e-3, 10.0),
        speed in log_uniform(1e-3, 1e3),
    ) {
        let center = SVector::<f64, 3>::from_column_slice(&c) * (10.0 * r);
        let sphere = Obstacle::sphere_outside(center, r).unwrap();
        let w = unit::<3>(&w);
        let tangent = orthogonal_unit(&w, &v);
        let direction = -w * cosine + tangent * (1.0 - cosine * cosine).sqrt();
        let p = direction * speed;
        let t = travel * r / speed;
        let x = center + w * r - p * t;
        let toi = sphere.time_of_impact(&x, &p).unwrap();
        prop_assert!((toi - t).abs() <= 1e-9 * t, "{toi} vs {t}");
    }
}

#[test]
fn time_of_impact_none_when_moving_away_or_missing() {
    let sphere = Obstacle::sphere_outside(SVector::<f64, 3>::zeros(), 1.0).unwrap();
    let x = SVector::<f64, 3>::new(2.0, 0.0, 0.0);
    assert_eq!(sphere.time_of_impact(&x, &SVector::x()), None);
    assert_eq!(sphere.time_of_impact(&x, &SVector::y()), None);
    assert_eq!(
        sphere.time_of_impact(&x, &SVector::<f64, 3>::new(-1.0, 1.1, 0.0)),
        None
    );
    assert_eq!(sphere.time_of_impact(&x, &SVector::zeros()), None);
    // Head on: 1 m to go at 2 m per unit of α.
    assert_eq!(
        sphere.time_of_impact(&x, &SVector::<f64, 3>::new(-2.0, 0.0, 0.0)),
        Some(0.5)
    );
    // Tangent: y = 1 touches at α = 2.
    let toi = sphere
        .time_of_impact(&SVector::<f64, 3>::new(2.0, 1.0, 0.0), &-SVector::x())
        .unwrap();
    assert!((toi - 2.0).abs() <= 4.0 * EPS);
    // Already touching or inside: 0; NaN: NaN.
    assert_eq!(
        sphere.time_of_impact(&SVector::<f64, 3>::new(0.5, 0.0, 0.0), &SVector::x()),
        Some(0.0)
    );
    assert!(sphere
        .time_of_impact(&x, &SVector::repeat(f64::NAN))
        .unwrap()
        .is_nan());
    let plane = Obstacle::half_space(SVector::<f64, 2>::zeros(), SVector::<f64, 2>::y()).unwrap();
    let x = SVector::<f64, 2>::new(3.0, 2.0);
    assert_eq!(
        plane.time_of_impact(&x, &SVector::<f64, 2>::new(1.0, 0.0)),
        None
    );
    assert_eq!(
        plane.time_of_impact(&x, &SVector::<f64, 2>::new(1.0, 1.0)),
        None
    );
    assert_eq!(
        plane.time_of_impact(&x, &SVector::<f64, 2>::new(5.0, -4.0)),
        Some(0.5)
    );
    // A root beyond f64::MAX is None.
    assert_eq!(
        plane.time_of_impact(&x, &SVector::<f64, 2>::new(1.0, -1e-320)),
        None
    );
}
