//! Library half of the `cta` tool, so integration tests can drive it directly.

// Checks are written `!(x > 0.0)` on purpose: a NaN fails them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// `cta beacon ...`: talk to the beacon board by hand (firmware-beacon issue).
pub mod beacon_cmd;
// Request/response client over a serial link, shared by both boards (firmware-beacon issue).
pub mod link;
// The CTA's beacon plate and the built-in constellations of the pose analyses (issue 5).
pub mod plate;
// `cta sensor floor`: the pose noise floor from spots alone and with magnitudes (issue 5).
pub mod pose_floor;
// `cta sensor ...` and the pose-accuracy table (firmware-sensor issue).
pub mod sensor_cmd;
// `cta calibrate`: the sensor board's calibration file from a measured sweep.
pub mod calibrate;
// The spot magnitude law (and each LED's brightness) `cta calibrate` fits to a sweep.
pub mod magnitude;

// The thesis subcommands.
pub mod commands;
// The effect vocabulary shared by `simulate` and `analyze`.
pub mod effects;
// The Ch V calibration fit and its evaluation.
pub mod fit;
// The measurement file format (`host/MEASUREMENTS.md`).
pub mod measurement;
// SVG charts.
pub mod plot;
// Emulated CTA data with injectable effects and a truth sidecar.
pub mod simulate;

// `cta analyze`: from measured data to a named cause, an extended model and a measured gain.
pub mod analyze;
// `cta demo`: the main job on the simulated CTA.
pub mod demo;
// `cta noise`: the noise of repeated samples and the weighting it implies.
pub mod noise;
// `cta sweep`: autonomous, resumable CTA data collection over serial (and the simulated CTA).
pub mod sweep;

/// What the binary does with a command's error: prints `cta: error: ...` with its causes and
/// exits with 1, or an interrupted sweep's [`sweep::Interrupted::exit_code`] (128 + the
/// signal). Returns on success.
pub fn exit_on_error(r: anyhow::Result<()>) {
    if let Err(e) = r {
        eprintln!("cta: error: {e:#}");
        let code = e
            .downcast_ref::<sweep::Interrupted>()
            .map_or(1, |i| i.exit_code);
        std::process::exit(code);
    }
}
