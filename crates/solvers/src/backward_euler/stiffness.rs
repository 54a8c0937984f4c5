//! IPC's adaptive barrier stiffness (Li et al. 2020, "Incremental Potential Contact", §4.3) for
//! backward Euler's contact terms, obstacles and self-contact alike: one dimensionless scale s ≥ 1
//! multiplies every barrier's stiffness (κ_v = s κ̂ m_v against obstacles, s κ between two parts
//! of the surface).
//!
//! This module owns the rule: the scale at a step's first iterate from the balance of the
//! gradients, and its doubling over the iterations where a gap keeps closing below a share of d̂.
//! The barriers it scales are the siblings' (`obstacles`, `self_contact`); the distances come from
//! them.

use crate::params::{real, ParamError};

/// The default [`AdaptiveStiffness::max_ratio`]: 10⁴. A pair held at a gap g by a force F under
/// the model's stiffness κ sits at about κ d̂²/F; the scale moves that gap up by as much as the
/// ratio (a cloth pulled onto a sphere by stiff springs, which rests nanometres from it under κ,
/// is held at micrometres).
pub const DEFAULT_MAX_STIFFNESS_RATIO: f64 = 1e4;

/// The default [`AdaptiveStiffness::gap_share`]: 10⁻³ of d̂ (1.4 µm at a 1 m cloth's default d̂).
pub const DEFAULT_GAP_SHARE: f64 = 1e-3;

/// IPC's adaptive barrier stiffness for the contact terms of a backward Euler step
/// ([`super::BackwardEulerStep::set_adaptive_stiffness`]): the barriers' stiffnesses, as the model
/// gives them, are a floor, and a scale s ∈ [1, `max_ratio`] multiplies them all.
///
/// - At each step's first iterate x⁰, s minimises |g + s ∇B|² (clamped to the range), with g the
///   gradient of Φ's other terms (inertia, springs, external forces) and ∇B that of h² times the
///   barriers at the model's stiffnesses: the barrier then balances what pushes the surfaces
///   together where contacts are already active. Without an active contact s = 1.
/// - After each accepted iterate, the smallest gap over every active pair and vertex–obstacle
///   contact, as a share of its d̂, is compared with the previous iterate's: when both are below
///   `gap_share` and it still closed, s doubles (up to `max_ratio`). The barrier is having
///   difficulty holding the surfaces apart at the current stiffness.
///
/// The scale starts afresh at every step from that step's state alone, so a run resumed from a
/// checkpoint takes the same scales as one that was not stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveStiffness {
    /// The largest scale s (dimensionless, finite, ≥ 1): the barriers' stiffness never exceeds this
    /// multiple of the model's. Default [`DEFAULT_MAX_STIFFNESS_RATIO`].
    pub max_ratio: f64,
    /// The gap, as a share of the barrier's reach d̂ (dimensionless, in (0, 1)), below which a
    /// gap that keeps closing doubles the scale. Default [`DEFAULT_GAP_SHARE`].
    pub gap_share: f64,
}

impl Default for AdaptiveStiffness {
    fn default() -> Self {
        AdaptiveStiffness {
            max_ratio: DEFAULT_MAX_STIFFNESS_RATIO,
            gap_share: DEFAULT_GAP_SHARE,
        }
    }
}

impl AdaptiveStiffness {
    /// Check the values.
    ///
    /// # Errors
    /// [`ParamError::Real`] naming the first value out of its range.
    pub fn validate(&self) -> Result<(), ParamError> {
        real(
            "AdaptiveStiffness::max_ratio",
            self.max_ratio,
            self.max_ratio.is_finite() && self.max_ratio >= 1.0,
            "finite and ≥ 1",
        )?;
        real(
            "AdaptiveStiffness::gap_share",
            self.gap_share,
            self.gap_share > 0.0 && self.gap_share < 1.0,
            "in (0, 1)",
        )
    }

    /// The scale that balances the barrier's gradient against the rest of Φ's: the s ∈ [1,
    /// `max_ratio`] nearest to the minimiser of |g + s b|², from the sums gᵀb (`rest_dot_barrier`)
    /// and bᵀb (`barrier_squared`). 1 where no barrier acts (bᵀb = 0) or the sums are not finite.
    pub fn balanced_scale(&self, rest_dot_barrier: f64, barrier_squared: f64) -> f64 {
        let s = -rest_dot_barrier / barrier_squared;
        if barrier_squared > 0.0 && s.is_finite() {
            s.clamp(1.0, self.max_ratio)
        } else {
            1.0
        }
    }
}

/// The scale during one step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StiffnessScale {
    pub(crate) settings: AdaptiveStiffness,
    /// The current scale s.
    pub(crate) scale: f64,
    /// The smallest gap as a share of d̂ (capped at 1) at the previous iterate.
    previous_gap: f64,
}

impl StiffnessScale {
    pub(crate) fn new(settings: AdaptiveStiffness) -> Self {
        StiffnessScale {
            settings,
            scale: 1.0,
            previous_gap: 1.0,
        }
    }

    /// Start a step at scale `scale` with the first iterate's relative gap `gap`.
    pub(crate) fn start(&mut self, scale: f64, gap: f64) {
        self.scale = scale;
        self.previous_gap = gap.min(1.0);
    }

    /// Record the relative gap `gap` of an accepted iterate; the new scale if it doubles.
    pub(crate) fn after_iterate(&mut self, gap: f64) -> Option<f64> {
        let gap = gap.min(1.0);
        let threshold = self.settings.gap_share;
        let closing = self.previous_gap < threshold && gap < threshold && gap < self.previous_gap;
        self.previous_gap = gap;
        if closing && self.scale < self.settings.max_ratio {
            self.scale = (2.0 * self.scale).min(self.settings.max_ratio);
            Some(self.scale)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_balance_is_clamped_to_the_range() {
        let a = AdaptiveStiffness::default();
        // g = −3 b: s = 3 balances exactly.
        assert_eq!(a.balanced_scale(-3.0, 1.0), 3.0);
        // A barrier pushing the same way as the rest: no scale below the model's.
        assert_eq!(a.balanced_scale(2.0, 1.0), 1.0);
        assert_eq!(a.balanced_scale(-1e9, 1.0), a.max_ratio);
        assert_eq!(a.balanced_scale(-1.0, 0.0), 1.0);
        assert_eq!(a.balanced_scale(f64::NAN, 1.0), 1.0);
    }

    #[test]
    fn the_scale_doubles_only_while_a_small_gap_keeps_closing() {
        let settings = AdaptiveStiffness {
            max_ratio: 4.0,
            gap_share: 1e-2,
        };
        let mut s = StiffnessScale::new(settings);
        s.start(1.0, 0.5);
        // Below the share but the previous gap was not: no change yet.
        assert_eq!(s.after_iterate(5e-3), None);
        // Closing further below it: double.
        assert_eq!(s.after_iterate(4e-3), Some(2.0));
        // Opening: no change.
        assert_eq!(s.after_iterate(4.5e-3), None);
        assert_eq!(s.after_iterate(1e-3), Some(4.0));
        // At the cap.
        assert_eq!(s.after_iterate(1e-4), None);
        assert_eq!(s.scale, 4.0);
    }

    #[test]
    fn settings_out_of_range_are_refused_by_name() {
        for (max_ratio, gap_share, field) in [
            (0.5, 1e-3, "AdaptiveStiffness::max_ratio"),
            (f64::INFINITY, 1e-3, "AdaptiveStiffness::max_ratio"),
            (10.0, 0.0, "AdaptiveStiffness::gap_share"),
            (10.0, 1.0, "AdaptiveStiffness::gap_share"),
            (10.0, f64::NAN, "AdaptiveStiffness::gap_share"),
        ] {
            let e = AdaptiveStiffness {
                max_ratio,
                gap_share,
            }
            .validate()
            .unwrap_err();
            assert_eq!(e.field(), field);
        }
        AdaptiveStiffness::default().validate().unwrap();
    }
}
