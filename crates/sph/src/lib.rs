//! # hooke-sph
//!
//! Weakly compressible smoothed particle hydrodynamics (docs/sph.md), beside the spring crates and
//! independent of them: 2D and 3D through one generic code (`const D: usize`).
//!
//! - [`Kernel`]: the cubic spline or Wendland's quintic, normalised per dimension, with analytic
//!   gradients;
//! - [`NeighbourGrid`]: a uniform grid of cells one support radius wide, particles sorted by cell
//!   with a counting sort, so that a step costs O(n);
//! - [`Fluid`]: density by summation (or the continuity equation), the Tait equation of state, the
//!   symmetric pressure force, Monaghan's artificial viscosity and gravity; symplectic Euler or
//!   leapfrog with the step from the CFL and force conditions; walls of boundary particles or a
//!   clamp onto the domain's faces; typed errors ([`SphError`]) for bad input and for a step that
//!   would leave the domain or go non-finite;
//! - [`scenes`]: docs/scenes.md §7's `dam-break-2d`, `hydrostatic-2d` and `dam-break-3d`.
//!
//! ```
//! use hooke_sph::{scenes, Fluid};
//! let scene = scenes::dam_break_2d(0.1)?;
//! let mut fluid = Fluid::new(scene.setup)?;
//! fluid.advance_to(0.02)?;
//! let front = fluid.front(0, 3).unwrap();
//! assert!(front >= 0.9 && front < 4.0);
//! # Ok::<(), hooke_sph::SphError>(())
//! ```
#![deny(missing_docs)]

mod error;
mod fluid;
mod grid;
mod kernel;
mod params;
pub mod scenes;

pub use error::SphError;
pub use fluid::{AdvanceReport, Evaluated, Fluid, PhaseTimings, StepReport};
pub use grid::NeighbourGrid;
pub use kernel::{Kernel, KernelKind};
pub use params::{DensityMethod, FluidParams, FluidSetup, Integrator, Walls};
