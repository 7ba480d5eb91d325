//! Link scripts for the firmware binary, only when building for the chip (the root
//! memory.x is found first: the budget both boards must fit).
fn main() {
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7m") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
