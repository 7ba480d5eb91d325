//! Peak stack of the beacon board's work on a Cortex-M3 (QEMU lm3s6965evb): the same
//! [`Board::init`], [`Board::start`], [`Board::feed`] and [`Board::poll`] the chip's `main`
//! calls (firmware-beacon/src/chip.rs), with outputs that do what the chip's do (the
//! modulator in a static under a critical section, reconfigured, then every port's `BSRR`
//! written; the registers are stand-ins in RAM), built at the firmware's opt-level. The
//! session reaches every request: identify, heartbeat, status, the frequency table and
//! the LED modes read back, limits raised to all 100 LEDs, all 100 set at once with two
//! frequencies each (the largest request; refused by the tick cost model), all 100 set at
//! once, ten of them with two frequencies (the deepest reconfiguration the board accepts),
//! one LED, a refusal, a new table, all off, garbage, and the dead-man timeout.
//!
//! The request frames are encoded before the stack is painted and fed byte by byte from
//! this `main`, with the reply buffer in its frame, as the chip's main loop does.
//!
//! The instruction count (run.sh) is per received byte; its maximum is the byte that
//! completes the costliest request (all 100 LEDs set: decode, validate, reconfigure the
//! modulator, encode the reply), the longest the chip's main loop is held up.
//!
//! Prints `STACK beacon_board_peak_bytes=N`: the bytes of stack used below this program's
//! `main` by `init` and `start` or by the session, whichever is more. firmware-beacon/ci.sh
//! adds the chip's own `main` frame (from its disassembly), the tick interrupt's stack
//! (`beacon_tick`) and an allowance for the USART interrupt and the reset handler, and the
//! firmware's static RAM (the board and the modulator live in statics there, as here).
#![no_std]
#![no_main]

use core::cell::RefCell;
use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use critical_section::Mutex;
use cta_core::schedule::{lost_ticks, Modulator, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{
    BeaconRequest, BeaconResponse, FreqSet, LedMode, LedSetting, Limits, LED_COUNT,
};
use cta_core::wire::{
    encode_frame, FrameDecoder, Header, Request, ResetCause, Response, MAX_FRAME,
};
use cta_firmware_beacon::board::{BeaconReply, Board, Outputs};
use cta_firmware_beacon::pins::{BEACON_LINES, PORTS};
use cta_qemu::{done, end, fail, mark, paint_stack, stack_used};

/// Stack region painted below the current stack pointer.
const PAINT: usize = 24 * 1024;
/// Room for every request frame of the session.
const WIRE: usize = 4096;

static MODULATOR: Mutex<RefCell<Modulator>> = Mutex::new(RefCell::new(Modulator::EMPTY));
/// Stand-ins for the seven GPIOx->BSRR registers.
static mut BSRR: [u32; PORTS] = [0; PORTS];

/// The chip's `ChipOutputs`: the modulator in its static, every port rewritten after a
/// change.
struct HarnessOutputs;

/// Cycles a reconfiguration is taken to last for the catch-up (QEMU has no STM32 timer
/// and no cycle counter): about the longest measured, so that the chip's most catch-up
/// ticks (15) are counted too.
const RECONFIGURE_CYCLES: u32 = 9000;

impl HarnessOutputs {
    fn with(&mut self, f: impl FnOnce(&mut Modulator)) {
        critical_section::with(|cs| {
            let mut m = MODULATOR.borrow_ref_mut(cs);
            f(&mut m);
            // The chip's catch-up of the ticks lost meanwhile, from mid-period.
            let mut caught = 0;
            while caught < 64 && caught < lost_ticks(false, 288, RECONFIGURE_CYCLES, 576) {
                m.tick_silently();
                caught += 1;
            }
            for (p, w) in m.all_bsrr().iter().enumerate() {
                // SAFETY: single-threaded program; volatile stores to RAM stand-ins.
                unsafe {
                    (core::ptr::addr_of_mut!(BSRR) as *mut u32)
                        .add(p)
                        .write_volatile(*w)
                };
            }
        });
    }
}

impl Outputs for HarnessOutputs {
    fn set_table(&mut self, table_mhz: &[u32]) {
        self.with(|m| Outputs::set_table(m, table_mhz));
    }
    fn set_modes(&mut self, modes: &[LedMode; LED_COUNT]) {
        self.with(|m| m.configure(modes));
    }
}

/// The request frames and other bytes of a session, back to back.
struct Wire<'a> {
    bytes: &'a mut [u8; WIRE],
    n: usize,
}

impl Wire<'_> {
    fn push(&mut self, seq: u16, req: Request<BeaconRequest>) {
        let Ok(f) = encode_frame(Header::new(seq), &req, &mut self.bytes[self.n..]) else {
            fail("request does not encode")
        };
        self.n += f.len();
    }
    fn raw(&mut self, b: &[u8]) {
        self.bytes[self.n..self.n + b.len()].copy_from_slice(b);
        self.n += b.len();
    }
}

/// The request frames of the session, back to back, with garbage in the middle.
fn session(bytes: &mut [u8; WIRE]) -> usize {
    let mut w = Wire { bytes, n: 0 };
    let board = Request::Board;
    w.push(1, Request::Identify);
    w.push(2, Request::Heartbeat);
    w.push(3, board(BeaconRequest::Status));
    w.push(4, board(BeaconRequest::GetTable));
    w.push(
        5,
        board(BeaconRequest::SetLimits(Limits {
            max_lit: LED_COUNT as u8,
            deadman_ms: 10_000,
        })),
    );
    // All 100 LEDs, two frequencies each (combinations: the deepest reconfiguration), is
    // more than the tick interrupt can keep up with: refused (seq 13). Ten of them at two
    // and the others at one are accepted (seq 6).
    let pair = |led: u8| LedMode::Modulated(FreqSet((1 << (led % 20)) | (1 << ((led + 7) % 20))));
    let mut all = heapless::Vec::new();
    let mut mixed = heapless::Vec::new();
    for led in 0..LED_COUNT as u8 {
        let _ = all.push(LedSetting {
            led,
            mode: pair(led),
        });
        let mode = match led < 10 {
            true => pair(led),
            false => LedMode::Modulated(FreqSet::single(led % 20)),
        };
        let _ = mixed.push(LedSetting { led, mode });
    }
    w.push(13, board(BeaconRequest::SetMany(all)));
    w.push(6, board(BeaconRequest::SetMany(mixed)));
    w.push(7, board(BeaconRequest::GetLeds));
    w.push(
        8,
        board(BeaconRequest::SetLimits(Limits {
            max_lit: 10,
            deadman_ms: 10_000,
        })),
    );
    w.push(
        9,
        board(BeaconRequest::Set(LedSetting {
            led: 3,
            mode: LedMode::On,
        })),
    );
    w.raw(&[0x13, 0x37, 0x00, 0x42, 0xff, 0x00]);
    let mut table = heapless::Vec::new();
    let _ = table.extend_from_slice(&NORTHSTAR_TABLE_MHZ);
    w.push(10, board(BeaconRequest::SetTable(table)));
    w.push(11, board(BeaconRequest::AllOff));
    w.push(
        12,
        board(BeaconRequest::Set(LedSetting {
            led: 42,
            mode: LedMode::Modulated(FreqSet::single(5)),
        })),
    );
    w.n
}

#[entry]
fn main() -> ! {
    static mut BOARD: MaybeUninit<Board> = MaybeUninit::uninit();
    static mut WIRE_BYTES: [u8; WIRE] = [0; WIRE];
    let wire = WIRE_BYTES;
    let len = session(wire);
    let mut out = HarnessOutputs;
    let mut tx = [0u8; MAX_FRAME];
    let mut replies = FrameDecoder::<MAX_FRAME>::new();
    let (mut frames, mut errors, mut lit_after_set_many) = (0u32, 0u32, 0u8);

    let (lo, sp) = paint_stack(PAINT);
    critical_section::with(|cs| {
        if MODULATOR
            .borrow_ref_mut(cs)
            .load(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES)
            .is_err()
        {
            fail("table")
        }
    });
    let board = Board::init(BOARD, false, ResetCause::PowerOn);
    board.start(&mut out);
    let init_used = stack_used(lo, sp);

    let (lo, sp) = paint_stack(PAINT);
    // Empty segments: the marker overhead run.sh subtracts.
    for _ in 0..4 {
        mark();
    }
    let mut now_ms = 0u64;
    for &byte in &wire[..len] {
        now_ms += 1;
        // Measured: each byte's `feed`, the frame's whole handling on its last byte.
        mark();
        let reply = board.feed(byte, now_ms, &mut out, &mut tx);
        end();
        if let Some(frame) = reply {
            for &b in frame {
                if let Some(r) = replies.push::<BeaconReply>(b) {
                    frames += 1;
                    match r {
                        Ok((h, Ok(_))) if h.seq == 6 => lit_after_set_many = board.lit(),
                        Ok((h, Ok(Response::Board(BeaconResponse::Leds(v)))))
                            if h.seq == 7 && v.len() == LED_COUNT => {}
                        Ok((h, _)) if h.seq == 7 => fail("GetLeds gave no 100 modes"),
                        Ok((_, Err(_))) => errors += 1,
                        Ok(_) => {}
                        Err(_) => fail("a reply frame did not decode"),
                    }
                }
            }
        }
        board.poll(now_ms, &mut out);
    }
    // Silence past the dead-man timeout: the lit LED goes off.
    let lit_before = board.lit();
    board.poll(now_ms + 10_001, &mut out);
    let session_used = stack_used(lo, sp);

    if lit_after_set_many != LED_COUNT as u8 {
        fail("SetMany did not light all 100 LEDs")
    }
    // Refused: the tick overload (seq 13), the cap below the lit count (seq 8); garbage:
    // two bad frames.
    if errors != 4 || frames != 15 {
        hprintln!("frames {} errors {}", frames, errors);
        fail("unexpected replies")
    }
    if lit_before != 1 || board.lit() != 0 {
        fail("the dead-man timeout did not switch the LED off")
    }
    hprintln!(
        "STACK beacon_board_peak_bytes={} (below main: init and start {} B, a session of requests {} B; {} replies)",
        init_used.max(session_used),
        init_used,
        session_used,
        frames
    );
    hprintln!(
        "BOARD bytes={} modulator bytes={}",
        core::mem::size_of::<Board>(),
        core::mem::size_of::<Modulator>()
    );
    done("beacon_board: ok")
}
