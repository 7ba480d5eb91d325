//! The analysis's unit tests (its text is the command line's: those tests are there).

use super::analysis::{data_notes, rivals};
use super::corners::place_by_corners;
use super::data::{Data, Weights};
use super::model::{Base, Cand, FitResult, Model};
use super::params::delta_method;
use super::{analyze, Options};
use crate::progress::Silent;
use crate::sim::effects::Effect;
use crate::sim::SimConfig;
use nalgebra::DMatrix;

/// The hidden-effect setup of tests/tests/hidden_effects.rs: 10 x 10 grid, 13
/// separations 2-30 in, 4 samples per point, 0.1 % of beta noise.
fn sim(effect: &str, seed: u64) -> SimConfig {
    SimConfig {
        separations: vec![
            2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 21.0, 25.0, 30.0,
        ],
        effects: vec![Effect::parse(effect).unwrap()],
        noise: 32.768,
        samples: 4,
        seed,
        ..Default::default()
    }
}

/// What the corner readings' note says: which separations were placed and which not
/// (no readings, or readings of a journal that did not record their order), and a warning
/// when the corners twist beyond what 1 mil readings of a flat plate give.
#[test]
fn corner_readings_are_applied_where_known_and_their_twist_is_checked() {
    use crate::sweep::corners::{corner_tilt, PlateCorners, RunCorners, ROD_XY_IN};
    let (ds, _) = SimConfig {
        separations: vec![5.0, 10.0, 20.0],
        grid: (3, 3),
        ..Default::default()
    }
    .run();
    let plate = |sep: f64, c: [f64; 4], ordered: bool| PlateCorners {
        separation: sep,
        corners: c.to_vec(),
        tilt: ordered.then(|| corner_tilt(&c, ROD_XY_IN).unwrap()),
    };
    let rc = |plates: Vec<PlateCorners>| RunCorners {
        journal: "run/journal.jsonl".into(),
        plates,
    };
    let data = || Data::from_dataset(&ds, Weights::Separation, None).unwrap();
    // 5 in placed (higher on +x), 10 in read by an older version, 20 in not read.
    let mut d = data();
    let out = place_by_corners(
        &rc(vec![
            plate(5.0, [5.003, 5.003, 4.997, 4.997], true),
            plate(10.0, [10.0; 4], false),
        ]),
        &mut d,
    );
    assert!(
        d.measured_tilts_deg[0][0] > 0.01,
        "{:?}",
        d.measured_tilts_deg
    );
    assert_eq!(&d.measured_tilts_deg[1..], [[0.0; 2]; 2]);
    assert_eq!(out.tilt_deg[1], None);
    assert!(out.note.contains("at 1 of 3 separations"), "{}", out.note);
    assert!(
        out.note
            .contains("level at 10, 20 in (no corner readings with a known order)"),
        "{}",
        out.note
    );
    assert!(!out.note.contains("twist"), "{}", out.note);
    // One corner misread by 5 mils: a twist of 1.25 mils is within...
    let mut d = data();
    let out = place_by_corners(
        &rc(vec![plate(20.0, [20.005, 20.0, 20.0, 20.0], true)]),
        &mut d,
    );
    assert!(!out.note.contains("twist"), "{}", out.note);
    // ...one misread by 10 mils is not.
    let out = place_by_corners(
        &rc(vec![plate(20.0, [20.010, 20.0, 20.0, 20.0], true)]),
        &mut d,
    );
    assert!(
        out.note.contains("the corners at 20 in twist by 2.5 mils"),
        "{}",
        out.note
    );
    // Only unordered readings: nothing applied, and the note says why.
    let mut d = data();
    let out = place_by_corners(&rc(vec![plate(5.0, [5.0; 4], false)]), &mut d);
    assert!(d.measured_tilts_deg.is_empty());
    assert!(
        out.note
            .contains("with a known order (journalled by an older version)"),
        "{}",
        out.note
    );
}

/// A rival is a tie: a candidate of the same round within RIVAL_DBIC of the cause, above
/// or below, and significant on its own. One far above (it fit better but failed the
/// held-out test, or it would have been named) is no tie, nor one of another round.
#[test]
fn rivals_are_candidates_within_the_bic_tie_of_the_cause() {
    let trial = |round: usize, cand: Cand, dbic: f64| super::select::Trial {
        round,
        cand,
        dchi2: dbic,
        k: 1,
        dbic,
        cv_rms: None,
        cv_chi2: None,
        accepted: false,
        failure: None,
        fit: None,
    };
    let trials = [
        trial(1, Cand::CellGain, 1000.0),
        trial(1, Cand::Proximity, 995.0),
        trial(1, Cand::BeaconPattern, 1008.0),
        trial(1, Cand::BeaconTilt, 357_865.0),
        trial(1, Cand::FaceAngle, 985.0),
        trial(2, Cand::Intensity, 1001.0),
    ];
    let r = rivals(&trials, 1, Cand::CellGain, 1000.0);
    let names: Vec<&str> = r.iter().map(|r| r.effect.as_str()).collect();
    assert_eq!(names, ["proximity", "beacon_pattern"]);
    // Small causes: a rival must be significant on its own.
    let trials = [
        trial(1, Cand::CellGain, 14.0),
        trial(1, Cand::Proximity, 8.0),
    ];
    assert!(rivals(&trials, 1, Cand::CellGain, 14.0).is_empty());
}

/// Settings whose noise differs within a separation, pooled by the default weights: the
/// note names the setting and `--weights setting`; with those weights, no note.
#[test]
fn settings_whose_noise_differs_are_pointed_out() {
    let cfg = SimConfig {
        effects: Vec::new(),
        separations: vec![4.0, 8.0, 15.0, 30.0],
        ..sim("cell_gain=0", 6)
    };
    let (mut ds, _) = cfg.run();
    // Power 2 on every other point, with 40 counts more noise (alternating signs, so the
    // means stay put).
    let groups = ds.points();
    for (k, g) in groups.iter().enumerate() {
        let loud = k % 2 == 0;
        for (j, &i) in g.rows.iter().enumerate() {
            let s = &mut ds.samples[i];
            s.power = Some(if loud { 2.0 } else { 1.0 });
            if loud && s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                let d = if j % 2 == 0 { 40.0 } else { -40.0 };
                s.x += d;
                s.y += d;
            }
        }
    }
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    let note = a.data_notes.join(" | ");
    assert!(
        note.contains("the noise differs between settings within a separation: power level")
            && note.contains("`--weights setting`"),
        "{note}"
    );
    let opts = Options {
        weights: Weights::Setting,
        ..Options::default()
    };
    let b = analyze(&ds, &opts, &Silent).unwrap();
    assert!(b.data_notes.is_empty(), "{:?}", b.data_notes);
}

/// The settings note for each setting alone: a separation's points differing only in
/// frequency, only in power or only in sensitivity (every other setting the same) make
/// more than one setting there, so the noise test runs and names it. Settings that
/// differ, with the same noise: no note.
#[test]
fn each_setting_alone_is_told_apart_by_the_settings_note() {
    type Set = fn(&mut crate::data::Sample, bool);
    let cases: [(Set, &str); 3] = [
        (
            |s, loud| s.frequency_hz = Some(if loud { 4050.0 } else { 2000.0 }),
            "modulation frequency",
        ),
        (
            |s, loud| s.power = Some(if loud { 2.0 } else { 1.0 }),
            "power level",
        ),
        (
            |s, loud| s.sensitivity = Some(if loud { 4.0 } else { 1.0 }),
            "sensitivity setting",
        ),
    ];
    let cfg = SimConfig {
        effects: Vec::new(),
        separations: vec![4.0, 8.0, 15.0, 30.0],
        ..sim("cell_gain=0", 6)
    };
    let base = cfg.run().0;
    for (set, name) in cases {
        for louder in [40.0, 0.0] {
            let mut ds = base.clone();
            // Every other point at the other setting, with `louder` counts more noise
            // (alternating signs, so the means stay put).
            for (k, g) in ds.points().iter().enumerate() {
                let loud = k % 2 == 0;
                for (j, &i) in g.rows.iter().enumerate() {
                    let s = &mut ds.samples[i];
                    set(s, loud);
                    if loud && s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                        let d = if j % 2 == 0 { louder } else { -louder };
                        s.x += d;
                        s.y += d;
                    }
                }
            }
            let (_, notes) = data_notes(&ds, &Options::default()).unwrap();
            let note = notes.join(" | ");
            let want = format!(
                "the noise differs between settings within a separation: {name} (max/min std"
            );
            assert_eq!(
                note.contains(&want),
                louder > 0.0,
                "{name} {louder}: {note}"
            );
        }
    }
}

/// One sample per point, 10 counts of noise, 32.8 assumed: chi2/dof ~0.1, and the note
/// says the assumed noise is far too large and what to rerun with.
#[test]
fn a_noise_far_larger_than_the_residuals_is_pointed_out() {
    let cfg = SimConfig {
        effects: Vec::new(),
        noise: 10.0,
        samples: 1,
        separations: vec![3.0, 6.0, 12.0, 20.0, 30.0],
        ..sim("cell_gain=0", 7)
    };
    let (ds, _) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert!(a.chi2_dof_before < 0.2, "{}", a.chi2_dof_before);
    let note = a.data_notes.join(" | ");
    assert!(
        note.contains("far smaller than the noise assumed for one sample per point (32.8 counts)"),
        "{note}"
    );
    let rerun: f64 = (note.split("rerun with --noise ").nth(1))
        .and_then(|t| t.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{note}"));
    assert!((8.0..12.0).contains(&rerun), "{note}");
    // At the true noise, no note; far above it, the note names --noise.
    let opts = Options {
        noise: Some(10.0),
        ..Options::default()
    };
    let b = analyze(&ds, &opts, &Silent).unwrap();
    assert!(b.data_notes.is_empty(), "{:?}", b.data_notes);
    let opts = Options {
        noise: Some(200.0),
        ..Options::default()
    };
    let c = analyze(&ds, &opts, &Silent).unwrap();
    let note = c.data_notes.join(" | ");
    assert!(
        note.contains("far smaller than the noise set by --noise (200.0 counts)"),
        "{note}"
    );
    // Measured noise: 4 samples per point, each moved by +/-60 counts in turn, so the
    // samples scatter ~4x more than their means (which stay put) do.
    let cfg = SimConfig { samples: 4, ..cfg };
    let (mut ds, _) = cfg.run();
    for g in ds.points() {
        for (j, &i) in g.rows.iter().enumerate() {
            let s = &mut ds.samples[i];
            if s.x.abs() < 30_000.0 && s.y.abs() < 30_000.0 {
                let d = if j % 2 == 0 { 60.0 } else { -60.0 };
                s.x += d;
                s.y += d;
            }
        }
    }
    let m = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert!(m.chi2_dof_before < 0.5, "{}", m.chi2_dof_before);
    let note = m.data_notes.join(" | ");
    assert!(
        note.contains("the point means scatter far less than their repeated samples say"),
        "{note}"
    );
}

/// One sample per point with 3x the assumed noise: the excess chi-square is no structure
/// (no extension gains), and the verdict says to rerun with the noise it sees; with that
/// noise nothing is named.
#[test]
fn a_noise_larger_than_assumed_is_pointed_out() {
    let cfg = SimConfig {
        effects: Vec::new(),
        noise: 100.0,
        samples: 1,
        ..sim("cell_gain=0", 3)
    };
    let (ds, _) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert!(a.unexplained, "{}", a.verdict);
    assert!(
        a.verdict.contains("rerun with --noise 10") && a.causes.is_empty(),
        "{}",
        a.verdict
    );
    let opts = Options {
        noise: Some(100.0),
        ..Options::default()
    };
    let a = analyze(&ds, &opts, &Silent).unwrap();
    assert!(!a.unexplained && a.causes.is_empty(), "{}", a.verdict);
}

/// The reported correlation is the real one: over 400 seeds, the sample correlation of
/// face_angle's (DX, DY) estimates agrees with the correlation each fit reports (a
/// smaller setup than the analysis tests to keep this fast: 6 separations, 1 sample per
/// point, the model fitted directly from the true pose).
#[test]
fn reported_correlation_matches_the_scatter_over_seeds() {
    let model = Model::new(Base::Thesis, 6).with(Cand::FaceAngle);
    let (mut dx, mut dy, mut reported) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 0..400 {
        let mut cfg = sim("face_angle=1,-0.5", 1000 + seed);
        cfg.separations = vec![2.0, 4.0, 6.0, 10.0, 18.0, 30.0];
        cfg.samples = 1;
        let (ds, _) = cfg.run();
        let data = Data::from_dataset(&ds, Weights::Separation, Some(32.768)).unwrap();
        let all: Vec<usize> = (0..data.points.len()).collect();
        let x0 = [0.6, 0.1, 0.062, 0.001, 0.002, 0.001, 0.0, 0.0];
        let f = super::select::fit_all(&model, &data, &all, &x0).unwrap();
        dx.push(f.x[6]);
        dy.push(f.x[7]);
        let p = delta_method(&model, Cand::FaceAngle, &f, |v| {
            Cand::FaceAngle.report(Base::Thesis, v)
        });
        reported.push(p.cov[(0, 1)] / (p.cov[(0, 0)] * p.cov[(1, 1)]).sqrt());
    }
    let n = dx.len() as f64;
    let (mx, my) = (dx.iter().sum::<f64>() / n, dy.iter().sum::<f64>() / n);
    let sxy: f64 = dx.iter().zip(&dy).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = dx.iter().map(|a| (a - mx).powi(2)).sum();
    let syy: f64 = dy.iter().map(|b| (b - my).powi(2)).sum();
    let sample = sxy / (sxx * syy).sqrt();
    let rep = reported.iter().sum::<f64>() / n;
    println!("face_angle DX, DY over 400 seeds: sample correlation {sample:.3}, reported {rep:.3}");
    // The sampling error of a correlation near 0.7 from 400 pairs is ~0.026 (60 pairs
    // gave 0.80 against 0.68: too few).
    assert!(rep > 0.5, "reported {rep}");
    assert!(
        (sample - rep).abs() < 0.1,
        "sample correlation {sample}, reported {rep}"
    );
}

/// A FitResult of the thesis model plus `beacon_tilt` at (tx, ty) with the given
/// covariance (free parameters: all 8).
fn tilt_fit(tx: f64, ty: f64, cov: DMatrix<f64>) -> (Model, FitResult) {
    let m = Model::new(Base::Thesis, 3).with(Cand::BeaconTilt);
    let x = vec![0.6, 0.1, 0.062, 0.001, 0.002, 0.001, tx, ty];
    let sigma = (0..8).map(|i| cov[(i, i)].sqrt()).collect();
    let f = FitResult {
        x,
        sigma,
        cov,
        free: (0..8).collect(),
        chi2: 0.0,
        ss: 0.0,
        m: 100,
    };
    (m, f)
}

/// The delta method carries a correlation through a nonlinear reparametrisation with the
/// right sign, and the thresholds (0.5 own, 0.9 with the starting model) hold.
#[test]
fn correlations_through_the_delta_method() {
    // sigma_tx = 0.1, sigma_ty = 0.2, rho(tx, ty) = 0.8; rho(tx, d1) = 0.95,
    // rho(ty, d2) = 0.85 (below the starting-model threshold).
    let mut cov = DMatrix::<f64>::identity(8, 8) * 1e-6;
    cov[(6, 6)] = 0.01;
    cov[(7, 7)] = 0.04;
    cov[(6, 7)] = 0.8 * 0.1 * 0.2;
    cov[(7, 6)] = cov[(6, 7)];
    cov[(0, 6)] = 0.95 * 1e-3 * 0.1;
    cov[(6, 0)] = cov[(0, 6)];
    cov[(1, 7)] = 0.85 * 1e-3 * 0.2;
    cov[(7, 1)] = cov[(1, 7)];
    // Tilt along +x: T moves with tx, AZ with ty: rho(T, AZ) = rho(tx, ty).
    let (m, f) = tilt_fit(3.0, 0.0, cov.clone());
    let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
        Cand::BeaconTilt.report(Base::Thesis, v)
    });
    let c = p.correlations();
    assert_eq!(c.len(), 1, "{c:?}");
    assert_eq!((c[0].a.as_str(), c[0].b.as_str()), ("T_deg", "AZ_deg"));
    assert!((c[0].rho - 0.8).abs() < 1e-3, "{c:?}");
    let b = p.base_correlations();
    assert_eq!(b.len(), 1, "{b:?}");
    assert_eq!((b[0].a.as_str(), b[0].b.as_str()), ("T_deg", "d1"));
    assert!((b[0].rho - 0.95).abs() < 1e-3, "{b:?}");
    // Tilt along +y: T moves with ty, AZ against tx: rho(T, AZ) = -rho(tx, ty).
    let (m, f) = tilt_fit(0.0, 3.0, cov.clone());
    let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
        Cand::BeaconTilt.report(Base::Thesis, v)
    });
    let c = p.correlations();
    assert!(c.len() == 1 && (c[0].rho + 0.8).abs() < 1e-3, "{c:?}");
    // AZ moves against tx, which correlates +0.95 with d1.
    let b = p.base_correlations();
    assert_eq!(b.len(), 1, "{b:?}");
    assert_eq!((b[0].a.as_str(), b[0].b.as_str()), ("AZ_deg", "d1"));
    assert!((b[0].rho + 0.95).abs() < 1e-3, "{b:?}");
    // Weaker than 0.5: not listed.
    cov[(6, 7)] = 0.45 * 0.1 * 0.2;
    cov[(7, 6)] = cov[(6, 7)];
    let (m, f) = tilt_fit(3.0, 0.0, cov);
    let p = delta_method(&m, Cand::BeaconTilt, &f, |v| {
        Cand::BeaconTilt.report(Base::Thesis, v)
    });
    assert!(p.correlations().is_empty());
}

/// Every effect `analyze` can name says what the sensor board does with it; those its
/// calibration holds name the field `cta calibrate` writes.
#[test]
fn every_nameable_effect_says_what_the_board_does_with_it() {
    let generic = crate::analyze::board_note("not an effect");
    for name in crate::sim::effects::VOCABULARY {
        assert_ne!(crate::analyze::board_note(name), generic, "{name}");
    }
    for (name, field) in [
        ("cell_gain", "gx, gy"),
        ("cell_bias", "bx, by"),
        ("face_angle", "a, ay"),
        ("proximity", "cell offset s"),
    ] {
        let n = crate::analyze::board_note(name);
        assert!(n.contains("holds it") && n.contains(field), "{name}: {n}");
    }
    assert!(crate::analyze::board_note("saturation").starts_with("outside the board's model"));
}

/// A named cause's parameters are the final model's: from `pinhole` on thesis data,
/// `proximity` is named first and, fitted alone, stands in for `intensity` (S ~0.85 in);
/// the cause reports the S of the final model, which holds `intensity` too, near the
/// thesis's 0.175 in, and equal to the final parameter `proximity.S`. `beacon_pattern`,
/// named too, lists its tie to d3 once.
#[test]
fn a_cause_reports_its_parameters_in_the_final_model() {
    let (ds, _) = SimConfig {
        effects: Vec::new(),
        samples: 10,
        ..sim("cell_gain=0", 24)
    }
    .run();
    let opts = Options {
        from: Base::Pinhole,
        ..Options::default()
    };
    let a = analyze(&ds, &opts, &Silent).unwrap();
    let names: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
    assert!(
        names.first() == Some(&"proximity") && names.contains(&"intensity"),
        "{}",
        a.verdict
    );
    let c = &a.causes[0];
    let (s, sigma) = (c.params["S"], c.sigma["S"]);
    assert!(
        (s - 0.175).abs() < 5.0 * sigma && sigma < 0.01,
        "S = {s} +/- {sigma}"
    );
    let fin = a
        .params_after
        .iter()
        .find(|p| p.name == "proximity.S")
        .expect("proximity.S in the final parameters");
    assert!((fin.value - s).abs() < 1e-12, "{} vs {s}", fin.value);
    // beacon_pattern's H_deg and m are one parameter: its strong tie to d3 is listed
    // once, for H_deg.
    let bp = a
        .causes
        .iter()
        .find(|c| c.effect == "beacon_pattern")
        .expect("beacon_pattern named");
    let base: Vec<&str> = bp.base_correlations.iter().map(|r| r.a.as_str()).collect();
    assert_eq!(base, ["H_deg"], "{:?}", bp.base_correlations);
}

/// The hidden-effect setup's separations, in the order a sweep visits them.
const SEPS13: [f64; 13] = [
    2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 21.0, 25.0, 30.0,
];

/// A cell gain that drifts over the run (issue 30): both pairs' gain ratio changes linearly
/// by `total` from the first separation visited to the last (centred on 0), emulated as a
/// gain that changes with the separation order, on top of `extra` effects.
fn drifting_gain(total: f64, extra: &[&str], seed: u64) -> crate::data::Dataset {
    let n = SEPS13.len();
    let mut samples = Vec::new();
    for (k, &sep) in SEPS13.iter().enumerate() {
        let g = total * (k as f64 / (n - 1) as f64 - 0.5);
        let mut effects = vec![Effect::CellGain(g, g)];
        effects.extend(extra.iter().map(|e| Effect::parse(e).unwrap()));
        let (ds, _) = SimConfig {
            separations: vec![sep],
            effects,
            noise: 32.768,
            samples: 4,
            seed: seed * 100 + k as u64,
            ..Default::default()
        }
        .run();
        samples.extend(ds.samples);
    }
    crate::data::Dataset {
        path: "drift.csv".into(),
        samples,
    }
}

/// Issue 30: a cell gain drifting 2 % over the run was named `plate_offset` with confidence
/// (a plate 3.6 times the Table 2 budget off its place). Whatever the search fits, a plate
/// offset that large is not named as found: it carries the budget line and a warning naming
/// the alternatives (a drift), and the verdict keeps it out of "named:".
#[test]
fn a_gain_drift_is_not_named_a_plate_offset_with_confidence() {
    let ds = drifting_gain(0.02, &[], 3);
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    let names: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
    eprintln!("{}\n{names:?}", a.verdict);
    for c in a.causes.iter().chain(&a.tentative) {
        if let Some(b) = &c.budget {
            eprintln!(
                "{}: {} mils, {:.2}x {}",
                c.effect, b.fitted_mils, b.ratio, b.line
            );
        }
    }
    let named = a.verdict.split(';').next().unwrap();
    assert!(!named.contains("plate_offset"), "{}", a.verdict);
    if let Some(c) = a.causes.iter().find(|c| c.effect == "plate_offset") {
        let b = c.budget.as_ref().unwrap();
        assert!(b.ratio > super::BEYOND_BUDGET, "{b:?}");
        let w = b.warning.as_ref().unwrap();
        assert!(
            w.contains("gain_drift") && w.contains("separation order"),
            "{w}"
        );
        assert!(a.verdict.contains("not named as found"), "{}", a.verdict);
    }
}

/// Within the budget an apparatus cause is named as found, with the line it was compared with.
#[test]
fn a_plate_offset_within_the_budget_is_named_with_its_budget_line() {
    let (ds, _) = sim("plate_offset=0.02", 18).run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert_eq!(a.causes[0].effect, "plate_offset", "{}", a.verdict);
    let b = a.causes[0].budget.as_ref().unwrap();
    assert!(b.warning.is_none() && b.ratio < 1.5, "{b:?}");
    assert!(
        b.line.contains("31.5 mils") || b.line.contains("24.4 mils"),
        "{}",
        b.line
    );
    assert!(
        a.verdict.starts_with("named: plate_offset"),
        "{}",
        a.verdict
    );
    // A tight budget of the user's: the same fit is now far beyond it.
    let tight = crate::budget::Budget {
        items: vec![("plate".into(), [2.0; 6])],
        file: Some("tight.toml".into()),
        unit_warning: None,
    };
    let opts = Options {
        budget: tight,
        ..Options::default()
    };
    let a = analyze(&ds, &opts, &Silent).unwrap();
    let b = a.causes[0].budget.as_ref().unwrap();
    assert!(
        b.line.contains("tight.toml") && b.line.contains("2.0 mils"),
        "{}",
        b.line
    );
    assert!(b.warning.is_some(), "{b:?}");
    assert!(
        a.verdict.starts_with("no cause named as found"),
        "{}",
        a.verdict
    );
}

/// The truth's LED offsets in `led_position`'s gauge ([`Model::led_gauge`]): their mean and
/// their mean turn about the plate's centre taken out (the head's d1, d2 and p3 hold those).
fn led_truth_in_gauge(leds: &[super::model::Led], truth: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let n = leds.len() as f64;
    let t: Vec<[f64; 2]> = leds.iter().map(|l| truth[l.id as usize]).collect();
    let m = [0, 1].map(|a| t.iter().map(|v| v[a]).sum::<f64>() / n);
    let t: Vec<[f64; 2]> = t.iter().map(|v| [v[0] - m[0], v[1] - m[1]]).collect();
    let (num, den) = leds.iter().zip(&t).fold((0.0, 0.0), |(a, b), (l, v)| {
        let [x, y] = l.xy;
        (a + x * v[1] - y * v[0], b + x * x + y * y)
    });
    let w = num / den;
    leds.iter()
        .zip(&t)
        .map(|(l, v)| [v[0] + w * l.xy[1], v[1] - w * l.xy[0]])
        .collect()
}

/// `led_position=0.004` (4 mils per axis, Table 2 budgets 21 and 6.5 mils): named first with
/// a held-out gain (each LED's place fitted on four folds predicts the fifth), within the
/// budget, and every LED's (dx, dy) recovered within its 1-sigma in the gauge: the RMS of
/// (estimate - truth) / sigma over the 200 values near 1.
#[test]
fn led_position_is_named_and_each_led_recovered() {
    let t0 = std::time::Instant::now();
    let (ds, truth) = sim("led_position=0.004", 25).run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    let c = &a.causes[0];
    assert_eq!(c.effect, "led_position", "{}", a.verdict);
    assert!(!a.unexplained && c.systematic_rms_after < 0.5 * c.systematic_rms_before);
    assert!(c.heldout_rms_after < c.heldout_rms_before);
    let b = c.budget.as_ref().unwrap();
    assert!(b.warning.is_none(), "{b:?}");
    let data = Data::from_dataset(&ds, Weights::Separation, None).unwrap();
    let leds = Model::leds_of(&data);
    assert_eq!(leds.len(), 100);
    let want = led_truth_in_gauge(&leds, &truth.led_offsets);
    let mut z = Vec::new();
    for (l, t) in leds.iter().zip(&want) {
        for (a, n) in ["dx", "dy"].iter().enumerate() {
            let name = format!("{n}@b{}", l.id);
            z.push((c.params[&name] - t[a]) / c.sigma[&name]);
        }
    }
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    // An RMS of 200 standard normals is 1 +/- 0.05; a 1-sigma off by 2 reads 0.5 or 2.
    assert!((0.75..1.3).contains(&rms), "RMS z {rms:.2}");
    let r = c.params["rms_in"];
    assert!((0.003..0.005).contains(&r), "rms_in {r}");
    eprintln!("{} ({:.1} s)", a.verdict, t0.elapsed().as_secs_f64());
}

/// A file without beacon ids: per-LED candidates are not tried, and the output says why.
#[test]
fn without_beacon_ids_per_led_candidates_are_not_tried() {
    let (mut ds, _) = sim("led_position=0.004", 25).run();
    for s in &mut ds.samples {
        s.beacon = None;
    }
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    let u = a
        .untested
        .iter()
        .find(|u| u.effect == "led_position")
        .unwrap();
    assert!(
        u.reason.contains("not identified") && u.reason.contains("`beacon`"),
        "{}",
        u.reason
    );
    assert!(a.trials.iter().all(|t| t.effect != "led_position"));
}

/// `led_tilt`: each LED's boresight tilted on its own (3 deg per axis): named (not
/// `led_position`, whose random-effects ratio is higher here but whose fit is 600 worse in
/// chi-square: the plain-BIC choice between per-LED candidates), with a held-out gain; the
/// per-LED tilts against the truth (mean taken out: the gauge) have an RMS z near 1.
#[test]
fn led_tilt_is_named_and_each_led_recovered() {
    let t0 = std::time::Instant::now();
    let (ds, truth) = sim("led_tilt=3", 27).run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    eprintln!("{} ({:.1} s)", a.verdict, t0.elapsed().as_secs_f64());
    let c = &a.causes[0];
    assert_eq!(c.effect, "led_tilt", "{}", a.verdict);
    assert!(c.heldout_rms_after < c.heldout_rms_before);
    let data = Data::from_dataset(&ds, Weights::Separation, None).unwrap();
    let leds = Model::leds_of(&data);
    let n = leds.len() as f64;
    let t: Vec<[f64; 2]> = leds
        .iter()
        .map(|l| truth.led_tilts_deg[l.id as usize])
        .collect();
    let m = [0, 1].map(|a| t.iter().map(|v| v[a]).sum::<f64>() / n);
    let mut z = Vec::new();
    for (l, v) in leds.iter().zip(&t) {
        for (a, name) in ["tx_deg", "ty_deg"].iter().enumerate() {
            let k = format!("{name}@b{}", l.id);
            z.push((c.params[&k] - (v[a] - m[a])) / c.sigma[&k]);
        }
    }
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    let within = z.iter().filter(|v| v.abs() < 1.0).count() as f64 / z.len() as f64;
    eprintln!(
        "RMS z {rms:.2}, {:.0} % within 1-sigma, rms_deg {}",
        100.0 * within,
        c.params["rms_deg"]
    );
    assert!((0.75..1.3).contains(&rms), "RMS z {rms:.2}");
    // 200 values: 68 % within their 1-sigma, give or take 3 standard errors (3.3 %).
    assert!((0.58..0.78).contains(&within), "{within}");
    // The scatter they were drawn with (3 deg per axis), not half or twice it.
    assert!(
        (2.5..3.5).contains(&c.params["rms_deg"]),
        "{}",
        c.params["rms_deg"]
    );
}

/// `array_pose` on the quad layout (four arrays 12 in apart, ids `100 a + LED`), each array
/// shifted by 20 mils per axis and turned by 0.3 deg: named first and alone, each array's
/// (dx, dy, dtheta) within its 1-sigma of the truth in the gauge. The gauge takes the arrays'
/// mean turn phi and mean shift out as a rigid motion of the plate (the head pose's):
/// `dtheta' = dtheta - phi`, `d' = R(-phi) (c + d) - c - t`, t making the mean d' zero.
#[test]
fn array_pose_is_named_and_each_array_recovered() {
    let t0 = std::time::Instant::now();
    let cfg = SimConfig {
        quad: Some(12.0),
        ..sim("array_pose=0.02,0.3", 31)
    };
    let (ds, truth) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    eprintln!("{} ({:.1} s)", a.verdict, t0.elapsed().as_secs_f64());
    assert_eq!(a.causes.len(), 1, "{}", a.verdict);
    let c = &a.causes[0];
    assert_eq!(c.effect, "array_pose", "{}", a.verdict);
    assert!(c.heldout_rms_after < c.heldout_rms_before);
    let (cs, ps) = (&truth.array_centres, &truth.array_poses);
    assert_eq!((cs.len(), ps.len()), (4, 4));
    let phi = ps.iter().map(|p| p[2]).sum::<f64>() / 4.0;
    let (s, co) = (-phi).to_radians().sin_cos();
    let moved: Vec<[f64; 2]> = cs
        .iter()
        .zip(ps)
        .map(|(c, p)| {
            let (x, y) = (c[0] + p[0], c[1] + p[1]);
            [co * x - s * y - c[0], s * x + co * y - c[1]]
        })
        .collect();
    let t = [0, 1].map(|k| moved.iter().map(|m| m[k]).sum::<f64>() / 4.0);
    let mut z = Vec::new();
    for (q, (m, p)) in moved.iter().zip(ps).enumerate() {
        let want = [m[0] - t[0], m[1] - t[1], p[2] - phi];
        for (k, name) in ["dx", "dy", "dtheta_deg"].iter().enumerate() {
            let key = format!("{name}@a{q}");
            let zk = (c.params[&key] - want[k]) / c.sigma[&key];
            eprintln!(
                "{key}: {:.6} +/- {:.6} (truth {:.6}, z {zk:+.2})",
                c.params[&key], c.sigma[&key], want[k]
            );
            z.push(zk);
        }
    }
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt();
    // 12 values, 9 of them free (the gauge holds three means): RMS z near 0.87.
    assert!(
        rms < 1.6 && z.iter().all(|v| v.abs() < 3.5),
        "RMS z {rms:.2}"
    );
    assert!(c.chi2_dof_after < 1.2, "{}", a.verdict);
    // The angle errors are against where the model puts each beacon (its array moved): at
    // 2 in 0.120 -> 0.014 deg; against the nominal places they grew, 0.120 -> 0.172.
    let (b, f) = (a.angle_std_before_deg[0], a.angle_std_after_deg[0]);
    assert!(f < 0.3 * b, "angle std at 2 in {b} -> {f} deg");
}

/// One array: `array_pose` is not tried (its pose is the head's), and the output says why.
#[test]
fn array_pose_needs_several_arrays() {
    let (ds, _) = sim("array_pose=0.02,0.3", 31).run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    let u = a
        .untested
        .iter()
        .find(|u| u.effect == "array_pose")
        .unwrap();
    assert!(u.reason.contains("one array"), "{}", u.reason);
    assert!(a.trials.iter().all(|t| t.effect != "array_pose"));
}

/// Clean data on the quad layout: nothing named; `array_pose` is tried and ruled out, its
/// per-array values at the noise (weighted RMS within twice the noise-only value).
#[test]
fn clean_quad_data_names_nothing() {
    let cfg = SimConfig {
        quad: Some(12.0),
        effects: Vec::new(),
        ..sim("ambient=0", 32)
    };
    let (ds, _) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert!(a.causes.is_empty() && !a.unexplained, "{}", a.verdict);
    let r = a
        .ruled_out
        .iter()
        .find(|r| r.effect == "array_pose")
        .unwrap();
    assert!(!r.per_separation.is_empty());
    for sp in &r.per_separation {
        assert!(
            sp.separations == 4 && sp.rms <= 2.0 * sp.noise_rms,
            "{sp:?}"
        );
    }
}
