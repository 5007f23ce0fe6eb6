//! CiA 301 objects a master expects of the node: SYNC consumer and synchronous TPDOs (0x1005,
//! 0x1800 sub 2 = 1..240), the error history (0x1003), the EMCY COB-ID (0x1014) and the
//! error behaviour (0x1029).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, NmtState, Node, NodeConfig, EMCY_HEARTBEAT, NMT_START};
use joint_core::canopen::sdo::Abort;
use joint_core::canopen::CanFrame;
use joint_core::safety::Faults;

fn node() -> Node<MemoryStorage> {
    let mut n = Node::new(NodeConfig::new(5), MemoryStorage::default(), 0);
    n.process(0, None, &mut |_| {});
    n
}

/// Runs the node from `t0` to `t1` µs (frames every 0.5 ms, a control step every 1 ms), the host
/// heartbeat every 50 ms when `beat`, a SYNC every `sync_every_ms`, and returns every frame it
/// sent with its time.
fn run(n: &mut Node<MemoryStorage>, t0: u64, t1: u64, beat: bool, sync_every_ms: Option<u64>) -> Vec<(u64, CanFrame)> {
    let mut out = Vec::new();
    let mut t = t0;
    while t < t1 {
        let hb = CanFrame::new(0x77F, &[5]).unwrap();
        let sync = CanFrame::new(0x80, &[]).unwrap();
        let rx = if beat && t % 50_000 == 0 {
            Some(hb)
        } else if sync_every_ms.is_some_and(|m| t % (m * 1000) == 500) {
            Some(sync)
        } else {
            None
        };
        n.process(t, rx.as_ref(), &mut |f| out.push((t, f)));
        if t % 1000 == 0 {
            // the 1 kHz control step, which runs the watchdog
            n.control(t, 0.1, 0.0, 0.0, 1e-3);
        }
        t += 500;
    }
    out
}

fn u32_of(n: &Node<MemoryStorage>, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 4];
    let k = n.read(index, sub, &mut b).unwrap();
    u32::from_le_bytes(b) & if k >= 4 { u32::MAX } else { (1 << (8 * k)) - 1 }
}

#[test]
fn a_synchronous_tpdo_goes_out_on_every_nth_sync_and_not_on_its_timer() {
    let mut n = node();
    n.write(0x1800, 2, &[2]).unwrap(); // TPDO1 on every 2nd SYNC
    n.write(0x2202, 0, &[1]).unwrap();
    n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
    assert_eq!(n.nmt_state(), NmtState::Operational);
    // 200 ms, SYNC every 10 ms: 20 SYNCs → 10 TPDO1; TPDO2 stays on its 10 ms timer
    let sent = run(&mut n, 1000, 201_000, true, Some(10));
    let tpdo1 = sent.iter().filter(|(_, f)| f.id() == 0x185).count();
    let tpdo2 = sent.iter().filter(|(_, f)| f.id() == 0x285).count();
    assert_eq!(tpdo1, 10, "one per two SYNCs");
    assert!((19..=21).contains(&tpdo2), "the event-driven TPDO keeps its timer: {tpdo2}");
    // without SYNC nothing: the timer does not drive a synchronous TPDO
    let sent = run(&mut n, 201_000, 301_000, true, None);
    assert_eq!(sent.iter().filter(|(_, f)| f.id() == 0x185).count(), 0);
    // types the node does not serve are refused, the old one stays
    assert_eq!(n.write(0x1800, 2, &[0]), Err(Abort::InvalidValue));
    assert_eq!(n.write(0x1800, 2, &[241]), Err(Abort::InvalidValue));
    assert_eq!(u32_of(&n, 0x1800, 2), 2);
    // a SYNC with more than the counter byte is dropped
    let before = n.dropped;
    n.process(301_000, Some(&CanFrame::new(0x80, &[1, 2]).unwrap()), &mut |_| {});
    assert_eq!(n.dropped, before + 1);
}

#[test]
fn the_sync_cob_id_is_a_consumer_s_11_bit_id() {
    let mut n = node();
    assert_eq!(u32_of(&n, 0x1005, 0), 0x80);
    assert_eq!(n.write(0x1005, 0, &0x4000_0080u32.to_le_bytes()), Err(Abort::InvalidValue), "no producer");
    assert_eq!(n.write(0x1005, 0, &0x2000_0080u32.to_le_bytes()), Err(Abort::InvalidValue), "no 29-bit id");
    n.write(0x1005, 0, &0x90u32.to_le_bytes()).unwrap();
    assert_eq!(u32_of(&n, 0x1005, 0), 0x90);
    assert_eq!(u32_of(&n, 0x1014, 0), 0x85, "EMCY at 0x80 + node");
    assert_eq!(n.write(0x1014, 0, &0x86u32.to_le_bytes()), Err(Abort::ReadOnly));
}

#[test]
fn errors_are_kept_newest_first_and_cleared_by_writing_zero() {
    let mut n = node();
    assert_eq!(u32_of(&n, 0x1003, 0), 0);
    n.write(0x2202, 0, &[1]).unwrap();
    n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
    // the host goes silent: heartbeat lost, EMCY 0x8130, recorded
    let sent = run(&mut n, 1000, 2_000_000, false, None);
    assert!(sent
        .iter()
        .any(|(_, f)| f.id() == 0x85 && u16::from_le_bytes([f.data()[0], f.data()[1]]) == EMCY_HEARTBEAT));
    assert!(n.safety().faults().contains(Faults::HEARTBEAT_LOST));
    assert_eq!(u32_of(&n, 0x1003, 0), 1);
    assert_eq!(u32_of(&n, 0x1003, 1) & 0xFFFF, u32::from(EMCY_HEARTBEAT));
    assert_eq!(u32_of(&n, 0x1003, 1) >> 16, u32::from(n.error_register()), "the error register beside it");
    assert_eq!(u32_of(&n, 0x1003, 2), 0, "an empty entry reads 0");
    assert_eq!(n.write(0x1003, 0, &[3]), Err(Abort::InvalidValue), "only 0 may be written");
    n.write(0x1003, 0, &[0]).unwrap();
    assert_eq!(u32_of(&n, 0x1003, 0), 0);
    assert_eq!(u32_of(&n, 0x1003, 1), 0);
    // the operational state stays by default (0x1029 sub 1 = 1): the TPDOs keep reporting
    assert_eq!(u32_of(&n, 0x1029, 1), 1);
    assert_eq!(n.nmt_state(), NmtState::Operational);
}

#[test]
fn the_error_behaviour_takes_the_node_out_of_operational_on_a_lost_heartbeat() {
    for (behaviour, state) in [(0u8, NmtState::PreOperational), (2, NmtState::Stopped)] {
        let mut n = node();
        n.write(0x1029, 1, &[behaviour]).unwrap();
        n.write(0x2202, 0, &[1]).unwrap();
        n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
        run(&mut n, 1000, 300_000, true, None);
        assert_eq!(n.nmt_state(), NmtState::Operational);
        run(&mut n, 300_000, 2_000_000, false, None);
        assert_eq!(n.nmt_state(), state, "0x1029 = {behaviour}");
    }
    let mut n = node();
    assert_eq!(n.write(0x1029, 1, &[3]), Err(Abort::InvalidValue));
}
