//! Tests of the measurement file: reading, refusals, separations, glitches, output files.

use super::*;
use std::path::Path;

#[test]
fn the_rail_rule() {
    let at = |x: f64, y: f64| Sample {
        x,
        y,
        ..Default::default()
    };
    assert!(any_sample_pinned(&[at(0.0, 0.0), at(10.0, -32767.0)]));
    assert!(!any_sample_pinned(&[at(0.0, 0.0), at(32766.0, -32766.0)]));
    // 3 sigma of a mean of 9 samples of noise 30 is 30 counts.
    assert!(mean_near_rail([32740.0, 0.0], 30.0, 9));
    assert!(mean_near_rail([0.0, -32740.0], 30.0, 9));
    assert!(!mean_near_rail([32730.0, 0.0], 30.0, 9));
}

/// Missing folders are made, an earlier file is replaced whole, nothing partial is left,
/// and a folder that cannot be made is named in `cannot write PATH: ...`.
#[test]
fn write_output_makes_folders_and_names_the_file() {
    let d = std::env::temp_dir().join(format!("cta-write-output-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    let f = d.join("a/b/out.json");
    write_output(&f, b"one").unwrap();
    write_output(&f, b"two").unwrap();
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "two");
    assert!(!d.join("a/b/out.json.partial").exists());
    let bad = f.join("x.json");
    let e = write_output(&bad, b"three").unwrap_err().to_string();
    assert!(
        e.starts_with(&format!(
            "cannot write {}: cannot create the folder",
            bad.display()
        )),
        "{e}"
    );
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "two");
    let e = write_output(&d.join("a"), b"x").unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("cannot write {}: ", d.join("a").display())),
        "{e}"
    );
    assert!(!d.join("a.partial").exists());
    std::fs::remove_dir_all(&d).unwrap();
}

fn read(s: &str) -> Result<Dataset, ReadError> {
    Dataset::from_reader(Path::new("m.csv"), s.as_bytes())
}

/// A file cut inside its last value (`-1234` to `-12`) still reads, so a last row with no
/// line break after it is warned about, naming its line and value and what to do; a file
/// ending with a line break (`\n`, `\r\n`, or a lone `\r`), or with a comment after its
/// last row, is not.
#[test]
fn a_last_value_without_a_line_break_may_be_cut_short() {
    let warned = |text: &str| {
        let (ds, w) = Dataset::from_reader_warned(Path::new("m.csv"), text.as_bytes())
            .unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_eq!(ds.samples.len(), 2, "{text:?}");
        (ds, w)
    };
    let head = "# title\nseparation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y\n\
                20,0,0,20,10,-1234\n";
    let (ds, w) = warned(&format!("{head}20,1,0,20,11,-12"));
    assert_eq!(ds.samples[1].y, -12.0);
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with(
            "m.csv:4: the file's last line has no end of line: its last value, `-12` \
             (column `y`), may be cut short"
        ) && w[0].contains("delete that line, or copy or export the file again"),
        "{w:?}"
    );
    // The plain reader reads the same rows.
    let plain = Dataset::from_reader(
        Path::new("m.csv"),
        format!("{head}20,1,0,20,11,-12").as_bytes(),
    );
    assert_eq!(plain.unwrap().samples, ds.samples);
    for ending in ["\n", "\r\n", "\r", "\n# the end", "\n\n"] {
        let (_, w) = warned(&format!("{head}20,1,0,20,11,-12{ending}"));
        assert!(w.is_empty(), "{ending:?}: {w:?}");
    }
    // An optional last column left empty by the cut, and a long value shown by its end.
    let (_, w) = warned(
        "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y,magnitude\n\
         20,0,0,20,10,-1234,0.5\n20,1,0,20,11,-1234,",
    );
    assert!(
        w[0].starts_with(
            "m.csv:3: the file's last line has no end of line: its last field (column \
             `magnitude`) is empty, and may be cut short"
        ),
        "{w:?}"
    );
    let note = format!("{}cut here", "x".repeat(100));
    let (_, w) = warned(&format!(
        "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y,note\n\
         20,0,0,20,10,-1234,a\n20,1,0,20,11,-1234,{note}"
    ));
    assert!(
        w[0].contains(&format!(
            "its last value, `...{}` (column `note`)",
            &note[68..]
        )),
        "{w:?}"
    );
}

#[test]
fn reads_with_comments_unknown_and_optional_columns() {
    let d = read("# a comment\nx,y,extra,separation_in,beacon_x_in,beacon_y_in,beacon_z_in,beacon\n1.5,-2,foo,20,0.5,-0.5,20,7\n# mid\n3,4,bar,20,1.5,-0.5,20,\n").unwrap();
    assert_eq!(d.samples.len(), 2);
    assert_eq!(d.samples[0].beacon, Some(7));
    assert_eq!(d.samples[1].beacon, None);
    assert_eq!(d.samples[1].line, 5);
    assert_eq!(d.samples[0].r, [0.5, -0.5, 20.0]);
}

#[test]
fn errors_name_column_and_line() {
    let e = read("x,y,separation_in,beacon_x_in,beacon_y_in\n1,2,3,4,5\n").unwrap_err();
    assert!(
        e.to_string()
            .contains("missing required column `beacon_z_in`"),
        "{e}"
    );
    let e =
        read("x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,2,3,4,5,6\n1,NaN,3,4,5,6\n")
            .unwrap_err();
    assert_eq!(
        e.to_string(),
        "m.csv:3: column `y`: `NaN` is not a finite number"
    );
    let e =
        read("x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,inf,3,4,5,6\n").unwrap_err();
    assert!(e.to_string().contains(":2: column `y`"));
    let e =
        read("x,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n1,abc,3,4,5,6\n").unwrap_err();
    assert!(e.to_string().contains("`abc`"));
    assert!(matches!(read(""), Err(ReadError::Empty(_))));
    assert!(matches!(
        read("# only\nx,y,separation_in,beacon_x_in,beacon_y_in,beacon_z_in\n"),
        Err(ReadError::Empty(_))
    ));
}

const H: &str = "separation_in,beacon_x_in,beacon_y_in,beacon_z_in,x,y";

#[test]
fn line_numbers_count_comments_blanks_and_indented_comments() {
    let d = read(&format!(
        "# c\n\n{H}\n   \n  # indented, with, commas\n20,0,0,20,1,2\n"
    ))
    .unwrap();
    assert_eq!(d.samples.len(), 1);
    assert_eq!(d.samples[0].line, 6);
    let e = read(&format!("# c\n\n{H}\n# x\n\n20,0,0,20,1,NaN\n")).unwrap_err();
    assert!(e.to_string().starts_with("m.csv:6: column `y`"), "{e}");
    // Two files joined: the second header is named as one.
    let e = read(&format!("{H}\n20,0,0,20,1,2\n{H}\n20,0,0,20,1,3\n")).unwrap_err();
    assert!(
        e.to_string()
            .contains("m.csv:3: column `separation_in`: `separation_in` is the column's name: a second header line"),
        "{e}"
    );
}

#[test]
fn bom_and_quoted_header_names_are_accepted() {
    let d = read(&format!("\u{feff}{H}\n20,0,0,20,1,2\n")).unwrap();
    assert_eq!(d.samples[0].x, 1.0);
    let d = read("\u{feff}\"separation_in\",\"beacon_x_in\", \"beacon_y_in\",beacon_z_in,\"x\",y\n20,0,0,20,\"1\",2\n").unwrap();
    assert_eq!(d.samples[0].separation_in, 20.0);
    assert_eq!(d.samples[0].x, 1.0);
    // A quoted note with a comma in an unknown column is one field.
    let d = read(&format!("{H},note\n20,0,0,20,1,2,\"a, b\"\n")).unwrap();
    assert_eq!(d.samples.len(), 1);
    let d = read(&format!("{H},note\n20,0,0,20,1,2,\"say \"\"hi\"\"\"\n")).unwrap();
    assert_eq!(d.samples.len(), 1);
    let e = read(&format!("{H},note\n20,0,0,20,1,2,\"open\n")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "m.csv:2: a quoted field is not closed on its line"
    );
}

#[test]
fn header_problems_show_the_header_and_the_likely_cause() {
    let e = read("separation_in;beacon_x_in;beacon_y_in;beacon_z_in;x;y\n20;0;0;20;1;2\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.csv:1: missing required column `separation_in`"),
        "{e}"
    );
    assert!(
        e.contains("`separation_in;beacon_x_in;beacon_y_in;beacon_z_in;x;y`"),
        "{e}"
    );
    assert!(e.contains("semicolons"), "{e}");
    let e = read(&H.replace(',', "\t")).unwrap_err().to_string();
    assert!(e.contains("tabs"), "{e}");
    let e = read(&format!("{}\n20,0,0,20,1,2\n", H.to_uppercase()))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("`SEPARATION_IN` should be `separation_in`"),
        "{e}"
    );
    let e = read(&format!("My CTA run, 2024\n{H}\n20,0,0,20,1,2\n"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.csv:1:") && e.contains("`My CTA run,2024`"),
        "{e}"
    );
    assert!(e.contains("start a title or note line with `#`"), "{e}");
}

#[test]
fn duplicate_header_columns_and_long_rows_are_refused() {
    let e = read(&format!("# c\n{H},x\n20,0,0,20,1,2,3\n"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.csv:2: column `x` appears more than once in the header `separation_in,"),
        "{e}"
    );
    // Unknown columns may repeat (they are ignored).
    assert!(read(&format!("{H},note,note\n20,0,0,20,1,2,a,b\n")).is_ok());
    // A decimal comma in the magnitude: one field too many.
    let e = read(&format!(
        "{H},magnitude\n20,0,0,20,1,2,0.5\n20,0,0,20,1,2,0,0024\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("m.csv:3: 8 fields, the header (line 1) has 7"),
        "{e}"
    );
    assert!(e.contains("decimal comma"), "{e}");
}

#[test]
fn documented_ranges_are_checked() {
    let row = |extra_h: &str, extra: &str, sep: &str, x: &str| {
        read(&format!("{H}{extra_h}\n{sep},0,0,20,{x},2{extra}\n"))
    };
    let err = |r: Result<Dataset, ReadError>| r.unwrap_err().to_string();
    assert_eq!(
        err(row("", "", "20", "99999")),
        "m.csv:2: column `x`: `99999` is out of range (allowed: -32768..32767 counts (signed 16-bit))"
    );
    assert!(row("", "", "20", "-32768").is_ok());
    assert!(row("", "", "20", "32767.4").is_err());
    assert_eq!(
        err(row("", "", "20", " ")),
        "m.csv:2: column `x` is empty: it needs a value on every line"
    );
    for sep in ["0", "-2"] {
        assert!(
            err(row("", "", sep, "1")).contains("column `separation_in`"),
            "{sep}"
        );
    }
    for (col, v, why) in [
        ("sensitivity", "9", "is not an integer in 1..4"),
        ("sensitivity", "2.5", "is not an integer in 1..4"),
        (
            "power",
            "9",
            "is not an integer in 1..2 (1 = 1 kOhm, 2 = 360 Ohm)",
        ),
        (
            "power",
            "0",
            "is not an integer in 1..2 (1 = 1 kOhm, 2 = 360 Ohm)",
        ),
        (
            "frequency_hz",
            "-4050",
            "is out of range (allowed: > 0 Hz, at most 1e9 Hz)",
        ),
        (
            "beacon",
            "500",
            "is not an integer in 0..399 (100 x array + LED)",
        ),
        (
            "beacon",
            "-3",
            "is not an integer in 0..399 (100 x array + LED)",
        ),
        (
            "beacon",
            "7.5",
            "is not an integer in 0..399 (100 x array + LED)",
        ),
        (
            "beacon",
            "-32768",
            "is not an integer in 0..399 (100 x array + LED)",
        ),
        (
            "beacon",
            "abc",
            "is not an integer in 0..399 (100 x array + LED)",
        ),
        ("sample", "-1", "is not an integer in 0..4294967295"),
        ("magnitude", "-0.5", "is out of range (allowed: 0..1e9)"),
        // Finite but past any rig: sums of squares would overflow into inf and NaN.
        ("magnitude", "2e9", "is out of range (allowed: 0..1e9)"),
        ("magnitude", "NaN", "is not a finite number"),
    ] {
        let e = err(row(&format!(",{col}"), &format!(",{v}"), "20", "1"));
        assert_eq!(e, format!("m.csv:2: column `{col}`: `{v}` {why}"));
    }
    // The documented "not recorded": an empty optional field.
    let d = read(&format!("{H},beacon,frequency_hz,power,sensitivity,sample,magnitude\n20,0,0,20,1,2,,,,,,\n20,0,0,20,1,2,399,4050,2,4,7,0\n")).unwrap();
    assert_eq!(d.samples[0].magnitude, None);
    assert_eq!(d.samples[1].beacon, Some(399));
    assert_eq!(d.samples[1].magnitude, Some(0.0));
}

#[test]
fn latin1_bytes_name_the_line_and_column() {
    let mut f = format!("{H},note\n20,0,0,20,1,2,ok\n").into_bytes();
    f.extend_from_slice(b"20,0,0,20,1\xb5,2,ok\n");
    let e = Dataset::from_reader(Path::new("m.csv"), &f[..])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("m.csv:3: column `x`: `1\u{fffd}` is not UTF-8 text"),
        "{e}"
    );
    // In an ignored column it is ignored, like the column.
    let mut f = format!("{H},note\n").into_bytes();
    f.extend_from_slice(b"20,0,0,20,1,2,M\xfcller\n");
    assert!(Dataset::from_reader(Path::new("m.csv"), &f[..]).is_ok());
}

#[test]
fn repeated_reports_are_refused_with_both_lines() {
    let body = "20,0,0,20,1,2,3,0\n20,0,0,20,1,3,3,1\n";
    let e = read(&format!("{H},beacon,sample\n{body}# again\n{body}"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "m.csv:5: repeats the report of line 2 (same separation, beacon position, beacon, frequency, \
         power, sensitivity, group and sample index 0): is (part of) the file in twice?"
    );
    // The same beacon measured alone and in its group (two sweep points): two reports.
    let body = "20,0,0,20,1,2,3,0,7\n20,0,0,20,1,3,3,0,9\n";
    assert!(read(&format!("{H},beacon,sample,group\n{body}")).is_ok());
    // Another setting, another report; without sample indices rows are repeated samples.
    assert!(read(&format!(
        "{H},beacon,sample,power\n20,0,0,20,1,2,3,0,1\n20,0,0,20,1,2,3,0,2\n"
    ))
    .is_ok());
    assert!(read(&format!("{H}\n20,0,0,20,1,2\n20,0,0,20,1,2\n")).is_ok());
}

#[test]
fn round_trip_and_select() {
    let s = Sample {
        separation_in: 20.0,
        r: [0.5, 1.5, 20.0],
        x: 10.25,
        y: -3.0,
        beacon: Some(3),
        sample: Some(0),
        ..Default::default()
    };
    let d = Dataset {
        path: "t.csv".into(),
        samples: vec![
            s,
            Sample {
                separation_in: 25.0,
                ..s
            },
        ],
    };
    let mut buf = Vec::new();
    d.write(&mut buf, &["made by a test".into()]).unwrap();
    let back = Dataset::from_reader(Path::new("t.csv"), &buf[..]).unwrap();
    assert_eq!(back.samples[0].x, 10.25);
    assert_eq!(back.samples[0].beacon, Some(3));
    assert_eq!(back.separations(), vec![20.0, 25.0]);
    assert_eq!(back.select(&[25.0]).unwrap().samples.len(), 1);
    // A measured plate position (mean of four corners) is found from its nominal value.
    let mut m = back.clone();
    m.samples[1].separation_in = 25.0125;
    let got = m.select(&[25.0]).unwrap();
    assert_eq!(got.samples.len(), 1);
    assert_eq!(got.samples[0].separation_in, 25.0125);
    assert_eq!(m.nearest_separation(19.95), Some(20.0));
    assert_eq!(m.nearest_separation(24.8), None);
    assert!(back.warnings().is_empty(), "{:?}", back.warnings());
    // A file in millimetres, and beacon z given from the plate: read, but warned about,
    // naming the file and the first line.
    let mut mm = back.clone();
    for s in &mut mm.samples {
        s.separation_in *= 25.4;
        s.r = s.r.map(|v| v * 25.4);
    }
    let w = mm.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("t.csv:3: separation_in 508 in (the file's largest 635 in)"),
        "{w:?}"
    );
    assert!(w[0].contains("millimetres"), "{w:?}");
    let mut z0 = back.clone();
    z0.samples[1].r[2] = 0.0;
    let w = z0.warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("t.csv:4: beacon_z_in 0 in with separation_in 25 in (1 of 2 rows"),
        "{w:?}"
    );
    let e = back.select(&[30.0]).unwrap_err().to_string();
    assert!(
        e.contains("separation(s) 30 not in the file, nor any within 0.1 in (it has 20, 25)"),
        "{e}"
    );
}

/// The typo warning's row ratio at its boundary: 2 rows at 2.0001 in beside 8 at 2 in
/// (4 times theirs) are warned about, beside 7 (3.5 times) are not; whichever side of
/// the value the few rows lie.
#[test]
fn a_separation_typo_needs_four_times_the_rows_beside_it() {
    let file = |many: usize, odd: f64| {
        let mut samples = Vec::new();
        for (sep, n) in [(2.0, many), (odd, 2)] {
            for k in 0..n {
                samples.push(Sample {
                    separation_in: sep,
                    r: [k as f64 - 4.0, 0.5, sep],
                    x: 100.0 * k as f64,
                    y: -50.0,
                    line: samples.len() + 2,
                    ..Default::default()
                });
            }
        }
        Dataset {
            path: "t.csv".into(),
            samples,
        }
    };
    for odd in [2.0001, 1.9999] {
        let w = file(4 * 2, odd).warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with(&format!(
                "t.csv:10: separation_in {odd} on 2 rows (lines 10, 11) beside 2 on 8 rows: \
                 within 0.01 in of a separation with at least 4 times the rows"
            )),
            "{w:?}"
        );
        let w = file(4 * 2 - 1, odd).warnings();
        assert!(w.is_empty(), "{odd}: {w:?}");
    }
}

/// The robust sigma is the noise for any number of samples per point (odd and even: the
/// [`MAD_FACTOR`] table), and a glitch is named, counted and kept.
#[test]
fn glitch_check_scales_to_sigma_and_names_glitches() {
    for samples in [3, 4, 5, 10, 20, 70] {
        let ds = crate::sim::SimConfig {
            separations: vec![10.0, 20.0, 30.0],
            noise: 30.0,
            samples,
            seed: samples as u64,
            ..Default::default()
        }
        .run()
        .0;
        let g = ds.glitches();
        assert_eq!(g.samples, 0, "{samples}: {g:?}");
        for a in &g.axes {
            // 300 points: the MAD to ~3 % at 3 samples per point.
            assert!(
                (a.robust_sigma / 30.0 - 1.0).abs() < 0.1,
                "{samples}: {a:?}"
            );
            assert!(
                (a.std_with / a.robust_sigma - 1.0).abs() < 0.1,
                "{samples}: {a:?}"
            );
        }
        assert!(ds.warnings().is_empty(), "{:?}", ds.warnings());
        let mut bad = ds.clone();
        bad.path = "g.csv".into();
        for (k, s) in bad.samples.iter_mut().enumerate() {
            s.line = k + 2;
        }
        bad.samples[7].y += 3000.0;
        bad.samples[400].y -= 500.0;
        let g = bad.glitches();
        assert_eq!((g.samples, g.axes[0].samples), (2, 0), "{samples}: {g:?}");
        assert_eq!(g.axes[1].lines, vec![9, 402]);
        let y = &g.axes[1];
        assert!(
            y.inflation() > 1.1 && (y.std_without / 30.0 - 1.0).abs() < 0.1,
            "{y:?}"
        );
        assert_eq!(bad.samples.len(), ds.samples.len());
        let w = bad.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        // 2 of 900-21,000 rows; from 20 samples per point (0.033 %, 0.0095 %), `{:.1}`
        // would print 0.0 %: under 0.1 % instead.
        let share = match samples {
            20 | 70 => "under 0.1 %".to_string(),
            _ => format!("{:.1} %", 200.0 / ds.samples.len() as f64),
        };
        assert!(
            w[0].starts_with(&format!(
                "g.csv: 2 samples ({share} of the rows) lie more than 8 robust sigma from \
                 their point's median (Y at lines 9, 402): glitches"
            )),
            "{w:?}"
        );
    }
    // A noise below the count resolution: the floor, not a robust sigma of 0, sets the
    // threshold (8 counts), so a 1-count step is no glitch and a 9-count one is.
    let mut ds = crate::sim::SimConfig {
        separations: vec![20.0],
        noise: 0.2,
        samples: 5,
        ..Default::default()
    }
    .run()
    .0;
    assert_eq!(ds.glitches().samples, 0);
    ds.samples[0].x += 1.0;
    assert_eq!(ds.glitches().samples, 0);
    ds.samples[0].x += 8.0;
    assert_eq!(ds.glitches().axes[0].samples, 1);
}

#[test]
fn separation_lists() {
    assert_eq!(parse_separations("20,25").unwrap(), vec![20.0, 25.0]);
    assert_eq!(parse_separations("2..5").unwrap(), vec![2.0, 3.0, 4.0, 5.0]);
    assert_eq!(
        parse_separations("2..30:14").unwrap(),
        vec![2.0, 16.0, 30.0]
    );
    assert!(parse_separations("a").is_err());
    assert!(parse_separations("-1").is_err());
    assert!(parse_separations("5..2").is_err());
    assert_eq!(
        parse_new_separations("25,25").unwrap_err().to_string(),
        "25 in is listed twice in `25,25`"
    );
    assert!(parse_new_separations("2..30:2,10").is_err());
    assert!(parse_new_separations("2..30:2,25").is_ok());
    assert!(parse_separations("2..10,10..30:5").is_ok());
}

#[test]
fn huge_or_unbounded_separation_ranges_are_refused_before_expanding() {
    // These used to expand in full (7.6 GB for `1..1e12`) or loop forever.
    for s in [
        "1..1e12",
        "2..30:0.0000001",
        "2..inf",
        "2..30:inf",
        "nan..3",
        "2..NaN",
    ] {
        let e = parse_separations(s).unwrap_err().to_string();
        assert!(e.contains(s), "{s}: {e}");
    }
    let e = parse_separations("1..1e12").unwrap_err().to_string();
    assert!(e.contains("more than the 10000 allowed"), "{e}");
    let e = parse_separations("2..inf").unwrap_err().to_string();
    assert!(e.contains("finite"), "{e}");
    assert!(parse_separations("inf").is_err());
    // The cap counts the whole list.
    assert_eq!(
        parse_separations("1..10000").unwrap().len(),
        MAX_SEPARATIONS
    );
    assert!(parse_separations("1..10000,20000").is_err());
    assert!(parse_separations("0.5,1..10000").is_err());
}
