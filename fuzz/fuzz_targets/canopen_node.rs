//! Fuzz the CANopen node's frame handling: the input is a sequence of frames (time step, id,
//! length, data) fed to one node; the node must never panic, and the parameter set in force
//! must only ever change to a set that passes `params::check`, with safety-relevant values
//! changing only from pre-operational (or by an NMT reset reloading the stored set).
#![no_main]

use joint_core::canopen::node::{MemoryStorage, NmtState, Node, NodeConfig};
use joint_core::canopen::CanFrame;
use joint_core::params::{check, PARAMS};
use libfuzzer_sys::fuzz_target;

const ID: u8 = 5;

/// Ids the node listens on, so most inputs reach a handler rather than being ignored.
const HOT: [u16; 6] = [0x000, 0x600 + ID as u16, 0x200 + ID as u16, 0x77F, 0x180 + ID as u16, 0x080];

fuzz_target!(|data: &[u8]| {
    let mut node = Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0);
    let mut now = 0u64;
    node.process(now, None, &mut |_| {});
    let mut rest = data;
    while rest.len() >= 3 {
        let (head, tail) = rest.split_at(3);
        let dt = u64::from(head[0]) * 97;
        let sel = head[1];
        let len = usize::from(head[2] % 9).min(tail.len());
        let id = if sel & 0x80 == 0 {
            HOT[usize::from(sel) % HOT.len()]
        } else {
            (u16::from(sel & 0x7F) << 4 | u16::from(head[2] >> 4)) & 0x7FF
        };
        let (payload, tail) = tail.split_at(len);
        rest = tail;
        now += dt;
        let Some(f) = CanFrame::new(id, payload) else { continue };
        let state = node.nmt_state();
        let before = node.params().raw().clone();
        node.process(now, Some(&f), &mut |_| {});
        node.control(now, 0.1, 0.0, 0.0, 0.001);
        let after = node.params().raw();
        assert!(check(after).is_ok(), "an unchecked set is in force");
        if after != &before {
            for d in PARAMS.iter().filter(|d| d.safety) {
                if after.get(d.id).to_bits() != before.get(d.id).to_bits() {
                    assert!(state == NmtState::PreOperational || id == 0, "{} changed in {state:?}", d.name);
                }
            }
        }
    }
});
