//! The STL reader (ASCII and binary) on arbitrary bytes: an `Ok` mesh or a typed error, never a
//! panic or a hang.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hooke_mesh::io::parse_stl(data, Path::new("fuzz.stl"));
});
