//! Damping (docs/model.md §4): drag, viscous and dashpot.

use crate::error::{non_negative, SimError};

/// The damping of a scene. All coefficients default to 0 (no damping): a scene models only what it
/// declares.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Damping {
    /// Drag rate c_drag (1/s): after each velocity update v ← v e^(−h c_drag) (seed-2d uses 1).
    /// Applied exactly, so it never limits the time step.
    pub drag: f64,
    /// Viscous coefficient c (N·s/m): f_i = −c v_i on every vertex.
    pub viscous: f64,
    /// Dashpot coefficient c_d (N·s/m): f_i = −c_d ((v_i − v_j)·d) d along each spring, d its
    /// direction (seed-2d uses 100).
    pub dashpot: f64,
}

impl Damping {
    /// Check that every coefficient is finite and non-negative.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the coefficient.
    pub fn validate(&self) -> Result<(), SimError> {
        non_negative("damping.drag", self.drag)?;
        non_negative("damping.viscous", self.viscous)?;
        non_negative("damping.dashpot", self.dashpot)?;
        Ok(())
    }

    /// True if no coefficient is set.
    pub fn is_none(&self) -> bool {
        self.drag == 0.0 && self.viscous == 0.0 && self.dashpot == 0.0
    }
}
