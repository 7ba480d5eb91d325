//! Helpers shared by the `cta` binary's end-to-end tests (host/tests/*.rs): run the binary,
//! a fresh scratch folder, simulate a file, parse JSON output, a simulated board on a pty.
// Each test file uses some of them.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Output, Stdio};

/// Run the `cta` binary with `args`.
pub fn cta(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cta"))
        .args(args)
        .output()
        .expect("run cta")
}

/// A fresh, empty scratch folder `cta-<tag>-<pid>-<name>` in the temp dir. Dropping it
/// removes it, unless the test is failing (panicking): a failed test leaves its files to
/// look at.
pub fn tmpdir_of(tag: &str, name: &str) -> TmpDir {
    let d = std::env::temp_dir().join(format!("cta-{tag}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TmpDir(d)
}

/// [`tmpdir_of`]'s folder.
#[derive(Debug)]
pub struct TmpDir(PathBuf);

impl std::ops::Deref for TmpDir {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TmpDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TmpDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A path as the `&str` an argument list takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `o` succeeded; its stdout parsed as JSON.
pub fn json(o: &Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("JSON output")
}

/// `cta simulate --out OUT ARGS...`, which must succeed.
pub fn simulate(out: &Path, args: &[&str]) {
    let mut all = vec!["simulate", "--out", s(out)];
    all.extend_from_slice(args);
    let o = cta(&all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `cta simulate` at 0.1 % of beta (32.8 counts) on `seps` (a list or range), `samples` per
/// point, `seed`, and `extra` arguments.
pub fn simulate_at(out: &Path, seps: &str, samples: &str, seed: &str, extra: &[&str]) {
    let mut args = vec![
        "--separations",
        seps,
        "--noise",
        "32.8",
        "--samples",
        samples,
        "--seed",
        seed,
    ];
    args.extend_from_slice(extra);
    simulate(out, &args);
}

/// `o`'s stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `o` failed, without a panic, with one line holding every needle.
pub fn fails_in_one_line(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks `{n}`: {err}");
    }
}

/// A simulated board served on a pty by `cta <board> sim ...` (killed when dropped).
pub struct Sim {
    child: Child,
    // Kept open so the board's own prints never hit a closed pipe.
    _out: BufReader<ChildStdout>,
    /// The pty it serves.
    pub path: String,
}

impl Sim {
    /// `cta ARGS --seconds 120`, from the current folder.
    pub fn start(args: &[&str]) -> Sim {
        Sim::start_in(Path::new("."), args)
    }

    /// The same, run in `dir` (its relative paths are `dir`'s).
    pub fn start_in(dir: &Path, args: &[&str]) -> Sim {
        let mut child = Command::new(env!("CARGO_BIN_EXE_cta"))
            .args(args)
            .args(["--seconds", "120"])
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start the simulated board");
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        // "simulated ... board on /dev/pts/N"
        let path = line.trim().rsplit(' ').next().unwrap().to_string();
        assert!(path.starts_with("/dev/"), "{line}");
        Sim {
            child,
            _out: out,
            path,
        }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
