//! The fluid's physical and numerical parameters, and how a fluid is set up.

use nalgebra::SVector;

use crate::{KernelKind, SphError};

/// The time integrator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Integrator {
    /// Symplectic Euler, in the 2D sketch's order (docs/model.md §6.2): v⁺ = v + Δt a(x, v),
    /// x⁺ = x + Δt v⁺.
    #[default]
    SymplecticEuler,
    /// Leapfrog in kick-drift-kick form (velocity Verlet): second order; one force evaluation a step.
    Leapfrog,
}

impl Integrator {
    /// Every integrator, in the order the command lists them.
    pub const ALL: &'static [Integrator] = &[Integrator::SymplecticEuler, Integrator::Leapfrog];

    /// The name used in scene files and summaries: `symplectic-euler` or `leapfrog`.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::SymplecticEuler => "symplectic-euler",
            Integrator::Leapfrog => "leapfrog",
        }
    }
}

impl std::str::FromStr for Integrator {
    type Err = SphError;

    fn from_str(s: &str) -> Result<Self, SphError> {
        match s {
            "symplectic-euler" => Ok(Integrator::SymplecticEuler),
            "leapfrog" => Ok(Integrator::Leapfrog),
            _ => Err(SphError::UnknownName {
                what: "integrator",
                name: s.into(),
                allowed: "symplectic-euler, leapfrog",
            }),
        }
    }
}

/// How densities are obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum DensityMethod {
    /// ρᵢ = Σⱼ mⱼ W(|xᵢ − xⱼ|, h) over fluid and boundary particles (docs/sph.md). Near a free
    /// surface the sum misses the kernel's outer part and ρ falls below ρ₀; the fluid's pressure is
    /// then clamped at 0 so that this deficit does not pull the surface in (no tensile
    /// instability).
    Summation,
    /// The continuity equation dρᵢ/dt = Σⱼ mⱼ (vᵢ − vⱼ)·∇ᵢWᵢⱼ, integrated with the velocities
    /// (the form PySPH's and DualSPHysics' WCSPH use): no free-surface deficit, so ρ ≈ ρ₀ at the
    /// surface; the initial densities are the setup's. The default.
    #[default]
    Continuity,
}

impl DensityMethod {
    /// The name used in scene files and summaries: `summation` or `continuity`.
    pub fn name(self) -> &'static str {
        match self {
            DensityMethod::Summation => "summation",
            DensityMethod::Continuity => "continuity",
        }
    }
}

impl std::str::FromStr for DensityMethod {
    type Err = SphError;

    fn from_str(s: &str) -> Result<Self, SphError> {
        match s {
            "summation" => Ok(DensityMethod::Summation),
            "continuity" => Ok(DensityMethod::Continuity),
            _ => Err(SphError::UnknownName {
                what: "density method",
                name: s.into(),
                allowed: "summation, continuity",
            }),
        }
    }
}

/// How the domain's walls hold the fluid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Walls {
    /// Walls are the setup's boundary particles (several layers, fixed in place, with densities and
    /// pressures like the fluid's). A fluid particle that would leave the domain is an error.
    #[default]
    BoundaryParticles,
    /// The 2D sketch's box walls: after each step a particle outside the domain is put back on its
    /// face and its velocity component along the face's normal set to zero. Boundary particles may
    /// be given too.
    Clamp,
}

impl Walls {
    /// The name used in scene files and summaries: `boundary-particles` or `clamp`.
    pub fn name(self) -> &'static str {
        match self {
            Walls::BoundaryParticles => "boundary-particles",
            Walls::Clamp => "clamp",
        }
    }
}

impl std::str::FromStr for Walls {
    type Err = SphError;

    fn from_str(s: &str) -> Result<Self, SphError> {
        match s {
            "boundary-particles" => Ok(Walls::BoundaryParticles),
            "clamp" => Ok(Walls::Clamp),
            _ => Err(SphError::UnknownName {
                what: "walls",
                name: s.into(),
                allowed: "boundary-particles, clamp",
            }),
        }
    }
}

/// Physical and numerical parameters of a weakly compressible fluid. SI units; `D` is 2 or 3. A 2D
/// fluid is a slice of unit depth (docs/sph.md, "Units"): its densities are kg/m³ and its
/// pressures Pa as in 3D, and only masses (kg/m), forces (N/m) and energies (J/m) are per metre
/// of depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FluidParams<const D: usize> {
    /// Rest density ρ₀ (kg/m³, in 2D too), > 0. Default 1000 (water).
    pub rest_density: f64,
    /// Numerical speed of sound c₀ (m/s), > 0: about 10× the largest expected flow speed keeps
    /// density variations near 1 %. Default 62.6 = 10·√(2gH) for the 2 m column of
    /// docs/scenes.md §7.
    pub sound_speed: f64,
    /// Exponent γ of the Tait equation p = B((ρ/ρ₀)^γ − 1), B = ρ₀c₀²/γ; ≥ 1. Default 7 (water).
    pub gamma: f64,
    /// Monaghan's artificial viscosity α, ≥ 0 (dimensionless). Default 0.1, as docs/scenes.md §7.
    pub viscosity_alpha: f64,
    /// Gravity (m/s²), finite. Default (0, −9.81) in 2D, (0, −9.81, 0) in 3D (y up).
    pub gravity: SVector<f64, D>,
    /// The smoothing kernel. Default the cubic spline.
    pub kernel: KernelKind,
    /// Smoothing length h (m), > 0; the kernel's support is 2h. Typically 1.3 Δx.
    pub smoothing_length: f64,
    /// CFL number C in Δt ≤ C·h/(c₀ + |v|max), in (0, 1]. Default 0.4.
    pub courant: f64,
    /// Factor of the force condition Δt ≤ f·√(h/|a|max), in (0, 1]. Default 0.25.
    pub force_factor: f64,
    /// The time integrator. Default symplectic Euler.
    pub integrator: Integrator,
    /// How densities are obtained. Default the continuity equation: with summation the free
    /// surface's density deficit leaves hydrostatic-2d's pressures 11–24 % above ρ₀gd and its
    /// surface densities 23 % below ρ₀ after 2 s (measured at Δx = 0.02), against 2 % and 0.6 %
    /// with continuity.
    pub density: DensityMethod,
    /// A fixed step Δt (s) instead of the adaptive one; a step above the stability bound is refused
    /// with the bound in the error. Default `None` (adaptive: Δt = the bound).
    pub fixed_step: Option<f64>,
}

impl<const D: usize> Default for FluidParams<D> {
    fn default() -> Self {
        let mut gravity = SVector::<f64, D>::zeros();
        if D > 1 {
            gravity[1] = -9.81;
        }
        FluidParams {
            rest_density: 1000.0,
            sound_speed: 62.6,
            gamma: 7.0,
            viscosity_alpha: 0.1,
            gravity,
            kernel: KernelKind::CubicSpline,
            smoothing_length: 0.026,
            courant: 0.4,
            force_factor: 0.25,
            integrator: Integrator::SymplecticEuler,
            density: DensityMethod::Continuity,
            fixed_step: None,
        }
    }
}

fn check(name: &'static str, value: f64, ok: bool, allowed: &'static str) -> Result<(), SphError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(SphError::InvalidParameter {
            name,
            value,
            allowed,
        })
    }
}

impl<const D: usize> FluidParams<D> {
    /// Checks every field's range.
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] naming the first field out of range;
    /// [`SphError::UnsupportedDimension`] unless `D` is 2 or 3.
    pub fn validate(&self) -> Result<(), SphError> {
        if D != 2 && D != 3 {
            return Err(SphError::UnsupportedDimension(D));
        }
        let p = self;
        check(
            "rest_density",
            p.rest_density,
            p.rest_density > 0.0,
            "> 0 (kg/m^3)",
        )?;
        check(
            "sound_speed",
            p.sound_speed,
            p.sound_speed > 0.0,
            "> 0 (m/s)",
        )?;
        check("gamma", p.gamma, p.gamma >= 1.0, ">= 1")?;
        check(
            "viscosity_alpha",
            p.viscosity_alpha,
            p.viscosity_alpha >= 0.0,
            ">= 0",
        )?;
        for a in 0..D {
            check("gravity", p.gravity[a], true, "finite (m/s^2)")?;
        }
        check(
            "smoothing_length",
            p.smoothing_length,
            p.smoothing_length > 0.0,
            "> 0 (m)",
        )?;
        check(
            "courant",
            p.courant,
            p.courant > 0.0 && p.courant <= 1.0,
            "in (0, 1]",
        )?;
        check(
            "force_factor",
            p.force_factor,
            p.force_factor > 0.0 && p.force_factor <= 1.0,
            "in (0, 1]",
        )?;
        if let Some(dt) = p.fixed_step {
            check("fixed_step", dt, dt > 0.0, "> 0 (s)")?;
        }
        Ok(())
    }

    /// The Tait stiffness B = ρ₀c₀²/γ (Pa).
    pub fn tait_stiffness(&self) -> f64 {
        self.rest_density * self.sound_speed * self.sound_speed / self.gamma
    }
}

/// Everything a fluid is built from: parameters, the domain, the walls and the particles.
#[derive(Debug, Clone, PartialEq)]
pub struct FluidSetup<const D: usize> {
    /// The parameters.
    pub params: FluidParams<D>,
    /// Lower corner of the domain (m). Every particle stays inside [`domain_min`, `domain_max`].
    pub domain_min: SVector<f64, D>,
    /// Upper corner of the domain (m).
    pub domain_max: SVector<f64, D>,
    /// How the walls act.
    pub walls: Walls,
    /// Mass of every particle, fluid and boundary (kg in 3D, kg per metre of depth in 2D), > 0:
    /// ρ₀Δxᴰ on a lattice of spacing Δx.
    pub particle_mass: f64,
    /// Initial fluid positions (m); at least one.
    pub fluid_positions: Vec<SVector<f64, D>>,
    /// Initial fluid velocities (m/s); empty for rest.
    pub fluid_velocities: Vec<SVector<f64, D>>,
    /// Initial fluid densities (continuity method only); empty for ρ₀.
    pub fluid_densities: Vec<f64>,
    /// Boundary particle positions (m), fixed.
    pub boundary_positions: Vec<SVector<f64, D>>,
    /// Initial boundary densities (continuity method only); empty for ρ₀.
    pub boundary_densities: Vec<f64>,
}
