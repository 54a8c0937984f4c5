//! The weakly compressible fluid: state, one step, and what a run reports.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use nalgebra::SVector;
use rayon::prelude::*;

use crate::kernel::Profile;
use crate::{
    DensityMethod, FluidParams, FluidSetup, Integrator, Kernel, NeighbourGrid, SphError, Walls,
};

/// Fewest grid cells allowed whatever the particle count (a 2D domain of 1024² cells).
const MIN_CELL_LIMIT: usize = 1 << 20;
/// Cells allowed per particle beyond [`MIN_CELL_LIMIT`]: a domain far larger than the fluid needs a
/// sparse search this crate does not have.
const CELLS_PER_PARTICLE: usize = 64;
/// A stable step below this fraction of the acoustic step C·h/c₀ means the flow has blown up.
const COLLAPSE_FRACTION: f64 = 1e-6;

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// The step taken, Δt (s).
    pub dt: f64,
    /// The stability bound at the step (s): the least of the CFL, force and viscous conditions
    /// ([`Evaluated::stable_step`]).
    pub bound: f64,
}

/// What [`Fluid::advance_to`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdvanceReport {
    /// Steps taken.
    pub steps: u64,
    /// Smallest step (s), not counting the last step when it was shortened to land on the end
    /// time (unless it was the only one); +∞ if no step was taken.
    pub min_dt: f64,
    /// Largest step (s), counted as `min_dt`; 0 if no step was taken.
    pub max_dt: f64,
}

/// Wall time spent in each phase of the force evaluations since the fluid was built (or
/// [`Fluid::reset_timings`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseTimings {
    /// Sorting particles by cell and permuting them into that order, then finding each particle's
    /// neighbours and the kernel derivative (dW/dr)/r at each pair. With the summation method this
    /// pass also sums the densities. With the continuity method it runs chunk by chunk together
    /// with the forces, so the pass's wall time is split between this and
    /// [`forces`](Self::forces) in proportion to their CPU time.
    pub neighbour_search: Duration,
    /// The equation of state, and the continuity equation's density rates (over the pairs) with
    /// the continuity method; with summation the density sums are counted in the search.
    pub density: Duration,
    /// Pressure, viscosity and gravity forces over the pairs.
    pub forces: Duration,
    /// Step size, the checks of the new state, and the position, velocity and density updates.
    pub integration: Duration,
    /// Force evaluations made (one per step, plus one for each [`Fluid::evaluated`] of a stale state).
    pub evaluations: u64,
}

/// Buffers of an evaluation, reused from one to the next.
#[derive(Debug, Clone, Default)]
struct Scratch<const D: usize> {
    /// The state being permuted into the new grid order (swapped with the fluid's arrays), and the
    /// kicked velocities of the continuity equation.
    positions: Vec<SVector<f64, D>>,
    velocities: Vec<SVector<f64, D>>,
    densities: Vec<f64>,
    ids: Vec<u32>,
    /// pᵢ/ρᵢ², the pressure force's per-particle term.
    pressure_terms: Vec<f64>,
    /// Each slot's neighbours and kernel derivatives, in chunks of [`PAIR_CHUNK`] slots.
    pairs: Vec<PairChunk>,
    /// `fluid_before[k]`: how many of the slots before k hold fluid particles (k = 0..=n), so that
    /// a run of slots holds fluid iff the counts at its ends differ.
    fluid_before: Vec<u32>,
    /// The state before a leapfrog step, put back if the step fails after the drift.
    backup: Backup<D>,
}

/// The state by slot before a leapfrog step: what the step's drift and re-sorting change.
#[derive(Debug, Clone, Default)]
struct Backup<const D: usize> {
    positions: Vec<SVector<f64, D>>,
    velocities: Vec<SVector<f64, D>>,
    densities: Vec<f64>,
    ids: Vec<u32>,
}

/// The state in the caller's particle order (fluid first, then boundary), built from the slots on
/// the first access after a change.
#[derive(Debug, Clone, Default)]
struct View<const D: usize> {
    positions: Vec<SVector<f64, D>>,
    velocities: Vec<SVector<f64, D>>,
    densities: Vec<f64>,
    pressures: Vec<f64>,
    accelerations: Vec<SVector<f64, D>>,
}

/// Sorted slots per [`PairChunk`]: each rayon job fills or reads whole chunks, so the lists need
/// no global prefix sum and their layout does not depend on the threads.
const PAIR_CHUNK: usize = 512;

/// The neighbours j ≠ i within the support of the sorted slots `first..first + ends.len()`, in grid
/// order, with (dW/dr)/r at their distance: found once per evaluation and used by the force loop
/// and the continuity equation's rates at the same positions, which so need no second search and
/// no second kernel evaluation. 12 bytes per pair (about 21 pairs a particle in 2D at h = 1.3 Δx,
/// 74 in 3D).
#[derive(Debug, Clone, Default)]
struct PairChunk {
    /// `ends[i]`: the end of slot first + i's pairs (the start is `ends[i - 1]`, or 0).
    ends: Vec<u32>,
    neighbours: Vec<u32>,
    derivatives: Vec<f64>,
}

impl PairChunk {
    /// The neighbours of the chunk's `i`-th slot and their (dW/dr)/r.
    #[inline]
    fn of(&self, i: usize) -> (&[u32], &[f64]) {
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        let end = self.ends[i] as usize;
        (&self.neighbours[start..end], &self.derivatives[start..end])
    }
}

/// A weakly compressible SPH fluid with fixed boundary particles, in `D` = 2 or 3 (the model, its
/// units and its validation: docs/sph.md).
///
/// Particles are numbered fluid first (`0..fluid_count()`), then boundary. Each step evaluates, on
/// a grid of cells one support radius wide (an O(n) neighbour search), the density (by summation,
/// or its rate by the continuity equation), the Tait pressure p = B((ρ/ρ₀)^γ − 1), the symmetric
/// pressure force −mᵢ Σⱼ mⱼ (pᵢ/ρᵢ² + pⱼ/ρⱼ²) ∇ᵢWᵢⱼ, Monaghan's artificial viscosity and gravity,
/// and advances by the stable step (CFL, force and viscous conditions). Boundary particles take
/// part in densities and forces with zero velocity and never move; their pressure is clamped at 0
/// so that walls push and never pull.
///
/// The state is the positions, velocities and (continuity method) densities, read from the fluid
/// at any time; what is evaluated from it (densities by summation, pressures, accelerations, the
/// stable step) is read through [`Fluid::evaluated`], which evaluates first if the state has moved,
/// so that no stale value can be read. A step that fails leaves the state exactly as it was.
///
/// Sums run over each particle's neighbours in grid order (cell by cell, and by particle index
/// within a cell), which depends on the positions only: results are the same, bit for bit, for any
/// number of threads.
///
/// The particles are stored in grid order: each evaluation sorts them by cell and permutes every
/// array into that order, so that the neighbour loops read contiguous memory however far the
/// particles have mixed. Every accessor returns particles in the caller's order (the setup's, fluid
/// first), gathered on the first access after a step.
///
/// ```
/// use hooke_sph::scenes::hydrostatic_2d;
/// let mut scene = hydrostatic_2d(0.1)?;
/// let mut fluid = hooke_sph::Fluid::new(scene.setup)?;
/// fluid.advance_to(0.01)?;
/// assert!(fluid.time() == 0.01 && fluid.steps() > 0);
/// let state = fluid.evaluated();
/// assert!(state.max_density_error() < 0.01 && state.pressures().iter().all(|p| p.is_finite()));
/// # Ok::<(), hooke_sph::SphError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Fluid<const D: usize> {
    params: FluidParams<D>,
    kernel: Kernel<D>,
    walls: Walls,
    domain_min: SVector<f64, D>,
    domain_max: SVector<f64, D>,
    mass: f64,
    fluid_count: usize,
    /// The state by slot: in the grid order of the last evaluation (the setup's order before the
    /// first).
    positions: Vec<SVector<f64, D>>,
    velocities: Vec<SVector<f64, D>>,
    densities: Vec<f64>,
    pressures: Vec<f64>,
    accelerations: Vec<SVector<f64, D>>,
    density_rates: Vec<f64>,
    /// Slot → particle index (fluid `0..fluid_count`, then boundary).
    ids: Vec<u32>,
    grid: NeighbourGrid<D>,
    scratch: Scratch<D>,
    /// The state in particle order, built on demand; reset whenever the state changes.
    view: OnceLock<View<D>>,
    /// Densities (summation), pressures, accelerations and the grid belong to the current state.
    evaluated: bool,
    time: f64,
    steps: u64,
    timings: PhaseTimings,
}

fn finite<const D: usize>(v: &SVector<f64, D>) -> Option<f64> {
    v.iter().copied().find(|x| !x.is_finite())
}

/// Runs `op` on a thread of the current rayon pool (the global pool, unless called inside
/// `ThreadPool::install`), the caller waiting. A step runs about eight parallel passes; each one
/// started from a thread outside the pool hands its work to the pool and waits to be woken (two
/// context switches), which on the 5,000-particle dam break made 45-60 context switches a step
/// against 1-4 from a pool thread, where the passes split by work stealing instead
/// (benches/results/sph-scene-speed.md; docs/sph.md, "Speed").
fn on_pool<R: Send>(op: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| op())
}

impl<const D: usize> Fluid<D> {
    /// Builds the fluid from `setup`, validating everything.
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] for a parameter out of range (naming it), a non-positive
    /// particle mass or an empty domain; [`SphError::EmptyFluid`]; [`SphError::LengthMismatch`];
    /// [`SphError::BadParticleValue`] for a NaN/infinite position or velocity or a non-positive
    /// density; [`SphError::OutsideDomain`]; [`SphError::GridTooLarge`].
    pub fn new(setup: FluidSetup<D>) -> Result<Self, SphError> {
        let p = setup.params;
        p.validate()?;
        let kernel = Kernel::new(p.kernel, p.smoothing_length)?;
        if !(setup.particle_mass.is_finite() && setup.particle_mass > 0.0) {
            return Err(SphError::InvalidParameter {
                name: "particle_mass",
                value: setup.particle_mass,
                allowed: "finite and > 0 (kg, or kg/m in 2D)",
            });
        }
        let nf = setup.fluid_positions.len();
        let nb = setup.boundary_positions.len();
        if nf == 0 {
            return Err(SphError::EmptyFluid);
        }
        let n = nf + nb;
        if u32::try_from(n).is_err() {
            return Err(SphError::InvalidParameter {
                name: "particle count",
                value: n as f64,
                allowed: "at most u32::MAX",
            });
        }
        for (what, len, expected) in [
            ("fluid_velocities", setup.fluid_velocities.len(), nf),
            ("fluid_densities", setup.fluid_densities.len(), nf),
            ("boundary_densities", setup.boundary_densities.len(), nb),
        ] {
            if len != 0 && len != expected {
                return Err(SphError::LengthMismatch {
                    what,
                    expected,
                    found: len,
                });
            }
        }
        let (lo, hi) = (setup.domain_min, setup.domain_max);
        for a in 0..D {
            if !(lo[a].is_finite() && hi[a].is_finite() && hi[a] > lo[a]) {
                return Err(SphError::InvalidParameter {
                    name: "domain",
                    value: hi[a] - lo[a],
                    allowed: "finite corners with domain_max > domain_min on every axis (m)",
                });
            }
        }
        let bad = |what, index, value| SphError::BadParticleValue { what, index, value };
        for (what, list) in [
            ("fluid particle", &setup.fluid_positions),
            ("boundary particle", &setup.boundary_positions),
        ] {
            for (i, x) in list.iter().enumerate() {
                if let Some(v) = finite(x) {
                    return Err(bad(what, i, v));
                }
                if (0..D).any(|a| x[a] < lo[a] || x[a] > hi[a]) {
                    return Err(SphError::OutsideDomain {
                        what,
                        index: i,
                        position: x.iter().copied().collect(),
                        min: lo.iter().copied().collect(),
                        max: hi.iter().copied().collect(),
                    });
                }
            }
        }
        for (i, v) in setup.fluid_velocities.iter().enumerate() {
            if let Some(x) = finite(v) {
                return Err(bad("fluid velocity", i, x));
            }
        }
        for (what, list) in [
            ("fluid density", &setup.fluid_densities),
            ("boundary density", &setup.boundary_densities),
        ] {
            if let Some((i, &r)) = list
                .iter()
                .enumerate()
                .find(|(_, r)| !(r.is_finite() && **r > 0.0))
            {
                return Err(bad(what, i, r));
            }
        }
        let grid = NeighbourGrid::new(
            lo,
            hi,
            kernel.support_radius(),
            MIN_CELL_LIMIT.max(CELLS_PER_PARTICLE.saturating_mul(n)),
        )?;

        let mut positions = setup.fluid_positions;
        positions.extend_from_slice(&setup.boundary_positions);
        let mut velocities = if setup.fluid_velocities.is_empty() {
            vec![SVector::zeros(); nf]
        } else {
            setup.fluid_velocities
        };
        velocities.resize(n, SVector::zeros());
        let mut densities = if setup.fluid_densities.is_empty() {
            vec![p.rest_density; nf]
        } else {
            setup.fluid_densities
        };
        if setup.boundary_densities.is_empty() {
            densities.resize(n, p.rest_density);
        } else {
            densities.extend_from_slice(&setup.boundary_densities);
        }
        Ok(Fluid {
            params: p,
            kernel,
            walls: setup.walls,
            domain_min: lo,
            domain_max: hi,
            mass: setup.particle_mass,
            fluid_count: nf,
            positions,
            velocities,
            densities,
            pressures: vec![0.0; n],
            accelerations: vec![SVector::zeros(); n],
            density_rates: vec![0.0; n],
            ids: (0..n as u32).collect(),
            grid,
            scratch: Scratch::default(),
            view: OnceLock::new(),
            evaluated: false,
            time: 0.0,
            steps: 0,
            timings: PhaseTimings::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &FluidParams<D> {
        &self.params
    }

    /// The kernel.
    pub fn kernel(&self) -> &Kernel<D> {
        &self.kernel
    }

    /// How the walls act.
    pub fn walls(&self) -> Walls {
        self.walls
    }

    /// The domain's corners (m).
    pub fn domain(&self) -> (SVector<f64, D>, SVector<f64, D>) {
        (self.domain_min, self.domain_max)
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The number of fluid particles.
    pub fn fluid_count(&self) -> usize {
        self.fluid_count
    }

    /// The number of boundary particles.
    pub fn boundary_count(&self) -> usize {
        self.positions.len() - self.fluid_count
    }

    /// The mass of each particle (kg, or kg/m in 2D).
    pub fn particle_mass(&self) -> f64 {
        self.mass
    }

    /// The total fluid mass m·n (kg, or kg/m in 2D): conserved by construction, since particles
    /// keep their mass and no particle is ever removed (a step that would take one out of the
    /// domain fails). What the flow can change is the volume the particles stand for:
    /// [`Evaluated::fluid_volume`].
    pub fn total_mass(&self) -> f64 {
        self.mass * self.fluid_count as f64
    }

    /// The state in particle order.
    fn view(&self) -> &View<D> {
        self.view.get_or_init(|| {
            let n = self.ids.len();
            let mut slot_of = vec![0u32; n];
            for (k, &i) in self.ids.iter().enumerate() {
                slot_of[i as usize] = k as u32;
            }
            let slot_of = &slot_of;
            View {
                positions: in_particle_order(slot_of, &self.positions),
                velocities: in_particle_order(slot_of, &self.velocities),
                densities: in_particle_order(slot_of, &self.densities),
                pressures: in_particle_order(slot_of, &self.pressures),
                accelerations: in_particle_order(slot_of, &self.accelerations),
            }
        })
    }

    /// Fluid positions (m), in particle order (as every accessor).
    pub fn positions(&self) -> &[SVector<f64, D>] {
        &self.view().positions[..self.fluid_count]
    }

    /// Fluid velocities (m/s).
    pub fn velocities(&self) -> &[SVector<f64, D>] {
        &self.view().velocities[..self.fluid_count]
    }

    /// Boundary particle positions (m).
    pub fn boundary_positions(&self) -> &[SVector<f64, D>] {
        &self.view().positions[self.fluid_count..]
    }

    /// The state with everything evaluated from it: densities, pressures, accelerations and the
    /// stable step, all of the current positions, velocities and densities. Evaluates them first
    /// if a step has moved the particles since the last evaluation (after a symplectic Euler step;
    /// the next step reuses the evaluation, so a run that reads every frame pays nothing extra).
    /// The view borrows the fluid, so it cannot outlive the state it describes.
    pub fn evaluated(&mut self) -> Evaluated<'_, D> {
        self.refresh();
        Evaluated { fluid: self }
    }

    /// Time spent per phase.
    pub fn timings(&self) -> PhaseTimings {
        self.timings
    }

    /// Zeroes [`timings`](Self::timings).
    pub fn reset_timings(&mut self) {
        self.timings = PhaseTimings::default();
    }

    /// Evaluates densities (summation), pressures and accelerations for the current state if they
    /// are stale.
    fn refresh(&mut self) {
        if !self.evaluated {
            self.evaluate();
        }
    }

    /// Kinetic energy ½ m Σ |vᵢ|² of the fluid (J, or J/m in 2D), summed in index order.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.mass
            * self
                .velocities()
                .iter()
                .map(|v| v.norm_squared())
                .sum::<f64>()
    }

    /// The largest fluid speed (m/s).
    pub fn max_speed(&self) -> f64 {
        // Boundary particles are at rest: the maximum over every slot is the fluid's.
        self.velocities
            .par_iter()
            .map(|v| v.norm())
            .reduce(|| 0.0, f64::max)
    }

    /// The front along `axis`: the largest coordinate over fluid particles with at least
    /// `min_neighbours` fluid neighbours within the kernel's support (so that spray is excluded);
    /// `None` if no particle has that many. The dam-break front of docs/scenes.md §7 is
    /// `front(0, 3)`.
    ///
    /// # Panics
    /// If `axis` ≥ `D`.
    pub fn front(&mut self, axis: usize, min_neighbours: usize) -> Option<f64> {
        assert!(axis < D, "axis {axis} out of range");
        self.refresh();
        let support2 = self.kernel.support_radius().powi(2);
        let nf = self.fluid_count as u32;
        let grid = &self.grid;
        let (positions, ids) = (&self.positions, &self.ids);
        (0..ids.len())
            .into_par_iter()
            .filter(|&k| ids[k] < nf)
            .filter_map(|k| {
                let x = positions[k];
                let mut count = 0usize;
                grid.for_each_candidate_run(&x, |run| {
                    for s in run {
                        if s != k && ids[s] < nf && (x - positions[s]).norm_squared() < support2 {
                            count += 1;
                        }
                    }
                });
                (count >= min_neighbours).then_some(x[axis])
            })
            .reduce_with(f64::max)
    }

    /// The stability bound of the evaluated state (s): the least of
    ///
    /// - the CFL condition C·h/(c₀ + |v|max);
    /// - the force condition f·√(h/|a|max);
    /// - the viscous condition of the artificial viscosity, Δt ≤ 0.125 h²/ν with its equivalent
    ///   kinematic viscosity ν = α h c₀ / (2(D + 2)), that is Δt ≤ (D + 2) h / (4 α c₀)
    ///   (docs/sph.md, "Time step"). At the scenes' α = 0.1 and C = 0.4 it is 25 times the CFL
    ///   bound (31 times in 3D) and never binds; it matters from α ≈ 2.5 on.
    fn stable_step(&self) -> f64 {
        let p = &self.params;
        let h = p.smoothing_length;
        // Boundary particles are at rest with zero acceleration: the maxima over every slot are
        // the fluid's. One pass for both.
        let (v2_max, a2_max) = self
            .velocities
            .par_iter()
            .zip(self.accelerations.par_iter())
            .map(|(v, a)| (v.norm_squared(), a.norm_squared()))
            .reduce(|| (0.0, 0.0), |x, y| (x.0.max(y.0), x.1.max(y.1)));
        let (v_max, a_max) = (v2_max.sqrt(), a2_max.sqrt());
        let cfl = p.courant * h / (p.sound_speed + v_max);
        let force = if a_max > 0.0 {
            p.force_factor * (h / a_max).sqrt()
        } else {
            f64::INFINITY
        };
        cfl.min(force).min(self.viscous_step())
    }

    /// The viscous condition (D + 2) h / (4 α c₀) (s), +∞ without viscosity: see
    /// [`Evaluated::stable_step`].
    pub fn viscous_step(&self) -> f64 {
        let p = &self.params;
        if p.viscosity_alpha > 0.0 {
            (D as f64 + 2.0) * p.smoothing_length / (4.0 * p.viscosity_alpha * p.sound_speed)
        } else {
            f64::INFINITY
        }
    }

    /// The acoustic step C·h/c₀ (s): the stable step of a fluid at rest.
    pub fn acoustic_step(&self) -> f64 {
        self.params.courant * self.params.smoothing_length / self.params.sound_speed
    }

    /// Takes one step: the stable step, or the fixed step if one is set.
    ///
    /// A step is all or nothing: if it fails, the fluid is exactly as before it (positions,
    /// velocities, densities, time and step count, bit for bit), whichever the integrator.
    ///
    /// # Errors
    /// [`SphError::StepAboveBound`] if the fixed step exceeds the bound; [`SphError::StepCollapsed`];
    /// [`SphError::LeftDomain`] or [`SphError::NonFiniteState`] if the step would move a fluid
    /// particle out of the domain (with boundary-particle walls) or make a value non-finite.
    pub fn step(&mut self) -> Result<StepReport, SphError> {
        on_pool(|| self.step_at_most(f64::INFINITY))
    }

    /// Steps until [`time`](Self::time) reaches `t_end` (s), shortening the last step to land on
    /// it exactly. Does nothing if `t_end` ≤ the current time.
    ///
    /// # Errors
    /// As [`step`](Self::step); the steps before the failing one are kept, the failing one leaves
    /// nothing behind.
    pub fn advance_to(&mut self, t_end: f64) -> Result<AdvanceReport, SphError> {
        if !t_end.is_finite() {
            return Err(SphError::InvalidParameter {
                name: "end time",
                value: t_end,
                allowed: "finite (s)",
            });
        }
        on_pool(|| self.advance_on_pool(t_end))
    }

    fn advance_on_pool(&mut self, t_end: f64) -> Result<AdvanceReport, SphError> {
        let mut report = AdvanceReport {
            steps: 0,
            min_dt: f64::INFINITY,
            max_dt: 0.0,
        };
        // Remainders below this are rounding, not time left.
        let slack = 1e-9 * self.acoustic_step();
        let mut last_shortened = None;
        while t_end - self.time > slack {
            let remaining = t_end - self.time;
            let step = self.step_at_most(remaining)?;
            report.steps += 1;
            if step.dt == remaining && step.dt < step.bound {
                self.time = t_end;
                last_shortened = Some(step.dt);
                continue;
            }
            report.min_dt = report.min_dt.min(step.dt);
            report.max_dt = report.max_dt.max(step.dt);
        }
        if let (Some(dt), true) = (last_shortened, report.max_dt == 0.0) {
            report.min_dt = dt;
            report.max_dt = dt;
        }
        Ok(report)
    }

    /// One step of at most `max_dt` (s). Everything that can fail is checked before anything
    /// moves, except the leapfrog's second half-kick, which needs the forces at the new
    /// positions: that step keeps a copy of the state and puts it back if the kick fails.
    fn step_at_most(&mut self, max_dt: f64) -> Result<StepReport, SphError> {
        self.refresh();
        let start = Instant::now();
        let bound = self.stable_step();
        let acoustic = self.acoustic_step();
        if bound < COLLAPSE_FRACTION * acoustic {
            return Err(SphError::StepCollapsed {
                bound,
                acoustic,
                time: self.time,
            });
        }
        let dt = match self.params.fixed_step {
            Some(dt) if dt > bound => {
                return Err(SphError::StepAboveBound {
                    step: dt,
                    bound,
                    time: self.time,
                })
            }
            Some(dt) => dt,
            None => bound,
        }
        .min(max_dt);
        let leapfrog = self.params.integrator == Integrator::Leapfrog;
        let kick = if leapfrog { 0.5 * dt } else { dt };
        self.kick_and_check(dt, kick)?;
        let continuity = self.params.density == DensityMethod::Continuity;
        if continuity {
            self.timings.integration += start.elapsed();
            let bad = self.continuity_rates(dt);
            if bad {
                let (i, k) = self
                    .first_slot(|k| {
                        let r = self.densities[k] + dt * self.density_rates[k];
                        !(r.is_finite() && r > 0.0)
                    })
                    .expect("a density the rates' pass found bad");
                let r = self.densities[k] + dt * self.density_rates[k];
                return Err(self.non_finite("density", i, Some(r)));
            }
        }
        let start = Instant::now();
        if leapfrog {
            let (b, s) = (&mut self.scratch.backup, &self.velocities);
            b.velocities.clone_from(s);
            b.positions.clone_from(&self.positions);
            b.densities.clone_from(&self.densities);
            b.ids.clone_from(&self.ids);
        }

        // The kick (the velocities kick_and_check computed, the same arithmetic), the drift and
        // the densities' update, in one pass.
        let nf = self.fluid_count as u32;
        let clamp = self.walls == Walls::Clamp;
        let (lo, hi) = (self.domain_min, self.domain_max);
        let (kicked, rates) = (&self.scratch.velocities, &self.density_rates);
        self.velocities
            .par_iter_mut()
            .zip(self.positions.par_iter_mut())
            .zip(self.densities.par_iter_mut())
            .zip(kicked.par_iter().zip(rates.par_iter()))
            .zip(self.ids.par_iter())
            .for_each(|((((v, x), r), (kicked, rate)), &i)| {
                if continuity {
                    *r += dt * rate;
                }
                if i >= nf {
                    return;
                }
                *v = *kicked;
                *x += *v * dt;
                if clamp {
                    for axis in 0..D {
                        if x[axis] < lo[axis] {
                            x[axis] = lo[axis];
                            v[axis] = 0.0;
                        } else if x[axis] > hi[axis] {
                            x[axis] = hi[axis];
                            v[axis] = 0.0;
                        }
                    }
                }
            });
        self.evaluated = false;
        self.view = OnceLock::new();
        self.timings.integration += start.elapsed();
        if leapfrog {
            self.evaluate();
            let second = Instant::now();
            let bad = self
                .velocities
                .par_iter_mut()
                .zip(self.accelerations.par_iter())
                .zip(self.ids.par_iter())
                .map(|((v, a), &i)| {
                    if i < nf {
                        *v += a * kick;
                    }
                    finite(v).is_some()
                })
                .reduce(|| false, |a, b| a | b);
            self.view = OnceLock::new();
            if bad {
                let (i, k) = self
                    .first_slot(|k| finite(&self.velocities[k]).is_some())
                    .expect("a velocity the kick's pass found bad");
                let error = self.non_finite("velocity", i, finite(&self.velocities[k]));
                self.restore_backup();
                self.timings.integration += second.elapsed();
                return Err(error);
            }
            self.timings.integration += second.elapsed();
        }
        self.time += dt;
        self.steps += 1;
        Ok(StepReport { dt, bound })
    }

    /// Puts back the state [`step_at_most`](Self::step_at_most) saved before a leapfrog step. The
    /// evaluation (grid, pairs, pressures, accelerations) is of the failed state, so it is marked
    /// stale: the next access evaluates the restored state again, to the same values as before
    /// the step, since an evaluation depends on the state only (not on the storage order).
    fn restore_backup(&mut self) {
        let b = &mut self.scratch.backup;
        std::mem::swap(&mut self.positions, &mut b.positions);
        std::mem::swap(&mut self.velocities, &mut b.velocities);
        std::mem::swap(&mut self.densities, &mut b.densities);
        std::mem::swap(&mut self.ids, &mut b.ids);
        self.evaluated = false;
        self.view = OnceLock::new();
    }

    fn non_finite(&self, what: &'static str, index: usize, value: Option<f64>) -> SphError {
        SphError::NonFiniteState {
            what,
            index,
            value: value.unwrap_or(f64::NAN),
            step: self.steps + 1,
            time: self.time,
        }
    }

    /// The particle of smallest index (and its slot) for which `bad(slot)` holds, or `None`: the
    /// first in particle order, whatever the storage order.
    fn first_slot(&self, bad: impl Fn(usize) -> bool + Sync) -> Option<(usize, usize)> {
        (0..self.ids.len())
            .into_par_iter()
            .filter(|&k| bad(k))
            .map(|k| (self.ids[k] as usize, k))
            .min()
    }

    /// Writes the kicked velocities v + `kick`·a of every slot into the scratch (zero for boundary
    /// particles, whose velocity and acceleration are zero), and checks, before anything moves,
    /// that they and the drifted positions x + `dt`·v' of the fluid particles are finite and (with
    /// boundary-particle walls) inside the domain.
    fn kick_and_check(&mut self, dt: f64, kick: f64) -> Result<(), SphError> {
        let nf = self.fluid_count as u32;
        let keep_inside = self.walls == Walls::BoundaryParticles;
        let (lo, hi) = (self.domain_min, self.domain_max);
        let n = self.positions.len();
        let kicked = &mut self.scratch.velocities;
        kicked.resize(n, SVector::zeros());
        let outside = |x: &SVector<f64, D>| (0..D).any(|a| x[a] < lo[a] || x[a] > hi[a]);
        let bad = kicked
            .par_iter_mut()
            .zip(self.velocities.par_iter())
            .zip(self.accelerations.par_iter())
            .zip(self.positions.par_iter().zip(self.ids.par_iter()))
            .map(|(((kicked, v), a), (x, &i))| {
                *kicked = v + a * kick;
                if i >= nf {
                    return false;
                }
                let x = x + *kicked * dt;
                finite(kicked).is_some() || finite(&x).is_some() || (keep_inside && outside(&x))
            })
            .reduce(|| false, |a, b| a | b);
        if !bad {
            return Ok(());
        }
        let candidate = |k: usize| {
            let v = self.velocities[k] + self.accelerations[k] * kick;
            (v, self.positions[k] + v * dt)
        };
        let (i, k) = self
            .first_slot(|k| {
                if self.ids[k] >= nf {
                    return false;
                }
                let (v, x) = candidate(k);
                finite(&v).is_some() || finite(&x).is_some() || (keep_inside && outside(&x))
            })
            .expect("a particle the kick's pass found bad");
        let (v, x) = candidate(k);
        Err(match (finite(&v), finite(&x)) {
            (Some(value), _) => self.non_finite("velocity", i, Some(value)),
            (None, Some(value)) => self.non_finite("position", i, Some(value)),
            (None, None) => SphError::LeftDomain {
                index: i,
                position: x.iter().copied().collect(),
                step: self.steps + 1,
                time: self.time,
            },
        })
    }

    /// The Tait pressure of density `rho`, clamped at 0 where negative pressures are not wanted.
    #[inline]
    fn pressure(params: &FluidParams<D>, stiffness: f64, rho: f64, clamp: bool) -> f64 {
        let ratio = rho / params.rest_density;
        let power = if params.gamma == 7.0 {
            let r2 = ratio * ratio;
            r2 * r2 * r2 * ratio
        } else {
            ratio.powf(params.gamma)
        };
        let p = stiffness * (power - 1.0);
        if clamp {
            p.max(0.0)
        } else {
            p
        }
    }

    /// The continuity equation's rates dρᵢ/dt = Σⱼ m (vᵢ' − vⱼ')·∇ᵢWᵢⱼ at the evaluated positions for
    /// the kicked velocities v' = v + kick·a of [`kick_and_check`](Self::kick_and_check), for every
    /// particle, into `density_rates`; returns whether some ρ + `dt`·dρ/dt would be non-finite or
    /// non-positive. Using the kicked velocities makes (x, ρ) move together with the new
    /// velocity, as symplectic Euler and leapfrog need: with the old ones the acoustic waves grow
    /// without bound.
    fn continuity_rates(&mut self, dt: f64) -> bool {
        let start = Instant::now();
        let bad = continuity_loop(
            &self.scratch.pairs,
            &self.positions,
            &self.scratch.velocities,
            self.mass,
            (&self.densities, dt),
            &mut self.density_rates,
        );
        self.timings.density += start.elapsed();
        bad
    }

    /// Rebuilds the grid and evaluates densities (summation), pressures and accelerations for the
    /// current positions, velocities and densities.
    fn evaluate(&mut self) {
        let t0 = Instant::now();
        let n = self.positions.len();
        let nf = self.fluid_count as u32;
        self.grid.rebuild_by_key(&self.positions, &self.ids);
        // Permute the state into the new grid order: the slots were in the last evaluation's order,
        // so this gathers from nearby slots.
        let s = &mut self.scratch;
        let order = self.grid.order();
        s.positions.resize(n, SVector::zeros());
        s.velocities.resize(n, SVector::zeros());
        s.densities.resize(n, 0.0);
        s.ids.resize(n, 0);
        s.pressure_terms.resize(n, 0.0);
        let (positions, velocities, densities, ids) = (
            &self.positions,
            &self.velocities,
            &self.densities,
            &self.ids,
        );
        s.positions
            .par_iter_mut()
            .zip(s.velocities.par_iter_mut())
            .zip(s.densities.par_iter_mut())
            .zip(s.ids.par_iter_mut())
            .zip(order.par_iter())
            .for_each(|((((x, v), r), id), &k)| {
                let k = k as usize;
                *x = positions[k];
                *v = velocities[k];
                *r = densities[k];
                *id = ids[k];
            });
        std::mem::swap(&mut self.positions, &mut s.positions);
        std::mem::swap(&mut self.velocities, &mut s.velocities);
        std::mem::swap(&mut self.densities, &mut s.densities);
        std::mem::swap(&mut self.ids, &mut s.ids);
        self.view = OnceLock::new();

        let params = self.params;
        let kernel = self.kernel;
        let grid = &self.grid;
        let support2 = kernel.support_radius().powi(2);
        let m = self.mass;
        let summation = params.density == DensityMethod::Summation;
        s.pairs
            .resize_with(n.div_ceil(PAIR_CHUNK), PairChunk::default);
        let b = params.tait_stiffness();
        let pressures = |pressures: &mut [f64], terms: &mut [f64], densities: &[f64]| {
            pressures
                .par_iter_mut()
                .zip(terms.par_iter_mut())
                .zip(densities.par_iter())
                .zip(self.ids.par_iter())
                .for_each(|(((p, term), &r), &i)| {
                    *p = Self::pressure(&params, b, r, summation || i >= nf);
                    *term = *p / (r * r);
                });
        };
        let h = params.smoothing_length;
        let constants = ForceConstants {
            m,
            h,
            eta2: 0.01 * h * h,
            alpha_c: params.viscosity_alpha * params.sound_speed,
            g: params.gravity,
            fluid_count: nf,
        };
        let (search, density, forces);
        if summation {
            // Densities first (with the pairs), then pressures, then forces over the pairs.
            let (sx, pairs, out) = (&self.positions, &mut s.pairs, &mut self.densities);
            match (kernel.cubic_profile(), kernel.wendland_profile()) {
                (Some(k), _) => summation_pair_loop(k, grid, sx, support2, m, pairs, out),
                (_, Some(k)) => summation_pair_loop(k, grid, sx, support2, m, pairs, out),
                _ => unreachable!("a kernel is the cubic spline or Wendland's quintic"),
            }
            let t1 = Instant::now();
            pressures(&mut self.pressures, &mut s.pressure_terms, &self.densities);
            let t2 = Instant::now();
            let inputs = ForceInputs {
                c: &constants,
                ids: &self.ids,
                sx: &self.positions,
                sv: &self.velocities,
                sr: &self.densities,
                terms: &s.pressure_terms,
            };
            self.accelerations
                .par_chunks_mut(PAIR_CHUNK)
                .zip(s.pairs.par_iter())
                .enumerate()
                .for_each(|(c, (out, chunk))| force_chunk(c, chunk, &inputs, out));
            (search, density, forces) = (t1 - t0, t2 - t1, t2.elapsed());
        } else {
            // The densities are the state's: pressures first, then, chunk by chunk, the pairs
            // and the forces over them while they are in cache.
            let t1 = Instant::now();
            pressures(&mut self.pressures, &mut s.pressure_terms, &self.densities);
            let t2 = Instant::now();
            let inputs = ForceInputs {
                c: &constants,
                ids: &self.ids,
                sx: &self.positions,
                sv: &self.velocities,
                sr: &self.densities,
                terms: &s.pressure_terms,
            };
            // Which runs of slots hold fluid: a boundary particle looks for fluid neighbours only.
            s.fluid_before.resize(n + 1, 0);
            let mut count = 0u32;
            for (before, &i) in s.fluid_before.iter_mut().zip(self.ids.iter()) {
                *before = count;
                count += u32::from(i < nf);
            }
            s.fluid_before[n] = count;
            let cpu = [AtomicU64::new(0), AtomicU64::new(0)];
            let pair_search = PairSearch {
                grid,
                support2,
                fluid_before: &s.fluid_before,
            };
            let ps = &pair_search;
            let (pairs, out) = (&mut s.pairs, &mut self.accelerations);
            match (kernel.cubic_profile(), kernel.wendland_profile()) {
                (Some(k), _) => pair_force_loop(k, ps, &inputs, pairs, out, &cpu),
                (_, Some(k)) => pair_force_loop(k, ps, &inputs, pairs, out, &cpu),
                _ => unreachable!("a kernel is the cubic spline or Wendland's quintic"),
            }
            // The pass's wall time, split between search and forces as their CPU times.
            let wall = t2.elapsed();
            let (a, f) = (cpu[0].load(Relaxed) as f64, cpu[1].load(Relaxed) as f64);
            let share = if a + f > 0.0 { a / (a + f) } else { 0.5 };
            let pass_search = wall.mul_f64(share);
            (search, density, forces) = ((t1 - t0) + pass_search, t2 - t1, wall - pass_search);
        }
        self.evaluated = true;
        self.timings.neighbour_search += search;
        self.timings.density += density;
        self.timings.forces += forces;
        self.timings.evaluations += 1;
    }
}

/// The fluid's state with everything evaluated from it, from [`Fluid::evaluated`]: densities,
/// pressures, accelerations and the stable step are those of the positions, velocities and
/// densities shown beside them, whatever the integrator and density method. It borrows the
/// fluid, so no step can run while it is held.
///
/// Units (docs/sph.md, "Units"): SI; in 2D the fluid is a slice of unit depth, so densities are
/// kg/m³ and pressures Pa in 2D as in 3D, while masses are per metre of depth (kg/m) in 2D.
#[derive(Debug, Clone, Copy)]
pub struct Evaluated<'a, const D: usize> {
    fluid: &'a Fluid<D>,
}

impl<'a, const D: usize> Evaluated<'a, D> {
    /// The fluid (its parameters, time, counts and state).
    pub fn fluid(&self) -> &'a Fluid<D> {
        self.fluid
    }

    /// Fluid positions (m), in particle order.
    pub fn positions(&self) -> &'a [SVector<f64, D>] {
        self.fluid.positions()
    }

    /// Fluid velocities (m/s).
    pub fn velocities(&self) -> &'a [SVector<f64, D>] {
        self.fluid.velocities()
    }

    /// Fluid densities ρ (kg/m³; > 0): by summation over the current positions, or the
    /// continuity equation's integrated state.
    pub fn densities(&self) -> &'a [f64] {
        &self.fluid.view().densities[..self.fluid.fluid_count]
    }

    /// Boundary particle densities (kg/m³), as [`densities`](Self::densities).
    pub fn boundary_densities(&self) -> &'a [f64] {
        &self.fluid.view().densities[self.fluid.fluid_count..]
    }

    /// Fluid pressures p = B((ρ/ρ₀)^γ − 1) (Pa), clamped at 0 with the summation method.
    pub fn pressures(&self) -> &'a [f64] {
        &self.fluid.view().pressures[..self.fluid.fluid_count]
    }

    /// Boundary particle pressures (Pa), clamped at 0 so that walls push and never pull.
    pub fn boundary_pressures(&self) -> &'a [f64] {
        &self.fluid.view().pressures[self.fluid.fluid_count..]
    }

    /// Fluid accelerations (m/s²): pressure, artificial viscosity and gravity.
    pub fn accelerations(&self) -> &'a [SVector<f64, D>] {
        &self.fluid.view().accelerations[..self.fluid.fluid_count]
    }

    /// The largest density error maxᵢ |ρᵢ/ρ₀ − 1| over fluid particles (dimensionless).
    pub fn max_density_error(&self) -> f64 {
        let f = self.fluid;
        let r0 = f.params.rest_density;
        let nf = f.fluid_count as u32;
        f.densities
            .par_iter()
            .zip(f.ids.par_iter())
            .filter(|(_, &i)| i < nf)
            .map(|(r, _)| (r / r0 - 1.0).abs())
            .reduce(|| 0.0, f64::max)
    }

    /// The fluid's volume Σᵢ m/ρᵢ over fluid particles (m³; in 2D m² per metre of depth), summed
    /// in particle order: the space the particles stand for. Weakly compressible, it stays within
    /// the density error of the initial volume.
    pub fn fluid_volume(&self) -> f64 {
        let m = self.fluid.mass;
        self.densities().iter().map(|r| m / r).sum()
    }

    /// The stability bound of the next step (s): the least of the CFL condition
    /// C·h/(c₀ + |v|max), the force condition f·√(h/|a|max) and the artificial viscosity's
    /// condition (D + 2) h / (4 α c₀) ([`Fluid::viscous_step`]; docs/sph.md, "Time step").
    pub fn stable_step(&self) -> f64 {
        self.fluid.stable_step()
    }
}

/// A neighbour loop's scratch, one per rayon job: the neighbours of the particle at hand as
/// (sorted slot, squared distance), in grid order.
type Neighbours = Vec<(u32, f64)>;

/// Fills `out` with the sorted slots j ≠ `skip` with |`x` − xⱼ|² < `support2`, in grid order (so the
/// sums over them run in the same order whatever the threads), and returns how many there are.
/// Every candidate is written and the count advanced by whether it is inside: no branch per
/// candidate, whose outcome (about a third are inside, in no pattern once the particles have
/// mixed) would be mispredicted.
#[inline(always)]
fn collect_neighbours<const D: usize>(
    grid: &NeighbourGrid<D>,
    sx: &[SVector<f64, D>],
    x: &SVector<f64, D>,
    skip: usize,
    support2: f64,
    out: &mut Neighbours,
) -> usize {
    let mut count = 0;
    grid.for_each_candidate_run(x, |run| {
        let needed = count + run.len();
        if out.len() < needed {
            out.resize(needed, (0, 0.0));
        }
        let start = run.start;
        for (offset, y) in sx[run].iter().enumerate() {
            let j = start + offset;
            let r2 = (x - y).norm_squared();
            out[count] = (j as u32, r2);
            // `&`, not `&&`: no branch.
            count += usize::from((r2 < support2) & (j != skip));
        }
    });
    count
}

/// Finds every slot's neighbours and their (dW/dr)/r into `chunks`, and its density
/// ρ = m Σⱼ W(rᵢⱼ) over every particle within the support, itself included, into `densities`.
fn summation_pair_loop<K: Profile, const D: usize>(
    kernel: K,
    grid: &NeighbourGrid<D>,
    sx: &[SVector<f64, D>],
    support2: f64,
    m: f64,
    chunks: &mut [PairChunk],
    densities: &mut [f64],
) {
    chunks
        .par_iter_mut()
        .zip(densities.par_chunks_mut(PAIR_CHUNK))
        .enumerate()
        .for_each_init(Neighbours::new, |nb, (c, (chunk, rho))| {
            chunk.ends.clear();
            chunk.neighbours.clear();
            chunk.derivatives.clear();
            for (i, rho) in rho.iter_mut().enumerate() {
                let k = c * PAIR_CHUNK + i;
                // The particle itself is in the list, in its place in grid order, for the density;
                // it is no pair.
                let count = collect_neighbours(grid, sx, &sx[k], usize::MAX, support2, nb);
                let found = &nb[..count];
                let mut sum = 0.0;
                for &(_, r2) in found {
                    sum += kernel.value(r2.sqrt());
                }
                *rho = m * sum;
                for &(j, r2) in found {
                    if j as usize != k {
                        chunk.neighbours.push(j);
                        chunk.derivatives.push(kernel.derivative_over_r(r2.sqrt()));
                    }
                }
                chunk.ends.push(chunk.neighbours.len() as u32);
            }
        });
}

/// What the pair search of the continuity method reads besides the particles.
struct PairSearch<'a, const D: usize> {
    grid: &'a NeighbourGrid<D>,
    /// The squared support radius (m²).
    support2: f64,
    /// `fluid_before[k]`: fluid particles among the slots before k.
    fluid_before: &'a [u32],
}

/// As [`collect_neighbours`], for a boundary particle: its fluid neighbours only, skipping runs of
/// slots without fluid (the walls away from the water) without looking at them.
#[inline(always)]
fn collect_fluid_neighbours<const D: usize>(
    search: &PairSearch<'_, D>,
    inputs: &ForceInputs<'_, D>,
    x: &SVector<f64, D>,
    out: &mut Neighbours,
) -> usize {
    let (sx, ids, nf) = (inputs.sx, inputs.ids, inputs.c.fluid_count);
    let mut count = 0;
    search.grid.for_each_candidate_run(x, |run| {
        if search.fluid_before[run.end] == search.fluid_before[run.start] {
            return;
        }
        let needed = count + run.len();
        if out.len() < needed {
            out.resize(needed, (0, 0.0));
        }
        let start = run.start;
        for (offset, (y, &id)) in sx[run.clone()].iter().zip(&ids[run]).enumerate() {
            let r2 = (x - y).norm_squared();
            out[count] = ((start + offset) as u32, r2);
            count += usize::from((r2 < search.support2) & (id < nf));
        }
    });
    count
}

/// Finds the neighbours of the slots of chunk `c` and their (dW/dr)/r into `chunk`. A boundary
/// particle's list holds its fluid neighbours only: its velocity and acceleration are zero, so a
/// boundary neighbour adds exactly zero to its continuity rate (and its force is not computed);
/// leaving them out changes no value.
#[inline(always)]
fn find_pairs<K: Profile, const D: usize>(
    kernel: K,
    search: &PairSearch<'_, D>,
    inputs: &ForceInputs<'_, D>,
    (c, len): (usize, usize),
    chunk: &mut PairChunk,
    nb: &mut Neighbours,
) {
    let sx = inputs.sx;
    chunk.ends.clear();
    chunk.neighbours.clear();
    chunk.derivatives.clear();
    for k in c * PAIR_CHUNK..c * PAIR_CHUNK + len {
        let count = if inputs.ids[k] < inputs.c.fluid_count {
            collect_neighbours(search.grid, sx, &sx[k], k, search.support2, nb)
        } else {
            collect_fluid_neighbours(search, inputs, &sx[k], nb)
        };
        let found = &nb[..count];
        // A loop without branches, which the compiler vectorises.
        chunk.neighbours.extend(found.iter().map(|&(j, _)| j));
        let base = chunk.derivatives.len();
        chunk.derivatives.resize(base + count, 0.0);
        for (f, &(_, r2)) in chunk.derivatives[base..].iter_mut().zip(found) {
            *f = kernel.derivative_over_r(r2.sqrt());
        }
        chunk.ends.push(chunk.neighbours.len() as u32);
    }
}

/// Chunk by chunk, finds the slots' neighbours and (dW/dr)/r into `chunks` and then their
/// accelerations into `out` from them while they are in cache; adds the CPU time of each part (ns)
/// to `cpu`.
fn pair_force_loop<K: Profile, const D: usize>(
    kernel: K,
    search: &PairSearch<'_, D>,
    inputs: &ForceInputs<'_, D>,
    chunks: &mut [PairChunk],
    out: &mut [SVector<f64, D>],
    cpu: &[AtomicU64; 2],
) {
    chunks
        .par_iter_mut()
        .zip(out.par_chunks_mut(PAIR_CHUNK))
        .enumerate()
        .for_each_init(Neighbours::new, |nb, (c, (chunk, out))| {
            let t0 = Instant::now();
            find_pairs(kernel, search, inputs, (c, out.len()), chunk, nb);
            let t1 = Instant::now();
            force_chunk(c, chunk, inputs, out);
            cpu[0].fetch_add((t1 - t0).as_nanos() as u64, Relaxed);
            cpu[1].fetch_add(t1.elapsed().as_nanos() as u64, Relaxed);
        });
}

/// dρᵢ/dt = Σⱼ m (vᵢ − vⱼ)·∇ᵢWᵢⱼ for every sorted slot into `out`, over the pairs of
/// [`pair_force_loop`]; returns whether some ρᵢ + Δt·dρᵢ/dt, with `(densities, dt)`, is
/// non-finite or non-positive.
fn continuity_loop<const D: usize>(
    chunks: &[PairChunk],
    sx: &[SVector<f64, D>],
    sv: &[SVector<f64, D>],
    m: f64,
    (densities, dt): (&[f64], f64),
    out: &mut [f64],
) -> bool {
    out.par_chunks_mut(PAIR_CHUNK)
        .zip(chunks.par_iter())
        .enumerate()
        .map(|(c, (rates, chunk))| {
            let mut bad = false;
            for (i, rate) in rates.iter_mut().enumerate() {
                let k = c * PAIR_CHUNK + i;
                let (xi, vi) = (sx[k], sv[k]);
                let (js, fs) = chunk.of(i);
                let mut d = 0.0;
                for (&j, &f) in js.iter().zip(fs) {
                    let j = j as usize;
                    let rij = xi - sx[j];
                    let vij = vi - sv[j];
                    d += m * f * vij.dot(&rij);
                }
                *rate = d;
                let r = densities[k] + dt * d;
                bad |= !(r.is_finite() && r > 0.0);
            }
            bad
        })
        .reduce(|| false, |a, b| a | b)
}

/// What the force loop needs besides the particle data.
struct ForceConstants<const D: usize> {
    m: f64,
    h: f64,
    /// η² = 0.01 h², the viscosity's regulariser.
    eta2: f64,
    /// α c₀.
    alpha_c: f64,
    g: SVector<f64, D>,
    fluid_count: u32,
}

/// What the force loop reads: the constants and the particle data by slot.
struct ForceInputs<'a, const D: usize> {
    c: &'a ForceConstants<D>,
    ids: &'a [u32],
    sx: &'a [SVector<f64, D>],
    sv: &'a [SVector<f64, D>],
    sr: &'a [f64],
    /// pⱼ/ρⱼ².
    terms: &'a [f64],
}

/// The accelerations of the slots of chunk `chunk_index` holding fluid particles (zero for
/// boundary particles), −Σⱼ m (pᵢ/ρᵢ² + pⱼ/ρⱼ² + Πᵢⱼ) ∇ᵢWᵢⱼ + g, over the chunk's pairs.
#[inline(always)]
fn force_chunk<const D: usize>(
    chunk_index: usize,
    chunk: &PairChunk,
    inputs: &ForceInputs<'_, D>,
    accelerations: &mut [SVector<f64, D>],
) {
    let c = inputs.c;
    let (sx, sv, sr, pressure_terms) = (inputs.sx, inputs.sv, inputs.sr, inputs.terms);
    let (m, h, eta2, alpha_c) = (c.m, c.h, c.eta2, c.alpha_c);
    for (i, acc) in accelerations.iter_mut().enumerate() {
        let k = chunk_index * PAIR_CHUNK + i;
        if inputs.ids[k] >= c.fluid_count {
            *acc = SVector::zeros();
            continue;
        }
        let (xi, vi, ri) = (sx[k], sv[k], sr[k]);
        let pi = pressure_terms[k];
        let (js, fs) = chunk.of(i);
        let mut a = SVector::<f64, D>::zeros();
        for (&j, &f) in js.iter().zip(fs) {
            let j = j as usize;
            let rij = xi - sx[j];
            let grad = rij * f;
            let rj = sr[j];
            let mut coefficient = pi + pressure_terms[j];
            let approach = (vi - sv[j]).dot(&rij);
            if approach < 0.0 {
                let r2 = rij.norm_squared();
                let mu = h * approach / (r2 + eta2);
                coefficient -= alpha_c * mu / (0.5 * (ri + rj));
            }
            a -= grad * (m * coefficient);
        }
        *acc = a + c.g;
    }
}

/// `values` (stored in grid order) in particle order: particle i's value is at `slot_of[i]`.
fn in_particle_order<T: Copy + Send + Sync>(slot_of: &[u32], values: &[T]) -> Vec<T> {
    slot_of
        .par_iter()
        .map(|&slot| values[slot as usize])
        .collect()
}
