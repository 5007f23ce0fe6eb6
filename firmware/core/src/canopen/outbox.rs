//! Frames a node emitted while its lock was held, waiting to be written to the CAN controller
//! once the lock is released (writing may wait for a free TX buffer, which must never happen
//! inside a critical section). Part of the control loop's body every firmware on the core
//! shares (the boards' CAN tasks; docs/porting.md).

use super::CanFrame;

/// Frames the node emitted while its lock was held, waiting to be written to the
/// controller once the lock is released (writing may wait for a free TX buffer, which must
/// never happen inside a critical section). Frames beyond `N` are counted, not kept.
#[derive(Debug, Clone)]
pub struct Outbox<const N: usize> {
    frames: [CanFrame; N],
    len: usize,
    /// Frames that did not fit since the last [`Outbox::take_overflow`].
    overflow: u32,
}

impl<const N: usize> Default for Outbox<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Outbox<N> {
    pub fn new() -> Self {
        Outbox { frames: [CanFrame::default(); N], len: 0, overflow: 0 }
    }

    /// The callback the node's `process`/`poll` send through.
    pub fn push(&mut self, f: CanFrame) {
        match self.frames.get_mut(self.len) {
            Some(slot) => {
                *slot = f;
                self.len += 1;
            }
            None => self.overflow = self.overflow.saturating_add(1),
        }
    }

    /// The callback to hand the node, as one concrete type: the node's `process` and `poll`
    /// are generic over their callback, and every distinct closure type would instantiate
    /// (and put in flash) another copy of the node's sending code.
    pub fn sink(&mut self) -> impl FnMut(CanFrame) + '_ {
        move |f| self.push(f)
    }

    /// The frames in the order the node sent them.
    pub fn frames(&self) -> &[CanFrame] {
        self.frames.get(..self.len).unwrap_or(&[])
    }

    pub fn clear(&mut self) {
        self.len = 0;
    }

    pub fn take_overflow(&mut self) -> u32 {
        core::mem::take(&mut self.overflow)
    }
}
