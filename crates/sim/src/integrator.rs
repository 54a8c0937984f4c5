//! Time integrators and their settings.

use std::fmt;
use std::str::FromStr;

/// A time integration method (SPEC §2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Integrator {
    /// Forward Euler: v⁺ = v + h M⁻¹ f(x, v), x⁺ = x + h v. Unstable for undamped springs at any
    /// step (its amplification factor exceeds 1): it gains energy, slowly at small steps.
    ExplicitEuler,
    /// Symplectic (semi-implicit) Euler, seed 004's order: v⁺ = v + h M⁻¹ f(x, v), drag,
    /// x⁺ = x + h v⁺, contact. Stable below the step bound; energy oscillates but does not drift.
    SymplecticEuler,
    /// Backward Euler solved by Newton's method (seed 003) to [`Settings::newton`]'s tolerance.
    /// Unconditionally stable; dissipates energy.
    Newton,
    /// Backward Euler solved approximately by projective dynamics (Liu et al. 2013) with
    /// [`Settings::pd`]'s iteration budget; converges to the Newton solution as iterations grow.
    ProjectiveDynamics,
}

impl Integrator {
    /// Every integrator, in the order the command lists them.
    pub const ALL: &'static [Integrator] =
        &[Integrator::ExplicitEuler, Integrator::SymplecticEuler];

    /// The name used in scene files and on the command line (`explicit-euler`, `symplectic-euler`).
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::ExplicitEuler => "explicit-euler",
            Integrator::SymplecticEuler => "symplectic-euler",
            Integrator::Newton => "newton",
            Integrator::ProjectiveDynamics => "pd",
        }
    }

    /// True for the explicit methods, which have a step-size limit and take substeps.
    pub fn is_explicit(&self) -> bool {
        matches!(
            self,
            Integrator::ExplicitEuler | Integrator::SymplecticEuler
        )
    }
}

impl fmt::Display for Integrator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown integrator name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown integrator {name:?}; expected one of: {}", Integrator::ALL.iter().map(|i| i.name()).collect::<Vec<_>>().join(", "))]
pub struct UnknownIntegrator {
    /// The name that was given.
    pub name: String,
}

impl FromStr for Integrator {
    type Err = UnknownIntegrator;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "explicit-euler" | "forward-euler" => Ok(Integrator::ExplicitEuler),
            "symplectic-euler" | "semi-implicit-euler" => Ok(Integrator::SymplecticEuler),
            "newton" | "backward-euler" => Ok(Integrator::Newton),
            "pd" | "projective-dynamics" => Ok(Integrator::ProjectiveDynamics),
            other => Err(UnknownIntegrator {
                name: other.to_string(),
            }),
        }
    }
}

/// How a simulation integrates time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// The method.
    pub integrator: Integrator,
    /// Substeps per frame for explicit methods; `None` picks the fewest that keep each substep under
    /// the safe stability bound.
    pub substeps: Option<usize>,
    /// Let an explicit method run with a step above its estimated stability bound (it will likely
    /// blow up, and then stop with [`crate::SimError::NonFinite`]).
    pub allow_unstable: bool,
    /// Use rayon for the per-spring and per-vertex loops (results are identical either way).
    pub parallel: bool,
    /// Newton's settings (default: relative gradient 1e-8).
    pub newton: hooke_solvers::NewtonParams,
    /// Projective dynamics' settings (default: 10 iterations).
    pub pd: hooke_solvers::PdParams,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            integrator: Integrator::SymplecticEuler,
            substeps: None,
            allow_unstable: false,
            parallel: true,
            newton: hooke_solvers::NewtonParams::default(),
            pd: hooke_solvers::PdParams::default(),
        }
    }
}
