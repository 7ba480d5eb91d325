//! `cta calibrate --out` keeps the near-field fit's full covariance with its parameters' names
//! and units, consistent with the file's 1-sigma; `cta evaluate` reads it back (and refuses a
//! file whose covariance was edited out of shape).

mod common;
use common::{cta, json, s, simulate_at, stderr};

#[test]
fn the_calibrations_covariance_is_kept_and_read_back() {
    let d = common::tmpdir_of("covariance", "sim");
    let csv = d.join("sim.csv");
    // A head with cell gains: the extended fit (13 parameters).
    simulate_at(
        &csv,
        "3..30:3",
        "3",
        "11",
        &["--effect", "cell_gain=0.02,-0.01"],
    );
    let cal = d.join("cal.json");
    let o = cta(&["calibrate", s(&csv), "--out", s(&cal), "--no-magnitude"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    let c = &file["fitted"]["covariance"];
    let names: Vec<&str> = c["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["d1", "d2", "d3", "p1", "p2", "p3", "a", "s", "gx", "gy", "bx", "by", "ay"]
    );
    assert_eq!(c["units"][0], "in");
    assert_eq!(c["units"][10], "1/in^2");
    let m: Vec<Vec<f64>> = serde_json::from_value(c["matrix"].clone()).unwrap();
    assert_eq!(m.len(), 13);
    for (i, n) in names.iter().enumerate() {
        assert_eq!(m[i].len(), 13);
        // Each variance is the square of the file's 1-sigma (not twice it, not its root).
        let sigma = file["fitted"]["sigma"][*n].as_f64().unwrap();
        assert!(sigma > 0.0, "{n}");
        assert!(
            (m[i][i].sqrt() / sigma - 1.0).abs() < 1e-9,
            "{n}: {} vs {sigma}",
            m[i][i]
        );
        for j in 0..i {
            assert_eq!(m[i][j], m[j][i]);
        }
    }
    // The strong correlation the file names is the matrix's.
    let a_ay = m[6][12] / (m[6][6] * m[12][12]).sqrt();
    let named = file["fitted"]["correlations"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r[0] == "a" && r[1] == "ay")
        .map(|r| r[2].as_f64().unwrap());
    if let Some(r) = named {
        assert!((r - a_ay).abs() < 1e-9, "{r} vs {a_ay}");
    }

    // `cta evaluate` reads it back: the same matrix in its JSON, a line in its text.
    let v = json(&cta(&["evaluate", s(&cal), s(&csv), "--json"]));
    let back: Vec<Vec<f64>> =
        serde_json::from_value(v["calibration_covariance"]["matrix"].clone()).unwrap();
    // (Through JSON text twice: equal to the last bit or two.)
    for (r, b) in m.iter().zip(&back) {
        for (x, y) in r.iter().zip(b) {
            assert!((x - y).abs() <= 1e-14 * x.abs(), "{x} vs {y}");
        }
    }
    assert_eq!(back.len(), 13);
    let o = cta(&["evaluate", s(&cal), s(&csv)]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("the calibration's covariance (13 parameters: d1, d2, d3,"),
        "{text}"
    );

    // A covariance edited out of shape is refused, naming the file and the entry.
    let mut edited = file.clone();
    edited["fitted"]["covariance"]["matrix"][3][0] = serde_json::json!(1.0);
    let bad = d.join("bad.json");
    std::fs::write(&bad, serde_json::to_string(&edited).unwrap()).unwrap();
    let o = cta(&["evaluate", s(&bad), s(&csv)]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("bad.json: field `fitted.covariance`: not symmetric: (p1, d1)"),
        "{e}"
    );
}
