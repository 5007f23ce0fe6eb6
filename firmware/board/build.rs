//! Link setup of the board image: the G431 memory map (this crate's memory.x) and the
//! cortex-m-rt and defmt link scripts, for the binary only (the library also builds on
//! the host for its unit tests, where none of this applies).
//!
//! Each board's map lives in its own crate and is copied into OUT_DIR as `memory.x`, which
//! cortex-m-rt's link.x INCLUDEs from the link search path. None may lie in the workspace
//! root: rustc links there, and lld looks for an INCLUDEd script in the working directory
//! before the search path, so a root memory.x would be every board's map (the G0B1 image
//! linked with the G431's 128 KiB map until the G431's moved here).
use std::{env, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").ok_or("no CARGO_MANIFEST_DIR")?);
    let memory_x = manifest.join("memory.x");
    fs::copy(&memory_x, out.join("memory.x"))
        .map_err(|e| format!("copying {} into OUT_DIR: {e}", memory_x.display()))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    if env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    Ok(())
}
