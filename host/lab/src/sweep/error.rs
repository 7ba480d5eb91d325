//! Why a sweep, a resume or a status could not go on. Every message names the file, port or
//! option at fault and, where there is one, what to do about it.

use std::fmt::Display;

use super::plan::PlanError;

/// A sweep's error. `{}` gives the message alone and the cause, when there is one, is its
/// `source`; `{:#}` gives the whole chain, `message: cause: cause`, as `anyhow` prints it.
#[derive(Debug)]
pub enum Error {
    /// A file or folder of the run, or a pseudo-terminal, could not be used: the path and
    /// what was tried, over the system's reason.
    Io {
        /// The path and what was tried, e.g. `run/data.csv: cannot write`.
        what: String,
        /// The system's reason.
        source: std::io::Error,
    },
    /// A JSON record of the run (journal, manifest, truth) could not be written or read.
    Json {
        /// The record and what was tried.
        what: String,
        /// The reason.
        source: serde_json::Error,
    },
    /// The plan file.
    Plan(PlanError),
    /// A system call with nothing to add to its reason, such as starting a thread.
    System(std::io::Error),
    /// A record that could not be encoded as JSON.
    Encode(serde_json::Error),
    /// The run cannot go on as asked: an option, the run directory's state or its files
    /// say no, and the message says why.
    Refused(String),
    /// A board failed, refused or was not the one the run was recorded on.
    Board(String),
    /// The operator gave no answer (stdin closed, or interrupted while asking).
    Operator(String),
    /// An error with what it happened in.
    Context {
        /// What was being done.
        context: String,
        /// What went wrong.
        source: Box<Error>,
    },
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Error::Io { what, .. } | Error::Json { what, .. } => f.write_str(what)?,
            Error::Plan(e) => write!(f, "{e}")?,
            Error::System(e) => write!(f, "{e}")?,
            Error::Encode(e) => write!(f, "{e}")?,
            Error::Refused(m) | Error::Board(m) | Error::Operator(m) => f.write_str(m)?,
            Error::Context { context, .. } => f.write_str(context)?,
        }
        if f.alternate() {
            let mut e: &dyn std::error::Error = self;
            while let Some(next) = e.source() {
                write!(f, ": {next}")?;
                e = next;
            }
        }
        Ok(())
    }
}

impl std::error::Error for Error {
    /// The cause: the system's or the parser's reason, or the error a context wraps. The
    /// plan's, the system's and the encoder's own errors are the message itself, so their
    /// cause is their own source.
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Json { source, .. } => Some(source),
            Error::Context { source, .. } => Some(source.as_ref()),
            Error::Plan(e) => e.source(),
            Error::System(e) => e.source(),
            Error::Encode(e) => e.source(),
            Error::Refused(_) | Error::Board(_) | Error::Operator(_) => None,
        }
    }
}

impl From<PlanError> for Error {
    fn from(e: PlanError) -> Self {
        Error::Plan(e)
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::System(e)
    }
}

impl From<serde_json::Error> for Error {
    fn from(e: serde_json::Error) -> Self {
        Error::Encode(e)
    }
}

/// A sweep's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Return a [`Error::Refused`] with a formatted message.
macro_rules! bail {
    ($($t:tt)*) => {
        return Err($crate::sweep::error::Error::Refused(format!($($t)*)))
    };
}
pub(crate) use bail;

/// What an error happened in, as `anyhow`'s `context` says it.
pub trait Context<T> {
    /// The error, with `what` was being done.
    fn context(self, what: impl Display) -> Result<T>;
    /// The error, with what was being done, computed only on error.
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T>;
}

impl<T> Context<T> for std::result::Result<T, std::io::Error> {
    fn context(self, what: impl Display) -> Result<T> {
        self.map_err(|source| Error::Io {
            what: what.to_string(),
            source,
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|source| Error::Io {
            what: what().to_string(),
            source,
        })
    }
}

impl<T> Context<T> for std::result::Result<T, serde_json::Error> {
    fn context(self, what: impl Display) -> Result<T> {
        self.map_err(|source| Error::Json {
            what: what.to_string(),
            source,
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|source| Error::Json {
            what: what().to_string(),
            source,
        })
    }
}

impl<T> Context<T> for std::result::Result<T, serialport::Error> {
    fn context(self, what: impl Display) -> Result<T> {
        self.map_err(|e| Error::Io {
            what: what.to_string(),
            source: e.into(),
        })
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| Error::Io {
            what: what().to_string(),
            source: e.into(),
        })
    }
}

impl<T> Context<T> for Result<T> {
    fn context(self, what: impl Display) -> Result<T> {
        self.map_err(|e| e.context(what))
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| e.context(what()))
    }
}

impl Error {
    /// This error, with what was being done.
    pub fn context(self, what: impl Display) -> Error {
        Error::Context {
            context: what.to_string(),
            source: Box::new(self),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chain reads as the command line prints it: the context first, then each cause.
    #[test]
    fn the_chain_reads_outside_in() {
        let io = std::io::Error::other("disk full");
        let e = Err::<(), _>(io)
            .context("run/data.csv: cannot write")
            .context("sweep stopped")
            .unwrap_err();
        assert_eq!(e.to_string(), "sweep stopped");
        assert_eq!(
            format!("{e:#}"),
            "sweep stopped: run/data.csv: cannot write: disk full"
        );
        let r: Result<()> = (|| bail!("{} of {}", 1, 2))();
        assert!(matches!(r, Err(Error::Refused(m)) if m == "1 of 2"));
    }
}
