//! A fresh user's mistakes with the data commands (fit, analyze, noise, calibrate, evaluate,
//! simulate) and `cta --help`: each is said in one line that names the file (and the line) at
//! fault and what to do.

use std::path::Path;
use std::process::Output;

mod common;
use common::{cta, s, simulate};

fn tmpdir(name: &str) -> common::TmpDir {
    common::tmpdir_of("fresh-user", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `o` failed, without a panic, with one line holding every needle.
fn fails_with(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert!(!o.status.success(), "expected failure: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks `{n}`: {err}");
    }
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
        fails_with(
            &run(&args),
            &[
                &format!("{}: is a folder, not a measurement file", s(&run1)),
                &format!("give the sweep's data file in it, {}", s(&data)),
            ],
        );
    }
    let fit = d.join("fit.json");
    assert!(cta(&["fit", s(&data), "--save", s(&fit)]).status.success());
    fails_with(
        &cta(&["evaluate", s(&fit), s(&run1)]),
        &[&format!("give the sweep's data file in it, {}", s(&data))],
    );
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fails_with(
        &cta(&["fit", s(&empty)]),
        &["is a folder, not a measurement file: give a CSV file"],
    );
}
