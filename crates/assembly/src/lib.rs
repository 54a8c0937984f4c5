//! # hooke-assembly
//!
//! Everything the integrators and solvers need from the physics of springs: per-spring energies and
//! forces ([`spring`]) and their sums over a mesh ([`forces`]), parallel and deterministic.
//!
//! Units: metres, kilograms, seconds; stiffness in N/m, energy in J, force in N.
#![deny(missing_docs)]

pub mod forces;
pub mod spring;

pub use forces::{deterministic_sum, max_stretch, spring_energy, Dashpot, Incidence, SpringForces};
