//! `cta sweep --estimate`: a plan's duration on the real boards, by part, with the operator's
//! minutes; nothing started and no run folder made.

use std::path::Path;
use std::process::Output;

mod common;
use common::{cta, s};

/// `cta sweep --plan host/plans/PLAN --estimate EXTRA...`.
fn estimate(plan: &str, extra: &[&str]) -> Output {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("plans")
        .join(plan);
    let mut args = vec!["sweep", "--plan", s(&path), "--estimate"];
    args.extend_from_slice(extra);
    cta(&args)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn the_estimate_says_how_long_a_plan_takes_and_starts_nothing() {
    let o = estimate("chvi.toml", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = stdout(&o);
    assert!(
        text.contains("3828 points, up to 19 beacons lit at once, 3485800 samples")
            && text.contains("29 plate moves at 3 min")
            && text.contains("total on the real boards: 7 h 46 min"),
        "{text}"
    );
    // Slower plate moves: 29 more minutes for each minute more a move.
    let text = stdout(&estimate("chvi.toml", &["--plate-move-min", "4"]));
    assert!(
        text.contains("total on the real boards: 8 h 15 min"),
        "{text}"
    );
    let text = stdout(&estimate("chvi-single.toml", &[]));
    assert!(
        text.contains("total on the real boards: 4 d 11 h"),
        "{text}"
    );
}

#[test]
fn minutes_that_are_not_minutes_are_refused_by_name() {
    let o = estimate("chvi.toml", &["--power-switch-min", "-1"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--power-switch-min -1"));
}
