//! Placing each separation's plate by its corner readings: the tilts the operator's four
//! corner readings in the run's journal measured ([`crate::sweep::corners`]).

use serde::Serialize;

use super::data::Data;
use crate::sweep::corners::RunCorners;

/// The corner readings' tilts applied to an analysis ([`Analysis::corners`]).
#[derive(Debug, Clone, Serialize)]
pub struct CornersOut {
    /// The journal they were read from.
    pub journal: String,
    /// Per analyzed separation (in the order of [`Analysis::separations`]): the tilt (tx,
    /// ty) applied, deg; `None` where no readings with a known order were journalled (the
    /// plate taken as level).
    pub tilt_deg: Vec<Option<[f64; 2]>>,
    /// Per separation, the corners' twist, in ([`crate::sweep::corners::CornerTilt`]).
    pub twist_in: Vec<Option<f64>>,
    /// The starting model's chi2/dof with every plate taken as level (the gain of placing
    /// them: against [`Analysis::chi2_dof_before`]); `None` when no tilt was applied.
    pub chi2_dof_level: Option<f64>,
    /// What was applied, in words (also among the data notes).
    pub note: String,
}

/// A twist (in) above this says a corner was misread or the plate is not flat: the note
/// warns, naming the separation.
pub const CORNER_TWIST_WARN_IN: f64 = 0.002;

/// Place each separation's plate of `data` with the tilt its corner readings in `rc`
/// measured ([`Data::measured_tilts_deg`]), and say what was applied.
pub(super) fn place_by_corners(rc: &RunCorners, data: &mut Data) -> CornersOut {
    let journal = rc.journal.display().to_string();
    let found: Vec<Option<crate::sweep::corners::CornerTilt>> = data
        .seps
        .iter()
        .map(|s| rc.at(*s).and_then(|p| p.tilt))
        .collect();
    let n = found.iter().flatten().count();
    let unordered = data
        .seps
        .iter()
        .filter(|s| rc.at(**s).is_some_and(|p| p.tilt.is_none()))
        .count();
    let tilt_deg: Vec<Option<[f64; 2]>> = found.iter().map(|t| t.map(|t| t.tilt_deg)).collect();
    let twist_in: Vec<Option<f64>> = found.iter().map(|t| t.map(|t| t.twist_in)).collect();
    let note = if n == 0 {
        format!(
            "{journal} records no corner readings {} for the file's separations: the plates are \
             taken as level",
            if unordered > 0 {
                "with a known order (journalled by an older version)"
            } else {
                "(a --yes run, or the file is not this run's)"
            }
        )
    } else {
        data.measured_tilts_deg = tilt_deg.iter().map(|t| t.unwrap_or_default()).collect();
        let mags: Vec<(f64, f64)> = data
            .seps
            .iter()
            .zip(&tilt_deg)
            .filter_map(|(s, t)| t.map(|t| (*s, t[0].hypot(t[1]))))
            .collect();
        let (at, most) = mags
            .iter()
            .copied()
            .fold((f64::NAN, 0.0), |m, v| if v.1 > m.1 { v } else { m });
        let rms = (mags.iter().map(|m| m.1 * m.1).sum::<f64>() / mags.len() as f64).sqrt();
        let missing: Vec<String> = data
            .seps
            .iter()
            .zip(&tilt_deg)
            .filter(|(_, t)| t.is_none())
            .map(|(s, _)| format!("{s}"))
            .collect();
        let (twist_at, twist) = data
            .seps
            .iter()
            .zip(&twist_in)
            .filter_map(|(s, t)| t.map(|t| (*s, t.abs())))
            .fold((f64::NAN, 0.0), |m, v| if v.1 > m.1 { v } else { m });
        let mut note = format!(
            "plates placed as their corner readings in {journal} tilt them, at {n} of {} \
             separations: |tilt| up to {most:.3} deg (at {at} in), RMS {rms:.3} deg; any \
             plate_tilt named below is the tilt beyond the corners' (--ignore-corners takes \
             the plates as level)",
            data.seps.len()
        );
        if !missing.is_empty() {
            note.push_str(&format!(
                "; level at {} in (no corner readings{})",
                missing.join(", "),
                if unordered > 0 {
                    " with a known order"
                } else {
                    ""
                }
            ));
        }
        if twist > CORNER_TWIST_WARN_IN {
            note.push_str(&format!(
                "; the corners at {twist_at} in twist by {:.1} mils (a flat plate read to 1 mil: \
                 under 1): a corner misread or a plate not flat, and its tilt uncertain by about \
                 that over the rods",
                twist * 1000.0
            ));
        }
        note
    };
    CornersOut {
        journal,
        tilt_deg,
        twist_in,
        chi2_dof_level: None,
        note,
    }
}
