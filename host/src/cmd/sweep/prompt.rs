//! The operator at the terminal: the manual steps of a run on hardware asked on stderr and
//! answered on stdin.

use std::io::{BufRead, IsTerminal, Write};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::Duration;

use cta_lab::sweep::corners::{CORNER_ORDER_TEXT, ROD_XY_IN};
use cta_lab::sweep::engine::{Operator, INTERRUPTED};
use cta_lab::sweep::points::Point;
use cta_lab::sweep::sim::separation_entry;
use cta_lab::sweep::store::{levelness_question, SeparationEntry};
use cta_lab::sweep::{Error, Result};

use super::Bars;

/// The controlling terminal, where a question is also asked when stderr is not it.
#[cfg(not(windows))]
const TERMINAL: &str = "/dev/tty";
/// The console, where a question is also asked when stderr is not it.
#[cfg(windows)]
const TERMINAL: &str = "CONOUT$";

/// Prompts on the terminal (stderr) and reads the answers from stdin.
///
/// Stdin is read on a helper thread, one line at a time, so that a wait for the operator can
/// be interrupted: Ctrl-C (or SIGTERM, SIGHUP) at a prompt stops the run at once, and nothing
/// is recorded for that prompt.
pub struct Prompt {
    /// Progress bars to hide while asking (and the log, when stderr is not a terminal).
    bars: Bars,
    /// Lines of stdin (`None`: end of input), from the reader thread started at the first
    /// question.
    lines: Option<Receiver<std::io::Result<Option<String>>>>,
}

impl Prompt {
    /// Prompts hiding `bars` while they ask.
    pub fn new(bars: &Bars) -> Prompt {
        Prompt {
            bars: bars.clone(),
            lines: None,
        }
    }

    fn ask(&mut self, question: &str) -> Result<String> {
        let lines = self.lines.get_or_insert_with(|| {
            let (tx, rx) = mpsc::channel();
            std::thread::spawn(move || loop {
                let mut s = String::new();
                let r = std::io::stdin().lock().read_line(&mut s);
                let end = !matches!(r, Ok(n) if n > 0);
                if tx.send(r.map(|n| (n > 0).then_some(s))).is_err() || end {
                    break;
                }
            });
            rx
        });
        let log = self.bars.log_prefix();
        self.bars.multi.suspend(|| {
            match log {
                // Not on a terminal: the question is a line of the log.
                Some(prefix) => eprintln!("{prefix} waiting for the operator: {}", question.trim()),
                None => eprint!("{question}"),
            }
            // Asked on the controlling terminal too, if there is one, when stderr is not it:
            // `cta sweep ... 2>log` must not wait on a question nobody sees.
            if !std::io::stderr().is_terminal() {
                if let Ok(mut tty) = std::fs::OpenOptions::new().write(true).open(TERMINAL) {
                    let _ = write!(tty, "{question}");
                }
            }
            let _ = std::io::stderr().flush();
            loop {
                if INTERRUPTED.load(Ordering::SeqCst) {
                    eprintln!();
                    return Err(Error::Operator(
                        "interrupted while waiting for the operator".into(),
                    ));
                }
                match lines.recv_timeout(Duration::from_millis(50)) {
                    Ok(Ok(Some(s))) => return Ok(s.trim().to_string()),
                    Ok(Err(e)) => {
                        return Err(Error::Operator(format!(
                            "cannot read the operator's answer: {e}"
                        )))
                    }
                    Ok(Ok(None)) | Err(RecvTimeoutError::Disconnected) => {
                        return Err(Error::Operator(
                            "stdin closed while waiting for the operator (use --yes for scripted \
                             runs)"
                                .into(),
                        ))
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                }
            }
        })
    }
}

impl Operator for Prompt {
    fn separation(
        &mut self,
        p: &Point,
        previous: Option<&SeparationEntry>,
    ) -> Result<SeparationEntry> {
        if let Some(prev) = previous {
            let a = self.ask(&format!(
                "\nResuming at separation {} in (recorded {:.4} +/- {:.4} in from corners {:?}). Is \
                 the plate still there? [Y = yes / n = measure again] ",
                p.separation, prev.mean, prev.uncertainty, prev.corners
            ))?;
            if !a.to_lowercase().starts_with('n') {
                return Ok(prev.clone());
            }
        }
        loop {
            let a = self.ask(&format!(
                "\nMove the plate to {} in (all LEDs are off). Enter the four corner \
                 separations in inches, at the rods x, y = +/-{} in of the sensor board's frame, \
                 in the order {} (e.g. `{0} {0} {0} {0}`; the order gives the plate's tilt): ",
                p.separation, ROD_XY_IN, CORNER_ORDER_TEXT
            ))?;
            let v: Result<Vec<f64>, _> = a
                .split([' ', ',', '\t'])
                .filter(|s| !s.is_empty())
                .map(str::parse::<f64>)
                .collect();
            match v {
                Ok(v) if v.len() == 4 && v.iter().all(|c| c.is_finite() && *c > 0.0) => {
                    let e = separation_entry(p.sep_idx, p.separation, v, "operator".into());
                    if (e.mean - p.separation).abs() > 0.5 {
                        let ok = self.ask(&format!(
                            "The mean {:.4} in is {:.3} in from the plan's {} in. Keep it? [y/N] ",
                            e.mean,
                            e.mean - p.separation,
                            p.separation
                        ))?;
                        if !ok.to_lowercase().starts_with('y') {
                            continue;
                        }
                    }
                    if let Some(q) = levelness_question(&e.corners) {
                        if !self.ask(&q)?.to_lowercase().starts_with('y') {
                            continue;
                        }
                    }
                    return Ok(e);
                }
                _ => eprintln!("  need four positive numbers, got `{a}`"),
            }
        }
    }
    fn quadrant(&mut self, q: usize) -> Result<String> {
        let names = ["-x,-y", "+x,-y", "-x,+y", "+x,+y"];
        self.ask(&format!(
            "\nMount the beacon array in quadrant {q} ({}) of the plate, then press Enter ",
            names[q % 4]
        ))?;
        Ok("operator".into())
    }
    fn power(&mut self, level: u8) -> Result<String> {
        let r = if level == 1 { "1 kOhm" } else { "360 Ohm" };
        self.ask(&format!(
            "\nSet every LED's slide switch to power level {level} ({r}), then press Enter "
        ))?;
        Ok("operator".into())
    }
}
