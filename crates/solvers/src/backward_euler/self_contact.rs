//! Self-contact inside backward Euler's objective: for every point–triangle and edge–edge pair of
//! the surface within the reach d̂, h² times IPC's barrier κ b(d) (edge–edge pairs mollified),
//! and the cap that keeps a line search from passing any pair through another.
//!
//! This module owns the sum over the surface: which pairs are active at a configuration (the broad
//! phase of `hooke_collision` on boxes grown by a margin, kept while the iterates stay inside
//! them), their energy, change, gradient and Hessian blocks (from
//! `hooke_assembly::surface_barrier`), the vertex pairs the Hessian's pattern must hold, and the
//! longest safe step along a direction (additive CCD of `hooke_collision::ccd` on every pair whose
//! swept boxes meet). Obstacles are in the sibling module `contact`.

use hooke_assembly::surface_barrier::{
    edge_edge_distance, edge_edge_energy, edge_edge_terms, point_triangle_distance,
    point_triangle_energy, point_triangle_terms, FeatureTerms,
};
use hooke_assembly::{deterministic_sum, Definiteness};
use hooke_collision::broad_phase::{BroadPhase, CandidatePairs, SurfaceTopology};
use hooke_collision::ccd::{edge_edge_ccd, point_triangle_ccd, CcdParams};
use hooke_collision::distance::edge_edge_mollifier_threshold;
use nalgebra::{SMatrix, SVector, Vector3};
use rayon::prelude::*;

/// The broad phase looks this many times d̂ around each box, so that its pairs hold every pair
/// within d̂ of any configuration whose vertices stay within d̂/4 of the boxes it was run on
/// (two boxes each moved out by d̂/4 come at most d̂/2 closer).
const REACH_FACTOR: f64 = 1.5;

/// Self-contact of a triangle surface, for [`super::BackwardEulerStep::set_self_contact`].
#[derive(Clone, Debug, PartialEq)]
pub struct SelfContactModel {
    /// The surface's triangles (vertex indices): a cloth's triangles, or a solid's boundary faces.
    pub triangles: Vec<[u32; 3]>,
    /// The rest positions of every vertex (m): they decide the pairs excluded because they are
    /// already within d̂ at rest on the same triangle fan, and the mollifier's thresholds.
    pub rest_positions: Vec<Vector3<f64>>,
    /// The barrier's reach d̂ (m, > 0): a pair farther apart than d̂ feels nothing.
    pub distance: f64,
    /// The barrier's stiffness κ (N/m, > 0): a pair's energy is κ b(d), b in m².
    pub stiffness: f64,
}

/// What self-contact does at one configuration
/// ([`super::BackwardEulerStep::self_contact_state`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfContactState {
    /// The barrier energy Σ κ b(d) over the pairs within d̂ (J), without the h² of Φ.
    pub energy: f64,
    /// The smallest distance between the primitives of a pair (m), among the pairs within 1.5 d̂
    /// (∞ if there is none).
    pub smallest_distance: f64,
    /// The point–triangle pairs within d̂.
    pub point_triangle_pairs: usize,
    /// The edge–edge pairs within d̂.
    pub edge_edge_pairs: usize,
    /// The barrier's stiffness κ (N/m).
    pub stiffness: f64,
}

/// A pair of the candidate list with its kind.
#[derive(Clone, Copy, Debug)]
enum Pair {
    /// (point, triangle's vertices).
    PointTriangle([u32; 4]),
    /// (edge a's vertices, edge b's vertices) and the mollifier's threshold ε_x (m⁴).
    EdgeEdge([u32; 4], f64),
}

impl Pair {
    #[inline]
    fn vertices(&self) -> [u32; 4] {
        match self {
            Pair::PointTriangle(v) | Pair::EdgeEdge(v, _) => *v,
        }
    }
}

/// The self-contact terms of a backward Euler step.
#[derive(Debug)]
pub(crate) struct StepSelfContact {
    pub(crate) model: SelfContactModel,
    topology: SurfaceTopology,
    broad: BroadPhase,
    found: CandidatePairs,
    /// The candidate pairs with at least one free vertex, in the broad phase's order.
    pairs: Vec<Pair>,
    /// Per vertex, the box (m) the candidates were found for: they hold every pair within d̂ of
    /// any configuration whose vertices stay within d̂/4 of their boxes. Empty: none yet.
    cover_low: Vec<Vector3<f64>>,
    cover_high: Vec<Vector3<f64>>,
    /// Per vertex, whether it is free (moved by the solver).
    free: Vec<bool>,
    /// |e|² at rest per edge of the topology (m²), for the mollifier's thresholds.
    edge_rest_squared: Vec<f64>,
    /// Scratch: positions and motions as 3-vectors.
    positions: Vec<Vector3<f64>>,
    motion: Vec<Vector3<f64>>,
    /// The parallel loops' switch (the same bits either way).
    pub(crate) parallel: bool,
    ccd: CcdParams,
}

/// `p` as a 3-vector (self-contact exists only in 3D; see `set_self_contact`).
#[inline]
fn v3<const D: usize>(p: &SVector<f64, D>) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

impl StepSelfContact {
    /// The terms for `model` over `vertex_count` vertices, `free[v]` telling which move.
    pub(crate) fn new(model: SelfContactModel, free: Vec<bool>) -> Self {
        let n = free.len();
        let mut topology = SurfaceTopology::new(n, &model.triangles);
        topology.exclude_close_at_rest(&model.rest_positions, model.distance);
        let edge_rest_squared = topology
            .edges()
            .iter()
            .map(|&[a, b]| {
                (model.rest_positions[a as usize] - model.rest_positions[b as usize]).norm_squared()
            })
            .collect();
        StepSelfContact {
            model,
            topology,
            broad: BroadPhase::new(),
            found: CandidatePairs::new(),
            pairs: Vec::new(),
            cover_low: Vec::new(),
            cover_high: Vec::new(),
            free,
            edge_rest_squared,
            positions: vec![Vector3::zeros(); n],
            motion: vec![Vector3::zeros(); n],
            parallel: true,
            ccd: CcdParams::default(),
        }
    }

    /// Whether every vertex of `x` lies within d̂/4 of its box.
    fn covers<const D: usize>(&self, x: &[SVector<f64, D>]) -> bool {
        if self.cover_low.len() != x.len() {
            return false;
        }
        let slack = 0.25 * self.model.distance;
        x.iter()
            .zip(self.cover_low.iter().zip(&self.cover_high))
            .all(|(p, (lo, hi))| (0..3).all(|a| p[a] >= lo[a] - slack && p[a] <= hi[a] + slack))
    }

    /// Whether the boxes cover both `x` and `x + delta` (and so the segment between).
    fn covers_move<const D: usize>(
        &self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> bool {
        if !self.covers(x) {
            return false;
        }
        let slack = 0.25 * self.model.distance;
        x.iter()
            .zip(delta)
            .zip(self.cover_low.iter().zip(&self.cover_high))
            .all(|((p, d), (lo, hi))| {
                (0..3).all(|a| {
                    let end = p[a] + d[a];
                    end >= lo[a] - slack && end <= hi[a] + slack
                })
            })
    }

    /// Search the pairs near `x`, or near its move by `delta` if given.
    fn search<const D: usize>(&mut self, x: &[SVector<f64, D>], delta: Option<&[SVector<f64, D>]>) {
        for (p, q) in self.positions.iter_mut().zip(x) {
            *p = v3(q);
        }
        if let Some(delta) = delta {
            for (m, d) in self.motion.iter_mut().zip(delta) {
                *m = v3(d);
            }
        }
        let reach = REACH_FACTOR * self.model.distance;
        self.broad.find(
            &self.topology,
            &self.positions,
            delta.map(|_| &self.motion[..]),
            reach,
            &mut self.found,
        );
        self.cover_low.clear();
        self.cover_high.clear();
        for (v, p) in self.positions.iter().enumerate() {
            let end = if delta.is_some() {
                p + self.motion[v]
            } else {
                *p
            };
            self.cover_low.push(p.inf(&end));
            self.cover_high.push(p.sup(&end));
        }
        let triangles = self.topology.triangles();
        let edges = self.topology.edges();
        let free = &self.free;
        let any_free = |v: &[u32; 4]| v.iter().any(|&i| free[i as usize]);
        self.pairs.clear();
        for &[p, t] in &self.found.point_triangle {
            let [a, b, c] = triangles[t as usize];
            let v = [p, a, b, c];
            if any_free(&v) {
                self.pairs.push(Pair::PointTriangle(v));
            }
        }
        for &[ea, eb] in &self.found.edge_edge {
            let [a0, a1] = edges[ea as usize];
            let [b0, b1] = edges[eb as usize];
            let v = [a0, a1, b0, b1];
            if any_free(&v) {
                let eps = 1e-3
                    * self.edge_rest_squared[ea as usize]
                    * self.edge_rest_squared[eb as usize];
                debug_assert_eq!(
                    eps,
                    edge_edge_mollifier_threshold(
                        &self.model.rest_positions[a0 as usize],
                        &self.model.rest_positions[a1 as usize],
                        &self.model.rest_positions[b0 as usize],
                        &self.model.rest_positions[b1 as usize],
                    )
                );
                self.pairs.push(Pair::EdgeEdge(v, eps));
            }
        }
    }

    /// Make the candidates hold every pair within d̂ at `x`.
    pub(crate) fn ensure<const D: usize>(&mut self, x: &[SVector<f64, D>]) {
        if !self.covers(x) {
            self.search(x, None);
        }
    }

    #[inline]
    fn gather<const D: usize>(x: &[SVector<f64, D>], v: [u32; 4]) -> [Vector3<f64>; 4] {
        v.map(|i| v3(&x[i as usize]))
    }

    #[inline]
    fn pair_energy(&self, pair: &Pair, p: &[Vector3<f64>; 4]) -> f64 {
        let (d_hat, kappa) = (self.model.distance, self.model.stiffness);
        match pair {
            Pair::PointTriangle(_) => point_triangle_energy(p, d_hat, kappa),
            Pair::EdgeEdge(_, eps) => edge_edge_energy(p, d_hat, kappa, *eps),
        }
    }

    #[inline]
    fn pair_terms(
        &self,
        pair: &Pair,
        p: &[Vector3<f64>; 4],
        hessian: Option<Definiteness>,
    ) -> Option<FeatureTerms<12>> {
        let (d_hat, kappa) = (self.model.distance, self.model.stiffness);
        match pair {
            Pair::PointTriangle(_) => point_triangle_terms(p, d_hat, kappa, hessian),
            Pair::EdgeEdge(_, eps) => edge_edge_terms(p, d_hat, kappa, *eps, hessian),
        }
    }

    #[inline]
    fn pair_distance(pair: &Pair, p: &[Vector3<f64>; 4]) -> f64 {
        match pair {
            Pair::PointTriangle(_) => point_triangle_distance(p),
            Pair::EdgeEdge(..) => edge_edge_distance(p),
        }
    }

    /// The barrier energy at `x` (J; +∞ if two primitives touch), summed in pair order.
    pub(crate) fn energy<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        self.ensure(x);
        let this = &*self;
        deterministic_sum(this.pairs.len(), this.parallel, |k| {
            let pair = &this.pairs[k];
            this.pair_energy(pair, &Self::gather(x, pair.vertices()))
        })
    }

    /// The change of [`StepSelfContact::energy`] from `x` to `x + delta` (J), pair by pair.
    pub(crate) fn energy_change<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        if !self.covers_move(x, delta) {
            self.search(x, Some(delta));
        }
        let this = &*self;
        let d_hat = this.model.distance;
        deterministic_sum(this.pairs.len(), this.parallel, |k| {
            let pair = &this.pairs[k];
            let v = pair.vertices();
            let start = Self::gather(x, v);
            let end = v.map(|i| v3(&(x[i as usize] + delta[i as usize])));
            let (d0, d1) = (
                Self::pair_distance(pair, &start),
                Self::pair_distance(pair, &end),
            );
            if d0 >= d_hat && d1 >= d_hat {
                return 0.0;
            }
            if d1 <= 0.0 {
                return f64::INFINITY;
            }
            match pair {
                Pair::PointTriangle(_) => {
                    this.model.stiffness
                        * hooke_assembly::contact::barrier_change(d0, d1 - d0, d_hat)
                }
                Pair::EdgeEdge(..) => this.pair_energy(pair, &end) - this.pair_energy(pair, &start),
            }
        })
    }

    /// Add `scale` ∇(energy) at `x` into `out`, per vertex (free vertices only).
    pub(crate) fn add_gradient<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) {
        self.ensure(x);
        for pair in &self.pairs {
            let v = pair.vertices();
            if let Some(terms) = self.pair_terms(pair, &Self::gather(x, v), None) {
                for (k, &i) in v.iter().enumerate() {
                    if self.free[i as usize] {
                        let target = &mut out[i as usize];
                        for (a, g) in terms.gradient.fixed_rows::<3>(3 * k).iter().enumerate() {
                            target[a] += scale * g;
                        }
                    }
                }
            }
        }
    }

    /// The vertex pairs (both free, lower index first) that the active pairs at `x` couple, into
    /// `links` (appended).
    pub(crate) fn links<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        links: &mut Vec<[u32; 2]>,
    ) {
        self.ensure(x);
        let d_hat = self.model.distance;
        for pair in &self.pairs {
            let v = pair.vertices();
            if Self::pair_distance(pair, &Self::gather(x, v)) >= d_hat {
                continue;
            }
            for a in 0..4 {
                for b in a + 1..4 {
                    let (i, j) = (v[a], v[b]);
                    if self.free[i as usize] && self.free[j as usize] {
                        links.push([i.min(j), i.max(j)]);
                    }
                }
            }
        }
    }

    /// Call `add(i, j, block)` with `scale` times every block (i, j) of the active pairs'
    /// Hessians at `x` with `definiteness` (exact, or projected to positive semidefinite; i, j free
    /// vertices; both (i, j) and (j, i), in pair order).
    pub(crate) fn for_each_hessian_block<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        mut add: impl FnMut(usize, usize, SMatrix<f64, D, D>),
    ) {
        self.ensure(x);
        for pair in &self.pairs {
            let v = pair.vertices();
            let Some(terms) = self.pair_terms(pair, &Self::gather(x, v), Some(definiteness)) else {
                continue;
            };
            for (a, &i) in v.iter().enumerate() {
                if !self.free[i as usize] {
                    continue;
                }
                for (b, &j) in v.iter().enumerate() {
                    if !self.free[j as usize] {
                        continue;
                    }
                    let mut block = SMatrix::<f64, D, D>::zeros();
                    for c in 0..3 {
                        for r in 0..3 {
                            block[(r, c)] = scale * terms.hessian[(3 * a + r, 3 * b + c)];
                        }
                    }
                    add(i as usize, j as usize, block);
                }
            }
        }
    }

    /// The longest share α ≤ 1 of the move `delta` from `x` over which no pair passes through
    /// another: the smallest safe time of additive CCD over the pairs whose swept boxes come
    /// within 1.5 d̂ (each pair keeps at least a tenth of its gap, the obstacles' safety
    /// fraction). 0 if two primitives already touch.
    pub(crate) fn max_step<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        self.search(x, Some(delta));
        let this = &*self;
        let time = |pair: &Pair| {
            let v = pair.vertices();
            if v.iter()
                .all(|&i| delta[i as usize].iter().all(|&c| c == 0.0))
            {
                return 1.0;
            }
            let p = Self::gather(x, v);
            let d = v.map(|i| v3(&delta[i as usize]));
            let xs = [&p[0], &p[1], &p[2], &p[3]];
            let ds = [&d[0], &d[1], &d[2], &d[3]];
            match pair {
                Pair::PointTriangle(_) => point_triangle_ccd(xs, ds, 1.0, 0.0, &this.ccd).time,
                Pair::EdgeEdge(..) => edge_edge_ccd(xs, ds, 1.0, 0.0, &this.ccd).time,
            }
        };
        // The minimum is the same whatever the order: parallel gives the serial bits.
        if this.parallel {
            this.pairs.par_iter().map(time).reduce(|| 1.0, f64::min)
        } else {
            this.pairs.iter().map(time).fold(1.0, f64::min)
        }
    }

    /// The smallest distance (m) between two primitives of a candidate pair at `x` (∞ if none
    /// is within 1.5 d̂).
    pub(crate) fn smallest_distance<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        self.ensure(x);
        self.pairs
            .iter()
            .map(|pair| Self::pair_distance(pair, &Self::gather(x, pair.vertices())))
            .fold(f64::INFINITY, f64::min)
    }

    /// The number of point–triangle and edge–edge pairs within d̂ at `x`.
    pub(crate) fn active_counts<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
    ) -> (usize, usize) {
        self.ensure(x);
        let d_hat = self.model.distance;
        let mut counts = (0, 0);
        for pair in &self.pairs {
            if Self::pair_distance(pair, &Self::gather(x, pair.vertices())) < d_hat {
                match pair {
                    Pair::PointTriangle(_) => counts.0 += 1,
                    Pair::EdgeEdge(..) => counts.1 += 1,
                }
            }
        }
        counts
    }
}
