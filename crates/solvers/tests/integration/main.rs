//! The solver crate's tests, one test binary (each module was a binary of its own, and each of them
//! compiled and linked its own copy of the sparse factorisations: most of the crate's test build).
//! The allocation tests stay a binary of their own (tests/allocations.rs): they count the whole
//! process's allocations. Run one module with `cargo test -p hooke-solvers --test integration --
//! MODULE::`.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/sheets.rs"]
mod sheets;
#[path = "../waved_step/mod.rs"]
mod waved_step;

mod amg;
mod anderson;
mod backward_euler;
mod chebyshev;
mod cholesky;
mod definite;
mod factor_reuse;
mod iterative;
mod lbfgs;
mod memory_budget;
mod newton;
mod newton_cg;
mod params;
mod pd_multilevel;
mod relaxation;
mod self_contact_friction;
