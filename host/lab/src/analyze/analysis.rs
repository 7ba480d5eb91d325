//! The analysis: the starting model, forward selection over the candidates, and what the
//! result says (named causes, ruled-out candidates, notes on the data).

use std::sync::atomic::{AtomicU64, Ordering};

use super::corners::place_by_corners;
use super::data::{self, Data, Weights};
use super::model::{Cand, FitResult, Model};
use super::params::{cause_params, cross_correlations, params_of, spreads, trial_params};
use super::result::{
    Analysis, Cause, Detail, DroppedOut, Rival, RuledOut, TrialOut, Untested, RIVAL_DBIC,
};
use super::{diag, select, Error, Options};
use crate::data::Dataset;
use crate::fit::wiring;
use crate::progress::Progress;

/// Chi-square per degree of freedom above which the final model is said to leave
/// unexplained structure (and no cause is named with confidence).
pub const UNEXPLAINED_CHI2_DOF: f64 = 1.2;

/// Fewest usable points at every separation for the per-separation corrections
/// (`plate_offset`, `separation_error`, `plate_tilt`) to be tried.
pub const MIN_POINTS_PER_SEPARATION: usize = 8;

/// A starting-model chi2/dof below this says the noise the fits weight by is far larger than
/// the residuals (with hundreds of degrees of freedom chi2/dof scatters by ~0.05 around 1).
pub const NOISE_TOO_LARGE_CHI2_DOF: f64 = 0.5;

/// What the sensor board's pose solver can do with a named effect: whether its calibration
/// (`cta calibrate`, firmware-sensor) or its constellation holds it, or it stays outside the
/// chip's model (host/CALIBRATE.md).
pub fn board_note(effect: &str) -> String {
    match effect {
        "cell_gain" => "the board's calibration holds it (gx, gy): `cta calibrate` fits it",
        "cell_bias" => "the board's calibration holds it (bx, by): `cta calibrate` fits it",
        "ambient" => {
            "outside the board's calibration (its biases bx, by are on cells 1 and 3 alone): \
             light common to all four cells compresses the outputs where the spot is weak; \
             shade the CTA from room light, or measure the cells' dark signal and subtract it"
        }
        "face_angle" => {
            "the board's calibration holds it (the pairs' face angles a, ay): `cta calibrate` \
             fits it"
        }
        "proximity" => {
            "the board's calibration holds it (the cell offset s): `cta calibrate` fits it"
        }
        "intensity" => "the board's near-field model includes it (eq 63's inverse square)",
        "beacon_pattern" => {
            "the board's calibration holds the LEDs' pattern exponent, but `cta calibrate` \
             cannot tell it from s and d3: give `--pattern-m` from the LED datasheet \
             (host/CALIBRATE.md)"
        }
        "beacon_tilt" => {
            "the board holds it in the constellation's LED boresight (`cta sensor template \
             constellation`), not in the calibration"
        }
        "saturation" => {
            "outside the board's model: its poses use saturated spots as they are; keep the \
             beacons outside the range where the cells clip"
        }
        "led_tilt" => {
            "the board's constellation holds one LED boresight for all (`cta sensor template \
             constellation`): a tilt per LED stays outside its model"
        }
        "array_pose" => {
            "the board holds each LED's place in its constellation (`cta sensor template \
             constellation`): give it each array's LEDs where the array's pose puts them"
        }
        "led_position" => {
            "the board holds each LED's place in its constellation (`cta sensor template \
             constellation`): give it the measured places, not the nominal grid"
        }
        "plate_offset" | "separation_error" | "plate_tilt" => {
            "an error of the apparatus, not of the sensor: nothing for the board to hold; the \
             sensor's calibration from these data absorbs part of it"
        }
        _ => "outside the board's model",
    }
    .to_string()
}

/// The rivals of the cause `cand` accepted in `round` with BIC improvement `dbic`: the other
/// candidates of that round significant on their own (`dBIC > 10`) whose improvement is
/// within [`RIVAL_DBIC`] of it, above or below. (One far above it fits the data better but was
/// not accepted, having failed to predict the held-out separations: not a tie.)
pub(super) fn rivals(trials: &[select::Trial], round: usize, cand: Cand, dbic: f64) -> Vec<Rival> {
    trials
        .iter()
        .filter(|t| {
            t.round == round
                && t.cand != cand
                && t.dbic > 10.0
                && (t.dbic - dbic).abs() < RIVAL_DBIC
        })
        .map(|t| Rival {
            effect: t.cand.name().into(),
            dbic: t.dbic,
        })
        .collect()
}

/// The candidates of the last round (tried on top of the final model) that were not
/// accepted, or why there are none.
pub(super) fn ruled_out(
    trials: &[TrialOut],
    sel: &select::Selection,
    max_effects: usize,
) -> (Vec<RuledOut>, Option<String>) {
    let last = trials.iter().map(|t| t.round).max();
    let Some(last) = last else {
        return (Vec::new(), Some("no candidate was tried".into()));
    };
    if trials.iter().any(|t| t.round == last && t.accepted) {
        let why = if sel.steps.len() >= max_effects {
            format!("the search stopped at --max-effects {max_effects}")
        } else {
            "every candidate was accepted: none is left to rule out".to_string()
        };
        return (Vec::new(), Some(why));
    }
    let list = trials
        .iter()
        .filter(|t| t.round == last)
        .map(|t| {
            let note = if let Some(f) = &t.failure {
                Some(f.clone())
            } else if !t.fitted && t.effect == Cand::Saturation.name() {
                Some(
                    "not fitted: no scanned clipping level (each clips >= 0.5 % of the points) \
                     fits better than none"
                        .into(),
                )
            } else if let Some(d) = sel.dropped.iter().find(|d| d.cand.name() == t.effect) {
                Some(format!("named in round {}, then dropped (above)", d.round))
            } else if t.dbic > select::BIC_MIN {
                Some(format!(
                    "dBIC above {} but the held-out chi-square did not drop{}",
                    select::BIC_MIN,
                    t.heldout_rms
                        .map(|r| format!(" (held-out RMS {r:.2} counts)"))
                        .unwrap_or_default()
                ))
            } else {
                None
            };
            RuledOut {
                effect: t.effect.clone(),
                k: t.k,
                dchi2: t.dchi2,
                dbic: t.dbic,
                fitted: t.fitted,
                params: t
                    .params
                    .iter()
                    .filter(|p| !p.name.contains('@'))
                    .cloned()
                    .collect(),
                per_separation: spreads(&t.params),
                correlations: t.correlations.clone(),
                base_correlations: t.base_correlations.clone(),
                note,
            }
        })
        .collect();
    (list, None)
}

/// Analyze a dataset (module doc). Each fit is reported to `progress`: `position(fits so far,
/// 0)` (how many fits the search takes is not known beforehand) and `message(what was
/// fitted)`.
pub fn analyze(ds: &Dataset, opts: &Options, progress: &dyn Progress) -> Result<Analysis, Error> {
    let fits = AtomicU64::new(0);
    let fitted = |what: &str| {
        let n = fits.fetch_add(1, Ordering::Relaxed) + 1;
        progress.position(n, 0);
        progress.message(what);
    };
    let progress: select::Progress = &fitted;
    let (ds, mut data_notes) = data_notes(ds, opts)?;
    let ds = ds.as_ref();
    let mut data = Data::from_dataset(ds, opts.weights, opts.noise)?;
    let mut corners = opts
        .corners
        .as_ref()
        .map(|rc| place_by_corners(rc, &mut data));
    let nsep = data.seps.len();
    let file = ds.path.display().to_string();
    if nsep < 2 {
        return Err(Error::TooFewSeparations {
            file,
            separations: data.seps.clone(),
            candidates: opts.candidates.clone(),
        });
    }
    let per_sep = data.points_per_sep();
    let fold_seps: Vec<Vec<usize>> = match &opts.holdout {
        Some(h) => {
            let mut idx = Vec::new();
            for s in h {
                let near = crate::data::nearest_within(&data.seps, *s);
                match near.and_then(|v| data.seps.iter().position(|w| *w == v)) {
                    Some(k) => idx.push(k),
                    None => {
                        return Err(Error::HoldoutMissing {
                            file,
                            separation: *s,
                            have: data.seps.clone(),
                        })
                    }
                }
            }
            if idx.len() >= nsep {
                return Err(Error::HoldoutAll);
            }
            vec![idx]
        }
        None => select::folds(nsep, opts.folds),
    };
    // What noise alone gives as held-out RMS: every held-out row's variance (the point
    // means' noise), over the separations the folds hold out.
    let mut noise_ss = vec![(0.0, 0usize); nsep];
    for p in &data.points {
        noise_ss[p.sep].0 += 1.0 / p.w[0] + 1.0 / p.w[1];
        noise_ss[p.sep].1 += 2;
    }
    let noise_rms_by_sep: Vec<f64> = noise_ss
        .iter()
        .map(|(ss, n)| (ss / (*n).max(1) as f64).sqrt())
        .collect();
    let heldout_noise_rms = {
        let held: std::collections::BTreeSet<usize> = fold_seps.iter().flatten().copied().collect();
        let (ss, n) = held.iter().fold((0.0, 0), |(a, b), &k| {
            (a + noise_ss[k].0, b + noise_ss[k].1)
        });
        (ss / n.max(1) as f64).sqrt()
    };
    let systematic = |rms: f64| {
        (rms * rms - heldout_noise_rms * heldout_noise_rms)
            .max(0.0)
            .sqrt()
    };
    let min_pts = per_sep.iter().copied().min().unwrap_or(0);
    // Per-separation corrections need enough points at every separation: with fewer they are
    // neither fitted nor named (listed as untested below).
    let few_points = min_pts < MIN_POINTS_PER_SEPARATION;
    // Per-LED candidates need each LED identified and seen at enough separations.
    let no_led = per_led_untestable(&data);
    // `array_pose` needs the LEDs identified too, and several arrays.
    let per_led = |c: &Cand| !c.led_names().is_empty() || *c == Cand::ArrayPose;
    let no_arrays = no_led.clone().or_else(|| {
        super::arrays::arrays_of(&Model::leds_of(&data))
            .is_empty()
            .then(|| {
                "the plate holds one array (every beacon id is in one hundred: ids 100 * array + \
                 LED): one array's pose is the head's"
                    .to_string()
            })
    });
    let sel_opts = select::Options {
        base: opts.from,
        folds: opts.folds,
        candidates: opts
            .candidates
            .iter()
            .filter(|c| !few_points || c.local_names().is_empty())
            .filter(|c| no_led.is_none() || !per_led(c))
            .filter(|c| no_arrays.is_none() || **c != Cand::ArrayPose)
            .cloned()
            .collect(),
        max_effects: opts.max_effects,
    };
    let sel =
        select::select_with_folds(&data, &sel_opts, &fold_seps, progress).map_err(|error| {
            Error::Selection {
                file: file.clone(),
                error,
                diagnosis: wiring::diagnose(ds),
            }
        })?;
    let mut untested: Vec<Untested> = sel
        .untested
        .iter()
        .map(|(c, r)| Untested {
            effect: c.name().into(),
            reason: r.clone(),
        })
        .collect();
    if few_points {
        for c in &opts.candidates {
            if !c.local_names().is_empty() && !untested.iter().any(|u| u.effect == c.name()) {
                untested.push(Untested {
                    effect: c.name().into(),
                    reason: format!(
                        "a separation has only {min_pts} usable points: too few to estimate a \
                         per-separation correction with any confidence"
                    ),
                });
            }
        }
    }
    if let Some(why) = &no_led {
        for c in opts.candidates.iter().filter(|c| !c.led_names().is_empty()) {
            untested.push(Untested {
                effect: c.name().into(),
                reason: why.clone(),
            });
        }
    }
    if let Some(why) = &no_arrays {
        if opts.candidates.contains(&Cand::ArrayPose) {
            untested.push(Untested {
                effect: Cand::ArrayPose.name().into(),
                reason: why.clone(),
            });
        }
    }
    let n_constraints = |m: &Model| m.n_constraints();
    let dof_chi2 = |m: &Model, f: &FitResult| f.chi2 / f.dof(n_constraints(m));
    let base_chi2 = dof_chi2(&sel.base_model, &sel.base_fit);
    if let Some(c) = &mut corners {
        if !data.measured_tilts_deg.is_empty() {
            // The gain of placing the plates: the starting model with them level.
            let level = Data {
                measured_tilts_deg: Vec::new(),
                ..data.clone()
            };
            progress("starting model with level plates");
            if let Ok(v) = select::base_chi2_dof(&level, opts.from) {
                c.chi2_dof_level = Some(v);
                c.note.push_str(&format!(
                    "; the starting model's chi2/dof {v:.2} with the plates level, {base_chi2:.2} \
                     placed by the corners"
                ));
            }
        }
        data_notes.push(c.note.clone());
    }
    let (fm, ff, fcv) = sel.last();
    let final_chi2 = dof_chi2(fm, ff);
    let unexplained = final_chi2 > UNEXPLAINED_CHI2_DOF;
    // The plate's farthest beacon from its centre: where a plate tilt moves a beacon most.
    let r_max = data
        .points
        .iter()
        .map(|p| p.r.x.hypot(p.r.y))
        .fold(0.0, f64::max);
    let mut causes = Vec::new();
    for st in &sel.steps {
        // The parameters as the final model (every named cause together) has them: the step
        // that added a cause fitted it without the causes named after it, which it may have
        // stood in for (from `pinhole`, `proximity` alone reads S = 0.85 in on thesis data,
        // near the truth, 0.175, once `intensity` and `beacon_pattern` are in).
        let (params, sigma, correlations, base_correlations) =
            cause_params(fm, st.cand, ff, &data.seps);
        let round = sel
            .trials
            .iter()
            .find(|t| t.accepted && t.cand == st.cand)
            .map(|t| t.round);
        let rivals = round.map_or_else(Vec::new, |r| rivals(&sel.trials, r, st.cand, st.dbic));
        let caution = match st.cand {
            Cand::Proximity => params.get("S").and_then(|&s| wiring::s_unit_note(s, "S")),
            _ => None,
        };
        let budget = super::plausible::check(st.cand, &params, &opts.budget, r_max);
        causes.push(Cause {
            effect: st.cand.name().into(),
            params,
            sigma,
            gain_rms_counts: st.cv_before.rms - st.cv_after.rms,
            heldout_noise_rms,
            systematic_rms_before: systematic(st.cv_before.rms),
            systematic_rms_after: systematic(st.cv_after.rms),
            dchi2: st.dchi2,
            dbic: st.dbic,
            heldout_rms_before: st.cv_before.rms,
            heldout_rms_after: st.cv_after.rms,
            chi2_dof_after: dof_chi2(&st.model, &st.fit),
            correlations,
            base_correlations,
            rivals,
            board: board_note(st.cand.name()),
            caution,
            budget,
        });
    }
    let effects: Vec<Cand> = sel.steps.iter().map(|st| st.cand).collect();
    let cross_correlations = cross_correlations(fm, ff, &effects);
    let (causes, tentative) = if unexplained {
        (Vec::new(), causes)
    } else {
        (causes, Vec::new())
    };
    let before_res = diag::residuals(&sel.base_model, &sel.base_fit.x, &data);
    let after_res = diag::residuals(fm, &ff.x, &data);
    let ab = diag::angle_errors(&sel.base_model, &sel.base_fit.x, &data);
    let aa = diag::angle_errors(fm, &ff.x, &data);
    // Compare the two models' angle errors over the same points: near the output rail one
    // model may not reach the measured output at all (no direction) while the other turns
    // a few counts into degrees where the output hardly changes with angle.
    let both = |e: &[f64]| -> Vec<f64> {
        e.iter()
            .zip(ab.iter().zip(&aa))
            .map(|(&v, (b, a))| {
                if b.is_finite() && a.is_finite() {
                    v
                } else {
                    f64::NAN
                }
            })
            .collect()
    };
    let angle_left_out = ab
        .iter()
        .zip(&aa)
        .filter(|(b, a)| !(b.is_finite() && a.is_finite()))
        .count();
    let diagnostics_before = diag::diagnose(&sel.base_model, &sel.base_fit.x, &data);
    let diagnostics_after = diag::diagnose(fm, &ff.x, &data);
    let structure = if final_chi2 > UNEXPLAINED_CHI2_DOF {
        diagnostics_after.notes()
    } else {
        Vec::new()
    };
    if let Some(n) = noise_too_large(&data, opts, base_chi2, sel.base_cv.rms) {
        data_notes.push(n);
    }
    let verdict = if unexplained {
        let part = if tentative.is_empty() {
            String::new()
        } else {
            format!(
                "; partial improvement from {} (not named: the structure is not explained)",
                tentative
                    .iter()
                    .map(|c| c.effect.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        // One sample per point and no --noise: the chi-square rests on an assumed noise. When
        // no extension gains even 1 % of the held-out RMS, the excess is most likely the
        // sensor's own noise, larger than assumed, not structure: say what to rerun with.
        let assumed = !data.noise_measured && opts.noise.is_none();
        let gain = sel.base_cv.rms - fcv.rms;
        let hint = if assumed && gain < 0.01 * sel.base_cv.rms {
            format!(
                ". But the noise was assumed ({:.1} counts; one sample per \
                 point) and no extension gains 1 % of the held-out RMS ({:.1} -> {:.1} counts): \
                 the residuals look like noise of about {:.0} counts rather than structure. If \
                 that is the sensor's noise, rerun with --noise {:.0} (better: sweep with \
                 repeated samples, which measure it)",
                data::DEFAULT_NOISE_COUNTS,
                sel.base_cv.rms,
                fcv.rms,
                sel.base_cv.rms,
                sel.base_cv.rms
            )
        } else {
            String::new()
        };
        format!(
            "unexplained structure remains: chi2/dof {:.2} after the best extension (starting model {:.2}){part}{hint}",
            final_chi2, base_chi2
        )
    } else if causes.is_empty() {
        match corners.as_ref().and_then(|c| c.chi2_dof_level) {
            Some(level) if level > UNEXPLAINED_CHI2_DOF => format!(
                "no significant effect beyond the plate tilts the corner readings measured: the \
                 `{}` model, its plates placed by them, explains the data (chi2/dof {:.2}; {:.2} \
                 with the plates level)",
                opts.from.name(),
                base_chi2,
                level
            ),
            _ => format!(
                "no significant effect: the `{}` model explains the data (chi2/dof {:.2})",
                opts.from.name(),
                base_chi2
            ),
        }
    } else {
        let list = |beyond: bool| {
            causes
                .iter()
                .filter(|c| c.beyond_budget() == beyond)
                .map(|c| c.effect.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let (found, beyond) = (list(false), list(true));
        let figures = format!(
            "chi2/dof {:.2} -> {:.2}, held-out RMS {:.1} -> {:.1} counts",
            base_chi2, final_chi2, sel.base_cv.rms, fcv.rms
        );
        let far = format!(
            "fitted far beyond the apparatus budget, so not named as found (see its warning): \
             {beyond}"
        );
        match (found.is_empty(), beyond.is_empty()) {
            (_, true) => format!("named: {found} ({figures})"),
            (true, false) => format!("no cause named as found ({figures}); {far}"),
            (false, false) => format!("named: {found} ({figures}); {far}"),
        }
    };
    // The crosstalk check of a grouped sweep, named before the fits' causes: it biases every
    // grouped point the fits use.
    let crosstalk = crate::crosstalk::check(ds);
    let verdict = match &crosstalk {
        Some(c) if c.named => format!(
            "named: spot_crosstalk by the crosstalk check (C = {:.2e} +/- {:.1e}: the grouped \
             data are biased by {:.2} counts RMS, at most {:.2}; rerun with smaller groups); \
             the fits: {verdict}",
            c.c, c.c_sigma, c.bias_rms, c.bias_max
        ),
        _ => verdict,
    };
    let trials: Vec<TrialOut> = sel
        .trials
        .iter()
        .map(|t| {
            let (params, correlations, base_correlations) = t
                .fit
                .as_deref()
                .map(|(m, f)| trial_params(m, t.cand, f, &data.seps))
                .unwrap_or_default();
            TrialOut {
                round: t.round,
                effect: t.cand.name().into(),
                k: t.k,
                dchi2: t.dchi2,
                dbic: t.dbic,
                heldout_rms: t.cv_rms,
                accepted: t.accepted,
                failure: t.failure.clone(),
                fitted: t.fit.is_some(),
                params,
                correlations,
                base_correlations,
            }
        })
        .collect();
    let (ruled_out, ruled_out_note) = ruled_out(&trials, &sel, opts.max_effects);
    // A head turned far from square fits as well as a square one (a pose like any other):
    // say so, with the reading of X and Y that squares it.
    let params_after = params_of(fm, ff, &data.seps, true);
    let value = |n: &str| params_after.iter().find(|q| q.name == n).map(|q| q.value);
    // Per-separation apparatus causes against the run's time: a drift looks like them.
    data_notes.extend(super::trend::notes(&causes, &ds));
    data_notes.extend(wiring::turned_head_note(
        ["p1", "p2", "p3"].map(|n| value(n).unwrap_or(0.0)),
        value("H"),
    ));
    Ok(Analysis {
        crosstalk,
        file,
        model_from: opts.from.name().into(),
        causes,
        tentative,
        cross_correlations,
        dropped: sel
            .dropped
            .iter()
            .map(|d| DroppedOut {
                effect: d.cand.name().into(),
                round: d.round,
                dbic_named: d.dbic_named,
                others: d.others.iter().map(|c| c.name().to_string()).collect(),
                k: d.k,
                dchi2_keep: d.dchi2_keep,
                dbic_keep: d.dbic_keep,
                heldout_rms_with: d.cv_rms_with,
                heldout_rms_without: d.cv_rms_without,
            })
            .collect(),
        untested,
        unexplained,
        verdict,
        chi2_dof_before: base_chi2,
        chi2_dof_after: final_chi2,
        rms_before: sel.base_cv.rms,
        rms_after: fcv.rms,
        separations: data.seps.clone(),
        angle_std_before_deg: diag::angle_std_by_sep(&both(&ab), &data),
        angle_std_after_deg: diag::angle_std_by_sep(&both(&aa), &data),
        angle_left_out,
        heldout_noise_rms,
        noise_rms_by_sep,
        heldout_rms_by_sep_before: sel.base_cv.rms_by_sep.clone(),
        heldout_rms_by_sep_after: fcv.rms_by_sep.clone(),
        params_before: params_of(&sel.base_model, &sel.base_fit, &data.seps, true),
        params_after,
        noise: data.noise_note.clone(),
        data_notes,
        corners,
        noise_by_sep: data.noise_by_sep.clone(),
        samples: data.samples,
        points: data.points.len(),
        excluded_points: data.excluded,
        folds: fold_seps
            .iter()
            .map(|f| f.iter().map(|&k| data.seps[k]).collect())
            .collect(),
        structure,
        diagnostics_before,
        diagnostics_after,
        trials,
        ruled_out,
        ruled_out_note,
        detail: Some(Box::new(Detail {
            data,
            before: before_res,
            after: after_res,
            angle_before: ab,
            angle_after: aa,
        })),
    })
}

/// Fewest separations the median LED must be seen at for per-LED candidates to be tried: an
/// LED's offset is then fitted on some separations and predicts the others.
pub const MIN_SEPARATIONS_PER_LED: usize = 3;

/// Why per-LED candidates (`led_position`) cannot be tried on `data`, or None: a point
/// without a beacon id (no `beacon` column: the LEDs are not identified, so nothing ties a
/// point to its LED across separations), or LEDs seen at too few separations.
pub(super) fn per_led_untestable(data: &Data) -> Option<String> {
    if let Some(p) = data.points.iter().find(|p| p.beacon.is_none()) {
        return Some(format!(
            "the LEDs are not identified (line {}: no beacon id; the file needs a `beacon` \
             column): a per-LED effect ties each LED's points across separations",
            p.line
        ));
    }
    let mut seen: std::collections::BTreeMap<u32, std::collections::BTreeSet<usize>> =
        Default::default();
    for p in &data.points {
        seen.entry(p.beacon.unwrap_or(0)).or_default().insert(p.sep);
    }
    let mut counts: Vec<usize> = seen.values().map(|s| s.len()).collect();
    counts.sort_unstable();
    let median = counts.get(counts.len() / 2).copied().unwrap_or(0);
    (median < MIN_SEPARATIONS_PER_LED).then(|| {
        format!(
            "the median LED is seen at {median} separation(s): at least \
             {MIN_SEPARATIONS_PER_LED} are needed to fit each LED's place on some and test it \
             on others"
        )
    })
}

/// The dataset the analysis uses (without the flagged glitches with `--drop-glitches`) and
/// the notes on it: glitches and how much they inflate the noise the fits weight by, and
/// settings whose noise differs while the weights pool them.
pub(super) fn data_notes<'d>(
    ds: &'d Dataset,
    opts: &Options,
) -> Result<(std::borrow::Cow<'d, Dataset>, Vec<String>), Error> {
    let mut notes = Vec::new();
    let mut used = std::borrow::Cow::Borrowed(ds);
    if let Some(clean) = ds.without_glitches() {
        let one = clean.samples == 1;
        let where_ = clean.where_();
        if opts.drop_glitches {
            notes.push(clean.note());
            used = std::borrow::Cow::Owned(clean.data);
        } else if opts.noise.is_none() {
            // The noise per separation and axis the fits weight by, with and without them.
            let with = Data::from_dataset(ds, opts.weights, None)?;
            let without = Data::from_dataset(&clean.data, opts.weights, None)?;
            if with.noise_measured {
                let (mut worst, mut at, mut axis) = (1.0, f64::NAN, 0);
                for (k, sep) in with.seps.iter().enumerate() {
                    let Some(j) = without.seps.iter().position(|v| v == sep) else {
                        continue;
                    };
                    for a in 0..2 {
                        let r = with.noise_by_sep[k][a] / without.noise_by_sep[j][a];
                        if r > worst {
                            (worst, at, axis) = (r, *sep, a);
                        }
                    }
                }
                let them = if one { "it" } else { "them" };
                if opts.weights == Weights::Point {
                    notes.push(format!(
                        "the glitch{} ({where_}) inflate{} the variance of {} point{}, which \
                         weight{} by it: --drop-glitches leaves {them} out (the file is not changed)",
                        if one { "" } else { "es" },
                        if one { "s" } else { "" },
                        if one { "its" } else { "their" },
                        if one { "" } else { "s" },
                        if one { "s" } else { "" },
                    ));
                } else if worst > 1.2 {
                    notes.push(format!(
                        "the glitch{} ({where_}) inflate{} the noise the fits weight by, most at \
                         {at} in on {}: {worst:.1}-fold. There the weights and the noise-alone \
                         figures are off. --drop-glitches leaves {them} out (the file is not \
                         changed)",
                        if one { "" } else { "es" },
                        if one { "s" } else { "" },
                        ["X", "Y"][axis],
                    ));
                }
            }
        }
    }
    // Settings (frequency, power, sensitivity) whose noise differs within a separation, while
    // the default weights pool them: `cta noise`'s test, run only when a separation has more
    // than one setting.
    if opts.weights == Weights::Separation && opts.noise.is_none() {
        let mut pairs: Vec<(u64, [u64; 3])> = (used.samples.iter())
            .map(|s| {
                let setting = [s.frequency_hz, s.power, s.sensitivity]
                    .map(|v| v.unwrap_or(f64::NAN).to_bits());
                (s.separation_in.to_bits(), setting)
            })
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        if pairs.len() > used.separations().len() {
            if let Ok(r) = crate::noise::analyze_noise(&used) {
                let differ = crate::noise::settings_that_differ(&r);
                if !differ.is_empty() {
                    notes.push(format!(
                        "the noise differs between settings within a separation: {}; these \
                         weights pool them per separation: `--weights setting` weights each \
                         setting by its own noise (`cta noise {}` shows it)",
                        differ
                            .iter()
                            .map(|f| format!("{} (max/min std {:.2})", f.factor, f.spread_ratio))
                            .collect::<Vec<_>>()
                            .join(", "),
                        ds.path.display()
                    ));
                }
            }
        }
    }
    Ok((used, notes))
}

/// A chi-square far below its expectation: the noise the fits weight by is far larger than
/// the scatter of the point means, so no effect could be significant against it.
pub(super) fn noise_too_large(
    data: &Data,
    opts: &Options,
    chi2_dof: f64,
    rms: f64,
) -> Option<String> {
    if !(chi2_dof < NOISE_TOO_LARGE_CHI2_DOF) {
        return None;
    }
    Some(if data.noise_measured {
        format!(
            "chi2/dof {chi2_dof:.2}: the point means scatter far less than their repeated \
             samples say (held-out RMS {rms:.1} counts): the noise the fits weight by looks \
             overestimated (glitches? samples that are not independent?), and an effect can \
             hide under it"
        )
    } else {
        let (what, n) = match opts.noise {
            Some(n) => ("set by --noise", n),
            None => (
                "assumed for one sample per point",
                data::DEFAULT_NOISE_COUNTS,
            ),
        };
        format!(
            "chi2/dof {chi2_dof:.2}: the residuals (held-out RMS {rms:.1} counts) are far \
             smaller than the noise {what} ({n:.1} counts): no effect can be significant \
             against it. If the sensor is that quiet, rerun with --noise {:.1} (better: \
             repeated samples, which measure it)",
            rms.max(0.1)
        )
    })
}
