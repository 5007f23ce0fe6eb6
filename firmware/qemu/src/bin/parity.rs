//! Parity image: runs the core's scripted session (`joint_core::vectors::session`) on the
//! emulated Cortex-M4F and prints every record, f32 values as their bit patterns in hex,
//! one line each, on semihosting stdout. The host computes the same session natively and
//! compares every word (tests/tests/qemu_parity.rs). The closing `# summary` line lets the
//! host check the session also ran to completion here.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

#[cfg(target_os = "none")]
fn run() -> i32 {
    use core::fmt::Write;
    use joint_core::vectors;

    let mut out = match firmware_qemu::LineOut::stdout() {
        Some(o) => o,
        None => return firmware_qemu::EXIT_CHECK_FAILED,
    };
    let mut write_failed = false;
    let summary = vectors::session(&mut |r: &vectors::Record| {
        write_failed |= r.write_line(&mut out).is_err();
    });
    write_failed |= writeln!(
        out,
        "# summary records={} steps={} accepted={} rejected={} rejected_but_changed={} unexpected={} unsafe={}",
        summary.records,
        summary.steps,
        summary.accepted,
        summary.rejected,
        summary.rejected_but_changed,
        summary.unexpected_results,
        summary.unsafe_outputs
    )
    .is_err();
    if write_failed {
        return firmware_qemu::EXIT_CHECK_FAILED;
    }
    0
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-parity")
}
