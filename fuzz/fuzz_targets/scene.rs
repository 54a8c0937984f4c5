//! The scene-file parser on arbitrary text: a built scene or a typed error, never a panic, a hang
//! or an allocation sized by a number in the file.
//!
//! The file is anchored in a directory that does not exist, so relative mesh paths give an I/O
//! error rather than reading whatever the fuzzer's working directory holds.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = hooke_sim::file::parse_scene(text, Path::new("/nonexistent-hooke-fuzz/fuzz.toml"));
});
