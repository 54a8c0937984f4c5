//! Self-contact of a triangle surface as a sum of barrier terms: for every point–triangle and
//! edge–edge pair within the reach d̂, IPC's κ b(d) (edge–edge pairs mollified where nearly
//! parallel), with its gradient and Hessian blocks over the vertices (Li et al. 2020,
//! "Incremental Potential Contact", §4).
//!
//! This module owns the sum over a surface: which pairs are candidates at a configuration (the
//! broad phase of `hooke_collision` on boxes grown by a margin, kept while the positions stay
//! inside them), their energy, change, gradient and Hessian blocks (each term from
//! [`crate::surface_barrier`]), and the vertex pairs a Hessian's pattern must hold. It leaves the
//! geometry (distances, broad phase, continuous collision detection) to `hooke_collision`, and
//! the cap on a line search (CCD over [`SelfContactBarrier::pairs_near_move`]) and the choice of
//! κ to the solvers (`hooke_solvers::backward_euler`).
//!
//! **Which pairs.** Pairs that share a vertex, and pairs already within d̂ at rest on the same
//! triangle fan, are excluded
//! (`hooke_collision::broad_phase::SurfaceTopology::exclude_close_at_rest`); so are pairs none of
//! whose vertices is free. Every other point–triangle and edge–edge pair counts on its own, as in
//! IPC's sum: a point near an edge shared by two triangles has a term with each.
//!
//! **Determinism.** The candidates come in the broad phase's order, which does not depend on the
//! thread count; sums are taken by [`crate::deterministic_sum`]; gradients and Hessian blocks are
//! computed in parallel in batches and added serially in pair order. Parallel and serial runs give
//! the same bits.
//!
//! Units: metres; κ in N/m, so that a term κ b (b in m²) is in J.

use hooke_collision::broad_phase::{BroadPhase, CandidatePairs, SurfaceTopology};
use nalgebra::{SMatrix, SVector, Vector3};
use rayon::prelude::*;

use crate::surface_barrier::{
    edge_edge_distance, edge_edge_energy, edge_edge_terms, point_triangle_distance,
    point_triangle_energy, point_triangle_terms, FeatureTerms,
};
use crate::{deterministic_sum, Definiteness};

/// The broad phase looks this many times d̂ around each box, so that its pairs hold every pair
/// within d̂ of any configuration whose vertices stay within d̂/4 of the boxes it was run on
/// (two boxes each moved out by d̂/4 come at most d̂/2 closer).
const REACH_FACTOR: f64 = 1.5;

/// Pairs per batch of the parallel gradient and Hessian: their terms are computed in parallel
/// into a buffer of this many (about 2.5 MB), then added in pair order.
const BATCH: usize = 2048;

/// The surface, reach and stiffness of a self-contact barrier.
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
    /// The Coulomb friction coefficient μ between parts of the surface (dimensionless, finite,
    /// ≥ 0; 0: frictionless, and friction costs nothing). The pairs' lagged friction is
    /// [`crate::self_friction`]'s; the barrier itself ignores it.
    pub friction: f64,
    /// IPC's friction smoothing velocity ε_v (m/s; finite and > 0 where `friction` > 0): below
    /// this relative tangential speed friction acts as a stiff spring towards sticking, above it
    /// as Coulomb's μ λ. The same ε_v as the obstacles' friction.
    pub friction_velocity: f64,
}

/// A candidate pair of a surface, by its four vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SurfacePair {
    /// A point and a triangle: (point, triangle's vertices).
    PointTriangle([u32; 4]),
    /// Two edges, (a0, a1, b0, b1), with the mollifier's threshold ε_x (m⁴) from the rest
    /// positions.
    EdgeEdge([u32; 4], f64),
}

impl SurfacePair {
    /// The pair's four vertices, in the order its distance takes them.
    #[inline]
    pub fn vertices(&self) -> [u32; 4] {
        match self {
            SurfacePair::PointTriangle(v) | SurfacePair::EdgeEdge(v, _) => *v,
        }
    }

    /// The distance (m) between the pair's two closed primitives at the vertex positions `p`.
    #[inline]
    pub fn distance(&self, p: &[Vector3<f64>; 4]) -> f64 {
        match self {
            SurfacePair::PointTriangle(_) => point_triangle_distance(p),
            SurfacePair::EdgeEdge(..) => edge_edge_distance(p),
        }
    }
}

/// The self-contact barrier Σ κ b(d) of a surface over its pairs, a reusable workspace: build it
/// once per surface with [`SelfContactBarrier::new`], then ask for its terms at any positions (one
/// 3-vector per vertex of the mesh). Positions within d̂/4 of those of its last search reuse its
/// candidates; any others search again.
#[derive(Debug)]
pub struct SelfContactBarrier {
    model: SelfContactModel,
    topology: SurfaceTopology,
    broad: BroadPhase,
    found: CandidatePairs,
    /// The candidate pairs with at least one free vertex, in the broad phase's order.
    pairs: Vec<SurfacePair>,
    /// Per vertex, the box (m) the candidates were found for. Empty: none yet.
    cover_low: Vec<Vector3<f64>>,
    cover_high: Vec<Vector3<f64>>,
    /// Per vertex, whether it is free (moved by the solver).
    free: Vec<bool>,
    /// |e|² at rest per edge of the topology (m²), for the mollifier's thresholds.
    edge_rest_squared: Vec<f64>,
    /// Scratch: positions and motions as 3-vectors.
    positions: Vec<Vector3<f64>>,
    motion: Vec<Vector3<f64>>,
    /// The candidates (indices into `pairs`) within d̂ at the positions `active_at`, in pair order;
    /// `active_at` empty: not known.
    active: Vec<u32>,
    active_at: Vec<Vector3<f64>>,
    /// Scratch: each candidate's energy change.
    changes: Vec<f64>,
    /// Scratch: per candidate, whether it is within d̂ at `active_at`.
    within: Vec<bool>,
    /// Scratch: one batch of terms, and of gradients.
    batch: Vec<Option<FeatureTerms<12>>>,
    gradients: Vec<Option<SVector<f64, 12>>>,
    parallel: bool,
}

/// `p` as a 3-vector (self-contact exists only in 3D).
#[inline]
fn v3<const D: usize>(p: &SVector<f64, D>) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

#[inline]
fn gather<const D: usize>(x: &[SVector<f64, D>], v: [u32; 4]) -> [Vector3<f64>; 4] {
    v.map(|i| v3(&x[i as usize]))
}

/// Push the vertex pairs (both free, lower index first) that a pair of primitives over the
/// vertices `v` couples: the off-diagonal blocks its Hessian needs in a pattern.
pub(crate) fn push_pair_links(free: &[bool], v: [u32; 4], links: &mut Vec<[u32; 2]>) {
    for a in 0..4 {
        for b in a + 1..4 {
            let (i, j) = (v[a], v[b]);
            if free[i as usize] && free[j as usize] {
                links.push([i.min(j), i.max(j)]);
            }
        }
    }
}

/// Add `scale` times the 12×12 Hessian of `terms`, a pair of vertices `v`, into `values` of
/// `pattern` (block columns by `column`; fixed vertices left out); `false` if the pattern lacks a
/// block. Shared by the barrier and the friction of the pairs.
pub(crate) fn add_pair_element<const D: usize>(
    pattern: &crate::HessianPattern<D>,
    column: &impl Fn(usize) -> Option<usize>,
    free: &[bool],
    v: [u32; 4],
    terms: &FeatureTerms<12>,
    scale: f64,
    values: &mut [f64],
) -> bool {
    let columns = v.map(|i| {
        if free[i as usize] {
            column(i as usize)
        } else {
            None
        }
    });
    pattern.add_element(&columns, terms.hessian.as_slice(), scale, values)
}

/// Call `add(i, j, block)` with `scale` times every 3×3 block (i, j) of the Hessian of `terms`, a
/// pair of vertices `v`: i, j free, both (i, j) and (j, i). Shared by the barrier and the
/// friction of the pairs.
pub(crate) fn for_each_pair_block<const D: usize>(
    free: &[bool],
    v: [u32; 4],
    terms: &FeatureTerms<12>,
    scale: f64,
    add: &mut impl FnMut(usize, usize, SMatrix<f64, D, D>),
) {
    for (a, &i) in v.iter().enumerate() {
        if !free[i as usize] {
            continue;
        }
        for (b, &j) in v.iter().enumerate() {
            if !free[j as usize] {
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

impl SelfContactBarrier {
    /// The barrier of `model` on a mesh whose vertex `v` is moved by the solver where `free[v]`
    /// (pairs of fixed vertices alone carry no term). The model is taken as given: its triangles
    /// must name vertices below `free.len()`, each three distinct ones, with one rest position
    /// per vertex, d̂ and κ finite and positive (the solvers' `set_self_contact` checks this and
    /// returns typed errors).
    ///
    /// # Panics
    /// If a triangle names a vertex out of range or there are fewer rest positions than vertices.
    pub fn new(model: SelfContactModel, free: Vec<bool>) -> Self {
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
        SelfContactBarrier {
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
            active: Vec::new(),
            active_at: Vec::new(),
            changes: Vec::new(),
            within: Vec::new(),
            batch: Vec::new(),
            gradients: Vec::new(),
            parallel: true,
        }
    }

    /// The model.
    pub fn model(&self) -> &SelfContactModel {
        &self.model
    }

    /// Set the stiffness κ (N/m, finite and positive; the caller checks).
    pub fn set_stiffness(&mut self, stiffness: f64) {
        self.model.stiffness = stiffness;
    }

    /// Whether the vertex `v` is free.
    #[inline]
    pub fn is_free(&self, v: usize) -> bool {
        self.free[v]
    }

    /// Run the loops with rayon (default) or serially: the same bits either way.
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
    }

    /// Whether the loops run with rayon.
    pub fn parallel(&self) -> bool {
        self.parallel
    }

    /// Drop the candidates, so that the next query searches anew (the line-search cap does, so
    /// that its candidates depend on the move alone, never on earlier searches).
    pub fn forget_pairs(&mut self) {
        self.cover_low.clear();
        self.cover_high.clear();
        self.pairs.clear();
        self.active_at.clear();
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
        self.active_at.clear();
        for &[p, t] in &self.found.point_triangle {
            let [a, b, c] = triangles[t as usize];
            let v = [p, a, b, c];
            if any_free(&v) {
                self.pairs.push(SurfacePair::PointTriangle(v));
            }
        }
        for &[ea, eb] in &self.found.edge_edge {
            let [a0, a1] = edges[ea as usize];
            let [b0, b1] = edges[eb as usize];
            let v = [a0, a1, b0, b1];
            if any_free(&v) {
                // hooke_collision::distance::edge_edge_mollifier_threshold, from |e|² at rest.
                let eps = 1e-3
                    * self.edge_rest_squared[ea as usize]
                    * self.edge_rest_squared[eb as usize];
                self.pairs.push(SurfacePair::EdgeEdge(v, eps));
            }
        }
    }

    /// Make the candidates hold every pair within d̂ at `x` (one position per vertex, m), and
    /// return them: a superset of the pairs within d̂.
    pub fn pairs_near<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> &[SurfacePair] {
        if !self.covers(x) {
            self.search(x, None);
        }
        &self.pairs
    }

    /// The candidate pairs whose primitives may come within reach anywhere on the straight move
    /// from `x` to `x + delta` (a superset of the pairs that could meet on the way: the broad
    /// phase over the swept boxes), for the collision detection that caps a line search. The
    /// candidates then serve every configuration on the way.
    pub fn pairs_near_move<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> &[SurfacePair] {
        if !self.covers_move(x, delta) {
            self.search(x, Some(delta));
        }
        &self.pairs
    }

    /// The candidates within d̂ at `x` (indices into the candidates, in pair order), computed once
    /// per configuration: the energy, gradient, Hessian and links at the same `x` (bit for bit)
    /// reuse them, which spares each a distance per candidate.
    fn active<const D: usize>(&mut self, x: &[SVector<f64, D>]) {
        self.pairs_near(x);
        let same = self.active_at.len() == x.len()
            && self
                .active_at
                .iter()
                .zip(x)
                .all(|(a, b)| (0..3).all(|k| a[k].to_bits() == b[k].to_bits()));
        if same {
            return;
        }
        let d_hat = self.model.distance;
        // One flag per candidate, computed in parallel into a kept buffer, then the list in pair
        // order: the serial list, and no allocation once the buffers have grown (rayon's
        // `par_extend` collects into a list of new vectors on every call).
        let mut flags = std::mem::take(&mut self.within);
        flags.clear();
        flags.resize(self.pairs.len(), false);
        let within = |(flag, pair): (&mut bool, &SurfacePair)| {
            *flag = pair.distance(&gather(x, pair.vertices())) < d_hat;
        };
        if self.parallel {
            flags.par_iter_mut().zip(&self.pairs).for_each(within);
        } else {
            flags.iter_mut().zip(&self.pairs).for_each(within);
        }
        let mut active = std::mem::take(&mut self.active);
        active.clear();
        active.extend(
            flags
                .iter()
                .enumerate()
                .filter_map(|(k, &inside)| inside.then_some(k as u32)),
        );
        self.active = active;
        self.within = flags;
        self.active_at.clear();
        self.active_at.extend(x.iter().map(v3));
    }

    /// The barrier energy of `pair` at its vertices' positions `p` (J).
    #[inline]
    fn pair_energy(&self, pair: &SurfacePair, p: &[Vector3<f64>; 4]) -> f64 {
        let (d_hat, kappa) = (self.model.distance, self.model.stiffness);
        match pair {
            SurfacePair::PointTriangle(_) => point_triangle_energy(p, d_hat, kappa),
            SurfacePair::EdgeEdge(_, eps) => edge_edge_energy(p, d_hat, kappa, *eps),
        }
    }

    #[inline]
    fn pair_terms(
        &self,
        pair: &SurfacePair,
        p: &[Vector3<f64>; 4],
        hessian: Option<Definiteness>,
    ) -> Option<FeatureTerms<12>> {
        let (d_hat, kappa) = (self.model.distance, self.model.stiffness);
        match pair {
            SurfacePair::PointTriangle(_) => point_triangle_terms(p, d_hat, kappa, hessian),
            SurfacePair::EdgeEdge(_, eps) => edge_edge_terms(p, d_hat, kappa, *eps, hessian),
        }
    }

    /// The barrier energy Σ κ b(d) at `x` (J; +∞ if two primitives touch), summed in pair order.
    pub fn energy<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        self.active(x);
        let this = &*self;
        deterministic_sum(this.active.len(), this.parallel, |k| {
            let pair = &this.pairs[this.active[k] as usize];
            this.pair_energy(pair, &gather(x, pair.vertices()))
        })
    }

    /// The change of [`SelfContactBarrier::energy`] from `x` to `x + delta` (J), pair by pair
    /// (point–triangle pairs without the cancellation of two rounded energies): +∞ if a pair
    /// touches at the end.
    pub fn energy_change<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        self.pairs_near_move(x, delta);
        let mut changes = std::mem::take(&mut self.changes);
        let this = &*self;
        let d_hat = this.model.distance;
        let change = |pair: &SurfacePair| {
            let v = pair.vertices();
            let start = gather(x, v);
            let end = v.map(|i| v3(&(x[i as usize] + delta[i as usize])));
            let (d0, d1) = (pair.distance(&start), pair.distance(&end));
            if d0 >= d_hat && d1 >= d_hat {
                return 0.0;
            }
            if d1 <= 0.0 {
                return f64::INFINITY;
            }
            match pair {
                SurfacePair::PointTriangle(_) => {
                    this.model.stiffness * crate::barrier::barrier_change(d0, d1 - d0, d_hat)
                }
                SurfacePair::EdgeEdge(..) => {
                    this.pair_energy(pair, &end) - this.pair_energy(pair, &start)
                }
            }
        };
        // Into the kept buffer, in place (rayon's extend would allocate per call).
        changes.resize(this.pairs.len(), 0.0);
        if this.parallel {
            changes
                .par_iter_mut()
                .zip(this.pairs.par_iter())
                .for_each(|(c, pair)| *c = change(pair));
        } else {
            for (c, pair) in changes.iter_mut().zip(&this.pairs) {
                *c = change(pair);
            }
        }
        // The candidates beyond d̂ at both ends (most of them) add exact zeros, and which of them
        // are candidates depends on earlier searches: only the others are summed, in pair order
        // (the candidates are sorted), so the sum's bits depend on the move alone.
        let sum = changes
            .iter()
            .filter(|c| **c != 0.0)
            .fold(-0.0, |sum, c| sum + c);
        self.changes = changes;
        sum
    }

    /// Call `each(free, vertices, terms)` for every pair within d̂ at `x`, in pair order, with its
    /// terms (Hessian with `hessian`'s definiteness if given): computed in parallel in batches.
    fn for_each_term<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        hessian: Option<Definiteness>,
        mut each: impl FnMut(&[bool], [u32; 4], &FeatureTerms<12>),
    ) {
        self.active(x);
        let mut batch = std::mem::take(&mut self.batch);
        let this = &*self;
        for indices in this.active.chunks(BATCH) {
            batch.resize(indices.len(), None);
            let compute = |(slot, &k): (&mut Option<FeatureTerms<12>>, &u32)| {
                let pair = &this.pairs[k as usize];
                *slot = this.pair_terms(pair, &gather(x, pair.vertices()), hessian);
            };
            if this.parallel {
                batch.par_iter_mut().zip(indices).for_each(compute);
            } else {
                batch.iter_mut().zip(indices).for_each(compute);
            }
            for (terms, &k) in batch.iter().zip(indices) {
                if let Some(terms) = terms {
                    each(&this.free, this.pairs[k as usize].vertices(), terms);
                }
            }
        }
        self.batch = batch;
    }

    /// Add `scale` ∇(energy) at `x` into `out`, per vertex (free vertices only), in pair order.
    pub fn add_gradient<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) {
        self.active(x);
        // Only the 12 gradient entries per pair go through the buffer.
        let mut batch = std::mem::take(&mut self.gradients);
        let this = &*self;
        for indices in this.active.chunks(BATCH) {
            batch.resize(indices.len(), None);
            let compute = |(slot, &k): (&mut Option<SVector<f64, 12>>, &u32)| {
                let pair = &this.pairs[k as usize];
                *slot = this
                    .pair_terms(pair, &gather(x, pair.vertices()), None)
                    .map(|t| t.gradient);
            };
            if this.parallel {
                batch.par_iter_mut().zip(indices).for_each(compute);
            } else {
                batch.iter_mut().zip(indices).for_each(compute);
            }
            for (gradient, &k) in batch.iter().zip(indices) {
                let Some(gradient) = gradient else { continue };
                for (v, &i) in this.pairs[k as usize].vertices().iter().enumerate() {
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

    /// Add `scale` times the Hessians of the pairs within d̂ at `x` (exact or projected to
    /// positive semidefinite by `definiteness`, as [`SelfContactBarrier::for_each_hessian_block`])
    /// into `values` of `pattern`, vertex v's block column being `column(v)` (`None` for a vertex
    /// that is not a column, such as a pinned one), in pair order. `false` if the pattern lacks a
    /// block (what it added until then stays).
    pub fn add_hessian_into<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        pattern: &crate::HessianPattern<D>,
        column: impl Fn(usize) -> Option<usize>,
        values: &mut [f64],
    ) -> bool {
        let mut complete = true;
        self.for_each_term(x, Some(definiteness), |free, v, terms| {
            if complete {
                complete = add_pair_element(pattern, &column, free, v, terms, scale, values);
            }
        });
        complete
    }

    /// Call `add(i, j, block)` with `scale` times every block (i, j) of the Hessians of the pairs
    /// within d̂ at `x`, exact or projected to positive semidefinite
    /// ([`crate::surface_barrier`]'s module documentation says how) by `definiteness`: i, j free
    /// vertices, both (i, j) and (j, i), in pair order.
    pub fn for_each_hessian_block<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        mut add: impl FnMut(usize, usize, SMatrix<f64, D, D>),
    ) {
        self.for_each_term(x, Some(definiteness), |free, v, terms| {
            for_each_pair_block(free, v, terms, scale, &mut add);
        });
    }

    /// The vertex pairs (both free, lower index first) that the pairs within d̂ at `x` couple,
    /// appended to `links`: the off-diagonal blocks a Hessian's pattern must hold.
    pub fn links<const D: usize>(&mut self, x: &[SVector<f64, D>], links: &mut Vec<[u32; 2]>) {
        self.active(x);
        for &k in &self.active {
            push_pair_links(&self.free, self.pairs[k as usize].vertices(), links);
        }
    }

    /// The candidate pairs within d̂ at `x` (one position per vertex, m): every pair with a free
    /// vertex whose primitives are closer than d̂, in the candidates' order (which depends on
    /// where the broad phase last searched; sort them where the order must not).
    pub fn pairs_within<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
    ) -> impl Iterator<Item = &SurfacePair> + '_ {
        self.active(x);
        self.active.iter().map(|&k| &self.pairs[k as usize])
    }

    /// The smallest distance (m) between the two primitives of a candidate pair at `x`: exact
    /// whenever a pair is within d̂ (every such pair is a candidate); above d̂ it says only that
    /// none is, as candidates farther apart come and go with the search (∞: no candidate).
    pub fn smallest_distance<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        self.pairs_near(x);
        let this = &*self;
        let distance = |pair: &SurfacePair| pair.distance(&gather(x, pair.vertices()));
        // The minimum does not depend on the order: parallel gives the serial bits.
        if this.parallel {
            this.pairs
                .par_iter()
                .map(distance)
                .reduce(|| f64::INFINITY, f64::min)
        } else {
            this.pairs
                .iter()
                .map(distance)
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// The smallest distance (m) between the two primitives of a pair within d̂ at `x` (∞: none):
    /// unlike [`SelfContactBarrier::smallest_distance`] it never depends on which candidates an
    /// earlier search found.
    pub fn smallest_active_distance<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        self.active(x);
        let this = &*self;
        let distance = |&k: &u32| {
            let pair = &this.pairs[k as usize];
            pair.distance(&gather(x, pair.vertices()))
        };
        // The minimum does not depend on the order: parallel gives the serial bits.
        if this.parallel {
            this.active
                .par_iter()
                .map(distance)
                .reduce(|| f64::INFINITY, f64::min)
        } else {
            this.active
                .iter()
                .map(distance)
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// The numbers of point–triangle and edge–edge pairs within d̂ at `x`.
    pub fn active_counts<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> (usize, usize) {
        self.active(x);
        let point_triangle = self
            .active
            .iter()
            .filter(|&&k| matches!(self.pairs[k as usize], SurfacePair::PointTriangle(_)))
            .count();
        (point_triangle, self.active.len() - point_triangle)
    }
}
