//! What a fault audit found (issue 32, items 5, 7, 8, 9), each held: a file without bound is
//! refused with the limit named, no NaN or inf reaches the text, `cta fit` refuses a file at
//! the 16-bit rail, and every message names its file with its numbers rounded.

mod common;

use std::path::Path;

use common::{cta, s, simulate, stderr, tmpdir_of};

fn tmpdir(name: &str) -> common::TmpDir {
    tmpdir_of("audit", name)
}

/// `file` rewritten with `edit` applied to each data row's fields (header and comments kept).
fn edit_rows(file: &Path, out: &Path, mut edit: impl FnMut(usize, &mut Vec<String>)) {
    let text = std::fs::read_to_string(file).unwrap();
    let mut k = 0;
    let mut lines = Vec::new();
    let mut header = true;
    for l in text.lines() {
        if l.starts_with('#') || header {
            header &= l.starts_with('#');
            lines.push(l.to_string());
            continue;
        }
        let mut f: Vec<String> = l.split(',').map(String::from).collect();
        edit(k, &mut f);
        k += 1;
        lines.push(f.join(","));
    }
    std::fs::write(out, lines.join("\n") + "\n").unwrap();
}

/// Exit status 1 (not a signal, not a panic), and the message holds every needle.
#[track_caller]
fn refused(o: &std::process::Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    for n in needles {
        assert!(e.contains(n), "lacks `{n}`: {e}");
    }
}

/// Item 5: `/dev/zero` as a measurement file, a fit, a plan: each refused at its bound, the
/// bound named, instead of read until the allocator aborts.
#[test]
fn files_without_bound_are_refused_naming_the_limit() {
    let d = tmpdir("bounds");
    refused(
        &cta(&["fit", "/dev/zero"]),
        &["/dev/zero:1: a line longer than 64 KiB"],
    );
    let sim = d.join("sim.csv");
    simulate(&sim, &["--separations", "20,25", "--samples", "2"]);
    refused(
        &cta(&["evaluate", "/dev/zero", s(&sim)]),
        &["/dev/zero", "larger than 64 MiB"],
    );
    refused(
        &cta(&[
            "sweep",
            "--sim",
            "--plan",
            "/dev/zero",
            "--out",
            s(&d.join("run")),
        ]),
        &["/dev/zero", "larger than 1 MiB"],
    );
    // A CR-only file (old Mac line breaks) reads as lines, not as one empty file.
    let cr = d.join("cr.csv");
    let text = std::fs::read_to_string(&sim).unwrap().replace('\n', "\r");
    std::fs::write(&cr, text).unwrap();
    let o = cta(&["fit", s(&cr)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Item 7: constant X, noise-free data, a separation of one row: the text says what does not
/// exist instead of printing NaN or inf; numbers too large to be a rig's are refused at the
/// line and column.
#[test]
fn no_nan_or_inf_in_the_text() {
    let d = tmpdir("nan");
    let sim = d.join("sim.csv");
    simulate(
        &sim,
        &["--separations", "20,25", "--samples", "4", "--noise", "10"],
    );
    let constant = d.join("constant-x.csv");
    edit_rows(&sim, &constant, |_, f| f[4] = "100".into());
    // Every sample of a point the same as its first.
    let noise_free = d.join("noise-free.csv");
    let mut first = (String::new(), String::new());
    edit_rows(&sim, &noise_free, |k, f| {
        if k % 4 == 0 {
            first = (f[4].clone(), f[5].clone());
        }
        (f[4], f[5]) = first.clone();
    });
    let one_row = d.join("one-row.csv");
    let mut text = std::fs::read_to_string(&sim).unwrap();
    let last = text.lines().last().unwrap().to_string();
    text.push_str(&format!("30{}\n", &last[last.find(',').unwrap()..]));
    std::fs::write(&one_row, text).unwrap();
    for (cmd, file) in [
        ("noise", &constant),
        ("noise", &noise_free),
        ("analyze", &one_row),
    ] {
        let o = cta(&[cmd, s(file)]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{cmd} {}: {}",
            file.display(),
            stderr(&o)
        );
        for bad in ["NaN", "inf"] {
            assert!(
                !out.contains(bad),
                "{cmd} {}: {bad} in\n{out}",
                file.display()
            );
        }
        assert!(out.contains("undefined") || out.contains(" - "), "{out}");
    }
    for (col, value, range) in [
        (
            1,
            "-1e308",
            "column `beacon_x_in`: `-1e308` is out of range (allowed: -1000..1000 in)",
        ),
        (
            11,
            "1e308",
            "column `magnitude`: `1e308` is out of range (allowed: 0..1e9)",
        ),
        (
            0,
            "1e300",
            "column `separation_in`: `1e300` is out of range",
        ),
    ] {
        let far = d.join("far.csv");
        edit_rows(&sim, &far, |k, f| {
            if k == 5 {
                f[col] = value.into();
            }
        });
        refused(&cta(&["noise", s(&far)]), &[&format!("far.csv:9: {range}")]);
    }
}

/// Item 8: a file whose every report but a few is at the 16-bit rail is refused by `cta fit`,
/// as `cta analyze` and `cta noise` refuse it, and nothing is saved.
#[test]
fn fit_refuses_a_file_at_the_rail() {
    let d = tmpdir("rail");
    let sim = d.join("sim.csv");
    simulate(&sim, &["--separations", "20,25", "--samples", "2"]);
    let rail = d.join("rail.csv");
    // Every point but the first three (beacons 0, 1, 2 at 20 in) pinned.
    edit_rows(&sim, &rail, |k, f| {
        if k >= 6 {
            f[4] = "32767".into();
        }
    });
    let save = d.join("fit.json");
    refused(
        &cta(&["fit", s(&rail), "--save", s(&save)]),
        &[
            "rail.csv: 197 of 200 points have an output at the 16-bit limit",
            "3 beacon position(s) off it give 6 equations",
        ],
    );
    assert!(!save.exists());
    // Pinned points with enough beacons off the rail: fitted, with the warning as before.
    edit_rows(&sim, &rail, |k, f| {
        if k < 6 {
            f[4] = "32767".into();
        }
    });
    let o = cta(&["fit", s(&rail)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Item 9: messages name their file, with their numbers rounded.
#[test]
fn messages_name_their_file_with_numbers_rounded() {
    let d = tmpdir("messages");
    let sim = d.join("sim.csv");
    simulate(
        &sim,
        &[
            "--separations",
            "20,25,30",
            "--samples",
            "3",
            "--noise",
            "10",
        ],
    );
    let flat = d.join("flat.csv");
    let mut first = (String::new(), String::new());
    edit_rows(&sim, &flat, |k, f| {
        if k % 3 == 0 {
            first = (f[4].clone(), f[5].clone());
        }
        (f[4], f[5]) = first.clone();
    });
    let cal = d.join("cal.json");
    refused(
        &cta(&["calibrate", s(&flat), "--out", s(&cal)]),
        &[&format!(
            "{}: the noise of its repeated samples is 0 counts",
            flat.display()
        )],
    );
    refused(
        &cta(&[
            "calibrate",
            s(&sim),
            "--noise",
            "0.0000000000005312494315246781",
            "--out",
            s(&cal),
        ]),
        &["--noise 5.312e-13: the board takes 0.01 to 10,000 counts"],
    );
    // A calibration with a number out of range where only the host reads it.
    let o = cta(&["calibrate", s(&sim), "--out", s(&cal)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&cal).unwrap();
    let at = text.rfind("\"sigma\": ").unwrap() + "\"sigma\": ".len();
    let end = at + text[at..].find([',', '\n']).unwrap();
    let big = d.join("big.json");
    std::fs::write(&big, format!("{}1e309{}", &text[..at], &text[end..])).unwrap();
    refused(
        &cta(&["sensor", "--sim", "load-calibration", s(&big)]),
        &[&format!("{}: ", big.display()), "number out of range"],
    );
    // An empty plan (a disk that filled as it was written) is said to be empty.
    let plan = d.join("empty.toml");
    std::fs::write(&plan, "").unwrap();
    refused(
        &cta(&[
            "sweep",
            "--sim",
            "--plan",
            s(&plan),
            "--out",
            s(&d.join("run")),
        ]),
        &[&format!("{}: the file is empty", plan.display())],
    );
    // The fault schedule's N counts from 1; the byte faults offered are ones a session
    // survives.
    let plan = d.join("plan.toml");
    std::fs::write(
        &plan,
        "separations_in = [10]\nbeacons = [0]\nsamples = 1\nsettle_ms = 0\n",
    )
    .unwrap();
    for (fault, said) in [
        ("vanish=sensor@0:500", "counts from 1"),
        ("drop=0.2", "0..=0.005"),
    ] {
        refused(
            &cta(&[
                "sweep",
                "--sim",
                "--sim-fault",
                fault,
                "--plan",
                s(&plan),
                "--out",
                s(&d.join("run")),
            ]),
            &[fault, said],
        );
    }
}
