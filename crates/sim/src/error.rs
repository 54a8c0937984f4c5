//! The simulation crate's error type.

use hooke_mesh::MeshError;
use hooke_solvers::{LbfgsError, NewtonCgError, NewtonError, ParamError, PdError, SolveError};

/// A solver's own error, typed, with the report it carries (Newton's, PD's or the contact
/// projection's linear solve).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolverFailure {
    /// Backward Euler by Newton: the error carries Newton's report up to the failure
    /// ([`NewtonError::report`]). A step is redone in halves before this is returned (see
    /// [`crate::Integrator::Newton`]), so it is the failure of the smallest piece tried.
    #[error("Newton: {0}")]
    Newton(#[from] NewtonError),
    /// Backward Euler by L-BFGS: its error, with its report (boxed, as the report is large). L-BFGS
    /// does not halve: this is the step's own failure.
    #[error("L-BFGS: {0}")]
    Lbfgs(Box<LbfgsError>),
    /// Backward Euler by Newton-CG: its error, with its report (halved first, as Newton's).
    #[error("Newton-CG: {0}")]
    NewtonCg(Box<NewtonCgError>),
    /// Projective dynamics could not be set up (its global matrix did not factor) or run.
    #[error("projective dynamics: {0}")]
    ProjectiveDynamics(#[from] PdError),
    /// The contact projection after an implicit step: its linear solve met NaN or a singular
    /// block.
    #[error("contact projection: {0}")]
    ContactProjection(#[from] SolveError),
}

impl From<LbfgsError> for SolverFailure {
    fn from(e: LbfgsError) -> Self {
        SolverFailure::Lbfgs(Box::new(e))
    }
}

impl From<NewtonCgError> for SolverFailure {
    fn from(e: NewtonCgError) -> Self {
        SolverFailure::NewtonCg(Box::new(e))
    }
}

/// Everything that can stop a scene from being built or a step from being taken.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The mesh is invalid (see [`MeshError`]).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// A physical or numerical parameter is out of its domain.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// Which parameter (e.g. "time step", "damping.dashpot").
        name: String,
        /// Its value, as text.
        value: String,
        /// Why it is rejected.
        reason: String,
    },
    /// A pinned vertex index is not a vertex of the mesh.
    #[error("pinned vertex {vertex} does not exist (the mesh has {vertex_count} vertices)")]
    PinOutOfRange {
        /// The offending index.
        vertex: usize,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A pin region that contains no vertex: almost certainly a mistake in the scene.
    #[error("the pin region {min:?}..{max:?} contains no vertex")]
    EmptyPinRegion {
        /// Lower corner (m).
        min: Vec<f64>,
        /// Upper corner (m).
        max: Vec<f64>,
    },
    /// Every vertex is pinned: nothing can move.
    #[error("all {vertex_count} vertices are pinned: nothing is left to simulate")]
    EverythingPinned {
        /// Number of vertices.
        vertex_count: usize,
    },
    /// An explicit step above its stability bound, not forced by the user.
    #[error(
        "the step {step:.3e} s is above the explicit stability bound {bound:.3e} s of this scene \
         (stiffest vertex: {vertex}); use at least {suggested_substeps} substeps, or force it"
    )]
    UnstableStep {
        /// The (sub)step asked for (s).
        step: f64,
        /// The estimated largest stable step (s).
        bound: f64,
        /// The vertex with the highest natural frequency.
        vertex: usize,
        /// Substeps per frame that would bring the step under the bound.
        suggested_substeps: usize,
    },
    /// The state ran away: a coordinate far outside any plausible motion of the scene.
    #[error(
        "step {step}: vertex {vertex} has {quantity} {value:.3e}, beyond the divergence limit \
         {limit:.3e}; the simulation exploded"
    )]
    Diverged {
        /// The step (1-based) during which it happened.
        step: usize,
        /// The first vertex found.
        vertex: usize,
        /// "position" (m) or "velocity" (m/s).
        quantity: &'static str,
        /// The offending coordinate's magnitude.
        value: f64,
        /// The limit it crossed.
        limit: f64,
    },
    /// The integrator cannot model a term the scene asks for; running without it would be wrong.
    /// `what` names the term, why, and what to use instead.
    #[error("the {integrator} integrator does not support {what}")]
    Unsupported {
        /// The integrator.
        integrator: String,
        /// The scene term, why it is not supported, and what to use instead.
        what: String,
    },
    /// The implicit solver failed: its typed error, with its report.
    #[error("step {step}: the solver failed: {source}")]
    Solver {
        /// The step (1-based) during which it happened; 0 while the simulation was being set
        /// up ([`crate::Simulation::new`]).
        step: usize,
        /// The solver's error.
        #[source]
        source: SolverFailure,
    },
    /// A solver's parameter struct is out of range ([`crate::Settings::validate`]): the field
    /// (e.g. `NewtonParams::blend_factor`) and its allowed range.
    #[error("invalid solver setting: {0}")]
    SolverParameter(#[from] ParamError),
    /// The linear solve of a linearised implicit Euler step failed: the system is not positive
    /// definite, Jacobi diverged, or NaN appeared. (A solve that merely reaches its iteration limit is
    /// not an error: the step's report says [`hooke_solvers::StopReason::IterationLimit`].)
    #[error("step {step}: the {solver} solve of the linearized system failed: {source}")]
    LinearSolve {
        /// The step (1-based) during which it happened.
        step: usize,
        /// The linear solver (`jacobi` or `cg`).
        solver: &'static str,
        /// The solver's error, with its report.
        #[source]
        source: hooke_solvers::SolveError,
    },
    /// The total energy of a scene without energy sources rose beyond the watchdog's limit
    /// ([`Settings::energy_limit`](crate::Settings::energy_limit)): the run is unstable.
    #[error(
        "step {step}: the total energy rose to {energy:.3e} J from {initial:.3e} J, beyond the \
         limit {limit:.3e} J of a scene without energy sources: the {integrator} run is unstable \
         ({advice}; the limit is the energy_limit setting, `--energy-limit FACTOR|off`)",
        advice = energy_growth_advice(integrator)
    )]
    EnergyGrowth {
        /// The step (1-based) after which it happened.
        step: usize,
        /// The integrator's name.
        integrator: &'static str,
        /// The total energy after the step, J.
        energy: f64,
        /// The total energy at the start, J.
        initial: f64,
        /// The limit it crossed, J.
        limit: f64,
    },
    /// The state became NaN or infinite.
    #[error("step {step}: vertex {vertex} has a non-finite {quantity}; the simulation diverged")]
    NonFinite {
        /// The step (1-based) during which it happened.
        step: usize,
        /// The first vertex found.
        vertex: usize,
        /// "position" or "velocity".
        quantity: &'static str,
    },
}

/// What helps a run of `integrator` (its name, as [`crate::Integrator::name`]) whose energy grew,
/// in the command's flags and the scene file's keys (docs/formats.md §1.8): the explicit methods
/// are stable only below their step bound (more substeps) or by an implicit integrator; the
/// linearised step is a single Newton iteration (backward Euler solved to convergence); backward
/// Euler itself dissipates energy, so with it the growth comes from a solve that stopped short
/// (more iterations, a tighter tolerance) or from a step too large for the solve (a smaller one).
pub(crate) fn energy_growth_advice(integrator: &str) -> &'static str {
    match integrator {
        "explicit-euler" | "symplectic-euler" => {
            "try more substeps (`--substeps`, integrator.substeps) or a backward Euler integrator \
             (`--integrator newton` or `pd`)"
        }
        "linearized" => {
            "the linearized step is one Newton iteration of backward Euler: try backward Euler \
             solved to convergence (`--integrator newton` or `pd`), or a smaller step (`--dt`, \
             integrator.time_step)"
        }
        "pd" | "pd-chebyshev" => {
            "backward Euler dissipates energy, so the iterations stopped short of it: try more \
             iterations per step (`--iterations`, integrator.iterations), a smaller step (`--dt`, \
             integrator.time_step), or `--integrator newton`"
        }
        _ => {
            "backward Euler dissipates energy, so the solve stopped short of it: try a tighter \
             tolerance (`--tolerance`, integrator.tolerance), more iterations (`--iterations`, \
             integrator.iterations), or a smaller step (`--dt`, integrator.time_step)"
        }
    }
}

impl SimError {
    /// A solver failure during set-up (step 0), which [`crate::Simulation::step`] renumbers.
    pub(crate) fn solver(source: impl Into<SolverFailure>) -> Self {
        SimError::Solver {
            step: 0,
            source: source.into(),
        }
    }

    /// This error with the step index set (for the errors that carry one and do not have it yet).
    pub(crate) fn at_step(mut self, index: usize) -> Self {
        if let SimError::Solver { step, .. } = &mut self {
            if *step == 0 {
                *step = index;
            }
        }
        self
    }

    pub(crate) fn invalid(
        name: impl Into<String>,
        value: impl ToString,
        reason: impl Into<String>,
    ) -> Self {
        SimError::InvalidParameter {
            name: name.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }
}

/// `Ok` if `value` is finite and ≥ 0.
pub(crate) fn non_negative(name: &str, value: f64) -> Result<f64, SimError> {
    if value >= 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(SimError::invalid(
            name,
            value,
            "must be finite and non-negative",
        ))
    }
}

/// `Ok` if `value` is finite and > 0.
pub(crate) fn positive(name: &str, value: f64) -> Result<f64, SimError> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(SimError::invalid(
            name,
            value,
            "must be finite and positive",
        ))
    }
}

/// `Ok` if every component is finite.
pub(crate) fn finite_vector<const D: usize>(
    name: &str,
    value: &nalgebra::SVector<f64, D>,
) -> Result<(), SimError> {
    if value.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(SimError::invalid(
            name,
            format!("{:?}", value.as_slice()),
            "must be finite",
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The watchdog never advises a run to switch to the integrator it already uses, and each
    /// family's advice names what helps it.
    #[test]
    fn energy_advice_depends_on_the_integrator() {
        let message = |integrator: &'static str| {
            SimError::EnergyGrowth {
                step: 3,
                integrator,
                energy: 2.0,
                initial: 1.0,
                limit: 1.5,
            }
            .to_string()
        };
        for integrator in ["explicit-euler", "symplectic-euler"] {
            let text = message(integrator);
            assert!(text.contains("--substeps"), "{text}");
            assert!(text.contains("--integrator newton"), "{text}");
        }
        let text = message("linearized");
        assert!(text.contains("--integrator newton"), "{text}");
        for integrator in crate::Integrator::ALL.iter().filter(|i| !i.is_explicit()) {
            let text = message(integrator.name());
            assert!(!text.contains("--substeps"), "{integrator}: {text}");
            assert!(
                !text.contains(&format!("--integrator {integrator}")),
                "{integrator} is advised to switch to itself: {text}"
            );
            if *integrator != crate::Integrator::Linearized {
                assert!(text.contains("--iterations"), "{text}");
                assert!(text.contains("--dt"), "{text}");
            }
        }
    }
}
