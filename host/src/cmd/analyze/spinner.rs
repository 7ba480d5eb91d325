//! The spinner `cta analyze` draws while it fits.

use std::time::Duration;

use cta_lab::progress::Progress;
use indicatif::{ProgressBar, ProgressStyle};

/// A spinner with the elapsed time, the fits so far and what was fitted last (hidden when
/// quiet).
pub struct Spinner(ProgressBar);

impl Spinner {
    /// A spinner on stderr, or a hidden one when `quiet`.
    pub fn new(quiet: bool) -> Self {
        if quiet {
            return Spinner(ProgressBar::hidden());
        }
        let b = ProgressBar::new_spinner();
        b.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {pos} fits  {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        b.enable_steady_tick(Duration::from_millis(120));
        Spinner(b)
    }

    /// Show `msg` beside the spinner.
    pub fn set_message(&self, msg: String) {
        self.0.set_message(msg);
    }

    /// Run `f` (which writes to the terminal) with the spinner out of the way.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.0.suspend(f)
    }

    /// Remove the spinner.
    pub fn finish_and_clear(&self) {
        self.0.finish_and_clear();
    }
}

impl Progress for Spinner {
    fn position(&self, done: u64, _total: u64) {
        self.0.set_position(done);
    }

    fn message(&self, what: &str) {
        self.0.set_message(what.to_string());
    }
}
