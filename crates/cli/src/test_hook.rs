//! A test hook of `hooke run`, not for users: the environment variable `HOOKE_TEST_HALT` halts the
//! run at a named point, so that a test kills it exactly there instead of racing it for a moment.
//!
//! - `HOOKE_TEST_HALT=after-frame:K` halts right after frame K is written, with whatever is due at
//!   frame K (checkpoint, `timings.json`, periodic `summary.json`);
//! - `HOOKE_TEST_HALT=in-frame:K` halts in the middle of writing frame K: half of its bytes are in
//!   its temporary file, synced, and the file is not renamed onto `frame_K` (spring runs only; a
//!   fluid run halts only after a frame).
//!
//! At the point, the process prints `halted at after-frame:K` (or `in-frame:K`) on standard error
//! and then waits for its standard input to close, so a test that pipes standard input reads the
//! line and kills the process (a real kill). When standard input closes first (it is empty, or the
//! test went away) the process exits at once with status [`EXIT_CODE`], running no destructors:
//! what it leaves on disk is what a kill at that point leaves. tests/integration/resume.rs uses both.

use std::fmt;
use std::io::Read;

/// The environment variable.
pub(crate) const VARIABLE: &str = "HOOKE_TEST_HALT";

/// The exit status of a halted process whose standard input closed.
pub(crate) const EXIT_CODE: i32 = 70;

/// Where to halt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Halt {
    /// Right after frame K and what is due with it are written.
    AfterFrame(usize),
    /// Halfway through writing frame K's temporary file.
    InFrame(usize),
}

impl fmt::Display for Halt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Halt::AfterFrame(k) => write!(f, "after-frame:{k}"),
            Halt::InFrame(k) => write!(f, "in-frame:{k}"),
        }
    }
}

impl Halt {
    /// The halt [`VARIABLE`] asks for, if it is set.
    ///
    /// # Errors
    /// What is wrong with a value that is not `after-frame:K` or `in-frame:K` (K a frame number).
    pub(crate) fn from_env() -> Result<Option<Halt>, String> {
        match std::env::var(VARIABLE) {
            Err(std::env::VarError::NotPresent) => Ok(None),
            Err(e) => Err(e.to_string()),
            Ok(text) => text.parse().map(Some),
        }
    }

    /// Halt here (see the [module documentation](self)).
    pub(crate) fn halt(self) -> ! {
        eprintln!("halted at {self}");
        // Whatever ends the wait, the process goes without unwinding, as a killed one would.
        let _ = std::io::stdin().lock().read_to_end(&mut Vec::new());
        std::process::exit(EXIT_CODE)
    }
}

impl std::str::FromStr for Halt {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let bad = || format!("{text:?}: expected after-frame:K or in-frame:K, K a frame number");
        let (point, frame) = text.split_once(':').ok_or_else(bad)?;
        let frame: usize = frame.parse().map_err(|_| bad())?;
        match point {
            "after-frame" => Ok(Halt::AfterFrame(frame)),
            "in-frame" => Ok(Halt::InFrame(frame)),
            _ => Err(bad()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_parse_and_print_back() {
        for text in ["after-frame:12", "in-frame:0"] {
            assert_eq!(text.parse::<Halt>().unwrap().to_string(), text);
        }
        for text in [
            "",
            "in-frame",
            "in-frame:-1",
            "in-frame:x",
            "before-frame:3",
        ] {
            let e = text.parse::<Halt>().unwrap_err();
            assert!(e.contains("after-frame:K"), "{e}");
        }
    }
}
