//! # hooke
//!
//! Mass-spring simulation (cloth, elastic solids, hair) with implicit solvers built on sparse linear
//! algebra. This crate is a thin facade over the workspace's crates, one module each:
//!
//! - [`mesh`]: triangle and tetrahedral meshes, spring graphs, lumped masses, generators, mesh files;
//! - [`collision`]: distances between a surface's primitives with their derivatives, the broad
//!   phase and continuous collision detection, under self-contact;
//! - [`assembly`]: spring energies, forces and their derivatives, contact barriers;
//! - [`solvers`]: linear and nonlinear solvers;
//! - [`sim`]: scenes, forces, damping, contact and time integration;
//! - [`sph`]: weakly compressible SPH fluids, independent of the spring crates.
//!
//! The `hooke` command-line program (scenes, runs, frames, summaries, previews, `hooke bench`) is the
//! `hooke-cli` crate, built only with the `cli` feature (on by default). A program that embeds the
//! library depends on
//!
//! ```toml
//! hooke = { version = "0.1", default-features = false }
//! ```
//!
//! and compiles no command-line, progress-bar, plotting or JSON crate. [`nalgebra`] is re-exported so
//! that vectors built by the caller have the version the library uses.
#![deny(missing_docs)]

pub use nalgebra;

pub use hooke_assembly as assembly;
pub use hooke_collision as collision;
pub use hooke_mesh as mesh;
pub use hooke_sim as sim;
pub use hooke_solvers as solvers;
pub use hooke_sph as sph;
