//! Link arguments for the target build only (the host build of the library and the
//! `sim` feature must not see them). memory.x is the workspace root's (STM32F103x8: the
//! linker finds the root's first, and it must be valid for both boards), so it gives the
//! whole 64 KiB of flash; a guard script of this firmware's own keeps the image out of the
//! last two pages, where the board stores its configuration (`chip.rs`, `PAGES`): an
//! image grown into them would be erased by the first `LoadCalibration`.
use std::{env, fs, path::PathBuf};

/// First byte of the configuration pages (page 62 of 1 KiB).
const CONFIG_PAGES: u32 = 0x0800_0000 + 62 * 1024;

fn main() {
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7m") {
        let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
        let guard = format!(
            "/* Written by firmware-sensor/build.rs. */\n\
             ASSERT(__sidata + (__edata - __sdata) <= {CONFIG_PAGES:#010x} && __veneer_limit <= {CONFIG_PAGES:#010x},\n\
             \"firmware-sensor: the image reaches the configuration pages (flash from {CONFIG_PAGES:#010x}, chip.rs PAGES)\");\n"
        );
        fs::write(out.join("sensor_guard.x"), guard).expect("write sensor_guard.x");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        println!("cargo:rustc-link-arg-bins=-Tsensor_guard.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
