//! The numbers of the signals that stop a sweep (Ctrl-C, SIGTERM, SIGHUP), as the journal and
//! the exit status (128 + the number) give them, on every system: the C library's on Unix; on
//! Windows the C runtime's SIGINT (2) and SIGTERM (15), which are POSIX's, and POSIX's SIGHUP
//! (1), which Windows never raises (a closed console window ends the process).

#[cfg(unix)]
pub use libc::{SIGHUP, SIGINT, SIGTERM};

/// Ctrl-C (Windows C runtime `signal.h`).
#[cfg(not(unix))]
pub const SIGINT: i32 = 2;
/// Termination request (Windows C runtime `signal.h`).
#[cfg(not(unix))]
pub const SIGTERM: i32 = 15;
/// Hang-up: POSIX's number, so a journal reads the same everywhere; never raised on Windows.
#[cfg(not(unix))]
pub const SIGHUP: i32 = 1;

#[cfg(test)]
mod tests {
    /// The numbers journals and exit statuses carry (128 + 2 after Ctrl-C, ...): POSIX's.
    #[test]
    fn the_numbers_are_posix() {
        assert_eq!((super::SIGHUP, super::SIGINT, super::SIGTERM), (1, 2, 15));
    }
}
