//! A scene: the mesh, what is pinned, which forces, damping and contact act, and the time step.

use hooke_mesh::SpringMesh;
use nalgebra::SVector;

use crate::contact::Contact;
use crate::damping::Damping;
use crate::error::{positive, SimError};
use crate::forces::{ExternalForce, ExternalForces};

/// Which vertices are pinned (held at their initial positions).
#[derive(Clone, Debug, PartialEq)]
pub enum Pins<const D: usize> {
    /// These vertex indices.
    Vertices(Vec<u32>),
    /// Every vertex whose initial position lies in the closed box [min, max] (m).
    Region {
        /// Lower corner, m.
        min: SVector<f64, D>,
        /// Upper corner, m.
        max: SVector<f64, D>,
    },
}

/// Positions (m), velocities (m/s) and time (s) of a simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct State<const D: usize> {
    /// One position per vertex, m.
    pub positions: Vec<SVector<f64, D>>,
    /// One velocity per vertex, m/s.
    pub velocities: Vec<SVector<f64, D>>,
    /// Simulated time, s.
    pub time: f64,
}

/// Kinetic, potential and total energy of a state (J).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energy {
    /// ½ Σ m_i |v_i|², J.
    pub kinetic: f64,
    /// Elastic energy of the springs plus the potentials of gravity, buoyancy and attractor, J.
    pub potential: f64,
    /// kinetic + potential, J.
    pub total: f64,
}

/// A validated scene in dimension `D`.
///
/// Invariants: the mesh is valid; pinned indices exist, are sorted and unique, and leave at least
/// one vertex free; forces, damping and contacts are validated; the time step is positive and finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene<const D: usize> {
    mesh: SpringMesh<D>,
    pinned: Vec<u32>,
    is_pinned: Vec<bool>,
    forces: ExternalForces<D>,
    damping: Damping,
    contacts: Vec<Contact<D>>,
    time_step: f64,
}

impl<const D: usize> Scene<D> {
    /// A scene with nothing pinned, no forces, no damping, no contact and time step `time_step` (s).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a time step that is not positive and finite.
    pub fn new(mesh: SpringMesh<D>, time_step: f64) -> Result<Self, SimError> {
        positive("time step", time_step)?;
        let n = mesh.vertex_count();
        Ok(Scene {
            mesh,
            pinned: Vec::new(),
            is_pinned: vec![false; n],
            forces: ExternalForces::default(),
            damping: Damping::default(),
            contacts: Vec::new(),
            time_step,
        })
    }

    /// Pin vertices (replacing earlier pins).
    ///
    /// # Errors
    /// [`SimError::PinOutOfRange`], [`SimError::EmptyPinRegion`] or [`SimError::EverythingPinned`].
    pub fn with_pins(mut self, pins: Pins<D>) -> Result<Self, SimError> {
        let n = self.mesh.vertex_count();
        let mut list: Vec<u32> = match pins {
            Pins::Vertices(list) => {
                if let Some(&bad) = list.iter().find(|&&v| v as usize >= n) {
                    return Err(SimError::PinOutOfRange {
                        vertex: bad as usize,
                        vertex_count: n,
                    });
                }
                list
            }
            Pins::Region { min, max } => {
                let inside: Vec<u32> = self
                    .mesh
                    .positions()
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| (0..D).all(|a| p[a] >= min[a] && p[a] <= max[a]))
                    .map(|(v, _)| v as u32)
                    .collect();
                if inside.is_empty() {
                    return Err(SimError::EmptyPinRegion {
                        min: min.as_slice().to_vec(),
                        max: max.as_slice().to_vec(),
                    });
                }
                inside
            }
        };
        list.sort_unstable();
        list.dedup();
        if list.len() == n {
            return Err(SimError::EverythingPinned { vertex_count: n });
        }
        self.is_pinned = vec![false; n];
        for &v in &list {
            self.is_pinned[v as usize] = true;
        }
        self.pinned = list;
        Ok(self)
    }

    /// Set the external forces (replacing earlier ones).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the bad field.
    pub fn with_forces(mut self, forces: Vec<ExternalForce<D>>) -> Result<Self, SimError> {
        self.forces = ExternalForces::new(forces)?;
        Ok(self)
    }

    /// Set the damping.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a negative or non-finite coefficient.
    pub fn with_damping(mut self, damping: Damping) -> Result<Self, SimError> {
        damping.validate()?;
        self.damping = damping;
        Ok(self)
    }

    /// Set the contact constraints (replacing earlier ones).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for an invalid shape.
    pub fn with_contacts(mut self, contacts: Vec<Contact<D>>) -> Result<Self, SimError> {
        self.contacts = contacts
            .into_iter()
            .map(Contact::validated)
            .collect::<Result<_, _>>()?;
        Ok(self)
    }

    /// Change the time step h (s).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] unless positive and finite.
    pub fn with_time_step(mut self, time_step: f64) -> Result<Self, SimError> {
        self.time_step = positive("time step", time_step)?;
        Ok(self)
    }

    /// The mesh.
    pub fn mesh(&self) -> &SpringMesh<D> {
        &self.mesh
    }

    /// Pinned vertices, sorted.
    pub fn pinned(&self) -> &[u32] {
        &self.pinned
    }

    /// One flag per vertex: pinned or not.
    pub fn is_pinned(&self) -> &[bool] {
        &self.is_pinned
    }

    /// The external forces.
    pub fn forces(&self) -> &ExternalForces<D> {
        &self.forces
    }

    /// The damping.
    pub fn damping(&self) -> Damping {
        self.damping
    }

    /// The contact constraints.
    pub fn contacts(&self) -> &[Contact<D>] {
        &self.contacts
    }

    /// The time step h (s) of one frame.
    pub fn time_step(&self) -> f64 {
        self.time_step
    }

    /// The initial state: mesh positions, at rest, time 0.
    pub fn initial_state(&self) -> State<D> {
        State {
            positions: self.mesh.positions().to_vec(),
            velocities: vec![SVector::zeros(); self.mesh.vertex_count()],
            time: 0.0,
        }
    }

    /// Kinetic, potential and total energy of `state` (J). Spring energy is summed in a fixed order,
    /// so the value does not depend on the number of threads.
    pub fn energy(&self, state: &State<D>) -> Energy {
        let masses = self.mesh.masses();
        let kinetic = 0.5
            * masses
                .iter()
                .zip(&state.velocities)
                .map(|(m, v)| m * v.norm_squared())
                .sum::<f64>();
        let elastic = hooke_assembly::spring_energy(self.mesh.springs(), &state.positions, true);
        let external: f64 = if self.forces.is_empty() {
            0.0
        } else {
            masses
                .iter()
                .zip(&state.positions)
                .map(|(&m, x)| self.forces.potential(m, x))
                .sum()
        };
        let potential = elastic + external;
        Energy {
            kinetic,
            potential,
            total: kinetic + potential,
        }
    }

    /// Largest stretch ratio |r|/l over the springs in `state` (1 at rest).
    pub fn max_stretch(&self, state: &State<D>) -> f64 {
        hooke_assembly::max_stretch(self.mesh.springs(), &state.positions)
    }
}
