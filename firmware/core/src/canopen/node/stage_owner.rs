//! A staged set never outlives its master.
//!
//! SDO writes stage parameters; only a commit makes them run. A master that stops half-way
//! (killed, unplugged) used to leave its values staged, waiting for whoever commits next.
//! Now the staged set belongs to the SDO channel that last wrote to it: when that channel
//! carries no request for [`STAGE_IDLE_US`] (a pushing master sends one every few ms, and an
//! abort between retries at least every SDO timeout, 1 s), the staged set is discarded (it
//! becomes the set in force again), and the node says so as it says a refused commit: 0x2201
//! (code 8, the message naming the set in force by its CRC, the one 0x2204 and `push` use)
//! and EMCY 0x6320, kept in 0x1003.
//!
//! Not the consumed heartbeat: the master that stages need not be the one whose heartbeat
//! the joint watches (a tool beside the controller), and a master without a heartbeat would
//! lose what it staged to the loss the joint latches after boot.

use super::{ControlStep, Node, ParamStorage};

/// A staged set whose channel is quiet this long is discarded.
pub const STAGE_IDLE_US: u64 = 3_000_000;

impl<S: ParamStorage, C: ControlStep> Node<S, C> {
    /// A write to the staged set, on the channel being served.
    pub(super) fn stage_touched(&mut self) {
        self.staged_by = Some(self.chan);
        self.stage_seen_us = self.now_us;
    }

    /// A request on the channel being served: its master is alive.
    pub(super) fn stage_seen(&mut self, now_us: u64) {
        if self.staged_by == Some(self.chan) {
            self.stage_seen_us = now_us;
        }
    }

    /// From `poll`: discard the staged set if its master went quiet.
    pub(super) fn stage_watch(&mut self, now_us: u64) {
        if self.staged_by.is_some() && now_us.saturating_sub(self.stage_seen_us) > STAGE_IDLE_US {
            self.stage_discard();
        }
    }

    /// Out of line and cold: the copy of the set in force may take a set-sized temporary,
    /// which must not sit in `poll`'s frame (the QEMU image measures the node's peak stack).
    #[cold]
    #[inline(never)]
    fn stage_discard(&mut self) {
        self.staged_by = None;
        self.staged.clone_from(self.active.current().raw());
        let crc = crate::store::set_crc(self.active.current().raw());
        self.set_commit_error(8, 0xFFFF, format_args!("staged set discarded: master quiet; {crc:08x} in force"));
    }
}
