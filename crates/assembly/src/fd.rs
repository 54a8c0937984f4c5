//! Central finite differences: gradients of scalar functions and Jacobians of vector functions.
//!
//! Library code (not only test code) so that users' property tests can check their own energies,
//! forces and stiffness matrices the way this crate checks its own.
//!
//! # Step and accuracy
//! The central difference (f(x + h e) − f(x − h e)) / 2h has truncation error h²/6 · |f'''| and a
//! round-off error of about ε |f| / h (ε = 2.2e-16). The two balance at h ≈ (3ε |f| / |f'''|)^(1/3);
//! for a function that varies on the length scale L (|f'''| ≈ |f| / L³) that is h ≈ 1e-5 L, where
//! both errors are about 1e-10 |f| / L. [`suggested_step`] returns that value; choose L as the length
//! over which your function changes (for a spring, its current length |r|, not the coordinates'
//! magnitude). Expect relative errors of 1e-9 to 1e-7 and compare with tolerances scaled by the size
//! of the quantity, never with absolute ones.
//!
//! The step actually used in each coordinate is the representable difference (x + h) − (x − h), so
//! rounding of x + h does not bias the quotient.

use nalgebra::DMatrix;

/// The step 1e-5 · `length_scale`: near-optimal for central differences of a function that varies
/// on `length_scale` (see the [module documentation](self)).
///
/// # Panics
/// If `length_scale` is not positive and finite.
#[track_caller]
pub fn suggested_step(length_scale: f64) -> f64 {
    assert!(
        length_scale > 0.0 && length_scale.is_finite(),
        "fd::suggested_step: the length scale must be positive and finite, got {length_scale}"
    );
    1e-5 * length_scale
}

#[track_caller]
fn check_step(step: f64) {
    assert!(
        step > 0.0 && step.is_finite(),
        "fd: the step must be positive and finite, got {step}"
    );
}

/// Central-difference gradient of `f` at `x` with step `step`: component c is
/// (f(x + h e_c) − f(x − h e_c)) / ((x_c + h) − (x_c − h)). Calls `f` 2·len(x) times.
///
/// # Panics
/// If `step` is not positive and finite.
#[track_caller]
pub fn gradient(f: impl Fn(&[f64]) -> f64, x: &[f64], step: f64) -> Vec<f64> {
    check_step(step);
    let mut probe = x.to_vec();
    (0..x.len())
        .map(|c| {
            let (plus, minus) = (x[c] + step, x[c] - step);
            probe[c] = plus;
            let f_plus = f(&probe);
            probe[c] = minus;
            let f_minus = f(&probe);
            probe[c] = x[c];
            (f_plus - f_minus) / (plus - minus)
        })
        .collect()
}

/// Central-difference Jacobian of `f: ℝⁿ → ℝᵐ` at `x` with step `step`, as an m × n matrix with
/// entry (r, c) ≈ ∂f_r/∂x_c. `f(x, out)` must write all `m` components of `out` (it is not cleared
/// between calls). Calls `f` 2n times.
///
/// # Panics
/// If `step` is not positive and finite.
#[track_caller]
pub fn jacobian(f: impl Fn(&[f64], &mut [f64]), x: &[f64], m: usize, step: f64) -> DMatrix<f64> {
    check_step(step);
    let mut probe = x.to_vec();
    let mut f_plus = vec![0.0; m];
    let mut f_minus = vec![0.0; m];
    let mut out = DMatrix::zeros(m, x.len());
    for c in 0..x.len() {
        let (plus, minus) = (x[c] + step, x[c] - step);
        probe[c] = plus;
        f(&probe, &mut f_plus);
        probe[c] = minus;
        f(&probe, &mut f_minus);
        probe[c] = x[c];
        let width = plus - minus;
        for r in 0..m {
            out[(r, c)] = (f_plus[r] - f_minus[r]) / width;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_on_quadratics_up_to_round_off() {
        // f = x0² + 3 x0 x1: central differences are exact for quadratics; only round-off remains.
        let f = |x: &[f64]| x[0] * x[0] + 3.0 * x[0] * x[1];
        let g = gradient(f, &[1.5, -2.0], 1e-3);
        assert!((g[0] - (3.0 - 6.0)).abs() < 1e-10);
        assert!((g[1] - 4.5).abs() < 1e-10);
        let j = jacobian(
            |x: &[f64], out: &mut [f64]| {
                out[0] = x[0] * x[1];
                out[1] = x[1] * x[1];
                out[2] = 2.0 * x[0];
            },
            &[2.0, 3.0],
            3,
            1e-3,
        );
        let expected = DMatrix::from_row_slice(3, 2, &[3.0, 2.0, 0.0, 6.0, 2.0, 0.0]);
        assert!((j - expected).amax() < 1e-10);
    }

    #[test]
    #[should_panic(expected = "step must be positive")]
    fn rejects_a_zero_step() {
        gradient(|x: &[f64]| x[0], &[1.0], 0.0);
    }
}
