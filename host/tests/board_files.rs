//! `cta sensor` with the wrong kind of file, its status in words, and its `--retries`.

use std::process::Output;

mod common;
use common::{cta, fails_in_one_line, s, simulate, stderr};

fn tmpdir(name: &str) -> common::TmpDir {
    common::tmpdir_of("board-files", name)
}

/// `o` succeeded; its stdout.
fn ok(o: &Output) -> String {
    assert!(o.status.success(), "failed: {}", stderr(o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The audit's case: `load-calibration fit.json` said "missing field `d` at line 88 column 1"
/// (the fit has `d` under `params`). Each kind of file `cta` writes, loaded where another
/// belongs, is named, with the command or file that is wanted.
#[test]
fn a_file_of_another_kind_is_named_with_what_to_do() {
    let d = tmpdir("kinds");
    let csv = d.join("sim.csv");
    simulate(&csv, &["--separations", "25,30"]);
    let fit = d.join("fit.json");
    ok(&cta(&["fit", s(&csv), "--save", s(&fit)]));
    let con = d.join("con.json");
    std::fs::write(&con, ok(&cta(&["sensor", "template", "constellation"]))).unwrap();
    let cal = d.join("cal.json");
    std::fs::write(&cal, ok(&cta(&["sensor", "template", "calibration"]))).unwrap();
    let load = |what: &str, file: &std::path::Path| cta(&["sensor", "--sim", what, s(file)]);
    fails_in_one_line(
        &load("load-calibration", &fit),
        &[
            "this is a saved fit (`cta fit --save`",
            "not a sensor board calibration",
            &format!("`cta calibrate {} --out cal.json`", s(&csv)),
        ],
    );
    fails_in_one_line(
        &load("load-calibration", &con),
        &[
            "this is a constellation",
            &format!("load-constellation {}", s(&con)),
        ],
    );
    fails_in_one_line(
        &load("load-constellation", &cal),
        &[
            "this is a sensor calibration",
            "not a sensor board constellation",
            &format!("load-calibration {}", s(&cal)),
        ],
    );
    fails_in_one_line(
        &load("load-constellation", &fit),
        &["this is a saved fit", "`cta sensor template constellation"],
    );
    fails_in_one_line(
        &load("load-calibration", &csv),
        &[
            "this is a measurement file (CSV)",
            &format!("`cta calibrate {} --out cal.json`", s(&csv)),
        ],
    );
    fails_in_one_line(
        &load("load-calibration", &d.join("sim.truth.json")),
        &["truth sidecar", "`cta sensor sim --truth"],
    );
    // A file of the right kind with a bad value keeps its own message.
    let bad = d.join("bad.json");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&cal)
            .unwrap()
            .replacen("\"d\": [", "\"d\": [[", 1),
    )
    .unwrap();
    fails_in_one_line(
        &load("load-calibration", &bad),
        &["not a valid JSON document of the expected shape"],
    );
    // And the right files load.
    ok(&load("load-calibration", &cal));
    ok(&load("load-constellation", &con));
}

/// The audit's case: `cta sensor status` printed `last pose Some(Ok)` / `None` (Rust's debug
/// text). It prints words now, before and after a pose.
#[test]
fn sensor_status_says_the_last_pose_in_words() {
    let out = ok(&cta(&["sensor", "--sim", "status"]));
    let line = |out: &str, key: &str| {
        out.lines()
            .find(|l| l.starts_with(key))
            .unwrap_or_else(|| panic!("no `{key}` line: {out}"))
            .to_string()
    };
    assert_eq!(
        line(&out, "last pose"),
        "last pose       none (no pose solved since the board started)"
    );
    assert_eq!(line(&out, "mode"), "mode            Idle");
    assert_eq!(line(&out, "last reset"), "last reset      power-on");
    // Killed when dropped, also when an assert below fails.
    let sim = common::Sim::start(&["sensor", "sim", "--configured"]);
    let port = sim.path.clone();
    ok(&cta(&["sensor", "--port", &port, "pose", "--count", "1"]));
    let out = ok(&cta(&["sensor", "--port", &port, "status"]));
    assert_eq!(line(&out, "last pose"), "last pose       Ok (converged)");
    assert!(!out.contains("Some("), "{out}");
}

/// `cta sensor` takes `--retries` as `cta beacon` does (the link's resends after a timeout,
/// before or after the subcommand): against a port nobody answers, the attempts follow it.
#[test]
#[cfg(unix)] // A port nobody answers: a pty.
fn sensor_retries_sets_the_links_resends() {
    use serialport::SerialPort as _;
    let (_master, slave) = serialport::TTYPort::pair().expect("a pseudo-terminal");
    let port = slave.name().unwrap();
    for (retries, attempts) in [("0", "1 attempt(s)"), ("3", "4 attempt(s)")] {
        fails_in_one_line(
            &cta(&[
                "sensor",
                "--port",
                &port,
                "--timeout-ms",
                "30",
                "--retries",
                retries,
                "status",
            ]),
            &[&format!(
                "no reply from the board after {attempts} of 30ms each"
            )],
        );
    }
    fails_in_one_line(
        &cta(&["sensor", "status", "--port", &port, "--timeout-ms", "30"]),
        &["after 3 attempt(s)"],
    );
    fails_in_one_line(
        &cta(&[
            "sensor",
            "--retries",
            "1",
            "status",
            "--retries",
            "2",
            "--port",
            &port,
        ]),
        &["--retries is given both before and after the subcommand"],
    );
    fails_in_one_line(
        &cta(&["sensor", "--retries", "1", "accuracy"]),
        &["--retries means nothing for `cta sensor accuracy`"],
    );
    let help = ok(&cta(&["sensor", "status", "--help"]));
    assert!(help.contains("--retries"), "{help}");
}
