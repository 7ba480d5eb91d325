//! The chip's face-angle sine and cosine ([`cta_core::trig::sin_cos_f32`], 64-bit fixed
//! point) against libm's `sinf` and `cosf` (double precision) on a Cortex-M3 (QEMU
//! lm3s6965evb), as the firmware is built: the host test compares every `f32` of
//! `|x| <= 3 pi / 4`; this checks the target's code gives the same bits, on every 97th
//! `f32` from 4 to 86 deg (379,000 of them, both signs) and the range's edges.
//!
//! Prints `TRIG checked=N mismatches=0` (firmware-sensor/ci.sh runs it, without tracing:
//! a few seconds).
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use cta_core::trig::sin_cos_f32;
use cta_qemu::{done, fail};

#[entry]
fn main() -> ! {
    // 4 and 86 deg in radians.
    let (lo, hi) = (0.069_813_17_f32.to_bits(), 1.500_983_5_f32.to_bits());
    let edges = [0, 1, 0x3980_0000, 0x3f49_0fda, 0x3f49_0fdb, 0x3fc9_0fdb, 0x4016_cbe3];
    let (mut checked, mut bad) = (0u32, 0u32);
    for b in (lo..=hi).step_by(97).chain(edges) {
        for x in [f32::from_bits(b), -f32::from_bits(b)] {
            let (s, c) = sin_cos_f32(x);
            checked += 1;
            if s.to_bits() != libm::sinf(x).to_bits() || c.to_bits() != libm::cosf(x).to_bits() {
                bad += 1;
            }
        }
    }
    hprintln!("TRIG checked={} mismatches={}", checked, bad);
    if bad != 0 {
        fail("sin_cos_f32 differs from libm on the target");
    }
    done("trig: ok")
}
