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
//! fits (about 0.05 s on 11,600 reports), run only when the file could not be fitted.

use crate::fit::{self, Weights};
use crate::measurement::{any_sample_pinned, fmt_list, Dataset};
use cta_core::collinearity::{Obs, ParamsExt};
use cta_core::emulator::Head;
use nalgebra::Vector3;

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
    match diagnose(ds) {
        Some(d) => format!("{}. {d}", err.trim_end_matches('.')),
        None => err,
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
/// Close in the pinhole model's H moves far by itself (1.9x at 2-3 in on thesis data: the
/// near-field errors it cannot follow), so below 20 in only a named mistake is said.
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
