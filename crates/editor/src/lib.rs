//! # hooke-editor
//!
//! The interactive 2D mass-spring editor of seed 004 (SPEC §7) as a deterministic state machine.
#![deny(missing_docs)]
