//! Sensor-board messages, carried by the framing of [`crate::wire`].
//!
//! The envelope's [`Request::Identify`](super::Request::Identify) and
//! [`Request::Heartbeat`](super::Request::Heartbeat) work as on every board; the
//! sensor board's own requests are [`SensorRequest`]. Every request is answered (with the
//! request's sequence number). In [`Mode::Stream`] and [`Mode::Pose`] the board also sends,
//! unsolicited, one [`SensorResponse::Spots`] or [`SensorResponse::Pose`] per NorthStar
//! frame, in a frame whose header carries [`SEQ_NONE`](super::SEQ_NONE); each report has
//! its own running sequence number and the board timestamp, so the host sees gaps.
//!
//! The constellation and calibration types, and their validation (fewer than 4 beacons,
//! duplicate IDs, calibration out of range — each named in the error reply), are those of
//! [`crate::pose`], the solver that uses them.

use core::fmt;

use serde::{Deserialize, Serialize};

use super::{BoardKind, DecoderStats, Protocol, ResetCause};
use crate::pose::{
    Calibration, ConfigError, Constellation, ModelKind, PoseSolution, PoseStatus, Spot, MAX_BEACONS,
};

/// Lowest and highest NorthStar light-sensitivity setting.
pub const SENSITIVITY_RANGE: (u8, u8) = (1, 4);
/// Allowed NorthStar report rates, Hz.
pub const RATE_RANGE: (u8, u8) = (1, 50);

/// What the board does with each NorthStar frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    /// Nothing is sent (the NorthStar keeps running; its frames are counted).
    Idle,
    /// Every frame is forwarded as a [`SpotReport`].
    Stream,
    /// Every frame is solved for the 6-dof pose with this model, sent as a [`PoseReport`].
    Pose(ModelKind),
}

/// Sensor-board requests (wrapped in [`super::Request::Board`]).
// Messages live on the stack once per exchange (no heap on the chip): size over boxing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SensorRequest {
    /// Report the board status ([`SensorResponse::Status`]).
    Status,
    /// Change the mode (answered with `Ack`; refused with [`SensorError::NotConfigured`]
    /// for pose mode without a stored constellation and calibration).
    SetMode(Mode),
    /// Set the NorthStar light sensitivity, 1..=4 (forwarded to the detector).
    SetSensitivity(u8),
    /// Set the NorthStar report rate, Hz (1..=50; forwarded to the detector).
    SetRate(u8),
    /// Validate and store (in flash) the sensor calibration.
    LoadCalibration(Calibration),
    /// Validate and store (in flash) the beacon constellation.
    LoadConstellation(Constellation),
    /// Read back what is stored ([`SensorResponse::Config`]).
    GetConfig,
}

/// One NorthStar frame, forwarded in stream mode.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SpotReport {
    /// Board report counter (all reports, spots and poses, share it; wraps).
    pub seq: u32,
    /// Board time when the board decoded the frame, microseconds since reset: after its
    /// last byte arrived, by at most one pass of the board's main loop (on the chip, up to
    /// a pose solve: tens of milliseconds; nothing is solved in stream mode).
    pub t_us: u64,
    /// The NorthStar's own frame counter.
    pub ns_seq: u8,
    /// Sensitivity setting the NorthStar reported.
    pub sensitivity: u8,
    /// The spots.
    pub spots: heapless::Vec<Spot, MAX_BEACONS>,
}

/// One pose solution, sent in pose mode. Sigma fields are `-1` when not available.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseReport {
    /// Board report counter (shared with [`SpotReport::seq`]).
    pub seq: u32,
    /// Board time when the board decoded the NorthStar frame (as [`SpotReport::t_us`]),
    /// microseconds since reset; the solve began then.
    pub t_us: u64,
    /// The NorthStar's frame counter.
    pub ns_seq: u8,
    /// Model used.
    pub model: ModelKind,
    /// Status (the pose is never NaN; see [`crate::pose`]).
    pub status: PoseStatus,
    /// Target origin in the board frame N, inches.
    pub position: [f32; 3],
    /// MRP of the attitude (N -> target frame T).
    pub mrp: [f32; 3],
    /// Position 1-sigma, inches.
    pub sigma_position: [f32; 3],
    /// Attitude 1-sigma about each axis, degrees.
    pub sigma_attitude_deg: [f32; 3],
    /// Residual RMS, counts.
    pub rms: f32,
    /// Condition number of the scaled Jacobian.
    pub condition: f32,
    /// GLSDC iterations.
    pub iterations: u8,
    /// Beacons used.
    pub beacons: u8,
    /// Spot magnitudes fitted with the spots ([`crate::pose::PoseSolution::magnitudes`]): 0
    /// when the pose is from the spots alone (no magnitude law in the calibration, the
    /// pinhole model, or a frame at another sensitivity than the law's).
    pub magnitudes: u8,
    /// Whether the solve started cold (no previous good pose).
    pub cold_start: bool,
    /// The ID of a beacon the solve left out ([`crate::pose::PoseSolution::dropped`]): its
    /// spot disagreed with all the others' (a spot under another beacon's ID), or the frame
    /// reported its ID twice.
    pub dropped: Option<u8>,
    /// Time spent solving on the board, microseconds.
    pub solve_us: u32,
}

/// Where a [`PoseReport`] comes from: the report counter, the frame's decoding time and
/// NorthStar counter, the model and the solve's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseHeader {
    /// Board report counter.
    pub seq: u32,
    /// Board time the frame was decoded, microseconds.
    pub t_us: u64,
    /// The NorthStar's frame counter.
    pub ns_seq: u8,
    /// Model used.
    pub model: ModelKind,
    /// Time spent solving, microseconds.
    pub solve_us: u32,
}

impl PoseReport {
    /// The report of the solution `sol`: the board and the host's off-line solve
    /// (`cta pose`) send the same fields the same way.
    pub fn new(h: PoseHeader, sol: &PoseSolution<f32>) -> PoseReport {
        let a = |v: nalgebra::Vector3<f32>| [v.x, v.y, v.z];
        PoseReport {
            seq: h.seq,
            t_us: h.t_us,
            ns_seq: h.ns_seq,
            model: h.model,
            status: sol.status,
            position: a(sol.position),
            mrp: a(sol.mrp),
            sigma_position: a(sol.sigma_position),
            sigma_attitude_deg: a(sol.sigma_attitude_deg),
            rms: sol.rms,
            condition: sol.condition,
            iterations: sol.iterations,
            beacons: sol.beacons,
            magnitudes: sol.magnitudes,
            cold_start: sol.cold_start,
            dropped: sol.dropped,
            solve_us: h.solve_us,
        }
    }
}

/// NorthStar link counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NorthStarStats {
    /// Frames decoded.
    pub frames: u32,
    /// Frames with a bad CRC.
    pub crc_errors: u32,
    /// Bytes discarded while resynchronising.
    pub discarded: u32,
}

/// Board status.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorStatus {
    /// Time since reset, milliseconds.
    pub uptime_ms: u64,
    /// Current mode.
    pub mode: Mode,
    /// NorthStar sensitivity setting in force (last commanded).
    pub sensitivity: u8,
    /// NorthStar report rate (last commanded), Hz.
    pub rate_hz: u8,
    /// A calibration is stored.
    pub calibrated: bool,
    /// A constellation is stored.
    pub constellation: bool,
    /// Generation of the stored flash record (0: none).
    pub config_generation: u32,
    /// PC-link decoder counters (bad frames by kind).
    pub pc: DecoderStats,
    /// NorthStar-link counters.
    pub northstar: NorthStarStats,
    /// Reports sent (spots and poses).
    pub reports: u32,
    /// Reports dropped because the PC link could not keep up.
    pub dropped: u32,
    /// Requests refused with an error.
    pub refused: u32,
    /// Milliseconds since the last frame from the host.
    pub since_host_ms: u32,
    /// Status of the last pose solve, if any.
    pub last_pose: Option<PoseStatus>,
    /// What started the board last: after a reset its sensitivity and rate are back at 4
    /// and 10 Hz, its mode idle.
    pub reset_cause: ResetCause,
}

/// Stored configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorConfig {
    /// Generation of the flash record (0: nothing stored).
    pub generation: u32,
    /// Stored calibration.
    pub calibration: Option<Calibration>,
    /// Stored constellation.
    pub constellation: Option<Constellation>,
}

/// Sensor-board responses (wrapped in [`super::Response::Board`]).
// Messages live on the stack once per exchange (no heap on the chip): size over boxing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SensorResponse {
    /// Answer to [`SensorRequest::Status`].
    Status(SensorStatus),
    /// Answer to [`SensorRequest::GetConfig`].
    Config(SensorConfig),
    /// Unsolicited, stream mode.
    Spots(SpotReport),
    /// Unsolicited, pose mode.
    Pose(PoseReport),
}

/// Why the sensor board refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SensorError {
    /// The constellation or calibration was rejected (fewer than 4 beacons, duplicate IDs,
    /// a calibration field out of range...).
    Config(ConfigError),
    /// Sensitivity outside 1..=4.
    SensitivityOutOfRange {
        /// Value asked for.
        got: u8,
    },
    /// Rate outside 1..=50 Hz.
    RateOutOfRange {
        /// Value asked for.
        got: u8,
    },
    /// Pose mode needs both a calibration and a constellation.
    NotConfigured {
        /// A calibration is stored.
        calibration: bool,
        /// A constellation is stored.
        constellation: bool,
    },
    /// Writing the flash failed (the previous record is intact).
    Flash,
}

impl fmt::Display for SensorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SensorError::Config(e) => write!(f, "{e}"),
            SensorError::SensitivityOutOfRange { got } => write!(
                f,
                "sensitivity {got} out of range ({}..={})",
                SENSITIVITY_RANGE.0, SENSITIVITY_RANGE.1
            ),
            SensorError::RateOutOfRange { got } => write!(
                f,
                "rate {got} Hz out of range ({}..={})",
                RATE_RANGE.0, RATE_RANGE.1
            ),
            SensorError::NotConfigured {
                calibration,
                constellation,
            } => {
                f.write_str("pose mode needs ")?;
                match (calibration, constellation) {
                    (false, false) => f.write_str("a calibration and a constellation"),
                    (false, true) => f.write_str("a calibration"),
                    _ => f.write_str("a constellation"),
                }?;
                f.write_str(" (load them first)")
            }
            SensorError::Flash => f.write_str("flash write failed (previous record kept)"),
        }
    }
}

impl From<ConfigError> for SensorError {
    fn from(e: ConfigError) -> Self {
        SensorError::Config(e)
    }
}

/// The sensor board's protocol, for generic clients and servers.
pub struct SensorProtocol;

impl Protocol for SensorProtocol {
    const BOARD: BoardKind = BoardKind::Sensor;
    type Request = SensorRequest;
    type Response = SensorResponse;
    type Error = SensorError;
}

#[cfg(test)]
mod tests {
    use super::super::{encode_frame, FrameDecoder, Header, Request, MAX_FRAME};
    use super::*;
    use crate::pose::cta_constellation;

    #[test]
    fn largest_messages_fit_a_frame() {
        let mut con = cta_constellation();
        for i in 10..MAX_BEACONS as u8 {
            con.beacons
                .push(crate::pose::Beacon {
                    id: i,
                    r: [f32::MAX; 3],
                    brightness: f32::MAX,
                })
                .unwrap();
        }
        let mut buf = [0u8; MAX_FRAME];
        let req = Request::Board(SensorRequest::LoadConstellation(con.clone()));
        let f = encode_frame(Header::new(1), &req, &mut buf).unwrap();
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let got = f
            .iter()
            .filter_map(|&b| d.push::<Request<SensorRequest>>(b))
            .next()
            .unwrap();
        assert_eq!(got.unwrap().1, req);
        let spots = heapless::Vec::from_slice(&[Spot::default(); MAX_BEACONS]).unwrap();
        let rep = SpotReport {
            seq: u32::MAX,
            t_us: u64::MAX,
            ns_seq: 1,
            sensitivity: 4,
            spots,
        };
        let reply: super::super::Reply<SensorResponse, SensorError> =
            Ok(super::super::Response::Board(SensorResponse::Spots(rep)));
        assert!(
            encode_frame(Header::new(0), &reply, &mut buf)
                .unwrap()
                .len()
                < 256
        );
    }

    #[test]
    fn errors_name_the_problem() {
        let e = SensorError::Config(ConfigError::DuplicateId { id: 3 });
        assert_eq!(e.to_string(), "duplicate beacon ID 3");
        let e = SensorError::Config(ConfigError::TooFewBeacons { count: 3, min: 4 });
        assert!(e.to_string().contains("3 beacons"));
        let e = SensorError::NotConfigured {
            calibration: false,
            constellation: true,
        };
        assert_eq!(
            e.to_string(),
            "pose mode needs a calibration (load them first)"
        );
    }
}
