//! The NorthStar link: the byte protocol between the sensor board and the NorthStar
//! detector, isolated here so that the real protocol can replace it in this one module.
//!
//! # The assumed frame format
//!
//! Evolution Robotics never published the NorthStar's byte-level protocol (REFERENCE.md
//! section 4). What is known: it tracks up to 20 IR spots (10 beacon pairs) modulated at
//! preset frequencies, reports per spot `x`, `y` as signed 16-bit counts, a magnitude
//! (signal strength 0..65535) and an ID, at a typical 10 Hz, with four light-sensitivity
//! settings. This module *assumes* the following framing, which carries exactly that
//! information; everything else in the firmware sees only [`SpotFrame`] and
//! [`NsCommand`], so the real format replaces this file and nothing else.
//!
//! The UART runs at [`NS_BAUD`] 8N1 (assumed). All multi-byte fields little-endian.
//! A frame is
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | sync `0xA5 0x5A` |
//! | 2 | 1 | kind (`0x01` spot report; `0x81` command acknowledge) |
//! | 3 | 1 | length `n` of the body that follows, in bytes |
//! | 4 | n | body |
//! | 4+n | 2 | CRC-16/XMODEM over bytes 2 .. 4+n (kind, length, body) |
//!
//! Spot report body (`kind = 0x01`): `seq: u8` (the detector's frame counter, wraps),
//! `sensitivity: u8` (1..=4, the setting in force), `count: u8` (0..=20), then `count`
//! spots of 7 bytes: `x: i16`, `y: i16`, `magnitude: u16`, `id: u8`. The ID is the
//! frequency channel 0..=19; channel `2k` and `2k + 1` are the two frequencies of
//! Rovio-style beacon `k` (REFERENCE.md section 4). The body length must equal
//! `3 + 7 count`.
//!
//! Command frames (board to detector) use the same envelope: kind `0x10` set sensitivity
//! (body: one byte 1..=4), kind `0x11` set update rate (body: one byte, Hz, 1..=50). The
//! detector answers a command with kind `0x81` (body: the command kind and a status byte,
//! 0 = accepted), which the decoder reports as [`NsEvent::Ack`].
//!
//! # Robustness
//!
//! The decoder holds at most one maximal frame ([`MAX_FRAME`] bytes). Whatever arrives —
//! line noise, truncated frames, a sync pattern inside a payload — it never panics and
//! resynchronises on the next valid frame: on any inconsistency (bad kind, impossible
//! length, CRC mismatch) it discards one byte and searches for the next sync pattern in
//! what it already holds, so a valid frame that follows garbage is still found; and while
//! it waits for the rest of a frame whose header may be false (a truncated frame, noise),
//! a complete CRC-valid frame ending at the newest byte is taken at once.

use cta_core::pose::Spot;
use heapless::Vec;

/// Assumed baud rate of the NorthStar's UART (8N1).
pub const NS_BAUD: u32 = 115_200;
/// Most spots the NorthStar reports in one frame (10 beacon pairs).
pub const MAX_SPOTS: usize = 20;
/// Bytes per spot in a report body.
const SPOT_BYTES: usize = 7;
/// Frame sync pattern.
const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Largest body (a report with 20 spots).
const MAX_BODY: usize = 3 + SPOT_BYTES * MAX_SPOTS;
/// Largest frame on the wire, the decoder's buffer size.
pub const MAX_FRAME: usize = 4 + MAX_BODY + 2;

const KIND_REPORT: u8 = 0x01;
const KIND_ACK: u8 = 0x81;
const KIND_SET_SENSITIVITY: u8 = 0x10;
const KIND_SET_RATE: u8 = 0x11;

/// Bitwise (table-free) CRC-16: a frame is at most 148 bytes, and the 512-byte table
/// would cost flash the sensor board does not have.
const CRC16: crc::Crc<u16, crc::NoTable> = crc::Crc::<u16, crc::NoTable>::new(&crc::CRC_16_XMODEM);

/// One report from the detector: every spot it currently tracks.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SpotFrame {
    /// The detector's own frame counter (wraps at 256).
    pub seq: u8,
    /// Sensitivity setting in force, 1..=4.
    pub sensitivity: u8,
    /// The spots (at most [`MAX_SPOTS`]).
    pub spots: Vec<Spot, MAX_SPOTS>,
}

/// A command to the detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NsCommand {
    /// Light sensitivity setting, 1 (least) ..= 4 (most sensitive).
    SetSensitivity(u8),
    /// Report rate in Hz, 1..=50 (the NorthStar's typical rate is 10 Hz).
    SetRate(u8),
}

/// What the decoder found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NsEvent {
    /// A spot report.
    Report(SpotFrame),
    /// The detector acknowledged a command: `(command kind, status)`, status 0 = accepted.
    Ack { kind: u8, status: u8 },
}

/// Decoder error counters (reported in the board status).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct NsStats {
    /// Frames decoded.
    pub frames: u32,
    /// Frames that failed the CRC.
    pub crc_errors: u32,
    /// Bytes discarded while hunting for a frame (noise, broken headers).
    pub discarded: u32,
}

/// Encode a command frame; returns the bytes used in `out`.
pub fn encode_command(cmd: NsCommand, out: &mut [u8; 7]) -> usize {
    let (kind, arg) = match cmd {
        NsCommand::SetSensitivity(s) => (KIND_SET_SENSITIVITY, s),
        NsCommand::SetRate(r) => (KIND_SET_RATE, r),
    };
    let body = [kind, 1, arg];
    out[..2].copy_from_slice(&SYNC);
    out[2..5].copy_from_slice(&body);
    out[5..7].copy_from_slice(&CRC16.checksum(&body).to_le_bytes());
    7
}

/// Decode a command frame (the simulated detector's side). `None` if `bytes` is not one.
pub fn decode_command(bytes: &[u8]) -> Option<NsCommand> {
    if bytes.len() != 7 || bytes[..2] != SYNC || bytes[3] != 1 {
        return None;
    }
    if CRC16.checksum(&bytes[2..5]).to_le_bytes() != [bytes[5], bytes[6]] {
        return None;
    }
    match bytes[2] {
        KIND_SET_SENSITIVITY => Some(NsCommand::SetSensitivity(bytes[4])),
        KIND_SET_RATE => Some(NsCommand::SetRate(bytes[4])),
        _ => None,
    }
}

/// Encode a spot report (used by the simulated detector and the tests). Returns the
/// number of bytes written into `out`.
pub fn encode_report(frame: &SpotFrame, out: &mut [u8; MAX_FRAME]) -> usize {
    let n = frame.spots.len();
    let body_len = 3 + SPOT_BYTES * n;
    out[..2].copy_from_slice(&SYNC);
    out[2] = KIND_REPORT;
    out[3] = body_len as u8;
    out[4] = frame.seq;
    out[5] = frame.sensitivity;
    out[6] = n as u8;
    for (i, s) in frame.spots.iter().enumerate() {
        let o = 7 + SPOT_BYTES * i;
        out[o..o + 2].copy_from_slice(&s.x.to_le_bytes());
        out[o + 2..o + 4].copy_from_slice(&s.y.to_le_bytes());
        out[o + 4..o + 6].copy_from_slice(&s.magnitude.to_le_bytes());
        out[o + 6] = s.id;
    }
    let end = 4 + body_len;
    let crc = CRC16.checksum(&out[2..end]);
    out[end..end + 2].copy_from_slice(&crc.to_le_bytes());
    end + 2
}

/// Encode a command acknowledgement (simulated detector side).
pub fn encode_ack(kind: u8, status: u8, out: &mut [u8; 8]) -> usize {
    let body = [KIND_ACK, 2, kind, status];
    out[..2].copy_from_slice(&SYNC);
    out[2..6].copy_from_slice(&body);
    out[6..8].copy_from_slice(&CRC16.checksum(&body).to_le_bytes());
    8
}

/// The bounded, resynchronising frame decoder.
#[derive(Debug)]
pub struct NsDecoder {
    buf: Vec<u8, MAX_FRAME>,
    /// Where the sync word starts in `buf` after the head: the only places a frame embedded
    /// in a false start can begin. Kept as bytes arrive, so that looking for one costs a
    /// few checks per byte, not a scan of the buffer at every byte (O(n^2) per frame).
    /// `None` after more than fit (noise full of sync words): then the buffer is scanned.
    syncs: Option<Vec<u8, SYNCS>>,
    stats: NsStats,
}

/// Sync words remembered inside one pending frame (beyond the head).
const SYNCS: usize = 8;
// Positions in the buffer fit a byte.
const _: () = assert!(MAX_FRAME < 256);

impl Default for NsDecoder {
    fn default() -> Self {
        Self::new()
    }
}

/// Outcome of examining the buffered bytes.
enum Scan {
    /// Need more bytes.
    More,
    /// Discard one byte and look again.
    Skip,
    /// A CRC-valid frame of this total length is at the start of the buffer.
    Frame(usize),
    /// A complete frame with a wrong CRC.
    BadCrc,
    /// A CRC-valid frame starts at this offset and ends at the last byte received.
    Embedded(usize),
}

/// Whether a header (kind, body length) can start a frame.
fn plausible(kind: u8, n: usize) -> bool {
    match kind {
        KIND_REPORT => (3..=MAX_BODY).contains(&n) && (n - 3).is_multiple_of(SPOT_BYTES),
        KIND_ACK => n == 2,
        _ => false,
    }
}

/// CRC check of a whole frame (sync .. CRC).
fn crc_ok(f: &[u8]) -> bool {
    let end = f.len() - 2;
    CRC16.checksum(&f[2..end]).to_le_bytes() == [f[end], f[end + 1]]
}

impl NsDecoder {
    /// A decoder with an empty buffer.
    pub const fn new() -> Self {
        Self {
            buf: Vec::new(),
            syncs: Some(Vec::new()),
            stats: NsStats {
                frames: 0,
                crc_errors: 0,
                discarded: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> NsStats {
        self.stats
    }

    /// Feed received bytes; `on_event` is called for every complete valid frame.
    pub fn feed(&mut self, bytes: &[u8], mut on_event: impl FnMut(NsEvent)) {
        for &b in bytes {
            let mut event = self.push(b);
            while let Some(ev) = event {
                on_event(ev);
                event = self.next_event();
            }
        }
    }

    /// One received byte; returns the first frame it completes, if any. Call
    /// [`Self::next_event`] after each event until it returns `None`: the bytes buffered
    /// may hold more (what [`Self::feed`] does). Unlike `feed` the caller keeps no borrow of
    /// the decoder while it handles the event: the board handles a frame (and solves its pose)
    /// without a copy of the decoder on its stack.
    pub fn push(&mut self, b: u8) -> Option<NsEvent> {
        if self.buf.push(b).is_err() {
            // Cannot happen (every full buffer is resolved below), but never panic:
            self.drop_front(1);
            let _ = self.buf.push(b);
        }
        let len = self.buf.len();
        if len >= 3 && self.buf[len - 2] == SYNC[0] && b == SYNC[1] {
            // A sync word starting after the head (position >= 1; MAX_FRAME < 256).
            if let Some(v) = self.syncs.as_mut() {
                if v.push((len - 2) as u8).is_err() {
                    self.syncs = None;
                }
            }
        }
        self.next_event()
    }

    /// The next frame the bytes already buffered hold (see [`Self::push`]).
    pub fn next_event(&mut self) -> Option<NsEvent> {
        loop {
            match self.scan() {
                Scan::More => return None,
                Scan::Skip => {
                    self.stats.discarded += 1;
                    self.drop_front(1);
                }
                Scan::BadCrc => {
                    self.stats.crc_errors += 1;
                    self.stats.discarded += 1;
                    self.drop_front(1);
                }
                Scan::Embedded(p) => {
                    self.stats.discarded += p as u32;
                    self.drop_front(p);
                }
                Scan::Frame(len) => {
                    let event = parse(&self.buf[..len]);
                    self.drop_front(len);
                    match event {
                        Some(ev) => {
                            self.stats.frames += 1;
                            return Some(ev);
                        }
                        None => self.stats.discarded += len as u32,
                    }
                }
            }
        }
    }

    fn scan(&self) -> Scan {
        let b = &self.buf;
        if b.is_empty() {
            return Scan::More;
        }
        if b[0] != SYNC[0] {
            return Scan::Skip;
        }
        if b.len() < 2 {
            return Scan::More;
        }
        if b[1] != SYNC[1] {
            return Scan::Skip;
        }
        if b.len() < 4 {
            return Scan::More;
        }
        let (kind, n) = (b[2], b[3] as usize);
        if !plausible(kind, n) {
            return Scan::Skip;
        }
        let total = 4 + n + 2;
        if b.len() < total {
            // The head may be a false start (a truncated frame, noise looking like a
            // header): a complete valid frame ending at the newest byte wins at once.
            return match self.embedded_frame() {
                Some(p) => Scan::Embedded(p),
                None => Scan::More,
            };
        }
        if crc_ok(&b[..total]) {
            Scan::Frame(total)
        } else {
            Scan::BadCrc
        }
    }

    /// Offset of a CRC-valid frame that starts after the head and ends at the last byte.
    fn embedded_frame(&self) -> Option<usize> {
        let b = &self.buf;
        let len = b.len();
        let fits = |p: usize| {
            p >= 1
                && p + 6 <= len
                && b[p] == SYNC[0]
                && b[p + 1] == SYNC[1]
                && plausible(b[p + 2], b[p + 3] as usize)
                && p + 6 + b[p + 3] as usize == len
                && crc_ok(&b[p..])
        };
        match &self.syncs {
            Some(v) => v.iter().map(|&p| p as usize).find(|&p| fits(p)),
            None => (1..len.saturating_sub(5)).find(|&p| fits(p)),
        }
    }

    fn drop_front(&mut self, k: usize) {
        let k = k.min(self.buf.len());
        let len = self.buf.len();
        // A forward byte loop rather than copy_within: the only memmove on the chip would
        // bring 1.5 KB of compiler-builtins' memmove into a 48 KiB budget.
        for i in k..len {
            self.buf[i - k] = self.buf[i];
        }
        self.buf.truncate(len - k);
        // The remembered sync words move with the bytes; one that becomes the head (or is
        // dropped) is no longer after it. After an overflow, recount them.
        match self.syncs.as_mut() {
            Some(v) => v.retain_mut(|p| {
                let keep = *p as usize > k;
                *p = p.wrapping_sub(k as u8);
                keep
            }),
            None => {
                let b = &self.buf;
                let mut v = Vec::new();
                let full = (1..b.len().saturating_sub(1))
                    .filter(|&p| b[p] == SYNC[0] && b[p + 1] == SYNC[1])
                    .any(|p| v.push(p as u8).is_err());
                self.syncs = if full { None } else { Some(v) };
            }
        }
    }
}

/// Parse a CRC-valid frame; `None` if its contents are inconsistent.
fn parse(f: &[u8]) -> Option<NsEvent> {
    let body = &f[4..f.len() - 2];
    match f[2] {
        KIND_ACK => Some(NsEvent::Ack {
            kind: body[0],
            status: body[1],
        }),
        KIND_REPORT => {
            let (seq, sensitivity, count) = (body[0], body[1], body[2] as usize);
            if !(1..=4).contains(&sensitivity) || body.len() != 3 + SPOT_BYTES * count {
                return None;
            }
            let mut spots = Vec::new();
            for c in body[3..].chunks_exact(SPOT_BYTES) {
                let spot = Spot {
                    id: c[6],
                    x: i16::from_le_bytes([c[0], c[1]]),
                    y: i16::from_le_bytes([c[2], c[3]]),
                    magnitude: u16::from_le_bytes([c[4], c[5]]),
                };
                spots.push(spot).ok()?;
            }
            Some(NsEvent::Report(SpotFrame {
                seq,
                sensitivity,
                spots,
            }))
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::vec::Vec as StdVec;

    fn frame(seq: u8, n: usize) -> SpotFrame {
        let mut spots = Vec::new();
        for i in 0..n {
            spots
                .push(Spot {
                    id: i as u8,
                    x: (i as i16 - 7) * 1000,
                    y: -(i as i16) * 999,
                    magnitude: 40000 + i as u16,
                })
                .unwrap();
        }
        SpotFrame {
            seq,
            sensitivity: 3,
            spots,
        }
    }

    fn decode_all(bytes: &[u8]) -> StdVec<NsEvent> {
        let mut d = NsDecoder::new();
        let mut out = StdVec::new();
        d.feed(bytes, |e| out.push(e));
        out
    }

    /// The sequence numbers of the reports decoded from `stream` (nothing else expected).
    fn report_seqs(stream: &[u8]) -> StdVec<u8> {
        decode_all(stream)
            .into_iter()
            .map(|e| match e {
                NsEvent::Report(f) => f.seq,
                _ => panic!("unexpected {e:?}"),
            })
            .collect()
    }

    #[test]
    fn round_trip_every_size() {
        for n in 0..=MAX_SPOTS {
            let f = frame(n as u8, n);
            let mut buf = [0; MAX_FRAME];
            let len = encode_report(&f, &mut buf);
            assert_eq!(decode_all(&buf[..len]), [NsEvent::Report(f)]);
        }
    }

    #[test]
    fn resyncs_after_garbage_and_partial_frames() {
        let mut stream = StdVec::new();
        stream.extend_from_slice(&[0x00, 0xA5, 0xA5, 0x5A, 0x01, 0xFF, 0x13]);
        let mut buf = [0; MAX_FRAME];
        // A truncated frame, then a whole one, then a corrupted one, then a whole one.
        let len = encode_report(&frame(1, 5), &mut buf);
        stream.extend_from_slice(&buf[..len - 4]);
        let len = encode_report(&frame(2, 20), &mut buf);
        stream.extend_from_slice(&buf[..len]);
        let len = encode_report(&frame(3, 4), &mut buf);
        buf[10] ^= 0x40;
        stream.extend_from_slice(&buf[..len]);
        let len = encode_report(&frame(4, 4), &mut buf);
        stream.extend_from_slice(&buf[..len]);
        assert_eq!(report_seqs(&stream), [2, 4]);
    }

    #[test]
    fn a_false_start_full_of_sync_words_lets_the_next_frames_through() {
        // A plausible head of a 20-spot report that never completes, more sync words than
        // the decoder remembers, then two whole frames: each is found as soon as it ends.
        let mut stream = StdVec::from([SYNC[0], SYNC[1], KIND_REPORT, MAX_BODY as u8]);
        for _ in 0..2 * SYNCS {
            stream.extend_from_slice(&SYNC);
        }
        let mut buf = [0; MAX_FRAME];
        for seq in [7, 8] {
            let len = encode_report(&frame(seq, 3), &mut buf);
            stream.extend_from_slice(&buf[..len]);
        }
        assert_eq!(report_seqs(&stream), [7, 8]);
        // The same with a few sync words only (remembered, no scan).
        let mut stream = StdVec::from([SYNC[0], SYNC[1], KIND_REPORT, MAX_BODY as u8]);
        stream.extend_from_slice(&[SYNC[0], SYNC[1], 0x00]);
        let len = encode_report(&frame(9, 2), &mut buf);
        stream.extend_from_slice(&buf[..len]);
        assert_eq!(decode_all(&stream).len(), 1);
    }

    #[test]
    fn commands_and_acks() {
        let mut c = [0; 7];
        for cmd in [NsCommand::SetSensitivity(4), NsCommand::SetRate(10)] {
            encode_command(cmd, &mut c);
            assert_eq!(decode_command(&c), Some(cmd));
        }
        c[4] ^= 1;
        assert_eq!(decode_command(&c), None);
        let mut a = [0; 8];
        encode_ack(0x10, 0, &mut a);
        assert_eq!(
            decode_all(&a),
            [NsEvent::Ack {
                kind: 0x10,
                status: 0
            }]
        );
    }
}
