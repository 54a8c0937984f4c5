//! The fluid crate's tests, one test binary (each module was a binary of its own). Run one module
//! with `cargo test -p hooke-sph --test integration -- MODULE::`.

mod brute_force;
mod fluid;
mod validation;
