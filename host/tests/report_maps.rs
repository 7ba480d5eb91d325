//! The analysis report's residual maps.

mod common;
use common::{cta, s, simulate, tmpdir_of};

/// The report's residual maps: each map is scaled for what it shows, so the final model's
/// residuals (the noise, once the hidden cause is named) get a smaller key than the starting
/// model's wherever the cause stood out of the noise.
#[test]
fn each_residual_map_has_its_own_scale() {
    let d = tmpdir_of("report-maps", "scale");
    let csv = d.join("po.csv");
    simulate(
        &csv,
        &[
            "--separations",
            "6..30:3",
            "--samples",
            "5",
            "--noise",
            "20",
            "--effect",
            "plate_offset=0.03",
        ],
    );
    let report = d.join("report");
    let o = cta(&["analyze", s(&csv), "--report", s(&report), "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    let keys: Vec<f64> = page
        .split("counts of mean residual")
        .filter_map(|chunk| chunk.rsplit("= ").next()?.trim().parse().ok())
        .collect();
    assert!(keys.len() >= 8 && keys.len() % 2 == 0, "{keys:?}");
    // Never larger after; at least twice smaller where the offset stood out of the noise.
    assert!(keys.chunks(2).all(|p| p[1] <= p[0]), "{keys:?}");
    let smaller = keys.chunks(2).filter(|p| p[1] * 2.0 <= p[0]).count();
    assert!(smaller * 2 >= keys.len() / 2, "{keys:?}");
}
