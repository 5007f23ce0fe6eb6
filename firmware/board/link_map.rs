//! Finds a board image's memory map for its build.rs, the same way for every board: the
//! `memory.x` at the root of the workspace the image is built in. That is where rustc links,
//! and lld looks for cortex-m-rt's `INCLUDE memory.x` in the working directory before the link
//! search path, so a map anywhere else would be overruled by the root's. The G431 image
//! (`firmware`) is built in the product's workspace, whose root holds the G431's map; the
//! G0B1 image (`firmware-g0b1`) is a workspace of its own, its crate folder holding its map.
//!
//! Included by path (`#[path]`) into both build scripts: a build script has no crate to share.
use std::{env, fs, path::PathBuf};

/// Copies the map into OUT_DIR as `memory.x` and puts OUT_DIR on the link search path (as
/// cortex-m-quickstart does), so the link does not depend on the working directory alone.
pub fn provide_memory_x() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("cargo did not set OUT_DIR")?);
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").ok_or("no CARGO_MANIFEST_DIR")?);
    let root = workspace_root(&manifest)?;
    let memory_x = root.join("memory.x");
    fs::copy(&memory_x, out.join("memory.x"))
        .map_err(|e| format!("copying {} into OUT_DIR: {e}", memory_x.display()))?;
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    Ok(())
}

/// The nearest folder at or above `dir` whose Cargo.toml has a `[workspace]` table: the root
/// cargo itself finds for the crate (neither crate names another root with
/// `package.workspace`).
fn workspace_root(dir: &std::path::Path) -> Result<PathBuf, String> {
    for d in dir.ancestors() {
        let manifest = d.join("Cargo.toml");
        let Ok(text) = fs::read_to_string(&manifest) else { continue };
        println!("cargo:rerun-if-changed={}", manifest.display());
        if text.lines().any(|l| l.trim() == "[workspace]") {
            return Ok(d.to_path_buf());
        }
    }
    Err(format!("no workspace root above {}", dir.display()))
}
