//! The OBJ reader on arbitrary bytes: an `Ok` mesh or a typed error, never a panic or a hang.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hooke_mesh::io::parse_obj(data, Path::new("fuzz.obj"));
});
