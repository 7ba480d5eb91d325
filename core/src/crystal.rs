//! The crystal check both boards run at boot (`cta_firmware_boot::start`): the crystal's
//! frequency, measured against the internal 8 MHz RC oscillator (HSI), which clocks the core
//! from reset until the clock tree is set up. The RTC, clocked by HSE / 128, counts down its
//! prescaler (`RTC_DIV`) while the DWT counts HSI cycles. The HSI is within -2 .. +2.5 % of
//! 8 MHz over -40 .. 105 degC (datasheet), so an 8 MHz crystal reads 7.8-8.2 MHz; a 12 or
//! 16 MHz one reads 12 or 16. Pure arithmetic on the two counters (no registers), so that it
//! is tested here, on the host, against a model of them: the HSI over its whole range,
//! crystals of 4-16 MHz, misreads, debugger halts, stopped counters.

use core::ops::RangeInclusive;

/// Frequencies taken for an 8 MHz crystal, kHz: +/-5 %, twice the HSI's tolerance.
pub const ACCEPTED_KHZ: RangeInclusive<u32> = 7_600..=8_400;
/// Prescaler counts timed: 500 counts are 64,000 crystal cycles (8 ms at 8 MHz).
pub const COUNTS: u32 = 500;
/// `RTC_PRL` after a backup-domain reset: `RTC_DIV` counts 0x8000 down to 0, then reloads.
pub const PRL: u32 = 0x8000;
/// Largest change between two passes taken as counting: a pass takes a fraction of a
/// count, so a larger change is a misread, or a pause of the core (a debugger halt, which
/// stops the cycle counter, not the RTC), and starts the timing again.
pub const MAX_STEP: u32 = 8;
/// Passes of the loop before the measurement is given up on: the slowest crystal the
/// chip takes, 4 MHz, counts `COUNTS` in 128,000 HSI cycles, under 13,000 passes of 10
/// cycles or more; a pass as built is about 30 instructions, so 200,000 take under a
/// second. Counted in passes, not cycles: the cycle counter may not run (a debugger can
/// stop it).
pub const MAX_PASSES: u32 = 200_000;
/// HSI frequency, kHz.
const HSI_KHZ: u32 = 8_000;

/// Prescaler counts from the value `from` down to `to`, across a reload (0, then PRL).
pub fn counts_down(from: u32, to: u32) -> u32 {
    if to <= from {
        from - to
    } else {
        from + 1 + PRL.saturating_sub(to)
    }
}

/// Crystal frequency, kHz, from `COUNTS` prescaler counts timed in HSI cycles: `div` reads
/// `RTC_DIV`, `cycles` the cycle counter. Timed from the first change of `RTC_DIV` seen,
/// so that both ends are changes; a value is used only when the next read repeats it, and
/// a change larger than `MAX_STEP` starts the timing again from there (a misread or a
/// pause can neither count nor stall the count). `None` if the prescaler did not count
/// `COUNTS` within `MAX_PASSES`, or the cycle counter did not run (the RTC or the DWT not
/// counting: no measurement, not a wrong crystal).
pub fn measure_khz(mut div: impl FnMut() -> u32, mut cycles: impl FnMut() -> u32) -> Option<u32> {
    let mut prev = None;
    let mut start = None;
    let mut counted = 0;
    for _ in 0..MAX_PASSES {
        let d = div();
        let t = cycles();
        if div() != d {
            continue;
        }
        let Some(p) = prev else {
            prev = Some(d);
            continue;
        };
        let step = counts_down(p, d);
        if step == 0 {
            continue;
        }
        prev = Some(d);
        let Some(t0) = start.filter(|_| step <= MAX_STEP) else {
            (start, counted) = (Some(t), 0);
            continue;
        };
        counted += step;
        if counted >= COUNTS {
            // 128 crystal cycles a count; HSI_KHZ * 128 * counted < 2^32 (counted < 508).
            let elapsed: u32 = t.wrapping_sub(t0);
            return (elapsed >= counted).then(|| HSI_KHZ * 128 * counted / elapsed);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::cell::Cell;

    /// The two counters of the chip, modelled: the core (and so the cycle counter) runs at
    /// `hsi_hz`; every register read takes `read_cycles`; `RTC_DIV` counts down at `hse_hz` /
    /// 128 from `start`, reloading from [`PRL`] after 0. `misread(n)`: the `n`-th read of
    /// `RTC_DIV` returns garbage; `halt`: at this many HSI cycles the core stops for that
    /// many RTC counts (a debugger halt: the RTC runs on, the cycle counter does not).
    struct Chip {
        hsi_hz: f64,
        hse_hz: f64,
        read_cycles: f64,
        start: u32,
        rtc_runs: bool,
        dwt_runs: bool,
        misread: fn(u32) -> bool,
        halt: Option<(f64, u32)>,
        // State: HSI cycles so far (the cycle counter when it runs), RTC counts lost to a
        // halt, reads of RTC_DIV.
        t: Cell<f64>,
        halted: Cell<u32>,
        reads: Cell<u32>,
    }

    impl Chip {
        fn new(hsi_hz: f64, hse_hz: f64) -> Chip {
            Chip {
                hsi_hz,
                hse_hz,
                read_cycles: 10.0,
                start: 0x7000,
                rtc_runs: true,
                dwt_runs: true,
                misread: |_| false,
                halt: None,
                t: Cell::new(0.0),
                halted: Cell::new(0),
                reads: Cell::new(0),
            }
        }

        fn tick(&self) {
            self.t.set(self.t.get() + self.read_cycles);
            if let Some((at, counts)) = self.halt {
                if self.t.get() >= at && self.halted.get() == 0 {
                    self.halted.set(counts);
                }
            }
        }

        fn div(&self) -> u32 {
            self.tick();
            let n = self.reads.get();
            self.reads.set(n + 1);
            if (self.misread)(n) {
                return 0xBEEF ^ n;
            }
            if !self.rtc_runs {
                return self.start;
            }
            let counts = (self.t.get() / self.hsi_hz * self.hse_hz / 128.0) as u64
                + u64::from(self.halted.get());
            // From `start` down to 0, then PRL down to 0, ...
            let period = u64::from(PRL) + 1;
            let from_top = (u64::from(PRL - self.start) + counts) % period;
            PRL - from_top as u32
        }

        fn cycles(&self) -> u32 {
            self.tick();
            if self.dwt_runs {
                self.t.get() as u64 as u32
            } else {
                0
            }
        }

        fn measure(&self) -> Option<u32> {
            measure_khz(|| self.div(), || self.cycles())
        }
    }

    /// The HSI's range over temperature (datasheet: -2 .. +2.5 %).
    const HSI: [f64; 5] = [0.98, 0.99, 1.0, 1.01, 1.025];

    #[test]
    fn counts_down_across_the_reload() {
        assert_eq!(counts_down(10, 7), 3);
        assert_eq!(counts_down(7, 7), 0);
        // 2, 1, 0, then PRL: three counts.
        assert_eq!(counts_down(2, PRL), 3);
        assert_eq!(counts_down(0, PRL - 4), 5);
    }

    /// An 8 MHz crystal is taken over the HSI's whole range; its reading is 8 MHz scaled by
    /// the HSI's error, to within a count of the 500 timed.
    #[test]
    fn an_8_mhz_crystal_is_taken_over_the_hsi_range() {
        for k in HSI {
            let khz = Chip::new(8e6 * k, 8e6).measure().unwrap();
            assert!(ACCEPTED_KHZ.contains(&khz), "HSI x{k}: {khz} kHz");
            let want = 8000.0 / k;
            assert!(
                (f64::from(khz) - want).abs() < want * 0.004,
                "HSI x{k}: {khz}"
            );
        }
    }

    /// The common wrong crystals are measured and refused at either end of the HSI range.
    #[test]
    fn other_crystals_are_measured_and_refused() {
        for mhz in [4.0, 6.0, 7.3728, 10.0, 11.0592, 12.0, 16.0] {
            for k in [HSI[0], HSI[4]] {
                let khz = Chip::new(8e6 * k, mhz * 1e6).measure().unwrap();
                assert!(!ACCEPTED_KHZ.contains(&khz), "{mhz} MHz read {khz} kHz");
                let want = mhz * 1000.0 / k;
                assert!((f64::from(khz) - want).abs() < want * 0.004, "{mhz}: {khz}");
            }
        }
    }

    /// A counter that does not count gives no measurement (the board then runs as before),
    /// never a wrong frequency.
    #[test]
    fn stopped_counters_give_no_measurement() {
        let mut c = Chip::new(8e6, 8e6);
        c.rtc_runs = false;
        assert_eq!(c.measure(), None);
        let mut c = Chip::new(8e6, 8e6);
        c.dwt_runs = false;
        assert_eq!(c.measure(), None);
    }

    /// Garbage reads of `RTC_DIV` (1 in 100) and a debugger halt mid-way (the RTC runs on
    /// 3,000 counts, the cycle counter stops) do not move the reading.
    #[test]
    fn misreads_and_a_halt_do_not_move_the_reading() {
        let mut c = Chip::new(8e6, 8e6);
        c.misread = |n| n % 100 == 37;
        let khz = c.measure().unwrap();
        assert!((7_970..=8_030).contains(&khz), "{khz}");
        let mut c = Chip::new(8e6, 12e6);
        c.halt = Some((20_000.0, 3_000));
        let khz = c.measure().unwrap();
        assert!((11_950..=12_050).contains(&khz), "{khz}");
    }

    /// Across the prescaler's reload (started 100 counts above 0).
    #[test]
    fn the_reload_is_counted_through() {
        let mut c = Chip::new(8e6, 8e6);
        c.start = 100;
        let khz = c.measure().unwrap();
        assert!((7_970..=8_030).contains(&khz), "{khz}");
    }
}
