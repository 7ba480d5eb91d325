//! Detection limits and false-alarm rate of `cta analyze` (host/ANALYZE.md, "Detection
//! limits"), measured on the detection table's setup: thesis physics, the CTA 10 x 10 grid at
//! 1 in pitch, separations 2, 3, 4, 5, 6, 8, 10, 12, 15, 18, 21, 25, 30 in, 4 samples per
//! point, noise 32.8 counts (0.1 % of beta), analysis from `thesis` with the default options.
//!
//! 1. Clean data, 200 seeds (400-599; a clean analysis is cheap, ~0.05 s, so more than the
//!    ladder's 10 per rung): how often anything is named (a false alarm), how often the
//!    verdict is "unexplained"; and the calibration of the ruled-out 1-sigma: for every
//!    candidate parameter, `z = (estimate - no-effect value) / sigma` over the seeds must have
//!    an RMS near 1 (the per-separation effects: the square of the weighted RMS of the
//!    per-separation estimates over its noise-only value, near 1 on average). The median
//!    1-sigma is the "ruled-out bound" the ladder is compared with.
//! 2. Every vocabulary effect but `intensity` (part of the `thesis` model, nothing to inject)
//!    on a ladder of sizes, 10 seeds each (300-309): the detection table's size times 1, 1/2,
//!    ..., 1/256 (the deviation from the thesis physics is scaled: `proximity` S - 0.175,
//!    `beacon_pattern` H - 60 deg, the rest from 0); `saturation`, whose size is a level, from
//!    0.245 (above the brightest usable signal, 0.239 at 2 in) down to the table's 0.08 in
//!    steps of 1.15. For each: how often the effect is named first, named at all, and how
//!    often something else is named instead.
//!
//! Slow (about 1,000 analyses, 1.5-2.5 min on 2 cores); run it in release:
//! `cargo test --release -p cta-tests --test detection_limits -- --ignored --nocapture detection_limits`

use cta_lab::analyze::{analyze, Analysis, Options};
use cta_lab::progress::Silent;
use cta_lab::sim::effects::Effect;
use cta_lab::sim::SimConfig;
use std::collections::BTreeMap;
use std::time::Instant;

const SEPS: [f64; 13] = [
    2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0, 18.0, 21.0, 25.0, 30.0,
];
const NOISE: f64 = 32.768;
const CLEAN_SEEDS: std::ops::Range<u64> = 400..600;
const LADDER_SEEDS: std::ops::Range<u64> = 300..310;
/// Fractions of the detection table's size.
const RUNGS: [f64; 9] = [
    1.0 / 256.0,
    1.0 / 128.0,
    1.0 / 64.0,
    1.0 / 32.0,
    1.0 / 16.0,
    1.0 / 8.0,
    1.0 / 4.0,
    1.0 / 2.0,
    1.0,
];

fn analyze_sim(effects: Vec<Effect>, seed: u64) -> Analysis {
    let cfg = SimConfig {
        separations: SEPS.to_vec(),
        effects,
        noise: NOISE,
        samples: 4,
        seed,
        ..Default::default()
    };
    let (ds, _) = cfg.run();
    analyze(&ds, &Options::default(), &Silent).unwrap_or_else(|e| panic!("analyze failed: {e}"))
}

/// The ladder of one effect: (effect at each rung, the rung's size in the effect's fitted
/// parameters as deviations from no effect, for the size/sigma column), the table size last.
fn ladder(name: &str) -> Vec<(Effect, Vec<f64>)> {
    let scaled = |f: f64| -> (Effect, Vec<f64>) {
        match name {
            "proximity" => (Effect::Proximity(0.175 + 0.035 * f), vec![0.035 * f]),
            "beacon_pattern" => (Effect::BeaconPattern(60.0 - 15.0 * f), vec![-15.0 * f]),
            "beacon_tilt" => {
                let t = 3.0 * f;
                let c = t * std::f64::consts::FRAC_1_SQRT_2;
                (Effect::BeaconTilt(t, 45.0), vec![c, c])
            }
            "cell_gain" => (
                Effect::CellGain(0.03 * f, -0.02 * f),
                vec![0.03 * f, -0.02 * f],
            ),
            "cell_bias" => (
                Effect::CellBias(1e-5 * f, -1e-5 * f),
                vec![1e-5 * f, -1e-5 * f],
            ),
            "ambient" => (Effect::Ambient(1e-5 * f), vec![1e-5 * f]),
            "face_angle" => (Effect::FaceAngle(f, -0.5 * f), vec![f, -0.5 * f]),
            "plate_offset" => (Effect::PlateOffset(0.05 * f), vec![0.05 * f]),
            "separation_error" => (Effect::SeparationError(0.05 * f), vec![0.05 * f]),
            "plate_tilt" => (Effect::PlateTilt(0.2 * f), vec![0.2 * f]),
            "led_position" => (Effect::LedPosition(0.004 * f), vec![0.004 * f]),
            "led_tilt" => (Effect::LedTilt(3.0 * f), vec![3.0 * f]),
            other => unreachable!("{other}"),
        }
    };
    if name == "saturation" {
        (0..9)
            .rev()
            .map(|k| (Effect::Saturation(0.08 * 1.15f64.powi(k)), vec![]))
            .collect()
    } else {
        RUNGS.iter().map(|&f| scaled(f)).collect()
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
#[ignore]
fn detection_limits() {
    let t0 = Instant::now();
    // 1. Clean data.
    let mut named = 0;
    let mut unexplained = 0;
    let mut named_what: BTreeMap<String, usize> = BTreeMap::new();
    let mut chi2_dof: Vec<f64> = Vec::new();
    // (effect, parameter) -> z values and sigmas; per-separation mean-square ratios.
    let mut z: BTreeMap<(String, String), (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    let mut ratio2: BTreeMap<(String, String), (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for seed in CLEAN_SEEDS {
        let a = analyze_sim(vec![], seed);
        if !a.causes.is_empty() || !a.tentative.is_empty() {
            named += 1;
            for c in a.causes.iter().chain(&a.tentative) {
                *named_what.entry(c.effect.clone()).or_default() += 1;
            }
        }
        unexplained += usize::from(a.unexplained);
        chi2_dof.push(a.chi2_dof_before);
        for r in &a.ruled_out {
            for p in &r.params {
                if let Some(n) = p.no_effect {
                    let e = z.entry((r.effect.clone(), p.name.clone())).or_default();
                    e.0.push((p.value - n) / p.sigma);
                    e.1.push(p.sigma);
                }
            }
            for sp in &r.per_separation {
                let e = ratio2
                    .entry((r.effect.clone(), sp.name.clone()))
                    .or_default();
                e.0.push((sp.rms / sp.noise_rms).powi(2));
                e.1.push(sp.noise_rms);
            }
        }
    }
    let nclean = CLEAN_SEEDS.count();
    let mean_chi2 = chi2_dof.iter().sum::<f64>() / nclean as f64;
    let max_chi2 = chi2_dof.iter().fold(0.0f64, |m, &v| m.max(v));
    println!(
        "clean data, {nclean} seeds: something named in {named} ({named_what:?}), unexplained in \
         {unexplained}; chi2/dof of the starting model mean {mean_chi2:.3}, max {max_chi2:.3} \
         ({:.0} s)",
        t0.elapsed().as_secs_f64()
    );
    println!("\nruled-out calibration on clean data (z = (estimate - no effect) / 1-sigma):");
    println!("| candidate | parameter | median 1-sigma | mean z | RMS z | max abs z | corr with previous |");
    println!("|---|---|---|---|---|---|---|");
    let mut sigma_of: BTreeMap<(String, String), f64> = BTreeMap::new();
    let mut bad_calibration = Vec::new();
    let mut prev: Option<(&String, &Vec<f64>)> = None;
    for ((e, p), (zs, ss)) in &z {
        let n = zs.len() as f64;
        let mean = zs.iter().sum::<f64>() / n;
        let rms = (zs.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let max = zs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let med = median(&mut ss.clone());
        sigma_of.insert((e.clone(), p.clone()), med);
        // The estimates of a two-parameter candidate are correlated: the sample correlation
        // of their z over the seeds.
        let corr = match prev {
            Some((pe, pz)) if pe == e && pz.len() == zs.len() => {
                let c = zs.iter().zip(pz).map(|(a, b)| a * b).sum::<f64>() / n;
                let pr = (pz.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
                format!("{:+.2}", c / (rms * pr))
            }
            _ => String::new(),
        };
        prev = Some((e, zs));
        println!("| {e} | {p} | {med:.2e} | {mean:+.2} | {rms:.2} | {max:.1} | {corr} |");
        // 200 seeds: the RMS of 200 standard normals is 1 +/- 0.05.
        if !(0.8..=1.25).contains(&rms) || zs.len() < nclean {
            bad_calibration.push(format!("{e} {p}: RMS z {rms:.2} over {} seeds", zs.len()));
        }
    }
    println!(
        "\n| candidate | per-separation | median noise-only weighted RMS (in; deg for plate_tilt) | mean (weighted RMS / noise-only)^2 |"
    );
    println!("|---|---|---|---|");
    for ((e, p), (rs, ss)) in &ratio2 {
        let mean = rs.iter().sum::<f64>() / rs.len() as f64;
        let med = median(&mut ss.clone());
        sigma_of.insert((e.clone(), p.clone()), med);
        println!("| {e} | {p} | {med:.2e} | {mean:.2} |");
        // ~12 degrees of freedom per seed, 200 seeds: 1 +/- 0.03.
        if !(0.8..=1.25).contains(&mean) || rs.len() < nclean {
            bad_calibration.push(format!("{e} {p}: mean square ratio {mean:.2}"));
        }
    }
    // The fitted parameters each effect's ladder is expressed in, for size / 1-sigma.
    let params_of = |e: &str| -> Vec<&str> {
        match e {
            "proximity" => vec!["S"],
            "beacon_pattern" => vec!["H_deg"],
            "beacon_tilt" => vec!["tx_deg", "ty_deg"],
            "cell_gain" => vec!["GX", "GY"],
            "cell_bias" => vec!["BX", "BY"],
            "ambient" => vec!["B"],
            "face_angle" => vec!["DX", "DY"],
            "plate_offset" => vec!["x"],
            "separation_error" => vec!["z"],
            "plate_tilt" => vec!["tx_deg"],
            _ => vec![],
        }
    };

    // 2. The ladders.
    println!("\n| hidden effect | size / clean 1-sigma | named first | named | other named instead | unexplained |");
    println!("|---|---|---|---|---|---|");
    let nseed = LADDER_SEEDS.count();
    let mut weak_at_table_size = Vec::new();
    let mut smallest: Vec<(String, String)> = Vec::new();
    // The compact matrix: per effect, per rung, "named (other named instead) u(nexplained)".
    let mut matrix: Vec<(String, Vec<String>)> = Vec::new();
    // Every effect `analyze` can name; `intensity` is a switch of the pinhole start only, and
    // `array_pose` needs the quad layout (its ladder is in host/ANALYZE.md, Detection limits).
    for name in cta_lab::sim::effects::VOCABULARY
        .into_iter()
        .filter(|n| *n != "intensity" && *n != "array_pose")
    {
        let rungs = ladder(name);
        let mut reliable: Option<String> = None;
        let mut cells = Vec::new();
        for (k, (effect, dev)) in rungs.iter().enumerate() {
            let (mut first, mut any, mut other, mut unexp) = (0, 0, 0, 0);
            let mut others: BTreeMap<String, usize> = BTreeMap::new();
            for seed in LADDER_SEEDS {
                let a = analyze_sim(vec![*effect], seed);
                let n: Vec<&str> = a.causes.iter().map(|c| c.effect.as_str()).collect();
                first += usize::from(n.first() == Some(&name));
                any += usize::from(n.contains(&name));
                if !n.contains(&name) && !n.is_empty() {
                    other += 1;
                    for o in n {
                        *others.entry(o.to_string()).or_default() += 1;
                    }
                }
                unexp += usize::from(a.unexplained);
            }
            // Size over the clean-data 1-sigma of each fitted parameter (marginal; for
            // per-separation effects the scatter D over the noise-only weighted RMS).
            let snr = {
                let ps = params_of(name);
                if ps.is_empty() {
                    "-".to_string()
                } else {
                    ps.iter()
                        .zip(dev)
                        .map(|(p, d)| {
                            let sg = sigma_of[&(name.to_string(), p.to_string())];
                            format!("{:.1}", (d / sg).abs())
                        })
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            };
            let other_s = if others.is_empty() {
                format!("{other}/{nseed}")
            } else {
                format!("{other}/{nseed} {others:?}")
            };
            println!(
                "| {effect} | {snr} | {first}/{nseed} | {any}/{nseed} | {other_s} | {unexp}/{nseed} |"
            );
            let mut cell = format!("{any}");
            if other > 0 {
                cell += &format!(" ({other})");
            }
            if unexp > 0 {
                cell += &format!(" u{unexp}");
            }
            cells.push(cell);
            if any >= nseed - 1 {
                reliable.get_or_insert(format!("{effect} ({snr} sigma)"));
            } else {
                reliable = None;
            }
            if k == rungs.len() - 1 && first < nseed - 1 {
                weak_at_table_size.push(format!("{effect}: named first {first}/{nseed}"));
            }
        }
        smallest.push((name.to_string(), reliable.unwrap_or_else(|| "none".into())));
        let table = format!("{}", rungs.last().expect("rungs").0);
        matrix.push((table, cells));
    }
    println!(
        "\nnamed in {nseed} seeds at each fraction of the table size; (k): something else named \
         instead in k; uk: unexplained in k"
    );
    println!("| table size | 1/256 | 1/128 | 1/64 | 1/32 | 1/16 | 1/8 | 1/4 | 1/2 | 1 |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (t, cells) in &matrix {
        if t.starts_with("saturation") {
            continue;
        }
        println!("| {t} | {} |", cells.join(" | "));
    }
    let sat = ladder("saturation");
    println!(
        "| saturation level | {} |",
        sat.iter()
            .map(|(e, _)| match e {
                Effect::Saturation(v) => format!("{v:.3}"),
                _ => unreachable!(),
            })
            .collect::<Vec<_>>()
            .join(" | ")
    );
    if let Some((_, cells)) = matrix.iter().find(|(t, _)| t.starts_with("saturation")) {
        println!("| saturation | {} |", cells.join(" | "));
    }
    println!("\nsmallest size named in >= 9/10 seeds (and at every larger rung):");
    for (n, s) in &smallest {
        println!("  {n}: {s}");
    }
    println!("\ntotal {:.0} s", t0.elapsed().as_secs_f64());
    // False alarms: with dBIC > 10 (k >= 1 added parameters, m ~ 2500 residuals) a candidate
    // needs dchi2 > 17.8 on clean data, P < 2.5e-5 for one parameter (chi-square, 1 dof),
    // ~3e-6 for two, and the cross-validation must also agree: the expected false-alarm rate
    // over 8 candidates is ~1e-4 per dataset, 0.02 in 200. At most 2 in 200 (1 %) leaves room
    // for the model's approximations (finite-difference fits, rounding to counts) while a
    // real rate of 5 % (10 expected) would fail with probability > 0.99.
    assert!(named <= 2, "{named}/{nclean} clean datasets name something");
    // chi2/dof > 1.2 with ~2500 degrees of freedom is a 7-sigma excursion.
    assert_eq!(unexplained, 0, "clean data reported as unexplained");
    assert!(bad_calibration.is_empty(), "{bad_calibration:?}");
    assert!(
        weak_at_table_size.is_empty(),
        "not named first in >= 9/10 seeds at the detection-table size: {weak_at_table_size:?}"
    );
}
