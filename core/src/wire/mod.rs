//! Wire protocol shared by the beacon board, the sensor board and the host.
//!
//! # Frame format
//!
//! Every message, in both directions, travels as one *frame*:
//!
//! ```text
//! 0x00 | COBS( postcard(Header) ++ postcard(body) ++ CRC-32C little-endian ) | 0x00
//! ```
//!
//! * The payload `postcard(Header) ++ postcard(body) ++ crc` is byte-for-byte what
//!   [`postcard::to_slice_crc32`] produces for the pair `(Header, body)` with the digest of
//!   [`CRC`] (CRC-32/ISCSI, "Castagnoli"): the CRC is postcard's own `use-crc` flavor's
//!   (computed here by [`crc32c`], without the `crc` crate's 1 KiB table; tested equal).
//! * COBS (consistent overhead byte stuffing, postcard's `Cobs` flavor) removes every zero
//!   byte from the payload, so `0x00` only ever appears as a frame delimiter.
//! * The sender writes a delimiter *before* and after each frame. A receiver that saw
//!   garbage or half a frame therefore always resynchronises on the leading zero of the next
//!   frame: no valid frame is ever lost because of what came before it.
//!
//! [`FrameDecoder`] is the bounded receiver (a `[u8; N]` buffer, no allocation, never
//! panics). It counts every bad frame by kind in [`DecoderStats`] and reports each one as a
//! [`FrameError`] so that the board can answer it.
//!
//! # Header
//!
//! [`Header`] carries the protocol version ([`PROTOCOL_VERSION`]) and a sequence number.
//! The version is the first field and the sequence number the second, in every version of
//! this protocol, so a board can always answer a frame from a newer or older host with
//! [`FrameFault::Version`] naming both versions. The host numbers its requests on from a
//! random start (a reply left on the line by an earlier connection cannot match), skipping
//! [`SEQ_NONE`] (0) on wrap-around; a board echoes the request's sequence number
//! in its reply, and uses [`SEQ_NONE`] when it answers a frame whose header it could not
//! read (bad COBS, bad CRC, oversized...).
//!
//! # Messages
//!
//! The bodies are generic: each board defines its own request, response and error enums
//! (in [`beacon`] and [`sensor`]) and ties them together with the [`Protocol`] trait. The
//! envelope adds what every board understands the same way:
//!
//! * host to board: [`Request<B>`]: [`Request::Identify`], [`Request::Heartbeat`] or
//!   [`Request::Board`] with the board's own request;
//! * board to host: [`Reply<B, E>`] `= Result<Response<B>, ErrorReply<E>>`: every request is
//!   answered, either with a response ([`Response::Ack`] when there is nothing to say) or
//!   with an error naming the problem.
//!
//! Because `Identify` is variant 0 of every `Request<B>` and `Identity` variant 0 of every
//! `Response<B>`, [`Request::<()>::Identify`] can be sent to a board of unknown kind and its
//! reply decoded without knowing the board's message types (see [`Identity`]).
//!
//! Everything here is `no_std` and allocation-free; bounded collections are `heapless`.

use core::fmt;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

pub mod beacon;
pub mod sensor;

/// Version of this wire protocol; bumped on any incompatible change of the framing,
/// the envelope or a board's messages. 6: both boards' status carries its [`ResetCause`]
/// (the beacon board's had a watchdog flag, the sensor board's nothing). 7: the sensor
/// board's calibration carries the spot magnitude law ([`crate::pose::Magnitude`]), its
/// constellation each beacon's brightness, and its pose report the magnitudes fitted
/// ([`sensor::PoseReport::magnitudes`]). 8: the pose report names the beacon a solve left
/// out ([`sensor::PoseReport::dropped`]: a wrong spot, or an ID reported twice).
pub const PROTOCOL_VERSION: u16 = 8;

/// Sequence number meaning "unknown": used in replies to frames whose header could not be
/// read. Hosts never use it for a request.
pub const SEQ_NONE: u16 = 0;

/// Largest frame (leading and trailing delimiters included) that the boards accept or send.
/// Both boards use it for their receive buffer ([`FrameDecoder<MAX_FRAME>`]) and transmit
/// buffer; larger frames are rejected as [`FrameFault::Oversized`].
pub const MAX_FRAME: usize = 1024;

/// The CRC of every frame: CRC-32/ISCSI (Castagnoli), as used by postcard's CRC flavors.
/// The crate's own framing computes it with [`crc32c`] (the same checksum; this object's
/// 1 KiB table would cost the sensor board's flash); this is for hosts that want the `crc`
/// crate's API.
pub const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// Reflected CRC-32C polynomial (0x1EDC6F41 bit-reversed).
const CRC32C_POLY: u32 = 0x82F6_3B78;

/// CRC-32C of every 4-bit value: two look-ups per byte from a 64-byte table.
const CRC32C_NIBBLES: [u32; 16] = {
    let mut t = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = (c >> 1) ^ (CRC32C_POLY & (c & 1).wrapping_neg());
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// The running CRC-32C register after `bytes` (no initial or final XOR: start from
/// `!0`, finish with `!`).
fn crc32c_update(mut crc: u32, bytes: &[u8]) -> u32 {
    for &b in bytes {
        crc ^= u32::from(b);
        crc = (crc >> 4) ^ CRC32C_NIBBLES[(crc & 15) as usize];
        crc = (crc >> 4) ^ CRC32C_NIBBLES[(crc & 15) as usize];
    }
    crc
}

/// CRC-32C (CRC-32/ISCSI) of `bytes`: `CRC.checksum(bytes)` without its 1 KiB table.
pub fn crc32c(bytes: &[u8]) -> u32 {
    !crc32c_update(!0, bytes)
}

/// postcard flavor appending the CRC-32C of everything serialized (little-endian), as
/// postcard's own `CrcModifier` with [`CRC`]'s digest does, byte for byte.
struct Crc32cFlavor<B> {
    flav: B,
    crc: u32,
}

impl<B: postcard::ser_flavors::Flavor> postcard::ser_flavors::Flavor for Crc32cFlavor<B> {
    type Output = B::Output;

    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.crc = crc32c_update(self.crc, &[data]);
        self.flav.try_push(data)
    }

    fn finalize(mut self) -> postcard::Result<Self::Output> {
        for byte in (!self.crc).to_le_bytes() {
            self.flav.try_push(byte)?;
        }
        self.flav.finalize()
    }
}

/// Length in bytes of the CRC trailer.
const CRC_LEN: usize = 4;

/// Frame header: protocol version, then sequence number (this order is fixed forever).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Protocol version of the sender ([`PROTOCOL_VERSION`]).
    pub version: u16,
    /// Request sequence number (host-chosen, echoed in the reply); [`SEQ_NONE`] if unknown.
    pub seq: u16,
}

impl Header {
    /// Header of the current protocol version with sequence number `seq`.
    pub const fn new(seq: u16) -> Self {
        Self {
            version: PROTOCOL_VERSION,
            seq,
        }
    }
}

/// Which board answered an [`Request::Identify`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BoardKind {
    /// The 10 x 10 IR beacon array (STM32F103ZET6).
    Beacon,
    /// The NorthStar sensor board (STM32F103 x8).
    Sensor,
}

impl fmt::Display for BoardKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BoardKind::Beacon => "beacon",
            BoardKind::Sensor => "sensor",
        })
    }
}

/// Reply to [`Request::Identify`]: who answered and which protocol it speaks.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// Board kind.
    pub board: BoardKind,
    /// Protocol version the board speaks ([`PROTOCOL_VERSION`] of its build).
    pub protocol: u16,
    /// Firmware version (the crate version), e.g. `"0.1.0"`.
    pub firmware: heapless::String<16>,
    /// `true` for the simulated board running on the host.
    pub simulated: bool,
    /// Largest frame the board accepts, delimiters included.
    pub max_frame: u16,
}

/// Why a board last started, as both boards report it in their status: read from the
/// STM32F1's reset flags (RCC_CSR, RM0008 7.3.10) at boot, which then clears them (RMVF) so
/// that the next reset is told apart. A simulated board says what started it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ResetCause {
    /// Power-on or power-down reset (PORRSTF): the board was powered up, or its supply
    /// dipped below the POR/PDR threshold (a brown-out).
    PowerOn,
    /// The NRST pin (PINRSTF alone): the reset button, or a probe's hardware reset.
    Pin,
    /// The independent or the window watchdog (IWDGRSTF, WWDGRSTF): the main loop stopped
    /// feeding it (stuck, or a fault handler waiting for it).
    Watchdog,
    /// A software reset (SFTRSTF, SYSRESETREQ): the firmware's own retry at start-up (the
    /// crystal check), or a probe's reset.
    Software,
    /// A low-power management reset (LPWRRSTF: Standby or Stop entered while the option
    /// bytes forbid it).
    LowPower,
    /// No flag set (not expected after a reset).
    Unknown,
}

impl ResetCause {
    /// RCC_CSR's reset flags (STM32F1).
    pub const CSR_LPWRRSTF: u32 = 1 << 31;
    /// Window watchdog reset flag.
    pub const CSR_WWDGRSTF: u32 = 1 << 30;
    /// Independent watchdog reset flag.
    pub const CSR_IWDGRSTF: u32 = 1 << 29;
    /// Software reset flag.
    pub const CSR_SFTRSTF: u32 = 1 << 28;
    /// Power-on/power-down reset flag.
    pub const CSR_PORRSTF: u32 = 1 << 27;
    /// NRST pin reset flag.
    pub const CSR_PINRSTF: u32 = 1 << 26;

    /// The cause a value of RCC_CSR read at boot names. An internal reset drives the NRST
    /// pin low too (PINRSTF may be set with its own flag), and a power-on reset sets
    /// PINRSTF with PORRSTF (the register's power-on value), so the pin counts only alone;
    /// the other flags are taken in the order low-power, watchdog, software, power-on.
    pub fn from_rcc_csr(csr: u32) -> ResetCause {
        if csr & Self::CSR_LPWRRSTF != 0 {
            ResetCause::LowPower
        } else if csr & (Self::CSR_IWDGRSTF | Self::CSR_WWDGRSTF) != 0 {
            ResetCause::Watchdog
        } else if csr & Self::CSR_SFTRSTF != 0 {
            ResetCause::Software
        } else if csr & Self::CSR_PORRSTF != 0 {
            ResetCause::PowerOn
        } else if csr & Self::CSR_PINRSTF != 0 {
            ResetCause::Pin
        } else {
            ResetCause::Unknown
        }
    }

    /// In words, as `cta beacon status` and `cta sensor status` print it.
    pub fn name(self) -> &'static str {
        match self {
            ResetCause::PowerOn => "power-on",
            ResetCause::Pin => "reset pin",
            ResetCause::Watchdog => "watchdog",
            ResetCause::Software => "software",
            ResetCause::LowPower => "low-power",
            ResetCause::Unknown => "unknown",
        }
    }
}

impl fmt::Display for ResetCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Host-to-board message: the common requests plus the board's own (`B`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Request<B> {
    /// Ask the board who it is; answered with [`Response::Identity`]. Always variant 0.
    Identify,
    /// "The host is alive": resets the board's dead-man timer; answered with [`Response::Ack`].
    Heartbeat,
    /// A board-specific request.
    Board(B),
}

/// Board-to-host message: the common responses plus the board's own (`B`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum Response<B> {
    /// Answer to [`Request::Identify`]. Always variant 0.
    Identity(Identity),
    /// The request was carried out and there is nothing else to report.
    Ack,
    /// A board-specific response.
    Board(B),
}

/// What a board sends back for every request: a response, or an error naming the problem.
pub type Reply<B, E> = Result<Response<B>, ErrorReply<E>>;

/// Error reply: the frame was unusable, or the board refused the request (`E`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorReply<E> {
    /// The request frame could not be decoded (the board counted it in its [`DecoderStats`]).
    BadFrame(FrameFault),
    /// The request was understood but refused, with the board's reason.
    Board(E),
}

impl<E: fmt::Display> fmt::Display for ErrorReply<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ErrorReply::BadFrame(fault) => write!(f, "board rejected the frame: {fault}"),
            ErrorReply::Board(e) => write!(f, "board refused the request: {e}"),
        }
    }
}

/// Ties a board's message types together, for generic clients (the host's link) and servers.
pub trait Protocol {
    /// The board this protocol talks to (checked against [`Identity::board`]).
    const BOARD: BoardKind;
    /// Board-specific requests (wrapped in [`Request::Board`]).
    type Request: Serialize + DeserializeOwned + fmt::Debug + Clone;
    /// Board-specific responses (wrapped in [`Response::Board`]).
    type Response: Serialize + DeserializeOwned + fmt::Debug + Clone;
    /// Board-specific refusals (wrapped in [`ErrorReply::Board`]).
    type Error: Serialize + DeserializeOwned + fmt::Debug + fmt::Display + Clone;
}

/// Why a received frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FrameFault {
    /// More than the receiver's buffer between two delimiters (bytes discarded up to the next
    /// delimiter).
    Oversized,
    /// Not valid COBS.
    Encoding,
    /// Too short to hold a header and a CRC (e.g. a truncated frame).
    Truncated,
    /// CRC mismatch (corrupted or truncated frame).
    Crc,
    /// CRC correct but the header could not be read.
    Header,
    /// The sender speaks another protocol version.
    Version {
        /// Version in the received header.
        got: u16,
        /// Version the receiver speaks.
        supported: u16,
    },
    /// Header fine but the body is not a message of the expected type (unknown request,
    /// out-of-range field, extra bytes...).
    Body,
}

impl fmt::Display for FrameFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameFault::Oversized => f.write_str("frame larger than the receive buffer"),
            FrameFault::Encoding => f.write_str("invalid COBS encoding"),
            FrameFault::Truncated => f.write_str("frame too short (truncated)"),
            FrameFault::Crc => f.write_str("CRC mismatch (corrupted frame)"),
            FrameFault::Header => f.write_str("unreadable header"),
            FrameFault::Version { got, supported } => write!(
                f,
                "protocol version {got} not supported (this side speaks {supported})"
            ),
            FrameFault::Body => f.write_str("unknown or malformed message body"),
        }
    }
}

/// A rejected frame: the fault, and the sequence number if the header could be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameError {
    /// What was wrong.
    pub fault: FrameFault,
    /// Sequence number from the header, or [`SEQ_NONE`] if it could not be read.
    pub seq: u16,
}

/// Counters kept by a [`FrameDecoder`] (reported by the boards' status replies).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DecoderStats {
    /// Frames decoded successfully.
    pub ok: u32,
    /// [`FrameFault::Oversized`] frames.
    pub oversized: u32,
    /// [`FrameFault::Encoding`] frames.
    pub encoding: u32,
    /// [`FrameFault::Truncated`] frames.
    pub truncated: u32,
    /// [`FrameFault::Crc`] frames.
    pub crc: u32,
    /// [`FrameFault::Header`] and [`FrameFault::Body`] frames (CRC fine, content not).
    pub malformed: u32,
    /// [`FrameFault::Version`] frames.
    pub version: u32,
}

impl DecoderStats {
    /// Total number of rejected frames.
    pub fn bad(&self) -> u32 {
        self.oversized
            .saturating_add(self.encoding)
            .saturating_add(self.truncated)
            .saturating_add(self.crc)
            .saturating_add(self.malformed)
            .saturating_add(self.version)
    }

    fn count(&mut self, fault: FrameFault) {
        let c = match fault {
            FrameFault::Oversized => &mut self.oversized,
            FrameFault::Encoding => &mut self.encoding,
            FrameFault::Truncated => &mut self.truncated,
            FrameFault::Crc => &mut self.crc,
            FrameFault::Header | FrameFault::Body => &mut self.malformed,
            FrameFault::Version { .. } => &mut self.version,
        };
        *c = c.saturating_add(1);
    }
}

/// Why a frame could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is too small for the frame.
    BufferFull,
    /// The message could not be serialized (should not happen with this crate's types).
    Serialize,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BufferFull => f.write_str("frame does not fit the output buffer"),
            EncodeError::Serialize => f.write_str("message could not be serialized"),
        }
    }
}

/// Encode `body` with `header` as one complete frame (both delimiters included) at the start
/// of `buf`; returns the frame. Fails with [`EncodeError::BufferFull`] if it does not fit.
pub fn encode_frame<'a, M: Serialize + ?Sized>(
    header: Header,
    body: &M,
    buf: &'a mut [u8],
) -> Result<&'a [u8], EncodeError> {
    use postcard::ser_flavors::{Cobs, Slice};
    let (first, rest) = buf.split_first_mut().ok_or(EncodeError::BufferFull)?;
    *first = 0;
    let map = |e| match e {
        postcard::Error::SerializeBufferFull => EncodeError::BufferFull,
        _ => EncodeError::Serialize,
    };
    // CRC over the raw payload, then COBS over payload + CRC (the Cobs flavor appends the
    // trailing delimiter).
    let cobs = Cobs::try_new(Slice::new(rest)).map_err(map)?;
    let flavor = Crc32cFlavor {
        flav: cobs,
        crc: !0,
    };
    let n = postcard::serialize_with_flavor(&(header, body), flavor)
        .map_err(map)?
        .len();
    Ok(&buf[..n + 1])
}

/// Bounded, resynchronising frame receiver with an `N`-byte buffer.
///
/// Feed it the received bytes one at a time with [`FrameDecoder::push`]. Bytes between two
/// delimiters are collected (at most `N - 1` of them; more is [`FrameFault::Oversized`] and
/// the rest is skipped up to the next delimiter); at each delimiter the collected bytes are
/// COBS-decoded in place, the CRC checked, then the header and the body of type `M`
/// deserialized. Empty frames (two delimiters in a row, e.g. the trailing delimiter of one
/// frame and the leading one of the next) are skipped silently. It never panics, whatever
/// the input.
pub struct FrameDecoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflowed: bool,
    stats: DecoderStats,
}

impl<const N: usize> Default for FrameDecoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameDecoder<N> {
    /// Empty decoder with zeroed counters.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflowed: false,
            stats: DecoderStats {
                ok: 0,
                oversized: 0,
                encoding: 0,
                truncated: 0,
                crc: 0,
                malformed: 0,
                version: 0,
            },
        }
    }

    /// Counters of good and bad frames so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Discard any partly received frame (the counters are kept).
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflowed = false;
    }

    /// Feed one byte. Returns `None` while a frame is in progress (or for an empty frame),
    /// and at a delimiter the decoded frame or the reason it was rejected.
    pub fn push<M: DeserializeOwned>(
        &mut self,
        byte: u8,
    ) -> Option<Result<(Header, M), FrameError>> {
        if byte != 0 {
            // Keep one byte of the buffer free so an N-byte frame (delimiters included)
            // is the largest accepted: N - 2 payload bytes plus the trailing delimiter slot.
            if self.len + 2 < N {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflowed = true;
            }
            return None;
        }
        let (len, overflowed) = (self.len, self.overflowed);
        self.reset();
        if overflowed {
            return Some(Err(self.reject(FrameFault::Oversized, SEQ_NONE)));
        }
        if len == 0 {
            return None;
        }
        let result = self.decode(len);
        match &result {
            Ok(_) => self.stats.ok = self.stats.ok.saturating_add(1),
            Err(e) => self.stats.count(e.fault),
        }
        Some(result)
    }

    fn reject(&mut self, fault: FrameFault, seq: u16) -> FrameError {
        self.stats.count(fault);
        FrameError { fault, seq }
    }

    fn decode<M: DeserializeOwned>(&mut self, len: usize) -> Result<(Header, M), FrameError> {
        let err = |fault, seq| FrameError { fault, seq };
        let n = cobs::decode_in_place(&mut self.buf[..len])
            .map_err(|_| err(FrameFault::Encoding, SEQ_NONE))?;
        let data = &self.buf[..n];
        if n < CRC_LEN + 2 {
            return Err(err(FrameFault::Truncated, SEQ_NONE));
        }
        let (payload, crc) = data.split_at(n - CRC_LEN);
        if crc32c(payload).to_le_bytes() != crc {
            return Err(err(FrameFault::Crc, SEQ_NONE));
        }
        let (header, body) = postcard::take_from_bytes::<Header>(payload)
            .map_err(|_| err(FrameFault::Header, SEQ_NONE))?;
        if header.version != PROTOCOL_VERSION {
            return Err(err(
                FrameFault::Version {
                    got: header.version,
                    supported: PROTOCOL_VERSION,
                },
                header.seq,
            ));
        }
        match postcard::take_from_bytes::<M>(body) {
            Ok((msg, [])) => Ok((header, msg)),
            _ => Err(err(FrameFault::Body, header.seq)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Msg = Request<u32>;

    fn frame(seq: u16, m: &Msg) -> heapless::Vec<u8, 64> {
        let mut buf = [0u8; 64];
        let f = encode_frame(Header::new(seq), m, &mut buf).unwrap();
        heapless::Vec::from_slice(f).unwrap()
    }

    fn feed<const N: usize>(
        d: &mut FrameDecoder<N>,
        bytes: &[u8],
    ) -> heapless::Vec<Result<(Header, Msg), FrameError>, 16> {
        let mut out = heapless::Vec::new();
        for &b in bytes {
            if let Some(r) = d.push::<Msg>(b) {
                out.push(r).unwrap();
            }
        }
        out
    }

    #[test]
    fn round_trip_and_format_is_postcard_crc_then_cobs() {
        let m = Request::Board(0xdead_beef);
        let f = frame(7, &m);
        assert_eq!(f[0], 0);
        assert_eq!(*f.last().unwrap(), 0);
        assert!(f[1..f.len() - 1].iter().all(|&b| b != 0));
        // Same bytes as postcard's own CRC serializer followed by COBS.
        let mut raw = [0u8; 64];
        let raw = postcard::to_slice_crc32(&(Header::new(7), &m), &mut raw, CRC.digest()).unwrap();
        let mut enc = [0u8; 64];
        let k = cobs::encode(raw, &mut enc);
        assert_eq!(&f[1..f.len() - 1], &enc[..k]);

        let mut d = FrameDecoder::<64>::new();
        let got = feed(&mut d, &f);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0], Ok((Header::new(7), m)));
        assert_eq!(d.stats().ok, 1);
        assert_eq!(d.stats().bad(), 0);
    }

    /// The CRC is CRC-32C: its catalogue check value (the CRC of the ASCII digits
    /// "123456789"), which CRC-32/ISO-HDLC (0xCBF43926) and the other 32-bit CRCs do not have.
    #[test]
    fn crc_is_crc32c() {
        assert_eq!(CRC.checksum(b"123456789"), 0xE306_9283);
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
    }

    /// [`crc32c`] (what the framing and the sensor board's storage use) is [`CRC`]'s
    /// checksum on every length and byte value, and [`encode_frame`] is postcard's CRC flavor
    /// byte for byte on longer messages too.
    #[test]
    fn nibble_crc_equals_the_crc_crate() {
        let mut x = 0x1234_5678_u32;
        let mut data = [0u8; 600];
        for b in data.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
        for n in 0..data.len() {
            assert_eq!(crc32c(&data[..n]), CRC.checksum(&data[..n]), "length {n}");
        }
        for v in 0..=255u8 {
            assert_eq!(crc32c(&[v]), CRC.checksum(&[v]));
            assert_eq!(crc32c(&[v; 3]), CRC.checksum(&[v; 3]));
        }
        let m: Request<[u32; 20]> = Request::Board(core::array::from_fn(|k| (k as u32) << (k + 7)));
        let mut buf = [0u8; 256];
        let f = encode_frame(Header::new(300), &m, &mut buf).unwrap();
        let mut raw = [0u8; 256];
        let raw =
            postcard::to_slice_crc32(&(Header::new(300), &m), &mut raw, CRC.digest()).unwrap();
        let mut enc = [0u8; 256];
        let k = cobs::encode(raw, &mut enc);
        assert_eq!(&f[1..f.len() - 1], &enc[..k]);
    }

    /// Golden frames: the exact bytes on the wire, so any change of the format (header,
    /// envelope, varints, CRC, COBS, delimiters) fails here. They were computed without this
    /// crate, by a short Python script written from the specifications: CRC-32C bitwise
    /// (reflected polynomial 0x82F63B78, init and final XOR 0xFFFFFFFF; its check value is
    /// 0xE3069283), postcard's varints (7 bits per byte, least significant first, high bit =
    /// more) for the u16 header fields, the enum variant indices and the u32, and COBS (each
    /// zero-free run prefixed with its length + 1):
    ///
    /// ```text
    /// def crc32c(d):
    ///     c = 0xFFFFFFFF
    ///     for b in d:
    ///         c ^= b
    ///         for _ in range(8): c = (c >> 1) ^ (0x82F63B78 if c & 1 else 0)
    ///     return c ^ 0xFFFFFFFF
    /// def varint(n):  # [n & 0x7F | 0x80, ...] until n < 0x80
    /// def cobs(d):    # split at zeros, each run r -> [len(r) + 1] + r (runs of 254 split)
    /// frame = [0] + cobs(payload + crc32c(payload).to_bytes(4, 'little')) + [0]
    /// ```
    ///
    /// Frame 1: header (version 8, seq 7) = 08 07, `Request::Board` = variant 2 = 02,
    /// 0xdeadbeef = varint ef fd b6 f5 0d; CRC-32C 0xddbefe65 = 65 fe be dd (LE); no zero,
    /// so COBS is one run of 12: 0d then the 12 bytes.
    /// Frame 2: header (8, seq 300 = varint ac 02), `Request::Board` 02,
    /// `SensorRequest::Status` = variant 0 = 00; CRC 0xe0dc90e6 = e6 90 dc e0; COBS splits at
    /// the zero: 05 | 08 ac 02 02, 05 | e6 90 dc e0. (Protocols 5, 6 and 7 had the same frames
    /// with 05, 06 and 07 for the version and the CRCs 0xf7a405f5, 0xfdef4a6b, 0x65dcffbb and
    /// 0x2ce0829c, 0xb5dcfa9f, 0x8dcd9533: the script reproduces them too.)
    /// RCC_CSR values as the STM32F1 leaves them (RM0008 7.3.10; bits 0-1 are LSION and
    /// LSIRDY, bit 24 RMVF): each cause on its own, with the NRST flag an internal reset may
    /// set along, and the power-on value.
    #[test]
    fn reset_cause_from_the_csr_flags() {
        use ResetCause::*;
        let pin = ResetCause::CSR_PINRSTF;
        for (csr, cause) in [
            (0x0C00_0000, PowerOn),
            (0x0C00_0003, PowerOn),
            (pin, Pin),
            (pin | 0x3, Pin),
            (ResetCause::CSR_IWDGRSTF | pin, Watchdog),
            (ResetCause::CSR_IWDGRSTF, Watchdog),
            (ResetCause::CSR_WWDGRSTF | pin, Watchdog),
            (ResetCause::CSR_SFTRSTF | pin, Software),
            (ResetCause::CSR_LPWRRSTF | pin, LowPower),
            (0, Unknown),
            (0x0100_0003, Unknown),
        ] {
            assert_eq!(ResetCause::from_rcc_csr(csr), cause, "{csr:#010x}");
        }
        assert_eq!(
            ResetCause::from_rcc_csr(ResetCause::CSR_IWDGRSTF | ResetCause::CSR_SFTRSTF),
            Watchdog
        );
        assert_eq!(Watchdog.to_string(), "watchdog");
    }

    #[test]
    fn golden_frames() {
        assert_eq!(
            PROTOCOL_VERSION, 8,
            "a protocol version bump changes the golden frames: recompute them (see above)"
        );
        let mut buf = [0u8; 64];
        let f = encode_frame(
            Header::new(7),
            &Request::<u32>::Board(0xdead_beef),
            &mut buf,
        )
        .unwrap();
        assert_eq!(
            f,
            [
                0x00, 0x0d, 0x08, 0x07, 0x02, 0xef, 0xfd, 0xb6, 0xf5, 0x0d, 0x65, 0xfe, 0xbe, 0xdd,
                0x00
            ]
        );
        let mut d = FrameDecoder::<64>::new();
        assert_eq!(
            feed(&mut d, f)[0],
            Ok((Header::new(7), Request::Board(0xdead_beef)))
        );

        let status = Request::Board(sensor::SensorRequest::Status);
        let f = encode_frame(Header::new(300), &status, &mut buf).unwrap();
        assert_eq!(
            f,
            [0x00, 0x05, 0x08, 0xac, 0x02, 0x02, 0x05, 0xe6, 0x90, 0xdc, 0xe0, 0x00]
        );
        let mut d = FrameDecoder::<64>::new();
        let got = f
            .iter()
            .filter_map(|&b| d.push::<Request<sensor::SensorRequest>>(b))
            .collect::<heapless::Vec<_, 2>>();
        assert_eq!(got.as_slice(), [Ok((Header::new(300), status))]);
    }

    #[test]
    fn corrupted_frame_is_counted_and_next_frame_survives() {
        let good = frame(3, &Request::Heartbeat);
        let mut bad = frame(2, &Request::Board(12345));
        bad[3] ^= 0x40;
        if bad[3] == 0 {
            bad[3] = 1;
        }
        let mut d = FrameDecoder::<64>::new();
        let mut stream: heapless::Vec<u8, 128> = heapless::Vec::new();
        stream.extend_from_slice(&bad).unwrap();
        stream.extend_from_slice(&good).unwrap();
        let got = feed(&mut d, &stream);
        assert_eq!(got.len(), 2);
        assert!(got[0].is_err());
        assert_eq!(got[1], Ok((Header::new(3), Request::Heartbeat)));
        assert_eq!(d.stats().bad(), 1);
    }

    #[test]
    fn truncated_then_valid_frame() {
        let good = frame(9, &Request::Identify);
        let mut d = FrameDecoder::<64>::new();
        // Half a frame without its trailing delimiter, then a full frame.
        let got = feed(&mut d, &good[..good.len() / 2]);
        assert!(got.is_empty());
        let got = feed(&mut d, &good);
        assert_eq!(got.len(), 2);
        assert!(got[0].is_err());
        assert_eq!(got[1], Ok((Header::new(9), Request::Identify)));
    }

    #[test]
    fn oversized_frame_is_rejected_and_decoder_recovers() {
        let mut d = FrameDecoder::<16>::new();
        let got = feed(&mut d, &[0x55; 100]);
        assert!(got.is_empty());
        let got = feed(&mut d, &[0]);
        assert_eq!(
            got[0],
            Err(FrameError {
                fault: FrameFault::Oversized,
                seq: SEQ_NONE
            })
        );
        let good = frame(1, &Request::Heartbeat);
        let got = feed(&mut d, &good);
        assert_eq!(got[0], Ok((Header::new(1), Request::Heartbeat)));
        assert_eq!(d.stats().oversized, 1);
        // A frame of exactly N bytes (delimiters included) fits a FrameDecoder<N>, not a FrameDecoder<N - 1>.
        fn accepts<const M: usize>(bytes: &[u8]) -> bool {
            let mut d = FrameDecoder::<M>::new();
            bytes
                .iter()
                .filter_map(|&b| d.push::<Msg>(b))
                .any(|r| r.is_ok())
        }
        let mut buf = [0u8; 32];
        let f = encode_frame(Header::new(1), &Request::<u32>::Board(u32::MAX), &mut buf).unwrap();
        assert_eq!(f.len(), 15);
        assert!(accepts::<15>(f));
        assert!(!accepts::<14>(f));
    }

    #[test]
    fn version_and_body_faults_carry_the_sequence_number() {
        let mut buf = [0u8; 64];
        let hdr = Header {
            version: 99,
            seq: 42,
        };
        let f = encode_frame(hdr, &Request::<u32>::Heartbeat, &mut buf).unwrap();
        let mut d = FrameDecoder::<64>::new();
        let got = feed(&mut d, f);
        assert_eq!(
            got[0],
            Err(FrameError {
                fault: FrameFault::Version {
                    got: 99,
                    supported: PROTOCOL_VERSION
                },
                seq: 42
            })
        );
        // Variant 7 does not exist in Request<u32>.
        let f = encode_frame(Header::new(43), &7u8, &mut buf).unwrap();
        let got = feed(&mut d, f);
        assert_eq!(
            got[0],
            Err(FrameError {
                fault: FrameFault::Body,
                seq: 43
            })
        );
        // Trailing bytes after a valid body are refused too.
        let f = encode_frame(Header::new(44), &(1u8, 5u8, 6u8), &mut buf).unwrap();
        let got = feed(&mut d, f);
        assert_eq!(
            got[0],
            Err(FrameError {
                fault: FrameFault::Body,
                seq: 44
            })
        );
        assert_eq!(d.stats().version, 1);
        assert_eq!(d.stats().malformed, 2);
    }

    #[test]
    fn identify_is_understood_without_the_board_types() {
        let mut buf = [0u8; 64];
        let f = encode_frame(Header::new(5), &Request::<()>::Identify, &mut buf).unwrap();
        let mut d = FrameDecoder::<64>::new();
        let got = feed(&mut d, f);
        assert_eq!(got[0], Ok((Header::new(5), Request::Identify)));
    }
}
