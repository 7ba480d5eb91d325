//! Stopping cleanly on Ctrl-C, SIGTERM and SIGHUP: the first signal sets a flag the command
//! checks, a second one leaves at once with 128 + the signal.

use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::Arc;

/// Whether `sig` is ignored (SIG_IGN), as `nohup` leaves SIGHUP.
fn ignored(sig: libc::c_int) -> bool {
    // SAFETY: a read-only sigaction query into a zeroed struct.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}

/// Catch SIGINT (Ctrl-C), SIGTERM (`kill`, systemd, `docker stop`) and SIGHUP (a closed
/// terminal or SSH session) with `signal_hook`'s flag handlers: the first sets `stop` (and
/// `which` to the signal's number, when given), a second one leaves at once with 128 + the
/// signal. A signal ignored at the start stays ignored: under `nohup` a hang-up does not stop
/// the command. Returns the signals that could not be caught, with why.
pub fn catch_stop(
    stop: &Arc<AtomicBool>,
    which: Option<&Arc<AtomicUsize>>,
) -> Vec<(i32, std::io::Error)> {
    use signal_hook::flag;
    let mut failed = Vec::new();
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
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
