//! Tests of the saved fit and the pinhole fit's words.

use super::*;
use crate::data::weights::{Weights, CHI2_WARN};
use cta_core::collinearity::{Params, NAMES};
use cta_core::glsdc;
use std::path::Path;

fn report() -> FitReport {
    let vals = [0.6, 0.1, 0.06, 0.001, 0.002, 0.001, 18918.6];
    let map = |f: &dyn Fn(usize) -> f64| {
        NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| (n.to_string(), f(i)))
            .collect()
    };
    FitReport {
        model: MODEL.into(),
        source: "sim.csv".into(),
        separations: vec![20.0, 25.0],
        weights: Weights::None,
        params: map(&|i| vals[i]),
        sigma: map(&|_| 1e-3),
        covariance: vec![1e-6; 49],
        rms_counts: 1.0,
        residual_variance_counts2: Some(1.0),
        chi2_per_dof: None,
        chi2_expected: None,
        chi2_dof: 1.0,
        iterations: 5,
        condition: 1e3,
        stop: "Converged".into(),
        observations: 200,
        warnings: Vec::new(),
        data_notes: Vec::new(),
    }
}

/// Save `r` (as JSON, after `edit`) and load it back.
fn load_edited(name: &str, edit: impl Fn(&mut serde_json::Value)) -> Result<FitReport, String> {
    let p = std::env::temp_dir().join(format!("cta-fit-{}-{name}.json", std::process::id()));
    let mut v = serde_json::to_value(report()).unwrap();
    edit(&mut v);
    std::fs::write(&p, v.to_string()).unwrap();
    let r = FitReport::load(&p);
    std::fs::remove_file(&p).ok();
    r.map_err(|e| e.to_string())
}

/// A sensor calibration given where a fit belongs is named as such.
#[test]
fn a_calibration_file_is_not_taken_for_a_fit() {
    let e = load_edited("cal", |v| {
        *v = serde_json::json!({"d": [0.6, 0.1, 0.06], "p": [0, 0, 0], "h": 19000.0,
            "noise": 32.8, "near_field": {"s": 0.175}});
    })
    .unwrap_err();
    assert!(
        e.contains("this is a sensor calibration (`cta calibrate --out`), not a fit"),
        "{e}"
    );
    let e = load_edited("other", |v| *v = serde_json::json!({"h": 1})).unwrap_err();
    assert!(e.contains("not a CTA fit file"), "{e}");
}

/// Every way GLSDC stops is said in words.
#[test]
fn stop_reasons_are_in_words() {
    use glsdc::Stop::*;
    for stop in [
        SmallStep,
        SmallCostChange,
        ZeroCost,
        NoFurtherDecrease,
        SmallPredictedDecrease,
    ] {
        let name = format!("{stop:?}");
        let words = describe_stop(&name);
        assert!(
            words.contains(' ') && !words.contains(&name),
            "{name}: {words}"
        );
    }
}

/// The chi2/dof warning: only with `repeat` weights, above `cta calibrate`'s line.
#[test]
fn chi2_warning_only_for_repeat_weights_above_the_line() {
    let f = Path::new("m.csv");
    let mut r = report();
    r.residual_variance_counts2 = Some(1921.0);
    assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
    r.weights = Weights::Repeat;
    r.residual_variance_counts2 = None;
    r.chi2_per_dof = Some(CHI2_WARN);
    assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
    // 10 samples per point: a right model gives 9/7 = 1.29.
    r.chi2_per_dof = Some(1.31);
    assert_eq!(chi2_warning(&r, f, Some(9.0 / 7.0)), None);
    // Without an expectation (none is known below 4 samples per point): only far above 1.
    r.chi2_per_dof = Some(1.9);
    assert_eq!(chi2_warning(&r, f, None), None);
    r.chi2_per_dof = Some(88.25);
    let w = chi2_warning(&r, f, None).unwrap();
    assert!(
        w.starts_with("chi2/dof 88.25 (far above the 1 a right model gives")
            && w.contains("the residuals are 9.4x the noise"),
        "{w}"
    );
    // The fit's own expectation goes before the caller's.
    r.chi2_expected = Some(3.0);
    assert_eq!(
        chi2_warning(&r, f, Some(1.0)).map(|w| w[..25].to_string()),
        Some("chi2/dof 88.25 (a right m".into())
    );
    r.chi2_per_dof = Some(3.5);
    assert_eq!(chi2_warning(&r, f, Some(1.0)), None);
    r.chi2_expected = None;
    r.chi2_per_dof = Some(2.25);
    let w = chi2_warning(&r, f, Some(1.0)).unwrap();
    assert!(
        w.starts_with("chi2/dof 2.25 (a right model gives 1.00")
            && w.contains("the residuals are 1.5x the noise")
            && w.contains("biases the parameters by an amount they do not bound")
            && w.contains("`cta analyze m.csv`"),
        "{w}"
    );
}

/// A fit saved before `residual_variance_counts2` and `chi2_per_dof` existed loads, with
/// them derived from `chi2_dof` by its weighting.
#[test]
fn earlier_fit_files_load_with_the_named_fields() {
    let strip = |v: &mut serde_json::Value| {
        let o = v.as_object_mut().unwrap();
        o.remove("residual_variance_counts2");
        o.remove("chi2_per_dof");
        o.insert("chi2_dof".into(), serde_json::json!(1921.0));
    };
    let r = load_edited("old-none", strip).unwrap();
    assert_eq!(
        (r.residual_variance_counts2, r.chi2_per_dof),
        (Some(1921.0), None)
    );
    let r = load_edited("old-repeat", |v| {
        strip(v);
        v["weights"] = serde_json::json!("repeat");
    })
    .unwrap();
    assert_eq!(
        (r.residual_variance_counts2, r.chi2_per_dof),
        (None, Some(1921.0))
    );
}

#[test]
fn saved_fits_are_validated_on_load() {
    assert!(load_edited("ok", |_| {}).is_ok());
    for (name, value, needle) in [
        (
            "h0",
            serde_json::json!(0.0),
            "field `params.H`: 0 is out of range",
        ),
        (
            "hneg",
            serde_json::json!(-5.0),
            "field `params.H`: -5 is out of range",
        ),
        ("hbig", serde_json::json!(1e308), "field `params.H`"),
    ] {
        let e = load_edited(name, |v| v["params"]["H"] = value.clone()).unwrap_err();
        assert!(
            e.contains(&format!("cta-fit-{}-{name}.json", std::process::id())),
            "{e}"
        );
        assert!(e.contains(needle), "{e}");
    }
    let e = load_edited("cov", |v| {
        v["covariance"] = serde_json::json!([1.0, 0.0, 0.0, 0.0, 1.0])
    })
    .unwrap_err();
    assert!(
        e.contains("field `covariance`: 5 entries, a 7 x 7 matrix has 49"),
        "{e}"
    );
    let e = load_edited("model", |v| {
        v["model"] = serde_json::json!("near-field (analyze)")
    })
    .unwrap_err();
    assert!(e.contains("field `model`: `near-field (analyze)`"), "{e}");
    let e = load_edited("d1", |v| {
        v["params"].as_object_mut().unwrap().remove("d1");
    })
    .unwrap_err();
    assert!(e.contains("field `params` lacks `d1`"), "{e}");
    let e = load_edited("sig", |v| v["sigma"]["p2"] = serde_json::json!(-1.0)).unwrap_err();
    assert!(e.contains("field `sigma.p2`"), "{e}");
    let e = load_edited("seps", |v| v["separations"] = serde_json::json!([])).unwrap_err();
    assert!(e.contains("field `separations` is empty"), "{e}");
}

/// The 20 in of the thesis's recommended 20-30 in fit is met within the separation matching
/// of the whole tool (a plate measured at 19.9992 in is at 20); 19.85 in is below it.
#[test]
fn twenty_inches_is_matched_within_a_tenth() {
    let warned = |near: f64| {
        let (ds, _) = crate::sim::SimConfig {
            separations: vec![near, 25.0],
            ..Default::default()
        }
        .run();
        let rep = fit(&ds, Weights::None).unwrap();
        rep.warnings
            .iter()
            .any(|w| w.contains("separations below 20 in"))
    };
    assert!(!warned(19.9992));
    assert!(!warned(20.0));
    assert!(warned(19.85));
}

/// A calibration whose near-field model is the simulation's own head turns every noise-free
/// report back into the true direction (error 0 to rounding at every separation, close in
/// too), where the pinhole model of the same calibration is off by degrees close in.
#[test]
fn a_calibration_with_the_true_head_evaluates_to_no_error() {
    let cal = crate::pose::calibrations::sim_calibration(0.0).unwrap();
    let (ds, truth) = crate::sim::SimConfig {
        separations: vec![3.0, 10.0, 30.0],
        noise: 0.0,
        ..Default::default()
    }
    .run();
    let d = truth.pose().d;
    let near = evaluate(
        DirectionModel::NearField(&cal),
        &ds,
        Reference::Truth(d),
        [0.0; 3],
        true,
    );
    assert_eq!(near.separation_in, vec![3.0, 10.0, 30.0]);
    assert_eq!(near.model, "near-field (eqs 60-63)");
    for i in 0..3 {
        assert!(near.angle_mean_deg[i] < 1e-5, "{near:?}");
        assert_eq!(near.unsolved[i], 0, "{near:?}");
    }
    let ph = cal.pinhole.unwrap();
    let f = |v: [f32; 3]| v.map(|x| x as f64);
    let [pd, pp] = [f(ph.d), f(ph.p)];
    let x = Params::from_column_slice(&[pd[0], pd[1], pd[2], pp[0], pp[1], pp[2], cal.h as f64]);
    let pin = evaluate(
        DirectionModel::Pinhole(&x),
        &ds,
        Reference::Truth(d),
        [0.0; 3],
        true,
    );
    assert!(pin.angle_mean_deg[0] > 0.5, "{pin:?}");
}
