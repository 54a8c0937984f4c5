//! The integration tests of the workspace, one test binary (each file below was a binary of its own,
//! and linking 21 of them against the whole workspace took minutes of every test build). Each
//! module is one area; run one with `cargo test --test integration -- MODULE::`.

mod bench_cli;
mod bench_contact;
mod bench_hard_cases;
mod bench_state;
mod bench_sweep;
mod bench_time_error;
mod cli;
mod cli_guidance;
mod command;
mod contact;
mod hard_cases;
mod implicit;
mod implicit_forces;
mod integrators;
mod memory_budget;
mod mesh_io;
mod mesh_properties;
mod moving_pins;
mod pin_methods;
mod readme_examples;
mod resume;
mod scenes;
mod self_contact;
mod self_contact_friction;
mod sph_cli;
mod tetrahedralize_cli;
mod threads;
