//! # hooke-assembly
//!
//! Everything the integrators and solvers need from the physics of springs: per-spring energies and
//! forces and their derivatives ([`spring`]), their sums over a mesh ([`forces`]), parallel and
//! deterministic, the sparse Hessian of the implicit Euler objective in faer's CSC format with a
//! fixed pattern refilled in place ([`hessian`]), the fixed-vertex reduction ([`FreeDofs`]), the
//! projective dynamics matrices with their Kronecker structure kept ([`pd`]), pinned vertices held
//! by counter-forces on all DOFs instead ([`CounterForce`]), contact with static obstacles for the
//! implicit solvers, IPC's log barrier and smooth lagged friction per vertex ([`barrier`]), the
//! barrier on a triangle surface's pairs and against spheres ([`surface_barrier`]) summed over a
//! surface for self-contact ([`self_contact`]) with its pairs' lagged friction ([`self_friction`]), and
//! central finite differences to check them ([`fd`]). With the cargo features `nalgebra-sparse` and `sprs`,
//! `interop` converts the assembled matrices to those crates' CSC types.
//!
//! Units: metres, kilograms, seconds; stiffness in N/m, energy in J, force in N.
#![deny(missing_docs)]

pub mod barrier;
mod counter_force;
mod definite;
mod dofs;
mod error;
pub mod fd;
pub mod forces;
mod graph;
pub mod hessian;
#[cfg(any(feature = "nalgebra-sparse", feature = "sprs"))]
pub mod interop;
pub mod pd;
mod schedule;
pub mod self_contact;
pub mod self_friction;
pub mod spring;
pub mod surface_barrier;

pub use counter_force::CounterForce;
pub use dofs::FreeDofs;
pub use error::AssemblyError;
pub use hessian::{HessianParams, HessianPattern, HessianWorkspace};
pub use pd::LaplacianPattern;

pub use forces::{
    deterministic_sum, deterministic_sum_lanes, max_stretch, spring_energy, Dashpot, Incidence,
    SpringForces,
};
pub use spring::Definiteness;
