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
    use firmware_qemu::canopen_session::{self, Line};

    let mut out = match firmware_qemu::LineOut::stdout() {
        Some(o) => o,
        None => return firmware_qemu::EXIT_CHECK_FAILED,
    };
    let mut write_failed = false;
    let boot = stack::peak(|| {
        use joint_core::canopen::{MemoryStorage, Node, NodeConfig};
        let storage = MemoryStorage { stored: Some(joint_core::vectors::trunk_right()), saves: 0 };
        let node = Node::new(NodeConfig::new(canopen_session::NODE_ID), storage, 0);
        core::hint::black_box(&node);
    });
    let mut summary = None;
    let session = stack::peak(|| {
        summary = Some(canopen_session::run(&mut |l: &Line| {
            write_failed |= l.write(&mut out).is_err();
        }));
    });
    let Some(summary) = summary else {
        return firmware_qemu::EXIT_CHECK_FAILED;
    };
    write_failed |= summary.write(&mut out).is_err();
    {
        use core::fmt::Write;
        write_failed |= writeln!(out, "# stack node_new={boot} session={session} bytes").is_err();
    }
    if write_failed {
        return firmware_qemu::EXIT_CHECK_FAILED;
    }
    0
}

/// Stack painting: how deep a call goes below the caller's stack pointer.
#[cfg(target_os = "none")]
mod stack {
    const SPAN: usize = 96 * 1024;
    const MARK: u32 = 0x5AA5_C33C;
    /// Kept free below the caller's SP for `paint`/`depth`'s own small frames.
    const GAP: usize = 256;

    fn sp() -> usize {
        let sp: usize;
        // SAFETY: reads the stack pointer register, nothing else.
        unsafe { core::arch::asm!("mov {}, sp", out(reg) sp) };
        sp
    }

    #[inline(never)]
    fn paint(top: usize) {
        for a in (top - SPAN..top).step_by(4) {
            // SAFETY: unused stack below the current frame (QEMU gives 4 MiB of RAM).
            unsafe { (a as *mut u32).write_volatile(MARK) };
        }
    }

    #[inline(never)]
    fn depth(top: usize) -> usize {
        let mut a = top - SPAN;
        // SAFETY: the same region, read back.
        while a < top && unsafe { (a as *const u32).read_volatile() } == MARK {
            a += 4;
        }
        top - a
    }

    /// Peak stack of `f` in bytes below the caller's frame (± the GAP's few words).
    pub fn peak(f: impl FnOnce()) -> usize {
        let top = sp() - GAP;
        paint(top);
        run(f);
        depth(top) + GAP
    }

    #[inline(never)]
    fn run(f: impl FnOnce()) {
        f()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-canopen")
}
