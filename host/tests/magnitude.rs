//! `cta calibrate`'s spot magnitude law end to end: from `cta simulate` magnitudes (the
//! NorthStar's magnitude law, counts: the summed cell signal times each LED's brightness, with
//! noise) to the calibration file the board
//! loads, `--no-magnitude`, and a file without magnitudes.

use std::process::Output;

mod common;
use common::{cta, json, s, simulate, stderr};

fn tmpdir(name: &str) -> common::TmpDir {
    common::tmpdir_of("magnitude", name)
}

/// `o` succeeded; its stdout.
fn ok(o: &Output) -> String {
    assert!(o.status.success(), "failed: {}", stderr(o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The brief's check on `cta simulate --magnitude-noise 0.2 --led-brightness 10` (a linear
/// law, offset 0): the exponent is 1 within its 1-sigma (a few of them), the offset near 0,
/// the noise 0.2 % within 15 %, and every LED's brightness the truth file's (normalised to a
/// geometric mean of 1) within a few of its own 1-sigma; the calibration file holds the law,
/// its 1-sigma and the brightness, and the board takes it (`load-calibration` on a pty board,
/// whose stored calibration then holds the law).
#[test]
fn calibrate_measures_a_simulated_law_and_the_leds_brightness() {
    let d = tmpdir("sim");
    let csv = d.join("sim.csv");
    simulate(
        &csv,
        &[
            "--separations",
            "2..30",
            "--noise",
            "32.8",
            "--samples",
            "4",
            "--seed",
            "5",
            "--magnitude-noise",
            "0.2",
            "--led-brightness",
            "10",
        ],
    );
    let cal = d.join("cal.json");
    let r = json(&cta(&["calibrate", s(&csv), "--out", s(&cal), "--json"]));
    let m = &r["magnitude"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"));
    let law = &m["law"];
    let (g, gs) = (f(&law["exponent"]), f(&m["exponent_sigma"]));
    // Fitted on 16-30 in: nearer, the law's readings saturate (power level 2, sensitivity 4).
    assert!(
        (g - 1.0).abs() < 4.0 * gs && gs < 5e-4,
        "exponent {g} +/- {gs}"
    );
    // The magnitudes are counts (about 20000 on the axis at 30 in): an offset of 60 counts
    // would be 0.3 % there.
    let (o, os) = (f(&law["offset"]), f(&m["offset_sigma"]));
    assert!(o.abs() < 4.0 * os && os < 60.0, "offset {o} +/- {os}: {m}");
    let noise = f(&law["noise_percent"]);
    assert!((noise / 0.2 - 1.0).abs() < 0.15, "noise {noise} %");
    assert_eq!(law["sensitivity"], 4);
    assert_eq!(law["max"], 65535.0);
    // Against the truth.
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("sim.truth.json")).unwrap()).unwrap();
    assert_eq!(truth["led_brightness_percent"], 10.0);
    let tb: Vec<f64> = truth["led_brightness"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let leds = m["led_brightness"].as_array().unwrap();
    assert_eq!(leds.len(), 100);
    let id = |l: &serde_json::Value| l["beacon"].as_u64().unwrap() as usize;
    let gm = (leds.iter().map(|l| tb[id(l)].ln()).sum::<f64>() / leds.len() as f64).exp();
    let z: Vec<f64> = leds
        .iter()
        .map(|l| (f(&l["brightness"]) - tb[id(l)] / gm) / f(&l["sigma"]))
        .collect();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
    assert!(
        z.iter().all(|z| z.abs() < 4.5) && (0.6..1.5).contains(&rms),
        "brightness z-scores: RMS {rms}: {z:?}"
    );

    // The file: the law, its 1-sigma, the brightness at the LEDs' plate positions.
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    assert_eq!(&file["magnitude"], law);
    for k in ["magnitude.exponent", "magnitude.offset"] {
        assert!(
            file["fitted"]["sigma"][k].is_number(),
            "{k}: {}",
            file["fitted"]
        );
    }
    let lb = file["led_brightness"].as_array().unwrap();
    assert_eq!(lb.len(), 100);
    // LED 0 is the grid's (-4.5, -4.5) corner.
    let first = lb.iter().find(|l| l["beacon"] == 0).unwrap();
    assert_eq!((f(&first["x_in"]), f(&first["y_in"])), (-4.5, -4.5));

    // The board takes the file (the host-side keys allowed) and stores the law.
    let sim = common::Sim::start(&["sensor", "sim"]);
    let out = ok(&cta(&[
        "sensor",
        "--port",
        &sim.path,
        "load-calibration",
        s(&cal),
    ]));
    assert!(out.contains("stored in flash"), "{out}");
    let config = ok(&cta(&["sensor", "--port", &sim.path, "config"]));
    let stored: serde_json::Value = serde_json::from_str(
        config
            .lines()
            .find_map(|l| l.strip_prefix("calibration: "))
            .unwrap_or_else(|| panic!("{config}")),
    )
    .unwrap();
    let close = |a: &serde_json::Value, b: &serde_json::Value| (f(a) - f(b)).abs() < 1e-6;
    for k in ["offset", "exponent", "noise_percent", "max"] {
        assert!(close(&stored["magnitude"][k], &law[k]), "{k}: {config}");
    }
    assert_eq!(stored["magnitude"]["sensitivity"], 4, "{config}");
}

/// `--no-magnitude` leaves the law out (and says so); a file without magnitudes gives no law
/// and no error, in one line of the report; the text report shows the law when there is one.
#[test]
fn no_magnitude_and_files_without_magnitudes_give_no_law() {
    let d = tmpdir("none");
    let csv = d.join("sim.csv");
    simulate(
        &csv,
        &[
            "--separations",
            "4..30:2",
            "--noise",
            "32.8",
            "--samples",
            "2",
            "--magnitude-noise",
            "0.5",
        ],
    );
    let text = ok(&cta(&["calibrate", s(&csv)]));
    assert!(
        text.contains("spot magnitudes (sensitivity 4)")
            && text.contains("M = offset + A (b S)^exponent"),
        "{text}"
    );
    let cal = d.join("cal.json");
    let text = ok(&cta(&[
        "calibrate",
        s(&csv),
        "--no-magnitude",
        "--out",
        s(&cal),
    ]));
    assert!(
        text.contains("spot magnitudes: no law (left out (--no-magnitude))"),
        "{text}"
    );
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    assert!(file["magnitude"].is_null(), "{file}");
    assert!(file.get("led_brightness").is_none(), "{file}");
    assert!(file["fitted"]["sigma"].get("magnitude.exponent").is_none());

    // The same file without its magnitude column (and the time after it).
    let plain = d.join("plain.csv");
    let stripped: String = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                l.to_string()
            } else {
                l.rsplitn(3, ',').nth(2).unwrap().to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert!(stripped.lines().nth(2).unwrap().ends_with(",sample"));
    std::fs::write(&plain, stripped + "\n").unwrap();
    let o = cta(&["calibrate", s(&plain), "--out", s(&cal)]);
    let text = ok(&o);
    let line: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("spot magnitudes"))
        .collect();
    assert_eq!(line.len(), 1, "{text}");
    assert!(
        line[0].contains("no law") && line[0].contains("records no spot magnitudes"),
        "{text}"
    );
    assert!(!stderr(&o).contains("magnitude"), "{}", stderr(&o));
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cal).unwrap()).unwrap();
    assert!(file["magnitude"].is_null(), "{file}");
    // --magnitude-sensitivity names a setting the file lacks: an error saying what it has.
    let o = cta(&["calibrate", s(&csv), "--magnitude-sensitivity", "2"]);
    common::fails_in_one_line(&o, &["no magnitudes at sensitivity 2", "4: "]);
}
