//! # hooke-cli
//!
//! The `hooke` command-line program as a library: the command itself ([`main`]), the speed-against-error
//! benchmark behind `hooke bench` ([`bench`](mod@bench), docs/model.md §9), and what a run writes
//! to disk ([`output`]: frames, `summary.json`, `preview.png`, the progress bar). `hooke run` of a
//! fluid scene (`dam-break-2d`, `hydrostatic-2d`, `dam-break-3d`, or a scene file with a `[fluid]`
//! table) and `hooke bench --sph` run hooke-sph's weakly compressible SPH.
//!
//! It is the only crate of the workspace that depends on clap, indicatif, plotters and serde_json. A
//! program that embeds the simulation library depends on `hooke` with `default-features = false` and
//! compiles none of them; the `hooke` binary (the `cli` feature, on by default) is a one-line call of
//! [`main`].
#![deny(missing_docs)]

pub mod bench;
mod checkpoint;
mod command;
pub mod edit_command;
mod mesh_command;
pub mod output;
mod scene_arg;
mod sph;
mod test_hook;

pub use command::main;

// The workspace crates under the names the facade gives them, so that paths read as in user code.
use hooke_mesh as mesh;
use hooke_sim as sim;
use hooke_solvers as solvers;
