//! SDO block transfer of the CANopen node (CiA 301 §7.2.4.3.9 ff.): golden frames of a block
//! download and upload with CRC, a lost segment in each direction, a wrong CRC that leaves the
//! old value in force, the aborts (block size, timeout, length), and a property run of random
//! frames after which a clean block transfer still works.
//!
//! The client side here is written from the standard, not from the node's code; the CRC too
//! (checked against the CRC-16/XMODEM check value of "123456789", 0x31C3).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig};
use joint_core::canopen::sdo;
use joint_core::canopen::CanFrame;
use proptest::prelude::*;

const ID: u8 = 5;
const RX: u16 = 0x605;
const TX: u16 = 0x585;
const TORQUE: u16 = 0x2102;

/// CRC-16 CCITT (x¹⁶+x¹²+x⁵+1), initial 0, over the message bits one by one (long division).
fn crc_ref(data: &[u8]) -> u16 {
    let mut reg: u32 = 0;
    for &b in data {
        for k in (0..8).rev() {
            let top = (reg >> 15) & 1;
            let bit = u32::from((b >> k) & 1);
            reg = ((reg << 1) & 0xFFFF) ^ if (top ^ bit) == 1 { 0x1021 } else { 0 };
        }
    }
    reg as u16
}

#[test]
fn the_crc_is_ccitt_xmodem() {
    assert_eq!(crc_ref(b"123456789"), 0x31C3);
    assert_eq!(sdo::crc16(b"123456789"), 0x31C3);
    assert_eq!(sdo::crc16(&[]), 0);
}

struct Bench {
    node: Node<MemoryStorage>,
    now: u64,
}

impl Bench {
    fn new() -> Bench {
        let mut b = Bench { node: Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0), now: 0 };
        b.poll(0); // boot-up
        b
    }

    /// Send one frame, return the SDO responses (other traffic filtered out).
    fn run(&mut self, id: u16, d: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        let f = CanFrame::new(id, d).unwrap();
        self.node.process(self.now, Some(&f), &mut |f: CanFrame| out.push(f));
        out.into_iter().filter(|f| f.id() == TX).map(|f| f.data().to_vec()).collect()
    }

    fn sdo(&mut self, d: [u8; 8]) -> Vec<Vec<u8>> {
        self.run(RX, &d)
    }

    /// Timers only: the SDO frames they send (upload bursts, timeouts).
    fn poll(&mut self, ms: u64) -> Vec<Vec<u8>> {
        self.now += ms * 1000;
        let mut out = Vec::new();
        self.node.process(self.now, None, &mut |f: CanFrame| out.push(f));
        out.into_iter().filter(|f| f.id() == TX).map(|f| f.data().to_vec()).collect()
    }

    fn torque_staged(&self, n: usize) -> Vec<f32> {
        self.node.staged().table.torque[..n].to_vec()
    }
}

fn torque_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn seg(seqno: u8, last: bool, chunk: &[u8]) -> [u8; 8] {
    let mut p = [0u8; 8];
    p[0] = seqno | if last { 0x80 } else { 0 };
    p[1..1 + chunk.len()].copy_from_slice(chunk);
    p
}

fn abort(index: u16, sub: u8, code: u32) -> Vec<u8> {
    let i = index.to_le_bytes();
    let c = code.to_le_bytes();
    vec![0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}

fn end_frame(n: usize, crc: u16) -> [u8; 8] {
    let c = crc.to_le_bytes();
    [0xC1 | ((n as u8) << 2), c[0], c[1], 0, 0, 0, 0, 0]
}

/// A complete, correct block download of `data` to 0x2102 (size indicated, CRC), in blocks
/// of whatever the node asks for; asserts every response.
fn download(b: &mut Bench, data: &[u8]) {
    let s = (data.len() as u32).to_le_bytes();
    let r = b.sdo([0xC6, 0x02, 0x21, 0x00, s[0], s[1], s[2], s[3]]);
    assert_eq!(r.len(), 1);
    assert_eq!(r[0][..4], [0xA4, 0x02, 0x21, 0x00]);
    let blksize = r[0][4] as usize;
    assert!((1..=127).contains(&blksize));
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (k, c) in chunks.iter().enumerate() {
        let last = k + 1 == chunks.len();
        let r = b.sdo(seg((k % blksize) as u8 + 1, last, c));
        if last || (k + 1) % blksize == 0 {
            assert_eq!(r, vec![vec![0xA2, (k % blksize) as u8 + 1, 127, 0, 0, 0, 0, 0]]);
        } else {
            assert!(r.is_empty(), "no answer inside a block: {r:02X?}");
        }
    }
    let n = chunks.len() * 7 - data.len();
    assert_eq!(b.sdo(end_frame(n, crc_ref(data))), vec![vec![0xA1, 0, 0, 0, 0, 0, 0, 0]]);
}

#[test]
fn golden_block_download_with_crc() {
    let mut b = Bench::new();
    let v: Vec<f32> = (0..9).map(|k| 0.5 * k as f32 - 1.0).collect();
    let data = torque_bytes(&v);
    // initiate: ccs 6, cc (CRC), s (size): 36 bytes; the node answers scs 5 with sc, blksize 127
    assert_eq!(b.sdo([0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0]), vec![vec![0xA4, 0x02, 0x21, 0x00, 127, 0, 0, 0]]);
    for k in 0..5u8 {
        assert!(b.sdo(seg(k + 1, false, &data[7 * k as usize..7 * k as usize + 7])).is_empty());
    }
    // 6th segment: c set, 1 byte of data; the block is acknowledged: ackseq 6, next blksize 127
    assert_eq!(b.sdo(seg(6, true, &data[35..])), vec![vec![0xA2, 6, 127, 0, 0, 0, 0, 0]]);
    // end: n = 6 bytes of the last segment unused, CRC over the 36 bytes
    let crc = crc_ref(&data);
    assert_eq!(b.sdo(end_frame(6, crc)), vec![vec![0xA1, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(b.torque_staged(9), v);
}

#[test]
fn golden_block_upload_with_crc_in_two_blocks() {
    let mut b = Bench::new();
    let v: Vec<f32> = (0..9).map(|k| 0.25 * k as f32).collect();
    let data = torque_bytes(&v);
    download(&mut b, &data);
    // the upload length follows the table's shape: 1 axis of 9 points
    b.node.write(0x2100, 1, &[1]).unwrap();
    b.node.write(0x2100, 6, &[9]).unwrap();
    // initiate: ccs 5, cc, blksize 4, pst 0 → scs 6 with sc and s, size 36
    assert_eq!(b.sdo([0xA4, 0x02, 0x21, 0x00, 4, 0, 0, 0]), vec![vec![0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0]]);
    // start → the first block: segments 1..=4
    let r = b.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    let want: Vec<Vec<u8>> = (0..4).map(|k| seg(k as u8 + 1, false, &data[7 * k..7 * k + 7]).to_vec()).collect();
    assert_eq!(r, want);
    // ack 4, blksize 127 → the rest: seqno restarts at 1, the last (c) carries 1 byte
    let r = b.sdo([0xA2, 4, 127, 0, 0, 0, 0, 0]);
    assert_eq!(r, vec![seg(1, false, &data[28..35]).to_vec(), seg(2, true, &data[35..36]).to_vec()]);
    // ack 2 → end: n = 6, CRC
    let r = b.sdo([0xA2, 2, 127, 0, 0, 0, 0, 0]);
    assert_eq!(r, vec![end_frame(6, crc_ref(&data)).to_vec()]);
    // client end: no answer, the server is idle again (a segmented upload works at once)
    assert!(b.sdo([0xA1, 0, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.sdo([0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0])[0][0], 0x43);
}

#[test]
fn a_small_object_uploads_in_block_mode_too() {
    let mut b = Bench::new();
    // 0x1018 sub 2, product code: 4 bytes in one segment, n = 3
    let r = b.sdo([0xA4, 0x18, 0x10, 0x02, 127, 0, 0, 0]);
    assert_eq!(r, vec![vec![0xC6, 0x18, 0x10, 0x02, 4, 0, 0, 0]]);
    let r = b.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    let pc = 0x4A4E_0001u32.to_le_bytes();
    assert_eq!(r, vec![vec![0x81, pc[0], pc[1], pc[2], pc[3], 0, 0, 0]]);
    assert_eq!(b.sdo([0xA2, 1, 127, 0, 0, 0, 0, 0]), vec![end_frame(3, crc_ref(&pc)).to_vec()]);
    assert!(b.sdo([0xA1, 0, 0, 0, 0, 0, 0, 0]).is_empty());
}

#[test]
fn a_lost_download_segment_is_retransmitted_from_the_last_acknowledged() {
    let mut b = Bench::new();
    let v: Vec<f32> = (0..9).map(|k| 3.0 - k as f32).collect();
    let data = torque_bytes(&v);
    let c: Vec<&[u8]> = data.chunks(7).collect();
    assert_eq!(b.sdo([0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0])[0][0], 0xA4);
    assert!(b.sdo(seg(1, false, c[0])).is_empty());
    assert!(b.sdo(seg(2, false, c[1])).is_empty());
    // segment 3 lost on the bus; 4 and 5 arrive out of sequence and are dropped
    assert!(b.sdo(seg(4, false, c[3])).is_empty());
    assert!(b.sdo(seg(5, false, c[4])).is_empty());
    // the last one: acknowledged with 2, the last segment received in order
    assert_eq!(b.sdo(seg(6, true, c[5])), vec![vec![0xA2, 2, 127, 0, 0, 0, 0, 0]]);
    // the client starts the next block at segment 3, numbered 1
    for (k, chunk) in c.iter().enumerate().take(5).skip(2) {
        assert!(b.sdo(seg(k as u8 - 1, false, chunk)).is_empty());
    }
    assert_eq!(b.sdo(seg(4, true, c[5])), vec![vec![0xA2, 4, 127, 0, 0, 0, 0, 0]]);
    assert_eq!(b.sdo(end_frame(6, crc_ref(&data))), vec![vec![0xA1, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(b.torque_staged(9), v);
}

#[test]
fn a_lost_upload_segment_is_sent_again() {
    let mut b = Bench::new();
    let v: Vec<f32> = (0..9).map(|k| k as f32 * 1.5).collect();
    let data = torque_bytes(&v);
    download(&mut b, &data);
    b.node.write(0x2100, 1, &[1]).unwrap();
    b.node.write(0x2100, 6, &[9]).unwrap();
    assert_eq!(b.sdo([0xA4, 0x02, 0x21, 0x00, 127, 0, 0, 0])[0][0], 0xC6);
    let r = b.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(r.len(), 6, "the whole object in one block: {r:02X?}");
    // the client lost the 3rd: acknowledges 2, the node resends from the 3rd, numbered 1
    let r = b.sdo([0xA2, 2, 127, 0, 0, 0, 0, 0]);
    assert_eq!(r.len(), 4);
    assert_eq!(r[0], seg(1, false, &data[14..21]).to_vec());
    assert_eq!(r[3], seg(4, true, &data[35..36]).to_vec());
    // acknowledging more than was sent is a sequence error
    assert_eq!(b.sdo([0xA2, 5, 127, 0, 0, 0, 0, 0]), vec![abort(TORQUE, 0, 0x0504_0003)]);
}

#[test]
fn a_wrong_crc_is_refused_and_the_old_value_stays() {
    let mut b = Bench::new();
    let old: Vec<f32> = (0..9).map(|k| k as f32).collect();
    download(&mut b, &torque_bytes(&old));
    let new: Vec<f32> = (0..9).map(|k| -(k as f32)).collect();
    let data = torque_bytes(&new);
    b.sdo([0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0]);
    for (k, c) in data.chunks(7).enumerate() {
        b.sdo(seg(k as u8 + 1, k == 5, c));
    }
    let r = b.sdo(end_frame(6, crc_ref(&data) ^ 0x0100));
    assert_eq!(r, vec![abort(TORQUE, 0, 0x0504_0004)]);
    assert_eq!(b.torque_staged(9), old);
    // without CRC (cc clear) the same end frame is taken as it is
    b.sdo([0xC2, 0x02, 0x21, 0x00, 36, 0, 0, 0]);
    for (k, c) in data.chunks(7).enumerate() {
        b.sdo(seg(k as u8 + 1, k == 5, c));
    }
    assert_eq!(b.sdo(end_frame(6, 0xDEAD)), vec![vec![0xA1, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(b.torque_staged(9), new);
}

#[test]
fn block_aborts_block_size_length_and_timeout() {
    let mut b = Bench::new();
    // upload block size 0 or 128: 0x05040002
    assert_eq!(b.sdo([0xA4, 0x02, 0x21, 0x00, 0, 0, 0, 0]), vec![abort(TORQUE, 0, 0x0504_0002)]);
    assert_eq!(b.sdo([0xA4, 0x02, 0x21, 0x00, 128, 0, 0, 0]), vec![abort(TORQUE, 0, 0x0504_0002)]);
    // a download announcing more than the object holds: 0x06070012
    assert_eq!(b.sdo([0xC6, 0x02, 0x21, 0x00, 0x04, 0x02, 0, 0]), vec![abort(TORQUE, 0, 0x0607_0012)]);
    // more data than announced: refused at the segment that starts past it
    b.sdo([0xC6, 0x02, 0x21, 0x00, 8, 0, 0, 0]);
    assert!(b.sdo(seg(1, false, &[0; 7])).is_empty());
    assert!(b.sdo(seg(2, false, &[0; 7])).is_empty(), "byte 8 and padding");
    assert_eq!(b.sdo(seg(3, false, &[0; 7])), vec![abort(TORQUE, 0, 0x0607_0012)]);
    // fewer bytes than announced (n = 6 of the 2nd segment's 7 unused: 8 bytes, not 12)
    b.sdo([0xC6, 0x02, 0x21, 0x00, 12, 0, 0, 0]);
    b.sdo(seg(1, false, &[0; 7]));
    assert_eq!(b.sdo(seg(2, true, &[0; 1])), vec![vec![0xA2, 2, 127, 0, 0, 0, 0, 0]]);
    assert_eq!(b.sdo(end_frame(6, 0)), vec![abort(TORQUE, 0, 0x0607_0010)]);
    // a read-only object is refused at initiate; a write-only one for upload
    assert_eq!(b.sdo([0xC6, 0x18, 0x10, 0x01, 4, 0, 0, 0]), vec![abort(0x1018, 1, 0x0601_0002)]);
    assert_eq!(b.sdo([0xA4, 0x00, 0x22, 0x00, 127, 0, 0, 0]), vec![abort(0x2200, 0, 0x0601_0001)]);
    // a client that goes quiet mid-block: 0x05040000 after the SDO timeout, then idle
    b.sdo([0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0]);
    b.sdo(seg(1, false, &[0; 7]));
    assert!(b.poll(900).is_empty());
    assert_eq!(b.poll(200), vec![abort(TORQUE, 0, 0x0504_0000)]);
    // an upload whose client never acknowledges: the same
    b.sdo([0xA4, 0x18, 0x10, 0x02, 127, 0, 0, 0]);
    b.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(b.poll(1100), vec![abort(0x1018, 2, 0x0504_0000)]);
    // the client's abort inside a sub-block ends it silently
    b.sdo([0xC6, 0x02, 0x21, 0x00, 36, 0, 0, 0]);
    assert!(b.sdo([0x80, 0x02, 0x21, 0x00, 0, 0, 0x04, 0x05]).is_empty());
    assert!(b.poll(1100).is_empty());
}

#[test]
fn a_long_upload_goes_out_in_bursts_the_outbox_can_hold() {
    let mut b = Bench::new();
    let v: Vec<f32> = (0..128).map(|k| k as f32).collect();
    download(&mut b, &torque_bytes(&v));
    b.node.write(0x2100, 1, &[2]).unwrap();
    b.node.write(0x2100, 6, &[16]).unwrap();
    b.node.write(0x2100, 7, &[8]).unwrap();
    assert_eq!(b.sdo([0xA4, 0x02, 0x21, 0x00, 127, 0, 0, 0])[0][..6], [0xC6, 0x02, 0x21, 0x00, 0x00, 0x02]);
    let mut got = b.sdo([0xA3, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(got.len(), 8, "at most 8 segments per call");
    while got.len() < 74 {
        let r = b.poll(1);
        assert!(!r.is_empty() && r.len() <= 8);
        got.extend(r);
    }
    assert_eq!(got.len(), 74);
    let bytes: Vec<u8> = got.iter().flat_map(|s| s[1..].to_vec()).take(512).collect();
    assert_eq!(bytes, torque_bytes(&v));
    assert_eq!(got[73][0], 0x80 | 74);
    assert_eq!(b.sdo([0xA2, 74, 127, 0, 0, 0, 0, 0]), vec![end_frame(74 * 7 - 512, crc_ref(&bytes)).to_vec()]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Random block-protocol frames (initiates, segments, acks, ends with random fields) never
    /// panic the node and never change the staged torques except by a complete, CRC-checked
    /// download; afterwards an abort and a clean transfer work.
    #[test]
    fn random_block_frames_then_a_clean_transfer(frames in proptest::collection::vec(
        (prop_oneof![Just(0xC0u8), Just(0xC2), Just(0xC4), Just(0xC6), Just(0xC1), Just(0xA0), Just(0xA4),
                     Just(0xA1), Just(0xA2), Just(0xA3), 0u8..=255], any::<[u8; 7]>(), 0u64..3),
        0..60)) {
        let mut b = Bench::new();
        let old: Vec<f32> = (0..128).map(|k| k as f32 * 0.5).collect();
        download(&mut b, &torque_bytes(&old));
        for (b0, rest, ms) in frames {
            let mut d = [0u8; 8];
            d[0] = b0;
            d[1..].copy_from_slice(&rest);
            // keep to the torque object so a random expedited write cannot touch the rest
            if b0 >> 5 != 0 && b0 != 0x80 {
                d[1] = 0x02;
                d[2] = 0x21;
                d[3] = 0;
            }
            for r in b.run(RX, &d) {
                prop_assert_eq!(r.len(), 8);
            }
            b.poll(ms);
            let now = b.torque_staged(128);
            prop_assert!(now == old || now.iter().all(|x| x.is_finite()));
        }
        b.sdo([0x80, 0x02, 0x21, 0x00, 0, 0, 0, 0]);
        let v: Vec<f32> = (0..128).map(|k| -(k as f32)).collect();
        download(&mut b, &torque_bytes(&v));
        prop_assert_eq!(b.torque_staged(128), v);
    }
}
