//! Per-tick cost of the beacon board's modulator interrupt with all 100 LEDs modulated
//! (LED i at NorthStar table entry i mod 20), run on a Cortex-M3 under QEMU.
//!
//! Each measured segment is the body of the firmware's TIM2 interrupt
//! (firmware-beacon/src/chip.rs): clear the timer flag, take the critical section,
//! borrow the modulator, [`Modulator::tick`] with a volatile `ODR` read-modify-write per
//! toggled port (`BSRR` store for multi-frequency LEDs). The timer and GPIO registers are
//! stand-ins in RAM (the lm3s6965 has no STM32 peripherals); the code path is the same. Hardware exception entry and exit
//! (12 + 10 cycles on the Cortex-M3) are not instructions and are added in the report.
//!
//! Also prints `STACK tick_peak_bytes=N`, the stack the interrupt body uses (painted),
//! for the RAM figure of firmware-beacon/ci.sh.
#![no_std]
#![no_main]

use core::cell::RefCell;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use critical_section::Mutex;
use cta_core::schedule::{tick_cost, tick_features, Gpio, Modulator, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{FreqSet, LedMode, FREQ_MAX_MHZ, LED_COUNT};
use cta_firmware_beacon::pins::BEACON_LINES;
use cta_qemu::{done, end, fail, mark, paint_stack, stack_used};

/// Ticks measured (~0.1 s of modulation at 125 kHz: every frequency toggles many times).
const TICKS: u32 = 12_500;

static MODULATOR: Mutex<RefCell<Modulator>> = Mutex::new(RefCell::new(Modulator::EMPTY));
/// Stand-ins for TIM2->SR and the seven GPIOx->ODR and GPIOx->BSRR registers.
static mut TIM_SR: u32 = 0;
/// (8 entries, indexed with `port & 7` as in the firmware.)
static mut ODR: [u32; 8] = [0; 8];
static mut BSRR: [u32; 8] = [0; 8];

/// Same as the firmware's `Ports`, on the RAM stand-ins.
struct Ports;

impl Gpio for Ports {
    #[inline(always)]
    fn toggle(&mut self, port: usize, mask: u16) {
        // SAFETY: single-threaded program; volatile accesses to RAM stand-ins.
        unsafe {
            let r = (core::ptr::addr_of_mut!(ODR) as *mut u32).add(port & 7);
            r.write_volatile(r.read_volatile() ^ mask as u32);
        }
    }
    #[inline(always)]
    fn write(&mut self, port: usize, w: u32) {
        // SAFETY: as above.
        unsafe {
            (core::ptr::addr_of_mut!(BSRR) as *mut u32)
                .add(port & 7)
                .write_volatile(w)
        }
    }
}

/// The TIM2 interrupt body of the firmware.
#[inline(never)]
fn tim2_isr() {
    // SAFETY: single-threaded program; volatile stores to RAM stand-ins.
    unsafe { core::ptr::addr_of_mut!(TIM_SR).write_volatile(!1) };
    critical_section::with(|cs| MODULATOR.borrow_ref_mut(cs).tick(&mut Ports));
}

/// The LED assignment measured: `BEACON_TICK_CASE` at build time (see `case`).
const CASE: &str = match option_env!("BEACON_TICK_CASE") {
    Some(c) => c,
    None => "all100",
};

/// A frequency table of 32 entries at the top of the range (12.5 kHz down in 10 Hz steps):
/// the most edges per second a table can ask for.
const FAST32_MHZ: [u32; 32] = {
    let mut t = [0u32; 32];
    let mut i = 0;
    while i < 32 {
        t[i] = FREQ_MAX_MHZ - 10_000 * i as u32;
        i += 1;
    }
    t
};

/// The case's table and LED modes:
/// * `all100` (the default, the figure `firmware-beacon/ci.sh` reports): every LED at one
///   NorthStar frequency (LED i at entry i mod 20);
/// * `off`: no LED lit (the waves alone);
/// * `comboKxN`: LEDs 0..K each at N frequencies (entries i, i+7, i+14, ... mod 20), the
///   others off;
/// * `same100`: every LED at the same two NorthStar frequencies;
/// * `fast32`: every LED at one of 32 frequencies near 12.5 kHz;
/// * `mixedK`: LEDs 0..K at all 20 NorthStar frequencies, the others at one each.
fn case(name: &str) -> (&'static [u32], [LedMode; LED_COUNT]) {
    let single = |i: usize, n: usize| LedMode::Modulated(FreqSet::single((i % n) as u8));
    let multi = |i: usize, n: u32| {
        LedMode::Modulated(FreqSet(
            (0..n).fold(0u32, |s, k| s | 1 << ((i as u32 + 7 * k) % 20)),
        ))
    };
    let num = |s: &str| s.parse::<usize>().unwrap_or_else(|_| fail("case number"));
    if name == "all100" {
        (
            &NORTHSTAR_TABLE_MHZ,
            core::array::from_fn(|i| single(i, 20)),
        )
    } else if name == "off" {
        (&NORTHSTAR_TABLE_MHZ, [LedMode::Off; LED_COUNT])
    } else if name == "same100" {
        // Every LED at the same two frequencies (3040 and 3810 Hz): combo ticks are rare,
        // so the union bound is tight there.
        (
            &NORTHSTAR_TABLE_MHZ,
            [LedMode::Modulated(FreqSet(1 | 1 << 7)); LED_COUNT],
        )
    } else if name == "fast32" {
        (&FAST32_MHZ, core::array::from_fn(|i| single(i, 32)))
    } else if let Some(k) = name.strip_prefix("mixed") {
        let k = num(k);
        (
            &NORTHSTAR_TABLE_MHZ,
            core::array::from_fn(|i| if i < k { multi(i, 20) } else { single(i, 20) }),
        )
    } else if let Some((k, n)) = name.strip_prefix("combo").and_then(|r| r.split_once('x')) {
        let (k, n) = (num(k), num(n) as u32);
        (
            &NORTHSTAR_TABLE_MHZ,
            core::array::from_fn(|i| if i < k { multi(i, n) } else { LedMode::Off }),
        )
    } else {
        fail("unknown BEACON_TICK_CASE")
    }
}

#[entry]
fn main() -> ! {
    let (table, modes) = case(CASE);
    let Ok(mut m) = Modulator::new(table, &BEACON_LINES) else {
        fail("table")
    };
    m.configure(&modes);
    let x = tick_features(table, &modes, &BEACON_LINES);
    hprintln!(
        "TICK case={} model_mean={} features_q16={} {} {} {} {}",
        CASE,
        tick_cost(table, &modes, &BEACON_LINES),
        x[0],
        x[1],
        x[2],
        x[3],
        x[4]
    );
    critical_section::with(|cs| MODULATOR.borrow(cs).replace(m));
    // Warm up past the staggered start.
    for _ in 0..1000 {
        tim2_isr();
    }
    // Marker overhead: empty segments.
    for _ in 0..4 {
        mark();
    }
    let (lo, sp) = paint_stack(1024);
    for _ in 0..TICKS {
        mark();
        tim2_isr();
    }
    end();
    // The interrupt body's stack (the hardware's 32-byte exception frame comes on top).
    hprintln!("STACK tick_peak_bytes={}", stack_used(lo, sp));
    done("beacon_tick: done")
}
