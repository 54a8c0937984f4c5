//! A scene: the mesh, what is pinned, which forces, damping and contact act, and the time step.

use hooke_mesh::SpringMesh;
use nalgebra::SVector;

use crate::contact_model::{obstacles, BarrierSettings, Contact, SelfContact};
use crate::damping::Damping;
use crate::error::{positive, SimError};
use crate::forces::{ExternalForce, ExternalForces};
use hooke_solvers::backward_euler::{ContactModel, SelfContactModel};
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
/// system matrix does not): a displacement d(t) (m) and, for keyframes, a rotation R(t) about an
/// axis through a point c (m), at simulated time t (s). A vertex on a path is at
/// x(t) = c + R(t)(x₀ − c) + d(t), its reference position x₀ being the one that puts it at
/// x(t₀) at t₀, the time of the state the simulation starts from (x₀ = x(t₀) − d(t₀) without
/// rotation; at t₀ = 0 with no displacement or turn at 0, x₀ is the initial position). Its
/// velocity over a step is the path's mean velocity over that step.
#[derive(Clone, Debug, PartialEq)]
pub enum PinPath<const D: usize> {
    /// d(t) = velocity · t, velocity in m/s; no rotation.
    ConstantVelocity {
        /// m/s.
        velocity: SVector<f64, D>,
    },
    /// d(t) and the angle of R(t) linearly interpolated between keyframes (the angle in degrees,
    /// unwrapped: keyframes at 0° and 720° make two full turns, passing 360° halfway); constant
    /// before the first keyframe and after the last. Times strictly increasing. Every keyframe
    /// that rotates names the same axis and point (one path turns about one axis); a keyframe
    /// without a rotation is at 0° about it.
    Keyframes(Vec<Keyframe<D>>),
}

/// One keyframe of a [`PinPath::Keyframes`] path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe<const D: usize> {
    /// Time, s.
    pub time: f64,
    /// Displacement at that time, m.
    pub offset: SVector<f64, D>,
    /// The turn at that time about the path's axis (`None`: 0°).
    pub rotation: Option<Rotation<D>>,
}

/// A right-handed rotation by `degrees` about the axis of direction `axis` through `point`.
///
/// In 3D `axis` is any finite non-zero vector (normalised on use). In 2D the rotation is in the
/// plane, about the out-of-plane axis: `axis` must be (0, 0, ±a), a > 0; +z turns
/// counter-clockwise (from x toward y). Other dimensions have no rotations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rotation<const D: usize> {
    /// Direction of the axis (any length > 0; 3 components in 2D too), right-handed.
    pub axis: nalgebra::Vector3<f64>,
    /// A point of the axis, m.
    pub point: SVector<f64, D>,
    /// The angle, degrees; any finite value (720 is two turns).
    pub degrees: f64,
}

impl<const D: usize> Rotation<D> {
    /// The unit axis.
    fn unit_axis(&self) -> nalgebra::Vector3<f64> {
        self.axis / self.axis.norm()
    }

    /// Check the rotation; `name` is the field's name in errors.
    fn validate(&self, name: &str) -> Result<(), SimError> {
        if D != 2 && D != 3 {
            return Err(SimError::invalid(
                name,
                format!("{D}D"),
                "rotations exist in 2D and 3D only",
            ));
        }
        let length = self.axis.norm();
        if !length.is_finite() || length == 0.0 {
            return Err(SimError::invalid(
                format!("{name}.axis"),
                format!("{:?}", self.axis.as_slice()),
                "must be finite and non-zero",
            ));
        }
        if D == 2 && (self.axis.x != 0.0 || self.axis.y != 0.0) {
            return Err(SimError::invalid(
                format!("{name}.axis"),
                format!("{:?}", self.axis.as_slice()),
                "a 2D rotation is about the out-of-plane axis: give (0, 0, ±1)",
            ));
        }
        crate::error::finite_vector(&format!("{name}.point"), &self.point)?;
        if !self.degrees.is_finite() {
            return Err(SimError::invalid(
                format!("{name}.degrees"),
                self.degrees,
                "must be finite",
            ));
        }
        Ok(())
    }
}

/// `v` turned by `radians` about the unit axis `k` through the origin (Rodrigues' formula). A 2D
/// vector is turned as (x, y, 0), which `k` = (0, 0, ±1) keeps in the plane.
fn rotate<const D: usize>(
    v: &SVector<f64, D>,
    k: &nalgebra::Vector3<f64>,
    radians: f64,
) -> SVector<f64, D> {
    let mut w = nalgebra::Vector3::zeros();
    for (a, c) in v.iter().enumerate().take(3) {
        w[a] = *c;
    }
    let (sin, cos) = radians.sin_cos();
    let turned = w * cos + k.cross(&w) * sin + k * (k.dot(&w) * (1.0 - cos));
    let mut out = *v;
    for (a, c) in out.iter_mut().enumerate().take(3) {
        *c = turned[a];
    }
    out
}

impl<const D: usize> PinPath<D> {
    /// Check finiteness and, for keyframes, at least one keyframe with strictly increasing times
    /// and valid rotations about one common axis and point.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the field (e.g. `pin path keyframes[1].rotation.axis`
    /// for a zero or non-finite axis, or one out of the plane's normal in 2D).
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
                let mut first_turn: Option<(usize, Rotation<D>)> = None;
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
                    if let Some(rotation) = &key.rotation {
                        let name = format!("pin path keyframes[{k}].rotation");
                        rotation.validate(&name)?;
                        match &first_turn {
                            None => first_turn = Some((k, *rotation)),
                            Some((j, first)) => {
                                // The same axis up to length (compared as unit vectors), and
                                // the same point.
                                if rotation.unit_axis() != first.unit_axis() {
                                    return Err(SimError::invalid(
                                        format!("{name}.axis"),
                                        format!("{:?}", rotation.axis.as_slice()),
                                        format!(
                                            "a path turns about one axis: keyframes[{j}] has {:?}",
                                            first.axis.as_slice()
                                        ),
                                    ));
                                }
                                if rotation.point != first.point {
                                    return Err(SimError::invalid(
                                        format!("{name}.point"),
                                        format!("{:?}", rotation.point.as_slice()),
                                        format!(
                                            "a path turns about one axis: keyframes[{j}] has {:?}",
                                            first.point.as_slice()
                                        ),
                                    ));
                                }
                            }
                        }
                    }
                }
                Ok(())
            }
        }
    }

    /// The keyframes around `t` and the fraction of the way from the first to the second; the
    /// same keyframe twice (fraction 0) before the first keyframe and after the last.
    fn bracket(keys: &[Keyframe<D>], t: f64) -> (&Keyframe<D>, &Keyframe<D>, f64) {
        let after = keys.partition_point(|k| k.time <= t);
        if after == 0 {
            return (&keys[0], &keys[0], 0.0);
        }
        if after == keys.len() {
            return (&keys[after - 1], &keys[after - 1], 0.0);
        }
        let (a, b) = (&keys[after - 1], &keys[after]);
        (a, b, (t - a.time) / (b.time - a.time))
    }

    /// The displacement d(t) (m).
    pub fn offset(&self, t: f64) -> SVector<f64, D> {
        match self {
            PinPath::ConstantVelocity { velocity } => velocity * t,
            PinPath::Keyframes(keys) => {
                let (a, b, s) = Self::bracket(keys, t);
                if s == 0.0 {
                    return a.offset;
                }
                a.offset + (b.offset - a.offset) * s
            }
        }
    }

    /// The first rotating keyframe's rotation (its axis and point are the path's), if any.
    fn turn(&self) -> Option<&Rotation<D>> {
        match self {
            PinPath::ConstantVelocity { .. } => None,
            PinPath::Keyframes(keys) => keys.iter().find_map(|k| k.rotation.as_ref()),
        }
    }

    /// The angle of R(t) (degrees), linearly interpolated between keyframes (0 for a keyframe
    /// without a rotation and for a path without any).
    pub fn angle_degrees(&self, t: f64) -> f64 {
        match self {
            PinPath::ConstantVelocity { .. } => 0.0,
            PinPath::Keyframes(keys) => {
                let angle = |k: &Keyframe<D>| k.rotation.map_or(0.0, |r| r.degrees);
                let (a, b, s) = Self::bracket(keys, t);
                if s == 0.0 {
                    return angle(a);
                }
                angle(a) + (angle(b) - angle(a)) * s
            }
        }
    }

    /// Where a vertex of reference position `reference` (m) is at time `t`:
    /// c + R(t)(x₀ − c) + d(t). Without rotation, or at 0°, exactly x₀ + d(t).
    pub fn position(&self, reference: &SVector<f64, D>, t: f64) -> SVector<f64, D> {
        let radians = self.angle_degrees(t).to_radians();
        let Some(turn) = self.turn().filter(|_| radians != 0.0) else {
            return reference + self.offset(t);
        };
        turn.point + rotate(&(reference - turn.point), &turn.unit_axis(), radians) + self.offset(t)
    }

    /// The reference position x₀ (m) of a vertex that is at `position` at time `t`: the inverse
    /// of [`PinPath::position`], x₀ = c + R(t)ᵀ(x − d(t) − c). Without rotation, or at 0°,
    /// exactly x − d(t): a run that starts unturned takes its start positions as references, bit
    /// for bit.
    pub fn reference(&self, position: &SVector<f64, D>, t: f64) -> SVector<f64, D> {
        let radians = self.angle_degrees(t).to_radians();
        let Some(turn) = self.turn().filter(|_| radians != 0.0) else {
            return position - self.offset(t);
        };
        turn.point
            + rotate(
                &(position - self.offset(t) - turn.point),
                &turn.unit_axis(),
                -radians,
            )
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
    self_contact: Option<SelfContact>,
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
            self_contact: None,
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

    /// Turn on self-contact of the mesh's surface (`None` turns it off): its triangles, or a
    /// solid's boundary faces, never pass through each other (docs/contact.md).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a reach that is not finite and positive, a scene that is
    /// not 3D, or a mesh without triangles or tetrahedra.
    pub fn with_self_contact(
        mut self,
        self_contact: Option<SelfContact>,
    ) -> Result<Self, SimError> {
        if let Some(settings) = &self_contact {
            settings.validate()?;
            if D != 3 {
                return Err(SimError::invalid(
                    "self_contact",
                    format!("{D}D"),
                    "self-contact is for triangle surfaces in 3D",
                ));
            }
            if self.mesh.triangles().is_empty() && self.mesh.tetrahedra().is_empty() {
                return Err(SimError::invalid(
                    "self_contact",
                    "a mesh of springs only",
                    "self-contact needs a surface: a mesh with triangles or tetrahedra",
                ));
            }
        }
        self.self_contact = self_contact;
        Ok(self)
    }

    /// The self-contact settings, if self-contact is on ([`Scene::with_self_contact`]).
    pub fn self_contact(&self) -> Option<SelfContact> {
        self.self_contact
    }

    /// The surface self-contact acts on: the mesh's triangles, or the boundary faces of its
    /// tetrahedra (empty for a mesh of springs only).
    pub fn surface_triangles(&self) -> Vec<[u32; 3]> {
        if !self.mesh.triangles().is_empty() {
            return self.mesh.triangles().to_vec();
        }
        boundary_faces(self.mesh.tetrahedra())
    }

    /// The self-contact model of the minimising implicit integrators: the surface
    /// ([`Scene::surface_triangles`]), the mesh's initial positions as the rest positions, d̂ and
    /// κ resolved ([`SelfContact::resolve`]), the friction coefficient μ ([`SelfContact::friction`])
    /// with the barrier's smoothing velocity ε_v ([`BarrierSettings::friction_velocity`]); `None`
    /// without self-contact (or in 2D).
    pub fn self_contact_model(&self) -> Option<SelfContactModel> {
        let settings = self.self_contact?;
        if D != 3 {
            return None;
        }
        let positions = self.mesh.positions();
        let (distance, stiffness) = settings.resolve(&self.barrier, positions, self.mesh.masses());
        Some(SelfContactModel {
            triangles: self.surface_triangles(),
            rest_positions: positions
                .iter()
                .map(|p| nalgebra::Vector3::new(p[0], p[1], p[2]))
                .collect(),
            distance,
            stiffness,
            friction: settings.friction,
            friction_velocity: self.barrier.friction_velocity,
        })
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
    /// [`Scene::contact_model`], and in 3D of the surface's triangles against the spheres (0
    /// without contact; +∞ if a free vertex or a triangle is on or inside an obstacle).
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
                        * hooke_assembly::barrier::barrier(d, model.distance);
                }
            }
        }
        if D == 3 {
            // The surface's triangles against the spheres, κ_t = κ̂ × the mean mass of the
            // triangle's vertices (as the solvers' obstacle terms).
            let v3 = |p: &SVector<f64, D>| nalgebra::Vector3::new(p[0], p[1], p[2]);
            let triangles = self.surface_triangles();
            for (obstacle, _) in &model.obstacles {
                let hooke_assembly::barrier::Obstacle::SphereOutside { center, radius } = obstacle
                else {
                    continue;
                };
                for t in &triangles {
                    if t.iter().all(|&v| self.is_pinned[v as usize]) {
                        continue;
                    }
                    let mass = t.iter().map(|&v| masses[v as usize]).sum::<f64>() / 3.0;
                    sum += hooke_assembly::surface_barrier::triangle_sphere_energy(
                        &t.map(|v| v3(&positions[v as usize])),
                        &v3(center),
                        *radius,
                        model.distance,
                        model.stiffness * mass,
                    );
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
    /// [`crate::barrier`]). Put them back with [`Scene::restore_contacts`].
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

/// The faces of `tetrahedra` that belong to one tetrahedron only (the boundary), each oriented as
/// in its tetrahedron, in the order of first appearance.
fn boundary_faces(tetrahedra: &[[u32; 4]]) -> Vec<[u32; 3]> {
    let mut faces: Vec<([u32; 3], [u32; 3])> = Vec::with_capacity(4 * tetrahedra.len());
    for t in tetrahedra {
        for face in [
            [t[1], t[2], t[3]],
            [t[0], t[3], t[2]],
            [t[0], t[1], t[3]],
            [t[0], t[2], t[1]],
        ] {
            let mut key = face;
            key.sort_unstable();
            faces.push((key, face));
        }
    }
    let mut order: Vec<usize> = (0..faces.len()).collect();
    order.sort_by_key(|&k| faces[k].0);
    let mut keep = vec![false; faces.len()];
    let mut k = 0;
    while k < order.len() {
        let mut end = k + 1;
        while end < order.len() && faces[order[end]].0 == faces[order[k]].0 {
            end += 1;
        }
        if end - k == 1 {
            keep[order[k]] = true;
        }
        k = end;
    }
    faces
        .iter()
        .zip(keep)
        .filter(|(_, keep)| *keep)
        .map(|(f, _)| f.1)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    fn turning(keys: &[(f64, f64)], axis: Vector3<f64>, point: Vector3<f64>) -> PinPath<3> {
        PinPath::Keyframes(
            keys.iter()
                .map(|&(time, degrees)| Keyframe {
                    time,
                    offset: Vector3::zeros(),
                    rotation: Some(Rotation {
                        axis,
                        point,
                        degrees,
                    }),
                })
                .collect(),
        )
    }

    /// 90° about z through (1, 1, 0): (2, 1, 0.5), one metre along x from the axis, goes one metre
    /// along y, to (1, 2, 0.5); halfway (45°) it is on the diagonal. With a displacement on top,
    /// the turn is about the point and the displacement added after.
    #[test]
    fn a_pin_turning_90_degrees_about_z_through_a_point_lands_where_it_should() {
        let point = Vector3::new(1.0, 1.0, 0.0);
        // Any length of axis: it is normalised.
        let path = turning(
            &[(0.0, 0.0), (2.0, 90.0)],
            Vector3::new(0.0, 0.0, 3.0),
            point,
        );
        path.validate().unwrap();
        let x0 = Vector3::new(2.0, 1.0, 0.5);
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() < 1e-15 * 4.0;
        assert_eq!(path.position(&x0, 0.0), x0);
        assert!(close(path.position(&x0, 2.0), Vector3::new(1.0, 2.0, 0.5)));
        let half = std::f64::consts::FRAC_1_SQRT_2;
        assert!(close(
            path.position(&x0, 1.0),
            Vector3::new(1.0 + half, 1.0 + half, 0.5)
        ));
        // A point on the axis does not move.
        assert!(close(
            path.position(&Vector3::new(1.0, 1.0, 7.0), 2.0),
            Vector3::new(1.0, 1.0, 7.0)
        ));
        // Turn and displacement: x(t) = c + R(t)(x₀ − c) + d(t).
        let PinPath::Keyframes(mut keys) = path.clone() else {
            unreachable!()
        };
        keys[1].offset = Vector3::new(0.0, 0.0, -0.25);
        let moved = PinPath::Keyframes(keys);
        assert!(close(
            moved.position(&x0, 2.0),
            Vector3::new(1.0, 2.0, 0.25)
        ));
        // The reference position of a vertex seen mid-path is where it started.
        let seen = moved.position(&x0, 1.3);
        assert!(close(moved.reference(&seen, 1.3), x0));
        // Without a rotation, position and reference are the plain displacement, bit for bit.
        let slide = PinPath::Keyframes(vec![Keyframe {
            time: 0.0,
            offset: Vector3::new(0.1, 0.2, 0.3),
            rotation: None,
        }]);
        assert_eq!(slide.position(&x0, 5.0), x0 + Vector3::new(0.1, 0.2, 0.3));
        assert_eq!(slide.reference(&x0, 5.0), x0 - Vector3::new(0.1, 0.2, 0.3));
    }

    /// The angle is interpolated, not the orientation: 0° → 720° over two seconds passes 360°
    /// (back where it started) at one second and 180° (turned half round) at half a second,
    /// whereas 720° and 0° are the same orientation.
    #[test]
    fn two_full_turns_pass_through_one_full_turn_halfway() {
        let point = Vector3::new(0.5, 0.0, 0.5);
        let path = turning(&[(0.0, 0.0), (2.0, 720.0)], Vector3::x(), point);
        path.validate().unwrap();
        let x0 = Vector3::new(1.0, 0.0, 1.0);
        assert_eq!(path.angle_degrees(1.0), 360.0);
        assert_eq!(path.angle_degrees(0.5), 180.0);
        assert_eq!(path.angle_degrees(1.75), 630.0);
        assert_eq!(path.angle_degrees(3.0), 720.0);
        assert_eq!(path.angle_degrees(-1.0), 0.0);
        // Unturned, the reference is the position itself, bit for bit (c + (x − c) is not).
        let odd = Vector3::new(0.1, 0.3, 0.7);
        assert_eq!(path.reference(&odd, 0.0), odd);
        assert_eq!(path.position(&odd, 0.0), odd);
        // Round-off of sin 2π and sin 4π on a 1 m lever: a few 1e-16 m.
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() < 1e-14;
        assert!(close(path.position(&x0, 1.0), x0));
        assert!(close(path.position(&x0, 2.0), x0));
        assert!(close(path.position(&x0, 0.5), Vector3::new(1.0, 0.0, 0.0)));
        // A quarter turn at 0.25 s: z − 0.5 = 0.5 turns to y = 0.5 (right-handed about +x).
        assert!(close(
            path.position(&x0, 0.25),
            Vector3::new(1.0, -0.5, 0.5)
        ));
        // The mean velocity over a step, as the simulation takes it: (x(t + h) − x(t))/h is the
        // chord of the circle, 720° in 2 s on radius 0.5 m being 2π·0.5·2/2 m/s along the arc.
        let h = 1e-4;
        let speed = (path.position(&x0, 0.5 + h) - path.position(&x0, 0.5)).norm() / h;
        assert!((speed - std::f64::consts::PI).abs() < 1e-6);
    }

    /// In 2D the turn is in the plane about the point, counter-clockwise for +z and clockwise for
    /// −z; an axis with an in-plane part is refused.
    #[test]
    fn a_2d_pin_turns_in_the_plane() {
        let path = |axis: Vector3<f64>| {
            PinPath::Keyframes(vec![
                Keyframe {
                    time: 0.0,
                    offset: Vector2::zeros(),
                    rotation: None,
                },
                Keyframe {
                    time: 1.0,
                    offset: Vector2::new(0.0, 1.0),
                    rotation: Some(Rotation {
                        axis,
                        point: Vector2::new(1.0, 0.0),
                        degrees: 90.0,
                    }),
                },
            ])
        };
        let x0 = Vector2::new(2.0, 0.0);
        let ccw = path(Vector3::z());
        ccw.validate().unwrap();
        assert!((ccw.position(&x0, 1.0) - Vector2::new(1.0, 2.0)).norm() < 1e-15);
        let cw = path(-Vector3::z());
        assert!((cw.position(&x0, 1.0) - Vector2::new(1.0, 0.0)).norm() < 1e-15);
        let err = path(Vector3::new(0.0, 1.0, 1.0)).validate().unwrap_err();
        assert!(
            matches!(&err, SimError::InvalidParameter { name, .. } if name == "pin path keyframes[1].rotation.axis"),
            "{err}"
        );
    }

    /// Bad rotations are refused with the field named.
    #[test]
    fn bad_rotations_name_the_field() {
        let point = Vector3::zeros();
        let name_of = |path: PinPath<3>| match path.validate() {
            Err(SimError::InvalidParameter { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        for axis in [
            Vector3::zeros(),
            Vector3::new(f64::NAN, 0.0, 1.0),
            Vector3::new(f64::INFINITY, 0.0, 0.0),
        ] {
            assert_eq!(
                name_of(turning(&[(0.0, 0.0), (1.0, 90.0)], axis, point)),
                "pin path keyframes[0].rotation.axis"
            );
        }
        assert_eq!(
            name_of(turning(&[(0.0, f64::NAN)], Vector3::z(), point)),
            "pin path keyframes[0].rotation.degrees"
        );
        assert_eq!(
            name_of(turning(
                &[(0.0, 0.0)],
                Vector3::z(),
                Vector3::new(0.0, f64::NAN, 0.0)
            )),
            "pin path keyframes[0].rotation.point"
        );
        // Two axes, or two points, on one path.
        let PinPath::Keyframes(mut keys) = turning(&[(0.0, 0.0), (1.0, 90.0)], Vector3::z(), point)
        else {
            unreachable!()
        };
        let mut other_axis = keys.clone();
        other_axis[1].rotation.as_mut().unwrap().axis = Vector3::x();
        assert_eq!(
            name_of(PinPath::Keyframes(other_axis)),
            "pin path keyframes[1].rotation.axis"
        );
        keys[1].rotation.as_mut().unwrap().point = Vector3::new(0.0, 0.0, 1.0);
        assert_eq!(
            name_of(PinPath::Keyframes(keys.clone())),
            "pin path keyframes[1].rotation.point"
        );
        // The same axis at another length is the same axis.
        keys[1].rotation.as_mut().unwrap().point = point;
        keys[1].rotation.as_mut().unwrap().axis = Vector3::new(0.0, 0.0, 2.0);
        PinPath::Keyframes(keys).validate().unwrap();
    }
}
