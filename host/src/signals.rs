//! Stopping cleanly on Ctrl-C, SIGTERM and SIGHUP: the first signal sets a flag the command
//! checks, a second one leaves at once with 128 + the signal. On Windows, Ctrl-C (SIGINT) and
//! SIGTERM (the C runtime's; Ctrl-C is what a console sends): SIGHUP is Unix only.

use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::Arc;

use signal_hook::consts::{SIGINT, SIGTERM};

/// The signals that stop a command cleanly on this system.
#[cfg(unix)]
const STOPS: [i32; 3] = [SIGINT, SIGTERM, signal_hook::consts::SIGHUP];
/// The signals that stop a command cleanly on this system (no SIGHUP outside Unix).
#[cfg(not(unix))]
const STOPS: [i32; 2] = [SIGINT, SIGTERM];

/// Whether `sig` is ignored (SIG_IGN), as `nohup` leaves SIGHUP.
#[cfg(unix)]
fn ignored(sig: libc::c_int) -> bool {
    // SAFETY: a read-only sigaction query into a zeroed struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}

/// Whether `sig` is ignored: nothing leaves a signal ignored for a child outside Unix.
#[cfg(not(unix))]
fn ignored(_sig: i32) -> bool {
    false
}

/// Catch SIGINT (Ctrl-C), SIGTERM (`kill`, systemd, `docker stop`) and SIGHUP (a closed
/// terminal or SSH session; Unix only) with `signal_hook`'s flag handlers: the first sets
/// `stop` (and `which` to the signal's number, when given), a second one leaves at once with
/// 128 + the signal. A signal ignored at the start stays ignored: under `nohup` a hang-up does
/// not stop the command. Returns the signals that could not be caught, with why.
pub fn catch_stop(
    stop: &Arc<AtomicBool>,
    which: Option<&Arc<AtomicUsize>>,
) -> Vec<(i32, std::io::Error)> {
    use signal_hook::flag;
    let mut failed = Vec::new();
    for sig in STOPS {
        if ignored(sig) {
            continue;
        }
        // In this order: the second signal finds the flag set and exits; the first sets it.
        let registered = flag::register_conditional_shutdown(sig, 128 + sig, Arc::clone(stop))
            .and_then(|_| match which {
                Some(w) => flag::register_usize(sig, Arc::clone(w), sig as usize).map(|_| ()),
                None => Ok(()),
            })
            .and_then(|_| flag::register(sig, Arc::clone(stop)));
        if let Err(e) = registered {
            failed.push((sig, e));
        }
    }
    failed
}

#[cfg(test)]
mod tests {
    /// The numbers signal_hook registers are the ones the sweep journals and exits with
    /// (cta_lab's): a Ctrl-C must read as Ctrl-C in the journal and give 130.
    #[test]
    fn the_caught_signals_are_the_ones_a_sweep_names() {
        use cta_lab::sweep::signals as lab;
        assert_eq!(super::STOPS[0], lab::SIGINT);
        assert_eq!(super::STOPS[1], lab::SIGTERM);
        #[cfg(unix)]
        assert_eq!(super::STOPS[2], lab::SIGHUP);
    }
}
