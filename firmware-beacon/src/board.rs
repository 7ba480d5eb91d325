//! The beacon board's protocol handling and safety logic, independent of the hardware.
//!
//! [`Board`] receives bytes from the host link, answers every request (or bad frame) with a
//! reply frame, keeps the LED modes, the frequency table and the safety limits, and tells
//! its [`Outputs`] (the modulator on the chip or in the simulator) what to drive. The
//! firmware's main loop and the simulated board both run exactly this code.
//!
//! Safety rules enforced here:
//! * every LED starts off ([`Board::new`]);
//! * a request that would light more than [`Limits::max_lit`] LEDs is refused with
//!   [`BeaconError::TooManyLit`] and changes nothing;
//! * when no valid frame has arrived for [`Limits::deadman_ms`] (default 10 s), every LED
//!   goes off ([`Board::poll`]); the host keeps the board alive with heartbeats.

use core::mem::MaybeUninit;

use crate::pins::BEACON_LINES;
use cta_core::schedule::{half_period_q24, tick_cost, NORTHSTAR_TABLE_MHZ, TICK_BUDGET, TICK_HZ};
use cta_core::wire::beacon::{
    BeaconError, BeaconRequest, BeaconResponse, BeaconStatus, LedMode, LedSetting, Limits,
    DEADMAN_MAX_MS, DEADMAN_MIN_MS, LED_COUNT, MAX_FREQS,
};
use cta_core::wire::{
    encode_frame, BoardKind, DecoderStats, ErrorReply, FrameDecoder, Header, Identity, Reply,
    Request, ResetCause, Response, MAX_FRAME, PROTOCOL_VERSION,
};

/// The reply type of the beacon board.
pub type BeaconReply = Reply<BeaconResponse, BeaconError>;

/// What the board drives: the modulator (through the timer interrupt on the chip).
pub trait Outputs {
    /// Load a new frequency table (validated); every LED is off afterwards.
    fn set_table(&mut self, table_mhz: &[u32]);
    /// Drive every LED as `modes` says (validated against the current table).
    fn set_modes(&mut self, modes: &[LedMode; LED_COUNT]);
}

/// Firmware version reported by [`Request::Identify`].
pub const FIRMWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Protocol state, LED modes and safety timers of the beacon board.
pub struct Board {
    decoder: FrameDecoder<MAX_FRAME>,
    modes: [LedMode; LED_COUNT],
    table: heapless::Vec<u32, MAX_FREQS>,
    limits: Limits,
    last_host_ms: u64,
    deadman_trips: u32,
    refused: u32,
    uart_errors: u32,
    simulated: bool,
    reset_cause: ResetCause,
}

impl Board {
    /// Board with every LED off, the NorthStar table and default limits. Call
    /// [`Board::start`] once to push that state to the outputs.
    /// `reset_cause`: what started the board, reported in its status.
    pub fn new(simulated: bool, reset_cause: ResetCause) -> Self {
        let mut table = heapless::Vec::new();
        // NORTHSTAR_TABLE_MHZ has 20 <= MAX_FREQS entries.
        let _ = table.extend_from_slice(&NORTHSTAR_TABLE_MHZ);
        Board {
            decoder: FrameDecoder::new(),
            modes: [LedMode::Off; LED_COUNT],
            table,
            limits: Limits::default(),
            last_host_ms: 0,
            deadman_trips: 0,
            refused: 0,
            uart_errors: 0,
            simulated,
            reset_cause,
        }
    }

    /// [`Self::new`] written into `slot`: the chip keeps the board in a static, so its
    /// state (the receive buffer above all) counts as static RAM and not as part of
    /// `main`'s stack frame, which `firmware-beacon/ci.sh` reads from the disassembly.
    /// Requests are handled in [`Self::feed`]'s own frame (never inlined), whose peak the
    /// QEMU program `tests/qemu/src/bin/beacon_board.rs` measures.
    pub fn init(
        slot: &mut MaybeUninit<Self>,
        simulated: bool,
        reset_cause: ResetCause,
    ) -> &mut Self {
        slot.write(Self::new(simulated, reset_cause))
    }

    /// Push the boot state (table, all LEDs off) to the outputs.
    pub fn start(&mut self, out: &mut impl Outputs) {
        out.set_table(&self.table);
        out.set_modes(&self.modes);
    }

    /// Current LED modes.
    pub fn modes(&self) -> &[LedMode; LED_COUNT] {
        &self.modes
    }

    /// Current safety limits.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// Frame decoder counters.
    pub fn decoder_stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// Count a UART receive error (overrun, framing, noise); the partial frame is dropped.
    pub fn uart_error(&mut self) {
        self.uart_errors = self.uart_errors.saturating_add(1);
        self.decoder.reset();
    }

    /// Number of LEDs lit.
    pub fn lit(&self) -> u8 {
        self.modes.iter().filter(|m| m.is_lit()).count() as u8
    }

    /// Safety timers: switch everything off when the host has been silent for longer than
    /// the dead-man timeout. Call often (every main-loop pass).
    pub fn poll(&mut self, now_ms: u64, out: &mut impl Outputs) {
        let silent = now_ms.saturating_sub(self.last_host_ms);
        if silent > self.limits.deadman_ms as u64 && self.lit() > 0 {
            self.modes = [LedMode::Off; LED_COUNT];
            out.set_modes(&self.modes);
            self.deadman_trips = self.deadman_trips.saturating_add(1);
        }
    }

    /// Feed one received byte. When it completes a frame, the reply frame is written to
    /// `tx` and returned. Never inlined (see [`Self::init`]).
    #[inline(never)]
    pub fn feed<'t>(
        &mut self,
        byte: u8,
        now_ms: u64,
        out: &mut impl Outputs,
        tx: &'t mut [u8; MAX_FRAME],
    ) -> Option<&'t [u8]> {
        let (seq, reply): (u16, BeaconReply) =
            match self.decoder.push::<Request<BeaconRequest>>(byte)? {
                Ok((header, request)) => {
                    self.last_host_ms = now_ms;
                    (header.seq, self.handle(request, now_ms, out))
                }
                Err(e) => (e.seq, Err(ErrorReply::BadFrame(e.fault))),
            };
        if let Err(ErrorReply::Board(_)) = reply {
            self.refused = self.refused.saturating_add(1);
        }
        // Every reply fits MAX_FRAME (tested): the error is never reached.
        encode_frame(Header::new(seq), &reply, tx).ok()
    }

    /// Carry out one request.
    pub fn handle(
        &mut self,
        request: Request<BeaconRequest>,
        now_ms: u64,
        out: &mut impl Outputs,
    ) -> BeaconReply {
        let r = match request {
            Request::Identify => return Ok(Response::Identity(self.identity())),
            Request::Heartbeat => return Ok(Response::Ack),
            Request::Board(r) => r,
        };
        let board = |r| Ok(Response::Board(r));
        match r {
            BeaconRequest::Status => board(BeaconResponse::Status(self.status(now_ms))),
            BeaconRequest::GetTable => board(BeaconResponse::Table(self.table.clone())),
            BeaconRequest::GetLeds => {
                let mut v = heapless::Vec::new();
                let _ = v.extend_from_slice(&self.modes);
                board(BeaconResponse::Leds(v))
            }
            BeaconRequest::AllOff => {
                self.modes = [LedMode::Off; LED_COUNT];
                out.set_modes(&self.modes);
                Ok(Response::Ack)
            }
            BeaconRequest::Set(s) => self.apply(&[s], out),
            BeaconRequest::SetMany(v) => self.apply(&v, out),
            BeaconRequest::SetTable(t) => {
                if t.is_empty() {
                    return Err(ErrorReply::Board(BeaconError::EmptyTable));
                }
                for (i, &mhz) in t.iter().enumerate() {
                    if half_period_q24(mhz).is_none() {
                        return Err(ErrorReply::Board(BeaconError::FrequencyOutOfRange {
                            index: i as u8,
                            mhz,
                        }));
                    }
                }
                let off = [LedMode::Off; LED_COUNT];
                overload(&t, &off)?;
                self.table = t;
                self.modes = off;
                out.set_table(&self.table);
                out.set_modes(&self.modes);
                Ok(Response::Ack)
            }
            BeaconRequest::SetLimits(l) => {
                if l.max_lit == 0 || l.max_lit as usize > LED_COUNT {
                    return Err(ErrorReply::Board(BeaconError::CapOutOfRange {
                        max_lit: l.max_lit,
                    }));
                }
                if !(DEADMAN_MIN_MS..=DEADMAN_MAX_MS).contains(&l.deadman_ms) {
                    return Err(ErrorReply::Board(BeaconError::DeadmanOutOfRange {
                        ms: l.deadman_ms,
                    }));
                }
                let lit = self.lit();
                if lit > l.max_lit {
                    return Err(ErrorReply::Board(BeaconError::TooManyLit {
                        requested: lit,
                        cap: l.max_lit,
                    }));
                }
                self.limits = l;
                Ok(Response::Ack)
            }
        }
    }

    /// Validate and apply LED settings atomically.
    fn apply(&mut self, settings: &[LedSetting], out: &mut impl Outputs) -> BeaconReply {
        let mut next = self.modes;
        let mut seen = [false; LED_COUNT];
        for s in settings {
            let id = s.led;
            if id as usize >= LED_COUNT {
                return Err(ErrorReply::Board(BeaconError::UnknownBeacon { id }));
            }
            if core::mem::replace(&mut seen[id as usize], true) {
                return Err(ErrorReply::Board(BeaconError::DuplicateBeacon { id }));
            }
            if let LedMode::Modulated(set) = s.mode {
                if set.0 == 0 {
                    return Err(ErrorReply::Board(BeaconError::NoFrequency { id }));
                }
                let highest = 31 - set.0.leading_zeros() as u8;
                if highest as usize >= self.table.len() {
                    return Err(ErrorReply::Board(BeaconError::FrequencyNotInTable {
                        id,
                        index: highest,
                        table_len: self.table.len() as u8,
                    }));
                }
            }
            next[id as usize] = s.mode;
        }
        let lit = next.iter().filter(|m| m.is_lit()).count() as u8;
        if lit > self.limits.max_lit {
            return Err(ErrorReply::Board(BeaconError::TooManyLit {
                requested: lit,
                cap: self.limits.max_lit,
            }));
        }
        overload(&self.table, &next)?;
        self.modes = next;
        out.set_modes(&self.modes);
        Ok(Response::Ack)
    }

    /// The identify reply.
    pub fn identity(&self) -> Identity {
        let mut firmware = heapless::String::new();
        let _ = firmware.push_str(FIRMWARE_VERSION);
        Identity {
            board: BoardKind::Beacon,
            protocol: PROTOCOL_VERSION,
            firmware,
            simulated: self.simulated,
            max_frame: MAX_FRAME as u16,
        }
    }

    /// The status reply.
    pub fn status(&self, now_ms: u64) -> BeaconStatus {
        BeaconStatus {
            uptime_ms: now_ms,
            lit: self.lit(),
            limits: self.limits,
            since_host_ms: now_ms
                .saturating_sub(self.last_host_ms)
                .min(u32::MAX as u64) as u32,
            deadman_trips: self.deadman_trips,
            decoder: *self.decoder.stats(),
            refused: self.refused,
            uart_errors: self.uart_errors,
            tick_hz: TICK_HZ,
            table_len: self.table.len() as u8,
            reset_cause: self.reset_cause,
        }
    }
}

/// Refuse a table and LED assignment whose tick interrupt would exceed its budget: at 125
/// kHz the interrupt has 576 cycles per tick, and a main loop starved of them stops feeding
/// the watchdog (the board resets) while ticks are lost (every wave runs slow). The cost is
/// the conservative model of [`tick_cost`], fitted to the interrupt's instruction counts.
fn overload(table: &[u32], modes: &[LedMode; LED_COUNT]) -> Result<(), ErrorReply<BeaconError>> {
    let instructions = tick_cost(table, modes, &BEACON_LINES);
    if instructions > TICK_BUDGET {
        return Err(ErrorReply::Board(BeaconError::TickOverload {
            instructions,
            budget: TICK_BUDGET,
        }));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cta_core::schedule::Modulator;
    use cta_core::wire::beacon::{FreqSet, FREQ_MAX_MHZ, FREQ_MIN_MHZ};
    use cta_core::wire::{FrameFault, SEQ_NONE};
    use std::vec::Vec;

    fn setup() -> (Board, Modulator) {
        let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_LINES).unwrap();
        let mut b = Board::new(true, ResetCause::PowerOn);
        b.start(&mut m);
        (b, m)
    }

    fn set(led: u8, mode: LedMode) -> Request<BeaconRequest> {
        Request::Board(BeaconRequest::Set(LedSetting { led, mode }))
    }

    /// Every LED at once, LED `led` in `mode(led)`.
    fn all_leds(mode: &dyn Fn(u8) -> LedMode) -> heapless::Vec<LedSetting, LED_COUNT> {
        (0..LED_COUNT as u8)
            .map(|led| LedSetting {
                led,
                mode: mode(led),
            })
            .collect()
    }

    /// A board that may light all 100 LEDs.
    fn setup_uncapped() -> (Board, Modulator) {
        let (mut b, mut m) = setup();
        let lim = Request::Board(BeaconRequest::SetLimits(Limits {
            max_lit: 100,
            deadman_ms: 10_000,
        }));
        b.handle(lim, 0, &mut m).unwrap();
        (b, m)
    }

    fn refused(r: BeaconReply) -> BeaconError {
        match r {
            Err(ErrorReply::Board(e)) => e,
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    /// Send `req` as a frame through `feed` and decode the reply frame.
    fn roundtrip(
        b: &mut Board,
        m: &mut Modulator,
        bytes: &[u8],
        now: u64,
    ) -> Vec<(Header, BeaconReply)> {
        let mut tx = [0u8; MAX_FRAME];
        let mut replies = Vec::new();
        let mut dec = FrameDecoder::<MAX_FRAME>::new();
        for &byte in bytes {
            if let Some(f) = b.feed(byte, now, m, &mut tx) {
                for &c in f {
                    if let Some(r) = dec.push::<BeaconReply>(c) {
                        replies.push(r.unwrap());
                    }
                }
            }
        }
        replies
    }

    #[test]
    fn boots_dark_and_identifies_as_beacon() {
        let (mut b, mut m) = setup();
        assert_eq!(b.lit(), 0);
        assert_eq!(m.levels(), [0; 7]);
        let mut buf = [0u8; 64];
        let f = encode_frame(
            Header::new(1),
            &Request::<BeaconRequest>::Identify,
            &mut buf,
        )
        .unwrap();
        let r = roundtrip(&mut b, &mut m, f, 0);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].0, Header::new(1));
        let Ok(Response::Identity(id)) = &r[0].1 else {
            panic!("{r:?}")
        };
        assert_eq!(id.board, BoardKind::Beacon);
        assert_eq!(id.protocol, PROTOCOL_VERSION);
        assert!(id.simulated);
    }

    #[test]
    fn bad_input_is_refused_with_a_named_error() {
        let (mut b, mut m) = setup();
        assert_eq!(
            refused(b.handle(set(100, LedMode::On), 0, &mut m)),
            BeaconError::UnknownBeacon { id: 100 }
        );
        assert_eq!(
            refused(b.handle(set(3, LedMode::Modulated(FreqSet::single(20))), 0, &mut m)),
            BeaconError::FrequencyNotInTable {
                id: 3,
                index: 20,
                table_len: 20
            }
        );
        assert_eq!(
            refused(b.handle(set(3, LedMode::Modulated(FreqSet(0))), 0, &mut m)),
            BeaconError::NoFrequency { id: 3 }
        );
        let mut v = heapless::Vec::new();
        v.push(LedSetting {
            led: 1,
            mode: LedMode::On,
        })
        .unwrap();
        v.push(LedSetting {
            led: 1,
            mode: LedMode::Off,
        })
        .unwrap();
        assert_eq!(
            refused(b.handle(Request::Board(BeaconRequest::SetMany(v)), 0, &mut m)),
            BeaconError::DuplicateBeacon { id: 1 }
        );
        let mut t = heapless::Vec::new();
        t.push(3_000_000).unwrap();
        t.push(40_000_000).unwrap();
        assert_eq!(
            refused(b.handle(Request::Board(BeaconRequest::SetTable(t)), 0, &mut m)),
            BeaconError::FrequencyOutOfRange {
                index: 1,
                mhz: 40_000_000
            }
        );
        assert_eq!(
            refused(b.handle(
                Request::Board(BeaconRequest::SetTable(heapless::Vec::new())),
                0,
                &mut m
            )),
            BeaconError::EmptyTable
        );
        let lim = |max_lit, deadman_ms| {
            Request::Board(BeaconRequest::SetLimits(Limits {
                max_lit,
                deadman_ms,
            }))
        };
        assert_eq!(
            refused(b.handle(lim(0, 1000), 0, &mut m)),
            BeaconError::CapOutOfRange { max_lit: 0 }
        );
        assert_eq!(
            refused(b.handle(lim(101, 1000), 0, &mut m)),
            BeaconError::CapOutOfRange { max_lit: 101 }
        );
        assert_eq!(
            refused(b.handle(lim(5, 50), 0, &mut m)),
            BeaconError::DeadmanOutOfRange { ms: 50 }
        );
        // Nothing was lit by any refused request.
        assert_eq!(b.lit(), 0);
        assert_eq!(m.levels(), [0; 7]);
    }

    /// Settings the tick interrupt could not keep up with are refused whole (nothing
    /// changes), with the estimate and the budget; every LED at one NorthStar frequency is
    /// well inside it, and so is a fast table with nothing lit.
    #[test]
    fn tick_overload_is_refused() {
        let (mut b, mut m) = setup_uncapped();
        let all =
            |mode: &dyn Fn(u8) -> LedMode| Request::Board(BeaconRequest::SetMany(all_leds(mode)));
        let singles = |led: u8| LedMode::Modulated(FreqSet::single(led % 20));
        assert_eq!(b.handle(all(&singles), 0, &mut m), Ok(Response::Ack));
        let before = *b.modes();
        // Every LED at two frequencies: the combination list is walked on most ticks.
        let pairs = |led: u8| LedMode::Modulated(FreqSet(1 << (led % 20) | 1 << ((led + 7) % 20)));
        match refused(b.handle(all(&pairs), 0, &mut m)) {
            BeaconError::TickOverload {
                instructions,
                budget,
            } => {
                assert_eq!(budget, TICK_BUDGET);
                assert!(instructions > 2 * budget, "{instructions}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(*b.modes(), before, "a refused request changes nothing");
        // Ten LEDs at two frequencies among the rest at one are fine.
        let some = |led: u8| if led < 10 { pairs(led) } else { singles(led) };
        assert_eq!(b.handle(all(&some), 0, &mut m), Ok(Response::Ack));
        // 32 frequencies near 12.5 kHz: accepted with nothing lit, not with every LED on one.
        let fast = (0..32).map(|i| FREQ_MAX_MHZ - 10_000 * i).collect();
        let table = Request::Board(BeaconRequest::SetTable(fast));
        assert_eq!(b.handle(table, 0, &mut m), Ok(Response::Ack));
        let fast_singles = |led: u8| LedMode::Modulated(FreqSet::single(led % 32));
        assert!(matches!(
            refused(b.handle(all(&fast_singles), 0, &mut m)),
            BeaconError::TickOverload { .. }
        ));
        assert_eq!(b.lit(), 0);
    }

    #[test]
    fn lit_cap_is_enforced_atomically() {
        let (mut b, mut m) = setup();
        assert_eq!(b.limits().max_lit, 20);
        let many = |ids: core::ops::Range<u8>| {
            let mut v = heapless::Vec::new();
            for led in ids {
                v.push(LedSetting {
                    led,
                    mode: LedMode::Modulated(FreqSet::single(led % 20)),
                })
                .unwrap();
            }
            Request::Board(BeaconRequest::SetMany(v))
        };
        assert_eq!(b.handle(many(0..20), 0, &mut m), Ok(Response::Ack));
        assert_eq!(b.lit(), 20);
        assert_eq!(
            refused(b.handle(set(50, LedMode::On), 0, &mut m)),
            BeaconError::TooManyLit {
                requested: 21,
                cap: 20
            }
        );
        assert_eq!(
            refused(b.handle(many(20..40), 0, &mut m)),
            BeaconError::TooManyLit {
                requested: 40,
                cap: 20
            }
        );
        assert_eq!(b.lit(), 20);
        // Lowering the cap below what is lit is refused; raising it allows 100.
        let lim = |max_lit| {
            Request::Board(BeaconRequest::SetLimits(Limits {
                max_lit,
                deadman_ms: 10_000,
            }))
        };
        assert_eq!(
            refused(b.handle(lim(10), 0, &mut m)),
            BeaconError::TooManyLit {
                requested: 20,
                cap: 10
            }
        );
        assert_eq!(b.handle(lim(100), 0, &mut m), Ok(Response::Ack));
        assert_eq!(b.handle(many(0..100), 0, &mut m), Ok(Response::Ack));
        assert_eq!(b.lit(), 100);
        assert_eq!(
            b.handle(Request::Board(BeaconRequest::AllOff), 0, &mut m),
            Ok(Response::Ack)
        );
        assert_eq!(b.lit(), 0);
        assert_eq!(m.levels(), [0; 7]);
    }

    #[test]
    fn deadman_switches_off_after_silence_and_heartbeats_keep_it_alive() {
        let (mut b, mut m) = setup();
        let mut buf = [0u8; 64];
        let mut send = |b: &mut Board, m: &mut Modulator, req: &Request<BeaconRequest>, now| {
            let f = encode_frame(Header::new(9), req, &mut buf)
                .unwrap()
                .to_vec();
            roundtrip(b, m, &f, now)
        };
        send(&mut b, &mut m, &set(7, LedMode::On), 1_000);
        assert_eq!(b.lit(), 1);
        assert_ne!(m.levels(), [0; 7]);
        // Heartbeats every 5 s keep it alive for a minute.
        for k in 1..=12u64 {
            b.poll(1_000 + k * 5_000 - 1, &mut m);
            send(&mut b, &mut m, &Request::Heartbeat, 1_000 + k * 5_000);
            assert_eq!(b.lit(), 1, "alive at {k}");
        }
        let last = 61_000;
        b.poll(last + 10_000, &mut m);
        assert_eq!(b.lit(), 1, "exactly the timeout is still fine");
        // Garbage does not count as the host being alive.
        send(&mut b, &mut m, &Request::Heartbeat, last);
        let _ = roundtrip(&mut b, &mut m, &[1, 2, 3, 0], last + 9_000);
        b.poll(last + 10_001, &mut m);
        assert_eq!(b.lit(), 0);
        assert_eq!(m.levels(), [0; 7]);
        assert_eq!(b.status(last + 10_001).deadman_trips, 1);
    }

    #[test]
    fn garbage_is_answered_and_counted() {
        let (mut b, mut m) = setup();
        let r = roundtrip(&mut b, &mut m, &[0, 0x55, 0x12, 0x33, 0x99, 0x01, 0], 0);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].0.seq, SEQ_NONE);
        assert!(matches!(
            r[0].1,
            Err(ErrorReply::BadFrame(FrameFault::Crc | FrameFault::Encoding))
        ));
        assert_eq!(b.decoder_stats().bad(), 1);
        // A frame with an unknown request variant carries its sequence number.
        let mut buf = [0u8; 64];
        let f = encode_frame(Header::new(77), &(2u8, 200u8), &mut buf).unwrap();
        let r = roundtrip(&mut b, &mut m, f, 0);
        assert_eq!(
            r[0],
            (Header::new(77), Err(ErrorReply::BadFrame(FrameFault::Body)))
        );
    }

    #[test]
    fn every_reply_fits_a_frame() {
        let (mut b, mut m) = setup_uncapped();
        // The longest table (32 slow entries, within the tick budget) and every LED at its
        // last entry: the largest encodings of a table and of an LED mode (bit 31).
        let table = (0..32).map(|i| FREQ_MIN_MHZ + 1000 * i).collect();
        b.handle(Request::Board(BeaconRequest::SetTable(table)), 0, &mut m)
            .unwrap();
        let v = all_leds(&|_| LedMode::Modulated(FreqSet::single(31)));
        b.handle(Request::Board(BeaconRequest::SetMany(v.clone())), 0, &mut m)
            .unwrap();
        let mut buf = [0u8; MAX_FRAME];
        // The largest request and the largest replies fit MAX_FRAME.
        encode_frame(
            Header::new(1),
            &Request::Board(BeaconRequest::SetMany(v)),
            &mut buf,
        )
        .unwrap();
        for req in [
            BeaconRequest::GetLeds,
            BeaconRequest::GetTable,
            BeaconRequest::Status,
        ] {
            let reply = b.handle(Request::Board(req), u64::MAX / 2, &mut m);
            encode_frame(Header::new(u16::MAX), &reply, &mut buf).unwrap();
        }
    }
}
