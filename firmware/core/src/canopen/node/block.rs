//! SDO block transfer, server side (CiA 301 §7.2.4.3.9 ff.), with the CRC of §7.2.4.3.16.
//!
//! A download's segments go straight into the transfer buffer the segmented download already
//! uses (at `base + 7·(seqno − 1)`), so a block costs no RAM of its own, and a lost or
//! out-of-order segment costs only a retransmission: the acknowledgement names the last
//! segment received in order, and the client restarts the next block from the one after it.
//! Nothing is written to the object before the end frame's CRC (when both sides asked for it)
//! and length check pass, so a damaged transfer leaves the old value in force.
//!
//! An upload copies the object into the same buffer at its initiate (the channel has one
//! transfer at a time, so the buffer is free), so every segment, a retransmitted one too, and
//! the CRC come from one consistent snapshot. Its segments go
//! out at most [`UPLOAD_BURST`] per `process`/`poll` call: the board's outbox holds 16 frames
//! and the heartbeat and TPDOs share it. The protocol switch threshold is ignored (CiA 301
//! allows it): every block upload is answered in block mode, a 1-byte object too.

use super::{le_u32, ControlStep, Node, ParamStorage, Transfer, Value, SDO_BUFFER};
use crate::canopen::frame::CanFrame;
use crate::canopen::od::{self, SubInfo};
use crate::canopen::sdo::{self, Abort, BLOCK_SEGMENTS_MAX};

/// Segments per block the node asks for in a download (and after each acknowledgement).
pub const DOWNLOAD_BLOCK: u8 = BLOCK_SEGMENTS_MAX;
/// Upload segments sent per `process`/`poll` call.
pub const UPLOAD_BURST: u8 = 8;

/// A block download in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Down {
    info: SubInfo,
    /// the client will send a CRC in its end frame (the node always supports it)
    crc: bool,
    /// bytes acknowledged in earlier blocks (7 per segment)
    base: usize,
    /// last segment of this block received in order
    seq: u8,
    /// the segment with `c` (no more data) was received in order
    last: bool,
    /// all blocks acknowledged: waiting for the end frame
    ending: bool,
    expected: Option<usize>,
    last_us: u64,
}

impl Down {
    /// (index, sub-index, time of the last request) for the SDO timeout
    pub(super) fn timer(&self) -> (u16, u8, u64) {
        (self.info.index, self.info.sub, self.last_us)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum UpPhase {
    /// initiate answered, waiting for the client's start
    Initiated,
    /// sending the current block
    Sending,
    /// block sent, waiting for its acknowledgement
    WaitAck,
    /// end frame sent, waiting for the client's end
    End,
}

/// A block upload in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Up {
    index: u16,
    sub: u8,
    crc: bool,
    total: usize,
    /// segments acknowledged in earlier blocks
    acked: usize,
    /// segments of this block already sent
    sent: u8,
    blksize: u8,
    phase: UpPhase,
    last_us: u64,
}

impl Up {
    /// (index, sub-index, time of the last request) for the SDO timeout
    pub(super) fn timer(&self) -> (u16, u8, u64) {
        (self.index, self.sub, self.last_us)
    }
    /// Segments the object takes (an empty one still takes one, with no data).
    fn segments(&self) -> usize {
        self.total.div_ceil(7).max(1)
    }
}

fn resp(cob: u16, d: [u8; 8], tx: &mut impl FnMut(CanFrame)) {
    tx(CanFrame::from_parts(cob, d, 8));
}

impl<S: ParamStorage, C: ControlStep> Node<S, C> {
    /// A request on an SDO channel if it is block traffic: returns `false` (and does nothing)
    /// for frames of the other protocols, which [`Node::sdo_request`] then serves.
    pub(super) fn block_request(&mut self, now_us: u64, d: &[u8], cob: u16, tx: &mut impl FnMut(CanFrame)) -> bool {
        let b0 = d.first().copied().unwrap_or(0);
        if let Transfer::BlockDownload(st) = self.transfer {
            if !st.ending {
                // Sub-block: every frame is a segment (its byte 0 is c | seqno); the client's
                // abort (0x80: c with the invalid seqno 0) ends it.
                if b0 == 0x80 {
                    self.transfer = Transfer::Idle;
                } else if d.len() != 8 {
                    self.dropped = self.dropped.saturating_add(1);
                } else {
                    self.block_segment(now_us, st, d, cob, tx);
                }
                return true;
            }
        }
        if d.len() != 8 {
            return false;
        }
        let index = u16::from_le_bytes([d.get(1).copied().unwrap_or(0), d.get(2).copied().unwrap_or(0)]);
        let sub = d.get(3).copied().unwrap_or(0);
        // an abort names the object of the transfer it ends (end frames carry no index)
        let (ai, asub, _) = match self.transfer {
            Transfer::BlockDownload(st) if b0 & 0x03 != 0 => st.timer(),
            Transfer::BlockUpload(st) if b0 & 0x03 != 0 => st.timer(),
            _ => (index, sub, 0),
        };
        let r = match b0 >> 5 {
            sdo::CCS_BLOCK_DOWNLOAD => match self.transfer {
                Transfer::BlockDownload(st) if b0 & 0x01 == 1 => self.block_download_end(st, b0, d),
                _ if b0 & 0x01 == 0 => self.block_download_init(now_us, index, sub, b0, d),
                _ => Err(Abort::Command),
            },
            sdo::CCS_BLOCK_UPLOAD => self.block_upload_request(now_us, index, sub, b0, d),
            _ => return false,
        };
        match r {
            Ok(Some(p)) => resp(cob, p, tx),
            Ok(None) => {}
            Err(a) => {
                self.transfer = Transfer::Idle;
                resp(cob, sdo::abort_payload(ai, asub, a), tx);
            }
        }
        true
    }

    fn block_download_init(
        &mut self,
        now_us: u64,
        index: u16,
        sub: u8,
        cmd: u8,
        d: &[u8],
    ) -> Result<Option<[u8; 8]>, Abort> {
        self.transfer = Transfer::Idle;
        let info = od::sub_info(index, sub)?;
        if !info.access.writable() {
            return Err(Abort::ReadOnly);
        }
        let expected = if cmd & 0x02 != 0 { Some(le_u32(d.get(4..8).unwrap_or(&[])) as usize) } else { None };
        if let Some(n) = expected {
            super::check_len(&info, n)?;
        }
        let crc = cmd & 0x04 != 0;
        self.transfer = Transfer::BlockDownload(Down {
            info,
            crc,
            base: 0,
            seq: 0,
            last: false,
            ending: false,
            expected,
            last_us: now_us,
        });
        let i = index.to_le_bytes();
        // scs 5, sc: the node checks a CRC whenever the client sends one
        Ok(Some([0xA4, i[0], i[1], sub, DOWNLOAD_BLOCK, 0, 0, 0]))
    }

    /// One segment of a download sub-block. In order, it lands in the buffer; out of order
    /// (one was lost, or a repeat), it is dropped. The block ends, and is acknowledged with
    /// the last in-order segment, at seqno = block size or at the client's last segment.
    fn block_segment(&mut self, now_us: u64, mut st: Down, d: &[u8], cob: u16, tx: &mut impl FnMut(CanFrame)) {
        let b0 = d.first().copied().unwrap_or(0);
        let seqno = b0 & 0x7F;
        let c = b0 & 0x80 != 0;
        st.last_us = now_us;
        if !st.last && seqno == st.seq.wrapping_add(1) {
            let off = st.base + 7 * (seqno as usize - 1);
            // A segment starting past the object's room carries at least one byte too many.
            // (an announced size is at most the object's, which is at most the buffer)
            let room = st.expected.unwrap_or(SDO_BUFFER);
            if off >= room {
                self.transfer = Transfer::Idle;
                resp(cob, sdo::abort_payload(st.info.index, st.info.sub, Abort::TooLong), tx);
                return;
            }
            // the last segment's padding past the buffer is not kept
            let end = (off + 7).min(super::SDO_BUFFER);
            if let (Some(dst), Some(src)) = (self.sdo_buf().get_mut(off..end), d.get(1..1 + end - off)) {
                dst.copy_from_slice(src);
            }
            st.seq = seqno;
            st.last = c;
        }
        if c || seqno >= DOWNLOAD_BLOCK {
            resp(cob, [0xA2, st.seq, DOWNLOAD_BLOCK, 0, 0, 0, 0, 0], tx);
            st.base += 7 * st.seq as usize;
            st.seq = 0;
            st.ending = st.last;
        }
        self.transfer = Transfer::BlockDownload(st);
    }

    fn block_download_end(&mut self, st: Down, cmd: u8, d: &[u8]) -> Result<Option<[u8; 8]>, Abort> {
        self.transfer = Transfer::Idle;
        let n = ((cmd >> 2) & 0x07) as usize;
        let len = st.base.checked_sub(n).ok_or(Abort::TypeLength)?;
        if st.expected.is_some_and(|e| e != len) {
            return Err(Abort::TypeLength);
        }
        let data = self.sdo_buf().get(..len).ok_or(Abort::TooLong)?;
        if st.crc
            && sdo::crc16(data) != u16::from_le_bytes([d.get(1).copied().unwrap_or(0), d.get(2).copied().unwrap_or(0)])
        {
            return Err(Abort::Crc);
        }
        self.write_from_buf(&st.info, len)?;
        Ok(Some([0xA1, 0, 0, 0, 0, 0, 0, 0]))
    }

    fn block_upload_request(
        &mut self,
        now_us: u64,
        index: u16,
        sub: u8,
        cmd: u8,
        d: &[u8],
    ) -> Result<Option<[u8; 8]>, Abort> {
        let cs = cmd & 0x03;
        if cs == 0 {
            return self.block_upload_init(now_us, index, sub, cmd, d);
        }
        let Transfer::BlockUpload(mut st) = self.transfer else {
            return Err(Abort::Command);
        };
        st.last_us = now_us;
        match (cs, st.phase) {
            (3, UpPhase::Initiated) => st.phase = UpPhase::Sending,
            (2, UpPhase::Sending | UpPhase::WaitAck) => {
                let ackseq = d.get(1).copied().unwrap_or(0);
                let blksize = d.get(2).copied().unwrap_or(0);
                if ackseq > st.sent {
                    return Err(Abort::SeqNo);
                }
                if blksize == 0 || blksize > BLOCK_SEGMENTS_MAX {
                    return Err(Abort::BlockSize);
                }
                st.acked += usize::from(ackseq);
                st.sent = 0;
                st.blksize = blksize;
                if st.acked >= st.segments() {
                    st.phase = UpPhase::End;
                    self.transfer = Transfer::BlockUpload(st);
                    return Ok(Some(self.block_upload_end_frame(&st)));
                }
                st.phase = UpPhase::Sending;
            }
            (1, UpPhase::End) => {
                self.transfer = Transfer::Idle;
                return Ok(None);
            }
            _ => return Err(Abort::Command),
        }
        // the segments go out from `poll`, which `process` runs next: one burst per call
        self.transfer = Transfer::BlockUpload(st);
        Ok(None)
    }

    fn block_upload_init(
        &mut self,
        now_us: u64,
        index: u16,
        sub: u8,
        cmd: u8,
        d: &[u8],
    ) -> Result<Option<[u8; 8]>, Abort> {
        self.transfer = Transfer::Idle;
        let blksize = d.get(4).copied().unwrap_or(0);
        let info = od::sub_info(index, sub)?;
        if !info.access.readable() {
            return Err(Abort::WriteOnly);
        }
        if blksize == 0 || blksize > BLOCK_SEGMENTS_MAX {
            return Err(Abort::BlockSize);
        }
        // the snapshot, byte by byte: no second buffer on the stack
        let total = match self.read_value(&info)? {
            Value::Small(v, n) => {
                if let Some(dst) = self.sdo_buf().get_mut(..4) {
                    dst.copy_from_slice(&v);
                }
                n.min(4)
            }
            Value::Big(b) => {
                let n = self.big_len(b).min(SDO_BUFFER);
                for k in 0..n {
                    let x = self.big_byte(b, k);
                    if let Some(dst) = self.sdo_buf().get_mut(k) {
                        *dst = x;
                    }
                }
                n
            }
        };
        self.transfer = Transfer::BlockUpload(Up {
            index,
            sub,
            crc: cmd & 0x04 != 0,
            total,
            acked: 0,
            sent: 0,
            blksize,
            phase: UpPhase::Initiated,
            last_us: now_us,
        });
        let i = index.to_le_bytes();
        let s = (total as u32).to_le_bytes();
        // scs 6, sc (CRC supported), s (size indicated)
        Ok(Some([0xC6, i[0], i[1], sub, s[0], s[1], s[2], s[3]]))
    }

    fn block_upload_end_frame(&mut self, st: &Up) -> [u8; 8] {
        // bytes of the last segment that carry no data (7 for an empty object)
        let n = (st.segments() * 7 - st.total) as u8;
        let crc = if st.crc { sdo::crc16(self.sdo_buf().get(..st.total).unwrap_or(&[])) } else { 0 };
        let c = crc.to_le_bytes();
        [0xC1 | (n << 2), c[0], c[1], 0, 0, 0, 0, 0]
    }

    /// Send the next segments of the block being uploaded, at most [`UPLOAD_BURST`].
    pub(super) fn block_pump(&mut self, cob: u16, tx: &mut impl FnMut(CanFrame)) {
        let Transfer::BlockUpload(mut st) = self.transfer else {
            return;
        };
        let mut burst = 0;
        while st.phase == UpPhase::Sending && burst < UPLOAD_BURST {
            let seg = st.acked + usize::from(st.sent);
            let last = seg + 1 >= st.segments();
            let mut p = [0u8; 8];
            st.sent += 1;
            p[0] = st.sent | if last { 0x80 } else { 0 };
            let data = self.sdo_buf().get(seg * 7..st.total.min(seg * 7 + 7)).unwrap_or(&[]);
            for (x, b) in p.iter_mut().skip(1).zip(data) {
                *x = *b;
            }
            resp(cob, p, tx);
            burst += 1;
            if last || st.sent >= st.blksize {
                st.phase = UpPhase::WaitAck;
            }
        }
        self.transfer = Transfer::BlockUpload(st);
    }
}
