//! Beacon-board messages, carried by the framing of [`crate::wire`].
//!
//! The board drives [`LED_COUNT`] LEDs (the 10 x 10 grid; id = `row * 10 + column`, see the
//! firmware's pin map). Each LED is off, steadily on, or square-wave modulated at one or
//! more frequencies of the board's frequency table (default: the 10 NorthStar ID pairs,
//! [`crate::schedule::NORTHSTAR_TABLE_MHZ`]). Frequencies travel in millihertz (`u32`) so the
//! chip needs no floating point.

use core::fmt;

use serde::{Deserialize, Serialize};

use super::{BoardKind, DecoderStats, Protocol, ResetCause};

/// Number of LEDs on the board (10 x 10).
pub const LED_COUNT: usize = 100;
/// Longest frequency table (a [`FreqSet`] is a 32-bit mask of table indices).
pub const MAX_FREQS: usize = 32;
/// Lowest table frequency accepted, in millihertz (the modulator's half period must stay
/// under its 256-tick wheel: see [`crate::schedule`]).
pub const FREQ_MIN_MHZ: u32 = 250_000;
/// Highest table frequency accepted, in millihertz (at least 10 ticks per period).
pub const FREQ_MAX_MHZ: u32 = 12_500_000;
/// Shortest dead-man timeout accepted, ms.
pub const DEADMAN_MIN_MS: u32 = 100;
/// Longest dead-man timeout accepted, ms (the dead-man cannot be switched off).
pub const DEADMAN_MAX_MS: u32 = 3_600_000;
/// Default dead-man timeout, ms.
pub const DEADMAN_DEFAULT_MS: u32 = 10_000;
/// Default cap on simultaneously lit LEDs: the NorthStar tracks at most 20 spots, and 20 LEDs
/// at the 360 Ohm setting draw ~0.11 A. Raise it with [`BeaconRequest::SetLimits`].
pub const MAX_LIT_DEFAULT: u8 = 20;

/// Set of frequency-table indices (bit `i` = table entry `i`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FreqSet(pub u32);

impl FreqSet {
    /// The set holding only table index `i` (`i < 32`).
    pub const fn single(i: u8) -> Self {
        FreqSet(1u32 << (i & 31))
    }
    /// Indices in the set, ascending.
    pub fn indices(self) -> impl Iterator<Item = u8> {
        (0..32u8).filter(move |i| self.0 & (1 << i) != 0)
    }
}

/// What one LED does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum LedMode {
    /// Dark.
    Off,
    /// Steadily lit.
    On,
    /// Square wave (50 % duty) at each frequency of the set; with several frequencies the LED
    /// is lit while any of them is in its "on" half (logical OR of the square waves).
    Modulated(FreqSet),
}

impl LedMode {
    /// `true` unless [`LedMode::Off`].
    pub fn is_lit(self) -> bool {
        !matches!(self, LedMode::Off)
    }
}

/// One LED and what it should do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LedSetting {
    /// LED id, `row * 10 + column` (0..=99).
    pub led: u8,
    /// New mode.
    pub mode: LedMode,
}

/// Safety limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Limits {
    /// Most LEDs lit at once (1..=100); requests that would exceed it are refused.
    pub max_lit: u8,
    /// All LEDs go off when no valid frame arrived for this long
    /// ([`DEADMAN_MIN_MS`]..=[`DEADMAN_MAX_MS`]).
    pub deadman_ms: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_lit: MAX_LIT_DEFAULT,
            deadman_ms: DEADMAN_DEFAULT_MS,
        }
    }
}

/// Beacon-board requests (wrapped in [`super::Request::Board`]).
// Messages live on the stack once per exchange (no heap on the chip): size over boxing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum BeaconRequest {
    /// Report [`BeaconStatus`].
    Status,
    /// Set one LED (the others keep their mode).
    Set(LedSetting),
    /// Set several LEDs at once, atomically: either all settings apply or none (error reply).
    SetMany(heapless::Vec<LedSetting, LED_COUNT>),
    /// Every LED off.
    AllOff,
    /// Replace the frequency table (millihertz; [`FREQ_MIN_MHZ`]..=[`FREQ_MAX_MHZ`]). All
    /// LEDs go off first (their indices referred to the old table).
    SetTable(heapless::Vec<u32, MAX_FREQS>),
    /// Report the frequency table.
    GetTable,
    /// Report the mode of every LED.
    GetLeds,
    /// Change the safety limits (refused if more LEDs than the new cap are lit).
    SetLimits(Limits),
}

/// Beacon-board state reported by [`BeaconRequest::Status`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BeaconStatus {
    /// Time since boot, ms.
    pub uptime_ms: u64,
    /// LEDs currently lit (on or modulated).
    pub lit: u8,
    /// Safety limits in force.
    pub limits: Limits,
    /// Time since the last valid frame, ms.
    pub since_host_ms: u32,
    /// Times the dead-man timeout switched everything off.
    pub deadman_trips: u32,
    /// Frame decoder counters (good and bad frames, by kind).
    pub decoder: DecoderStats,
    /// Requests refused with an error reply.
    pub refused: u32,
    /// UART receive errors (overrun, framing, noise).
    pub uart_errors: u32,
    /// Modulator tick rate, Hz.
    pub tick_hz: u32,
    /// Entries in the frequency table.
    pub table_len: u8,
    /// What started the board last ([`ResetCause::Watchdog`]: its watchdog, which it feeds
    /// only while the modulator ticks).
    pub reset_cause: ResetCause,
}

/// Beacon-board responses (wrapped in [`super::Response::Board`]).
// Messages live on the stack once per exchange (no heap on the chip): size over boxing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum BeaconResponse {
    /// Answer to [`BeaconRequest::Status`].
    Status(BeaconStatus),
    /// Answer to [`BeaconRequest::GetTable`] (millihertz).
    Table(heapless::Vec<u32, MAX_FREQS>),
    /// Answer to [`BeaconRequest::GetLeds`], indexed by LED id.
    Leds(heapless::Vec<LedMode, LED_COUNT>),
}

/// Why the beacon board refused a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BeaconError {
    /// No LED with this id.
    UnknownBeacon {
        /// The id asked for.
        id: u8,
    },
    /// A frequency index beyond the table.
    FrequencyNotInTable {
        /// LED it was asked for.
        id: u8,
        /// Highest index asked for.
        index: u8,
        /// Table length.
        table_len: u8,
    },
    /// [`LedMode::Modulated`] with no frequency.
    NoFrequency {
        /// LED it was asked for.
        id: u8,
    },
    /// The same LED twice in one [`BeaconRequest::SetMany`].
    DuplicateBeacon {
        /// The repeated id.
        id: u8,
    },
    /// More LEDs would be lit than the cap allows.
    TooManyLit {
        /// LEDs that would be lit.
        requested: u8,
        /// The cap ([`Limits::max_lit`]).
        cap: u8,
    },
    /// A table frequency outside [`FREQ_MIN_MHZ`]..=[`FREQ_MAX_MHZ`].
    FrequencyOutOfRange {
        /// Table index.
        index: u8,
        /// The frequency, millihertz.
        mhz: u32,
    },
    /// An empty frequency table.
    EmptyTable,
    /// A cap outside 1..=100.
    CapOutOfRange {
        /// The cap asked for.
        max_lit: u8,
    },
    /// A dead-man timeout outside [`DEADMAN_MIN_MS`]..=[`DEADMAN_MAX_MS`].
    DeadmanOutOfRange {
        /// The timeout asked for, ms.
        ms: u32,
    },
    /// The table and LED settings would cost the modulator's tick interrupt more than its
    /// budget (the model of [`crate::schedule::tick_cost`]): too many LEDs at several
    /// frequencies, or a table of many fast frequencies.
    TickOverload {
        /// Estimated mean instructions per tick.
        instructions: u32,
        /// The budget ([`crate::schedule::TICK_BUDGET`]).
        budget: u32,
    },
}

impl fmt::Display for BeaconError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BeaconError::UnknownBeacon { id } => {
                write!(f, "unknown beacon {id} (ids are 0..={})", LED_COUNT - 1)
            }
            BeaconError::FrequencyNotInTable { id, index, table_len } => write!(
                f,
                "beacon {id}: frequency index {index} is not in the table (it has {table_len} entries)"
            ),
            BeaconError::NoFrequency { id } => {
                write!(f, "beacon {id}: modulated with an empty frequency set")
            }
            BeaconError::DuplicateBeacon { id } => {
                write!(f, "beacon {id} appears twice in one request")
            }
            BeaconError::TooManyLit { requested, cap } => write!(
                f,
                "{requested} LEDs would be lit but the cap is {cap} (raise it with `cta beacon limits --max-lit N`)"
            ),
            BeaconError::FrequencyOutOfRange { index, mhz } => write!(
                f,
                "table entry {index}: {}.{:03} Hz is outside {}..={} Hz",
                mhz / 1000,
                mhz % 1000,
                FREQ_MIN_MHZ / 1000,
                FREQ_MAX_MHZ / 1000
            ),
            BeaconError::EmptyTable => f.write_str("empty frequency table"),
            BeaconError::CapOutOfRange { max_lit } => {
                write!(f, "cap {max_lit} is outside 1..={LED_COUNT}")
            }
            BeaconError::DeadmanOutOfRange { ms } => write!(
                f,
                "dead-man timeout {ms} ms is outside {DEADMAN_MIN_MS}..={DEADMAN_MAX_MS} ms"
            ),
            BeaconError::TickOverload {
                instructions,
                budget,
            } => write!(
                f,
                "the modulator's tick interrupt would take about {instructions} instructions per \
                 tick, over its budget of {budget} (half the 576 cycles between ticks): light \
                 fewer LEDs at several frequencies at once, or use fewer or slower table \
                 frequencies"
            ),
        }
    }
}

/// The beacon board's [`Protocol`].
#[derive(Debug, Clone, Copy)]
pub struct Beacon;

impl Protocol for Beacon {
    const BOARD: BoardKind = BoardKind::Beacon;
    type Request = BeaconRequest;
    type Response = BeaconResponse;
    type Error = BeaconError;
}
