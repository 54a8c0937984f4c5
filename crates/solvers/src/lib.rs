//! # hooke-solvers
//!
//! Linear and nonlinear solvers for hooke's implicit integrators:
//! - the [`LinearOperator`] and [`Preconditioner`] traits, preconditioned [`ConjugateGradient`]
//!   and block [`Jacobi`], which return `Result<`[`Report`]`, `[`SolveError`]`>`;
//! - [`Amg`], a smoothed-aggregation algebraic multigrid preconditioner for 3 × 3-block (or
//!   scalar) SPD systems, `Result<_, `[`AmgError`]`>`;
//! - [`SparseCholesky`] (faer, symbolic analysis reused, the factor bounded by a
//!   [`MemoryBudget`]), `Result<_, `[`CholeskyError`]`>`;
//! - [`Newton`] on a [`NewtonProblem`] (LDLᵀ with inertia, an indefinite-Hessian policy, a line
//!   search, and an opt-in nonlinear relaxation; [`BackwardEulerStep`] is backward Euler's
//!   problem), which returns `Result<`[`NewtonReport`]`, `[`NewtonError`]`>`;
//! - [`ProjectiveDynamics`] for a backward Euler step, `Result<`[`PdReport`]`, `[`PdError`]`>`,
//!   [`ChebyshevPd`], its Chebyshev-accelerated form, and [`AndersonPd`], its Anderson-accelerated
//!   form with an energy guard;
//! - [`Lbfgs`] (the PD matrix as initial Hessian) and [`NewtonCg`] (CG on the exact Hessian,
//!   preconditioned by the PD factor) on a [`NewtonProblem`], with PD's factor as their
//!   [`Preconditioner`].
//!
//! Every solver takes a `Copy + Default` parameter struct with a `validate()` that names the
//! first field out of its range ([`ParamError`]); the solver calls it where the struct enters (its
//! constructor, and at the start of each solve, since the settings are public fields). Every report
//! says why the solve stopped ([`StopReason`]; only [`StopReason::is_converged`] stops found the
//! solution asked for), and every error after the first iteration carries the report up to the
//! failure. Workspaces live in the solver objects and are reused across solves, so the iterations
//! do not allocate; reports reserve a fixed number of records, never the iteration limit.
//!
//! ```
//! use hooke_solvers::{CgParams, ConjugateGradient, Identity, StopReason};
//! use nalgebra::DMatrix;
//!
//! let a = DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 3.0]);
//! let b = [1.0, 2.0];
//! let mut x = [0.0; 2];
//! let report = ConjugateGradient::new(CgParams::default()).solve(&a, &mut Identity, &b, &mut x)?;
//! assert_eq!(report.stop, StopReason::Converged);
//! assert!((x[0] - 1.0 / 11.0).abs() < 1e-12 && (x[1] - 7.0 / 11.0).abs() < 1e-12);
//! # Ok::<(), hooke_solvers::SolveError>(())
//! ```
#![deny(missing_docs)]

/// The faer version whose types ([`faer::sparse::SparseColMat`], [`faer::Par`], …) appear in this
/// crate's public signatures, re-exported so that callers build them with the same version.
pub use faer;

pub mod amg;
pub mod anderson;
pub mod backward_euler;
pub mod cg;
pub mod chebyshev;
pub mod cholesky;
mod forest_solve;
pub mod jacobi;
pub mod lbfgs;
pub mod multilevel;
pub mod newton;
pub mod newton_cg;
pub mod operator;
mod params;
pub mod projective;
mod report;

pub use amg::{
    Amg, AmgColumns, AmgError, AmgParams, AmgSmoother, AMG_MAX_BLOCK, AMG_PARTS_MIN_ROWS,
};
pub use anderson::{
    AndersonParams, AndersonPd, AndersonReport, ANDERSON_MAX_ITERATIONS, ANDERSON_MAX_WINDOW,
};
pub use backward_euler::BackwardEulerStep;
pub use cg::{CgParams, ConjugateGradient};
pub use chebyshev::{ChebyshevParams, ChebyshevPd, ChebyshevReport, CHEBYSHEV_MAX_ITERATIONS};
pub use cholesky::{
    CholeskyError, CholeskyParams, FactorKind, Inertia, SparseCholesky, SPLIT_MIN_FACTOR,
};
pub use jacobi::{Jacobi, JacobiParams};
pub use lbfgs::{
    Lbfgs, LbfgsError, LbfgsParams, LbfgsReport, LBFGS_MAX_HISTORY, LBFGS_MAX_ITERATIONS,
};
pub use multilevel::{
    MemoryBudget, MultilevelSolve, MultilevelStats, FALLBACK_BUDGET, MULTILEVEL_MAX_ITERATIONS,
    MULTILEVEL_TOLERANCE,
};
pub use newton::{
    Convergence, FactorReuse, IndefinitePolicy, Newton, NewtonError, NewtonIteration, NewtonParams,
    NewtonProblem, NewtonReport, Relaxation, RelaxationWork, DEFAULT_STEP_TOLERANCE,
    MAX_LINE_SEARCH_HALVINGS, MAX_PATCH_COVERS, MAX_RELAXATION_COUNT, MAX_RINGS, MAX_SHIFT_STEPS,
    MULTILEVEL_FILL,
};
pub use newton_cg::{
    NewtonCg, NewtonCgError, NewtonCgParams, NewtonCgReport, NEWTON_CG_MAX_ITERATIONS,
};
pub use operator::{BlockJacobi, Identity, LinearOperator, Preconditioner, Symmetric};
pub use params::{ParamError, MAX_THREADS};
pub use projective::{
    FixedPointError, GlobalSolveKind, PdContactModel, PdError, PdMultilevelParams, PdParams,
    PdReport, ProjectiveDynamics, DEFAULT_CONTACT_WEIGHT, MULTILEVEL_PD_FILL,
    MULTILEVEL_PD_UNKNOWNS, PD_MAX_ITERATIONS,
};
pub use report::{Report, SolveError, SolveSummary, StopReason};
