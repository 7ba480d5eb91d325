//! # cta-firmware-boot
//!
//! The start-up both boards run first, before their clock tree: what reset the chip
//! ([`ResetCause`], from `RCC_CSR`), and whether the 8 MHz crystal (HSE) starts and runs at
//! 8 MHz against the internal RC oscillator ([`cta_core::crystal`]). Both boards multiply
//! the crystal by 9 for 72 MHz, so a board on another crystal logs why and resets instead of
//! running its clocks, timers and baud rates off by the ratio.
//!
//! # Why a crate of its own, and here
//!
//! `core` is free of the HAL and of pins; the two firmwares' `chip.rs` files are their only
//! HAL users, and this is the code they had in common. A crate (not a module file shared by
//! path) gives it one set of dependencies and one place in the build. It lives inside
//! `firmware-beacon/` because the top level holds core, the two firmwares, the host and the
//! tests only; the sensor firmware depends on it by path.
//!
//! It asks the HAL (`stm32f1xx-hal`) for the chip family alone (`stm32f103`): the density
//! feature comes from the firmware that uses it (`high` for the beacon's ZET6, `medium` for
//! the sensor's C8). Cargo unifies features per invocation, and each firmware is built in an
//! invocation of its own (its `ci.sh`, `cargo run --release` from its folder), so the HAL is
//! compiled for the one board being built, and this code with it. The registers used here
//! (RCC, PWR, RTC, the backup domain) are the same on both densities.
#![no_std]

#[cfg(target_os = "none")]
mod chip;
#[cfg(target_os = "none")]
pub use chip::start;
