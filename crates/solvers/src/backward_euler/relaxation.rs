//! The nonlinear relaxation of a backward Euler step ([`crate::Relaxation`]): Gauss–Seidel sweeps of
//! per-vertex Newton steps, focused sweeps over the hottest vertices, and the nonlinear elimination
//! over the patches of [`super::patches`].

use hooke_assembly::{spring, Definiteness};
use nalgebra::{SMatrix, SVector};

use super::{spring_energy_change_from, BackwardEulerStep};
use crate::{NewtonProblem, Relaxation, RelaxationWork};

/// Armijo constant and step halvings of a vertex's line search in [`crate::NewtonProblem::relax`].
const RELAX_ARMIJO: f64 = 1e-4;
const RELAX_HALVINGS: usize = 20;

impl<const D: usize> BackwardEulerStep<D> {
    /// Build the elimination's patches for `relaxation` (see [`Relaxation::region_share`]) unless
    /// they are built for its settings already, or there is no elimination.
    pub(super) fn prepare_patches(&mut self, relaxation: Relaxation) {
        if relaxation.region_blocks(self.free.free_count()) == 0 {
            return;
        }
        if self
            .patches
            .as_ref()
            .is_some_and(|cover| cover.is_for(&relaxation))
        {
            return;
        }
        self.patches = None;
        let cover = self.build_cover(&relaxation);
        self.patches = Some(Box::new(cover));
    }

    /// Gauss–Seidel over the free vertices in index order: each vertex takes up to
    /// `block_iterations` Newton steps on Φ as a function of its own position (the others fixed),
    /// with its clamped 3×3 Hessian (positive definite: the mass is in it) and a backtracking line
    /// search on the exact change of Φ, so Φ never rises. Then the focused sweeps (see
    /// [`Relaxation`]): the vertices with the largest ‖∂Φ/∂x_v‖ (ties to the lower index) and their
    /// rings of spring neighbours, swept in index order. Then the nonlinear elimination over the
    /// patches (see [`Relaxation::region_share`]). Serial, hence deterministic. The pinned
    /// vertices, and with counter-forces the pinned unknowns, stay where they are.
    pub(super) fn relax_all(
        &mut self,
        xf: &mut [f64],
        relaxation: Relaxation,
    ) -> Option<RelaxationWork> {
        self.expand(xf);
        let mut work = RelaxationWork::default();
        let free_count = self.free.free_count();
        for _ in 0..relaxation.sweeps {
            for f in 0..free_count {
                let v = self.free.free_vertices()[f] as usize;
                self.relax_block(v, relaxation.block_iterations);
            }
            work.sweeps += 1;
            work.block_visits += free_count;
        }
        let focused = relaxation.focused_blocks(free_count);
        if focused > 0 && relaxation.block_iterations > 0 {
            self.relax_focused(focused, relaxation, &mut work);
        }
        let region = relaxation.region_blocks(free_count);
        if region > 0 {
            self.relax_region(region, relaxation, &mut work);
        }
        let full = self.counter.is_some();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let o = Self::offset(full, f, v as usize);
            xf[o..o + D].copy_from_slice(self.x[v as usize].as_slice());
        }
        Some(work)
    }

    /// Up to `iterations` line-searched Newton steps of free vertex `v` (see
    /// [`NewtonProblem::relax`]), stopping once it no longer moves.
    pub(super) fn relax_block(&mut self, v: usize, iterations: usize) {
        for _ in 0..iterations {
            if !self.relax_vertex(v) {
                break;
            }
        }
    }

    /// Select the `count` free vertices with the largest ‖∂Φ/∂x_v‖ (ties to the lower index) and
    /// `rings` rings of their free spring neighbours into `focus_region` (sorted), and return the
    /// squared gradient norm of the hottest vertex left out (0 if none is).
    pub(super) fn select_hottest(&mut self, count: usize, rings: usize) -> f64 {
        let mut heat = std::mem::take(&mut self.focus_heat);
        let mut region = std::mem::take(&mut self.focus_region);
        heat.clear();
        for &v in self.free.free_vertices() {
            let (gradient, _) = self.vertex_model::<false>(v as usize, &mut []);
            heat.push((gradient.norm_squared(), v));
        }
        // Hottest first, ties to the lower index: a total order, so the selection is deterministic.
        let hotter = |a: &(f64, u32), b: &(f64, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
        let threshold = if count < heat.len() {
            heat.select_nth_unstable_by(count, hotter);
            heat[count].0
        } else {
            0.0
        };
        region.clear();
        for &(_, v) in &heat[..count] {
            self.focus_mark[v as usize] = true;
            region.push(v);
        }
        self.grow_rings(&mut region, rings);
        region.sort_unstable();
        for &v in &region {
            self.focus_mark[v as usize] = false;
        }
        self.focus_heat = heat;
        self.focus_region = region;
        threshold
    }

    /// The focused sweeps of [`NewtonProblem::relax`] over the `count` hottest free vertices and
    /// their rings, added to `work`.
    pub(super) fn relax_focused(
        &mut self,
        count: usize,
        relaxation: Relaxation,
        work: &mut RelaxationWork,
    ) {
        // The sweeps stop once no selected vertex is hotter than the hottest one left out.
        let threshold = self.select_hottest(count, relaxation.focus_rings);
        let region = std::mem::take(&mut self.focus_region);
        for _ in 0..relaxation.focus_sweeps {
            for &v in &region {
                self.relax_block(v as usize, relaxation.block_iterations);
            }
            work.focused_sweeps += 1;
            work.block_visits += region.len();
            let hottest = region.iter().fold(0.0, |hottest: f64, &v| {
                hottest.max(
                    self.vertex_model::<false>(v as usize, &mut [])
                        .0
                        .norm_squared(),
                )
            });
            if hottest <= threshold {
                break;
            }
        }
        self.focus_region = region;
    }

    /// The nonlinear elimination of [`Relaxation::region_share`] over the patches (see the
    /// `patches` module), added to `work`. It is skipped (and counted as such) where the `count`
    /// hottest blocks carry less than [`Relaxation::region_concentration`] of ‖∇Φ‖²: the error
    /// is spread out, not in a fold. Builds the patches if
    /// [`NewtonProblem::prepare_relaxation`] has not (the one case in which it allocates).
    pub(super) fn relax_region(
        &mut self,
        count: usize,
        relaxation: Relaxation,
        work: &mut RelaxationWork,
    ) {
        self.select_hottest(count, 0);
        // The hottest blocks come first in `focus_heat`.
        let total: f64 = self.focus_heat.iter().map(|&(heat, _)| heat).sum();
        let hottest: f64 = self.focus_heat[..count].iter().map(|&(heat, _)| heat).sum();
        if hottest < relaxation.region_concentration * total || total.is_nan() {
            work.skipped_regions += 1;
            return;
        }
        self.prepare_relaxation(relaxation);
        let Some(mut cover) = self.patches.take() else {
            return;
        };
        self.eliminate(&mut cover, count, hottest, relaxation, work);
        self.patches = Some(cover);
    }

    /// ∂Φ/∂x_v and, if `BLOCK`, v's diagonal 3×3 block of the clamped Hessian of Φ (else zero) and
    /// the length of each incident spring in `lengths` (in `incident` order; untouched otherwise):
    /// Φ as a function of x_v alone, the other vertices fixed.
    #[inline]
    pub(super) fn vertex_model<const BLOCK: bool>(
        &self,
        v: usize,
        lengths: &mut [f64],
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>) {
        let h2 = self.h * self.h;
        let p = self.x[v];
        let mass = self.masses[v];
        let incident = &self.incident[self.incident_start[v]..self.incident_start[v + 1]];
        let mut gradient = (p - self.y[v]) * mass;
        let mut hessian = SMatrix::<f64, D, D>::zeros();
        if BLOCK {
            hessian += SMatrix::<f64, D, D>::identity() * mass;
        }
        for (k, &(s, other)) in incident.iter().enumerate() {
            let spring = &self.springs[s as usize];
            let r = p - self.x[other as usize];
            if BLOCK {
                // One square root per spring for the force, the block and the line search's
                // energy change (the same bits as three separate calls).
                let (force, block, length) = spring::force_and_hessian_block(
                    spring.stiffness,
                    spring.rest_length,
                    &r,
                    Definiteness::Clamped,
                );
                gradient -= force * h2;
                hessian += block * h2;
                lengths[k] = length;
            } else {
                gradient -= spring::force(spring.stiffness, spring.rest_length, &r) * h2;
            }
        }
        let dashpot = self.h * self.dashpot;
        if dashpot > 0.0 {
            // Ψ's terms at v: (h c / 2) a², a = (Δx_v − Δx_o)·d.
            for &(s, other) in incident {
                let d = self.dashpot_directions[s as usize];
                let a = self.dashpot_relative(v, other as usize, &p).dot(&d);
                gradient += d * (dashpot * a);
                if BLOCK {
                    hessian += d * d.transpose() * dashpot;
                }
            }
        }
        (gradient, hessian)
    }

    /// One line-searched Newton step of free vertex `v` on Φ with every other vertex fixed (see
    /// [`NewtonProblem::relax`]); false if it did not move.
    pub(super) fn relax_vertex(&mut self, v: usize) -> bool {
        let mut lengths = std::mem::take(&mut self.incident_lengths);
        let moved = self.relax_vertex_with(v, &mut lengths);
        self.incident_lengths = lengths;
        moved
    }

    /// [`BackwardEulerStep::relax_vertex`] with a buffer for the incident springs' lengths.
    pub(super) fn relax_vertex_with(&mut self, v: usize, lengths: &mut [f64]) -> bool {
        let p = self.x[v];
        let (gradient, hessian) = self.vertex_model::<true>(v, lengths);
        let Some(cholesky) = hessian.cholesky() else {
            return false;
        };
        let step = -cholesky.solve(&gradient);
        let slope = gradient.dot(&step);
        if slope.is_nan() || slope >= 0.0 {
            return false;
        }
        let mut alpha = 1.0;
        for _ in 0..RELAX_HALVINGS {
            let q = p + step * alpha;
            let delta = q - p;
            let change = self.vertex_change(v, &p, lengths, &delta);
            if change.is_finite() && change <= RELAX_ARMIJO * alpha * slope {
                self.x[v] = q;
                return delta != SVector::<f64, D>::zeros();
            }
            alpha *= 0.5;
        }
        false
    }

    /// Δx_v − Δx_o (displacements from the dashpot's start) with v at `p`.
    pub(super) fn dashpot_relative(
        &self,
        v: usize,
        other: usize,
        p: &SVector<f64, D>,
    ) -> SVector<f64, D> {
        (p - self.dashpot_start[v]) - (self.x[other] - self.dashpot_start[other])
    }

    /// Φ(v at p + δ) − Φ(v at p), the others fixed, term by term as in
    /// [`NewtonProblem::objective_change`]; `lengths` are the incident springs' lengths at p.
    pub(super) fn vertex_change(
        &self,
        v: usize,
        p: &SVector<f64, D>,
        lengths: &[f64],
        delta: &SVector<f64, D>,
    ) -> f64 {
        let incident = &self.incident[self.incident_start[v]..self.incident_start[v + 1]];
        let inertia = 0.5 * self.masses[v] * delta.dot(&((p - self.y[v]) * 2.0 + delta));
        let mut energy = 0.0;
        for (&(s, other), &length) in incident.iter().zip(lengths) {
            let spring = &self.springs[s as usize];
            energy += spring_energy_change_from(
                spring.stiffness,
                spring.rest_length,
                &(p - self.x[other as usize]),
                length,
                delta,
            );
        }
        let mut dashpot = 0.0;
        if self.dashpot > 0.0 {
            for &(s, other) in incident {
                let d = self.dashpot_directions[s as usize];
                let a = self.dashpot_relative(v, other as usize, p).dot(&d);
                let da = delta.dot(&d);
                dashpot += da * (2.0 * a + da);
            }
        }
        inertia + self.h * self.h * energy + 0.5 * self.h * self.dashpot * dashpot
    }
}
