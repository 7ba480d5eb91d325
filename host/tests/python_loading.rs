//! The Python of host/MEASUREMENTS.md ("In Python and MATLAB") on files `cta` wrote: a
//! measurement file with comment lines, a saved fit and a calibration. With pandas and numpy
//! when they are installed, with the standard library's `csv` and `json` otherwise; skipped,
//! saying so, without `python3`.

use std::process::Command;

mod common;
use common::{cta, s};

/// The documented pandas and numpy lines, and the standard-library equivalent, printing
/// what they read: rows, the header, d1 and its 1-sigma, the head's H.
const SCRIPT: &str = r##"
import json, sys
csv_path, fit_path, cal_path = sys.argv[1:4]
fit = json.load(open(fit_path))
cal = json.load(open(cal_path))
try:
    import pandas as pd
    import numpy as np
    data = pd.read_csv(csv_path, comment="#")
    means = data.groupby(["separation_in", "beacon"])[["x", "y"]].mean()
    with open(csv_path) as f:
        arr = np.genfromtxt((l for l in f if not l.startswith("#")), delimiter=",", names=True)
    assert len(arr) == len(data) and list(arr.dtype.names) == list(data.columns)
    rows, columns, points, how = len(data), list(data.columns), len(means), "pandas"
except ImportError:
    import csv
    with open(csv_path) as f:
        r = list(csv.reader(l for l in f if not l.startswith("#")))
    columns, rows = r[0], len(r) - 1
    sep, beacon = columns.index("separation_in"), columns.index("beacon")
    points = len({(row[sep], row[beacon]) for row in r[1:]})
    how = "csv"
print(how, rows, points, ",".join(columns))
print(fit["params"]["d1"], fit["sigma"]["d1"], cal["h"], len(cal["d"]), len(cal["p"]))
"##;

#[test]
fn the_documented_python_reads_ctas_files() {
    let Ok(probe) = Command::new("python3").arg("--version").output() else {
        eprintln!("skipped: no python3 on this machine");
        return;
    };
    assert!(probe.status.success());
    let d = common::tmpdir_of("python", "load");
    let csv = d.join("data.csv");
    let fit = d.join("fit.json");
    let cal = d.join("cal.json");
    let run = |args: &[&str]| {
        let o = cta(args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&[
        "simulate",
        "--out",
        s(&csv),
        "--separations",
        "20,25,30",
        "--samples",
        "2",
        "--noise",
        "32.8",
    ]);
    run(&["fit", s(&csv), "--separations", "25,30", "--save", s(&fit)]);
    run(&["calibrate", s(&csv), "--out", s(&cal)]);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with('#'), "the file starts with a comment line");
    let header = text.lines().find(|l| !l.starts_with('#')).unwrap();
    let rows = text.lines().filter(|l| !l.starts_with('#')).count() - 1;
    let o = Command::new("python3")
        .args(["-c", SCRIPT, s(&csv), s(&fit), s(&cal)])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{}{}",
        out,
        String::from_utf8_lossy(&o.stderr)
    );
    let mut lines = out.lines();
    let first: Vec<&str> = lines.next().unwrap().split(' ').collect();
    eprintln!("read with {}", first[0]);
    // Every sample row, 3 separations x 100 beacons as points, the header as written.
    assert_eq!(first[1].parse::<usize>().unwrap(), rows);
    assert_eq!(first[2], "300");
    assert_eq!(first[3], header);
    let fitted: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&fit).unwrap()).unwrap();
    let second: Vec<f64> = lines
        .next()
        .unwrap()
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(second[0], fitted["params"]["d1"].as_f64().unwrap());
    assert_eq!(second[1], fitted["sigma"]["d1"].as_f64().unwrap());
    assert!(
        second[2] > 10_000.0 && second[3] == 3.0 && second[4] == 3.0,
        "{second:?}"
    );
}
