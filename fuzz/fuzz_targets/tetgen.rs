//! The TetGen `.node`/`.ele` reader on arbitrary text: the input is split at its first NUL byte
//! into the `.node` text and the `.ele` text (the seeds in `scripts/fuzz.sh` are built that way).
//! An `Ok` mesh or a typed error, never a panic or a hang.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (node, ele) = match data.iter().position(|&b| b == 0) {
        Some(cut) => (&data[..cut], &data[cut + 1..]),
        None => (data, &[][..]),
    };
    // The reader takes text (the files are read as UTF-8); other bytes are not its input.
    let (Ok(node), Ok(ele)) = (std::str::from_utf8(node), std::str::from_utf8(ele)) else {
        return;
    };
    let _ = hooke_mesh::io::parse_tetgen(node, ele, Path::new("fuzz.node"));
});
