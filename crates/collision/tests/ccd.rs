//! Tests of additive CCD (hooke_collision::ccd): known times of impact (returned time at most the
//! true one, and at least a stated fraction of it), never passing a contact on random motions
//! (dense sampling of the distance, and the exact crossings found as roots of the coplanarity
//! cubic), the gap kept at the returned time, and adversarial motions: coplanar and parallel
//! sheets moving through each other, parallel edges, a vertex starting on a face, no motion,
//! sliding at a constant small gap (bounded iterations), NaN and invalid inputs.

use hooke_collision::ccd::{edge_edge_ccd, point_triangle_ccd, CcdOutcome, CcdParams};
use hooke_collision::distance::{edge_edge_distance_squared, point_triangle_distance_squared};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use std::time::Instant;

type V = Vector3<f64>;

fn v(x: f64, y: f64, z: f64) -> V {
    V::new(x, y, z)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    PointTriangle,
    EdgeEdge,
}

/// The CCD of either kind on owned arrays.
fn ccd(
    kind: Kind,
    x: &[V; 4],
    d: &[V; 4],
    t_max: f64,
    thickness: f64,
    p: &CcdParams,
) -> CcdOutcome {
    let (xr, dr) = (x.each_ref(), d.each_ref());
    match kind {
        Kind::PointTriangle => point_triangle_ccd(xr, dr, t_max, thickness, p),
        Kind::EdgeEdge => edge_edge_ccd(xr, dr, t_max, thickness, p),
    }
}

/// The pair's squared distance at α, in the caller's (global) coordinates.
fn distance_squared_at(kind: Kind, x: &[V; 4], d: &[V; 4], alpha: f64) -> f64 {
    let p: [V; 4] = std::array::from_fn(|i| x[i] + d[i] * alpha);
    match kind {
        Kind::PointTriangle => point_triangle_distance_squared(&p[0], &p[1], &p[2], &p[3]),
        Kind::EdgeEdge => edge_edge_distance_squared(&p[0], &p[1], &p[2], &p[3]),
    }
}

/// The gap d − ξ at α.
fn gap_at(kind: Kind, x: &[V; 4], d: &[V; 4], alpha: f64, thickness: f64) -> f64 {
    distance_squared_at(kind, x, d, alpha).sqrt() - thickness
}

/// Asserts that the pair stays apart (computed distance above the thickness) at `samples + 1`
/// evenly spaced times in [0, time], the end included.
fn assert_apart_until(
    kind: Kind,
    x: &[V; 4],
    d: &[V; 4],
    time: f64,
    thickness: f64,
    samples: usize,
) {
    for k in 0..=samples {
        let alpha = time * k as f64 / samples as f64;
        let squared = distance_squared_at(kind, x, d, alpha);
        assert!(
            squared > thickness * thickness,
            "{kind:?} touches at α = {alpha:e} ≤ returned time {time:e}: d² = {squared:e}, ξ = {thickness:e}"
        );
    }
}

/// The first time in [0, t_max] where the four points are coplanar and the pair touches there
/// (distance below 1e-9): the exact crossings of a pair with ξ = 0, found as the sign changes of
/// the coplanarity cubic det[x₁ − x₀, x₂ − x₀, x₃ − x₀](α) over `samples` intervals, refined by
/// bisection. Tangential double roots inside one interval are not seen (the check is one-sided).
fn first_crossing(kind: Kind, x: &[V; 4], d: &[V; 4], t_max: f64, samples: usize) -> Option<f64> {
    let det = |alpha: f64| {
        let p: [V; 4] = std::array::from_fn(|i| x[i] + d[i] * alpha);
        Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]).determinant()
    };
    let touches = |alpha: f64| distance_squared_at(kind, x, d, alpha) < 1e-18;
    let mut previous = (0.0, det(0.0));
    if previous.1 == 0.0 && touches(0.0) {
        return Some(0.0);
    }
    for k in 1..=samples {
        let alpha = t_max * k as f64 / samples as f64;
        let value = det(alpha);
        if value == 0.0 && touches(alpha) {
            return Some(alpha);
        }
        if (previous.1 < 0.0) != (value < 0.0) && previous.1 != 0.0 && value != 0.0 {
            let (mut lo, mut hi) = (previous.0, alpha);
            let lo_sign = previous.1 < 0.0;
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if (det(mid) < 0.0) == lo_sign {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            // The root is within [lo, hi]; the pair touches there if it crosses.
            if touches(lo) || touches(hi) {
                return Some(lo);
            }
        }
        previous = (alpha, value);
    }
    None
}

/// The first of `samples + 1` evenly spaced times in [0, t_max] at which the computed distance is
/// at most `thickness` + 1e-12: a contact at or before it.
fn first_sampled_contact(
    kind: Kind,
    x: &[V; 4],
    d: &[V; 4],
    t_max: f64,
    thickness: f64,
    samples: usize,
) -> Option<f64> {
    (0..=samples)
        .map(|k| t_max * k as f64 / samples as f64)
        .find(|&alpha| gap_at(kind, x, d, alpha, thickness) <= 1e-12)
}

/// The fraction of the true time of impact that a pair whose gap closes at a constant rate r ≤ l_p
/// gets at least, for s = 0.1 when not limited. At the stop, t was accepted and the check at
/// t + 0.9 g(t)/l_p (or at t_max, before it) failed: g(t)(1 − 0.9ρ) < s g₀ with ρ = r/l_p, so
/// toi − t = g(t)/r < s·toi/(1 − 0.9ρ); and t is at least the first advance (1 − s)ρ·toi. The
/// larger of the two bounds is least where (1 − 0.9ρ)² = s: 1 − √0.1 = 0.684.
const LINEAR_FRACTION: f64 = 0.68;

/// Whether `time` is in [(1 − s)·toi, toi] (s = 0.1, rounding allowed below): where a pair that
/// closes at the full rate l_p stops, after its first advance.
fn at_first_advance(time: f64, toi: f64) -> bool {
    (0.9 * toi * (1.0 - 1e-12)..=toi).contains(&time)
}

fn unit_triangle() -> [V; 3] {
    [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)]
}

// ---------------------------------------------------------------------------------------------
// Known times of impact
// ---------------------------------------------------------------------------------------------

#[test]
fn point_falling_head_on_onto_a_triangle_stops_at_the_first_advance() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.2, 0.5), t0, t1, t2];
    let d = [v(0.0, 0.0, -1.0), V::zeros(), V::zeros(), V::zeros()];
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &CcdParams::default());
    let toi = 0.5;
    // Closing at the full rate l_p: the first advance (1 − s)·toi, then the next one falls below
    // s·g₀ and stops.
    assert!(at_first_advance(out.time, toi), "{out:?}");
    assert!(!out.limited && out.iterations <= 2, "{out:?}");
    assert_apart_until(Kind::PointTriangle, &x, &d, out.time, 0.0, 1000);
}

#[test]
fn edge_falling_across_an_edge_stops_at_the_first_advance() {
    let x = [
        v(-1.0, 0.0, 0.3),
        v(1.0, 0.0, 0.3),
        v(0.0, -1.0, 0.0),
        v(0.0, 1.0, 0.0),
    ];
    let d = [v(0.0, 0.0, -1.0), v(0.0, 0.0, -1.0), V::zeros(), V::zeros()];
    let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default());
    let toi = 0.3;
    assert!(at_first_advance(out.time, toi), "{out:?}");
    assert!(!out.limited && out.iterations <= 2, "{out:?}");
    assert_eq!(
        first_crossing(Kind::EdgeEdge, &x, &d, 1.0, 1000).map(|t| (t - toi).abs() < 1e-9),
        Some(true)
    );
}

#[test]
fn a_static_sphere_centre_with_its_radius_as_thickness() {
    // The triangle rises towards a sphere of radius 0.5 centred at height 1: contact at α = 0.5.
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.25, 0.25, 1.0), t0, t1, t2];
    let up = v(0.0, 0.0, 1.0);
    let d = [V::zeros(), up, up, up];
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.5, &CcdParams::default());
    assert!(at_first_advance(out.time, 0.5), "{out:?}");
    assert_apart_until(Kind::PointTriangle, &x, &d, out.time, 0.5, 1000);
    // Touching at the start: time 0.
    let x = [v(0.25, 0.25, 0.5), t0, t1, t2];
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.5, &CcdParams::default());
    assert_eq!(out.time, 0.0);
}

#[test]
fn the_time_is_capped_at_t_max_and_receding_pairs_are_free() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.2, 0.5), t0, t1, t2];
    let down = [v(0.0, 0.0, -1.0), V::zeros(), V::zeros(), V::zeros()];
    // Contact at 0.5, but only [0, 0.3] asked for: the gap at 0.3 is 0.2 ≥ s·g₀.
    let out = ccd(
        Kind::PointTriangle,
        &x,
        &down,
        0.3,
        0.0,
        &CcdParams::default(),
    );
    assert_eq!(out.time, 0.3);
    assert!(!out.limited);
    // Moving away.
    let up = [v(0.3, -0.1, 1.0), V::zeros(), V::zeros(), V::zeros()];
    let out = ccd(
        Kind::PointTriangle,
        &x,
        &up,
        1.0,
        0.0,
        &CcdParams::default(),
    );
    assert_eq!(out.time, 1.0);
    assert!(!out.limited && out.iterations < 10, "{out:?}");
    // t_max = 0.
    let out = ccd(
        Kind::PointTriangle,
        &x,
        &down,
        0.0,
        0.0,
        &CcdParams::default(),
    );
    assert_eq!(out.time, 0.0);
}

#[test]
fn a_smaller_kept_share_gets_closer() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.2, 0.5), t0, t1, t2];
    let d = [v(0.1, 0.1, -1.0), V::zeros(), V::zeros(), V::zeros()];
    let params = CcdParams {
        kept_share: 0.01,
        ..CcdParams::default()
    };
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &params);
    assert!((0.95 * 0.5..=0.5).contains(&out.time), "{out:?}");
}

// ---------------------------------------------------------------------------------------------
// Adversarial motions
// ---------------------------------------------------------------------------------------------

#[test]
fn a_vertex_starting_on_the_face_gets_time_zero() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.3, 0.0), t0, t1, t2];
    let d = [v(0.0, 0.0, 1.0), V::zeros(), V::zeros(), V::zeros()];
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &CcdParams::default());
    assert_eq!(
        out,
        CcdOutcome {
            time: 0.0,
            iterations: 0,
            limited: false
        }
    );
    // On an edge of the triangle, and crossing segments.
    let x = [v(0.5, 0.0, 0.0), t0, t1, t2];
    assert_eq!(
        ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &CcdParams::default()).time,
        0.0
    );
    let x = [
        v(-1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.0, -1.0, 0.0),
        v(0.0, 1.0, 0.0),
    ];
    assert_eq!(
        ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default()).time,
        0.0
    );
}

#[test]
fn no_relative_motion_is_free_up_to_t_max() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.2, 1e-6), t0, t1, t2];
    for kind in [Kind::PointTriangle, Kind::EdgeEdge] {
        let zero = [V::zeros(); 4];
        let out = ccd(kind, &x, &zero, 1.0, 0.0, &CcdParams::default());
        assert_eq!(
            out,
            CcdOutcome {
                time: 1.0,
                iterations: 0,
                limited: false
            }
        );
        // A common translation moves nothing relative to anything else.
        let shift = [v(3.0, -2.0, 7.0); 4];
        let out = ccd(kind, &x, &shift, 0.7, 0.0, &CcdParams::default());
        assert_eq!(
            out,
            CcdOutcome {
                time: 0.7,
                iterations: 0,
                limited: false
            }
        );
    }
}

#[test]
fn nan_and_invalid_inputs_give_time_zero() {
    let [t0, t1, t2] = unit_triangle();
    let x = [v(0.2, 0.2, 0.5), t0, t1, t2];
    let d = [v(0.0, 0.0, 1.0), V::zeros(), V::zeros(), V::zeros()];
    let nan = v(f64::NAN, 0.0, 0.0);
    let p = CcdParams::default();
    for kind in [Kind::PointTriangle, Kind::EdgeEdge] {
        for i in 0..4 {
            let mut xn = x;
            xn[i] = nan;
            assert_eq!(ccd(kind, &xn, &d, 1.0, 0.0, &p).time, 0.0);
            let mut dn = d;
            dn[i] = nan;
            assert_eq!(ccd(kind, &x, &dn, 1.0, 0.0, &p).time, 0.0);
            let mut di = d;
            di[i] = v(f64::INFINITY, 0.0, 0.0);
            assert_eq!(ccd(kind, &x, &di, 1.0, 0.0, &p).time, 0.0);
        }
        assert_eq!(ccd(kind, &x, &d, f64::NAN, 0.0, &p).time, 0.0);
        assert_eq!(ccd(kind, &x, &d, -1.0, 0.0, &p).time, 0.0);
        assert_eq!(ccd(kind, &x, &d, 1.0, f64::NAN, &p).time, 0.0);
        assert_eq!(ccd(kind, &x, &d, 1.0, -0.1, &p).time, 0.0);
        for kept_share in [0.0, 1.0, -0.5, f64::NAN] {
            let p = CcdParams { kept_share, ..p };
            assert_eq!(ccd(kind, &x, &d, 1.0, 0.0, &p).time, 0.0);
        }
        let none = CcdParams {
            max_iterations: 0,
            ..p
        };
        let out = ccd(kind, &x, &d, 1.0, 0.0, &none);
        assert_eq!(
            out,
            CcdOutcome {
                time: 0.0,
                iterations: 0,
                limited: true
            }
        );
    }
}

/// The PT and EE pairs between two triangles (as index quadruples into their six vertices).
fn pairs_between_triangles() -> Vec<(Kind, [usize; 4])> {
    let mut pairs = Vec::new();
    for (a, b) in [(0, 3), (3, 0)] {
        for i in 0..3 {
            pairs.push((Kind::PointTriangle, [a + i, b, b + 1, b + 2]));
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            pairs.push((Kind::EdgeEdge, [i, (i + 1) % 3, 3 + j, 3 + (j + 1) % 3]));
        }
    }
    pairs
}

/// Runs every pair between two moving triangles: each is apart up to its time, its time is not
/// after the first sampled contact, and it ends within `iterations`. Returns the least time.
fn two_triangles(x: &[V; 6], d: &[V; 6], iterations: u32) -> f64 {
    let p = CcdParams::default();
    let mut least: f64 = 1.0;
    for (kind, idx) in pairs_between_triangles() {
        let (xs, ds) = (idx.map(|i| x[i]), idx.map(|i| d[i]));
        let out = ccd(kind, &xs, &ds, 1.0, 0.0, &p);
        assert!((0.0..=1.0).contains(&out.time));
        assert!(out.iterations <= iterations, "{kind:?} {idx:?}: {out:?}");
        assert_apart_until(kind, &xs, &ds, out.time, 0.0, 2000);
        if let Some(contact) = first_sampled_contact(kind, &xs, &ds, 1.0, 0.0, 20_000) {
            assert!(
                out.time <= contact,
                "{kind:?} {idx:?}: {out:?} after {contact}"
            );
        }
        least = least.min(out.time);
    }
    least
}

#[test]
fn parallel_triangles_moving_through_each_other() {
    // Two equal triangles, one 0.2 above the other, the upper moving down through the lower: its
    // corners land on the lower one's corners and its edges on the lower one's (parallel) edges,
    // all at α = 0.4.
    let [t0, t1, t2] = unit_triangle();
    let h = v(0.0, 0.0, 0.2);
    let x = [t0, t1, t2, t0 + h, t1 + h, t2 + h];
    let down = v(0.0, 0.0, -0.5);
    let d = [V::zeros(), V::zeros(), V::zeros(), down, down, down];
    let least = two_triangles(&x, &d, 10);
    assert!(at_first_advance(least, 0.4), "{least}");
    // The same with the upper one shifted inside, so its corners hit the lower one's face.
    let s = v(0.1, 0.1, 0.0);
    let x = [
        t0,
        t1,
        t2,
        t0 * 0.5 + s + h,
        t1 * 0.5 + s + h,
        t2 * 0.5 + s + h,
    ];
    let least = two_triangles(&x, &d, 10);
    assert!(at_first_advance(least, 0.4), "{least}");
}

#[test]
fn coplanar_triangles_sliding_through_each_other() {
    // Both triangles in z = 0; the second slides in the plane through the first. The pairs touch
    // where a corner reaches the other's boundary or two edges meet: in-plane contacts, where
    // every coplanarity test of exact CCD is degenerate.
    let [t0, t1, t2] = unit_triangle();
    let s = v(1.5, 0.2, 0.0);
    let x = [t0, t1, t2, t0 + s, t1 + s, t2 + s];
    let slide = v(-3.0, 0.0, 0.0);
    let d = [V::zeros(), V::zeros(), V::zeros(), slide, slide, slide];
    let least = two_triangles(&x, &d, 50);
    // First contact: the moving corner (1.5, 0.2) meets the hypotenuse x + y = 1 at (0.8, 0.2)
    // when 1.5 − 3α = 0.8. Its gap closes at 3/√2 < l_p = 3, at a constant rate.
    let toi = 0.7 / 3.0;
    assert!(
        (LINEAR_FRACTION * toi..=toi).contains(&least),
        "{least} vs {toi}"
    );
}

#[test]
fn parallel_edges_moving_through_each_other() {
    // Parallel: overlapping along x, one above the other, moving down through it (contact at 0.25).
    let x = [
        v(0.0, 0.0, 0.25),
        v(1.0, 0.0, 0.25),
        v(0.5, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
    ];
    let d = [v(0.0, 0.0, -1.0), v(0.0, 0.0, -1.0), V::zeros(), V::zeros()];
    let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default());
    assert!(at_first_advance(out.time, 0.25), "{out:?}");
    // Collinear, one sliding into the other end first (contact when x = 0.5 is reached at 0.5).
    let x = [
        v(-1.0, 0.0, 0.0),
        v(0.0, 0.0, 0.0),
        v(0.5, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
    ];
    let d = [v(1.0, 0.0, 0.0), v(1.0, 0.0, 0.0), V::zeros(), V::zeros()];
    let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default());
    assert!(at_first_advance(out.time, 0.5), "{out:?}");
    // Parallel, sliding along each other at a distance: never touch.
    let x = [
        v(-1.0, 0.0, 0.1),
        v(0.0, 0.0, 0.1),
        v(0.5, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
    ];
    let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default());
    assert_eq!(out.time, 1.0, "{out:?}");
}

#[test]
fn sliding_at_a_tiny_constant_gap_ends_within_the_iteration_bound() {
    // A point sliding 1 m over a face 1e-9 m below it: the gap never closes, but each advance is
    // 0.9e-9 of the motion, so the bound stops it. The time reached is still safe.
    let big = [v(-10.0, -10.0, 0.0), v(10.0, -10.0, 0.0), v(0.0, 10.0, 0.0)];
    let x = [v(-0.5, 0.0, 1e-9), big[0], big[1], big[2]];
    let d = [v(1.0, 0.0, 0.0), V::zeros(), V::zeros(), V::zeros()];
    let started = Instant::now();
    let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &CcdParams::default());
    let elapsed = started.elapsed();
    assert!(out.limited && out.iterations == 10_000, "{out:?}");
    assert!(out.time > 0.0 && out.time < 1e-4, "{out:?}");
    assert_apart_until(Kind::PointTriangle, &x, &d, out.time, 0.0, 1000);
    assert!(elapsed.as_secs_f64() < 1.0, "{elapsed:?}");
    // Coplanar parallel edges, one sliding along the other 1e-9 m off its line, and a small bound.
    let x = [
        v(0.6, 1e-9, 0.0),
        v(1.0, 1e-9, 0.0),
        v(0.5, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
    ];
    let d = [v(0.5, 0.0, 0.0), v(0.5, 0.0, 0.0), V::zeros(), V::zeros()];
    let p = CcdParams {
        max_iterations: 50,
        ..CcdParams::default()
    };
    let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &p);
    assert!(out.limited && out.iterations == 50, "{out:?}");
    assert_apart_until(Kind::EdgeEdge, &x, &d, out.time, 0.0, 1000);
}

// ---------------------------------------------------------------------------------------------
// Properties on random motions
// ---------------------------------------------------------------------------------------------

fn point() -> impl Strategy<Value = V> {
    (-1.0f64..=1.0, -1.0f64..=1.0, -1.0f64..=1.0).prop_map(|(x, y, z)| v(x, y, z))
}

/// Four vertices with starts and ends in the cube [−1, 1]³ (their paths cross often), a thickness
/// (0 half the time), and a kind. A third of the motions are flattened into the plane z = 0
/// (coplanar motion, the degenerate case of exact CCD), a sixth to within 1e-7 of it.
fn random_motion() -> impl Strategy<Value = (Kind, [V; 4], [V; 4], f64)> {
    (
        prop_oneof![Just(Kind::PointTriangle), Just(Kind::EdgeEdge)],
        [point(), point(), point(), point()],
        [point(), point(), point(), point()],
        prop_oneof![Just(0.0), 0.0f64..=0.2],
        prop_oneof![3 => Just(1.0), 2 => Just(0.0), 1 => Just(1e-7)],
    )
        .prop_map(|(kind, x, end, thickness, flatten)| {
            let squash = |p: V| v(p.x, p.y, p.z * flatten);
            let (x, end) = (x.map(squash), end.map(squash));
            let d = std::array::from_fn(|i| end[i] - x[i]);
            (kind, x, d, thickness)
        })
}

/// Barycentric coordinates of a point inside a triangle, each at least 0.03.
fn interior() -> impl Strategy<Value = [f64; 3]> {
    (0.0f64..=1.0, 0.0f64..=1.0).prop_map(|(a, b)| {
        // Uniform on the triangle (fold the square's other half), then shrunk towards the centroid.
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        [1.0 - a - b, a, b].map(|w| 0.1 / 3.0 + 0.9 * w)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Never passes a contact: the distance stays above the thickness on [0, time], the time is
    /// not after the first exact crossing (ξ = 0) or the first sampled contact, and the gap at the
    /// returned time is at least s·g₀.
    #[test]
    fn never_passes_a_contact((kind, x, d, thickness) in random_motion()) {
        let p = CcdParams::default();
        let out = ccd(kind, &x, &d, 1.0, thickness, &p);
        prop_assert!((0.0..=1.0).contains(&out.time), "{:?}", out);
        let start_gap = gap_at(kind, &x, &d, 0.0, thickness);
        if start_gap <= 0.0 {
            prop_assert_eq!(out.time, 0.0);
            return Ok(());
        }
        assert_apart_until(kind, &x, &d, out.time, thickness, 2000);
        if out.time > 0.0 {
            let kept = gap_at(kind, &x, &d, out.time, thickness);
            prop_assert!(kept >= p.kept_share * start_gap - 1e-12, "{} < s·{}", kept, start_gap);
        }
        if thickness == 0.0 {
            if let Some(crossing) = first_crossing(kind, &x, &d, 1.0, 4000) {
                prop_assert!(out.time <= crossing, "{:?} after the crossing at {}", out, crossing);
            }
        }
        if let Some(contact) = first_sampled_contact(kind, &x, &d, 1.0, thickness, 4000) {
            prop_assert!(out.time <= contact, "{:?} after the contact at {}", out, contact);
        }
    }

    /// A point falling onto a triangle's interior along a straight line (the triangle translating
    /// too): the gap closes at a constant rate, so the time is in [0.68·toi, toi].
    #[test]
    fn a_point_falling_obliquely_onto_a_face(
        start in interior(),
        end in interior(),
        height in 0.01f64..=1.0,
        toi in 0.05f64..=0.95,
        drift in point(),
        corners in [point(), point(), point()],
    ) {
        let normal = (corners[1] - corners[0]).cross(&(corners[2] - corners[0]));
        prop_assume!(normal.norm() > 0.1);
        let n = normal.normalize();
        let at = |b: [f64; 3]| corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2];
        let p0 = at(start) + n * height;
        let p_hit = at(end);
        let x = [p0, corners[0], corners[1], corners[2]];
        let d = [(p_hit - p0) / toi + drift, drift, drift, drift];
        let out = ccd(Kind::PointTriangle, &x, &d, 1.0, 0.0, &CcdParams::default());
        prop_assert!(!out.limited);
        prop_assert!(out.time <= toi, "{:?} after {}", out, toi);
        prop_assert!(out.time >= LINEAR_FRACTION * toi, "{:?} below 0.68·{}", out, toi);
    }

    /// An edge falling across another edge, both interiors meeting: [0.68·toi, toi].
    #[test]
    fn an_edge_falling_across_an_edge(
        along_a in 0.1f64..=0.9,
        along_b in 0.1f64..=0.9,
        end_a in 0.1f64..=0.9,
        end_b in 0.1f64..=0.9,
        height in 0.01f64..=1.0,
        toi in 0.05f64..=0.95,
        drift in point(),
    ) {
        // Edge a along x at the given height, edge b along y in z = 0; their closest points
        // move from (along_a, along_b) to (end_a, end_b) in the segments' parameters.
        let x = [
            v(-along_a, 0.0, height),
            v(1.0 - along_a, 0.0, height),
            v(0.0, -along_b, 0.0),
            v(0.0, 1.0 - along_b, 0.0),
        ];
        let da = v(along_a - end_a, 0.0, -height) / toi + drift;
        let db = v(0.0, along_b - end_b, 0.0) / toi + drift;
        let d = [da, da, db, db];
        let out = ccd(Kind::EdgeEdge, &x, &d, 1.0, 0.0, &CcdParams::default());
        prop_assert!(!out.limited);
        prop_assert!(out.time <= toi, "{:?} after {}", out, toi);
        prop_assert!(out.time >= LINEAR_FRACTION * toi, "{:?} below 0.68·{}", out, toi);
    }
}
