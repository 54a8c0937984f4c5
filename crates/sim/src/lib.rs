//! # hooke-sim
//!
//! Scenes, forces, damping, contact and time integration for hooke.
//!
//! A [`Scene`] holds a validated mesh with its pins, external forces, damping, contact and time
//! step; a [`Simulation`] steps it from a [`State`] with an [`Integrator`]. The canonical scenes of
//! docs/scenes.md are built by [`scenes::builtin`], and scene files are read by
//! [`file::load_scene`].
//!
//! Units: metres, kilograms, seconds (N, N/m, N·s/m, J).
//!
//! ```
//! use hooke_sim::{scenes, Simulation};
//!
//! let setup = scenes::cloth(10, false)?; // cloth-10, k = 1e3 N/m
//! let mut sim = Simulation::new(setup.scene, setup.initial, setup.settings)?;
//! let before = sim.energy().total;
//! for _ in 0..5 {
//!     sim.step()?;
//! }
//! // The cloth falls: potential energy turns into motion; nothing is NaN.
//! assert!(sim.state().positions.iter().all(|p| p.y <= 1e-12));
//! assert!(sim.energy().total.is_finite() && before.is_finite());
//! # Ok::<(), hooke_sim::SimError>(())
//! ```
#![deny(missing_docs)]

pub mod contact_model;
pub mod damping;
mod error;
pub mod file;
pub mod forces;
mod implicit;
pub mod integrator;
mod linearized;
mod projection;
mod scene;
pub mod scenes;
mod simulation;
pub mod stability;

pub use contact_model::{AdaptiveStiffness, BarrierSettings, Contact, SelfContact, Shape};
pub use damping::Damping;
pub use error::{SimError, SolverFailure};
pub use forces::ExternalForce;
pub use implicit::RateSource;
pub use integrator::{
    parse_energy_limit, Integrator, LinearSolver, LinearizedParams, PinMethod, RelaxationPreset,
    Settings, SolverOptions, UnknownPinMethod, UnknownRelaxation,
};
pub use scene::{Energy, Keyframe, MovingPins, PinPath, Pins, Rotation, Scene, State};
pub use simulation::{HalvingMemory, Simulation, Snapshot, StepReport, MAX_AUTO_SUBSTEPS};
pub use stability::{stability_bound, StabilityBound};
