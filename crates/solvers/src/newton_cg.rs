//! Inexact (truncated) Newton: each Newton system ∇²Φ p = −∇Φ is solved only roughly, by
//! preconditioned conjugate gradients on the exact Hessian, so that no iteration factors a matrix.
//!
//! - The Hessian is refilled in its fixed pattern ([`NewtonProblem::hessian`]) once per outer
//!   iteration and applied as a [`Symmetric`] operator; the preconditioner is the caller's (for
//!   backward Euler, projective dynamics' prefactored K (M + h² L) Kᵀ, one 3-column solve per CG
//!   iteration).
//! - Forcing terms (Eisenstat & Walker 1996, choice 2): CG stops at a relative residual
//!   ηₖ = γ (‖gₖ‖ / ‖gₖ₋₁‖)^α, with their safeguard ηₖ ≥ γ ηₖ₋₁^α when that exceeds 0.1, at most
//!   η_max, and, under the relative-gradient criterion, at least ½ tolerance·‖g₀‖/‖gₖ‖ (no solve
//!   finer than the outer tolerance needs).
//!   Far from x* the systems are solved loosely; near it η → 0 and convergence is superlinear.
//! - Negative curvature (Φ is not convex where springs are compressed): CG stops at the first
//!   direction d with dᵀHd ≤ 0 and keeps the step built so far (Steihaug's truncation, with a line
//!   search in place of the trust region); if that happens at the first CG iteration, the step is
//!   the preconditioned steepest descent −P g. Every step is thus a descent direction.
//! - A backtracking Armijo search on the exactly computed change of Φ accepts each step, so Φ never
//!   increases; it starts at the longest step the problem allows
//!   ([`NewtonProblem::max_step_length`]: no iterate crosses an obstacle). It converges as
//!   [`Newton`](crate::Newton) does ([`NewtonCgParams::convergence`]): by default when a step that
//!   CG did not truncate has [`NewtonProblem::step_size`] at most the tolerance (backward Euler:
//!   m/s), or ‖∇Φ‖ ≤ tolerance · ‖∇Φ(x⁰)‖. It stops unconverged at the iteration limit or at a
//!   failed search at the gradient's rounding error ([`StopReason::RoundOff`]); a failed search
//!   above it is an error.

use std::time::{Duration, Instant};

use crate::newton::{Convergence, NewtonProblem};
use crate::operator::{dot, LinearOperator, Preconditioner, Symmetric};
use crate::params::{self, ParamError};
use crate::report::StopReason;

/// Settings of [`NewtonCg`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonCgParams {
    /// Outer (Newton) iterations at most. Default 100.
    pub max_iterations: usize,
    /// What `tolerance` bounds (as [`crate::NewtonParams::convergence`]). Default
    /// [`Convergence::StepSize`].
    pub convergence: Convergence,
    /// The tolerance, in the criterion's unit (step size: m/s for backward Euler; relative
    /// gradient: dimensionless). Default [`crate::DEFAULT_STEP_TOLERANCE`], as Newton's.
    pub tolerance: f64,
    /// η_max, the loosest relative residual a CG solve stops at, in (0, 1). Default 0.5.
    pub forcing_max: f64,
    /// Eisenstat–Walker's γ in (0, 1]. Default 0.9.
    pub forcing_gamma: f64,
    /// Eisenstat–Walker's α in (1, 2]. Default 2 (quadratic decrease of η near x*).
    pub forcing_alpha: f64,
    /// CG iterations per Newton iteration at most. Default 500.
    pub max_cg_iterations: usize,
    /// The Armijo constant c in (0, 1). Default 1e-4.
    pub armijo: f64,
    /// Halvings of the step the line search tries. Default 30.
    pub max_halvings: usize,
}

impl Default for NewtonCgParams {
    fn default() -> Self {
        NewtonCgParams {
            max_iterations: 100,
            convergence: Convergence::StepSize,
            tolerance: crate::DEFAULT_STEP_TOLERANCE,
            forcing_max: 0.5,
            forcing_gamma: 0.9,
            forcing_alpha: 2.0,
            max_cg_iterations: 500,
            armijo: 1e-4,
            max_halvings: 30,
        }
    }
}

/// The most iterations [`NewtonCgParams::max_iterations`] and
/// [`NewtonCgParams::max_cg_iterations`] may ask for.
pub const NEWTON_CG_MAX_ITERATIONS: usize = 1 << 24;

impl NewtonCgParams {
    /// Check every field.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field outside its range (each range is in the field's
    /// documentation; iteration limits in 1..=[`NEWTON_CG_MAX_ITERATIONS`], `tolerance` finite and
    /// ≥ 0, `max_halvings` ≤ 1100).
    pub fn validate(&self) -> Result<(), ParamError> {
        let limit = NEWTON_CG_MAX_ITERATIONS;
        params::count_in(
            "NewtonCgParams::max_iterations",
            self.max_iterations,
            1,
            limit,
            "in 1 ..= 2^24",
        )?;
        params::count_in(
            "NewtonCgParams::max_cg_iterations",
            self.max_cg_iterations,
            1,
            limit,
            "in 1 ..= 2^24",
        )?;
        params::non_negative("NewtonCgParams::tolerance", self.tolerance)?;
        let (eta, gamma, alpha) = (self.forcing_max, self.forcing_gamma, self.forcing_alpha);
        params::real(
            "NewtonCgParams::forcing_max",
            eta,
            eta > 0.0 && eta < 1.0,
            "in (0, 1)",
        )?;
        params::real(
            "NewtonCgParams::forcing_gamma",
            gamma,
            gamma > 0.0 && gamma <= 1.0,
            "in (0, 1]",
        )?;
        params::real(
            "NewtonCgParams::forcing_alpha",
            alpha,
            alpha > 1.0 && alpha <= 2.0,
            "in (1, 2]",
        )?;
        params::real(
            "NewtonCgParams::armijo",
            self.armijo,
            self.armijo > 0.0 && self.armijo < 1.0,
            "in (0, 1)",
        )?;
        params::count_in(
            "NewtonCgParams::max_halvings",
            self.max_halvings,
            0,
            1100,
            "in 0 ..= 1100",
        )
    }
}

/// The account of one Newton-CG solve.
#[derive(Clone, Debug, PartialEq)]
pub struct NewtonCgReport {
    /// Newton iterations (accepted steps).
    pub iterations: usize,
    /// ‖∇Φ‖ / ‖∇Φ(x⁰)‖ before the first iteration and after each one.
    pub gradients: Vec<f64>,
    /// CG iterations in all (each one Hessian product and one preconditioner solve).
    pub cg_iterations: usize,
    /// CG solves stopped by a direction of non-positive curvature.
    pub negative_curvature: usize,
    /// CG solves stopped by [`NewtonCgParams::max_cg_iterations`] before their forcing term.
    pub cg_limit_hits: usize,
    /// Φ(x) − Φ(x⁰), summed from the exactly computed changes (≤ 0), J·s².
    pub objective_change: f64,
    /// Trial steps of the line searches.
    pub line_search_trials: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// The criterion it was run to.
    pub convergence: Convergence,
    /// [`NewtonProblem::step_size`] of the last step computed (∞ before any; 0 at a stationary
    /// start).
    pub step_size: f64,
    /// Wall time of the solve.
    pub wall_time: Duration,
}

impl NewtonCgReport {
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

/// Why a Newton-CG solve failed; every variant carries the report so far.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NewtonCgError {
    /// The settings are invalid.
    #[error(transparent)]
    Params(#[from] ParamError),
    /// Φ, its gradient or the Hessian product became NaN or infinite.
    #[error("non-finite objective, gradient or curvature at iteration {}", report.iterations)]
    NonFinite {
        /// The report so far.
        report: NewtonCgReport,
    },
    /// No step along the (descent) direction lowered Φ, with a gradient above its rounding error.
    #[error("the line search failed at iteration {} (relative gradient {:e})", report.iterations, report.gradient())]
    LineSearchFailed {
        /// The report so far.
        report: NewtonCgReport,
    },
}

/// Newton-CG with its buffers kept across solves of the same dimension.
#[derive(Clone, Debug)]
pub struct NewtonCg {
    params: NewtonCgParams,
    g: Vec<f64>,
    step: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    d: Vec<f64>,
    hd: Vec<f64>,
    trial: Vec<f64>,
}

impl NewtonCg {
    /// A Newton-CG solver for problems with `n` unknowns.
    ///
    /// # Errors
    /// [`ParamError`] if `params` is invalid.
    pub fn new(n: usize, params: NewtonCgParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(NewtonCg {
            params,
            g: vec![0.0; n],
            step: vec![0.0; n],
            r: vec![0.0; n],
            z: vec![0.0; n],
            d: vec![0.0; n],
            hd: vec![0.0; n],
            trial: vec![0.0; n],
        })
    }

    /// The settings.
    pub fn params(&self) -> NewtonCgParams {
        self.params
    }

    /// Minimise the problem's Φ from the guess in `x` (the result on return), with
    /// `preconditioner` ≈ (∇²Φ)⁻¹, symmetric positive definite.
    ///
    /// # Errors
    /// [`NewtonCgError`], carrying the report so far; `x` then holds the last accepted iterate.
    ///
    /// # Panics
    /// If `x` or the problem does not have the solver's dimension, or the problem's Hessian is not
    /// square of that dimension.
    #[track_caller]
    pub fn minimize(
        &mut self,
        problem: &mut impl NewtonProblem,
        preconditioner: &mut impl Preconditioner,
        x: &mut [f64],
    ) -> Result<NewtonCgReport, NewtonCgError> {
        let n = self.g.len();
        assert_eq!(problem.dim(), n, "the problem's dimension");
        assert_eq!(x.len(), n, "unknowns");
        let start = Instant::now();
        let p = self.params;
        let mut report = NewtonCgReport {
            iterations: 0,
            gradients: Vec::with_capacity(p.max_iterations.min(4096) + 1),
            cg_iterations: 0,
            negative_curvature: 0,
            cg_limit_hits: 0,
            objective_change: 0.0,
            line_search_trials: 0,
            stop: StopReason::IterationLimit,
            convergence: p.convergence,
            step_size: f64::INFINITY,
            wall_time: Duration::ZERO,
        };
        let step_test = p.convergence == Convergence::StepSize;
        let phi0 = problem.objective(x);
        problem.gradient(x, &mut self.g);
        let g0 = norm(&self.g);
        let scale = if g0 > 0.0 { 1.0 / g0 } else { 1.0 };
        report.gradients.push(g0 * scale);
        let finish = |r: &mut NewtonCgReport, stop| {
            r.stop = stop;
            r.wall_time = start.elapsed();
        };
        let (mut forcing, mut previous_gradient) = (p.forcing_max, 1.0);
        loop {
            let gradient = report.gradient();
            if !(phi0.is_finite() && gradient.is_finite()) {
                finish(&mut report, StopReason::NonFinite);
                return Err(NewtonCgError::NonFinite { report });
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
            if report.iterations > 0 {
                forcing = self.forcing(forcing, gradient / previous_gradient, gradient);
            }
            previous_gradient = gradient;
            // Only the products need the pattern (no symbolic analysis here): grow it so that
            // the Hessian holds every term at x (self-contact pairs).
            problem.update_pattern(x);
            let hessian = Symmetric(problem.hessian(x));
            let truncations = report.negative_curvature;
            if !self.truncated_cg(&hessian, preconditioner, forcing, &mut report) {
                finish(&mut report, StopReason::NonFinite);
                return Err(NewtonCgError::NonFinite { report });
            }
            report.step_size = problem.step_size(&self.step);
            // A step CG truncated at negative curvature does not estimate the distance to x*.
            let small = step_test
                && report.negative_curvature == truncations
                && report.step_size <= p.tolerance;
            let slope = dot(&self.g, &self.step);
            let accepted = if slope < 0.0 {
                self.line_search(problem, x, slope, &mut report)
            } else {
                None
            };
            let Some((alpha, change)) = accepted else {
                if small {
                    finish(&mut report, StopReason::Converged);
                    return Ok(report);
                }
                if norm(&self.g) <= problem.gradient_round_off(x) {
                    finish(&mut report, StopReason::RoundOff);
                    return Ok(report);
                }
                finish(&mut report, StopReason::LineSearchFailed);
                return Err(NewtonCgError::LineSearchFailed { report });
            };
            for (x, s) in x.iter_mut().zip(&self.step) {
                *x += alpha * s;
            }
            if !small {
                // Φ may change here (a stiffer barrier); the next iteration works on the new one.
                problem.after_iterate(x);
            }
            problem.gradient(x, &mut self.g);
            report.iterations += 1;
            report.objective_change += change;
            report.gradients.push(norm(&self.g) * scale);
            if small {
                finish(&mut report, StopReason::Converged);
                return Ok(report);
            }
        }
    }

    /// Eisenstat–Walker's choice 2 with its safeguards; `ratio` = ‖gₖ‖/‖gₖ₋₁‖, `gradient` the
    /// relative ‖gₖ‖.
    fn forcing(&self, previous: f64, ratio: f64, gradient: f64) -> f64 {
        let p = self.params;
        let mut eta = p.forcing_gamma * ratio.powf(p.forcing_alpha);
        let safeguard = p.forcing_gamma * previous.powf(p.forcing_alpha);
        if safeguard > 0.1 {
            eta = eta.max(safeguard);
        }
        // No finer than a relative-gradient tolerance needs: a relative residual η leaves
        // ‖g‖ ≈ η‖gₖ‖.
        if p.convergence == Convergence::RelativeGradient {
            eta = eta.max(0.5 * p.tolerance / gradient);
        }
        eta.min(p.forcing_max)
    }

    /// step ≈ −H⁻¹ g by preconditioned CG from 0 to the relative residual `forcing`, truncated at
    /// the first direction of non-positive curvature. Returns false if a product was not finite.
    fn truncated_cg(
        &mut self,
        hessian: &Symmetric<'_>,
        preconditioner: &mut impl Preconditioner,
        forcing: f64,
        report: &mut NewtonCgReport,
    ) -> bool {
        let p = self.params;
        for (r, g) in self.r.iter_mut().zip(&self.g) {
            *r = -g;
        }
        self.step.fill(0.0);
        preconditioner.apply(&self.r, &mut self.z);
        self.d.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        let target = forcing * norm(&self.r);
        for j in 0..p.max_cg_iterations {
            hessian.apply(&self.d, &mut self.hd);
            report.cg_iterations += 1;
            let curvature = dot(&self.d, &self.hd);
            if !curvature.is_finite() || !rz.is_finite() {
                return false;
            }
            if curvature <= 0.0 {
                report.negative_curvature += 1;
                if j == 0 {
                    // −P g: the preconditioned steepest descent.
                    self.step.copy_from_slice(&self.d);
                }
                return true;
            }
            let a = rz / curvature;
            for ((s, r), (d, hd)) in self
                .step
                .iter_mut()
                .zip(self.r.iter_mut())
                .zip(self.d.iter().zip(&self.hd))
            {
                *s += a * d;
                *r -= a * hd;
            }
            if norm(&self.r) <= target {
                return true;
            }
            preconditioner.apply(&self.r, &mut self.z);
            let rz_new = dot(&self.r, &self.z);
            let beta = rz_new / rz;
            rz = rz_new;
            for (d, z) in self.d.iter_mut().zip(&self.z) {
                *d = z + beta * *d;
            }
        }
        report.cg_limit_hits += 1;
        true
    }

    fn line_search(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &[f64],
        slope: f64,
        report: &mut NewtonCgReport,
    ) -> Option<(f64, f64)> {
        let mut alpha = problem.max_step_length(x, &self.step).min(1.0);
        if alpha.is_nan() || alpha <= 0.0 {
            return None;
        }
        for _ in 0..=self.params.max_halvings {
            for ((t, x), s) in self.trial.iter_mut().zip(x).zip(&self.step) {
                *t = x + alpha * s;
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

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
