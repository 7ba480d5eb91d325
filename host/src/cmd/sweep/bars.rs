//! The sweep's progress on stderr: two bars (the run and the current separation, with ETA)
//! on a terminal, plain log lines otherwise.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cta_lab::sweep::estimate::{self, Steps};
use cta_lab::sweep::plan::Plan;
use cta_lab::sweep::points::Point;
use cta_lab::sweep::watch::Watch;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The progress bars: the whole run and the current separation, with ETA. When stderr is not
/// a terminal (a run under `nohup`, `tee`, cron or systemd) there are no bars; plain log lines
/// take their place ([`Bars::log`]): the start, each separation finished, the progress with
/// its ETA at least every [`PROGRESS_EVERY`] (a separation of the Ch VI plan takes hours),
/// each fault, retry and reconnection, each wait for the operator, the stop.
#[derive(Clone)]
pub struct Bars {
    /// The bars' container (prompts suspend it).
    pub multi: MultiProgress,
    total: ProgressBar,
    sep: ProgressBar,
    /// Log lines instead of bars: when the session started.
    log: Option<Instant>,
    /// When the last line about progress was logged.
    last_progress: Arc<Mutex<Instant>>,
    /// The manual steps' durations the ETA's model assumes.
    steps: Steps,
    /// The run's modelled timeline and where this session started ([`Eta`]).
    eta: Arc<Mutex<Option<Eta>>>,
}

/// The ETA: the run's duration model ([`estimate::timeline`]), scaled by the pace this session
/// has kept against it. On the real boards the pace is about 1; on the unthrottled simulated
/// CTA far below.
struct Eta {
    /// When each point starts in the model, s; the run's end last.
    timeline: Vec<f64>,
    /// The first point of the session.
    from: usize,
    /// When the session's first point started.
    t0: Instant,
}

impl Eta {
    /// The time left after point `i` is done.
    fn after(&self, i: usize) -> Duration {
        let t = &self.timeline;
        let (done, end) = (i + 1, t.len() - 1);
        if done > end || done <= self.from {
            return Duration::ZERO;
        }
        let modelled = (t[done] - t[self.from]).max(1e-9);
        let pace = self.t0.elapsed().as_secs_f64() / modelled;
        Duration::from_secs_f64(((t[end] - t[done]) * pace).max(0.0))
    }
}

/// `H:MM:SS`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

/// Log mode: the longest time without a line about progress.
pub const PROGRESS_EVERY: Duration = Duration::from_secs(60);

/// The log line after point `i` (0-based) of `n`, at `separation`, when a separation is done
/// (`per` points each) or `since` the last progress line is [`PROGRESS_EVERY`] or more;
/// `per_sec` and `eta` are the run's rate and estimate, as the terminal's run bar shows them
/// (its points done of all, its ETA). Both lines say how many points are done of how many
/// (`1234/69600 points`: a count, where `point 9` elsewhere is an index, from 0); the rate and
/// the ETA are left out while there is no estimate yet, and once the run is done.
fn progress_line(
    i: usize,
    n: usize,
    per: usize,
    separation: f64,
    since: Duration,
    per_sec: f64,
    eta: Duration,
) -> Option<String> {
    let done = i + 1;
    let rate = || {
        if done >= n || !per_sec.is_finite() || per_sec <= 0.0 {
            return String::new();
        }
        format!("; {:.1} points/min, ETA {}", per_sec * 60.0, clock(eta))
    };
    if done.is_multiple_of(per.max(1)) || done == n {
        Some(format!(
            "separation {separation} in done: {done}/{n} points{}",
            rate()
        ))
    } else if since >= PROGRESS_EVERY {
        Some(format!("{done}/{n} points, at {separation} in{}", rate()))
    } else {
        None
    }
}

impl Bars {
    /// Bars on stderr; with `quiet`, neither bars nor log lines. Log lines replace the bars
    /// when stderr is not a terminal. `steps`: the manual steps' durations for the ETA.
    pub fn new(quiet: bool, steps: Steps) -> Bars {
        Bars {
            steps,
            ..Bars::with(quiet, !quiet && !std::io::stderr().is_terminal())
        }
    }

    /// Bars (hidden when `hidden` or when stderr is not a terminal), and log lines when `log`.
    pub fn with(hidden: bool, log: bool) -> Bars {
        let multi = MultiProgress::with_draw_target(if hidden || log {
            ProgressDrawTarget::hidden()
        } else {
            ProgressDrawTarget::stderr_with_hz(10)
        });
        let style = |t: &str| {
            ProgressStyle::with_template(t)
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> ")
        };
        let total = multi.add(ProgressBar::new(0).with_style(style(
            "run        [{bar:40}] {pos}/{len} points  {elapsed_precise} ETA {prefix}  {msg}",
        )));
        let sep = multi.add(ProgressBar::new(0).with_style(style(
            "{prefix:>10} [{bar:40}] {pos}/{len} points  ETA {eta}",
        )));
        Bars {
            multi,
            total,
            sep,
            log: log.then(Instant::now),
            last_progress: Arc::new(Mutex::new(Instant::now())),
            steps: Steps::default(),
            eta: Arc::new(Mutex::new(None)),
        }
    }

    /// The start of a log line, `cta sweep [+H:MM:SS]` (time since the session started);
    /// `None` when not logging.
    pub(super) fn log_prefix(&self) -> Option<String> {
        self.log.map(|t0| {
            let s = t0.elapsed().as_secs();
            format!("cta sweep [+{}:{:02}:{:02}]", s / 3600, s / 60 % 60, s % 60)
        })
    }

    /// A line of the log on stderr (only when logging instead of drawing bars).
    pub fn log(&self, line: &str) {
        if let Some(prefix) = self.log_prefix() {
            // Not `eprintln!`, which panics when stderr has gone (a closed pipe or terminal).
            let _ = writeln!(std::io::stderr(), "{prefix} {line}");
        }
    }

    /// Remove the bars.
    pub fn finish(&self) {
        self.sep.finish_and_clear();
        self.total.finish_and_clear();
    }
}

impl Watch for Bars {
    fn start(&self, plan: &Plan, from: usize) {
        self.total.set_length(plan.len() as u64);
        self.total.set_position(from as u64);
        let timeline = estimate::timeline(plan, &self.steps);
        // Until a point is done: the model's own estimate, at the boards' pace.
        let left = timeline[timeline.len() - 1] - timeline[from.min(timeline.len() - 1)];
        self.total
            .set_prefix(clock(Duration::from_secs_f64(left.max(0.0))));
        *self.eta.lock().unwrap_or_else(|e| e.into_inner()) = Some(Eta {
            timeline,
            from,
            t0: Instant::now(),
        });
        self.sep.set_length(plan.per_separation() as u64);
        self.sep
            .set_position((from % plan.per_separation().max(1)) as u64);
    }

    fn separation(&self, plan: &Plan, p: &Point) {
        self.sep.set_prefix(format!("{} in", p.separation));
        self.sep
            .set_position((p.index % plan.per_separation().max(1)) as u64);
        self.sep.reset_eta();
    }

    /// Point `i` of `plan`, at `separation`, is committed: the bars move, and in log mode a
    /// line is logged when the separation is done or a while has passed ([`progress_line`]).
    fn point_done(&self, plan: &Plan, i: usize, separation: f64) {
        self.total.inc(1);
        self.sep.inc(1);
        let eta = self
            .eta
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()
            .map_or(Duration::ZERO, |e| e.after(i));
        self.total.set_prefix(clock(eta));
        if self.log.is_none() {
            return;
        }
        let mut last = self.last_progress.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(line) = progress_line(
            i,
            plan.len(),
            plan.per_separation(),
            separation,
            last.elapsed(),
            self.total.per_sec(),
            eta,
        ) {
            self.log(&line);
            *last = Instant::now();
        }
    }

    fn message(&self, m: &str) {
        self.total.set_message(m.to_string());
    }

    fn log(&self, line: &str) {
        Bars::log(self, line);
    }
    fn note(&self, dir: &Path, note: &str) {
        crate::say::line(format_args!("cta: note: {}: {note}", dir.display()));
    }
    fn warning(&self, w: &str) {
        crate::say::line(format_args!("cta: warning: {w}"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ETA is the model's time left, scaled by the session's pace against the model: a
    /// session twice as fast as the model halves it; a resumed session counts from its first
    /// point; nothing is left after the last point.
    #[test]
    fn the_eta_is_the_model_scaled_by_the_pace_kept() {
        let timeline = vec![0.0, 10.0, 20.0, 40.0, 100.0];
        let eta = |from: usize, elapsed: f64, i: usize| {
            Eta {
                timeline: timeline.clone(),
                from,
                t0: Instant::now() - Duration::from_secs_f64(elapsed),
            }
            .after(i)
            .as_secs_f64()
        };
        // Point 0 done in its modelled 10 s: 90 s left.
        assert!((eta(0, 10.0, 0) - 90.0).abs() < 0.5);
        // Twice as fast: half.
        assert!((eta(0, 5.0, 0) - 45.0).abs() < 0.5);
        // Resumed at point 2, which took 20 s of model in 40 s: 60 s of model left, 120 s.
        assert!((eta(2, 40.0, 2) - 120.0).abs() < 0.5);
        assert_eq!(eta(0, 10.0, 3), 0.0);
    }

    /// In log mode a line comes at each separation's end, and in between at least every
    /// [`PROGRESS_EVERY`], each with the points done of all, the rate and the ETA (but at
    /// the end, and before the rate is known).
    #[test]
    fn log_lines_come_per_separation_and_every_minute() {
        let eta = Duration::from_secs(3 * 3600 + 12 * 60 + 5);
        let line = |i, since| progress_line(i, 2400, 800, 10.0, since, 0.2, eta);
        assert_eq!(
            line(799, Duration::ZERO).as_deref(),
            Some("separation 10 in done: 800/2400 points; 12.0 points/min, ETA 3:12:05")
        );
        assert_eq!(
            line(2399, Duration::ZERO).as_deref(),
            Some("separation 10 in done: 2400/2400 points")
        );
        assert_eq!(line(5, PROGRESS_EVERY - Duration::from_millis(1)), None);
        assert_eq!(
            line(5, PROGRESS_EVERY).as_deref(),
            Some("6/2400 points, at 10 in; 12.0 points/min, ETA 3:12:05")
        );
        // No estimate yet: no rate, no ETA.
        assert_eq!(
            progress_line(799, 2400, 800, 10.0, Duration::ZERO, 0.0, Duration::ZERO).as_deref(),
            Some("separation 10 in done: 800/2400 points")
        );
    }
}
