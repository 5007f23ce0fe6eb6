//! Link setup: this example's memory map (found as every board's is: see
//! firmware/board/link_map.rs) and cortex-m-rt's link script, for the binary only.
#[path = "../board/link_map.rs"]
mod link_map;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    link_map::provide_memory_x()?;
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
    Ok(())
}
