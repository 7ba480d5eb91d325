//! `cta beacon` and `cta sensor` end to end: against the simulated boards (on a pty, or in
//! process with `--sim`), the connection options only where a board is talked to, flags
//! checked up front, and every documented command line still parsing.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Output, Stdio};

mod common;
use common::{cta, stderr, Sim};

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
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
    // The simulated board was started, not reset: its reset cause says so.
    assert!(out.contains("\nlast reset      power-on\n"), "{out}");
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

#[test]
fn sensor_pose_prints_every_field_and_json() {
    let o = cta(&["sensor", "--sim", "pose", "--count", "3"]);
    let out = ok(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 4, "{out}");
    for col in [
        "rx (deg)", "sx(in)", "srx(deg)", "rms", "it", "bcn", "mag", "solve us", "cold", "drop",
        "status",
    ] {
        assert!(lines[0].contains(col), "header lacks {col}: {}", lines[0]);
    }
    // The first pose is a cold start, the next warm; every pose uses the 10 beacons and
    // their 10 magnitudes (the simulated CTA's calibration holds its NorthStar's law).
    for (i, row) in lines[1..].iter().enumerate() {
        let f: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(f.len(), 22, "{row}");
        assert_eq!(f[16], "10", "beacons used: {row}");
        assert_eq!(f[17], "10", "magnitudes fitted: {row}");
        assert!(f[18].parse::<u32>().is_ok(), "solve us: {row}");
        assert_eq!(
            f[19],
            if i == 0 { "yes" } else { "no" },
            "cold start: {row}"
        );
        assert_eq!(f[20], "-", "no beacon dropped: {row}");
        assert_eq!(f[21], "Ok", "{row}");
        let sigma_att: f64 = f[11].parse().unwrap();
        assert!(sigma_att > 0.0 && sigma_att < 5.0, "{row}");
    }

    let out = ok(&cta(&["sensor", "--sim", "pose", "--count", "2", "--json"]));
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for (i, l) in lines.iter().enumerate() {
        let v: serde_json::Value = serde_json::from_str(l).expect("one JSON object per line");
        for k in [
            "seq",
            "t_us",
            "ns_seq",
            "model",
            "status",
            "position",
            "mrp",
            "sigma_position",
            "sigma_attitude_deg",
            "rms",
            "condition",
            "iterations",
            "beacons",
            "magnitudes",
            "cold_start",
            "dropped",
            "solve_us",
            "attitude_deg",
        ] {
            assert!(v.get(k).is_some(), "no {k}: {l}");
        }
        assert_eq!(v["beacons"], 10);
        assert_eq!(v["magnitudes"], 10);
        assert_eq!(v["cold_start"], i == 0);
        assert_eq!(v["model"], "NearField");
        assert_eq!(v["sigma_attitude_deg"].as_array().unwrap().len(), 3);
        let z = v["position"][2].as_f64().unwrap();
        assert!((z - 12.0).abs() < 0.5, "{l}");
    }
}

#[test]
fn sensor_stream_json() {
    let out = ok(&cta(&[
        "sensor", "stream", "--sim", "--count", "2", "--json",
    ]));
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for l in lines {
        let v: serde_json::Value = serde_json::from_str(l).expect("one JSON object per line");
        assert_eq!(v["spots"].as_array().unwrap().len(), 10, "{l}");
        for k in ["seq", "t_us", "ns_seq", "sensitivity"] {
            assert!(v.get(k).is_some(), "no {k}: {l}");
        }
    }
}

#[test]
fn sensor_flags_are_checked_up_front() {
    let cases: &[(&[&str], &str)] = &[
        (
            &["accuracy", "--trials", "0"],
            "--trials 0: expected 1 or more",
        ),
        (
            &["accuracy", "--ranges", "0"],
            "--ranges 0: a range must be above 0",
        ),
        (
            &["accuracy", "--ranges=-5"],
            "--ranges -5: a range must be above 0",
        ),
        (&["accuracy", "--ranges", "2,-5"], "--ranges -5"),
        (&["accuracy", "--ranges", "1e9"], "at most 1000 inches"),
        (
            &["accuracy", "--noise-fraction", "0"],
            "--noise-fraction 0: expected 1e-6 to 0.3 of beta",
        ),
        (&["accuracy", "--noise-fraction", "1"], "--noise-fraction 1"),
        (&["accuracy", "--cal-samples", "0"], "--cal-samples 0"),
        (
            &["accuracy", "--magnitude-noise", "101"],
            "--magnitude-noise 101: expected 0 to 100 percent",
        ),
        (
            &["floor", "--poses", "0"],
            "--poses 0: expected 1 or more poses",
        ),
        (&["floor", "--ranges", "0"], "--ranges 0"),
        (&["floor", "--noise-fraction", "0"], "--noise-fraction 0"),
        (
            &["floor", "--magnitude-noise", "0.3,0"],
            "--magnitude-noise 0",
        ),
        (
            &["sim", "--range", "0"],
            "--range 0: a range must be above 0",
        ),
        (&["sim", "--range", "-3"], "--range -3"),
        (&["sim", "--noise", "-1"], "--noise -1"),
        (
            &["sim", "--magnitude-noise", "-0.1"],
            "--magnitude-noise -0.1: expected 0 to 100 percent",
        ),
        (
            &["sim", "--magnitude-noise", "101"],
            "--magnitude-noise 101",
        ),
        (&["sim", "--garbage", "1.5"], "--garbage 1.5"),
        (&["sim", "--wrong-id", "1.5"], "--wrong-id 1.5"),
        (&["sim", "--wrong-id", "-0.1"], "--wrong-id -0.1"),
        (&["sim", "--attitude-deg", "10,20"], "--attitude-deg"),
        (&["sim", "--attitude-deg", "10,x,20"], "--attitude-deg"),
        (&["sim", "--attitude-deg", "1,2,3,4"], "--attitude-deg"),
        (&["sim", "--attitude-deg", "1,2,inf"], "--attitude-deg"),
        (&["sim", "--seconds", "0"], "--seconds 0"),
    ];
    for (args, needle) in cases {
        let mut a = vec!["sensor"];
        a.extend_from_slice(args);
        let o = cta(&a);
        fails_with(&o, &[needle]);
        assert_eq!(
            stderr(&o).trim().lines().count(),
            1,
            "{args:?}: {}",
            stderr(&o)
        );
    }
}

#[test]
fn sensor_sim_offset_takes_exactly_x_comma_y() {
    let help = ok(&cta(&["sensor", "sim", "--help"]));
    assert!(help.contains("[default: 0.2,-0.1]"), "{help}");
    let range = help
        .lines()
        .skip_while(|l| !l.contains("--range"))
        .take_while(|l| !l.contains("--offset"))
        .collect::<Vec<_>>()
        .join(" ");
    assert!(
        range.contains("inches") && !range.contains("), in."),
        "{range}"
    );
    fails_with(
        &cta(&["sensor", "sim", "--offset", "0.3", "--seconds", "0.1"]),
        &["expected 2 comma-separated numbers x,y"],
    );
    fails_with(
        &cta(&[
            "sensor",
            "sim",
            "--offset",
            "0.3",
            "-0.2",
            "--seconds",
            "0.1",
        ]),
        &["unexpected argument"],
    );
    fails_with(
        &cta(&["sensor", "sim", "--offset", "1,2,3", "--seconds", "0.1"]),
        &["expected 2 comma-separated numbers x,y"],
    );
    // The accepted form puts the target there (a negative x too).
    let sim = Sim::start(&[
        "sensor",
        "sim",
        "--configured",
        "--offset",
        "-0.3,0.25",
        "--range",
        "10",
    ]);
    let out = ok(&cta(&[
        "sensor", "--port", &sim.path, "pose", "--count", "1", "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let p: Vec<f64> = (0..3).map(|i| v["position"][i].as_f64().unwrap()).collect();
    assert!(
        (p[0] + 0.3).abs() < 0.05 && (p[1] - 0.25).abs() < 0.05 && (p[2] - 10.0).abs() < 0.2,
        "{p:?}"
    );
}

#[test]
fn sensor_connection_options_only_where_a_board_is_talked_to() {
    fails_with(
        &cta(&["sensor", "--sim", "--port", "/dev/null", "identify"]),
        &["'--sim' cannot be used with '--port"],
    );
    fails_with(
        &cta(&["sensor", "--sim", "identify", "--port", "/dev/null"]),
        &["--sim and --port exclude each other"],
    );
    for sub in ["template", "sim", "accuracy", "floor"] {
        let help = ok(&cta(&["sensor", sub, "--help"]));
        for opt in ["--port", "--sim", "--timeout-ms"] {
            assert!(
                !help.contains(opt),
                "`sensor {sub} --help` offers {opt}: {help}"
            );
        }
    }
    fails_with(
        &cta(&["sensor", "--port", "/dev/null", "template", "calibration"]),
        &["--port means nothing for `cta sensor template`"],
    );
    fails_with(
        &cta(&["sensor", "--sim", "accuracy"]),
        &["--sim means nothing for `cta sensor accuracy`"],
    );
    fails_with(
        &cta(&["sensor", "--timeout-ms", "100", "floor"]),
        &["--timeout-ms means nothing for `cta sensor floor`"],
    );
    fails_with(
        &cta(&["sensor", "sim", "--sim", "--seconds", "0.1"]),
        &["unexpected argument '--sim'"],
    );
    // After the subcommand works as before it.
    let out = ok(&cta(&[
        "sensor",
        "identify",
        "--sim",
        "--timeout-ms",
        "300",
    ]));
    assert!(
        out.contains("sensor board") && out.contains("(simulated)"),
        "{out}"
    );
    let help = ok(&cta(&["sensor", "pose", "--help"]));
    assert!(help.contains("--port") && help.contains("--sim"), "{help}");
}

/// The `cta beacon` / `cta sensor` lines of the READMEs' command blocks.
fn documented_lines() -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut docs = vec![
        root.join("README.md"),
        root.join("firmware-beacon/README.md"),
        root.join("firmware-sensor/README.md"),
    ];
    for e in std::fs::read_dir(root.join("host")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            docs.push(p);
        }
    }
    let mut out = Vec::new();
    for doc in docs {
        let text = std::fs::read_to_string(&doc).unwrap();
        let mut fenced = false;
        for (i, l) in text.lines().enumerate() {
            let t = l.trim();
            if t.starts_with("```") {
                fenced = !fenced;
                continue;
            }
            if fenced && (t.starts_with("cta beacon") || t.starts_with("cta sensor")) {
                // Up to a comment or a redirection.
                let cmd = t.split(['#', '>']).next().unwrap().trim().to_string();
                out.push((format!("{}:{}", doc.display(), i + 1), cmd));
            }
        }
    }
    out
}

/// Every documented command line parses: those naming a port get as far as opening it
/// (exit 1 with the port in the message, not clap's exit 2), the others run.
#[test]
fn documented_command_lines_parse() {
    let lines = documented_lines();
    assert!(lines.len() >= 25, "{lines:?}");
    let port = "/nonexistent/cta-doc-port";
    let tmp = std::env::temp_dir().join(format!("cta-boards-cli-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    // The demo's rehearsal (firmware-sensor/README.md) reads the truth sidecar of the demo's
    // sweep: a small simulation writes one in its place (tests/rehearsal.rs runs the demo).
    let truth = tmp.join("cta-demo/run/data.csv");
    let o = cta(&[
        "simulate",
        "--out",
        truth.to_str().unwrap(),
        "--separations",
        "20",
        "--grid",
        "2x2",
        "--effect",
        "cell_gain=0.02,-0.01",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (at, line) in lines {
        let mut words: Vec<String> = line
            .split_whitespace()
            .skip(1)
            .map(str::to_string)
            .collect();
        let has_port = match words.iter().position(|w| w == "--port") {
            Some(i) => {
                words[i + 1] = port.into();
                true
            }
            None => false,
        };
        if words.iter().any(|w| w == "sim") && !words.iter().any(|w| w == "--seconds") {
            words.extend(["--seconds".into(), "0.2".into()]);
        }
        let o = Command::new(env!("CARGO_BIN_EXE_cta"))
            .args(&words)
            .current_dir(&tmp)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{at}: {line}: {err}");
        if has_port {
            assert_eq!(o.status.code(), Some(1), "{at}: {line}: {err}");
            assert!(err.contains(port), "{at}: {line}: {err}");
        } else {
            assert!(o.status.success(), "{at}: {line}: {err}");
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

/// A typo in a calibration or constellation key is refused, naming it and the keys there
/// (it used to be dropped: `gains` left the cell gains at 0); a constellation on channels 2
/// and 19, which share 4050 Hz in the NorthStar table, is refused; the built-in four-19 loads.
/// A calibration's host-side `led_brightness` is accepted, and `load-constellation
/// --brightness CAL.json` sets the beacons' brightness from it on a board on a pty (read back
/// with `config`), naming a beacon with no LED there.
#[test]
fn board_files_with_unknown_keys_or_shared_channels_are_refused() {
    let d = std::env::temp_dir().join(format!("cta-board-files-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let file = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    };
    let cal = ok(&cta(&["sensor", "template", "calibration"]));
    let typo = file("cal.json", &cal.replace("\"gain\"", "\"gains\""));
    assert_ne!(cal, std::fs::read_to_string(&typo).unwrap());
    fails_with(
        &cta(&["sensor", "--sim", "load-calibration", &typo]),
        &["unknown key `near_field.gains`", "`gain`"],
    );
    // The pinhole model's own head (`pinhole`): a file without the key (written before the
    // calibration held it) loads; one with it loads, and is checked as the head is, by name.
    // The template has no pinhole eye point: an edit of d, p moves both models.
    let mut v: serde_json::Value = serde_json::from_str(&cal).unwrap();
    assert!(v["pinhole"].is_null(), "{cal}");
    v.as_object_mut().unwrap().remove("pinhole");
    let old = file("old.json", &v.to_string());
    ok(&cta(&["sensor", "--sim", "load-calibration", &old]));
    v["pinhole"] = serde_json::json!({"d": [0.6, 0.1, 1.1], "p": [0.001, 0.002, 0.001]});
    let eye = file("eye.json", &v.to_string());
    ok(&cta(&["sensor", "--sim", "load-calibration", &eye]));
    v["pinhole"]["d"][2] = 40.0.into();
    let far = file("far.json", &v.to_string());
    fails_with(
        &cta(&["sensor", "--sim", "load-calibration", &far]),
        &["pinhole d (each component finite, within +/-12 in)"],
    );
    v["pinhole"]["d"][2] = 1.1.into();
    v["pinhole"]["h"] = 18900.0.into();
    let typo = file("eye-typo.json", &v.to_string());
    fails_with(
        &cta(&["sensor", "--sim", "load-calibration", &typo]),
        &["unknown key `pinhole.h`", "`d`, `p`"],
    );
    let con = ok(&cta(&["sensor", "template", "constellation"]));
    let typo = file("con.json", &con.replacen("\"id\"", "\"ID\"", 1));
    fails_with(
        &cta(&["sensor", "--sim", "load-constellation", &typo]),
        &["con.json"],
    );
    // Channel 9 renamed 19: with channel 2 that is 4050 Hz twice.
    let mut v: serde_json::Value = serde_json::from_str(&con).unwrap();
    v["beacons"][9]["id"] = 19.into();
    let shared = file("shared.json", &v.to_string());
    fails_with(
        &cta(&["sensor", "--sim", "load-constellation", &shared]),
        &["channels 2 and 19", "4050 Hz"],
    );
    let four = file(
        "four.json",
        &ok(&cta(&[
            "sensor",
            "template",
            "constellation",
            "--name",
            "four-19",
        ])),
    );
    let out = ok(&cta(&["sensor", "--sim", "load-constellation", &four]));
    assert!(out.contains("constellation of 19 beacons"), "{out}");
    // Slips: two beacons at one place, all on a line, more than the board holds; positions
    // in millimetres are warned about.
    let base: serde_json::Value = serde_json::from_str(&con).unwrap();
    let edited = |name: &str, f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = base.clone();
        f(&mut v);
        file(name, &v.to_string())
    };
    let same = edited("same.json", &|v| {
        v["beacons"][1]["r"] = v["beacons"][0]["r"].clone()
    });
    fails_with(
        &cta(&["sensor", "--sim", "load-constellation", &same]),
        &["beacons 0 and 1 are at the same place"],
    );
    let line = edited("line.json", &|v| {
        for (i, b) in v["beacons"].as_array_mut().unwrap().iter_mut().enumerate() {
            b["r"] = serde_json::json!([i as f64, 0.0, 0.0]);
        }
    });
    fails_with(
        &cta(&["sensor", "--sim", "load-constellation", &line]),
        &["all 10 beacons lie on one line"],
    );
    let many = edited("many.json", &|v| {
        v["beacons"] = (0..30)
            .map(|i| serde_json::json!({"id": i % 20, "r": [i as f64, (i % 3) as f64, 0.0]}))
            .collect();
    });
    fails_with(
        &cta(&["sensor", "--sim", "load-constellation", &many]),
        &["30 beacons; the board holds at most 20"],
    );
    // The LEDs' brightness of a calibration (as `cta calibrate` writes it) for every beacon
    // of the template but the last, moved off the grid.
    let mut calv: serde_json::Value = serde_json::from_str(&cal).unwrap();
    let beacons = base["beacons"].as_array().unwrap();
    let n = beacons.len();
    calv["led_brightness"] = beacons[..n - 1]
        .iter()
        .enumerate()
        .map(|(i, b)| {
            serde_json::json!({
                "x_in": b["r"][0].as_f64().unwrap() + 0.02,
                "y_in": b["r"][1],
                "brightness": 0.8 + 0.05 * i as f64,
                "sigma": 0.001,
            })
        })
        .collect();
    let bright = file("bright.json", &calv.to_string());
    ok(&cta(&["sensor", "--sim", "load-calibration", &bright]));
    let moved = edited("moved.json", &|v| {
        let x = v["beacons"][n - 1]["r"][0].as_f64().unwrap();
        v["beacons"][n - 1]["r"][0] = (x + 0.3).into();
    });
    let sim = Sim::start(&["sensor", "sim", "--configured"]);
    let o = cta(&[
        "sensor",
        "--port",
        &sim.path,
        "load-constellation",
        &moved,
        "--brightness",
        &bright,
    ]);
    let out = ok(&o);
    assert!(
        out.contains(&format!("the brightness of {} from {bright}", n - 1)),
        "{out}"
    );
    let last = base["beacons"][n - 1]["id"].as_u64().unwrap();
    assert!(
        stderr(&o).contains(&format!("no LED within 0.05 in of beacon(s) {last} at")),
        "{}",
        stderr(&o)
    );
    let config = ok(&cta(&["sensor", "--port", &sim.path, "config"]));
    let stored: serde_json::Value = serde_json::from_str(
        config
            .lines()
            .find_map(|l| l.strip_prefix("constellation: "))
            .unwrap(),
    )
    .unwrap();
    let got: Vec<f64> = stored["beacons"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["brightness"].as_f64().unwrap())
        .collect();
    let want: Vec<f64> = (0..n)
        .map(|i| {
            if i + 1 < n {
                0.8 + 0.05 * i as f64
            } else {
                1.0
            }
        })
        .collect();
    assert!(
        got.iter().zip(&want).all(|(g, w)| (g - w).abs() < 1e-6),
        "{got:?} against {want:?}"
    );
    // A file without the LEDs' brightness is named.
    fails_with(
        &cta(&[
            "sensor",
            "--sim",
            "load-constellation",
            &moved,
            "--brightness",
            &moved,
        ]),
        &["no `led_brightness`", "this is a constellation"],
    );
    let mm = edited("mm.json", &|v| {
        for b in v["beacons"].as_array_mut().unwrap() {
            for x in b["r"].as_array_mut().unwrap() {
                *x = (x.as_f64().unwrap() * 25.4).into();
            }
        }
    });
    let o = cta(&["sensor", "--sim", "load-constellation", &mm]);
    ok(&o);
    assert!(
        stderr(&o).contains("positions are in inches"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Ctrl-C during `cta sensor pose --count 0` (until Ctrl-C) leaves the board idle, not
/// solving and sending for ever.
#[test]
fn ctrl_c_during_pose_leaves_the_board_idle() {
    let sim = Sim::start(&["sensor", "sim", "--configured"]);
    let mut pose = Command::new(env!("CARGO_BIN_EXE_cta"))
        .args(["sensor", "--port", &sim.path, "pose", "--count", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(pose.stdout.take().unwrap());
    let mut line = String::new();
    // The header, then the first pose: the board is solving.
    for _ in 0..2 {
        line.clear();
        out.read_line(&mut line).unwrap();
    }
    assert!(line.contains("Ok"), "{line}");
    let killed = Command::new("kill")
        .args(["-INT", &pose.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = pose.wait_with_output().unwrap();
    assert!(
        stderr(&o).contains("stopped by a signal: the board is idle"),
        "{}",
        stderr(&o)
    );
    let status = ok(&cta(&["sensor", "--port", &sim.path, "status"]));
    assert!(
        status
            .lines()
            .any(|l| l.starts_with("mode") && l.contains("Idle")),
        "{status}"
    );
}

/// The `--sim` board starts with the simulated CTA's calibration, the pinhole fit's own eye
/// point among it, so its pinhole pose of the target at 12 in reads about 12 in (with the
/// head's `d, p` and the nominal H it read 10.96 in, 1 in short, status Ok).
#[test]
fn the_sim_boards_pinhole_pose_reads_the_range() {
    for model in ["pinhole", "near-field"] {
        let out = ok(&cta(&[
            "sensor", "--sim", "pose", "--model", model, "--count", "2", "--json",
        ]));
        for line in out.lines() {
            let v: serde_json::Value = serde_json::from_str(line).unwrap();
            assert_eq!(v["status"], "Ok", "{line}");
            let z = v["position"][2].as_f64().unwrap();
            assert!((z - 12.0).abs() < 0.2, "{model}: z {z}: {line}");
        }
    }
}

/// The error of a command whose port went away while it ran: the board and the port named in
/// front, the port's error once (it used to read `cta: error: Broken pipe` for `stream`, and
/// `serial port error: Broken pipe: Broken pipe` for `heartbeat`).
#[cfg(unix)]
fn names_the_lost_port_once(o: &Output, board: &str, port: &str) {
    fails_with(o, &[&format!("{board} board on {port}: port lost: ")]);
    let err = stderr(o);
    let line = err
        .lines()
        .find(|l| l.contains("port lost: "))
        .unwrap_or_default();
    let cause = line.rsplit("port lost: ").next().unwrap_or_default();
    assert!(!cause.is_empty(), "{err}");
    assert_eq!(err.matches(cause).count(), 1, "said twice: {err}");
    assert_eq!(err.matches(port).count(), 1, "port named twice: {err}");
}

#[test]
#[cfg(unix)] // The boards on ptys.
fn a_port_lost_mid_command_is_named_with_its_board() {
    // Sensor: a stream until Ctrl-C, its board stopped after the first report.
    let sim = Sim::start(&["sensor", "sim"]);
    let mut stream = Command::new(env!("CARGO_BIN_EXE_cta"))
        .args(["sensor", "--port", &sim.path, "stream", "--count", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(stream.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    assert!(line.contains("spots="), "{line}");
    let port = sim.path.clone();
    drop(sim);
    // The stream goes on printing until it finds the port gone.
    std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
    let o = stream.wait_with_output().unwrap();
    names_the_lost_port_once(&o, "sensor", &port);

    // Beacon: heartbeats every 50 ms until stopped, its board stopped once the first
    // heartbeat has come (the command has identified the board by then, however slow the
    // machine). The board is the simulated board's code (as `cta beacon sim` runs it), played
    // here on a pty of the test's own so the test sees the requests.
    use cta_core::schedule::{Modulator, NORTHSTAR_TABLE_MHZ};
    use cta_core::wire::{beacon::BeaconRequest, FrameDecoder, Request, ResetCause, MAX_FRAME};
    use cta_firmware_beacon::pins::BEACON_LINES;
    use serialport::SerialPort;
    use std::io::{Read, Write};
    use std::os::fd::AsRawFd;
    use std::time::{Duration, Instant};
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    let port = slave.name().unwrap();
    master.set_timeout(Duration::from_millis(5)).unwrap();
    // Not inherited by the command: closing it here must hang its port up.
    for fd in [master.as_raw_fd(), slave.as_raw_fd()] {
        assert_eq!(
            unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) },
            0
        );
    }
    let heartbeat = Command::new(env!("CARGO_BIN_EXE_cta"))
        .args(["beacon", "--port", &port, "heartbeat", "--every-ms", "50"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut modulator = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES).unwrap();
    let mut board = cta_firmware_beacon::board::Board::new(true, ResetCause::PowerOn);
    board.start(&mut modulator);
    let mut requests = FrameDecoder::<MAX_FRAME>::new();
    let (mut rx, mut tx) = ([0u8; 256], [0u8; MAX_FRAME]);
    let t0 = Instant::now();
    'board: loop {
        assert!(t0.elapsed() < Duration::from_secs(120), "no heartbeat came");
        let n = match master.read(&mut rx) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => 0,
            Err(e) => panic!("the board's end of the pty: {e}"),
        };
        let now_ms = t0.elapsed().as_millis() as u64;
        for &b in &rx[..n] {
            if let Some(frame) = board.feed(b, now_ms, &mut modulator, &mut tx) {
                master.write_all(frame).unwrap();
            }
            if let Some(Ok((_, Request::<BeaconRequest>::Heartbeat))) = requests.push(b) {
                break 'board;
            }
        }
    }
    drop((master, slave));
    let o = heartbeat.wait_with_output().unwrap();
    names_the_lost_port_once(&o, "beacon", &port);
}

/// A board of the other kind on the port: the message says the ports may be swapped.
#[test]
fn the_other_board_on_the_port_suggests_swapped_ports() {
    let sim = Sim::start(&["sensor", "sim"]);
    fails_with(
        &cta(&["beacon", "--port", &sim.path, "status"]),
        &[
            &format!("identifying the board on {}", sim.path),
            "expected a beacon board",
            "a sensor board",
            "is this the sensor board's port? the beacon and sensor ports may be swapped",
        ],
    );
}

/// A status text's lines as (label, value): the label in the first 16 columns, as both
/// boards print it.
fn status_lines(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(|l| {
            assert!(
                l.len() > 16 && l.as_bytes()[15] == b' ' && l.as_bytes()[16] != b' ',
                "not a 16-column label: {l:?}"
            );
            (l[..16].trim_end().to_string(), l[16..].to_string())
        })
        .collect()
}

/// The numbers of a status value, in order (`8 good, 0 bad (crc 0, ...)` -> 8, 0, 0, ...).
fn numbers(v: &str) -> Vec<f64> {
    v.split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|w| w.trim_end_matches('.').parse().ok())
        .collect()
}

/// The unsigned integers of a JSON array of values, in order.
/// The JSON's `uptime_ms` is at or after the text's uptime (read to 0.1 s, the text first).
fn uptime_agrees(j: &serde_json::Value, text: &str) {
    let up_text = numbers(text)[0];
    let up = j["uptime_ms"].as_u64().unwrap() as f64;
    assert!(
        up >= 1000.0 * up_text - 50.0 && up < 1000.0 * up_text + 10_000.0,
        "{up} ms after {up_text} s"
    );
}

/// A frame counter object of the JSON (ok, bad, then each kind) against the numbers of the
/// text's line, in order; the good frames only grow with the status request between them.
fn frames_agree(c: &serde_json::Value, text: &str, out: &str) {
    let json = u64s(&[
        &c["ok"],
        &c["bad"],
        &c["oversized"],
        &c["encoding"],
        &c["truncated"],
        &c["crc"],
        &c["malformed"],
        &c["version"],
    ]);
    let text = numbers(text);
    assert_eq!(json.len(), text.len(), "{out}");
    assert!(json[0] > text[0], "{out}");
    assert_eq!(json[1..], text[1..], "{out}");
}

fn u64s(v: &[&serde_json::Value]) -> Vec<f64> {
    v.iter()
        .map(|x| x.as_u64().unwrap_or_else(|| panic!("not a count: {x}")) as f64)
        .collect()
}

/// `cta sensor status` prints the same lines as ever, and with `--json` one JSON object with
/// every field of them: after two poses on a pty board the text and then the JSON agree
/// (the counters that move with each command only up), the reset cause and mode in words.
#[test]
fn sensor_status_text_and_json() {
    let sim = Sim::start(&["sensor", "sim", "--configured"]);
    let p = sim.path.as_str();
    ok(&cta(&["sensor", "--port", p, "pose", "--count", "2"]));
    let text = ok(&cta(&["sensor", "--port", p, "status"]));
    let lines = status_lines(&text);
    let labels: Vec<&str> = lines.iter().map(|(l, _)| l.as_str()).collect();
    assert_eq!(
        labels,
        [
            "uptime",
            "last reset",
            "mode",
            "northstar",
            "stored",
            "pc frames",
            "northstar link",
            "reports",
            "host silent",
            "last pose"
        ],
        "{text}"
    );
    let value = |label: &str| &lines.iter().find(|(l, _)| l == label).unwrap().1;
    for (label, v) in [
        ("last reset", "power-on"),
        ("mode", "Idle"),
        ("northstar", "sensitivity 4, 10 Hz"),
        (
            "stored",
            "calibration: true, constellation: true (flash generation 2)",
        ),
        ("last pose", "Ok (converged)"),
    ] {
        assert_eq!(value(label), v, "{text}");
    }
    assert!(value("uptime").ends_with(" s"), "{text}");
    assert!(
        value("pc frames").contains(
            " good, 0 bad (oversized 0, encoding 0, truncated 0, crc 0, malformed 0, version 0)"
        ) && value("northstar link").ends_with(" CRC errors, 0 bytes discarded")
            && value("reports").ends_with(" sent, 0 dropped; 0 requests refused")
            && value("host silent").ends_with(" ms"),
        "{text}"
    );

    // The connection options after the subcommand, as the text's before it.
    let out = ok(&cta(&["sensor", "status", "--port", p, "--json"]));
    let j: serde_json::Value = serde_json::from_str(&out).expect("one JSON object");
    let keys: Vec<&str> = j.as_object().unwrap().keys().map(String::as_str).collect();
    let mut want = [
        "uptime_ms",
        "reset_cause",
        "mode",
        "sensitivity",
        "rate_hz",
        "calibrated",
        "constellation",
        "config_generation",
        "pc",
        "northstar",
        "reports",
        "dropped",
        "refused",
        "since_host_ms",
        "last_pose",
    ];
    want.sort_unstable();
    let mut keys = keys;
    keys.sort_unstable();
    assert_eq!(keys, want, "{out}");
    assert_eq!(j["reset_cause"], "power-on", "{out}");
    assert_eq!(j["mode"], "Idle", "{out}");
    assert_eq!(j["last_pose"], "Ok", "{out}");
    assert_eq!(
        (&j["sensitivity"], &j["rate_hz"]),
        (&4.into(), &10.into()),
        "{out}"
    );
    assert_eq!(
        (
            &j["calibrated"],
            &j["constellation"],
            &j["config_generation"]
        ),
        (&true.into(), &true.into(), &2.into()),
        "{out}"
    );
    uptime_agrees(&j, value("uptime"));
    // Counters: every number of the text's lines, in their order; the frames received only
    // grow with the commands since.
    frames_agree(&j["pc"], value("pc frames"), &out);
    let ns = &j["northstar"];
    let ns_json = u64s(&[&ns["frames"], &ns["crc_errors"], &ns["discarded"]]);
    let ns_text = numbers(value("northstar link"));
    assert!(ns_json[0] >= ns_text[0] && ns_json[0] > 0.0, "{out}");
    assert_eq!(ns_json[1..], ns_text[1..], "{out}");
    let reports = u64s(&[&j["reports"], &j["dropped"], &j["refused"]]);
    assert_eq!(reports, numbers(value("reports")), "{out}");
    assert!(reports[0] >= 2.0, "{out}");
    assert!(j["since_host_ms"].as_u64().unwrap() < 5_000, "{out}");

    // The in-process board: nothing solved yet.
    let j = common::json(&cta(&["sensor", "--sim", "status", "--json"]));
    assert_eq!(j["last_pose"], serde_json::Value::Null, "{j}");
    assert_eq!(j["reports"], 0, "{j}");
    assert_eq!(j["reset_cause"], "power-on", "{j}");
}

/// `cta beacon status` prints the same lines as ever, and with `--json` one JSON object with
/// every field of them: with the cap at 1, one LED lit and a second refused, the text and
/// then the JSON agree (the frames received only up), the reset cause in words.
#[test]
fn beacon_status_text_and_json() {
    let sim = Sim::start(&["beacon", "sim"]);
    let p = sim.path.as_str();
    ok(&cta(&["beacon", "--port", p, "limits", "--max-lit", "1"]));
    ok(&cta(&["beacon", "--port", p, "set", "45", "3"]));
    fails_with(
        &cta(&["beacon", "--port", p, "set", "46", "3"]),
        &["the cap is 1"],
    );
    let text = ok(&cta(&["beacon", "--port", p, "status"]));
    let lines = status_lines(&text);
    let labels: Vec<&str> = lines.iter().map(|(l, _)| l.as_str()).collect();
    assert_eq!(
        labels,
        [
            "uptime",
            "last reset",
            "lit LEDs",
            "dead-man",
            "frames",
            "refused",
            "uart errors",
            "tick"
        ],
        "{text}"
    );
    let value = |label: &str| &lines.iter().find(|(l, _)| l == label).unwrap().1;
    for (label, v) in [
        ("last reset", "power-on"),
        ("lit LEDs", "1 (cap 1)"),
        ("refused", "1"),
        ("uart errors", "0"),
        ("tick", "125000 Hz, table of 20 frequencies"),
    ] {
        assert_eq!(value(label), v, "{text}");
    }
    assert!(value("uptime").ends_with(" s"), "{text}");
    assert!(
        value("dead-man").starts_with("10000 ms, host silent for ")
            && value("dead-man").ends_with(" ms, tripped 0 time(s)")
            && value("frames").contains(" good, 0 bad (oversized 0, encoding 0, truncated 0, crc 0, malformed 0, version 0)"),
        "{text}"
    );

    let out = ok(&cta(&["beacon", "status", "--port", p, "--json"]));
    let j: serde_json::Value = serde_json::from_str(&out).expect("one JSON object");
    let mut keys: Vec<&str> = j.as_object().unwrap().keys().map(String::as_str).collect();
    keys.sort_unstable();
    let mut want = [
        "uptime_ms",
        "reset_cause",
        "lit",
        "limits",
        "since_host_ms",
        "deadman_trips",
        "decoder",
        "refused",
        "uart_errors",
        "tick_hz",
        "table_len",
    ];
    want.sort_unstable();
    assert_eq!(keys, want, "{out}");
    assert_eq!(j["reset_cause"], "power-on", "{out}");
    assert_eq!(
        u64s(&[
            &j["lit"],
            &j["limits"]["max_lit"],
            &j["limits"]["deadman_ms"],
            &j["deadman_trips"],
            &j["refused"],
            &j["uart_errors"],
            &j["tick_hz"],
            &j["table_len"],
        ]),
        [1.0, 1.0, 10_000.0, 0.0, 1.0, 0.0, 125_000.0, 20.0],
        "{out}"
    );
    uptime_agrees(&j, value("uptime"));
    frames_agree(&j["decoder"], value("frames"), &out);
    assert!(j["since_host_ms"].as_u64().unwrap() < 5_000, "{out}");
}

/// `cta sensor sim --attitude-deg` at a half turn about the line of sight (every frame
/// diverged before the attitude-free cold start), tilted, with a wrong ID in every frame: the
/// board solves each frame Ok at the simulated pose and names a dropped beacon in each.
#[test]
fn sensor_sim_attitude_and_wrong_ids() {
    let sim = Sim::start(&[
        "sensor",
        "sim",
        "--configured",
        "--range",
        "8",
        "--attitude-deg",
        "8,-5,180",
        "--wrong-id",
        "1",
    ]);
    let out = ok(&cta(&[
        "sensor", "--port", &sim.path, "pose", "--count", "4", "--json",
    ]));
    let want = cta_core::pose::attitude_xyz([8.0, -5.0, 180.0]);
    for l in out.lines() {
        let v: serde_json::Value = serde_json::from_str(l).expect("one JSON object per line");
        assert_eq!(v["status"], "Ok", "{l}");
        assert!(v["dropped"].as_u64().is_some(), "a beacon dropped: {l}");
        assert_eq!(
            v["beacons"], 8,
            "ten spots, one ID moved onto another, one left out: {l}"
        );
        let q: Vec<f64> = (0..3).map(|i| v["mrp"][i].as_f64().unwrap()).collect();
        let q = nalgebra::Vector3::new(q[0], q[1], q[2]);
        let c = cta_core::mrp::dcm(&q) * cta_core::mrp::dcm(&want).transpose();
        let angle = ((c.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!(
            angle < 1.0,
            "attitude {angle} deg from the simulated one: {l}"
        );
        let z = v["position"][2].as_f64().unwrap();
        assert!((z - 8.0).abs() < 0.1, "{l}");
    }
}

/// `cta sensor accuracy --envelope`: one row per range with the envelope's limits, the
/// usable frames, both models' cold acquisition and errors (the near-field's far below the
/// pinhole's at 3 in) and the failed frames by why; JSON carries the same rows; options it
/// does not take are refused in one line.
#[test]
fn sensor_accuracy_envelope_table() {
    let out = ok(&cta(&[
        "sensor",
        "accuracy",
        "--envelope",
        "--trials",
        "50",
        "--ranges",
        "3,20",
    ]));
    assert!(
        out.contains("Cold acquisition over a docking envelope"),
        "{out}"
    );
    let rows: Vec<Vec<&str>> = out
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|f| f.len() == 21 && f[0].parse::<f64>().is_ok())
        .collect();
    assert_eq!(rows.len(), 2, "{out}");
    for (r, range) in rows.iter().zip([3.0, 20.0]) {
        assert_eq!(r[0].parse::<f64>().unwrap(), range, "{r:?}");
        assert_eq!(r[3], "50", "{r:?}");
        let usable: usize = r[4].parse().unwrap();
        assert!(usable >= 30 && usable <= 50, "{r:?}");
        let nf_acq: f64 = r[5].parse().unwrap();
        assert!(nf_acq >= 95.0, "{r:?}");
        assert!(r[13].starts_with('D') && r[17].starts_with('D'), "{r:?}");
    }
    let ratio: f64 = rows[0][11].parse().unwrap();
    assert!(
        ratio > 5.0,
        "pinhole / near-field position error at 3 in: {ratio}"
    );
    let json = ok(&cta(&[
        "sensor",
        "accuracy",
        "--envelope",
        "--trials",
        "5",
        "--ranges",
        "8",
        "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let row = &v["rows"][0];
    assert_eq!(row["frames"], 5);
    assert!(row["near_field"]["failures"]["diverged"].is_u64(), "{json}");
    assert!(row["max_tilt_deg"].as_f64().unwrap() > 20.0, "{json}");
    let o = cta(&["sensor", "accuracy", "--envelope", "--check"]);
    fails_with(&o, &["--check"]);
}
