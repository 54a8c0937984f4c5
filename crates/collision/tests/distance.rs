//! Tests of `hooke_collision::distance`: the values against independent references (an active-set
//! enumeration and a dense one-dimensional scan, neither sharing code with the module), the
//! classification against the values, every gradient and Hessian against central finite
//! differences, the degenerate and nearly degenerate configurations, and the mollifier.

use hooke_collision::distance::*;
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

type V12 = SVector<f64, 12>;
type M12 = SMatrix<f64, 12, 12>;

const CASES: u32 = 256;

const PT_CASES: [PointTriangleCase; 7] = [
    PointTriangleCase::Vertex(0),
    PointTriangleCase::Vertex(1),
    PointTriangleCase::Vertex(2),
    PointTriangleCase::Edge(0),
    PointTriangleCase::Edge(1),
    PointTriangleCase::Edge(2),
    PointTriangleCase::Face,
];

const EE_CASES: [EdgeEdgeCase; 9] = [
    EdgeEdgeCase::Ea0Eb0,
    EdgeEdgeCase::Ea0Eb1,
    EdgeEdgeCase::Ea1Eb0,
    EdgeEdgeCase::Ea1Eb1,
    EdgeEdgeCase::Ea0Eb,
    EdgeEdgeCase::Ea1Eb,
    EdgeEdgeCase::EaEb0,
    EdgeEdgeCase::EaEb1,
    EdgeEdgeCase::LineLine,
];

// ---------------------------------------------------------------------------------------------
// Independent references
// ---------------------------------------------------------------------------------------------

/// Squared distance from p to the closed segment (a, b): the clamped projection, then the
/// distance to that point (not the module's formula).
fn segment_reference(p: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    let e = b - a;
    let ee = e.dot(&e);
    let s = if ee > 0.0 {
        ((p - a).dot(&e) / ee).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + s * e - p).norm_squared()
}

/// Point–triangle by active sets: the free minimiser over barycentric coordinates if it is
/// feasible, and the three edges (which hold the vertices).
fn point_triangle_enumeration(p: &Vec3, t: &[Vec3; 3]) -> f64 {
    let mut best = segment_reference(p, &t[0], &t[1])
        .min(segment_reference(p, &t[1], &t[2]))
        .min(segment_reference(p, &t[2], &t[0]));
    let (u, v, w) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (uu, uv, vv) = (u.dot(&u), u.dot(&v), v.dot(&v));
    let det = uu * vv - uv * uv;
    if det > 1e-12 * uu * vv {
        let (bu, bv) = (u.dot(&w), v.dot(&w));
        let a = (vv * bu - uv * bv) / det;
        let b = (uu * bv - uv * bu) / det;
        if a >= 0.0 && b >= 0.0 && a + b <= 1.0 {
            best = best.min((t[0] + a * u + b * v - p).norm_squared());
        }
    }
    best
}

/// Point–triangle by a scan: for 2001 values of the barycentric coordinate a along t1 − t0, the
/// exact distance to the segment {t0 + a u + b v : 0 ≤ b ≤ 1 − a}. Returns the smallest and the
/// bound δ (m) on how far its square root can lie above the true distance: the segments of
/// neighbouring a are within h·max(|u|, |v − u|) of each other (Hausdorff), h the spacing, and the
/// nearest scanned a is within h/2.
fn point_triangle_scan(p: &Vec3, t: &[Vec3; 3]) -> (f64, f64) {
    const N: usize = 2000;
    let (u, v) = (t[1] - t[0], t[2] - t[0]);
    let mut best = f64::INFINITY;
    for i in 0..=N {
        let a = i as f64 / N as f64;
        let start = t[0] + a * u;
        best = best.min(segment_reference(p, &start, &(start + (1.0 - a) * v)));
    }
    let delta = 0.5 / N as f64 * u.norm().max((v - u).norm());
    (best, delta)
}

/// Edge–edge by active sets: the free minimiser over (s, t) if it is feasible, and the four
/// endpoint-to-segment distances.
fn edge_edge_enumeration(a0: &Vec3, a1: &Vec3, b0: &Vec3, b1: &Vec3) -> f64 {
    let mut best = segment_reference(a0, b0, b1)
        .min(segment_reference(a1, b0, b1))
        .min(segment_reference(b0, a0, a1))
        .min(segment_reference(b1, a0, a1));
    let (u, v, w) = (a1 - a0, b1 - b0, a0 - b0);
    let (uu, uv, vv) = (u.dot(&u), u.dot(&v), v.dot(&v));
    let det = uu * vv - uv * uv;
    if det > 1e-12 * uu * vv {
        // Minimise |w + s u − t v|²: uu s − uv t = −u·w, uv s − vv t = −v·w.
        let (ru, rv) = (-u.dot(&w), -v.dot(&w));
        let s = (-vv * ru + uv * rv) / (-det);
        let t = (uu * rv - uv * ru) / (-det);
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            best = best.min((w + s * u - t * v).norm_squared());
        }
    }
    best
}

/// Edge–edge by a scan: for 2001 points along edge a, the exact distance to segment b. The
/// distance to segment b is |u|-Lipschitz in s, so the square root of the smallest is within
/// δ = |u|·h/2 above the true distance.
fn edge_edge_scan(a0: &Vec3, a1: &Vec3, b0: &Vec3, b1: &Vec3) -> (f64, f64) {
    const N: usize = 2000;
    let u = a1 - a0;
    let mut best = f64::INFINITY;
    for i in 0..=N {
        let s = i as f64 / N as f64;
        best = best.min(segment_reference(&(a0 + s * u), b0, b1));
    }
    (best, 0.5 / N as f64 * u.norm())
}

/// The reference check of a distance d against a scan (smallest `scan`, bound `delta`) and an
/// exact reference `exact`: d is at most every scanned distance, at least the scan minus its
/// bound, and equal to `exact` within `tol` (m²).
fn check_value(d: f64, exact: f64, scan: (f64, f64), tol: f64) -> Result<(), TestCaseError> {
    prop_assert!(d.is_finite() && d >= 0.0, "d = {d}");
    prop_assert!(
        (d - exact).abs() <= tol,
        "d = {d}, exact {exact}, tol {tol}"
    );
    prop_assert!(d <= scan.0 + tol, "d = {d} above the scan's {}", scan.0);
    prop_assert!(
        scan.0.sqrt() - d.sqrt() <= scan.1 * (1.0 + 1e-9) + tol.sqrt(),
        "d = {d} far below the scan's {} (bound {})",
        scan.0,
        scan.1
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Finite differences
// ---------------------------------------------------------------------------------------------

fn vertex<const N: usize>(x: &SVector<f64, N>, i: usize) -> Vec3 {
    Vec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

fn stack4(a: &Vec3, b: &Vec3, c: &Vec3, d: &Vec3) -> V12 {
    let mut x = V12::zeros();
    for (i, v) in [a, b, c, d].into_iter().enumerate() {
        x.fixed_rows_mut::<3>(3 * i).copy_from(v);
    }
    x
}

/// Central differences of a scalar function, step h.
fn fd_gradient<const N: usize>(
    f: impl Fn(&SVector<f64, N>) -> f64,
    x: &SVector<f64, N>,
    h: f64,
) -> SVector<f64, N> {
    SVector::from_fn(|i, _| {
        let (mut xp, mut xm) = (*x, *x);
        xp[i] += h;
        xm[i] -= h;
        (f(&xp) - f(&xm)) / (2.0 * h)
    })
}

/// Central differences of a gradient (column j is ∂g/∂x_j), step h.
fn fd_jacobian<const N: usize>(
    g: impl Fn(&SVector<f64, N>) -> SVector<f64, N>,
    x: &SVector<f64, N>,
    h: f64,
) -> SMatrix<f64, N, N> {
    let mut jac = SMatrix::<f64, N, N>::zeros();
    for j in 0..N {
        let (mut xp, mut xm) = (*x, *x);
        xp[j] += h;
        xm[j] -= h;
        jac.set_column(j, &((g(&xp) - g(&xm)) / (2.0 * h)));
    }
    jac
}

/// The finite-difference step and tolerance. With h = 1e-6·L (L the configuration's size), the
/// central difference errs by h²|f'''|/6 ≈ 1e-12·K (relative, K the conditioning: ratios of
/// lengths and 1/sin of angles, below ~1e2 in the generated configurations) plus the rounding
/// ε|f|/h ≈ 2e-10 (relative to f'·L). So 1e-6 relative to the derivative's size, floored at its
/// natural size (L for gradients of m² quantities, 1 for their Hessians), leaves a margin of
/// 1e3 over the expected error, and still catches any wrong term (which is O(1) relative).
const FD_STEP: f64 = 1e-6;
const FD_TOL: f64 = 1e-6;

/// Checks an analytic gradient and Hessian of f against central differences, the Hessian's
/// exact symmetry, and that the gradient-only variant gives the same value and gradient.
#[allow(clippy::too_many_arguments)]
fn check_derivatives<const N: usize>(
    what: &str,
    value: impl Fn(&SVector<f64, N>) -> f64,
    gradient: impl Fn(&SVector<f64, N>) -> (f64, SVector<f64, N>),
    hessian: impl Fn(&SVector<f64, N>) -> (f64, SVector<f64, N>, SMatrix<f64, N, N>),
    x: &SVector<f64, N>,
    h: f64,
    length: f64,
    gradient_floor: f64,
    hessian_floor: f64,
) -> Result<(), TestCaseError> {
    let (d, g, hess) = hessian(x);
    let (d_g, g_g) = gradient(x);
    prop_assert!(
        d.is_finite() && g.iter().all(|v| v.is_finite()),
        "{what}: not finite"
    );
    prop_assert!(
        hess.iter().all(|v| v.is_finite()),
        "{what}: Hessian not finite"
    );
    // The three entry points compute the same thing by the same arithmetic.
    let d_v = value(x);
    prop_assert!(
        (d - d_v).abs() <= 1e-12 * d.abs().max(gradient_floor * length),
        "{what}: value {d} vs {d_v}"
    );
    prop_assert!(
        (d - d_g).abs() <= 1e-12 * d.abs().max(gradient_floor * length),
        "{what}: value {d} vs {d_g}"
    );
    prop_assert!(
        (g - g_g).amax() <= 1e-12 * g.amax().max(gradient_floor),
        "{what}: gradients differ"
    );
    prop_assert!(
        hess == hess.transpose(),
        "{what}: Hessian not exactly symmetric"
    );

    let g_fd = fd_gradient(&value, x, h);
    let tol = FD_TOL * g.amax().max(gradient_floor);
    prop_assert!(
        (g - g_fd).amax() <= tol,
        "{what}: gradient off by {} (tol {tol})\nanalytic {g}\nfd {g_fd}",
        (g - g_fd).amax()
    );
    let h_fd = fd_jacobian(|y| gradient(y).1, x, h);
    let tol = FD_TOL * hess.amax().max(hessian_floor);
    prop_assert!(
        (hess - h_fd).amax() <= tol,
        "{what}: Hessian off by {} (tol {tol})\nanalytic {hess}\nfd {h_fd}",
        (hess - h_fd).amax()
    );
    Ok(())
}

/// The squared distances are invariant under translation: the four 3-blocks of the gradient sum to
/// zero, and so do the block rows of the Hessian (up to rounding relative to their size).
fn check_translation_invariance(g: &V12, h: &M12, scale_g: f64) -> Result<(), TestCaseError> {
    let sum_g: Vec3 = (0..4).map(|i| vertex(g, i)).sum();
    prop_assert!(
        sum_g.amax() <= 1e-12 * g.amax().max(scale_g),
        "gradient blocks sum to {sum_g}"
    );
    let h_amax = h.amax().max(1.0);
    for r in 0..12 {
        let row_sum: Vec3 = (0..4)
            .map(|j| Vec3::new(h[(r, 3 * j)], h[(r, 3 * j + 1)], h[(r, 3 * j + 2)]))
            .sum();
        prop_assert!(
            row_sum.amax() <= 1e-11 * h_amax,
            "Hessian row {r} blocks sum to {row_sum}"
        );
    }
    Ok(())
}

/// The vertices (of 4) that a point–triangle case involves.
fn pt_involved(case: PointTriangleCase) -> [bool; 4] {
    match case {
        PointTriangleCase::Vertex(k) => {
            let mut m = [true, false, false, false];
            m[1 + k as usize] = true;
            m
        }
        PointTriangleCase::Edge(k) => {
            let mut m = [true, false, false, false];
            m[1 + k as usize] = true;
            m[1 + (k as usize + 1) % 3] = true;
            m
        }
        PointTriangleCase::Face => [true; 4],
    }
}

/// The vertices (of 4) that an edge–edge case involves.
fn ee_involved(case: EdgeEdgeCase) -> [bool; 4] {
    use EdgeEdgeCase::*;
    match case {
        Ea0Eb0 => [true, false, true, false],
        Ea0Eb1 => [true, false, false, true],
        Ea1Eb0 => [false, true, true, false],
        Ea1Eb1 => [false, true, false, true],
        Ea0Eb => [true, false, true, true],
        Ea1Eb => [false, true, true, true],
        EaEb0 => [true, true, true, false],
        EaEb1 => [true, true, false, true],
        LineLine => [true; 4],
    }
}

/// Gradient rows and Hessian rows and columns of uninvolved vertices are exactly zero.
fn check_uninvolved_zero(involved: [bool; 4], g: &V12, h: &M12) -> Result<(), TestCaseError> {
    for (i, &inv) in involved.iter().enumerate() {
        if !inv {
            prop_assert!(
                vertex(g, i) == Vec3::zeros(),
                "gradient of uninvolved vertex {i}"
            );
            for r in 0..3 {
                prop_assert!(h.row(3 * i + r).iter().all(|&v| v == 0.0));
                prop_assert!(h.column(3 * i + r).iter().all(|&v| v == 0.0));
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Strategies
// ---------------------------------------------------------------------------------------------

fn unit_vec3() -> impl Strategy<Value = Vec3> {
    [-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64].prop_map(Vec3::from)
}

/// Sizes from a millimetre to a hundred metres, to check that nothing depends on units.
fn scale() -> impl Strategy<Value = f64> {
    prop_oneof![Just(1e-3), Just(1.0), Just(1e2)]
}

/// |u × v| / max(|u|², |v|², |u − v|²): twice the area over the longest edge squared, which is
/// about the sine of the triangle's smallest angle.
fn triangle_quality(t0: &Vec3, t1: &Vec3, t2: &Vec3) -> f64 {
    let (u, v) = (t1 - t0, t2 - t0);
    let longest = u
        .norm_squared()
        .max(v.norm_squared())
        .max((v - u).norm_squared());
    u.cross(&v).norm() / longest
}

/// sin of the angle between two edges.
fn edge_sine(a0: &Vec3, a1: &Vec3, b0: &Vec3, b1: &Vec3) -> f64 {
    let (u, v) = (a1 - a0, b1 - b0);
    u.cross(&v).norm() / (u.norm() * v.norm())
}

// ---------------------------------------------------------------------------------------------
// Values and classification
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// The point–triangle distance against the enumeration and the scan, and its case's primitive
    /// equal to it, for points anywhere near a random triangle (all seven regions come up).
    #[test]
    fn point_triangle_value_matches_references(
        t in [unit_vec3(), unit_vec3(), unit_vec3()],
        ab in (-0.6..1.6f64, -0.6..1.6f64),
        height in -1.0..1.0f64,
        scale in scale(),
    ) {
        let t = t.map(|v| v * scale);
        prop_assume!(triangle_quality(&t[0], &t[1], &t[2]) > 1e-3);
        let (u, v) = (t[1] - t[0], t[2] - t[0]);
        let n = u.cross(&v).normalize();
        let p = t[0] + ab.0 * u + ab.1 * v + height * scale * n;

        let d = point_triangle_distance_squared(&p, &t[0], &t[1], &t[2]);
        let length = (p - t[0]).norm().max(u.norm()).max(v.norm());
        // The references and d are each accurate to a few ε·L²·K; 1e-10·L² leaves room.
        let tol = 1e-10 * length * length;
        check_value(d, point_triangle_enumeration(&p, &t), point_triangle_scan(&p, &t), tol)?;

        let case = point_triangle_case(&p, &t[0], &t[1], &t[2]);
        // The case's primitive through the public primitives, then through the combined function.
        let primitive = match case {
            PointTriangleCase::Vertex(k) => point_point_distance_squared(&p, &t[k as usize]),
            PointTriangleCase::Edge(k) => {
                point_line_distance_squared(&p, &t[k as usize], &t[(k as usize + 1) % 3])
            }
            PointTriangleCase::Face => point_plane_distance_squared(&p, &t[0], &t[1], &t[2]),
        };
        prop_assert!((primitive - d).abs() <= tol, "{case:?}: primitive {primitive} vs {d}");
        let (d_case, _) = point_triangle_distance_squared_gradient(&p, &t[0], &t[1], &t[2], case);
        prop_assert!((d_case - d).abs() <= tol, "{case:?}: {d_case} vs {d}");
    }

    /// The edge–edge distance against the enumeration and the scan, and its case's primitive
    /// equal to it. Edges are random, so every case comes up.
    #[test]
    fn edge_edge_value_matches_references(
        e in [unit_vec3(), unit_vec3(), unit_vec3(), unit_vec3()],
        scale in scale(),
    ) {
        let [a0, a1, b0, b1] = e.map(|v| v * scale);
        prop_assume!((a1 - a0).norm() > 1e-3 * scale && (b1 - b0).norm() > 1e-3 * scale);
        let d = edge_edge_distance_squared(&a0, &a1, &b0, &b1);
        let length = [a0, a1, b0, b1].iter().map(|v| v.norm()).fold(0.0, f64::max);
        let tol = 1e-10 * length * length;
        check_value(d, edge_edge_enumeration(&a0, &a1, &b0, &b1), edge_edge_scan(&a0, &a1, &b0, &b1), tol)?;

        let case = edge_edge_case(&a0, &a1, &b0, &b1);
        use EdgeEdgeCase::*;
        let primitive = match case {
            Ea0Eb0 => point_point_distance_squared(&a0, &b0),
            Ea0Eb1 => point_point_distance_squared(&a0, &b1),
            Ea1Eb0 => point_point_distance_squared(&a1, &b0),
            Ea1Eb1 => point_point_distance_squared(&a1, &b1),
            Ea0Eb => point_line_distance_squared(&a0, &b0, &b1),
            Ea1Eb => point_line_distance_squared(&a1, &b0, &b1),
            EaEb0 => point_line_distance_squared(&b0, &a0, &a1),
            EaEb1 => point_line_distance_squared(&b1, &a0, &a1),
            LineLine => line_line_distance_squared(&a0, &a1, &b0, &b1),
        };
        prop_assert!((primitive - d).abs() <= tol, "{case:?}: primitive {primitive} vs {d}");
        let (d_case, _) = edge_edge_distance_squared_gradient(&a0, &a1, &b0, &b1, case);
        prop_assert!((d_case - d).abs() <= tol, "{case:?}: {d_case} vs {d}");
        // The distance is symmetric in the two edges and in each edge's orientation.
        let swapped = edge_edge_distance_squared(&b1, &b0, &a0, &a1);
        prop_assert!((swapped - d).abs() <= tol, "swapped {swapped} vs {d}");
    }
}

// ---------------------------------------------------------------------------------------------
// Derivatives
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Every point–triangle case's value, gradient and Hessian over the 12 DOFs against finite
    /// differences, at points around well-shaped triangles. Each case's primitive is smooth
    /// everywhere (not only in its region), so all seven are checked at every configuration and
    /// no region boundary needs avoiding.
    #[test]
    fn point_triangle_derivatives_match_finite_differences(
        t in [unit_vec3(), unit_vec3(), unit_vec3()],
        ab in (-0.6..1.6f64, -0.6..1.6f64),
        height in -1.0..1.0f64,
        scale in scale(),
    ) {
        let t = t.map(|v| v * scale);
        prop_assume!(triangle_quality(&t[0], &t[1], &t[2]) > 0.1);
        let (u, v) = (t[1] - t[0], t[2] - t[0]);
        prop_assume!(u.norm().max(v.norm()) > 0.3 * scale);
        let n = u.cross(&v).normalize();
        let p = t[0] + ab.0 * u + ab.1 * v + height * scale * n;
        let x = stack4(&p, &t[0], &t[1], &t[2]);
        let length = (p - t[0]).norm().max(u.norm()).max(v.norm());
        for case in PT_CASES {
            let split = |x: &V12| (vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
            check_derivatives(
                &format!("point-triangle {case:?}"),
                |x| { let (p, a, b, c) = split(x); point_triangle_distance_squared_gradient(&p, &a, &b, &c, case).0 },
                |x| { let (p, a, b, c) = split(x); point_triangle_distance_squared_gradient(&p, &a, &b, &c, case) },
                |x| { let (p, a, b, c) = split(x); point_triangle_distance_squared_hessian(&p, &a, &b, &c, case) },
                &x, FD_STEP * length, length, length, 1.0,
            )?;
            let (_, g, h) = point_triangle_distance_squared_hessian(&p, &t[0], &t[1], &t[2], case);
            check_translation_invariance(&g, &h, length)?;
            check_uninvolved_zero(pt_involved(case), &g, &h)?;
        }
    }

    /// Every edge–edge case's value, gradient and Hessian over the 12 DOFs against finite
    /// differences, for edges at least ~6° from parallel (line–line's derivatives grow like
    /// 1/sin of the angle; near-parallel edges are tested for robustness below).
    #[test]
    fn edge_edge_derivatives_match_finite_differences(
        e in [unit_vec3(), unit_vec3(), unit_vec3(), unit_vec3()],
        scale in scale(),
    ) {
        let [a0, a1, b0, b1] = e.map(|v| v * scale);
        prop_assume!((a1 - a0).norm() > 0.2 * scale && (b1 - b0).norm() > 0.2 * scale);
        prop_assume!(edge_sine(&a0, &a1, &b0, &b1) > 0.1);
        let x = stack4(&a0, &a1, &b0, &b1);
        let length = [a1 - a0, b0 - a0, b1 - a0].iter().map(|v| v.norm()).fold(0.0, f64::max);
        for case in EE_CASES {
            let split = |x: &V12| (vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
            check_derivatives(
                &format!("edge-edge {case:?}"),
                |x| { let (a, b, c, d) = split(x); edge_edge_distance_squared_gradient(&a, &b, &c, &d, case).0 },
                |x| { let (a, b, c, d) = split(x); edge_edge_distance_squared_gradient(&a, &b, &c, &d, case) },
                |x| { let (a, b, c, d) = split(x); edge_edge_distance_squared_hessian(&a, &b, &c, &d, case) },
                &x, FD_STEP * length, length, length, 1.0,
            )?;
            let (_, g, h) = edge_edge_distance_squared_hessian(&a0, &a1, &b0, &b1, case);
            check_translation_invariance(&g, &h, length)?;
            check_uninvolved_zero(ee_involved(case), &g, &h)?;
        }
    }

    /// The four primitives over their own DOFs (6, 9, 12, 12): value, gradient-only and Hessian
    /// variants against finite differences and each other.
    #[test]
    fn primitive_derivatives_match_finite_differences(
        e in [unit_vec3(), unit_vec3(), unit_vec3(), unit_vec3()],
        scale in scale(),
    ) {
        let [a, b, c, d] = e.map(|v| v * scale);
        prop_assume!((c - b).norm() > 0.2 * scale && (d - c).norm() > 0.2 * scale);
        prop_assume!(triangle_quality(&b, &c, &d) > 0.1);
        prop_assume!(edge_sine(&a, &b, &c, &d) > 0.1);
        let length = [b - a, c - a, d - a].iter().map(|v| v.norm()).fold(0.0, f64::max);

        let x6 = SVector::<f64, 6>::from_iterator(a.iter().chain(b.iter()).copied());
        check_derivatives(
            "point-point",
            |x| point_point_distance_squared(&vertex(x, 0), &vertex(x, 1)),
            |x| point_point_distance_squared_gradient(&vertex(x, 0), &vertex(x, 1)),
            |x| point_point_distance_squared_hessian(&vertex(x, 0), &vertex(x, 1)),
            &x6, FD_STEP * length, length, length, 1.0,
        )?;
        let x9 = SVector::<f64, 9>::from_iterator(a.iter().chain(b.iter()).chain(c.iter()).copied());
        check_derivatives(
            "point-line",
            |x| point_line_distance_squared(&vertex(x, 0), &vertex(x, 1), &vertex(x, 2)),
            |x| point_line_distance_squared_gradient(&vertex(x, 0), &vertex(x, 1), &vertex(x, 2)),
            |x| point_line_distance_squared_hessian(&vertex(x, 0), &vertex(x, 1), &vertex(x, 2)),
            &x9, FD_STEP * length, length, length, 1.0,
        )?;
        let x12 = stack4(&a, &b, &c, &d);
        let split = |x: &V12| (vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
        check_derivatives(
            "point-plane",
            |x| { let (p, q, r, s) = split(x); point_plane_distance_squared(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); point_plane_distance_squared_gradient(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); point_plane_distance_squared_hessian(&p, &q, &r, &s) },
            &x12, FD_STEP * length, length, length, 1.0,
        )?;
        check_derivatives(
            "line-line",
            |x| { let (p, q, r, s) = split(x); line_line_distance_squared(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); line_line_distance_squared_gradient(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); line_line_distance_squared_hessian(&p, &q, &r, &s) },
            &x12, FD_STEP * length, length, length, 1.0,
        )?;

        // The primitives against their definitions: the foot of the perpendicular, the normal.
        let foot_t = (a - b).dot(&(c - b)) / (c - b).norm_squared();
        let foot = b + foot_t * (c - b);
        let tol = 1e-12 * length * length;
        prop_assert!((point_line_distance_squared(&a, &b, &c) - (a - foot).norm_squared()).abs() <= tol);
        let normal = (c - b).cross(&(d - b)).normalize();
        prop_assert!((point_plane_distance_squared(&a, &b, &c, &d) - (a - b).dot(&normal).powi(2)).abs() <= tol);
        let normal = (b - a).cross(&(d - c)).normalize();
        prop_assert!((line_line_distance_squared(&a, &b, &c, &d) - (c - a).dot(&normal).powi(2)).abs() <= tol);
    }
}

// ---------------------------------------------------------------------------------------------
// Degenerate and nearly degenerate configurations
// ---------------------------------------------------------------------------------------------

/// The 12-DOF derivatives of a case are finite (no NaN, no infinity).
fn all_finite(d: f64, g: &V12, h: &M12) -> bool {
    d.is_finite() && g.iter().all(|v| v.is_finite()) && h.iter().all(|v| v.is_finite())
}

/// Exactly parallel edges at every overlap, both orientations: never `LineLine`, the distance
/// right, the derivatives finite.
#[test]
fn parallel_edges_are_never_line_line() {
    let a0 = Vec3::new(0.0, 0.0, 0.0);
    let a1 = Vec3::new(1.0, 0.0, 0.0);
    for start in [-2.0, -0.5, 0.0, 0.3, 0.9, 1.0, 1.5] {
        for length in [0.25, 1.0, 3.0] {
            for offset in [
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 0.3, 0.4),
                Vec3::zeros(),
            ] {
                let b0 = Vec3::new(start, 0.0, 0.0) + offset;
                let b1 = b0 + Vec3::new(length, 0.0, 0.0);
                // Gap along x between the intervals [0, 1] and [start, start + length].
                let gap = (start - 1.0).max(-(start + length)).max(0.0);
                let expected = offset.norm_squared() + gap * gap;
                for (p0, p1, q0, q1) in [(a0, a1, b0, b1), (a1, a0, b1, b0), (b0, b1, a1, a0)] {
                    let case = edge_edge_case(&p0, &p1, &q0, &q1);
                    assert_ne!(
                        case,
                        EdgeEdgeCase::LineLine,
                        "start {start}, length {length}"
                    );
                    let d = edge_edge_distance_squared(&p0, &p1, &q0, &q1);
                    assert!(
                        (d - expected).abs() <= 1e-14,
                        "{d} vs {expected} ({case:?})"
                    );
                    let (dh, g, h) = edge_edge_distance_squared_hessian(&p0, &p1, &q0, &q1, case);
                    assert!(all_finite(dh, &g, &h));
                    assert!((dh - expected).abs() <= 1e-14);
                }
            }
        }
    }
    // The line–line primitive itself on parallel lines: the point–line distance, finite.
    let b0 = Vec3::new(0.5, 0.3, 0.4);
    let b1 = Vec3::new(2.0, 0.3, 0.4);
    let (d, g, h) = line_line_distance_squared_hessian(&a0, &a1, &b0, &b1);
    assert!(all_finite(d, &g, &h));
    assert!(
        (d - 0.25).abs() <= 1e-15
            && (line_line_distance_squared(&a0, &a1, &b0, &b1) - 0.25).abs() <= 1e-15
    );
    let (dg, gg) = line_line_distance_squared_gradient(&a0, &a1, &b0, &b1);
    assert_eq!((dg, gg), (d, g));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Nearly parallel edges, at angles from 1e-16 to 1e-4 rad, in random placements: no NaN, no
    /// `LineLine` below the threshold sin²θ ≤ 1e-16 (tested with a margin for the rounding of
    /// sin θ), and the value right: within ~ε/sin θ of the lengths where `LineLine` is allowed
    /// (the rounding in its normal) and never off by more than 1e-7 of them.
    #[test]
    fn nearly_parallel_edges(
        a0 in unit_vec3(),
        dir in unit_vec3(),
        side in unit_vec3(),
        exponent in -16.0..-4.0f64,
        along in (-1.5..1.5f64, 0.2..2.0f64),
        offset in 0.0..0.5f64,
        exact in any::<bool>(),
    ) {
        prop_assume!(dir.norm() > 0.2);
        let dir = dir.normalize();
        let perp = side - side.dot(&dir) * dir;
        prop_assume!(perp.norm() > 0.2);
        let perp = perp.normalize();
        let theta = if exact { 0.0 } else { 10f64.powf(exponent) };
        let a1 = a0 + dir;
        let b_dir = theta.cos() * dir + theta.sin() * perp;
        let b0 = a0 + along.0 * dir + offset * perp.cross(&dir) + 0.1 * offset * perp;
        let b1 = b0 + along.1 * b_dir;

        let case = edge_edge_case(&a0, &a1, &b0, &b1);
        let sine = edge_sine(&a0, &a1, &b0, &b1);
        if sine * sine <= 0.5e-16 {
            prop_assert_ne!(case, EdgeEdgeCase::LineLine);
        }
        let d = edge_edge_distance_squared(&a0, &a1, &b0, &b1);
        let (scan, delta) = edge_edge_scan(&a0, &a1, &b0, &b1);
        let exact_d = edge_edge_enumeration(&a0, &a1, &b0, &b1);
        let length = 4.0; // all points lie within ~4 of each other
        let tol = 1e-9 * length + (10.0 * f64::EPSILON / sine.max(1e-300)).min(1e-9) * length;
        prop_assert!(d.is_finite() && d >= 0.0);
        prop_assert!((d.sqrt() - exact_d.sqrt()).abs() <= tol, "{case:?}: {d} vs {exact_d}");
        prop_assert!(d.sqrt() <= scan.sqrt() + tol && scan.sqrt() - d.sqrt() <= delta + tol);
        let (dh, g, h) = edge_edge_distance_squared_hessian(&a0, &a1, &b0, &b1, case);
        prop_assert!(all_finite(dh, &g, &h), "{case:?}: not finite");
        prop_assert!(h == h.transpose());
    }

    /// Points right over (or on) a triangle's edge or vertex, up to a rounding's jitter: on the
    /// boundary between regions, whichever case comes out gives the right value, and the
    /// neighbouring regions' primitives agree there.
    #[test]
    fn points_over_edges_and_vertices(
        t in [unit_vec3(), unit_vec3(), unit_vec3()],
        k in 0u8..3,
        s in prop_oneof![Just(0.0), Just(1.0), 0.0..1.0f64],
        height in prop_oneof![Just(0.0), Just(1e-12), -1.0..1.0f64],
        jitter in unit_vec3(),
    ) {
        prop_assume!(triangle_quality(&t[0], &t[1], &t[2]) > 0.05);
        let (a, b) = (t[k as usize], t[(k as usize + 1) % 3]);
        let n = (t[1] - t[0]).cross(&(t[2] - t[0])).normalize();
        let p = a + s * (b - a) + height * n + 1e-15 * jitter;
        let expected = height * height;
        let d = point_triangle_distance_squared(&p, &t[0], &t[1], &t[2]);
        // The jitter moves the distance by ≤ 1e-15, so the square by ≤ 2e-15|h| + 1e-30.
        let tol = 1e-13;
        prop_assert!((d - expected).abs() <= tol, "{d} vs {expected}");
        let case = point_triangle_case(&p, &t[0], &t[1], &t[2]);
        let (dh, g, h) = point_triangle_distance_squared_hessian(&p, &t[0], &t[1], &t[2], case);
        prop_assert!(all_finite(dh, &g, &h));
        prop_assert!((dh - expected).abs() <= tol, "{case:?}: {dh} vs {expected}");
        // The three features meeting there all give h² (the face, the edge, and at an end the
        // vertex).
        let face = point_plane_distance_squared(&p, &t[0], &t[1], &t[2]);
        let edge = point_line_distance_squared(&p, &a, &b);
        prop_assert!((face - expected).abs() <= tol && (edge - expected).abs() <= tol);
        if s == 0.0 {
            prop_assert!((point_point_distance_squared(&p, &a) - expected).abs() <= tol);
        }
    }

    /// Zero-area triangles (collinear, two or three coincident vertices) never give `Face`; the
    /// distance is that to their segment; the case's derivatives are finite. Slivers just above
    /// zero area still get the right value.
    #[test]
    fn degenerate_triangles(
        t0 in unit_vec3(),
        t1 in unit_vec3(),
        p in unit_vec3(),
        lambda in prop_oneof![Just(0.0), Just(1.0), -1.0..2.0f64],
        coincide in any::<bool>(),
        width in prop_oneof![Just(0.0), Just(1e-14), Just(1e-8)],
        side in unit_vec3(),
        rotate in 0usize..3,
    ) {
        let t1 = if coincide { t0 } else { t1 };
        let t2 = t0 + lambda * (t1 - t0) + width * side;
        let mut t = [t0, t1, t2];
        t.rotate_left(rotate);
        let case = point_triangle_case(&p, &t[0], &t[1], &t[2]);
        if width == 0.0 {
            prop_assert_ne!(case, PointTriangleCase::Face);
        }
        let d = point_triangle_distance_squared(&p, &t[0], &t[1], &t[2]);
        let expected = point_triangle_enumeration(&p, &t);
        // A sliver of width w is at most w from its edges.
        let tol = 1e-12 + 4.0 * width;
        prop_assert!((d - expected).abs() <= tol, "{case:?}: {d} vs {expected}");
        let (dh, g, h) = point_triangle_distance_squared_hessian(&p, &t[0], &t[1], &t[2], case);
        prop_assert!(all_finite(dh, &g, &h), "{case:?}: not finite");
        prop_assert!((dh - d).abs() <= 1e-14 * d.max(1.0));
        prop_assert!(h == h.transpose());
        // The point–plane primitive of an exactly flat triangle falls back to its line.
        // (Collinear up to rounding is not exactly flat: then the plane is a rounding's, and only
        // finiteness is asked of it.)
        let (dp, gp, hp) = point_plane_distance_squared_hessian(&p, &t[0], &t[1], &t[2]);
        prop_assert!(all_finite(dp, &gp, &hp));
        if (t[1] - t[0]).cross(&(t[2] - t[0])) == Vec3::zeros() {
            prop_assert!(dp <= d + 1e-12, "the line through the triangle is nearer than it");
        }
    }

    /// Zero-length edges (one or both): never `LineLine`, the distance that to the other segment
    /// or point, derivatives finite.
    #[test]
    fn zero_length_edges(
        e in [unit_vec3(), unit_vec3(), unit_vec3()],
        both in any::<bool>(),
        swap in any::<bool>(),
    ) {
        let [a0, b0, b1] = e;
        let b1 = if both { b0 } else { b1 };
        let (p0, p1, q0, q1) = if swap { (b0, b1, a0, a0) } else { (a0, a0, b0, b1) };
        let case = edge_edge_case(&p0, &p1, &q0, &q1);
        prop_assert_ne!(case, EdgeEdgeCase::LineLine);
        let d = edge_edge_distance_squared(&p0, &p1, &q0, &q1);
        let expected = segment_reference(&a0, &b0, &b1);
        prop_assert!((d - expected).abs() <= 1e-13, "{case:?}: {d} vs {expected}");
        let (dh, g, h) = edge_edge_distance_squared_hessian(&p0, &p1, &q0, &q1, case);
        prop_assert!(all_finite(dh, &g, &h) && (dh - d).abs() <= 1e-13);
        // The point–line primitive of a zero-length edge is the point–point distance.
        let (dl, gl, hl) = point_line_distance_squared_hessian(&b0, &a0, &a0);
        let (dp, gp, hp) = point_point_distance_squared_hessian(&b0, &a0);
        prop_assert_eq!(dl, dp);
        prop_assert!(gl.rows(0, 6) == gp && gl.rows(6, 3).iter().all(|&v| v == 0.0));
        prop_assert!(hl.view((0, 0), (6, 6)) == hp);
    }
}

/// A few configurations worked by hand, for each kind of case.
#[test]
fn hand_worked_cases() {
    let t0 = Vec3::new(0.0, 0.0, 0.0);
    let t1 = Vec3::new(1.0, 0.0, 0.0);
    let t2 = Vec3::new(0.0, 1.0, 0.0);
    let checks = [
        (Vec3::new(0.25, 0.25, 2.0), PointTriangleCase::Face, 4.0),
        (Vec3::new(2.0, 0.0, 1.0), PointTriangleCase::Vertex(1), 2.0),
        (
            Vec3::new(-1.0, -1.0, 0.0),
            PointTriangleCase::Vertex(0),
            2.0,
        ),
        (Vec3::new(0.0, 3.0, 0.0), PointTriangleCase::Vertex(2), 4.0),
        (Vec3::new(0.5, -1.0, 1.0), PointTriangleCase::Edge(0), 2.0),
        (Vec3::new(1.0, 1.0, 0.0), PointTriangleCase::Edge(1), 0.5),
        (Vec3::new(-0.5, 0.5, 0.0), PointTriangleCase::Edge(2), 0.25),
    ];
    for (p, case, d) in checks {
        assert_eq!(point_triangle_case(&p, &t0, &t1, &t2), case, "{p}");
        assert!(
            (point_triangle_distance_squared(&p, &t0, &t1, &t2) - d).abs() < 1e-15,
            "{p}"
        );
    }
    // Face: the gradient pushes p along the normal, 2h n, and pulls the vertices by thirds of
    // it weighted by barycentric coordinates (0.5, 0.25, 0.25).
    let (_, g) = point_triangle_distance_squared_gradient(
        &checks[0].0,
        &t0,
        &t1,
        &t2,
        PointTriangleCase::Face,
    );
    let expected = V12::from_column_slice(&[
        0.0, 0.0, 4.0, 0.0, 0.0, -2.0, 0.0, 0.0, -1.0, 0.0, 0.0, -1.0,
    ]);
    assert!((g - expected).amax() < 1e-14, "{g}");

    use EdgeEdgeCase::*;
    let a0 = Vec3::new(0.0, 0.0, 0.0);
    let a1 = Vec3::new(1.0, 0.0, 0.0);
    let ee = [
        (
            Vec3::new(0.5, -1.0, 1.0),
            Vec3::new(0.5, 1.0, 1.0),
            LineLine,
            1.0,
        ),
        (
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(2.0, 1.0, 1.0),
            Ea1Eb,
            2.0,
        ),
        (
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
            Ea0Eb,
            2.0,
        ),
        (
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, 2.0, 0.0),
            EaEb0,
            1.0,
        ),
        (
            Vec3::new(0.5, 2.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            EaEb1,
            1.0,
        ),
        (
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(3.0, 2.0, 0.0),
            Ea1Eb0,
            2.0,
        ),
        (
            Vec3::new(3.0, 2.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Ea1Eb1,
            2.0,
        ),
        (
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(-2.0, 2.0, 0.0),
            Ea0Eb0,
            2.0,
        ),
        (
            Vec3::new(-2.0, 2.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
            Ea0Eb1,
            2.0,
        ),
    ];
    for (b0, b1, case, d) in ee {
        assert_eq!(edge_edge_case(&a0, &a1, &b0, &b1), case, "{b0} {b1}");
        assert!((edge_edge_distance_squared(&a0, &a1, &b0, &b1) - d).abs() < 1e-15);
    }
}

/// NaN in, NaN out: no panic, no silent finite answer.
#[test]
fn nan_inputs_give_nan() {
    let z = Vec3::zeros();
    let x = Vec3::new(1.0, 0.0, 0.0);
    let y = Vec3::new(0.0, 1.0, 0.0);
    let nan = Vec3::new(f64::NAN, 0.0, 0.0);
    assert!(point_triangle_distance_squared(&nan, &z, &x, &y).is_nan());
    assert!(point_triangle_distance_squared(&z, &nan, &x, &y).is_nan());
    assert!(edge_edge_distance_squared(&nan, &z, &x, &y).is_nan());
    assert!(edge_edge_distance_squared(&z, &x, &y, &nan).is_nan());
}

// ---------------------------------------------------------------------------------------------
// The mollifier
// ---------------------------------------------------------------------------------------------

/// m(c) on its own: the polynomial below ε_x, 1 above, continuous with a continuous slope at
/// ε_x (C¹), m' and m'' against finite differences.
#[test]
fn scalar_mollifier() {
    let eps = 2.5e-3;
    assert_eq!(mollifier(0.0, eps), 0.0);
    assert_eq!(mollifier(eps, eps), 1.0);
    assert!((mollifier(0.5 * eps, eps) - 0.75).abs() < 1e-15);
    for c in [eps, 2.0 * eps, 1e3] {
        assert_eq!(
            (
                mollifier(c, eps),
                mollifier_derivative(c, eps),
                mollifier_second_derivative(c, eps)
            ),
            (1.0, 0.0, 0.0)
        );
    }
    // C¹ at ε_x: from below, 1 − m = δ² and m' = 2δ/ε_x with δ = 1 − c/ε_x.
    for delta in [1e-3, 1e-6, 1e-9] {
        let c = eps * (1.0 - delta);
        assert!((1.0 - mollifier(c, eps) - delta * delta).abs() < 1e-15);
        assert!((mollifier_derivative(c, eps) - 2.0 * delta / eps).abs() < 1e-9 * 2.0 / eps);
    }
    // Derivatives: central differences with h = 1e-6 ε on a quadratic are exact up to rounding
    // (ε_mach / 1e-6 relative).
    let h = 1e-6 * eps;
    for c in [0.0, 0.1 * eps, 0.5 * eps, 0.9 * eps] {
        let dm = (mollifier(c + h, eps) - mollifier(c - h, eps)) / (2.0 * h);
        assert!((dm - mollifier_derivative(c, eps)).abs() < 1e-8 / eps);
        let ddm = (mollifier_derivative(c + h, eps) - mollifier_derivative(c - h, eps)) / (2.0 * h);
        assert!((ddm - mollifier_second_derivative(c, eps)).abs() < 1e-6 / (eps * eps));
    }
    // No threshold (a zero-length rest edge): no mollifier.
    assert_eq!(mollifier(0.0, 0.0), 1.0);
    let z = Vec3::zeros();
    assert_eq!(
        edge_edge_mollifier_threshold(&z, &z, &z, &Vec3::new(1.0, 0.0, 0.0)),
        0.0
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// The edge–edge mollifier and the cross-product norm under it: values from their
    /// definitions, gradients and Hessians against finite differences, m = 1 with zero
    /// derivatives above ε_x, and C¹ across ε_x. Edge b is edge a turned by θ ≤ 0.06 rad, so
    /// sin²θ straddles the threshold's 1e-3; the rest shape differs from the current one.
    #[test]
    fn edge_edge_mollifier_matches_definition_and_finite_differences(
        a0 in unit_vec3(),
        dir in unit_vec3(),
        side in unit_vec3(),
        b0 in unit_vec3(),
        lengths in (0.3..1.0f64, 0.3..1.0f64),
        theta in 0.0..0.06f64,
        rest_stretch in 0.8..1.25f64,
        scale in scale(),
    ) {
        prop_assume!(dir.norm() > 0.2);
        let dir = dir.normalize();
        let perp = side - side.dot(&dir) * dir;
        prop_assume!(perp.norm() > 0.2);
        let perp = perp.normalize();
        let a0 = a0 * scale;
        let a1 = a0 + lengths.0 * scale * dir;
        let b0 = b0 * scale;
        let b1 = b0 + lengths.1 * scale * (theta.cos() * dir + theta.sin() * perp);

        // ε_x from a rest shape whose edge a is stretched.
        let eps = edge_edge_mollifier_threshold(&a0, &(a0 + rest_stretch * (a1 - a0)), &b0, &b1);
        let expected_eps = 1e-3 * (rest_stretch * lengths.0 * scale).powi(2) * (lengths.1 * scale).powi(2);
        prop_assert!((eps - expected_eps).abs() <= 1e-12 * expected_eps);

        let c = edge_edge_cross_squared(&a0, &a1, &b0, &b1);
        let expected_c = ((a1 - a0).norm() * (b1 - b0).norm() * theta.sin()).powi(2);
        prop_assert!((c - expected_c).abs() <= 1e-10 * (scale.powi(4) * 1e-3).max(expected_c));
        let m = edge_edge_mollifier(&a0, &a1, &b0, &b1, eps);
        let expected_m = if c < eps { -c * c / (eps * eps) + 2.0 * c / eps } else { 1.0 };
        prop_assert!((m - expected_m).abs() <= 1e-14);

        let x = stack4(&a0, &a1, &b0, &b1);
        let split = |x: &V12| (vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
        let length = 2.0 * scale;
        // c is in m⁴: its gradient's natural size is L³, its Hessian's L².
        check_derivatives(
            "cross squared",
            |x| { let (p, q, r, s) = split(x); edge_edge_cross_squared(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); edge_edge_cross_squared_gradient(&p, &q, &r, &s) },
            |x| { let (p, q, r, s) = split(x); edge_edge_cross_squared_hessian(&p, &q, &r, &s) },
            &x, FD_STEP * length, length, length.powi(3), length.powi(2),
        )?;
        let (_, g, h) = edge_edge_mollifier_hessian(&a0, &a1, &b0, &b1, eps);
        prop_assert!(h == h.transpose());
        if c >= eps {
            prop_assert!(g == V12::zeros() && h == M12::zeros());
        }
        // Finite differences need the step to stay on one side of the kink in m'' at c = ε_x: a
        // step h moves c by at most h·|∇c|₁ (the step is along one coordinate, so |∇c|∞ bounds
        // it), kept 10× away.
        // m(c(x)) varies on the scale of the shorter edge times sin θ (c ∝ sin²θ), so the step
        // is 1e-6 of that; the floor on sin θ keeps the rounding, ε_mach/h, below the tolerance
        // where m' → 0.
        let h = FD_STEP * lengths.0.min(lengths.1) * scale * theta.sin().max(0.03);
        let (_, gc) = edge_edge_cross_squared_gradient(&a0, &a1, &b0, &b1);
        prop_assume!((c - eps).abs() > 10.0 * h * gc.amax());
        // m is dimensionless, so its gradient's natural size is 1/L and its Hessian's 1/L²; near
        // parallel they grow like 1/(ε_x) ∇c ~ 1e3 sin θ / L, which the relative tolerance covers.
        check_derivatives(
            "mollifier",
            |x| { let (p, q, r, s) = split(x); edge_edge_mollifier(&p, &q, &r, &s, eps) },
            |x| { let (p, q, r, s) = split(x); edge_edge_mollifier_gradient(&p, &q, &r, &s, eps) },
            |x| { let (p, q, r, s) = split(x); edge_edge_mollifier_hessian(&p, &q, &r, &s, eps) },
            &x, h, length, 1.0 / length, 1.0 / (length * length),
        )?;
    }
}

/// The mollified edge pair is C¹ across c = ε_x: just below, m ≈ 1 and its gradient ≈ 0,
/// matching the constant 1 just above.
#[test]
fn edge_edge_mollifier_is_c1_at_threshold() {
    let a0 = Vec3::zeros();
    let a1 = Vec3::new(1.0, 0.0, 0.0);
    let b0 = Vec3::new(0.0, 0.0, 1.0);
    let theta = 0.03f64;
    let b1 = b0 + Vec3::new(theta.cos(), theta.sin(), 0.0);
    // ε_x such that c sits at ε_x(1 ∓ δ).
    let c = edge_edge_cross_squared(&a0, &a1, &b0, &b1);
    let (_, gc) = edge_edge_cross_squared_gradient(&a0, &a1, &b0, &b1);
    for delta in [1e-4, 1e-7, 1e-10] {
        let below = edge_edge_mollifier_hessian(&a0, &a1, &b0, &b1, c / (1.0 - delta));
        let above = edge_edge_mollifier_hessian(&a0, &a1, &b0, &b1, c / (1.0 + delta));
        assert_eq!(
            (above.0, above.1, above.2),
            (1.0, V12::zeros(), M12::zeros())
        );
        assert!((1.0 - below.0) <= 2.0 * delta * delta);
        // |∇m| = m'(c)|∇c| = (2δ/ε_x)|∇c| → 0 with δ.
        let eps = c / (1.0 - delta);
        assert!(below.1.amax() <= 2.0 * delta / eps * gc.amax() * (1.0 + 1e-6));
        // The Hessian keeps the jump m'' ∇c∇cᵀ = −2/ε_x² ∇c∇cᵀ (m is C¹, not C²).
        let jump = -2.0 / (eps * eps) * gc * gc.transpose();
        assert!((below.2 - jump).amax() <= 1e-3 * jump.amax());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Nearly collinear edges one after the other, with a gap g between them, around the
    /// parallel threshold (sin θ from 1e-10 to 1e-7): the distance is g (to ~1e-6), never the
    /// near-zero distance between their lines. Only the across-valley difference of the closest
    /// points' parameters decides this, so it must not inherit the ~ε/sin²θ error of the
    /// parameters themselves.
    #[test]
    fn nearly_collinear_edges_with_a_gap(
        origin in unit_vec3(),
        dir in unit_vec3(),
        side in unit_vec3(),
        exponent in -10.0..-7.0f64,
        gap in 0.01..0.5f64,
        len_b in 0.2..2.0f64,
        flip in any::<bool>(),
    ) {
        prop_assume!(dir.norm() > 0.2);
        let dir = dir.normalize();
        let perp = side - side.dot(&dir) * dir;
        prop_assume!(perp.norm() > 0.2);
        let perp = perp.normalize();
        let theta = 10f64.powf(exponent);
        let a0 = origin;
        let a1 = origin + dir;
        let b0 = a1 + gap * dir;
        let b1 = b0 + len_b * (theta.cos() * dir + theta.sin() * perp);
        let (b0, b1) = if flip { (b1, b0) } else { (b0, b1) };
        let d = edge_edge_distance_squared(&a0, &a1, &b0, &b1);
        let case = edge_edge_case(&a0, &a1, &b0, &b1);
        prop_assert!((d.sqrt() - gap).abs() <= 1e-6, "{case:?}: distance {} vs gap {gap}", d.sqrt());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Nearly parallel edges crossing over each other's middles at a height h (a flat X): the
    /// closest points are interior, the distance is h exactly, at angles from 1e-12 to 1e-4 rad,
    /// on both sides of the parallel threshold. Above it, line–line's normal carries a rounding
    /// error of ~ε/sin θ; below it, an endpoint's distance exceeds h by ≤ L sin θ; the threshold
    /// balances the two, so the distance is within ~1e-8 of the edges' length at every angle.
    /// (With the IPC Toolkit's 1e-20 this fails near θ = 1e-10, by 2e-7.)
    #[test]
    fn nearly_parallel_crossing_edges(
        center in unit_vec3(),
        dir in unit_vec3(),
        side in unit_vec3(),
        exponent in -12.0..-4.0f64,
        height in prop_oneof![Just(0.0), 1e-6..1e-2f64, 0.01..0.5f64],
        halves in (0.2..1.0f64, 0.2..1.0f64, 0.2..1.0f64, 0.2..1.0f64),
    ) {
        prop_assume!(dir.norm() > 0.2);
        let dir = dir.normalize();
        let perp = side - side.dot(&dir) * dir;
        prop_assume!(perp.norm() > 0.2);
        let perp = perp.normalize();
        let up = dir.cross(&perp);
        let theta = 10f64.powf(exponent);
        let b_dir = theta.cos() * dir + theta.sin() * perp;
        let a0 = center - halves.0 * dir;
        let a1 = center + halves.1 * dir;
        let b0 = center + height * up - halves.2 * b_dir;
        let b1 = center + height * up + halves.3 * b_dir;
        let d = edge_edge_distance_squared(&a0, &a1, &b0, &b1);
        let case = edge_edge_case(&a0, &a1, &b0, &b1);
        // ~1e-8 L by the balance, L ≤ 2 here; 2× margin.
        let tol = 2e-8 * 2.0;
        prop_assert!((d.sqrt() - height).abs() <= tol, "θ {theta:e}, {case:?}: {} vs {height}", d.sqrt());
    }
}
