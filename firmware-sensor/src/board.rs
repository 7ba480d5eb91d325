//! The sensor board's logic: PC requests in, NorthStar frames in, replies, spot reports
//! and poses out. Hardware-free: the chip's `main.rs` and the simulated board drive the
//! same [`Board`] through [`Io`].

use core::mem::MaybeUninit;
use cta_core::pose::{
    Calibration, Constellation, ModelKind, PoseSolver, PoseStatus, SolverSettings,
};
use cta_core::wire::sensor::{
    Mode, NorthStarStats, PoseHeader, PoseReport, SensorConfig, SensorError, SensorRequest,
    SensorResponse, SensorStatus, SpotReport, RATE_RANGE, SENSITIVITY_RANGE,
};
use cta_core::wire::{
    encode_frame, BoardKind, ErrorReply, FrameDecoder, Header, Identity, Reply, Request,
    ResetCause, Response, PROTOCOL_VERSION, SEQ_NONE,
};
use serde::{Deserialize, Serialize};

use crate::northstar::{self, NsCommand, NsDecoder, NsEvent, SpotFrame};
use crate::storage::{self, FlashPages};

/// Largest frame the board sends (a full constellation read-back fits with room to spare).
pub const TX_FRAME: usize = 512;

/// Largest frame the board receives (announced as `max_frame` by identify): the largest
/// request, a 20-beacon constellation with its beacons' brightness, takes 366 bytes (a
/// test checks it fits). Half the protocol's
/// [`MAX_FRAME`](cta_core::wire::MAX_FRAME): RAM is the board's tightest budget.
pub const RX_FRAME: usize = 512;

/// Size of the chip's PC-link transmit queue (a `heapless::spsc::Queue`, which holds one
/// byte less): the widest reply, the configuration read-back (487 bytes framed with a full
/// constellation with its beacons' brightness and a calibration holding the near-field
/// part, the pinhole head and the magnitude law), fits (a test checks every reply's widest
/// encoding fits).
pub const TX_QUEUE: usize = 496;

/// Save a configuration to flash from borrowed parts; returns the new generation.
/// `(calibration, constellation)` serialises exactly as [`Stored`] (postcard writes a
/// struct as the tuple of its fields), without a copy of the whole configuration on the
/// stack.
#[inline(never)]
fn save<F: FlashPages>(
    flash: &mut F,
    calibration: Option<&Calibration>,
    constellation: Option<&Constellation>,
) -> Result<u32, SensorError> {
    storage::save(flash, &(calibration, constellation)).map_err(|_| SensorError::Flash)
}

/// What the board needs from its surroundings.
pub trait Io {
    /// Monotonic board time, microseconds since reset.
    fn now_us(&mut self) -> u64;
    /// Send a frame to the PC; `false` if it had to be dropped.
    fn send_pc(&mut self, bytes: &[u8]) -> bool;
    /// Send bytes to the NorthStar.
    fn send_ns(&mut self, bytes: &[u8]);
}

/// Queue a whole frame for an interrupt-driven transmitter, or nothing: `false` (the caller
/// counts it as dropped) when the queue lacks room for all of it. Only the consumer (the
/// interrupt) removes bytes, so the room checked here can only grow before the bytes are in.
pub fn queue_whole(tx: &mut heapless::spsc::Producer<'_, u8>, frame: &[u8]) -> bool {
    if tx.capacity() - tx.len() < frame.len() {
        return false;
    }
    for &b in frame {
        if tx.enqueue(b).is_err() {
            return false;
        }
    }
    true
}

/// What is kept in flash.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Stored {
    /// The sensor calibration.
    pub calibration: Option<Calibration>,
    /// The beacon constellation.
    pub constellation: Option<Constellation>,
}

type SensorReply = Reply<SensorResponse, SensorError>;

/// `us / 1000` without a 64-bit division (a libcall on the Cortex-M3): multiply by
/// `ceil(2^64 / 1000)` and keep the high word; exact for any `us` below ~1500 years.
fn us_to_ms(us: u64) -> u64 {
    ((us as u128 * 18_446_744_073_709_552u128) >> 64) as u64
}

/// The sensor board.
pub struct Board<F: FlashPages> {
    flash: F,
    simulated: bool,
    pc: FrameDecoder<RX_FRAME>,
    ns: NsDecoder,
    mode: Mode,
    sensitivity: u8,
    rate_hz: u8,
    stored: Stored,
    generation: u32,
    /// Configured in place (about 2 KiB: never copied on the stack); `solver_ready` says
    /// whether it holds the stored configuration for pose mode.
    solver: PoseSolver<f32>,
    solver_ready: bool,
    reports: u32,
    dropped: u32,
    refused: u32,
    last_host_us: u64,
    last_pose: Option<PoseStatus>,
    /// Frames in a row whose sensitivity differs from the board's, modulo `RESEND_EVERY`
    /// (see `on_frame`).
    mismatched: u8,
    /// What started the board (reported in its status).
    reset_cause: ResetCause,
}

/// While the detector's frames show another sensitivity than the board set, the settings
/// are sent again on the first such frame and every this many after it.
const RESEND_EVERY: u8 = 10;

impl<F: FlashPages> Board<F> {
    /// Start the board: load the stored configuration (if any) from `flash`. `reset_cause`:
    /// what started it, reported in its status.
    pub fn new(flash: F, simulated: bool, reset_cause: ResetCause) -> Self {
        let (generation, stored) = storage::load::<Stored, F>(&flash).unwrap_or_default();
        Board {
            flash,
            simulated,
            pc: FrameDecoder::new(),
            ns: NsDecoder::new(),
            mode: Mode::Idle,
            sensitivity: 4,
            rate_hz: 10,
            stored,
            generation,
            solver: PoseSolver::blank(),
            solver_ready: false,
            reports: 0,
            dropped: 0,
            refused: 0,
            last_host_us: 0,
            last_pose: None,
            mismatched: 0,
            reset_cause,
        }
    }

    /// Build the board in `slot` (a static on the chip, where the linker's static RAM
    /// counts it) and return it. Never inlined, like [`Self::poll`]: the chip's `main`
    /// and the QEMU harness that measures the board's stack (tests/qemu/src/bin/board.rs)
    /// run the same function with its own frame.
    #[inline(never)]
    pub fn init(
        slot: &mut MaybeUninit<Self>,
        flash: F,
        simulated: bool,
        reset_cause: ResetCause,
    ) -> &mut Self {
        slot.write(Self::new(flash, simulated, reset_cause))
    }

    /// One pass of the main loop: the bytes received from the PC, then those from the
    /// NorthStar (either may be empty). Never inlined (see [`Self::init`]).
    #[inline(never)]
    pub fn poll(&mut self, pc_bytes: &[u8], ns_bytes: &[u8], io: &mut impl Io) {
        self.on_pc_bytes(pc_bytes, io);
        self.on_ns_bytes(ns_bytes, io);
    }

    /// Commands to send the NorthStar at start-up (sensitivity and rate in force).
    pub fn start(&mut self, io: &mut impl Io) {
        self.command_ns(NsCommand::SetSensitivity(self.sensitivity), io);
        self.command_ns(NsCommand::SetRate(self.rate_hz), io);
    }

    /// The stored configuration.
    pub fn stored(&self) -> &Stored {
        &self.stored
    }

    /// The current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Bytes received from the PC. Never inlined into [`Self::poll`] (nor is
    /// [`Self::on_ns_bytes`]): the request being decoded and the frame being parsed do not
    /// share a stack frame.
    #[inline(never)]
    pub fn on_pc_bytes(&mut self, bytes: &[u8], io: &mut impl Io) {
        for &b in bytes {
            let Some(frame) = self.pc.push::<Request<SensorRequest>>(b) else {
                continue;
            };
            self.last_host_us = io.now_us();
            let (seq, reply) = match frame {
                Ok((h, req)) => (h.seq, self.handle(&req, io)),
                Err(e) => (e.seq, Err(ErrorReply::BadFrame(e.fault))),
            };
            if reply.is_err() {
                self.refused = self.refused.saturating_add(1);
            }
            self.send(seq, &reply, io);
        }
    }

    /// Bytes received from the NorthStar. The decoder is asked byte by byte
    /// ([`NsDecoder::push`]), so that it is not borrowed while a frame is handled: no copy of
    /// it on the stack under the pose solve.
    #[inline(never)]
    pub fn on_ns_bytes(&mut self, bytes: &[u8], io: &mut impl Io) {
        for &b in bytes {
            let mut event = self.ns.push(b);
            while let Some(ev) = &event {
                if let NsEvent::Report(frame) = ev {
                    self.on_frame(frame, io);
                }
                event = self.ns.next_event();
            }
        }
    }

    #[inline(never)]
    fn send(&mut self, seq: u16, reply: &SensorReply, io: &mut impl Io) -> bool {
        let mut buf = [0u8; TX_FRAME];
        let ok = match encode_frame(Header::new(seq), reply, &mut buf) {
            Ok(frame) => io.send_pc(frame),
            Err(_) => false,
        };
        if !ok {
            self.dropped = self.dropped.saturating_add(1);
        }
        ok
    }

    fn command_ns(&mut self, cmd: NsCommand, io: &mut impl Io) {
        let mut out = [0u8; 7];
        let n = northstar::encode_command(cmd, &mut out);
        io.send_ns(&out[..n]);
    }

    // The request and frame paths, the solver's construction and the reply's encoding are
    // never inlined into `poll`: each keeps its large temporaries (requests, replies, the
    // solver) in its own frame, so the stack peak is the deepest path, not their sum.
    #[inline(never)]
    fn handle(&mut self, req: &Request<SensorRequest>, io: &mut impl Io) -> SensorReply {
        match req {
            Request::Identify => Ok(Response::Identity(Identity {
                board: BoardKind::Sensor,
                protocol: PROTOCOL_VERSION,
                firmware: heapless::String::try_from(env!("CARGO_PKG_VERSION")).unwrap_or_default(),
                simulated: self.simulated,
                max_frame: RX_FRAME as u16,
            })),
            Request::Heartbeat => Ok(Response::Ack),
            Request::Board(r) => self.handle_board(r, io).map_err(ErrorReply::Board),
        }
    }

    fn handle_board(
        &mut self,
        req: &SensorRequest,
        io: &mut impl Io,
    ) -> Result<Response<SensorResponse>, SensorError> {
        match *req {
            SensorRequest::Status => Ok(Response::Board(SensorResponse::Status(self.status(io)))),
            SensorRequest::GetConfig => Ok(Response::Board(SensorResponse::Config(SensorConfig {
                generation: self.generation,
                calibration: self.stored.calibration,
                constellation: self.stored.constellation.clone(),
            }))),
            SensorRequest::SetMode(mode) => {
                if let Mode::Pose(model) = mode {
                    self.build_solver(model)?;
                } else {
                    self.solver_ready = false;
                }
                self.mode = mode;
                Ok(Response::Ack)
            }
            SensorRequest::SetSensitivity(s) => {
                if !(SENSITIVITY_RANGE.0..=SENSITIVITY_RANGE.1).contains(&s) {
                    return Err(SensorError::SensitivityOutOfRange { got: s });
                }
                self.sensitivity = s;
                self.command_ns(NsCommand::SetSensitivity(s), io);
                Ok(Response::Ack)
            }
            SensorRequest::SetRate(r) => {
                if !(RATE_RANGE.0..=RATE_RANGE.1).contains(&r) {
                    return Err(SensorError::RateOutOfRange { got: r });
                }
                self.rate_hz = r;
                self.command_ns(NsCommand::SetRate(r), io);
                Ok(Response::Ack)
            }
            SensorRequest::LoadCalibration(ref cal) => {
                cal.validate()?;
                self.generation = save(
                    &mut self.flash,
                    Some(cal),
                    self.stored.constellation.as_ref(),
                )?;
                self.stored.calibration = Some(*cal);
                self.rebuild_solver();
                Ok(Response::Ack)
            }
            SensorRequest::LoadConstellation(ref con) => {
                con.validate()?;
                self.generation =
                    save(&mut self.flash, self.stored.calibration.as_ref(), Some(con))?;
                self.stored.constellation = Some(con.clone());
                self.rebuild_solver();
                Ok(Response::Ack)
            }
        }
    }

    /// Configure the solver for `model` from the stored configuration, in place.
    #[inline(never)]
    fn build_solver(&mut self, model: ModelKind) -> Result<(), SensorError> {
        self.solver_ready = false;
        match (&self.stored.calibration, &self.stored.constellation) {
            (Some(cal), Some(con)) => {
                let settings = SolverSettings {
                    model,
                    ..SolverSettings::default()
                };
                self.solver.configure(cal, con, settings)?;
                self.solver_ready = true;
                Ok(())
            }
            (cal, con) => Err(SensorError::NotConfigured {
                calibration: cal.is_some(),
                constellation: con.is_some(),
            }),
        }
    }

    /// A new configuration invalidates the solver (and its warm start).
    fn rebuild_solver(&mut self) {
        if let Mode::Pose(model) = self.mode {
            if self.build_solver(model).is_err() {
                self.mode = Mode::Idle;
            }
        }
    }

    fn status(&mut self, io: &mut impl Io) -> SensorStatus {
        let now = io.now_us();
        let ns = self.ns.stats();
        SensorStatus {
            uptime_ms: us_to_ms(now),
            mode: self.mode,
            sensitivity: self.sensitivity,
            rate_hz: self.rate_hz,
            calibrated: self.stored.calibration.is_some(),
            constellation: self.stored.constellation.is_some(),
            config_generation: self.generation,
            pc: *self.pc.stats(),
            northstar: NorthStarStats {
                frames: ns.frames,
                crc_errors: ns.crc_errors,
                discarded: ns.discarded,
            },
            reports: self.reports,
            dropped: self.dropped,
            refused: self.refused,
            since_host_ms: us_to_ms(now.saturating_sub(self.last_host_us)).min(u32::MAX as u64)
                as u32,
            last_pose: self.last_pose,
            reset_cause: self.reset_cause,
        }
    }

    #[inline(never)]
    fn on_frame(&mut self, frame: &SpotFrame, io: &mut impl Io) {
        let t_us = io.now_us();
        // A detector that booted after the board (or lost power) missed the start-up
        // commands: its frames show another sensitivity. Send both settings again, at most
        // every RESEND_EVERY frames while that lasts (acknowledgements are not awaited).
        if frame.sensitivity != self.sensitivity {
            if self.mismatched == 0 {
                self.start(io);
            }
            self.mismatched = (self.mismatched + 1) % RESEND_EVERY;
        } else {
            self.mismatched = 0;
        }
        let seq = self.reports;
        let body = match self.mode {
            Mode::Idle => return,
            Mode::Stream => SensorResponse::Spots(SpotReport {
                seq,
                t_us,
                ns_seq: frame.seq,
                sensitivity: frame.sensitivity,
                spots: frame.spots.clone(),
            }),
            Mode::Pose(model) => {
                if !self.solver_ready {
                    return;
                }
                // The magnitudes only at the sensitivity their law was fitted at.
                let sol = self.solver.solve_frame(&frame.spots, frame.sensitivity);
                let solve_us = io.now_us().saturating_sub(t_us).min(u32::MAX as u64) as u32;
                self.last_pose = Some(sol.status);
                let header = PoseHeader {
                    seq,
                    t_us,
                    ns_seq: frame.seq,
                    model,
                    solve_us,
                };
                SensorResponse::Pose(PoseReport::new(header, &sol))
            }
        };
        self.reports = self.reports.wrapping_add(1);
        self.send(SEQ_NONE, &Ok(Response::Board(body)), io);
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::storage::RamFlash;
    use cta_core::pose::{cta_constellation, Beacon, CalField, ConfigError, Spot};
    use cta_core::wire::MAX_FRAME;
    use std::vec::Vec;

    /// A calibration with every optional part present (its widest encoding: postcard's
    /// floats have a fixed size).
    fn widest_calibration() -> Calibration {
        Calibration {
            near_field: Some(cta_core::pose::NearField {
                alpha_y_deg: Some(30.0),
                ..cta_core::pose::NearField::nominal()
            }),
            pinhole: Some(cta_core::pose::PinholeHead {
                d: [0.6, 0.1, 1.1],
                p: [0.001, 0.002, 0.001],
            }),
            magnitude: Some(cta_core::pose::Magnitude::simulated(0.07)),
            ..Calibration::table3()
        }
    }

    /// The widest stored record, a 20-beacon constellation at its widest encoding with the
    /// widest calibration, fits a flash record ([`storage::MAX_RECORD`]) and survives a reset.
    #[test]
    fn the_widest_configuration_is_stored_and_survives_a_reset() {
        // As the board saves it ((calibration, constellation), see `save`), every field at
        // its widest encoding.
        let mut wide = cta_core::pose::four_array_constellation();
        for (k, b) in wide.beacons.iter_mut().enumerate() {
            b.r = [-1.0e30, 1.0e-30, f32::MAX - k as f32];
        }
        let cal = widest_calibration();
        let mut flash = RamFlash::default();
        storage::save(&mut flash, &(Some(cal), Some(wide.clone()))).unwrap();
        let (_, back): (u32, Stored) = storage::load(&flash).unwrap();
        assert_eq!(back.calibration, Some(cal));
        assert_eq!(back.constellation, Some(wide));
        // Through the board: the widest calibration and a 20-beacon constellation.
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        let load = SensorRequest::LoadCalibration(cal);
        assert_eq!(request(&mut b, &mut io, 1, load), Ok(Response::Ack));
        let con = cta_core::pose::four_array_constellation();
        let load = SensorRequest::LoadConstellation(con.clone());
        assert_eq!(request(&mut b, &mut io, 2, load), Ok(Response::Ack));
        let b = Board::new(b.flash.clone(), false, ResetCause::PowerOn);
        assert_eq!(b.stored().calibration, Some(cal));
        assert_eq!(b.stored().constellation.as_ref(), Some(&con));
    }

    #[test]
    fn the_largest_request_fits_the_receive_buffer() {
        // A full constellation (every beacon, every field at its widest encoding) and a
        // calibration with every optional part.
        let mut con = cta_core::pose::four_array_constellation();
        for b in con.beacons.iter_mut() {
            b.r = [-1.0e30, 1.0e-30, f32::MAX];
        }
        let cal = widest_calibration();
        let mut buf = [0u8; MAX_FRAME];
        for req in [
            SensorRequest::LoadConstellation(con),
            SensorRequest::LoadCalibration(cal),
        ] {
            let f = encode_frame(Header::new(u16::MAX), &Request::Board(req), &mut buf).unwrap();
            // The decoder keeps one byte free (see FrameDecoder::push).
            assert!(f.len() + 1 < RX_FRAME, "{} bytes", f.len());
            let mut d = FrameDecoder::<RX_FRAME>::new();
            let got = f
                .iter()
                .filter_map(|&b| d.push::<Request<SensorRequest>>(b))
                .last();
            assert!(matches!(got, Some(Ok(_))), "{got:?}");
        }
    }

    #[test]
    fn the_largest_replies_fit_the_transmit_queue() {
        // Every reply at its widest encoding: the configuration read-back (a full
        // constellation and a calibration with every optional part), a stream report with every spot at
        // its extremes, a status with every counter saturated.
        let mut con = cta_core::pose::four_array_constellation();
        for b in con.beacons.iter_mut() {
            b.r = [-1.0e30, 1.0e-30, f32::MAX];
        }
        let cal = widest_calibration();
        let config = SensorResponse::Config(SensorConfig {
            generation: u32::MAX,
            calibration: Some(cal),
            constellation: Some(con),
        });
        let mut spots = heapless::Vec::new();
        while spots
            .push(Spot {
                id: u8::MAX,
                x: i16::MIN,
                y: i16::MIN,
                magnitude: u16::MAX,
            })
            .is_ok()
        {}
        let stream = SensorResponse::Spots(SpotReport {
            seq: u32::MAX,
            t_us: u64::MAX,
            ns_seq: u8::MAX,
            sensitivity: u8::MAX,
            spots,
        });
        let m = u32::MAX;
        let status = SensorResponse::Status(SensorStatus {
            uptime_ms: u64::MAX,
            mode: Mode::Pose(ModelKind::NearField),
            sensitivity: u8::MAX,
            rate_hz: u8::MAX,
            calibrated: true,
            constellation: true,
            config_generation: m,
            pc: cta_core::wire::DecoderStats {
                ok: m,
                oversized: m,
                encoding: m,
                truncated: m,
                crc: m,
                malformed: m,
                version: m,
            },
            northstar: NorthStarStats {
                frames: m,
                crc_errors: m,
                discarded: m,
            },
            reports: m,
            dropped: m,
            refused: m,
            since_host_ms: m,
            last_pose: Some(PoseStatus::IllConditioned),
            reset_cause: ResetCause::Unknown,
        });
        let mut buf = [0u8; TX_FRAME];
        for reply in [config, stream, status] {
            let f = encode_frame(
                Header::new(u16::MAX),
                &Ok::<_, ErrorReply<SensorError>>(Response::Board(reply)),
                &mut buf,
            )
            .unwrap();
            assert!(f.len() < TX_QUEUE, "{} bytes", f.len());
        }
    }

    #[test]
    fn frames_are_queued_whole_or_not_at_all() {
        let mut q = heapless::spsc::Queue::<u8, 8>::new();
        let (mut tx, mut rx) = q.split();
        assert!(queue_whole(&mut tx, &[1, 2, 3, 4, 5]));
        // Two bytes of room left: a three-byte frame is refused and leaves nothing behind.
        assert!(!queue_whole(&mut tx, &[6, 7, 8]));
        assert!(queue_whole(&mut tx, &[6, 7]));
        assert!(!queue_whole(&mut tx, &[9]));
        // The interrupt sends two bytes: exactly two bytes of room again.
        assert_eq!((rx.dequeue(), rx.dequeue()), (Some(1), Some(2)));
        assert!(!queue_whole(&mut tx, &[9, 10, 11]));
        assert!(queue_whole(&mut tx, &[9, 10]));
        let sent: Vec<u8> = core::iter::from_fn(|| rx.dequeue()).collect();
        assert_eq!(sent, [3, 4, 5, 6, 7, 9, 10]);
    }

    type Frame = (Header, SensorReply);

    #[derive(Default)]
    struct FakeIo {
        t: u64,
        pc: Vec<u8>,
        ns: Vec<u8>,
    }

    impl Io for FakeIo {
        fn now_us(&mut self) -> u64 {
            self.t += 10;
            self.t
        }
        fn send_pc(&mut self, bytes: &[u8]) -> bool {
            self.pc.extend_from_slice(bytes);
            true
        }
        fn send_ns(&mut self, bytes: &[u8]) {
            self.ns.extend_from_slice(bytes);
        }
    }

    fn replies(io: &mut FakeIo) -> Vec<Frame> {
        let mut d = FrameDecoder::<MAX_FRAME>::new();
        let out = io
            .pc
            .iter()
            .filter_map(|&b| d.push::<SensorReply>(b))
            .map(|r| r.expect("board frames decode"))
            .collect();
        io.pc.clear();
        out
    }

    fn request(
        board: &mut Board<RamFlash>,
        io: &mut FakeIo,
        seq: u16,
        r: SensorRequest,
    ) -> SensorReply {
        let mut buf = [0u8; MAX_FRAME];
        let f = encode_frame(Header::new(seq), &Request::Board(r), &mut buf).unwrap();
        board.on_pc_bytes(f, io);
        let mut got = replies(io);
        assert_eq!(got.len(), 1);
        let (h, reply) = got.pop().unwrap();
        assert_eq!(h.seq, seq);
        reply
    }

    #[test]
    fn refuses_bad_configurations_by_name() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        let mut con = cta_constellation();
        con.beacons[2].id = con.beacons[0].id;
        let r = request(&mut b, &mut io, 1, SensorRequest::LoadConstellation(con));
        assert_eq!(
            r,
            Err(ErrorReply::Board(SensorError::Config(
                ConfigError::DuplicateId { id: 0 }
            )))
        );
        let mut con = cta_constellation();
        con.beacons.truncate(3);
        let r = request(&mut b, &mut io, 2, SensorRequest::LoadConstellation(con));
        assert!(matches!(
            r,
            Err(ErrorReply::Board(SensorError::Config(
                ConfigError::TooFewBeacons { count: 3, .. }
            )))
        ));
        let mut cal = Calibration::table3();
        cal.d[2] = 40.0;
        let r = request(&mut b, &mut io, 3, SensorRequest::LoadCalibration(cal));
        assert_eq!(
            r,
            Err(ErrorReply::Board(SensorError::Config(
                ConfigError::CalibrationOutOfRange { field: CalField::D }
            )))
        );
        let r = request(
            &mut b,
            &mut io,
            4,
            SensorRequest::SetMode(Mode::Pose(ModelKind::NearField)),
        );
        assert_eq!(
            r,
            Err(ErrorReply::Board(SensorError::NotConfigured {
                calibration: false,
                constellation: false
            }))
        );
        let r = request(&mut b, &mut io, 5, SensorRequest::SetSensitivity(5));
        assert_eq!(
            r,
            Err(ErrorReply::Board(SensorError::SensitivityOutOfRange {
                got: 5
            }))
        );
    }

    #[test]
    fn configuration_survives_a_reset_and_poses_are_reported() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        let con = cta_constellation();
        assert_eq!(
            request(
                &mut b,
                &mut io,
                1,
                SensorRequest::LoadConstellation(con.clone())
            ),
            Ok(Response::Ack)
        );
        assert_eq!(
            request(
                &mut b,
                &mut io,
                2,
                SensorRequest::LoadCalibration(Calibration::table3())
            ),
            Ok(Response::Ack)
        );
        let set = SensorRequest::SetSensitivity(2);
        assert_eq!(request(&mut b, &mut io, 3, set), Ok(Response::Ack));
        assert_eq!(
            request(&mut b, &mut io, 4, SensorRequest::SetRate(20)),
            Ok(Response::Ack)
        );
        // Reset (by the watchdog): a new board on the same flash.
        let flash = b.flash.clone();
        let mut b = Board::new(flash, false, ResetCause::Watchdog);
        // Saved from borrowed parts, read back whole (see `save`).
        assert_eq!(b.stored().constellation.as_ref(), Some(&con));
        assert_eq!(b.stored().calibration, Some(Calibration::table3()));
        // The status says why it started, and that the settings are the start-up ones.
        match request(&mut b, &mut io, 5, SensorRequest::Status) {
            Ok(Response::Board(SensorResponse::Status(s))) => {
                assert_eq!(s.reset_cause, ResetCause::Watchdog);
                assert_eq!((s.sensitivity, s.rate_hz, s.mode), (4, 10, Mode::Idle));
                assert!(s.calibrated && s.constellation, "{s:?}");
            }
            other => panic!("expected the status, got {other:?}"),
        }
        assert_eq!(
            request(
                &mut b,
                &mut io,
                6,
                SensorRequest::SetMode(Mode::Pose(ModelKind::Pinhole))
            ),
            Ok(Response::Ack)
        );
        // A far-field-ish frame: target 20 in away, spots from the pinhole model.
        let solver = PoseSolver::<f64>::new(
            &Calibration::table3(),
            &con,
            SolverSettings {
                model: ModelKind::Pinhole,
                ..Default::default()
            },
        )
        .unwrap();
        let x = nalgebra::SVector::<f64, 6>::new(0.1, 0.2, 20.0, 0.0, 0.0, 0.0);
        let mut frame = SpotFrame {
            seq: 7,
            sensitivity: 4,
            spots: heapless::Vec::new(),
        };
        for Beacon { id, r, .. } in &con.beacons {
            let r = nalgebra::Vector3::new(r[0] as f64, r[1] as f64, r[2] as f64);
            let y = solver.predict(&x, &r).unwrap();
            frame
                .spots
                .push(Spot {
                    id: *id,
                    x: y[0].round() as i16,
                    y: y[1].round() as i16,
                    magnitude: 9000,
                })
                .unwrap();
        }
        let mut bytes = [0u8; northstar::MAX_FRAME];
        let n = northstar::encode_report(&frame, &mut bytes);
        // Line noise first: the board must still find the frame.
        b.on_ns_bytes(&[0xA5, 0x5A, 0x01, 0x30, 0x00, 0x13], &mut io);
        b.on_ns_bytes(&bytes[..n], &mut io);
        let got = replies(&mut io);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].0.seq, SEQ_NONE);
        match &got[0].1 {
            Ok(Response::Board(SensorResponse::Pose(p))) => {
                assert_eq!(p.status, PoseStatus::Ok, "{p:?}");
                assert_eq!(p.ns_seq, 7);
                assert!((p.position[2] - 20.0).abs() < 0.05, "{p:?}");
            }
            other => panic!("expected a pose, got {other:?}"),
        }
    }

    /// The calibration's pinhole head is kept in flash with the rest, and a record of
    /// format 3 (written before the calibration held it) is ignored: the board starts
    /// unconfigured, as firmware-sensor/README.md says, instead of reading the old bytes as
    /// the new type.
    #[test]
    fn pinhole_head_survives_a_reset_and_an_older_record_is_ignored() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        let cal = widest_calibration();
        let con = cta_constellation();
        let load = SensorRequest::LoadCalibration(cal);
        assert_eq!(request(&mut b, &mut io, 1, load), Ok(Response::Ack));
        let load = SensorRequest::LoadConstellation(con.clone());
        assert_eq!(request(&mut b, &mut io, 2, load), Ok(Response::Ack));
        let b = Board::new(b.flash.clone(), false, ResetCause::PowerOn);
        assert_eq!(b.stored().calibration, Some(cal));

        // Format 3's calibration: the same fields without the pinhole head.
        #[derive(Serialize, Deserialize)]
        struct CalibrationV3 {
            d: [f32; 3],
            p: [f32; 3],
            h: f32,
            noise: f32,
            near_field: Option<cta_core::pose::NearField>,
        }
        type StoredV3 = (Option<CalibrationV3>, Option<Constellation>);
        let t = Calibration::table3();
        let old: StoredV3 = (
            Some(CalibrationV3 {
                d: t.d,
                p: t.p,
                h: t.h,
                noise: t.noise,
                near_field: t.near_field,
            }),
            Some(con),
        );
        let mut flash = RamFlash::default();
        storage::save(&mut flash, &old).unwrap();
        // The header as format 3 wrote it: version 3, its CRC.
        let page = &mut flash.pages[0];
        page[4..6].copy_from_slice(&3u16.to_le_bytes());
        let n = usize::from(u16::from_le_bytes([page[6], page[7]]));
        let crc = cta_core::wire::crc32c(&page[..12 + n]);
        page[12 + n..16 + n].copy_from_slice(&crc.to_le_bytes());
        // Refused by its version, even to a reader of its own layout.
        assert!(storage::load::<StoredV3, _>(&flash).is_none());
        let mut b = Board::new(flash, false, ResetCause::PowerOn);
        assert_eq!(b.stored(), &Stored::default());
        let pose = SensorRequest::SetMode(Mode::Pose(ModelKind::Pinhole));
        assert_eq!(
            request(&mut b, &mut io, 3, pose),
            Err(ErrorReply::Board(SensorError::NotConfigured {
                calibration: false,
                constellation: false
            }))
        );
    }

    /// With a magnitude law in the calibration the near-field pose fits the spot magnitudes
    /// of frames at the law's sensitivity, and says so in its report; frames at another
    /// sensitivity are solved from the spots alone (`magnitudes` 0), as is every pinhole pose.
    #[test]
    fn magnitudes_are_fitted_at_the_laws_sensitivity_only() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        let cal = Calibration {
            magnitude: Some(cta_core::pose::Magnitude::simulated(0.07)),
            ..Calibration::table3()
        };
        assert_eq!(cal.magnitude.unwrap().sensitivity, 4);
        let load = SensorRequest::LoadCalibration(cal);
        assert_eq!(request(&mut b, &mut io, 1, load), Ok(Response::Ack));
        let load = SensorRequest::LoadConstellation(cta_constellation());
        assert_eq!(request(&mut b, &mut io, 2, load), Ok(Response::Ack));
        let (f1, f2, t2, _) = cta_core::pose::benchmark_frames();
        let pose =
            |b: &mut Board<RamFlash>, io: &mut FakeIo, spots: &heapless::Vec<Spot, 20>, s: u8| {
                let frame = SpotFrame {
                    seq: 1,
                    sensitivity: s,
                    spots: spots.clone(),
                };
                let mut bytes = [0u8; northstar::MAX_FRAME];
                let n = northstar::encode_report(&frame, &mut bytes);
                b.on_ns_bytes(&bytes[..n], io);
                let mut got = replies(io);
                assert_eq!(got.len(), 1);
                match got.pop().unwrap().1 {
                    Ok(Response::Board(SensorResponse::Pose(p))) => p,
                    other => panic!("expected a pose, got {other:?}"),
                }
            };
        for (model, fitted) in [(ModelKind::NearField, 10), (ModelKind::Pinhole, 0)] {
            let mode = SensorRequest::SetMode(Mode::Pose(model));
            assert_eq!(request(&mut b, &mut io, 3, mode), Ok(Response::Ack));
            for (spots, s, want) in [
                (&f1, 4, fitted),
                (&f2, 4, fitted),
                (&f2, 3, 0),
                (&f2, 4, fitted),
            ] {
                let p = pose(&mut b, &mut io, spots, s);
                assert_eq!(p.status, PoseStatus::Ok, "{model:?} at {s}: {p:?}");
                assert_eq!(p.magnitudes, want, "{model:?} at {s}: {p:?}");
                assert_eq!(p.beacons, 10, "{p:?}");
                if model == ModelKind::NearField {
                    assert!((p.position[2] as f64 - t2.z).abs() < 0.1, "{p:?}");
                }
            }
        }
    }

    /// A record of format 4 (protocol 5 and 6: no magnitude law in the calibration, no
    /// brightness in the beacons) is ignored: read as format 5's types its bytes would not
    /// give back what was stored, so the version, not the decoding, has to tell them apart.
    #[test]
    fn a_format_4_record_is_ignored() {
        #[derive(Serialize, Deserialize)]
        struct CalibrationV4 {
            d: [f32; 3],
            p: [f32; 3],
            h: f32,
            noise: f32,
            near_field: Option<cta_core::pose::NearField>,
            pinhole: Option<cta_core::pose::PinholeHead>,
        }
        #[derive(Serialize, Deserialize)]
        struct BeaconV4 {
            id: u8,
            r: [f32; 3],
        }
        #[derive(Serialize, Deserialize)]
        struct ConstellationV4 {
            beacons: heapless::Vec<BeaconV4, 20>,
            boresight: [f32; 3],
        }
        type StoredV4 = (Option<CalibrationV4>, Option<ConstellationV4>);
        let t = widest_calibration();
        let con = cta_constellation();
        let old: StoredV4 = (
            Some(CalibrationV4 {
                d: t.d,
                p: t.p,
                h: t.h,
                noise: t.noise,
                near_field: t.near_field,
                pinhole: t.pinhole,
            }),
            Some(ConstellationV4 {
                beacons: con
                    .beacons
                    .iter()
                    .map(|b| BeaconV4 { id: b.id, r: b.r })
                    .collect(),
                boresight: con.boresight,
            }),
        );
        let mut flash = RamFlash::default();
        storage::save(&mut flash, &old).unwrap();
        let page = &mut flash.pages[0];
        let n = usize::from(u16::from_le_bytes([page[6], page[7]]));
        // Format 4's bytes read as format 5's types: not what was stored.
        let misread = postcard::from_bytes::<Stored>(&page[12..12 + n]);
        let stored = Stored {
            calibration: Some(Calibration {
                magnitude: None,
                ..t
            }),
            constellation: Some(con),
        };
        assert!(misread.as_ref() != Ok(&stored), "{misread:?}");
        // The header as format 4 wrote it: version 4, its CRC.
        page[4..6].copy_from_slice(&4u16.to_le_bytes());
        let crc = cta_core::wire::crc32c(&page[..12 + n]);
        page[12 + n..16 + n].copy_from_slice(&crc.to_le_bytes());
        assert!(storage::load::<StoredV4, _>(&flash).is_none());
        let b = Board::new(flash, false, ResetCause::PowerOn);
        assert_eq!(b.stored(), &Stored::default());
    }

    /// A detector that missed the start-up commands (it booted later) reports its own
    /// sensitivity: the board sends both settings again, on the first such frame and every
    /// tenth after it, and stops once the frames agree.
    #[test]
    fn settings_are_sent_again_while_the_detector_disagrees() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        b.start(&mut io);
        let sent = |io: &mut FakeIo| -> Vec<NsCommand> {
            let out = io
                .ns
                .chunks(7)
                .map(|c| northstar::decode_command(c).expect("whole commands"))
                .collect();
            io.ns.clear();
            out
        };
        let settings = std::vec![NsCommand::SetSensitivity(4), NsCommand::SetRate(10)];
        assert_eq!(sent(&mut io), settings);
        let frame = |sensitivity: u8| {
            let f = SpotFrame {
                seq: 0,
                sensitivity,
                spots: heapless::Vec::new(),
            };
            let mut bytes = [0u8; northstar::MAX_FRAME];
            let n = northstar::encode_report(&f, &mut bytes);
            bytes[..n].to_vec()
        };
        let mut resent = Vec::new();
        for k in 0..25 {
            b.on_ns_bytes(&frame(2), &mut io);
            if !io.ns.is_empty() {
                assert_eq!(sent(&mut io), settings, "frame {k}");
                resent.push(k);
            }
        }
        assert_eq!(resent, [0, 10, 20]);
        // Agreement ends it; a later disagreement starts again at once.
        b.on_ns_bytes(&frame(4), &mut io);
        b.on_ns_bytes(&frame(4), &mut io);
        assert!(io.ns.is_empty());
        b.on_ns_bytes(&frame(3), &mut io);
        assert_eq!(sent(&mut io), settings);
    }

    #[test]
    fn milliseconds_are_exact() {
        for us in [
            0u64,
            999,
            1000,
            1999,
            123_456_789,
            u32::MAX as u64 * 1000 + 999,
            1 << 50,
        ] {
            assert_eq!(us_to_ms(us), us / 1000, "{us}");
        }
    }

    #[test]
    fn bad_frames_are_answered_and_counted() {
        let mut b = Board::new(RamFlash::default(), false, ResetCause::PowerOn);
        let mut io = FakeIo::default();
        b.on_pc_bytes(&[0, 1, 2, 3, 4, 5, 6, 0], &mut io);
        let got = replies(&mut io);
        assert_eq!(got.len(), 1);
        assert!(matches!(got[0].1, Err(ErrorReply::BadFrame(_))));
        match request(&mut b, &mut io, 9, SensorRequest::Status) {
            Ok(Response::Board(SensorResponse::Status(s))) => {
                assert_eq!(s.pc.bad(), 1);
                assert_eq!(s.refused, 1);
            }
            other => panic!("{other:?}"),
        }
    }
}
