//! Link setup of the G431 image: its memory map (the `memory.x` at the workspace root, found as
//! every board's is: see link_map.rs) and the cortex-m-rt and defmt link scripts, for the
//! binary only (the library also builds on the host for its unit tests, where none of this
//! applies).
//!
//! Only with the `g431` feature, which the binary requires: the G0B1 image uses this crate's
//! library without it, and a map this script put on the search path would reach that image's
//! link too.
#[path = "link_map.rs"]
mod link_map;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    if std::env::var_os("CARGO_FEATURE_G431").is_none() {
        return Ok(());
    }
    link_map::provide_memory_x()?;
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    Ok(())
}
