//! How long a run takes on the real boards, before anything starts (`cta sweep --estimate`),
//! and the model the progress bar's ETA scales by the pace it measures.
//!
//! A point takes its settle time, one report to start the stream, `samples` reports at the
//! plan's `rate_hz` (the NorthStar reports every spot lit, so a group takes no longer than one
//! beacon) and the requests around it. The manual steps come on top: a plate move with its
//! four corner readings at each separation, the power switches when the power level changes
//! (the serpentine order flips them once per plate position), an array mount per quadrant in
//! the quad layout. Their durations are the operator's, not the boards': [`Steps`] holds
//! assumed values a lab replaces with its own.

use super::plan::Plan;

/// Requests around a point (light the beacons, stream on and off, beacons off), s: four
/// exchanges of a few dozen bytes at 115,200 baud, each answered within a pass of the
/// board's main loop. The same figure times simulated files ([`crate::sim::sweep_time`]).
pub const REQUESTS_S: f64 = crate::sim::SIM_REQUESTS_S;

/// Durations of the manual steps, s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Steps {
    /// Move the plate to the next separation and read its four corners.
    pub plate_move_s: f64,
    /// Flip the array's power switches.
    pub power_switch_s: f64,
    /// Mount the array in the next quadrant (quad layout).
    pub quadrant_s: f64,
}

impl Default for Steps {
    /// Assumed: 3 minutes a plate move (four nuts on threaded rods, four dial readings), a
    /// minute for the switches, 5 minutes an array mount.
    fn default() -> Self {
        Steps {
            plate_move_s: crate::sim::SIM_PLATE_MOVE_S,
            power_switch_s: 60.0,
            quadrant_s: 300.0,
        }
    }
}

/// A run's duration on the real boards, by part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Points to measure.
    pub points: usize,
    /// Samples they take.
    pub samples: u64,
    /// One point's duration, s ([`point_seconds`]).
    pub point_s: f64,
    /// All points, s.
    pub measuring_s: f64,
    /// Plate moves.
    pub plate_moves: usize,
    /// Power switch changes.
    pub power_switches: usize,
    /// Array mounts (quad layout).
    pub quadrant_mounts: usize,
    /// The manual steps, s.
    pub manual_s: f64,
    /// Everything, s.
    pub total_s: f64,
}

/// One point's duration on the real boards, s: settle, one report for the stream to start,
/// `samples` reports at `rate_hz`, and the requests ([`REQUESTS_S`]).
pub fn point_seconds(plan: &Plan) -> f64 {
    plan.settle_ms as f64 / 1000.0 + (plan.samples as f64 + 1.0) / plan.rate_hz as f64 + REQUESTS_S
}

/// The modelled time at which each point of `plan` starts, counted from the run's start, with
/// the manual steps before it; the last entry is the run's end (`len() + 1` entries).
pub fn timeline(plan: &Plan, steps: &Steps) -> Vec<f64> {
    let point = point_seconds(plan);
    let mut t = Vec::with_capacity(plan.len() + 1);
    let mut now = 0.0;
    let mut last: Option<(usize, usize, u8)> = None;
    for i in 0..plan.len() {
        let p = plan.point(i);
        now += manual(last, (p.sep_idx, p.quadrant, p.power), plan, steps).3;
        last = Some((p.sep_idx, p.quadrant, p.power));
        t.push(now);
        now += point;
    }
    t.push(now);
    t
}

/// The manual steps between the place and power `last` (`None`: the run's start) and `next`:
/// (plate moves, array mounts, power switches, their duration).
fn manual(
    last: Option<(usize, usize, u8)>,
    next: (usize, usize, u8),
    plan: &Plan,
    steps: &Steps,
) -> (usize, usize, usize, f64) {
    let moved = last.is_none_or(|l| l.0 != next.0);
    let mounted =
        plan.layout.quadrants() > 1 && last.is_none_or(|l| (l.0, l.1) != (next.0, next.1));
    let switched = last.is_none_or(|l| l.2 != next.2);
    let (m, q, s) = (
        usize::from(moved),
        usize::from(mounted),
        usize::from(switched),
    );
    (
        m,
        q,
        s,
        m as f64 * steps.plate_move_s
            + q as f64 * steps.quadrant_s
            + s as f64 * steps.power_switch_s,
    )
}

/// The duration of points `from..` of `plan` on the real boards.
pub fn estimate(plan: &Plan, from: usize, steps: &Steps) -> Estimate {
    let mut e = Estimate {
        points: plan.len().saturating_sub(from),
        samples: 0,
        point_s: point_seconds(plan),
        measuring_s: 0.0,
        plate_moves: 0,
        power_switches: 0,
        quadrant_mounts: 0,
        manual_s: 0.0,
        total_s: 0.0,
    };
    let mut last = None;
    for i in from..plan.len() {
        let p = plan.point(i);
        let (m, q, s, t) = manual(last, (p.sep_idx, p.quadrant, p.power), plan, steps);
        last = Some((p.sep_idx, p.quadrant, p.power));
        e.plate_moves += m;
        e.quadrant_mounts += q;
        e.power_switches += s;
        e.manual_s += t;
        e.samples += p.lit.len() as u64 * plan.samples as u64;
    }
    e.measuring_s = e.points as f64 * e.point_s;
    e.total_s = e.measuring_s + e.manual_s;
    e
}

/// A duration as people read it: `4 d 1 h 12 min`, `5 h 3 min`, `12 min 5 s`, `8.2 s`.
pub fn human(s: f64) -> String {
    let t = s.round() as u64;
    let (d, h, m, sec) = (t / 86_400, t / 3600 % 24, t / 60 % 60, t % 60);
    if d > 0 {
        format!("{d} d {h} h {m} min")
    } else if h > 0 {
        format!("{h} h {m} min")
    } else if m > 0 {
        format!("{m} min {sec} s")
    } else {
        format!("{s:.1} s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn shipped(name: &str) -> Plan {
        Plan::load(
            &Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../plans")
                .join(name),
        )
        .unwrap()
    }

    /// The one-at-a-time Ch VI scheme: 69,600 points of 0.3 s settle, 51 reports at 10 Hz and
    /// the requests; 29 plate moves, and the switches set at the start and flipped once per
    /// plate position (serpentine): about 4 days.
    #[test]
    fn the_single_ch_vi_plan_takes_days_and_the_grouped_one_hours() {
        let steps = Steps::default();
        let single = estimate(&shipped("chvi-single.toml"), 0, &steps);
        assert!((single.point_s - (0.3 + 5.1 + REQUESTS_S)).abs() < 1e-12);
        assert_eq!(
            (single.points, single.plate_moves, single.power_switches),
            (69_600, 29, 30)
        );
        assert_eq!(single.samples, 3_480_000);
        let days = single.total_s / 86_400.0;
        assert!((4.0..4.6).contains(&days), "{days}");
        let grouped = estimate(&shipped("chvi.toml"), 0, &steps);
        assert_eq!(grouped.samples, 3_480_000 + 29 * 4 * 50);
        let hours = grouped.total_s / 3600.0;
        eprintln!("single {days:.2} d, grouped {hours:.2} h");
        assert!(hours < 8.0, "{hours}");
        assert!(single.total_s / grouped.total_s > 10.0);
        // The timeline ends where the estimate does.
        let t = timeline(&shipped("chvi.toml"), &steps);
        assert!((t[t.len() - 1] - grouped.total_s).abs() < 1e-6 * grouped.total_s);
        // From the middle: what is left.
        let half = estimate(&shipped("chvi.toml"), grouped.points / 2, &steps);
        assert!(half.total_s < 0.55 * grouped.total_s && half.total_s > 0.45 * grouped.total_s);
    }

    #[test]
    fn durations_read_as_people_say_them() {
        assert_eq!(human(4.0 * 86_400.0 + 3600.0 + 720.0), "4 d 1 h 12 min");
        assert_eq!(human(5.0 * 3600.0 + 180.0), "5 h 3 min");
        assert_eq!(human(725.0), "12 min 5 s");
        assert_eq!(human(8.24), "8.2 s");
    }
}
