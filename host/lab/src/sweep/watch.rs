//! What a running sweep tells whoever watches it. The command line draws progress bars or
//! writes log lines from these calls; a library caller may show nothing ([`Unwatched`]).

use std::path::Path;

use super::plan::Plan;
use super::points::Point;

/// The sweep's progress and events as they happen. Every method does nothing by default.
pub trait Watch {
    /// The session starts at point `from` of `plan`.
    fn start(&self, _plan: &Plan, _from: usize) {}
    /// Point `p` begins a separation.
    fn separation(&self, _plan: &Plan, _p: &Point) {}
    /// Point `i` of `plan`, at `separation` inches, is committed.
    fn point_done(&self, _plan: &Plan, _i: usize, _separation: f64) {}
    /// What the run is waiting on now, such as a board's recovery; empty when nothing.
    fn message(&self, _m: &str) {}
    /// A line of the run's log: the start, each fault, retry and reconnection, the stop.
    fn log(&self, _line: &str) {}
    /// A note on the run directory `dir`, such as what a resume repaired.
    fn note(&self, _dir: &Path, _note: &str) {}
    /// Something went wrong that does not stop the command, such as a stop recorded only in
    /// part.
    fn warning(&self, _w: &str) {}
}

/// A watcher that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unwatched;

impl Watch for Unwatched {}
