//! The terminal progress bar of a run.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

/// Template of the visible bar: elapsed time, bar, steps done, rate and estimated time left.
const TEMPLATE: &str =
    "{elapsed_precise} [{wide_bar:.cyan/blue}] {pos}/{len} steps  {per_sec}  ETA {eta}  {msg}";

/// A progress bar over `steps` steps, drawn on stderr.
///
/// The bar is hidden (every call on it is a cheap no-op) when `quiet` is set or when stderr is
/// not a terminal, so that logs and pipes stay clean. Advance it with
/// [`ProgressBar::inc`] and end it with [`ProgressBar::finish`] (or
/// [`ProgressBar::finish_and_clear`]).
pub fn progress_bar(steps: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        let bar = ProgressBar::hidden();
        bar.set_length(steps);
        return bar;
    }
    let bar = ProgressBar::new(steps);
    // The template is a constant, checked by a test; fall back to the default style regardless.
    if let Ok(style) = ProgressStyle::with_template(TEMPLATE) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn template_is_valid() {
        assert!(ProgressStyle::with_template(TEMPLATE).is_ok());
    }

    #[test]
    fn quiet_bar_is_hidden() {
        let bar = progress_bar(10, true);
        assert!(bar.is_hidden());
        bar.inc(3);
        assert_eq!(bar.position(), 3);
        bar.finish_and_clear();
    }
}
