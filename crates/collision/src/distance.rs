//! Squared distances between the primitives of triangle surfaces, with their exact derivatives,
//! for IPC's self-contact (Li et al. 2020, "Incremental Potential Contact", §4; the IPC Toolkit's
//! distance module).
//!
//! This module owns:
//!
//! - the true squared distances between a point and a closed triangle,
//!   [`point_triangle_distance_squared`], and between two closed segments,
//!   [`edge_edge_distance_squared`];
//! - the closest-feature classification behind them, [`point_triangle_case`] and
//!   [`edge_edge_case`]: which vertex, edge or face (which pair of vertices or edges) is closest;
//! - the primitive squared distances point–point, point–line, point–plane and line–line, each
//!   with its value, `*_gradient` (value and gradient) and `*_hessian` (value, gradient and exact
//!   Hessian) in closed form;
//! - the same over the 12 DOFs of a pair for a given case,
//!   [`point_triangle_distance_squared_hessian`] and [`edge_edge_distance_squared_hessian`] (and
//!   their `_gradient` variants);
//! - IPC's mollifier of nearly parallel edges, [`edge_edge_mollifier`] with its threshold
//!   [`edge_edge_mollifier_threshold`] and derivatives.
//!
//! It leaves the barrier energies built on these distances to `hooke-assembly`, the time of impact
//! to [`ccd`](crate::ccd) and the candidate pairs to [`broad_phase`](crate::broad_phase).
//!
//! DOF order: gradients and Hessians stack the vertices' coordinates in argument order, xyz per
//! vertex: (p, t0, t1, t2) for a point and a triangle, (ea0, ea1, eb0, eb1) for two edges.
//!
//! Units: metres; every distance here is squared, in m², so gradients are in m and Hessians
//! dimensionless. Hessians are exactly symmetric and indefinite in general (a barrier's projection
//! to a definite matrix is the caller's).
//!
//! No function here allocates, panics or divides by zero: degenerate inputs (zero-length edges,
//! zero-area triangles, parallel edges) are classified away from the formulas that would, and the
//! primitives called on them directly fall back to the distance to what is left (a line or a
//! point), as each says. NaN in an input comes out as NaN in the value.

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

/// A point or a vector in space (m).
pub type Vec3 = Vector3<f64>;

/// Edges are nearly parallel, for the classification, where |ea × eb|² ≤ this · |ea|²|eb|²
/// (sin²θ, θ their angle): then no `LineLine`. Above it, the line–line formula's normal carries a
/// rounding error of ~ε/sin θ, which moves the distance by up to ~ε L/sin θ (L the edges' size);
/// below it, the nearest endpoint-to-segment distance exceeds the distance by at most L sin θ.
/// sin²θ = ε balances the two at ~1e-8 L. (The IPC Toolkit's 1e-20, in absolute units, lets the
/// first grow to ~2e-6 L.)
const PARALLEL_THRESHOLD: f64 = 1e-16;

/// A triangle is too thin for the face formula, for the classification, where
/// |(t1 − t0) × (t2 − t0)|² ≤ this · |t1 − t0|²|t2 − t0|² (sin² of its angle at t0): then no
/// `Face`. The same balance as for parallel edges: the face's normal errs by ~ε/sin θ, while the
/// triangle is then within L sin θ of its edges.
const DEGENERATE_TRIANGLE_THRESHOLD: f64 = 1e-16;

// ---------------------------------------------------------------------------------------------
// Classification
// ---------------------------------------------------------------------------------------------

/// Which feature of a triangle (t0, t1, t2) is closest to a point p.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PointTriangleCase {
    /// The vertex t_k (k ∈ {0, 1, 2}): the distance is point–point.
    Vertex(u8),
    /// The interior of the edge t_k–t_{(k+1) mod 3} (k ∈ {0, 1, 2}): the distance is point–line.
    Edge(u8),
    /// The interior of the face: the distance is point–plane. Never given for a degenerate
    /// triangle.
    Face,
}

/// Which features of two edges (ea0, ea1) and (eb0, eb1) are closest to each other. `Ea0Eb` is
/// the vertex ea0 and the interior of edge b, `EaEb1` the interior of edge a and the vertex eb1,
/// and so on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EdgeEdgeCase {
    /// ea0 and eb0: point–point.
    Ea0Eb0,
    /// ea0 and eb1: point–point.
    Ea0Eb1,
    /// ea1 and eb0: point–point.
    Ea1Eb0,
    /// ea1 and eb1: point–point.
    Ea1Eb1,
    /// ea0 and the interior of edge b: point–line.
    Ea0Eb,
    /// ea1 and the interior of edge b: point–line.
    Ea1Eb,
    /// The interior of edge a and eb0: point–line.
    EaEb0,
    /// The interior of edge a and eb1: point–line.
    EaEb1,
    /// The interiors of both edges: line–line. Never given for nearly parallel or degenerate
    /// edges.
    LineLine,
}

/// Where on the segment (e0, e1) the point closest to p lies: `0` at e0, `1` at e1, `2` in the
/// interior; a zero-length segment gives `0`.
#[inline]
fn point_edge_feature(p: &Vec3, e0: &Vec3, e1: &Vec3) -> u8 {
    let e = e1 - e0;
    // t = (p − e0)·e / |e|², compared without dividing (|e|² may be 0).
    let num = (p - e0).dot(&e);
    if num <= 0.0 {
        0
    } else if num >= e.norm_squared() {
        1
    } else {
        2
    }
}

/// The squared distance from p to the closed segment (e0, e1) and its feature as in
/// [`point_edge_feature`], with the value of that feature's primitive.
#[inline]
fn point_edge_closest(p: &Vec3, e0: &Vec3, e1: &Vec3) -> (u8, f64) {
    let feature = point_edge_feature(p, e0, e1);
    let d = match feature {
        0 => point_point_distance_squared(p, e0),
        1 => point_point_distance_squared(p, e1),
        _ => point_line_distance_squared(p, e0, e1),
    };
    (feature, d)
}

/// The closest feature of the triangle and its squared distance (the value of that feature's
/// primitive).
#[inline]
fn point_triangle_closest(p: &Vec3, t0: &Vec3, t1: &Vec3, t2: &Vec3) -> (PointTriangleCase, f64) {
    let u = t1 - t0;
    let v = t2 - t0;
    let n = u.cross(&v);
    let n2 = n.norm_squared();
    if n2 > DEGENERATE_TRIANGLE_THRESHOLD * u.norm_squared() * v.norm_squared() {
        // The projection of p lies inside the triangle iff it is on the inner side of all three
        // edges: (t_{k+1} − t_k) × (p − t_k) along n. Then the closest point is the projection.
        let inside = |a: &Vec3, b: &Vec3| (b - a).cross(&(p - a)).dot(&n) >= 0.0;
        if inside(t0, t1) && inside(t1, t2) && inside(t2, t0) {
            return (
                PointTriangleCase::Face,
                point_plane_distance_squared(p, t0, t1, t2),
            );
        }
    }
    // Outside (or degenerate): the closest point of the triangle to the projection, hence to p,
    // lies on its boundary, the nearest of the three edges.
    let edges = [(t0, t1), (t1, t2), (t2, t0)];
    let mut best = (PointTriangleCase::Vertex(0), f64::INFINITY);
    for (k, (a, b)) in edges.iter().enumerate() {
        let (feature, d) = point_edge_closest(p, a, b);
        // Taking a NaN makes NaN inputs give NaN, not +∞.
        if d < best.1 || d.is_nan() {
            let k = k as u8;
            let case = match feature {
                0 => PointTriangleCase::Vertex(k),
                1 => PointTriangleCase::Vertex((k + 1) % 3),
                _ => PointTriangleCase::Edge(k),
            };
            best = (case, d);
        }
    }
    best
}

/// The feature of the closed triangle (t0, t1, t2) closest to p.
///
/// `Face` where p projects into the triangle's interior, else the closest vertex or edge. A
/// degenerate triangle (collinear or coincident vertices, or with sin² of its angle at t0 at most
/// 1e-16, so within 1e-8 of its edges' length of them) never gives `Face`: its closest edge or vertex instead. On a boundary between two regions
/// either case may come out; their distances agree there.
#[inline]
pub fn point_triangle_case(p: &Vec3, t0: &Vec3, t1: &Vec3, t2: &Vec3) -> PointTriangleCase {
    point_triangle_closest(p, t0, t1, t2).0
}

/// [`point_triangle_case`] and [`point_triangle_distance_squared`] at once (m²), for one pass
/// where both are wanted.
#[inline]
pub fn point_triangle_case_and_distance_squared(
    p: &Vec3,
    t0: &Vec3,
    t1: &Vec3,
    t2: &Vec3,
) -> (PointTriangleCase, f64) {
    point_triangle_closest(p, t0, t1, t2)
}

/// The squared distance (m²) between the point p and the closed triangle (t0, t1, t2), vertices,
/// edges and interior included. Degenerate triangles are fine (the distance to their segment or
/// point). Equals the primitive distance of [`point_triangle_case`]'s case.
#[inline]
pub fn point_triangle_distance_squared(p: &Vec3, t0: &Vec3, t1: &Vec3, t2: &Vec3) -> f64 {
    point_triangle_closest(p, t0, t1, t2).1
}

/// The closest features of two closed segments when they are nearly parallel or degenerate: the
/// nearest of the four endpoint-to-segment distances, which is where the distance of two parallel
/// segments is attained.
#[inline]
fn edge_edge_parallel_closest(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3) -> EdgeEdgeCase {
    use EdgeEdgeCase::*;
    let (fa0, da0) = point_edge_closest(ea0, eb0, eb1);
    let (fa1, da1) = point_edge_closest(ea1, eb0, eb1);
    let (fb0, db0) = point_edge_closest(eb0, ea0, ea1);
    let (fb1, db1) = point_edge_closest(eb1, ea0, ea1);
    let candidates = [
        ([Ea0Eb0, Ea0Eb1, Ea0Eb][fa0 as usize], da0),
        ([Ea1Eb0, Ea1Eb1, Ea1Eb][fa1 as usize], da1),
        ([Ea0Eb0, Ea1Eb0, EaEb0][fb0 as usize], db0),
        ([Ea0Eb1, Ea1Eb1, EaEb1][fb1 as usize], db1),
    ];
    let mut best = candidates[0];
    for candidate in &candidates[1..] {
        if candidate.1 < best.1 {
            best = *candidate;
        }
    }
    best.0
}

/// The features of the closed segments (ea0, ea1) and (eb0, eb1) closest to each other.
///
/// The closest points minimise the convex quadratic |ea0 + s(ea1 − ea0) − eb0 − t(eb1 − eb0)|²
/// over (s, t) ∈ [0, 1]²: `LineLine` where its free minimum lies inside, else clamped to the
/// square's boundary (Sunday's algorithm, as in the IPC Toolkit, with its free minimum computed
/// through ea × eb). Nearly parallel edges (|ea × eb|² ≤ 1e-16·|ea|²|eb|², where the nearest
/// endpoint is within 1e-8 of the edges' length of the distance) and zero-length edges never give
/// `LineLine`: the nearest endpoint-to-segment pair instead. On a boundary between regions either case may come out;
/// their distances agree there.
#[inline]
pub fn edge_edge_case(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3) -> EdgeEdgeCase {
    use EdgeEdgeCase::*;
    let u = ea1 - ea0;
    let v = eb1 - eb0;
    let w = ea0 - eb0;
    let a = u.norm_squared();
    let b = u.dot(&v);
    let c = v.norm_squared();
    let d = u.dot(&w);
    let e = v.dot(&w);
    let n = u.cross(&v);
    let det = n.norm_squared();
    // Also catches a = 0 or c = 0 (the cross product is then exactly 0).
    if det <= PARALLEL_THRESHOLD * a * c {
        return edge_edge_parallel_closest(ea0, ea1, eb0, eb1);
    }
    // The free minimum is s = s_num / det, t = t_num / det with det = ac − b² = |n|². Sunday's
    // ac − b², b e − c d and a e − b d cancel to an error of ~ε/sin²θ in s and t independently,
    // enough near the threshold to take two nearly collinear edges with a gap between them for
    // overlapping. The same quantities through n (Lagrange's identity) carry n's rounding error
    // into s and t alike, where it cancels in t − s, which is what tells overlapping from apart.
    let ab = eb0 - ea0;
    let s_num = ab.cross(&v).dot(&n);
    let t_num_interior = ab.cross(&u).dot(&n);
    let (t_num, t_den, interior_case) = if s_num <= 0.0 {
        (e, c, Ea0Eb)
    } else if s_num >= det {
        (e + b, c, Ea1Eb)
    } else {
        (t_num_interior, det, LineLine)
    };
    if t_num <= 0.0 {
        // t clamped to 0: the best s for eb0 is −d / a.
        if -d <= 0.0 {
            Ea0Eb0
        } else if -d >= a {
            Ea1Eb0
        } else {
            EaEb0
        }
    } else if t_num >= t_den {
        // t clamped to 1: the best s for eb1 is (b − d) / a.
        if b - d <= 0.0 {
            Ea0Eb1
        } else if b - d >= a {
            Ea1Eb1
        } else {
            EaEb1
        }
    } else {
        interior_case
    }
}

/// The squared distance (m²) between the closed segments (ea0, ea1) and (eb0, eb1). Parallel and
/// zero-length edges are fine. Equals the primitive distance of [`edge_edge_case`]'s case.
#[inline]
pub fn edge_edge_distance_squared(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3) -> f64 {
    edge_edge_case_and_distance_squared(ea0, ea1, eb0, eb1).1
}

/// [`edge_edge_case`] and [`edge_edge_distance_squared`] at once (m²), for one pass where both
/// are wanted.
#[inline]
pub fn edge_edge_case_and_distance_squared(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
) -> (EdgeEdgeCase, f64) {
    use EdgeEdgeCase::*;
    let case = edge_edge_case(ea0, ea1, eb0, eb1);
    let s = match case {
        Ea0Eb0 => point_point_distance_squared(ea0, eb0),
        Ea0Eb1 => point_point_distance_squared(ea0, eb1),
        Ea1Eb0 => point_point_distance_squared(ea1, eb0),
        Ea1Eb1 => point_point_distance_squared(ea1, eb1),
        Ea0Eb => point_line_distance_squared(ea0, eb0, eb1),
        Ea1Eb => point_line_distance_squared(ea1, eb0, eb1),
        EaEb0 => point_line_distance_squared(eb0, ea0, ea1),
        EaEb1 => point_line_distance_squared(eb1, ea0, ea1),
        LineLine => line_line_distance_squared(ea0, ea1, eb0, eb1),
    };
    (case, s)
}

// ---------------------------------------------------------------------------------------------
// Primitive distances
//
// Each primitive is a function of a few difference vectors y_a = x_at[a] − x_ref from one
// reference vertex (r = p − e0, e = e1 − e0; w = p − t0, u = t1 − t0, v = t2 − t0; line–line
// after a change of variables). A core computes the value and the derivatives in y as 3×3
// blocks; `scatter_*_relative` applies the chain rule for any such layout, so one core serves a
// primitive's own DOFs and every placement of it in the 12 DOFs of a pair. Its cost is a few
// block copies and sums, where a general Jᵀ H J would be 12×9×9 + 12×12×9 multiply-adds.
// ---------------------------------------------------------------------------------------------

/// The chain rule for y_a = x_at[a] − x_reference: vertex at[a] gets ∂/∂y_a, the reference minus
/// their sum, every other vertex zero. **Invariant:** the indices are distinct and below N/3.
#[inline(always)]
fn scatter_gradient_relative<const NY: usize, const N: usize>(
    gy: &[Vec3; NY],
    at: [usize; NY],
    reference: usize,
) -> SVector<f64, N> {
    let mut g = SVector::<f64, N>::zeros();
    let mut sum = Vec3::zeros();
    for (ga, &i) in gy.iter().zip(&at) {
        g.fixed_rows_mut::<3>(3 * i).copy_from(ga);
        sum += ga;
    }
    g.fixed_rows_mut::<3>(3 * reference).copy_from(&(-sum));
    g
}

/// The chain rule for the Hessian of the same layout: block (at[a], at[b]) is H_y's block (a, b),
/// block (reference, at[b]) minus the sum of H_y's block column b (and its transpose across the
/// diagonal), block (reference, reference) the sum of all of H_y. Exactly symmetric, given
/// H_y's off-diagonal blocks as exact transposes of each other: the diagonal blocks, whose sums
/// may round differently across their diagonal, are mirrored. **Invariant:** as for the gradient.
#[inline(always)]
fn scatter_hessian_relative<const NY: usize, const N: usize>(
    hy: &[[Matrix3<f64>; NY]; NY],
    at: [usize; NY],
    reference: usize,
) -> SMatrix<f64, N, N> {
    let mut h = SMatrix::<f64, N, N>::zeros();
    let mut total = Matrix3::zeros();
    for (b, &j) in at.iter().enumerate() {
        let mut column = Matrix3::zeros();
        for (hy_a, &i) in hy.iter().zip(&at) {
            let block = if i == j {
                mirror_upper(&hy_a[b])
            } else {
                hy_a[b]
            };
            column += block;
            h.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&block);
        }
        total += column;
        h.fixed_view_mut::<3, 3>(3 * reference, 3 * j)
            .copy_from(&(-column));
        h.fixed_view_mut::<3, 3>(3 * j, 3 * reference)
            .copy_from(&(-column.transpose()));
    }
    h.fixed_view_mut::<3, 3>(3 * reference, 3 * reference)
        .copy_from(&mirror_upper(&total));
    h
}

/// The 3×3 matrix with its upper triangle copied onto its lower one: exactly symmetric.
#[inline(always)]
fn mirror_upper(m: &Matrix3<f64>) -> Matrix3<f64> {
    let mut m = *m;
    m[(1, 0)] = m[(0, 1)];
    m[(2, 0)] = m[(0, 2)];
    m[(2, 1)] = m[(1, 2)];
    m
}

/// |r|² in r = p − q, with its gradient and Hessian.
#[inline(always)]
fn point_point_core(r: &Vec3) -> (f64, [Vec3; 1], [[Matrix3<f64>; 1]; 1]) {
    (
        r.norm_squared(),
        [2.0 * r],
        [[Matrix3::from_diagonal_element(2.0)]],
    )
}

/// The squared distance from the point to the line in r = p − e0, e = e1 − e0, with t the
/// parameter of the foot e0 + t e and q = r − t e the perpendicular from the foot to p:
/// d = |q|². For e = 0, |r|² (the line is the point e0).
#[inline(always)]
fn point_line_foot(r: &Vec3, e: &Vec3) -> (f64, f64, Vec3, f64) {
    let c = e.norm_squared();
    if c == 0.0 {
        return (0.0, 0.0, *r, r.norm_squared());
    }
    let t = r.dot(e) / c;
    let q = r - t * e;
    (c, t, q, q.norm_squared())
}

/// [`point_line_foot`]'s d with ∂d/∂r = 2q and ∂d/∂e = −2t q.
#[inline(always)]
fn point_line_gradient_core(r: &Vec3, e: &Vec3) -> (f64, [Vec3; 2]) {
    let (_, t, q, d) = point_line_foot(r, e);
    (d, [2.0 * q, -2.0 * t * q])
}

/// [`point_line_gradient_core`] with the Hessian in (r, e): with P = I − e eᵀ/c (c = |e|²),
/// H_rr = 2P, H_re = −2tP − (2/c) e qᵀ, H_ee = 2t²P + (2t/c)(q eᵀ + e qᵀ) − (2/c) q qᵀ.
#[inline(always)]
fn point_line_hessian_core(r: &Vec3, e: &Vec3) -> (f64, [Vec3; 2], [[Matrix3<f64>; 2]; 2]) {
    let (c, t, q, d) = point_line_foot(r, e);
    let grad = [2.0 * q, -2.0 * t * q];
    if c == 0.0 {
        let zero = Matrix3::zeros();
        return (
            d,
            grad,
            [[Matrix3::from_diagonal_element(2.0), zero], [zero, zero]],
        );
    }
    let inv_c = 1.0 / c;
    let projector = Matrix3::identity() - e * (e.transpose() * inv_c);
    let eq = e * (q.transpose() * (2.0 * inv_c)); // (2/c) e qᵀ
    let h_rr = 2.0 * projector;
    let h_re = -2.0 * t * projector - eq;
    let h_ee =
        (2.0 * t * t) * projector + t * (eq + eq.transpose()) - q * (q.transpose() * (2.0 * inv_c));
    (d, grad, [[h_rr, h_re], [h_re.transpose(), h_ee]])
}

/// The quantities of d = (w·n)²/|n|², n = u × v: the distance from the point w to the plane
/// through 0 spanned by u and v, which is point–plane (w = p − t0, u = t1 − t0, v = t2 − t0) and
/// line–line (w = eb0 − ea0, u = ea1 − ea0, v = eb1 − eb0) alike. Returns (n, c = |n|², k = s/c
/// with s = w·n, d); meaningful for c > 0 only.
#[inline(always)]
fn plane_parts(w: &Vec3, u: &Vec3, v: &Vec3) -> (Vec3, f64, f64, f64) {
    let n = u.cross(v);
    let c = n.norm_squared();
    let s = w.dot(&n);
    let k = s / c;
    (n, c, k, s * k)
}

/// d = (w·n)²/|n|² (c > 0) with its gradient: with k = s/c and q = w − k n (w's projection into
/// the plane), ∂d/∂w = 2k n, ∂d/∂u = 2k v × q, ∂d/∂v = 2k q × u.
#[inline(always)]
fn plane_gradient_core(w: &Vec3, u: &Vec3, v: &Vec3) -> (f64, [Vec3; 3]) {
    let (n, _, k, d) = plane_parts(w, u, v);
    let q = w - k * n;
    let two_k = 2.0 * k;
    (d, [two_k * n, two_k * v.cross(&q), two_k * q.cross(u)])
}

/// [`plane_gradient_core`] with the Hessian. From d = s²/c:
/// ∇²d = (2/c) z zᵀ + 2k ∇²s − k² ∇²c with z = ∇s − k ∇c = (n, v × m, m × u), m = w − 2k n;
/// s = w·(u × v) has the blocks ∂²s/∂w∂u = −[v]ₓ, ∂²s/∂w∂v = [u]ₓ, ∂²s/∂u∂v = −[w]ₓ, and
/// c = |u|²|v|² − (u·v)² has ∂²c/∂u² = 2(|v|²I − v vᵀ), ∂²c/∂v² = 2(|u|²I − u uᵀ),
/// ∂²c/∂u∂v = 4u vᵀ − 2v uᵀ − 2(u·v)I.
#[inline(always)]
fn plane_hessian_core(w: &Vec3, u: &Vec3, v: &Vec3) -> (f64, [Vec3; 3], [[Matrix3<f64>; 3]; 3]) {
    let (n, c, k, d) = plane_parts(w, u, v);
    let q = w - k * n;
    let two_k = 2.0 * k;
    let grad = [two_k * n, two_k * v.cross(&q), two_k * q.cross(u)];

    let m = q - k * n;
    let z = [n, v.cross(&m), m.cross(u)];
    let scale = 2.0 / c;
    let zs = [z[0] * scale, z[1] * scale, z[2] * scale];
    let k2 = k * k;
    let uu = u.norm_squared();
    let vv = v.norm_squared();
    let uv = u.dot(v);

    let h_ww = z[0] * zs[0].transpose();
    let h_wu = z[0] * zs[1].transpose() - two_k * v.cross_matrix();
    let h_wv = z[0] * zs[2].transpose() + two_k * u.cross_matrix();
    let h_uu = z[1] * zs[1].transpose()
        - (2.0 * k2) * (Matrix3::from_diagonal_element(vv) - v * v.transpose());
    let h_vv = z[2] * zs[2].transpose()
        - (2.0 * k2) * (Matrix3::from_diagonal_element(uu) - u * u.transpose());
    let h_uv = z[1] * zs[2].transpose()
        - two_k * w.cross_matrix()
        - k2 * (4.0 * u * v.transpose()
            - 2.0 * v * u.transpose()
            - Matrix3::from_diagonal_element(2.0 * uv));
    (
        d,
        grad,
        [
            [h_ww, h_wu, h_wv],
            [h_wu.transpose(), h_uu, h_uv],
            [h_wv.transpose(), h_uv.transpose(), h_vv],
        ],
    )
}

/// Line–line's derivatives in (w, u, v) = (eb0 − ea0, ea1 − ea0, eb1 − eb0) taken to
/// (w, u, v′) with v′ = eb1 − ea0 = v + w, which are all relative to ea0: ∂/∂w′ = ∂/∂w − ∂/∂v,
/// and for the Hessian H′ = Kᵀ H K with v = v′ − w.
#[inline(always)]
fn line_line_gradient_to_relative(g: &[Vec3; 3]) -> [Vec3; 3] {
    [g[0] - g[2], g[1], g[2]]
}

/// [`line_line_gradient_to_relative`]'s Hessian: H′_ww = H_ww − H_wv − H_vw + H_vv,
/// H′_wu = H_wu − H_vu, H′_wv′ = H_wv − H_vv, the others unchanged.
#[inline(always)]
fn line_line_hessian_to_relative(h: &[[Matrix3<f64>; 3]; 3]) -> [[Matrix3<f64>; 3]; 3] {
    let ww = h[0][0] - h[0][2] - h[2][0] + h[2][2];
    let wu = h[0][1] - h[2][1];
    let wv = h[0][2] - h[2][2];
    [
        [ww, wu, wv],
        [wu.transpose(), h[1][1], h[1][2]],
        [wv.transpose(), h[2][1], h[2][2]],
    ]
}

/// Where (w, u, v′) of [`line_line_gradient_to_relative`] sit among (ea0, ea1, eb0, eb1), all
/// relative to ea0.
const LINE_LINE_AT: [usize; 3] = [2, 1, 3];

/// The index k of the triangle's longest edge (t_k, t_{k+1}): where a triangle without a plane
/// takes its line.
#[inline]
fn longest_edge_index(t0: &Vec3, t1: &Vec3, t2: &Vec3) -> u8 {
    let l0 = (t1 - t0).norm_squared();
    let l1 = (t2 - t1).norm_squared();
    let l2 = (t0 - t2).norm_squared();
    if l0 >= l1 && l0 >= l2 {
        0
    } else if l1 >= l2 {
        1
    } else {
        2
    }
}

/// |p − q|² (m²).
#[inline]
pub fn point_point_distance_squared(p: &Vec3, q: &Vec3) -> f64 {
    (p - q).norm_squared()
}

/// |p − q|² (m²) and its gradient (m) in the 6 DOFs (p, q): (2(p − q), −2(p − q)).
#[inline]
pub fn point_point_distance_squared_gradient(p: &Vec3, q: &Vec3) -> (f64, SVector<f64, 6>) {
    let (d, g, _) = point_point_core(&(p - q));
    (d, scatter_gradient_relative(&g, [0], 1))
}

/// |p − q|² (m²), its gradient (m) and its Hessian (dimensionless) in the 6 DOFs (p, q):
/// [[2I, −2I], [−2I, 2I]], constant.
#[inline]
pub fn point_point_distance_squared_hessian(
    p: &Vec3,
    q: &Vec3,
) -> (f64, SVector<f64, 6>, SMatrix<f64, 6, 6>) {
    let (d, g, h) = point_point_core(&(p - q));
    (
        d,
        scatter_gradient_relative(&g, [0], 1),
        scatter_hessian_relative(&h, [0], 1),
    )
}

/// The squared distance (m²) from p to the infinite line through e0 and e1: |p − f|² with f the
/// foot of the perpendicular. For e0 = e1 (no line) |p − e0|², and likewise in the derivatives.
#[inline]
pub fn point_line_distance_squared(p: &Vec3, e0: &Vec3, e1: &Vec3) -> f64 {
    point_line_foot(&(p - e0), &(e1 - e0)).3
}

/// [`point_line_distance_squared`] (m²) and its gradient (m) in the 9 DOFs (p, e0, e1). With t
/// the foot's parameter (f = e0 + t(e1 − e0)) and q = p − f: (2q, −2(1 − t)q, −2t q).
#[inline]
pub fn point_line_distance_squared_gradient(
    p: &Vec3,
    e0: &Vec3,
    e1: &Vec3,
) -> (f64, SVector<f64, 9>) {
    let (d, g) = point_line_gradient_core(&(p - e0), &(e1 - e0));
    (d, scatter_gradient_relative(&g, [0, 2], 1))
}

/// [`point_line_distance_squared`] (m²), its gradient (m) and its exact Hessian (dimensionless,
/// exactly symmetric, indefinite in general) in the 9 DOFs (p, e0, e1). Entries grow like
/// |p − e0|/|e1 − e0|: large for short edges.
#[inline]
pub fn point_line_distance_squared_hessian(
    p: &Vec3,
    e0: &Vec3,
    e1: &Vec3,
) -> (f64, SVector<f64, 9>, SMatrix<f64, 9, 9>) {
    let (d, g, h) = point_line_hessian_core(&(p - e0), &(e1 - e0));
    (
        d,
        scatter_gradient_relative(&g, [0, 2], 1),
        scatter_hessian_relative(&h, [0, 2], 1),
    )
}

/// The squared distance (m²) from p to the plane through t0, t1 and t2,
/// ((p − t0)·n)² / |n|² with n = (t1 − t0) × (t2 − t0). For collinear or coincident vertices
/// (n = 0 exactly, no plane) the distance to their line or point instead,
/// [`point_line_distance_squared`] to the longest edge's line, and likewise in the derivatives.
#[inline]
pub fn point_plane_distance_squared(p: &Vec3, t0: &Vec3, t1: &Vec3, t2: &Vec3) -> f64 {
    let (_, c, _, d) = plane_parts(&(p - t0), &(t1 - t0), &(t2 - t0));
    if c == 0.0 {
        return match longest_edge_index(t0, t1, t2) {
            0 => point_line_distance_squared(p, t0, t1),
            1 => point_line_distance_squared(p, t1, t2),
            _ => point_line_distance_squared(p, t2, t0),
        };
    }
    d
}

/// [`point_plane_distance_squared`] (m²) and its gradient (m) in the 12 DOFs (p, t0, t1, t2).
#[inline]
pub fn point_plane_distance_squared_gradient(
    p: &Vec3,
    t0: &Vec3,
    t1: &Vec3,
    t2: &Vec3,
) -> (f64, SVector<f64, 12>) {
    let (u, v) = (t1 - t0, t2 - t0);
    if u.cross(&v).norm_squared() == 0.0 {
        let edge = PointTriangleCase::Edge(longest_edge_index(t0, t1, t2));
        return point_triangle_distance_squared_gradient(p, t0, t1, t2, edge);
    }
    let (d, g) = plane_gradient_core(&(p - t0), &u, &v);
    (d, scatter_gradient_relative(&g, [0, 2, 3], 1))
}

/// [`point_plane_distance_squared`] (m²), its gradient (m) and its exact Hessian (dimensionless,
/// exactly symmetric, indefinite in general) in the 12 DOFs (p, t0, t1, t2). Entries grow like
/// 1/sin of the triangle's angle at t0 (times |p − t0| over an edge): large for slivers.
#[inline]
pub fn point_plane_distance_squared_hessian(
    p: &Vec3,
    t0: &Vec3,
    t1: &Vec3,
    t2: &Vec3,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (u, v) = (t1 - t0, t2 - t0);
    if u.cross(&v).norm_squared() == 0.0 {
        let edge = PointTriangleCase::Edge(longest_edge_index(t0, t1, t2));
        return point_triangle_distance_squared_hessian(p, t0, t1, t2, edge);
    }
    let (d, g, h) = plane_hessian_core(&(p - t0), &u, &v);
    (
        d,
        scatter_gradient_relative(&g, [0, 2, 3], 1),
        scatter_hessian_relative(&h, [0, 2, 3], 1),
    )
}

/// The squared distance (m²) between the infinite lines through (ea0, ea1) and (eb0, eb1),
/// ((eb0 − ea0)·n)² / |n|² with n = (ea1 − ea0) × (eb1 − eb0). For exactly parallel lines
/// (n = 0) the distance from ea0 to line b (or from eb0 to line a if edge b has no length, or
/// between the points if neither has), and likewise in the derivatives.
#[inline]
pub fn line_line_distance_squared(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3) -> f64 {
    let (_, c, _, d) = plane_parts(&(eb0 - ea0), &(ea1 - ea0), &(eb1 - eb0));
    if c == 0.0 {
        return if eb0 != eb1 {
            point_line_distance_squared(ea0, eb0, eb1)
        } else {
            point_line_distance_squared(eb0, ea0, ea1)
        };
    }
    d
}

/// The point–line case that [`line_line_distance_squared`] falls back to for parallel lines.
#[inline]
fn parallel_lines_case(eb0: &Vec3, eb1: &Vec3) -> EdgeEdgeCase {
    if eb0 != eb1 {
        EdgeEdgeCase::Ea0Eb
    } else {
        EdgeEdgeCase::EaEb0
    }
}

/// [`line_line_distance_squared`] (m²) and its gradient (m) in the 12 DOFs (ea0, ea1, eb0, eb1).
#[inline]
pub fn line_line_distance_squared_gradient(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
) -> (f64, SVector<f64, 12>) {
    let (u, v) = (ea1 - ea0, eb1 - eb0);
    if u.cross(&v).norm_squared() == 0.0 {
        let case = parallel_lines_case(eb0, eb1);
        return edge_edge_distance_squared_gradient(ea0, ea1, eb0, eb1, case);
    }
    let (d, g) = plane_gradient_core(&(eb0 - ea0), &u, &v);
    let g = line_line_gradient_to_relative(&g);
    (d, scatter_gradient_relative(&g, LINE_LINE_AT, 0))
}

/// [`line_line_distance_squared`] (m²), its gradient (m) and its exact Hessian (dimensionless,
/// exactly symmetric, indefinite in general) in the 12 DOFs (ea0, ea1, eb0, eb1). Entries grow
/// like 1/sin of the angle between the edges: large for nearly parallel edges, which
/// [`edge_edge_case`] keeps away from this formula.
#[inline]
pub fn line_line_distance_squared_hessian(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (u, v) = (ea1 - ea0, eb1 - eb0);
    if u.cross(&v).norm_squared() == 0.0 {
        let case = parallel_lines_case(eb0, eb1);
        return edge_edge_distance_squared_hessian(ea0, ea1, eb0, eb1, case);
    }
    let (d, g, h) = plane_hessian_core(&(eb0 - ea0), &u, &v);
    let (g, h) = (
        line_line_gradient_to_relative(&g),
        line_line_hessian_to_relative(&h),
    );
    (
        d,
        scatter_gradient_relative(&g, LINE_LINE_AT, 0),
        scatter_hessian_relative(&h, LINE_LINE_AT, 0),
    )
}

// ---------------------------------------------------------------------------------------------
// Point–triangle and edge–edge over 12 DOFs
//
// Every arm below names its vertices with constants, so that each scatter is compiled for its
// own layout.
// ---------------------------------------------------------------------------------------------

/// p to vertex a (index `at_a` among the 4), gradient over 12 DOFs.
#[inline(always)]
fn point_point_12_gradient(
    p: &Vec3,
    a: &Vec3,
    at_p: usize,
    at_a: usize,
) -> (f64, SVector<f64, 12>) {
    let (d, g, _) = point_point_core(&(p - a));
    (d, scatter_gradient_relative(&g, [at_p], at_a))
}

/// p to vertex a, Hessian over 12 DOFs.
#[inline(always)]
fn point_point_12_hessian(
    p: &Vec3,
    a: &Vec3,
    at_p: usize,
    at_a: usize,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (d, g, h) = point_point_core(&(p - a));
    (
        d,
        scatter_gradient_relative(&g, [at_p], at_a),
        scatter_hessian_relative(&h, [at_p], at_a),
    )
}

/// p to the line through a and b, gradient over 12 DOFs (`at` = indices of p, a, b).
#[inline(always)]
fn point_line_12_gradient(p: &Vec3, a: &Vec3, b: &Vec3, at: [usize; 3]) -> (f64, SVector<f64, 12>) {
    let (d, g) = point_line_gradient_core(&(p - a), &(b - a));
    (d, scatter_gradient_relative(&g, [at[0], at[2]], at[1]))
}

/// p to the line through a and b, Hessian over 12 DOFs (`at` = indices of p, a, b).
#[inline(always)]
fn point_line_12_hessian(
    p: &Vec3,
    a: &Vec3,
    b: &Vec3,
    at: [usize; 3],
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (d, g, h) = point_line_hessian_core(&(p - a), &(b - a));
    (
        d,
        scatter_gradient_relative(&g, [at[0], at[2]], at[1]),
        scatter_hessian_relative(&h, [at[0], at[2]], at[1]),
    )
}

/// The squared distance (m²) between p and the triangle's feature `case`, and its gradient (m)
/// in the 12 DOFs (p, t0, t1, t2); zero for the vertices the case does not involve.
///
/// `case` is normally [`point_triangle_case`] of the same positions, so the value is
/// [`point_triangle_distance_squared`]; another case gives that feature's primitive distance
/// (point–point, point–line or point–plane, as in the `*_distance_squared_gradient` primitives),
/// smooth across the region boundaries. Indices in `Vertex(k)` and `Edge(k)` are taken mod 3.
#[inline]
pub fn point_triangle_distance_squared_gradient(
    p: &Vec3,
    t0: &Vec3,
    t1: &Vec3,
    t2: &Vec3,
    case: PointTriangleCase,
) -> (f64, SVector<f64, 12>) {
    match case {
        PointTriangleCase::Vertex(k) => match k % 3 {
            0 => point_point_12_gradient(p, t0, 0, 1),
            1 => point_point_12_gradient(p, t1, 0, 2),
            _ => point_point_12_gradient(p, t2, 0, 3),
        },
        PointTriangleCase::Edge(k) => match k % 3 {
            0 => point_line_12_gradient(p, t0, t1, [0, 1, 2]),
            1 => point_line_12_gradient(p, t1, t2, [0, 2, 3]),
            _ => point_line_12_gradient(p, t2, t0, [0, 3, 1]),
        },
        PointTriangleCase::Face => point_plane_distance_squared_gradient(p, t0, t1, t2),
    }
}

/// [`point_triangle_distance_squared_gradient`] with the exact Hessian (dimensionless, exactly
/// symmetric, indefinite in general) of the case's primitive, in the 12 DOFs (p, t0, t1, t2).
#[inline]
pub fn point_triangle_distance_squared_hessian(
    p: &Vec3,
    t0: &Vec3,
    t1: &Vec3,
    t2: &Vec3,
    case: PointTriangleCase,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    match case {
        PointTriangleCase::Vertex(k) => match k % 3 {
            0 => point_point_12_hessian(p, t0, 0, 1),
            1 => point_point_12_hessian(p, t1, 0, 2),
            _ => point_point_12_hessian(p, t2, 0, 3),
        },
        PointTriangleCase::Edge(k) => match k % 3 {
            0 => point_line_12_hessian(p, t0, t1, [0, 1, 2]),
            1 => point_line_12_hessian(p, t1, t2, [0, 2, 3]),
            _ => point_line_12_hessian(p, t2, t0, [0, 3, 1]),
        },
        PointTriangleCase::Face => point_plane_distance_squared_hessian(p, t0, t1, t2),
    }
}

/// The squared distance (m²) between the features `case` of edges (ea0, ea1) and (eb0, eb1), and
/// its gradient (m) in the 12 DOFs (ea0, ea1, eb0, eb1); zero for the vertices the case does not
/// involve.
///
/// `case` is normally [`edge_edge_case`] of the same positions, so the value is
/// [`edge_edge_distance_squared`]; another case gives those features' primitive distance
/// (point–point, point–line or line–line), smooth across the region boundaries.
#[inline]
pub fn edge_edge_distance_squared_gradient(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
    case: EdgeEdgeCase,
) -> (f64, SVector<f64, 12>) {
    use EdgeEdgeCase::*;
    match case {
        Ea0Eb0 => point_point_12_gradient(ea0, eb0, 0, 2),
        Ea0Eb1 => point_point_12_gradient(ea0, eb1, 0, 3),
        Ea1Eb0 => point_point_12_gradient(ea1, eb0, 1, 2),
        Ea1Eb1 => point_point_12_gradient(ea1, eb1, 1, 3),
        Ea0Eb => point_line_12_gradient(ea0, eb0, eb1, [0, 2, 3]),
        Ea1Eb => point_line_12_gradient(ea1, eb0, eb1, [1, 2, 3]),
        EaEb0 => point_line_12_gradient(eb0, ea0, ea1, [2, 0, 1]),
        EaEb1 => point_line_12_gradient(eb1, ea0, ea1, [3, 0, 1]),
        LineLine => line_line_distance_squared_gradient(ea0, ea1, eb0, eb1),
    }
}

/// [`edge_edge_distance_squared_gradient`] with the exact Hessian (dimensionless, exactly
/// symmetric, indefinite in general) of the case's primitive, in the 12 DOFs (ea0, ea1, eb0,
/// eb1).
#[inline]
pub fn edge_edge_distance_squared_hessian(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
    case: EdgeEdgeCase,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    use EdgeEdgeCase::*;
    match case {
        Ea0Eb0 => point_point_12_hessian(ea0, eb0, 0, 2),
        Ea0Eb1 => point_point_12_hessian(ea0, eb1, 0, 3),
        Ea1Eb0 => point_point_12_hessian(ea1, eb0, 1, 2),
        Ea1Eb1 => point_point_12_hessian(ea1, eb1, 1, 3),
        Ea0Eb => point_line_12_hessian(ea0, eb0, eb1, [0, 2, 3]),
        Ea1Eb => point_line_12_hessian(ea1, eb0, eb1, [1, 2, 3]),
        EaEb0 => point_line_12_hessian(eb0, ea0, ea1, [2, 0, 1]),
        EaEb1 => point_line_12_hessian(eb1, ea0, ea1, [3, 0, 1]),
        LineLine => line_line_distance_squared_hessian(ea0, ea1, eb0, eb1),
    }
}

// ---------------------------------------------------------------------------------------------
// The mollifier of nearly parallel edges (IPC §4.3)
// ---------------------------------------------------------------------------------------------

/// The chain rule for (u, v) = (ea1 − ea0, eb1 − eb0) over (ea0, ea1, eb0, eb1):
/// (−∂/∂u, ∂/∂u, −∂/∂v, ∂/∂v).
#[inline(always)]
fn scatter_gradient_two_edges(g: &[Vec3; 2]) -> SVector<f64, 12> {
    let mut out = SVector::<f64, 12>::zeros();
    out.fixed_rows_mut::<3>(0).copy_from(&(-g[0]));
    out.fixed_rows_mut::<3>(3).copy_from(&g[0]);
    out.fixed_rows_mut::<3>(6).copy_from(&(-g[1]));
    out.fixed_rows_mut::<3>(9).copy_from(&g[1]);
    out
}

/// The Hessian of the same layout: block (i, j) is σ_i σ_j H_{y_i y_j} with σ = (−1, 1, −1, 1)
/// and y = (u, u, v, v); the upper block triangle, mirrored (exactly symmetric).
#[inline(always)]
fn scatter_hessian_two_edges(h: &[[Matrix3<f64>; 2]; 2]) -> SMatrix<f64, 12, 12> {
    const SIGN: [f64; 4] = [-1.0, 1.0, -1.0, 1.0];
    const Y: [usize; 4] = [0, 0, 1, 1];
    let diagonal = [mirror_upper(&h[0][0]), mirror_upper(&h[1][1])];
    let mut out = SMatrix::<f64, 12, 12>::zeros();
    for i in 0..4 {
        for j in i..4 {
            let source = if Y[i] == Y[j] {
                &diagonal[Y[i]]
            } else {
                &h[Y[i]][Y[j]]
            };
            let block = source * (SIGN[i] * SIGN[j]);
            out.fixed_view_mut::<3, 3>(3 * i, 3 * j).copy_from(&block);
            if i != j {
                out.fixed_view_mut::<3, 3>(3 * j, 3 * i)
                    .copy_from(&block.transpose());
            }
        }
    }
    out
}

/// c = |u × v|² with ∂c/∂u = 2 v × n, ∂c/∂v = 2 n × u (n = u × v): the cross-product forms, which
/// keep their digits for nearly parallel edges where |u|²|v|² − (u·v)² cancels.
#[inline(always)]
fn cross_gradient_core(u: &Vec3, v: &Vec3) -> (f64, [Vec3; 2]) {
    let n = u.cross(v);
    (n.norm_squared(), [2.0 * v.cross(&n), 2.0 * n.cross(u)])
}

/// The Hessian blocks of c = |u × v|² in (u, v): 2(|v|²I − v vᵀ), 2(|u|²I − u uᵀ) and
/// ∂²c/∂u∂v = 4u vᵀ − 2v uᵀ − 2(u·v)I.
#[inline(always)]
fn cross_hessian_blocks(u: &Vec3, v: &Vec3) -> [[Matrix3<f64>; 2]; 2] {
    let h_uu = 2.0 * (Matrix3::from_diagonal_element(v.norm_squared()) - v * v.transpose());
    let h_vv = 2.0 * (Matrix3::from_diagonal_element(u.norm_squared()) - u * u.transpose());
    let h_uv = 4.0 * u * v.transpose()
        - 2.0 * v * u.transpose()
        - Matrix3::from_diagonal_element(2.0 * u.dot(v));
    [[h_uu, h_uv], [h_uv.transpose(), h_vv]]
}

/// c(x) = |(ea1 − ea0) × (eb1 − eb0)|² (m⁴): zero exactly for parallel (or zero-length) edges;
/// the mollifier's argument.
#[inline]
pub fn edge_edge_cross_squared(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3) -> f64 {
    (ea1 - ea0).cross(&(eb1 - eb0)).norm_squared()
}

/// [`edge_edge_cross_squared`] (m⁴) and its gradient (m³) in the 12 DOFs (ea0, ea1, eb0, eb1).
#[inline]
pub fn edge_edge_cross_squared_gradient(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
) -> (f64, SVector<f64, 12>) {
    let (c, g) = cross_gradient_core(&(ea1 - ea0), &(eb1 - eb0));
    (c, scatter_gradient_two_edges(&g))
}

/// [`edge_edge_cross_squared`] (m⁴), its gradient (m³) and its exact Hessian (m², exactly
/// symmetric) in the 12 DOFs (ea0, ea1, eb0, eb1).
#[inline]
pub fn edge_edge_cross_squared_hessian(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (u, v) = (ea1 - ea0, eb1 - eb0);
    let (c, g) = cross_gradient_core(&u, &v);
    (
        c,
        scatter_gradient_two_edges(&g),
        scatter_hessian_two_edges(&cross_hessian_blocks(&u, &v)),
    )
}

/// IPC's mollifier threshold ε_x = 1e-3·|ea1 − ea0|²·|eb1 − eb0|² (m⁴), from the edges' REST
/// positions, so that it is fixed over the simulation: the mollifier is active where
/// sin²∠(ea, eb) < 1e-3 at rest lengths. Zero for a zero-length rest edge (then no mollifier:
/// [`mollifier`] is 1).
#[inline]
pub fn edge_edge_mollifier_threshold(
    ea0_rest: &Vec3,
    ea1_rest: &Vec3,
    eb0_rest: &Vec3,
    eb1_rest: &Vec3,
) -> f64 {
    1e-3 * (ea1_rest - ea0_rest).norm_squared() * (eb1_rest - eb0_rest).norm_squared()
}

/// m(c) = −c²/ε_x² + 2c/ε_x for c < ε_x, 1 otherwise (dimensionless): rises from m(0) = 0 to 1 at
/// c = ε_x with zero slope there (C¹). c and ε_x in m⁴; ε_x ≤ 0 gives 1 for every c ≥ 0.
#[inline]
pub fn mollifier(c: f64, eps_x: f64) -> f64 {
    // Tested this way round so that a NaN comes out as NaN.
    if c >= eps_x {
        1.0
    } else {
        let y = c / eps_x;
        y * (2.0 - y)
    }
}

/// m'(c) = (2/ε_x)(1 − c/ε_x) for c < ε_x, 0 otherwise (1/m⁴): continuous, 0 at c = ε_x.
#[inline]
pub fn mollifier_derivative(c: f64, eps_x: f64) -> f64 {
    if c >= eps_x {
        0.0
    } else {
        2.0 / eps_x * (1.0 - c / eps_x)
    }
}

/// m''(c) = −2/ε_x² for c < ε_x, 0 otherwise (1/m⁸): jumps at c = ε_x (m is C¹, not C²).
#[inline]
pub fn mollifier_second_derivative(c: f64, eps_x: f64) -> f64 {
    if c >= eps_x {
        0.0
    } else {
        -2.0 / (eps_x * eps_x)
    }
}

/// The edge–edge mollifier m(c(x)) (dimensionless) with c = [`edge_edge_cross_squared`] and the
/// threshold `eps_x` of [`edge_edge_mollifier_threshold`] (m⁴, from rest positions). IPC
/// multiplies the edge–edge barrier by it, so that the energy and its derivatives vanish smoothly
/// as the edges become parallel, where the edge–edge distance's classification jumps.
#[inline]
pub fn edge_edge_mollifier(ea0: &Vec3, ea1: &Vec3, eb0: &Vec3, eb1: &Vec3, eps_x: f64) -> f64 {
    mollifier(edge_edge_cross_squared(ea0, ea1, eb0, eb1), eps_x)
}

/// [`edge_edge_mollifier`] and its gradient (1/m) in the 12 DOFs (ea0, ea1, eb0, eb1),
/// m'(c) ∇c: exactly (1, 0) where c ≥ ε_x, which a caller can test first with
/// [`edge_edge_cross_squared`] to skip the product rule.
#[inline]
pub fn edge_edge_mollifier_gradient(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
    eps_x: f64,
) -> (f64, SVector<f64, 12>) {
    let (u, v) = (ea1 - ea0, eb1 - eb0);
    let (c, g) = cross_gradient_core(&u, &v);
    if c >= eps_x {
        return (1.0, SVector::zeros());
    }
    let dm = mollifier_derivative(c, eps_x);
    (
        mollifier(c, eps_x),
        scatter_gradient_two_edges(&[g[0] * dm, g[1] * dm]),
    )
}

/// [`edge_edge_mollifier_gradient`] with the exact Hessian (1/m², exactly symmetric),
/// m''(c) ∇c ∇cᵀ + m'(c) ∇²c, in the 12 DOFs (ea0, ea1, eb0, eb1); (1, 0, 0) where c ≥ ε_x.
#[inline]
pub fn edge_edge_mollifier_hessian(
    ea0: &Vec3,
    ea1: &Vec3,
    eb0: &Vec3,
    eb1: &Vec3,
    eps_x: f64,
) -> (f64, SVector<f64, 12>, SMatrix<f64, 12, 12>) {
    let (u, v) = (ea1 - ea0, eb1 - eb0);
    let (c, g) = cross_gradient_core(&u, &v);
    if c >= eps_x {
        return (1.0, SVector::zeros(), SMatrix::zeros());
    }
    let dm = mollifier_derivative(c, eps_x);
    let ddm = mollifier_second_derivative(c, eps_x);
    // In (u, v): m'' g gᵀ + m' ∇²c, then the same chain rule as c's.
    let mut h = cross_hessian_blocks(&u, &v);
    for (a, row) in h.iter_mut().enumerate() {
        for (b, block) in row.iter_mut().enumerate() {
            *block = *block * dm + g[a] * (g[b].transpose() * ddm);
        }
    }
    (
        mollifier(c, eps_x),
        scatter_gradient_two_edges(&[g[0] * dm, g[1] * dm]),
        scatter_hessian_two_edges(&h),
    )
}
