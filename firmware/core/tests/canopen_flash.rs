//! The node's `save` (0x1010) and `load` (0x1011) through the real A/B flash store on a RAM
//! flash: a saved set survives a power cycle, "load" brings the defaults back after a reset,
//! and a damaged store raises PARAMS_CORRUPT at boot.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{Node, NodeConfig};
use joint_core::canopen::storage::FlashStorage;
use joint_core::canopen::CanFrame;
use joint_core::params::ParamId;
use joint_core::safety::Faults;
use joint_core::store::Store;

const PAGE: usize = 2048;

// The shared NOR-flash double (the core's `mock-flash` feature).
use joint_core::store::mock::MemFlash;

fn boot(flash: MemFlash) -> Node<FlashStorage<MemFlash>> {
    let mut n = Node::new(NodeConfig::new(5), FlashStorage::new(Store::new(flash).unwrap()), 0);
    n.process(0, None, &mut |_| {});
    n
}

fn sdo(n: &mut Node<FlashStorage<MemFlash>>, d: [u8; 8]) -> [u8; 8] {
    let mut r = None;
    n.process(0, Some(&CanFrame::new(0x605, &d).unwrap()), &mut |f: CanFrame| {
        if f.id() == 0x585 {
            r = Some(*f.raw_data());
        }
    });
    r.unwrap()
}

/// The commit of what is staged, named by its CRC (0x2205; a plain commit is refused).
fn commit(n: &mut Node<FlashStorage<MemFlash>>) -> [u8; 8] {
    let c = joint_core::store::set_crc(n.staged()).to_le_bytes();
    sdo(n, [0x23, 0x05, 0x22, 0x00, c[0], c[1], c[2], c[3]])
}

fn power_cycle(n: Node<FlashStorage<MemFlash>>) -> Node<FlashStorage<MemFlash>> {
    boot(n.into_storage().into_flash().unwrap())
}

#[test]
fn saved_set_survives_a_power_cycle_and_load_restores_defaults() {
    let mut n = boot(MemFlash::blank(4 * PAGE));
    assert!(n.safety().faults().is_empty(), "a blank store is not a fault");
    let v = 3.25f32.to_le_bytes();
    assert_eq!(sdo(&mut n, [0x23, 0x02, 0x20, 0x00, v[0], v[1], v[2], v[3]])[0], 0x60); // friction_c
    assert_eq!(commit(&mut n)[0], 0x60);
    assert_eq!(sdo(&mut n, [0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']), [0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0]);

    let mut n = power_cycle(n);
    assert_eq!(n.params().get(ParamId::FrictionC), 3.25);
    assert!(n.safety().faults().is_empty());

    assert_eq!(sdo(&mut n, [0x23, 0x11, 0x10, 0x01, b'l', b'o', b'a', b'd']), [0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0]);
    // still running the saved set until the reset
    assert_eq!(n.params().get(ParamId::FrictionC), 3.25);
    let n = power_cycle(n);
    assert_eq!(n.params().get(ParamId::FrictionC), 0.0);
    assert!(n.safety().faults().is_empty());
}

#[test]
fn a_damaged_store_boots_on_defaults_with_a_fault() {
    let mut n = boot(MemFlash::blank(4 * PAGE));
    let v = 3.25f32.to_le_bytes();
    sdo(&mut n, [0x23, 0x02, 0x20, 0x00, v[0], v[1], v[2], v[3]]);
    commit(&mut n);
    sdo(&mut n, [0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']);
    let mut flash = n.into_storage().into_flash().unwrap();
    // flip a payload bit of the only record
    flash.mem[100] ^= 0x01;
    let n = boot(flash);
    assert_eq!(n.params().get(ParamId::FrictionC), 0.0);
    assert!(n.safety().faults().contains(Faults::PARAMS_CORRUPT), "{:?}", n.safety().faults());
}

fn r32(n: &Node<FlashStorage<MemFlash>>, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 8];
    let k = n.read(index, sub, &mut b).unwrap();
    let mut w = [0u8; 4];
    w[..k.min(4)].copy_from_slice(&b[..k.min(4)]);
    u32::from_le_bytes(w)
}

fn w32(n: &mut Node<FlashStorage<MemFlash>>, index: u16, sub: u8, v: u32) {
    n.write(index, sub, &v.to_le_bytes()).unwrap();
}

fn lss(n: &mut Node<FlashStorage<MemFlash>>, d: [u8; 8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    n.process(0, Some(&CanFrame::new(0x7E5, &d).unwrap()), &mut |f: CanFrame| {
        if f.id() == 0x7E4 {
            out.push(f.data().to_vec());
        }
    });
    out
}

/// On a board's flash store too: PDO mappings saved by 0x1010 with the set and an LSS node id
/// stored by LSS survive a power cycle; 0x1011 brings the default mappings and the default set
/// back at the next reset and keeps the LSS node id (CiA 305's, not the application's).
#[test]
fn mappings_and_the_lss_node_id_survive_a_power_cycle_on_the_flash_store() {
    let mut n = boot(MemFlash::blank(4 * PAGE));
    let default_map: Vec<u32> = (1..=2).map(|s| r32(&n, 0x1A00, s)).collect();
    // TPDO1: the fault bits and the error register only (CiA 301 remapping sequence)
    w32(&mut n, 0x1800, 1, 0x8000_0185);
    n.write(0x1A00, 0, &[0]).unwrap();
    w32(&mut n, 0x1A00, 1, 0x2300_0410);
    w32(&mut n, 0x1A00, 2, 0x1001_0008);
    n.write(0x1A00, 0, &[2]).unwrap();
    w32(&mut n, 0x1800, 1, 0x185);
    assert_eq!(sdo(&mut n, [0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']), [0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0]);
    // LSS: switch to configuration, node id 21, store (answer 0 = stored)
    assert!(lss(&mut n, [0x04, 0x01, 0, 0, 0, 0, 0, 0]).is_empty());
    assert_eq!(lss(&mut n, [0x11, 21, 0, 0, 0, 0, 0, 0]), vec![vec![0x11, 0, 0, 0, 0, 0, 0, 0]]);
    assert_eq!(lss(&mut n, [0x17, 0, 0, 0, 0, 0, 0, 0]), vec![vec![0x17, 0, 0, 0, 0, 0, 0, 0]]);

    let mut n = power_cycle(n);
    assert_eq!(n.node_id(), 21, "the stored LSS node id");
    assert!(n.safety().faults().is_empty(), "{:?}", n.safety().faults());
    assert_eq!(r32(&n, 0x1A00, 0), 2);
    assert_eq!([r32(&n, 0x1A00, 1), r32(&n, 0x1A00, 2)], [0x2300_0410, 0x1001_0008]);

    // restore defaults (0x1011), then a reset: default mappings, the LSS id stays
    let mut r = None;
    n.process(
        0,
        Some(&CanFrame::new(0x600 + 21, &[0x23, 0x11, 0x10, 0x01, b'l', b'o', b'a', b'd']).unwrap()),
        &mut |f| {
            if f.id() == 0x580 + 21 {
                r = Some(f.data()[0]);
            }
        },
    );
    assert_eq!(r, Some(0x60));
    let n = power_cycle(n);
    assert_eq!(n.node_id(), 21);
    assert_eq!((1..=2).map(|s| r32(&n, 0x1A00, s)).collect::<Vec<_>>(), default_map);
}
