//! A fresh user's mistakes with the data commands (fit, analyze, noise, calibrate, evaluate,
//! simulate) and `cta --help`: each is said in one line that names the file (and the line) at
//! fault and what to do.

use std::path::Path;
use std::process::Output;

mod common;
use common::{cta, fails_in_one_line, s, simulate, stderr};

fn tmpdir(name: &str) -> common::TmpDir {
    common::tmpdir_of("fresh-user", name)
}

/// The data commands that read a measurement file, each with `file`.
fn readers(file: &Path, out: &Path) -> Vec<Vec<String>> {
    let f = s(file).to_string();
    vec![
        vec!["fit".into(), f.clone()],
        vec!["analyze".into(), f.clone()],
        vec!["noise".into(), f.clone()],
        vec![
            "calibrate".into(),
            f.clone(),
            "--out".into(),
            s(out).to_string(),
        ],
    ]
}

fn run(args: &[String]) -> Output {
    cta(&args.iter().map(String::as_str).collect::<Vec<_>>())
}

/// The audit's case: `cta fit run1` said "run1: Is a directory (os error 21)". A sweep's run
/// folder now suggests its data.csv, in every command that reads a measurement file; another
/// folder is said to be one.
#[test]
fn a_run_folder_suggests_its_data_csv() {
    let d = tmpdir("folder");
    let run1 = d.join("run1");
    std::fs::create_dir_all(&run1).unwrap();
    simulate(&run1.join("data.csv"), &["--separations", "25,30"]);
    let data = run1.join("data.csv");
    for args in readers(&run1, &d.join("cal.json")) {
        fails_in_one_line(
            &run(&args),
            &[
                &format!("{}: is a folder, not a measurement file", s(&run1)),
                &format!("give the sweep's data file in it, {}", s(&data)),
            ],
        );
    }
    let fit = d.join("fit.json");
    assert!(cta(&["fit", s(&data), "--save", s(&fit)]).status.success());
    fails_in_one_line(
        &cta(&["evaluate", s(&fit), s(&run1)]),
        &[&format!("give the sweep's data file in it, {}", s(&data))],
    );
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fails_in_one_line(
        &cta(&["fit", s(&empty)]),
        &["is a folder, not a measurement file: give a CSV file"],
    );
}

/// The audit's case: a CSV cut off mid-row said only "trunc.csv:5603: 4 fields, the header has
/// 12". Its last line, without an end of line, is now said to look cut off; a short row
/// elsewhere keeps the plain message, and a complete last row without a newline reads.
#[test]
fn a_file_cut_off_mid_row_is_said_to_be() {
    let d = tmpdir("cut");
    let full = d.join("full.csv");
    simulate(&full, &["--separations", "25,30"]);
    let text = std::fs::read_to_string(&full).unwrap();
    let lines = text.lines().count();
    // Cut in the middle of the last row's fifth field (x).
    let last = text.trim_end().rsplit('\n').next().unwrap();
    let keep = text.trim_end().len() - last.len() + last.match_indices(',').nth(3).unwrap().0 + 3;
    let cut = d.join("trunc.csv");
    std::fs::write(&cut, &text[..keep]).unwrap();
    for args in readers(&cut, &d.join("cal.json")) {
        fails_in_one_line(
            &run(&args),
            &[
                &format!("trunc.csv:{lines}: 5 fields, the header has 13"),
                "the file looks cut off (a copy not finished, a sweep still writing?)",
            ],
        );
    }
    // A short row with an end of line: not a cut.
    let short = d.join("short.csv");
    std::fs::write(&short, format!("{}\n", &text[..keep])).unwrap();
    let o = cta(&["fit", s(&short)]);
    fails_in_one_line(&o, &["5 fields, the header has 13"]);
    assert!(!stderr(&o).contains("cut off"), "{}", stderr(&o));
    // A whole last row without a newline is fine.
    let whole = d.join("whole.csv");
    std::fs::write(&whole, text.trim_end()).unwrap();
    assert!(cta(&["fit", s(&whole)]).status.success());
}

/// A file cut inside its last value (`0.006927100158441942` to `0.0069271001584`) still
/// reads, so every command that reads a measurement file warns when the last row has no line
/// break after it, naming the line and the value and saying what to do; the same file ending
/// with a line break is not warned about.
#[test]
fn a_file_cut_inside_its_last_value_is_warned_about() {
    let d = tmpdir("cut-value");
    let full = d.join("full.csv");
    simulate(&full, &["--separations", "25,30", "--samples", "3"]);
    let text = std::fs::read_to_string(&full).unwrap();
    let lines = text.lines().count();
    // The last value is the time (`180.98`): cut to `180.`, which still reads.
    let body = &text.trim_end()[..text.trim_end().len() - 2];
    let value = body.rsplit(',').next().unwrap();
    assert!(value.parse::<f64>().is_ok() && value.len() > 3, "{value}");
    let cut = d.join("cut.csv");
    std::fs::write(&cut, body).unwrap();
    let want = format!(
        "warning: {}:{lines}: the file's last line has no end of line: its last value, \
         `{value}` (column `time_s`), may be cut short",
        s(&cut)
    );
    for args in readers(&cut, &d.join("cal.json")) {
        let o = run(&args);
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        let line = err
            .lines()
            .find(|l| l.starts_with(&want))
            .unwrap_or_else(|| panic!("{args:?}: {err}"));
        assert!(
            line.contains(
                "If the file was cut, delete that line, or copy or export the file again"
            ),
            "{line}"
        );
    }
    let o = cta(&["fit", s(&cut)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Ended by a line break: no warning.
    let whole = d.join("whole.csv");
    std::fs::write(&whole, format!("{body}\n")).unwrap();
    let o = cta(&["fit", s(&whole)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("cut short"), "{}", stderr(&o));
}

/// The audit's case: `cta simulate --out g.csv --d 100,0,0` (millimetres typed for inches)
/// said "0 points outside the field of view" though every report was railed. The rail is now
/// counted when the file is written, with its likely cause; the close-in rail of a default
/// simulation is a note; counts of one are singular.
#[test]
fn simulate_says_when_reports_rail_and_why() {
    let d = tmpdir("rail");
    let o = cta(&["simulate", "--out", s(&d.join("g.csv")), "--d", "100,0,0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("warning: 2900 of 2900 reports (100.0 %) are at the 16-bit rail")
            && err.contains("--d 100,0,0 puts the head 100.0 in from the board origin")
            && err.contains("was it given in millimetres? divide by 25.4"),
        "{err}"
    );
    let o = cta(&["simulate", "--out", s(&d.join("a.csv"))]);
    let err = stderr(&o);
    assert!(
        err.contains("note: 68 of 2900 reports (2.3 %) are at the 16-bit rail")
            && err.contains("at 2, 3 in: close in")
            && !err.contains("warning"),
        "{err}"
    );
    let o = cta(&[
        "simulate",
        "--out",
        s(&d.join("one.csv")),
        "--separations",
        "20",
        "--grid",
        "1x1",
    ]);
    let err = stderr(&o);
    assert!(
        err.starts_with("wrote 1 report (1 separation x 1 beacon x 1 sample, 0 points outside")
            && !err.contains("16-bit rail"),
        "{err}"
    );
}

/// `o`'s stderr holds no control character but its line ends.
fn no_control_bytes(o: &Output) {
    let err = stderr(o);
    assert!(
        !o.stderr
            .iter()
            .any(|&b| (b < 0x20 && b != b'\n') || b == 0x7f),
        "control bytes: {err:?}"
    );
}

/// The audit's cases: `cta fit` of a program dumped its bytes to the terminal as "the header
/// line found", and an HTML page was said to be "separated by semicolons" (its style
/// attribute). A binary file is now "not a text CSV file", an HTML page is named, semicolons
/// are said only of fields that are column names, and no control byte is ever printed.
#[test]
fn binary_and_html_files_are_named_for_what_they_are() {
    let d = tmpdir("binary");
    let program = env!("CARGO_BIN_EXE_cta");
    for args in readers(Path::new(program), &d.join("cal.json")) {
        let o = run(&args);
        fails_in_one_line(
            &o,
            &[
                &format!("{program}:1: not a text CSV file"),
                "control characters (binary data",
            ],
        );
        no_control_bytes(&o);
    }
    let png = d.join("plot.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR").unwrap();
    let o = cta(&["fit", s(&png)]);
    fails_in_one_line(&o, &["plot.png:1: not a text CSV file", "not UTF-8 text"]);
    no_control_bytes(&o);
    let html = d.join("page.csv");
    std::fs::write(
        &html,
        "<!DOCTYPE html>\n<html><head><style>td{color:red;margin:0;padding:1px}</style></head>\n\
         <body>separation_in;x</body></html>\n",
    )
    .unwrap();
    let o = cta(&["fit", s(&html)]);
    fails_in_one_line(
        &o,
        &["page.csv:1:", "an HTML or XML document, not a CSV file"],
    );
    assert!(!stderr(&o).contains("semicolons"), "{}", stderr(&o));
    // Text with semicolons that are not between column names: not a delimiter.
    // A JSON file (a saved fit, a calibration) given as the data.
    let js = d.join("fit.json");
    std::fs::write(&js, "{\n  \"params\": {\"d\": [1.1, 0.1, 0.6]}\n}\n").unwrap();
    let o = cta(&["fit", s(&js)]);
    fails_in_one_line(&o, &["fit.json:1:", "this looks like a JSON file"]);
    let notes = d.join("notes.csv");
    std::fs::write(&notes, "run 3; plate level; 20 in\n1,2\n").unwrap();
    let o = cta(&["fit", s(&notes)]);
    fails_in_one_line(&o, &["start a title or note line with `#`"]);
    assert!(!stderr(&o).contains("semicolons"), "{}", stderr(&o));
    // Semicolon-separated column names still are.
    let semi = d.join("semi.csv");
    std::fs::write(
        &semi,
        "separation_in;beacon_x_in;beacon_y_in;beacon_z_in;x;y\n20;0;0;20;1;2\n",
    )
    .unwrap();
    fails_in_one_line(&cta(&["fit", s(&semi)]), &["separated by semicolons"]);
    // A control character in a value is shown escaped.
    let esc = d.join("esc.csv");
    std::fs::write(
        &esc,
        "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y\n20,0,0,20,1\x1b[31m,2\n",
    )
    .unwrap();
    let o = cta(&["fit", s(&esc)]);
    fails_in_one_line(
        &o,
        &["esc.csv:2: column `x`: `1\\u{1b}[31m` is not a finite number"],
    );
    no_control_bytes(&o);
}

/// The audit's case: `cta evaluate sim.csv fit.json` (arguments swapped) said "not a CTA fit
/// file: expected value at line 1 column 1". It now says they look swapped, with the right
/// order; a measurement file given alone as the fit says how to save one.
#[test]
fn evaluate_with_its_arguments_swapped_says_so() {
    let d = tmpdir("swapped");
    let csv = d.join("sim.csv");
    simulate(&csv, &["--separations", "25,30"]);
    let fit = d.join("fit.json");
    assert!(cta(&["fit", s(&csv), "--save", s(&fit)]).status.success());
    fails_in_one_line(
        &cta(&["evaluate", s(&csv), s(&fit)]),
        &[
            "the arguments look swapped",
            &format!("cta evaluate {} {}", s(&fit), s(&csv)),
        ],
    );
    fails_in_one_line(
        &cta(&["evaluate", s(&csv), s(&csv)]),
        &[
            "this is a measurement file (CSV), not a saved fit",
            &format!("`cta fit {} --save fit.json`", s(&csv)),
        ],
    );
    assert!(cta(&["evaluate", s(&fit), s(&csv)]).status.success());
}

/// The audit's case: one row's separation 2 edited to 2.0001 made a separation of its own,
/// silently. Every command that reads a measurement file now warns, naming the values and the
/// line; two values of comparable rows, or farther apart than 0.01 in, are not warned about.
#[test]
fn a_separation_typo_is_warned_about_with_its_line() {
    let d = tmpdir("typo");
    let csv = d.join("sim.csv");
    simulate(
        &csv,
        &["--separations", "2..5", "--noise", "32.8", "--samples", "3"],
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    // The 20th row of 2 in, as a typo.
    let mut rows = 0;
    let mut line_no = 0;
    let edited: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if l.starts_with("2,") {
                rows += 1;
                if rows == 20 {
                    line_no = i + 1;
                    return l.replacen("2,", "2.0001,", 1);
                }
            }
            l.to_string()
        })
        .collect();
    let typo = d.join("typo.csv");
    std::fs::write(&typo, edited.join("\n") + "\n").unwrap();
    let want = format!(
        "warning: {}:{line_no}: separation_in 2.0001 on 1 row (line {line_no}) beside 2 on 299 \
         rows: within 0.01 in",
        s(&typo)
    );
    for args in [
        vec!["fit", s(&typo)],
        vec!["noise", s(&typo)],
        vec!["analyze", s(&typo)],
    ] {
        let o = cta(&args);
        let err = stderr(&o);
        assert!(err.contains(&want), "{args:?}: {err}");
        assert!(err.contains("a typo? Correct them"), "{err}");
    }
    // The same slip below the value (1.9999 beside 2) is warned about too.
    let below = edited.join("\n").replacen("2.0001,", "1.9999,", 1) + "\n";
    let f = d.join("below.csv");
    std::fs::write(&f, below).unwrap();
    let err = stderr(&cta(&["fit", s(&f)]));
    assert!(
        err.contains(&format!(
            "separation_in 1.9999 on 1 row (line {line_no}) beside 2 on 299 rows"
        )),
        "{err}"
    );
    // Not typos: one row at 2.02 in (beyond 0.01 in), and a whole separation at 2.005 beside
    // the one at 2 (as many rows).
    let far = edited.join("\n").replacen("2.0001,", "2.02,", 1) + "\n";
    let whole = text
        .lines()
        .map(|l| match l.strip_prefix("3,") {
            Some(rest) => format!("2.005,{rest}"),
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    for (name, body) in [("far.csv", far), ("whole.csv", whole)] {
        let f = d.join(name);
        std::fs::write(&f, body).unwrap();
        let o = cta(&["fit", s(&f)]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(
            !stderr(&o).contains("within 0.01 in"),
            "{name}: {}",
            stderr(&o)
        );
    }
}

/// The audit's case: `cta --help` started a new user on simulate -> fit -> evaluate, not on
/// `cta demo` (the main job), and `cta -h` named "simulate, fit, evaluate, analyze" only.
#[test]
fn help_starts_with_the_demo_and_names_sweep_and_calibrate() {
    let o = cta(&["-h"]);
    assert!(o.status.success());
    // The summary above the usage line (the command list below names every command).
    let out = String::from_utf8_lossy(&o.stdout).replace('\n', " ");
    let short = out.split("Usage:").next().unwrap();
    for w in [
        "simulate",
        "sweep",
        "fit",
        "evaluate",
        "calibrate",
        "analyze",
        "`cta demo`",
    ] {
        assert!(short.contains(w), "`cta -h` lacks {w}: {short}");
    }
    let o = cta(&["--help"]);
    let long = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(long.contains("Start with:  cta demo"), "{long}");
    assert!(long.contains("Step by step:  cta simulate"), "{long}");
}
