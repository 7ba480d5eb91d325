//! Helpers shared by the `cta` binary's end-to-end tests (cli.rs, glitches.rs, wiring.rs):
//! run the binary, a fresh scratch folder, simulate a file, parse JSON output.
// Each test file uses some of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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
