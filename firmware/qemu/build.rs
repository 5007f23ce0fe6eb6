//! Link setup of the QEMU images: their memory map (this crate's `memory.x`, at the root of the
//! crate's own workspace, found as every board's is: see firmware/board/link_map.rs) and
//! cortex-m-rt's link script, for the thumb binaries only (a host `cargo check` of the crate
//! builds plain binaries that say they are not meant for the host).
#[path = "../board/link_map.rs"]
mod link_map;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    link_map::provide_memory_x()?;
    // thumbv6m (Cortex-M0/M0+, no FPU, no Thumb-2): the bench's budget differs; the same
    // images then run on mps2-an385.
    println!("cargo::rustc-check-cfg=cfg(armv6m)");
    if std::env::var("TARGET").is_ok_and(|t| t.starts_with("thumbv6m")) {
        println!("cargo:rustc-cfg=armv6m");
    }
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
    Ok(())
}
