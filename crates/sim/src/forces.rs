//! External forces (docs/model.md §3): gravity, wind, buoyancy and a point attractor, with their
//! potentials.

use nalgebra::SVector;

use crate::error::{finite_vector, non_negative, positive, SimError};

/// A force field acting on every free vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ExternalForce<const D: usize> {
    /// Uniform gravity: f_i = m_i g, with `acceleration` g in m/s² (the 3D scenes of docs/scenes.md
    /// use (0, −9.81, 0)). Potential −Σ m_i g·x_i.
    Gravity {
        /// g, m/s².
        acceleration: SVector<f64, D>,
    },
    /// Air drag toward a uniform wind: f_i = c (w − v_i), with `velocity` w in m/s and `coefficient`
    /// c in N·s/m per vertex. Depends on velocity, not position: no potential; it is damping toward
    /// the moving air, and a still body in wind feels the force c w.
    Wind {
        /// w, m/s.
        velocity: SVector<f64, D>,
        /// c, N·s/m, ≥ 0.
        coefficient: f64,
    },
    /// Archimedes' force of a fluid below the level `surface` (m, measured along "up" = −g/|g|):
    /// f_i = −(ρ_fluid / ρ_body) m_i g on submerged vertices, zero above. Needs gravity in the scene.
    /// Potential (ρ_f/ρ_b) m_i |g| (surface − min(height_i, surface)).
    Buoyancy {
        /// ρ_fluid, kg/m³, ≥ 0.
        fluid_density: f64,
        /// ρ_body, kg/m³, > 0: the body's density, which turns vertex mass into displaced volume.
        body_density: f64,
        /// Height of the fluid surface along "up", m.
        surface: f64,
    },
    /// The 2D editor's right-button pull (docs/editor.md), as a zero-length spring to a point per
    /// unit mass: f_i = −s m_i (x_i − p), with `strength` s in 1/s² (the editor uses 100).
    /// Potential ½ s m_i |x_i − p|².
    Attractor {
        /// p, m.
        point: SVector<f64, D>,
        /// s, 1/s², ≥ 0.
        strength: f64,
    },
}

impl<const D: usize> ExternalForce<D> {
    /// Check the parameters (finite, signs as documented).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), SimError> {
        match self {
            ExternalForce::Gravity { acceleration } => finite_vector("gravity", acceleration),
            ExternalForce::Wind {
                velocity,
                coefficient,
            } => {
                finite_vector("wind.velocity", velocity)?;
                non_negative("wind.coefficient", *coefficient).map(drop)
            }
            ExternalForce::Buoyancy {
                fluid_density,
                body_density,
                surface,
            } => {
                non_negative("buoyancy.fluid_density", *fluid_density)?;
                positive("buoyancy.body_density", *body_density)?;
                if surface.is_finite() {
                    Ok(())
                } else {
                    Err(SimError::invalid(
                        "buoyancy.surface",
                        surface,
                        "must be finite",
                    ))
                }
            }
            ExternalForce::Attractor { point, strength } => {
                finite_vector("attractor.point", point)?;
                non_negative("attractor.strength", *strength).map(drop)
            }
        }
    }
}

/// The external forces of a scene, resolved for fast evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalForces<const D: usize> {
    forces: Vec<ExternalForce<D>>,
    gravity: Option<SVector<f64, D>>,
    /// "Up" (−g/|g|) and |g| (m/s²), resolved once for buoyancy; zero without gravity.
    up: SVector<f64, D>,
    g_norm: f64,
}

impl<const D: usize> Default for ExternalForces<D> {
    /// No external force.
    fn default() -> Self {
        ExternalForces {
            forces: Vec::new(),
            gravity: None,
            up: SVector::zeros(),
            g_norm: 0.0,
        }
    }
}

impl<const D: usize> ExternalForces<D> {
    /// Validate and collect. Gravity terms add up; buoyancy needs non-zero total gravity.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`].
    pub fn new(forces: Vec<ExternalForce<D>>) -> Result<Self, SimError> {
        let mut gravity: Option<SVector<f64, D>> = None;
        for f in &forces {
            f.validate()?;
            if let ExternalForce::Gravity { acceleration } = f {
                *gravity.get_or_insert_with(SVector::zeros) += acceleration;
            }
        }
        let has_buoyancy = forces
            .iter()
            .any(|f| matches!(f, ExternalForce::Buoyancy { .. }));
        if has_buoyancy && gravity.is_none_or(|g| g.norm() == 0.0) {
            return Err(SimError::invalid(
                "buoyancy",
                "set",
                "buoyancy needs gravity in the scene",
            ));
        }
        let g = gravity.unwrap_or_else(SVector::zeros);
        let g_norm = g.norm();
        let up = if g_norm > 0.0 {
            -g / g_norm
        } else {
            SVector::zeros()
        };
        Ok(ExternalForces {
            forces,
            gravity,
            up,
            g_norm,
        })
    }

    /// The forces, as given.
    pub fn as_slice(&self) -> &[ExternalForce<D>] {
        &self.forces
    }

    /// True when there is no external force at all.
    pub fn is_empty(&self) -> bool {
        self.forces.is_empty()
    }

    /// Total gravitational acceleration (m/s²), if the scene has gravity.
    pub fn gravity(&self) -> Option<SVector<f64, D>> {
        self.gravity
    }

    /// The external force (N) on a vertex of mass `mass` at `x` moving at `v`.
    #[inline]
    pub fn force(&self, mass: f64, x: &SVector<f64, D>, v: &SVector<f64, D>) -> SVector<f64, D> {
        let mut f = SVector::zeros();
        for force in &self.forces {
            match force {
                ExternalForce::Gravity { acceleration } => f += acceleration * mass,
                ExternalForce::Wind {
                    velocity,
                    coefficient,
                } => f += (velocity - v) * *coefficient,
                ExternalForce::Buoyancy {
                    fluid_density,
                    body_density,
                    surface,
                } => {
                    if x.dot(&self.up) < *surface {
                        f += self.up * (self.g_norm * fluid_density / body_density * mass);
                    }
                }
                ExternalForce::Attractor { point, strength } => {
                    f -= (x - point) * (strength * mass)
                }
            }
        }
        f
    }

    /// The buoyancy part of [`ExternalForces::force`] alone (N): the implicit integrators evaluate it
    /// at the start of the step, where the others enter their objective exactly.
    pub(crate) fn buoyancy_force(&self, mass: f64, x: &SVector<f64, D>) -> SVector<f64, D> {
        let mut f = SVector::zeros();
        for force in &self.forces {
            if let ExternalForce::Buoyancy {
                fluid_density,
                body_density,
                surface,
            } = force
            {
                if x.dot(&self.up) < *surface {
                    f += self.up * (self.g_norm * fluid_density / body_density * mass);
                }
            }
        }
        f
    }

    /// The potential energy (J) of the conservative external forces for one vertex (wind has none).
    #[inline]
    pub fn potential(&self, mass: f64, x: &SVector<f64, D>) -> f64 {
        let mut e = 0.0;
        for force in &self.forces {
            match force {
                ExternalForce::Gravity { acceleration } => e -= mass * acceleration.dot(x),
                ExternalForce::Wind { .. } => {}
                ExternalForce::Buoyancy {
                    fluid_density,
                    body_density,
                    surface,
                } => {
                    let height = x.dot(&self.up);
                    e += fluid_density / body_density
                        * mass
                        * self.g_norm
                        * (surface - height.min(*surface));
                }
                ExternalForce::Attractor { point, strength } => {
                    e += 0.5 * strength * mass * (x - point).norm_squared()
                }
            }
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn position_forces_are_minus_potential_gradients() {
        let forces = ExternalForces::new(vec![
            ExternalForce::Gravity {
                acceleration: Vector3::new(0.0, -9.81, 0.0),
            },
            ExternalForce::Attractor {
                point: Vector3::new(0.2, 0.3, -0.1),
                strength: 100.0,
            },
            ExternalForce::Buoyancy {
                fluid_density: 1000.0,
                body_density: 500.0,
                surface: 0.5,
            },
        ])
        .unwrap();
        let (m, v) = (0.3, Vector3::zeros());
        // Below and above the surface, away from the kink at height 0.5.
        for x in [Vector3::new(0.1, 0.2, 0.3), Vector3::new(-0.4, 0.9, 0.2)] {
            let f = forces.force(m, &x, &v);
            for a in 0..3 {
                let mut e = Vector3::zeros();
                e[a] = 1e-6;
                let numeric =
                    -(forces.potential(m, &(x + e)) - forces.potential(m, &(x - e))) / 2e-6;
                // The potentials are at most quadratic: central differences are exact up to round-off
                // ≈ ε·|U|/h ≈ 1e-16 · 10 / 1e-6 = 1e-9.
                assert!(
                    (numeric - f[a]).abs() < 1e-7,
                    "axis {a}: {numeric} vs {}",
                    f[a]
                );
            }
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let err = ExternalForces::new(vec![ExternalForce::Wind {
            velocity: Vector3::new(1.0, 0.0, 0.0),
            coefficient: -1.0,
        }])
        .unwrap_err();
        assert!(err.to_string().contains("wind.coefficient"), "{err}");
        assert!(ExternalForces::<3>::new(vec![ExternalForce::Buoyancy {
            fluid_density: 1.0,
            body_density: 1.0,
            surface: 0.0
        }])
        .is_err());
    }
}
