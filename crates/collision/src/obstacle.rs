//! Static obstacles as geometry: a half-space or the outside of a sphere ([`Obstacle`]), with
//! the signed distance of a point (m, positive on the allowed side), its gradient and Hessian, the
//! change of distance along a move computed without cancellation, and the time of impact of a
//! straight-line move (the share of it after which the point would first reach the surface).
//!
//! This module owns the geometry of obstacles; the barrier and friction energies built on the
//! distance are `hooke_assembly::barrier`'s, and the line-search caps built on the time of impact
//! are the solvers'. A box container is 2·D half-spaces. Works in 2D and 3D (`D`).
//!
//! Units: metres.

use nalgebra::{SMatrix, SVector};

/// The machine epsilon, 2.2e-16.
const EPS: f64 = f64::EPSILON;

/// A static obstacle: the allowed side is where the signed distance is positive.
///
/// A box container is 2·D half-spaces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Obstacle<const D: usize> {
    /// The half-space (x − point)·normal ≥ 0, bounded by the plane through `point` (m).
    /// **Invariant:** `normal` has unit length (the distance is measured along it);
    /// [`Obstacle::half_space`] normalises it.
    HalfSpace {
        /// A point on the boundary plane (m).
        point: SVector<f64, D>,
        /// The unit normal, pointing into the allowed side.
        normal: SVector<f64, D>,
    },
    /// The outside of the solid sphere |x − center| ≤ radius (m). **Invariant:** radius > 0
    /// ([`Obstacle::sphere_outside`] checks it).
    SphereOutside {
        /// The centre (m).
        center: SVector<f64, D>,
        /// The radius (m), positive.
        radius: f64,
    },
}

/// `v / |v|` and `|v|`, computed on v / max|vᵢ| so that neither tiny nor huge vectors underflow or
/// overflow; `None` for a zero or non-finite vector.
fn unit_and_norm<const D: usize>(v: &SVector<f64, D>) -> Option<(SVector<f64, D>, f64)> {
    let scale = v.amax();
    if !(scale > 0.0 && scale.is_finite()) {
        return None;
    }
    let scaled = v / scale;
    let norm = scaled.norm();
    Some((scaled / norm, scale * norm))
}

impl<const D: usize> Obstacle<D> {
    /// The half-space (x − point)·n̂ ≥ 0 with n̂ = normal/|normal|. `None` if `normal` is zero or
    /// not finite, or `point` is not finite. Tiny and huge normals are normalised without
    /// underflow or overflow.
    pub fn half_space(point: SVector<f64, D>, normal: SVector<f64, D>) -> Option<Self> {
        if !point.iter().all(|c| c.is_finite()) {
            return None;
        }
        let (normal, _) = unit_and_norm(&normal)?;
        Some(Obstacle::HalfSpace { point, normal })
    }

    /// The outside of the sphere of `radius` (m) about `center`. `None` unless the radius is
    /// positive and finite and the centre finite.
    pub fn sphere_outside(center: SVector<f64, D>, radius: f64) -> Option<Self> {
        if radius > 0.0 && radius.is_finite() && center.iter().all(|c| c.is_finite()) {
            Some(Obstacle::SphereOutside { center, radius })
        } else {
            None
        }
    }

    /// The signed distance d(x) (m): positive on the allowed side, zero on the surface, negative
    /// inside the obstacle. Plane: (x − point)·n; sphere: |x − center| − radius.
    #[inline]
    pub fn distance(&self, x: &SVector<f64, D>) -> f64 {
        match self {
            Obstacle::HalfSpace { point, normal } => (x - point).dot(normal),
            Obstacle::SphereOutside { center, radius } => (x - center).norm() - radius,
        }
    }

    /// d(x + δ) − d(x) (m), without subtracting two rounded distances: plane δ·n; sphere
    /// δ·(2(x − c) + δ) / (|x + δ − c| + |x − c|), which is 0 when both norms are 0. Accurate to a
    /// few ulps of the result even when |δ| is far below the rounding of d(x).
    #[inline]
    pub fn distance_change(&self, x: &SVector<f64, D>, delta: &SVector<f64, D>) -> f64 {
        match self {
            Obstacle::HalfSpace { normal, .. } => delta.dot(normal),
            Obstacle::SphereOutside { center, .. } => {
                let offset = x - center;
                let moved = offset + delta;
                let sum = moved.norm() + offset.norm();
                if sum == 0.0 {
                    0.0
                } else {
                    delta.dot(&(offset * 2.0 + delta)) / sum
                }
            }
        }
    }

    /// The gradient ∇d(x), a unit vector pointing into the allowed side: the plane's normal, or
    /// (x − c)/|x − c| for a sphere. At a sphere's centre, where d has no gradient, e₀.
    #[inline]
    pub fn normal(&self, x: &SVector<f64, D>) -> SVector<f64, D> {
        match self {
            Obstacle::HalfSpace { normal, .. } => *normal,
            Obstacle::SphereOutside { center, .. } => {
                let offset = x - center;
                let length = offset.norm();
                if length > 0.0 {
                    offset / length
                } else {
                    let mut e0 = SVector::zeros();
                    e0[0] = 1.0;
                    e0
                }
            }
        }
    }

    /// The Hessian ∇²d(x) (1/m): zero for a plane, (I − n nᵀ)/|x − c| for a sphere (positive
    /// semidefinite, rank D − 1, exactly symmetric). At a sphere's centre, where d has no second
    /// derivative, the limit along e₀: +∞ on the diagonal entries other than (0, 0), 0 elsewhere
    /// (only reached inside the obstacle, where the barrier does not use it).
    #[inline]
    pub fn distance_hessian(&self, x: &SVector<f64, D>) -> SMatrix<f64, D, D> {
        match self {
            Obstacle::HalfSpace { .. } => SMatrix::zeros(),
            Obstacle::SphereOutside { center, .. } => {
                let offset = x - center;
                let length = offset.norm();
                if length == 0.0 {
                    let mut diagonal = SVector::repeat(f64::INFINITY);
                    diagonal[0] = 0.0;
                    return SMatrix::from_diagonal(&diagonal);
                }
                let n = offset / length;
                let inverse = 1.0 / length;
                let mut h = SMatrix::zeros();
                for b in 0..D {
                    for a in 0..D {
                        let identity = if a == b { 1.0 } else { 0.0 };
                        h[(a, b)] = (identity - n[a] * n[b]) * inverse;
                    }
                }
                h
            }
        }
    }

    /// The time of impact of the straight-line step x + α p: the smallest α ≥ 0 with
    /// d(x + α p) = 0 (dimensionless, a fraction of p), or `None` if the line never reaches the
    /// surface (plane: p·n ≥ 0; sphere: p moves away from the centre, or the line misses the
    /// sphere). `Some(0)` if d(x) ≤ 0 already; `Some(NaN)` if an input is NaN (note that
    /// `f64::min` drops NaN: test for it). A root beyond `f64::MAX` is `None`.
    ///
    /// Analytic: the plane's root is d(x)/(−p̂·n)/|p|; the sphere's is the smaller root of
    /// |x − c + s p̂|² = r² in the distance s along p̂, written s = c'/(−β + √(r² − m²)) with
    /// β = (x − c)·p̂, c' = d(x)(|x − c| + r) and m = |(x − c) − β p̂| the line's distance from the
    /// centre (the "citardauq" form: no cancellation between −β > 0 and the square root). A line
    /// that passes the sphere within rounding of its surface (m − r ≤ 32ε(|c| + |x − c| + r)) counts
    /// as touching at its closest point, the cautious answer.
    ///
    /// **Guarantee** (what a line search capped at 0.9·toi relies on): if d(x) > 0, then for every
    /// α with 0 ≤ α ≤ 0.9·toi (every α ≥ 0 when `None`) the computed `distance(x + α p)` is ≥ 0,
    /// provided d(x) ≥ 1e-12·(|x| + |point or center| + radius + α|p|), i.e. d(x) is above the
    /// rounding error of the coordinates involved. The true distance there is at least 0.1 d(x)
    /// (plane) or 0.01 d(x) (sphere: the distance can fall quadratically near a tangential touch),
    /// and the computed one differs from it by a few ulps of those coordinates.
    pub fn time_of_impact(&self, x: &SVector<f64, D>, p: &SVector<f64, D>) -> Option<f64> {
        let start = self.distance(x);
        if start.is_nan() || p.iter().any(|c| c.is_nan()) {
            return Some(f64::NAN);
        }
        if start <= 0.0 {
            return Some(0.0);
        }
        // p = |p| p̂, computed without underflow; p = 0 never moves, an infinite p is no direction.
        let (direction, length) = unit_and_norm(p)?;
        let along = match self {
            Obstacle::HalfSpace { normal, .. } => {
                let rate = direction.dot(normal);
                if rate >= 0.0 || rate.is_nan() {
                    return None;
                }
                start / -rate
            }
            Obstacle::SphereOutside { center, radius } => {
                let offset = x - center;
                let offset_length = offset.norm();
                let beta = offset.dot(&direction);
                // |o + s p̂|² = |o|² + 2sβ + s² ≥ |o|² for s ≥ 0: moving away never gets closer.
                if beta >= 0.0 || beta.is_nan() {
                    return None;
                }
                let miss = (offset - direction * beta).norm();
                let band = 32.0 * EPS * (center.norm() + offset_length + radius);
                if miss - radius > band {
                    return None;
                }
                // The tangent point −β (the closest approach) bounds the first root from above.
                let closest = -beta;
                if miss >= *radius {
                    closest
                } else {
                    let c = start * (offset_length + radius);
                    let root = c / (closest + ((radius - miss) * (radius + miss)).sqrt());
                    root.min(closest)
                }
            }
        };
        let alpha = along / length;
        alpha.is_finite().then_some(alpha)
    }
}
