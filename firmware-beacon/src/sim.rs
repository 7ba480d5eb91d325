//! The simulated beacon board (feature `sim`): the same [`Board`] and [`Modulator`] as the
//! firmware, running on a host thread behind a pseudo-terminal, so the host talks to it
//! exactly as to the real board over RS-232.
//!
//! ```no_run
//! let sim = cta_firmware_beacon::sim::SimBoard::spawn().unwrap();
//! println!("simulated beacon board on {}", sim.path());
//! // open sim.path() with any serial-port client...
//! ```

use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cta_core::schedule::{Levels, Modulator, NORTHSTAR_TABLE_MHZ, TICK_HZ};
use cta_core::wire::{ResetCause, MAX_FRAME};
use serialport::{SerialPort, TTYPort};

use crate::board::Board;
use crate::pins::{BEACON_LINES, PORTS};

/// What the simulated board's outputs look like right now (for tests and the CLI).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Snapshot {
    /// Port levels (bit set = LED lit), ports A..G.
    pub levels: [u16; PORTS],
    /// Modulator ticks run so far.
    pub ticks: u64,
}

/// A running simulated beacon board.
pub struct SimBoard {
    path: String,
    stop: Arc<AtomicBool>,
    snapshot: Arc<Mutex<Snapshot>>,
    thread: Option<JoinHandle<io::Result<()>>>,
}

impl SimBoard {
    /// Start the simulated board on a new pseudo-terminal; [`SimBoard::path`] is the device
    /// to open (e.g. `/dev/pts/3`).
    pub fn spawn() -> io::Result<SimBoard> {
        let (mut master, slave) = TTYPort::pair().map_err(io::Error::other)?;
        let path = slave
            .name()
            .ok_or_else(|| io::Error::other("pseudo-terminal has no name"))?;
        master
            .set_timeout(Duration::from_millis(5))
            .map_err(io::Error::other)?;
        let stop = Arc::new(AtomicBool::new(false));
        let snapshot = Arc::new(Mutex::new(Snapshot {
            levels: [0; PORTS],
            ticks: 0,
        }));
        let (stop2, snap2) = (stop.clone(), snapshot.clone());
        let thread = std::thread::Builder::new()
            .name("sim-beacon".into())
            .spawn(move || {
                // Keep the slave end open so the master never sees a hang-up while the
                // host reopens the port.
                let _slave = slave;
                run(&mut master, &stop2, &snap2)
            })?;
        Ok(SimBoard {
            path,
            stop,
            snapshot,
            thread: Some(thread),
        })
    }

    /// Path of the pseudo-terminal the host should open.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Current outputs.
    pub fn snapshot(&self) -> Snapshot {
        *self.snapshot.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Stop the board and return its thread's result.
    pub fn stop(mut self) -> io::Result<()> {
        self.shutdown()
    }

    fn shutdown(&mut self) -> io::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.thread.take() {
            Some(t) => t
                .join()
                .unwrap_or_else(|_| Err(io::Error::other("simulated board thread panicked"))),
            None => Ok(()),
        }
    }
}

impl Drop for SimBoard {
    fn drop(&mut self) {
        let _ = self.shutdown();
    }
}

fn run(port: &mut TTYPort, stop: &AtomicBool, snapshot: &Mutex<Snapshot>) -> io::Result<()> {
    // Every table in NORTHSTAR_TABLE_MHZ is valid.
    let mut modulator = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES)
        .map_err(|e| io::Error::other(format!("{e:?}")))?;
    let mut board = Board::new(true, ResetCause::PowerOn);
    board.start(&mut modulator);
    let t0 = Instant::now();
    let mut ticks: u64 = 0;
    let mut rx = [0u8; 256];
    let mut tx = [0u8; MAX_FRAME];
    while !stop.load(Ordering::Relaxed) {
        let n = match port.read(&mut rx) {
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::TimedOut => 0,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => 0,
            Err(e) => return Err(e),
        };
        let now = t0.elapsed();
        let now_ms = now.as_millis() as u64;
        for &b in &rx[..n] {
            if let Some(frame) = board.feed(b, now_ms, &mut modulator, &mut tx) {
                match port.write_all(frame) {
                    Ok(()) => {}
                    // The host is not reading its replies (the pty's buffer is full): as on a
                    // UART the reply is lost and the board goes on, never stops answering.
                    Err(e)
                        if matches!(
                            e.kind(),
                            io::ErrorKind::TimedOut
                                | io::ErrorKind::WouldBlock
                                | io::ErrorKind::Interrupted
                        ) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        board.poll(now_ms, &mut modulator);
        // Run the modulator in step with the wall clock (at most 0.1 s behind).
        let due = (now.as_micros() as u64 * TICK_HZ as u64) / 1_000_000;
        ticks = ticks.max(due.saturating_sub(TICK_HZ as u64 / 10));
        while ticks < due {
            modulator.tick(&mut Levels::default());
            ticks += 1;
        }
        if let Ok(mut s) = snapshot.lock() {
            *s = Snapshot {
                levels: modulator.levels(),
                ticks,
            };
        }
    }
    Ok(())
}
