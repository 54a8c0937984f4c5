//! Per-spring kernels: energy, force, dashpot force, stretch. Generic over the dimension `D`.
//!
//! Conventions (docs/model.md §2.2): a spring (i, j) with stiffness k (N/m) and rest length l (m),
//! r = x_i − x_j. Energy ½ k (|r| − l)²; force on i f_i = −k (|r| − l) r̂, and f_j = −f_i.

use nalgebra::{SMatrix, SVector};

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

/// Which second derivative of the spring energy [`hessian_block`] returns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Definiteness {
    /// The exact Hessian k[(1 − l/|r|)(I − r̂r̂ᵀ) + r̂r̂ᵀ]: indefinite when the spring is compressed
    /// (|r| < l). Newton's default (quadratic convergence, docs/model.md §2.4).
    #[default]
    Exact,
    /// The factor (1 − l/|r|) clamped at 0: k[max(0, 1 − l/|r|)(I − r̂r̂ᵀ) + r̂r̂ᵀ], positive
    /// semidefinite for every r. A fallback for Newton (linear convergence) and the choice of the
    /// linearised integrators and CG, which need a definite system.
    Clamped,
}

/// The D×D block ∂²E/∂x_i∂x_i of the spring energy E = ½ k (|r| − l)², r = x_i − x_j (N/m):
///
/// H = k [ (1 − l/|r|) (I − r̂r̂ᵀ) + r̂r̂ᵀ ],
///
/// with the factor (1 − l/|r|) clamped at 0 for [`Definiteness::Clamped`]. The other blocks of the
/// spring's 2D×2D Hessian follow: ∂²E/∂x_j∂x_j = H and ∂²E/∂x_i∂x_j = ∂²E/∂x_j∂x_i = −H. The force
/// Jacobian is minus the Hessian: ∂f_i/∂x_i = −H, ∂f_i/∂x_j = H.
///
/// The block is exactly symmetric (bit for bit). Its eigenvalues are k along r̂ and k(1 − l/|r|)
/// (clamped: k·max(0, 1 − l/|r|)) across, with multiplicity D − 1.
///
/// **Zero length.** Where r has no direction ([`direction`] returns `None`: |r| = 0, or |r| so small
/// that its square underflows) the exact block is unbounded (the transverse eigenvalue −k l/|r|
/// diverges) and the clamped one, k r̂r̂ᵀ, depends on a direction that does not exist. Both variants
/// then return the finite stand-in k/D · I, the average of k r̂r̂ᵀ over all directions: positive
/// definite, so a solver still gets a usable system, and rotation-invariant, so no direction is
/// preferred. The same stand-in is used if a block entry would overflow (k l/|r| beyond ~1e308).
#[inline]
pub fn hessian_block<const D: usize>(
    stiffness: f64,
    rest_length: f64,
    r: &SVector<f64, D>,
    definiteness: Definiteness,
) -> SMatrix<f64, D, D> {
    HessianTerms::new(stiffness, rest_length, r, definiteness).block()
}

/// [`force`], [`hessian_block`] and |r| together, from one square root of |r|² (the same bits as
/// the separate calls and `r.norm()`), for callers that need all three of one spring: per-vertex
/// relaxation, which also reuses |r| in its energy differences.
#[inline]
pub fn force_and_hessian_block<const D: usize>(
    stiffness: f64,
    rest_length: f64,
    r: &SVector<f64, D>,
    definiteness: Definiteness,
) -> (SVector<f64, D>, SMatrix<f64, D, D>, f64) {
    let length_squared = r.norm_squared();
    let length = length_squared.sqrt();
    // As `direction` and `force`.
    let force = if length > 0.0 && length.is_finite() {
        (r / length) * (-stiffness * (length - rest_length))
    } else {
        SVector::zeros()
    };
    let block = HessianTerms::with_inverse_length(
        stiffness,
        rest_length,
        r,
        length_squared,
        1.0 / length,
        definiteness,
    )
    .block();
    (force, block, length)
}

/// A spring's Hessian block in factored form, H = along · ûûᵀ + across · I (N/m): what
/// [`hessian_block`] expands. Kept apart so that assembly can expand it straight into a matrix.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HessianTerms<const D: usize> {
    /// r̂, or zero where r has no direction.
    pub unit: SVector<f64, D>,
    /// k l/|r| (exact, or clamped: k when l/|r| > 1), 0 for the stand-in.
    pub along: f64,
    /// k (1 − l/|r|) (clamped: at least 0), k/D for the stand-in.
    pub across: f64,
}

impl<const D: usize> HessianTerms<D> {
    #[inline]
    pub fn new(
        stiffness: f64,
        rest_length: f64,
        r: &SVector<f64, D>,
        definiteness: Definiteness,
    ) -> Self {
        let length_squared = r.norm_squared();
        Self::with_inverse_length(
            stiffness,
            rest_length,
            r,
            length_squared,
            1.0 / length_squared.sqrt(),
            definiteness,
        )
    }

    /// As [`HessianTerms::new`], given |r|² and 1/|r| = 1/√|r|² (computed by the caller, e.g. for
    /// several springs at once so that the square roots and divisions overlap; IEEE square root and
    /// division are correctly rounded, so the result is the same bits either way).
    #[inline(always)]
    pub fn with_inverse_length(
        stiffness: f64,
        rest_length: f64,
        r: &SVector<f64, D>,
        length_squared: f64,
        inverse_length: f64,
        definiteness: Definiteness,
    ) -> Self {
        // A closure: the division is only paid on the rare stand-in path.
        let stand_in = || HessianTerms {
            unit: SVector::zeros(),
            along: 0.0,
            across: stiffness / D as f64,
        };
        // As `direction`: no direction where |r|² is zero (or underflows) or infinite.
        if !(length_squared > 0.0 && length_squared.is_finite()) {
            return stand_in();
        }
        let ratio = rest_length * inverse_length;
        // H = k [c I + (1 − c) r̂r̂ᵀ] with c = 1 − l/|r| (clamped: max(0, c)); 1 − c is written l/|r|
        // (or 1) directly rather than computed, so the longitudinal eigenvalue k is not polluted by
        // the cancellation 1 − (1 − l/|r|) when l/|r| is large.
        let (across, along) = match definiteness {
            Definiteness::Clamped if ratio > 1.0 => (0.0, 1.0),
            _ => (1.0 - ratio, ratio),
        };
        let (along, across) = (stiffness * along, stiffness * across);
        // |r̂| = 1, so the block is finite exactly when these two are.
        if along.is_finite() && across.is_finite() {
            HessianTerms {
                unit: r * inverse_length,
                along,
                across,
            }
        } else {
            stand_in()
        }
    }

    /// These terms with a negative transverse eigenvalue (a compressed spring) multiplied by
    /// `scale` where `scale` < 1 (`stiffness` k: the longitudinal eigenvalue along + across = k is
    /// kept): across' = scale · across, along' = k − across'. Unchanged otherwise (stretched springs
    /// and the stand-in, whose eigenvalues are not negative). `scale` = 0 gives the clamped terms.
    #[inline]
    pub fn with_across_scale(self, stiffness: f64, scale: f64) -> Self {
        if self.across < 0.0 && scale < 1.0 {
            let across = scale * self.across;
            HessianTerms {
                unit: self.unit,
                along: stiffness - across,
                across,
            }
        } else {
            self
        }
    }

    /// along · ûûᵀ + across · I, exactly symmetric (entry (a, b) and (b, a) are the same product).
    #[inline]
    pub fn block(&self) -> SMatrix<f64, D, D> {
        let mut block = SMatrix::<f64, D, D>::zeros();
        for b in 0..D {
            for a in 0..D {
                block[(a, b)] = self.along * (self.unit[a] * self.unit[b]);
            }
            block[(b, b)] += self.across;
        }
        block
    }
}

/// The D×D block ∂f_i/∂v_i of the dashpot force f_i = −c ((v_i − v_j)·r̂) r̂ with respect to the
/// velocities (N·s/m): −c r̂r̂ᵀ. Also ∂f_j/∂v_j; ∂f_i/∂v_j = ∂f_j/∂v_i = +c r̂r̂ᵀ. Negative
/// semidefinite and exactly symmetric. Zero at zero length, consistent with [`dashpot_force`].
///
/// The dependence of the dashpot force on positions (through r̂) is not included: implicit
/// integrators that linearise damping in v only (docs/model.md §6.3) do not use it.
#[inline]
pub fn dashpot_velocity_block<const D: usize>(
    coefficient: f64,
    r: &SVector<f64, D>,
) -> SMatrix<f64, D, D> {
    match direction(r) {
        Some((unit, _)) => unit * unit.transpose() * (-coefficient),
        None => SMatrix::zeros(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector2, Vector3};

    #[test]
    fn force_and_hessian_block_are_the_separate_calls_bit_for_bit() {
        let (k, l) = (3.0, 0.7);
        for r in [
            Vector3::new(0.3, -0.4, 0.1),
            Vector3::new(2.0, 1.0, -3.0),
            Vector3::new(1e-3, 0.0, 2e-4),
            Vector3::new(1e-170, 0.0, 0.0),
            Vector3::zeros(),
            Vector3::new(1e200, 1e200, 0.0),
        ] {
            for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
                let (f, h, length) = force_and_hessian_block(k, l, &r, definiteness);
                assert_eq!(f, force(k, l, &r), "{r:?}");
                assert_eq!(h, hessian_block(k, l, &r, definiteness), "{r:?}");
                assert_eq!(length.to_bits(), r.norm().to_bits(), "{r:?}");
            }
        }
    }

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

#[cfg(test)]
mod derivative_tests {
    //! Property tests of the derivative chain energy → force → Hessian block against central
    //! differences, over random directions and lengths from 1e-6 l to 1e3 l, in 2D and 3D.

    use super::*;
    use crate::fd;
    use nalgebra::DMatrix;
    use proptest::prelude::*;

    /// A random spring: stiffness k ∈ [1e-2, 1e4] N/m and rest length l ∈ [1e-2, 10] m (both
    /// log-uniform), and r = λ l û with û a random unit vector and λ ∈ [1e-6, 1e3] (log-uniform, the
    /// two extremes also drawn on their own).
    fn spring_case<const D: usize>() -> impl Strategy<Value = (f64, f64, SVector<f64, D>)> {
        let exponent = prop_oneof![Just(-6.0), Just(3.0), -6.0f64..=3.0];
        (
            -2.0f64..=4.0,
            -2.0f64..=1.0,
            exponent,
            proptest::collection::vec(-1.0f64..=1.0, D),
        )
            .prop_map(|(k, l, lambda, u)| {
                let (k, l, lambda) = (10f64.powf(k), 10f64.powf(l), 10f64.powf(lambda));
                let mut u = SVector::<f64, D>::from_column_slice(&u);
                if u.norm() < 1e-3 {
                    u = SVector::<f64, D>::zeros();
                    u[0] = 1.0;
                }
                (k, l, u.normalize() * (lambda * l))
            })
    }

    fn to_dynamic<const D: usize>(m: &SMatrix<f64, D, D>) -> DMatrix<f64> {
        DMatrix::from_column_slice(D, D, m.as_slice())
    }

    fn check_force_gradient<const D: usize>(k: f64, l: f64, r: SVector<f64, D>) {
        // E ≈ ½ k max(l, |r|)² is stored to relative ε, and the step must stay well below |r| (the
        // scale on which r̂ turns): with h = 5e-4 |r| the round-off ε E / h and the truncation
        // h² |E'''| / 6 ≈ h² k l / (6 |r|²) are both below 3e-7 k max(l, |r|) even at |r| = 1e-6 l.
        // Hence a tolerance of 1e-5 k max(l, |r|): the size of the force scale, not of the force,
        // which vanishes at rest.
        let step = 5e-4 * r.norm();
        let numeric = fd::gradient(
            |x| energy(k, l, &SVector::<f64, D>::from_column_slice(x)),
            r.as_slice(),
            step,
        );
        let f = force(k, l, &r);
        let scale = k * l.max(r.norm());
        for a in 0..D {
            assert!(
                (f[a] + numeric[a]).abs() <= 1e-5 * scale,
                "axis {a}: force {} vs −∇E {} (k {k}, l {l}, |r| {})",
                f[a],
                -numeric[a],
                r.norm()
            );
        }
    }

    fn check_hessian<const D: usize>(k: f64, l: f64, r: SVector<f64, D>) {
        let h = hessian_block(k, l, &r, Definiteness::Exact);
        // The spring's full 2D×2D force Jacobian with respect to (x_i, x_j), x_j = 0 so that r is
        // exact, by central differences of (f_i, f_j) = (f, −f).
        let mut x = vec![0.0; 2 * D];
        x[..D].copy_from_slice(r.as_slice());
        let step = fd::suggested_step(r.norm());
        let jac = fd::jacobian(
            |x, out| {
                let r = SVector::<f64, D>::from_column_slice(&x[..D])
                    - SVector::<f64, D>::from_column_slice(&x[D..]);
                let f = force(k, l, &r);
                out[..D].copy_from_slice(f.as_slice());
                out[D..].copy_from_slice((-f).as_slice());
            },
            &x,
            2 * D,
            step,
        );
        // With h = 1e-5 |r| both the round-off ε |f| / h and the truncation h² |f'''| / 6 are below
        // 1e-10 of the largest block entry k max(1, l/|r|) (f varies on the scale |r|), for short and
        // long springs alike; 1e-7 of the largest entry leaves a wide margin for the D terms per entry.
        let scale = h.amax();
        for (bi, bj, sign) in [(0, 0, 1.0), (0, 1, -1.0), (1, 0, -1.0), (1, 1, 1.0)] {
            for a in 0..D {
                for b in 0..D {
                    let numeric = -jac[(bi * D + a, bj * D + b)];
                    let analytic = sign * h[(a, b)];
                    assert!(
                        (numeric - analytic).abs() <= 1e-7 * scale,
                        "block ({bi},{bj}) entry ({a},{b}): Hessian {analytic} vs −∂f/∂x {numeric} \
                         (k {k}, l {l}, |r| {})",
                        r.norm()
                    );
                }
            }
        }
    }

    fn check_spectrum<const D: usize>(k: f64, l: f64, r: SVector<f64, D>) {
        let c = 1.0 - l / r.norm();
        for (definiteness, across) in [
            (Definiteness::Exact, c),
            (Definiteness::Clamped, c.max(0.0)),
        ] {
            let h = hessian_block(k, l, &r, definiteness);
            assert_eq!(
                h,
                h.transpose(),
                "{definiteness:?} block not exactly symmetric"
            );
            let mut eig: Vec<f64> = to_dynamic(&h)
                .symmetric_eigen()
                .eigenvalues
                .iter()
                .copied()
                .collect();
            eig.sort_by(f64::total_cmp);
            // Eigenvalues of a symmetric matrix are computed to ~D ε times its norm k max(1, |c|).
            let tol = 1e-13 * k * c.abs().max(1.0);
            let mut expected = vec![k * across; D - 1];
            expected.push(k);
            expected.sort_by(f64::total_cmp);
            for (got, want) in eig.iter().zip(&expected) {
                assert!(
                    (got - want).abs() <= tol,
                    "{definiteness:?}: eigenvalues {eig:?}, expected {expected:?}"
                );
            }
            if definiteness == Definiteness::Clamped {
                assert!(eig[0] >= -1e-12 * k, "clamped block not PSD: {eig:?}");
            }
        }
    }

    fn check_dashpot<const D: usize>(r: SVector<f64, D>) {
        let c = 3.5;
        let block = dashpot_velocity_block(c, &r);
        assert_eq!(block, block.transpose());
        // The dashpot force is linear in the relative velocity: central differences are exact up to
        // round-off ε c / h with h = 1e-3 (velocities of size 1).
        let jac = fd::jacobian(
            |v, out| {
                let f = dashpot_force(c, &r, &SVector::<f64, D>::from_column_slice(v));
                out.copy_from_slice(f.as_slice());
            },
            &vec![0.5; D],
            D,
            1e-3,
        );
        assert!((jac - to_dynamic(&block)).amax() <= 1e-10 * c);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn force_is_minus_the_energy_gradient_2d((k, l, r) in spring_case::<2>()) {
            check_force_gradient(k, l, r);
        }

        #[test]
        fn force_is_minus_the_energy_gradient_3d((k, l, r) in spring_case::<3>()) {
            check_force_gradient(k, l, r);
        }

        #[test]
        fn hessian_block_is_minus_the_force_jacobian_2d((k, l, r) in spring_case::<2>()) {
            check_hessian(k, l, r);
        }

        #[test]
        fn hessian_block_is_minus_the_force_jacobian_3d((k, l, r) in spring_case::<3>()) {
            check_hessian(k, l, r);
        }

        #[test]
        fn hessian_block_spectrum_and_symmetry_2d((k, l, r) in spring_case::<2>()) {
            check_spectrum(k, l, r);
        }

        #[test]
        fn hessian_block_spectrum_and_symmetry_3d((k, l, r) in spring_case::<3>()) {
            check_spectrum(k, l, r);
        }

        #[test]
        fn dashpot_velocity_block_is_the_dashpot_jacobian((_k, _l, r) in spring_case::<3>()) {
            check_dashpot(r);
        }
    }

    #[test]
    fn zero_and_underflowing_lengths_give_the_finite_stand_in() {
        let (k, l) = (7.0, 0.3);
        for r in [
            nalgebra::Vector3::zeros(),
            nalgebra::Vector3::new(1e-170, 0.0, -1e-170),
        ] {
            for definiteness in [Definiteness::Exact, Definiteness::Clamped] {
                let h = hessian_block(k, l, &r, definiteness);
                assert_eq!(h, nalgebra::Matrix3::identity() * (k / 3.0));
            }
            assert_eq!(dashpot_velocity_block(2.0, &r), nalgebra::Matrix3::zeros());
        }
        // Just above the underflow limit the exact block is huge but finite.
        let h = hessian_block(
            k,
            l,
            &nalgebra::Vector2::new(1e-150, 0.0),
            Definiteness::Exact,
        );
        assert!(h.iter().all(|v| v.is_finite()));
    }
}
