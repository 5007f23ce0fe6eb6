//! CANopen session image: runs `firmware_qemu::canopen_session` (the core's CANopen node fed
//! a scripted master's frames, interleaved with 1 kHz poll + control steps) on the emulated
//! Cortex-M4F and prints every frame the node sends and every control output, one line each,
//! then a `# canopen` summary line. The host runs the same file natively and compares the
//! text line by line (tests/tests/qemu_parity.rs).
//!
//! It also measures the stack the node needs on a Cortex-M4F (`# stack` line, not compared):
//! the region below the stack pointer is painted, `Node::new` (boot with a stored set: load,
//! check, reset) and then the whole session run, and the deepest overwritten word gives the
//! peak. The board has 32 KiB of RAM for static data and the stack together.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

#[cfg(target_os = "none")]
fn run() -> i32 {
    firmware_qemu::canopen_image::run::<joint_core::control::Controller>()
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-canopen")
}
