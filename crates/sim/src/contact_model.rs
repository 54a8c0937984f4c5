//! The scene's contact model: obstacle shapes ([`Shape`], [`Contact`]) with their friction, the
//! barrier's settings for the implicit solvers ([`BarrierSettings`]) and self-contact's
//! ([`SelfContact`]), and the per-vertex projection the explicit integrators apply after each
//! substep ([`Contact::project`]).
//!
//! This module owns what a scene says about contact and turns it into the solvers' models
//! ([`obstacles`]). It leaves the geometry (signed distances, times of impact, distances between a
//! surface's primitives, the broad phase, continuous collision detection) to `hooke_collision`,
//! the barrier energies to `hooke_assembly` (`barrier`, `surface_barrier`, `self_contact`), the
//! terms inside backward Euler's objective and the line-search caps to `hooke_solvers`
//! (`backward_euler`, and projective dynamics' collision constraints), and the projection of the
//! whole mesh after a linearised implicit step to the sibling module `projection`
//! (docs/contact.md).

use hooke_assembly::barrier::Obstacle;
pub use hooke_solvers::backward_euler::AdaptiveStiffness;
use nalgebra::SVector;

use crate::error::{finite_vector, non_negative, positive, SimError};

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
    /// IPC's adaptive stiffness ([`AdaptiveStiffness`]): the stiffness above (and self-contact's
    /// κ, made from it) becomes a floor, and one scale s ∈ [1, `max_ratio`] multiplies every
    /// barrier, set at each step's first iterate by the balance of the barrier's gradient against
    /// the rest of Φ's and doubled while a gap keeps closing below `gap_share` of d̂. `None`
    /// (default): the stiffnesses are fixed.
    pub adaptive_stiffness: Option<AdaptiveStiffness>,
}

impl Default for BarrierSettings {
    fn default() -> Self {
        BarrierSettings {
            distance: None,
            stiffness: None,
            friction_velocity: DEFAULT_FRICTION_VELOCITY,
            adaptive_stiffness: None,
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
        if let Some(adaptive) = &self.adaptive_stiffness {
            adaptive.validate().map_err(|e| {
                let (key, value) = match e.field() {
                    "AdaptiveStiffness::max_ratio" => {
                        ("barrier.max_stiffness_ratio", adaptive.max_ratio)
                    }
                    _ => ("barrier.stiffness_gap_share", adaptive.gap_share),
                };
                let allowed = match e {
                    hooke_solvers::ParamError::Real { allowed, .. } => allowed,
                    _ => "in range",
                };
                SimError::invalid(key, value, format!("must be {allowed}"))
            })?;
        }
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
/// the surface never intersects itself; with `friction` > 0 the pairs also rub, by IPC's smooth
/// lagged Coulomb friction. Modelled by the integrators whose step minimises Φ with the barrier
/// (newton, newton-cg, lbfgs); the others refuse it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SelfContact {
    /// The barrier's reach d̂ (m, finite, > 0). `None`: the obstacles' d̂
    /// ([`BarrierSettings::distance`], or its default from the mesh's size).
    pub distance: Option<f64>,
    /// The Coulomb friction coefficient μ between parts of the surface (dimensionless, finite,
    /// ≥ 0; default 0, frictionless, which costs nothing). Each pair within d̂ at a step's start
    /// resists sliding by at most μ times its barrier force there, smoothed below the sliding
    /// speed [`BarrierSettings::friction_velocity`] (docs/contact.md, "Self-contact friction").
    pub friction: f64,
}

impl SelfContact {
    /// Check every value set.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the value: a reach that is not finite and positive,
    /// a friction coefficient that is not finite and ≥ 0.
    pub fn validate(&self) -> Result<(), SimError> {
        if let Some(d) = self.distance {
            positive("self_contact.dhat", d)?;
        }
        non_negative("self_contact.friction", self.friction)?;
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
