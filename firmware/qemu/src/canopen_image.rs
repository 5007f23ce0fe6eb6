//! The CANopen session image's body, shared by `qemu-canopen` (f32 node) and
//! `qemu-canopen-q16` (Q16.16 node): runs [`crate::canopen_session`], prints every line and
//! the summary, and measures the node's peak stack by painting (see the bins' docs).

/// Runs the session on a node with the control step `C`, prints it, returns the exit status.
pub fn run<C: joint_core::canopen::ControlStep>() -> i32 {
    use crate::canopen_session::{self, Line};

    let mut out = match crate::LineOut::stdout() {
        Some(o) => o,
        None => return crate::EXIT_CHECK_FAILED,
    };
    let mut write_failed = false;
    let boot = stack::peak(|| {
        use joint_core::canopen::{MemoryStorage, Node, NodeConfig};
        let storage =
            MemoryStorage { stored: Some(joint_core::vectors::trunk_right()), saves: 0, pdo: None, lss: None };
        let node = Node::<_, C>::with_step(NodeConfig::new(canopen_session::NODE_ID), storage, 0);
        core::hint::black_box(&node);
    });
    let mut summary = None;
    let session = stack::peak(|| {
        summary = Some(canopen_session::run_with::<C>(&mut |l: &Line| {
            write_failed |= l.write(&mut out).is_err();
        }));
    });
    let Some(summary) = summary else {
        return crate::EXIT_CHECK_FAILED;
    };
    write_failed |= summary.write(&mut out).is_err();
    let mut fd_summary = None;
    let fd_session = stack::peak(|| {
        fd_summary = Some(canopen_session::run_fd_with::<C>(&mut |l: &Line| {
            write_failed |= l.write(&mut out).is_err();
        }));
    });
    let Some(fd_summary) = fd_summary else {
        return crate::EXIT_CHECK_FAILED;
    };
    write_failed |= fd_summary.write_fd(&mut out).is_err();
    {
        use core::fmt::Write;
        let session = session.max(fd_session);
        // the node itself (a local here; a static on the boards, counted in their static RAM)
        let node = core::mem::size_of::<joint_core::canopen::Node<joint_core::canopen::MemoryStorage, C>>();
        write_failed |= writeln!(out, "# stack node_new={boot} session={session} bytes").is_err();
        write_failed |= writeln!(out, "# node size={node} bytes").is_err();
    }
    if write_failed {
        return crate::EXIT_CHECK_FAILED;
    }
    0
}

/// Stack painting: how deep a call goes below the caller's stack pointer.
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
