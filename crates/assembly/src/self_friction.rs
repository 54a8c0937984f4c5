//! Lagged Coulomb friction between the parts of a triangle surface: IPC's smooth friction (Li et
//! al. 2020, "Incremental Potential Contact", §5) on the self-contact pairs of
//! [`crate::self_contact`], as [`crate::barrier::LaggedFriction`] is on a vertex against an
//! obstacle.
//!
//! **The lag.** At the start of a step, every pair within d̂ at the start positions x_n gets,
//! frozen for the step ([`lag_pair_friction`], [`PairFriction`]):
//!
//! - its normal force λ = −κ b'(d) (N; times the mollifier m(c) for an edge–edge pair, as the
//!   barrier's force has it), the magnitude of the barrier's force on the pair at x_n;
//! - the barycentric weights w of its closest points at x_n (point–triangle: 1 on the point and
//!   −β₀, −β₁, −β₂ on the triangle's vertices; edge–edge: 1 − a, a on the first edge,
//!   −(1 − b), −b on the second), so that Σ wᵢ xᵢ is the vector between the closest points;
//! - an orthonormal basis T = [t₀, t₁] (3×2) of the plane orthogonal to the contact normal n (the
//!   direction between the closest points at x_n; where they are closer than 1e-6 d̂, so that
//!   their difference is mostly rounding, the triangle's normal or the edges' cross product, and
//!   for nearly parallel edges the part of the edges' offset across them).
//!
//! **The potential.** The pair's relative tangential displacement over the step is
//! u = Tᵀ Σ wᵢ (xᵢ − xᵢⁿ) ∈ R² (m), and its dissipation potential D = μ λ f₀(|u|) (J), with IPC's
//! f₀ ([`crate::barrier::friction_f0`]) smoothed below ε = ε_v h (m). The friction force on the
//! pair, −∇_u D, has magnitude μ λ f₁(|u|) ≤ μ λ (Coulomb's bound). Since w, T and λ are fixed, u
//! is linear in x and D is convex in x: its Hessian wwᵀ ⊗ T H_u Tᵀ, with H_u the 2×2 Hessian of
//! μ λ f₀(|u|), is positive semidefinite as it stands (no projection).
//!
//! [`SelfContactFriction`] sums the potentials of a surface's lagged pairs: energy, change,
//! gradient, Hessian blocks and the vertex pairs a Hessian's pattern must hold. Its pairs are
//! sorted (point–triangle before edge–edge, then by vertices), so that neither the order in which
//! the broad phase found them nor the thread count changes a bit; the per-pair terms are computed
//! in parallel in batches and added serially in pair order; no buffer is allocated after the
//! first step of a given size.
//!
//! Units: metres, seconds; λ in N, so that μ λ f₀ (f₀ in m) is in J.

use hooke_collision::distance::{
    edge_edge_case, edge_edge_cross_squared, mollifier, point_triangle_case, EdgeEdgeCase,
    PointTriangleCase,
};
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};
use rayon::prelude::*;

use crate::barrier::{barrier_derivative, friction_f0, friction_f0_change, friction_f1_over_y};
use crate::deterministic_sum;
use crate::self_contact::{
    add_pair_element, for_each_pair_block, push_pair_links, SelfContactBarrier, SurfacePair,
};
use crate::surface_barrier::{edge_edge_distance, point_triangle_distance, FeatureTerms};

/// A position (m).
type Vec3 = Vector3<f64>;

/// Where the closest points of a pair are closer than this share of d̂, the contact normal is
/// taken from the primitives' shape instead of from their difference (which rounding dominates
/// there: a difference of 1e-6 d̂ ≈ 1e-9 m between coordinates of order 1 m is exact to ~1e-7).
const NORMAL_FROM_SHAPE_SHARE: f64 = 1e-6;

/// Edges are taken as parallel, for the fallback normal, where |ea × eb|² ≤ this · |ea|²|eb|²
/// (sin²θ; the distance module's classification threshold).
const PARALLEL_SHARE: f64 = 1e-16;

/// Pairs per batch of the parallel gradient and Hessian (about 1.2 MB of terms).
const BATCH: usize = 1024;

/// The lagged friction of one self-contact pair, frozen at the step's start (see the module
/// documentation): D(x) = μ λ f₀(|Tᵀ Σ wᵢ (xᵢ − xᵢⁿ)|).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairFriction {
    /// Whether the pair is point–triangle (`false`: edge–edge); orders the pairs.
    pub point_triangle: bool,
    /// The pair's four vertices, in [`SurfacePair::vertices`]'s order.
    pub vertices: [u32; 4],
    /// The closest points' weights (dimensionless, summing to 0): Σ wᵢ xᵢ is the vector from the
    /// second primitive's closest point to the first's at the lag point.
    pub weights: [f64; 4],
    /// The contact normal n at the lag point (unit length).
    pub normal: Vec3,
    /// T: two unit vectors orthogonal to each other and to `normal`, spanning the tangent plane.
    pub tangents: [Vec3; 2],
    /// The normal force λ (N, > 0).
    pub normal_force: f64,
    /// The friction coefficient μ (dimensionless, ≥ 0).
    pub coefficient: f64,
}

/// `p` as a 3-vector (self-contact exists only in 3D).
#[inline]
fn v3<const D: usize>(p: &SVector<f64, D>) -> Vec3 {
    Vec3::new(p[0], p[1], p[2])
}

/// The parameter in [0, 1] of the point of the segment (e0, e1) closest to p (0 for a
/// zero-length segment).
#[inline]
fn segment_parameter(p: &Vec3, e0: &Vec3, e1: &Vec3) -> f64 {
    let e = e1 - e0;
    let length2 = e.norm_squared();
    if length2 > 0.0 {
        ((p - e0).dot(&e) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// A unit vector orthogonal to the unit vector `n`: the coordinate axis least aligned with it,
/// with its part along n removed (well conditioned: that axis makes at least 54.7° with n).
#[inline]
fn orthogonal_unit(n: &Vec3) -> Vec3 {
    let k = if n[0].abs() <= n[1].abs() && n[0].abs() <= n[2].abs() {
        0
    } else if n[1].abs() <= n[2].abs() {
        1
    } else {
        2
    };
    let mut axis = Vec3::zeros();
    axis[k] = 1.0;
    (axis - n * n[k]).normalize()
}

/// `v` normalised if its squared length exceeds `floor`, else `None`.
#[inline]
fn unit_above(v: &Vec3, floor: f64) -> Option<Vec3> {
    let n2 = v.norm_squared();
    (n2 > floor && n2.is_finite()).then(|| v / n2.sqrt())
}

/// The closest points' weights of a point–triangle pair `p` = (p, t0, t1, t2): [1, −β₀, −β₁, −β₂]
/// with β the barycentric coordinates of the triangle's point closest to p.
fn point_triangle_weights(p: &[Vec3; 4]) -> [f64; 4] {
    let [x, t0, t1, t2] = p;
    let t = [t0, t1, t2];
    let mut beta = [0.0; 3];
    match point_triangle_case(x, t0, t1, t2) {
        PointTriangleCase::Vertex(k) => beta[k as usize] = 1.0,
        PointTriangleCase::Edge(k) => {
            let (a, b) = (k as usize, (k as usize + 1) % 3);
            let s = segment_parameter(x, t[a], t[b]);
            beta[a] = 1.0 - s;
            beta[b] = s;
        }
        PointTriangleCase::Face => {
            // The projection t0 + β₁ u + β₂ v: (w × v)·n = β₁ |n|², (u × w)·n = β₂ |n|².
            let (u, v, w) = (t1 - t0, t2 - t0, x - t0);
            let n = u.cross(&v);
            let n2 = n.norm_squared();
            beta[1] = w.cross(&v).dot(&n) / n2;
            beta[2] = u.cross(&w).dot(&n) / n2;
            beta[0] = 1.0 - beta[1] - beta[2];
        }
    }
    [1.0, -beta[0], -beta[1], -beta[2]]
}

/// The closest points' weights of an edge–edge pair `p` = (ea0, ea1, eb0, eb1):
/// [1 − a, a, −(1 − b), −b] with a, b the closest points' parameters along the edges.
fn edge_edge_weights(p: &[Vec3; 4]) -> [f64; 4] {
    use EdgeEdgeCase::*;
    let [a0, a1, b0, b1] = p;
    let (a, b) = match edge_edge_case(a0, a1, b0, b1) {
        Ea0Eb0 => (0.0, 0.0),
        Ea0Eb1 => (0.0, 1.0),
        Ea1Eb0 => (1.0, 0.0),
        Ea1Eb1 => (1.0, 1.0),
        Ea0Eb => (0.0, segment_parameter(a0, b0, b1)),
        Ea1Eb => (1.0, segment_parameter(a1, b0, b1)),
        EaEb0 => (segment_parameter(b0, a0, a1), 0.0),
        EaEb1 => (segment_parameter(b1, a0, a1), 1.0),
        LineLine => {
            // a0 + a u − b0 − b v ⟂ u, v: with n = u × v and r = b0 − a0,
            // (r × v)·n = a |n|² and (r × u)·n = b |n|² (the classification's formulas).
            let (u, v, r) = (a1 - a0, b1 - b0, b0 - a0);
            let n = u.cross(&v);
            let n2 = n.norm_squared();
            (
                (r.cross(&v).dot(&n) / n2).clamp(0.0, 1.0),
                (r.cross(&u).dot(&n) / n2).clamp(0.0, 1.0),
            )
        }
    };
    [1.0 - a, a, -(1.0 - b), -b]
}

/// The contact normal where the closest points nearly coincide: for a point–triangle pair the
/// triangle's normal (its nearest edge's normal towards the point if it is degenerate); for an
/// edge–edge pair ea × eb, or for parallel edges the part of the offset between their midpoints
/// across edge a; any vector orthogonal to edge a where even that vanishes.
fn normal_from_shape(point_triangle: bool, p: &[Vec3; 4]) -> Vec3 {
    if point_triangle {
        let (u, v) = (p[2] - p[1], p[3] - p[1]);
        let floor = PARALLEL_SHARE * u.norm_squared() * v.norm_squared();
        if let Some(n) = unit_above(&u.cross(&v), floor) {
            return n;
        }
        let e = unit_above(&u, 0.0)
            .or_else(|| unit_above(&v, 0.0))
            .unwrap_or(Vec3::x());
        return orthogonal_unit(&e);
    }
    let (ea, eb) = (p[1] - p[0], p[3] - p[2]);
    let floor = PARALLEL_SHARE * ea.norm_squared() * eb.norm_squared();
    if let Some(n) = unit_above(&ea.cross(&eb), floor) {
        return n;
    }
    let Some(along) = unit_above(&ea, 0.0).or_else(|| unit_above(&eb, 0.0)) else {
        return Vec3::x();
    };
    let offset = (p[2] + p[3] - p[0] - p[1]) * 0.5;
    let across = offset - along * along.dot(&offset);
    let floor = (f64::EPSILON * offset.norm()).powi(2);
    unit_above(&across, floor).unwrap_or_else(|| orthogonal_unit(&along))
}

/// The lagged friction of the self-contact `pair` at its vertices' lag positions `p` (m), with
/// reach `d_hat` (m, > 0), barrier stiffness `kappa` (N/m) and friction coefficient `mu` (≥ 0):
/// `Some` when 0 < d < d̂ and the normal force λ = −κ b'(d) (times the mollifier m(c) for an
/// edge–edge pair) is positive; `None` otherwise (out of reach, touching, NaN, or an edge–edge
/// pair exactly parallel, whose mollified force vanishes). See the module documentation for the
/// weights, the normal and the tangent basis.
pub fn lag_pair_friction(
    pair: &SurfacePair,
    p: &[Vec3; 4],
    d_hat: f64,
    kappa: f64,
    mu: f64,
) -> Option<PairFriction> {
    let (point_triangle, d, force, weights) = match pair {
        SurfacePair::PointTriangle(_) => {
            let d = point_triangle_distance(p);
            (true, d, 1.0, point_triangle_weights(p))
        }
        SurfacePair::EdgeEdge(_, eps_x) => {
            let d = edge_edge_distance(p);
            let c = edge_edge_cross_squared(&p[0], &p[1], &p[2], &p[3]);
            let m = if c < *eps_x {
                mollifier(c, *eps_x)
            } else {
                1.0
            };
            (false, d, m, edge_edge_weights(p))
        }
    };
    if !(d > 0.0 && d < d_hat) {
        return None;
    }
    let normal_force = -kappa * force * barrier_derivative(d, d_hat);
    if !(normal_force > 0.0 && normal_force.is_finite()) {
        return None;
    }
    let gap = p[0] * weights[0] + p[1] * weights[1] + p[2] * weights[2] + p[3] * weights[3];
    let floor = (NORMAL_FROM_SHAPE_SHARE * d_hat).powi(2);
    let normal = unit_above(&gap, floor).unwrap_or_else(|| normal_from_shape(point_triangle, p));
    let t0 = orthogonal_unit(&normal);
    let t1 = normal.cross(&t0);
    Some(PairFriction {
        point_triangle,
        vertices: pair.vertices(),
        weights,
        normal,
        tangents: [t0, t1],
        normal_force,
        coefficient: mu,
    })
}

impl PairFriction {
    /// Σ wᵢ vᵢ of per-vertex vectors `v` (m).
    #[inline]
    fn weighted(&self, v: &[Vec3; 4]) -> Vec3 {
        let w = &self.weights;
        v[0] * w[0] + v[1] * w[1] + v[2] * w[2] + v[3] * w[3]
    }

    /// Tᵀ r (m).
    #[inline]
    fn project(&self, r: &Vec3) -> Vector2<f64> {
        Vector2::new(self.tangents[0].dot(r), self.tangents[1].dot(r))
    }

    /// The relative tangential displacement u = Tᵀ Σ wᵢ (xᵢ − xᵢⁿ) ∈ R² (m) of the pair's
    /// vertices at `x` from their lag positions `start`.
    #[inline]
    pub fn tangential(&self, x: &[Vec3; 4], start: &[Vec3; 4]) -> Vector2<f64> {
        let moved = [
            x[0] - start[0],
            x[1] - start[1],
            x[2] - start[2],
            x[3] - start[3],
        ];
        self.project(&self.weighted(&moved))
    }

    /// The potential D = μ λ f₀(|u|) (J), with ε = ε_v h (m, > 0).
    #[inline]
    pub fn energy(&self, x: &[Vec3; 4], start: &[Vec3; 4], eps: f64) -> f64 {
        let y = self.tangential(x, start).norm();
        self.coefficient * self.normal_force * friction_f0(y, eps)
    }

    /// The friction force on the pair in its tangent coordinates, −∇_u D = −μ λ f₁(|u|) u/|u|
    /// (N, zero at u = 0): its magnitude is at most μ λ (Coulomb's bound). Vertex i feels
    /// wᵢ T times it.
    #[inline]
    pub fn force(&self, x: &[Vec3; 4], start: &[Vec3; 4], eps: f64) -> Vector2<f64> {
        let u = self.tangential(x, start);
        -u * (self.coefficient * self.normal_force * friction_f1_over_y(u.norm(), eps))
    }

    /// The energy D (J), its gradient over the 12 coordinates of the pair's vertices in
    /// [`PairFriction::vertices`]' order (N; vertex i's block wᵢ T μ λ f₁(y) u/y, y = |u|) and,
    /// with `hessian`, its Hessian (N/m; zero without): block (i, j) = wᵢ wⱼ T H_u Tᵀ with
    ///
    /// H_u = μ λ [ f₁'(y) ûûᵀ + f₁(y)/y (I − ûûᵀ) ], û = u/y,
    ///
    /// the construction of [`crate::barrier::LaggedFriction::terms`] in the 2D tangent
    /// coordinates. It is the exact Hessian (u is linear in x), and positive semidefinite without
    /// any projection: f₁' = (2/ε)(1 − y/ε) ≥ 0 below ε and 0 beyond, f₁/y > 0, and
    /// wwᵀ ⊗ T H_u Tᵀ is a Kronecker product of two positive semidefinite matrices. At u = 0 it
    /// is the limit, H_u = (2/ε) μ λ I. Exactly symmetric.
    pub fn terms(
        &self,
        x: &[Vec3; 4],
        start: &[Vec3; 4],
        eps: f64,
        hessian: bool,
    ) -> FeatureTerms<12> {
        let scale = self.coefficient * self.normal_force;
        let u = self.tangential(x, start);
        let y = u.norm();
        let across = friction_f1_over_y(y, eps);
        let [t0, t1] = &self.tangents;
        // T ∇_u D, a 3-vector in the tangent plane.
        let g_u = u * (scale * across);
        let g = t0 * g_u[0] + t1 * g_u[1];
        let mut gradient = SVector::<f64, 12>::zeros();
        for (i, w) in self.weights.iter().enumerate() {
            gradient.fixed_rows_mut::<3>(3 * i).copy_from(&(g * *w));
        }
        let mut full = SMatrix::<f64, 12, 12>::zeros();
        if hessian {
            let along = if y >= eps {
                0.0
            } else {
                2.0 / eps * (1.0 - y / eps)
            };
            let unit = if y > 0.0 { u / y } else { Vector2::zeros() };
            let radial = unit * unit.transpose();
            let h_u = (radial * along + (Matrix2::identity() - radial) * across) * scale;
            let t = nalgebra::Matrix3x2::from_columns(&[*t0, *t1]);
            let block: Matrix3<f64> = t * h_u * t.transpose();
            // Exactly symmetric, so that every block pair (i, j), (j, i) is too.
            let block = (block + block.transpose()) * 0.5;
            for (j, wj) in self.weights.iter().enumerate() {
                for (i, wi) in self.weights.iter().enumerate() {
                    // wᵢwⱼ = wⱼwᵢ exactly: (i, j) and (j, i) are transposes bit for bit.
                    full.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                        .copy_from(&(block * (wi * wj)));
                }
            }
        }
        FeatureTerms {
            energy: scale * friction_f0(y, eps),
            gradient,
            hessian: full,
        }
    }

    /// The change D(x + δ) − D(x) (J) for vertex moves `delta` (m), without subtracting two
    /// rounded energies (which carry the constant μ λ ε/3 and lose small changes): the change of
    /// |u| times the mean of f₁ over it, in closed form, as
    /// [`crate::barrier::LaggedFriction::energy_change`].
    pub fn energy_change(
        &self,
        x: &[Vec3; 4],
        start: &[Vec3; 4],
        delta: &[Vec3; 4],
        eps: f64,
    ) -> f64 {
        let u = self.tangential(x, start);
        let step = self.project(&self.weighted(delta));
        let (change, slope) = friction_f0_change(&u, &step, eps);
        self.coefficient * self.normal_force * change * slope
    }
}

/// The lagged friction of a surface's self-contact pairs summed: a reusable workspace that
/// [`SelfContactFriction::lag`] fills at the start of every step from the pairs of a
/// [`SelfContactBarrier`] within d̂ there, and whose potential, change, gradient and Hessian the
/// solver adds to its objective during the step. Empty (no terms, no cost) until lagged, and
/// after a lag where no pair is within d̂.
#[derive(Debug)]
pub struct SelfContactFriction {
    coefficient: f64,
    friction_velocity: f64,
    /// ε = ε_v h of the last lag (m).
    eps: f64,
    pairs: Vec<PairFriction>,
    /// The lag positions x_n, one per vertex (m).
    start: Vec<Vec3>,
    free: Vec<bool>,
    /// Scratch: one batch of terms, and of gradients.
    batch: Vec<FeatureTerms<12>>,
    gradients: Vec<SVector<f64, 12>>,
    parallel: bool,
}

#[inline]
fn gather<const D: usize>(x: &[SVector<f64, D>], v: [u32; 4]) -> [Vec3; 4] {
    v.map(|i| v3(&x[i as usize]))
}

impl SelfContactFriction {
    /// The friction with coefficient μ = `coefficient` (dimensionless, ≥ 0) and smoothing velocity
    /// ε_v = `friction_velocity` (m/s, > 0) over a mesh whose vertex v is moved by the solver
    /// where `free[v]` (the gradient and Hessian skip the others). The caller checks the values.
    pub fn new(coefficient: f64, friction_velocity: f64, free: Vec<bool>) -> Self {
        SelfContactFriction {
            coefficient,
            friction_velocity,
            eps: friction_velocity,
            pairs: Vec::new(),
            start: Vec::new(),
            free,
            batch: Vec::new(),
            gradients: Vec::new(),
            parallel: true,
        }
    }

    /// Run the loops with rayon (default) or serially: the same bits either way.
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
    }

    /// The friction coefficient μ.
    pub fn coefficient(&self) -> f64 {
        self.coefficient
    }

    /// ε = ε_v h (m) of the last lag.
    pub fn smoothing_length(&self) -> f64 {
        self.eps
    }

    /// The lagged pairs, sorted (point–triangle before edge–edge, then by vertices).
    pub fn pairs(&self) -> &[PairFriction] {
        &self.pairs
    }

    /// The lag positions x_n (m, one per vertex; empty before the first lag).
    pub fn start(&self) -> &[Vec3] {
        &self.start
    }

    /// Lag the friction at the step's start `start` (one position per vertex, m) for a step of
    /// `h` (s): every pair of `barrier` within d̂ there gets its normal force, weights and tangent
    /// basis ([`lag_pair_friction`], with the barrier's d̂ and κ), and ε becomes ε_v h. The pairs
    /// are sorted, so the result depends on `start` alone, not on where the barrier last searched.
    /// With μ = 0 nothing is lagged.
    pub fn lag<const D: usize>(
        &mut self,
        barrier: &mut SelfContactBarrier,
        start: &[SVector<f64, D>],
        h: f64,
    ) {
        self.pairs.clear();
        self.eps = self.friction_velocity * h;
        if self.coefficient <= 0.0 {
            return;
        }
        self.start.clear();
        self.start.extend(start.iter().map(v3));
        let (d_hat, kappa) = (barrier.model().distance, barrier.model().stiffness);
        let mu = self.coefficient;
        for pair in barrier.pairs_within(start) {
            if let Some(lagged) =
                lag_pair_friction(pair, &gather(start, pair.vertices()), d_hat, kappa, mu)
            {
                self.pairs.push(lagged);
            }
        }
        self.pairs
            .sort_unstable_by_key(|p| (!p.point_triangle, p.vertices));
    }

    /// Multiply every lagged pair's normal force λ by `scale` (dimensionless, finite, > 0): for a
    /// barrier whose stiffness is scaled after the lag (an adaptive stiffness set at the step's
    /// first iterate), so that the friction carries the step's κ as the obstacles' does.
    pub fn scale_normal_forces(&mut self, scale: f64) {
        for pair in &mut self.pairs {
            pair.normal_force *= scale;
        }
    }

    /// Drop the lagged pairs: no terms until the next lag.
    pub fn clear(&mut self) {
        self.pairs.clear();
    }

    /// The lag positions of pair `pair`'s vertices.
    #[inline]
    fn pair_start(&self, pair: &PairFriction) -> [Vec3; 4] {
        pair.vertices.map(|i| self.start[i as usize])
    }

    /// The friction potential Σ D at `x` (J), summed in pair order.
    pub fn energy<const D: usize>(&self, x: &[SVector<f64, D>]) -> f64 {
        deterministic_sum(self.pairs.len(), self.parallel, |k| {
            let pair = &self.pairs[k];
            pair.energy(&gather(x, pair.vertices), &self.pair_start(pair), self.eps)
        })
    }

    /// The change of [`SelfContactFriction::energy`] from `x` to `x + delta` (J), pair by pair
    /// without the cancellation of two rounded energies.
    pub fn energy_change<const D: usize>(
        &self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        deterministic_sum(self.pairs.len(), self.parallel, |k| {
            let pair = &self.pairs[k];
            pair.energy_change(
                &gather(x, pair.vertices),
                &self.pair_start(pair),
                &gather(delta, pair.vertices),
                self.eps,
            )
        })
    }

    /// Add `scale` ∇(energy) at `x` into `out`, per vertex (free vertices only), in pair order.
    pub fn add_gradient<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) {
        let mut batch = std::mem::take(&mut self.gradients);
        let this = &*self;
        for pairs in this.pairs.chunks(BATCH) {
            batch.resize(pairs.len(), SVector::zeros());
            let compute = |(slot, pair): (&mut SVector<f64, 12>, &PairFriction)| {
                *slot = pair
                    .terms(
                        &gather(x, pair.vertices),
                        &this.pair_start(pair),
                        this.eps,
                        false,
                    )
                    .gradient;
            };
            if this.parallel {
                batch.par_iter_mut().zip(pairs).for_each(compute);
            } else {
                batch.iter_mut().zip(pairs).for_each(compute);
            }
            for (gradient, pair) in batch.iter().zip(pairs) {
                for (v, &i) in pair.vertices.iter().enumerate() {
                    if this.free[i as usize] {
                        let target = &mut out[i as usize];
                        for (a, g) in gradient.fixed_rows::<3>(3 * v).iter().enumerate() {
                            target[a] += scale * g;
                        }
                    }
                }
            }
        }
        self.gradients = batch;
    }

    /// Call `each(free, vertices, terms)` for every lagged pair, in pair order, with its terms and
    /// Hessian: computed in parallel in batches.
    fn for_each_term<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        mut each: impl FnMut(&[bool], [u32; 4], &FeatureTerms<12>),
    ) {
        let mut batch = std::mem::take(&mut self.batch);
        let this = &*self;
        for pairs in this.pairs.chunks(BATCH) {
            batch.resize(
                pairs.len(),
                FeatureTerms {
                    energy: 0.0,
                    gradient: SVector::zeros(),
                    hessian: SMatrix::zeros(),
                },
            );
            let compute = |(slot, pair): (&mut FeatureTerms<12>, &PairFriction)| {
                *slot = pair.terms(
                    &gather(x, pair.vertices),
                    &this.pair_start(pair),
                    this.eps,
                    true,
                );
            };
            if this.parallel {
                batch.par_iter_mut().zip(pairs).for_each(compute);
            } else {
                batch.iter_mut().zip(pairs).for_each(compute);
            }
            for (terms, pair) in batch.iter().zip(pairs) {
                each(&this.free, pair.vertices, terms);
            }
        }
        self.batch = batch;
    }

    /// Add `scale` times the pairs' Hessians (positive semidefinite, see [`PairFriction::terms`])
    /// at `x` into `values` of `pattern`, vertex v's block column being `column(v)` (`None` for a
    /// vertex that is not a column, such as a pinned one), in pair order. `false` if the pattern
    /// lacks a block (what it added until then stays); [`SelfContactFriction::links`] names the
    /// blocks it needs.
    pub fn add_hessian_into<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        pattern: &crate::HessianPattern<D>,
        column: impl Fn(usize) -> Option<usize>,
        values: &mut [f64],
    ) -> bool {
        let mut complete = true;
        self.for_each_term(x, |free, v, terms| {
            if complete {
                complete = add_pair_element(pattern, &column, free, v, terms, scale, values);
            }
        });
        complete
    }

    /// Call `add(i, j, block)` with `scale` times every block (i, j) of the pairs' Hessians at
    /// `x`: i, j free vertices, both (i, j) and (j, i), in pair order.
    pub fn for_each_hessian_block<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        mut add: impl FnMut(usize, usize, SMatrix<f64, D, D>),
    ) {
        self.for_each_term(x, |free, v, terms| {
            for_each_pair_block(free, v, terms, scale, &mut add);
        });
    }

    /// The vertex pairs (both free, lower index first) that the lagged pairs couple, appended to
    /// `links`: the off-diagonal blocks a Hessian's pattern must hold for the whole step, also
    /// where a pair has left d̂ (its friction stays until the next lag).
    pub fn links(&self, links: &mut Vec<[u32; 2]>) {
        for pair in &self.pairs {
            push_pair_links(&self.free, pair.vertices, links);
        }
    }
}
