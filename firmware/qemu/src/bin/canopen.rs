//! CANopen session image: runs `firmware_qemu::canopen_session` (the core's CANopen node fed
//! a scripted master's frames, interleaved with 1 kHz poll + control steps) on the emulated
//! Cortex-M4F and prints every frame the node sends and every control output, one line each,
//! then a `# canopen` summary line. The host runs the same file natively and compares the
//! text line by line (tests/tests/qemu_parity.rs).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

#[cfg(target_os = "none")]
fn run() -> i32 {
    use firmware_qemu::canopen_session::{self, Line};

    let mut out = match firmware_qemu::LineOut::stdout() {
        Some(o) => o,
        None => return firmware_qemu::EXIT_CHECK_FAILED,
    };
    let mut write_failed = false;
    let summary = canopen_session::run(&mut |l: &Line| {
        write_failed |= l.write(&mut out).is_err();
    });
    write_failed |= summary.write(&mut out).is_err();
    if write_failed {
        return firmware_qemu::EXIT_CHECK_FAILED;
    }
    0
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-canopen")
}
