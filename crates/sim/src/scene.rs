//! A scene: the mesh, what is pinned, which forces, damping and contact act, and the time step.

use hooke_mesh::SpringMesh;
use nalgebra::SVector;

use crate::contact::{obstacles, BarrierSettings, Contact};
use crate::damping::Damping;
use crate::error::{positive, SimError};
use crate::forces::{ExternalForce, ExternalForces};
use hooke_solvers::backward_euler::ContactModel;
use hooke_solvers::PdContactModel;

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

/// A prescribed path for pinned vertices (docs/model.md §5.4: the pinned positions b change, the
/// system matrix does not): the displacement d(t) (m) at simulated time t (s). A vertex on a path
/// is at x(t) = x(t₀) + d(t) − d(t₀), t₀ the time of the state the simulation starts from; its
/// velocity over a step is the path's mean velocity over that step.
#[derive(Clone, Debug, PartialEq)]
pub enum PinPath<const D: usize> {
    /// d(t) = velocity · t, velocity in m/s.
    ConstantVelocity {
        /// m/s.
        velocity: SVector<f64, D>,
    },
    /// d(t) linearly interpolated between keyframes; constant before the first keyframe and after
    /// the last. Times strictly increasing.
    Keyframes(Vec<Keyframe<D>>),
}

/// One keyframe of a [`PinPath::Keyframes`] path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe<const D: usize> {
    /// Time, s.
    pub time: f64,
    /// Displacement at that time, m.
    pub offset: SVector<f64, D>,
}

impl<const D: usize> PinPath<D> {
    /// Check finiteness and, for keyframes, at least one keyframe with strictly increasing times.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the field.
    pub fn validate(&self) -> Result<(), SimError> {
        match self {
            PinPath::ConstantVelocity { velocity } => {
                crate::error::finite_vector("pin path velocity", velocity)
            }
            PinPath::Keyframes(keys) => {
                if keys.is_empty() {
                    return Err(SimError::invalid(
                        "pin path keyframes",
                        "[]",
                        "give at least one keyframe",
                    ));
                }
                for (k, key) in keys.iter().enumerate() {
                    if !key.time.is_finite() {
                        return Err(SimError::invalid(
                            format!("pin path keyframes[{k}].time"),
                            key.time,
                            "must be finite",
                        ));
                    }
                    crate::error::finite_vector(
                        &format!("pin path keyframes[{k}].offset"),
                        &key.offset,
                    )?;
                    if k > 0 && keys[k - 1].time >= key.time {
                        return Err(SimError::invalid(
                            format!("pin path keyframes[{k}].time"),
                            key.time,
                            "keyframe times must be strictly increasing",
                        ));
                    }
                }
                Ok(())
            }
        }
    }

    /// The displacement d(t) (m).
    pub fn offset(&self, t: f64) -> SVector<f64, D> {
        match self {
            PinPath::ConstantVelocity { velocity } => velocity * t,
            PinPath::Keyframes(keys) => {
                let after = keys.partition_point(|k| k.time <= t);
                if after == 0 {
                    return keys[0].offset;
                }
                if after == keys.len() {
                    return keys[after - 1].offset;
                }
                let (a, b) = (&keys[after - 1], &keys[after]);
                let s = (t - a.time) / (b.time - a.time);
                a.offset + (b.offset - a.offset) * s
            }
        }
    }
}

/// Pinned vertices that follow a [`PinPath`].
#[derive(Clone, Debug, PartialEq)]
pub struct MovingPins<const D: usize> {
    /// The vertices, sorted.
    pub vertices: Vec<u32>,
    /// Their common path.
    pub path: PinPath<D>,
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
    /// The contact barrier's energy, J ([`Scene::barrier_energy`]): counted only where the
    /// integrator models contact by barriers (newton, newton-cg, lbfgs), 0 otherwise.
    pub contact: f64,
    /// kinetic + potential + contact, J.
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
    barrier: BarrierSettings,
    time_step: f64,
    moving: Vec<MovingPins<D>>,
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
            barrier: BarrierSettings::default(),
            time_step,
            moving: Vec::new(),
        })
    }

    /// Pin vertices (replacing earlier pins, moving ones included).
    ///
    /// # Errors
    /// [`SimError::PinOutOfRange`], [`SimError::EmptyPinRegion`] or [`SimError::EverythingPinned`].
    pub fn with_pins(mut self, pins: Pins<D>) -> Result<Self, SimError> {
        let list = self.resolve_pins(pins)?;
        self.moving.clear();
        self.set_pinned(list)?;
        Ok(self)
    }

    /// Pin the vertices of `pins` (in addition to those pinned already) and move them along
    /// `path`. The system matrices of the implicit integrators do not change (docs/model.md §5.4):
    /// only the pinned positions do, and factorisations are kept.
    ///
    /// # Errors
    /// As [`Scene::with_pins`]; [`SimError::InvalidParameter`] for an invalid path or a vertex that
    /// is already on another path.
    pub fn with_pin_path(mut self, pins: Pins<D>, path: PinPath<D>) -> Result<Self, SimError> {
        path.validate()?;
        let mut vertices = self.resolve_pins(pins)?;
        vertices.sort_unstable();
        vertices.dedup();
        if let Some(&v) = vertices.iter().find(|&&v| {
            self.moving
                .iter()
                .any(|m| m.vertices.binary_search(&v).is_ok())
        }) {
            return Err(SimError::invalid(
                "pin path",
                v,
                "the vertex is already on another pin path",
            ));
        }
        let mut all = self.pinned.clone();
        all.extend_from_slice(&vertices);
        self.set_pinned(all)?;
        self.moving.push(MovingPins { vertices, path });
        Ok(self)
    }

    fn set_pinned(&mut self, mut list: Vec<u32>) -> Result<(), SimError> {
        let n = self.mesh.vertex_count();
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
        Ok(())
    }

    fn resolve_pins(&self, pins: Pins<D>) -> Result<Vec<u32>, SimError> {
        let n = self.mesh.vertex_count();
        let list: Vec<u32> = match pins {
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
        Ok(list)
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

    /// Set how the minimising implicit integrators model contact ([`BarrierSettings`]).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a value that is not finite and positive.
    pub fn with_barrier(mut self, barrier: BarrierSettings) -> Result<Self, SimError> {
        barrier.validate()?;
        self.barrier = barrier;
        Ok(self)
    }

    /// The contact barrier's settings as given ([`Scene::with_barrier`]; defaults unresolved).
    pub fn barrier(&self) -> BarrierSettings {
        self.barrier
    }

    /// The contact model of the minimising implicit integrators: the obstacles (a box as its
    /// walls) with their friction, d̂ and κ̂ resolved against the mesh's initial positions
    /// ([`BarrierSettings::resolve`]); `None` for a scene without contact, which then costs
    /// nothing.
    pub fn contact_model(&self) -> Option<ContactModel<D>> {
        if self.contacts.is_empty() {
            return None;
        }
        let (distance, stiffness) = self.barrier.resolve(self.mesh.positions());
        Some(ContactModel {
            obstacles: obstacles(&self.contacts),
            distance,
            stiffness,
            friction_velocity: self.barrier.friction_velocity,
        })
    }

    /// The contact model of projective dynamics (with or without Chebyshev's acceleration): the
    /// obstacles (a box as its walls) with their friction, and d̂ ([`BarrierSettings::resolve`])
    /// as the reach within which a vertex's way makes it take part in a step's contact solve;
    /// `None` for a scene without contact.
    pub fn pd_contact_model(&self) -> Option<PdContactModel<D>> {
        if self.contacts.is_empty() {
            return None;
        }
        let (distance, _) = self.barrier.resolve(self.mesh.positions());
        Some(PdContactModel::new(obstacles(&self.contacts), distance))
    }

    /// The barrier energy Σ κ̂ m_v b(d) (J) of the free vertices at `positions` under
    /// [`Scene::contact_model`] (0 without contact; +∞ if a free vertex is on or inside an
    /// obstacle).
    pub fn barrier_energy(&self, positions: &[SVector<f64, D>]) -> f64 {
        let Some(model) = self.contact_model() else {
            return 0.0;
        };
        let masses = self.mesh.masses();
        let mut sum = 0.0;
        for (v, x) in positions.iter().enumerate() {
            if self.is_pinned[v] {
                continue;
            }
            for (obstacle, _) in &model.obstacles {
                let d = obstacle.distance(x);
                if d < model.distance {
                    sum += model.stiffness
                        * masses[v]
                        * hooke_assembly::contact::barrier(d, model.distance);
                }
            }
        }
        sum
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

    /// Pinned vertices that follow a prescribed path (a subset of [`Scene::pinned`]).
    pub fn pin_paths(&self) -> &[MovingPins<D>] {
        &self.moving
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

    /// Take the contacts out (no allocation), so that an implicit solver given this scene does not
    /// project: [`crate::Simulation`] projects the whole mesh after the step instead (see
    /// [`crate::contact`]). Put them back with [`Scene::restore_contacts`].
    pub(crate) fn take_contacts(&mut self) -> Vec<Contact<D>> {
        std::mem::take(&mut self.contacts)
    }

    /// Put back the contacts taken by [`Scene::take_contacts`].
    pub(crate) fn restore_contacts(&mut self, contacts: Vec<Contact<D>>) {
        self.contacts = contacts;
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
            contact: 0.0,
            total: kinetic + potential,
        }
    }

    /// The tetrahedra of the mesh (solids; none for cloth and graphs) that are inverted at
    /// `positions`: whose signed volume has lost the sign it has at the mesh's rest positions (or
    /// become zero). A mass-spring solid has no volume term, so a hard impact solved inexactly can
    /// turn elements inside out; 0 in dimensions other than 3.
    pub fn inverted_tetrahedra(&self, positions: &[SVector<f64, D>]) -> usize {
        if D != 3 {
            return 0;
        }
        let rest = self.mesh.positions();
        let volume = |p: &[SVector<f64, D>], t: &[u32; 4]| {
            let [a, b, c, d] = t.map(|i| p[i as usize]);
            let (u, v, w) = (b - a, c - a, d - a);
            u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0])
        };
        self.mesh
            .tetrahedra()
            .iter()
            .filter(|t| {
                let now = volume(positions, t);
                now == 0.0 || now.signum() != volume(rest, t).signum()
            })
            .count()
    }

    /// Largest stretch ratio |r|/l over the springs in `state` (1 at rest).
    pub fn max_stretch(&self, state: &State<D>) -> f64 {
        hooke_assembly::max_stretch(self.mesh.springs(), &state.positions)
    }
}
