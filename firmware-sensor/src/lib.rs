//! Sensor-board firmware logic (host-testable, `no_std`): the NorthStar link, the PC
//! link, flash storage of the constellation and calibration, and the on-chip pose.
//! `main.rs` only wires these to the STM32F103C8's peripherals.
//!
//! With the `sim` feature (host only) [`sim`] runs the same [`board::Board`] behind a
//! pseudo-terminal, fed by a simulated NorthStar.
#![cfg_attr(not(feature = "std"), no_std)]

pub mod board;
pub mod northstar;
pub mod storage;

#[cfg(feature = "sim")]
pub mod sim;
