//! Smoothing kernels W(r, h), normalised so that ∫ W dV = 1 in the dimension `D`, with analytic
//! derivatives.

use nalgebra::SVector;

use crate::SphError;

/// Which smoothing kernel to use. Both have compact support of radius 2h.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum KernelKind {
    /// The cubic B-spline of Monaghan & Lattanzio (1985), the usual WCSPH kernel.
    #[default]
    CubicSpline,
    /// Wendland's C² quintic, W ∝ (1 − q/2)⁴ (2q + 1): no pairing instability at large neighbour
    /// counts.
    WendlandQuintic,
}

impl KernelKind {
    /// The name used in scene files and summaries: `cubic-spline` or `wendland-quintic`.
    pub fn name(self) -> &'static str {
        match self {
            KernelKind::CubicSpline => "cubic-spline",
            KernelKind::WendlandQuintic => "wendland-quintic",
        }
    }
}

impl std::str::FromStr for KernelKind {
    type Err = SphError;

    fn from_str(s: &str) -> Result<Self, SphError> {
        match s {
            "cubic-spline" => Ok(KernelKind::CubicSpline),
            "wendland-quintic" => Ok(KernelKind::WendlandQuintic),
            _ => Err(SphError::UnknownName {
                what: "kernel",
                name: s.to_string(),
                allowed: "cubic-spline, wendland-quintic",
            }),
        }
    }
}

/// A kernel of a given kind and smoothing length h (m) in dimension `D` (2 or 3).
///
/// Values are in m⁻ᴰ, derivatives in m⁻ᴰ⁻¹. With q = r/h, the support is q < 2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kernel<const D: usize> {
    kind: KernelKind,
    h: f64,
    inv_h: f64,
    /// The normalisation constant divided by hᴰ.
    sigma: f64,
}

impl<const D: usize> Kernel<D> {
    /// A kernel of smoothing length `h` (m).
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] if `h` is not finite and positive;
    /// [`SphError::UnsupportedDimension`] unless `D` is 2 or 3.
    pub fn new(kind: KernelKind, h: f64) -> Result<Self, SphError> {
        if !(h.is_finite() && h > 0.0) {
            return Err(SphError::InvalidParameter {
                name: "smoothing_length",
                value: h,
                allowed: "finite and > 0 (m)",
            });
        }
        let pi = std::f64::consts::PI;
        let unit = match (kind, D) {
            (KernelKind::CubicSpline, 2) => 10.0 / (7.0 * pi),
            (KernelKind::CubicSpline, 3) => 1.0 / pi,
            (KernelKind::WendlandQuintic, 2) => 7.0 / (4.0 * pi),
            (KernelKind::WendlandQuintic, 3) => 21.0 / (16.0 * pi),
            _ => return Err(SphError::UnsupportedDimension(D)),
        };
        Ok(Kernel {
            kind,
            h,
            inv_h: 1.0 / h,
            sigma: unit / h.powi(D as i32),
        })
    }

    /// The kernel's kind.
    pub fn kind(&self) -> KernelKind {
        self.kind
    }

    /// The smoothing length h (m).
    pub fn smoothing_length(&self) -> f64 {
        self.h
    }

    /// The support radius 2h (m): W and its derivative vanish at and beyond it.
    pub fn support_radius(&self) -> f64 {
        2.0 * self.h
    }

    /// W(r) for a distance `r` ≥ 0 (m), in m⁻ᴰ.
    #[inline]
    pub fn value(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        match self.kind {
            KernelKind::CubicSpline => {
                if q < 1.0 {
                    self.sigma * (1.0 - 1.5 * q * q + 0.75 * q * q * q)
                } else if q < 2.0 {
                    let t = 2.0 - q;
                    self.sigma * 0.25 * t * t * t
                } else {
                    0.0
                }
            }
            KernelKind::WendlandQuintic => {
                if q < 2.0 {
                    let t = 1.0 - 0.5 * q;
                    let t2 = t * t;
                    self.sigma * t2 * t2 * (2.0 * q + 1.0)
                } else {
                    0.0
                }
            }
        }
    }

    /// dW/dr at `r` ≥ 0, in m⁻ᴰ⁻¹ (≤ 0: the kernel decreases outwards).
    #[inline]
    pub fn derivative(&self, r: f64) -> f64 {
        self.derivative_over_r(r) * r
    }

    /// (dW/dr)/r, in m⁻ᴰ⁻²: finite at r = 0, so that ∇W = (dW/dr / r) r⃗ needs no division by r.
    #[inline]
    pub fn derivative_over_r(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        let s = self.sigma * self.inv_h * self.inv_h;
        match self.kind {
            KernelKind::CubicSpline => {
                if q < 1.0 {
                    s * (-3.0 + 2.25 * q)
                } else if q < 2.0 {
                    let t = 2.0 - q;
                    -0.75 * s * t * t / q
                } else {
                    0.0
                }
            }
            KernelKind::WendlandQuintic => {
                if q < 2.0 {
                    let t = 1.0 - 0.5 * q;
                    -5.0 * s * t * t * t
                } else {
                    0.0
                }
            }
        }
    }

    /// ∇ᵢ W(|xᵢ − xⱼ|) for `rij` = xᵢ − xⱼ (m), in m⁻ᴰ⁻¹; zero at rij = 0.
    #[inline]
    pub fn gradient(&self, rij: &SVector<f64, D>) -> SVector<f64, D> {
        rij * self.derivative_over_r(rij.norm())
    }
}

/// A kernel's radial profile with its kind resolved and its constants precomputed, for the
/// neighbour loops: the same arithmetic as [`Kernel::value`] and [`Kernel::derivative_over_r`], bit
/// for bit, with the pieces of the cubic spline chosen by selects rather than branches (whether a
/// neighbour is inside q = 1 is unpredictable).
pub(crate) trait Profile: Copy + Send + Sync {
    /// W(r), as [`Kernel::value`].
    fn value(&self, r: f64) -> f64;
    /// (dW/dr)/r, as [`Kernel::derivative_over_r`].
    fn derivative_over_r(&self, r: f64) -> f64;
}

/// The cubic spline's [`Profile`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct CubicProfile {
    inv_h: f64,
    sigma: f64,
    /// σ/h², as `derivative_over_r` computes it.
    s: f64,
}

/// Wendland's quintic's [`Profile`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct WendlandProfile {
    inv_h: f64,
    sigma: f64,
    s: f64,
}

impl<const D: usize> Kernel<D> {
    /// The cubic spline's profile, if this is the cubic spline.
    pub(crate) fn cubic_profile(&self) -> Option<CubicProfile> {
        (self.kind == KernelKind::CubicSpline).then_some(CubicProfile {
            inv_h: self.inv_h,
            sigma: self.sigma,
            s: self.sigma * self.inv_h * self.inv_h,
        })
    }

    /// Wendland's quintic's profile, if this is Wendland's quintic.
    pub(crate) fn wendland_profile(&self) -> Option<WendlandProfile> {
        (self.kind == KernelKind::WendlandQuintic).then_some(WendlandProfile {
            inv_h: self.inv_h,
            sigma: self.sigma,
            s: self.sigma * self.inv_h * self.inv_h,
        })
    }
}

impl Profile for CubicProfile {
    #[inline(always)]
    fn value(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        let inner = self.sigma * (1.0 - 1.5 * q * q + 0.75 * q * q * q);
        let t = 2.0 - q;
        let outer = self.sigma * 0.25 * t * t * t;
        let w = if q < 2.0 { outer } else { 0.0 };
        if q < 1.0 {
            inner
        } else {
            w
        }
    }

    #[inline(always)]
    fn derivative_over_r(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        let s = self.s;
        let inner = s * (-3.0 + 2.25 * q);
        let t = 2.0 - q;
        let outer = -0.75 * s * t * t / q;
        let d = if q < 2.0 { outer } else { 0.0 };
        if q < 1.0 {
            inner
        } else {
            d
        }
    }
}

impl Profile for WendlandProfile {
    #[inline(always)]
    fn value(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        let t = 1.0 - 0.5 * q;
        let t2 = t * t;
        let w = self.sigma * t2 * t2 * (2.0 * q + 1.0);
        if q < 2.0 {
            w
        } else {
            0.0
        }
    }

    #[inline(always)]
    fn derivative_over_r(&self, r: f64) -> f64 {
        let q = r * self.inv_h;
        let t = 1.0 - 0.5 * q;
        let d = -5.0 * self.s * t * t * t;
        if q < 2.0 {
            d
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KINDS: [KernelKind; 2] = [KernelKind::CubicSpline, KernelKind::WendlandQuintic];

    /// ∫ W dV by the composite Simpson rule in r on a fine grid: 2D ∫ W 2πr dr, 3D ∫ W 4πr² dr.
    fn radial_integral<const D: usize>(k: &Kernel<D>) -> f64 {
        let n = 20_000;
        let b = k.support_radius();
        let dr = b / n as f64;
        let shell = |r: f64| {
            let area = if D == 2 {
                2.0 * std::f64::consts::PI * r
            } else {
                4.0 * std::f64::consts::PI * r * r
            };
            k.value(r) * area
        };
        let mut sum = shell(0.0) + shell(b);
        for i in 1..n {
            sum += shell(i as f64 * dr) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        sum * dr / 3.0
    }

    #[test]
    fn integrates_to_one() {
        for kind in KINDS {
            for h in [0.013, 1.0, 7.5] {
                // Simpson's error on a piecewise polynomial with kinks at q = 1 (on a node) is
                // O(dr⁴): far below 1e-9.
                let i2 = radial_integral(&Kernel::<2>::new(kind, h).unwrap());
                let i3 = radial_integral(&Kernel::<3>::new(kind, h).unwrap());
                assert!((i2 - 1.0).abs() < 1e-9, "{kind:?} 2D h={h}: {i2}");
                assert!((i3 - 1.0).abs() < 1e-9, "{kind:?} 3D h={h}: {i3}");
            }
        }
    }

    #[test]
    fn lattice_sum_is_one() {
        // Σⱼ Δx² W on a square lattice is a quadrature of ∫ W dA.
        for kind in KINDS {
            let h = 0.026;
            let dx = h / 1.3;
            let k = Kernel::<2>::new(kind, h).unwrap();
            let mut sum = 0.0;
            for i in -5..=5 {
                for j in -5..=5 {
                    sum += dx * dx * k.value((((i * i + j * j) as f64).sqrt()) * dx);
                }
            }
            // Wendland's quintic is wider in its core and sums less accurately at h = 1.3 Δx
            // (1.0105 here; it is usually run at h ≥ 1.5 Δx).
            let tolerance = match kind {
                KernelKind::CubicSpline => 1e-2,
                KernelKind::WendlandQuintic => 2e-2,
            };
            assert!((sum - 1.0).abs() < tolerance, "{kind:?}: {sum}");
        }
    }

    #[test]
    fn derivative_matches_finite_differences() {
        for kind in KINDS {
            let h = 0.3;
            let k = Kernel::<3>::new(kind, h).unwrap();
            let eps = 1e-6 * h;
            for i in 1..200 {
                let r = i as f64 * 0.01 * h;
                let fd = (k.value(r + eps) - k.value(r - eps)) / (2.0 * eps);
                // Central differences err by O(eps² W''') ~ 1e-12 of the scale σ/h; the kinks
                // at q = 1 and 2 are smooth to first order, so no point is skipped.
                let scale = k.value(0.0) / h;
                assert!(
                    (fd - k.derivative(r)).abs() < 1e-7 * scale,
                    "{kind:?} r = {r}: fd {fd} analytic {}",
                    k.derivative(r)
                );
            }
            assert_eq!(k.value(2.0 * h), 0.0);
            assert_eq!(k.derivative(2.0 * h), 0.0);
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        for kind in KINDS {
            let h = 0.05;
            let k = Kernel::<2>::new(kind, h).unwrap();
            let eps = 1e-7 * h;
            let scale = k.value(0.0) / h;
            for (a, b) in [(0.01, 0.02), (-0.03, 0.04), (0.07, -0.002), (0.0, 0.0999)] {
                let r = SVector::<f64, 2>::new(a, b);
                let g = k.gradient(&r);
                for axis in 0..2 {
                    let mut p = r;
                    let mut m = r;
                    p[axis] += eps;
                    m[axis] -= eps;
                    let fd = (k.value(p.norm()) - k.value(m.norm())) / (2.0 * eps);
                    assert!((fd - g[axis]).abs() < 1e-6 * scale, "{kind:?} {r:?}");
                }
            }
            assert_eq!(
                k.gradient(&SVector::<f64, 2>::zeros()),
                SVector::<f64, 2>::zeros()
            );
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                Kernel::<2>::new(KernelKind::CubicSpline, h),
                Err(SphError::InvalidParameter { .. })
            ));
        }
        assert!(matches!(
            Kernel::<1>::new(KernelKind::CubicSpline, 1.0),
            Err(SphError::UnsupportedDimension(1))
        ));
        assert!("gauss".parse::<KernelKind>().is_err());
        assert_eq!(
            "wendland-quintic".parse::<KernelKind>().unwrap(),
            KernelKind::WendlandQuintic
        );
    }

    #[test]
    fn profiles_match_the_kernel_bit_for_bit() {
        for h in [0.013, 0.026, 1.0, 7.5] {
            let k2 = Kernel::<2>::new(KernelKind::CubicSpline, h).unwrap();
            let k3 = Kernel::<3>::new(KernelKind::WendlandQuintic, h).unwrap();
            let (c, w) = (k2.cubic_profile().unwrap(), k3.wendland_profile().unwrap());
            assert!(k2.wendland_profile().is_none() && k3.cubic_profile().is_none());
            // Every r from 0 past the support, with the pieces' edges q = 1 and 2 and their
            // neighbouring floats.
            let mut points: Vec<f64> = (0..=5000).map(|i| i as f64 * 2.2 * h / 5000.0).collect();
            for edge in [h, 2.0 * h] {
                let bits = edge.to_bits();
                points.extend([edge, f64::from_bits(bits - 1), f64::from_bits(bits + 1)]);
            }
            for &x in &points {
                assert_eq!(c.value(x).to_bits(), k2.value(x).to_bits(), "h {h} r {x}");
                assert_eq!(
                    c.derivative_over_r(x).to_bits(),
                    k2.derivative_over_r(x).to_bits(),
                    "h {h} r {x}"
                );
                assert_eq!(w.value(x).to_bits(), k3.value(x).to_bits(), "h {h} r {x}");
                assert_eq!(
                    w.derivative_over_r(x).to_bits(),
                    k3.derivative_over_r(x).to_bits(),
                    "h {h} r {x}"
                );
            }
        }
    }
}
