//! # hooke
//!
//! Mass-spring simulation (cloth, elastic solids, hair) with implicit solvers built on sparse linear
//! algebra. This crate is a thin facade over the workspace's crates, one module each:
//!
//! - [`mesh`]: triangle and tetrahedral meshes, spring graphs, lumped masses, generators, mesh files;
//! - [`assembly`]: spring energies, forces and their derivatives;
//! - [`solvers`]: linear and nonlinear solvers;
//! - [`sim`]: scenes, forces, damping, contact and time integration;
//! - [`bench`](mod@bench): speed against error (SPEC §8), the library behind `hooke bench`.
//!
//! The `hooke` command-line program runs scenes and writes frames, a summary and a preview.
#![deny(missing_docs)]

pub mod bench;

pub use hooke_assembly as assembly;
pub use hooke_mesh as mesh;
pub use hooke_sim as sim;
pub use hooke_solvers as solvers;

/// The README's code blocks, compiled and run as doc tests so that the README stays true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
