//! # hooke-sph
//!
//! Weakly compressible smoothed particle hydrodynamics (SPEC §7), beside the spring crates and
//! independent of them.
#![deny(missing_docs)]
