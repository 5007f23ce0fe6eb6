//! CAN FD in the core: the frame type's FD lengths and flags (ISO 11898-1:2015), the classic
//! API unchanged, and a node configured for FD sending the whole joint state in one 32-byte
//! TPDO3 of REAL32 values with bit-rate switch, SDO in the request's format.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::frame::{fd_dlc_of_len, fd_len_of_dlc, fd_padded_len, FD_LENGTHS};
use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, NMT_START};
use joint_core::canopen::sdo::Abort;
use joint_core::canopen::CanFrame;

#[test]
fn dlc_codes_and_lengths_follow_the_iso_table() {
    // ISO 11898-1:2015 table 5, written out rather than derived
    let table = [(9u8, 12usize), (10, 16), (11, 20), (12, 24), (13, 32), (14, 48), (15, 64)];
    for c in 0..=8u8 {
        assert_eq!(fd_len_of_dlc(c), Some(usize::from(c)));
        assert_eq!(fd_dlc_of_len(usize::from(c)), Some(c));
    }
    for (c, l) in table {
        assert_eq!(fd_len_of_dlc(c), Some(l));
        assert_eq!(fd_dlc_of_len(l), Some(c));
    }
    assert_eq!(fd_len_of_dlc(16), None);
    for bad in [9, 10, 11, 13, 17, 33, 49, 63, 65] {
        assert_eq!(fd_dlc_of_len(bad), None, "{bad}");
    }
    assert_eq!(fd_padded_len(9), Some(12));
    assert_eq!(fd_padded_len(33), Some(48));
    assert_eq!(fd_padded_len(64), Some(64));
    assert_eq!(fd_padded_len(65), None);
    assert_eq!(FD_LENGTHS.len(), 16);
}

#[test]
fn classic_frames_keep_their_api() {
    let f = CanFrame::new(0x605, &[1, 2, 3]).unwrap();
    assert!(!f.is_fd() && !f.brs());
    assert_eq!((f.id(), f.dlc(), f.len(), f.data()), (0x605, 3, 3, &[1u8, 2, 3][..]));
    assert_eq!(f.raw_data(), &[1, 2, 3, 0, 0, 0, 0, 0]);
    assert_eq!(CanFrame::new(0x605, &[0; 9]), None, "a classic frame holds 8 bytes");
    assert_eq!(CanFrame::new(0x800, &[]), None);
    let p = CanFrame::from_parts(0xFFFF, [9; 8], 12);
    assert_eq!((p.id(), p.dlc(), p.data()), (0x7FF, 8, &[9u8; 8][..]), "clamped");
    assert_eq!(CanFrame::default().len(), 0);
}

#[test]
fn fd_frames_pad_to_the_next_valid_length() {
    let d: Vec<u8> = (1..=10).collect();
    let f = CanFrame::new_fd(0x385, &d, true).unwrap();
    assert!(f.is_fd() && f.brs());
    assert_eq!((f.len(), f.dlc()), (12, 9));
    assert_eq!(&f.data()[..10], &d[..]);
    assert_eq!(&f.data()[10..], &[0, 0], "padding is 0x00");
    let full = CanFrame::new_fd(0x385, &[0xA5; 64], false).unwrap();
    assert!(full.is_fd() && !full.brs());
    assert_eq!((full.len(), full.dlc()), (64, 15));
    assert_eq!(full.raw_data(), &[0xA5; 8]);
    assert_eq!(CanFrame::new_fd(0x385, &[0; 65], true), None);
    assert_eq!(CanFrame::new_fd(0x800, &[], true), None);
    // a classic frame as FD keeps its bytes; FD ≠ classic with the same bytes
    let c = CanFrame::new(0x585, &[1, 2]).unwrap();
    assert_eq!(c.into_fd(true).data(), c.data());
    assert_ne!(c.into_fd(true), c);
}

fn started(cfg: NodeConfig) -> Node<MemoryStorage> {
    let mut n = Node::new(cfg, MemoryStorage::default(), 0);
    n.process(0, None, &mut |_| {});
    n.write(0x1017, 0, &0u16.to_le_bytes()).unwrap(); // no heartbeats in the frames below
    n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 0]).unwrap()), &mut |_| {});
    n
}

/// Frames the node sends over `ms` milliseconds of 1 kHz control steps with a fixed state.
fn run(n: &mut Node<MemoryStorage>, t0_ms: u64, ms: u64) -> Vec<CanFrame> {
    let mut out = Vec::new();
    for k in 0..ms {
        let t = (t0_ms + k) * 1000;
        n.set_measurements(-1.25, 41.5);
        n.control(t, 0.5, -0.25, 3.0, 1e-3);
        n.process(t, Some(&CanFrame::new(0x77F, &[5]).unwrap()), &mut |f| out.push(f));
    }
    out
}

fn f32_at(d: &[u8], i: usize) -> f32 {
    f32::from_le_bytes(d[i..i + 4].try_into().unwrap())
}

#[test]
fn an_fd_node_sends_the_whole_state_in_one_32_byte_tpdo_with_brs() {
    let mut n = started(NodeConfig::new(5).with_fd(true));
    let sent = run(&mut n, 2, 100);
    let pdo: Vec<&CanFrame> = sent.iter().filter(|f| f.id() == 0x385).collect();
    assert!((9..=11).contains(&pdo.len()), "10 ms event timer: {}", pdo.len());
    assert!(sent.iter().all(|f| f.id() != 0x185 && f.id() != 0x285), "classic TPDOs off on FD");
    let f = pdo.last().unwrap();
    assert!(f.is_fd() && f.brs());
    assert_eq!((f.len(), f.dlc()), (32, 13));
    let d = f.data();
    let s = *n.joint_state();
    // q, q̇, q̈, τ, τ measured, u, temperature — REAL32, no scale
    assert_eq!(f32_at(d, 0), 0.5);
    assert_eq!(f32_at(d, 4), -0.25);
    assert_eq!(f32_at(d, 8), 3.0);
    assert_eq!(f32_at(d, 12), s.tau_cmd);
    assert_eq!(f32_at(d, 16), -1.25);
    assert_eq!(f32_at(d, 20), s.tau_cmd * n.params().inv_ratio_m1());
    assert_eq!(f32_at(d, 24), 41.5);
    assert_eq!(u16::from_le_bytes([d[28], d[29]]), n.safety().faults().bits());
    assert_eq!(d[30], 1, "mode: assist (operational)");
    assert_eq!(d[31], n.error_register());
    // the mapping says the same (0x1A02: 10 entries, 32 bytes)
    let mut b = [0u8; 4];
    n.read(0x1A02, 0, &mut b).unwrap();
    assert_eq!(b[0], 10);
    let mut bits = 0;
    for s in 1..=10 {
        n.read(0x1A02, s, &mut b).unwrap();
        bits += u32::from_le_bytes(b) & 0xFF;
    }
    assert_eq!(bits, 256);
}

#[test]
fn a_classic_node_keeps_tpdo1_and_2_and_refuses_the_fd_tpdo() {
    let mut n = started(NodeConfig::new(5));
    let sent = run(&mut n, 2, 50);
    assert!(sent.iter().all(|f| !f.is_fd()), "a classic node sends classic frames only");
    assert!(sent.iter().any(|f| f.id() == 0x185 && f.len() == 8));
    assert!(sent.iter().any(|f| f.id() == 0x285 && f.len() == 8));
    assert!(sent.iter().all(|f| f.id() != 0x385));
    let mut b = [0u8; 4];
    n.read(0x1802, 1, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x8000_0385, "TPDO3 invalid on a classic node");
    // 32 bytes do not fit a classic frame: refused, the old COB-ID stays
    assert_eq!(n.write(0x1802, 1, &0x385u32.to_le_bytes()), Err(Abort::MapLength));
    n.read(0x1802, 1, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x8000_0385);
    // the REAL32 state is readable by SDO on either node
    n.read(0x2301, 1, &mut b).unwrap();
    assert_eq!(f32::from_le_bytes(b), 0.5);
}

#[test]
fn sdo_in_an_fd_frame_is_answered_in_an_fd_frame_of_8_bytes() {
    let mut n = started(NodeConfig::new(5).with_fd(true));
    let req = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]).unwrap().into_fd(true);
    let mut out = Vec::new();
    n.process(200_000, Some(&req), &mut |f| out.push(f));
    let r = out.iter().find(|f| f.id() == 0x585).unwrap();
    assert!(r.is_fd() && r.brs());
    assert_eq!(r.len(), 8);
    assert_eq!(&r.data()[..4], &[0x43, 0x18, 0x10, 1]);
    // a classic request still gets a classic reply
    let mut out = Vec::new();
    let req = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0]).unwrap();
    n.process(201_000, Some(&req), &mut |f| out.push(f));
    assert!(!out.iter().find(|f| f.id() == 0x585).unwrap().is_fd());
}

#[test]
fn fd_nodes_take_their_command_from_their_slot_of_the_shared_frame() {
    // joint 3: two 16-bit slots before its own (one UNSIGNED32 dummy), COB-ID 0x200
    let mut n = started(NodeConfig::new(3).with_fd(true));
    let mut b = [0u8; 4];
    n.read(0x1400, 1, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x200);
    n.read(0x1600, 0, &mut b).unwrap();
    assert_eq!(b[0], 2);
    n.read(0x1600, 1, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x0007_0020, "UNSIGNED32 dummy");
    n.read(0x1600, 2, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x2310_0110);
    n.read(0x1600, 3, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0, "past sub 0: no entry");
    // six joints' commands: joint k gets k × 0.01 N·m; joint 3 reads bytes 4..6
    let cmd: Vec<u8> = (1..=6i16).flat_map(|k| k.to_le_bytes()).collect();
    let shared = CanFrame::new_fd(0x200, &cmd, true).unwrap();
    n.process(5000, Some(&shared), &mut |_| {});
    assert!((n.assist_cmd() - 0.03).abs() < 1e-6, "{}", n.assist_cmd());
    // a shared frame too short for our slot is not processed (EMCY 0x8210), the command stays
    let mut out = Vec::new();
    n.process(6000, Some(&CanFrame::new(0x200, &[9, 9, 9, 9]).unwrap()), &mut |f| out.push(f));
    assert!((n.assist_cmd() - 0.03).abs() < 1e-6);
    assert!(out.iter().any(|f| f.id() == 0x83 && f.data()[..2] == [0x10, 0x82]));
    // a classic node keeps its own RPDO1 (0x200 + id, one entry)
    let c = started(NodeConfig::new(3));
    c.read(0x1400, 1, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes(b), 0x203);
    c.read(0x1600, 0, &mut b).unwrap();
    assert_eq!(b[0], 1);
}
