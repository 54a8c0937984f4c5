//! Preconditioned conjugate gradient (docs/solvers.md §3.2) for symmetric positive definite
//! systems.

use std::time::Instant;

use crate::operator::{dot, LinearOperator, Preconditioner};
use crate::params::{self, ParamError};
use crate::report::{Report, SolveError, StopReason};

/// Settings of [`ConjugateGradient`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgParams {
    /// Stop when ‖b − A x‖ ≤ `tolerance` · ‖b‖ (relative residual). Default 1e-8.
    pub tolerance: f64,
    /// Stop after this many iterations (reported as [`StopReason::IterationLimit`]). Default 1000.
    pub max_iterations: usize,
}

impl CgParams {
    /// Check the fields: `tolerance` finite and ≥ 0 (relative), `max_iterations` ≥ 1.
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("CgParams::tolerance", self.tolerance)?;
        params::at_least(
            "CgParams::max_iterations",
            self.max_iterations,
            1,
            "at least 1",
        )
    }
}

impl Default for CgParams {
    fn default() -> Self {
        CgParams {
            tolerance: 1e-8,
            max_iterations: 1000,
        }
    }
}

/// Preconditioned conjugate gradient with caller-reusable workspace: the four work vectors are
/// allocated when the dimension changes, never inside the iteration.
#[derive(Clone, Debug, Default)]
pub struct ConjugateGradient {
    /// The settings.
    pub params: CgParams,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

impl ConjugateGradient {
    /// A solver with these settings.
    pub fn new(params: CgParams) -> Self {
        ConjugateGradient {
            params,
            ..Default::default()
        }
    }

    /// Solve A x = b from the initial guess in `x`, which holds the solution on return.
    /// The residuals in the report are ‖b − A x‖ / ‖b‖ (or ‖b − A x‖ when b = 0).
    ///
    /// # Errors
    /// - [`SolveError::InvalidParameter`] (before anything is computed) if [`ConjugateGradient::params`]
    ///   does not pass [`CgParams::validate`];
    /// - [`SolveError::NotPositiveDefinite`] when a search direction has pᵀAp ≤ 0;
    /// - [`SolveError::NonFinite`] when NaN or infinity appears.
    ///
    /// # Panics
    /// If `b` or `x` does not have the operator's dimension.
    #[track_caller]
    pub fn solve(
        &mut self,
        a: &impl LinearOperator,
        preconditioner: &mut impl Preconditioner,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<Report, SolveError> {
        let mut report = Report::start(self.params.max_iterations);
        self.solve_into(a, preconditioner, b, x, &mut report, |_, _| false)?;
        Ok(report)
    }

    /// [`ConjugateGradient::solve`] into `report`, which is reset first and keeps its history's
    /// capacity: with a report made once, a solve allocates nothing. On an error the report's
    /// history moves into the error and `report` is left empty. `give_up(k, residual)` is asked
    /// after each iteration k ≥ 1 that has not converged: `true` stops the solve as
    /// [`StopReason::Stagnated`] (a caller that expects fast convergence cuts a slow solve short).
    ///
    /// # Errors
    /// As [`ConjugateGradient::solve`].
    ///
    /// # Panics
    /// As [`ConjugateGradient::solve`].
    #[track_caller]
    pub(crate) fn solve_into(
        &mut self,
        a: &impl LinearOperator,
        preconditioner: &mut impl Preconditioner,
        b: &[f64],
        x: &mut [f64],
        report: &mut Report,
        give_up: impl Fn(usize, f64) -> bool,
    ) -> Result<(), SolveError> {
        let n = a.dim();
        assert_eq!(b.len(), n, "right-hand side length");
        assert_eq!(x.len(), n, "solution length");
        self.params.validate()?;
        let start = Instant::now();
        for v in [&mut self.r, &mut self.z, &mut self.p, &mut self.ap] {
            v.resize(n, 0.0);
        }
        report.iterations = 0;
        report.residuals.clear();
        report.stop = StopReason::IterationLimit;
        let b_norm = dot(b, b).sqrt();
        let scale = if b_norm > 0.0 { 1.0 / b_norm } else { 1.0 };
        let finish = |report: &mut Report, stop| {
            report.stop = stop;
            report.wall_time = start.elapsed();
        };
        let fail = |report: &mut Report, stop, error: fn(Report) -> SolveError| {
            finish(report, stop);
            Err(error(take_report(report)))
        };
        // r = b − A x
        a.apply(x, &mut self.r);
        for (r, b) in self.r.iter_mut().zip(b) {
            *r = b - *r;
        }
        let mut residual = dot(&self.r, &self.r).sqrt() * scale;
        report.residuals.push(residual);
        // Convergence is tested before each application of the preconditioner, so that a solve
        // converged in k iterations applies it k times (a factorisation's solve may cost more
        // than the rest of an iteration).
        let mut rz = 0.0;
        loop {
            if !residual.is_finite() {
                return fail(report, StopReason::NonFinite, |report| {
                    SolveError::NonFinite { report }
                });
            }
            if residual <= self.params.tolerance {
                finish(report, StopReason::Converged);
                return Ok(());
            }
            if report.iterations >= self.params.max_iterations {
                finish(report, StopReason::IterationLimit);
                return Ok(());
            }
            if report.iterations > 0 && give_up(report.iterations, residual) {
                finish(report, StopReason::Stagnated);
                return Ok(());
            }
            preconditioner.apply(&self.r, &mut self.z);
            let rz_next = dot(&self.r, &self.z);
            if report.iterations == 0 {
                self.p.copy_from_slice(&self.z);
            } else {
                let beta = rz_next / rz;
                for (p, z) in self.p.iter_mut().zip(&self.z) {
                    *p = z + beta * *p;
                }
            }
            rz = rz_next;
            a.apply(&self.p, &mut self.ap);
            let curvature = dot(&self.p, &self.ap);
            if curvature.is_nan() {
                return fail(report, StopReason::NonFinite, |report| {
                    SolveError::NonFinite { report }
                });
            }
            if curvature <= 0.0 {
                finish(report, StopReason::NotPositiveDefinite);
                return Err(SolveError::NotPositiveDefinite {
                    curvature,
                    report: take_report(report),
                });
            }
            let alpha = rz / curvature;
            for ((x, r), (p, ap)) in x
                .iter_mut()
                .zip(self.r.iter_mut())
                .zip(self.p.iter().zip(&self.ap))
            {
                *x += alpha * p;
                *r -= alpha * ap;
            }
            report.iterations += 1;
            residual = dot(&self.r, &self.r).sqrt() * scale;
            report.residuals.push(residual);
        }
    }
}

/// Move `report` out (for an error), leaving it with an empty history: no allocation.
fn take_report(report: &mut Report) -> Report {
    Report {
        iterations: report.iterations,
        residuals: std::mem::take(&mut report.residuals),
        wall_time: report.wall_time,
        stop: report.stop,
    }
}
