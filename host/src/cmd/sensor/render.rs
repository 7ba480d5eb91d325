//! The pose tables as text: `cta sensor accuracy` (and its `--envelope`) and `cta sensor floor`.

use cta_core::pose::NearField;
use cta_lab::pose::accuracy::AccuracyTable;
use cta_lab::pose::envelope::EnvelopeTable;
use cta_lab::pose::floor::{FloorTable, CLAIM_RANGE};

/// The accuracy table as text: its setup, the errors per frame, the systematic errors and
/// the design targets' verdicts.
pub fn accuracy(t: &AccuracyTable) -> String {
    let mut s = String::new();
    let pc = &t.pinhole_calibration;
    let nc = &t.nearfield_calibration;
    let nn = nc.near_field.unwrap_or(NearField::nominal());
    let sg = &t.nearfield_sigma;
    s += &format!(
        "Pose accuracy on simulated data: eq 63 physics (proximity, intensity, Lambertian beacon), Table 3 head,\n\
         noise {:.1} counts (1-sigma), {} trials per range (random lateral offset +/-0.5 in, attitude +/-3 deg),\n\
         {},\n{} solver, cold start. (`cta sensor floor` draws its own poses: the figures both print agree to the\n\
         scatter of the pose sets, ~10 %.)\n",
        t.noise_counts, t.trials, t.constellation, t.arithmetic,
    );
    s += &format!(
        "pinhole    = eq 65 with the 7-parameter calibration fitted at 25 and 30 in (every LED of the plate)\n\
         \x20            (noise-free data: the best case for it): d = {:.4} {:.4} {:.4} in, H = {:.1}.\n",
        pc.d[0], pc.d[1], pc.d[2], pc.h
    );
    if t.true_calibration {
        s += "near-field = the eq 60-63 model with the true head (--true-calibration).\n";
    } else {
        s += &format!(
            "near-field = the eq 60-63 model with d, p, a, s fitted to a simulated CTA sweep (the plate's LEDs,\n\
             \x20            2-30 in in 1 in steps, {} samples per point, same noise): d = {:.4} {:.4} {:.4} in\n\
             \x20            (d3 +/-{:.1e}; truth 0.6 0.1 0.062), a = {:.4} deg (+/-{:.1e}; 30), s = {:.5} in (+/-{:.1e}; 0.175).\n",
            t.cal_samples, nc.d[0], nc.d[1], nc.d[2], sg[2], nn.alpha_deg, sg[6], nn.s, sg[7]
        );
    }
    if let (true, Some(m)) = (t.magnitudes, nc.magnitude) {
        s += &format!(
            "             The near-field pose also fits the spot magnitudes (`spots only`: the same model without them),\n\
             \x20            simulated with {} % scatter on top of their rounding to counts, with the law ",
            t.magnitude_noise_percent
        );
        s += &match &t.magnitude_law {
            Some(r) => format!(
                "fitted to the sweep's\n\
                 \x20            magnitudes as `cta calibrate` fits it: exponent {:.5} (+/-{:.1e}; 1), offset {:.2} counts,\n\
                 \x20            scatter {:.3} % (readings {:.0}-{:.0} counts).\n",
                m.exponent, r.exponent_sigma, m.offset, m.noise_percent, m.min, m.max
            ),
            None => format!(
                "the simulated NorthStar's (linear, scatter {} %).\n",
                m.noise_percent
            ),
        };
    } else {
        s += "             From the spots alone (--no-magnitudes).\n";
    }
    s += "floor = RMS of the near-field solver's predicted 1-sigma (the noise floor of one frame). Errors are RMS;\n\
          'not ok' counts solves whose status was not Ok (the pinhole's at 2 in: residual RMS above the\n\
          2000-count limit, i.e. the model cannot fit the frame; the error columns include those solves).\n\
          seen = beacons in view, mean over the trials";
    if t.magnitudes {
        s += "; mags = magnitudes the near-field pose fitted, mean.\n\n";
        s += "range  seen  mags |  position error (in)                              |  attitude error (deg)                             | not ok\n";
        s += " (in)             |  near-field spots only  pinhole   ratio    floor  |  near-field spots only pinhole   ratio    floor | nf  ph\n";
        for r in &t.rows {
            s += &format!(
                "{:5.1} {:5.1} {:5.1} |  {:10.5} {:10.5} {:8.5} {:7.1} {:8.5}  |  {:9.4} {:10.4} {:8.4} {:7.1} {:8.4} | {:2} {:3}\n",
                r.range,
                r.beacons,
                r.magnitudes,
                r.nf_pos,
                r.ns_pos,
                r.ph_pos,
                r.ph_pos / r.nf_pos,
                r.floor_pos,
                r.nf_att,
                r.ns_att,
                r.ph_att,
                r.ph_att / r.nf_att,
                r.floor_att,
                r.nf_failures,
                r.ph_failures
            );
        }
    } else {
        s += ".\n\n";
        s += "range  seen |  position error (in)                    |  attitude error (deg)                  | not ok\n";
        s += " (in)       |  near-field   pinhole   ratio    floor  |  near-field  pinhole   ratio    floor | nf  ph\n";
        for r in &t.rows {
            s += &format!(
                "{:5.1} {:5.1} |  {:10.5} {:9.5} {:7.1} {:8.5}  |  {:9.4} {:8.4} {:7.1} {:8.4} | {:2} {:3}\n",
                r.range,
                r.beacons,
                r.nf_pos,
                r.ph_pos,
                r.ph_pos / r.nf_pos,
                r.floor_pos,
                r.nf_att,
                r.ph_att,
                r.ph_att / r.nf_att,
                r.floor_att,
                r.nf_failures,
                r.ph_failures
            );
        }
    }
    s += "\nSystematic error: the same poses seen without noise (rounded to counts). This is the part a\n\
          navigation filter cannot average away at a standing pose; the rows above add the noise of one frame.\n\
          The near-field column is calibration error, f32 rounding and the solver's stop rule (its last step,\n\
          worth less than 0.1 chi-square, is taken as predicted: what that leaves is second order). 'not ok'\n\
          counts noise-free frames whose solve failed (e.g. too few usable coordinates at 1 in); their\n\
          fallback pose is in the columns.\n";
    if t.magnitudes {
        s += "With the magnitudes it also holds their rounding to whole counts: the simulated NorthStar reads\n\
              about 520 counts at 10 in and 58 at 30 in (0.06 % and 0.5 %: as much as their scatter, or more),\n\
              which a moving target turns into noise but a standing one keeps.\n";
    }
    s += "\n";
    s +=
        "range |  position error (in)              |  attitude error (deg)              | not ok\n";
    s += " (in) |  near-field   pinhole     ratio   |  near-field  pinhole     ratio   | nf  ph\n";
    for r in &t.rows {
        s += &format!(
            "{:5.1} |  {:10.6} {:9.5} {:>9} |  {:10.5} {:8.4} {:>9} | {:2} {:3}\n",
            r.range,
            r.nf_pos_sys,
            r.ph_pos_sys,
            ratio(r.ph_pos_sys, r.nf_pos_sys),
            r.nf_att_sys,
            r.ph_att_sys,
            ratio(r.ph_att_sys, r.nf_att_sys),
            r.nf_sys_failures,
            r.ph_sys_failures,
        );
    }
    s += "\nDesign targets (`--check` fails unless all hold):\n";
    for c in t.claims() {
        s += &format!(
            "  [{}] {}: {}\n",
            if c.holds { " ok " } else { "FAIL" },
            c.name,
            c.detail
        );
    }
    s
}

/// `a / b` for the table (`>1e5` when `b` is at rounding level).
fn ratio(a: f64, b: f64) -> String {
    if a > 1e5 * b {
        ">1e5".into()
    } else {
        format!("{:.1}", a / b)
    }
}

/// The floor table as text: the spots alone against the attitude floor the pinhole
/// comparison needs, then the floors with the spot magnitudes.
pub fn floor(t: &FloorTable) -> String {
    let mut s = String::new();
    s += &format!(
        "Noise floor of one frame (Cramer-Rao bound: no unbiased pose from these measurements does better),\n\
         eq 60-63 physics, Table 3 head, spot noise {:.1} counts,\n{},\nRMS over {} poses per range \
         (lateral offset +/-0.5 in, attitude up to 3 deg). `cta sensor accuracy` draws its own poses and \
         calibrations,\nso the figures both print (floor, pinhole systematic) agree to the scatter of the pose sets (~10 %).\n\n",
        t.noise_counts, t.constellation, t.poses
    );
    s += "Spots alone (what the chip solves with) against the attitude floor the pinhole comparison needs:\n";
    s += "range  used |  floor, spots only       | solver's own | pinhole     | floor needed | best ratio\n";
    s += " (in)       |  pos (in)   att (deg)    | att (deg)    | syst. (deg) | for 5x (deg) | one frame\n";
    for r in &t.rows {
        if r.poses_used == 0 {
            s += &format!("{:5.1}       |  no pose with 4 usable beacons\n", r.range);
            continue;
        }
        s += &format!(
            "{:5.1} {:5.1} |  {:8.5}  {:9.4}     | {:9.4}    | {:9.4}   | {:9.4}    | {:6.1}x{}\n",
            r.range,
            r.beacons,
            r.spots.position,
            r.spots.attitude_deg,
            r.solver_predicted.attitude_deg,
            r.pinhole_systematic_deg,
            r.needed_for_5x_deg,
            r.best_ratio_spots,
            if r.range > CLAIM_RANGE || r.spots.attitude_deg <= r.needed_for_5x_deg {
                ""
            } else {
                "  (spots alone: out of reach)"
            }
        );
    }
    let short: Vec<String> = t
        .rows
        .iter()
        .filter(|r| r.poses_used < t.poses)
        .map(|r| format!("{} in: {} of {}", r.range, r.poses_used, t.poses))
        .collect();
    if !short.is_empty() {
        s += &format!(
            "Poses with fewer than 4 usable beacons (no bound), left out: {}.\n",
            short.join(", ")
        );
    }
    let railed: Vec<String> = t
        .rows
        .iter()
        .filter(|r| r.railed > 0.05)
        .map(|r| format!("{} in: {:.1}", r.range, r.railed))
        .collect();
    if !railed.is_empty() {
        s += &format!(
            "Coordinates per frame on the 16-bit rail (a cell in the dark), left out as the solver does: {}.\n\
             (With noise such a coordinate can fall just below the rail and be used; the model has no slope\n\
             there, so it adds nothing.)\n",
            railed.join(", ")
        );
    }
    s += "\nWith the spot magnitudes as well (ASSUMED model: magnitude = k x sum of the cell signals, k common\n\
          and unknown, noise a fixed percentage; the real NorthStar's magnitude has not been measured;\n\
          0.07 % is what the spot noise implies if both come from noise in the cells alone):\n";
    let mc = t.monte_carlo > 0;
    let width = if mc { 28 } else { 19 };
    s += "range |";
    if let Some(r) = t.rows.first() {
        for m in &r.with_magnitude {
            s += &format!(
                " {:>w$} |",
                format!("{} % noise", m.noise_percent),
                w = width
            );
        }
    }
    s += "\n      |";
    if let Some(r) = t.rows.first() {
        for _ in &r.with_magnitude {
            let h = if mc {
                "att deg (pos in) [reached]"
            } else {
                "att deg (pos in)"
            };
            s += &format!(" {:>w$} |", h, w = width);
        }
    }
    s += "\n";
    for r in &t.rows {
        if r.poses_used == 0 {
            s += &format!("{:5.1} |  no pose with 4 usable beacons\n", r.range);
            continue;
        }
        s += &format!("{:5.1} |", r.range);
        for m in &r.with_magnitude {
            let mut c = format!(
                "{:.4}{} ({:.4})",
                m.floor.attitude_deg,
                if r.range <= CLAIM_RANGE && m.floor.attitude_deg <= r.needed_for_5x_deg {
                    "*"
                } else {
                    " "
                },
                m.floor.position,
            );
            if let Some(x) = &m.reached {
                c += &format!(" [{:.4}]", x.attitude_deg);
            }
            s += &format!(" {:>w$} |", c, w = width);
        }
        s += "\n";
    }
    s += "\n* = at 2-10 in, at or below the attitude floor needed for the pinhole pose to be 5x worse per frame.\n\
          'solver's own' is the on-chip near-field solver's 1-sigma (f64 here) on the noise-free frame before its\n\
          scaling by the residual variance: it should equal the spots-only bound. 'floor needed for 5x' =\n\
          pinhole systematic / sqrt(24), since the pinhole's error per frame is at least\n\
          sqrt(systematic^2 + floor^2); 'best ratio' = sqrt(1 + (systematic / spots floor)^2), the most a pose\n\
          from the spots alone can show (try other --constellation). --json has every figure.\n";
    if t.monte_carlo > 0 {
        s += &format!(
            "[reached] = RMS attitude error of a host GLSDC pose fit with magnitudes, {} noisy frames per pose.\n",
            t.monte_carlo
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use cta_lab::pose::accuracy::{accuracy_table, AccuracyOptions};
    use cta_lab::pose::floor::{floor_table, FloorOptions};

    /// The accuracy table's text has its parts (the systematic errors, the design targets),
    /// and says whether the near-field pose fitted the magnitudes.
    #[test]
    fn the_accuracy_text_has_its_parts() {
        let args = AccuracyOptions {
            trials: 2,
            ranges: vec![10.0],
            cal_samples: 5,
            ..AccuracyOptions::default()
        };
        let with = accuracy(&accuracy_table(&args).unwrap());
        assert!(
            with.contains("Design targets") && with.contains("Systematic error"),
            "{with}"
        );
        assert!(with.contains("spots only"), "{with}");
        let without = accuracy(
            &accuracy_table(&AccuracyOptions {
                no_magnitudes: true,
                ..args
            })
            .unwrap(),
        );
        assert!(without.contains("From the spots alone"), "{without}");
    }

    /// A range without any usable pose prints no figures, and is named with the poses left
    /// out.
    #[test]
    fn an_empty_range_prints_no_figures() {
        let t = floor_table(&FloorOptions {
            ranges: vec![0.3, 8.0],
            magnitude_noise: vec![0.3],
            poses: 2,
            ..FloorOptions::default()
        })
        .unwrap();
        let text = floor(&t);
        assert!(text.contains("no pose with 4 usable beacons"), "{text}");
        assert!(text.contains("0.3 in: 0 of 2"), "{text}");
    }
}

/// `cta sensor accuracy --envelope` as text: one row per range.
pub fn envelope(t: &EnvelopeTable) -> String {
    let mut s = format!(
        "Cold acquisition over a docking envelope: eq 63 physics, Table 3 head, noise {:.1} counts (1-sigma),\n\
         {}, {} solver, every frame solved from the cold start (no previous pose).\n\
         Poses: roll about the line of sight anywhere in +/-180 deg, tilt up to `tilt` (the largest at which every\n\
         roll and direction keeps {} whole spots on axis), lateral offset up to `offset` (the same, untilted: the field\n\
         of view's edge). Frames with fewer whole spots are counted (`usable`), not solved. Acquired: Ok within {} of\n\
         its 1-sigma of the truth (near-field, with the true head) or of the pinhole's own solve from the truth\n\
         (eq 65 fitted at 25-30 in: biased near the target). Errors: RMS over the acquired frames, against the truth.\n\
         failed: D diverged, I ill-conditioned, F too few beacons, W Ok at a wrong minimum.\n\n",
        t.noise,
        t.label,
        if t.f64 { "f64" } else { "f32 (as on the chip)" },
        cta_lab::pose::envelope::USABLE_SPOTS,
        cta_lab::pose::envelope::ACQUIRED_SIGMAS,
    );
    s += &format!(
        "{:>6} {:>5} {:>7} {:>6} {:>6} {:>8} {:>8} {:>9} {:>9} {:>8} {:>8} {:>6} {:>6}  {:<13} {:<13}\n",
        "range", "tilt", "offset", "frames", "usable", "nf acq", "ph acq", "nf pos", "ph pos", "nf att",
        "ph att", "x pos", "x att", "nf failed", "ph failed"
    );
    s += &format!(
        "{:>6} {:>5} {:>7} {:>6} {:>6} {:>8} {:>8} {:>9} {:>9} {:>8} {:>8} {:>6} {:>6}\n",
        "(in)",
        "(deg)",
        "(in)",
        "",
        "",
        "(%)",
        "(%)",
        "(in)",
        "(in)",
        "(deg)",
        "(deg)",
        "ph/nf",
        "ph/nf"
    );
    let pct = |a: usize, n: usize| 100.0 * a as f64 / n.max(1) as f64;
    let failed = |f: &cta_lab::pose::envelope::Failures| {
        format!(
            "D{} I{} F{} W{}",
            f.diverged, f.ill_conditioned, f.too_few, f.wrong_minimum
        )
    };
    for r in &t.rows {
        s += &format!(
            "{:>6.1} {:>5.0} {:>7.2} {:>6} {:>6} {:>8.2} {:>8.2} {:>9.5} {:>9.5} {:>8.4} {:>8.4} {:>6.1} {:>6.1}  {:<13} {:<13}\n",
            r.range,
            r.max_tilt_deg,
            r.max_offset,
            r.frames,
            r.usable,
            pct(r.near_field.acquired, r.usable),
            pct(r.pinhole.acquired, r.usable),
            r.near_field.pos,
            r.pinhole.pos,
            r.near_field.att,
            r.pinhole.att,
            r.ratio_pos(),
            r.ratio_att(),
            failed(&r.near_field.failures),
            failed(&r.pinhole.failures),
        );
    }
    s
}
