//! LSS slave of the CANopen node (CiA 305): golden frames of every service, an unconfigured
//! node that stays silent until fast scan finds it and it is given an id, storing the id so
//! it survives reset node and a power cycle, and random LSS frames.
//!
//! The fast scan master here follows CiA 305 §8.4.1 (as python-canopen's does): one bit at a
//! time from the top, a missing answer means the bit is 1.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::lss::{LssConfig, LssMode, UNCONFIGURED};
use joint_core::canopen::node::{Identity, MemoryStorage, NmtState, Node, NodeConfig, NMT_RESET_NODE};
use joint_core::canopen::CanFrame;
use proptest::prelude::*;

const MASTER: u16 = 0x7E5;
const SLAVE: u16 = 0x7E4;

fn cfg(id: u8, serial: u32) -> NodeConfig {
    let mut c = NodeConfig::new(id);
    c.identity.serial = serial;
    c
}

struct Bench {
    node: Node<MemoryStorage>,
    now: u64,
}

impl Bench {
    fn new(c: NodeConfig, storage: MemoryStorage) -> (Bench, Vec<(u16, Vec<u8>)>) {
        let mut b = Bench { node: Node::new(c, storage, 0), now: 0 };
        let boot = b.tick(0);
        (b, boot)
    }

    fn run(&mut self, id: u16, d: &[u8]) -> Vec<(u16, Vec<u8>)> {
        let mut out = Vec::new();
        let f = CanFrame::new(id, d).unwrap();
        self.node.process(self.now, Some(&f), &mut |f: CanFrame| out.push((f.id(), f.data().to_vec())));
        out
    }

    fn tick(&mut self, ms: u64) -> Vec<(u16, Vec<u8>)> {
        self.now += ms * 1000;
        let mut out = Vec::new();
        self.node.process(self.now, None, &mut |f: CanFrame| out.push((f.id(), f.data().to_vec())));
        out
    }

    /// An LSS request; the LSS answers only.
    fn lss(&mut self, d: [u8; 8]) -> Vec<Vec<u8>> {
        self.run(MASTER, &d).into_iter().filter(|(i, _)| *i == SLAVE).map(|(_, d)| d).collect()
    }

    fn lss_word(&mut self, cs: u8, v: u32) -> Vec<Vec<u8>> {
        let b = v.to_le_bytes();
        self.lss([cs, b[0], b[1], b[2], b[3], 0, 0, 0])
    }
}

fn answer(cs: u8, b1: u8) -> Vec<Vec<u8>> {
    vec![vec![cs, b1, 0, 0, 0, 0, 0, 0]]
}

#[test]
fn golden_switch_state_configure_inquire_and_store() {
    let (mut b, boot) = Bench::new(cfg(5, 0x1234), MemoryStorage::default());
    assert_eq!(boot, vec![(0x705, vec![0])]);
    let ident = b.node.config().identity;
    // configuration services are ignored in the waiting state
    assert!(b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0]).is_empty());
    // switch state global: configuration (no answer)
    assert!(b.lss([0x04, 0x01, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.lss().mode, LssMode::Configuration);
    // inquire node id and identity
    assert_eq!(b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0]), answer(0x5E, 5));
    let pc = ident.product_code.to_le_bytes();
    assert_eq!(b.lss([0x5B, 0, 0, 0, 0, 0, 0, 0]), vec![vec![0x5B, pc[0], pc[1], pc[2], pc[3], 0, 0, 0]]);
    assert_eq!(b.lss([0x5D, 0, 0, 0, 0, 0, 0, 0]), vec![vec![0x5D, 0x34, 0x12, 0, 0, 0, 0, 0]]);
    // configure node id: 0 and 128 out of range (error 1), 9 accepted
    assert_eq!(b.lss([0x11, 0, 0, 0, 0, 0, 0, 0]), answer(0x11, 1));
    assert_eq!(b.lss([0x11, 128, 0, 0, 0, 0, 0, 0]), answer(0x11, 1));
    assert_eq!(b.lss([0x11, 9, 0, 0, 0, 0, 0, 0]), answer(0x11, 0));
    // still 5 until reset communication; inquire answers the active id
    assert_eq!(b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0]), answer(0x5E, 5));
    // bit timing: table 0 index 0 (1 Mbit/s) yes; 500 kbit/s and another table: error 1
    assert_eq!(b.lss([0x13, 0, 0, 0, 0, 0, 0, 0]), answer(0x13, 0));
    assert_eq!(b.lss([0x13, 0, 2, 0, 0, 0, 0, 0]), answer(0x13, 1));
    assert_eq!(b.lss([0x13, 1, 0, 0, 0, 0, 0, 0]), answer(0x13, 1));
    // activate bit timing: no answer, recorded
    assert!(b.lss([0x15, 0xE8, 0x03, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.lss().activate_ms, Some(1000));
    // store configuration
    assert_eq!(b.lss([0x17, 0, 0, 0, 0, 0, 0, 0]), answer(0x17, 0));
    assert_eq!(b.node.storage().lss, Some(LssConfig { node_id: 9, bit_timing: 0 }));
    // back to waiting: a configured node keeps its id until reset communication
    assert!(b.lss([0x04, 0x00, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.node_id(), 5);
    let out = b.run(0x000, &[0x82, 5]);
    assert_eq!(out, vec![(0x709, vec![0])], "boot-up under the new id");
    assert_eq!(b.node.node_id(), 9);
}

#[test]
fn a_node_without_lss_storage_answers_store_not_supported() {
    let mut n = Node::new(cfg(5, 0), joint_core::canopen::node::NoStorage, 0);
    n.process(0, None, &mut |_| {});
    let mut out = Vec::new();
    for d in [[0x04u8, 1, 0, 0, 0, 0, 0, 0], [0x17, 0, 0, 0, 0, 0, 0, 0]] {
        n.process(0, Some(&CanFrame::new(MASTER, &d).unwrap()), &mut |f: CanFrame| out.push(f));
    }
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].data(), &[0x17, 1, 0, 0, 0, 0, 0, 0]);
}

#[test]
fn switch_state_selective_and_identify_remote_slave() {
    let (mut b, _) = Bench::new(cfg(5, 77), MemoryStorage::default());
    let id = b.node.config().identity;
    // the four parts in turn: 0x44 and configuration
    assert!(b.lss_word(0x40, id.vendor_id).is_empty());
    assert!(b.lss_word(0x41, id.product_code).is_empty());
    assert!(b.lss_word(0x42, id.revision).is_empty());
    assert_eq!(b.lss_word(0x43, 77), answer(0x44, 0));
    assert_eq!(b.node.lss().mode, LssMode::Configuration);
    b.lss([0x04, 0, 0, 0, 0, 0, 0, 0]);
    // a wrong serial: no answer, still waiting
    b.lss_word(0x40, id.vendor_id);
    b.lss_word(0x41, id.product_code);
    b.lss_word(0x42, id.revision);
    assert!(b.lss_word(0x43, 78).is_empty());
    assert_eq!(b.node.lss().mode, LssMode::Waiting);
    // identify remote slave: serial in [70, 80] → 0x4F; in [78, 80] → silence
    for (lo, hi, want) in [(70, 80, answer(0x4F, 0)), (78, 80, vec![])] {
        b.lss_word(0x46, id.vendor_id);
        b.lss_word(0x47, id.product_code);
        b.lss_word(0x48, 0);
        b.lss_word(0x49, u32::MAX);
        b.lss_word(0x4A, lo);
        assert_eq!(b.lss_word(0x4B, hi), want);
    }
    // identify non-configured: this node has an id, so it stays silent
    assert!(b.lss([0x4C, 0, 0, 0, 0, 0, 0, 0]).is_empty());
}

/// Fast scan as a master does it: returns the identity found, or None.
fn fast_scan(b: &mut Bench) -> Option<[u32; 4]> {
    let probe = |b: &mut Bench, id: u32, bit: u8, sub: u8, next: u8| {
        let v = id.to_le_bytes();
        !b.lss([0x51, v[0], v[1], v[2], v[3], bit, sub, next]).is_empty()
    };
    if !probe(b, 0, 0x80, 0, 0) {
        return None;
    }
    let mut found = [0u32; 4];
    for sub in 0..4u8 {
        for bit in (0..32u8).rev() {
            if !probe(b, found[sub as usize], bit, sub, sub) {
                found[sub as usize] |= 1 << bit;
            }
        }
        if !probe(b, found[sub as usize], 0, sub, (sub + 1) & 3) {
            return None;
        }
    }
    Some(found)
}

#[test]
fn an_unconfigured_node_is_silent_until_fast_scan_finds_it_and_it_gets_an_id() {
    let (mut b, boot) = Bench::new(cfg(UNCONFIGURED, 0xC0FFEE), MemoryStorage::default());
    assert!(boot.is_empty(), "no boot-up without an id: {boot:02X?}");
    assert!(b.tick(1000).is_empty(), "no heartbeat either");
    // NMT and SDO do not reach it
    assert!(b.run(0x000, &[0x01, 0]).is_empty());
    assert!(b.run(0x67F, &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]).is_empty());
    assert_eq!(b.node.nmt_state(), NmtState::Initialising);
    // it answers identify non-configured remote slave
    assert_eq!(b.lss([0x4C, 0, 0, 0, 0, 0, 0, 0]), answer(0x50, 0));
    let id: Identity = b.node.config().identity;
    assert_eq!(fast_scan(&mut b), Some([id.vendor_id, id.product_code, id.revision, 0xC0FFEE]));
    assert_eq!(b.node.lss().mode, LssMode::Configuration, "fast scan ends in configuration");
    assert_eq!(b.lss([0x5E, 0, 0, 0, 0, 0, 0, 0]), answer(0x5E, 0xFF));
    assert_eq!(b.lss([0x11, 12, 0, 0, 0, 0, 0, 0]), answer(0x11, 0));
    assert_eq!(b.lss([0x17, 0, 0, 0, 0, 0, 0, 0]), answer(0x17, 0));
    // back to waiting: the unconfigured node takes its new id at once and boots
    let out = b.run(MASTER, &[0x04, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(out, vec![(0x70C, vec![0])]);
    assert_eq!(b.node.nmt_state(), NmtState::PreOperational);
    let r = b.run(0x60C, &[0x40, 0x18, 0x10, 4, 0, 0, 0, 0]);
    assert_eq!(r, vec![(0x58C, vec![0x43, 0x18, 0x10, 4, 0xEE, 0xFF, 0xC0, 0])]);
    // a configured node takes no part in fast scan
    assert_eq!(fast_scan(&mut b), None);
    // reset node: the stored id
    assert_eq!(b.run(0x000, &[NMT_RESET_NODE, 12]), vec![(0x70C, vec![0])]);
    // power cycle on the same storage: boots as 12, not as the unconfigured node it was built as
    let storage = std::mem::take(b.node.storage_mut());
    let (_, boot) = Bench::new(cfg(UNCONFIGURED, 0xC0FFEE), storage);
    assert_eq!(boot, vec![(0x70C, vec![0])]);
}

#[test]
fn configuring_0xff_makes_a_node_unconfigured_at_reset_communication() {
    let (mut b, _) = Bench::new(cfg(5, 1), MemoryStorage::default());
    b.lss([0x04, 1, 0, 0, 0, 0, 0, 0]);
    assert_eq!(b.lss([0x11, 0xFF, 0, 0, 0, 0, 0, 0]), answer(0x11, 0));
    b.lss([0x04, 0, 0, 0, 0, 0, 0, 0]);
    assert!(b.run(0x000, &[0x82, 0]).is_empty(), "reset communication: silent, unconfigured");
    assert!(b.tick(500).is_empty());
    assert_eq!(b.lss([0x4C, 0, 0, 0, 0, 0, 0, 0]), answer(0x50, 0));
}

#[test]
fn two_unconfigured_nodes_fast_scan_finds_the_lower_serial_first() {
    let (mut a, _) = Bench::new(cfg(UNCONFIGURED, 0x50), MemoryStorage::default());
    let (mut c, _) = Bench::new(cfg(UNCONFIGURED, 0x30), MemoryStorage::default());
    // a shared bus: a request reaches both; an answer from either counts
    let probe = |a: &mut Bench, c: &mut Bench, d: [u8; 8]| {
        let x = a.lss(d);
        let y = c.lss(d);
        !x.is_empty() || !y.is_empty()
    };
    assert!(probe(&mut a, &mut c, [0x51, 0, 0, 0, 0, 0x80, 0, 0]));
    let mut found = [0u32; 4];
    for sub in 0..4u8 {
        for bit in (0..32u8).rev() {
            let v = found[sub as usize].to_le_bytes();
            if !probe(&mut a, &mut c, [0x51, v[0], v[1], v[2], v[3], bit, sub, sub]) {
                found[sub as usize] |= 1 << bit;
            }
        }
        let v = found[sub as usize].to_le_bytes();
        assert!(probe(&mut a, &mut c, [0x51, v[0], v[1], v[2], v[3], 0, sub, (sub + 1) & 3]));
    }
    assert_eq!(found[3], 0x30);
    assert_eq!(c.node.lss().mode, LssMode::Configuration);
    assert_eq!(a.node.lss().mode, LssMode::Waiting);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Random LSS frames (any length) never panic the node; a node with an id keeps it and
    /// its NMT state unless the frames configured one and reset communication came after.
    #[test]
    fn random_lss_frames(frames in proptest::collection::vec(
        (prop_oneof![Just(0x04u8), Just(0x11), Just(0x13), Just(0x15), Just(0x17), 0x40u8..=0x5E, any::<u8>()],
         proptest::collection::vec(any::<u8>(), 0..9)), 0..80)) {
        let (mut b, _) = Bench::new(cfg(5, 3), MemoryStorage::default());
        for (cs, mut rest) in frames {
            rest.insert(0, cs);
            rest.truncate(8);
            for (id, d) in b.run(MASTER, &rest) {
                prop_assert_eq!(id, SLAVE);
                prop_assert_eq!(d.len(), 8);
            }
            prop_assert_eq!(b.node.node_id(), 5);
        }
    }
}
