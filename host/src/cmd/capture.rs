//! A command's report into a file instead of the terminal: `cta demo` keeps each step's full
//! output (tables, notes, warnings) in its folder and prints a summary that fits one screen.

use anyhow::{Context, Result};
use std::io::Write;
use std::path::Path;

/// Run `f` with the process's standard output and error going to `log` (created or
/// truncated), then restore them, whatever `f` returns. An error of `f` is returned as it is
/// (the caller prints it on the restored terminal), with the log's path for the details.
#[cfg(unix)]
pub fn to_file<T>(log: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    use std::os::unix::io::AsRawFd;
    let file =
        std::fs::File::create(log).with_context(|| format!("{}: cannot write", log.display()))?;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    // SAFETY: dup/dup2/close on the process's own descriptors 1 and 2 and on `file`'s, which
    // lives until after they are restored; no Rust handle owns the duplicates.
    let saved = unsafe { [libc::dup(1), libc::dup(2)] };
    if saved.iter().any(|&fd| fd < 0) {
        unsafe {
            saved.iter().filter(|&&fd| fd >= 0).for_each(|&fd| {
                libc::close(fd);
            });
        }
        // Cannot redirect: run on the terminal rather than not at all.
        return f();
    }
    unsafe {
        libc::dup2(file.as_raw_fd(), 1);
        libc::dup2(file.as_raw_fd(), 2);
    }
    let r = f();
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    unsafe {
        libc::dup2(saved[0], 1);
        libc::dup2(saved[1], 2);
        libc::close(saved[0]);
        libc::close(saved[1]);
    }
    r.with_context(|| format!("its report so far: {}", log.display()))
}

/// Elsewhere the step's report stays on the terminal (the demo's simulated boards need Unix
/// pseudo-terminals, so it stops before this on Windows).
#[cfg(not(unix))]
pub fn to_file<T>(_log: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    f()
}

/// The first line of the text file `log` that contains `needle`, trimmed (none when the file
/// or the line is missing).
pub fn line_with(log: &Path, needle: &str) -> Option<String> {
    std::fs::read_to_string(log)
        .ok()?
        .lines()
        .find(|l| l.contains(needle))
        .map(|l| l.trim().to_string())
}

/// The lines of `log` that start with `warning:`.
pub fn warnings(log: &Path) -> usize {
    std::fs::read_to_string(log)
        .map(|t| {
            t.lines()
                .filter(|l| l.trim_start().starts_with("warning:") || l.contains(": warning: "))
                .count()
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both streams of a step land in its log, the terminal's are back afterwards, and an
    /// error names the log.
    #[test]
    #[cfg(unix)]
    fn a_steps_output_goes_to_its_log_and_the_terminal_comes_back() {
        let d = std::env::temp_dir().join(format!("cta-capture-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let log = d.join("step.txt");
        // Written to the descriptors (the test harness captures `println!` itself).
        let v = to_file(&log, || {
            writeln!(std::io::stdout(), "table row 1")?;
            writeln!(std::io::stderr(), "warning: something to see")?;
            Ok(7)
        })
        .unwrap();
        assert_eq!(v, 7);
        let text = std::fs::read_to_string(&log).unwrap();
        assert!(
            text.contains("table row 1") && text.contains("warning: something"),
            "{text}"
        );
        assert_eq!(line_with(&log, "row"), Some("table row 1".into()));
        assert_eq!(warnings(&log), 1);
        let e = to_file(&log, || -> Result<()> { anyhow::bail!("broke") }).unwrap_err();
        assert!(format!("{e:#}").contains("step.txt"), "{e:#}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
