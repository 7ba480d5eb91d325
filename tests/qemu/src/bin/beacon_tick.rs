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
use cta_core::schedule::{Gpio, Modulator, BEACON_PINS, NORTHSTAR_TABLE_MHZ};
use cta_core::wire::beacon::{FreqSet, LedMode, LED_COUNT};
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

#[entry]
fn main() -> ! {
    let Ok(mut m) = Modulator::new(&NORTHSTAR_TABLE_MHZ, &BEACON_PINS) else {
        fail("table")
    };
    let modes: [LedMode; LED_COUNT] =
        core::array::from_fn(|i| LedMode::Modulated(FreqSet::single((i % 20) as u8)));
    m.configure(&modes);
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
