//! The second SDO server channel (0x1201), so a tool and a controller never share one
//! transfer: two masters on the default channel would have one's segments acknowledged into
//! the other's transfer, since CiA 301 SDO frames carry no client address.
//!
//! The channel has its own transfer state and its own 512-byte transfer buffer. A request on
//! it runs the same server code as the default channel: its transfer is swapped into
//! [`Node::transfer`] for the request (a few dozen bytes) and `chan` selects its buffer, so
//! neither channel ever sees the other's state, and a tool and a controller each run a
//! download of their own at once. (The buffer was shared for a while, to keep the QEMU image's
//! stack check under 20 KiB; that check now counts the stack beyond the node, which the
//! boards keep in static RAM, where the G431 has room for it.) Its COB-IDs are "not valid" (bit 31) after
//! every reset communication, as CiA 301 has it for additional server channels, until a
//! master writes them; the id bits of a valid COB-ID cannot change (write bit 31 first).

use super::{frame, put_u32, put_u8, ControlStep, Node, ParamStorage, Transfer, Value, SDO_BUFFER};
use crate::canopen::frame::CanFrame;
use crate::canopen::node::COB_INVALID;
use crate::canopen::sdo::{self, Abort};

/// State of the second channel.
pub(super) struct Server2 {
    /// 0x1201 sub 1: client → server
    rx: u32,
    /// 0x1201 sub 2: server → client
    tx: u32,
    /// 0x1201 sub 3
    client: u8,
    transfer: Transfer,
    buf: [u8; SDO_BUFFER],
}

impl Server2 {
    pub(super) const fn new() -> Server2 {
        Server2 { rx: COB_INVALID, tx: COB_INVALID, client: 0, transfer: Transfer::Idle, buf: [0; SDO_BUFFER] }
    }

    /// Reset communication: not valid again, no transfer.
    pub(super) fn reset(&mut self) {
        self.rx = COB_INVALID;
        self.tx = COB_INVALID;
        self.client = 0;
        self.transfer = Transfer::Idle;
    }

    /// The response COB-ID when the channel is valid and `id` is its request COB-ID.
    fn serves(&self, id: u16) -> Option<u16> {
        let valid = (self.rx | self.tx) & COB_INVALID == 0;
        (valid && u32::from(id) == self.rx & 0x7FF).then_some((self.tx & 0x7FF) as u16)
    }
}

impl<S: ParamStorage, C: ControlStep> Node<S, C> {
    /// The transfer buffer of the channel being served.
    pub(super) fn sdo_buf(&mut self) -> &mut [u8; SDO_BUFFER] {
        if self.chan == 1 {
            &mut self.sdo2.buf
        } else {
            &mut self.buf
        }
    }

    /// Run `f` with the second channel's transfer in [`Node::transfer`] and its buffer selected.
    fn on_channel2<R>(&mut self, f: impl FnOnce(&mut Self) -> R) -> R {
        core::mem::swap(&mut self.transfer, &mut self.sdo2.transfer);
        self.chan = 1;
        let r = f(self);
        self.chan = 0;
        core::mem::swap(&mut self.transfer, &mut self.sdo2.transfer);
        r
    }

    /// A frame on the second channel's request COB-ID: served, `true`. Otherwise `false`.
    pub(super) fn sdo2_frame(&mut self, now_us: u64, f: &CanFrame, tx: &mut impl FnMut(CanFrame)) -> bool {
        let Some(cob) = self.sdo2.serves(f.id()) else {
            return false;
        };
        let d = f.data();
        // a reply takes its request's format (classic SDO in FD frames, as on channel 1)
        let brs = f.is_fd().then(|| f.brs());
        let mut reply = |r: CanFrame| {
            tx(match brs {
                Some(b) => r.into_fd(b),
                None => r,
            })
        };
        self.on_channel2(|n| n.sdo_serve(now_us, d, cob, &mut reply));
        true
    }

    /// The second channel's timers (timeout, upload bursts), only while it has a transfer.
    pub(super) fn sdo2_poll(&mut self, now_us: u64, tx: &mut impl FnMut(CanFrame)) {
        if matches!(self.sdo2.transfer, Transfer::Idle) {
            return;
        }
        let cob = (self.sdo2.tx & 0x7FF) as u16;
        self.on_channel2(|n| n.sdo_timers(now_us, cob, tx));
    }

    pub(super) fn sdo_server_value(&self, ch: u8, sub: u8) -> Value {
        let me = u32::from(self.cfg.node_id);
        // (0x1200 has subs 1 and 2 only: the dictionary refuses the rest before)
        match (ch, sub) {
            (0, 1) => put_u32(u32::from(sdo::RX_BASE) + me),
            (0, _) => put_u32(u32::from(sdo::TX_BASE) + me),
            (_, 1) => put_u32(self.sdo2.rx),
            (_, 2) => put_u32(self.sdo2.tx),
            _ => put_u8(self.sdo2.client),
        }
    }

    /// 0x1201: a COB-ID (11-bit, bit 31 = not valid; its id only while not valid) or the
    /// client's node id. An id the default channel or NMT uses is refused.
    pub(super) fn write_sdo_server(&mut self, ch: u8, sub: u8, u: u32) -> Result<(), Abort> {
        if ch == 0 {
            // (0x1200 has no sub 3: the dictionary refuses it before)
            return Err(Abort::ReadOnly);
        }
        if sub == 3 {
            if u > 127 {
                return Err(Abort::InvalidValue);
            }
            self.sdo2.client = u as u8;
            return Ok(());
        }
        // 11-bit id, bit 31 = not valid; no extended frames (29), no dynamic allocation (30)
        if u & 0x3FFF_F800 != 0 || (u & COB_INVALID == 0 && u & 0x7FF == 0) {
            return Err(Abort::InvalidValue);
        }
        let v = u & (COB_INVALID | 0x7FF);
        let me = u16::from(self.cfg.node_id);
        let id = (v & 0x7FF) as u16;
        if id == sdo::RX_BASE + me || id == sdo::TX_BASE + me {
            return Err(Abort::InvalidValue);
        }
        let old = if sub == 1 { self.sdo2.rx } else { self.sdo2.tx };
        if old & COB_INVALID == 0 && v & COB_INVALID == 0 && v != old {
            return Err(Abort::InvalidValue);
        }
        if sub == 1 {
            self.sdo2.rx = v;
        } else {
            self.sdo2.tx = v;
        }
        if v & COB_INVALID != 0 {
            self.sdo2.transfer = Transfer::Idle;
        }
        Ok(())
    }

    /// A frame on an SDO channel whose response COB-ID is `cob`: block traffic or the rest.
    pub(super) fn sdo_serve(&mut self, now_us: u64, d: &[u8], cob: u16, tx: &mut impl FnMut(CanFrame)) {
        self.stage_seen(now_us);
        if !self.block_request(now_us, d, cob, tx) {
            if let Some(resp) = self.sdo_request(now_us, d) {
                tx(frame(cob, resp, 8));
            }
        }
    }
}
