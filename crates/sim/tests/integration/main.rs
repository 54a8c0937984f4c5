//! The simulation crate's tests, one test binary (each module was a binary of its own, linking the
//! whole solver stack again). The allocation tests stay a binary of their own
//! (tests/allocations.rs): they count the whole process's allocations. Run one module with
//! `cargo test -p hooke-sim --test integration -- MODULE::`.

mod pd_factored_integrators;
mod robust;
mod solids_from_surfaces;
