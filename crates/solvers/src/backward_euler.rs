//! One backward Euler step of a spring mesh as an objective for [`crate::Newton`]: the step's data
//! and set-up here; Φ, its gradient and Hessians in `objective`; the nonlinear relaxation in
//! `relaxation`, with the elimination's fixed patches in `patches`.

use hooke_assembly::{
    CounterForce, Definiteness, FreeDofs, HessianPattern, HessianWorkspace, SpringForces,
};
use std::sync::OnceLock;

use hooke_mesh::Spring;

use crate::params::ParamError;
use nalgebra::SVector;

mod objective;
mod obstacles;
mod patches;
mod relaxation;
mod self_contact;
mod stiffness;
use obstacles::StepContact;
pub use obstacles::{ContactModel, TIME_OF_IMPACT_SHARE};
use patches::PatchCover;
use self_contact::StepSelfContact;
pub use self_contact::{collision_free_step, SelfContactModel, SelfContactState};
use stiffness::StiffnessScale;
pub use stiffness::{AdaptiveStiffness, DEFAULT_GAP_SHARE, DEFAULT_MAX_STIFFNESS_RATIO};

/// The default θ of [`BackwardEulerStep::set_definite_share`]: half of every vertex's mass may
/// hold its compressed springs, half is kept as the margin of definiteness.
pub const DEFAULT_DEFINITE_SHARE: f64 = 0.5;

/// The nonlinear elimination stops a region's solve at this many times its gradient's rounding
/// error ([`crate::NewtonProblem::gradient_round_off`]).
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

/// One backward Euler step as a [`crate::NewtonProblem`]: Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x) over the
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
/// # Pins: reduction or counter-forces (docs/model.md §5)
/// [`BackwardEulerStep::new`] removes the pinned vertices from the unknowns (the reduction, the
/// default). [`BackwardEulerStep::with_counter_forces`] keeps every vertex an unknown (D per vertex,
/// DOF D·v + a component a of vertex v) and applies [`CounterForce`] to the full-DOF Hessian and
/// gradient: the pinned rows and columns of the Hessian become m_p I (the effective masses) and the
/// pinned gradient entries zero, the counter-force cancelling every force on a pinned vertex. The
/// objective is Φ̂(x) = Φ(x with every pinned vertex at its held position), which depends on the free
/// unknowns only, so its gradient is exactly that modified gradient; its value and
/// [`crate::NewtonProblem::objective_change`] are those of the reduction. [`BackwardEulerStep::set_step`]
/// puts the pinned unknowns on the pinned positions; a Newton step then never moves them (their
/// gradient is zero and their rows decouple, so the factorisation gives Δx_p = 0), and the positions
/// read back take them from the held positions in any case. Both modes solve the same free system
/// (see [`CounterForce`]); the counter-force one carries the pinned DOFs as extra decoupled rows.
#[derive(Debug)]
pub struct BackwardEulerStep<const D: usize> {
    free: FreeDofs,
    /// The Hessian's pattern, assembly workspace and values, made when first asked for: a step
    /// whose solver never assembles a Hessian (L-BFGS, Anderson-accelerated PD, a gradient-only
    /// measurement) never stores one (on cloth-640, 0.7 GB).
    assembly: OnceLock<HessianAssembly<D>>,
    /// Counter-force mode: every vertex an unknown, the pinned rows and columns replaced.
    counter: Option<CounterForce<D>>,
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
    /// The elimination's patches, built once by [`crate::NewtonProblem::prepare_relaxation`].
    patches: Option<Box<PatchCover<D>>>,
    /// The lengths of one vertex's springs, for the relaxation's line search.
    incident_lengths: Vec<f64>,
    definiteness: Definiteness,
    /// θ of the mass-split projection ([`BackwardEulerStep::set_definite_share`]), its loads (one
    /// per block column of the pattern), its per-spring weights, and how many springs the last
    /// projected assembly weighted down.
    definite_share: f64,
    loads: Vec<f64>,
    scales: Vec<f64>,
    projected_springs: usize,
    /// Run the per-spring loops (energy, forces, Hessian) with rayon; the same bits either way.
    parallel: bool,
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
    /// Contact barriers and lagged friction ([`BackwardEulerStep::set_contact`]); `None`: no
    /// obstacles, and no cost.
    contact: Option<Box<StepContact<D>>>,
    /// Self-contact barriers ([`BackwardEulerStep::set_self_contact`]); `None`: none, and no cost.
    self_contact: Option<Box<StepSelfContact>>,
    /// IPC's adaptive scale of every barrier's stiffness
    /// ([`BackwardEulerStep::set_adaptive_stiffness`]); `None`: the models' stiffnesses.
    adaptive_stiffness: Option<StiffnessScale>,
    /// The vertex pairs the Hessian's pattern holds beyond the springs (the self-contact pairs
    /// seen in this step), sorted, and the pairs the last pattern update asked for (scratch).
    links: Vec<[u32; 2]>,
    wanted_links: Vec<[u32; 2]>,
    /// Set by [`BackwardEulerStep::set_step`]: the next pattern update replaces the links instead
    /// of adding to them, so that the pattern (and with it the factor's ordering and its rounding)
    /// depends on the step's own iterates only, not on how earlier steps were run.
    links_replaced_next: bool,
    /// Per vertex, a contact term's gradient or a trial move (scratch of the contact terms).
    contact_scratch: Vec<SVector<f64, D>>,
    /// The unknowns of a candidate initial guess (sized on first use).
    start_guess: Vec<f64>,
}

/// A Hessian pattern with the workspace and values of its assembly.
#[derive(Debug)]
pub(crate) struct HessianAssembly<const D: usize> {
    pub(crate) pattern: HessianPattern<D>,
    pub(crate) workspace: HessianWorkspace<D>,
    pub(crate) values: Vec<f64>,
}

impl<const D: usize> HessianAssembly<D> {
    fn new(pattern: HessianPattern<D>) -> Self {
        HessianAssembly {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            pattern,
        }
    }
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
        // Counter-force mode needs the pattern now (its pinned entries); otherwise it waits.
        let assembly = OnceLock::new();
        let counter = counter.then(|| {
            let built = HessianAssembly::new(HessianPattern::new(n, springs, None));
            let counter = CounterForce::new(&built.pattern, &free);
            assembly.get_or_init(|| built);
            counter
        });
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
            definite_share: DEFAULT_DEFINITE_SHARE,
            // One per block column of the pattern.
            loads: vec![
                0.0;
                if counter.is_some() {
                    n
                } else {
                    free.free_count()
                }
            ],
            scales: vec![1.0; springs.len()],
            projected_springs: 0,
            parallel: true,
            h,
            y: vec![SVector::zeros(); n],
            x: vec![SVector::zeros(); n],
            trial_positions: vec![SVector::zeros(); n],
            dashpot: 0.0,
            dashpot_start: Vec::new(),
            dashpot_directions: Vec::new(),
            contact: None,
            self_contact: None,
            adaptive_stiffness: None,
            links: Vec::new(),
            wanted_links: Vec::new(),
            links_replaced_next: false,
            contact_scratch: Vec::new(),
            start_guess: Vec::new(),
            free,
            assembly,
            counter,
        }
    }

    /// The Hessian's pattern and buffers, made on first use.
    pub(crate) fn assembly(&self) -> &HessianAssembly<D> {
        self.assembly.get_or_init(|| {
            HessianAssembly::new(HessianPattern::with_links(
                self.free.vertex_count(),
                &self.springs,
                &self.links,
                Some(&self.free),
            ))
        })
    }

    /// Add `wanted` (vertex pairs, lower index first) to the pattern's links, or with `replace`
    /// make them the links; if the links changed, make the pattern again (and the counter-forces
    /// on it). Returns whether the pattern changed.
    fn update_links(&mut self, wanted: &mut Vec<[u32; 2]>, replace: bool) -> bool {
        wanted.sort_unstable();
        wanted.dedup();
        if replace {
            if *wanted == self.links {
                return false;
            }
            self.links.clone_from(wanted);
        } else {
            let links = &self.links;
            if wanted.iter().all(|l| links.binary_search(l).is_ok()) {
                return false;
            }
            self.links.extend_from_slice(wanted);
            self.links.sort_unstable();
            self.links.dedup();
        }
        let n = self.free.vertex_count();
        if self.counter.is_some() {
            let built = HessianAssembly::new(HessianPattern::with_links(
                n,
                &self.springs,
                &self.links,
                None,
            ));
            self.counter = Some(CounterForce::new(&built.pattern, &self.free));
            self.assembly = OnceLock::from(built);
        } else {
            self.assembly = OnceLock::new();
        }
        true
    }

    /// Run the per-spring loops (energy, forces, Hessian assembly) with rayon or serially (default:
    /// parallel). Every sum is taken in a fixed order, so the result is the same bit for bit
    /// either way; the relaxation is serial in both.
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
        if let Some(terms) = &mut self.self_contact {
            terms.set_parallel(parallel);
        }
    }

    /// Whether the per-spring loops run in parallel ([`BackwardEulerStep::set_parallel`]).
    pub fn is_parallel(&self) -> bool {
        self.parallel
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

    /// Set the inertial target y (per vertex, m) and the positions (per vertex, m: the step's start
    /// x_n at free vertices; the pinned ones are held there), and write the initial guess into
    /// `unknowns` (with counter-forces, the pinned unknowns get the pinned positions): the free
    /// part of `y`; with obstacles ([`BackwardEulerStep::set_contact`]) y only if no vertex meets
    /// an obstacle on its straight way from x_n to y, x_n otherwise; and the friction (obstacles'
    /// and self-contact's) is lagged at x_n.
    /// Call [`BackwardEulerStep::set_contact`] first.
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
        self.set_step_with_velocities(y, positions, None, unknowns);
    }

    /// [`BackwardEulerStep::set_step`] with the velocities v_n (m/s, per vertex) at the step's
    /// start: with obstacles, where the way from x_n to y meets one, the initial guess is x_n + h v_n
    /// (x_n moved on at its velocity, without the external forces' share of y) if the way from
    /// x_n to it meets no obstacle and Φ (without the dashpot's Ψ, which
    /// [`BackwardEulerStep::set_dashpot`] sets after this call) is lower there than at x_n; x_n
    /// otherwise. A body resting on an obstacle, whose y lies inside it, but sliding or turning at
    /// a steady velocity then starts where that velocity takes it: from x_n the first Newton step
    /// would be that velocity, and a second one would be needed wherever it exceeds the
    /// step-size tolerance. Without obstacles, or where the way to y is clear, the guess is y, as
    /// for [`BackwardEulerStep::set_step`].
    ///
    /// # Panics
    /// On length mismatches.
    #[track_caller]
    pub fn set_step_with_velocities(
        &mut self,
        y: &[SVector<f64, D>],
        positions: &[SVector<f64, D>],
        velocities: Option<&[SVector<f64, D>]>,
        unknowns: &mut [f64],
    ) {
        self.y.copy_from_slice(y);
        self.x.copy_from_slice(positions);
        self.links_replaced_next = self.self_contact.is_some();
        // Every step starts from the models' stiffnesses: the scale depends on this step's state
        // alone (see `balance_stiffness` at the end).
        if self.adaptive_stiffness.is_some() {
            self.apply_stiffness_scale(1.0);
        }
        let full = self.counter.is_some();
        if let Some(v) = velocities {
            assert_eq!(v.len(), positions.len(), "one velocity per vertex");
        }
        // With obstacles the start must be feasible: y if the way from x_n to y stays clear of
        // every obstacle, x_n (outside every obstacle) otherwise. A start part of the way to y
        // would put the vertices nearest an obstacle at a tenth of their distance, deep in the
        // barrier, for Newton to push back out.
        if self.contact.is_some() || self.self_contact.is_some() {
            for (d, (y, x)) in self.contact_scratch.iter_mut().zip(y.iter().zip(positions)) {
                *d = y - x;
            }
            // Pinned vertices stay where they are put.
            for &p in self.free.pinned() {
                self.contact_scratch[p as usize] = SVector::zeros();
            }
        }
        let mut share = match &mut self.contact {
            Some(contact) => {
                let free = self.free.free_vertices();
                contact.lag_friction(free, positions);
                contact.max_step(free, positions, &self.contact_scratch)
            }
            None => 1.0,
        };
        if let Some(self_contact) = &mut self.self_contact {
            share = share.min(self_contact.max_step(positions, &self.contact_scratch));
            // The pairs' friction, as the obstacles', is lagged at x_n.
            self_contact.lag_friction(positions, self.h);
        }
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let o = Self::offset(full, f, v);
            let start = if share == 1.0 { self.y[v] } else { self.x[v] };
            unknowns[o..o + D].copy_from_slice(start.as_slice());
        }
        if full {
            for &p in self.free.pinned() {
                let o = D * p as usize;
                unknowns[o..o + D].copy_from_slice(self.x[p as usize].as_slice());
            }
        }
        if share < 1.0 {
            if let Some(velocities) = velocities {
                self.try_moving_start(velocities, unknowns);
            }
        }
        if self.adaptive_stiffness.is_some() {
            self.balance_stiffness(unknowns);
        }
    }

    /// IPC's adaptive barrier stiffness (`None`: the models' stiffnesses, the default): see
    /// [`AdaptiveStiffness`]. It scales the obstacles' barriers ([`BackwardEulerStep::set_contact`])
    /// and self-contact's ([`BackwardEulerStep::set_self_contact`]) alike, from each step's
    /// first iterate on; without either it does nothing.
    ///
    /// # Errors
    /// [`ParamError`] naming a setting out of range ([`AdaptiveStiffness::validate`]).
    pub fn set_adaptive_stiffness(
        &mut self,
        settings: Option<AdaptiveStiffness>,
    ) -> Result<(), ParamError> {
        if let Some(settings) = &settings {
            settings.validate()?;
        }
        self.adaptive_stiffness = settings.map(StiffnessScale::new);
        self.apply_stiffness_scale(1.0);
        Ok(())
    }

    /// The adaptive stiffness's settings, if on.
    pub fn adaptive_stiffness(&self) -> Option<AdaptiveStiffness> {
        self.adaptive_stiffness.map(|a| a.settings)
    }

    /// The scale s the barriers' stiffnesses carry now (dimensionless, ≥ 1; 1 without the adaptive
    /// stiffness).
    pub fn stiffness_scale(&self) -> f64 {
        self.adaptive_stiffness.map_or(1.0, |a| a.scale)
    }

    /// Multiply every barrier's model stiffness by `scale`.
    fn apply_stiffness_scale(&mut self, scale: f64) {
        if let Some(contact) = &mut self.contact {
            contact.set_stiffness_scale(scale);
        }
        if let Some(terms) = &mut self.self_contact {
            terms.set_stiffness_scale(scale);
        }
        if let Some(adaptive) = &mut self.adaptive_stiffness {
            adaptive.scale = scale;
        }
    }

    /// The smallest gap at the full positions `x` as a share of its d̂, over every free vertex
    /// against every obstacle and every self-contact pair within d̂ (1 where none is within d̂).
    fn relative_gap(&mut self) -> f64 {
        let mut gap = 1.0f64;
        if let Some(contact) = &self.contact {
            let d = contact.smallest_distance(self.free.free_vertices(), &self.x);
            gap = gap.min(d / contact.model.distance);
        }
        if let Some(terms) = &mut self.self_contact {
            let d = terms.barrier.smallest_active_distance(&self.x);
            gap = gap.min(d / terms.barrier.model().distance);
        }
        gap
    }

    /// Set the adaptive scale at the first iterate `unknowns` from the balance of gradients (see
    /// [`AdaptiveStiffness`]): g the gradient of inertia and springs, b that of h² times the
    /// barriers at the models' stiffnesses (friction and the dashpot left out), over the free
    /// vertices. The friction (obstacles' and self-contact's), lagged at the models' stiffnesses,
    /// takes the scale too.
    fn balance_stiffness(&mut self, unknowns: &[f64]) {
        let Some(adaptive) = self.adaptive_stiffness else {
            return;
        };
        if self.contact.is_none() && self.self_contact.is_none() {
            return;
        }
        self.expand(unknowns);
        self.forces
            .compute(&self.springs, &self.x, None, &mut self.force, self.parallel);
        for b in self.contact_scratch.iter_mut() {
            *b = SVector::zeros();
        }
        if let Some(contact) = &self.contact {
            contact.add_gradient(
                self.free.free_vertices(),
                &self.x,
                1.0,
                false,
                &mut self.contact_scratch,
            );
        }
        if let Some(terms) = &mut self.self_contact {
            terms
                .barrier
                .add_gradient(&self.x, 1.0, &mut self.contact_scratch);
        }
        let h2 = self.h * self.h;
        let (mut rest_dot_barrier, mut barrier_squared) = (0.0, 0.0);
        for &v in self.free.free_vertices() {
            let v = v as usize;
            let rest = (self.x[v] - self.y[v]) * self.masses[v] - self.force[v] * h2;
            let barrier = self.contact_scratch[v] * h2;
            rest_dot_barrier += rest.dot(&barrier);
            barrier_squared += barrier.norm_squared();
        }
        let scale = adaptive
            .settings
            .balanced_scale(rest_dot_barrier, barrier_squared);
        self.apply_stiffness_scale(scale);
        let gap = self.relative_gap();
        if let Some(a) = &mut self.adaptive_stiffness {
            a.start(scale, gap);
        }
        if let Some(contact) = &mut self.contact {
            contact.scale_friction(scale);
        }
        if let Some(terms) = &mut self.self_contact {
            terms.scale_friction(scale);
        }
    }

    /// After an accepted iterate `unknowns`: double the adaptive scale if the smallest gap keeps
    /// closing below its share of d̂ (see [`AdaptiveStiffness`]). Returns whether Φ changed.
    pub(crate) fn adapt_stiffness(&mut self, unknowns: &[f64]) -> bool {
        if self.adaptive_stiffness.is_none()
            || (self.contact.is_none() && self.self_contact.is_none())
        {
            return false;
        }
        self.expand(unknowns);
        let gap = self.relative_gap();
        let doubled = self
            .adaptive_stiffness
            .as_mut()
            .and_then(|a| a.after_iterate(gap));
        match doubled {
            Some(scale) => {
                self.apply_stiffness_scale(scale);
                true
            }
            None => false,
        }
    }

    /// Replace the initial guess x_n in `unknowns` by x_n + h v_n if the way there is clear of every
    /// obstacle and Φ is lower there (see [`BackwardEulerStep::set_step_with_velocities`]).
    fn try_moving_start(&mut self, velocities: &[SVector<f64, D>], unknowns: &mut [f64]) {
        if self.contact.is_none() && self.self_contact.is_none() {
            return;
        }
        let h = self.h;
        for (d, v) in self.contact_scratch.iter_mut().zip(velocities) {
            *d = v * h;
        }
        for &p in self.free.pinned() {
            self.contact_scratch[p as usize] = SVector::zeros();
        }
        let free = self.free.free_vertices();
        if let Some(contact) = &self.contact {
            if contact.max_step(free, &self.x, &self.contact_scratch) < 1.0 {
                return;
            }
        }
        if let Some(self_contact) = &mut self.self_contact {
            if self_contact.max_step(&self.x, &self.contact_scratch) < 1.0 {
                return;
            }
        }
        let free = self.free.free_vertices();
        let full = self.counter.is_some();
        let mut moved = std::mem::take(&mut self.start_guess);
        moved.clear();
        moved.extend_from_slice(unknowns);
        for (f, &v) in free.iter().enumerate() {
            let v = v as usize;
            let o = Self::offset(full, f, v);
            let p = self.x[v] + self.contact_scratch[v];
            moved[o..o + D].copy_from_slice(p.as_slice());
        }
        let dashpot = std::mem::replace(&mut self.dashpot, 0.0);
        let change = crate::NewtonProblem::objective_change(self, unknowns, &moved);
        self.dashpot = dashpot;
        if change < 0.0 {
            unknowns.copy_from_slice(&moved);
        }
        self.start_guess = moved;
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

    /// Add contact with static obstacles to Φ (`None` removes it): for every free vertex v and
    /// obstacle, h² κ_v b(d) with IPC's log barrier b (zero at distances d ≥ d̂, +∞ at the
    /// surface) and κ_v = κ̂ m_v (`masses`: kg per vertex, the lumped masses, so that the barrier
    /// energy does not depend on the damping folded into the effective masses), and h² times the
    /// lagged friction potential of the contacts within
    /// d̂ at the step's start (see docs/contact.md). Newton's line search then never crosses an
    /// obstacle ([`crate::NewtonProblem::max_step_length`]). Every free vertex must start each step
    /// strictly outside every obstacle (d > 0); the caller checks it.
    ///
    /// # Panics
    /// If the model's distance, stiffness or friction velocity is not finite and positive, a
    /// friction coefficient is negative or NaN, or `masses` does not have one entry per vertex.
    #[track_caller]
    pub fn set_contact(&mut self, model: Option<ContactModel<D>>, masses: &[f64]) {
        assert_eq!(masses.len(), self.x.len(), "one mass per vertex");
        self.contact = model.map(|model| {
            for (name, value) in [
                ("distance", model.distance),
                ("stiffness", model.stiffness),
                ("friction velocity", model.friction_velocity),
            ] {
                assert!(
                    value.is_finite() && value > 0.0,
                    "the contact {name} must be finite and > 0, got {value}"
                );
            }
            for &(_, mu) in &model.obstacles {
                assert!(mu >= 0.0, "friction must be ≥ 0, got {mu}");
            }
            Box::new(StepContact::new(model, masses, self.h))
        });
        if self.contact.is_some() && self.contact_scratch.len() != self.x.len() {
            self.contact_scratch = vec![SVector::zeros(); self.x.len()];
        }
    }

    /// Add self-contact of a triangle surface to Φ (`None` removes it): for every point–triangle
    /// and edge–edge pair of `model.triangles` within the reach d̂ that shares no vertex (and is
    /// not excluded at rest, see `hooke_collision::broad_phase::SurfaceTopology::exclude_close_at_rest`),
    /// h² κ b(d) with IPC's log barrier, edge–edge pairs mollified where nearly parallel
    /// (docs/contact.md). Every line search is then capped so that no pair passes through another
    /// ([`crate::NewtonProblem::max_step_length`], by additive CCD), and the Hessian's pattern
    /// grows by the vertex pairs that active pairs couple ([`crate::NewtonProblem::update_pattern`]).
    /// The surface must be free of intersections and every pair apart (d > 0) at the start of each
    /// step; the caller checks it. With `model.friction` μ > 0, h² times the pairs' lagged
    /// friction potential joins Φ, lagged at each step's start ([`BackwardEulerStep::set_step`];
    /// `hooke_assembly::self_friction`); μ = 0 adds nothing.
    ///
    /// # Errors
    /// [`ParamError`] if D ≠ 3, the distance or stiffness is not finite and positive, the friction
    /// coefficient is not finite and ≥ 0 (or, with friction, its velocity not finite and
    /// positive), a triangle names a vertex out of range or repeats one, or there is not one rest
    /// position per vertex.
    pub fn set_self_contact(&mut self, model: Option<SelfContactModel>) -> Result<(), ParamError> {
        let Some(model) = model else {
            self.self_contact = None;
            return Ok(());
        };
        let n = self.x.len();
        if D != 3 {
            return Err(ParamError::Input {
                field: "SelfContactModel",
                problem: format!("self-contact is for triangle surfaces in 3D, not {D}D"),
            });
        }
        crate::params::positive("SelfContactModel::distance", model.distance)?;
        crate::params::positive("SelfContactModel::stiffness", model.stiffness)?;
        crate::params::non_negative("SelfContactModel::friction", model.friction)?;
        if model.friction > 0.0 {
            crate::params::positive(
                "SelfContactModel::friction_velocity",
                model.friction_velocity,
            )?;
        }
        if model.rest_positions.len() != n {
            return Err(ParamError::Input {
                field: "SelfContactModel::rest_positions",
                problem: format!(
                    "{} rest positions for {n} vertices: give one per vertex",
                    model.rest_positions.len()
                ),
            });
        }
        if let Some(p) = model
            .rest_positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(ParamError::Input {
                field: "SelfContactModel::rest_positions",
                problem: format!("rest position {p} is not finite"),
            });
        }
        check_triangles("SelfContactModel::triangles", &model.triangles, n)?;
        let mut free = vec![false; n];
        for &v in self.free.free_vertices() {
            free[v as usize] = true;
        }
        let mut terms = StepSelfContact::new(model, free);
        terms.set_parallel(self.parallel);
        self.self_contact = Some(Box::new(terms));
        if self.contact_scratch.len() != n {
            self.contact_scratch = vec![SVector::zeros(); n];
        }
        Ok(())
    }

    /// The self-contact model, if any ([`BackwardEulerStep::set_self_contact`]).
    pub fn self_contact(&self) -> Option<&SelfContactModel> {
        self.self_contact.as_ref().map(|c| c.barrier.model())
    }

    /// What self-contact does at the full positions `positions` (one per vertex, m): `None`
    /// without self-contact.
    pub fn self_contact_state(
        &mut self,
        positions: &[SVector<f64, D>],
    ) -> Option<SelfContactState> {
        let terms = self.self_contact.as_mut()?;
        let (point_triangle_pairs, edge_edge_pairs) = terms.barrier.active_counts(positions);
        Some(SelfContactState {
            energy: terms.barrier.energy(positions),
            smallest_distance: terms.barrier.smallest_distance(positions),
            point_triangle_pairs,
            edge_edge_pairs,
            stiffness: terms.barrier.model().stiffness,
        })
    }

    /// Hold the triangles `triangles` (vertex indices) off every sphere obstacle of the contact
    /// model as wholes: h² κ_t b(d) with d the distance from the closed triangle to the sphere and
    /// κ_t the mean of its vertices' κ_v, and the line search capped by additive CCD of each
    /// triangle against each sphere, so that no point of a triangle enters a sphere, not only its
    /// vertices. Planes and boxes keep their vertex terms alone: their allowed side is convex, so a
    /// triangle whose vertices are on it is on it. Call it after [`BackwardEulerStep::set_contact`]
    /// (which removes it); it does nothing without a sphere or in 2D.
    ///
    /// # Errors
    /// [`ParamError::Input`] for a triangle that names a vertex out of range or repeats one.
    pub fn set_contact_surface(&mut self, triangles: Vec<[u32; 3]>) -> Result<(), ParamError> {
        let n = self.x.len();
        check_triangles("BackwardEulerStep::set_contact_surface", &triangles, n)?;
        let mut free = vec![false; n];
        for &v in self.free.free_vertices() {
            free[v as usize] = true;
        }
        let (incident, start) = (&self.incident, &self.incident_start);
        let joined = |i: u32, j: u32| {
            incident[start[i as usize]..start[i as usize + 1]]
                .iter()
                .any(|&(_, other)| other == j)
        };
        if let Some(contact) = &mut self.contact {
            contact.set_surface(triangles, free, joined);
        }
        Ok(())
    }

    /// The contact model, if any ([`BackwardEulerStep::set_contact`]).
    pub fn contact(&self) -> Option<&ContactModel<D>> {
        self.contact.as_ref().map(|c| &c.model)
    }

    /// The smallest distance (m) of a free vertex from an obstacle at the unknowns `xf` (∞ without
    /// obstacles).
    pub fn smallest_contact_distance(&mut self, xf: &[f64]) -> f64 {
        self.expand(xf);
        match &self.contact {
            Some(contact) => contact.smallest_distance(self.free.free_vertices(), &self.x),
            None => f64::INFINITY,
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

    /// Which spring Hessian [`crate::NewtonProblem::hessian`] assembles: [`Definiteness::Exact`] (the
    /// default; indefinite under compression, quadratic convergence) or [`Definiteness::Clamped`]
    /// (positive definite with the masses, so every Newton matrix factors, but only linear
    /// convergence where springs are compressed).
    pub fn set_definiteness(&mut self, definiteness: Definiteness) {
        self.definiteness = definiteness;
    }

    /// Set θ, the share of every vertex's mass that the mass-split projection of
    /// [`crate::NewtonProblem::definite_hessian`] may spend on holding the compressed springs at
    /// it (docs/solvers.md §3.2): in [0, 1); larger keeps more springs exact, and leaves a
    /// smaller margin (1 − θ) M of definiteness. Default [`DEFAULT_DEFINITE_SHARE`].
    ///
    /// # Errors
    /// [`ParamError`] if `share` is not in [0, 1).
    pub fn set_definite_share(&mut self, share: f64) -> Result<(), ParamError> {
        crate::params::real(
            "BackwardEulerStep::definite_share",
            share,
            (0.0..1.0).contains(&share),
            "in [0, 1)",
        )?;
        self.definite_share = share;
        Ok(())
    }

    /// θ of the mass-split projection ([`BackwardEulerStep::set_definite_share`]).
    pub fn definite_share(&self) -> f64 {
        self.definite_share
    }

    /// How many compressed springs the last [`crate::NewtonProblem::definite_hessian`] weighted
    /// down (projected partly or wholly); the others had their exact blocks.
    pub fn projected_springs(&self) -> usize {
        self.projected_springs
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

/// [`ParamError::Input`] naming `field` for a triangle with a vertex ≥ `n` or a repeated vertex.
fn check_triangles(
    field: &'static str,
    triangles: &[[u32; 3]],
    n: usize,
) -> Result<(), ParamError> {
    for (k, t) in triangles.iter().enumerate() {
        if t.iter().any(|&v| v as usize >= n) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Err(ParamError::Input {
                field,
                problem: format!("triangle {k} {t:?} needs three distinct vertices below {n}"),
            });
        }
    }
    Ok(())
}
