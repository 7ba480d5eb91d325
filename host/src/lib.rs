//! Library half of the `cta` tool, so integration tests can drive it directly.

/// `cta beacon ...`: talk to the beacon board by hand (firmware-beacon issue).
pub mod beacon_cmd;
/// Request/response client over a serial link, shared by both boards (firmware-beacon issue).
pub mod link;
/// `cta sensor ...` and the pose-accuracy table (firmware-sensor issue).
pub mod sensor_cmd;

/// The effect vocabulary shared by `simulate` and `analyze`.
pub mod effects;
/// The measurement file format (`host/MEASUREMENTS.md`).
pub mod measurement;
/// Emulated CTA data with injectable effects and a truth sidecar.
pub mod simulate;
