//! IPC's log barrier on the features of a triangle surface: the pairs of self-contact
//! (point–triangle and edge–edge, Li et al. 2020, "Incremental Potential Contact", §4) and a
//! triangle against a sphere, with their gradients and Hessians over the vertices involved.
//!
//! This module owns the energies of single terms. The distances, their derivatives and the
//! edge–edge mollifier come from `hooke_collision::distance`; the sum over a surface's pairs is
//! [`crate::self_contact`]; the continuous collision detection that caps a line search belongs to
//! the solvers (`hooke_solvers::backward_euler`). Vertex-level barriers against static obstacles
//! are in [`crate::barrier`], whose barrier b this module shares.
//!
//! Every term is κ b(d) with b(d) = −(d − d̂)² ln(d/d̂) (m²) for 0 < d < d̂, zero beyond d̂, +∞ at
//! and below 0, κ in N/m, so that a term is in J, and d the unsigned distance (m) between the two
//! closed primitives (for a sphere, the distance from its surface). An edge–edge term is
//! multiplied by IPC's mollifier m(c) of c = |(ea1 − ea0) × (eb1 − eb0)|², which takes it smoothly
//! to zero as the edges turn parallel (their distance is not smooth there).
//!
//! # The Hessians
//! [`Definiteness::Exact`] gives the exact Hessian (indefinite in general). [`Definiteness::Clamped`]
//! gives a positive semidefinite one by a Gauss–Newton projection: the Hessian of the outer
//! function with respect to the distance ρ = √s (and the mollifier's c) projected onto the
//! positive semidefinite matrices, composed with the Jacobians of the inner quantities,
//! Jᵀ P(G) J with J = [∇ρ, ∇c]; the curvature of the inner maps (b'∇²ρ, m'b∇²c) is left out. For
//! a pair without mollification this is κ b''(d) ∇ρ∇ρᵀ, rank one: along ∇ρ it is exact (b is
//! convex in d), and the part it leaves out, b'(d)∇²ρ with b' < 0, only turns the distance's
//! convex curvature negative. It is positive semidefinite by construction and costs an outer
//! product of one 12-vector, where projecting the exact 12×12 Hessian needs an eigen-decomposition
//! per pair; it is the projection the sphere obstacles' vertex terms already use.
//!
//! No function here allocates or panics; NaN in an input comes out as NaN.

use hooke_collision::distance::{
    edge_edge_case_and_distance_squared, edge_edge_cross_squared, edge_edge_cross_squared_gradient,
    edge_edge_cross_squared_hessian, edge_edge_distance_squared_gradient,
    edge_edge_distance_squared_hessian, mollifier, mollifier_derivative,
    mollifier_second_derivative, point_triangle_case, point_triangle_case_and_distance_squared,
    point_triangle_distance_squared, point_triangle_distance_squared_gradient,
    point_triangle_distance_squared_hessian,
};
use nalgebra::{SMatrix, SVector, Vector3};

use crate::barrier::{barrier, barrier_derivative, barrier_second_derivative};
use crate::Definiteness;

/// A position (m).
pub type Vec3 = Vector3<f64>;

/// The energy (J), gradient (N) and Hessian (N/m) of one barrier term over the N coordinates of
/// the vertices it involves (3 per vertex, in the order the function names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureTerms<const N: usize> {
    /// The energy (J).
    pub energy: f64,
    /// Its gradient (N); the forces are minus this.
    pub gradient: SVector<f64, N>,
    /// Its Hessian (N/m), exactly symmetric; zero when not asked for.
    pub hessian: SMatrix<f64, N, N>,
}

/// The distance (m) between a point and a closed triangle, `x` = (p, t0, t1, t2).
#[inline]
pub fn point_triangle_distance(x: &[Vec3; 4]) -> f64 {
    point_triangle_distance_squared(&x[0], &x[1], &x[2], &x[3]).sqrt()
}

/// The distance (m) between two closed segments, `x` = (ea0, ea1, eb0, eb1).
#[inline]
pub fn edge_edge_distance(x: &[Vec3; 4]) -> f64 {
    hooke_collision::distance::edge_edge_distance_squared(&x[0], &x[1], &x[2], &x[3]).sqrt()
}

/// The point–triangle barrier energy κ b(d) (J) of `x` = (p, t0, t1, t2): 0 at d ≥ `d_hat`, +∞
/// at d = 0.
#[inline]
pub fn point_triangle_energy(x: &[Vec3; 4], d_hat: f64, kappa: f64) -> f64 {
    let d = point_triangle_distance(x);
    if d >= d_hat {
        0.0
    } else {
        kappa * barrier(d, d_hat)
    }
}

/// The edge–edge barrier energy κ m(c) b(d) (J) of `x` = (ea0, ea1, eb0, eb1), with the
/// mollifier's threshold `eps_x` (m⁴, from the rest positions:
/// `hooke_collision::distance::edge_edge_mollifier_threshold`).
#[inline]
pub fn edge_edge_energy(x: &[Vec3; 4], d_hat: f64, kappa: f64, eps_x: f64) -> f64 {
    let d = edge_edge_distance(x);
    if d >= d_hat {
        return 0.0;
    }
    let c = edge_edge_cross_squared(&x[0], &x[1], &x[2], &x[3]);
    let m = if c < eps_x { mollifier(c, eps_x) } else { 1.0 };
    kappa * m * barrier(d, d_hat)
}

/// The point–triangle barrier term of `x` = (p, t0, t1, t2) with reach `d_hat` (m) and stiffness
/// `kappa` (N/m): `None` at d ≥ d̂ (no term). The gradient and, with `hessian` given, the Hessian
/// (see the module documentation for [`Definiteness::Clamped`]) are over (p, t0, t1, t2). At
/// d = 0 the energy is +∞ and the derivatives are not finite.
#[inline]
pub fn point_triangle_terms(
    x: &[Vec3; 4],
    d_hat: f64,
    kappa: f64,
    hessian: Option<Definiteness>,
) -> Option<FeatureTerms<12>> {
    let (case, s) = point_triangle_case_and_distance_squared(&x[0], &x[1], &x[2], &x[3]);
    // Most candidates of a broad phase are out of reach: no derivative for them.
    if s.sqrt() >= d_hat {
        return None;
    }
    match hessian {
        Some(Definiteness::Exact) => {
            let (s, gs, hs) =
                point_triangle_distance_squared_hessian(&x[0], &x[1], &x[2], &x[3], case);
            barrier_of_squared(
                s,
                &gs,
                Some(&hs),
                0.0,
                d_hat,
                kappa,
                Some(Definiteness::Exact),
            )
        }
        definiteness => {
            let (s, gs) =
                point_triangle_distance_squared_gradient(&x[0], &x[1], &x[2], &x[3], case);
            barrier_of_squared(s, &gs, None, 0.0, d_hat, kappa, definiteness)
        }
    }
}

/// The edge–edge barrier term κ m(c) b(d) of `x` = (ea0, ea1, eb0, eb1), as
/// [`point_triangle_terms`], with the mollifier's threshold `eps_x` (m⁴).
#[inline]
pub fn edge_edge_terms(
    x: &[Vec3; 4],
    d_hat: f64,
    kappa: f64,
    eps_x: f64,
    hessian: Option<Definiteness>,
) -> Option<FeatureTerms<12>> {
    let (case, s) = edge_edge_case_and_distance_squared(&x[0], &x[1], &x[2], &x[3]);
    // Most candidates of a broad phase are out of reach: no derivative for them.
    if s.sqrt() >= d_hat {
        return None;
    }
    let exact = hessian == Some(Definiteness::Exact);
    let (s, gs, hs) = if exact {
        let (s, g, h) = edge_edge_distance_squared_hessian(&x[0], &x[1], &x[2], &x[3], case);
        (s, g, Some(h))
    } else {
        let (s, g) = edge_edge_distance_squared_gradient(&x[0], &x[1], &x[2], &x[3], case);
        (s, g, None)
    };
    let c = edge_edge_cross_squared(&x[0], &x[1], &x[2], &x[3]);
    if c >= eps_x {
        return barrier_of_squared(s, &gs, hs.as_ref(), 0.0, d_hat, kappa, hessian);
    }
    let rho = s.sqrt();
    if rho >= d_hat {
        return None;
    }
    let (b, db, ddb) = (
        barrier(rho, d_hat),
        barrier_derivative(rho, d_hat),
        barrier_second_derivative(rho, d_hat),
    );
    let (m, dm, ddm) = (
        mollifier(c, eps_x),
        mollifier_derivative(c, eps_x),
        mollifier_second_derivative(c, eps_x),
    );
    let grad_rho = gs / (2.0 * rho);
    let (gc, hc) = if exact {
        let (_, g, h) = edge_edge_cross_squared_hessian(&x[0], &x[1], &x[2], &x[3]);
        (g, Some(h))
    } else {
        let (_, g) = edge_edge_cross_squared_gradient(&x[0], &x[1], &x[2], &x[3]);
        (g, None)
    };
    let gradient = (grad_rho * (m * db) + gc * (b * dm)) * kappa;
    let hessian = match (hessian, hs, hc) {
        (Some(Definiteness::Exact), Some(hs), Some(hc)) => {
            let distance =
                hs * (db / (2.0 * rho)) + grad_rho * grad_rho.transpose() * (ddb - db / rho);
            let cross = grad_rho * gc.transpose();
            (distance * m
                + (cross + cross.transpose()) * (dm * db)
                + gc * gc.transpose() * (b * ddm)
                + hc * (b * dm))
                * kappa
        }
        (Some(_), _, _) => {
            // Jᵀ P(G) J with J = [∇ρ, ∇c] and G the Hessian of κ m(c) b(ρ) in (ρ, c).
            let [[p00, p01], [_, p11]] = project_2x2(m * ddb, dm * db, b * ddm);
            let h = grad_rho * grad_rho.transpose() * p00
                + (grad_rho * gc.transpose() + gc * grad_rho.transpose()) * p01
                + gc * gc.transpose() * p11;
            symmetrize(h * kappa)
        }
        (None, _, _) => SMatrix::zeros(),
    };
    Some(FeatureTerms {
        energy: kappa * m * b,
        gradient,
        hessian,
    })
}

/// The barrier term of a triangle `t` = (t0, t1, t2) against the sphere of `radius` (m) about
/// `center`: κ b(d) with d the distance from the closed triangle to the sphere's surface (its
/// distance to the centre minus the radius), so that the barrier keeps every point of the
/// triangle outside, not only its vertices. `None` at d ≥ d̂. Derivatives over (t0, t1, t2).
#[inline]
pub fn triangle_sphere_terms(
    t: &[Vec3; 3],
    center: &Vec3,
    radius: f64,
    d_hat: f64,
    kappa: f64,
    hessian: Option<Definiteness>,
) -> Option<FeatureTerms<9>> {
    let case = point_triangle_case(center, &t[0], &t[1], &t[2]);
    let full = match hessian {
        Some(Definiteness::Exact) => {
            let (s, gs, hs) =
                point_triangle_distance_squared_hessian(center, &t[0], &t[1], &t[2], case);
            barrier_of_squared(s, &gs, Some(&hs), radius, d_hat, kappa, hessian)
        }
        _ => {
            let (s, gs) =
                point_triangle_distance_squared_gradient(center, &t[0], &t[1], &t[2], case);
            barrier_of_squared(s, &gs, None, radius, d_hat, kappa, hessian)
        }
    }?;
    // The centre does not move: keep the triangle's coordinates.
    Some(FeatureTerms {
        energy: full.energy,
        gradient: full.gradient.fixed_rows::<9>(3).into_owned(),
        hessian: full.hessian.fixed_view::<9, 9>(3, 3).into_owned(),
    })
}

/// The distance (m) from the closed triangle `t` to the surface of the sphere (`center`,
/// `radius`): negative where the triangle dips into it.
#[inline]
pub fn triangle_sphere_distance(t: &[Vec3; 3], center: &Vec3, radius: f64) -> f64 {
    point_triangle_distance_squared(center, &t[0], &t[1], &t[2]).sqrt() - radius
}

/// The barrier energy of [`triangle_sphere_terms`] (J).
#[inline]
pub fn triangle_sphere_energy(
    t: &[Vec3; 3],
    center: &Vec3,
    radius: f64,
    d_hat: f64,
    kappa: f64,
) -> f64 {
    let d = triangle_sphere_distance(t, center, radius);
    if d >= d_hat {
        0.0
    } else {
        kappa * barrier(d, d_hat)
    }
}

/// The change (J) of [`triangle_sphere_energy`] when the triangle's vertices move by `delta` (m),
/// written without subtracting two rounded energies or distances: with q(w; y) = Σ wᵢ yᵢ, w₀ and w₁
/// the barycentric weights of the closest points before and after the move, the squared distance
/// changes by (Σ w₀ᵢδᵢ)·(2(q₀ − c) + Σ w₀ᵢδᵢ) − |D|² − 2(q₁ − c)·D with D = Σ (w₀ᵢ − w₁ᵢ)(yᵢ − y₀)
/// (the first term moves the old closest point, the rest finds the new one), every term a product
/// of small quantities; the barrier's change then follows [`crate::barrier::barrier_change`]. So
/// the change keeps its digits when the move is far below the rounding of coordinates relative to
/// the centre, which a line search needs near convergence.
pub fn triangle_sphere_energy_change(
    t: &[Vec3; 3],
    delta: &[Vec3; 3],
    center: &Vec3,
    radius: f64,
    d_hat: f64,
    kappa: f64,
) -> f64 {
    let end = [t[0] + delta[0], t[1] + delta[1], t[2] + delta[2]];
    let w0 = closest_weights(center, t);
    let w1 = closest_weights(center, &end);
    let q0 = t[0] * w0[0] + t[1] * w0[1] + t[2] * w0[2];
    let q1 = end[0] * w1[0] + end[1] * w1[1] + end[2] * w1[2];
    let moved = delta[0] * w0[0] + delta[1] * w0[1] + delta[2] * w0[2];
    let dw = [w0[0] - w1[0], w0[1] - w1[1], w0[2] - w1[2]];
    let shift = (end[1] - end[0]) * dw[1] + (end[2] - end[0]) * dw[2];
    let change_squared = moved.dot(&((q0 - center) * 2.0 + moved))
        - shift.norm_squared()
        - 2.0 * (q1 - center).dot(&shift);
    let (rho0, rho1) = ((q0 - center).norm(), (q1 - center).norm());
    let sum = rho0 + rho1;
    let change = if sum > 0.0 { change_squared / sum } else { 0.0 };
    let d0 = rho0 - radius;
    if d0 >= d_hat && d0 + change >= d_hat {
        return 0.0;
    }
    kappa * crate::barrier::barrier_change(d0, change, d_hat)
}

/// The barycentric weights of the point of the closed triangle `t` closest to `p` (Ericson,
/// "Real-Time Collision Detection", §5.1.5); a degenerate triangle gives a closest point of its
/// edges.
fn closest_weights(p: &Vec3, t: &[Vec3; 3]) -> [f64; 3] {
    let (a, b, c) = (&t[0], &t[1], &t[2]);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        // Degenerate: the closest of the three edges (handled above for each vertex region).
        return [1.0, 0.0, 0.0];
    }
    let (v, w) = (vb / sum, vc / sum);
    [1.0 - v - w, v, w]
}

/// κ b(ρ − offset) of a squared distance s = ρ² with gradient `gs` (and Hessian `hs` for the
/// exact Hessian): `None` where ρ − offset ≥ d̂.
#[inline]
fn barrier_of_squared<const N: usize>(
    s: f64,
    gs: &SVector<f64, N>,
    hs: Option<&SMatrix<f64, N, N>>,
    offset: f64,
    d_hat: f64,
    kappa: f64,
    definiteness: Option<Definiteness>,
) -> Option<FeatureTerms<N>> {
    let rho = s.sqrt();
    let d = rho - offset;
    if d >= d_hat {
        return None;
    }
    let (b, db, ddb) = (
        barrier(d, d_hat),
        barrier_derivative(d, d_hat),
        barrier_second_derivative(d, d_hat),
    );
    // ∇ρ = ∇s / (2ρ).
    let grad_rho = gs / (2.0 * rho);
    let hessian = match (definiteness, hs) {
        (Some(Definiteness::Exact), Some(hs)) => {
            // ∇²ρ = ∇²s/(2ρ) − ∇ρ∇ρᵀ/ρ.
            symmetrize(
                (hs * (db / (2.0 * rho)) + grad_rho * grad_rho.transpose() * (ddb - db / rho))
                    * kappa,
            )
        }
        (Some(_), _) => symmetrize(grad_rho * grad_rho.transpose() * (kappa * ddb)),
        (None, _) => SMatrix::zeros(),
    };
    Some(FeatureTerms {
        energy: kappa * b,
        gradient: grad_rho * (kappa * db),
        hessian,
    })
}

/// The projection of the symmetric 2×2 matrix [[a, b], [b, c]] onto the positive semidefinite
/// matrices (its negative eigenvalues set to zero).
#[inline]
fn project_2x2(a: f64, b: f64, c: f64) -> [[f64; 2]; 2] {
    let half_trace = 0.5 * (a + c);
    let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (high, low) = (half_trace + radius, half_trace - radius);
    if low >= 0.0 {
        return [[a, b], [b, c]];
    }
    if high <= 0.0 {
        return [[0.0; 2]; 2];
    }
    // high · v vᵀ, v the unit eigenvector of `high`: (b, high − a) or (high − c, b), whichever is
    // larger (the other may vanish).
    let (v0, v1) = if (high - a).abs() >= (high - c).abs() {
        (b, high - a)
    } else {
        (high - c, b)
    };
    let norm2 = v0 * v0 + v1 * v1;
    if norm2 == 0.0 {
        // b = 0 and a = c = high: diagonal.
        return [[a.max(0.0), 0.0], [0.0, c.max(0.0)]];
    }
    let scale = high / norm2;
    [
        [scale * v0 * v0, scale * v0 * v1],
        [scale * v0 * v1, scale * v1 * v1],
    ]
}

/// (H + Hᵀ)/2, so that a Hessian summed from products is exactly symmetric.
#[inline]
fn symmetrize<const N: usize>(h: SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (h + h.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use hooke_collision::distance::edge_edge_case;
    use proptest::prelude::*;

    /// Central differences of `f` over the 12 coordinates at `x` with step `step`.
    fn fd_gradient(f: impl Fn(&[Vec3; 4]) -> f64, x: &[Vec3; 4], step: f64) -> SVector<f64, 12> {
        let mut g = SVector::zeros();
        for k in 0..12 {
            let (v, a) = (k / 3, k % 3);
            let (mut plus, mut minus) = (*x, *x);
            plus[v][a] += step;
            minus[v][a] -= step;
            g[k] = (f(&plus) - f(&minus)) / (2.0 * step);
        }
        g
    }

    fn fd_hessian(
        f: impl Fn(&[Vec3; 4]) -> SVector<f64, 12>,
        x: &[Vec3; 4],
        step: f64,
    ) -> SMatrix<f64, 12, 12> {
        let mut h = SMatrix::<f64, 12, 12>::zeros();
        for k in 0..12 {
            let (v, a) = (k / 3, k % 3);
            let (mut plus, mut minus) = (*x, *x);
            plus[v][a] += step;
            minus[v][a] -= step;
            h.set_column(k, &((f(&plus) - f(&minus)) / (2.0 * step)));
        }
        h
    }

    fn vec3() -> impl Strategy<Value = Vec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(a, b, c)| Vec3::new(a, b, c))
    }

    /// A point at a height in (0.15, 0.85)·d̂ above a random spot near a unit-sized triangle, so
    /// that the barrier is active and the classification stays away from d = 0.
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

    const D_HAT: f64 = 1e-2;
    const KAPPA: f64 = 1e3;

    /// Relative error of `a` against `b`, measured on the scale of `b`'s largest entry.
    fn relative(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
            / scale
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// The gradient and the exact Hessian against central differences. The step is 1e-4 of
        /// the smallest length of the problem (d̂·0.1): the truncation error is then ~1e-8 of the
        /// derivatives relative to their scale, the rounding ~ε/step·scale ~1e-10; 1e-5 leaves
        /// room for the barrier's growth near d → 0.1 d̂. Configurations where the closest feature
        /// changes within the stencil are skipped (the Hessian jumps there).
        #[test]
        fn point_triangle_derivatives_match_differences(x in point_triangle_config()) {
            let step = 1e-4 * 0.1 * D_HAT;
            let case = point_triangle_case(&x[0], &x[1], &x[2], &x[3]);
            for k in 0..12 {
                for sign in [-1.0, 1.0] {
                    let mut y = x;
                    y[k / 3][k % 3] += sign * step;
                    prop_assume!(point_triangle_case(&y[0], &y[1], &y[2], &y[3]) == case);
                }
            }
            let terms = point_triangle_terms(&x, D_HAT, KAPPA, Some(Definiteness::Exact)).unwrap();
            let fd = fd_gradient(|y| point_triangle_energy(y, D_HAT, KAPPA), &x, step);
            prop_assert!(relative(terms.gradient.as_slice(), fd.as_slice()) < 1e-5);
            let fd_h = fd_hessian(
                |y| point_triangle_terms(y, D_HAT, KAPPA, None).unwrap().gradient,
                &x,
                step,
            );
            prop_assert!(relative(terms.hessian.as_slice(), fd_h.as_slice()) < 1e-5);
            prop_assert_eq!(terms.hessian, terms.hessian.transpose());
            prop_assert!((terms.energy - point_triangle_energy(&x, D_HAT, KAPPA)).abs()
                <= 1e-12 * terms.energy.abs());
        }

        /// The projected Hessian is positive semidefinite, of rank one along the gradient, with
        /// the barrier's curvature: κ b''(d) ∇ρ∇ρᵀ, where the gradient is κ b'(d) ∇ρ.
        #[test]
        fn point_triangle_projection_is_semidefinite(x in point_triangle_config()) {
            let clamped =
                point_triangle_terms(&x, D_HAT, KAPPA, Some(Definiteness::Clamped)).unwrap();
            let eigen = clamped.hessian.symmetric_eigenvalues();
            let scale = clamped.hessian.amax();
            prop_assert!(eigen.iter().all(|&l| l >= -1e-12 * scale));
            let d = point_triangle_distance(&x);
            let grad_rho = clamped.gradient / (KAPPA * barrier_derivative(d, D_HAT));
            let expected = grad_rho * grad_rho.transpose() * (KAPPA * barrier_second_derivative(d, D_HAT));
            prop_assert!(relative(clamped.hessian.as_slice(), expected.as_slice()) < 1e-12);
        }

        /// Edge–edge terms (nearly parallel edges included, where the mollifier acts) against
        /// differences; the projected Hessian is positive semidefinite.
        #[test]
        fn edge_edge_derivatives_match_differences(
            a0 in vec3(), a1 in vec3(), tilt in -0.3..0.3f64, u in 0.2..0.8f64,
            height in 0.2..0.8f64, slide in -0.3..0.3f64, parallel in any::<bool>()
        ) {
            let ea = a1 - a0;
            prop_assume!(ea.norm() > 0.3);
            let normal = ea.cross(&Vec3::new(0.3, -0.5, 0.8));
            prop_assume!(normal.norm() > 0.1);
            let normal = normal.normalize();
            let across = normal.cross(&ea).normalize();
            // Edge b crosses over edge a at height·d̂, turned by `tilt` (near 0: nearly parallel).
            let angle = if parallel { tilt * 1e-1 } else { 0.5 + tilt };
            let dir = ea.normalize() * angle.cos() + across * angle.sin();
            let mid = a0 + ea * u + normal * (height * D_HAT) + ea.normalize() * slide * 0.1;
            let x = [a0, a1, mid - dir * 0.4, mid + dir * 0.4];
            let d = edge_edge_distance(&x);
            prop_assume!(d > 0.15 * D_HAT && d < 0.85 * D_HAT);
            let eps = hooke_collision::distance::edge_edge_mollifier_threshold(&x[0], &x[1], &x[2], &x[3]);
            // The step is 1e-4 of the smallest length of the problem: 0.1 d̂, or for nearly
            // parallel edges the width |ea × eb| / |ea| over which c = |ea × eb|² doubles.
            let width = (x[1] - x[0]).cross(&(x[3] - x[2])).norm() / (x[1] - x[0]).norm();
            // Nearer to parallel the distance's rounding grows like ε/sin θ while the step shrinks
            // with the width, and the differences measure rounding only; the distance module's
            // own tests cover exactly parallel edges. sin θ ≥ 1e-4 keeps c/ε_x = sin²θ/1e-3 deep
            // in the mollifier's range (down to 1e-5).
            prop_assume!(width > 1e-4 * (x[1] - x[0]).norm().min(1.0));
            let step = 1e-4 * (0.1 * D_HAT).min(width);
            let case = edge_edge_case(&x[0], &x[1], &x[2], &x[3]);
            for k in 0..12 {
                for sign in [-1.0, 1.0] {
                    let mut y = x;
                    y[k / 3][k % 3] += sign * step;
                    prop_assume!(edge_edge_case(&y[0], &y[1], &y[2], &y[3]) == case);
                }
            }
            let terms = edge_edge_terms(&x, D_HAT, KAPPA, eps, Some(Definiteness::Exact)).unwrap();
            let fd = fd_gradient(|y| edge_edge_energy(y, D_HAT, KAPPA, eps), &x, step);
            prop_assert!(
                relative(terms.gradient.as_slice(), fd.as_slice()) < 1e-5,
                "{} {:?} c/eps {} d/dhat {} step {step:e} width {width:e}",
                relative(terms.gradient.as_slice(), fd.as_slice()),
                case,
                hooke_collision::distance::edge_edge_cross_squared(&x[0], &x[1], &x[2], &x[3]) / eps,
                d / D_HAT
            );
            let fd_h = fd_hessian(
                |y| edge_edge_terms(y, D_HAT, KAPPA, eps, None).unwrap().gradient,
                &x,
                step,
            );
            prop_assert!(relative(terms.hessian.as_slice(), fd_h.as_slice()) < 1e-5, "{} {:?} c/eps {} d/dhat {}", relative(terms.hessian.as_slice(), fd_h.as_slice()), case, hooke_collision::distance::edge_edge_cross_squared(&x[0], &x[1], &x[2], &x[3]) / eps, d / D_HAT);
            let clamped = edge_edge_terms(&x, D_HAT, KAPPA, eps, Some(Definiteness::Clamped)).unwrap();
            let scale = clamped.hessian.amax();
            prop_assert!(clamped.hessian.symmetric_eigenvalues().iter().all(|&l| l >= -1e-10 * scale));
        }

        /// The sphere's triangle term against differences, and zero beyond d̂.
        #[test]
        fn triangle_sphere_derivatives_match_differences(x in point_triangle_config(), radius in 0.1..2.0f64) {
            // Put the sphere's centre below the point by its radius: the point's distance to the
            // triangle becomes the sphere's.
            let normal = (x[2] - x[1]).cross(&(x[3] - x[1])).normalize();
            let side = if (x[0] - x[1]).dot(&normal) >= 0.0 { 1.0 } else { -1.0 };
            let center = x[0] + normal * (side * radius);
            let t = [x[1], x[2], x[3]];
            let Some(terms) = triangle_sphere_terms(&t, &center, radius, D_HAT, KAPPA, Some(Definiteness::Exact)) else {
                prop_assert!(triangle_sphere_distance(&t, &center, radius) >= D_HAT);
                return Ok(());
            };
            let step = 1e-4 * 0.1 * D_HAT;
            let case = point_triangle_case(&center, &t[0], &t[1], &t[2]);
            let energy = |y: &[Vec3; 4]| triangle_sphere_energy(&[y[1], y[2], y[3]], &center, radius, D_HAT, KAPPA);
            let padded = [center, t[0], t[1], t[2]];
            for k in 3..12 {
                for sign in [-1.0, 1.0] {
                    let mut y = padded;
                    y[k / 3][k % 3] += sign * step;
                    prop_assume!(point_triangle_case(&center, &y[1], &y[2], &y[3]) == case);
                    prop_assume!(triangle_sphere_distance(&[y[1], y[2], y[3]], &center, radius) > 0.05 * D_HAT);
                }
            }
            let fd = fd_gradient(energy, &padded, step);
            prop_assert!(relative(terms.gradient.as_slice(), &fd.as_slice()[3..]) < 1e-5);
        }
    }

    /// The change without cancellation agrees with the difference of energies for moves well
    /// above the coordinates' rounding (there the difference is accurate to ~1e-10 of the change),
    /// and with the first-order change g·δ for moves of 1e-13 m, where the difference of energies
    /// is mostly rounding.
    #[test]
    fn triangle_sphere_change_keeps_its_digits() {
        let center = Vec3::new(0.5, 0.0, 0.5);
        let radius = 0.25;
        let t = [
            Vec3::new(0.47, 0.2512, 0.48),
            Vec3::new(0.54, 0.2515, 0.49),
            Vec3::new(0.50, 0.2513, 0.54),
        ];
        let dir = [
            Vec3::new(0.3, -0.8, 0.1),
            Vec3::new(-0.2, -0.5, 0.4),
            Vec3::new(0.1, -0.9, -0.3),
        ];
        let d_hat = 1.4e-3;
        let kappa = 1.7e4;
        let energy = |p: &[Vec3; 3]| triangle_sphere_energy(p, &center, radius, d_hat, kappa);
        assert!(energy(&t) > 0.0, "the triangle is within reach");
        let large = dir.map(|d| d * 1e-5);
        let moved = [t[0] + large[0], t[1] + large[1], t[2] + large[2]];
        let direct = energy(&moved) - energy(&t);
        let change = triangle_sphere_energy_change(&t, &large, &center, radius, d_hat, kappa);
        assert!(
            (change - direct).abs() <= 1e-8 * direct.abs(),
            "{change} vs {direct}"
        );
        let tiny = dir.map(|d| d * 1e-13);
        let terms = triangle_sphere_terms(&t, &center, radius, d_hat, kappa, None).unwrap();
        let first_order: f64 = (0..3)
            .map(|k| terms.gradient.fixed_rows::<3>(3 * k).dot(&tiny[k]))
            .sum();
        let change = triangle_sphere_energy_change(&t, &tiny, &center, radius, d_hat, kappa);
        assert!(
            (change - first_order).abs() <= 1e-6 * first_order.abs(),
            "{change} vs {first_order}"
        );
    }

    #[test]
    fn projection_of_2x2_is_the_positive_part() {
        for (a, b, c) in [
            (2.0, 1.0, -3.0),
            (1.0, 0.0, -1.0),
            (-1.0, 0.5, -2.0),
            (3.0, 1.0, 2.0),
            (0.0, 2.0, 0.0),
        ] {
            let p = project_2x2(a, b, c);
            let m = nalgebra::Matrix2::new(a, b, b, c);
            let e = m.symmetric_eigen();
            let mut expected = nalgebra::Matrix2::zeros();
            for k in 0..2 {
                let v = e.eigenvectors.column(k);
                expected += v * v.transpose() * e.eigenvalues[k].max(0.0);
            }
            for i in 0..2 {
                for j in 0..2 {
                    assert!(
                        (p[i][j] - expected[(i, j)]).abs() < 1e-12 * (1.0 + m.amax()),
                        "{a} {b} {c}"
                    );
                }
            }
        }
    }
}
