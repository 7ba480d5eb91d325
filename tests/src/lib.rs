//! Shared helpers for the integration tests.
//!
//! The sweep tests (`tests/sweep_*.rs`) share:
//!
//! * a fresh directory per test, removed when the test passes: [`TestDir`];
//! * the plan file in it and the arguments of a quiet sweep or resume: [`write_plan`],
//!   [`sweep_args`], [`resume_args`];
//! * this test binary re-executed as a child process that runs one test (a sweep that can be
//!   killed, interrupted or run under a file size limit): [`child`], [`child_in_shell`],
//!   [`child_paths`];
//! * readers of what a run leaves on disk: [`journal`], [`journal_points`], [`older_journal`],
//!   [`journal_field`], [`data_lines`], [`data_rows`], [`assert_same_data`], [`snapshot`];
//! * a run made to look killed mid-way: [`crash_after`].

use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::Command;

use cta_cli::cmd::sweep::SweepArgs;
use cta_lab::sweep::{self, SweepOptions};

/// A fresh, empty directory for one test: `$TMPDIR/cta-NAME-PID`, emptied if a previous run
/// left it. Dropping it removes it, unless the test is failing (panicking): a failed test
/// leaves its files to look at. `NAME` must be unique among the tests of one test binary
/// (they run in parallel, in one process).
#[derive(Debug)]
pub struct TestDir(PathBuf);

impl TestDir {
    /// Create (or empty) the directory for the test `name`.
    pub fn new(name: &str) -> TestDir {
        let d = std::env::temp_dir().join(format!("cta-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        TestDir(d)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Deref for TestDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TestDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A plan slow enough (the simulated sensor at 50 Hz in real time, two samples per point)
/// that a run is still going when a test interrupts it a few points in.
pub const SLOW_PLAN: &str = r#"
name = "slow test"
separations_in = "10..30"
beacons = "all"
samples = 2
settle_ms = 0
rate_hz = 50
"#;

/// Write `text` to `dir/plan.toml`; returns its path.
pub fn write_plan(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("plan.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A sweep of `plan` into `out` on the simulated CTA, everything else the command's defaults.
/// Tests add what they need: `SweepOptions { sim_seed: Some(5), ..sweep_args(&plan, &out) }`.
pub fn sweep_args(plan: &Path, out: &Path) -> SweepOptions {
    SweepOptions {
        plan: Some(plan.to_path_buf()),
        out: Some(out.to_path_buf()),
        ..Default::default()
    }
}

/// A resume of `run`: the run's own plan and simulation settings.
pub fn resume_args(run: &Path) -> SweepOptions {
    SweepOptions {
        resume: Some(run.to_path_buf()),
        ..Default::default()
    }
}

/// `cta sweep --plan PLAN --out OUT --quiet`, as the command line reads it (for tests of the
/// command: its signal handling, exit status and summary).
pub fn sweep_cli_args(plan: &Path, out: &Path) -> SweepArgs {
    SweepArgs {
        plan: Some(plan.to_path_buf()),
        out: Some(out.to_path_buf()),
        quiet: true,
        ..Default::default()
    }
}

/// Arguments that make a Rust test binary run only the test `test`, printing what it prints.
fn only(test: &str) -> [&str; 4] {
    [test, "--exact", "--nocapture", "--test-threads=1"]
}

/// The value of `var` that hands `paths` to a child test ([`child_paths`] reads it).
fn joined(paths: &[&Path]) -> String {
    let s: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
    assert!(s.iter().all(|p| !p.contains('|')), "{s:?}: a path with `|`");
    s.join("|")
}

/// This test binary, to be started as a child process that runs only the test `test`, with
/// the environment variable `var` giving it `paths` (read with [`child_paths`]). The child
/// test does its work only when `var` is set, so it passes at once in the ordinary run; the
/// parent can kill it, interrupt it or read its output and exit status. The child's temporary
/// folder (`TMPDIR`, where a simulated CTA keeps its pseudo-terminal links) is the folder of
/// the first path, so a child killed before it could clean up leaves nothing behind outside
/// the test's own folder.
pub fn child(test: &str, var: &str, paths: &[&Path]) -> Command {
    let mut c = Command::new(std::env::current_exe().unwrap());
    c.args(only(test)).env(var, joined(paths));
    with_tmpdir(&mut c, paths);
    c
}

/// Sets the child's `TMPDIR` to the folder of the first path ([`child`]).
fn with_tmpdir(c: &mut Command, paths: &[&Path]) {
    if let Some(dir) = paths.first().and_then(|p| p.parent()) {
        c.env("TMPDIR", dir);
    }
}

/// [`child`], started by `sh -c 'SETUP && exec ...'`: `setup` (e.g. `ulimit -f 48`) applies
/// to the child test, not to this process.
pub fn child_in_shell(setup: &str, test: &str, var: &str, paths: &[&Path]) -> Command {
    let mut c = Command::new("sh");
    c.args(["-c", &format!("{setup} && exec \"$0\" \"$@\"")])
        .arg(std::env::current_exe().unwrap())
        .args(only(test))
        .env(var, joined(paths));
    with_tmpdir(&mut c, paths);
    c
}

/// In a child test started by [`child`] or [`child_in_shell`]: the `N` paths it was given in
/// `var` (`let Some([out, plan]) = child_paths("VAR") else { return };`). `None` when `var`
/// is not set: the ordinary test run, in which the child test returns at once. Panics when
/// `var` holds another number of paths.
pub fn child_paths<const N: usize>(var: &str) -> Option<[PathBuf; N]> {
    let v = std::env::var(var).ok()?;
    let paths: Vec<PathBuf> = v.split('|').map(PathBuf::from).collect();
    Some(
        paths
            .try_into()
            .unwrap_or_else(|_| panic!("{var}={v}: expected {N} paths")),
    )
}

/// `RUN/journal.jsonl`; empty while it does not exist.
pub fn journal(run: &Path) -> String {
    std::fs::read_to_string(run.join("journal.jsonl")).unwrap_or_default()
}

/// Points committed so far in `RUN/journal.jsonl` (its `point` lines); 0 while it does not
/// exist. Reads a journal that a running sweep is writing.
pub fn journal_points(run: &Path) -> usize {
    journal(run).matches("\"event\":\"point\"").count()
}

/// The number in field `key` of a journal line:
/// `journal_field(r#"{"event":"point","i":7,"status":"ok"}"#, "i") == 7`. Panics when the
/// line has no such number.
pub fn journal_field(line: &str, key: &str) -> u64 {
    let k = format!("\"{key}\":");
    let at = line
        .find(&k)
        .unwrap_or_else(|| panic!("no `{key}` in {line}"))
        + k.len();
    line[at..]
        .split([',', '}'])
        .next()
        .unwrap()
        .parse()
        .unwrap_or_else(|e| panic!("`{key}` in {line}: {e}"))
}

/// The journal of `run` cut back to its first `points` point lines, as if the session had been
/// killed with the data of the later points written but their journal lines not (`data.csv`
/// keeps them: a resume sets them aside and measures those points again), and its manifest
/// saying no more than `points` were done (a killed session's manifest is the one it wrote
/// when it started). Returns the length of `data.csv` the last point kept committed.
pub fn crash_after(run: &Path, points: usize) -> u64 {
    let j = journal(run);
    let mut kept = String::new();
    let mut n = 0;
    let mut end = 0;
    for l in j.lines() {
        if l.contains("\"event\":\"point\"") {
            if n == points {
                break;
            }
            n += 1;
            end = journal_field(l, "csv_end");
        }
        kept.push_str(l);
        kept.push('\n');
    }
    std::fs::write(run.join("journal.jsonl"), kept).unwrap();
    let mp = run.join("manifest.json");
    if let Ok(m) = std::fs::read_to_string(&mp) {
        if let Some(at) = m.find("\"done\": ") {
            let from = at + "\"done\": ".len();
            let to = from + m[from..].find(|c: char| !c.is_ascii_digit()).unwrap();
            std::fs::write(&mp, format!("{}{points}{}", &m[..from], &m[to..])).unwrap();
        }
    }
    end
}

/// Every file in `dir` (not in its subfolders) with its bytes and permission bits, by name:
/// two snapshots compare equal when nothing in the folder was written, cut, added or removed.
pub fn snapshot(dir: &Path) -> Vec<(String, u32, Vec<u8>)> {
    use std::os::unix::fs::PermissionsExt;
    let mut files: Vec<(String, u32, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let mode = e.metadata().unwrap().permissions().mode();
            let bytes = if e.file_type().unwrap().is_file() {
                std::fs::read(e.path()).unwrap()
            } else {
                Vec::new()
            };
            (e.file_name().to_string_lossy().into_owned(), mode, bytes)
        })
        .collect();
    files.sort();
    files
}

/// The lines of `RUN/data.csv` after its first, which names the plan file the run was
/// started with (so two runs of one plan from different places compare equal), without the
/// clock columns ([`without_clock`]).
pub fn data_lines(run: &Path) -> Vec<String> {
    without_clock(&std::fs::read_to_string(sweep::data_path(run)).unwrap())
        .lines()
        .skip(1)
        .map(String::from)
        .collect()
}

/// A measurement file's text without its clock columns, `time_s` and `report`: when each report
/// was taken and the board's counter differ from one run of a plan to the next (a resumed run
/// took its later points later, on a board whose counter started again), every measured value
/// does not.
pub fn without_clock(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut drop: Vec<usize> = Vec::new();
    let mut header = false;
    for line in text.split_inclusive('\n') {
        let body = line.trim_end_matches(['\n', '\r']);
        if body.starts_with('#') || body.is_empty() {
            out.push_str(line);
            continue;
        }
        let fields: Vec<&str> = body.split(',').collect();
        if !header {
            header = true;
            drop = fields
                .iter()
                .enumerate()
                .filter(|(_, f)| **f == "time_s" || **f == "report")
                .map(|(k, _)| k)
                .collect();
        }
        let kept: Vec<&str> = fields
            .iter()
            .enumerate()
            .filter(|(k, _)| !drop.contains(k))
            .map(|(_, f)| *f)
            .collect();
        out.push_str(&kept.join(","));
        out.push_str(&line[body.len()..]);
    }
    out
}

/// The sample rows of `RUN/data.csv`: its lines but the comments (header comments, "no
/// signal" and "partial" lines).
pub fn data_rows(run: &Path) -> Vec<String> {
    data_lines(run)
        .into_iter()
        .filter(|l| !l.starts_with('#'))
        .collect()
}

/// `run`'s `data.csv` is `expected`'s, line for line after the first, the clock columns left
/// out ([`data_lines`]); otherwise panics with the first line that differs.
#[track_caller]
pub fn assert_same_data(expected: &Path, run: &Path) {
    let (a, b) = (data_lines(expected), data_lines(run));
    if let Some(k) = (0..a.len().min(b.len())).find(|&k| a[k] != b[k]) {
        panic!(
            "{} differs from {} at line {}:\n{}\n{}",
            sweep::data_path(run).display(),
            sweep::data_path(expected).display(),
            k + 2,
            b[k],
            a[k]
        );
    }
    assert_eq!(
        a.len(),
        b.len(),
        "{} and {}: lines",
        sweep::data_path(expected).display(),
        sweep::data_path(run).display()
    );
}

/// A journal as an older version wrote it, without the check (`"chain"`) that ends each line
/// now: for tests of what a resume does with the journals of older versions, whose lines
/// they edit.
pub fn older_journal(text: &str) -> String {
    text.split_inclusive('\n')
        .map(|l| match l.rfind(",\"chain\":\"") {
            Some(k) => format!("{}}}\n", &l[..k]),
            None => l.to_string(),
        })
        .collect()
}
