//! The errors of the fluid: bad input, and a step that would leave the domain or go non-finite.

/// Everything the fluid can fail with. Each variant carries the offending value or index.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SphError {
    /// A parameter is out of its allowed range.
    #[error("{name} = {value} is out of range: must be {allowed}")]
    InvalidParameter {
        /// The parameter's name, as in [`crate::FluidParams`] or [`crate::FluidSetup`].
        name: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range, with its unit.
        allowed: &'static str,
    },
    /// A name (kernel, integrator, density method, walls) is not one of the known ones.
    #[error("unknown {what} {name:?}: expected one of {allowed}")]
    UnknownName {
        /// What was being named.
        what: &'static str,
        /// The name given.
        name: String,
        /// The known names.
        allowed: &'static str,
    },
    /// Only dimensions 2 and 3 are supported.
    #[error("dimension {0} is not supported: the fluid is 2D or 3D")]
    UnsupportedDimension(usize),
    /// The fluid has no particles.
    #[error("the fluid has no particles")]
    EmptyFluid,
    /// A per-particle list has the wrong length.
    #[error("{what} has {found} entries, expected {expected} (one per particle) or none")]
    LengthMismatch {
        /// The list.
        what: &'static str,
        /// The number of particles.
        expected: usize,
        /// Its length.
        found: usize,
    },
    /// An input value of a particle is NaN or infinite, or a density is not positive.
    #[error("{what} of particle {index} is {value}: must be finite (densities > 0)")]
    BadParticleValue {
        /// The quantity: `fluid position`, `fluid velocity`, `fluid density`, `boundary position`…
        what: &'static str,
        /// The particle's index in its list.
        index: usize,
        /// The offending component or value.
        value: f64,
    },
    /// A particle given at construction lies outside the domain.
    #[error("{what} {index} at {position:?} is outside the domain [{min:?}, {max:?}]")]
    OutsideDomain {
        /// `fluid particle` or `boundary particle`.
        what: &'static str,
        /// Its index in its list.
        index: usize,
        /// Its position (m).
        position: Vec<f64>,
        /// The domain's lower corner (m).
        min: Vec<f64>,
        /// The domain's upper corner (m).
        max: Vec<f64>,
    },
    /// The neighbour grid over the domain would be too large for the number of particles.
    #[error("the neighbour grid would have {cells} cells, more than the limit of {limit} for this many particles: the domain is too large for the smoothing length")]
    GridTooLarge {
        /// The number of cells asked for (saturated).
        cells: u128,
        /// The limit.
        limit: usize,
    },
    /// A user-forced time step exceeds the stability bound.
    #[error("the time step {step:e} s exceeds the stability bound {bound:e} s (CFL and force conditions) at t = {time} s")]
    StepAboveBound {
        /// The step asked for (s).
        step: f64,
        /// The bound (s).
        bound: f64,
        /// Simulated time (s).
        time: f64,
    },
    /// A step would move a fluid particle out of the domain; the state is left as before the step.
    #[error("step {step} (t = {time} s) would move fluid particle {index} out of the domain, to {position:?}")]
    LeftDomain {
        /// The fluid particle.
        index: usize,
        /// Where it would go (m).
        position: Vec<f64>,
        /// The number of the step that failed (1 for the first).
        step: u64,
        /// Simulated time before the step (s).
        time: f64,
    },
    /// A step would make a particle's position, velocity or density NaN, infinite or (density)
    /// non-positive; the state is left as before the step.
    #[error("step {step} (t = {time} s) would make the {what} of particle {index} {value}")]
    NonFiniteState {
        /// `position`, `velocity` or `density`.
        what: &'static str,
        /// The particle (fluid particles first, then boundary particles).
        index: usize,
        /// The offending value.
        value: f64,
        /// The number of the step that failed.
        step: u64,
        /// Simulated time before the step (s).
        time: f64,
    },
    /// The stable step collapsed (velocities or accelerations blew up).
    #[error("the stable time step collapsed to {bound:e} s at t = {time} s (below 1e-6 of the acoustic step {acoustic:e} s): the flow is unstable")]
    StepCollapsed {
        /// The bound (s).
        bound: f64,
        /// The acoustic step C·h/c₀ (s).
        acoustic: f64,
        /// Simulated time (s).
        time: f64,
    },
}
