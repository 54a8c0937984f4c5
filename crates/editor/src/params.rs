//! The editor's fixed parameters (their defaults in docs/editor.md) and the integrators
//! it offers.

use hooke_sim::{Integrator, LinearSolver, Settings};
use serde::{Deserialize, Serialize};

use crate::EditorError;

/// Constants of the editor that do not change while it runs; [`EditorParams::validate`] checks
/// every field where it enters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EditorParams {
    /// Simulated time of one frame, s (default: 10 substeps of 1e-3 s).
    pub frame_time: f64,
    /// Substeps per frame at the start (every integrator steps frame_time / substeps; default: 10).
    pub substeps: usize,
    /// Mass of every particle, kg (default: 1).
    pub particle_mass: f64,
    /// Gravity, m/s², pointing down (default: 9.8).
    pub gravity: f64,
    /// A new particle is joined to every particle closer than this, m (default: 0.15).
    pub connection_radius: f64,
    /// Rest length of a new spring, m (default: 0.1).
    pub rest_length: f64,
    /// Young's modulus Y at the start, N: a spring of rest length l has stiffness k = Y / l
    /// (the force −Y(|r|/l − 1) r̂; default: 1000).
    pub young: f64,
    /// Drag rate at the start, 1/s: v ← v e^(−h c) (default: 1).
    pub drag: f64,
    /// Dashpot coefficient along springs at the start, N·s/m (default: 100).
    pub dashpot: f64,
    /// Strength s of the right-button pull, 1/s²: each frame every free particle's velocity
    /// changes by −T s (x − p), T the frame time (default: 100).
    pub attractor_strength: f64,
    /// A click within this distance of a particle picks it (pin toggle, drag), m.
    pub pick_radius: f64,
    /// Most particles the editor holds (default: 1024); a click beyond is refused with a notice.
    pub max_particles: usize,
}

impl Default for EditorParams {
    fn default() -> Self {
        EditorParams {
            frame_time: 1e-2,
            substeps: 10,
            particle_mass: 1.0,
            gravity: 9.8,
            connection_radius: 0.15,
            rest_length: 0.1,
            young: 1000.0,
            drag: 1.0,
            dashpot: 100.0,
            attractor_strength: 100.0,
            pick_radius: 0.02,
            max_particles: 1024,
        }
    }
}

/// The smallest drag rate other than 0 that the drag key sets, 1/s: raising 0 gives it, lowering
/// below it gives 0 (velocities then lose 1 % a second; the default drag is 1/s).
pub const DRAG_FLOOR: f64 = 0.01;
/// The smallest dashpot coefficient other than 0 that the dashpot key sets, N·s/m: raising 0 gives
/// it, lowering below it gives 0 (1 % of the default 100 N·s/m).
pub const DASHPOT_FLOOR: f64 = 1.0;

/// Most substeps per frame the `]` key reaches.
pub const MAX_SUBSTEPS: usize = 1024;
/// Largest particle budget [`EditorParams::validate`] accepts.
pub const MAX_PARTICLES: usize = 100_000;

fn positive(name: &'static str, value: f64) -> Result<(), EditorError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(EditorError::InvalidParameter {
            name,
            value: value.to_string(),
            allowed: "finite and > 0",
        })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), EditorError> {
    if value >= 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(EditorError::InvalidParameter {
            name,
            value: value.to_string(),
            allowed: "finite and >= 0",
        })
    }
}

impl EditorParams {
    /// Check every field.
    ///
    /// # Errors
    /// [`EditorError::InvalidParameter`] naming the field and its allowed range.
    pub fn validate(&self) -> Result<(), EditorError> {
        positive("frame_time", self.frame_time)?;
        if !(1..=MAX_SUBSTEPS).contains(&self.substeps) {
            return Err(EditorError::InvalidParameter {
                name: "substeps",
                value: self.substeps.to_string(),
                allowed: "1 to 1024",
            });
        }
        positive("particle_mass", self.particle_mass)?;
        non_negative("gravity", self.gravity)?;
        positive("connection_radius", self.connection_radius)?;
        positive("rest_length", self.rest_length)?;
        positive("young", self.young)?;
        non_negative("drag", self.drag)?;
        non_negative("dashpot", self.dashpot)?;
        non_negative("attractor_strength", self.attractor_strength)?;
        non_negative("pick_radius", self.pick_radius)?;
        if !(1..=MAX_PARTICLES).contains(&self.max_particles) {
            return Err(EditorError::InvalidParameter {
                name: "max_particles",
                value: self.max_particles.to_string(),
                allowed: "1 to 100000",
            });
        }
        Ok(())
    }
}

/// An integrator the editor can switch to live (every one the library has; the linearised β = 1
/// step with each of its linear solvers).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum IntegratorChoice {
    /// Symplectic Euler, the default.
    SymplecticEuler,
    /// Forward Euler (gains energy; refused above its growth bound).
    ExplicitEuler,
    /// Linearised backward Euler (β = 1) solved by conjugate gradient.
    LinearizedCg,
    /// Linearised backward Euler (β = 1) solved by block Jacobi.
    LinearizedJacobi,
    /// Backward Euler solved by Newton's method.
    Newton,
    /// Backward Euler by projective dynamics (10 iterations a step).
    #[serde(rename = "pd")]
    ProjectiveDynamics,
    /// Backward Euler by L-BFGS, the PD matrix as its initial Hessian.
    Lbfgs,
    /// Backward Euler by Newton-CG, preconditioned by the PD factor.
    NewtonCg,
    /// Projective dynamics with Chebyshev acceleration (10 iterations a step).
    #[serde(rename = "pd-chebyshev")]
    ChebyshevPd,
}

impl IntegratorChoice {
    /// The order the integrator key cycles through.
    pub const ALL: &'static [IntegratorChoice] = &[
        IntegratorChoice::SymplecticEuler,
        IntegratorChoice::ExplicitEuler,
        IntegratorChoice::LinearizedCg,
        IntegratorChoice::LinearizedJacobi,
        IntegratorChoice::Newton,
        IntegratorChoice::ProjectiveDynamics,
        IntegratorChoice::Lbfgs,
        IntegratorChoice::NewtonCg,
        IntegratorChoice::ChebyshevPd,
    ];

    /// The name shown and written to STATE.json.
    pub fn name(&self) -> &'static str {
        match self {
            IntegratorChoice::SymplecticEuler => "symplectic-euler",
            IntegratorChoice::ExplicitEuler => "explicit-euler",
            IntegratorChoice::LinearizedCg => "linearized-cg",
            IntegratorChoice::LinearizedJacobi => "linearized-jacobi",
            IntegratorChoice::Newton => "newton",
            IntegratorChoice::ProjectiveDynamics => "pd",
            IntegratorChoice::Lbfgs => "lbfgs",
            IntegratorChoice::NewtonCg => "newton-cg",
            IntegratorChoice::ChebyshevPd => "pd-chebyshev",
        }
    }

    /// Parse a name as [`IntegratorChoice::name`] writes it.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == name)
    }

    /// The next (`forward`) or previous integrator in [`IntegratorChoice::ALL`], wrapping.
    pub fn cycled(self, forward: bool) -> Self {
        let all = Self::ALL;
        let at = all.iter().position(|&c| c == self).unwrap_or(0);
        let next = if forward {
            (at + 1) % all.len()
        } else {
            (at + all.len() - 1) % all.len()
        };
        all[next]
    }

    /// The choice that matches the library's settings (the linear solver picks the linearised
    /// variant).
    pub fn from_settings(settings: &Settings) -> Self {
        match settings.integrator {
            Integrator::ExplicitEuler => IntegratorChoice::ExplicitEuler,
            Integrator::Linearized => match settings.linearized.solver {
                LinearSolver::Jacobi => IntegratorChoice::LinearizedJacobi,
                _ => IntegratorChoice::LinearizedCg,
            },
            Integrator::Newton => IntegratorChoice::Newton,
            Integrator::ProjectiveDynamics => IntegratorChoice::ProjectiveDynamics,
            Integrator::Lbfgs => IntegratorChoice::Lbfgs,
            Integrator::NewtonCg => IntegratorChoice::NewtonCg,
            Integrator::ChebyshevPd => IntegratorChoice::ChebyshevPd,
            _ => IntegratorChoice::SymplecticEuler,
        }
    }

    /// The library's settings for this choice: one step of the library per editor substep, no
    /// energy watchdog (the pull and the drag feed energy in on purpose).
    pub fn settings(&self) -> Settings {
        let mut settings = Settings {
            substeps: Some(1),
            energy_limit: None,
            ..Settings::default()
        };
        settings.integrator = match self {
            IntegratorChoice::SymplecticEuler => Integrator::SymplecticEuler,
            IntegratorChoice::ExplicitEuler => Integrator::ExplicitEuler,
            IntegratorChoice::LinearizedCg => {
                settings.linearized.solver = LinearSolver::ConjugateGradient;
                Integrator::Linearized
            }
            IntegratorChoice::LinearizedJacobi => {
                settings.linearized.solver = LinearSolver::Jacobi;
                Integrator::Linearized
            }
            IntegratorChoice::Newton => Integrator::Newton,
            IntegratorChoice::ProjectiveDynamics => Integrator::ProjectiveDynamics,
            IntegratorChoice::Lbfgs => Integrator::Lbfgs,
            IntegratorChoice::NewtonCg => Integrator::NewtonCg,
            IntegratorChoice::ChebyshevPd => Integrator::ChebyshevPd,
        };
        settings
    }

    /// True if the library's integrator for this choice models dashpot damping (projective
    /// dynamics does not: its one constant matrix cannot hold the dashpot's direction-dependent
    /// Jacobian, so the editor runs it without the dashpot and says so).
    pub fn models_dashpot(&self) -> bool {
        !matches!(
            self,
            IntegratorChoice::ProjectiveDynamics | IntegratorChoice::ChebyshevPd
        )
    }
}
