//! # hooke-mesh
//!
//! Meshes and spring graphs for hooke: triangle and tetrahedral meshes, springs from their edges
//! (and cloth bending springs), lumped masses, generators for the canonical scenes, mesh files, and
//! exact self-intersection checks of triangle surfaces ([`intersection`]).
//!
//! Units are SI throughout: metres, kilograms, seconds, newtons per metre.
//!
//! Every constructor and reader validates its input and returns a [`MeshError`] that names the
//! offending vertex, element, file or line; nothing here panics on bad data.
//!
//! ```
//! use hooke_mesh::generators::cloth;
//!
//! let mesh = cloth(40, 1e3)?; // the cloth-40 scene's mesh, k = 1e3 N/m
//! assert_eq!(mesh.vertex_count(), 1600);
//! assert_eq!(mesh.springs().len(), 9202);
//! assert!((mesh.total_mass() - 1.0).abs() < 1e-12);
//! # Ok::<(), hooke_mesh::MeshError>(())
//! ```
#![deny(missing_docs)]

mod elements;
mod error;
pub mod generators;
pub mod intersection;
pub mod io;
#[cfg(feature = "proptest-support")]
pub mod proptest_support;
mod spring_mesh;
pub mod stuffing;

pub use elements::{
    tetrahedron_signed_volume, triangle_area, TetMesh, TriMesh, Vec3, DEGENERACY_TOLERANCE,
};
pub use error::{ElementKind, MeshError};
pub use spring_mesh::{Bending, MassModel, Spring, SpringMesh, SpringMesh2, SpringMesh3};

/// A point or vector in 2D, in metres.
pub type Vec2 = nalgebra::Vector2<f64>;
