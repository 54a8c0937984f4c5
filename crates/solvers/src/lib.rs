//! # hooke-solvers
//!
//! Linear and nonlinear solvers for hooke's implicit integrators: sparse Cholesky with symbolic
//! reuse, projective dynamics, Newton with line search, conjugate gradient and Jacobi.
//!
//! This crate is being built (see the project's issues); today it holds only the report type that
//! every solver will return, so that the simulation layer can already carry solver reports.
#![deny(missing_docs)]

/// Why an iterative solver stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum StopReason {
    /// The residual met the requested tolerance.
    Converged,
    /// The iteration limit was reached first.
    IterationLimit,
    /// The residual stopped decreasing.
    Stagnated,
}

/// What an iterative solve did: iterations, final residual and why it stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveSummary {
    /// Iterations performed.
    pub iterations: usize,
    /// The residual after the last iteration (the solver documents its norm).
    pub residual: f64,
    /// Why it stopped.
    pub stop: StopReason,
}
