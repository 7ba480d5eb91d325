//! Sensor-board firmware entry point (wiring only; the logic is in the library).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod chip;

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "cta-firmware-sensor runs on the STM32F103C8: build it with `cargo build --release` \
         (or flash with `cargo run --release`) from firmware-sensor/, or use `cta sensor --sim` \
         for the simulated board"
    );
    std::process::exit(2);
}
