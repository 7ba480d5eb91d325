//! Link arguments for the target build only (the host build of the library and the
//! `sim` feature must not see them). memory.x is the workspace root's (STM32F103x8).
fn main() {
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7m") {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
