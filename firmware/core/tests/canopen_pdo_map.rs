//! Writable PDO mappings (CiA 301 §7.5.2.36/38): the disable / sub 0 = 0 / entries / sub 0 = n
//! / enable sequence, the aborts of every refused step (each leaving the mapping as it was),
//! RPDO dummy entries, and the mapping saved by 0x1010 and restored at reset.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, NMT_RESET_NODE, NMT_START};
use joint_core::canopen::sdo::Abort;
use joint_core::canopen::CanFrame;

fn node(cfg: NodeConfig, storage: MemoryStorage) -> Node<MemoryStorage> {
    let mut n = Node::new(cfg, storage, 0);
    n.process(0, None, &mut |_| {});
    n
}

fn u32_of(n: &Node<MemoryStorage>, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 4];
    let k = n.read(index, sub, &mut b).unwrap();
    u32::from_le_bytes(b) & if k >= 4 { u32::MAX } else { (1 << (8 * k)) - 1 }
}

fn w32(n: &mut Node<MemoryStorage>, index: u16, sub: u8, v: u32) -> Result<(), Abort> {
    n.write(index, sub, &v.to_le_bytes())
}

fn mapping(n: &Node<MemoryStorage>, index: u16) -> Vec<u32> {
    (1..=u32_of(n, index, 0) as u8).map(|s| u32_of(n, index, s)).collect()
}

const Q_F32: u32 = 0x2301_0120;
const FAULTS: u32 = 0x2300_0410;
const ERR_REG: u32 = 0x1001_0008;

/// The CiA 301 sequence: TPDO1 of node 5 to q (REAL32), faults, error register: 7 bytes.
fn remap_tpdo1(n: &mut Node<MemoryStorage>) {
    w32(n, 0x1800, 1, 0x8000_0185).unwrap();
    n.write(0x1A00, 0, &[0]).unwrap();
    for (s, e) in [Q_F32, FAULTS, ERR_REG].into_iter().enumerate() {
        w32(n, 0x1A00, s as u8 + 1, e).unwrap();
    }
    n.write(0x1A00, 0, &[3]).unwrap();
    w32(n, 0x1800, 1, 0x185).unwrap();
}

fn tpdo1_after_start(n: &mut Node<MemoryStorage>, t0: u64) -> CanFrame {
    n.process(t0, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
    let mut got = None;
    for k in 0..30u64 {
        let t = t0 + 1000 * k;
        n.control(t, 0.75, 0.0, 0.0, 1e-3);
        n.process(t, Some(&CanFrame::new(0x77F, &[5]).unwrap()), &mut |f| {
            if f.id() == 0x185 {
                got = Some(f);
            }
        });
    }
    got.expect("TPDO1 while operational")
}

#[test]
fn a_tpdo_remapped_the_cia_301_way_sends_the_new_layout() {
    let mut n = node(NodeConfig::new(5), MemoryStorage::default());
    remap_tpdo1(&mut n);
    assert_eq!(mapping(&n, 0x1A00), [Q_F32, FAULTS, ERR_REG]);
    let f = tpdo1_after_start(&mut n, 1000);
    assert_eq!(f.len(), 7);
    assert_eq!(f32::from_le_bytes(f.data()[..4].try_into().unwrap()), 0.75);
    assert_eq!(u16::from_le_bytes([f.data()[4], f.data()[5]]), n.safety().faults().bits());
    assert_eq!(f.data()[6], n.error_register());
}

#[test]
fn every_refused_mapping_write_names_its_reason_and_changes_nothing() {
    let mut n = node(NodeConfig::new(5), MemoryStorage::default());
    let before = mapping(&n, 0x1A00);
    // the PDO is valid: nothing may change (0x06010000)
    assert_eq!(n.write(0x1A00, 0, &[0]), Err(Abort::Unsupported));
    assert_eq!(w32(&mut n, 0x1A00, 1, Q_F32), Err(Abort::Unsupported));
    assert_eq!(mapping(&n, 0x1A00), before);
    w32(&mut n, 0x1800, 1, 0x8000_0185).unwrap();
    // sub 0 is not 0: entries are locked (0x06010000)
    assert_eq!(w32(&mut n, 0x1A00, 1, Q_F32), Err(Abort::Unsupported));
    n.write(0x1A00, 0, &[0]).unwrap();
    // not mappable (0x06040041): device type, a parameter, a wrong length, a missing object,
    // a write-only object
    for bad in [0x1000_0020, 0x2000_0020, 0x2301_0110, 0x2301_0020, 0x5000_0010, 0x2202_0008] {
        assert_eq!(w32(&mut n, 0x1A00, 1, bad), Err(Abort::CannotMap), "{bad:08X}");
    }
    // three REAL32 = 12 bytes: more than a classic frame (0x06040042); an empty entry too
    for (s, e) in [Q_F32, Q_F32, Q_F32].into_iter().enumerate() {
        w32(&mut n, 0x1A00, s as u8 + 1, e).unwrap();
    }
    assert_eq!(n.write(0x1A00, 0, &[3]), Err(Abort::MapLength));
    assert_eq!(n.write(0x1A00, 0, &[17]), Err(Abort::MapLength));
    w32(&mut n, 0x1A00, 5, 0).unwrap();
    assert_eq!(n.write(0x1A00, 0, &[5]), Err(Abort::MapLength), "entry 4 and 5 are empty");
    assert_eq!(u32_of(&n, 0x1A00, 0), 0, "sub 0 stayed where the master left it");
    n.write(0x1A00, 0, &[2]).unwrap();
    assert_eq!(mapping(&n, 0x1A00), [Q_F32, Q_F32]);
    // a classic node cannot validate a TPDO longer than 8 bytes (TPDO3's 32)
    assert_eq!(w32(&mut n, 0x1802, 1, 0x385), Err(Abort::MapLength));
    // an RPDO maps only what may be written: the joint state is read-only
    w32(&mut n, 0x1400, 1, 0x8000_0205).unwrap();
    n.write(0x1600, 0, &[0]).unwrap();
    assert_eq!(w32(&mut n, 0x1600, 1, 0x2300_0110), Err(Abort::CannotMap));
    assert_eq!(w32(&mut n, 0x1600, 1, 0x0006_0020), Err(Abort::CannotMap), "a dummy of the wrong length");
    assert_eq!(u32_of(&n, 0x1600, 1), 0x2310_0110, "the refused entry left the old one");
}

#[test]
fn an_rpdo_skips_dummy_entries_to_its_value() {
    let mut n = node(NodeConfig::new(5), MemoryStorage::default());
    w32(&mut n, 0x1400, 1, 0x8000_0205).unwrap();
    n.write(0x1600, 0, &[0]).unwrap();
    w32(&mut n, 0x1600, 1, 0x0006_0010).unwrap(); // UNSIGNED16 dummy
    w32(&mut n, 0x1600, 2, 0x2310_0110).unwrap();
    n.write(0x1600, 0, &[2]).unwrap();
    w32(&mut n, 0x1400, 1, 0x205).unwrap();
    n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
    n.process(2000, Some(&CanFrame::new(0x205, &[0xFF, 0xFF, 40, 0]).unwrap()), &mut |_| {});
    assert!((n.assist_cmd() - 0.40).abs() < 1e-6, "{}", n.assist_cmd());
}

#[test]
fn an_fd_node_maps_up_to_64_bytes() {
    let mut n = node(NodeConfig::new(5).with_fd(true), MemoryStorage::default());
    w32(&mut n, 0x1802, 1, 0x8000_0385).unwrap();
    n.write(0x1A02, 0, &[0]).unwrap();
    for s in 1..=16u8 {
        w32(&mut n, 0x1A02, s, 0x2301_0020 | (u32::from((s - 1) % 7 + 1) << 8)).unwrap();
    }
    n.write(0x1A02, 0, &[16]).unwrap();
    w32(&mut n, 0x1802, 1, 0x385).unwrap();
    n.process(1000, Some(&CanFrame::new(0, &[NMT_START, 5]).unwrap()), &mut |_| {});
    let mut got = None;
    n.process(20_000, None, &mut |f| {
        if f.id() == 0x385 {
            got = Some(f)
        }
    });
    let f = got.unwrap();
    assert!(f.is_fd() && f.len() == 64);
    assert_eq!(w32(&mut n, 0x1A02, 17, 0), Err(Abort::NoSubIndex));
}

#[test]
fn the_mapping_is_saved_with_the_parameters_and_restored_at_reset() {
    let mut n = node(NodeConfig::new(5), MemoryStorage::default());
    remap_tpdo1(&mut n);
    w32(&mut n, 0x1010, 1, 0x6576_6173).unwrap();
    assert!(n.storage().pdo.is_some());
    // power cycle: a new node on the same storage
    let storage = n.into_storage();
    let mut n = node(NodeConfig::new(5), storage);
    assert_eq!(mapping(&n, 0x1A00), [Q_F32, FAULTS, ERR_REG]);
    assert_eq!(tpdo1_after_start(&mut n, 1000).len(), 7);
    // NMT reset node keeps it too; a change not saved is lost at reset
    n.process(50_000, Some(&CanFrame::new(0, &[0x80, 5]).unwrap()), &mut |_| {});
    w32(&mut n, 0x1800, 1, 0x8000_0185).unwrap();
    n.write(0x1A00, 0, &[1]).unwrap();
    n.process(51_000, Some(&CanFrame::new(0, &[NMT_RESET_NODE, 5]).unwrap()), &mut |_| {});
    assert_eq!(mapping(&n, 0x1A00), [Q_F32, FAULTS, ERR_REG]);
    // 0x1011 restore defaults: the dictionary's mapping after the next reset
    w32(&mut n, 0x1011, 1, 0x6461_6F6C).unwrap();
    n.process(52_000, Some(&CanFrame::new(0, &[NMT_RESET_NODE, 5]).unwrap()), &mut |_| {});
    assert_eq!(mapping(&n, 0x1A00), [0x2300_0110, 0x2300_0210, 0x2300_0310, 0x2300_0410]);
}

#[test]
fn a_stored_mapping_this_firmware_would_refuse_is_not_loaded() {
    let mut n = node(NodeConfig::new(5), MemoryStorage::default());
    remap_tpdo1(&mut n);
    w32(&mut n, 0x1010, 1, 0x6576_6173).unwrap();
    let mut storage = n.into_storage();
    // TPDO1 (slot 4 of 7, 65 bytes each): its first entry now names an object that is not
    // mappable, as a stored image from a firmware with another dictionary might
    let b = storage.pdo.as_mut().unwrap();
    b[4 * 65 + 1..4 * 65 + 5].copy_from_slice(&0x1000_0020u32.to_le_bytes());
    let n = node(NodeConfig::new(5), storage);
    assert_eq!(mapping(&n, 0x1A00), [0x2300_0110, 0x2300_0210, 0x2300_0310, 0x2300_0410], "defaults");
}
