//! `cta beacon` and `cta sensor` end to end: against the simulated boards (on a pty, or in
//! process with `--sim`), the connection options only where a board is talked to, flags
//! checked up front, and every documented command line still parsing.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Output, Stdio};

fn cta(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cta"))
        .args(args)
        .output()
        .expect("run cta")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `o` succeeded; its stdout.
fn ok(o: &Output) -> String {
    assert!(o.status.success(), "failed: {}", stderr(o));
    stdout(o)
}

/// `o` failed without a panic and its stderr contains every needle.
fn fails_with(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert!(
        !o.status.success(),
        "expected failure, got success: {}",
        stdout(o)
    );
    assert!(!err.contains("panicked"), "panic: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks `{n}`: {err}");
    }
}

/// A simulated board served on a pty by `cta <board> sim` (killed when dropped).
struct Sim {
    child: Child,
    // Kept open so the board's own prints never hit a closed pipe.
    _out: BufReader<ChildStdout>,
    path: String,
}

impl Sim {
    fn start(args: &[&str]) -> Sim {
        let mut child = Command::new(env!("CARGO_BIN_EXE_cta"))
            .args(args)
            .args(["--seconds", "120"])
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

#[test]
fn beacon_limits_keep_the_value_not_given() {
    let sim = Sim::start(&["beacon", "sim"]);
    let p = sim.path.as_str();
    let out = ok(&cta(&[
        "beacon",
        "--port",
        p,
        "limits",
        "--max-lit",
        "40",
        "--deadman-ms",
        "30000",
    ]));
    assert!(out.contains("cap 40 LEDs, dead-man 30000 ms"), "{out}");
    // Only the cap: the dead-man stays at 30 s (it used to fall back to 10 s).
    let out = ok(&cta(&["beacon", "--port", p, "limits", "--max-lit", "3"]));
    assert!(out.contains("cap 3 LEDs, dead-man 30000 ms"), "{out}");
    // Only the dead-man (the cap used to be required).
    let out = ok(&cta(&[
        "beacon",
        "--port",
        p,
        "limits",
        "--deadman-ms",
        "20000",
    ]));
    assert!(out.contains("cap 3 LEDs, dead-man 20000 ms"), "{out}");
    let out = ok(&cta(&["beacon", "--port", p, "status"]));
    assert!(out.contains("(cap 3)") && out.contains("20000 ms"), "{out}");
    // Neither: refused before talking to the board.
    fails_with(
        &cta(&["beacon", "--port", p, "limits"]),
        &["--max-lit", "--deadman-ms"],
    );
}

#[test]
fn beacon_errors_name_the_command_and_the_id_range() {
    let sim = Sim::start(&["beacon", "sim"]);
    let p = sim.path.as_str();
    ok(&cta(&["beacon", "--port", p, "limits", "--max-lit", "2"]));
    fails_with(
        &cta(&["beacon", "--port", p, "set-many", "0=on", "1=on", "2=on"]),
        &["the cap is 2", "`cta beacon limits --max-lit N`"],
    );
    fails_with(
        &cta(&["beacon", "--port", p, "set-many", "100=on"]),
        &["unknown beacon 100 (ids are 0..=99)"],
    );
    // `set` checks the id itself; its help gives the range 100 is not in.
    fails_with(
        &cta(&["beacon", "--port", p, "set", "100", "on"]),
        &["100 is not in 0..=99"],
    );
    ok(&cta(&["beacon", "--port", p, "set", "99", "on"]));
    let help = ok(&cta(&["beacon", "set", "--help"]));
    assert!(
        help.contains("(0-99)") && !help.contains("0..100"),
        "{help}"
    );
}

#[test]
fn beacon_connection_options_only_where_a_board_is_talked_to() {
    for sub in ["pins", "measure", "sim"] {
        let help = ok(&cta(&["beacon", sub, "--help"]));
        for opt in ["--port", "--timeout-ms", "--retries"] {
            assert!(
                !help.contains(opt),
                "`beacon {sub} --help` offers {opt}: {help}"
            );
        }
        fails_with(
            &cta(&["beacon", sub, "--port", "/dev/null"]),
            &["unexpected argument '--port'"],
        );
    }
    fails_with(
        &cta(&["beacon", "--port", "/dev/null", "pins"]),
        &["--port means nothing for `cta beacon pins`"],
    );
    fails_with(
        &cta(&["beacon", "--retries", "1", "--timeout-ms", "100", "measure"]),
        &["--timeout-ms, --retries mean nothing for `cta beacon measure`"],
    );
    let help = ok(&cta(&["beacon", "status", "--help"]));
    assert!(
        help.contains("--port") && help.contains("--retries"),
        "{help}"
    );
    // Before or after the subcommand, not both.
    let sim = Sim::start(&["beacon", "sim"]);
    let p = sim.path.as_str();
    let out = ok(&cta(&["beacon", "identify", "--port", p, "--retries", "1"]));
    assert!(
        out.contains("beacon board") && out.contains("(simulated)"),
        "{out}"
    );
    fails_with(
        &cta(&["beacon", "--port", p, "identify", "--port", p]),
        &["--port is given both before and after the subcommand"],
    );
}
