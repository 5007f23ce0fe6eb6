//! Property tests of the CANopen node: SDO round trips of every parameter and of the gravity
//! table through a minimal SDO client, PDO scaling, and a fuzz-style run that throws random
//! frames at the node and checks that it never panics and that the running parameter set only
//! ever changes to a set that passed `params::check` (and its safety-relevant values only in
//! pre-operational). The cargo-fuzz target in `fuzz/` runs the same harness unbounded.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, NmtState, Node, NodeConfig};
use joint_core::canopen::od::{self, PARAM_BASE};
use joint_core::canopen::pdo::{from_i16, to_i16, Q_LSB};
use joint_core::canopen::sdo::{self, Abort};
use joint_core::canopen::CanFrame;
use joint_core::params::{check, ParamId, PARAMS, PARAM_COUNT};
use proptest::prelude::*;

const ID: u8 = 9;

fn node() -> Node<MemoryStorage> {
    let mut n = Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0);
    n.process(0, None, &mut |_| {});
    n
}

/// One request, one response (the node answers SDO synchronously).
fn sdo_req(n: &mut Node<MemoryStorage>, d: [u8; 8]) -> [u8; 8] {
    let mut resp = None;
    let f = CanFrame::new(0x600 + ID as u16, &d).unwrap();
    n.process(0, Some(&f), &mut |f: CanFrame| {
        if f.id() == 0x580 + ID as u16 {
            resp = Some(*f.raw_data());
        }
    });
    resp.expect("SDO response")
}

fn abort_of(r: [u8; 8]) -> Option<u32> {
    (r[0] == 0x80).then(|| u32::from_le_bytes([r[4], r[5], r[6], r[7]]))
}

fn download(n: &mut Node<MemoryStorage>, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
    if data.len() <= 4 {
        let r = sdo_req(n, sdo::expedited_download(index, sub, data));
        return abort_of(r).map_or(Ok(()), Err);
    }
    let r = sdo_req(n, sdo::segmented_download(index, sub, data.len() as u32));
    if let Some(a) = abort_of(r) {
        return Err(a);
    }
    let mut toggle = 0u8;
    let chunks: Vec<&[u8]> = data.chunks(7).collect();
    for (i, c) in chunks.iter().enumerate() {
        let last = i + 1 == chunks.len();
        let mut d = [0u8; 8];
        d[0] = (toggle << 4) | (((7 - c.len()) as u8) << 1) | u8::from(last);
        d[1..1 + c.len()].copy_from_slice(c);
        let r = sdo_req(n, d);
        if let Some(a) = abort_of(r) {
            return Err(a);
        }
        assert_eq!(r[0], 0x20 | (toggle << 4));
        toggle ^= 1;
    }
    Ok(())
}

fn upload(n: &mut Node<MemoryStorage>, index: u16, sub: u8) -> Result<Vec<u8>, u32> {
    let r = sdo_req(n, sdo::upload_request(index, sub));
    if let Some(a) = abort_of(r) {
        return Err(a);
    }
    if r[0] & 0x02 != 0 {
        let len = 4 - ((r[0] >> 2) & 3) as usize;
        return Ok(r[4..4 + len].to_vec());
    }
    let total = u32::from_le_bytes([r[4], r[5], r[6], r[7]]) as usize;
    let mut out = Vec::new();
    let mut toggle = 0u8;
    loop {
        let r = sdo_req(n, [0x60 | (toggle << 4), 0, 0, 0, 0, 0, 0, 0]);
        if let Some(a) = abort_of(r) {
            return Err(a);
        }
        let len = 7 - ((r[0] >> 1) & 7) as usize;
        out.extend_from_slice(&r[1..1 + len]);
        if r[0] & 1 != 0 {
            break;
        }
        toggle ^= 1;
    }
    assert_eq!(out.len(), total);
    Ok(out)
}

#[test]
fn every_object_in_the_dictionary_answers_as_described() {
    let mut n = node();
    for index in od::indices() {
        let obj = od::object_info(index).unwrap();
        for &sub in obj.subs {
            let info = od::sub_info(index, sub).unwrap();
            let r = upload(&mut n, index, sub);
            if info.access.readable() {
                let v = r.unwrap_or_else(|a| panic!("{index:04X}:{sub} ({}) read abort {a:08X}", info.name));
                if let Some(s) = info.dtype.size() {
                    assert_eq!(v.len(), s, "{}", info.name);
                }
            } else {
                assert_eq!(r, Err(Abort::WriteOnly.code()), "{}", info.name);
            }
        }
        // one past the last sub-index does not exist
        let last = *obj.subs.last().unwrap();
        if last < 0xFF {
            assert_eq!(upload(&mut n, index, last + 1), Err(Abort::NoSubIndex.code()), "{index:04X}");
        }
    }
    // the parameter objects are exactly the table, in order
    for (i, d) in PARAMS.iter().enumerate() {
        assert_eq!(od::object_info(PARAM_BASE + i as u16).unwrap().name, d.name);
    }
    assert!(od::object_info(PARAM_BASE + PARAM_COUNT as u16).is_none());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any in-range value of any parameter reads back bit-exact, and commits.
    #[test]
    fn parameter_round_trip(i in 0..PARAM_COUNT, t in 0.0f64..=1.0) {
        let d = &PARAMS[i];
        let v = (d.min as f64 + t * (d.max as f64 - d.min as f64)) as f32;
        let v = v.clamp(d.min, d.max);
        let mut n = node();
        download(&mut n, PARAM_BASE + i as u16, 0, &v.to_le_bytes()).unwrap();
        let back = upload(&mut n, PARAM_BASE + i as u16, 0).unwrap();
        prop_assert_eq!(back, v.to_le_bytes().to_vec());
        prop_assert_eq!(n.staged().get(d.id).to_bits(), v.to_bits());
    }

    /// Out-of-range writes abort with the direction's code and change nothing.
    #[test]
    fn out_of_range_is_refused(i in 0..PARAM_COUNT, over in 1.0f32..1.0e6, high in any::<bool>()) {
        let d = &PARAMS[i];
        let v = if high { d.max + over.max(d.max.abs() * 1e-3) } else { d.min - over.max(d.min.abs() * 1e-3) };
        let mut n = node();
        let before = n.staged().clone();
        let r = download(&mut n, PARAM_BASE + i as u16, 0, &v.to_le_bytes());
        let want = if high { Abort::TooHigh } else { Abort::TooLow };
        prop_assert_eq!(r, Err(want.code()));
        prop_assert_eq!(n.staged(), &before);
    }

    /// A gravity table of any shape goes through segmented SDO and commits as a whole.
    #[test]
    fn gravity_table_round_trip(points in 2u8..=16, torque in proptest::collection::vec(-50.0f32..50.0, 16)) {
        let mut n = node();
        let grid: Vec<f32> = (0..points).map(|k| -1.0 + 0.1 * k as f32).collect();
        let cells = &torque[..points as usize];
        download(&mut n, od::TABLE_SHAPE, 1, &[1]).unwrap();
        download(&mut n, od::TABLE_SHAPE, 6, &[points]).unwrap();
        let gb: Vec<u8> = grid.iter().flat_map(|v| v.to_le_bytes()).collect();
        let tb: Vec<u8> = cells.iter().flat_map(|v| v.to_le_bytes()).collect();
        download(&mut n, od::TABLE_GRID, 0, &gb).unwrap();
        download(&mut n, od::TABLE_TORQUE, 0, &tb).unwrap();
        let crc = joint_core::store::set_crc(n.staged());
        download(&mut n, od::COMMIT_CRC, 0, &crc.to_le_bytes()).unwrap();
        prop_assert_eq!(n.params().table().n_axes, 1);
        prop_assert_eq!(&n.params().table().torque[..points as usize], cells);
        let back = upload(&mut n, od::TABLE_TORQUE, 0).unwrap();
        prop_assert_eq!(back, tb);
        let gback = upload(&mut n, od::TABLE_GRID, 0).unwrap();
        prop_assert_eq!(&gback[..gb.len()], &gb[..]);
    }

    #[test]
    fn pdo_scaling_round_trip(x in -3.2767f32..3.2767) {
        let back = from_i16(to_i16(x, Q_LSB), Q_LSB);
        prop_assert!((back - x).abs() <= Q_LSB * 0.5 + 1e-6);
    }
}

/// A random frame, biased toward the ids the node listens on so the SDO/NMT/RPDO paths are
/// actually exercised rather than ignored.
fn arb_frame() -> impl Strategy<Value = CanFrame> {
    let id = prop_oneof![
        4 => Just(0x600u16 + ID as u16),
        1 => Just(0x000u16),
        1 => Just(0x77Fu16),
        1 => Just(0x200u16 + ID as u16),
        2 => 0u16..=0x7FF,
    ];
    let sdo_like = (
        prop_oneof![Just(0x23u8), Just(0x2F), Just(0x2B), Just(0x21), Just(0x40), Just(0x60), Just(0x70), Just(0x00), Just(0x10), any::<u8>()],
        prop_oneof![Just(0x2000u16), 0x2000u16..0x2020, Just(0x2200), Just(0x2100), 0x2101u16..0x2104, Just(0x1010), Just(0x1011), Just(0x1016), Just(0x1017), 0x1400u16..0x1404, 0x1800u16..0x1802, any::<u16>()],
        0u8..12,
        prop_oneof![2 => any::<[u8; 4]>(), 1 => Just([1u8, 0, 0, 0]), 1 => Just([0u8, 0, 0, 0]), 1 => (0u8..8).prop_map(|b| [b, 0, 0x80, 0x3F])],
    )
        .prop_map(|(c, i, s, v)| {
            let i = i.to_le_bytes();
            vec![c, i[0], i[1], s, v[0], v[1], v[2], v[3]]
        });
    let nmt = (
        prop_oneof![Just(1u8), Just(2), Just(0x80), Just(0x81), Just(0x82), any::<u8>()],
        prop_oneof![Just(ID), Just(0), any::<u8>()],
    )
        .prop_map(|(a, b)| vec![a, b]);
    let data = prop_oneof![3 => sdo_like, 1 => nmt, 2 => proptest::collection::vec(any::<u8>(), 0..=8)];
    (id, data).prop_map(|(id, d)| CanFrame::new(id, &d).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn random_frames_never_panic_nor_run_an_unchecked_set(
        frames in proptest::collection::vec((arb_frame(), 0u64..5_000), 1..400)
    ) {
        let mut n = node();
        let mut now = 0u64;
        let mut sent = 0usize;
        for (f, dt) in frames {
            now += dt;
            let state_before = n.nmt_state();
            let before = n.params().raw().clone();
            n.process(now, Some(&f), &mut |_| sent += 1);
            n.control(now, 0.1, 0.0, 0.0, 0.001);
            let after = n.params().raw();
            if after != &before {
                // only ever a set that passes the check ...
                prop_assert!(check(after).is_ok());
                // ... and safety-relevant values change only from pre-operational
                for d in PARAMS.iter().filter(|d| d.safety) {
                    if after.get(d.id).to_bits() != before.get(d.id).to_bits() {
                        prop_assert!(
                            state_before == NmtState::PreOperational || f.id() == 0,
                            "{} changed in {:?}", d.name, state_before
                        );
                    }
                }
            }
            prop_assert!(check(after).is_ok());
            prop_assert!(n.params().get(ParamId::TorqueLimit) >= 0.0);
        }
        // still alive: after an NMT pre-operational it answers an SDO read of its identity
        let _ = sent;
        let nmt = CanFrame::new(0, &[0x80, ID]).unwrap();
        n.process(now, Some(&nmt), &mut |_| {});
        // a transfer the frames left open ends at the SDO timeout (a block download's sub-block
        // takes every frame on the channel as a segment, as CiA 301 has it)
        now += 1_100_000;
        n.process(now, None, &mut |_| {});
        let r = sdo_req(&mut n, sdo::upload_request(0x1018, 2));
        prop_assert_eq!(r, [0x43, 0x18, 0x10, 0x02, 0x01, 0x00, 0x4E, 0x4A]);
    }
}

/// The node lives in the G431's 32 KiB RAM next to the control loop: keep it small. Most of it
/// is the staged and the committed parameter sets (each with the 256-cell gravity table and
/// its sigma) and the 1 KiB segmented-download buffer.
#[test]
fn node_fits_its_ram_budget() {
    use joint_core::canopen::node::NoStorage;
    let size = std::mem::size_of::<Node<NoStorage>>();
    println!("Node<NoStorage>: {size} bytes");
    assert!(size <= 8 * 1024, "{size} bytes");
}
