//! Sensor-board firmware entry point (wiring only; the logic is in the library).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("cta-firmware-sensor runs on the STM32F103C8: build it with `cargo build --release` from firmware-sensor/ (target thumbv7m-none-eabi)");
}
