//! # hooke-collision
//!
//! The geometry of contact between moving triangle surfaces, below the energies that use it:
//!
//! - [`distance`]: point–triangle and edge–edge squared distances with the closest-feature
//!   classification, their exact gradients and Hessians, and the mollifier of nearly parallel
//!   edges;
//! - [`broad_phase`]: the candidate point–triangle and edge–edge pairs of a surface whose boxes
//!   (static or swept along a motion, grown by a reach) overlap;
//! - [`ccd`]: continuous collision detection of a pair moving along straight lines, conservative:
//!   it may stop short of the first contact, it never passes it;
//! - [`obstacle`]: static obstacles (half-spaces, outsides of spheres) with a point's signed
//!   distance, its derivatives and the time of impact of a straight move.
//!
//! The barrier energies built on these distances live in `hooke-assembly`, the line search that
//! the collision detection caps in `hooke-solvers`, and the wiring into scenes in `hooke-sim`.
//!
//! Units: metres; squared distances in m².
#![deny(missing_docs)]

pub mod broad_phase;
pub mod ccd;
pub mod distance;
pub mod obstacle;
