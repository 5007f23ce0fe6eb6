//! The second SDO server channel (0x1201): not valid until a master configures it, then its
//! own transfer and its own buffer, so two masters' interleaved transfers complete
//! independently, never mixed; 0x1200 describes the default channel.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, NMT_RESET_COMMUNICATION};
use joint_core::canopen::CanFrame;

const ID: u8 = 5;
const RX1: u16 = 0x605;
const TX1: u16 = 0x585;
const RX2: u16 = 0x640;
const TX2: u16 = 0x5C0;

struct Bench {
    node: Node<MemoryStorage>,
    now: u64,
}

impl Bench {
    fn new() -> Bench {
        let mut b = Bench { node: Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0), now: 0 };
        b.node.process(0, None, &mut |_| {});
        b
    }

    /// Send one frame; the SDO responses as (COB-ID, bytes).
    fn run(&mut self, id: u16, d: &[u8]) -> Vec<(u16, Vec<u8>)> {
        let mut out = Vec::new();
        let f = CanFrame::new(id, d).unwrap();
        self.node.process(self.now, Some(&f), &mut |f: CanFrame| out.push(f));
        out.into_iter().filter(|f| (0x580..0x600).contains(&f.id())).map(|f| (f.id(), f.data().to_vec())).collect()
    }

    /// One request on channel `rx`, exactly one response on `tx`.
    fn sdo(&mut self, rx: u16, tx: u16, d: [u8; 8]) -> Vec<u8> {
        let r = self.run(rx, &d);
        assert_eq!(r.len(), 1, "one answer to {d:02X?}: {r:02X?}");
        assert_eq!(r[0].0, tx, "answered on the request's channel");
        r[0].1.clone()
    }

    fn write_u32(&mut self, index: u16, sub: u8, v: u32) -> Vec<u8> {
        let i = index.to_le_bytes();
        let b = v.to_le_bytes();
        self.sdo(RX1, TX1, [0x23, i[0], i[1], sub, b[0], b[1], b[2], b[3]])
    }

    fn read_u32(&mut self, rx: u16, tx: u16, index: u16, sub: u8) -> u32 {
        let i = index.to_le_bytes();
        let r = self.sdo(rx, tx, [0x40, i[0], i[1], sub, 0, 0, 0, 0]);
        assert_eq!(r[0] & 0xE3, 0x43, "expedited upload: {r:02X?}");
        u32::from_le_bytes([r[4], r[5], r[6], r[7]])
    }

    fn configure(&mut self) {
        assert_eq!(self.write_u32(0x1201, 1, u32::from(RX2))[0], 0x60);
        assert_eq!(self.write_u32(0x1201, 2, u32::from(TX2))[0], 0x60);
        assert_eq!(self.sdo(RX1, TX1, [0x2F, 0x01, 0x12, 3, 0x10, 0, 0, 0])[0], 0x60);
    }
}

fn ok_abort(r: &[u8], code: u32) {
    assert_eq!(r[0], 0x80, "abort: {r:02X?}");
    assert_eq!(u32::from_le_bytes([r[4], r[5], r[6], r[7]]), code);
}

#[test]
fn the_second_channel_is_not_valid_until_configured() {
    let mut b = Bench::new();
    assert_eq!(b.read_u32(RX1, TX1, 0x1200, 1), 0x605);
    assert_eq!(b.read_u32(RX1, TX1, 0x1200, 2), 0x585);
    assert_eq!(b.read_u32(RX1, TX1, 0x1201, 1), 0x8000_0000);
    assert_eq!(b.read_u32(RX1, TX1, 0x1201, 2), 0x8000_0000);
    // the default channel's COB-IDs are fixed
    ok_abort(&b.write_u32(0x1200, 1, 0x610), 0x0601_0002);
    // nothing answers on 0x640 yet
    assert!(b.run(RX2, &[0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]).is_empty());
    b.configure();
    assert_eq!(b.read_u32(RX2, TX2, 0x1018, 2), 0x4A4E_0001);
    assert_eq!(b.read_u32(RX2, TX2, 0x1201, 3) & 0xFF, 0x10);
    // a valid COB-ID's id cannot change; not valid first, then it can
    ok_abort(&b.write_u32(0x1201, 1, 0x641), 0x0609_0030);
    assert_eq!(b.write_u32(0x1201, 1, 0x8000_0641)[0], 0x60);
    assert!(b.run(RX2, &[0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]).is_empty(), "not valid: silent");
    assert_eq!(b.write_u32(0x1201, 1, 0x641)[0], 0x60);
    assert_eq!(b.read_u32(0x641, TX2, 0x1018, 2), 0x4A4E_0001);
    // the default channel's ids, extended frames and id 0 are refused
    assert_eq!(b.write_u32(0x1201, 1, 0x8000_0000)[0], 0x60);
    ok_abort(&b.write_u32(0x1201, 1, 0x605), 0x0609_0030);
    ok_abort(&b.write_u32(0x1201, 1, 0x2000_0640), 0x0609_0030);
    ok_abort(&b.write_u32(0x1201, 1, 0), 0x0609_0030);
    // reset communication: not valid again
    b.write_u32(0x1201, 1, u32::from(RX2));
    b.run(0x000, &[NMT_RESET_COMMUNICATION, ID]);
    b.run(0x000, &[0x80, ID]);
    assert_eq!(b.read_u32(RX1, TX1, 0x1201, 1), 0x8000_0000);
    assert!(b.run(RX2, &[0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]).is_empty());
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A segmented download of `data` to `index` as (request, channel, expected answer) steps, so
/// two can be interleaved frame by frame.
fn segmented_steps(rx: u16, index: u16, data: Vec<u8>) -> Vec<([u8; 8], u16, Vec<u8>)> {
    let i = index.to_le_bytes();
    let s = (data.len() as u32).to_le_bytes();
    let mut steps = vec![([0x21, i[0], i[1], 0, s[0], s[1], s[2], s[3]], rx, vec![0x60, i[0], i[1], 0, 0, 0, 0, 0])];
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (k, c) in chunks.iter().enumerate() {
        let t = (k as u8 & 1) << 4;
        let last = k + 1 == chunks.len();
        let mut p = [0u8; 8];
        p[0] = t | (((7 - c.len()) as u8) << 1) | u8::from(last);
        p[1..1 + c.len()].copy_from_slice(c);
        steps.push((p, rx, vec![0x20 | t, 0, 0, 0, 0, 0, 0, 0]));
    }
    steps
}

#[test]
fn interleaved_downloads_on_the_two_channels_complete_independently() {
    let mut b = Bench::new();
    b.configure();
    let torque: Vec<f32> = (0..9).map(|k| k as f32 - 4.0).collect();
    let sigma: Vec<f32> = (0..9).map(|k| 0.1 * k as f32).collect();
    let a = segmented_steps(RX1, 0x2102, f32s(&torque));
    let c = segmented_steps(RX2, 0x2103, f32s(&sigma));
    assert_eq!(a.len(), c.len());
    // frame by frame, alternating: a master on each channel, each with its own buffer,
    // neither waiting for the other nor seeing its segments
    for (x, y) in a.iter().zip(c.iter()) {
        assert_eq!(b.sdo(x.1, TX1, x.0), x.2);
        assert_eq!(b.sdo(y.1, TX2, y.0), y.2);
    }
    assert_eq!(&b.node.staged().table.torque[..9], &torque[..]);
    assert_eq!(&b.node.staged().table.sigma[..9], &sigma[..]);
}

#[test]
fn a_segmented_upload_on_one_channel_through_a_download_on_the_other() {
    let mut b = Bench::new();
    b.configure();
    let torque: Vec<f32> = (0..9).map(|k| k as f32 * 0.5).collect();
    let steps = segmented_steps(RX1, 0x2102, f32s(&torque));
    // channel 2 reads the device name (10 bytes: "joint-node") segment by segment meanwhile
    let mut name = Vec::new();
    let r = b.sdo(RX2, TX2, [0x40, 0x08, 0x10, 0, 0, 0, 0, 0]);
    assert_eq!(r[0], 0x41);
    let total = r[4] as usize;
    let mut toggle = 0u8;
    for s in &steps {
        assert_eq!(b.sdo(s.1, TX1, s.0), s.2);
        if name.len() < total {
            let r = b.sdo(RX2, TX2, [0x60 | toggle, 0, 0, 0, 0, 0, 0, 0]);
            assert_eq!(r[0] & 0x10, toggle);
            let n = 7 - ((r[0] >> 1) & 7) as usize;
            name.extend_from_slice(&r[1..1 + n]);
            toggle ^= 0x10;
        }
    }
    assert_eq!(name, b"joint-node");
    assert_eq!(&b.node.staged().table.torque[..9], &torque[..]);
}

#[test]
fn a_stalled_transfer_times_out_on_its_own_channel_only() {
    let mut b = Bench::new();
    b.configure();
    // channel 2 starts a download and goes quiet; channel 1 keeps working
    assert_eq!(b.sdo(RX2, TX2, [0x21, 0x02, 0x21, 0, 36, 0, 0, 0])[0], 0x60);
    b.now += 600_000;
    assert_eq!(b.read_u32(RX1, TX1, 0x1018, 2), 0x4A4E_0001);
    b.now += 600_000;
    let mut out = Vec::new();
    b.node.process(b.now, None, &mut |f: CanFrame| out.push(f));
    let sdo: Vec<_> = out.iter().filter(|f| (0x580..0x600).contains(&f.id())).collect();
    assert_eq!(sdo.len(), 1);
    assert_eq!(sdo[0].id(), TX2);
    assert_eq!(sdo[0].data(), &[0x80, 0x02, 0x21, 0x00, 0x00, 0x00, 0x04, 0x05]);
}

#[test]
fn a_block_download_on_the_second_channel_with_requests_on_the_first_in_between() {
    let mut b = Bench::new();
    b.configure();
    let torque: Vec<f32> = (0..9).map(|k| 2.0 - k as f32).collect();
    let data = f32s(&torque);
    assert_eq!(b.sdo(RX2, TX2, [0xC2, 0x02, 0x21, 0, 36, 0, 0, 0])[0], 0xA4);
    for (k, c) in data.chunks(7).enumerate() {
        // a read on the default channel between the segments is not a segment of this block
        assert_eq!(b.read_u32(RX1, TX1, 0x1018, 2), 0x4A4E_0001);
        let mut p = [0u8; 8];
        p[0] = (k as u8 + 1) | if k == 5 { 0x80 } else { 0 };
        p[1..1 + c.len()].copy_from_slice(c);
        let r = b.run(RX2, &p);
        if k == 5 {
            assert_eq!(r, vec![(TX2, vec![0xA2, 6, 127, 0, 0, 0, 0, 0])]);
        } else {
            assert!(r.is_empty());
        }
    }
    assert_eq!(b.sdo(RX2, TX2, [0xC1 | (6 << 2), 0, 0, 0, 0, 0, 0, 0]), vec![0xA1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(&b.node.staged().table.torque[..9], &torque[..]);
}
