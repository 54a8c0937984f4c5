//! Contact (SPEC §4) as a projection after each step: positions are moved back onto the allowed
//! side and the velocity component into the obstacle is removed, so contact never adds energy.
//! Pinned vertices are never touched.

use nalgebra::SVector;

use crate::error::{finite_vector, non_negative, positive, SimError};

/// The shape of an obstacle or container.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Shape<const D: usize> {
    /// Axis-aligned box walls that keep vertices inside [min, max] (m), seed 004's unit box.
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
