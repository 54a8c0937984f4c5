//! Running the `hooke` binary from the tests: one copy of the helpers every command test uses.

use std::process::{Command, Output, Stdio};

/// Runs `hooke args` in the package root (where `data/` is), with no standard input, and waits.
pub fn hooke(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hooke"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::null())
        .output()
        .expect("the hooke binary runs")
}

/// The run's standard output as text.
pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The run's standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs `args`, which must fail with a message (no panic) containing every one of `needles`;
/// returns the message.
pub fn fails_with(args: &[&str], needles: &[&str]) -> String {
    let out = hooke(args);
    let text = stderr(&out);
    assert!(!out.status.success(), "{args:?} should fail:\n{text}");
    assert!(!text.contains("panicked"), "{args:?} panicked:\n{text}");
    for needle in needles {
        assert!(
            text.contains(needle),
            "{args:?}: {needle:?} not in:\n{text}"
        );
    }
    text
}
