//! Newton's method for minimising a smooth objective Φ whose Hessian has a fixed sparsity pattern
//! (backward Euler: Φ(x) = ½ (x − y)ᵀ M (x − y) + h² E(x), seed 003).
//!
//! The exact Hessian is indefinite where springs are compressed, so a plain Newton step may not
//! descend and a Cholesky may fail. The default here is a Levenberg–Marquardt-like shift: factor
//! H + μ D (D a positive diagonal, the mass matrix for backward Euler), starting from μ = 0 (the exact
//! Newton step, quadratic convergence near the solution) and raising μ by a factor 10 each time the
//! factorisation fails or the step needs a short line search; lowering it after full steps. Every
//! shift is counted in the report. A backtracking (Armijo) line search on Φ guarantees decrease.
//! When a shortened step no longer lowers Φ beyond its round-off, the solve stops with
//! [`StopReason::Stagnated`]: the tolerance asked for is below what the arithmetic resolves.

use std::time::{Duration, Instant};

use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};

use crate::cholesky::{CholeskyError, CholeskyParams, SparseCholesky};
use crate::operator::dot;
use crate::report::StopReason;

/// A line-searched step that lowers Φ by at most this many units of round-off (ε|Φ|) counts as no
/// progress: the iterate is at the resolution floor of Φ and its gradient.
const STAGNATION_ULPS: f64 = 8.0;

/// The objective Newton minimises. The Hessian's pattern is fixed: [`NewtonProblem::hessian`]
/// refills the values of [`NewtonProblem::pattern`] and returns the matrix (full symmetric storage).
pub trait NewtonProblem {
    /// Number of unknowns.
    fn dim(&self) -> usize;
    /// Φ(x).
    fn objective(&mut self, x: &[f64]) -> f64;
    /// g = ∇Φ(x).
    fn gradient(&mut self, x: &[f64], g: &mut [f64]);
    /// The Hessian's sparsity pattern (never changes; every diagonal entry must be stored).
    fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize>;
    /// Refill the Hessian's values at x and return it.
    fn hessian(&mut self, x: &[f64]) -> SparseColMatRef<'_, usize, f64>;
    /// The positive diagonal D of the shift H + μ D, one entry per unknown (the masses for backward
    /// Euler, which makes μ dimensionless: μ = 1 doubles the inertia).
    fn shift_diagonal(&self) -> &[f64];
}

/// Settings of [`Newton`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// Stop when ‖∇Φ(x)‖ ≤ `tolerance` · ‖∇Φ(x⁰)‖. Default 1e-8 (1e-10 for reference solutions).
    pub tolerance: f64,
    /// Iteration limit. Default 50.
    pub max_iterations: usize,
    /// Armijo constant c in Φ(x + αΔ) ≤ Φ(x) + c α ∇Φᵀ Δ. Default 1e-4.
    pub armijo: f64,
    /// Step halvings before the line search gives up. Default 40.
    pub max_halvings: usize,
    /// The first non-zero shift μ tried after a failed factorisation. Default 1e-4.
    pub initial_shift: f64,
    /// Above this shift the solve gives up (the problem is not convex enough to fix). Default 1e12.
    pub max_shift: f64,
    /// Factorisation settings.
    pub cholesky: CholeskyParams,
}

impl Default for NewtonParams {
    fn default() -> Self {
        NewtonParams {
            tolerance: 1e-8,
            max_iterations: 50,
            armijo: 1e-4,
            max_halvings: 40,
            initial_shift: 1e-4,
            max_shift: 1e12,
            cholesky: CholeskyParams::default(),
        }
    }
}

/// One Newton iteration's record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonIteration {
    /// Relative gradient norm ‖∇Φ‖ / ‖∇Φ(x⁰)‖ after the iteration.
    pub gradient: f64,
    /// Φ after the iteration.
    pub objective: f64,
    /// The shift μ of the accepted step (0: exact Hessian).
    pub shift: f64,
    /// Failed factorisations before the step was found.
    pub failed_factorizations: usize,
    /// Line-search step length α.
    pub step_length: f64,
}

/// The account of a Newton solve.
#[derive(Clone, Debug, PartialEq)]
pub struct NewtonReport {
    /// Iterations (accepted steps).
    pub iterations: usize,
    /// Relative gradient norm before the first iteration.
    pub initial_gradient: f64,
    /// Φ before the first iteration.
    pub initial_objective: f64,
    /// One record per iteration.
    pub history: Vec<NewtonIteration>,
    /// Iterations that used a non-zero shift.
    pub shifted_steps: usize,
    /// Failed factorisations in all (each one raised the shift).
    pub failed_factorizations: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// Wall time, and the part spent in numeric factorisations.
    pub wall_time: Duration,
    /// Time in numeric factorisations.
    pub factor_time: Duration,
}

impl NewtonReport {
    /// The last relative gradient norm.
    pub fn gradient(&self) -> f64 {
        self.history
            .last()
            .map_or(self.initial_gradient, |h| h.gradient)
    }
}

/// Why Newton failed; each variant keeps the report so far.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NewtonError {
    /// No step along the Newton direction decreased Φ enough.
    #[error("the line search failed at iteration {} (relative gradient {:e})", report.iterations, report.gradient())]
    LineSearchFailed {
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// Even the largest shift did not give a factorisable matrix.
    #[error("the Hessian could not be made positive definite (shift above {max_shift:e}) at iteration {}", report.iterations)]
    NotPositiveDefinite {
        /// The limit that was passed.
        max_shift: f64,
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// Φ or its gradient is NaN or infinite.
    #[error("non-finite objective or gradient at iteration {}", report.iterations)]
    NonFinite {
        /// The report so far.
        report: Box<NewtonReport>,
    },
    /// The Hessian does not have the analysed pattern, or its analysis failed.
    #[error(transparent)]
    Factorization(#[from] CholeskyError),
}

/// Newton's method with its workspace (factorisation, vectors, the shifted value buffer), reused
/// across solves on the same pattern: the symbolic analysis is done once.
#[derive(Debug)]
pub struct Newton {
    /// The settings.
    pub params: NewtonParams,
    cholesky: SparseCholesky,
    diagonal_slots: Vec<usize>,
    shifted: Vec<f64>,
    g: Vec<f64>,
    step: Vec<f64>,
    trial: Vec<f64>,
    shift: f64,
}

impl Newton {
    /// Analyse the problem's Hessian pattern once.
    ///
    /// # Errors
    /// [`NewtonError::Factorization`] if the symbolic analysis fails.
    ///
    /// # Panics
    /// If the pattern lacks a diagonal entry.
    #[track_caller]
    pub fn new(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        params: NewtonParams,
    ) -> Result<Self, NewtonError> {
        let n = pattern.ncols();
        let diagonal_slots = (0..n)
            .map(|j| {
                let start = pattern.col_ptr()[j];
                let rows = pattern.row_idx_of_col_raw(j);
                let k = rows
                    .iter()
                    .position(|&i| i == j)
                    .expect("every diagonal entry is stored");
                start + k
            })
            .collect();
        Ok(Newton {
            cholesky: SparseCholesky::analyze(pattern, params.cholesky)?,
            diagonal_slots,
            shifted: vec![0.0; pattern.compute_nnz()],
            g: vec![0.0; n],
            step: vec![0.0; n],
            trial: vec![0.0; n],
            shift: 0.0,
            params,
        })
    }

    /// Minimise Φ from the guess in `x` (which holds the result on return).
    ///
    /// # Errors
    /// [`NewtonError`], carrying the report so far.
    ///
    /// # Panics
    /// If `x` or the problem's pattern does not match the analysed dimension.
    #[track_caller]
    pub fn minimize(
        &mut self,
        problem: &mut impl NewtonProblem,
        x: &mut [f64],
    ) -> Result<NewtonReport, NewtonError> {
        let n = problem.dim();
        assert_eq!(x.len(), n, "unknowns");
        assert_eq!(
            self.g.len(),
            n,
            "the problem's dimension changed since the analysis"
        );
        let start = Instant::now();
        let p = self.params;
        let mut phi = problem.objective(x);
        problem.gradient(x, &mut self.g);
        let g0 = dot(&self.g, &self.g).sqrt();
        let scale = if g0 > 0.0 { 1.0 / g0 } else { 1.0 };
        let mut report = NewtonReport {
            iterations: 0,
            initial_gradient: 1.0,
            initial_objective: phi,
            history: Vec::with_capacity(p.max_iterations),
            shifted_steps: 0,
            failed_factorizations: 0,
            stop: StopReason::IterationLimit,
            wall_time: Duration::ZERO,
            factor_time: Duration::ZERO,
        };
        // Every solve starts from the exact Hessian: a shift earned in an earlier solve says nothing
        // about this one.
        self.shift = 0.0;
        let finish = |mut r: NewtonReport, stop| {
            r.stop = stop;
            r.wall_time = start.elapsed();
            r
        };
        let mut gradient = g0 * scale;
        loop {
            if !(phi.is_finite() && gradient.is_finite()) {
                return Err(NewtonError::NonFinite {
                    report: Box::new(finish(report, StopReason::IterationLimit)),
                });
            }
            if gradient <= p.tolerance || g0 == 0.0 {
                return Ok(finish(report, StopReason::Converged));
            }
            if report.iterations >= p.max_iterations {
                return Ok(finish(report, StopReason::IterationLimit));
            }
            // Factor H + μ D, raising μ until it factors.
            let mut failed = 0;
            loop {
                {
                    let h = problem.hessian(x);
                    assert_eq!(
                        h.val().len(),
                        self.shifted.len(),
                        "the Hessian's pattern changed"
                    );
                    self.shifted.copy_from_slice(h.val());
                }
                let d = problem.shift_diagonal();
                if self.shift > 0.0 {
                    for (j, &slot) in self.diagonal_slots.iter().enumerate() {
                        self.shifted[slot] += self.shift * d[j];
                    }
                }
                let shifted = SparseColMatRef::new(problem.pattern(), &self.shifted);
                match self.cholesky.factorize(shifted) {
                    Ok(()) => {
                        report.factor_time += self.cholesky.factor_time();
                        break;
                    }
                    Err(CholeskyError::NotPositiveDefinite { .. }) => {
                        report.factor_time += self.cholesky.factor_time();
                        failed += 1;
                        self.shift = if self.shift == 0.0 {
                            p.initial_shift
                        } else {
                            10.0 * self.shift
                        };
                        if self.shift > p.max_shift {
                            report.failed_factorizations += failed;
                            return Err(NewtonError::NotPositiveDefinite {
                                max_shift: p.max_shift,
                                report: Box::new(finish(report, StopReason::IterationLimit)),
                            });
                        }
                    }
                    Err(e) => return Err(e.into()),
                }
            }
            report.failed_factorizations += failed;
            // Δ = −(H + μD)⁻¹ g
            for (s, g) in self.step.iter_mut().zip(&self.g) {
                *s = -g;
            }
            self.cholesky.solve_slice(&mut self.step);
            let slope = dot(&self.g, &self.step);
            // Backtracking line search on Φ.
            let mut alpha = 1.0;
            let mut accepted = None;
            for _ in 0..=p.max_halvings {
                for ((t, x), s) in self.trial.iter_mut().zip(x.iter()).zip(&self.step) {
                    *t = x + alpha * s;
                }
                let trial_phi = problem.objective(&self.trial);
                if trial_phi.is_finite() && trial_phi <= phi + p.armijo * alpha * slope {
                    accepted = Some(trial_phi);
                    break;
                }
                alpha *= 0.5;
            }
            let Some(new_phi) = accepted else {
                return Err(NewtonError::LineSearchFailed {
                    report: Box::new(finish(report, StopReason::IterationLimit)),
                });
            };
            x.copy_from_slice(&self.trial);
            // A shortened step that lowers Φ by no more than its round-off means the iterate sits on
            // the floor of what the arithmetic can resolve: further iterations would only inflate
            // the shift. Stop and say so.
            let stagnated =
                alpha < 1.0 && phi - new_phi <= STAGNATION_ULPS * f64::EPSILON * phi.abs();
            phi = new_phi;
            problem.gradient(x, &mut self.g);
            gradient = dot(&self.g, &self.g).sqrt() * scale;
            report.iterations += 1;
            if self.shift > 0.0 {
                report.shifted_steps += 1;
            }
            report.history.push(NewtonIteration {
                gradient,
                objective: phi,
                shift: self.shift,
                failed_factorizations: failed,
                step_length: alpha,
            });
            if stagnated {
                return Ok(finish(report, StopReason::Stagnated));
            }
            // A full step means the model is trusted: relax the shift. A short one: stiffen it.
            if alpha == 1.0 {
                self.shift = if self.shift <= p.initial_shift {
                    0.0
                } else {
                    self.shift / 10.0
                };
            } else if alpha < 0.25 {
                self.shift = if self.shift == 0.0 {
                    p.initial_shift
                } else {
                    10.0 * self.shift
                }
                .min(p.max_shift);
            }
        }
    }
}
