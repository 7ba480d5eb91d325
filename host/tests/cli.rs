//! The `cta` binary end to end: the thesis commands, and bad input giving a one-line error
//! and a non-zero exit, never a panic.

use std::path::Path;
use std::process::Output;

mod common;
use common::{cta, json, s, simulate};

fn tmpdir(name: &str) -> common::TmpDir {
    common::tmpdir_of("cli", name)
}

fn fails_with(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "expected failure, got success: {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(err.contains(needle), "stderr lacks `{needle}`: {err}");
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
}

#[test]
fn simulate_fit_evaluate_round_trip() {
    let d = tmpdir("rt");
    let csv = d.join("sim.csv");
    let fit = d.join("fit.json");
    let o = cta(&["simulate", "--out", s(&csv), "--separations", "20,25,30"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(d.join("sim.truth.json").exists());
    let f = json(&cta(&[
        "fit",
        s(&csv),
        "--separations",
        "25,30",
        "--save",
        s(&fit),
        "--json",
    ]));
    // Table 3, (25, 30): d3 = +1.1378, H = 19016, rms 1.6.
    assert!((f["params"]["d3"].as_f64().unwrap() - 1.1378).abs() < 0.03);
    assert!((f["params"]["H"].as_f64().unwrap() - 19016.0).abs() < 0.003 * 19016.0);
    for k in ["d1", "d2", "d3", "p1", "p2", "p3", "H"] {
        assert!(f["sigma"][k].as_f64().unwrap() > 0.0);
    }
    assert!(f["rms_counts"].as_f64().is_some() && f["iterations"].as_u64().is_some());
    assert!(f["condition"].as_f64().unwrap() > 1.0 && f["warnings"].is_array());
    let e = json(&cta(&["evaluate", s(&fit), s(&csv), "--json"]));
    assert_eq!(e["separation_in"].as_array().unwrap().len(), 3);
    let std30 = e["angle_std_deg"][2].as_f64().unwrap();
    // Figure 57 at 30 in: ~0.1 deg, within REFERENCE's factor 1.5 (core/tests/figure57.rs
    // checks 1 and 100 in as well).
    assert!(std30 > 0.1 / 1.5 && std30 < 0.1 * 1.5, "{std30}");
    // The text says how far the error stands above the CTA uncertainty (about 1.3x at 30 in,
    // not the thesis's order of magnitude).
    let o = cta(&["evaluate", s(&fit), s(&csv)]);
    let text = String::from_utf8_lossy(&o.stdout);
    let note = text
        .lines()
        .find(|l| l.starts_with("note: std over the CTA uncertainty: "))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        note.contains(
            "x at 30 in; the thesis's \"an order of magnitude below\" (10x or more) holds at none \
             of these separations"
        ),
        "{note}"
    );
    let r30: f64 = note
        .split(" to ")
        .nth(1)
        .unwrap()
        .split('x')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((1.2..1.45).contains(&r30), "{note}");
    assert_eq!(e["reference"], "truth");
    assert_eq!(e["at_rail"], serde_json::json!([0, 0, 0]));
    // The same data without the sidecar: measured from the fit's own eye point the error
    // is far smaller (self-consistency only), which a warning says; with the head centre
    // given (`--head`, here the truth's) it is the Figure 57 error again.
    let bare = d.join("bare.csv");
    std::fs::copy(&csv, &bare).unwrap();
    let o = cta(&["evaluate", s(&fit), s(&bare), "--json"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("no truth sidecar and no --head") && err.contains("self"),
        "{err}"
    );
    let e = json(&o);
    assert_eq!(e["reference"], "fit");
    assert!(
        e["angle_std_deg"][2].as_f64().unwrap() < std30 / 10.0,
        "{e}"
    );
    let o = cta(&[
        "evaluate",
        s(&fit),
        s(&bare),
        "--head",
        "0.6,0.1,0.062",
        "--json",
    ]);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("warning"));
    let e = json(&o);
    assert_eq!(e["reference"], "head");
    assert_eq!(e["reference_in"][2].as_f64().unwrap(), 0.062);
    assert_eq!(e["budget"], "thesis Table 2");
    assert_eq!(e["angle_std_deg"][2].as_f64().unwrap(), std30);
    // A head typed in mm (or 40 in below the board) is refused.
    let o = cta(&["evaluate", s(&fit), s(&bare), "--head", "15.2,2.5,1.6"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("within +/-12 in"));
    // The sidecar and --head together are refused: which would be meant?
    let o = cta(&["evaluate", s(&fit), s(&csv), "--head", "0.6,0.1,0.062"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("leave out --head"));
    // A lab's own budget sets the CTA uncertainty column: 4x Table 2's items, 4x the angle.
    let table2 = e["cta_uncertainty_deg"][2].as_f64().unwrap();
    let b = d.join("budget.toml");
    std::fs::write(
        &b,
        "[[item]]\nname = \"all\"\nx = 126.0198\ny = 97.4731\nz = 70.0857\n",
    )
    .unwrap();
    let e = json(&cta(&[
        "evaluate",
        s(&fit),
        s(&bare),
        "--head",
        "0.6,0.1,0.062",
        "--budget",
        s(&b),
        "--json",
    ]));
    assert_eq!(e["budget"], s(&b));
    let mine = e["cta_uncertainty_deg"][2].as_f64().unwrap();
    assert!((mine / table2 - 4.0).abs() < 0.01, "{mine} vs {table2}");
}

#[test]
fn nearfield_and_uncertainty_json() {
    let n = json(&cta(&[
        "nearfield",
        "--profile",
        "quartic",
        "--theta",
        "6",
        "--json",
    ]));
    let p = n["crossing_D"]["proximity"][0].as_f64().unwrap();
    assert!((p - 68.5).abs() < 0.02 * 68.5);
    assert!(n["coeff_deg_D"]["intensity"][0].as_f64().unwrap() > 10.0);
    assert_eq!(n["theta_deg"][0], 6.0);
    // The quartic is evaluated at the ray to the farther cell, past theta close in: at
    // theta = 30 deg (below its 31 deg limit) it is past the limit inside 24.6 D, which the
    // plot draws (from 3 D) and the crossings (1,462 D and more) do not reach.
    let nf = tmpdir("nf-quartic");
    let q = |plot: bool| {
        let svg = nf.join("nf.svg");
        let mut args = vec![
            "nearfield",
            "--profile",
            "quartic",
            "--theta",
            "30",
            "--json",
        ];
        if plot {
            args.extend(["--plot", s(&svg)]);
        }
        json(&cta(&args))["warnings"].to_string()
    };
    let w = q(true);
    assert!(w.contains("theta = 30 deg closer than 24.6 D"), "{w}");
    assert_eq!(q(false), "[]");
    let n = json(&cta(&["nearfield", "--theta", "30", "--json"]));
    assert_eq!(n["warnings"], serde_json::json!([]));
    let u = json(&cta(&["uncertainty", "--json"]));
    assert!((u["rss_mils"]["x"].as_f64().unwrap() - 31.54).abs() < 0.05);
    assert!((u["rss_mils"]["z"].as_f64().unwrap() - 17.52).abs() < 0.05);
    // Eq 40 at 6 and 18 deg (REFERENCE: 1.800 and 1.746 deg in, 0.5 %), and the near-field
    // error over it: "over four times" at 6 deg, 11.8 / 15.4 at 18 deg (README).
    for (k, (t, v)) in [(6.0, 1.800), (18.0, 1.746)].into_iter().enumerate() {
        let e = &u["eq40_u_theta_times_R_deg_in"][k];
        assert_eq!(e["theta_deg"], t);
        let got = e["value"].as_f64().unwrap();
        assert!((got / v - 1.0).abs() < 0.005, "{t} deg: {got}");
    }
    let ratio = |k: usize, p: &str| u["nearfield_over_cta"][k][p].as_f64().unwrap();
    assert!(ratio(0, "lambertian") > 4.0 && ratio(0, "quartic") > 3.95);
    assert!((ratio(1, "lambertian") - 11.76).abs() < 0.05, "{u}");
    assert!((ratio(1, "quartic") - 15.38).abs() < 0.05, "{u}");
    // A user budget.
    let d = tmpdir("budget");
    let b = d.join("b.toml");
    std::fs::write(
        &b,
        "[[item]]\nname = \"a\"\nx = 3\n[[item]]\nname = \"b\"\nx = 4\nz_plus = 1\n",
    )
    .unwrap();
    let o = cta(&["uncertainty", "--budget", s(&b), "--json"]);
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let u = json(&o);
    assert!((u["rss_mils"]["x"].as_f64().unwrap() - 5.0).abs() < 1e-12);
    // Values that look like inches (or beyond 1 in) are taken, with a caution naming mils.
    for (text, needle) in [
        (
            "[[item]]\nname = \"a\"\nx = 0.005\n",
            "the largest uncertainty is 0.005 mils",
        ),
        (
            "[[item]]\nname = \"a\"\nx = 3\n[[item]]\nname = \"b\"\nz = 5000\n",
            "item `b`: 5000 mils is more than 1 in",
        ),
    ] {
        std::fs::write(&b, text).unwrap();
        let o = cta(&["uncertainty", "--budget", s(&b)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && err.contains(needle), "{err}");
    }
    std::fs::write(&b, "[[item]]\nname = \"a\"\nxx = 3\n").unwrap();
    // TOML errors quote the offending line under the one-line summary.
    let o = cta(&["uncertainty", "--budget", s(&b)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("line 3") && err.contains("unknown field `xx`"),
        "{err}"
    );
    // Budgets that would print nonsense (inf or 0 ratios, merged sides) are refused by name.
    for (text, needle) in [
        ("[[item]]\nname = \"a\"\n", "item `a` has no uncertainty"),
        (
            "[[item]]\nname = \"a\"\nx = 1e308\n",
            "1e308 mils must be in 0..=1000000",
        ),
        (
            "[[item]]\nname = \"a\"\nx = 0\n",
            "every uncertainty in the budget is 0",
        ),
        (
            "[[item]]\nname = \"a\"\nx = 1\nx_plus = 2\n",
            "gives both `x` and `x_plus`/`x_minus`",
        ),
    ] {
        std::fs::write(&b, text).unwrap();
        fails_with(&cta(&["uncertainty", "--budget", s(&b)]), needle);
    }
    fails_with(
        &cta(&["analyze", "any.csv", "--max-effects", "0"]),
        "--max-effects 0: no effect could be named",
    );
    // Beacons raised to the sensor or past it: refused before any work.
    fails_with(
        &cta(&["sensor", "accuracy", "--depth", "50", "--ranges", "4,30"]),
        "at the 4 in range it would be at the sensor or behind it",
    );
    fails_with(
        &cta(&["uncertainty", "--diameter-in=-1"]),
        "the sensor diameter must be > 0",
    );
    // A negative number after a space reaches the option's own check (not "unexpected
    // argument '-1'").
    fails_with(
        &cta(&["uncertainty", "--diameter-in", "-1"]),
        "the sensor diameter must be > 0",
    );
    fails_with(
        &cta(&["simulate", "--out", "x.csv", "--noise", "-3"]),
        "--noise must be >= 0 counts",
    );
    // A list starting with a negative number reaches the list's own check too.
    fails_with(
        &cta(&["simulate", "--out", "x.csv", "--separations", "-5,3"]),
        "separation -5 in must be a positive",
    );
    fails_with(
        &cta(&["nearfield", "--theta", "-6,18"]),
        "--theta -6: must be in (0, 60) deg",
    );
    // A noise far below the effects' 1/R tails: above the noise out to 1e7 D, not "below".
    let n = json(&cta(&["nearfield", "--noise-deg", "1e-7", "--json"]));
    assert_eq!(n["crossing_kind"]["proximity"][0], "above_noise_to_1e7_D");
    assert!(n["crossing_D"]["proximity"][0].is_null());
    let n = json(&cta(&["nearfield", "--noise-deg", "80", "--json"]));
    assert_eq!(n["crossing_kind"]["combined"][0], "below_noise");
    let o = cta(&["nearfield", "--noise-deg", "1e-7"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("> 1e7") && !out.contains("below noise"),
        "{out}"
    );
}

#[test]
fn bad_measurement_files() {
    let d = tmpdir("bad");
    let f = d.join("m.csv");
    std::fs::write(&f, "").unwrap();
    fails_with(&cta(&["fit", s(&f)]), "no measurements");
    std::fs::write(&f, "x,y,separation_in,beacon_x_in,beacon_y_in\n1,2,3,4,5\n").unwrap();
    fails_with(
        &cta(&["fit", s(&f)]),
        "missing required column `beacon_z_in`",
    );
    std::fs::write(
        &f,
        "x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,2,20,0,0,20\n1,inf,20,1,0,20\n",
    )
    .unwrap();
    fails_with(
        &cta(&["fit", s(&f)]),
        "m.csv:3: column `y`: `inf` is not a finite number",
    );
    std::fs::write(&f, "x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,2,20,0,0,20\n3,4,20,1,0,20\n5,6,20,0,1,20\n").unwrap();
    fails_with(&cta(&["fit", s(&f)]), "fewer than the 7 parameters");
    let sim = d.join("sim.csv");
    assert!(
        cta(&["simulate", "--out", s(&sim), "--separations", "20,25"])
            .status
            .success()
    );
    fails_with(
        &cta(&["fit", s(&sim), "--separations", "30"]),
        "separation(s) 30 not in the file, nor any within 0.1 in (it has 20, 25)",
    );
    fails_with(
        &cta(&["fit", s(&sim), "--weights", "repeat"]),
        "needs repeated samples",
    );
    fails_with(&cta(&["fit", s(&d.join("absent.csv"))]), "absent.csv");
    fails_with(
        &cta(&["simulate", "--out", s(&sim), "--effect", "glare=1"]),
        "unknown effect `glare`",
    );
}

#[test]
fn one_separation_names_the_parallel_pair() {
    let d = tmpdir("one");
    let sim = d.join("one.csv");
    assert!(cta(&[
        "simulate",
        "--out",
        s(&sim),
        "--separations",
        "20",
        "--far-field",
        "--p",
        "0,0,0"
    ])
    .status
    .success());
    fails_with(&cta(&["fit", s(&sim)]), "d3");
}

/// The README's main command: the demo on the simulated CTA names its hidden effect and ends
/// in an HTML report.
#[test]
fn demo_runs_end_to_end() {
    let d = tmpdir("demo");
    let out = d.join("demo");
    let o = cta(&["demo", "--out", s(&out)]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{}\n{}",
        stdout,
        String::from_utf8_lossy(&o.stderr)
    );
    // One screen: a line per step, the files, the rehearsal; the details in logs/.
    assert!(stdout.lines().count() <= 25, "{stdout}");
    assert!(stdout.contains("named: cell_gain"), "{stdout}");
    let log = |n: &str| std::fs::read_to_string(out.join("logs").join(n)).unwrap();
    assert!(log("7-analyze.txt").contains("named: cell_gain"));
    assert!(
        log("3-sweep.txt").contains("1400/1400 points") && stdout.contains("1400 ok"),
        "{stdout}"
    );
    assert!(
        stdout.contains("on the sensor board: the board's calibration holds it (gx, gy)"),
        "{stdout}"
    );
    // The board's calibration holds the hidden cell gain (cell_gain=0.02,-0.01).
    let cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("cal.json")).unwrap()).unwrap();
    let gx = cal["near_field"]["gain"][0].as_f64().unwrap();
    assert!((gx - 0.02).abs() < 0.001, "{cal}");
    // The board's calibration holds it: `cta calibrate` does not warn (the pinhole `cta fit`
    // at 20-30 in does, pointing at `cta analyze`, which names it).
    assert!(
        !log("6-calibrate.txt").contains("the chip's near-field model (d, p"),
        "{stdout}"
    );
    assert!(log("4-fit.txt").contains("the pinhole model (eq 65: d, p, H) cannot represent"));
    assert!(stdout.contains("1 warning(s)"), "{stdout}");
    for f in [
        "nearfield.svg",
        "uncertainty.svg",
        "fit.json",
        "figure57.svg",
        "cal.json",
        "calibration.svg",
        "run/data.csv",
        "report/index.html",
        "index.html",
        "logs/1-nearfield.txt",
        "logs/2-uncertainty.txt",
        "logs/5-figure57.txt",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // The index shows every plot the demo made.
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    for svg in [
        "nearfield.svg",
        "uncertainty.svg",
        "figure57.svg",
        "calibration.svg",
    ] {
        assert!(
            index.contains(&format!("<img src=\"{svg}\"")),
            "{svg} not shown"
        );
    }
    // Never overwritten without --force.
    let again = cta(&["demo", "--out", s(&out)]);
    assert!(!again.status.success() && String::from_utf8_lossy(&again.stderr).contains("--force"));
}

#[test]
#[cfg(unix)]
fn a_closed_output_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    // The reader is gone before cta writes its first line: like `cta nearfield | head -0`.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_cta"))
        .arg("nearfield")
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("run cta");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(
        o.status.signal(),
        Some(libc::SIGPIPE),
        "{:?} {err}",
        o.status
    );
}

#[test]
fn outputs_never_replace_other_kinds_of_file() {
    let d = tmpdir("replace");
    let data = d.join("data.csv");
    let text =
        "# cta 0.1.0 sweep: plan `x`\nseparation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y\n";
    std::fs::write(&data, text).unwrap();
    let keep = |what: &str| {
        assert_eq!(std::fs::read_to_string(&data).unwrap(), text, "{what}");
    };
    // simulate --out: an earlier simulation is replaced, anything else only with --force;
    // the message names the file and the way on.
    fails_with(
        &cta(&["simulate", "--out", s(&data), "--separations", "20"]),
        &format!(
            "--out {}: exists and is not an earlier `cta simulate` output (first line: `# cta 0.1.0 \
             sweep: plan `x``); not replaced: give another file name, or --force to replace it",
            data.display()
        ),
    );
    keep("simulate");
    // Refused before simulating: a simulation that would fail (nothing to write) is not run.
    fails_with(
        &cta(&[
            "simulate",
            "--out",
            s(&data),
            "--separations",
            "2",
            "--d",
            "1000,0,0.062",
        ]),
        "is not an earlier `cta simulate` output",
    );
    keep("simulate, refused first");
    assert!(!d.join("data.csv.partial").exists() && !d.join("data.truth.json").exists());
    let sim = d.join("sim.csv");
    for _ in 0..2 {
        let o = cta(&["simulate", "--out", s(&sim), "--separations", "20,25"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // A folder is refused, with a file name to use instead.
    fails_with(
        &cta(&["simulate", "--out", s(&d), "--separations", "20"]),
        &format!(
            "--out {}: is a folder; give a file name (e.g. {})",
            d.display(),
            d.join("sim.csv").display()
        ),
    );
    // fit --save: never the measurement file; an earlier fit is replaced.
    fails_with(
        &cta(&["fit", s(&sim), "--save", s(&sim)]),
        "is the measurement file",
    );
    fails_with(
        &cta(&["fit", s(&sim), "--save", s(&data)]),
        "is not an earlier saved fit",
    );
    keep("fit");
    let fit = d.join("fit.json");
    for _ in 0..2 {
        let o = cta(&["fit", s(&sim), "--save", s(&fit)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // --plot: an earlier plot is replaced, never another file.
    fails_with(
        &cta(&["evaluate", s(&fit), s(&sim), "--plot", s(&data)]),
        "is not a plot or report cta wrote",
    );
    fails_with(
        &cta(&["nearfield", "--plot", s(&data)]),
        "is not a plot or report cta wrote",
    );
    keep("plot");
    let svg = d.join("f.svg");
    for _ in 0..2 {
        let o = cta(&["evaluate", s(&fit), s(&sim), "--plot", s(&svg)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // A simulation that would write nothing is an error, and leaves nothing behind.
    let none = d.join("none.csv");
    fails_with(
        &cta(&[
            "simulate",
            "--out",
            s(&none),
            "--separations",
            "2",
            "--d",
            "1000,0,0.062",
        ]),
        "nothing to write",
    );
    assert!(!none.exists() && !d.join("none.csv.partial").exists());
}

/// Plots and reports replace only files `cta` wrote (they carry its mark), never a lab's own
/// SVG or web page; the analysis is printed whatever happens to the report.
#[test]
fn plots_and_reports_replace_only_what_cta_wrote() {
    let d = tmpdir("own-files");
    let own_svg = "<svg xmlns=\"http://www.w3.org/2000/svg\"><!-- lab schematic --></svg>";
    let schem = d.join("schem.svg");
    std::fs::write(&schem, own_svg).unwrap();
    fails_with(
        &cta(&["nearfield", "--plot", s(&schem)]),
        "is not a plot or report cta wrote",
    );
    assert_eq!(std::fs::read_to_string(&schem).unwrap(), own_svg);
    // cta's own plot: replaced, and marked again.
    let nf = d.join("nf.svg");
    for _ in 0..2 {
        let o = cta(&["nearfield", "--plot", s(&nf)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let text = std::fs::read_to_string(&nf).unwrap();
    // The root element first (content sniffers see an SVG), the mark on the next line.
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("<svg "), "{text:.300}");
    assert!(
        lines.next().unwrap().starts_with("<!-- written by cta"),
        "{text:.300}"
    );
    let o = cta(&["nearfield", "--plot", s(&nf)]);
    assert_eq!(
        String::from_utf8_lossy(&o.stderr).trim(),
        format!("plot: {}", nf.display())
    );
    // Plots are SVG: not written under another extension.
    let png = d.join("out.png");
    fails_with(
        &cta(&["nearfield", "--plot", s(&png)]),
        "plots are SVG files: give a name ending in .svg",
    );
    assert!(!png.exists());

    let csv = d.join("sim.csv");
    common::simulate(&csv, &["--separations", "10,20,30", "--samples", "2"]);
    let page = "<html>my lab wiki page</html>";
    let site = d.join("site");
    std::fs::create_dir_all(&site).unwrap();
    std::fs::write(site.join("index.html"), page).unwrap();
    let o = cta(&["analyze", s(&csv), "--report", s(&site)]);
    fails_with(&o, "is not a plot or report cta wrote");
    assert!(o.stdout.is_empty(), "refused after the work");
    let notes = d.join("notes");
    std::fs::create_dir_all(&notes).unwrap();
    std::fs::write(notes.join("noise.svg"), "my notes").unwrap();
    fails_with(
        &cta(&["noise", s(&csv), "--plot", s(&notes)]),
        "is not a plot or report cta wrote",
    );
    assert_eq!(
        std::fs::read_to_string(site.join("index.html")).unwrap(),
        page
    );
    assert_eq!(
        std::fs::read_to_string(notes.join("noise.svg")).unwrap(),
        "my notes"
    );
    // A report cta wrote is replaced; a report path that is a file is named, after the
    // analysis was printed.
    let rep = d.join("rep");
    for _ in 0..2 {
        let o = cta(&["analyze", s(&csv), "--report", s(&rep)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let o = cta(&["analyze", s(&csv), "--report", s(&csv)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !o.stdout.is_empty(), "{err}");
    assert!(
        err.contains(&format!(
            "cannot write {}",
            csv.join("index.html").display()
        )) && err.contains("the report was not written"),
        "{err}"
    );
}

#[test]
fn demo_force_replaces_only_an_earlier_demo() {
    let d = tmpdir("demo-force");
    let out = d.join("notes");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notebook.txt"), "precious").unwrap();
    fails_with(
        &cta(&["demo", "--out", s(&out), "--force"]),
        "holds files the demo did not write (notebook.txt)",
    );
    assert!(out.join("notebook.txt").exists());
    // A bad effect is refused by its own flag's name, before anything is written.
    let fresh = d.join("fresh");
    fails_with(
        &cta(&["demo", "--out", s(&fresh), "--effect", "bogus"]),
        "--effect",
    );
    assert!(!fresh.exists());
}

/// `cta calibrate` closes the loop from a sweep to the board: on a simulated sweep of a
/// head at a non-default place, it recovers d, p, the face angle and the cell offset within
/// 4 sigma, the noise within 5 %, chi2/dof near 1, and the board stores the file it writes.
/// Cell gains and offsets and the pairs' face angles are fitted; a hidden effect the chip's
/// model cannot represent is flagged, pointing at `cta analyze`.
#[test]
fn calibrate_writes_what_the_board_loads() {
    let d = tmpdir("cal");
    let csv = d.join("sweep.csv");
    let cal = d.join("cal.json");
    let sim = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "--separations",
            "2..30:2,25",
            "--samples",
            "4",
            "--noise",
            "32.8",
            "--d",
            "0.55,0.12,0.07",
            "--p",
            "0.002,-0.001,0.003",
            "--seed",
            "5",
        ];
        args.extend_from_slice(extra);
        simulate(out, &args);
    };
    sim(&csv, &[]);
    let r = json(&cta(&["calibrate", s(&csv), "--out", s(&cal), "--json"]));
    let f = &r["file"];
    let sigma = |n: &str| f["fitted"]["sigma"][n].as_f64().unwrap();
    let near = |v: &serde_json::Value, truth: f64, n: &str| {
        let v = v.as_f64().unwrap();
        assert!(
            (v - truth).abs() < 4.0 * sigma(n),
            "{n} = {v}, truth {truth}, sigma {}",
            sigma(n)
        );
    };
    for (k, t) in [0.55, 0.12, 0.07].into_iter().enumerate() {
        near(&f["d"][k], t, ["d1", "d2", "d3"][k]);
    }
    for (k, t) in [0.002, -0.001, 0.003].into_iter().enumerate() {
        near(&f["p"][k], t, ["p1", "p2", "p3"][k]);
    }
    near(&f["near_field"]["alpha_deg"], 30.0, "a");
    near(&f["near_field"]["s"], 0.175, "s");
    // The pinhole fit's own d, p, for the chip's pinhole model: its eye point, about 1 in
    // above the head (README, "virtual eye"), with its 1-sigma.
    let eye = |k: usize| f["pinhole"]["d"][k].as_f64().unwrap();
    assert!(
        eye(2) - f["d"][2].as_f64().unwrap() > 0.8,
        "{}",
        f["pinhole"]
    );
    assert!(sigma("pinhole.d3") > 0.0 && sigma("pinhole.p3") > 0.0);
    assert_eq!(
        f["fitted"]["pinhole_separations"],
        serde_json::json!([25.0, 30.0])
    );
    let noise = f["noise"].as_f64().unwrap();
    assert!((noise / 32.8 - 1.0).abs() < 0.05, "noise {noise}");
    let chi2 = f["fitted"]["chi2_dof"].as_f64().unwrap();
    assert!((0.85..1.15).contains(&chi2), "chi2/dof {chi2}");
    assert_eq!(
        r["warnings"].as_array().unwrap().len(),
        1,
        "{}",
        r["warnings"]
    );
    // The near-field model gains over the pinhole one close in, not at 30 in.
    let by = r["by_separation"].as_array().unwrap();
    let rms = |k: usize, m: &str| by[k][m].as_f64().unwrap();
    assert!(rms(0, "pinhole_counts") > 100.0 * rms(0, "near_field_counts"));
    let last = by.len() - 1;
    assert!(rms(last, "near_field_counts") < 1.2 * rms(last, "noise_counts"));
    // The board stores it; the file is replaced by a later calibration.
    let o = cta(&["sensor", "--sim", "load-calibration", s(&cal)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The in-process board ends with the command: said, so nobody expects it kept.
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(
        said.contains("stored in flash of the simulated board") && said.contains("cta sensor sim"),
        "{said}"
    );
    let svg = d.join("cal.svg");
    let o = cta(&["calibrate", s(&csv), "--out", s(&cal), "--plot", s(&svg)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("load-calibration"), "{text}");
    // Clean data: nothing flagged, and a note on what the 1-sigma assume.
    assert!(
        !text.contains("misses") && text.contains("note: the 1-sigma"),
        "{text}"
    );
    // Each estimate to the digits its 1-sigma resolves, as `cta analyze` prints them.
    let row = |n: &str| {
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{n} ")))
            .unwrap_or_else(|| panic!("no {n} line in {text}"));
        (line.to_string(), f["fitted"]["sigma"][n].as_f64().unwrap())
    };
    let (line, s_d1) = row("d1");
    let (v, sd) = cta_lab::analyze::digits::pm_parts(f["d"][0].as_f64().unwrap(), s_d1);
    assert!(line.contains(&format!("{v} ± {sd}")), "{line}");
    let (v, sd) = cta_lab::analyze::digits::pm_parts(eye(2), sigma("pinhole.d3"));
    assert!(
        text.contains("its d = ") && text.contains(&format!("{v} ± {sd} in")),
        "{text}"
    );
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(
        plot.contains("<svg") && plot.contains("near-field"),
        "{plot}"
    );

    // The head's d within 4 sigma of the simulated one.
    let d_on_truth = |f: &serde_json::Value| {
        for (k, (n, t)) in [("d1", 0.55), ("d2", 0.12), ("d3", 0.07)]
            .into_iter()
            .enumerate()
        {
            let v = f["d"][k].as_f64().unwrap();
            let sd = f["fitted"]["sigma"][n].as_f64().unwrap();
            assert!((v - t).abs() < 4.0 * sd, "{n} = {v} +/- {sd}, truth {t}");
        }
    };

    // A cell gain mismatch: the chip's model holds it, so it is fitted.
    let gain = d.join("gain.csv");
    sim(&gain, &["--effect", "cell_gain=0.03,-0.02"]);
    let r = json(&cta(&["calibrate", s(&gain), "--json"]));
    let f = &r["file"];
    let sigma = |n: &str| f["fitted"]["sigma"][n].as_f64().unwrap();
    for (k, (n, t)) in [("gx", 0.03), ("gy", -0.02)].into_iter().enumerate() {
        let g = f["near_field"]["gain"][k].as_f64().unwrap();
        assert!((g - t).abs() < 4.0 * sigma(n), "{n} = {g}, truth {t}");
    }
    assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.15);

    // Ambient light on two cells (cell_bias), 10 % of a beacon's signal at 30 in on cell 1:
    // the chip's model holds it, so it is fitted. It pulls the pinhole fit at 25-30 in
    // inches off (d1 ~4 in, at a pinhole chi2/dof of ~25 that the text shows). With the
    // pinhole stage weighted by each point's own 4 samples, the near-field fit failed from
    // that start and was started again from the nominal head pose; weighted by the pooled
    // noise, it converges from the pinhole start. Either way it lands on the truth.
    let bias = d.join("bias.csv");
    sim(&bias, &["--effect", "cell_bias=1e-4,-5e-5"]);
    let r = json(&cta(&["calibrate", s(&bias), "--json"]));
    let f = &r["file"];
    let sigma = |n: &str| f["fitted"]["sigma"][n].as_f64().unwrap();
    for (k, (n, t)) in [("bx", 1e-4), ("by", -5e-5)].into_iter().enumerate() {
        let b = f["near_field"]["bias"][k].as_f64().unwrap();
        assert!((b - t).abs() < 4.0 * sigma(n), "{n} = {b}, truth {t}");
    }
    d_on_truth(f);
    assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.15, "{r}");
    assert!(r["pinhole_chi2_dof"].as_f64().unwrap() > 10.0, "{r}");
    // ... and says so, as `cta fit --weights pooled` would on those separations.
    let w = r["pinhole_warnings"].to_string();
    assert!(
        w.contains("the pinhole stage at 25, 30 in: chi2/dof") && w.contains("cta analyze"),
        "{w}"
    );

    // Cells 0.5 in off the head's centre (proximity=0.5, nominal 0.175): the pinhole fit's d
    // leaves beacons close in in a cell's shadow, so the near-field fit starts again from the
    // nominal head pose, says so, and lands on the truth.
    let wide = d.join("wide.csv");
    sim(&wide, &["--effect", "proximity=0.5"]);
    let r = json(&cta(&["calibrate", s(&wide), "--json"]));
    let f = &r["file"];
    let sigma = |n: &str| f["fitted"]["sigma"][n].as_f64().unwrap();
    let w = r["warnings"].to_string();
    assert!(
        w.contains("the near-field fit started from the nominal head pose"),
        "{w}"
    );
    let s_fit = f["near_field"]["s"].as_f64().unwrap();
    assert!((s_fit - 0.5).abs() < 4.0 * sigma("s"), "s = {s_fit}");
    d_on_truth(f);
    assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.15, "{r}");

    // A plate tilted 5 deg: absorbed by d and p (d1 off by ~40 sigma) except close in, so
    // chi2/dof stays under the warning line; the 2 in separation is flagged on its own.
    let tilt = d.join("tilt.csv");
    sim(&tilt, &["--effect", "beacon_tilt=5,45"]);
    let r = json(&cta(&["calibrate", s(&tilt), "--json"]));
    let f = &r["file"];
    assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.2, "{r}");
    let z = |k: usize| r["by_separation"][k]["near_field_z"].as_f64().unwrap();
    assert!(z(0) > 5.0, "{r}");
    assert!((1..15).all(|k| z(k) < 5.0), "{r}");
    let w = r["warnings"].to_string();
    assert!(w.contains("misses the data at 2 in"), "{w}");
    let o = cta(&["calibrate", s(&tilt)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("<- near-field misses") && !text.contains("note: the 1-sigma"),
        "{text}"
    );

    // Face angles that differ between the pairs (31 and 30 deg): fitted.
    let faces = d.join("faces.csv");
    sim(&faces, &["--effect", "face_angle=1,0"]);
    let r = json(&cta(&["calibrate", s(&faces), "--json"]));
    let f = &r["file"];
    let sigma = |n: &str| f["fitted"]["sigma"][n].as_f64().unwrap();
    for (n, key, t) in [("a", "alpha_deg", 31.0), ("ay", "alpha_y_deg", 30.0)] {
        let v = f["near_field"][key].as_f64().unwrap();
        assert!((v - t).abs() < 4.0 * sigma(n), "{n} = {v}, truth {t}");
    }
    assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.15, "{r}");

    // Cells that saturate close in (at 0.2/in^2): the chip's model cannot hold it, so the
    // calibration says so and names the file to analyze; the restart from the nominal head
    // pose reaches the same minimum and is not reported.
    let sat = d.join("sat.csv");
    sim(&sat, &["--effect", "saturation=0.2"]);
    let r = json(&cta(&["calibrate", s(&sat), "--json"]));
    let w = r["warnings"].to_string();
    assert!(w.contains("cta analyze") && w.contains("sat.csv"), "{w}");
    assert!(!w.contains("nominal head pose"), "{w}");
    assert!(r["file"]["fitted"]["chi2_dof"].as_f64().unwrap() > 2.0);

    // A narrower LED pattern than assumed (45 deg half angle) is NOT flagged: the cell
    // offset and d3 absorb it (chi2/dof ~1, s off by many sigma). With the LEDs' exponent
    // (m = ln 0.5 / ln cos 45 deg = 2) the fit is right. host/CALIBRATE.md says so.
    let narrow = d.join("narrow.csv");
    sim(&narrow, &["--effect", "beacon_pattern=45"]);
    let s_off = |extra: &[&str]| {
        let mut args = vec!["calibrate", s(&narrow), "--json"];
        args.extend_from_slice(extra);
        let r = json(&cta(&args));
        let f = &r["file"];
        assert!(f["fitted"]["chi2_dof"].as_f64().unwrap() < 1.15, "{r}");
        (f["near_field"]["s"].as_f64().unwrap() - 0.175).abs()
            / f["fitted"]["sigma"]["s"].as_f64().unwrap()
    };
    assert!(s_off(&[]) > 20.0);
    assert!(s_off(&["--pattern-m", "2"]) < 4.0);

    // Refusals, one line each, nothing written.
    fails_with(
        &cta(&["calibrate", s(&csv), "--out", s(&csv)]),
        "is the measurement file",
    );
    fails_with(
        &cta(&["calibrate", s(&csv), "--plot", s(&csv)]),
        "is not a plot or report cta wrote",
    );
    let truth = d.join("sweep.truth.json");
    fails_with(
        &cta(&["calibrate", s(&csv), "--out", s(&truth)]),
        "not an earlier `cta calibrate` calibration",
    );
    fails_with(
        &cta(&["calibrate", s(&csv), "--separations", "30"]),
        "at least 2 separations",
    );
    let one = d.join("one.csv");
    let o = cta(&["simulate", "--out", s(&one), "--separations", "10,20"]);
    assert!(o.status.success());
    fails_with(&cta(&["calibrate", s(&one)]), "give --noise");
    let o = cta(&["calibrate", s(&one), "--noise", "32.8"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `cta fit` names its spread by the weighting: with `none` a residual variance in counts^2
/// (what `chi2/dof` used to label), with `repeat` a true chi2/dof, warned about above
/// `cta calibrate`'s line as `cta calibrate` does; every estimate to the digits its 1-sigma
/// resolves, and no Rust names in the text.
#[test]
fn fit_names_its_spread_by_the_weighting() {
    let d = tmpdir("fit-spread");
    let sim = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut args = vec![
            "--separations",
            "20,25",
            // Many samples: weights from few are noisy, and their chi2/dof is biased high
            // by (n - 1)/(n - 3) (3 with 4 samples).
            "--samples",
            "40",
            "--noise",
            "32.8",
            "--seed",
            "3",
        ];
        args.extend_from_slice(extra);
        simulate(&out, &args);
        out
    };
    let far = sim("far.csv", &["--far-field"]);
    let text = |args: &[&str]| {
        let o = cta(args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    // Unweighted: a variance of about the noise squared, in counts^2, never called chi2/dof.
    let f = json(&cta(&["fit", s(&far), "--json"]));
    let v = f["residual_variance_counts2"].as_f64().unwrap();
    assert!((900.0..1300.0).contains(&v), "{f}");
    assert!(f["chi2_per_dof"].is_null(), "{f}");
    assert_eq!(
        f["chi2_dof"].as_f64(),
        Some(v),
        "the old field keeps its value"
    );
    let t = text(&["fit", s(&far)]);
    assert!(
        t.contains("unweighted") && t.contains("counts^2 per degree of freedom"),
        "{t}"
    );
    assert!(!t.contains("chi2"), "{t}");
    // Each estimate to the 2nd significant digit of its sigma, in words not Rust names.
    let line = t
        .lines()
        .find(|l| l.trim_start().starts_with("H ="))
        .unwrap();
    let (h, sh) = cta_lab::analyze::digits::pm_parts(
        f["params"]["H"].as_f64().unwrap(),
        f["sigma"]["H"].as_f64().unwrap(),
    );
    assert!(
        line.contains(&format!("{h} ± {sh} ")) && line.contains("counts"),
        "{line}"
    );
    for leak in [
        "None",
        "Repeat",
        "SmallStep",
        "SmallCostChange",
        "ZeroCost",
        "NoFurtherDecrease",
        "SmallPredictedDecrease",
    ] {
        assert!(!t.contains(leak), "{leak} in {t}");
    }
    assert!(t.contains("iterations (converged: "), "{t}");
    // Repeat weights on far-field data: chi2/dof near 1, no warning.
    let f = json(&cta(&["fit", s(&far), "--weights", "repeat", "--json"]));
    let c = f["chi2_per_dof"].as_f64().unwrap();
    assert!((0.8..1.2).contains(&c), "{f}");
    assert!(f["residual_variance_counts2"].is_null(), "{f}");
    let t = text(&["fit", s(&far), "--weights", "repeat"]);
    assert!(t.contains(&format!("chi2/dof {c:.3}")), "{t}");
    assert!(!t.contains("warning"), "{t}");
    // Near-field data the pinhole model cannot follow: above the line, the 1-sigma are too
    // small, said in the text and the JSON.
    let near = sim("near.csv", &[]);
    let f = json(&cta(&["fit", s(&near), "--weights", "repeat", "--json"]));
    let c = f["chi2_per_dof"].as_f64().unwrap();
    assert!(c > cta_lab::data::weights::CHI2_WARN, "{f}");
    let w = f["warnings"].to_string();
    assert!(
        w.contains(&format!("chi2/dof {c:.2}"))
            && w.contains("biases the parameters by an amount they do not bound")
            && w.contains("near.csv"),
        "{w}"
    );
    let t = text(&["fit", s(&near), "--weights", "repeat"]);
    assert!(t.contains("warning: chi2/dof"), "{t}");
}

/// With 2 samples per point, each point's own variance is too rough to weight by (two equal
/// integer samples give 0): `--weights repeat` refuses below 6 samples and names `pooled`,
/// which weights by the noise pooled per separation and lands on the truth (the reviewer's
/// file: repeat gave d1 = 0.4284 +/- 0.0020 for 0.6 at chi2/dof 88, with no warning).
#[test]
fn fit_with_few_samples_refuses_repeat_and_pools() {
    let d = tmpdir("fit-few");
    let two = d.join("w2-3.csv");
    common::simulate_at(&two, "25,30", "2", "3", &[]);
    fails_with(
        &cta(&["fit", s(&two), "--weights", "repeat"]),
        "needs repeated samples, at least 6 per point, and this point has 2",
    );
    fails_with(
        &cta(&["fit", s(&two), "--weights", "repeat"]),
        "--weights pooled",
    );
    let f = json(&cta(&["fit", s(&two), "--weights", "pooled", "--json"]));
    assert_eq!(f["weights"], "pooled", "{f}");
    let c = f["chi2_per_dof"].as_f64().unwrap();
    let e = f["chi2_expected"].as_f64().unwrap();
    assert!((0.8..1.2).contains(&c) && (1.0..1.05).contains(&e), "{f}");
    for (n, truth) in [("d1", 0.6), ("d2", 0.1), ("p2", 0.002)] {
        let (v, sd) = (
            f["params"][n].as_f64().unwrap(),
            f["sigma"][n].as_f64().unwrap(),
        );
        assert!(
            (v - truth).abs() < 3.0 * sd,
            "{n} = {v} +/- {sd}, truth {truth}"
        );
    }
    assert_eq!(f["warnings"], serde_json::json!([]), "{f}");

    // From 6 samples `repeat` is taken, and its 1-sigma (the sandwich) say it is the less
    // precise weighting, as it is: each point's own variance is a rough weight. Its former
    // (J'WJ)^-1 took those variances for the truth and claimed more than `pooled` (5-7x too
    // small over 20 far-field seeds with 4 samples).
    let six = d.join("w6.csv");
    common::simulate_at(&six, "20,25", "6", "1", &["--far-field"]);
    let r = json(&cta(&["fit", s(&six), "--weights", "repeat", "--json"]));
    let p = json(&cta(&["fit", s(&six), "--weights", "pooled", "--json"]));
    for n in ["d1", "d2", "d3", "p1", "p2", "p3", "H"] {
        let (sr, sp) = (
            r["sigma"][n].as_f64().unwrap(),
            p["sigma"][n].as_f64().unwrap(),
        );
        assert!(sr > sp, "{n}: repeat {sr} against pooled {sp}");
    }
}

/// `cta calibrate`'s pinhole stage weights its point means by the noise pooled per
/// separation (as the near-field stage and CALIBRATE.md say), not by each point's own few
/// samples: with 2 samples per point its H agrees with `cta fit --weights pooled` on the same
/// separations, and the text gives the stage's chi2/dof (before: H = 18715 +/- 20 against
/// the fit's 19060 +/- 110, at a pinhole chi2/dof of 31 nobody saw).
#[test]
fn calibrate_pinhole_stage_pools_the_noise() {
    let d = tmpdir("cal-two");
    let csv = d.join("c2s.csv");
    common::simulate_at(&csv, "2..30", "2", "3", &[]);
    let r = json(&cta(&["calibrate", s(&csv), "--json"]));
    let h = r["pinhole_h"].as_f64().unwrap();
    let c = r["pinhole_chi2_dof"].as_f64().unwrap();
    assert!((0.8..1.2).contains(&c), "pinhole chi2/dof {c}");
    let f = json(&cta(&[
        "fit",
        s(&csv),
        "--separations",
        "25,30",
        "--weights",
        "pooled",
        "--json",
    ]));
    let (hf, sf) = (
        f["params"]["H"].as_f64().unwrap(),
        f["sigma"]["H"].as_f64().unwrap(),
    );
    assert!(
        (h - hf).abs() < 0.1 * sf,
        "calibrate H {h}, fit {hf} +/- {sf}"
    );
    assert!(
        (r["file"]["fitted"]["sigma"]["H"].as_f64().unwrap() / sf - 1.0).abs() < 0.01,
        "{r}"
    );
    // The unweighted fit of the reports agrees to its 1-sigma.
    let f = json(&cta(&["fit", s(&csv), "--separations", "25,30", "--json"]));
    let (hn, sn) = (
        f["params"]["H"].as_f64().unwrap(),
        f["sigma"]["H"].as_f64().unwrap(),
    );
    assert!(
        (h - hn).abs() < sn,
        "calibrate H {h}, unweighted fit {hn} +/- {sn}"
    );
    let o = cta(&["calibrate", s(&csv)]);
    let text = String::from_utf8_lossy(&o.stdout);
    let line = text
        .lines()
        .find(|l| l.contains("pinhole (eq 65) at 25, 30 in"))
        .unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains(&format!("(chi2/dof {c:.2})")), "{line}");
}

/// One policy for every output file: missing folders are created, so a computed result is
/// never lost to one; a write that still fails says `cannot write PATH: reason` after the
/// report, and that the result was not saved.
#[test]
fn outputs_create_missing_folders() {
    let d = tmpdir("folders");
    let sim = d.join("new1/sub/sim.csv");
    let o = cta(&[
        "simulate",
        "--out",
        s(&sim),
        "--separations",
        "10,20,25,30",
        "--samples",
        "3",
        "--noise",
        "32.8",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(sim.exists() && d.join("new1/sub/sim.truth.json").exists());
    let fit = d.join("new2/fit.json");
    let o = cta(&["fit", s(&sim), "--separations", "25,30", "--save", s(&fit)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("H ="));
    assert!(cta_lab::fit::FitReport::load(&fit).is_ok());
    let cal = d.join("new3/cal.json");
    let svg = d.join("new4/cal.svg");
    let o = cta(&["calibrate", s(&sim), "--out", s(&cal), "--plot", s(&svg)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(cal.exists() && std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    for (cmd, svg) in [
        (vec!["evaluate", s(&fit), s(&sim)], d.join("new5/a/f57.svg")),
        (vec!["nearfield"], d.join("new6/nf.svg")),
        (vec!["uncertainty"], d.join("new7/u.svg")),
    ] {
        let mut args = cmd.clone();
        args.extend(["--plot", s(&svg)]);
        let o = cta(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(svg.exists(), "{cmd:?}");
    }
    assert!(!d.join("new2/fit.json.partial").exists() && !d.join("new6/nf.svg.partial").exists());

    // A folder that cannot be made (a file is in the way): the report, then the error.
    let blocker = d.join("blocker");
    std::fs::write(&blocker, "not a folder").unwrap();
    let bad = blocker.join("fit.json");
    let o = cta(&["fit", s(&sim), "--separations", "25,30", "--save", s(&bad)]);
    fails_with(&o, &format!("cannot write {}: ", bad.display()));
    fails_with(&o, "the fit above was not saved");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("H =") && !out.contains("saved to"), "{out}");
    let bad = blocker.join("cal.svg");
    let o = cta(&["calibrate", s(&sim), "--plot", s(&bad)]);
    fails_with(&o, &format!("cannot write {}: ", bad.display()));
    fails_with(&o, "the plot was not written");
    assert!(String::from_utf8_lossy(&o.stdout).contains("near-field (eqs 60-63)"));
    // --out that cannot be written: the report, without "(not written: give --out)".
    let bad = blocker.join("cal.json");
    let o = cta(&["calibrate", s(&sim), "--out", s(&bad)]);
    fails_with(&o, "the calibration above was not saved");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("near-field (eqs 60-63)") && !out.contains("give --out"),
        "{out}"
    );
    let bad = blocker.join("sim.csv");
    fails_with(
        &cta(&["simulate", "--out", s(&bad), "--separations", "20"]),
        &format!("cannot write {}: ", bad.display()),
    );
    assert_eq!(std::fs::read_to_string(&blocker).unwrap(), "not a folder");
}

/// The face angles and the cell offset show only in how the outputs change close in: fitted
/// to far separations alone, the near-field calibration ends outside what the board takes (a
/// negative cell offset `s` here) or does not converge. Either way the error names the file,
/// the problem (where the separations start) and what to do: measure closer separations, or
/// include the closer ones the file has; nothing is written.
#[test]
fn calibrate_from_far_separations_only_says_to_measure_closer() {
    let d = tmpdir("far-only");
    let fails = |args: &[&str], needles: &[String]| {
        let o = cta(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !err.contains("panicked"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
        for n in needles {
            assert!(err.contains(n.as_str()), "stderr lacks `{n}`: {err}");
        }
        // No Rust debug output (the optimizer's state) in the message.
        assert!(!err.contains("VecStorage") && !err.contains(" { "), "{err}");
    };
    let noisy = |csv: &Path, seps: &str, seed: &str| {
        // 1 % of beta, 2 samples per point: noisy enough that the far data leave s free.
        let args = ["--separations", seps, "--noise", "300", "--samples", "2"];
        simulate(csv, &[&args[..], &["--seed", seed]].concat());
    };
    let cal = d.join("cal.json");
    // Only 25 and 30 in were measured.
    let far = d.join("far.csv");
    noisy(&far, "25,30", "2");
    fails(
        &["calibrate", s(&far), "--out", s(&cal)],
        &[
            format!(
                "cta: error: {}: the fitted calibration is outside what the board accepts: \
                 calibration out of range: near-field cell offset s (0 ..= 2 in) (fitted s = -",
                far.display()
            ),
            "The face angles and the cell offset show only close in, and these separations \
             start at 25 in: measure separations down to a few inches (a sweep of 2..30 in, as \
             host/plans/chvi.toml), and calibrate from that file"
                .into(),
        ],
    );
    assert!(!cal.exists());
    // Closer separations measured, but left out with --separations: the fit ends out of range
    // or does not converge, and the message says to include them.
    for (seed, problem) in [
        (
            "2",
            "the fitted calibration is outside what the board accepts: calibration out of \
             range: d (each component finite, within +/-12 in).",
        ),
        (
            "5",
            "near-field calibration fit failed: it did not converge in 100 iterations \
             (chi-square ",
        ),
    ] {
        let mix = d.join(format!("mix{seed}.csv"));
        noisy(&mix, "2,10,25,30", seed);
        fails(
            &[
                "calibrate",
                s(&mix),
                "--separations",
                "25,30",
                "--out",
                s(&cal),
            ],
            &[
                format!("cta: error: {}: {problem}", mix.display()),
                "these separations start at 25 in: the file also has closer ones, from 2 in: \
                 include them (leave out --separations, or e.g. --separations 2..30)"
                    .into(),
            ],
        );
        assert!(!cal.exists());
    }
}

/// On very noisy data the pinhole fit's eye point can land outside what the board takes
/// (d3 = -20 +/- 27 in here) while the near-field fit is fine: `cta calibrate` still writes
/// the calibration, without `pinhole`, and says so.
#[test]
fn calibrate_drops_an_out_of_range_pinhole_eye() {
    let d = tmpdir("noisy-eye");
    let csv = d.join("noisy.csv");
    common::simulate(&csv, &["--noise", "1800", "--samples", "2", "--seed", "1"]);
    let out = d.join("cal.json");
    let o = cta(&["calibrate", s(&csv), "--out", s(&out)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        text.contains("the pinhole fit's eye point is outside what the board takes"),
        "{text}"
    );
    let cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(cal["pinhole"].is_null(), "{cal}");
}

/// Close in, reports at the 16-bit rail are counted (Figure 57 counts every report), and
/// `cta evaluate` says how many.
#[test]
fn evaluate_counts_reports_at_the_rail() {
    let d = tmpdir("eval-rail");
    let csv = d.join("sim.csv");
    let fit = d.join("fit.json");
    common::simulate(&csv, &["--separations", "2,25,30"]);
    let o = cta(&["fit", s(&csv), "--separations", "25,30", "--save", s(&fit)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = cta(&["evaluate", s(&fit), s(&csv)]);
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("reports with an output at the 16-bit rail") && out.contains("of 100 at 2 in"),
        "{out}"
    );
    let e = json(&cta(&["evaluate", s(&fit), s(&csv), "--json"]));
    let at2 = e["at_rail"][0].as_u64().unwrap();
    assert!(at2 > 0 && at2 < 100, "{e}");
    assert_eq!(e["at_rail"][2], 0);
    assert_eq!(e["rail_left_out"], false);

    // --without-rail leaves them out of the statistics, and says so.
    let o = cta(&["evaluate", s(&fit), s(&csv), "--without-rail"]);
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("are left out (--without-rail")
            && out.contains(&format!("{at2} of 100 at 2 in")),
        "{out}"
    );
    let w = json(&cta(&[
        "evaluate",
        s(&fit),
        s(&csv),
        "--json",
        "--without-rail",
    ]));
    assert_eq!(w["rail_left_out"], true);
    assert_eq!(w["at_rail"], e["at_rail"]);
    assert_eq!(w["reports"][0].as_u64().unwrap(), 100 - at2, "{w}");
    assert_eq!(w["reports"][2], e["reports"][2]);
    // The clipped reports' errors were part of the 2 in statistics, not of 30 in's.
    assert_ne!(w["angle_std_deg"][0], e["angle_std_deg"][0]);
    assert_eq!(w["angle_std_deg"][2], e["angle_std_deg"][2]);
}

/// `cta evaluate CAL.json DATA.csv`: Figure 57 of a sensor calibration, its near-field model
/// and its pinhole model on the same reports, against the truth sidecar; the near-field model
/// is the better close in, as the calibration is meant to be.
#[test]
fn evaluate_takes_a_sensor_calibration() {
    let d = tmpdir("evalcal");
    let csv = d.join("sim.csv");
    let cal = d.join("cal.json");
    let plot = d.join("fig57.svg");
    common::simulate_at(&csv, "3,10,20,30", "2", "4", &[]);
    let o = cta(&["calibrate", s(&csv), "--out", s(&cal)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = json(&cta(&[
        "evaluate",
        s(&cal),
        s(&csv),
        "--json",
        "--plot",
        s(&plot),
    ]));
    let evs = v["models"].as_array().expect("one evaluation a model");
    assert_eq!(evs.len(), 2, "{v}");
    assert_eq!(evs[0]["model"], "near-field (eqs 60-63)");
    assert_eq!(evs[1]["model"], "pinhole (eq 65)");
    assert_eq!(evs[0]["reference"], "truth");
    let at3 = |e: &serde_json::Value| e["angle_mean_deg"][0].as_f64().unwrap();
    assert!(at3(&evs[0]) * 5.0 < at3(&evs[1]), "{v}");
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("near-field (eqs 60-63)") && svg.contains("pinhole (eq 65)"));
}

/// Outputs say where they came from: the saved fit, `--json`, the calibration file and the
/// analysis report carry the tool with its commit, the date, the command line and the input
/// file's SHA-256, read back here against the file's own hash.
#[test]
fn outputs_carry_their_provenance() {
    use sha2::{Digest, Sha256};
    let d = tmpdir("prov");
    let csv = d.join("sim.csv");
    common::simulate_at(&csv, "10,20,25,30", "2", "3", &[]);
    let want: String = Sha256::digest(std::fs::read(&csv).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let check = |p: &serde_json::Value, what: &str| {
        assert!(
            p["software"].as_str().unwrap().starts_with("cta "),
            "{what}: {p}"
        );
        assert!(
            p["date_utc"].as_str().unwrap().ends_with('Z'),
            "{what}: {p}"
        );
        assert!(p["command"].as_array().unwrap().len() > 2, "{what}: {p}");
        let hashes: Vec<&str> = p["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|f| f["sha256"].as_str())
            .collect();
        assert!(hashes.contains(&want.as_str()), "{what}: {p}");
    };
    let fit = d.join("fit.json");
    let v = json(&cta(&[
        "fit",
        s(&csv),
        "--separations",
        "25,30",
        "--save",
        s(&fit),
        "--json",
    ]));
    check(&v["provenance"], "fit --json");
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&fit).unwrap()).unwrap();
    check(&saved["provenance"], "fit.json");
    // The saved fit still loads.
    let o = cta(&["evaluate", s(&fit), s(&csv), "--json"]);
    check(&json(&o)["provenance"], "evaluate --json");
    let cal = d.join("cal.json");
    let o = cta(&["calibrate", s(&csv), "--out", s(&cal)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    check(&c["fitted"]["run"], "cal.json");
    let report = d.join("report");
    let o = cta(&["analyze", s(&csv), "--report", s(&report), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(
        html.contains("<h2>Provenance</h2>") && html.contains(&want),
        "no provenance"
    );
    assert!(html.contains("name=viewport") && !html.contains("host/ANALYZE.md"));
}

/// `--quiet`, before or after the command: no warning, note or "plot:" line on stderr; the
/// result on stdout is the same. Errors are still said.
#[test]
fn quiet_silences_warnings_not_errors() {
    let d = tmpdir("quiet");
    let csv = d.join("sim.csv");
    let bare = d.join("bare.csv");
    let fit = d.join("fit.json");
    let plot = d.join("fig.svg");
    common::simulate_at(&csv, "25,30", "2", "3", &[]);
    // Without its truth sidecar, the evaluation warns that it measures from the fit's eye.
    std::fs::copy(&csv, &bare).unwrap();
    let o = cta(&["fit", s(&csv), "--save", s(&fit)]);
    assert!(o.status.success());
    let eval = |extra: &[&str]| {
        let mut args = vec!["evaluate", s(&fit), s(&bare)];
        args.extend_from_slice(extra);
        cta(&args)
    };
    let loud = eval(&[]);
    let said = String::from_utf8_lossy(&loud.stderr);
    assert!(
        said.contains("warning:") && said.contains("no truth sidecar"),
        "{said}"
    );
    for quiet in [eval(&["--quiet"]), eval(&["-q"])] {
        assert!(quiet.status.success());
        assert_eq!(String::from_utf8_lossy(&quiet.stderr), "");
        assert_eq!(quiet.stdout, loud.stdout);
    }
    let o = cta(&["--quiet", "nearfield", "--plot", s(&plot)]);
    assert!(
        o.status.success() && o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(plot.exists());
    let o = cta(&["--quiet", "fit", s(&d.join("missing.csv"))]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cta: error:"));
}
