//! Per-spring kernels: energy, force, dashpot force, stretch. Generic over the dimension `D`.
//!
//! Conventions (SPEC §1): a spring (i, j) with stiffness k (N/m) and rest length l (m), r = x_i − x_j.
//! Energy ½ k (|r| − l)²; force on i f_i = −k (|r| − l) r̂, and f_j = −f_i.

use nalgebra::SVector;

/// The unit direction of `r`, or `None` where it has none: zero length, or a length so small that
/// its square underflows (|r| below ~1e-154 m). Callers then use a zero force, the symmetric choice
/// (any direction is equally valid, so none is preferred).
#[inline]
pub fn direction<const D: usize>(r: &SVector<f64, D>) -> Option<(SVector<f64, D>, f64)> {
    let length = r.norm();
    if length > 0.0 && length.is_finite() {
        Some((r / length, length))
    } else {
        None
    }
}

/// Spring energy ½ k (|r| − l)² (J). Finite for every finite input, zero length included.
#[inline]
pub fn energy<const D: usize>(stiffness: f64, rest_length: f64, r: &SVector<f64, D>) -> f64 {
    let stretch = r.norm() - rest_length;
    0.5 * stiffness * stretch * stretch
}

/// Force on the first vertex, −k (|r| − l) r̂ (N). At zero length (no direction) it is zero.
#[inline]
pub fn force<const D: usize>(
    stiffness: f64,
    rest_length: f64,
    r: &SVector<f64, D>,
) -> SVector<f64, D> {
    match direction(r) {
        Some((unit, length)) => unit * (-stiffness * (length - rest_length)),
        None => SVector::zeros(),
    }
}

/// Dashpot force on the first vertex, −c ((v_i − v_j)·r̂) r̂ (N), with c in N·s/m and `relative_velocity`
/// = v_i − v_j (m/s). It opposes the rate of change of the spring's length only. Zero at zero length.
#[inline]
pub fn dashpot_force<const D: usize>(
    coefficient: f64,
    r: &SVector<f64, D>,
    relative_velocity: &SVector<f64, D>,
) -> SVector<f64, D> {
    match direction(r) {
        Some((unit, _)) => unit * (-coefficient * relative_velocity.dot(&unit)),
        None => SVector::zeros(),
    }
}

/// Stretch ratio |r| / l (dimensionless; 1 at rest).
#[inline]
pub fn stretch<const D: usize>(rest_length: f64, r: &SVector<f64, D>) -> f64 {
    r.norm() / rest_length
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn zero_length_is_finite_and_forceless() {
        let zero = Vector3::zeros();
        assert_eq!(force(10.0, 0.5, &zero), Vector3::zeros());
        assert_eq!(energy(10.0, 0.5, &zero), 0.5 * 10.0 * 0.25);
        assert_eq!(dashpot_force(1.0, &zero, &Vector3::x()), Vector3::zeros());
        let tiny = Vector3::new(1e-170, 0.0, 0.0);
        assert!(force(10.0, 0.5, &tiny).iter().all(|c| c.is_finite()));
    }

    #[test]
    fn force_is_minus_the_energy_gradient() {
        // Central differences with step 1e-6 of a quantity of size ~1: truncation O(h²) ≈ 1e-12,
        // round-off ≈ 1e-16 / 1e-6 = 1e-10, so 1e-8 relative is a safe, still sharp, bound.
        let (k, l) = (3.0, 0.7);
        for r in [Vector2::new(0.3, -0.4), Vector2::new(2.0, 1.0)] {
            let f = force(k, l, &r);
            for a in 0..2 {
                let mut e = Vector2::zeros();
                e[a] = 1e-6;
                let numeric = -(energy(k, l, &(r + e)) - energy(k, l, &(r - e))) / 2e-6;
                assert!(
                    (numeric - f[a]).abs() <= 1e-8 * f.norm().max(1.0),
                    "axis {a}"
                );
            }
        }
    }

    #[test]
    fn dashpot_only_resists_length_change() {
        let r = Vector3::new(1.0, 0.0, 0.0);
        // Moving sideways does not change the length: no dashpot force.
        assert_eq!(dashpot_force(5.0, &r, &Vector3::y()), Vector3::zeros());
        assert_eq!(
            dashpot_force(5.0, &r, &Vector3::new(2.0, 1.0, 0.0)),
            Vector3::new(-10.0, 0.0, 0.0)
        );
    }
}
