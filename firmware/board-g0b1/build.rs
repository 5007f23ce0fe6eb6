//! Link setup of the G0B1 image: this crate's own memory map and the cortex-m-rt and defmt
//! link scripts, for the binary only. The map is found the same way as the G431's (see firmware/board/build.rs for why no board's map may
//! lie in the workspace root).
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
