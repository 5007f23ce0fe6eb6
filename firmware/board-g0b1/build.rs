//! Link setup of the G0B1 image: its memory map (this crate's `memory.x`, at the root of the
//! crate's own workspace, found as every board's is: see firmware/board/link_map.rs) and the
//! cortex-m-rt and defmt link scripts, for the binary only.
#[path = "../board/link_map.rs"]
mod link_map;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    link_map::provide_memory_x()?;
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    Ok(())
}
