//! Hands the linker the QEMU images' own memory map and link script.
//!
//! `memory.x` is copied into OUT_DIR under the name `mps2-an386-memory.x` because the
//! workspace root holds the board's `memory.x`, and lld resolves an INCLUDE relative to
//! the working directory (the workspace root) before the search path.
use std::{env, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    fs::copy("memory.x", out.join("mps2-an386-memory.x"))?;
    fs::copy("qemu.x", out.join("qemu.x"))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=qemu.x");
    // Only the thumb images link with this script; a host `cargo check` of the crate
    // builds plain binaries that say they are not meant for the host.
    // thumbv6m (Cortex-M0/M0+, no FPU, no Thumb-2): the runtime's start-up code and the
    // bench's budget differ; the same images then run on mps2-an385 (see src/rt.rs).
    println!("cargo::rustc-check-cfg=cfg(armv6m)");
    if env::var("TARGET").is_ok_and(|t| t.starts_with("thumbv6m")) {
        println!("cargo:rustc-cfg=armv6m");
    }
    if env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=-Tqemu.x");
    }
    Ok(())
}
