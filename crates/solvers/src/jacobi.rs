//! Block Jacobi iteration (docs/solvers.md §2.2): x ← x + ω D⁻¹ (b − A x), D the B × B diagonal
//! blocks.
//!
//! It converges when the spectral radius of I − ω D⁻¹ A is below 1 (e.g. for block diagonally dominant
//! systems); otherwise the residual grows, and the solver reports [`SolveError::Diverged`] instead of
//! running on.

use std::time::Instant;

use crate::operator::{dot, BlockJacobi, LinearOperator};
use crate::params::{self, ParamError};
use crate::report::{Report, SolveError, StopReason};

/// Settings of [`Jacobi`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JacobiParams {
    /// Stop when ‖b − A x‖ ≤ `tolerance` · ‖b‖. Default 1e-8.
    pub tolerance: f64,
    /// Stop after this many iterations. Default 1000.
    pub max_iterations: usize,
    /// Relaxation weight ω in (0, 1]: 1 is plain Jacobi, smaller damps it (weighted Jacobi, which
    /// converges for SPD systems when ω < 2 / λ_max(D⁻¹A)). Default 1.
    pub weight: f64,
    /// Report divergence once the residual exceeds this factor times the initial one, > 1
    /// (+∞: never). Default 1e3.
    pub divergence_factor: f64,
}

impl JacobiParams {
    /// Check the fields: `tolerance` finite and ≥ 0 (relative), `max_iterations` ≥ 1, `weight`
    /// in (0, 1], `divergence_factor` > 1 (+∞ turns the divergence check off).
    ///
    /// # Errors
    /// [`ParamError`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("JacobiParams::tolerance", self.tolerance)?;
        params::at_least(
            "JacobiParams::max_iterations",
            self.max_iterations,
            1,
            "at least 1",
        )?;
        params::real(
            "JacobiParams::weight",
            self.weight,
            self.weight > 0.0 && self.weight <= 1.0,
            "in (0, 1]",
        )?;
        params::real(
            "JacobiParams::divergence_factor",
            self.divergence_factor,
            self.divergence_factor > 1.0,
            "> 1 (infinity: never report divergence)",
        )
    }
}

impl Default for JacobiParams {
    fn default() -> Self {
        JacobiParams {
            tolerance: 1e-8,
            max_iterations: 1000,
            weight: 1.0,
            divergence_factor: 1e3,
        }
    }
}

/// Block Jacobi with caller-reusable workspace.
#[derive(Clone, Debug, Default)]
pub struct Jacobi {
    /// The settings.
    pub params: JacobiParams,
    r: Vec<f64>,
    z: Vec<f64>,
}

impl Jacobi {
    /// A solver with these settings.
    pub fn new(params: JacobiParams) -> Self {
        Jacobi {
            params,
            ..Default::default()
        }
    }

    /// Solve A x = b from the guess in `x`, with `diagonal` the inverted diagonal blocks of A.
    /// Residuals in the report are ‖b − A x‖ / ‖b‖ (or ‖b − A x‖ when b = 0).
    ///
    /// # Errors
    /// [`SolveError::InvalidParameter`] (before anything is computed) if [`Jacobi::params`] does
    /// not pass [`JacobiParams::validate`];
    /// [`SolveError::Diverged`] when the residual grows past `divergence_factor` × its start;
    /// [`SolveError::NonFinite`] when NaN or infinity appears.
    ///
    /// # Panics
    /// If the lengths of `b`, `x` or `diagonal` do not match the operator.
    #[track_caller]
    pub fn solve<const B: usize>(
        &mut self,
        a: &impl LinearOperator,
        diagonal: &BlockJacobi<B>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<Report, SolveError> {
        let n = a.dim();
        assert_eq!(b.len(), n, "right-hand side length");
        assert_eq!(x.len(), n, "solution length");
        assert_eq!(diagonal.dim(), n, "diagonal blocks cover the operator");
        self.params.validate()?;
        let start = Instant::now();
        self.r.resize(n, 0.0);
        self.z.resize(n, 0.0);
        let mut report = Report::start(self.params.max_iterations);
        let b_norm = dot(b, b).sqrt();
        let scale = if b_norm > 0.0 { 1.0 / b_norm } else { 1.0 };
        let finish = |mut report: Report, stop| {
            report.stop = stop;
            report.wall_time = start.elapsed();
            report
        };
        let mut first = f64::NAN;
        loop {
            a.apply(x, &mut self.r);
            for (r, b) in self.r.iter_mut().zip(b) {
                *r = b - *r;
            }
            let residual = dot(&self.r, &self.r).sqrt() * scale;
            report.residuals.push(residual);
            if report.iterations == 0 {
                first = residual;
            }
            if !residual.is_finite() {
                return Err(SolveError::NonFinite {
                    report: finish(report, StopReason::NonFinite),
                });
            }
            if residual <= self.params.tolerance {
                return Ok(finish(report, StopReason::Converged));
            }
            if residual > self.params.divergence_factor * first {
                return Err(SolveError::Diverged {
                    report: finish(report, StopReason::Diverged),
                });
            }
            if report.iterations >= self.params.max_iterations {
                return Ok(finish(report, StopReason::IterationLimit));
            }
            diagonal.apply_blocks(&self.r, &mut self.z);
            for (x, z) in x.iter_mut().zip(&self.z) {
                *x += self.params.weight * z;
            }
            report.iterations += 1;
        }
    }
}
