//! The energies of contact with static obstacles for the implicit solvers: IPC's log barrier and
//! its smooth lagged Coulomb friction (Li et al. 2020, "Incremental Potential Contact", §4 and
//! §5), per vertex.
//!
//! Backward Euler minimises Φ(x) = ½(x − y)ᵀM(x − y) + h²E(x); the terms here are added to E. The
//! obstacles are static, so every term depends on one vertex only and every Hessian is a D×D
//! diagonal block.
//!
//! - [`Obstacle`] (the geometry, from `hooke_collision::obstacle`, re-exported here): a half-space
//!   or the outside of a sphere, with the signed distance d (m, positive on the allowed side), its
//!   derivatives, and the [time of impact](Obstacle::time_of_impact) of a straight-line step (the
//!   line search's upper bound, which keeps every iterate feasible).
//! - The barrier b(d) = −(d − d̂)² ln(d/d̂) (m²) for 0 < d < d̂, 0 beyond d̂, +∞ at and below 0:
//!   [`barrier`], [`barrier_derivative`], [`barrier_second_derivative`], the cancellation-free
//!   difference [`barrier_change`], and the per-vertex energy κ b(d(x)) with its gradient and
//!   Hessian block, [`vertex_barrier`] (κ in N/m, so κ b is in J).
//! - Friction: the smoothed Coulomb potential f₀ ([`friction_f0`], [`friction_f1`]) and the lagged
//!   friction term of one contact, [`LaggedFriction`], made from the barrier's normal force at the
//!   lag point by [`lagged_friction`].
//!
//! This module owns the per-vertex terms and the barrier function b itself (which
//! [`crate::surface_barrier`] shares for a surface's pairs and triangles); their sums over a mesh
//! inside backward Euler's objective, and the line-search caps, are `hooke_solvers`'.
//!
//! Units: metres, kilograms, seconds; energy in J, force in N, stiffness in N/m.
//!
//! No function here allocates or panics. NaN in an input comes out as NaN in the results (each
//! function says where that differs, e.g. [`vertex_barrier`] returns `Some` with NaN terms).

use crate::Definiteness;
pub use hooke_collision::obstacle::Obstacle;
use nalgebra::{SMatrix, SVector};

/// The barrier b(d) = −(d − d̂)² ln(d/d̂) (m²) for 0 < d < d̂, with d̂ > 0 (m) the distance at
/// which contact starts; 0 for d ≥ d̂; +∞ for d ≤ 0, so that a line search rejects any step that
/// crosses the surface. Positive, decreasing and convex on (0, d̂), and C² at d̂ (b, b', b'' → 0).
/// NaN in, NaN out.
#[inline]
pub fn barrier(d: f64, d_hat: f64) -> f64 {
    if d >= d_hat {
        0.0
    } else if d <= 0.0 {
        f64::INFINITY
    } else {
        let (a, log) = gap_and_log(d, d_hat);
        -(a * a) * log
    }
}

/// a = d − d̂ and ln(d/d̂), the latter through ln_1p(a/d̂) near d̂ (no cancellation as d → d̂)
/// and ln(d/d̂) below d̂/2 (where a/d̂ → −1 would lose d).
#[inline]
fn gap_and_log(d: f64, d_hat: f64) -> (f64, f64) {
    let a = d - d_hat;
    let log = if d > 0.5 * d_hat {
        (a / d_hat).ln_1p()
    } else {
        (d / d_hat).ln()
    };
    (a, log)
}

/// b'(d) = −(d − d̂)[2 ln(d/d̂) + (d − d̂)/d] (m): negative on (0, d̂), 0 for d ≥ d̂, −∞ for
/// d ≤ 0 (the limit as d → 0⁺). NaN in, NaN out.
#[inline]
pub fn barrier_derivative(d: f64, d_hat: f64) -> f64 {
    if d >= d_hat {
        0.0
    } else if d <= 0.0 {
        f64::NEG_INFINITY
    } else {
        let (a, log) = gap_and_log(d, d_hat);
        -a * (2.0 * log + a / d)
    }
}

/// b''(d) = −2 ln(d/d̂) − 4(d − d̂)/d + (d − d̂)²/d² (dimensionless): with t = d/d̂ each of
/// −2 ln t, 4(1 − t)/t and (1 − t)²/t² is ≥ 0 on (0, d̂), so b'' ≥ 0 (the barrier is convex in d).
/// 0 for d ≥ d̂, +∞ for d ≤ 0 (the limit as d → 0⁺). NaN in, NaN out.
#[inline]
pub fn barrier_second_derivative(d: f64, d_hat: f64) -> f64 {
    if d >= d_hat {
        0.0
    } else if d <= 0.0 {
        f64::INFINITY
    } else {
        let (a, log) = gap_and_log(d, d_hat);
        let ratio = -a / d;
        // Three non-negative terms: no cancellation.
        -2.0 * log + 4.0 * ratio + ratio * ratio
    }
}

/// b(d + δ) − b(d) (m²), without subtracting two rounded barrier values where both ends lie in
/// (0, d̂): with a = d − d̂, L = ln(d/d̂) and λ = ln((d + δ)/d) it is −[(2aδ + δ²)L + (a + δ)²λ],
/// two terms of the same sign, so the result is accurate to a few ulps even when |δ| ≪ d (where
/// the direct difference loses all its digits). λ is ln_1p(δ/d), or ln((d + δ)/d) where the end
/// is below d/2: there d + δ is exact (Sterbenz) and 1 + δ/d would lose its digits as d + δ → 0. If one end is at or beyond d̂ the result is the other
/// end's value with the right sign; 0 if both are. +∞ if d + δ ≤ 0 < d; −∞ if d ≤ 0 < d + δ; NaN
/// if both are ≤ 0 (∞ − ∞) or an input is NaN.
#[inline]
pub fn barrier_change(d: f64, delta: f64, d_hat: f64) -> f64 {
    let end = d + delta;
    if d.is_nan() || end.is_nan() {
        return f64::NAN;
    }
    match (d <= 0.0, end <= 0.0) {
        (true, true) => return f64::NAN,
        (false, true) => return f64::INFINITY,
        (true, false) => return f64::NEG_INFINITY,
        (false, false) => {}
    }
    match (d >= d_hat, end >= d_hat) {
        (true, true) => 0.0,
        (true, false) => barrier(end, d_hat),
        (false, true) => -barrier(d, d_hat),
        (false, false) => {
            let (a, log) = gap_and_log(d, d_hat);
            let step_log = if end < 0.5 * d {
                (end / d).ln()
            } else {
                (delta / d).ln_1p()
            };
            let moved = a + delta;
            -((2.0 * a + delta) * delta * log + moved * moved * step_log)
        }
    }
}

/// The energy (J), gradient (N) and Hessian block (N/m) of one vertex's contact term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexTerms<const D: usize> {
    /// The energy (J).
    pub energy: f64,
    /// Its gradient with respect to the vertex position (N); the force is minus this.
    pub gradient: SVector<f64, D>,
    /// Its Hessian with respect to the vertex position (N/m), exactly symmetric.
    pub hessian: SMatrix<f64, D, D>,
}

/// The barrier term κ b(d(x)) of one vertex and one obstacle, with d̂ (m, > 0) and stiffness κ
/// (N/m): `None` when d(x) ≥ d̂ (no term: energy, gradient and Hessian are all zero). Otherwise
///
/// - energy κ b(d) (J),
/// - gradient κ b'(d) n (N), n = ∇d (the force −κ b' n pushes into the allowed side),
/// - Hessian κ (b'' n nᵀ + b' ∇²d) for [`Definiteness::Exact`]: indefinite at a sphere, where
///   b' < 0 multiplies the positive curvature (I − n nᵀ)/|x − c|; for [`Definiteness::Clamped`]
///   its projection onto the positive semidefinite matrices, κ b'' n nᵀ (exact, because the range
///   of ∇²d is orthogonal to n). On a plane both are κ b'' n nᵀ.
///
/// For d(x) ≤ 0 (an infeasible state) the energy is +∞, so a line search rejects it, and the
/// gradient and Hessian, which do not exist there, are NaN so that any use of them shows. NaN in
/// x gives `Some` with NaN terms. For d below ~1e-154 d̂ the Hessian overflows to +∞.
pub fn vertex_barrier<const D: usize>(
    obstacle: &Obstacle<D>,
    x: &SVector<f64, D>,
    d_hat: f64,
    stiffness: f64,
    definiteness: Definiteness,
) -> Option<VertexTerms<D>> {
    let d = obstacle.distance(x);
    if d >= d_hat {
        return None;
    }
    if d <= 0.0 {
        return Some(VertexTerms {
            energy: f64::INFINITY,
            gradient: SVector::repeat(f64::NAN),
            hessian: SMatrix::repeat(f64::NAN),
        });
    }
    let n = obstacle.normal(x);
    let first = stiffness * barrier_derivative(d, d_hat);
    let second = stiffness * barrier_second_derivative(d, d_hat);
    let mut hessian = SMatrix::zeros();
    for b in 0..D {
        for a in 0..D {
            hessian[(a, b)] = second * (n[a] * n[b]);
        }
    }
    if definiteness == Definiteness::Exact {
        hessian += obstacle.distance_hessian(x) * first;
    }
    Some(VertexTerms {
        energy: stiffness * barrier(d, d_hat),
        gradient: n * first,
        hessian,
    })
}

/// IPC's smoothed friction magnitude f₀(y) (m), with ε = ε_v h > 0 (m; ε_v in m/s is the sliding
/// speed below which friction is smoothed, h the time step) and y ≥ 0 the tangential displacement
/// over the step: −y³/(3ε²) + y²/ε + ε/3 for y < ε, y for y ≥ ε. C² at ε (f₀ = ε, f₁ = 1,
/// f₁' = 0 there), f₀ ≥ ε/3 > 0 on [0, ε). Negative y gets the cubic (outside the domain); NaN in,
/// NaN out.
#[inline]
pub fn friction_f0(y: f64, eps: f64) -> f64 {
    if y >= eps {
        y
    } else {
        let s = y / eps;
        eps * ((s * s) * (1.0 - s / 3.0) + 1.0 / 3.0)
    }
}

/// f₁ = f₀' (dimensionless): 2y/ε − y²/ε² = 1 − (1 − y/ε)² for y < ε, 1 for y ≥ ε. In [0, 1] for
/// y ≥ 0, which is the Coulomb bound of the friction force. NaN in, NaN out.
#[inline]
pub fn friction_f1(y: f64, eps: f64) -> f64 {
    if y >= eps {
        1.0
    } else {
        let s = y / eps;
        s * (2.0 - s)
    }
}

/// f₁(y)/y (1/m), finite at y = 0: (2 − y/ε)/ε below ε, 1/y beyond.
#[inline]
pub(crate) fn friction_f1_over_y(y: f64, eps: f64) -> f64 {
    if y >= eps {
        1.0 / y
    } else {
        (2.0 - y / eps) / eps
    }
}

/// The mean of f₁ over [lo, hi] with 0 ≤ lo ≤ hi ≤ ε: (f₀(hi) − f₀(lo))/(hi − lo) =
/// (hi + lo)/ε − (hi² + hi·lo + lo²)/(3ε²), in [0, 1].
#[inline]
fn friction_mean_slope_below(lo: f64, hi: f64, eps: f64) -> f64 {
    let (l, h) = (lo / eps, hi / eps);
    (h + l) - (h * h + h * l + l * l) / 3.0
}

/// The lagged friction term of one vertex against one obstacle (IPC §5):
/// energy μ λ f₀(|u|) with u = P(x − start), P = I − n nᵀ, where the coefficient μ, the normal
/// force λ, the normal n and `start` are frozen while the solver minimises over x (they are
/// updated between solves, "lagging"). Its gradient is the friction force's negative, bounded by
/// the Coulomb limit μλ; its Hessian is positive semidefinite.
///
/// In IPC, u is the tangential displacement over the time step, so `start` is the vertex's
/// position at the start of the step; [`lagged_friction`] sets it to the lag point, which is the
/// same point when the contact is lagged at the start of the step (the usual single lag). If the
/// contact is lagged again at a later iterate, keep `start` at the start of the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaggedFriction<const D: usize> {
    /// The friction coefficient μ ≥ 0 (dimensionless).
    pub coefficient: f64,
    /// The normal force magnitude λ ≥ 0 (N).
    pub normal_force: f64,
    /// The contact normal n, unit length, frozen.
    pub normal: SVector<f64, D>,
    /// The origin of the tangential displacement (m).
    pub start: SVector<f64, D>,
}

impl<const D: usize> LaggedFriction<D> {
    /// The tangential displacement u = P(x − start) = r − n(n·r) (m).
    #[inline]
    pub fn tangential(&self, x: &SVector<f64, D>) -> SVector<f64, D> {
        self.tangent_part(&(x - self.start))
    }

    #[inline]
    fn tangent_part(&self, r: &SVector<f64, D>) -> SVector<f64, D> {
        r - self.normal * self.normal.dot(r)
    }

    /// The energy μ λ f₀(|u|) (J), gradient μ λ f₁(|u|) u/|u| (N, 0 at u = 0; u = P u already lies
    /// in the tangent plane) and Hessian block (N/m)
    ///
    /// μ λ P [ (f₁'(y) y − f₁(y))/y³ u uᵀ + f₁(y)/y I ] P = μ λ [ f₁'(y) ûûᵀ + f₁(y)/y (P − ûûᵀ) ],
    ///
    /// y = |u|, û = u/y, with ε = ε_v h (m, > 0). Both coefficients are ≥ 0 (f₁' = (2/ε)(1 − y/ε)
    /// below ε, 0 beyond; f₁/y > 0), so the block is positive semidefinite in both regimes; at
    /// u = 0 it is the limit (2/ε) μ λ P. Exactly symmetric.
    pub fn terms(&self, x: &SVector<f64, D>, eps: f64) -> VertexTerms<D> {
        let scale = self.coefficient * self.normal_force;
        let u = self.tangential(x);
        let y = u.norm();
        let across = friction_f1_over_y(y, eps);
        let along = if y >= eps {
            0.0
        } else {
            2.0 / eps * (1.0 - y / eps)
        };
        let unit = if y > 0.0 { u / y } else { SVector::zeros() };
        let n = &self.normal;
        let mut hessian = SMatrix::zeros();
        for b in 0..D {
            for a in 0..D {
                let identity = if a == b { 1.0 } else { 0.0 };
                let projector = identity - n[a] * n[b];
                let radial = unit[a] * unit[b];
                hessian[(a, b)] = scale * (along * radial + across * (projector - radial));
            }
        }
        VertexTerms {
            energy: scale * friction_f0(y, eps),
            gradient: u * (scale * across),
            hessian,
        }
    }

    /// The energy change E(x + δ) − E(x) (J), without subtracting two rounded energies (which
    /// carry the constant μ λ ε/3 and lose small changes): the change of y = |u| is
    /// Pδ·(2u + Pδ)/(|u + Pδ| + |u|), times the mean of f₁ over the interval between the two
    /// values of y, which is computed in closed form (f₀ is a cubic below ε and linear beyond).
    pub fn energy_change(&self, x: &SVector<f64, D>, delta: &SVector<f64, D>, eps: f64) -> f64 {
        let u = self.tangential(x);
        let step = self.tangent_part(delta);
        let (change, slope) = friction_f0_change(&u, &step, eps);
        self.coefficient * self.normal_force * change * slope
    }
}

/// f₀(|u + s|) − f₀(|u|) as (Δy, mean slope) with Δy = s·(2u + s)/(|u + s| + |u|) (m, the change
/// of y = |u| without cancellation) and the mean of f₁ over the interval between the two values
/// of y (dimensionless, in [0, 1], in closed form: f₀ is a cubic below ε and linear beyond); the
/// change is their product. Shared by the obstacles' [`LaggedFriction::energy_change`] (in the
/// tangent plane, K = D) and self-contact's pair friction (in its 2D tangent coordinates).
#[inline]
pub(crate) fn friction_f0_change<const K: usize>(
    u: &SVector<f64, K>,
    step: &SVector<f64, K>,
    eps: f64,
) -> (f64, f64) {
    let moved = u + step;
    let (y0, y1) = (u.norm(), moved.norm());
    let sum = y0 + y1;
    let change = if sum == 0.0 {
        0.0
    } else {
        step.dot(&(u * 2.0 + step)) / sum
    };
    let (lo, hi) = if y0 <= y1 { (y0, y1) } else { (y1, y0) };
    let slope = if lo >= eps {
        1.0
    } else if hi < eps {
        friction_mean_slope_below(lo, hi, eps)
    } else {
        // Split at ε: slope 1 on [ε, hi], the cubic's mean on [lo, ε]; a convex combination,
        // so rounding in the two widths only moves it within [its mean below ε, 1].
        let (above, below) = (hi - eps, eps - lo);
        (above + below * friction_mean_slope_below(lo, eps, eps)) / (above + below)
    };
    (change, slope)
}

/// The lagged friction of one vertex against one obstacle from its state at the lag point
/// `x_lag`: `Some` when 0 < d(x_lag) < d̂, with normal force λ = −κ b'(d) (the magnitude of the
/// barrier's force there, N), n the obstacle's normal there, `start` = x_lag and μ = `mu`.
/// `None` when d(x_lag) ≥ d̂ (no contact), d(x_lag) ≤ 0 (an infeasible lag point, where λ is
/// unbounded) or d(x_lag) is NaN.
pub fn lagged_friction<const D: usize>(
    obstacle: &Obstacle<D>,
    x_lag: &SVector<f64, D>,
    d_hat: f64,
    stiffness: f64,
    mu: f64,
) -> Option<LaggedFriction<D>> {
    let d = obstacle.distance(x_lag);
    if !(d > 0.0 && d < d_hat) {
        return None;
    }
    Some(LaggedFriction {
        coefficient: mu,
        normal_force: -stiffness * barrier_derivative(d, d_hat),
        normal: obstacle.normal(x_lag),
        start: *x_lag,
    })
}
