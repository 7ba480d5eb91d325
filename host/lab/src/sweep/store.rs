//! The run directory: what a sweep leaves on disk, written so that nothing is lost and
//! nothing is written twice, whatever stops the run.
//!
//! ```text
//! RUN_DIR/plan.toml      the plan, as given (a resume reads it from here; its timing keys
//!                        may be edited between sessions, or changed by a resume's --plan)
//! RUN_DIR/data.csv       the measurements (host/MEASUREMENTS.md), appended per point
//! RUN_DIR/journal.jsonl  one JSON event per line: sessions, operator entries, points, faults
//! RUN_DIR/manifest.json  the run's metadata, rewritten from the journal at every session
//!                        start and stop, operator entry and fault
//! RUN_DIR/sweep.lock     the pid of the `cta sweep` using the run (locked while it runs)
//! ```
//!
//! One process at a time: a [`RunDir`] holds an exclusive lock on `sweep.lock` (`flock(2)` on
//! Unix, `LockFileEx` on Windows, through `fs4`; released by the system however the process
//! ends), so a second `cta sweep` on the same directory is refused with the holder's pid
//! instead of interleaving its journal lines with the first's. A pid left in the file by a
//! process that was killed (nobody holds the lock) is taken over, and a note says so. (Windows
//! locks are mandatory: there the file cannot be read while held, and the refusal says "pid
//! unknown".)
//!
//! Commit protocol for a point: its rows (or its "no signal" comment) are appended to
//! `data.csv` and flushed to the operating system; its `point` event, carrying the file length
//! after them, is appended to the journal only once `data.csv` is synced to disk, then the
//! journal is synced. Syncs are grouped: at most one pair every [`SYNC_INTERVAL`] (a slow
//! point, as on the real CTA, is synced as soon as it is done; the unthrottled simulated CTA
//! commits many points per sync), and always before any other event and at the end of a
//! session. So the journal never runs ahead of the data on disk, whatever stops the run. The journal is the authority: on resume,
//! `data.csv` is cut back to the length of the last journalled point (dropping the rows of a
//! point whose journal line never made it), a torn last journal line is dropped, and the run
//! continues with the next point. No duplicate, no gap.

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::error::{bail, Context, Result};

pub use super::event::*;
pub(crate) use super::layout::recovery_folder;
pub use super::layout::{DATA, DATA_TAIL, JOURNAL, JOURNAL_TAIL, LOCK, MANIFEST, PLAN, TRUTH};
use super::plan::{Change, Plan, RESUME_MAY_CHANGE};
use crate::data::{comment_text, write_row, Sample, OPTIONAL, REQUIRED};

/// Seconds since the Unix epoch.
pub fn now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// FNV-1a, 64 bits: a running hash of data.csv as it is written (no cryptographic claim: it
/// catches edits and replacements, not an adversary).
#[derive(Debug, Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// An exclusive lock on a run directory: `flock(2)` (Unix) or `LockFileEx` (Windows) on
/// [`LOCK`], which holds the holder's pid.
struct Lock {
    file: File,
}

impl Lock {
    /// Lock `dir` (which must exist), or say who holds it. Also returns the pid a previous
    /// holder left in the file without holding the lock (it died: killed, crashed, power cut).
    fn acquire(dir: &Path) -> Result<(Lock, Option<String>)> {
        let path = dir.join(LOCK);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("{}: cannot open the lock file", path.display()))?;
        // Called through the trait: `File::try_lock` (Rust 1.89) is another method.
        let r = fs4::FileExt::try_lock(&file);
        let mut holder = String::new();
        let _ = file.read_to_string(&mut holder);
        let holder = holder.trim().to_string();
        if let Err(e) = r {
            if let fs4::TryLockError::WouldBlock = e {
                bail!(
                    "{}: the run is in use by another `cta sweep` ({}); wait for it to end or stop \
                     it first: two sessions on one run directory would corrupt its journal",
                    path.display(),
                    if holder.is_empty() {
                        "pid unknown".to_string()
                    } else {
                        format!("pid {holder}")
                    }
                );
            }
            return Err(std::io::Error::from(e))
                .with_context(|| format!("{}: cannot lock", path.display()));
        }
        let mut lock = Lock { file };
        lock.write(&format!("{}\n", std::process::id()))
            .with_context(|| format!("{}: cannot write", path.display()))?;
        Ok((lock, Some(holder).filter(|h| !h.is_empty())))
    }

    fn write(&mut self, s: &str) -> std::io::Result<()> {
        self.file.set_len(0)?;
        self.file.seek(SeekFrom::Start(0))?;
        self.file.write_all(s.as_bytes())
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Released: no pid left behind (the lock itself goes with the file handle).
        let _ = self.write("");
    }
}

/// An open run directory.
pub struct RunDir {
    /// The directory.
    pub dir: PathBuf,
    /// What opening it found and did that the operator should know (printed and journalled
    /// with the session): a dead holder's lock taken over, uncommitted data discarded, ...
    pub notes: Vec<String>,
    csv: BufWriter<File>,
    csv_len: u64,
    /// Hash of data.csv's first `csv_len` bytes.
    csv_hash: Fnv,
    journal: File,
    /// Length of the journal's complete lines (a failed write is cut back to it).
    journal_len: u64,
    /// The chain of the journal's last line ([`super::journal`]).
    journal_chain: u64,
    /// Every event so far (this and previous sessions).
    pub events: Vec<Event>,
    sync: bool,
    /// Journal lines of points whose rows are not yet synced.
    pending: Vec<u8>,
    /// Number of events in `pending` (the last ones of `events`).
    pending_events: usize,
    last_sync: std::time::Instant,
    /// A resume's changes not made yet ([`RunDir::begin`]).
    unapplied: Option<Unapplied>,
    /// Where the plate was last recorded when the run was opened (the journal's last
    /// `separation`, also when a recovery cut it from the journal): a resume asks to confirm
    /// it only when the next point is at that separation.
    pub plate: Option<SeparationEntry>,
    _lock: Lock,
}

/// The changes to the run directory a resume decided and [`RunDir::begin`] makes (the cuts'
/// lengths are the run's `journal_len` and `csv_len`).
struct Unapplied {
    /// The text to write as plan.toml (`--plan FILE` with another text).
    plan_text: Option<String>,
    /// A recovery of a data file cut short (`--recover-truncated`): what is moved aside
    /// before the cuts.
    recovery: Option<Recovery>,
}

/// What `--recover-truncated` keeps before it cuts: the journal from `journal_from` (the
/// lines after the last point the data file still holds whole) and data.csv from `data_from`
/// (the bytes past that point), each to its own file in `folder`.
struct Recovery {
    folder: PathBuf,
    journal_from: u64,
    data_from: u64,
}

/// Longest time between two syncs while points complete.
pub const SYNC_INTERVAL: std::time::Duration = std::time::Duration::from_millis(250);

fn took_over(pid: String) -> String {
    format!(
        "took over {LOCK} from pid {pid}, which no longer holds it (killed or crashed without \
         releasing it)"
    )
}

impl RunDir {
    /// Start a new run in `dir` with the plan text `plan_src`. An existing non-empty `dir` is
    /// refused unless `force` (then its sweep files are removed first).
    pub fn create(
        dir: &Path,
        plan_src: &str,
        header: &[String],
        force: bool,
        sync: bool,
    ) -> Result<RunDir> {
        RunDir::check_new(dir, force)?;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        // Locked before anything is removed: --force must not pull a run from under a live
        // session.
        let (lock, stale) = Lock::acquire(dir)?;
        for f in [PLAN, DATA, JOURNAL, MANIFEST, TRUTH] {
            let p = dir.join(f);
            if p.exists() {
                std::fs::remove_file(&p)
                    .with_context(|| format!("{}: cannot remove", p.display()))?;
            }
        }
        let mut run = RunDir::create_files(dir, plan_src, header, sync, lock)?;
        run.notes.extend(stale.map(took_over));
        Ok(run)
    }

    /// Refuse to start a new run in an existing, non-empty `dir` unless `force`.
    pub fn check_new(dir: &Path, force: bool) -> Result<()> {
        // --out names a folder: a file there (or above it) is not one to create the run in.
        let file_above = dir
            .ancestors()
            .filter(|a| !a.as_os_str().is_empty())
            .find(|a| a.exists())
            .filter(|a| !a.is_dir());
        if let Some(f) = file_above {
            bail!(
                "{}: is a file, not a folder: --out names the folder a new run creates (its {DATA}, \
                 {JOURNAL}, {MANIFEST} and {PLAN} go in it){}; nothing was started: choose \
                 another --out",
                f.display(),
                if f == dir {
                    String::new()
                } else {
                    format!(", and {} would be under it", dir.display())
                }
            );
        }
        if dir.exists() {
            let nonempty = std::fs::read_dir(dir)
                .with_context(|| format!("{}: cannot read the directory", dir.display()))?
                .next()
                .is_some();
            if nonempty && !force {
                bail!(
                    "{} already exists and is not empty: continue it with `cta sweep --resume {}`, \
                     or start over with --force (deletes its {DATA}, {JOURNAL}, {MANIFEST})",
                    dir.display(),
                    dir.display()
                );
            }
        }
        // The run directory is created, or emptied, once both boards answered: a place it
        // cannot be written in is refused now, before any port is opened.
        let existing = dir
            .ancestors()
            .map(|a| {
                if a.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    a
                }
            })
            .find(|a| a.exists());
        if let Some(at) = existing.filter(|a| a.is_dir()) {
            if let Err(e) = writable(at) {
                let itself = at == dir;
                // `.` by its name.
                let at = if at == Path::new(".") {
                    std::env::current_dir().unwrap_or_else(|_| at.to_path_buf())
                } else {
                    at.to_path_buf()
                };
                bail!(
                    "{}: cannot write: {e}. {}: nothing was started; choose another --out, or \
                     make {} writable",
                    at.display(),
                    if itself {
                        "A new run writes its files in it".to_string()
                    } else {
                        format!("A new run would create {} in it", dir.display())
                    },
                    at.display()
                );
            }
        }
        Ok(())
    }

    fn create_files(
        dir: &Path,
        plan_src: &str,
        header: &[String],
        sync: bool,
        lock: Lock,
    ) -> Result<RunDir> {
        // Whole or not at all: an empty plan.toml (a disk that filled) is not a plan.
        write_atomically(&dir.join(PLAN), plan_src.as_bytes(), sync)?;
        let mut csv = File::create(dir.join(DATA))
            .with_context(|| format!("{}: cannot create", dir.join(DATA).display()))?;
        let mut head = String::new();
        for h in header {
            head.push_str(&format!("# {}\n", comment_text(h)));
        }
        head.push_str(&format!("{},{}\n", REQUIRED.join(","), OPTIONAL.join(",")));
        let dp = dir.join(DATA);
        csv.write_all(head.as_bytes())
            .and_then(|_| csv.sync_all())
            .with_context(|| format!("{}: cannot write", dp.display()))?;
        let journal = File::create(dir.join(JOURNAL))
            .with_context(|| format!("{}: cannot create", dir.join(JOURNAL).display()))?;
        let csv_len = head.len() as u64;
        let mut csv_hash = Fnv::new();
        csv_hash.update(head.as_bytes());
        Ok(RunDir {
            dir: dir.to_path_buf(),
            notes: Vec::new(),
            csv: BufWriter::with_capacity(1 << 16, csv),
            csv_len,
            csv_hash,
            journal,
            journal_len: 0,
            journal_chain: super::journal::START,
            events: Vec::new(),
            sync,
            pending: Vec::new(),
            pending_events: 0,
            last_sync: std::time::Instant::now(),
            unapplied: None,
            plate: None,
            _lock: lock,
        })
    }

    /// Reopen `dir` to continue it with `plan` read from its own `plan.toml`: [`RunDir::resume`]
    /// without a plan file given.
    pub fn open(dir: &Path, sync: bool, plan: &Plan) -> Result<RunDir> {
        RunDir::resume(dir, sync, plan, None)
    }

    /// Reopen `dir` to continue it with `plan`: reads the journal (dropping a torn last line),
    /// checks the plan is the one the run started with (only the timing keys and the
    /// `[metadata]` of [`RESUME_MAY_CHANGE`] may differ from the last session's plan, each
    /// change said in a note) and the committed data are intact, and decides what to cut: `data.csv` back to
    /// the last committed point (said in a note), the journal to its last whole line.
    /// [`RunDir::begin`] makes those changes and positions both files for appending, once the
    /// session goes ahead; nothing is modified before (a check that fails here, or the
    /// caller's own refusal after it, leaves the run directory as it was).
    ///
    /// `plan` is read from the run's `plan.toml`, or from `given` (`--resume RUN --plan FILE`):
    /// the same checks and notes, naming that file; then, when its text differs from the run's
    /// `plan.toml`, it replaces it ([`RunDir::begin`]), so the run directory holds the plan the
    /// run continues with, as it does after `plan.toml` was edited in place.
    pub fn resume(
        dir: &Path,
        sync: bool,
        plan: &Plan,
        given: Option<GivenPlan<'_>>,
    ) -> Result<RunDir> {
        RunDir::resume_recovering(dir, sync, plan, given, false)
    }

    /// [`RunDir::resume`], and with `recover` (`--recover-truncated`) a data file cut short
    /// (fewer bytes than the journal committed) is not refused but resumed from the last
    /// point it still holds whole: that point's bytes, and so every earlier point's, must
    /// have the hash journalled with it (a file whose remaining bytes differ is refused as an
    /// edited one). The journal lines after that point and the data bytes past it are moved
    /// to `RUN_DIR/recovered-N/` ([`JOURNAL_TAIL`], [`DATA_TAIL`]) by [`RunDir::begin`], which
    /// then cuts both files there: the run is as if it had been killed just after that point,
    /// and the points after it are measured again. Said in a note. Without `recover` the
    /// refusal names that point and the command that recovers.
    pub fn resume_recovering(
        dir: &Path,
        sync: bool,
        plan: &Plan,
        given: Option<GivenPlan<'_>>,
        recover: bool,
    ) -> Result<RunDir> {
        let jp = dir.join(JOURNAL);
        let dp = dir.join(DATA);
        match (jp.exists(), dp.exists()) {
            (true, true) => {}
            (false, false) => bail!(
                "{}: not a sweep run directory (no {JOURNAL} and no {DATA}); start a run with --out",
                dir.display()
            ),
            // Half a run: nothing to resume from, and --out --force would delete the half
            // that is left, so it is named and kept.
            (journal, _) => {
                let (have, missing) = if journal { (JOURNAL, DATA) } else { (DATA, JOURNAL) };
                bail!(
                    "{}: has {have} but no {missing}, so the run cannot be resumed (the journal \
                     records what data.csv holds; one without the other cannot be checked). \
                     Restore {missing} if you have it; `--out {} --force` would delete {have}: \
                     copy it away first",
                    dir.display(),
                    dir.display()
                )
            }
        }
        check_writable_run(dir)?;
        let (lock, stale) = Lock::acquire(dir)?;
        let mut notes: Vec<String> = stale.map(took_over).into_iter().collect();
        let super::journal::Read {
            mut events,
            mut good_len,
            line_ends,
            chains,
            mut chain,
        } = super::journal::read(&jp, &mut notes)?;
        // The points are numbered by the plan: continuing with another one would leave points
        // never measured (or measured under other settings) while the run says complete. Each
        // session journals the plan it ran with; the last one is what this session continues.
        // Only the keys that govern waiting and retrying may differ from it (their change is
        // said, and this session journals the plan with it); every other key is the same in
        // all sessions, so it is still the plan the run started with.
        let last = events.iter().rev().find_map(|e| match e {
            Event::Session { plan: Some(p), .. } => Some(p),
            _ => None,
        });
        let pp = dir.join(PLAN);
        // What the plan is compared with: the last session's, or, in a journal of an older
        // version that records none, the run's own plan.toml when another file is given.
        let reference = match (last, given) {
            (Some(v), _) => Some((
                serde_json::from_value::<Plan>(v.clone())
                    .with_context(|| format!("{}: unreadable plan in a session", jp.display()))?,
                jp.display().to_string(),
            )),
            (None, Some(_)) => Some((Plan::load(&pp)?, pp.display().to_string())),
            (None, None) => None,
        };
        // The file the plan was read from, in full (errors) and as said in notes.
        let (file, short) = match given {
            Some(g) => (g.path.display().to_string(), g.path.display().to_string()),
            None => (pp.display().to_string(), PLAN.to_string()),
        };
        match reference {
            Some((was, recorded)) => {
                // Through the same JSON text as the journalled one, so floats compare exactly.
                let now: Plan = serde_json::from_str(&serde_json::to_string(plan)?)?;
                let (timing, refused): (Vec<Change>, Vec<Change>) = now
                    .differences(&was)
                    .into_iter()
                    .partition(Change::resumable);
                let (metadata, timing): (Vec<Change>, Vec<Change>) =
                    timing.into_iter().partition(|c| c.key == "metadata");
                let list = |c: &[Change]| {
                    c.iter()
                        .map(|c| c.to_string())
                        .collect::<Vec<_>>()
                        .join("; ")
                };
                let keys = |c: &[Change]| {
                    c.iter()
                        .map(|c| format!("`{}`", c.key))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                if !refused.is_empty() {
                    bail!(
                        "{file}: the plan was changed since the run started (as recorded in \
                         {recorded}): {}. A resume continues the plan the run started with, whose \
                         point numbers the data use, measuring and recording the points as \
                         before: only the keys that govern waiting and retrying, and the \
                         run's description `[metadata]` ({}) may change{}; not resuming, nothing was changed: {}, or start a new run \
                         with --out for the new plan",
                        list(&refused),
                        RESUME_MAY_CHANGE.join(", "),
                        {
                            let ok = [&timing[..], &metadata[..]].concat();
                            if ok.is_empty() {
                                String::new()
                            } else {
                                format!(" (the change of {} alone would be accepted)", keys(&ok))
                            }
                        },
                        match given {
                            Some(_) => format!(
                                "resume with the run's own {} (leave out --plan)",
                                pp.display()
                            ),
                            None => format!("restore {PLAN}"),
                        },
                    );
                }
                if !timing.is_empty() {
                    notes.push(format!(
                        "{short}: timing changed since the last session (as recorded in {}): \
                         {}; these govern only waiting and retrying, not what is measured or \
                         recorded: the run continues with the new values, journalled with this \
                         session's plan",
                        if last.is_some() { JOURNAL } else { PLAN },
                        list(&timing)
                    ));
                }
                if !metadata.is_empty() {
                    notes.push(format!(
                        "{short}: [metadata] changed since the last session (as recorded in {}): \
                         {}; it describes the run and is not measured: the run continues, \
                         journalled with this session's plan (the earlier sessions keep theirs)",
                        if last.is_some() { JOURNAL } else { PLAN },
                        now.metadata.changes(&was.metadata).join("; ")
                    ));
                }
            }
            None if !events.is_empty() => notes.push(format!(
                "{JOURNAL} records no plan (written by an older version): {PLAN} could not be \
                 checked against the plan the run started with"
            )),
            None => {}
        }
        // Where the plate was last recorded (before any recovery cuts the journal).
        let plate = events.iter().rev().find_map(|e| match e {
            Event::Separation(s) => Some(s.clone()),
            _ => None,
        });
        // The CSV ends where the last committed point ended (or after the header).
        let mut last_point = events.iter().rev().find_map(|e| match e {
            Event::Point { i, csv_end, .. } => Some((*i, *csv_end)),
            _ => None,
        });
        let header_len = match last_point {
            Some(_) => None,
            None => Some(csv_header_len(&dp)?),
        };
        let mut end = last_point.map_or(header_len.unwrap_or(0), |(_, e)| e);
        let csv = OpenOptions::new()
            .write(true)
            .open(&dp)
            .with_context(|| format!("{}: cannot open for writing", dp.display()))?;
        let len = csv
            .metadata()
            .with_context(|| format!("{}: cannot read", dp.display()))?
            .len();
        let mut recovery = None;
        if len < end {
            // Cut short: the last point the file still holds whole, checked; without
            // `recover`, a refusal that names it and the command that recovers.
            let (k, i, whole_end) = whole_points(&dp, &events, len, end, last_point)?;
            if !recover {
                let last = last_point.map_or(0, |(l, _)| l);
                bail!(
                    "{}: {len} bytes, but the journal committed {end} (through point {last}): the \
                     data file was cut short. It still holds points 0 to {i} whole (its first \
                     {whole_end} bytes are as written: checked against the hash journalled with \
                     point {i}); the rows of points {} to {last} are gone from it. Not resuming, \
                     nothing was changed. Put back a copy of {DATA} that holds them, if you have \
                     one, and resume as usual; or continue from point {} with `{} \
                     --recover-truncated`, which measures points {} to {last} again and moves what \
                     it cuts (the journal's lines after point {i}, the {} bytes past it) to {}",
                    dp.display(),
                    i + 1,
                    i + 1,
                    super::resume_command(
                        dir,
                        super::last_session_ports(&events)
                            .as_ref()
                            .map(|(b, s)| (b.as_str(), s.as_str()))
                    ),
                    i + 1,
                    len - whole_end,
                    recovery_folder(dir).display()
                );
            }
            let folder = recovery_folder(dir);
            let last = last_point.map_or(0, |(l, _)| l);
            let cut = events.len() - (k + 1);
            notes.push(format!(
                "{DATA}: cut short at {len} bytes, where the journal committed {end} (through \
                 point {last}): resuming after point {i}, the last it holds whole (its first \
                 {whole_end} bytes checked against the hash journalled with it); points {} to \
                 {last} are measured again. Moved to {}: the journal's {cut} line{} after point \
                 {i} ({JOURNAL_TAIL}: their points, sessions, faults){}",
                i + 1,
                folder.display(),
                if cut == 1 { "" } else { "s" },
                if len > whole_end {
                    format!(
                        " and {DATA}'s {} bytes past it ({DATA_TAIL})",
                        len - whole_end
                    )
                } else {
                    String::new()
                }
            ));
            recovery = Some(Recovery {
                folder,
                journal_from: line_ends[k],
                data_from: whole_end,
            });
            events.truncate(k + 1);
            good_len = line_ends[k];
            chain = chains[k];
            last_point = Some((i, whole_end));
            end = whole_end;
        }
        if last_point.is_none() {
            // Nothing committed: rows past the header can only be a first session's uncommitted
            // leftovers, which come after its `session` line. An empty journal with rows, or a
            // manifest counting committed points, means the journal was emptied or replaced:
            // resuming would start again at point 0 and cut every measurement.
            let (rows, _) = data_lines(&dp, end)?;
            if rows > 0 && events.is_empty() {
                bail!(
                    "{} is empty but {} holds {rows} data rows: the journal was emptied or \
                     replaced, and resuming would delete every measurement; not resuming \
                     (restore the journal, or start a new run with --out)",
                    jp.display(),
                    dp.display()
                );
            }
            let mp = dir.join(MANIFEST);
            let done = std::fs::read_to_string(&mp)
                .ok()
                .and_then(|m| serde_json::from_str::<serde_json::Value>(&m).ok())
                .and_then(|m| m["points"]["done"].as_u64())
                .unwrap_or(0);
            if done > 0 {
                bail!(
                    "{} records no committed point, but {} says {done} were done: the journal was \
                     emptied or replaced, and resuming would delete every measurement; not \
                     resuming (restore the journal, or start a new run with --out)",
                    jp.display(),
                    mp.display()
                );
            }
        }
        // A manifest that saw more points done than the journal commits: the journal lost
        // lines, refused (or, with `recover`, gone ahead, what is past them kept aside).
        if recovery.is_none() {
            let next = last_point.map_or(0, |(i, _)| i + 1);
            if let Some((note, folder)) =
                super::journal::contradiction(dir, &events, next, recover, len.saturating_sub(end))?
            {
                notes.push(note);
                recovery = Some(Recovery {
                    folder,
                    journal_from: good_len,
                    data_from: end,
                });
            } else if recover {
                notes.push(format!(
                    "--recover-truncated: {DATA} holds every committed point ({end} bytes): \
                     nothing to recover"
                ));
            }
        }
        // The committed data must be what was written: a file edited within them (a line
        // inserted, a value changed) would otherwise be cut at the journalled length in the
        // middle of a row, silently.
        let csv_hash = verify_committed(&dp, &events, end)?;
        if len > end && recovery.is_none() {
            // Rows of points whose journal line never made it (the session stopped between
            // the two), or anything appended since: set aside (never deleted: they may be
            // measurements whose journal lines were lost), and said.
            let (rows, comments) = data_lines(&dp, end)?;
            let plural =
                |n: u64, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
            let folder = recovery_folder(dir);
            notes.push(format!(
                "{DATA}: set aside {} ({}, {}) past {}: not committed in the journal (written by \
                 the previous session before it stopped, or added since), moved to {}; {}",
                plural(len - end, "byte"),
                plural(rows, "data row"),
                plural(comments, "comment line"),
                match last_point {
                    Some((i, _)) => format!("the last committed point, {i}"),
                    None => "the header (no committed point)".into(),
                },
                Path::new(folder.file_name().unwrap_or_default())
                    .join(DATA_TAIL)
                    .display(),
                match last_point.map_or(0, |(i, _)| i + 1) {
                    n if n >= plan.len() => {
                        "every point is committed (the run is complete)".to_string()
                    }
                    n => format!("measuring resumes at point {n}"),
                }
            ));
            recovery = Some(Recovery {
                folder,
                journal_from: good_len,
                data_from: end,
            });
        }
        // Every check passed. What the resume changes in the run directory is done by
        // [`RunDir::begin`], once the session goes ahead (the boards answered as the run's
        // did): a plan given as another file becomes the run's plan.toml (as an edit in place
        // would have), so the next resume reads the plan this session continues with; the
        // journal and data.csv are cut back to what was committed.
        let plan_text = given
            .filter(|g| std::fs::read_to_string(&pp).ok().as_deref() != Some(g.text))
            .map(|g| {
                notes.push(format!(
                    "{PLAN}: replaced by {} (--plan), the plan this session continues with",
                    g.path.display()
                ));
                g.text.to_string()
            });
        let journal = OpenOptions::new()
            .write(true)
            .open(&jp)
            .with_context(|| format!("{}: cannot open for writing", jp.display()))?;
        Ok(RunDir {
            dir: dir.to_path_buf(),
            notes,
            csv: BufWriter::with_capacity(1 << 16, csv),
            csv_len: end,
            csv_hash,
            journal,
            journal_len: good_len,
            journal_chain: chain,
            events,
            sync,
            pending: Vec::new(),
            pending_events: 0,
            last_sync: std::time::Instant::now(),
            unapplied: Some(Unapplied {
                plan_text,
                recovery,
            }),
            plate,
            _lock: lock,
        })
    }

    /// Make the changes a resume decided ([`RunDir::resume`]): the given plan written as the
    /// run's plan.toml, the journal cut back to its last whole line and data.csv to the end
    /// of the last committed point, both positioned for appending. Until then the run
    /// directory is as the resume found it, so a session refused after the checks (the boards
    /// answering are not the run's kind, a port that does not open) changes nothing. Done
    /// once; a no-op for a new run. Anything written to the run calls it first.
    pub fn begin(&mut self) -> Result<()> {
        let Some(u) = &self.unapplied else {
            return Ok(());
        };
        let (jp, dp) = (self.dir.join(JOURNAL), self.dir.join(DATA));
        if let Some(r) = &u.recovery {
            // Kept before anything is cut (synced: the cut follows).
            std::fs::create_dir(&r.folder)
                .with_context(|| format!("{}: cannot create", r.folder.display()))?;
            copy_tail(&jp, r.journal_from, &r.folder.join(JOURNAL_TAIL))?;
            copy_tail(&dp, r.data_from, &r.folder.join(DATA_TAIL))?;
            // The folder's entries, then the run folder's entry for the folder itself.
            for d in [&r.folder, &self.dir] {
                if let Ok(d) = File::open(d) {
                    let _ = d.sync_all();
                }
            }
        }
        if let Some(text) = &u.plan_text {
            write_atomically(&self.dir.join(PLAN), text.as_bytes(), self.sync)?;
        }
        let (good_len, end) = (self.journal_len, self.csv_len);
        let journal = &mut self.journal;
        journal
            .set_len(good_len)
            .and_then(|_| journal.seek(SeekFrom::End(0)))
            .and_then(|_| journal.sync_all())
            .with_context(|| format!("{}: cannot cut back to {good_len} bytes", jp.display()))?;
        let csv = self.csv.get_mut();
        csv.set_len(end)
            .and_then(|_| csv.seek(SeekFrom::End(0)))
            .and_then(|_| csv.sync_all())
            .with_context(|| format!("{}: cannot cut back to {end} bytes", dp.display()))?;
        // Only now: until both files are positioned, nothing may be written to them.
        self.unapplied = None;
        Ok(())
    }

    /// Index of the next point to measure (one past the last committed).
    pub fn next_point(&self) -> usize {
        self.events
            .iter()
            .rev()
            .find_map(|e| match e {
                Event::Point { i, .. } => Some(i + 1),
                _ => None,
            })
            .unwrap_or(0)
    }

    /// Number of sessions so far.
    pub fn sessions(&self) -> u32 {
        self.events
            .iter()
            .filter(|e| matches!(e, Event::Session { .. }))
            .count() as u32
    }

    /// Append an event to the journal (after any pending points; synced when configured).
    pub fn log(&mut self, e: Event) -> Result<()> {
        let mut line = serde_json::to_string(&e)?;
        line.push('\n');
        self.pending.extend_from_slice(line.as_bytes());
        self.pending_events += 1;
        self.events.push(e);
        self.sync_now()
    }

    /// Sync `data.csv`, then write and sync the pending journal lines.
    pub fn sync_now(&mut self) -> Result<()> {
        self.begin()?;
        let dp = self.dir.join(DATA);
        self.csv
            .flush()
            .with_context(|| format!("{}: cannot write", dp.display()))?;
        if self.sync {
            self.csv
                .get_ref()
                .sync_data()
                .with_context(|| format!("{}: cannot sync", dp.display()))?;
        }
        if !self.pending.is_empty() {
            let pending = std::mem::take(&mut self.pending);
            self.append_journal(&pending)?;
            self.pending_events = 0;
        }
        self.last_sync = std::time::Instant::now();
        Ok(())
    }

    /// Write whole lines to the journal (synced when configured); on failure the journal is
    /// cut back to its last complete line, so a later line cannot follow a torn one.
    fn append_journal(&mut self, bytes: &[u8]) -> Result<()> {
        self.begin()?;
        let (bytes, chain) = super::journal::seal_lines(self.journal_chain, bytes);
        let bytes = bytes.as_slice();
        let r = self.journal.write_all(bytes).and_then(|_| {
            if self.sync {
                self.journal.sync_data()
            } else {
                Ok(())
            }
        });
        if let Err(e) = r {
            let _ = self.journal.set_len(self.journal_len);
            let _ = self.journal.seek(SeekFrom::Start(self.journal_len));
            return Err(e)
                .with_context(|| format!("{}: cannot write", self.dir.join(JOURNAL).display()));
        }
        self.journal_len += bytes.len() as u64;
        self.journal_chain = chain;
        Ok(())
    }

    /// Record that the session stopped on an error (`reason`), as far as the disk allows.
    /// Points whose rows could not be written and synced stay uncommitted (they are measured
    /// again on resume): their journal lines are dropped, the other pending events are kept.
    pub fn stop_after_failure(&mut self, reason: String) -> Result<()> {
        if self.sync_now().is_err() {
            let start = self.events.len() - self.pending_events;
            let unsynced = self.events.split_off(start);
            self.pending.clear();
            self.pending_events = 0;
            for u in unsynced {
                if !matches!(u, Event::Point { .. }) {
                    let mut line = serde_json::to_string(&u)?;
                    line.push('\n');
                    self.pending.extend_from_slice(line.as_bytes());
                    self.pending_events += 1;
                    self.events.push(u);
                }
            }
        }
        let e = Event::Stop {
            at: now(),
            reason,
            next_point: self.next_point(),
            notes: Vec::new(),
        };
        let mut line = serde_json::to_string(&e)?;
        line.push('\n');
        let mut bytes = std::mem::take(&mut self.pending);
        bytes.extend_from_slice(line.as_bytes());
        self.pending_events = 0;
        self.events.push(e);
        self.append_journal(&bytes)
    }

    /// Commit a point: its comment lines (`# no signal: ...` for each beacon short of its
    /// samples) and rows, then its journal line.
    #[allow(clippy::too_many_arguments)]
    pub fn commit_point(
        &mut self,
        i: usize,
        status: PointStatus,
        rows: &[Sample],
        comments: &[String],
        reports: u32,
        lost: u32,
        attempts: u32,
    ) -> Result<()> {
        self.begin()?;
        let mut buf = Vec::with_capacity(64 * rows.len() + 64);
        for c in comments {
            writeln!(buf, "# {}", comment_text(c))?;
        }
        for r in rows {
            write_row(&mut buf, r)?;
        }
        self.csv
            .write_all(&buf)
            .and_then(|_| self.csv.flush())
            .with_context(|| format!("{}: cannot write", self.dir.join(DATA).display()))?;
        self.csv_len += buf.len() as u64;
        self.csv_hash.update(&buf);
        let e = Event::Point {
            i,
            status,
            samples: rows.len() as u32,
            reports,
            lost,
            attempts,
            csv_end: self.csv_len,
            csv_hash: Some(self.csv_hash.hex()),
            at: Some(now()),
        };
        let mut line = serde_json::to_string(&e)?;
        line.push('\n');
        self.pending.extend_from_slice(line.as_bytes());
        self.pending_events += 1;
        self.events.push(e);
        if !self.sync || self.last_sync.elapsed() >= SYNC_INTERVAL {
            self.sync_now()?;
        }
        Ok(())
    }

    /// Write `manifest.json` (atomically: temp file + rename) from `value`.
    pub fn write_manifest(&self, value: &serde_json::Value) -> Result<()> {
        let mut text = serde_json::to_string_pretty(value)?;
        text.push('\n');
        write_atomically(&self.dir.join(MANIFEST), text.as_bytes(), self.sync)
    }

    /// Path of the measurement file.
    pub fn data_path(&self) -> PathBuf {
        self.dir.join(DATA)
    }
}

/// The plan file given with `cta sweep --resume RUN --plan FILE` ([`RunDir::resume`]).
#[derive(Debug, Clone, Copy)]
pub struct GivenPlan<'a> {
    /// The file.
    pub path: &'a Path,
    /// Its text, as parsed into the plan.
    pub text: &'a str,
}

/// `Err` with the operating system's reason when this process may not write `path`: the
/// permission bits, a file system mounted read-only, an immutable file (`access(2)`, `W_OK`;
/// nothing is opened or changed).
#[cfg(unix)]
fn writable(path: &Path) -> std::io::Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).map_err(std::io::Error::other)?;
    // SAFETY: a read-only query on a NUL-terminated path we own.
    if unsafe { libc::access(c.as_ptr(), libc::W_OK) } == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// `Err` when the file `path` is read-only (its read-only attribute; nothing is opened or
/// changed). Elsewhere than Unix there is no `access(2)`, and Windows does not enforce a
/// folder's read-only attribute: a folder, or an access-control list that refuses writing,
/// is found when the session writes, and named then.
#[cfg(not(unix))]
fn writable(path: &Path) -> std::io::Result<()> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_dir() && meta.permissions().readonly() {
        Err(std::io::Error::new(
            std::io::ErrorKind::PermissionDenied,
            "read-only",
        ))
    } else {
        Ok(())
    }
}

/// A resumed session appends to `data.csv` and the journal, rewrites the lock and (simulated
/// runs) the truth in place, and adds files to the run directory (the manifest through a
/// temporary file, plan.toml likewise): the first of them it may not write is refused before
/// anything is locked, cut or written, naming it and the reason. Without this, a read-only
/// directory with writable files failed only at the manifest, after the resume had cut the
/// uncommitted rows and journalled a session.
fn check_writable_run(dir: &Path) -> Result<()> {
    let files = [DATA, JOURNAL, LOCK, TRUTH].map(|f| dir.join(f));
    let must = std::iter::once(dir.to_path_buf()).chain(files.into_iter().filter(|p| p.exists()));
    for p in must {
        if let Err(e) = writable(&p) {
            bail!(
                "{}: cannot write: {e}. A resumed session writes in the run directory {} ({DATA}, \
                 {JOURNAL}, {MANIFEST} through a temporary file): not resuming, nothing was \
                 changed; make it and its files writable again (e.g. chmod -R u+w), or copy the \
                 run to a writable place and resume the copy",
                p.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// Write `path` whole or not at all: through `.NAME.tmp` in the same directory, synced when
/// `sync`, renamed into place.
fn write_atomically(path: &Path, bytes: &[u8], sync: bool) -> Result<()> {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    (|| {
        let mut f = File::create(&tmp)?;
        f.write_all(bytes)?;
        if sync {
            f.sync_all()?;
        }
        std::fs::rename(&tmp, path)
    })()
    .with_context(|| {
        format!(
            "{}: cannot write (through {})",
            path.display(),
            tmp.display()
        )
    })
}

impl Drop for RunDir {
    fn drop(&mut self) {
        // A resume that never began leaves the run directory as it found it.
        if self.unapplied.is_none() {
            let _ = self.sync_now();
        }
    }
}

/// Check `data.csv`'s committed bytes (up to `end`) against the prefix hashes journalled with
/// the points; returns the hash of the first `end` bytes. Nothing is modified.
fn verify_committed(path: &Path, events: &[Event], end: u64) -> Result<Fnv> {
    let f = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut r = BufReader::with_capacity(1 << 16, f);
    let mut hash = Fnv::new();
    let mut pos = 0u64;
    let feed = |r: &mut BufReader<File>, hash: &mut Fnv, mut n: u64| -> Result<()> {
        while n > 0 {
            let buf = r
                .fill_buf()
                .with_context(|| format!("{}: cannot read", path.display()))?;
            if buf.is_empty() {
                bail!("{}: shorter than the journal says", path.display());
            }
            let k = buf.len().min(n as usize);
            hash.update(&buf[..k]);
            r.consume(k);
            n -= k as u64;
        }
        Ok(())
    };
    let mut good: Option<(usize, u64)> = None;
    for e in events {
        let Event::Point {
            i,
            csv_end,
            csv_hash: Some(h),
            ..
        } = e
        else {
            continue;
        };
        if *csv_end < pos || *csv_end > end {
            bail!(
                "{}: point {i} ends at byte {csv_end}, out of order with the other points: the \
                 journal was edited; not resuming",
                path.parent().unwrap_or(path).join(JOURNAL).display()
            );
        }
        feed(&mut r, &mut hash, csv_end - pos)?;
        pos = *csv_end;
        if hash.hex() != *h {
            bail!(
                "{}: the committed data are not what was written: the file differs from the journal \
                 within its first {csv_end} bytes (the rows up to point {i}; {}): it was edited or \
                 replaced since. Not resuming, nothing was changed: restore {DATA} as it was \
                 written, or start a new run with --out",
                path.display(),
                match good {
                    Some((k, b)) => format!("it matches up to point {k}, byte {b}"),
                    None => "already at the first committed point".into(),
                }
            );
        }
        good = Some((*i, *csv_end));
    }
    feed(&mut r, &mut hash, end - pos)?;
    Ok(hash)
}

/// Copy `from`'s bytes past `start` to a new file `to`, synced (an empty tail makes an empty
/// file: the folder says what was cut, even when nothing of the data was).
fn copy_tail(from: &Path, start: u64, to: &Path) -> Result<()> {
    (|| -> std::io::Result<()> {
        let mut src = File::open(from)?;
        src.seek(SeekFrom::Start(start))?;
        let mut dst = OpenOptions::new().write(true).create_new(true).open(to)?;
        std::io::copy(&mut src, &mut dst)?;
        dst.sync_all()
    })()
    .with_context(|| {
        format!(
            "{}: cannot keep what the recovery cuts from {}",
            to.display(),
            from.display()
        )
    })
}

/// For a data file cut short to `len` bytes (the journal committed `end`, through
/// `last_point`): the last point it still holds whole, as (its event's index in `events`, its
/// point index, its end), once its first bytes are checked against the hash journalled with
/// it (which covers every earlier point's). Refused, saying why, when none is whole, when the
/// journal has no hash to check with (an older version), or when the bytes differ.
fn whole_points(
    dp: &Path,
    events: &[Event],
    len: u64,
    end: u64,
    last_point: Option<(usize, u64)>,
) -> Result<(usize, usize, u64)> {
    let last = last_point.map_or(0, |(l, _)| l);
    let short = format!(
        "{}: {len} bytes, but the journal committed {end} (through point {last}): the data file \
         was cut short",
        dp.display()
    );
    let whole = events.iter().enumerate().rev().find_map(|(k, e)| match e {
        Event::Point { i, csv_end, .. } if *csv_end <= len => Some((k, *i, *csv_end)),
        _ => None,
    });
    let Some((k, i, whole_end)) = whole else {
        bail!(
            "{short}, and holds no committed point whole (point 0 ends at byte {}). Not \
             resuming, nothing was changed: put back a copy of {DATA} that holds the committed \
             points, or start a new run with --out",
            events
                .iter()
                .find_map(|e| match e {
                    Event::Point { csv_end, .. } => Some(*csv_end),
                    _ => None,
                })
                .unwrap_or(end)
        );
    };
    if !matches!(
        &events[k],
        Event::Point {
            csv_hash: Some(_),
            ..
        }
    ) {
        bail!(
            "{short}. The journal (of an older version) has no hash to check what the file still \
             holds against. Not resuming, nothing was changed: put back a copy of {DATA} that \
             holds the committed points, or start a new run with --out"
        );
    }
    // Every hashed point up to it: a file replaced or edited within them is refused here.
    verify_committed(dp, &events[..=k], whole_end).with_context(|| short.clone())?;
    Ok((k, i, whole_end))
}

/// Data rows and comment lines (blank lines aside) in `path` from byte `from`.
fn data_lines(path: &Path, from: u64) -> Result<(u64, u64)> {
    let mut f = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    f.seek(SeekFrom::Start(from))
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut r = BufReader::new(f);
    let mut line = Vec::new();
    let (mut rows, mut comments) = (0, 0);
    loop {
        line.clear();
        let n = r
            .read_until(b'\n', &mut line)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        if n == 0 {
            return Ok((rows, comments));
        }
        if line.starts_with(b"#") {
            comments += 1;
        } else if !line.trim_ascii().is_empty() {
            rows += 1;
        }
    }
}

/// Length of the comment and header lines at the top of a measurement file.
fn csv_header_len(path: &Path) -> Result<u64> {
    let f = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    let mut r = BufReader::new(f);
    let mut len = 0u64;
    let mut line = String::new();
    loop {
        line.clear();
        let n = r
            .read_line(&mut line)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        if n == 0 {
            bail!("{}: no header line", path.display());
        }
        len += n as u64;
        if !line.starts_with('#') && !line.trim().is_empty() {
            return Ok(len);
        }
    }
}

#[cfg(test)]
mod tests;
