//! One backward Euler step of a spring mesh as an objective for [`crate::Newton`].

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use hooke_assembly::spring;
use hooke_assembly::{
    CounterForce, Definiteness, FreeDofs, HessianParams, HessianPattern, HessianWorkspace,
    SpringForces,
};
use hooke_mesh::Spring;
use nalgebra::{SMatrix, SVector};

use crate::{NewtonProblem, Relaxation, RelaxationWork};

mod patches;
use patches::PatchCover;

/// Armijo constant and step halvings of a vertex's line search in [`NewtonProblem::relax`].
const RELAX_ARMIJO: f64 = 1e-4;
const RELAX_HALVINGS: usize = 20;
/// The nonlinear elimination stops a region's solve at this many times its gradient's rounding
/// error ([`NewtonProblem::gradient_round_off`]).
const REGION_NOISE_FACTOR: f64 = 8.0;

/// ½ k (|r + Δr| − l)² − ½ k (|r| − l)², written without subtracting two rounded energies:
/// (|r_t| − |r|)(|r_t| + |r| − 2l) k/2 with |r_t| − |r| = Δr·(2r + Δr)/(|r_t| + |r|).
#[inline]
pub(crate) fn spring_energy_change<const D: usize>(
    stiffness: f64,
    rest_length: f64,
    r: &SVector<f64, D>,
    dr: &SVector<f64, D>,
) -> f64 {
    spring_energy_change_from(stiffness, rest_length, r, r.norm(), dr)
}

/// [`spring_energy_change`] given `length` = `r.norm()`.
#[inline]
fn spring_energy_change_from<const D: usize>(
    stiffness: f64,
    rest_length: f64,
    r: &SVector<f64, D>,
    length: f64,
    dr: &SVector<f64, D>,
) -> f64 {
    let sum = length + (r + dr).norm();
    if sum == 0.0 {
        return 0.0;
    }
    let difference = dr.dot(&(r * 2.0 + dr)) / sum;
    0.5 * stiffness * difference * (sum - 2.0 * rest_length)
}

/// One backward Euler step as a [`NewtonProblem`]: Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) over the
/// free DOFs (D per free vertex, numbered as in [`FreeDofs`]), with the Hessian assembled by
/// [`HessianPattern`] into a fixed pattern. Pinned vertices are held where [`BackwardEulerStep::set_step`]
/// puts them. Every buffer is allocated here, once (the dashpot's on its first use).
///
/// Forces linear in velocity and position fold into M and y exactly (the caller passes the
/// effective masses and target; see hooke-sim's implicit integrator). Dashpot damping along the
/// springs, f_i = −c ((v_i − v_j)·d) d, does not: with v = (x − x_n)/h and the direction d frozen at
/// the step's start x_n, h² times it is −∇Ψ of the dissipation potential
/// Ψ(x) = (h c / 2) Σ_s ((Δx_i − Δx_j)·d_s)², Δx = x − x_n, which
/// [`BackwardEulerStep::set_dashpot`] adds to Φ (value, gradient and Hessian h c d dᵀ blocks).
///
/// # Pins: reduction or counter-forces (SPEC §3)
/// [`BackwardEulerStep::new`] removes the pinned vertices from the unknowns (the reduction, the
/// default). [`BackwardEulerStep::with_counter_forces`] keeps every vertex an unknown (D per vertex,
/// DOF D·v + a component a of vertex v) and applies [`CounterForce`] to the full-DOF Hessian and
/// gradient: the pinned rows and columns of the Hessian become m_p I (the effective masses) and the
/// pinned gradient entries zero, the counter-force cancelling every force on a pinned vertex. The
/// objective is Φ̂(x) = Φ(x with every pinned vertex at its held position), which depends on the free
/// unknowns only, so its gradient is exactly that modified gradient; its value and
/// [`NewtonProblem::objective_change`] are those of the reduction. [`BackwardEulerStep::set_step`]
/// puts the pinned unknowns on the pinned positions; a Newton step then never moves them (their
/// gradient is zero and their rows decouple, so the factorisation gives Δx_p = 0), and the positions
/// read back take them from the held positions in any case. Both modes solve the same free system
/// (see [`CounterForce`]); the counter-force one carries the pinned DOFs as extra decoupled rows.
#[derive(Debug)]
pub struct BackwardEulerStep<const D: usize> {
    free: FreeDofs,
    pattern: HessianPattern<D>,
    /// Counter-force mode: every vertex an unknown, the pinned rows and columns replaced.
    counter: Option<CounterForce<D>>,
    workspace: HessianWorkspace<D>,
    values: Vec<f64>,
    forces: SpringForces<D>,
    force: Vec<SVector<f64, D>>,
    masses: Vec<f64>,
    springs: Vec<Spring>,
    shift: Vec<f64>,
    /// The largest number of springs at one vertex (bounds the terms of a gradient entry).
    max_degree: usize,
    /// The springs at each vertex as (spring, other end), vertex v's at
    /// `incident[incident_start[v]..incident_start[v + 1]]`, for the relaxation.
    incident: Vec<(u32, u32)>,
    incident_start: Vec<usize>,
    /// The focused sweeps' buffers: (‖∂Φ/∂x_v‖², v) per free vertex, the selected vertices with
    /// their rings, and a mark per vertex (all false between calls).
    focus_heat: Vec<(f64, u32)>,
    focus_region: Vec<u32>,
    focus_mark: Vec<bool>,
    /// The elimination's map from a vertex to its number in the region's problem (u32::MAX: not
    /// in it; all u32::MAX between calls).
    region_local: Vec<u32>,
    /// The elimination's patches, built once by [`NewtonProblem::prepare_relaxation`].
    patches: Option<Box<PatchCover<D>>>,
    /// The lengths of one vertex's springs, for the relaxation's line search.
    incident_lengths: Vec<f64>,
    definiteness: Definiteness,
    h: f64,
    /// Inertial target per vertex.
    y: Vec<SVector<f64, D>>,
    /// The full positions: pinned vertices fixed, free ones overwritten from the unknowns.
    x: Vec<SVector<f64, D>>,
    /// Full positions of a line-search trial point.
    trial_positions: Vec<SVector<f64, D>>,
    /// Dashpot coefficient c (N·s/m; 0: none), the step's start x_n and each spring's direction
    /// there (zero for a spring of zero length).
    dashpot: f64,
    dashpot_start: Vec<SVector<f64, D>>,
    dashpot_directions: Vec<SVector<f64, D>>,
}

impl<const D: usize> BackwardEulerStep<D> {
    /// The step for `springs` and `masses` (kg, per vertex) over the free vertices of `free`, with
    /// time step `h` (s): pins by reduction, one unknown per free DOF.
    ///
    /// # Panics
    /// If `masses` does not have one entry per vertex of `free`.
    #[track_caller]
    pub fn new(springs: &[Spring], masses: &[f64], free: FreeDofs, h: f64) -> Self {
        Self::build(springs, masses, free, h, false)
    }

    /// The step for `springs` and `masses` (kg, per vertex) with the pinned vertices of `pins` held
    /// by counter-forces (see the type's documentation), with time step `h` (s): one unknown per DOF
    /// of every vertex, pinned or not.
    ///
    /// # Panics
    /// If `masses` does not have one entry per vertex of `pins`.
    #[track_caller]
    pub fn with_counter_forces(springs: &[Spring], masses: &[f64], pins: FreeDofs, h: f64) -> Self {
        Self::build(springs, masses, pins, h, true)
    }

    #[track_caller]
    fn build(springs: &[Spring], masses: &[f64], free: FreeDofs, h: f64, counter: bool) -> Self {
        let n = free.vertex_count();
        assert_eq!(masses.len(), n, "one mass per vertex");
        let (pattern, counter) = if counter {
            let pattern = HessianPattern::new(n, springs, None);
            let counter = CounterForce::new(&pattern, &free);
            (pattern, Some(counter))
        } else {
            (HessianPattern::new(n, springs, Some(&free)), None)
        };
        // The shift's diagonal, one mass per unknown.
        let shift = if counter.is_some() {
            masses.iter().flat_map(|&m| [m; D]).collect()
        } else {
            free.free_vertices()
                .iter()
                .flat_map(|&v| [masses[v as usize]; D])
                .collect()
        };
        let mut incident_start = vec![0usize; n + 1];
        for spring in springs {
            let (i, j) = spring.ends();
            incident_start[i + 1] += 1;
            incident_start[j + 1] += 1;
        }
        for v in 0..n {
            incident_start[v + 1] += incident_start[v];
        }
        let mut incident = vec![(0u32, 0u32); incident_start[n]];
        let mut next = incident_start.clone();
        for (s, spring) in springs.iter().enumerate() {
            let (i, j) = spring.ends();
            incident[next[i]] = (s as u32, j as u32);
            next[i] += 1;
            incident[next[j]] = (s as u32, i as u32);
            next[j] += 1;
        }
        let max_degree = (0..n)
            .map(|v| incident_start[v + 1] - incident_start[v])
            .max()
            .unwrap_or(0);
        BackwardEulerStep {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            forces: SpringForces::new(n, springs),
            force: vec![SVector::zeros(); n],
            masses: masses.to_vec(),
            springs: springs.to_vec(),
            shift,
            max_degree,
            incident,
            incident_start,
            focus_heat: Vec::with_capacity(free.free_count()),
            focus_region: Vec::with_capacity(free.free_count()),
            focus_mark: vec![false; n],
            region_local: vec![u32::MAX; n],
            patches: None,
            incident_lengths: vec![0.0; max_degree],
            definiteness: Definiteness::Exact,
            h,
            y: vec![SVector::zeros(); n],
            x: vec![SVector::zeros(); n],
            trial_positions: vec![SVector::zeros(); n],
            dashpot: 0.0,
            dashpot_start: Vec::new(),
            dashpot_directions: Vec::new(),
            free,
            pattern,
            counter,
        }
    }

    /// Whether the pins are held by counter-forces (every vertex an unknown) rather than removed.
    pub fn has_counter_forces(&self) -> bool {
        self.counter.is_some()
    }

    /// The first unknown of vertex `v`, free vertex number `f`: D·v with counter-forces, D·f with
    /// the reduction.
    #[inline]
    fn offset(full: bool, f: usize, v: usize) -> usize {
        D * if full { v } else { f }
    }

    /// Set the inertial target y (per vertex, m) and the positions (per vertex, m; the pinned ones
    /// are held there), and write the free part of `y`, the usual initial guess, into `unknowns`
    /// (with counter-forces, the pinned unknowns get the pinned positions).
    ///
    /// # Panics
    /// On length mismatches.
    #[track_caller]
    pub fn set_step(
        &mut self,
        y: &[SVector<f64, D>],
        positions: &[SVector<f64, D>],
        unknowns: &mut [f64],
    ) {
        self.y.copy_from_slice(y);
        self.x.copy_from_slice(positions);
        let full = self.counter.is_some();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let o = Self::offset(full, f, v as usize);
            unknowns[o..o + D].copy_from_slice(self.y[v as usize].as_slice());
        }
        if full {
            for &p in self.free.pinned() {
                let o = D * p as usize;
                unknowns[o..o + D].copy_from_slice(self.x[p as usize].as_slice());
            }
        }
    }

    /// Add the dashpot dissipation potential Ψ (see the type's documentation) with coefficient
    /// `coefficient` (N·s/m, ≥ 0; 0 removes it) and the step's start positions `start` (m, one per
    /// vertex), from which the spring directions are taken. Call it after
    /// [`BackwardEulerStep::set_step`] on every step.
    ///
    /// # Panics
    /// If `start` does not have one position per vertex, or the coefficient is negative or NaN.
    #[track_caller]
    pub fn set_dashpot(&mut self, coefficient: f64, start: &[SVector<f64, D>]) {
        assert!(
            coefficient >= 0.0,
            "the dashpot coefficient must be ≥ 0, got {coefficient}"
        );
        assert_eq!(start.len(), self.x.len(), "one start position per vertex");
        self.dashpot = coefficient;
        if coefficient == 0.0 {
            return;
        }
        if self.dashpot_directions.len() != self.springs.len() {
            self.dashpot_directions = vec![SVector::zeros(); self.springs.len()];
            self.dashpot_start = vec![SVector::zeros(); start.len()];
        }
        self.dashpot_start.copy_from_slice(start);
        for (d, spring) in self.dashpot_directions.iter_mut().zip(&self.springs) {
            let (i, j) = spring.ends();
            *d = hooke_assembly::spring::direction(&(start[i] - start[j]))
                .map_or(SVector::zeros(), |(unit, _)| unit);
        }
    }

    /// (Δx_i − Δx_j)·d for spring `s` at full positions `x`.
    fn dashpot_stretch(&self, s: usize, x: &[SVector<f64, D>]) -> f64 {
        let (i, j) = self.springs[s].ends();
        let start = &self.dashpot_start;
        ((x[i] - start[i]) - (x[j] - start[j])).dot(&self.dashpot_directions[s])
    }

    /// Ψ at the full positions `x`.
    fn dashpot_potential(&self, x: &[SVector<f64, D>]) -> f64 {
        if self.dashpot == 0.0 {
            return 0.0;
        }
        let sum = hooke_assembly::deterministic_sum(self.springs.len(), true, |s| {
            self.dashpot_stretch(s, x).powi(2)
        });
        0.5 * self.h * self.dashpot * sum
    }

    /// Which spring Hessian [`NewtonProblem::hessian`] assembles: [`Definiteness::Exact`] (the
    /// default; indefinite under compression, quadratic convergence) or [`Definiteness::Clamped`]
    /// (positive definite with the masses, so every Newton matrix factors, but only linear
    /// convergence where springs are compressed).
    pub fn set_definiteness(&mut self, definiteness: Definiteness) {
        self.definiteness = definiteness;
    }

    /// The full positions for the unknowns `xf` (pinned vertices as set by
    /// [`BackwardEulerStep::set_step`], whatever the pinned unknowns hold).
    pub fn positions(&mut self, xf: &[f64]) -> &[SVector<f64, D>] {
        self.expand(xf);
        &self.x
    }

    /// The free-DOF map.
    pub fn free(&self) -> &FreeDofs {
        &self.free
    }

    fn expand(&mut self, xf: &[f64]) {
        let full = self.counter.is_some();
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let o = Self::offset(full, f, v as usize);
            self.x[v as usize] = SVector::from_column_slice(&xf[o..o + D]);
        }
    }
}

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
        inertia
            + self.h * self.h * hooke_assembly::spring_energy(&self.springs, &self.x, true)
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
        let energy = hooke_assembly::deterministic_sum(springs.len(), true, |s| {
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
            let sum = hooke_assembly::deterministic_sum(this.springs.len(), true, |s| {
                let (i, j) = this.springs[s].ends();
                let a_x = this.dashpot_stretch(s, &this.x);
                let da = (this.trial_positions[i] - this.trial_positions[j])
                    .dot(&this.dashpot_directions[s]);
                da * (2.0 * a_x + da)
            });
            0.5 * this.h * this.dashpot * sum
        };
        inertia + self.h * self.h * energy + dashpot
    }

    fn gradient(&mut self, xf: &[f64], g: &mut [f64]) {
        self.expand(xf);
        self.forces
            .compute(&self.springs, &self.x, None, &mut self.force, true);
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

    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.pattern.symbolic()
    }

    fn hessian(&mut self, xf: &[f64]) -> SparseColMatRef<'_, usize, f64> {
        self.assemble(xf, self.definiteness)
    }

    fn shift_diagonal(&self) -> &[f64] {
        &self.shift
    }

    fn has_convexified_hessian(&self) -> bool {
        true
    }

    /// The Hessian with the clamped spring blocks ([`Definiteness::Clamped`]): positive definite
    /// with the masses.
    fn convexified_hessian(&mut self, xf: &[f64]) -> Option<SparseColMatRef<'_, usize, f64>> {
        Some(self.assemble(xf, Definiteness::Clamped))
    }

    /// Build the elimination's patches for `relaxation` (see [`Relaxation::region_share`]) unless
    /// they are built for its settings already, or there is no elimination.
    fn prepare_relaxation(&mut self, relaxation: Relaxation) {
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
    fn relax(&mut self, xf: &mut [f64], relaxation: Relaxation) -> Option<RelaxationWork> {
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
}

impl<const D: usize> BackwardEulerStep<D> {
    /// Assemble the Hessian at `xf` with the spring blocks of `definiteness` (dashpot and
    /// counter-forces included) into `values`.
    fn assemble(
        &mut self,
        xf: &[f64],
        definiteness: Definiteness,
    ) -> SparseColMatRef<'_, usize, f64> {
        self.expand(xf);
        self.pattern.assemble_into(
            &self.springs,
            &self.x,
            &self.masses,
            self.h,
            HessianParams {
                definiteness,
                ..HessianParams::default()
            },
            &mut self.workspace,
            &mut self.values,
        );
        if self.dashpot > 0.0 {
            // ∇²Ψ = h c d dᵀ blocks, directions from the step's start.
            self.pattern.add_dashpot_into(
                &self.springs,
                &self.dashpot_start,
                self.dashpot,
                self.h,
                &mut self.values,
            );
        }
        if let Some(counter) = &self.counter {
            // Pinned rows and columns: m_p I on the diagonal, zero elsewhere.
            counter.apply_to_matrix(&self.masses, &mut self.values);
        }
        self.pattern.matrix(&self.values)
    }

    /// Up to `iterations` line-searched Newton steps of free vertex `v` (see
    /// [`NewtonProblem::relax`]), stopping once it no longer moves.
    fn relax_block(&mut self, v: usize, iterations: usize) {
        for _ in 0..iterations {
            if !self.relax_vertex(v) {
                break;
            }
        }
    }

    /// Select the `count` free vertices with the largest ‖∂Φ/∂x_v‖ (ties to the lower index) and
    /// `rings` rings of their free spring neighbours into `focus_region` (sorted), and return the
    /// squared gradient norm of the hottest vertex left out (0 if none is).
    fn select_hottest(&mut self, count: usize, rings: usize) -> f64 {
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
    fn relax_focused(&mut self, count: usize, relaxation: Relaxation, work: &mut RelaxationWork) {
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
    fn relax_region(&mut self, count: usize, relaxation: Relaxation, work: &mut RelaxationWork) {
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
    fn vertex_model<const BLOCK: bool>(
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
    fn relax_vertex(&mut self, v: usize) -> bool {
        let mut lengths = std::mem::take(&mut self.incident_lengths);
        let moved = self.relax_vertex_with(v, &mut lengths);
        self.incident_lengths = lengths;
        moved
    }

    /// [`BackwardEulerStep::relax_vertex`] with a buffer for the incident springs' lengths.
    fn relax_vertex_with(&mut self, v: usize, lengths: &mut [f64]) -> bool {
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
    fn dashpot_relative(&self, v: usize, other: usize, p: &SVector<f64, D>) -> SVector<f64, D> {
        (p - self.dashpot_start[v]) - (self.x[other] - self.dashpot_start[other])
    }

    /// Φ(v at p + δ) − Φ(v at p), the others fixed, term by term as in
    /// [`NewtonProblem::objective_change`]; `lengths` are the incident springs' lengths at p.
    fn vertex_change(
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
