//! The CANopen session image with the node's control step in Q16.16 (what the FPU-less board
//! image runs): the same script as `qemu-canopen`, compared line by line with the host's run
//! of it (tests/tests/qemu_parity.rs, `QEMU_CANOPEN_Q16_LOG`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

#[cfg(target_os = "none")]
fn run() -> i32 {
    firmware_qemu::canopen_image::run::<joint_core::fixed::ControllerFx>()
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-canopen-q16")
}
