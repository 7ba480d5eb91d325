//! Peak stack of the sensor board's work on a Cortex-M3 (QEMU lm3s6965evb): the same
//! [`Board::init`] and [`Board::poll`] the chip's `main` calls (firmware-sensor/src/chip.rs),
//! built at the firmware's opt-level, fed a session that reaches every deep path: identify,
//! status, a bad frame, loading the calibration (with every optional part: the near-field
//! physics, the pinhole head and the magnitude law) and the 20-beacon constellation (stored
//! to flash, solver built), reading the configuration back, pose mode with the near-field
//! model, then NorthStar frames at the magnitude law's sensitivity solved for the pose with
//! the spot magnitudes (cold start, then warm starts: 20 beacons' spots and magnitudes are
//! more rows than the solver carries from frame to frame), then frames at another
//! sensitivity solved from the spots alone (with the carried linearisation), then stream
//! mode.
//!
//! The instruction counts (run.sh) are of warm frames in pose mode, from the NorthStar's bytes
//! to the pose report sent (decoding, matching, the 20-beacon near-field solve and encoding):
//! segments 1-3 with the magnitudes, 4-5 from the spots alone (`board: counts=...`).
//!
//! Prints `STACK board_peak_bytes=N`: the bytes of stack used below this program's `main`
//! by `init`, by the requests up to pose mode, or by the rest of the session (the NorthStar
//! frames among it), whichever is more (the stack is painted before each and scanned
//! after). firmware-sensor/ci.sh adds the
//! chip's own `main` frame (from its disassembly) and an interrupt allowance, and the
//! firmware's static RAM (the board lives in a static there, as here).
#![no_std]
#![no_main]

use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use cta_core::pose::{
    benchmark_frames_of, four_array_constellation, Calibration, Magnitude, ModelKind, NearField,
    PinholeHead, PoseStatus,
};
use cta_core::wire::sensor::{Mode, SensorRequest, SensorResponse};
use cta_core::wire::{encode_frame, FrameDecoder, Header, Reply, Request, ResetCause, MAX_FRAME};
use cta_firmware_sensor::board::{Board, Io};
use cta_firmware_sensor::northstar::{self, SpotFrame};
use cta_firmware_sensor::storage::RamFlash;
use cta_qemu::{done, end, fail, mark, paint_stack, stack_used};

/// Stack region painted below the current stack pointer.
const PAINT: usize = 24 * 1024;

/// The PC side: counts frames, keeps the last one.
struct HarnessIo {
    t_us: u64,
    frames: u32,
    last: [u8; 512],
    last_len: usize,
}

impl Io for HarnessIo {
    fn now_us(&mut self) -> u64 {
        self.t_us += 100;
        self.t_us
    }
    fn send_pc(&mut self, bytes: &[u8]) -> bool {
        self.frames += 1;
        let n = bytes.len().min(self.last.len());
        self.last[..n].copy_from_slice(&bytes[..n]);
        self.last_len = n;
        true
    }
    fn send_ns(&mut self, _bytes: &[u8]) {}
}

/// The pose report of the last frame sent: `(status, beacons, magnitudes)`.
fn last_pose(io: &HarnessIo) -> Option<(PoseStatus, u8, u8)> {
    let mut d = FrameDecoder::<MAX_FRAME>::new();
    let mut last = None;
    for &b in &io.last[..io.last_len] {
        if let Some(r) = d.push::<Reply<SensorResponse, cta_core::wire::sensor::SensorError>>(b) {
            last = Some(r);
        }
    }
    match last {
        Some(Ok((_, Ok(cta_core::wire::Response::Board(SensorResponse::Pose(p)))))) => {
            Some((p.status, p.beacons, p.magnitudes))
        }
        _ => None,
    }
}

/// A NorthStar report of `spots` at `sensitivity`, as bytes on the wire; returns their length.
fn ns_frame(
    seq: u8,
    sensitivity: u8,
    spots: &heapless::Vec<cta_core::pose::Spot, 20>,
    bytes: &mut [u8; northstar::MAX_FRAME],
) -> usize {
    let frame = SpotFrame {
        seq,
        sensitivity,
        spots: spots.clone(),
    };
    northstar::encode_report(&frame, bytes)
}

/// One request from the PC, as bytes on the wire, handed to the board from `main`'s frame as
/// the chip's `main` hands it the bytes of its receive queue (a static). Always inlined, its
/// encoding buffer a static: neither is on the stack measured below `main` (until 2026-11-28
/// this function had a frame of its own, 1,120 B with its 1 KiB buffer, under every
/// request the board handled: the requests' path was measured that much deeper than the
/// chip's).
#[inline(always)]
fn pc(io: &mut HarnessIo, board: &mut Board<RamFlash>, seq: u16, req: Request<SensorRequest>) {
    static mut BUF: [u8; MAX_FRAME] = [0; MAX_FRAME];
    // SAFETY: one thread, and the borrow ends with this call.
    let buf = unsafe { &mut *core::ptr::addr_of_mut!(BUF) };
    let Ok(f) = encode_frame(Header::new(seq), &req, buf) else {
        fail("request does not encode")
    };
    board.poll(f, &[], io);
}

#[entry]
fn main() -> ! {
    static mut BOARD: MaybeUninit<Board<RamFlash>> = MaybeUninit::uninit();
    let con = four_array_constellation();
    let (f1, f2, _, _) = benchmark_frames_of(&con);
    // Every optional part (the widest calibration), the magnitude law the simulated
    // NorthStar's, at sensitivity 4.
    let cal = Calibration {
        near_field: Some(NearField {
            alpha_y_deg: Some(30.0),
            ..NearField::nominal()
        }),
        pinhole: Some(PinholeHead {
            d: [0.6, 0.1, 0.062],
            p: [0.001, 0.002, 0.001],
        }),
        magnitude: Some(Magnitude::simulated(0.07)),
        ..Calibration::table3()
    };
    let law = Magnitude::simulated(0.07).sensitivity;
    let mut io = HarnessIo {
        t_us: 0,
        frames: 0,
        last: [0; 512],
        last_len: 0,
    };
    let (lo, sp) = paint_stack(PAINT);
    let board = Board::init(BOARD, RamFlash::default(), false, ResetCause::PowerOn);
    let init_used = stack_used(lo, sp);
    let (lo, sp) = paint_stack(PAINT);
    board.start(&mut io);
    pc(&mut io, board, 1, Request::Identify);
    pc(&mut io, board, 2, Request::Board(SensorRequest::Status));
    board.poll(&[0x13, 0x37, 0x00, 0x42, 0x00], &[], &mut io);
    pc(
        &mut io,
        board,
        3,
        Request::Board(SensorRequest::LoadCalibration(cal)),
    );
    pc(
        &mut io,
        board,
        4,
        Request::Board(SensorRequest::LoadConstellation(con)),
    );
    pc(&mut io, board, 5, Request::Board(SensorRequest::GetConfig));
    let pose = Mode::Pose(ModelKind::NearField);
    pc(
        &mut io,
        board,
        6,
        Request::Board(SensorRequest::SetMode(pose)),
    );
    let requests_used = stack_used(lo, sp);
    let (lo, sp) = paint_stack(PAINT);
    let mut bytes = [0u8; northstar::MAX_FRAME];
    // Empty segments: the marker overhead run.sh subtracts.
    for _ in 0..4 {
        mark();
    }
    for (k, spots) in [&f1, &f2, &f1, &f2].into_iter().enumerate() {
        let n = ns_frame(k as u8, law, spots, &mut bytes);
        // Measured: the warm frames (the first is solved from the cold start), each from
        // its bytes to the pose report sent.
        if k > 0 {
            mark();
        }
        board.poll(&[], &bytes[..n], &mut io);
    }
    end();
    // The last frame sent is the last pose: it must be one, solved with every magnitude.
    if last_pose(&io) != Some((PoseStatus::Ok, 20, 20)) {
        fail("the last NorthStar frame gave no Ok pose with the 20 magnitudes");
    }
    // At another sensitivity: the spots alone, the linearisation carried; the warm frames
    // measured too (segments 4 and 5).
    pc(
        &mut io,
        board,
        7,
        Request::Board(SensorRequest::SetSensitivity(law - 1)),
    );
    for (k, spots) in [&f1, &f2, &f1].into_iter().enumerate() {
        let n = ns_frame(4 + k as u8, law - 1, spots, &mut bytes);
        if k > 0 {
            mark();
        }
        board.poll(&[], &bytes[..n], &mut io);
    }
    end();
    if last_pose(&io) != Some((PoseStatus::Ok, 20, 0)) {
        fail("a NorthStar frame at another sensitivity gave no Ok pose from the spots alone");
    }
    pc(
        &mut io,
        board,
        8,
        Request::Board(SensorRequest::SetMode(Mode::Stream)),
    );
    let n = ns_frame(9, law - 1, &f2, &mut bytes);
    board.poll(&[], &bytes[..n], &mut io);
    let frames_used = stack_used(lo, sp);
    hprintln!(
        "STACK board_peak_bytes={} (below main: init {} B, the requests up to pose mode {} B, the NorthStar frames and the rest {} B; {} frames sent)",
        init_used.max(requests_used).max(frames_used),
        init_used,
        requests_used,
        frames_used,
        io.frames
    );
    hprintln!("BOARD bytes={}", core::mem::size_of::<Board<RamFlash>>());
    done("board: ok")
}
