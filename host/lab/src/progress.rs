//! How long work reports its progress. The library calls a [`Progress`]; the command line
//! draws it (a bar or a spinner); tests and quiet runs pass [`Silent`].

/// The progress of one long piece of work: how far it has got, and what it is doing now.
pub trait Progress: Sync {
    /// `done` of `total` steps are finished.
    fn position(&self, _done: u64, _total: u64) {}
    /// What the work is doing now, in a few words.
    fn message(&self, _what: &str) {}
}

/// Progress nobody watches.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {}
