//! A staged set never outlives its master: the node discards staged values when the SDO
//! channel that wrote them goes quiet for 3 s, and says so (0x2201 code 8, EMCY 0x6320 kept in 0x1003); the set in force never changes.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig};
use joint_core::canopen::CanFrame;
use joint_core::params::ParamId;

const ID: u8 = 5;

struct Bench {
    node: Node<MemoryStorage>,
    now: u64,
}

impl Bench {
    fn new() -> Bench {
        let mut b = Bench { node: Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0), now: 0 };
        b.tick(0);
        b
    }

    fn run(&mut self, id: u16, d: &[u8]) -> Vec<(u16, Vec<u8>)> {
        let mut out = Vec::new();
        let f = CanFrame::new(id, d).unwrap();
        self.node.process(self.now, Some(&f), &mut |f: CanFrame| out.push((f.id(), f.data().to_vec())));
        out
    }

    /// Advance `ms`, with a control step (it runs the heartbeat watchdog) and the timers.
    fn tick(&mut self, ms: u64) -> Vec<(u16, Vec<u8>)> {
        self.now += ms * 1000;
        self.node.control(self.now, 0.0, 0.0, 0.0, 0.001);
        let mut out = Vec::new();
        self.node.process(self.now, None, &mut |f: CanFrame| out.push((f.id(), f.data().to_vec())));
        out
    }

    /// Run the timers for `ms` in 10 ms steps; every frame sent.
    fn wait(&mut self, ms: u64) -> Vec<(u16, Vec<u8>)> {
        (0..ms / 10).flat_map(|_| self.tick(10)).collect()
    }

    fn read(&mut self, rx: u16, index: u16, sub: u8) -> Vec<u8> {
        let i = index.to_le_bytes();
        let r = self.run(rx, &[0x40, i[0], i[1], sub, 0, 0, 0, 0]);
        r.into_iter().find(|(id, _)| (0x580..0x600).contains(id)).unwrap().1
    }

    /// Stage friction_a = 0.5 by SDO on the channel whose request COB-ID is `rx`.
    fn stage(&mut self, rx: u16) {
        let v = 0.5f32.to_le_bytes();
        let r = self.run(rx, &[0x23, 0x00, 0x20, 0x00, v[0], v[1], v[2], v[3]]);
        assert!(r.iter().any(|(_, d)| d[0] == 0x60), "{r:02X?}");
        assert!(self.pending());
    }

    fn pending(&mut self) -> bool {
        self.read(0x605, 0x2203, 0)[4] == 1
    }
}

fn emcy_discard(out: &[(u16, Vec<u8>)]) -> bool {
    out.iter().any(|(id, d)| *id == 0x085 && d[..2] == [0x20, 0x63] && d[3] == 8)
}

#[test]
fn a_staged_set_is_discarded_when_its_master_goes_quiet() {
    let mut b = Bench::new();
    let before = b.node.params().raw().clone();
    b.stage(0x605);
    // under 3 s: still staged
    let out = b.wait(2900);
    assert!(!emcy_discard(&out));
    assert_eq!(b.node.staged().get(ParamId::FrictionA), 0.5);
    // the pending read above was a request on the same channel: 3 s from it
    let out = b.wait(3100);
    assert!(emcy_discard(&out), "EMCY 0x6320 with code 8: {out:02X?}");
    assert!(!b.pending());
    assert_eq!(b.node.staged(), b.node.params().raw());
    assert_eq!(b.node.params().raw(), &before, "the set in force never changed");
    assert_eq!(b.read(0x605, 0x2201, 1)[4], 8);
    // newest first in the error history (the boot-time heartbeat loss is older)
    assert!(b.read(0x605, 0x1003, 0)[4] >= 1);
    assert_eq!(b.read(0x605, 0x1003, 1)[4..6], [0x20, 0x63], "kept in the error history");
}

#[test]
fn a_master_that_keeps_talking_keeps_its_staged_set_and_commits_it() {
    let mut b = Bench::new();
    b.stage(0x605);
    for _ in 0..10 {
        b.wait(1000);
        assert!(b.pending(), "a read every second keeps it");
    }
    let c = joint_core::store::set_crc(b.node.staged()).to_le_bytes();
    let r = b.run(0x605, &[0x23, 0x05, 0x22, 0x00, c[0], c[1], c[2], c[3]]);
    assert!(r.iter().any(|(id, d)| *id == 0x585 && d[0] == 0x60));
    assert_eq!(b.node.params().get(ParamId::FrictionA), 0.5);
    // committed: nothing staged, nothing to discard later
    assert!(!emcy_discard(&b.wait(5000)));
    assert_eq!(b.node.params().get(ParamId::FrictionA), 0.5);
}

#[test]
fn traffic_on_the_other_channel_does_not_keep_a_quiet_masters_set() {
    let mut b = Bench::new();
    // the second channel at 0x640/0x5C0
    for (sub, v) in [(1u8, 0x640u32), (2, 0x5C0)] {
        let x = v.to_le_bytes();
        b.run(0x605, &[0x23, 0x01, 0x12, sub, x[0], x[1], x[2], x[3]]);
    }
    b.stage(0x640);
    // channel 1 (another master) keeps polling; the stager on channel 2 is gone
    let mut out = Vec::new();
    for _ in 0..35 {
        out.extend(b.wait(100));
        b.read(0x605, 0x1018, 2);
    }
    assert!(emcy_discard(&out));
    assert!(!b.pending());
}
