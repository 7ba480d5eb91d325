//! Hidden-effect tests of `cta analyze` (issue 3): data simulated with a known effect on top
//! of the thesis physics must come back with that effect named first, its parameters near
//! the truth, and a held-out gain; clean data must name nothing; an effect outside the
//! vocabulary must be reported as unexplained structure, not as a false name.
//!
//! Datasets (documented choice, to keep the debug-build suite fast while honest): the CTA
//! 10 x 10 grid at 1 in pitch, 13 separations spanning 2-30 in (2, 3, 4, 5, 6, 8, 10, 12,
//! 15, 18, 21, 25, 30: dense near the board where the near-field effects live, sparse far),
//! 4 samples per point with Gaussian noise of 0.1 % of beta (32.8 counts, rounded to whole
//! counts as the NorthStar reports), seeded. The `--from pinhole` test needs the precision
//! REFERENCE.md's d3 claim rests on: all 29 separations and 200 samples per point (the
//! thesis's Ch VI protocol takes 100-200 samples per point).
//!
//! `intensity` has no test of its own on top of the thesis physics (the `thesis` model
//! already contains it: injecting it changes nothing); it is found from `pinhole` below.

use cta_cli::cmd::analyze::render_text;
use cta_lab::analyze::{analyze, model::Base, Analysis, Cause, Options};
use cta_lab::progress::Silent;
use cta_lab::sim::effects::{Effect, VOCABULARY};
use cta_lab::sim::{SimConfig, Truth};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::FRAC_1_SQRT_2;

const SEPS: [f64; 13] = [
    2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 21.0, 25.0, 30.0,
];
const NOISE: f64 = 32.768;
/// Datasets per effect in `every_effect_at_random_sizes`.
const RANDOM_SEEDS: usize = 3;
/// Clean datasets in `ruled_out_one_sigma_is_honest_on_clean_data` (a clean analysis is cheap).
const CLEAN_SEEDS: std::ops::Range<u64> = 500..530;
/// The per-LED boresight scatter `led_tilt` is hidden at, deg per axis.
const LED_TILT_DEG: f64 = 3.0;

fn sim(effects: &[&str], seed: u64) -> SimConfig {
    SimConfig {
        separations: SEPS.to_vec(),
        effects: effects.iter().map(|e| Effect::parse(e).unwrap()).collect(),
        noise: NOISE,
        samples: 4,
        seed,
        ..Default::default()
    }
}

fn run(cfg: &SimConfig, from: Base) -> (Analysis, Truth) {
    let (ds, truth) = cfg.run();
    let opts = Options {
        from,
        ..Default::default()
    };
    let a = analyze(&ds, &opts, &Silent).unwrap_or_else(|e| panic!("analyze failed: {e}"));
    (a, truth)
}

fn names(a: &Analysis) -> Vec<&str> {
    a.causes.iter().map(|c| c.effect.as_str()).collect()
}

/// How far a fitted parameter may lie from the truth, in its reported 1-sigma. With ~100
/// parameters checked over the default run, a 4-sigma excursion of an honest Gaussian
/// estimate (P = 6e-5 each) is not expected; a larger 1-sigma would make every check easier,
/// which `every_effect_at_random_sizes` and
/// `ruled_out_one_sigma_is_honest_on_clean_data` guard against.
const K_SIGMA: f64 = 4.0;

/// `(value - truth) / sigma` of parameter `p` of cause `c`; the 1-sigma must be reported,
/// positive and finite.
fn z_of(c: &Cause, p: &str, truth: f64) -> f64 {
    let v = c.params[p];
    let s = c.sigma.get(p).copied().unwrap_or(f64::NAN);
    assert!(s > 0.0 && s.is_finite(), "{}: {p} = {v} +/- {s}", c.effect);
    (v - truth) / s
}

/// Parameter `p` of the first cause is within [`K_SIGMA`] of its 1-sigma of `truth`.
fn near(a: &Analysis, p: &str, truth: f64) -> f64 {
    let c = &a.causes[0];
    let z = z_of(c, p, truth);
    assert!(
        z.abs() <= K_SIGMA,
        "{}: {p} = {} +/- {}, truth {truth} (z = {z:.2})",
        c.effect,
        c.params[p],
        c.sigma[p]
    );
    z
}

/// The per-separation corrections of the first cause (`plate_offset`: `x`, `y`;
/// `separation_error`: `z`) against the truth relative to its mean over the separations (the
/// common part is the head offset d); `plate_tilt`'s `tx_deg`, `ty_deg` against the truth
/// itself when named alone (its offsets in proportion to the separation tell a common
/// tilt), relative to its mean when `plate_offset` is named too (`Model::zero_mean`); each
/// within [`K_SIGMA`]; their z values.
fn near_per_separation(a: &Analysis, t: &Truth) -> Vec<f64> {
    near_per_separation_of(a, 0, t)
}

/// [`near_per_separation`] of cause `i`.
fn near_per_separation_of(a: &Analysis, i: usize, t: &Truth) -> Vec<f64> {
    let n = t.separations.len() as f64;
    let mean = |f: &dyn Fn(usize) -> f64| (0..t.separations.len()).map(f).sum::<f64>() / n;
    let with_offsets = a.causes.iter().any(|c| c.effect == "plate_offset");
    let truths: Vec<(&str, Vec<f64>)> = match a.causes[i].effect.as_str() {
        "plate_offset" => (0..2)
            .map(|j| {
                let m = mean(&|k| t.plate_offsets[k][j]);
                let name = if j == 0 { "x" } else { "y" };
                (name, t.plate_offsets.iter().map(|o| o[j] - m).collect())
            })
            .collect(),
        "separation_error" => {
            let m = mean(&|k| t.separation_errors[k]);
            vec![("z", t.separation_errors.iter().map(|e| e - m).collect())]
        }
        "plate_tilt" => (0..2)
            .map(|j| {
                let m = if with_offsets {
                    mean(&|k| t.plate_tilts_deg[k][j])
                } else {
                    0.0
                };
                let name = if j == 0 { "tx_deg" } else { "ty_deg" };
                (name, t.plate_tilts_deg.iter().map(|v| v[j] - m).collect())
            })
            .collect(),
        other => panic!("{other} has no per-separation corrections"),
    };
    let mut zs = Vec::new();
    for (name, tv) in truths {
        for (k, sep) in t.separations.iter().enumerate() {
            let p = format!("{name}@{sep}in");
            let c = &a.causes[i];
            let z = z_of(c, &p, tv[k]);
            assert!(
                z.abs() <= K_SIGMA,
                "{}: {p} = {} +/- {}, truth {} (z = {z:.2})",
                c.effect,
                c.params[&p],
                c.sigma[&p],
                tv[k]
            );
            zs.push(z);
        }
    }
    assert_eq!(zs.len() % SEPS.len(), 0);
    zs
}

/// Root mean square.
fn rms(z: &[f64]) -> f64 {
    (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt()
}

/// The effect is named first, alone, with a held-out gain and chi2/dof brought near 1.
fn named_first(effect: &str, seed: u64) -> (Analysis, Truth) {
    let (a, t) = run(&sim(&[effect], seed), Base::Thesis);
    let name = effect.split('=').next().unwrap();
    assert!(
        !a.unexplained && a.causes.first().map(|c| c.effect.as_str()) == Some(name),
        "hidden {effect}: got {:?} ({})",
        names(&a),
        a.verdict
    );
    assert!(a.causes[0].gain_rms_counts > 0.0, "no held-out gain");
    assert!(a.rms_after < a.rms_before);
    assert!(a.chi2_dof_after < 1.2 && a.chi2_dof_before > a.chi2_dof_after);
    (a, t)
}

#[test]
fn proximity() {
    let (a, _) = named_first("proximity=0.21", 11);
    no_per_led_cause(&a);
    near(&a, "S", 0.21);
}

#[test]
fn beacon_pattern() {
    let (a, _) = named_first("beacon_pattern=45", 12);
    near(&a, "H_deg", 45.0);
}

#[test]
fn beacon_tilt() {
    let (a, _) = named_first("beacon_tilt=3,45", 13);
    near(&a, "T_deg", 3.0);
    near(&a, "AZ_deg", 45.0);
}

#[test]
fn cell_gain() {
    let (a, _) = named_first("cell_gain=0.03,-0.02", 14);
    near(&a, "GX", 0.03);
    near(&a, "GY", -0.02);
}

#[test]
fn cell_bias() {
    let (a, _) = named_first("cell_bias=1e-5,-1e-5", 15);
    near(&a, "BX", 1e-5);
    near(&a, "BY", -1e-5);
}

/// Light on all four cells: 1e-5 /in^2 compresses the outputs at 30 in by about 1 % (the
/// pair's signal sum there is ~2e-3 /in^2), 2 % at the plate's corners.
#[test]
fn ambient() {
    let (a, _) = named_first("ambient=1e-5", 24);
    near(&a, "B", 1e-5);
}

/// LEDs off their pads by 4 mils per axis (seeded, one draw per LED): named first; each
/// LED's recovery is the unit test `led_position_is_named_and_each_led_recovered`.
#[test]
fn led_position() {
    let (a, t) = named_first("led_position=0.004", 26);
    assert_eq!(t.led_offsets.len(), 100);
    assert_eq!(a.causes.len(), 1, "{}", a.verdict);
}

/// LEDs soldered askew one by one, 3 deg per axis: named first; each LED's recovery is the
/// unit test `led_tilt_is_named_and_each_led_recovered`. The draws' mean (about 0.3 deg per
/// axis for 100 LEDs) is a tilt common to every LED, `beacon_tilt`'s by the gauge: when it is
/// named too, it must be that mean.
#[test]
fn led_tilt() {
    let (a, t) = named_first(&format!("led_tilt={LED_TILT_DEG}"), 28);
    assert_eq!(t.led_tilts_deg.len(), 100);
    let n = t.led_tilts_deg.len() as f64;
    let m = [0, 1].map(|k| t.led_tilts_deg.iter().map(|v| v[k]).sum::<f64>() / n);
    for c in &a.causes[1..] {
        assert_eq!(c.effect, "beacon_tilt", "{}", a.verdict);
        let z_t = z_of(c, "T_deg", m[0].hypot(m[1]));
        let z_az = z_of(c, "AZ_deg", m[1].atan2(m[0]).to_degrees());
        assert!(
            z_t.abs() < 3.0 && z_az.abs() < 3.0,
            "z {z_t:.2} {z_az:.2}: {}",
            a.verdict
        );
    }
}

/// A global near-field cause is not taken for the per-LED freedom that can mimic it LED by
/// LED (`led_tilt`, `led_position`): those must beat it by the plain BIC, every one of their
/// parameters charged (host/ANALYZE.md, per-LED causes).
fn no_per_led_cause(a: &Analysis) {
    assert!(
        !a.causes.iter().any(|c| c.effect.starts_with("led_")),
        "{}",
        a.verdict
    );
}

#[test]
fn face_angle() {
    let (a, _) = named_first("face_angle=1,-0.5", 16);
    no_per_led_cause(&a);
    near(&a, "DX", 1.0);
    near(&a, "DY", -0.5);
}

#[test]
fn saturation() {
    let (a, _) = named_first("saturation=0.08", 17);
    no_per_led_cause(&a);
    near(&a, "S", 0.08);
}

#[test]
fn plate_offset() {
    let (a, t) = named_first("plate_offset=0.05", 18);
    assert_eq!(near_per_separation(&a, &t).len(), 2 * SEPS.len());
}

/// The per-separation 1-sigma grows from 0.002 in at 2 in to 0.016 in at 30 in: a fixed
/// tolerance is too loose near and too tight far.
#[test]
fn separation_error() {
    let (a, t) = named_first("separation_error=0.05", 19);
    assert_eq!(near_per_separation(&a, &t).len(), SEPS.len());
}

/// The thesis levels the plates to 5 mils/ft (0.024 deg); uneven nuts on the rods tilt the
/// plate by tenths of a degree. 0.2 deg (1-sigma per axis and separation) is found, and
/// each separation's tilt recovered: not relative to a mean, since alone a common tilt shows
/// as the plate moved sideways in proportion to the separation.
#[test]
fn plate_tilt() {
    let (a, t) = named_first("plate_tilt=0.2", 23);
    assert_eq!(near_per_separation(&a, &t).len(), 2 * SEPS.len());
}

/// A tilted plate that also sits off its place: both named, and each effect's
/// per-separation values match the truth relative to their mean. Once `plate_offset` is in
/// the model its offsets absorb the sideways move a common tilt makes, so the tilts' mean is
/// held at zero (a head rotation takes it). Without that hold the two were nearly
/// degenerate: the head offset's 1-sigma grew 57-fold (7.2e-4 in with `plate_offset` alone
/// to 0.041 in) and the tilts' to 0.2 deg, their mean off by 0.1 deg. With it d1's 1-sigma
/// is 8.3e-3 in, still 11-fold: a separation's tilt and sideways move are told apart only by
/// the bend the tilt puts across the plate (host/ANALYZE.md), so the pair costs the head
/// offset precision honestly; the test holds it under 20-fold.
#[test]
fn plate_tilt_with_plate_offset() {
    let (a, t) = run(
        &sim(&["plate_offset=0.05", "plate_tilt=0.2"], 23),
        Base::Thesis,
    );
    let mut n = names(&a);
    n.sort_unstable();
    assert_eq!(n, ["plate_offset", "plate_tilt"], "{}", a.verdict);
    assert!(!a.unexplained && a.chi2_dof_after < 1.2, "{}", a.verdict);
    for i in 0..2 {
        assert_eq!(near_per_separation_of(&a, i, &t).len(), 2 * SEPS.len());
    }
    let (alone, _) = run(&sim(&["plate_offset=0.05"], 23), Base::Thesis);
    let sigma = |a: &Analysis, p: &str| {
        a.params_after
            .iter()
            .find(|q| q.name == p)
            .map(|q| q.sigma)
            .unwrap_or_else(|| panic!("no {p}"))
    };
    for p in ["d1", "d2", "p1", "p2"] {
        let (both, one) = (sigma(&a, p), sigma(&alone, p));
        assert!(
            both < 20.0 * one,
            "{p}: 1-sigma {both:.2e} with both, {one:.2e} with plate_offset alone"
        );
    }
}

/// Every vocabulary effect (but `intensity`, part of the `thesis` physics) hidden at random
/// sizes within a detectable range, on [`RANDOM_SEEDS`] seeded datasets each: named first and
/// alone, every parameter within [`K_SIGMA`] of the truth; and the reported 1-sigma are
/// honest: pooled over all of them, the RMS of `(estimate - truth) / sigma` is near 1 (a
/// 1-sigma twice the true one gives ~0.5, half of it ~2). The per-separation corrections
/// are pooled separately (26 or 13 per dataset, they would swamp the global parameters).
/// The sizes and seeds come from one seeded generator; each case is printed.
#[test]
fn every_effect_at_random_sizes() {
    let mut rng = StdRng::seed_from_u64(2024);
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let (mut z_global, mut z_local) = (Vec::new(), Vec::new());
    // `array_pose` needs the quad layout: its recovery is the unit test
    // `array_pose_is_named_and_each_array_recovered`.
    for name in VOCABULARY
        .iter()
        .copied()
        .filter(|n| *n != "intensity" && *n != "array_pose")
    {
        for _ in 0..RANDOM_SEEDS {
            let (s1, s2) = (sign(&mut rng), sign(&mut rng));
            let (u, v): (f64, f64) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
            // The effect and the truth of each reported parameter.
            let (spec, truth): (String, Vec<(&str, f64)>) = match name {
                "proximity" => {
                    let s = 0.175 + s1 * (0.02 + 0.04 * u);
                    (format!("proximity={s}"), vec![("S", s)])
                }
                "beacon_pattern" => {
                    let h = 40.0 + 15.0 * u;
                    (format!("beacon_pattern={h}"), vec![("H_deg", h)])
                }
                "beacon_tilt" => {
                    let (t, az) = (3.0 + 3.0 * u, 360.0 * v - 180.0);
                    (
                        format!("beacon_tilt={t},{az}"),
                        vec![("T_deg", t), ("AZ_deg", az)],
                    )
                }
                "cell_gain" => {
                    let (gx, gy) = (s1 * (0.01 + 0.03 * u), s2 * 0.02 * v);
                    (format!("cell_gain={gx},{gy}"), vec![("GX", gx), ("GY", gy)])
                }
                "cell_bias" => {
                    let (bx, by) = (s1 * (5e-6 + 1e-5 * u), s2 * 1e-5 * v);
                    (format!("cell_bias={bx},{by}"), vec![("BX", bx), ("BY", by)])
                }
                "ambient" => {
                    let b = 5e-6 + 1e-5 * u;
                    (format!("ambient={b}"), vec![("B", b)])
                }
                "face_angle" => {
                    let (dx, dy) = (s1 * (0.5 + u), s2 * 0.5 * v);
                    (
                        format!("face_angle={dx},{dy}"),
                        vec![("DX", dx), ("DY", dy)],
                    )
                }
                "saturation" => {
                    let l = 0.05 + 0.05 * u;
                    (format!("saturation={l}"), vec![("S", l)])
                }
                "plate_offset" => (format!("plate_offset={}", 0.03 + 0.05 * u), vec![]),
                "separation_error" => (format!("separation_error={}", 0.03 + 0.05 * u), vec![]),
                "plate_tilt" => (format!("plate_tilt={}", 0.1 + 0.2 * u), vec![]),
                "led_position" => (format!("led_position={}", 0.003 + 0.004 * u), vec![]),
                "led_tilt" => (format!("led_tilt={}", LED_TILT_DEG), vec![]),
                other => unreachable!("{other}"),
            };
            let seed = rng.random_range(1..1000);
            println!("{spec} seed {seed}");
            let (a, t) = named_first(&spec, seed);
            assert_eq!(a.causes.len(), 1, "{spec} seed {seed}: {:?}", names(&a));
            for (p, v) in truth {
                let z = if p == "AZ_deg" {
                    // The azimuth is reported in (-180, 180].
                    let c = &a.causes[0];
                    let d = (c.params[p] - v + 180.0).rem_euclid(360.0) - 180.0;
                    let z = d / c.sigma[p];
                    assert!(z.abs() <= K_SIGMA, "{spec} seed {seed}: AZ off by {d} deg");
                    z
                } else {
                    near(&a, p, v)
                };
                z_global.push(z);
            }
            if t.plate_offsets.iter().any(|o| o != &[0.0, 0.0])
                || t.separation_errors.iter().any(|e| *e != 0.0)
                || t.plate_tilts_deg.iter().any(|v| v != &[0.0, 0.0])
            {
                z_local.extend(near_per_separation(&a, &t));
            }
        }
    }
    let (rg, rl) = (rms(&z_global), rms(&z_local));
    println!(
        "RMS (estimate - truth) / 1-sigma: {rg:.2} over {} global parameters, {rl:.2} over {} \
         per-separation ones",
        z_global.len(),
        z_local.len()
    );
    // The RMS of n standard normals is 1 +/- 1/sqrt(2n): +/- 0.12 for the 33 global ones,
    // +/- 0.05 for the 195 per-separation ones; the band is 2.5 and 6 of those wide below.
    assert!(
        (0.7..=1.4).contains(&rg),
        "global RMS z {rg:.2}: {z_global:.2?}"
    );
    assert!((0.7..=1.4).contains(&rl), "per-separation RMS z {rl:.2}");
}

#[test]
fn two_effects_at_once() {
    let (a, _) = run(
        &sim(&["cell_gain=0.03,-0.02", "beacon_tilt=3,45"], 21),
        Base::Thesis,
    );
    let mut n = names(&a);
    n.sort_unstable();
    assert_eq!(n, ["beacon_tilt", "cell_gain"], "{}", a.verdict);
    assert!(!a.unexplained);
    assert!(a.causes.iter().all(|c| c.gain_rms_counts > 0.0));
}

/// Forward selection alone named `plate_offset` first here: its per-separation freedom
/// absorbs most of a cell-gain plus cell-bias error in round 1, and it stayed named (rms 0.005
/// in) after the true causes joined it, with their 1-sigma five times too large. The
/// backward step (host/ANALYZE.md, Method 4) drops it and searches again without it.
#[test]
fn a_cause_that_stood_in_for_others_is_dropped() {
    let (a, _) = run(
        &sim(&["cell_gain=0.03,-0.02", "cell_bias=1e-5,-1e-5"], 7),
        Base::Thesis,
    );
    assert_eq!(names(&a), ["cell_gain", "cell_bias"], "{}", a.verdict);
    assert!(!a.unexplained);
    // `led_position`'s per-LED freedom could stand in for them too, but it must beat
    // `plate_offset` by the plain BIC, its 196 parameters charged: it is not named.
    let d: Vec<&str> = a.dropped.iter().map(|d| d.effect.as_str()).collect();
    assert_eq!(d, ["plate_offset"]);
    assert!(a
        .dropped
        .iter()
        .all(|d| d.round == 1 && d.dbic_keep <= 10.0));
    let text = render_text(&a);
    assert!(
        text.contains("dropped: plate_offset: named in round 1"),
        "{text}"
    );
    // Reported with the ruled-out candidates, fitted on top of the final model.
    assert!(
        a.ruled_out
            .iter()
            .any(|r| r.effect == "plate_offset"
                && r.note.as_deref().unwrap_or("").contains("dropped")),
        "{text}"
    );
    near(&a, "GX", 0.03);
    // The angle columns compare the same points: near the rail the final model turns a few
    // counts into degrees where the starting model has no direction at all (3.3 deg at 2 in
    // when each column kept its own points).
    assert!(a.angle_left_out > 0, "{text}");
    assert!(
        a.angle_std_after_deg[0] < 0.1 * a.angle_std_before_deg[0],
        "{text}"
    );
}

#[test]
fn clean_data_names_nothing() {
    let (a, _) = run(&sim(&[], 22), Base::Thesis);
    assert!(
        a.causes.is_empty() && a.tentative.is_empty(),
        "{}",
        a.verdict
    );
    assert!(!a.unexplained);
    assert!(
        a.verdict.starts_with("no significant effect"),
        "{}",
        a.verdict
    );
    assert!((a.chi2_dof_before - 1.0).abs() < 0.1);
}

/// How tightly clean data rule every candidate out: each is tried on top of the starting
/// model and not accepted, and its estimate lies within 4 sigma of the value at which the
/// effect is absent (the 1-sigma are the GLSDC covariance's: if they were too small, or the
/// no-effect values wrong, e.g. S against 0 instead of 0.175 in, this fails).
#[test]
fn clean_data_rules_every_candidate_out() {
    let (a, _) = run(&sim(&[], 22), Base::Thesis);
    assert!(a.causes.is_empty(), "{}", a.verdict);
    let tried: Vec<&str> = a.ruled_out.iter().map(|r| r.effect.as_str()).collect();
    // `array_pose` needs several arrays: on one it is listed as not testable instead.
    let want: Vec<&str> = VOCABULARY
        .iter()
        .copied()
        .filter(|n| *n != "intensity" && *n != "array_pose")
        .collect();
    assert_eq!(tried, want, "{:?}", a.ruled_out_note);
    assert!(a.untested.iter().any(|u| u.effect == "array_pose"));
    for r in &a.ruled_out {
        assert!(r.dbic <= 10.0, "{}: dBIC {}", r.effect, r.dbic);
        if r.effect == "saturation" {
            // No finite no-effect value: on clean data no clipping level of the scan (which
            // starts at the median predicted peak signal) fits better than none, so it is not
            // fitted at all, and says why.
            assert!(
                !r.fitted
                    && r.params.is_empty()
                    && r.note.as_deref().is_some_and(|n| n.contains(
                        "no scanned clipping level (each clips >= 0.5 % of the points) fits \
                         better than none"
                    )),
                "{r:?}"
            );
            continue;
        }
        assert!(r.fitted && r.note.is_none(), "{}: {:?}", r.effect, r.note);
        assert!(
            !r.params.is_empty() || !r.per_separation.is_empty(),
            "{}: no estimates",
            r.effect
        );
        for p in &r.params {
            let null = p.no_effect.expect("a no-effect value");
            assert!(p.sigma > 0.0 && p.sigma.is_finite(), "{}: {p:?}", r.effect);
            assert!(
                (p.value - null).abs() <= 4.0 * p.sigma,
                "{}: {} = {} +/- {}, no effect at {null}",
                r.effect,
                p.name,
                p.value,
                p.sigma
            );
        }
        for sp in &r.per_separation {
            // Mean square of 13 estimates against its noise-only expectation: a chi-square
            // of ~12 degrees of freedom over 12; 4 is far in its tail.
            // The per-LED candidates' values are per LED (100), the others per separation.
            let n = if r.effect.starts_with("led_") {
                100
            } else {
                SEPS.len()
            };
            assert!(
                sp.separations == n && sp.rms <= 2.0 * sp.noise_rms,
                "{}: {sp:?}",
                r.effect
            );
        }
    }
    let by = |e: &str| a.ruled_out.iter().find(|r| r.effect == e).unwrap();
    assert_eq!(by("proximity").params[0].no_effect, Some(0.175));
    assert_eq!(by("beacon_pattern").params[0].name, "H_deg");
    assert_eq!(by("beacon_pattern").params[0].no_effect, Some(60.0));
    let text = render_text(&a);
    assert!(
        text.contains("not named (tried on top of the final model"),
        "{text}"
    );
    assert!(
        text.contains("  cell_bias: BX = ")
            && text.contains("  plate_offset: per separation (13): x weighted RMS "),
        "{text}"
    );
    // Every trial keeps its estimates (in JSON too).
    assert!(a
        .trials
        .iter()
        .all(|t| !t.fitted || !t.params.is_empty() || t.effect == "intensity"));
}

/// The default-run share of `detection_limits`' calibration (tests/tests/detection_limits.rs,
/// 200 seeds, ignored): on [`CLEAN_SEEDS`] clean datasets every candidate's estimate of the
/// effect, `z = (estimate - no-effect value) / 1-sigma`, pooled over the candidates' global
/// parameters, has an RMS near 1. The ruled-out intervals the report prints ("the data allow
/// about estimate +/- 2 sigma") are only honest if it does.
#[test]
fn ruled_out_one_sigma_is_honest_on_clean_data() {
    let mut z: Vec<f64> = Vec::new();
    for seed in CLEAN_SEEDS {
        let (a, _) = run(&sim(&[], seed), Base::Thesis);
        assert!(a.causes.is_empty(), "seed {seed}: {}", a.verdict);
        for r in &a.ruled_out {
            for p in &r.params {
                if let Some(null) = p.no_effect {
                    z.push((p.value - null) / p.sigma);
                }
            }
        }
    }
    let n = CLEAN_SEEDS.count();
    // proximity S, beacon_pattern H, ambient B, and two each of beacon_tilt, cell_gain,
    // cell_bias, face_angle.
    assert_eq!(z.len(), 11 * n);
    let r = rms(&z);
    println!(
        "ruled-out RMS z over {} estimates, {n} seeds: {r:.2}",
        z.len()
    );
    // ANALYZE.md's 200 seeds give 0.88-1.07 per parameter (slightly conservative). The
    // candidates' estimates on one dataset are correlated (face_angle and cell_gain absorb
    // the same noise), so the 330 values count for fewer: seeds 500-559 gave 0.77 over the
    // first 15 and 0.88 over all 60. The band leaves room for that and still fails a 1-sigma
    // twice too large (~0.45) or half the true one (~1.8).
    assert!((0.6..=1.6).contains(&r), "RMS z {r:.2}: {z:.2?}");
}

/// An effect too small to be named on this seed is not named, and the ruled-out interval
/// (estimate +/- 3 sigma) contains its true size: the report's "the data allow about
/// estimate +/- 2 sigma" is honest. cell_gain (GX, GY) and beacon_tilt (tx, ty) are fitted
/// in the simulator's own parameters, so the truth compares directly.
#[test]
fn sub_threshold_effect_lies_in_the_ruled_out_interval() {
    let cases = [
        (
            "cell_gain=1.5e-4,-1e-4",
            31,
            [("GX", 1.5e-4), ("GY", -1e-4)],
        ),
        (
            "beacon_tilt=0.3,45",
            32,
            [
                ("tx_deg", 0.3 * FRAC_1_SQRT_2),
                ("ty_deg", 0.3 * FRAC_1_SQRT_2),
            ],
        ),
    ];
    for (spec, seed, truth) in cases {
        let (a, _) = run(&sim(&[spec], seed), Base::Thesis);
        assert!(a.causes.is_empty(), "{spec}: named {:?}", names(&a));
        let name = spec.split('=').next().unwrap();
        let r = a
            .ruled_out
            .iter()
            .find(|r| r.effect == name)
            .unwrap_or_else(|| panic!("{spec}: not among the candidates not named"));
        for (p, t) in truth {
            let e = r.params.iter().find(|q| q.name == p).unwrap();
            println!(
                "{spec} seed {seed}: {p} = {} +/- {}, truth {t}",
                e.value, e.sigma
            );
            assert!(
                (e.value - t).abs() <= 3.0 * e.sigma,
                "{spec}: {p} = {} +/- {}, truth {t}",
                e.value,
                e.sigma
            );
            // And the effect is really below what can be named: within ~5 sigma of zero.
            assert!(
                t.abs() < 5.0 * e.sigma,
                "{spec}: {p} {t} vs sigma {}",
                e.sigma
            );
        }
    }
}

/// Cross-talk between the pairs is outside the vocabulary: it must be reported as
/// unexplained structure, with no confident false name.
#[test]
fn crosstalk_is_unexplained() {
    let (a, _) = run(&sim(&["crosstalk=0.03"], 23), Base::Thesis);
    assert!(a.unexplained, "{}", a.verdict);
    assert!(a.causes.is_empty(), "false name: {:?}", names(&a));
    assert!(a.verdict.contains("unexplained structure remains"));
    assert!(!a.structure.is_empty(), "no indication of where");
}

/// From the 7-parameter pinhole model on thesis-physics data: proximity and intensity are
/// found and the virtual eye is gone (d3 within 0.001 in of the truth, REFERENCE.md
/// "beyond the thesis").
#[test]
fn from_pinhole_finds_the_near_field() {
    let cfg = SimConfig {
        separations: (2..=30).map(f64::from).collect(),
        noise: NOISE,
        samples: 200,
        seed: 24,
        ..Default::default()
    };
    let (a, t) = run(&cfg, Base::Pinhole);
    let n = names(&a);
    assert!(
        n.contains(&"proximity") && n.contains(&"intensity"),
        "{}",
        a.verdict
    );
    assert!(!a.unexplained);
    let d3_before = a
        .params_before
        .iter()
        .find(|p| p.name == "d3")
        .unwrap()
        .value;
    let d3 = a
        .params_after
        .iter()
        .find(|p| p.name == "d3")
        .unwrap()
        .value;
    // Weighted over 2-30 in the pinhole's virtual eye sits ~0.1 in off (more for far pairs
    // alone, REFERENCE.md Table 3).
    assert!(
        (d3_before - t.d[2]).abs() > 0.05,
        "pinhole d3 {d3_before}: where is the virtual eye?"
    );
    assert!((d3 - t.d[2]).abs() < 0.001, "d3 {d3} vs truth {}", t.d[2]);
}

#[test]
fn one_separation_is_refused_with_reason() {
    let mut cfg = sim(&["cell_gain=0.03,0"], 25);
    cfg.separations = vec![10.0];
    let (ds, _) = cfg.run();
    let e = analyze(&ds, &Options::default(), &Silent)
        .unwrap_err()
        .to_string();
    assert!(e.contains("at least 2 separations"), "{e}");
    assert!(e.contains("No candidate could be tested"), "{e}");
}

#[test]
fn two_separations_cannot_test_per_separation_effects() {
    let mut cfg = sim(&["face_angle=1,0"], 26);
    cfg.separations = vec![5.0, 20.0];
    let (ds, _) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    for e in ["plate_offset", "separation_error"] {
        let u = a.untested.iter().find(|u| u.effect == e).unwrap();
        assert!(u.reason.contains("at least 3 separations"), "{}", u.reason);
    }
    assert_eq!(names(&a), ["face_angle"], "{}", a.verdict);
}

/// A 2 x 2 grid cannot constrain everything: whatever cannot be tested is listed with a
/// reason, and nothing is named on clean data.
#[test]
fn tiny_grid_names_nothing_false() {
    let mut cfg = sim(&[], 27);
    cfg.grid = (2, 2);
    let (ds, _) = cfg.run();
    let a = analyze(&ds, &Options::default(), &Silent).unwrap();
    assert!(a.causes.is_empty(), "{}", a.verdict);
    // 4 points per separation: the per-separation corrections are listed as untested, each
    // with the reason.
    let u: Vec<(&str, &str)> = a
        .untested
        .iter()
        .map(|u| (u.effect.as_str(), u.reason.as_str()))
        .collect();
    assert_eq!(
        u.iter().map(|u| u.0).collect::<Vec<_>>(),
        [
            "plate_offset",
            "separation_error",
            "plate_tilt",
            "array_pose"
        ],
        "{u:?}"
    );
    // One array: `array_pose` cannot be told from the head pose.
    assert!(u[3].1.contains("one array"), "{u:?}");
    for (e, reason) in u.into_iter().take(3) {
        assert!(
            reason.contains("a separation has only 4 usable points: too few to estimate"),
            "{e}: {reason}"
        );
    }
    // Untested means not tried: neither fitted in any round nor shown as ruled out.
    for name in ["plate_offset", "separation_error"] {
        assert!(!a.trials.iter().any(|t| t.effect == name), "{name} tried");
        assert!(
            !a.ruled_out.iter().any(|r| r.effect == name),
            "{name} ruled out"
        );
    }
}

/// The detection table of host/ANALYZE.md: every effect at a moderate size on 5 seeds, which
/// effect is named first. Slow in debug; run it in release:
/// `cargo test --release -p cta-tests --test hidden_effects -- --ignored --nocapture detection_table`
#[test]
#[ignore]
fn detection_table() {
    let cases = [
        "proximity=0.21",
        "beacon_pattern=45",
        "beacon_tilt=3,45",
        "cell_gain=0.03,-0.02",
        "cell_bias=1e-5,-1e-5",
        "face_angle=1,-0.5",
        "saturation=0.08",
        "plate_offset=0.05",
        "separation_error=0.05",
        "plate_tilt=0.2",
        "crosstalk=0.03",
    ];
    let mut failures = 0;
    println!("| hidden effect | seed | named first | all named | chi2/dof before -> after | held-out RMS before -> after |");
    println!("|---|---|---|---|---|---|");
    for spec in cases {
        for seed in 100..105 {
            let (a, _) = run(&sim(&[spec], seed), Base::Thesis);
            let first = a
                .causes
                .first()
                .map(|c| c.effect.clone())
                .unwrap_or_else(|| {
                    if a.unexplained {
                        "(unexplained)".into()
                    } else {
                        "(none)".into()
                    }
                });
            let want = spec.split('=').next().unwrap();
            let ok = if want == "crosstalk" {
                a.unexplained && a.causes.is_empty()
            } else {
                first == want
            };
            failures += usize::from(!ok);
            println!(
                "| {spec} | {seed} | {first}{} | {} | {:.2} -> {:.2} | {:.1} -> {:.1} |",
                if ok { "" } else { " **wrong**" },
                names(&a).join(", "),
                a.chi2_dof_before,
                a.chi2_dof_after,
                a.rms_before,
                a.rms_after
            );
        }
    }
    assert_eq!(failures, 0);
}

/// A small proximity shift (S = 0.1772 in, 1/16 of the detection table's) is fitted by
/// `beacon_pattern` about as well (dBIC within 2 on five seeds): the named cause says so.
/// At the table's size the two are told apart (dBIC over 100 apart) and no rival is reported.
#[test]
fn a_near_degenerate_rival_is_reported() {
    let (a, _) = run(&sim(&["proximity=0.1772"], 300), Base::Thesis);
    let c = &a.causes[0];
    let rivals: Vec<&str> = c.rivals.iter().map(|r| r.effect.as_str()).collect();
    assert!(
        ["proximity", "beacon_pattern"].contains(&c.effect.as_str()),
        "{}",
        c.effect
    );
    let other = if c.effect == "proximity" {
        "beacon_pattern"
    } else {
        "proximity"
    };
    assert!(rivals.contains(&other), "{} rivals {rivals:?}", c.effect);
    assert!(render_text(&a).contains("explains the data about as well"));
    let (a, _) = named_first("proximity=0.21", 300);
    assert!(a.causes[0].rivals.is_empty(), "{:?}", a.causes[0].rivals);
}

/// Parameter `p` of the named cause `effect` is within 4 sigma (or `tol`) of `truth`.
fn near_cause(a: &Analysis, effect: &str, p: &str, truth: f64, tol: f64) {
    let c = a
        .causes
        .iter()
        .find(|c| c.effect == effect)
        .unwrap_or_else(|| panic!("{effect} not named"));
    let (v, s) = (c.params[p], c.sigma.get(p).copied().unwrap_or(0.0));
    assert!(
        (v - truth).abs() <= (4.0 * s).max(tol),
        "{effect}: {p} = {v} +/- {s}, truth {truth}"
    );
}

/// Saturation that only the nearest separation reaches: the fold that holds 2 in out has no
/// clipped point to train `saturation.lnS` on. That fold's training fit used to be singular
/// for every candidate after saturation was named (each "ruled out" by a failed
/// cross-validation, the verdict "unexplained"), and predicted 2 in without saturation, so
/// saturation's own held-out RMS stayed at ~204 counts. The level is now estimated from the
/// held-out data in that fold (host/ANALYZE.md, Method 4).
#[test]
fn saturation_and_a_second_effect_are_both_named() {
    for (second, seed) in [("cell_gain=0.01,-0.01", 21), ("beacon_tilt=2,0", 21)] {
        let sat = if second.starts_with("cell_gain") {
            "saturation=0.12"
        } else {
            "saturation=0.16"
        };
        let (a, _) = run(&sim(&[sat, second], seed), Base::Thesis);
        let mut n = names(&a);
        n.sort_unstable();
        let other = second.split('=').next().unwrap();
        let mut want = ["saturation", other];
        want.sort_unstable();
        assert_eq!(n, want, "{second}: {}", a.verdict);
        assert!(!a.unexplained && a.chi2_dof_after < 1.2, "{}", a.verdict);
        assert!(a.causes.iter().all(|c| c.gain_rms_counts > 0.0));
        // Held-out RMS near the noise of a 4-sample mean (16.4 counts).
        assert!(a.rms_after < 20.0, "held-out RMS {}", a.rms_after);
        if other == "cell_gain" {
            near_cause(&a, "saturation", "S", 0.12, 0.0);
            near_cause(&a, "cell_gain", "GX", 0.01, 0.0);
            near_cause(&a, "cell_gain", "GY", -0.01, 0.0);
        } else {
            near_cause(&a, "saturation", "S", 0.16, 0.0);
            near_cause(&a, "beacon_tilt", "T_deg", 2.0, 0.0);
            near_cause(&a, "beacon_tilt", "AZ_deg", 0.0, 0.0);
        }
    }
    // Saturation alone: its own held-out gain reaches the noise (was 205.1 -> 204.2 counts).
    let (a, _) = named_first("saturation=0.16", 21);
    assert!(
        a.causes[0].heldout_rms_after < 20.0,
        "held-out RMS with saturation {}",
        a.causes[0].heldout_rms_after
    );
}
