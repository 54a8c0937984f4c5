//! Backward Euler's objective Φ, its change, gradient and Hessians: the [`NewtonProblem`] side of
//! [`BackwardEulerStep`].

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use hooke_assembly::{Definiteness, HessianParams};
use nalgebra::SVector;

use super::{spring_energy_change, BackwardEulerStep, HessianAssembly};
use crate::{NewtonProblem, Relaxation, RelaxationWork};

impl<const D: usize> NewtonProblem for BackwardEulerStep<D> {
    fn dim(&self) -> usize {
        if self.counter.is_some() {
            D * self.free.vertex_count()
        } else {
            D * self.free.free_count()
        }
    }

    fn objective(&mut self, xf: &[f64]) -> f64 {
        self.expand(xf);
        let inertia: f64 = self
            .free
            .free_vertices()
            .iter()
            .map(|&v| {
                let v = v as usize;
                0.5 * self.masses[v] * (self.x[v] - self.y[v]).norm_squared()
            })
            .sum();
        let mut contact = match &self.contact {
            Some(contact) => contact.energy(self.free.free_vertices(), &self.x),
            None => 0.0,
        };
        if let Some(terms) = &mut self.self_contact {
            contact += terms.energy(&self.x);
        }
        inertia
            + self.h
                * self.h
                * (hooke_assembly::spring_energy(&self.springs, &self.x, self.parallel) + contact)
            + self.dashpot_potential(&self.x)
    }

    /// Φ(trial) − Φ(x) term by term, so that its round-off is relative to the change rather than to
    /// Φ. Everything is written in the displacements δ = t − x (exact in floating point for nearby
    /// t and x), never as a difference of two rounded values of a term: per vertex
    /// ½ m δ·(2(x − y) + δ); per spring, with Δr = δ_i − δ_j and r_t = r_x + Δr,
    /// ½ k (|r_t| − |r_x|)(|r_t| + |r_x| − 2l) where |r_t| − |r_x| = Δr·(2 r_x + Δr) / (|r_t| + |r_x|);
    /// the dashpot likewise. Summed in a fixed order.
    fn objective_change(&mut self, xf: &[f64], trial: &[f64]) -> f64 {
        self.expand(xf);
        // trial_positions holds δ per vertex (zero at pinned ones).
        for d in self.trial_positions.iter_mut() {
            *d = SVector::zeros();
        }
        let mut inertia = 0.0;
        let full = self.counter.is_some();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let o = Self::offset(full, f, v);
            let x = SVector::<f64, D>::from_column_slice(&xf[o..o + D]);
            let t = SVector::<f64, D>::from_column_slice(&trial[o..o + D]);
            let delta = t - x;
            self.trial_positions[v] = delta;
            inertia += 0.5 * self.masses[v] * delta.dot(&((x - self.y[v]) * 2.0 + delta));
        }
        let (x, delta) = (&self.x, &self.trial_positions);
        let springs = &self.springs;
        let energy = hooke_assembly::deterministic_sum(springs.len(), self.parallel, |s| {
            let spring = &springs[s];
            let (i, j) = spring.ends();
            spring_energy_change(
                spring.stiffness,
                spring.rest_length,
                &(x[i] - x[j]),
                &(delta[i] - delta[j]),
            )
        });
        let dashpot = if self.dashpot == 0.0 {
            0.0
        } else {
            let this = &*self;
            let sum = hooke_assembly::deterministic_sum(this.springs.len(), this.parallel, |s| {
                let (i, j) = this.springs[s].ends();
                let a_x = this.dashpot_stretch(s, &this.x);
                let da = (this.trial_positions[i] - this.trial_positions[j])
                    .dot(&this.dashpot_directions[s]);
                da * (2.0 * a_x + da)
            });
            0.5 * this.h * this.dashpot * sum
        };
        let mut contact = match &self.contact {
            Some(contact) => {
                contact.energy_change(self.free.free_vertices(), &self.x, &self.trial_positions)
            }
            None => 0.0,
        };
        if let Some(terms) = &mut self.self_contact {
            contact += terms.energy_change(&self.x, &self.trial_positions);
        }
        inertia + self.h * self.h * (energy + contact) + dashpot
    }

    fn gradient(&mut self, xf: &[f64], g: &mut [f64]) {
        self.expand(xf);
        self.forces
            .compute(&self.springs, &self.x, None, &mut self.force, self.parallel);
        let h2 = self.h * self.h;
        if self.dashpot > 0.0 {
            // h² times the dashpot force, −∇Ψ, scattered serially in spring order (deterministic).
            let scale = self.h * self.dashpot / h2;
            for s in 0..self.springs.len() {
                let (i, j) = self.springs[s].ends();
                let f = self.dashpot_directions[s] * (scale * self.dashpot_stretch(s, &self.x));
                self.force[i] -= f;
                self.force[j] += f;
            }
        }
        if let Some(contact) = &self.contact {
            // The contact force −∇E_c joins the spring forces.
            contact.add_gradient(
                self.free.free_vertices(),
                &self.x,
                -1.0,
                true,
                &mut self.force,
            );
        }
        if let Some(terms) = &mut self.self_contact {
            terms.add_gradient(&self.x, -1.0, &mut self.force);
        }
        let full = self.counter.is_some();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let gv = (self.x[v] - self.y[v]) * self.masses[v] - self.force[v] * h2;
            let o = Self::offset(full, f, v);
            g[o..o + D].copy_from_slice(gv.as_slice());
        }
        if let Some(counter) = &self.counter {
            // The counter-force cancels the whole force on a pinned vertex held in place.
            counter.apply_to_gradient(g);
        }
    }

    /// ε times the sizes of the terms the gradient sums per DOF: m (|x − y| + |x|) and
    /// h² Σ_s (|f_s| + k_s (|x_i| + |x_j|)) over the vertex's springs (and the dashpot's), the |x|
    /// terms for the rounding of the positions themselves, with a factor for the number of terms
    /// (the largest vertex degree + 2, the usual bound on a sum's rounding).
    fn gradient_round_off(&mut self, xf: &[f64]) -> f64 {
        self.expand(xf);
        let h2 = self.h * self.h;
        // Per vertex: Σ |f_s|, into `force` (reused).
        for f in self.force.iter_mut() {
            *f = SVector::zeros();
        }
        for (s, spring) in self.springs.iter().enumerate() {
            let (i, j) = spring.ends();
            let mut f = hooke_assembly::spring::force(
                spring.stiffness,
                spring.rest_length,
                &(self.x[i] - self.x[j]),
            )
            .abs()
                // Rounding of r = x_i − x_j itself moves |r| − l by ε (|x_i| + |x_j|).
                + SVector::repeat(spring.stiffness * (self.x[i].norm() + self.x[j].norm()));
            if self.dashpot > 0.0 {
                f += (self.dashpot_directions[s]
                    * (self.h * self.dashpot / h2 * self.dashpot_stretch(s, &self.x)))
                .abs();
            }
            self.force[i] += f;
            self.force[j] += f;
        }
        if self.contact.is_some() || self.self_contact.is_some() {
            // The contact forces' magnitudes, per vertex (their rounding is relative to them).
            for g in self.contact_scratch.iter_mut() {
                *g = SVector::zeros();
            }
            if let Some(contact) = &self.contact {
                contact.add_gradient(
                    self.free.free_vertices(),
                    &self.x,
                    1.0,
                    true,
                    &mut self.contact_scratch,
                );
            }
            if let Some(terms) = &mut self.self_contact {
                terms.add_gradient(&self.x, 1.0, &mut self.contact_scratch);
            }
            for (f, g) in self.force.iter_mut().zip(&self.contact_scratch) {
                *f += g.abs();
            }
        }
        let terms = self.max_degree as f64 + 2.0;
        let sum: f64 = self
            .free
            .free_vertices()
            .iter()
            .map(|&v| {
                let v = v as usize;
                // |x| as well as |x − y|: y and x carry their own rounding of ε |x|.
                ((self.x[v] - self.y[v]).abs() * self.masses[v]
                    + SVector::repeat(self.masses[v] * self.x[v].norm())
                    + self.force[v] * h2)
                    .norm_squared()
            })
            .sum();
        terms * f64::EPSILON * sum.sqrt()
    }

    /// The largest vertex displacement of the step divided by h: m/s.
    fn step_size(&self, step: &[f64]) -> f64 {
        let largest = step
            .chunks_exact(D)
            .map(|c| c.iter().map(|v| v * v).sum::<f64>())
            .fold(0.0, f64::max);
        largest.sqrt() / self.h
    }

    /// With obstacles, [`super::TIME_OF_IMPACT_SHARE`] of the first time at which a free vertex
    /// moving along the step would reach an obstacle (at most 1); 1 without.
    fn max_step_length(&mut self, xf: &[f64], step: &[f64]) -> f64 {
        if self.contact.is_none() && self.self_contact.is_none() {
            return 1.0;
        }
        self.expand(xf);
        let full = self.counter.is_some();
        // Pinned vertices do not move.
        for &p in self.free.pinned() {
            self.contact_scratch[p as usize] = SVector::zeros();
        }
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let o = Self::offset(full, f, v as usize);
            self.contact_scratch[v as usize] = SVector::from_column_slice(&step[o..o + D]);
        }
        let mut longest = match &self.contact {
            Some(contact) => {
                contact.max_step(self.free.free_vertices(), &self.x, &self.contact_scratch)
            }
            None => 1.0,
        };
        if let Some(terms) = &mut self.self_contact {
            longest = longest.min(terms.max_step(&self.x, &self.contact_scratch));
        }
        longest
    }

    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.assembly().pattern.symbolic()
    }

    /// With self-contact, the vertex pairs of the pairs within d̂ at `xf` join the pattern's
    /// links. Within a step they are kept (the pattern only grows, so a contact that comes and goes
    /// costs one analysis); the first update of a step starts from the pairs at its first iterate,
    /// so the pattern never depends on earlier steps (a resumed run factors the same matrices).
    fn update_pattern(&mut self, xf: &[f64]) -> bool {
        if self.self_contact.is_none() {
            return false;
        }
        self.expand(xf);
        let mut wanted = std::mem::take(&mut self.wanted_links);
        wanted.clear();
        if let Some(terms) = &mut self.self_contact {
            terms.links(&self.x, &mut wanted);
        }
        let replace = std::mem::take(&mut self.links_replaced_next);
        let changed = self.update_links(&mut wanted, replace);
        self.wanted_links = wanted;
        changed
    }

    fn hessian(&mut self, xf: &[f64]) -> SparseColMatRef<'_, usize, f64> {
        let blocks = match self.definiteness {
            Definiteness::Exact => SpringBlocks::Exact,
            Definiteness::Clamped => SpringBlocks::Clamped,
        };
        self.assemble(xf, blocks)
    }

    fn shift_diagonal(&self) -> &[f64] {
        &self.shift
    }

    fn has_convexified_hessian(&self) -> bool {
        true
    }

    /// D × D vertex blocks and the rigid-body modes at `xf` (docs/solvers.md §2.4): in 3D the
    /// 3 translations and 3 rotations of [`crate::Amg::rigid_body_modes`]; in 2D the 2
    /// translations and the rotation about the centroid.
    fn near_nullspace(&self, xf: &[f64]) -> Option<(usize, Vec<f64>)> {
        if D == 3 {
            return Some((3, crate::Amg::rigid_body_modes(xf)));
        }
        let dim = xf.len();
        let n = dim / D;
        let mut centroid = [0.0; D];
        for p in xf.chunks_exact(D) {
            for (c, v) in centroid.iter_mut().zip(p) {
                *c += v / n.max(1) as f64;
            }
        }
        let rotation = usize::from(D == 2);
        let mut modes = vec![0.0; (D + rotation) * dim];
        for (v, p) in xf.chunks_exact(D).enumerate() {
            for a in 0..D {
                modes[a * dim + D * v + a] = 1.0;
            }
            if D == 2 {
                // ω × r in the plane: (−y, x).
                modes[2 * dim + 2 * v] = -(p[1] - centroid[1]);
                modes[2 * dim + 2 * v + 1] = p[0] - centroid[0];
            }
        }
        Some((D, modes))
    }

    /// The Hessian with the clamped spring blocks ([`Definiteness::Clamped`]): positive definite
    /// with the masses.
    fn convexified_hessian(&mut self, xf: &[f64]) -> Option<SparseColMatRef<'_, usize, f64>> {
        Some(self.assemble(xf, SpringBlocks::Clamped))
    }

    fn has_definite_hessian(&self) -> bool {
        true
    }

    /// The Hessian with the mass-split projection of the compressed springs (docs/solvers.md
    /// §2.1): every spring's exact block where its ends' share
    /// [`BackwardEulerStep::definite_share`] of their masses holds its negative transverse
    /// eigenvalue, that eigenvalue weighted down to what the share holds where it does not
    /// ([`hooke_assembly::HessianPattern::definite_scales`]); the contact barriers' clamped
    /// blocks (exact on a plane), the friction's and the dashpot's (positive semidefinite).
    /// Positive definite, with smallest eigenvalue at least (1 − θ) times the smallest mass, up to
    /// rounding.
    fn definite_hessian(&mut self, xf: &[f64]) -> Option<SparseColMatRef<'_, usize, f64>> {
        Some(self.assemble(xf, SpringBlocks::Definite))
    }

    /// Nothing with contact ([`BackwardEulerStep::set_contact`]): the relaxation's per-vertex
    /// sweeps and patch solves do not see the obstacles.
    fn prepare_relaxation(&mut self, relaxation: Relaxation) {
        if self.contact.is_none() && self.self_contact.is_none() {
            self.prepare_patches(relaxation)
        }
    }

    /// `None` (nothing done) with contact: see [`NewtonProblem::prepare_relaxation`].
    fn after_iterate(&mut self, xf: &[f64]) -> bool {
        self.adapt_stiffness(xf)
    }

    fn relax(&mut self, xf: &mut [f64], relaxation: Relaxation) -> Option<RelaxationWork> {
        if self.contact.is_some() || self.self_contact.is_some() {
            return None;
        }
        self.relax_all(xf, relaxation)
    }
}

/// Which spring blocks [`BackwardEulerStep::assemble`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SpringBlocks {
    /// Exact, and the exact contact barriers.
    Exact,
    /// Clamped, and the clamped contact barriers.
    Clamped,
    /// The mass-split projection (see [`NewtonProblem::definite_hessian`]), and the clamped
    /// contact barriers.
    Definite,
}

impl<const D: usize> BackwardEulerStep<D> {
    /// Assemble the Hessian at `xf` with the spring blocks `blocks` (dashpot, contact and
    /// counter-forces included) into `values`.
    pub(crate) fn assemble(
        &mut self,
        xf: &[f64],
        blocks: SpringBlocks,
    ) -> SparseColMatRef<'_, usize, f64> {
        self.expand(xf);
        let definiteness = match blocks {
            SpringBlocks::Exact => Definiteness::Exact,
            SpringBlocks::Clamped | SpringBlocks::Definite => Definiteness::Clamped,
        };
        self.assembly();
        let HessianAssembly {
            pattern,
            workspace,
            values,
        } = self.assembly.get_mut().expect("made above");
        if blocks == SpringBlocks::Definite {
            self.projected_springs = pattern.definite_scales(
                &self.springs,
                &self.x,
                &self.masses,
                self.h,
                self.definite_share,
                self.parallel,
                &mut self.loads,
                &mut self.scales,
            );
            pattern.assemble_scaled_into(
                &self.springs,
                &self.x,
                &self.masses,
                self.h,
                &self.scales,
                self.parallel,
                workspace,
                values,
            );
        } else {
            pattern.assemble_into(
                &self.springs,
                &self.x,
                &self.masses,
                self.h,
                HessianParams {
                    definiteness,
                    parallel: self.parallel,
                },
                workspace,
                values,
            );
        }
        if self.dashpot > 0.0 {
            // ∇²Ψ = h c d dᵀ blocks, directions from the step's start.
            pattern.add_dashpot_into(
                &self.springs,
                &self.dashpot_start,
                self.dashpot,
                self.h,
                values,
            );
        }
        if let Some(contact) = &self.contact {
            // Per-vertex blocks: the obstacles are static.
            let full = self.counter.is_some();
            let free = &self.free;
            contact.for_each_hessian_block(
                free.free_vertices(),
                &self.x,
                self.h * self.h,
                definiteness,
                |i, j, block| {
                    let column = |v: usize| {
                        if full {
                            v
                        } else {
                            free.free_index(v).expect("a free vertex")
                        }
                    };
                    let stored = pattern.add_block(column(i), column(j), &block, values);
                    debug_assert!(stored, "the pattern lacks the contact block ({i}, {j})");
                },
            );
        }
        if let Some(terms) = &mut self.self_contact {
            // The pairs' blocks, exact or projected as the springs'; the pattern holds them
            // (update_pattern).
            let full = self.counter.is_some();
            let free = &self.free;
            let column = |v: usize| if full { Some(v) } else { free.free_index(v) };
            let complete = terms.add_hessian_into(
                &self.x,
                self.h * self.h,
                definiteness,
                pattern,
                column,
                values,
            );
            debug_assert!(complete, "the pattern lacks a self-contact block");
        }
        if let Some(counter) = &self.counter {
            // Pinned rows and columns: m_p I on the diagonal, zero elsewhere.
            counter.apply_to_matrix(&self.masses, values);
        }
        pattern.matrix(values)
    }
}
