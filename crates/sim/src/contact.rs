//! Contact (docs/model.md §7) as a projection after each step: positions are moved back onto the
//! allowed side and the velocity component into the obstacle is removed. Pinned vertices are never
//! touched.
//!
//! The explicit integrators project each vertex on its own ([`Contact::project`]) after every
//! substep, whose penetrations are tiny. (Newton, Newton-CG, L-BFGS and projective dynamics handle
//! contact inside their solves instead: docs/contact.md.) After an implicit step of a whole frame
//! (the linearised integrator) that is not enough: the solve knows nothing of the obstacles, and at
//! h = 1/30 s it moves vertices far into them. Projecting each such vertex on its own moves it by the
//! penetration depth d while its neighbours stay, which stores about ½ k d² in every spring to it:
//! cloth-12 (k = 1e3 N/m, 1 kg) falling on a sphere of radius 0.15 m under Newton went 0.058 m and
//! then 0.102 m into the sphere in frames 7 and 8, and the per-vertex projection raised the spring
//! energy from 0.34 J to 16.2 J and then 106 J (total energy +15.6 J and +105.5 J above the
//! initial 0 J). Energy is not created by the velocity update (removing the inward velocity only
//! lowers the kinetic energy) but by these independent position moves.
//!
//! So after an implicit step the projection is done for the mesh (`StepProjection`). Each vertex
//! that ended inside an obstacle (the active set) gets the normal displacement that puts it on the
//! surface, at the point [`Contact::project`] would give, and may still move in that point's
//! tangent plane; every free vertex then moves by the displacement Δ of least increase of the
//! step's objective Φ (docs/model.md §6.4) to second order, ½ Δᵀ (M + h² ∇²E) Δ, under those
//! constraints: one Newton step of the contact-constrained backward Euler problem from the
//! unconstrained solution x⁺ (the clamped spring Hessian at x⁺, so the system is positive definite;
//! solved by CG with Baraff and Witkin's per-vertex filter I − n nᵀ). A vertex that Δ leaves inside
//! an obstacle joins the active set and Δ is solved again (at most [`MAX_PROJECTION_ROUNDS`]
//! rounds); a last per-vertex pass puts anything still inside on the surface, so no vertex ends
//! inside (a vertex in contact with a sphere ends on its tangent plane, just outside it). Each
//! vertex's velocity becomes that of its projected position, v⁺ + Δ/h (times the drag factor where
//! the integrator applies drag to (x⁺ − x_n)/h), and at the active vertices the inward normal
//! component is removed and friction applied, as [`Contact::project`] does. Pinned vertices are not
//! unknowns, so nothing moves them.
//!
//! Measured on the same scene (`cargo run -p hooke-sim --example contact_probe -- newton`): the
//! energy now rises at most 1.57 J above E₀ (frame 8; spring energy 2.9 J), the cloth drapes over
//! the sphere and slides off, and it ends 3.2 J below E₀ after 45 frames; the linearised integrator
//! never rises above E₀. What is left is the error of the one Newton step
//! (the springs near the sphere turn by large angles in a frame): the projection does not make
//! contact part of the solve, and does not promise energy decrease.

use hooke_assembly::contact::Obstacle;
use hooke_assembly::{Definiteness, FreeDofs, HessianParams, HessianPattern, HessianWorkspace};
use hooke_solvers::{
    BlockJacobi, CgParams, ConjugateGradient, LinearOperator, Preconditioner, SolveError, Symmetric,
};
use nalgebra::SVector;

use crate::error::{finite_vector, non_negative, positive, SimError};
use crate::Scene;

/// The shape of an obstacle or container.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Shape<const D: usize> {
    /// Axis-aligned box walls that keep vertices inside [min, max] (m), as seed-2d's unit box
    /// (docs/scenes.md §5).
    Box {
        /// Lower corner, m.
        min: SVector<f64, D>,
        /// Upper corner, m.
        max: SVector<f64, D>,
    },
    /// A plane through `point` (m); vertices stay on the side its `normal` points to (a ground plane
    /// has normal "up").
    Plane {
        /// A point of the plane, m.
        point: SVector<f64, D>,
        /// The allowed side's direction; normalised on construction.
        normal: SVector<f64, D>,
    },
    /// A solid sphere (m) that vertices stay outside of.
    Sphere {
        /// Centre, m.
        center: SVector<f64, D>,
        /// Radius, m, > 0.
        radius: f64,
    },
}

impl<const D: usize> Shape<D> {
    /// The signed distance (m) of `x` from the surface: positive on the allowed side, negative
    /// inside the obstacle (see [`Contact::signed_distance`]). A plane's normal must be unit length
    /// ([`Contact::validated`] normalises it).
    #[inline]
    pub fn signed_distance(&self, x: &SVector<f64, D>) -> f64 {
        match self {
            Shape::Box { min, max } => (0..D)
                .map(|a| (x[a] - min[a]).min(max[a] - x[a]))
                .fold(f64::INFINITY, f64::min),
            Shape::Plane { point, normal } => (x - point).dot(normal),
            Shape::Sphere { center, radius } => (x - center).norm() - radius,
        }
    }
}

/// Standard gravity g₀ (m/s²), the default barrier stiffness's acceleration scale.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// The default barrier reach d̂ as a share of the bounding-box diagonal of the mesh's initial
/// positions: 1e-3 (1.4 mm for a 1 m square of cloth, 0.3 mm for a 0.3 m solid).
pub const DEFAULT_BARRIER_SHARE: f64 = 1e-3;

/// The default barrier stiffness κ̂ in units of g₀/d̂: 1000. At d = d̂/2 the barrier pushes a
/// vertex with about 1,200 times its weight, so that a vertex at the bottom of a solid, which
/// carries the weight of many, still rests at a distance of the order of d̂, which the solvers'
/// step-size tolerance resolves (measurements: benches/results/contact-scenes.md).
pub const DEFAULT_BARRIER_STIFFNESS: f64 = 1000.0;

/// The default friction smoothing velocity ε_v, m/s.
pub const DEFAULT_FRICTION_VELOCITY: f64 = 1e-3;

/// How the implicit integrators that minimise Φ (newton, newton-cg, lbfgs) model contact: IPC's
/// log barrier between every free vertex and every obstacle, and smooth lagged Coulomb friction
/// (docs/contact.md). Every value is fixed for a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BarrierSettings {
    /// The barrier's reach d̂ (m, finite, > 0): a vertex farther than d̂ from an obstacle feels
    /// nothing; the barrier grows without bound as it nears the surface. `None`:
    /// [`DEFAULT_BARRIER_SHARE`] of the bounding-box diagonal of the mesh's initial positions.
    pub distance: Option<f64>,
    /// The barrier's stiffness per unit of vertex mass κ̂ (1/s², finite, > 0): vertex v's barrier
    /// energy is κ̂ m_v b(d) (J) with b(d) = −(d − d̂)² ln(d/d̂) (m²). `None`:
    /// [`DEFAULT_BARRIER_STIFFNESS`] g₀/d̂.
    pub stiffness: Option<f64>,
    /// Friction's smoothing velocity ε_v (m/s, finite, > 0): below this tangential speed friction
    /// acts as a stiff spring towards sticking, above it as μ times the normal force. Default
    /// [`DEFAULT_FRICTION_VELOCITY`].
    pub friction_velocity: f64,
}

impl Default for BarrierSettings {
    fn default() -> Self {
        BarrierSettings {
            distance: None,
            stiffness: None,
            friction_velocity: DEFAULT_FRICTION_VELOCITY,
        }
    }
}

impl BarrierSettings {
    /// Check every value set.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first value that is not finite and positive.
    pub fn validate(&self) -> Result<(), SimError> {
        if let Some(d) = self.distance {
            positive("barrier.distance", d)?;
        }
        if let Some(k) = self.stiffness {
            positive("barrier.stiffness", k)?;
        }
        positive("barrier.friction_velocity", self.friction_velocity)?;
        Ok(())
    }

    /// (d̂ in m, κ̂ in 1/s²) for a mesh whose initial positions are `positions`.
    pub fn resolve<const D: usize>(&self, positions: &[SVector<f64, D>]) -> (f64, f64) {
        let distance = self.distance.unwrap_or_else(|| {
            let mut lo = SVector::<f64, D>::repeat(f64::INFINITY);
            let mut hi = SVector::<f64, D>::repeat(f64::NEG_INFINITY);
            for p in positions {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            let diagonal = (hi - lo).norm();
            // A single point (or nothing): fall back to 1 m.
            let diagonal = if diagonal.is_finite() && diagonal > 0.0 {
                diagonal
            } else {
                1.0
            };
            DEFAULT_BARRIER_SHARE * diagonal
        });
        let stiffness = self
            .stiffness
            .unwrap_or(DEFAULT_BARRIER_STIFFNESS * STANDARD_GRAVITY / distance);
        (distance, stiffness)
    }
}

/// Self-contact of the mesh's surface (docs/contact.md): the point–triangle and edge–edge pairs of
/// its triangles (a cloth's triangles, a solid's boundary faces) within the reach d̂ repel each
/// other by IPC's barrier, and every line search stops before a pair passes through another, so
/// the surface never intersects itself. Modelled by the integrators whose step minimises Φ with
/// the barrier (newton, newton-cg, lbfgs); the others refuse it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SelfContact {
    /// The barrier's reach d̂ (m, finite, > 0). `None`: the obstacles' d̂
    /// ([`BarrierSettings::distance`], or its default from the mesh's size).
    pub distance: Option<f64>,
}

impl SelfContact {
    /// Check every value set.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the value that is not finite and positive.
    pub fn validate(&self) -> Result<(), SimError> {
        if let Some(d) = self.distance {
            positive("self_contact.dhat", d)?;
        }
        Ok(())
    }

    /// d̂ (m) and κ (N/m) resolved for a mesh at `positions` with `masses` under `barrier`: d̂ as
    /// given or the barrier's (resolved); κ = κ̂ m̄ with κ̂ the barrier's stiffness per unit mass
    /// (its default taken at this d̂) and m̄ the mean vertex mass, so that a pair of average
    /// vertices feels what a vertex feels from an obstacle.
    pub fn resolve<const D: usize>(
        &self,
        barrier: &BarrierSettings,
        positions: &[SVector<f64, D>],
        masses: &[f64],
    ) -> (f64, f64) {
        let distance = self
            .distance
            .unwrap_or_else(|| barrier.resolve(positions).0);
        let per_mass = barrier
            .stiffness
            .unwrap_or(DEFAULT_BARRIER_STIFFNESS * STANDARD_GRAVITY / distance);
        let mean_mass = masses.iter().sum::<f64>() / masses.len().max(1) as f64;
        (distance, per_mass * mean_mass)
    }
}

/// The obstacles of `contacts` as the solvers see them: a plane as one half-space, a box as its
/// 2·D walls (half-spaces facing inwards), a sphere as a sphere to stay outside of; each with its
/// friction coefficient.
pub fn obstacles<const D: usize>(contacts: &[Contact<D>]) -> Vec<(Obstacle<D>, f64)> {
    let mut out = Vec::new();
    for c in contacts {
        match c.shape {
            Shape::Plane { point, normal } => {
                out.push((Obstacle::HalfSpace { point, normal }, c.friction));
            }
            Shape::Sphere { center, radius } => {
                out.push((Obstacle::SphereOutside { center, radius }, c.friction));
            }
            Shape::Box { min, max } => {
                for a in 0..D {
                    let mut normal = SVector::zeros();
                    normal[a] = 1.0;
                    out.push((Obstacle::HalfSpace { point: min, normal }, c.friction));
                    out.push((
                        Obstacle::HalfSpace {
                            point: max,
                            normal: -normal,
                        },
                        c.friction,
                    ));
                }
            }
        }
    }
    out
}

/// A contact constraint: a shape and a friction coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact<const D: usize> {
    /// The shape.
    pub shape: Shape<D>,
    /// Coulomb-like friction μ ≥ 0: on contact the tangential velocity is reduced by μ times the
    /// normal velocity removed, and never reversed. 0 is frictionless.
    pub friction: f64,
}

impl<const D: usize> Contact<D> {
    /// A frictionless contact.
    pub fn new(shape: Shape<D>) -> Self {
        Contact {
            shape,
            friction: 0.0,
        }
    }

    /// Check the parameters and normalise a plane's normal.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a non-finite value, an empty box, a zero normal or a
    /// non-positive radius.
    pub fn validated(mut self) -> Result<Self, SimError> {
        non_negative("contact.friction", self.friction)?;
        match &mut self.shape {
            Shape::Box { min, max } => {
                finite_vector("contact.box.min", min)?;
                finite_vector("contact.box.max", max)?;
                if (0..D).any(|a| min[a] >= max[a]) {
                    return Err(SimError::invalid(
                        "contact.box",
                        format!("{:?}..{:?}", min.as_slice(), max.as_slice()),
                        "min must be below max on every axis",
                    ));
                }
            }
            Shape::Plane { point, normal } => {
                finite_vector("contact.plane.point", point)?;
                finite_vector("contact.plane.normal", normal)?;
                let length = normal.norm();
                if length == 0.0 {
                    return Err(SimError::invalid(
                        "contact.plane.normal",
                        "zero",
                        "must be non-zero",
                    ));
                }
                *normal /= length;
            }
            Shape::Sphere { center, radius } => {
                finite_vector("contact.sphere.center", center)?;
                positive("contact.sphere.radius", *radius)?;
            }
        }
        Ok(self)
    }

    /// The signed distance (m) of `x` from the obstacle's surface: positive on the allowed side,
    /// zero on the surface, negative inside the obstacle. For a box, the distance to the nearest
    /// wall, measured inwards; for a plane, along its (normalised) normal; for a sphere,
    /// |x − c| − r.
    #[inline]
    pub fn signed_distance(&self, x: &SVector<f64, D>) -> f64 {
        self.shape.signed_distance(x)
    }

    /// Project one vertex: returns true if it was in contact.
    #[inline]
    pub fn project(&self, x: &mut SVector<f64, D>, v: &mut SVector<f64, D>) -> bool {
        match self.shape {
            Shape::Box { min, max } => {
                let mut hit = false;
                for a in 0..D {
                    let (bound, normal_sign) = if x[a] < min[a] {
                        (min[a], 1.0)
                    } else if x[a] > max[a] {
                        (max[a], -1.0)
                    } else {
                        continue;
                    };
                    hit = true;
                    x[a] = bound;
                    let mut n = SVector::zeros();
                    n[a] = normal_sign;
                    self.remove_inward(v, &n);
                }
                hit
            }
            Shape::Plane { point, normal } => {
                let depth = (*x - point).dot(&normal);
                if depth >= 0.0 {
                    return false;
                }
                *x -= normal * depth;
                self.remove_inward(v, &normal);
                true
            }
            Shape::Sphere { center, radius } => {
                let offset = *x - center;
                let distance = offset.norm();
                if distance >= radius {
                    return false;
                }
                // At the centre any direction is as good; pick the first axis.
                let n = if distance > 0.0 {
                    offset / distance
                } else {
                    let mut e = SVector::zeros();
                    e[0] = 1.0;
                    e
                };
                *x = center + n * radius;
                self.remove_inward(v, &n);
                true
            }
        }
    }

    /// Remove the velocity component along −n (into the obstacle) and apply friction.
    #[inline]
    fn remove_inward(&self, v: &mut SVector<f64, D>, n: &SVector<f64, D>) {
        let vn = v.dot(n);
        if vn >= 0.0 {
            return;
        }
        *v -= n * vn;
        if self.friction > 0.0 {
            let speed = v.norm();
            if speed > 0.0 {
                let reduced = (speed - self.friction * (-vn)).max(0.0);
                *v *= reduced / speed;
            }
        }
    }
}

/// Rounds of the implicit steps' contact projection (see the module documentation): solve for
/// the displacement, then activate the vertices it left inside an obstacle.
pub const MAX_PROJECTION_ROUNDS: usize = 8;

/// The relative residual to which [`StepProjection`] solves for Δ: 1e-8 of the prescribed
/// displacements (m) leaves an error far below the penetration depths it corrects.
const PROJECTION_TOLERANCE: f64 = 1e-8;

/// Iteration limit of that solve (a solve that reaches it is kept: Δ is then less smooth, and the
/// final per-vertex pass still puts every vertex outside).
const PROJECTION_ITERATIONS: usize = 2000;

/// Contact after an implicit step, for the whole mesh (see the module documentation). Workspaces
/// are allocated once, in [`StepProjection::new`].
#[derive(Debug)]
pub(crate) struct StepProjection<const D: usize> {
    free: FreeDofs,
    pattern: HessianPattern<D>,
    workspace: HessianWorkspace<D>,
    values: Vec<f64>,
    blocks: BlockJacobi<D>,
    cg: ConjugateGradient,
    /// Per free vertex: the contact normal if it is in contact (its normal displacement is
    /// prescribed), zero otherwise.
    normals: Vec<SVector<f64, D>>,
    /// Per free vertex in contact: the point that was projected (for the velocity update).
    probe: Vec<SVector<f64, D>>,
    /// The unconstrained positions x⁺ (full numbering).
    start: Vec<SVector<f64, D>>,
    /// Per free DOF: the prescribed displacement (m) that puts a vertex in contact on the
    /// surface; zero elsewhere.
    prescribed: Vec<f64>,
    /// Per free DOF: the free part of the displacement (m), tangential at vertices in contact.
    follow: Vec<f64>,
    rhs: Vec<f64>,
}

/// S v: v without its component along the unit normal `n` (v itself where n = 0).
#[inline]
fn filter<const D: usize>(n: &SVector<f64, D>, v: &mut [f64]) {
    let along: f64 = (0..D).map(|a| n[a] * v[a]).sum();
    for a in 0..D {
        v[a] -= along * n[a];
    }
}

/// S A S + (I − S), S the per-vertex filter I − n nᵀ at the vertices in contact (Baraff and
/// Witkin's constraint filter): the objective's Hessian on the displacements that keep those
/// vertices on their tangent planes, and the identity across them. Symmetric positive definite
/// when A is.
struct Filtered<'a, const D: usize> {
    matrix: Symmetric<'a>,
    normals: &'a [SVector<f64, D>],
}

impl<const D: usize> LinearOperator for Filtered<'_, D> {
    fn dim(&self) -> usize {
        self.matrix.dim()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.matrix.apply(x, y);
        for (f, n) in self.normals.iter().enumerate() {
            if n.iter().any(|&c| c != 0.0) {
                let (x, y) = (&x[D * f..D * f + D], &mut y[D * f..D * f + D]);
                filter(n, y);
                // + (I − S) x = n (n·x): zero for the vectors CG forms, kept for definiteness.
                let along: f64 = (0..D).map(|a| n[a] * x[a]).sum();
                for a in 0..D {
                    y[a] += along * n[a];
                }
            }
        }
    }
}

/// S B⁻¹ S + (I − S), B the diagonal blocks of A: the block-Jacobi preconditioner of
/// [`Filtered`].
struct FilteredBlocks<'a, const D: usize> {
    blocks: &'a BlockJacobi<D>,
    normals: &'a [SVector<f64, D>],
}

impl<const D: usize> Preconditioner for FilteredBlocks<'_, D> {
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        for (f, (inverse, n)) in self.blocks.inverses().iter().zip(self.normals).enumerate() {
            let r = &r[D * f..D * f + D];
            let mut s = SVector::<f64, D>::from_column_slice(r);
            filter(n, s.as_mut_slice());
            let mut out = inverse * s;
            filter(n, out.as_mut_slice());
            let along: f64 = (0..D).map(|a| n[a] * r[a]).sum();
            out += n * along;
            z[D * f..D * f + D].copy_from_slice(out.as_slice());
        }
    }
}

impl<const D: usize> StepProjection<D> {
    /// Workspaces for `scene` (its mesh and pins).
    pub(crate) fn new(scene: &Scene<D>) -> Result<Self, SimError> {
        let mesh = scene.mesh();
        let n = mesh.vertex_count();
        let free = FreeDofs::new(n, scene.pinned())
            .map_err(|e| SimError::invalid("pins", "", e.to_string()))?;
        let pattern = HessianPattern::new(n, mesh.springs(), Some(&free));
        let count = free.free_count();
        let dim = D * count;
        Ok(StepProjection {
            workspace: pattern.workspace(),
            values: pattern.new_values(),
            blocks: BlockJacobi::identity(count),
            cg: ConjugateGradient::new(CgParams {
                tolerance: PROJECTION_TOLERANCE,
                max_iterations: PROJECTION_ITERATIONS,
            }),
            normals: vec![SVector::zeros(); count],
            probe: vec![SVector::zeros(); count],
            start: vec![SVector::zeros(); n],
            prescribed: vec![0.0; dim],
            follow: vec![0.0; dim],
            rhs: vec![0.0; dim],
            free,
            pattern,
        })
    }

    /// Project the state after an implicit step: `positions` are the solver's x⁺, `velocities` its
    /// v⁺ = (x⁺ − x_n)/h · `velocity_scale` (the drag factor where it was applied to that quotient,
    /// else 1). Both are updated in place (see the module documentation); pinned vertices are not
    /// read or written. Returns the number of vertices in contact.
    ///
    /// # Errors
    /// [`SimError::Solver`] if the solve for Δ meets NaN or a singular block.
    pub(crate) fn apply(
        &mut self,
        scene: &Scene<D>,
        positions: &mut [SVector<f64, D>],
        velocities: &mut [SVector<f64, D>],
        velocity_scale: f64,
        parallel: bool,
    ) -> Result<usize, SimError> {
        let contacts = scene.contacts();
        if contacts.is_empty() {
            return Ok(0);
        }
        self.normals.fill(SVector::zeros());
        self.prescribed.fill(0.0);
        self.follow.fill(0.0);
        self.start.copy_from_slice(positions);
        let touched = self.activate_penetrating(contacts);
        if touched == 0 {
            return Ok(0);
        }
        let mut touched = touched;
        let h = scene.time_step();
        let mesh = scene.mesh();
        self.pattern.assemble_into(
            mesh.springs(),
            &self.start,
            mesh.masses(),
            h,
            HessianParams {
                definiteness: Definiteness::Clamped,
                parallel,
            },
            &mut self.workspace,
            &mut self.values,
        );
        self.blocks
            .refill(self.pattern.diagonal_blocks(&self.values))
            .map_err(SimError::solver)?;
        for _ in 0..MAX_PROJECTION_ROUNDS {
            self.solve().map_err(SimError::solver)?;
            let joined = self.activate_penetrating(contacts);
            touched += joined;
            if joined == 0 {
                break;
            }
        }
        let scale = velocity_scale / h;
        for (f, &v) in self.free.free_vertices().iter().enumerate() {
            let v = v as usize;
            let delta = SVector::<f64, D>::from_fn(|a, _| {
                self.prescribed[D * f + a] + self.follow[D * f + a]
            });
            positions[v] = self.start[v] + delta;
            velocities[v] += delta * scale;
            if self.normals[f].iter().any(|&c| c != 0.0) {
                let mut probe = self.probe[f];
                for contact in contacts {
                    contact.project(&mut probe, &mut velocities[v]);
                }
            }
            // Whatever the rounds left inside (a vertex slid into a second obstacle, or the round
            // limit), each contact puts on its surface, as after an explicit step.
            let mut unused = SVector::zeros();
            for contact in contacts {
                contact.project(&mut positions[v], &mut unused);
            }
        }
        Ok(touched)
    }

    /// Put in contact every free vertex not yet in contact that x⁺ + Δ leaves inside an
    /// obstacle: its displacement becomes the one to the surface point, plus a tangential part
    /// to be solved for. Returns how many joined.
    fn activate_penetrating(&mut self, contacts: &[Contact<D>]) -> usize {
        let mut joined = 0;
        for f in 0..self.free.free_count() {
            if self.normals[f].iter().any(|&c| c != 0.0) {
                continue;
            }
            let start = self.start[self.free.free_vertices()[f] as usize];
            let x = start
                + SVector::<f64, D>::from_fn(|a, _| {
                    self.prescribed[D * f + a] + self.follow[D * f + a]
                });
            let Some(moved) = surface_point(contacts, &x) else {
                continue;
            };
            let push = moved - x;
            let depth = push.norm();
            if depth == 0.0 {
                continue;
            }
            self.normals[f] = push / depth;
            self.probe[f] = x;
            let delta = moved - start;
            self.prescribed[D * f..D * f + D].copy_from_slice(delta.as_slice());
            self.follow[D * f..D * f + D].fill(0.0);
            joined += 1;
        }
        joined
    }

    /// The free part z of the displacement for the current contacts: S A S z = −S A Δ_prescribed,
    /// from the previous rounds' z.
    fn solve(&mut self) -> Result<(), SolveError> {
        let matrix = Symmetric(self.pattern.matrix(&self.values));
        matrix.apply(&self.prescribed, &mut self.rhs);
        for (r, n) in self.rhs.chunks_exact_mut(D).zip(&self.normals) {
            for r in r.iter_mut() {
                *r = -*r;
            }
            filter(n, r);
        }
        let operator = Filtered {
            matrix,
            normals: &self.normals,
        };
        let mut preconditioner = FilteredBlocks {
            blocks: &self.blocks,
            normals: &self.normals,
        };
        self.cg
            .solve(&operator, &mut preconditioner, &self.rhs, &mut self.follow)?;
        Ok(())
    }
}

/// Where the contacts put `x` (each in turn, as [`Contact::project`] does), or `None` if it is
/// outside every obstacle.
fn surface_point<const D: usize>(
    contacts: &[Contact<D>],
    x: &SVector<f64, D>,
) -> Option<SVector<f64, D>> {
    let mut p = *x;
    let mut v = SVector::zeros();
    let mut hit = false;
    for contact in contacts {
        hit |= contact.project(&mut p, &mut v);
    }
    hit.then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn box_walls_clamp_like_the_seed() {
        let walls = Contact::new(Shape::Box {
            min: Vector2::zeros(),
            max: Vector2::new(1.0, 1.0),
        })
        .validated()
        .unwrap();
        let mut x = Vector2::new(-0.1, 0.5);
        let mut v = Vector2::new(-2.0, 0.3);
        assert!(walls.project(&mut x, &mut v));
        assert_eq!(x, Vector2::new(0.0, 0.5));
        assert_eq!(v, Vector2::new(0.0, 0.3));
    }

    #[test]
    fn ground_and_sphere_never_add_energy() {
        let ground = Contact {
            shape: Shape::Plane {
                point: Vector3::zeros(),
                normal: Vector3::new(0.0, 2.0, 0.0),
            },
            friction: 0.5,
        }
        .validated()
        .unwrap();
        let mut x = Vector3::new(0.3, -0.2, 0.1);
        let mut v = Vector3::new(1.0, -1.0, 0.0);
        ground.project(&mut x, &mut v);
        assert_eq!(x, Vector3::new(0.3, 0.0, 0.1));
        assert!(v.y == 0.0 && v.norm() < 1.0 && v.x > 0.0);
        let ball = Contact::new(Shape::Sphere {
            center: Vector3::zeros(),
            radius: 1.0,
        })
        .validated()
        .unwrap();
        let mut x = Vector3::new(0.0, 0.5, 0.0);
        let mut v = Vector3::new(0.1, -1.0, 0.0);
        ball.project(&mut x, &mut v);
        assert!((x.norm() - 1.0).abs() < 1e-15);
        assert_eq!(v, Vector3::new(0.1, 0.0, 0.0));
    }

    #[test]
    fn invalid_shapes_are_rejected() {
        assert!(Contact::new(Shape::Sphere {
            center: Vector3::zeros(),
            radius: 0.0
        })
        .validated()
        .is_err());
        assert!(Contact::new(Shape::Plane {
            point: Vector3::zeros(),
            normal: Vector3::zeros()
        })
        .validated()
        .is_err());
    }
}
