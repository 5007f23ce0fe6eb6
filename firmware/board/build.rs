//! Link setup of the board image: the G431 memory map from the workspace root and the
//! cortex-m-rt and defmt link scripts, for the binary only (the library also builds on
//! the host for its unit tests, where none of this applies).
use std::{env, fs, path::PathBuf};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").ok_or("no CARGO_MANIFEST_DIR")?);
    let memory_x = manifest.join("../../memory.x");
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
