//! Limited-memory BFGS on a [`NewtonProblem`]'s objective, with a caller's initial inverse Hessian
//! (Liu, Bouaziz, Kavan, "Quasi-Newton Methods for Real-Time Simulation of Hyperelastic Materials",
//! ACM TOG 2017).
//!
//! For backward Euler the initial inverse Hessian is projective dynamics' prefactored matrix
//! K (M + h² L) Kᵀ ([`ProjectiveDynamics`](crate::ProjectiveDynamics) is a [`Preconditioner`]): one
//! 3-column solve per iteration, the price of a PD iteration, buys a direction that the curvature
//! pairs of the last few steps correct towards Newton's. Each iteration:
//!
//! 1. the two-loop recursion turns the gradient g into the direction p = −H g, H the L-BFGS inverse
//!    Hessian built on H₀ from the stored pairs (s, t) = (x⁺ − x, g⁺ − g);
//! 2. a backtracking Armijo search on Φ from α = 1, with the change of Φ computed by
//!    [`NewtonProblem::objective_change`] (without cancellation), accepts the first α with
//!    Φ(x + αp) − Φ(x) ≤ c α gᵀp < 0: Φ never increases;
//! 3. the pair is stored only if its curvature sᵀt is positive (beyond rounding), which keeps H
//!    positive definite; a skipped pair is counted. Φ is not convex where springs are compressed, so
//!    pairs are skipped there.
//!
//! It converges ([`StopReason::Converged`]) when its criterion holds, as [`Newton`](crate::Newton)'s
//! ([`LbfgsParams::convergence`]): by default the direction p's [`NewtonProblem::step_size`] is at
//! most the tolerance (backward Euler: m/s; the step is still taken when the search accepts it), or
//! ‖∇Φ(x)‖ ≤ tolerance · ‖∇Φ(x⁰)‖. It stops unconverged at the iteration limit, or when no step
//! along a descent direction lowers Φ while the gradient is within its rounding error
//! ([`StopReason::RoundOff`]); a failed search with a larger gradient first retries along −H₀ g
//! with the history cleared, and is an error if that fails too. Every search starts at the longest
//! step the problem allows ([`NewtonProblem::max_step_length`]: no iterate crosses an obstacle).

use std::time::{Duration, Instant};

use crate::newton::{Convergence, NewtonProblem};
use crate::operator::{dot, Preconditioner};
use crate::params::{self, ParamError};
use crate::report::StopReason;

/// Settings of [`Lbfgs`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LbfgsParams {
    /// Iterations (accepted steps) at most. Default 100.
    pub max_iterations: usize,
    /// What `tolerance` bounds (as [`crate::NewtonParams::convergence`]). Default
    /// [`Convergence::StepSize`].
    pub convergence: Convergence,
    /// The tolerance, in the criterion's unit (step size: the problem's, m/s for backward Euler;
    /// relative gradient: dimensionless). 0 runs to the iteration limit. Default
    /// [`crate::DEFAULT_STEP_TOLERANCE`], as Newton's.
    pub tolerance: f64,
    /// Curvature pairs kept (the memory). Default 5 (Liu et al. 2017 use 5; measured in the bench).
    pub history: usize,
    /// The Armijo constant c in Φ(x + αp) − Φ(x) ≤ c α gᵀp, in (0, 1). Default 1e-4.
    pub armijo: f64,
    /// Halvings of α the line search tries before it gives up on a direction. Default 30.
    pub max_halvings: usize,
}

impl Default for LbfgsParams {
    fn default() -> Self {
        LbfgsParams {
            max_iterations: 100,
            convergence: Convergence::StepSize,
            tolerance: crate::DEFAULT_STEP_TOLERANCE,
            history: 5,
            armijo: 1e-4,
            max_halvings: 30,
        }
    }
}

/// The most history pairs [`LbfgsParams::history`] may ask for: each pair holds two vectors of the
/// problem's size, and the benefit of a longer memory ends far below this.
pub const LBFGS_MAX_HISTORY: usize = 256;

/// The most iterations [`LbfgsParams::max_iterations`] may ask for (the report's history is
/// reserved up to this size, never more).
pub const LBFGS_MAX_ITERATIONS: usize = 1 << 24;

impl LbfgsParams {
    /// Check every field.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field outside its range: `max_iterations` in
    /// 1..=[`LBFGS_MAX_ITERATIONS`], `tolerance` finite and ≥ 0, `history` in
    /// 1..=[`LBFGS_MAX_HISTORY`], `armijo` in (0, 1), `max_halvings` in 0..=1100 (2⁻¹¹⁰⁰ is below
    /// the smallest double).
    pub fn validate(&self) -> Result<(), ParamError> {
        params::count_in(
            "LbfgsParams::max_iterations",
            self.max_iterations,
            1,
            LBFGS_MAX_ITERATIONS,
            "in 1 ..= 2^24",
        )?;
        params::non_negative("LbfgsParams::tolerance", self.tolerance)?;
        params::count_in(
            "LbfgsParams::history",
            self.history,
            1,
            LBFGS_MAX_HISTORY,
            "in 1 ..= 256",
        )?;
        params::real(
            "LbfgsParams::armijo",
            self.armijo,
            self.armijo > 0.0 && self.armijo < 1.0,
            "in (0, 1)",
        )?;
        params::count_in(
            "LbfgsParams::max_halvings",
            self.max_halvings,
            0,
            1100,
            "in 0 ..= 1100",
        )
    }
}

/// The account of one L-BFGS solve.
#[derive(Clone, Debug, PartialEq)]
pub struct LbfgsReport {
    /// Accepted steps.
    pub iterations: usize,
    /// ‖∇Φ‖ / ‖∇Φ(x⁰)‖ before the first iteration and after each one.
    pub gradients: Vec<f64>,
    /// Φ(x⁰) (J·s², the objective's unit).
    pub initial_objective: f64,
    /// Φ(x) − Φ(x⁰) after the last iteration, summed from the exactly computed changes (≤ 0).
    pub objective_change: f64,
    /// Evaluations of Φ's change in the line searches (one per trial step).
    pub line_search_trials: usize,
    /// Curvature pairs not stored because sᵀt was not positive.
    pub skipped_pairs: usize,
    /// Times the history was cleared after a failed search (the retry along −H₀ g).
    pub restarts: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// The criterion it was run to.
    pub convergence: Convergence,
    /// [`NewtonProblem::step_size`] of the last direction computed (∞ before any; 0 at a
    /// stationary start).
    pub step_size: f64,
    /// Wall time of the solve.
    pub wall_time: Duration,
}

impl LbfgsReport {
    /// The last relative gradient norm (NaN for an empty report).
    pub fn gradient(&self) -> f64 {
        self.gradients.last().copied().unwrap_or(f64::NAN)
    }

    /// The criterion's own quantity: the last step size or the relative gradient.
    pub fn residual(&self) -> f64 {
        match self.convergence {
            Convergence::StepSize => self.step_size,
            Convergence::RelativeGradient => self.gradient(),
        }
    }
}

/// Why an L-BFGS solve failed; every variant carries the report so far.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LbfgsError {
    /// The settings are invalid.
    #[error(transparent)]
    Params(#[from] ParamError),
    /// Φ or its gradient became NaN or infinite.
    #[error("non-finite objective or gradient at iteration {}", report.iterations)]
    NonFinite {
        /// The report so far.
        report: LbfgsReport,
    },
    /// Neither the L-BFGS direction nor −H₀ g gave a decrease of Φ, with a gradient above its
    /// rounding error: objective and gradient disagree, or H₀ is not positive definite.
    #[error("the line search failed at iteration {} (relative gradient {:e})", report.iterations, report.gradient())]
    LineSearchFailed {
        /// The report so far.
        report: LbfgsReport,
    },
}

/// L-BFGS with its history and buffers kept across solves of the same dimension, so that a solve
/// allocates only its report.
#[derive(Clone, Debug)]
pub struct Lbfgs {
    params: LbfgsParams,
    /// s_k = x_{k+1} − x_k, `history + 1` rows of `n`, used as a ring: a new pair is written into
    /// the slot after the newest, which never holds a stored pair, so a pair whose curvature test
    /// fails leaves the stored ones (and their ρ) as they were.
    s: Vec<f64>,
    /// t_k = g_{k+1} − g_k, as `s`.
    t: Vec<f64>,
    /// 1 / (s_k · t_k) per stored pair.
    rho: Vec<f64>,
    alpha: Vec<f64>,
    g: Vec<f64>,
    g_new: Vec<f64>,
    q: Vec<f64>,
    direction: Vec<f64>,
    trial: Vec<f64>,
}

impl Lbfgs {
    /// An L-BFGS solver for problems with `n` unknowns.
    ///
    /// # Errors
    /// [`ParamError`] if `params` is invalid ([`LbfgsParams::validate`]).
    pub fn new(n: usize, params: LbfgsParams) -> Result<Self, ParamError> {
        params.validate()?;
        let slots = params.history + 1;
        Ok(Lbfgs {
            params,
            s: vec![0.0; slots * n],
            t: vec![0.0; slots * n],
            rho: vec![0.0; slots],
            alpha: vec![0.0; slots],
            g: vec![0.0; n],
            g_new: vec![0.0; n],
            q: vec![0.0; n],
            direction: vec![0.0; n],
            trial: vec![0.0; n],
        })
    }

    /// The settings.
    pub fn params(&self) -> LbfgsParams {
        self.params
    }

    /// Minimise the problem's Φ from the guess in `x` (which holds the result on return), with
    /// `initial` applying H₀ ≈ (∇²Φ)⁻¹ (symmetric positive definite, in the problem's unknowns).
    ///
    /// # Errors
    /// [`LbfgsError`], carrying the report so far; `x` then holds the last accepted iterate, whose
    /// Φ is not above the start's.
    ///
    /// # Panics
    /// If `x` or the problem does not have the dimension the solver was made for.
    #[track_caller]
    pub fn minimize(
        &mut self,
        problem: &mut impl NewtonProblem,
        initial: &mut impl Preconditioner,
        x: &mut [f64],
    ) -> Result<LbfgsReport, LbfgsError> {
        let n = self.g.len();
        assert_eq!(problem.dim(), n, "the problem's dimension");
        assert_eq!(x.len(), n, "unknowns");
        let start = Instant::now();
        let p = self.params;
        let mut report = LbfgsReport {
            iterations: 0,
            gradients: Vec::with_capacity(p.max_iterations.min(4096) + 1),
            initial_objective: problem.objective(x),
            objective_change: 0.0,
            line_search_trials: 0,
            skipped_pairs: 0,
            restarts: 0,
            stop: StopReason::IterationLimit,
            convergence: p.convergence,
            step_size: f64::INFINITY,
            wall_time: Duration::ZERO,
        };
        let step_test = p.convergence == Convergence::StepSize;
        problem.gradient(x, &mut self.g);
        let g0 = norm(&self.g);
        let scale = if g0 > 0.0 { 1.0 / g0 } else { 1.0 };
        report.gradients.push(g0 * scale);
        // Stored pairs, and the ring slot of the newest.
        let (mut stored, mut newest) = (0usize, 0usize);
        let finish = |r: &mut LbfgsReport, stop| {
            r.stop = stop;
            r.wall_time = start.elapsed();
        };
        loop {
            let gradient = report.gradient();
            if !(report.initial_objective.is_finite() && gradient.is_finite()) {
                finish(&mut report, StopReason::NonFinite);
                return Err(LbfgsError::NonFinite { report });
            }
            if g0 == 0.0 || gradient == 0.0 {
                report.step_size = 0.0;
                finish(&mut report, StopReason::Converged);
                return Ok(report);
            }
            if !step_test && gradient <= p.tolerance {
                finish(&mut report, StopReason::Converged);
                return Ok(report);
            }
            if report.iterations >= p.max_iterations {
                finish(&mut report, StopReason::IterationLimit);
                return Ok(report);
            }
            let mut small;
            let accepted = loop {
                self.two_loop(initial, stored, newest);
                let slope = dot(&self.g, &self.direction);
                report.step_size = problem.step_size(&self.direction);
                small = step_test && report.step_size <= p.tolerance;
                if slope < 0.0 {
                    if let Some(found) = self.line_search(problem, x, slope, &mut report) {
                        break Some(found);
                    }
                }
                if small {
                    break None;
                }
                if stored == 0 {
                    break None;
                }
                // The history misled the direction (a non-convex region): retry along −H₀ g.
                stored = 0;
                report.restarts += 1;
            };
            let Some((alpha, change)) = accepted else {
                if small {
                    // The criterion holds at x; no step of the direction lowers Φ further.
                    finish(&mut report, StopReason::Converged);
                    return Ok(report);
                }
                let noise = problem.gradient_round_off(x);
                if norm(&self.g) <= noise {
                    finish(&mut report, StopReason::RoundOff);
                    return Ok(report);
                }
                finish(&mut report, StopReason::LineSearchFailed);
                return Err(LbfgsError::LineSearchFailed { report });
            };
            // x⁺ = x + α p; the new pair goes into the free slot after the newest.
            let slot = if stored == 0 {
                0
            } else {
                (newest + 1) % (p.history + 1)
            };
            let s = &mut self.s[slot * n..(slot + 1) * n];
            for ((s, x), d) in s.iter_mut().zip(x.iter_mut()).zip(&self.direction) {
                let step = alpha * d;
                *s = step;
                *x += step;
            }
            let adapted = !small && problem.after_iterate(x);
            problem.gradient(x, &mut self.g_new);
            let t = &mut self.t[slot * n..(slot + 1) * n];
            for ((t, new), old) in t.iter_mut().zip(&self.g_new).zip(&self.g) {
                *t = new - old;
            }
            std::mem::swap(&mut self.g, &mut self.g_new);
            report.iterations += 1;
            report.objective_change += change;
            report.gradients.push(norm(&self.g) * scale);
            let curvature = dot(s_of(&self.s, slot, n), t_of(&self.t, slot, n));
            let sizes = norm(s_of(&self.s, slot, n)) * norm(t_of(&self.t, slot, n));
            // Positive beyond the rounding of the dot product, or H would lose definiteness.
            if adapted {
                // The two gradients belong to different objectives: their difference is no
                // curvature of either, and the pair is dropped.
            } else if curvature > f64::EPSILON * sizes && curvature.is_finite() {
                self.rho[slot] = 1.0 / curvature;
                newest = slot;
                stored = (stored + 1).min(p.history);
            } else {
                report.skipped_pairs += 1;
            }
            if small {
                finish(&mut report, StopReason::Converged);
                return Ok(report);
            }
        }
    }

    /// direction = −H g by the two-loop recursion over the `stored` newest pairs, ending at
    /// `newest`, on H₀ = `initial`.
    fn two_loop(&mut self, initial: &mut impl Preconditioner, stored: usize, newest: usize) {
        let n = self.g.len();
        let m = self.params.history + 1;
        self.q.copy_from_slice(&self.g);
        for back in 0..stored {
            let k = (newest + m - back) % m;
            let a = self.rho[k] * dot(s_of(&self.s, k, n), &self.q);
            self.alpha[k] = a;
            for (q, t) in self.q.iter_mut().zip(t_of(&self.t, k, n)) {
                *q -= a * t;
            }
        }
        initial.apply(&self.q, &mut self.direction);
        for forward in (0..stored).rev() {
            let k = (newest + m - forward) % m;
            let b = self.rho[k] * dot(t_of(&self.t, k, n), &self.direction);
            let a = self.alpha[k];
            for (d, s) in self.direction.iter_mut().zip(s_of(&self.s, k, n)) {
                *d += (a - b) * s;
            }
        }
        for d in &mut self.direction {
            *d = -*d;
        }
    }

    /// Backtracking Armijo search along `direction` from the longest step the problem allows (at
    /// most 1): the accepted α and Φ's change, or `None` if no trial lowers Φ enough.
    fn line_search(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        slope: f64,
        report: &mut LbfgsReport,
    ) -> Option<(f64, f64)> {
        let mut alpha = problem.max_step_length(x, &self.direction).min(1.0);
        if alpha.is_nan() || alpha <= 0.0 {
            return None;
        }
        for _ in 0..=self.params.max_halvings {
            for ((t, x), d) in self.trial.iter_mut().zip(x).zip(&self.direction) {
                *t = x + alpha * d;
            }
            report.line_search_trials += 1;
            let change = problem.objective_change(x, &self.trial);
            if change.is_finite() && change <= self.params.armijo * alpha * slope {
                return Some((alpha, change));
            }
            alpha *= 0.5;
        }
        None
    }
}

fn s_of(s: &[f64], k: usize, n: usize) -> &[f64] {
    &s[k * n..(k + 1) * n]
}

fn t_of(t: &[f64], k: usize, n: usize) -> &[f64] {
    &t[k * n..(k + 1) * n]
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
