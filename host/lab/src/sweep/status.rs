//! `cta sweep --status RUN_DIR`: how far a run has got, read from its files without changing
//! anything, also while another `cta sweep` is writing them.
//!
//! Read-only by construction: the journal, the plan, the manifest's neighbours and the lock
//! file are only read (never opened for writing, never locked, never cut). Whether a session is
//! running is learnt from the kernel's table of `flock(2)` locks (`/proc/locks`), which lists
//! the lock a running sweep holds on `sweep.lock` without anyone taking it; where that table
//! cannot be read (macOS), from the pid the running sweep writes in `sweep.lock` (emptied when
//! it ends) and whether that process is alive. On Windows the lock is mandatory: a held
//! `sweep.lock` cannot be read, which is itself the answer (running, pid unknown). A sweep
//! appends whole lines to the journal, so a reader can only see its last line half-written: a
//! last line without its newline is left out (and said), as a resume would drop it.

use std::path::{Path, PathBuf};

use super::error::{bail, Context, Error, Result};
use serde_json::{json, Value};

use super::plan::Plan;
use super::stamp;
use super::store::{self, Event, PointStatus};

/// Whether a session holds the run, and how that is known.
#[derive(Debug, Clone, PartialEq)]
pub enum Holder {
    /// A `cta sweep` holds the run's lock: it is running (pid, when known).
    Running(Option<u32>),
    /// Nobody holds it; the pid a killed session left in the lock file, if any.
    Free(Option<u32>),
}

/// One session, as journalled.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// Its number, from 1.
    pub n: u32,
    /// When it started, seconds since the epoch.
    pub at: f64,
    /// The point it started at.
    pub from_point: usize,
    /// What it ran on (`simulated CTA`, `CTA hardware`, ...), with `(real time)` for a
    /// simulated CTA run at the plan's rate.
    pub on: String,
}

/// Progress at one separation of the plan.
#[derive(Debug, Clone, PartialEq)]
pub struct SeparationProgress {
    /// The plan's separation, in.
    pub separation_in: f64,
    /// Points done there.
    pub done: usize,
    /// Points there.
    pub total: usize,
}

/// What `cta sweep --status` reports.
#[derive(Debug, Clone)]
pub struct Status {
    /// The run directory.
    pub dir: PathBuf,
    /// `running`, `complete`, `stopped` (a stop was journalled: `reason`) or `interrupted`
    /// (the last session ended without journalling a stop: killed, crashed, a power cut).
    pub state: &'static str,
    /// Why the last session stopped (`stopped`), as journalled.
    pub reason: Option<String>,
    /// The running session's pid (`running`).
    pub pid: Option<u32>,
    /// The plan's name.
    pub plan_name: String,
    /// The plan's `[metadata]`, as the last session ran under it.
    pub metadata: super::metadata::Metadata,
    /// Points in the plan.
    pub total: usize,
    /// Points done (committed); also the index of the next point.
    pub done: usize,
    /// Committed points by outcome: ok, no signal, partial.
    pub outcomes: (usize, usize, usize),
    /// Samples written.
    pub samples: u64,
    /// The next point's separation, in (none when complete).
    pub next_separation: Option<f64>,
    /// Per separation of the plan.
    pub separations: Vec<SeparationProgress>,
    /// The last committed point and when (seconds since the epoch; none in journals of older
    /// versions, which did not record it).
    pub last_commit: Option<(usize, Option<f64>)>,
    /// The sessions so far.
    pub sessions: Vec<Session>,
    /// Faults journalled so far.
    pub faults: usize,
    /// The last fault: point, board, what, action.
    pub last_fault: Option<(usize, String, String, String)>,
    /// The last session's rate, points per minute (from its start to its last commit).
    pub rate_per_min: Option<f64>,
    /// Estimated time to the end, s (`running` only).
    pub eta_s: Option<f64>,
    /// data.csv's length now, bytes (none when it is missing).
    pub data_bytes: Option<u64>,
    /// The length the journal committed.
    pub committed_bytes: Option<u64>,
    /// A half-written last journal line left out, bytes.
    pub torn_bytes: Option<usize>,
    /// What else to know (data cut short, uncommitted bytes, a stale lock, ...).
    pub notes: Vec<String>,
    /// The command that continues the run (not when complete).
    pub resume: Option<String>,
}

/// Read the status of the run in `dir`. Nothing is written, locked or cut.
pub fn status(dir: &Path) -> Result<Status> {
    super::run_dir_given(dir, "--status")?;
    // The lock's holder read before and after the journal: a session that starts or ends in
    // between (a clean stop read as a kill) is read again.
    for _ in 0..3 {
        let before = holder(dir);
        let s = status_held(dir, before.clone())?;
        if holder(dir) == before {
            return Ok(s);
        }
    }
    status_held(dir, holder(dir))
}

/// [`status`] with the lock's holder as read.
fn status_held(dir: &Path, holder: Holder) -> Result<Status> {
    let jp = dir.join(store::JOURNAL);
    let bytes = match std::fs::read(&jp) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e).with_context(|| format!("{}: cannot read", jp.display())),
    };
    let (events, torn) = parse_journal(&jp, &bytes)?;
    let plan = journalled_plan(&events)
        .map(Ok)
        .unwrap_or_else(|| Plan::load(&dir.join(store::PLAN)).map_err(Error::from))?;
    let total = plan.len();
    let per = plan.per_separation().max(1);

    let mut outcomes = (0, 0, 0);
    let mut samples = 0u64;
    let mut last_commit = None;
    let mut committed = None;
    let mut faults = 0;
    let mut last_fault = None;
    let mut sessions = Vec::new();
    let mut last_stop: Option<(usize, String)> = None;
    // Points of the last session and the times they span.
    let mut session_points = 0usize;
    let mut last_at = None;
    for (k, e) in events.iter().enumerate() {
        match e {
            Event::Session {
                n,
                at,
                from_point,
                sim,
                boards,
                ..
            } => {
                let simulated = |b: &str| boards[b]["simulated"].as_bool().unwrap_or(false);
                let mut on =
                    super::apparatus(sim.is_some(), simulated("beacon"), simulated("sensor"))
                        .to_string();
                if sim.as_ref().is_some_and(|v| v["realtime"] == true) {
                    on.push_str(" (real time)");
                }
                sessions.push(Session {
                    n: *n,
                    at: *at,
                    from_point: *from_point,
                    on,
                });
                session_points = 0;
                last_at = None;
            }
            Event::Point {
                i,
                status,
                samples: s,
                csv_end,
                at,
                ..
            } => {
                match status {
                    PointStatus::Ok => outcomes.0 += 1,
                    PointStatus::NoSignal => outcomes.1 += 1,
                    PointStatus::Partial => outcomes.2 += 1,
                }
                samples += u64::from(*s);
                last_commit = Some((*i, *at));
                committed = Some(*csv_end);
                session_points += 1;
                last_at = *at;
            }
            Event::Fault {
                point,
                board,
                what,
                action,
                ..
            } => {
                faults += 1;
                last_fault = Some((*point, board.clone(), what.clone(), action.clone()));
            }
            Event::Stop { reason, .. } => last_stop = Some((k, reason.clone())),
            _ => {}
        }
    }
    let done = last_commit.map_or(0, |(i, _)| i + 1);
    let separations = plan
        .separations
        .iter()
        .enumerate()
        .map(|(s, &separation_in)| SeparationProgress {
            separation_in,
            done: done.saturating_sub(s * per).min(per),
            total: per,
        })
        .collect();

    let last_session_at = events
        .iter()
        .rposition(|e| matches!(e, Event::Session { .. }));
    // A stop journalled after the last session start: that session ended cleanly.
    let stopped = match (&last_stop, last_session_at) {
        (Some((k, r)), Some(s)) if *k > s => Some(r.clone()),
        (Some((_, r)), None) => Some(r.clone()),
        _ => None,
    };
    let mut notes = Vec::new();
    let (state, pid) = match holder {
        Holder::Running(pid) => ("running", pid),
        Holder::Free(stale) => {
            if let Some(p) = stale {
                notes.push(format!(
                    "{} holds pid {p}, a session that no longer runs (killed or crashed); the \
                     next session takes it over",
                    store::LOCK
                ));
            }
            if done >= total {
                ("complete", None)
            } else if stopped.is_some() {
                ("stopped", None)
            } else {
                ("interrupted", None)
            }
        }
    };

    // The last session's rate, from its start to its last commit.
    let rate_per_min = match (sessions.last(), last_at) {
        (Some(s), Some(t)) if session_points > 0 && t > s.at => {
            Some(session_points as f64 / (t - s.at) * 60.0)
        }
        _ => None,
    };
    let eta_s = match (state, rate_per_min) {
        ("running", Some(r)) if r > 0.0 => Some((total - done.min(total)) as f64 / r * 60.0),
        _ => None,
    };

    let dp = dir.join(store::DATA);
    let data_bytes = std::fs::metadata(&dp).ok().map(|m| m.len());
    match (data_bytes, committed) {
        (None, _) => notes.push(format!(
            "{}: missing: the run cannot be resumed without it",
            dp.display()
        )),
        (Some(len), Some(end)) if len < end => notes.push(format!(
            "{}: {len} bytes, fewer than the {end} the journal committed: the file was cut \
             short; `cta sweep --resume` says which points it still holds whole, and \
             `--recover-truncated` continues after them",
            dp.display()
        )),
        (Some(len), Some(end)) if len > end && state != "running" => notes.push(format!(
            "{}: {} bytes past the last committed point (written but never committed, or \
             added since): the next resume cuts them",
            dp.display(),
            len - end
        )),
        _ => {}
    }
    if let Some(n) = torn {
        notes.push(format!(
            "{}: its last line is not whole ({n} bytes){}",
            jp.display(),
            if state == "running" {
                ": being written now"
            } else {
                ": the next resume drops it"
            }
        ));
    }
    let resume = (state != "complete").then(|| {
        let ports = super::last_session_ports(&events);
        super::resume_command(dir, ports.as_ref().map(|(b, s)| (b.as_str(), s.as_str())))
    });
    Ok(Status {
        dir: dir.to_path_buf(),
        state,
        reason: stopped,
        pid,
        plan_name: plan.name.clone(),
        metadata: plan.metadata.clone(),
        total,
        done,
        outcomes,
        samples,
        next_separation: (done < total).then(|| plan.point(done).separation),
        separations,
        last_commit,
        sessions,
        faults,
        last_fault,
        rate_per_min,
        eta_s,
        data_bytes,
        committed_bytes: committed,
        torn_bytes: torn,
        notes,
        resume,
    })
}

/// The journal's events, and the length of a last line without its newline (left out: being
/// written, or torn by a session that died mid-write).
pub(crate) fn parse_journal(path: &Path, bytes: &[u8]) -> Result<(Vec<Event>, Option<usize>)> {
    let mut events = Vec::new();
    let mut rest = bytes;
    let mut lineno = 0;
    while !rest.is_empty() {
        let Some(nl) = rest.iter().position(|&b| b == b'\n') else {
            return Ok((events, Some(rest.len())));
        };
        lineno += 1;
        let line = &rest[..nl];
        rest = &rest[nl + 1..];
        if line.trim_ascii().is_empty() {
            continue;
        }
        match serde_json::from_slice::<Event>(line.trim_ascii_end()) {
            Ok(e) => events.push(e),
            Err(e) => bail!("{}:{lineno}: unreadable journal entry: {e}", path.display()),
        }
    }
    Ok((events, None))
}

/// The plan the last session ran with, as journalled.
fn journalled_plan(events: &[Event]) -> Option<Plan> {
    events.iter().rev().find_map(|e| match e {
        Event::Session { plan: Some(p), .. } => serde_json::from_value(p.clone()).ok(),
        _ => None,
    })
}

/// Who holds `dir`'s lock, without taking it: the kernel's lock table first (Linux), then
/// the pid in the lock file.
#[cfg(unix)]
pub fn holder(dir: &Path) -> Holder {
    let path = dir.join(store::LOCK);
    let written: Option<u32> = std::fs::read_to_string(&path)
        .ok()
        .and_then(|s| s.trim().parse().ok());
    let Ok(meta) = std::fs::metadata(&path) else {
        return Holder::Free(None);
    };
    #[cfg(target_os = "linux")]
    if let Ok(table) = std::fs::read_to_string("/proc/locks") {
        use std::os::unix::fs::MetadataExt;
        let id = format!(
            "{:02x}:{:02x}:{}",
            libc::major(meta.dev()),
            libc::minor(meta.dev()),
            meta.ino()
        );
        // `1: FLOCK  ADVISORY  WRITE 5350 fe:00:10010679 0 EOF` (a waiter's line has `->`).
        let held = table.lines().find_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f.len() >= 6 && f[1] == "FLOCK" && f[5] == id).then(|| f[4].parse::<u32>().ok())
        });
        return match held {
            Some(pid) => Holder::Running(written.or(pid)),
            // Not in the table: free, unless the pid written is a live `cta` (on btrfs
            // subvolumes and overlayfs `stat` gives another device number than the table
            // prints, so a held lock is not found by its id there).
            None => match written {
                Some(pid) if runs_cta(pid) => Holder::Running(Some(pid)),
                other => Holder::Free(other),
            },
        };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = meta; // The file exists: all that is asked of it without a lock table.
                  // No lock table: the pid a running sweep writes (and empties when it ends).
    match written {
        Some(pid) if runs_cta(pid) => Holder::Running(Some(pid)),
        other => Holder::Free(other),
    }
}

/// Who holds `dir`'s lock, without taking it. Windows locks are mandatory and cover the whole
/// file: while a sweep holds it, reading the file fails with a lock violation, so a read that
/// works says nobody holds it (and gives the pid a killed session left).
#[cfg(not(unix))]
pub fn holder(dir: &Path) -> Holder {
    /// Windows' ERROR_LOCK_VIOLATION: the file is locked by another process.
    const LOCK_VIOLATION: i32 = 33;
    match std::fs::read_to_string(dir.join(store::LOCK)) {
        Ok(s) => Holder::Free(s.trim().parse().ok()),
        Err(e) if e.raw_os_error() == Some(LOCK_VIOLATION) => Holder::Running(None),
        Err(_) => Holder::Free(None),
    }
}

/// Whether `pid` is a live `cta` process: its name where `/proc` gives it (a pid reused by
/// another program is no sweep), else whether it exists at all.
#[cfg(unix)]
fn runs_cta(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/comm")) {
        Ok(name) => name.trim() == "cta",
        Err(_) => alive(pid),
    }
}

/// Whether process `pid` exists (signal 0: nothing is sent).
#[cfg(unix)]
fn alive(pid: u32) -> bool {
    let Ok(p) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: kill with signal 0 only checks that the process exists.
    unsafe {
        libc::kill(p, 0) == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
}

/// `2026-11-23 07:34:24 UTC` for seconds since the epoch.
pub fn utc(t: f64) -> String {
    let s = t.max(0.0) as i64;
    let (days, rem) = (s.div_euclid(86_400), s.rem_euclid(86_400));
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// `H:MM:SS`.
fn hms(s: f64) -> String {
    let s = s.max(0.0).round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

/// `3 s`, `4 min`, `2.5 h`, `3.1 days`: how long ago.
fn ago(s: f64) -> String {
    let s = s.max(0.0);
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.0} min", s / 60.0)
    } else if s < 172_800.0 {
        format!("{:.1} h", s / 3600.0)
    } else {
        format!("{:.1} days", s / 86_400.0)
    }
}

impl Status {
    /// The human report (what `cta sweep --status RUN_DIR` prints).
    pub fn render(&self) -> String {
        let now = store::now();
        let mut o = String::new();
        let state = match (self.state, &self.reason, self.pid) {
            ("running", _, Some(pid)) => format!("running (pid {pid})"),
            ("stopped", Some(r), _) => format!("stopped ({r})"),
            ("interrupted", _, _) => "interrupted (its last session ended without recording a \
                                      stop: killed, crashed or a power cut)"
                .to_string(),
            (s, _, _) => s.to_string(),
        };
        o += &format!(
            "sweep {}: {state}; {}",
            self.dir.display(),
            super::points_done(self.done, self.total)
        );
        if let Some(s) = self.next_separation {
            o += &format!(", at {s} in");
        }
        o += "\n";
        o += &format!(
            "  plan `{}`: {} points, {} per separation\n",
            self.plan_name,
            self.total,
            self.separations.first().map_or(0, |s| s.total)
        );
        if !self.metadata.is_empty() {
            o += &format!(
                "  metadata: {}
",
                self.metadata.lines().join(", ")
            );
        }
        o += &format!(
            "  points: {} ok, {} no signal, {} partial; {} samples\n",
            self.outcomes.0, self.outcomes.1, self.outcomes.2, self.samples
        );
        o += "  separation  points\n";
        for s in &self.separations {
            let mark = if s.done == s.total {
                "  done"
            } else if s.done > 0 {
                "  <- here"
            } else {
                ""
            };
            o += &format!(
                "  {:>7} in  {:>w$}/{}{mark}\n",
                s.separation_in,
                s.done,
                s.total,
                w = s.total.to_string().len()
            );
        }
        match self.last_commit {
            Some((i, Some(t))) => {
                o += &format!(
                    "  last commit: point {i}, {} ({} ago)\n",
                    utc(t),
                    ago(now - t)
                )
            }
            Some((i, None)) => {
                o += &format!("  last commit: point {i} (its time not journalled)\n")
            }
            None => o += "  last commit: none yet\n",
        }
        if let Some(s) = self.sessions.last() {
            o += &format!(
                "  sessions: {}; the last started {} at point {}, on the {}\n",
                self.sessions.len(),
                utc(s.at),
                s.from_point,
                s.on
            );
        }
        match (self.rate_per_min, self.eta_s) {
            (Some(r), Some(eta)) => {
                o += &format!("  rate: {r:.1} points/min this session, ETA {}\n", hms(eta))
            }
            (Some(r), None) => o += &format!("  rate: {r:.1} points/min in the last session\n"),
            _ => {}
        }
        o += &format!("  faults: {}", self.faults);
        if let Some((p, b, w, a)) = &self.last_fault {
            o += &format!(" (the last at point {p}: {b}: {w}; {a})");
        }
        o += "\n";
        if let Some(len) = self.data_bytes {
            o += &format!(
                "  data: {}, {len} bytes{}\n",
                self.dir.join(store::DATA).display(),
                match self.committed_bytes {
                    Some(end) if end == len => ", as committed".to_string(),
                    Some(end) => format!(" ({end} committed)"),
                    None => String::new(),
                }
            );
        }
        for n in &self.notes {
            o += &format!("  note: {n}\n");
        }
        match (self.state, &self.resume) {
            ("running", Some(r)) => o += &format!("  continue, once it has stopped: {r}\n"),
            (_, Some(r)) => o += &format!("  continue with: {r}\n"),
            _ => {}
        }
        o
    }

    /// The report as JSON (`--status --json`).
    pub fn to_json(&self) -> Value {
        json!({
            "run": self.dir.display().to_string(),
            "state": self.state,
            "reason": self.reason,
            "pid": self.pid,
            "plan": { "name": self.plan_name, "points": self.total, "metadata": self.metadata },
            "points": {
                "total": self.total,
                "done": self.done,
                "next": (self.done < self.total).then_some(self.done),
                "ok": self.outcomes.0,
                "no_signal": self.outcomes.1,
                "partial": self.outcomes.2,
            },
            "samples": self.samples,
            "next_separation_in": self.next_separation,
            "separations": self.separations.iter().map(|s| json!({
                "separation_in": s.separation_in, "done": s.done, "total": s.total,
            })).collect::<Vec<_>>(),
            "last_commit": self.last_commit.map(|(i, at)| json!({
                "point": i, "at": at, "time": at.and_then(stamp::iso8601),
            })),
            "sessions": self.sessions.iter().map(|s| json!({
                "n": s.n, "at": s.at, "time": stamp::iso8601(s.at), "from_point": s.from_point,
                "on": s.on,
            })).collect::<Vec<_>>(),
            "faults": self.faults,
            "last_fault": self.last_fault.as_ref().map(|(p, b, w, a)| json!({
                "point": p, "board": b, "what": w, "action": a,
            })),
            "rate_points_per_min": self.rate_per_min,
            "eta_s": self.eta_s,
            "data": {
                "path": self.dir.join(store::DATA).display().to_string(),
                "bytes": self.data_bytes,
                "committed_bytes": self.committed_bytes,
            },
            "torn_journal_line_bytes": self.torn_bytes,
            "notes": self.notes,
            "resume": self.resume,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc(0.0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc(951_782_400.0), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc(1_795_419_264.0), "2026-11-23 07:34:24 UTC");
    }

    /// A half-written last line is left out and measured; a bad line elsewhere is named.
    #[test]
    fn a_torn_last_line_is_left_out() {
        let stop = r#"{"event":"stop","at":1.0,"reason":"complete","next_point":0}"#;
        let text = format!("{stop}\n{{\"event\":\"poi");
        let (e, torn) = parse_journal(Path::new("j"), text.as_bytes()).unwrap();
        assert_eq!((e.len(), torn), (1, Some(13)));
        let e = parse_journal(Path::new("j"), b"{\"event\":\nx\n").unwrap_err();
        assert!(
            format!("{e}").starts_with("j:1: unreadable journal entry"),
            "{e}"
        );
    }
}
