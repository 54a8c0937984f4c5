//! What every solver returns: a report of its iterations, or an error that carries the report so far.

use std::time::Duration;

use crate::params::{ParamError, HISTORY_RESERVE};

/// Why an iterative solver stopped. Only [`StopReason::Converged`] means the solution asked for
/// was found ([`StopReason::is_converged`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum StopReason {
    /// The residual met the requested tolerance.
    Converged,
    /// The residual is at its proven rounding floor (the solver's problem bounds the rounding
    /// error of its residual, and the residual is below that bound) while the criterion does not
    /// hold: the tolerance asked for is below what the arithmetic resolves. Not converged; the
    /// iterate is as close as the arithmetic gets.
    RoundOff,
    /// The iteration limit was reached first: not converged.
    IterationLimit,
    /// The iterations stopped making progress while the residual was still above the tolerance
    /// and above its rounding floor: not converged.
    Stagnated,
    /// The objective, the residual or the iterate became NaN or infinite: not converged.
    NonFinite,
    /// No step along a descent direction lowered the objective enough (the line search's Armijo
    /// condition failed at every trial length) while the gradient was above its rounding floor:
    /// not converged. Objective and gradient disagree, or the tolerance is below what they resolve
    /// and the problem gives no rounding estimate.
    LineSearchFailed,
    /// The matrix or model the solver needs positive definite was not: CG met a direction of
    /// non-positive curvature, or Newton found no definite matrix within its shift or blend
    /// limit. Not converged.
    NotPositiveDefinite,
    /// The residual grew past the solver's divergence bound (Jacobi on a system that is not
    /// diagonally dominant enough): not converged.
    Diverged,
}

impl StopReason {
    /// Whether the solve reached its goal: its criterion holds ([`StopReason::Converged`]).
    pub fn is_converged(self) -> bool {
        matches!(self, StopReason::Converged)
    }

    /// Whether the solve is as converged as the arithmetic allows: [`StopReason::Converged`], or
    /// [`StopReason::RoundOff`] (the criterion is below the rounding floor). For reference
    /// solutions run to a tolerance below what the arithmetic resolves.
    pub fn is_at_resolution(self) -> bool {
        matches!(self, StopReason::Converged | StopReason::RoundOff)
    }

    /// A short name for reports (`converged`, `round-off`, `iteration-limit`, `stagnated`,
    /// `non-finite`, `line-search-failed`, `not-positive-definite`, `diverged`).
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::RoundOff => "round-off",
            StopReason::IterationLimit => "iteration-limit",
            StopReason::Stagnated => "stagnated",
            StopReason::NonFinite => "non-finite",
            StopReason::LineSearchFailed => "line-search-failed",
            StopReason::NotPositiveDefinite => "not-positive-definite",
            StopReason::Diverged => "diverged",
        }
    }
}

/// What an iterative solve did: iterations, final residual and why it stopped, without the history
/// (cheap to copy into per-step records).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveSummary {
    /// Iterations performed.
    pub iterations: usize,
    /// The residual after the last iteration (the solver documents its norm).
    pub residual: f64,
    /// Why it stopped.
    pub stop: StopReason,
    /// Time steps the solve was split into: 1, unless an integrator redid a step it could not
    /// finish as several smaller ones (backward Euler by Newton halves such steps); then
    /// `iterations` sums over them, including the attempts that were given up.
    pub substeps: usize,
}

/// The full account of a solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Iterations performed.
    pub iterations: usize,
    /// The residual before the first iteration and after each one (`iterations + 1` entries); each
    /// solver documents which norm (CG and Jacobi: ‖b − A x‖ / ‖b‖).
    pub residuals: Vec<f64>,
    /// Wall time of the solve.
    pub wall_time: Duration,
    /// Why it stopped.
    pub stop: StopReason,
}

impl Report {
    pub(crate) fn start(max_iterations: usize) -> Self {
        Report {
            iterations: 0,
            // Reserved up front, so that the usual solve never allocates in its iterations; a
            // limit beyond the reserve grows the history as it goes, never by the user's limit.
            residuals: Vec::with_capacity(max_iterations.saturating_add(1).min(HISTORY_RESERVE)),
            wall_time: Duration::ZERO,
            stop: StopReason::IterationLimit,
        }
    }

    /// The last residual (NaN for a report with none).
    pub fn residual(&self) -> f64 {
        self.residuals.last().copied().unwrap_or(f64::NAN)
    }

    /// Iterations, last residual and stop reason.
    pub fn summary(&self) -> SolveSummary {
        SolveSummary {
            iterations: self.iterations,
            residual: self.residual(),
            stop: self.stop,
            substeps: 1,
        }
    }
}

/// Why a solve failed. Every variant carries the report up to the failure.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolveError {
    /// A direction of non-positive curvature pᵀAp ≤ 0 was met: the matrix is not positive definite.
    #[error("the matrix is not positive definite: pᵀAp = {curvature:e} at iteration {}", report.iterations)]
    NotPositiveDefinite {
        /// The offending pᵀAp.
        curvature: f64,
        /// The report so far.
        report: Report,
    },
    /// The residual grew far beyond its start (e.g. Jacobi on a system that is not diagonally
    /// dominant enough).
    #[error("the iteration diverged: residual {:e} after {} iterations, from {:e}", report.residual(), report.iterations, report.residuals.first().copied().unwrap_or(f64::NAN))]
    Diverged {
        /// The report so far.
        report: Report,
    },
    /// NaN or infinity appeared in the iterate or the residual.
    #[error("non-finite values at iteration {}", report.iterations)]
    NonFinite {
        /// The report so far.
        report: Report,
    },
    /// A parameter of the solver is out of its range (checked before the first iteration).
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
    /// A diagonal block of the preconditioner or of Jacobi's splitting is singular.
    #[error("diagonal block {block} is singular")]
    SingularBlock {
        /// Index of the block (vertex).
        block: usize,
    },
}

impl SolveError {
    /// The report carried by the error, if it has one (every variant but
    /// [`SolveError::InvalidParameter`] and [`SolveError::SingularBlock`]).
    pub fn into_report(self) -> Option<Report> {
        match self {
            SolveError::NotPositiveDefinite { report, .. }
            | SolveError::Diverged { report }
            | SolveError::NonFinite { report } => Some(report),
            SolveError::InvalidParameter(_) | SolveError::SingularBlock { .. } => None,
        }
    }
}
