//! Preconditioned conjugate gradient (seed 000) for symmetric positive definite systems.

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
        let n = a.dim();
        assert_eq!(b.len(), n, "right-hand side length");
        assert_eq!(x.len(), n, "solution length");
        self.params.validate()?;
        let start = Instant::now();
        for v in [&mut self.r, &mut self.z, &mut self.p, &mut self.ap] {
            v.resize(n, 0.0);
        }
        let mut report = Report::start(self.params.max_iterations);
        let b_norm = dot(b, b).sqrt();
        let scale = if b_norm > 0.0 { 1.0 / b_norm } else { 1.0 };
        // r = b − A x
        a.apply(x, &mut self.r);
        for (r, b) in self.r.iter_mut().zip(b) {
            *r = b - *r;
        }
        let mut residual = dot(&self.r, &self.r).sqrt() * scale;
        report.residuals.push(residual);
        preconditioner.apply(&self.r, &mut self.z);
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        let finish = |mut report: Report, stop| {
            report.stop = stop;
            report.wall_time = start.elapsed();
            report
        };
        loop {
            if !residual.is_finite() {
                return Err(SolveError::NonFinite {
                    report: finish(report, StopReason::NonFinite),
                });
            }
            if residual <= self.params.tolerance {
                return Ok(finish(report, StopReason::Converged));
            }
            if report.iterations >= self.params.max_iterations {
                return Ok(finish(report, StopReason::IterationLimit));
            }
            a.apply(&self.p, &mut self.ap);
            let curvature = dot(&self.p, &self.ap);
            if curvature.is_nan() || curvature <= 0.0 {
                return Err(if curvature.is_nan() {
                    SolveError::NonFinite {
                        report: finish(report, StopReason::NonFinite),
                    }
                } else {
                    SolveError::NotPositiveDefinite {
                        curvature,
                        report: finish(report, StopReason::IterationLimit),
                    }
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
            preconditioner.apply(&self.r, &mut self.z);
            let rz_next = dot(&self.r, &self.z);
            let beta = rz_next / rz;
            rz = rz_next;
            for (p, z) in self.p.iter_mut().zip(&self.z) {
                *p = z + beta * *p;
            }
        }
    }
}
