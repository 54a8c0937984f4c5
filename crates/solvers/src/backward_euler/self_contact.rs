//! Self-contact inside backward Euler's objective: h² times the self-contact barrier of
//! `hooke_assembly::self_contact` (the sum of IPC's κ b(d) over the surface's point–triangle and
//! edge–edge pairs within d̂), and the cap that keeps a line search from passing any pair through
//! another.
//!
//! With a friction coefficient μ > 0 it also holds the pairs' lagged friction
//! (`hooke_assembly::self_friction`), lagged at each step's start x_n, and adds h² times its
//! potential to the barrier's terms: energy, change, gradient, Hessian blocks (positive
//! semidefinite) and the pattern's links (the pairs lagged at x_n stay coupled for the whole step,
//! also where they leave d̂). With μ = 0 there is no friction state and nothing to pay.
//!
//! This module owns the cap: the longest safe share of a step, by additive continuous collision
//! detection (`hooke_collision::ccd`) on every pair whose swept boxes come within reach. The terms
//! themselves (energy, gradient, Hessian blocks, the pattern's links) are the barrier's and the
//! friction's; obstacles are in the sibling module `obstacles`.

pub use hooke_assembly::self_contact::SelfContactModel;
use hooke_assembly::self_contact::{SelfContactBarrier, SurfacePair};
use hooke_assembly::self_friction::SelfContactFriction;
use hooke_assembly::{Definiteness, HessianPattern};
use hooke_collision::ccd::{edge_edge_ccd, point_triangle_ccd, CcdParams};
use nalgebra::{SVector, Vector3};
use rayon::prelude::*;

/// What self-contact does at one configuration
/// ([`super::BackwardEulerStep::self_contact_state`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfContactState {
    /// The barrier energy Σ κ b(d) over the pairs within d̂ (J), without the h² of Φ.
    pub energy: f64,
    /// The smallest distance between the primitives of a candidate pair of the broad phase (m):
    /// exact whenever a pair is within d̂ (every such pair is a candidate); above d̂ it says only
    /// that none is, as candidates farther apart come and go with the search (∞: no candidate).
    pub smallest_distance: f64,
    /// The point–triangle pairs within d̂.
    pub point_triangle_pairs: usize,
    /// The edge–edge pairs within d̂.
    pub edge_edge_pairs: usize,
    /// The barrier's stiffness κ (N/m).
    pub stiffness: f64,
}

/// The self-contact terms of a backward Euler step and its line-search cap.
#[derive(Debug)]
pub(crate) struct StepSelfContact {
    pub(crate) barrier: SelfContactBarrier,
    /// The pairs' lagged friction; `None` when μ = 0 (no cost).
    friction: Option<SelfContactFriction>,
    ccd: CcdParams,
    /// The model's κ (N/m), before the adaptive scale.
    base_stiffness: f64,
}

impl StepSelfContact {
    /// The terms for `model` over `free.len()` vertices, `free[v]` telling which move.
    pub(crate) fn new(model: SelfContactModel, free: Vec<bool>) -> Self {
        let friction = (model.friction > 0.0).then(|| {
            SelfContactFriction::new(model.friction, model.friction_velocity, free.clone())
        });
        StepSelfContact {
            base_stiffness: model.stiffness,
            barrier: SelfContactBarrier::new(model, free),
            friction,
            ccd: CcdParams::default(),
        }
    }

    /// Multiply the model's κ by `scale` (the adaptive stiffness's s ≥ 1).
    pub(crate) fn set_stiffness_scale(&mut self, scale: f64) {
        self.barrier.set_stiffness(self.base_stiffness * scale);
    }

    /// Multiply the lagged friction's normal forces by `scale` (lagged at the model's κ, they
    /// then carry the adaptive scale of the step's start); nothing without friction.
    pub(crate) fn scale_friction(&mut self, scale: f64) {
        if let Some(friction) = &mut self.friction {
            friction.scale_normal_forces(scale);
        }
    }

    /// Run the barrier's and the friction's loops in parallel or serially (the same bits).
    pub(crate) fn set_parallel(&mut self, parallel: bool) {
        self.barrier.set_parallel(parallel);
        if let Some(friction) = &mut self.friction {
            friction.set_parallel(parallel);
        }
    }

    /// Lag the friction at the step's start `start` for a step of `h` (s); nothing without
    /// friction.
    pub(crate) fn lag_friction<const D: usize>(&mut self, start: &[SVector<f64, D>], h: f64) {
        if let Some(friction) = &mut self.friction {
            friction.lag(&mut self.barrier, start, h);
        }
    }

    /// The barrier energy and the friction potential at `x` (J).
    pub(crate) fn energy<const D: usize>(&mut self, x: &[SVector<f64, D>]) -> f64 {
        let barrier = self.barrier.energy(x);
        match &self.friction {
            Some(friction) => barrier + friction.energy(x),
            None => barrier,
        }
    }

    /// The change of [`StepSelfContact::energy`] from `x` to `x + delta` (J).
    pub(crate) fn energy_change<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        let barrier = self.barrier.energy_change(x, delta);
        match &self.friction {
            Some(friction) => barrier + friction.energy_change(x, delta),
            None => barrier,
        }
    }

    /// Add `scale` times the gradient of [`StepSelfContact::energy`] at `x` into `out` (free
    /// vertices only).
    pub(crate) fn add_gradient<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        out: &mut [SVector<f64, D>],
    ) {
        self.barrier.add_gradient(x, scale, out);
        if let Some(friction) = &mut self.friction {
            friction.add_gradient(x, scale, out);
        }
    }

    /// Add `scale` times the Hessians at `x` (the barrier's with `definiteness`, the friction's,
    /// which is positive semidefinite) into `values` of `pattern`; `false` if the pattern lacks a
    /// block.
    pub(crate) fn add_hessian_into<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        scale: f64,
        definiteness: Definiteness,
        pattern: &HessianPattern<D>,
        column: impl Fn(usize) -> Option<usize>,
        values: &mut [f64],
    ) -> bool {
        let mut complete =
            self.barrier
                .add_hessian_into(x, scale, definiteness, pattern, &column, values);
        if let Some(friction) = &mut self.friction {
            complete &= friction.add_hessian_into(x, scale, pattern, &column, values);
        }
        complete
    }

    /// The vertex pairs the Hessian's pattern must hold at `x`: the barrier's pairs within d̂
    /// there and every pair whose friction is lagged for this step.
    pub(crate) fn links<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        links: &mut Vec<[u32; 2]>,
    ) {
        self.barrier.links(x, links);
        if let Some(friction) = &self.friction {
            friction.links(links);
        }
    }

    /// [`collision_free_step`] of the barrier's pairs along `delta` from `x`.
    pub(crate) fn max_step<const D: usize>(
        &mut self,
        x: &[SVector<f64, D>],
        delta: &[SVector<f64, D>],
    ) -> f64 {
        collision_free_step(&mut self.barrier, x, delta, &self.ccd)
    }
}

/// The longest share α ≤ 1 of the straight move `delta` from `x` (one vector per vertex, m) over
/// which no pair of `barrier`'s surface passes through another: the smallest safe time of
/// additive CCD (`hooke_collision::ccd`, with `ccd`'s settings) over the pairs whose swept boxes
/// come within 1.5 d̂ of each other. Each pair keeps at least [`CcdParams::kept_share`] of its gap
/// (a tenth by default, the obstacles' safety fraction); 0 if two primitives already touch. The
/// result is conservative: it may stop short of the first contact, never past it. The same bits
/// in parallel and serially (a minimum does not depend on the order).
pub fn collision_free_step<const D: usize>(
    barrier: &mut SelfContactBarrier,
    x: &[SVector<f64, D>],
    delta: &[SVector<f64, D>],
    ccd: &CcdParams,
) -> f64 {
    let parallel = barrier.parallel();
    // A fresh search over the boxes swept by this move: candidates kept from an earlier search
    // could add pairs whose conservative CCD stops shorter, and the step would then depend on how
    // the run got here (a resumed run must take the same steps).
    barrier.forget_pairs();
    let pairs = barrier.pairs_near_move(x, delta);
    let v3 = |p: &SVector<f64, D>| Vector3::new(p[0], p[1], p[2]);
    let time = |pair: &SurfacePair| {
        let v = pair.vertices();
        if v.iter()
            .all(|&i| delta[i as usize].iter().all(|&c| c == 0.0))
        {
            return 1.0;
        }
        let p = v.map(|i| v3(&x[i as usize]));
        let d = v.map(|i| v3(&delta[i as usize]));
        let xs = [&p[0], &p[1], &p[2], &p[3]];
        let ds = [&d[0], &d[1], &d[2], &d[3]];
        match pair {
            SurfacePair::PointTriangle(_) => point_triangle_ccd(xs, ds, 1.0, 0.0, ccd).time,
            SurfacePair::EdgeEdge(..) => edge_edge_ccd(xs, ds, 1.0, 0.0, ccd).time,
        }
    };
    if parallel {
        pairs.par_iter().map(time).reduce(|| 1.0, f64::min)
    } else {
        pairs.iter().map(time).fold(1.0, f64::min)
    }
}
