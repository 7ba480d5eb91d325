//! What the tool says on stderr besides its errors: warnings, notes and where its outputs
//! went. `--quiet` silences all of it; errors are always said.

use std::fmt::Display;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

static QUIET: AtomicBool = AtomicBool::new(false);

/// Silence (or not) warnings and notes for the rest of the process (`--quiet`).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether `--quiet` was given.
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// `warning: MESSAGE` on stderr, unless `--quiet`.
pub fn warning(message: impl Display) {
    line(format_args!("warning: {message}"));
}

/// A line on stderr (a note, where an output went), unless `--quiet`. A closed stderr is
/// no reason to fail.
pub fn line(text: impl Display) {
    if !quiet() {
        let _ = writeln!(std::io::stderr(), "{text}");
    }
}
