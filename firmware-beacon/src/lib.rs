//! # cta-firmware-beacon
//!
//! Firmware of the CTA beacon board: 100 VSML3710 IR LEDs on a 10 x 10 grid (1 in pitch),
//! each switched by a MOSFET from its own GPIO of an STM32F103ZET6, square-wave modulated
//! at the NorthStar frequencies and commanded from the PC over RS-232 (thesis Ch IV,
//! Table 1; REFERENCE.md section 4).
//!
//! This library is the host-testable part; `src/main.rs` is only the wiring to the chip.
//!
//! * [`board`]: protocol handling (the [`cta_core::wire`] framing with the
//!   [`cta_core::wire::beacon`] messages), LED state and the safety rules (lit-LED cap,
//!   dead-man timeout).
//! * [`pins`]: the pin map (LED id -> GPIO, the reserved pins) and its output lines.
//! * The modulation schedule lives in [`cta_core::schedule`]
//!   ([`cta_core::schedule::Modulator`], driving [`pins::BEACON_LINES`]); the modulator is
//!   this board's [`board::Outputs`].
//! * `sim` (feature `sim`): the simulated board behind a pseudo-terminal, running the
//!   same [`board::Board`] and [`cta_core::schedule::Modulator`].
#![cfg_attr(not(feature = "sim"), no_std)]

#[cfg(test)]
extern crate std;

pub mod board;
pub mod pins;
// The simulated board runs behind a pseudo-terminal: Unix only.
#[cfg(all(feature = "sim", unix))]
pub mod sim;

pub use cta_core::schedule::{Modulator, TICK_HZ};
pub use pins::{BEACON_LINES, BEACON_PINS, RESERVED_PINS};

use cta_core::wire::beacon::{LedMode, LED_COUNT};

impl board::Outputs for Modulator {
    fn set_table(&mut self, table_mhz: &[u32]) {
        // The board validated the table; a refusal here would leave the old table running
        // with every LED off, which is safe.
        let _ = Modulator::set_table(self, table_mhz);
    }
    fn set_modes(&mut self, modes: &[LedMode; LED_COUNT]) {
        self.configure(modes);
    }
}
