//! When a file cannot be fitted at all: is it one of the common lab mistakes?
//!
//! A NorthStar with one cell pair wired the other way round, a file with `x` and `y`
//! swapped, or a separation written in centimetres does not give a poor fit: it gives none
//! (the starting model of `cta analyze`, the pinhole stage of `cta calibrate`, stop with an
//! optimizer error). [`diagnose`] tries the named transforms that undo such a mistake on a
//! copy of the file's point means, fits the cheap pinhole model (eq 65) to each, and says
//! which one makes the data look like a NorthStar on the CTA:
//!
//! - **orientation**: X's sign flipped, Y's, both, X and Y swapped, swapped with X's, Y's or
//!   both signs flipped. The fit with the lowest RMS is taken when it is at least
//!   [`RMS_MARGIN`] times lower than the data as given (or the data as given cannot be
//!   fitted). A turn of the head about its boresight is one of the pinhole model's poses,
//!   so transforms that differ by one (X flipped, and Y flipped with the head rolled
//!   180 deg) fit as well (within [`SAME_FIT`]): of those, the one whose fitted head attitude
//!   is nearest the nominal (the head mounted square to the board) is named. When the data
//!   as given fit as well but only with the head turned more than [`TURNED_DEG`], that is
//!   said, with the reading that squares it.
//! - **length unit**: `separation_in` and `beacon_z_in` divided by 2.54 (centimetres) or
//!   25.4 (millimetres). The pinhole model takes such a file in its stride with a scale
//!   height `H` as many times the NorthStar's (18918.6 counts): a fitted `H` more than
//!   [`H_OFF`] times off it that a transform brings within [`H_OK`] of it, at an RMS no
//!   worse (within [`SAME_FIT`]), is named.
//!
//! The fits use the point means (samples at the 16-bit rail left out) at the file's largest
//! third of separations (at least 2), where the pinhole model holds best: 8 to 10 small
//! fits, run only when the file could not be fitted.
//!
//! A file that *can* be fitted may still be read turned: a head turned about its boresight
//! is a pose like any other, so a file with both signs flipped (a half turn), or swapped with
//! one sign flipped (a quarter turn), fits as well as the file read square, with the head
//! turned. [`turned_head_note`] says so from a fit's head attitude (`cta fit`, `cta
//! calibrate`): more than [`TURNED_DEG`] from square, the turn about the boresight, and the
//! reading of X and Y that squares it.

use crate::data::weights::Weights;
use crate::data::{any_sample_pinned, fmt_list, Dataset};
use crate::fit;
use cta_core::collinearity::{Obs, ParamsExt};
use cta_core::emulator::Head;
use cta_core::mrp;
use nalgebra::{Matrix3, Vector3};

/// A transform must fit the pinhole model with an RMS this many times lower than the data as
/// given (a chi-square 25 times lower) to be named.
pub const RMS_MARGIN: f64 = 5.0;
/// Two fits whose RMS are within this ratio fit as well (transforms that differ by a turn of
/// the head about its boresight).
pub const SAME_FIT: f64 = 1.5;
/// A fitted scale height more than this many times off the NorthStar's points at a length
/// unit...
pub const H_OFF: f64 = 1.5;
/// ...when a length transform brings it within this factor of it.
pub const H_OK: f64 = 1.2;

/// A fitted head attitude turned more than this from square to the board (degrees) is
/// named when a reading of X and Y fits as well with the head square.
pub const TURNED_DEG: f64 = 45.0;

/// One way of reading the file's `x` and `y` columns.
struct Orientation {
    /// How the sentence names it ("with X's sign flipped").
    what: &'static str,
    /// (X, Y) as given to (X, Y) as meant.
    map: fn([f64; 2]) -> [f64; 2],
    /// What to check.
    check: &'static str,
}

const FLIP: &str = "check the NorthStar's wiring (a cell pair connected the other way round) or \
                    the file's sign convention (host/MEASUREMENTS.md)";
const SWAP: &str = "check the NorthStar's X and Y wiring or the file's `x` and `y` columns \
                    (host/MEASUREMENTS.md)";
const TURN: &str = "check how the head is mounted (turned about its boresight) and the \
                    NorthStar's X and Y wiring (host/MEASUREMENTS.md)";

/// The data as given first, then the seven transforms.
const ORIENTATIONS: [Orientation; 8] = [
    Orientation {
        what: "as given",
        map: |[x, y]| [x, y],
        check: "",
    },
    Orientation {
        what: "with X's sign flipped",
        map: |[x, y]| [-x, y],
        check: FLIP,
    },
    Orientation {
        what: "with Y's sign flipped",
        map: |[x, y]| [x, -y],
        check: FLIP,
    },
    Orientation {
        what: "with both X's and Y's signs flipped",
        map: |[x, y]| [-x, -y],
        check: TURN,
    },
    Orientation {
        what: "with X and Y swapped",
        map: |[x, y]| [y, x],
        check: SWAP,
    },
    Orientation {
        what: "with X and Y swapped and X's sign flipped",
        map: |[x, y]| [-y, x],
        check: TURN,
    },
    Orientation {
        what: "with X and Y swapped and Y's sign flipped",
        map: |[x, y]| [y, -x],
        check: TURN,
    },
    Orientation {
        what: "with X and Y swapped and both signs flipped",
        map: |[x, y]| [-y, -x],
        check: SWAP,
    },
];

/// Length units a file may have been written in by mistake: (divisor, unit).
const UNITS: [(f64, &str); 2] = [(2.54, "centimetres"), (25.4, "millimetres")];

/// One point mean.
#[derive(Clone, Copy)]
struct Pt {
    r: Vector3<f64>,
    y: [f64; 2],
}

/// One pinhole fit.
#[derive(Clone, Copy, Debug)]
struct Fitted {
    /// Unweighted RMS of the point-mean residuals, counts.
    rms: f64,
    /// Scale height, counts.
    h: f64,
    /// How far the fitted head attitude is turned from square to the board, degrees
    /// (180 more with a negative `H`: the same image turned half a turn).
    turn_deg: f64,
}

/// The point means [`diagnose`] fits, and the separations they are at.
fn far_points(ds: &Dataset) -> Option<(Vec<Pt>, Vec<f64>)> {
    let seps = ds.separations();
    if seps.len() < 2 {
        return None;
    }
    let keep = (seps.len().div_ceil(3)).max(2);
    let far = seps[seps.len() - keep..].to_vec();
    let mut pts = Vec::new();
    for p in ds.points() {
        if !far.contains(&p.first.separation_in) {
            continue;
        }
        let rows: Vec<_> = p.rows.iter().map(|&i| &ds.samples[i]).collect();
        if any_sample_pinned(rows.iter().copied()) {
            continue;
        }
        let n = rows.len() as f64;
        pts.push(Pt {
            r: Vector3::from(p.first.r),
            y: [
                rows.iter().map(|s| s.x).sum::<f64>() / n,
                rows.iter().map(|s| s.y).sum::<f64>() / n,
            ],
        });
    }
    (pts.len() >= 8).then_some((pts, far))
}

/// Fit eq 65 to `pts` read through `map`, with `beacon_z_in` divided by `z_div`. `None` when
/// the fit fails.
fn fit_pinhole(
    ds: &Dataset,
    pts: &[Pt],
    map: fn([f64; 2]) -> [f64; 2],
    z_div: f64,
) -> Option<Fitted> {
    let obs = pts
        .iter()
        .map(|p| Obs {
            r: Vector3::new(p.r.x, p.r.y, p.r.z / z_div),
            y: map(p.y),
            w: [1.0; 2],
        })
        .collect();
    let shell = Dataset {
        path: ds.path.clone(),
        samples: Vec::new(),
    };
    let rep = fit::fit_observations(&shell, Weights::None, obs).ok()?;
    let x = rep.x();
    let p = Vector3::new(x[3], x[4], x[5]).norm();
    let turn = 4.0 * p.min(1.0 / p).atan().to_degrees();
    let h = x.h();
    (rep.rms_counts.is_finite() && h.is_finite()).then_some(Fitted {
        rms: rep.rms_counts,
        h,
        turn_deg: if h < 0.0 { 180.0 - turn } else { turn },
    })
}

/// Counts, to a sensible precision.
fn counts(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.1}")
    }
}

/// What a common lab mistake would explain about `ds`, in sentences to add to the error of
/// a fit that failed; `None` when no transform does clearly better than the data as given
/// (module doc).
pub fn diagnose(ds: &Dataset) -> Option<String> {
    let (pts, far) = far_points(ds)?;
    let span = |v: &[f64]| match v {
        [a, .., b] => format!("{}-{}", fmt_list(&[*a]), fmt_list(&[*b])),
        _ => fmt_list(v),
    };
    let at = format!("at {} in", span(&far));
    let fits: Vec<Option<Fitted>> = ORIENTATIONS
        .iter()
        .map(|o| fit_pinhole(ds, &pts, o.map, 1.0))
        .collect();
    let best = fits
        .iter()
        .flatten()
        .map(|f| f.rms)
        .fold(f64::INFINITY, f64::min);
    let mut said = Vec::new();
    // Of the fits as good as the best, the one with the head nearest square to the board.
    let chosen = (0..fits.len())
        .filter(|&i| fits[i].is_some_and(|f| f.rms <= SAME_FIT * best))
        .min_by(|&a, &b| {
            let t = |i: usize| fits[i].map_or(f64::INFINITY, |f| f.turn_deg);
            t(a).total_cmp(&t(b))
        })?;
    let mut used = 0;
    if chosen != 0 {
        let c = fits[chosen]?;
        let o = &ORIENTATIONS[chosen];
        match fits[0] {
            Some(g) if g.rms >= RMS_MARGIN * c.rms => {
                said.push(format!(
                    "The data fit the pinhole model {:.0}x better {} (RMS {} counts against {} \
                     as given, {at}): {}.",
                    g.rms / c.rms,
                    o.what,
                    counts(c.rms),
                    counts(g.rms),
                    o.check
                ));
                used = chosen;
            }
            None => {
                said.push(format!(
                    "The data fit the pinhole model {} (RMS {} counts {at}) and cannot be \
                     fitted as given: {}.",
                    o.what,
                    counts(c.rms),
                    o.check
                ));
                used = chosen;
            }
            // As good as given, but only with the head turned far from square to the
            // board: a head mounted turned about its boresight, or X and Y wired so.
            Some(g) if g.turn_deg > TURNED_DEG && c.turn_deg < TURNED_DEG => {
                said.push(format!(
                    "The pinhole model fits the data as given only with the head turned {:.0} \
                     deg from square to the board (RMS {} counts {at}), and as well with it \
                     square {}: {TURN}.",
                    g.turn_deg,
                    counts(g.rms),
                    o.what,
                ));
            }
            Some(_) => {}
        }
    }
    // The length unit, in the orientation taken.
    let base = fits[used]?;
    let h0 = Head::<f64>::northstar().h();
    let off = |h: f64| (h.abs() / h0).max(h0 / h.abs());
    if off(base.h) > H_OFF {
        for (div, unit) in UNITS {
            let Some(f) = fit_pinhole(ds, &pts, ORIENTATIONS[used].map, div) else {
                continue;
            };
            if off(f.h) <= H_OK && f.rms <= SAME_FIT * base.rms {
                let far_true: Vec<f64> = far.iter().map(|s| s / div).collect();
                said.push(format!(
                    "The pinhole model fits the data {at} only with a scale height H = {:.0} \
                     counts, {:.2}x the NorthStar's {h0:.0}; with separation_in and beacon_z_in \
                     divided by {div} (i.e. at {} in) it gives H = {:.0} (RMS {} counts against \
                     {}): are the lengths in {unit}? Every length column is in inches \
                     (host/MEASUREMENTS.md).",
                    base.h.abs(),
                    base.h.abs() / h0,
                    span(
                        &far_true
                            .iter()
                            .map(|v| (v * 1e3).round() / 1e3)
                            .collect::<Vec<_>>()
                    ),
                    f.h.abs(),
                    counts(f.rms),
                    counts(base.rms),
                ));
                break;
            }
        }
    }
    (!said.is_empty()).then(|| said.join(" "))
}

/// `err`, with [`diagnose`]'s sentences after it when it has any.
pub fn explain(ds: &Dataset, err: String) -> String {
    explained(&err, diagnose(ds).as_deref())
}

/// `err`, with a diagnosis ([`diagnose`]'s sentences) after it when there is one: the text of
/// an error that carries its diagnosis.
pub fn explained(err: &str, diagnosis: Option<&str>) -> String {
    match diagnosis {
        Some(d) => format!("{}. {d}", err.trim_end_matches('.')),
        None => err.to_string(),
    }
}

/// A caution when a fitted cell offset `s` (eq 61's proximity, 0.175 in on the NorthStar) is
/// a length unit times the NorthStar's: a file whose every length column is in centimetres or
/// millimetres fits perfectly with `s` and `d` scaled so (the outputs depend only on ratios of
/// lengths: the intensities' inverse squares cancel in eq 63's ratios, and the angles do not
/// change), and nothing else in the fit shows it. Within [`S_UNIT_TOL`] of the factor;
/// `name` is what the caller's output calls the offset (`S` in analyze, `s` in calibrate).
pub fn s_unit_note(s: f64, name: &str) -> Option<String> {
    let s0 = Head::<f64>::northstar().s;
    let ratio = s / s0;
    UNITS
        .iter()
        .find(|(div, _)| (ratio / div - 1.0).abs() <= S_UNIT_TOL)
        .map(|(div, unit)| {
            format!(
                "the cell offset {name} = {s:.4} in is {ratio:.2}x the NorthStar's {s0} in: a \
                 NorthStar measured with every length in {unit} gives exactly this (with d \
                 {div} times too); are the lengths in {unit}? Every length column is in \
                 inches (host/MEASUREMENTS.md)"
            )
        })
}

/// How close `s / 0.175 in` must come to 2.54 or 25.4 for [`s_unit_note`] (relative).
pub const S_UNIT_TOL: f64 = 0.05;

/// A warning when a fit that succeeded gives a scale height `h` more than `H_OFF` times off
/// the NorthStar's (`H = beta tan a`: eq 5's scale height in counts, as eq 65 uses it): with [`diagnose`]'s sentences when a common
/// mistake (lengths in cm or mm, ...) explains it. `cta calibrate` and `cta fit` succeed on a
/// file in centimetres (the angles are right; only H and d scale), so this is where it shows.
///
/// Close in the pinhole model's H moves far by itself (the near-field errors it cannot
/// follow), so below 20 in only a named mistake is said.
pub fn h_warning(ds: &Dataset, h: f64) -> Option<String> {
    let h0 = Head::<f64>::northstar().h();
    let off = (h.abs() / h0).max(h0 / h.abs());
    if !(off > H_OFF) {
        return None;
    }
    let head = format!(
        "the pinhole fit's H = {:.0} counts is {:.2}x the NorthStar's {h0:.0}",
        h.abs(),
        h.abs() / h0
    );
    let far = ds.separations().iter().all(|&s| s >= 20.0);
    match diagnose(ds) {
        // It states H itself.
        Some(d) if d.contains("scale height") => Some(d),
        Some(d) if far => Some(format!("{head}. {d}")),
        None if far => Some(format!(
            "{head}: another detector, or lengths not in inches? Every length column is in \
             inches (host/MEASUREMENTS.md)"
        )),
        _ => None,
    }
}

/// A turn about the boresight within this of a multiple of 90 deg (degrees) is named as the
/// reading of X and Y that squares it ([`turned_head_note`]).
pub const QUARTER_TOL_DEG: f64 = 15.0;
/// [`turned_head_note`] gives the tilt of the boresight from the board's normal when it is at
/// least this (degrees): below it, an ordinary mounting tolerance.
pub const TILT_SAID_DEG: f64 = 5.0;

/// How a head attitude `p_mrp` (the MRP of eq 65's `C(p)`, board to head) with scale height
/// `h` is turned from square to the board, in degrees: `(total, about the boresight, tilt of
/// the boresight)`. A negative `h` turns the image half a turn about the boresight (eq 65's
/// `H u1 / u3`, `H u2 / u3`), so it counts as 180 deg more; `None` is a model without `H` (it
/// is positive). The turn about the boresight is in (-180, 180]: positive when the image of a
/// beacon on the board's +x axis lies on the head's -y side.
pub fn head_turn(p_mrp: [f64; 3], h: Option<f64>) -> (f64, f64, f64) {
    let mut c = mrp::dcm(&Vector3::from(p_mrp));
    if h.is_some_and(|h| h < 0.0) {
        c = Matrix3::from_diagonal(&Vector3::new(-1.0, -1.0, 1.0)) * c;
    }
    let total = ((c.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let about = (c[(0, 1)] - c[(1, 0)])
        .atan2(c[(0, 0)] + c[(1, 1)])
        .to_degrees();
    let tilt = c[(2, 2)].clamp(-1.0, 1.0).acos().to_degrees();
    (total, about, tilt)
}

/// The reading of X and Y ([`ORIENTATIONS`]) that squares a head turned `quarters` x 90 deg
/// about its boresight ([`head_turn`]'s sense): the image of a beacon in direction `(a, b)` of
/// a square head is `(a cos t + b sin t, -a sin t + b cos t)` on the turned head, and the
/// reading maps it back to `(a, b)`.
fn squaring(quarters: i64) -> &'static Orientation {
    let t = (quarters.rem_euclid(4) as f64) * std::f64::consts::FRAC_PI_2;
    let (s, c) = (t.sin().round(), t.cos().round());
    let turned = |[a, b]: [f64; 2]| [a * c + b * s, -a * s + b * c];
    ORIENTATIONS
        .iter()
        .find(|o| {
            [[1.0, 0.0], [0.0, 1.0]]
                .iter()
                .all(|&e| (o.map)(turned(e)) == e)
        })
        .expect("every quarter turn is one of the readings")
}

/// A warning when a fit's head attitude `p_mrp` (scale height `h`; `None` for a model without
/// `H`: see [`head_turn`]) is turned more than [`TURNED_DEG`] from square to the board: the
/// turn about the boresight (and the boresight's tilt, from [`TILT_SAID_DEG`]), and what it
/// means. Either the head is mounted so, and the fit is right as it is, or X and Y are read
/// turned: within [`QUARTER_TOL_DEG`] of a quarter or half turn, the reading that squares it
/// (the one [`diagnose`] names for a file that cannot be fitted at all).
pub fn turned_head_note(p_mrp: [f64; 3], h: Option<f64>) -> Option<String> {
    let (total, about, tilt) = head_turn(p_mrp, h);
    if !(total > TURNED_DEG) {
        return None;
    }
    if tilt > TURNED_DEG {
        return Some(format!(
            "the fit has the head's boresight tilted {tilt:.0} deg from the board's normal \
             (and the head turned {:.0} deg about it): no swap or sign flip of X and Y squares \
             that: check how the head is mounted and the file's beacon positions \
             (host/MEASUREMENTS.md)",
            about.abs()
        ));
    }
    let half = if h.is_some_and(|h| h < 0.0) {
        " (H is negative: eq 65 turns the image half a turn with it)"
    } else {
        ""
    };
    let tilted = if tilt >= TILT_SAID_DEG {
        format!(", its boresight tilted {tilt:.0} deg from the board's normal")
    } else {
        String::new()
    };
    let quarters = (about / 90.0).round();
    let reading = if quarters != 0.0 && (about - 90.0 * quarters).abs() <= QUARTER_TOL_DEG {
        let o = squaring(quarters as i64);
        format!(
            "the data read {} fit as well with the head square: {}",
            o.what, o.check
        )
    } else {
        "no swap or sign flip of X and Y squares it (those turn it by multiples of 90 deg): \
         check how the head is mounted (host/MEASUREMENTS.md)"
            .into()
    };
    Some(format!(
        "the fit has the head turned {:.0} deg about its boresight from square to the \
         board{half}{tilted}. If the head is mounted so, the fit is right as it is and nothing \
         needs doing; if not, {reading}",
        about.abs()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use cta_core::collinearity::{self, Params};

    fn about_z(deg: f64) -> [f64; 3] {
        mrp::from_axis_angle(&Vector3::z(), deg.to_radians()).into()
    }

    const H0: Option<f64> = Some(18918.6);

    /// A head square to the board, or a few degrees off it (a mounting tolerance), or turned
    /// up to TURNED_DEG: nothing is said.
    #[test]
    fn square_heads_are_not_warned() {
        let few = mrp::from_axis_angle(&Vector3::new(1.0, -2.0, 3.0), 5f64.to_radians());
        for (p, h) in [
            ([0.001, 0.002, 0.001], H0),
            ([0.001, 0.002, 0.001], None),
            (few.into(), H0),
            (about_z(40.0), H0),
            (about_z(-40.0), None),
            // A negative H and a half turn cancel.
            (about_z(180.0), Some(-18918.6)),
        ] {
            assert_eq!(turned_head_note(p, h), None, "{p:?} {h:?}");
        }
    }

    /// `head_turn` reads the turn about the boresight and the tilt apart, with a negative H
    /// half a turn more.
    #[test]
    fn head_turn_separates_turn_and_tilt() {
        let (total, about, tilt) = head_turn(about_z(60.0), H0);
        assert!((total - 60.0).abs() < 1e-9 && (about - 60.0).abs() < 1e-9 && tilt < 1e-6);
        let (total, about, tilt) = head_turn([0.0; 3], Some(-1.0));
        assert!((total - 180.0).abs() < 1e-9 && (about.abs() - 180.0).abs() < 1e-9 && tilt < 1e-6);
        // Turned 90 deg about the boresight, then tilted 10 deg about the head's x.
        let tilt10 = mrp::from_axis_angle(&Vector3::x(), 10f64.to_radians());
        let p = mrp::compose(&tilt10, &Vector3::from(about_z(90.0)));
        let (_, about, tilt) = head_turn(p.into(), H0);
        assert!(
            (about - 90.0).abs() < 1.0 && (tilt - 10.0).abs() < 1e-6,
            "{about} {tilt}"
        );
    }

    /// The reading named for each quarter turn squares eq 65's image: read through it, the
    /// turned head's outputs are the square head's.
    #[test]
    fn the_reading_named_squares_the_image() {
        let square = Params::from_column_slice(&[0.6, 0.1, 0.062, 0.0, 0.0, 0.0, 18918.6]);
        for q in 1..4 {
            let mut turned = square;
            let p = about_z(90.0 * q as f64);
            turned.fixed_rows_mut::<3>(3).copy_from_slice(&p);
            let o = squaring(q);
            for (x, y) in [(3.0, -2.0), (-4.0, 1.0), (0.5, 4.5)] {
                let r = Vector3::new(x, y, 25.0);
                let a = collinearity::predict(&square, &r).unwrap();
                let b = (o.map)(collinearity::predict(&turned, &r).unwrap());
                assert!(
                    (a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6,
                    "{q}: {} {a:?} {b:?}",
                    o.what
                );
            }
            let note = turned_head_note(p, H0).unwrap();
            assert!(
                note.contains(&format!(
                    "turned {:.0} deg about its boresight",
                    90 * (2 - (q - 2).abs())
                )) && note.contains(&format!("the data read {} fit as well", o.what))
                    && note.contains("If the head is mounted so, the fit is right as it is"),
                "{note}"
            );
        }
        assert_eq!(
            squaring(1).what,
            "with X and Y swapped and X's sign flipped"
        );
        assert_eq!(squaring(2).what, "with both X's and Y's signs flipped");
        assert_eq!(
            squaring(-1).what,
            "with X and Y swapped and Y's sign flipped"
        );
    }

    /// Both signs flipped fits eq 65 with H negative and the head square (`cta fit`'s start
    /// reaches it): said as a half turn.
    #[test]
    fn a_negative_h_is_a_half_turn() {
        let note = turned_head_note([0.001, 0.002, 0.001], Some(-18918.6)).unwrap();
        assert!(
            note.contains("turned 180 deg about its boresight")
                && note.contains("H is negative")
                && note.contains("with both X's and Y's signs flipped fit as well"),
            "{note}"
        );
        assert!(!note.contains("tilted"), "{note}");
    }

    /// A turn no reading squares (60 deg), and a tilt worth saying.
    #[test]
    fn other_turns_and_tilts_are_said_as_they_are() {
        let note = turned_head_note(about_z(-60.0), H0).unwrap();
        assert!(
            note.contains("turned 60 deg about its boresight")
                && note.contains("no swap or sign flip of X and Y squares it"),
            "{note}"
        );
        let tilt = mrp::from_axis_angle(&Vector3::y(), 12f64.to_radians());
        let p = mrp::compose(&tilt, &Vector3::from(about_z(180.0)));
        let note = turned_head_note(p.into(), H0).unwrap();
        assert!(
            note.contains("turned 180 deg about its boresight")
                && note.contains("its boresight tilted 12 deg from the board's normal.")
                && note.contains("with both X's and Y's signs flipped"),
            "{note}"
        );
        let p = mrp::from_axis_angle(&Vector3::x(), 70f64.to_radians());
        let note = turned_head_note(p.into(), H0).unwrap();
        assert!(
            note.contains("tilted 70 deg")
                && note.contains("no swap or sign flip of X and Y squares that"),
            "{note}"
        );
    }
}
