//! The run directory's layout: the names of its files, and where a recovery keeps what it
//! cuts. The store writes them; every other reader asks here.

use std::path::{Path, PathBuf};

/// The plan, as the run uses it.
pub const PLAN: &str = "plan.toml";
/// The measurement file.
pub const DATA: &str = "data.csv";
/// The event journal.
pub const JOURNAL: &str = "journal.jsonl";
/// The manifest.
pub const MANIFEST: &str = "manifest.json";
/// The lock file: the pid of the process using the run, `flock`ed while it runs.
pub const LOCK: &str = "sweep.lock";
/// The truth behind a simulated run's data (written at every session of one).
pub const TRUTH: &str = "data.truth.json";
/// In a recovery folder: the journal lines cut.
pub const JOURNAL_TAIL: &str = "journal-tail.jsonl";
/// In a recovery folder: the data bytes cut.
pub const DATA_TAIL: &str = "data-tail.csv";

/// The folder a recovery of `dir` moves what it cuts to: `recovered-N`, the first N not taken.
pub(crate) fn recovery_folder(dir: &Path) -> PathBuf {
    (1..)
        .map(|n| dir.join(format!("recovered-{n}")))
        .find(|p| !p.exists())
        .expect("a free name")
}
