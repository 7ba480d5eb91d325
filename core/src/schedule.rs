//! Beacon modulation schedule: which LED output lines change on which tick.
//!
//! The beacon board (thesis Ch IV, Table 1; REFERENCE.md section 4) square-wave modulates
//! each of its 100 LEDs at frequencies of a table (default: the 10 NorthStar ID pairs,
//! [`NORTHSTAR_TABLE_MHZ`]). This module is the whole modulation logic, host-testable and
//! `no_std`; the firmware's timer interrupt only calls [`Modulator::tick`] and writes the
//! GPIO `BSRR` words it is handed, and the simulated board runs the very same code.
//!
//! # Algorithm: a timing wheel of half-period edges
//!
//! A timer interrupt runs at [`TICK_HZ`]. Each table frequency `f` toggles its square wave
//! every half period `h = TICK_HZ / (2 f)` ticks, kept in fixed point (Q8.24, so the mean
//! frequency is exact to ~1e-8 and edges fall on the tick at or just after the ideal time:
//! the edge jitter is below one tick, 8 us). The next toggle of every frequency is
//! recorded in a 256-slot wheel (`wheel[slot]` = bit mask of the frequencies toggling on
//! that tick), so a tick only touches the frequencies due on it: ~1.6 on average with the 20
//! NorthStar frequencies, instead of scanning all 20 every tick. On a toggle of `f`:
//!
//! * every LED modulated at `f` alone flips: one `ODR ^= mask` per output bank (a GPIO port
//!   on the chip) holding such LEDs ([`Gpio::toggle`]), which leaves the other lines of the
//!   bank (the USART, SWD and crystal pins) untouched;
//! * every LED modulated at several frequencies (OR of their square waves) is set or reset
//!   from the current wave levels with a `BSRR` write ([`Gpio::write`]; rare, kept in a
//!   separate list).
//!
//! [`Modulator::levels`] computes the outputs from the wave levels alone; the tests check on
//! every tick that the incremental line changes reproduce them.
//!
//! # Lines, not pins
//!
//! The modulator drives LED `id` (`row * 10 + column`, [`grid_position`]) on the output
//! [`Line`] it is given for it: a bit of one of [`BANKS`] 16-bit banks. Which GPIO pin that
//! is belongs to the board: firmware-beacon's pin map.

use crate::wire::beacon::{LedMode, FREQ_MAX_MHZ, FREQ_MIN_MHZ, LED_COUNT, MAX_FREQS};

/// Modulator tick rate, Hz: TIM2 update interrupt at 72 MHz / 576 (8 us per tick).
pub const TICK_HZ: u32 = 125_000;
/// Output banks of 16 lines the modulator drives (on the beacon board: its seven GPIO ports).
pub const BANKS: usize = 7;
/// Slots of the timing wheel; every half period must be shorter than this many ticks.
pub const WHEEL: usize = 256;

/// The default frequency table, millihertz: the 10 NorthStar beacon ID pairs as measured by
/// Rovio hobbyists (REFERENCE.md section 4; not an official table). Entry `2k` is the first
/// LED of ID `k`, entry `2k + 1` the second: ID 0 = 3040 / 2010 Hz; ID k = 1..9 =
/// 4050 + 120 (k - 1) / 3090 + 120 (k - 1) Hz.
pub const NORTHSTAR_TABLE_MHZ: [u32; 20] = northstar_table();

const fn northstar_table() -> [u32; 20] {
    let mut t = [0u32; 20];
    t[0] = 3_040_000;
    t[1] = 2_010_000;
    let mut k = 1;
    while k < 10 {
        t[2 * k] = (4050 + 120 * (k as u32 - 1)) * 1000;
        t[2 * k + 1] = (3090 + 120 * (k as u32 - 1)) * 1000;
        k += 1;
    }
    t
}

/// An LED's output line: bit `bit` (0..16) of output bank `bank` (0..[`BANKS`]). The board
/// maps banks to its GPIO ports and bits to their pins (firmware-beacon's pin map); the
/// modulator writes whole banks, so that one write changes every LED of a bank at a frequency.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Line {
    /// Output bank, 0..[`BANKS`].
    pub bank: u8,
    /// Bit within the bank, 0..16.
    pub bit: u8,
}

impl Line {
    /// Bit `bit` of bank `bank`.
    pub const fn new(bank: u8, bit: u8) -> Self {
        Line { bank, bit }
    }
}

/// Grid cell and board position of LED `id`: `(row, column, x, y)` with x, y in inches in
/// the beacon-plate frame, 1 in pitch, centred on the plate (x, y in -4.5..=4.5;
/// REFERENCE.md section 1): `x = column - 4.5`, `y = row - 4.5`.
pub fn grid_position(id: u8) -> (u8, u8, f64, f64) {
    let (row, col) = (id / 10, id % 10);
    (row, col, col as f64 - 4.5, row as f64 - 4.5)
}

/// Half period of `mhz` in ticks, Q8.24 fixed point; `None` outside the wheel's range.
pub fn half_period_q24(mhz: u32) -> Option<u32> {
    if !(FREQ_MIN_MHZ..=FREQ_MAX_MHZ).contains(&mhz) {
        return None;
    }
    // TICK_HZ / (2 f) ticks, f = mhz / 1000, scaled by 2^24, rounded.
    let num = (TICK_HZ as u64 * 1000) << 23;
    let hp = (num + mhz as u64 / 2) / mhz as u64;
    (hp < ((WHEEL as u64) << 24) && hp >= (2 << 24)).then_some(hp as u32)
}

/// An LED modulated at several frequencies (lit while any is high).
#[derive(Debug, Clone, Copy)]
struct Combo {
    bank: u8,
    bit: u16,
    freqs: u32,
}

/// The LED lines of one bank that a frequency toggles.
#[derive(Debug, Clone, Copy, Default)]
struct Leg {
    bank: u8,
    mask: u16,
}

/// Where [`Modulator::tick`] sends its line changes: the GPIO ports on the chip, a
/// [`Levels`] image on the host.
pub trait Gpio {
    /// Invert the lines `mask` of bank `bank` (`ODR ^= mask` on the STM32: a read-modify-write
    /// that leaves the bank's other lines untouched; only the tick interrupt writes `ODR`).
    fn toggle(&mut self, bank: usize, mask: u16);
    /// Write a `BSRR` word (low half: lines to set, high half: lines to reset) to bank `bank`.
    fn write(&mut self, bank: usize, bsrr: u32);
}

/// Output levels of the banks (bit set = line high = LED lit), as a [`Gpio`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Levels(pub [u16; BANKS]);

impl Gpio for Levels {
    #[inline]
    fn toggle(&mut self, bank: usize, mask: u16) {
        self.0[bank] ^= mask;
    }
    #[inline]
    fn write(&mut self, bank: usize, bsrr: u32) {
        self.0[bank] = (self.0[bank] | bsrr as u16) & !((bsrr >> 16) as u16);
    }
}

/// The modulator: frequency table, LED assignment and the tick state.
///
/// About 2.6 KiB; the firmware keeps one in a static and swaps configurations under a
/// critical section.
#[derive(Clone)]
pub struct Modulator {
    /// Half period per table entry, ticks, Q8.24.
    half_period: [u32; MAX_FREQS],
    /// Fractional part (Q0.24) of the next edge time of each frequency.
    frac: [u32; MAX_FREQS],
    table_len: u8,
    /// Bit f of `wheel[s]`: frequency f toggles on the next tick whose number is s (mod 256).
    wheel: [u32; WHEEL],
    /// Ticks since the table was loaded (wrapping).
    now: u32,
    /// Bit f: square wave f is in its "on" half.
    high: u32,
    /// Lines of the LEDs modulated at exactly frequency f: `legs[f][..nlegs[f]]`.
    legs: [[Leg; BANKS]; MAX_FREQS],
    nlegs: [u8; MAX_FREQS],
    /// Steadily lit lines per bank.
    steady: [u16; BANKS],
    combos: heapless::Vec<Combo, LED_COUNT>,
    /// Frequencies used by combos.
    combo_freqs: u32,
    /// LED id -> line.
    lines: [Line; LED_COUNT],
    /// All LED lines per bank (the only bits ever written).
    owned: [u16; BANKS],
}

/// Why [`Modulator::new`] or [`Modulator::set_table`] refused a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TableError {
    /// No entries.
    Empty,
    /// More than [`MAX_FREQS`] entries.
    TooLong,
    /// Entry `index` is outside the supported range.
    OutOfRange {
        /// Table index.
        index: u8,
        /// The frequency, millihertz.
        mhz: u32,
    },
}

impl Modulator {
    /// A modulator that drives nothing (no table, no lines): the initial value of the
    /// firmware's static, loaded at boot by [`Modulator::load`]. Its tick does nothing.
    pub const EMPTY: Modulator = Modulator {
        half_period: [0; MAX_FREQS],
        frac: [0; MAX_FREQS],
        table_len: 0,
        wheel: [0; WHEEL],
        now: 0,
        high: 0,
        legs: [[Leg { bank: 0, mask: 0 }; BANKS]; MAX_FREQS],
        nlegs: [0; MAX_FREQS],
        steady: [0; BANKS],
        combos: heapless::Vec::new(),
        combo_freqs: 0,
        lines: [Line::new(0, 0); LED_COUNT],
        owned: [0; BANKS],
    };

    /// All LEDs off, frequency table `table_mhz`, LED `id` on `lines[id]` (on the board, its pin
    /// map).
    pub fn new(table_mhz: &[u32], lines: &[Line; LED_COUNT]) -> Result<Self, TableError> {
        let mut m = Modulator::EMPTY;
        m.load(table_mhz, lines)?;
        Ok(m)
    }

    /// [`Modulator::new`] in place, over whatever this modulator held: the firmware loads
    /// its static this way at boot, without a 2.6 KiB temporary on the stack.
    pub fn load(&mut self, table_mhz: &[u32], lines: &[Line; LED_COUNT]) -> Result<(), TableError> {
        let mut owned = [0u16; BANKS];
        for p in lines {
            owned[p.bank as usize % BANKS] |= 1 << (p.bit & 15);
        }
        self.lines = *lines;
        self.owned = owned;
        // A new table clears the rest: the waves, the assignment and the tick count.
        self.set_table(table_mhz)
    }

    /// Load a new frequency table; all LEDs go off and every wave restarts low.
    pub fn set_table(&mut self, table_mhz: &[u32]) -> Result<(), TableError> {
        if table_mhz.is_empty() {
            return Err(TableError::Empty);
        }
        if table_mhz.len() > MAX_FREQS {
            return Err(TableError::TooLong);
        }
        let mut hp = [0u32; MAX_FREQS];
        for (i, &mhz) in table_mhz.iter().enumerate() {
            hp[i] = half_period_q24(mhz).ok_or(TableError::OutOfRange {
                index: i as u8,
                mhz,
            })?;
        }
        self.half_period = hp;
        self.table_len = table_mhz.len() as u8;
        self.frac = [0; MAX_FREQS];
        self.wheel = [0; WHEEL];
        self.now = 0;
        self.high = 0;
        // Stagger the first edges so the waves do not all toggle on the same tick.
        for (f, &h) in hp.iter().enumerate().take(table_mhz.len()) {
            let first = 1 + (f as u32 * 37) % (h >> 24);
            self.wheel[first as usize % WHEEL] |= 1 << f;
        }
        self.clear_assignment();
        Ok(())
    }

    /// Entries in the frequency table.
    pub fn table_len(&self) -> u8 {
        self.table_len
    }

    /// Ticks since the table was loaded (wrapping).
    pub fn now(&self) -> u32 {
        self.now
    }

    /// Assign every LED its mode (`modes[id]`, LED `id` on the line given to
    /// [`Modulator::new`]). The caller has validated the modes (frequency indices within the
    /// table); unknown indices are ignored. Modulated LEDs join their running wave in phase;
    /// the caller then drives the banks to [`Modulator::all_bsrr`] (with the tick excluded).
    pub fn configure(&mut self, modes: &[LedMode; LED_COUNT]) {
        self.clear_assignment();
        let valid = if self.table_len as usize >= 32 {
            u32::MAX
        } else {
            (1u32 << self.table_len) - 1
        };
        let mut xor = [[0u16; BANKS]; MAX_FREQS];
        let lines = self.lines;
        for (mode, line) in modes.iter().zip(lines.iter()) {
            let (bank, bit) = (line.bank as usize % BANKS, 1u16 << (line.bit & 15));
            match *mode {
                LedMode::Off => {}
                LedMode::On => self.steady[bank] |= bit,
                LedMode::Modulated(set) => {
                    let freqs = set.0 & valid;
                    if freqs == 0 {
                        continue;
                    }
                    if freqs.is_power_of_two() {
                        xor[freqs.trailing_zeros() as usize][bank] |= bit;
                    } else {
                        // Capacity is LED_COUNT: cannot overflow.
                        let _ = self.combos.push(Combo {
                            bank: bank as u8,
                            bit,
                            freqs,
                        });
                        self.combo_freqs |= freqs;
                    }
                }
            }
        }
        for (f, banks) in xor.iter().enumerate() {
            for (bank, &mask) in banks.iter().enumerate() {
                if mask != 0 {
                    self.legs[f][self.nlegs[f] as usize] = Leg {
                        bank: bank as u8,
                        mask,
                    };
                    self.nlegs[f] += 1;
                }
            }
        }
    }

    /// Every LED off (the waves keep running).
    fn clear_assignment(&mut self) {
        self.nlegs = [0; MAX_FREQS];
        self.steady = [0; BANKS];
        self.combos.clear();
        self.combo_freqs = 0;
    }

    /// Output level of every bank (bit set = LED lit), computed from the wave levels.
    pub fn levels(&self) -> [u16; BANKS] {
        let mut out = self.steady;
        for f in 0..MAX_FREQS {
            if self.high & (1 << f) != 0 {
                for leg in &self.legs[f][..self.nlegs[f] as usize] {
                    out[leg.bank as usize] |= leg.mask;
                }
            }
        }
        for c in &self.combos {
            if self.high & c.freqs != 0 {
                out[c.bank as usize] |= c.bit;
            }
        }
        out
    }

    /// `BSRR` words that drive every bank to [`Modulator::levels`] (LED lines only); written
    /// after every reconfiguration.
    pub fn all_bsrr(&self) -> [u32; BANKS] {
        let levels = self.levels();
        let mut w = [0u32; BANKS];
        for p in 0..BANKS {
            let (o, owned) = (levels[p], self.owned[p]);
            w[p] = (o & owned) as u32 | (((!o & owned) as u32) << 16);
        }
        w
    }

    /// One tick: advance the waves due on this tick and send the line changes to `gpio`. This
    /// is the body of the firmware's timer interrupt. Banks passed to `gpio` are below
    /// [`BANKS`]. Most ticks have nothing due and return after a few instructions.
    #[inline(always)]
    pub fn tick(&mut self, gpio: &mut impl Gpio) {
        let slot = self.now as u8;
        self.now = self.now.wrapping_add(1);
        let due = core::mem::take(&mut self.wheel[slot as usize]);
        if due != 0 {
            self.advance(slot, due, gpio);
        }
    }

    /// One tick without driving any line: the firmware catches up, inside the critical
    /// section of a reconfiguration, the ticks its timer raised while the interrupt was
    /// masked ([`lost_ticks`]), then drives every bank to [`Modulator::all_bsrr`].
    pub fn tick_silently(&mut self) {
        struct NoLines;
        impl Gpio for NoLines {
            fn toggle(&mut self, _bank: usize, _mask: u16) {}
            fn write(&mut self, _bank: usize, _bsrr: u32) {}
        }
        self.tick(&mut NoLines);
    }

    /// The edges due on tick `slot` (mask `due`).
    #[inline(never)]
    fn advance(&mut self, slot: u8, due: u32, gpio: &mut impl Gpio) {
        self.high ^= due;
        let mut pending = due;
        while pending != 0 {
            let f = pending.trailing_zeros() as usize & (MAX_FREQS - 1);
            pending &= pending - 1;
            // Line changes first (an edge leaves ~60 instructions after the previous
            // frequency's), then the next edge of f: the fractional time accumulates in Q0.24.
            let n = self.nlegs[f] as usize;
            for leg in &self.legs[f][..n.min(BANKS)] {
                gpio.toggle(leg.bank as usize, leg.mask);
            }
            let t = self.frac[f] + self.half_period[f];
            self.frac[f] = t & 0x00ff_ffff;
            let next = slot.wrapping_add((t >> 24) as u8);
            self.wheel[next as usize] |= 1 << f;
        }
        if due & self.combo_freqs != 0 {
            for c in &self.combos {
                if due & c.freqs != 0 {
                    let bit = c.bit as u32;
                    let w = if self.high & c.freqs != 0 {
                        bit
                    } else {
                        bit << 16
                    };
                    gpio.write(c.bank as usize, w);
                }
            }
        }
    }
}

/// Ticks a periodic timer raised while its interrupt was masked that the one interrupt
/// left pending will not make up: the timer counts `period` cycles per tick; at the start of
/// the masked stretch its counter stood at `count_at_entry` (cycles since its last update)
/// and an update was already pending or not; the stretch has lasted `elapsed` cycles. Every
/// update raises the same flag, so however many occur, one interrupt follows the unmasking.
pub fn lost_ticks(pending_at_entry: bool, count_at_entry: u32, elapsed: u32, period: u32) -> u32 {
    let updates = (u64::from(count_at_entry) + u64::from(elapsed)) / u64::from(period.max(1));
    let raised = u64::from(pending_at_entry) + updates;
    raised.saturating_sub(1).min(u64::from(u32::MAX)) as u32
}

/// What drives the cost of the tick interrupt, per tick on average, in Q16 (1 << 16 = one
/// per tick), for a table and an LED assignment (see [`tick_cost`]): `[edges, legs,
/// combo_ticks, combo_visits, combo_writes]`:
///
/// * `edges`: frequency edges (`sum 2 f / TICK_HZ` over the table: every wave runs, lit or
///   not);
/// * `legs`: bank toggles (each edge of `f` toggles one bank per bank holding LEDs at `f`
///   alone);
/// * `combo_ticks`: ticks with an edge of a frequency some multi-frequency LED uses (at
///   most 1; the sum of their rates bounds it);
/// * `combo_visits`: multi-frequency LEDs looked at (all of them on such a tick);
/// * `combo_writes`: `BSRR` writes for them (each on a tick with an edge of one of its
///   frequencies).
///
/// The tick probabilities are bounded by the sums of the rates (union bounds), so the
/// features over-count ticks on which several edges coincide: the model errs high.
pub fn tick_features(
    table_mhz: &[u32],
    modes: &[LedMode; LED_COUNT],
    lines: &[Line; LED_COUNT],
) -> [u64; 5] {
    const ONE: u64 = 1 << 16;
    let n = table_mhz.len().min(MAX_FREQS);
    // Edges per tick of entry f, Q16: 2 f / TICK_HZ with f in millihertz (divided once per
    // entry: a 64-bit division is a library call on the chip).
    let mut rates = [0u64; MAX_FREQS];
    for (r, &mhz) in rates.iter_mut().zip(table_mhz) {
        *r = 2 * u64::from(mhz) * ONE / (1000 * u64::from(TICK_HZ));
    }
    let rate = |f: usize| rates[f];
    // Sum of the rates of the entries in a set, by its bits.
    let rates_of = |mut set: u32| {
        let mut sum = 0;
        while set != 0 {
            sum += rates[set.trailing_zeros() as usize];
            set &= set - 1;
        }
        sum
    };
    let valid = if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
    let mut banks = [0u8; MAX_FREQS];
    let mut combos = 0u64;
    let mut combo_freqs = 0u32;
    let mut writes = 0u64;
    for (mode, line) in modes.iter().zip(lines) {
        let LedMode::Modulated(set) = *mode else {
            continue;
        };
        let freqs = set.0 & valid;
        if freqs.is_power_of_two() {
            banks[freqs.trailing_zeros() as usize] |= 1 << (line.bank as usize % BANKS);
        } else if freqs != 0 {
            combos += 1;
            combo_freqs |= freqs;
            // One write on a tick with an edge of any of its frequencies.
            writes += rates_of(freqs).min(ONE);
        }
    }
    let edges = (0..n).map(rate).sum();
    let legs = (0..n)
        .map(|f| rate(f) * u64::from(banks[f].count_ones()))
        .sum();
    let combo_ticks = rates_of(combo_freqs).min(ONE);
    [edges, legs, combo_ticks, combo_ticks * combos, writes]
}

/// Instructions of the tick interrupt on a tick with nothing due (its QEMU count).
pub const TICK_COST_BASE: u64 = 28;
/// Tenths of an instruction per unit of each of [`tick_features`]: fitted to the
/// Cortex-M3 counts of `tests/qemu/src/bin/beacon_tick.rs` over its cases (about 38 per
/// edge, 9 per bank toggle, 6 per multi-frequency LED looked at and per write) and
/// rounded up, so that the model is not below any case (`firmware-beacon/ci.sh` checks
/// three of them on every run).
pub const TICK_COST_PER_TENTH: [u64; 5] = [400, 100, 50, 70, 65];

/// Mean instructions per tick of the firmware's tick interrupt (exception entry and exit
/// not included) for a table and an LED assignment: the model of [`TICK_COST_BASE`] and
/// [`TICK_COST_PER_TENTH`] over [`tick_features`]. The beacon board refuses assignments
/// and tables above its budget ([`TICK_BUDGET`]).
pub fn tick_cost(
    table_mhz: &[u32],
    modes: &[LedMode; LED_COUNT],
    lines: &[Line; LED_COUNT],
) -> u32 {
    let x = tick_features(table_mhz, modes, lines);
    let sum: u64 = x.iter().zip(TICK_COST_PER_TENTH).map(|(x, c)| x * c).sum();
    (TICK_COST_BASE + sum.div_ceil(10 << 16)) as u32
}

/// Most instructions per tick, on average, the beacon board accepts ([`tick_cost`]): half
/// the 576 cycles between ticks, so that the main loop keeps the other half even if flash
/// wait states make an instruction cost more than a cycle.
pub const TICK_BUDGET: u32 = 288;

/// Frequency and jitter measured from the simulated tick stream (host side).
#[cfg(feature = "alloc")]
pub mod measure {
    use alloc::vec::Vec;

    use super::{Gpio, Levels, Modulator, BANKS, TICK_HZ};
    use crate::wire::beacon::{LedMode, LED_COUNT};

    /// What the tick stream of one LED modulated at a single frequency showed.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct WaveStats {
        /// LED id.
        pub led: u8,
        /// Table index.
        pub index: u8,
        /// Table frequency, Hz.
        pub nominal_hz: f64,
        /// Mean frequency, Hz: from the least-squares slope of edge time against edge number.
        pub mean_hz: f64,
        /// `(mean_hz - nominal_hz) / nominal_hz`.
        pub rel_error: f64,
        /// Peak-to-peak deviation of the edge times from that best-fit ideal square wave, us.
        pub jitter_pp_us: f64,
        /// RMS of the same deviations, us.
        pub jitter_rms_us: f64,
        /// Edges observed (rising and falling).
        pub edges: usize,
    }

    /// Per-tick work seen while measuring.
    #[derive(Debug, Clone, Copy, PartialEq, Default)]
    pub struct TickLoad {
        /// Ticks run.
        pub ticks: u64,
        /// Mean bank operations ([`Gpio::toggle`] or [`Gpio::write`]) per tick.
        pub mean_writes: f64,
        /// Most bank operations in one tick.
        pub max_writes: u32,
    }

    /// Run `m` for `ticks` ticks, following every line through the changes it sends, and
    /// return the statistics of every LED modulated at exactly one frequency (with
    /// `table_mhz[i]` the frequency of index `i`), plus the write load. The caller has
    /// configured `m` with `modes`. Also checks on every tick that the incremental outputs
    /// equal [`Modulator::levels`]; returns `Err(tick)` at the first mismatch.
    pub fn run(
        m: &mut Modulator,
        modes: &[LedMode; LED_COUNT],
        table_mhz: &[u32],
        ticks: u32,
    ) -> Result<(Vec<WaveStats>, TickLoad), u32> {
        let mut led_at = [[u8::MAX; 16]; BANKS];
        for (id, p) in m.lines.iter().enumerate() {
            led_at[p.bank as usize][p.bit as usize] = id as u8;
        }
        /// Follows the lines and records every LED edge.
        struct Probe<'a> {
            level: [u16; BANKS],
            led_at: &'a [[u8; 16]; BANKS],
            edges: &'a mut Vec<Vec<u32>>,
            tick: u32,
            writes: u32,
        }
        impl Probe<'_> {
            fn change(&mut self, bank: usize, new: u16) {
                let mut changed = self.level[bank] ^ new;
                self.level[bank] = new;
                while changed != 0 {
                    let b = changed.trailing_zeros() as usize;
                    changed &= changed - 1;
                    let id = self.led_at[bank][b];
                    if (id as usize) < LED_COUNT {
                        // The change happens during tick n (time n / TICK_HZ).
                        self.edges[id as usize].push(self.tick);
                    }
                }
            }
        }
        impl Gpio for Probe<'_> {
            fn toggle(&mut self, bank: usize, mask: u16) {
                self.writes += 1;
                self.change(bank, self.level[bank] ^ mask);
            }
            fn write(&mut self, bank: usize, bsrr: u32) {
                self.writes += 1;
                let mut l = Levels([0; BANKS]);
                l.0[bank] = self.level[bank];
                l.write(bank, bsrr);
                self.change(bank, l.0[bank]);
            }
        }
        let mut edges: Vec<Vec<u32>> = (0..LED_COUNT).map(|_| Vec::new()).collect();
        let mut probe = Probe {
            level: m.levels(),
            led_at: &led_at,
            edges: &mut edges,
            tick: 0,
            writes: 0,
        };
        let mut load = TickLoad::default();
        let mut writes_total = 0u64;
        for n in 0..ticks {
            probe.tick = n;
            probe.writes = 0;
            m.tick(&mut probe);
            if probe.level != m.levels() {
                return Err(n);
            }
            let writes = probe.writes;
            writes_total += writes as u64;
            load.max_writes = load.max_writes.max(writes);
        }
        load.ticks = ticks as u64;
        load.mean_writes = writes_total as f64 / ticks.max(1) as f64;
        let mut out = Vec::new();
        for (id, mode) in modes.iter().enumerate() {
            let LedMode::Modulated(set) = *mode else {
                continue;
            };
            if !set.0.is_power_of_two() {
                continue;
            }
            let index = set.0.trailing_zeros() as u8;
            let Some(&mhz) = table_mhz.get(index as usize) else {
                continue;
            };
            if let Some(s) = wave_stats(&edges[id], mhz) {
                out.push(WaveStats {
                    led: id as u8,
                    index,
                    ..s
                });
            }
        }
        Ok((out, load))
    }

    /// Least-squares fit `t_j = a + b j` of the edge ticks (both edges, j = 0, 1, ...).
    fn wave_stats(edges: &[u32], mhz: u32) -> Option<WaveStats> {
        let n = edges.len();
        if n < 3 {
            return None;
        }
        let nf = n as f64;
        let jm = (nf - 1.0) / 2.0;
        let tm = edges.iter().map(|&t| t as f64).sum::<f64>() / nf;
        let (mut sjt, mut sjj) = (0.0, 0.0);
        for (j, &t) in edges.iter().enumerate() {
            let dj = j as f64 - jm;
            sjt += dj * (t as f64 - tm);
            sjj += dj * dj;
        }
        let b = sjt / sjj;
        let (mut lo, mut hi, mut ss) = (f64::MAX, f64::MIN, 0.0);
        for (j, &t) in edges.iter().enumerate() {
            let r = t as f64 - (tm + b * (j as f64 - jm));
            lo = lo.min(r);
            hi = hi.max(r);
            ss += r * r;
        }
        let us_per_tick = 1e6 / TICK_HZ as f64;
        let nominal_hz = mhz as f64 / 1000.0;
        let mean_hz = TICK_HZ as f64 / (2.0 * b);
        Some(WaveStats {
            led: 0,
            index: 0,
            nominal_hz,
            mean_hz,
            rel_error: (mean_hz - nominal_hz) / nominal_hz,
            jitter_pp_us: (hi - lo) * us_per_tick,
            jitter_rms_us: libm::sqrt(ss / nf) * us_per_tick,
            edges: n,
        })
    }
}

/// The tests' line map: LED `id` on the `id`-th line in bank order, leaving bit 15 of every
/// bank to other uses (a board's pin map leaves gaps too).
#[cfg(test)]
const LINES: [Line; LED_COUNT] = {
    let mut lines = [Line::new(0, 0); LED_COUNT];
    let mut id = 0;
    while id < LED_COUNT {
        lines[id] = Line::new((id / 15) as u8, (id % 15) as u8);
        id += 1;
    }
    lines
};

#[cfg(test)]
mod catch_up_tests {
    use super::*;
    use crate::wire::beacon::FreqSet;

    #[test]
    fn lost_ticks_counts_the_updates_beyond_the_pending_one() {
        // Nothing pending, shorter than the rest of the period: nothing raised.
        assert_eq!(lost_ticks(false, 100, 400, 576), 0);
        // One update: it stays pending, nothing lost.
        assert_eq!(lost_ticks(false, 100, 476, 576), 0);
        // Two updates: one lost; with one already pending, two lost.
        assert_eq!(lost_ticks(false, 100, 476 + 576, 576), 1);
        assert_eq!(lost_ticks(true, 100, 476 + 576, 576), 2);
        // A pending update alone is made up by its interrupt.
        assert_eq!(lost_ticks(true, 0, 0, 576), 0);
        // 9,000 cycles from mid-period: (288 + 9000) / 576 = 16 updates, 15 lost.
        assert_eq!(lost_ticks(false, 288, 9000, 576), 15);
    }

    /// Catching up silently leaves the waves where ticking all along would have, so that
    /// every LED keeps its phase across a reconfiguration.
    #[test]
    fn silent_ticks_keep_the_phase() {
        let modes: [LedMode; LED_COUNT] = core::array::from_fn(|i| match i % 3 {
            0 => LedMode::Modulated(FreqSet::single((i % 20) as u8)),
            1 => LedMode::Modulated(FreqSet(1 << (i % 20) | 1 << ((i + 7) % 20))),
            _ => LedMode::Off,
        });
        let new = || {
            let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
            m.configure(&modes);
            m
        };
        let (mut a, mut b) = (new(), new());
        let mut lines = Levels(a.levels());
        for _ in 0..1000 {
            a.tick(&mut lines);
            b.tick(&mut Levels([0; BANKS]));
        }
        for k in 0..40 {
            a.tick(&mut lines);
            b.tick_silently();
            assert_eq!(a.now(), b.now());
            assert_eq!(a.levels(), b.levels(), "tick {k}");
        }
        assert_eq!(lines.0, b.levels());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::beacon::FreqSet;

    #[test]
    fn northstar_table_matches_reference() {
        let t = NORTHSTAR_TABLE_MHZ;
        assert_eq!((t[0], t[1]), (3_040_000, 2_010_000));
        assert_eq!((t[2], t[3]), (4_050_000, 3_090_000));
        assert_eq!((t[18], t[19]), (5_010_000, 4_050_000));
        for k in 1..10 {
            assert_eq!(
                t[2 * k] - t[2 * k + 1],
                960_000,
                "ID {k} pair differs by 960 Hz"
            );
        }
    }

    #[test]
    fn grid_positions_are_centred() {
        assert_eq!(grid_position(0), (0, 0, -4.5, -4.5));
        assert_eq!(grid_position(99), (9, 9, 4.5, 4.5));
        assert_eq!(grid_position(37), (3, 7, 2.5, -1.5));
    }

    #[test]
    fn table_validation() {
        assert_eq!(Modulator::new(&[], &LINES).err(), Some(TableError::Empty));
        assert_eq!(
            Modulator::new(&[1_000_000, 100_000], &LINES).err(),
            Some(TableError::OutOfRange {
                index: 1,
                mhz: 100_000
            })
        );
        assert!(Modulator::new(&[FREQ_MIN_MHZ, FREQ_MAX_MHZ], &LINES).is_ok());
        assert_eq!(
            Modulator::new(&[1_000_000; 33], &LINES).err(),
            Some(TableError::TooLong)
        );
    }

    fn all_modulated() -> [LedMode; LED_COUNT] {
        core::array::from_fn(|i| LedMode::Modulated(FreqSet::single((i % 20) as u8)))
    }

    #[test]
    fn off_and_steady_leds_never_change() {
        let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
        let mut modes = [LedMode::Off; LED_COUNT];
        modes[5] = LedMode::On;
        modes[50] = LedMode::On;
        m.configure(&modes);
        struct Untouchable;
        impl Gpio for Untouchable {
            fn toggle(&mut self, _: usize, _: u16) {
                panic!("nothing is modulated, nothing may be written")
            }
            fn write(&mut self, _: usize, _: u32) {
                panic!("nothing is modulated, nothing may be written")
            }
        }
        let want = m.all_bsrr();
        let lvl = m.levels();
        for _ in 0..10_000 {
            m.tick(&mut Untouchable);
        }
        assert_eq!(m.levels(), lvl);
        let p5 = LINES[5];
        assert_ne!(want[p5.bank as usize] & (1 << p5.bit), 0);
    }

    #[test]
    fn every_table_frequency_is_exact_and_jitter_is_below_one_tick() {
        let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
        let modes = all_modulated();
        m.configure(&modes);
        // One simulated second.
        let (stats, load) = measure::run(&mut m, &modes, &NORTHSTAR_TABLE_MHZ, TICK_HZ).unwrap();
        assert_eq!(stats.len(), 100);
        for s in &stats {
            assert!(s.rel_error.abs() < 5e-4 / 10.0, "{s:?}");
            assert!(s.jitter_pp_us < 10.0, "{s:?}");
            // Edge count matches the frequency: 2 f edges per second (+-1).
            assert!((s.edges as f64 - 2.0 * s.nominal_hz).abs() <= 1.5, "{s:?}");
        }
        assert!(load.mean_writes > 0.0);
    }

    #[test]
    fn several_frequencies_on_one_led_and_reconfiguration_stay_consistent() {
        let mut m = Modulator::new(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
        let mut modes = all_modulated();
        modes[3] = LedMode::Modulated(FreqSet(0b11));
        modes[4] = LedMode::Modulated(FreqSet((1 << 19) | (1 << 7) | 1));
        modes[5] = LedMode::On;
        modes[6] = LedMode::Off;
        m.configure(&modes);
        measure::run(&mut m, &modes, &NORTHSTAR_TABLE_MHZ, 20_000).unwrap();
        // Reconfigure mid-stream: outputs must follow the running waves.
        modes[10] = LedMode::Modulated(FreqSet(0b1100));
        modes[11] = LedMode::Off;
        m.configure(&modes);
        let (stats, _) = measure::run(&mut m, &modes, &NORTHSTAR_TABLE_MHZ, 30_000).unwrap();
        assert!(stats.iter().all(|s| s.led != 3 && s.led != 4));
        // A new table restarts with everything dark.
        m.set_table(&[1_000_000]).unwrap();
        assert_eq!(m.levels(), [0; BANKS]);
    }

    #[test]
    fn loading_in_place_equals_a_new_modulator() {
        let mut modes = all_modulated();
        modes[4] = LedMode::Modulated(FreqSet((1 << 19) | (1 << 7) | 1));
        modes[5] = LedMode::On;
        // A used modulator (other lines, table, assignment and phase) loaded in place...
        let mut reused = Modulator::new(&[1_000_000, 2_000_000], &LINES).unwrap();
        let mut other = LINES;
        other.swap(0, 1);
        reused.load(&[1_000_000], &other).unwrap();
        reused.configure(&[LedMode::On; LED_COUNT]);
        for _ in 0..777 {
            reused.tick(&mut Levels::default());
        }
        reused.load(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
        // ...drives the lines exactly as a fresh one, tick by tick.
        let mut fresh = Modulator::new(&NORTHSTAR_TABLE_MHZ, &LINES).unwrap();
        assert_eq!(reused.all_bsrr(), fresh.all_bsrr());
        reused.configure(&modes);
        fresh.configure(&modes);
        let (mut a, mut b) = (Levels::default(), Levels::default());
        for _ in 0..20_000 {
            reused.tick(&mut a);
            fresh.tick(&mut b);
            assert_eq!((a, reused.levels()), (b, fresh.levels()));
        }
        assert_eq!(reused.now(), fresh.now());
    }

    #[test]
    fn duty_cycle_is_half() {
        let table = [2_010_000, 5_130_000, FREQ_MAX_MHZ, FREQ_MIN_MHZ];
        let mut m = Modulator::new(&table, &LINES).unwrap();
        let modes: [LedMode; LED_COUNT] =
            core::array::from_fn(|i| LedMode::Modulated(FreqSet::single((i % 4) as u8)));
        m.configure(&modes);
        let mut on = [0u32; 4];
        let n = 200_000;
        for _ in 0..n {
            m.tick(&mut Levels::default());
            for (f, c) in on.iter_mut().enumerate() {
                let p = LINES[f];
                if m.levels()[p.bank as usize] & (1 << p.bit) != 0 {
                    *c += 1;
                }
            }
        }
        for c in on {
            let duty = c as f64 / n as f64;
            assert!((duty - 0.5).abs() < 0.01, "duty {duty}");
        }
    }
}
