//! Chebyshev-accelerated projective dynamics (Wang, "A Chebyshev Semi-Iterative Approach for
//! Accelerating Projective and Position-based Dynamics", ACM TOG 2015).
//!
//! Plain PD converges linearly, at a rate ρ close to 1 on cloth. The Chebyshev semi-iterative method
//! extrapolates each PD iterate x̂ₖ₊₁ from the two before it,
//!
//! qₖ₊₁ = ωₖ₊₁ (γ (x̂ₖ₊₁ − qₖ) + qₖ − qₖ₋₁) + qₖ₋₁,
//!
//! with ω = 1 for the first S iterations (the delay), then ω = 2 / (2 − ρ²) and
//! ωₖ₊₁ = 4 / (4 − ρ² ωₖ): the rate becomes about 1 − √(1 − ρ) per iteration. ρ is the scene's
//! (estimate it once from plain PD with [`ProjectiveDynamics::estimate_rate`]); γ under-relaxes.
//!
//! PD is a fixed-point iteration on a non-convex Φ, so the extrapolation can overshoot and raise Φ
//! (it does on stiff cloth at large steps). The guard checks Φ every k iterations
//! ([`ChebyshevParams::check_interval`]) and where the solve stops, against the last checked point
//! (the start or the last passed check), by the exactly computed change of Φ (term by term, one
//! pass over springs and vertices). When Φ rose, the last extrapolated point is dropped for the
//! plain PD iterate x̂ of that iteration, if x̂ is not above the checked point; otherwise the
//! stretch since the check is rolled back to the checked point and the next stretch is plain PD
//! (which does not raise Φ but for the rounding of its global solve). Either way the schedule
//! restarts with ω = 1. If a stretch of plain PD rises, PD is at its rounding floor: the solve keeps
//! the checked point and stops as [`StopReason::Stagnated`]. Φ never increases from one checked
//! point to the next, and the result is a checked point: Φ(result) ≤ Φ(start). Points between
//! checks may lie above (they are never returned). A check costs 0.12–0.30 of a PD iteration on
//! cloth (docs/solvers.md §7).

use std::time::{Duration, Instant};

use hooke_mesh::Spring;
use nalgebra::SVector;

use crate::params::{self, ParamError, HISTORY_RESERVE};
use crate::projective::{FixedPointError, PdError, ProjectiveDynamics};
use crate::report::StopReason;

/// Settings of [`ChebyshevPd`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChebyshevParams {
    /// Iterations per step. Default 10.
    pub max_iterations: usize,
    /// ρ, the convergence rate of plain PD on the scene (its spectral radius), in (0, 1). No default
    /// fits every scene: estimate it with [`ProjectiveDynamics::estimate_rate`]. Default 0.99.
    pub rate: f64,
    /// Plain PD iterations before the acceleration starts, and after each restart (S). Default 2:
    /// the step's budget is about 10 iterations, and the first ones move far from the start.
    pub delay: usize,
    /// Under-relaxation γ in (0, 1]. Default 1 (none).
    pub under_relaxation: f64,
    /// Restart to plain PD when Φ rises. Default true; `false` is the paper's unguarded method, for
    /// comparison only (it can gain energy; Φ is then recorded after every iteration).
    pub restart: bool,
    /// k: with the restart, Φ is checked every k iterations (and where the solve stops), against
    /// the last checked point; a stretch of k iterations that raised Φ is rolled back to it (if
    /// the last plain iterate rose too). Default 4 (docs/solvers.md §7: a check costs 0.12–0.30 of
    /// a PD iteration on cloth-160 and cloth-40; larger k saved nothing measurable and a rollback
    /// loses up to k iterations). 1 checks after every iteration.
    pub check_interval: usize,
    /// Stop when the estimated distance to the solution divided by h is at most `tolerance` (m/s),
    /// as [`crate::PdParams::tolerance`] ([`crate::FixedPointError`], restarted with the
    /// schedule). Default 0.
    pub tolerance: f64,
}

impl Default for ChebyshevParams {
    fn default() -> Self {
        ChebyshevParams {
            max_iterations: 10,
            rate: 0.99,
            delay: 2,
            under_relaxation: 1.0,
            restart: true,
            check_interval: 4,
            tolerance: 0.0,
        }
    }
}

/// The most iterations [`ChebyshevParams::max_iterations`] may ask for.
pub const CHEBYSHEV_MAX_ITERATIONS: usize = 1 << 24;

impl ChebyshevParams {
    /// Check every field.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field outside its range: `max_iterations` in
    /// 1..=[`CHEBYSHEV_MAX_ITERATIONS`], `rate` in (0, 1), `under_relaxation` in (0, 1],
    /// `check_interval` in 1..=[`CHEBYSHEV_MAX_ITERATIONS`], `tolerance` finite and ≥ 0 (`delay`
    /// may be any value: at or beyond the budget it is plain PD).
    pub fn validate(&self) -> Result<(), ParamError> {
        params::count_in(
            "ChebyshevParams::max_iterations",
            self.max_iterations,
            1,
            CHEBYSHEV_MAX_ITERATIONS,
            "in 1 ..= 2^24",
        )?;
        params::real(
            "ChebyshevParams::rate",
            self.rate,
            self.rate > 0.0 && self.rate < 1.0,
            "in (0, 1)",
        )?;
        let gamma = self.under_relaxation;
        params::real(
            "ChebyshevParams::under_relaxation",
            gamma,
            gamma > 0.0 && gamma <= 1.0,
            "in (0, 1]",
        )?;
        params::count_in(
            "ChebyshevParams::check_interval",
            self.check_interval,
            1,
            CHEBYSHEV_MAX_ITERATIONS,
            "in 1 ..= 2^24",
        )?;
        params::non_negative("ChebyshevParams::tolerance", self.tolerance)
    }
}

/// The account of one accelerated solve.
#[derive(Clone, Debug, PartialEq)]
pub struct ChebyshevReport {
    /// Iterations performed (each one PD iteration; those of a rolled-back stretch included).
    pub iterations: usize,
    /// Φ before the first iteration and at each passed check (J·s²; after every iteration
    /// without the restart), the first evaluated and the others accumulated from the exactly
    /// computed changes ([`ProjectiveDynamics::objective_change`]), so that changes below Φ's
    /// rounding are kept: never increasing when [`ChebyshevParams::restart`] is on. The last is
    /// Φ of the result.
    pub objectives: Vec<f64>,
    /// Largest position change (m) in each iteration.
    pub changes: Vec<f64>,
    /// Restarts to plain PD (Φ rose at a check): the last plain iterate taken instead, or the
    /// stretch rolled back.
    pub restarts: usize,
    /// Those restarts that rolled a stretch of iterations back to the last checked point (the
    /// last plain iterate had raised Φ too).
    pub rollbacks: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// Wall time of the solve.
    pub wall_time: Duration,
}

/// Chebyshev-accelerated projective dynamics over a [`ProjectiveDynamics`] (whose factor it uses),
/// with its buffers kept across steps.
#[derive(Clone, Debug)]
pub struct ChebyshevPd<const D: usize> {
    params: ChebyshevParams,
    /// qₖ₋₁, qₖ and the plain iterate x̂ₖ₊₁, per vertex.
    previous: Vec<SVector<f64, D>>,
    current: Vec<SVector<f64, D>>,
    plain: Vec<SVector<f64, D>>,
    /// The last point whose Φ was checked (the start, or a passed check).
    checked: Vec<SVector<f64, D>>,
}

impl<const D: usize> ChebyshevPd<D> {
    /// Accelerated PD for meshes of `vertex_count` vertices.
    ///
    /// # Errors
    /// [`ParamError`] if `params` is invalid.
    pub fn new(vertex_count: usize, params: ChebyshevParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(ChebyshevPd {
            params,
            previous: vec![SVector::zeros(); vertex_count],
            current: vec![SVector::zeros(); vertex_count],
            plain: vec![SVector::zeros(); vertex_count],
            checked: vec![SVector::zeros(); vertex_count],
        })
    }

    /// The settings.
    pub fn params(&self) -> ChebyshevParams {
        self.params
    }

    /// Set ρ, for example to an estimate from [`ProjectiveDynamics::estimate_rate`].
    ///
    /// # Errors
    /// [`ParamError`] if `rate` is not in (0, 1); the settings are then unchanged.
    pub fn set_rate(&mut self, rate: f64) -> Result<(), ParamError> {
        let params = ChebyshevParams {
            rate,
            ..self.params
        };
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// Solve the step with inertial target `y` as [`ProjectiveDynamics::solve`] does (`x` the
    /// initial guess with the pinned vertices in place, or the step's start with contact, and the
    /// result), accelerated. With contact, the extrapolated point is limited as PD's iterates are,
    /// so that every iterate is outside every obstacle.
    ///
    /// # Errors
    /// [`PdError::Factorization`] if the contact solve's matrix does not factor.
    ///
    /// # Panics
    /// If the lengths of `springs`, `y` or `x` do not match `pd`'s system or this solver's size.
    #[track_caller]
    pub fn solve(
        &mut self,
        pd: &mut ProjectiveDynamics<D>,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &mut [SVector<f64, D>],
    ) -> Result<ChebyshevReport, PdError> {
        assert_eq!(x.len(), self.current.len(), "one position per vertex");
        let start = Instant::now();
        let p = self.params;
        let reserve = p.max_iterations.min(HISTORY_RESERVE);
        let mut report = ChebyshevReport {
            iterations: 0,
            objectives: Vec::with_capacity(reserve + 1),
            changes: Vec::with_capacity(reserve),
            restarts: 0,
            rollbacks: 0,
            stop: StopReason::IterationLimit,
            wall_time: Duration::ZERO,
        };
        pd.begin_step(springs, y, x)?;
        let mut phi = pd.objective(springs, y, x);
        report.objectives.push(phi);
        self.previous.copy_from_slice(x);
        self.checked.copy_from_slice(x);
        // The unguarded method checks nothing: it records Φ after every iteration, to show rises.
        let interval = if p.restart { p.check_interval } else { 1 };
        // Iterations since the last check, and whether one of them was extrapolated.
        let (mut unchecked, mut extrapolated_since_check) = (0usize, false);
        // Iterations since the start or the last restart, the current ω, and the plain iterations
        // before the extrapolation (re)starts: S, or after a rollback the whole next stretch.
        let (mut since, mut omega, mut delay) = (0usize, 1.0, p.delay);
        let rho2 = p.rate * p.rate;
        let gamma = p.under_relaxation;
        let mut error = FixedPointError::default();
        let mut largest_displacement: f64 = 0.0;
        while report.iterations < p.max_iterations {
            // previous = qₖ₋₁, current = qₖ, plain = x̂ₖ₊₁.
            self.current.copy_from_slice(x);
            let plain_change = pd.iteration(springs, y, x, &mut largest_displacement);
            let mut change = plain_change;
            omega = match since.cmp(&delay) {
                std::cmp::Ordering::Less => 1.0,
                std::cmp::Ordering::Equal => 2.0 / (2.0 - rho2),
                std::cmp::Ordering::Greater => 4.0 / (4.0 - rho2 * omega),
            };
            let extrapolated = omega != 1.0 || gamma != 1.0;
            if extrapolated {
                self.plain.copy_from_slice(x);
                change = 0.0;
                for &v in pd.free_vertices() {
                    let v = v as usize;
                    let (q, q_old) = (self.current[v], self.previous[v]);
                    x[v] = omega * (gamma * (self.plain[v] - q) + q - q_old) + q_old;
                    change = change.max((x[v] - q).amax());
                }
                if pd.has_contact() {
                    pd.limit_moves(&self.current, x);
                    // The position change of the point kept, not of the plain iterate.
                    change = largest_change(pd.free_vertices(), &self.current, x);
                }
            }
            extrapolated_since_check |= extrapolated;
            since += 1;
            unchecked += 1;
            report.iterations += 1;
            report.changes.push(change);
            std::mem::swap(&mut self.previous, &mut self.current);
            let mut trial = error;
            let small = trial.after(change) <= p.tolerance * pd.time_step();
            let last = report.iterations == p.max_iterations;
            if unchecked < interval && !small && !last && change.is_finite() {
                error = trial;
                continue;
            }
            // The check: Φ(x) − Φ(checked), exact to rounding (no cancellation of two values of
            // Φ); NaN counts as a rise.
            let rise = pd.objective_change(springs, y, &self.checked, x);
            let rose = |rise: f64| rise > 0.0 || rise.is_nan();
            let mut restarted = false;
            let accepted = if !p.restart || !rose(rise) {
                Some(rise)
            } else if extrapolated {
                // The last iteration's plain iterate instead, as a restart.
                let plain_rise = pd.objective_change(springs, y, &self.checked, &self.plain);
                (!rose(plain_rise)).then(|| {
                    x.copy_from_slice(&self.plain);
                    *report.changes.last_mut().expect("an iteration was made") = plain_change;
                    (since, omega, delay) = (0, 1.0, p.delay);
                    report.restarts += 1;
                    restarted = true;
                    // The rate of the changes to come is plain PD's again.
                    trial = FixedPointError::default();
                    trial.after(plain_change);
                    plain_rise
                })
            } else {
                None
            };
            if let Some(rise) = accepted {
                phi += rise;
                report.objectives.push(phi);
                self.checked.copy_from_slice(x);
                (unchecked, extrapolated_since_check) = (0, false);
                error = trial;
                if !change.is_finite() {
                    // Unguarded only: the guard never accepts a non-finite point.
                    report.stop = StopReason::NonFinite;
                    break;
                }
                if small && !restarted {
                    report.stop = StopReason::Converged;
                    break;
                }
            } else if unchecked == 1 || !extrapolated_since_check {
                // Plain PD from the checked point rose: PD is at the rounding floor of its global
                // solve (its positions are exact to about ε|x|). Keep the checked point and stop.
                x.copy_from_slice(&self.checked);
                report.objectives.push(phi);
                report.stop = StopReason::Stagnated;
                break;
            } else {
                // Roll the stretch back to the checked point, and make the next stretch plain PD
                // (which does not raise Φ), so that every rollback is followed by progress.
                x.copy_from_slice(&self.checked);
                self.previous.copy_from_slice(x);
                (since, omega, delay) = (0, 1.0, p.delay.max(interval));
                (unchecked, extrapolated_since_check) = (0, false);
                report.restarts += 1;
                report.rollbacks += 1;
                error = FixedPointError::default();
            }
        }
        report.wall_time = start.elapsed();
        Ok(report)
    }
}

impl<const D: usize> ProjectiveDynamics<D> {
    /// Estimate plain PD's convergence rate ρ on a step: run `iterations` (at least 4) plain
    /// iterations from `x` (left unchanged) and return the geometric mean of the ratios of
    /// successive position changes over the second half of them, the part where the slowest mode
    /// dominates. Returns `None` when the iteration converged to round-off before the estimate
    /// could form (any ρ then works) or the ratio is not in (0, 1).
    pub fn estimate_rate(
        &mut self,
        springs: &[Spring],
        y: &[SVector<f64, D>],
        x: &[SVector<f64, D>],
        iterations: usize,
    ) -> Option<f64> {
        let iterations = iterations.max(4);
        // Plain iterations without contact: the estimate is of the spring system's rate.
        let contact = self.take_contact();
        let mut work = x.to_vec();
        let mut largest_displacement = 0.0;
        // Only the change halfway and the last one are needed: nothing is sized by `iterations`.
        let (mut a, mut b) = (0.0, 0.0);
        for k in 0..iterations {
            b = self.iteration(springs, y, &mut work, &mut largest_displacement);
            if k == iterations / 2 {
                a = b;
            }
        }
        self.restore_contact(contact);
        let span = (iterations - 1 - iterations / 2) as f64;
        let rate = (b / a).powf(1.0 / span);
        (a > 0.0 && b > 0.0 && rate > 0.0 && rate < 1.0).then_some(rate)
    }
}

/// The largest coordinate change between `a` and `b` over the `free` vertices (m).
pub(crate) fn largest_change<const D: usize>(
    free: &[u32],
    a: &[SVector<f64, D>],
    b: &[SVector<f64, D>],
) -> f64 {
    free.iter()
        .map(|&v| (a[v as usize] - b[v as usize]).amax())
        .fold(0.0, f64::max)
}
