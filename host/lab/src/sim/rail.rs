//! What a simulation's reports at the 16-bit rail say: how many, at which separations, and the
//! likely cause, so that a head placed off the board (`--d` in millimetres) is caught.

use super::SimConfig;
use crate::data::{any_sample_pinned, Dataset};

/// The note (or warning) on a simulation's reports at the 16-bit rail, when it has any, with
/// its `note: ` or `warning: ` prefix. Close in, beacons at the grid's edge leave a cell of a
/// pair in the dark (a note: the CTA gives the same at 2-3 in); a head far off the board or a
/// view that misses the grid rails reports farther out (a warning).
pub fn rail_note(cfg: &SimConfig, ds: &Dataset) -> Option<String> {
    let railed: Vec<f64> = ds
        .samples
        .iter()
        .filter(|s| any_sample_pinned([*s]))
        .map(|s| s.separation_in)
        .collect();
    if railed.is_empty() {
        return None;
    }
    let total = ds.samples.len();
    let mut at: Vec<f64> = railed.clone();
    at.sort_by(f64::total_cmp);
    at.dedup();
    let shown: Vec<String> = at.iter().take(8).map(|v| format!("{v}")).collect();
    let where_ = format!(
        "at {} in{}",
        shown.join(", "),
        if at.len() > 8 {
            format!(" and {} more separations", at.len() - 8)
        } else {
            String::new()
        }
    );
    let head = format!(
        "{} of {} reports ({:.1} %) are at the 16-bit rail (x or y at +/-32767: a cell of a pair \
         in the dark, so the report says nothing of where the beacon is), {where_}",
        railed.len(),
        total,
        100.0 * railed.len() as f64 / total as f64
    );
    let d = cfg.pose.d;
    let far = d.iter().any(|v| v.abs() > 12.0);
    let close_in = at.last().is_some_and(|&s| s <= 5.0);
    if far {
        Some(format!(
            "warning: {head}: the head offset --d {},{},{} puts the head {:.1} in from the board \
             origin, beyond the beacons' view (a head on the CTA board sits within 12 in of it): \
             --d is in inches (was it given in millimetres? divide by 25.4)",
            d.x,
            d.y,
            d.z,
            d.norm()
        ))
    } else if close_in && 2 * railed.len() <= total {
        Some(format!(
            "note: {head}: close in, beacons at the grid's edge leave a cell of a pair in the \
             dark, as on the CTA (evaluate counts such reports and says so; calibrate, analyze \
             and noise leave their points out)"
        ))
    } else {
        Some(format!(
            "warning: {head}: beacons outside the head's view (the head's attitude --p, the \
             grid, or the effects [{}]?): those reports say nothing of the head",
            cfg.effects
                .iter()
                .map(|e| e.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        ))
    }
}
