//! Golden frames of the CANopen node: exact COB-IDs and bytes for every service, as a CANopen
//! master would see them on the bus. A change here is a protocol change.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, NMT_PRE_OPERATIONAL, NMT_START};
use joint_core::canopen::CanFrame;
use joint_core::params::{ParamId, RawParams};
use joint_core::store::set_crc;

const ID: u8 = 5;

struct Bench {
    node: Node<MemoryStorage>,
    now: u64,
}

impl Bench {
    fn new() -> Bench {
        let mut b = Bench { node: Node::new(NodeConfig::new(ID), MemoryStorage::default(), 0), now: 0 };
        let boot = b.run(None);
        assert_eq!(boot, vec![(0x705, vec![0x00])], "boot-up message");
        b
    }

    fn run(&mut self, rx: Option<(u16, &[u8])>) -> Vec<(u16, Vec<u8>)> {
        let mut out = Vec::new();
        let f = rx.map(|(id, d)| CanFrame::new(id, d).unwrap());
        self.node.process(self.now, f.as_ref(), &mut |f: CanFrame| out.push((f.id(), f.data().to_vec())));
        out
    }

    /// Send and return only the frames on `id`.
    fn ask(&mut self, id: u16, d: &[u8], want: u16) -> Vec<Vec<u8>> {
        self.run(Some((id, d))).into_iter().filter(|(i, _)| *i == want).map(|(_, d)| d).collect()
    }

    fn sdo(&mut self, d: [u8; 8]) -> Vec<u8> {
        let r = self.ask(0x605, &d, 0x585);
        assert_eq!(r.len(), 1, "one SDO response for {d:02X?}");
        r.into_iter().next().unwrap()
    }

    /// The commit request that names `set` (0x2205 ← its CRC-32).
    fn commit_request(set: &RawParams) -> [u8; 8] {
        let c = set_crc(set).to_le_bytes();
        [0x23, 0x05, 0x22, 0x00, c[0], c[1], c[2], c[3]]
    }

    fn advance_ms(&mut self, ms: u64) -> Vec<(u16, Vec<u8>)> {
        self.now += ms * 1000;
        self.run(None)
    }
}

#[test]
fn boot_up_then_heartbeat_in_pre_operational() {
    let mut b = Bench::new();
    assert!(b.advance_ms(50).is_empty());
    assert_eq!(b.advance_ms(50), vec![(0x705, vec![0x7F])]);
    assert_eq!(b.advance_ms(100), vec![(0x705, vec![0x7F])]);
}

#[test]
fn nmt_start_gives_operational_heartbeat_and_tpdos() {
    let mut b = Bench::new();
    let out = b.run(Some((0x000, &[NMT_START, ID])));
    // TPDO1 and TPDO2 at once on entering operational (event timer restarts), zero state:
    // q, qd, tau = 0, faults = 0; q̈, τ_meas, temp = 0, gain 0 (soft start not yet run).
    assert_eq!(out, vec![(0x185, vec![0; 8]), (0x285, vec![0; 8])]);
    let out = b.advance_ms(100);
    assert!(out.contains(&(0x705, vec![0x05])), "{out:02X?}");
    // NMT to another node is ignored, broadcast (0) is obeyed.
    b.run(Some((0x000, &[NMT_PRE_OPERATIONAL, 6])));
    assert_eq!(b.node.nmt_state().name(), "operational");
    b.run(Some((0x000, &[NMT_PRE_OPERATIONAL, 0])));
    assert_eq!(b.node.nmt_state().name(), "pre-operational");
}

#[test]
fn tpdo1_scaling() {
    let mut b = Bench::new();
    b.run(Some((0x77F, &[0x05]))); // host heartbeat
    b.run(Some((0x000, &[NMT_START, ID])));
    b.node.control(b.now, 0.5, -1.25, 3.0, 0.001);
    b.advance_ms(10);
    let (data, len) = b.node.tpdo_payload(0);
    assert_eq!(len, 8);
    // q = 0.5 rad / 1e-4 = 5000 = 0x1388; qd = -1.25 / 1e-3 = -1250 = 0xFB1E; tau 0; faults 0.
    assert_eq!(data, [0x88, 0x13, 0x1E, 0xFB, 0x00, 0x00, 0x00, 0x00]);
    let (d2, _) = b.node.tpdo_payload(1);
    // q̈ = 3.0 / 1e-2 = 300 = 0x012C
    assert_eq!(&d2[..2], &[0x2C, 0x01]);
}

#[test]
fn sdo_expedited_upload_device_type_and_identity() {
    let mut b = Bench::new();
    assert_eq!(b.sdo([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]), vec![0x43, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
    // product code 0x4A4E0001
    assert_eq!(b.sdo([0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]), vec![0x43, 0x18, 0x10, 0x02, 0x01, 0x00, 0x4E, 0x4A]);
    // sub 0 of identity: 4, one byte (n = 3 → 0x4F)
    assert_eq!(b.sdo([0x40, 0x18, 0x10, 0x00, 0, 0, 0, 0]), vec![0x4F, 0x18, 0x10, 0x00, 4, 0, 0, 0]);
    // producer heartbeat 100 ms, two bytes (0x4B)
    assert_eq!(b.sdo([0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0]), vec![0x4B, 0x17, 0x10, 0x00, 100, 0, 0, 0]);
}

#[test]
fn sdo_segmented_upload_device_name() {
    let mut b = Bench::new();
    // "joint-node": 10 bytes, segmented.
    assert_eq!(b.sdo([0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]), vec![0x41, 0x08, 0x10, 0x00, 10, 0, 0, 0]);
    assert_eq!(b.sdo([0x60, 0, 0, 0, 0, 0, 0, 0]), [&[0x00][..], b"joint-n"].concat());
    // toggle 1, 4 bytes unused (n = 4 → 0x08), last (c = 1)
    assert_eq!(b.sdo([0x70, 0, 0, 0, 0, 0, 0, 0]), vec![0x19, b'o', b'd', b'e', 0, 0, 0, 0]);
}

#[test]
fn sdo_expedited_download_parameter_and_read_back() {
    let mut b = Bench::new();
    // friction_a = 1.5 (0x3FC00000) at 0x2000
    assert_eq!(b.sdo([0x23, 0x00, 0x20, 0x00, 0x00, 0x00, 0xC0, 0x3F]), vec![0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]);
    assert_eq!(b.sdo([0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]), vec![0x43, 0x00, 0x20, 0x00, 0x00, 0x00, 0xC0, 0x3F]);
    // staged, not yet running
    assert_eq!(b.node.params().get(ParamId::FrictionA), 0.0);
    assert_eq!(b.sdo([0x40, 0x03, 0x22, 0x00, 0, 0, 0, 0]), vec![0x4F, 0x03, 0x22, 0x00, 1, 0, 0, 0]);
    // commit, naming the set meant: the defaults with friction_a = 1.5
    let mut want = RawParams::defaults();
    want.set(ParamId::FrictionA, 1.5);
    assert_eq!(b.sdo(Bench::commit_request(&want)), vec![0x60, 0x05, 0x22, 0x00, 0, 0, 0, 0]);
    assert_eq!(b.node.params().get(ParamId::FrictionA), 1.5);
    assert_eq!(b.sdo([0x40, 0x03, 0x22, 0x00, 0, 0, 0, 0]), vec![0x4F, 0x03, 0x22, 0x00, 0, 0, 0, 0]);
}

#[test]
fn sdo_segmented_download_table_torque() {
    let mut b = Bench::new();
    // 3 f32 = 12 bytes: 1.0, 2.0, -1.0
    let bytes: Vec<u8> = [1.0f32, 2.0, -1.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    assert_eq!(b.sdo([0x21, 0x02, 0x21, 0x00, 12, 0, 0, 0]), vec![0x60, 0x02, 0x21, 0x00, 0, 0, 0, 0]);
    let mut s1 = [0u8; 8];
    s1[1..8].copy_from_slice(&bytes[..7]);
    assert_eq!(b.sdo(s1), vec![0x20, 0, 0, 0, 0, 0, 0, 0]);
    // toggle 1, 5 bytes (n = 2 → 0x04), last → 0x15
    let mut s2 = [0x15u8, 0, 0, 0, 0, 0, 0, 0];
    s2[1..6].copy_from_slice(&bytes[7..]);
    assert_eq!(b.sdo(s2), vec![0x30, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(&b.node.staged().table.torque[..3], &[1.0, 2.0, -1.0]);
}

#[test]
fn sdo_aborts() {
    let mut b = Bench::new();
    // read-only object written: 0x06010002
    assert_eq!(b.sdo([0x23, 0x00, 0x10, 0x00, 1, 0, 0, 0]), vec![0x80, 0x00, 0x10, 0x00, 0x02, 0x00, 0x01, 0x06]);
    // write-only object read: 0x06010001
    assert_eq!(b.sdo([0x40, 0x00, 0x22, 0x00, 0, 0, 0, 0]), vec![0x80, 0x00, 0x22, 0x00, 0x01, 0x00, 0x01, 0x06]);
    // object missing: 0x06020000
    assert_eq!(b.sdo([0x40, 0x00, 0x30, 0x00, 0, 0, 0, 0]), vec![0x80, 0x00, 0x30, 0x00, 0x00, 0x00, 0x02, 0x06]);
    // sub-index missing: 0x06090011
    assert_eq!(b.sdo([0x40, 0x18, 0x10, 0x09, 0, 0, 0, 0]), vec![0x80, 0x18, 0x10, 0x09, 0x11, 0x00, 0x09, 0x06]);
    // friction_v_band (0x2003, max 1.0) = 2.0: too high 0x06090031
    assert_eq!(b.sdo([0x23, 0x03, 0x20, 0x00, 0, 0, 0, 0x40]), vec![0x80, 0x03, 0x20, 0x00, 0x31, 0x00, 0x09, 0x06]);
    // friction_a = -1.0: too low 0x06090032
    assert_eq!(b.sdo([0x23, 0x00, 0x20, 0x00, 0, 0, 0x80, 0xBF]), vec![0x80, 0x00, 0x20, 0x00, 0x32, 0x00, 0x09, 0x06]);
    // NaN: invalid value 0x06090030
    assert_eq!(b.sdo([0x23, 0x00, 0x20, 0x00, 0, 0, 0xC0, 0x7F]), vec![0x80, 0x00, 0x20, 0x00, 0x30, 0x00, 0x09, 0x06]);
    // 2 bytes to a REAL32: length too low 0x06070013; 1 byte to U16 heartbeat ok? no: too low
    assert_eq!(b.sdo([0x2B, 0x00, 0x20, 0x00, 0, 0, 0, 0]), vec![0x80, 0x00, 0x20, 0x00, 0x13, 0x00, 0x07, 0x06]);
    // segmented download announcing 8 bytes for a REAL32: too high 0x06070012
    assert_eq!(b.sdo([0x21, 0x00, 0x20, 0x00, 8, 0, 0, 0]), vec![0x80, 0x00, 0x20, 0x00, 0x12, 0x00, 0x07, 0x06]);
    // ccs 7 does not exist: command not valid 0x05040001 (block transfer: tests/canopen_block.rs)
    assert_eq!(b.sdo([0xE0, 0x00, 0x20, 0x00, 0, 0, 0, 0]), vec![0x80, 0x00, 0x20, 0x00, 0x01, 0x00, 0x04, 0x05]);
    // nothing of the above changed the staged set
    assert_eq!(b.node.staged(), b.node.params().raw());

    // compensation_fraction (0x200F) is safety-relevant: refused in operational, 0x08000022
    b.run(Some((0x000, &[NMT_START, ID])));
    assert_eq!(b.sdo([0x23, 0x0F, 0x20, 0x00, 0, 0, 0, 0x3F]), vec![0x80, 0x0F, 0x20, 0x00, 0x22, 0x00, 0x00, 0x08]);
    // ... and accepted in pre-operational
    b.run(Some((0x000, &[NMT_PRE_OPERATIONAL, ID])));
    assert_eq!(b.sdo([0x23, 0x0F, 0x20, 0x00, 0, 0, 0, 0x3F]), vec![0x60, 0x0F, 0x20, 0x00, 0, 0, 0, 0]);
}

#[test]
fn refused_commit_keeps_the_old_set_and_reports_the_parameter() {
    let mut b = Bench::new();
    let before = b.node.params().raw().clone();
    // controller_accel_cutoff (0x2016) = 600 Hz with the 1000 Hz control rate: in range but
    // inconsistent (must be below half the rate).
    let v = 600.0f32.to_le_bytes();
    assert_eq!(b.sdo([0x23, 0x16, 0x20, 0x00, v[0], v[1], v[2], v[3]])[0], 0x60);
    let mut want = before.clone();
    want.set(ParamId::AccelCutoff, 600.0);
    let out = b.run(Some((0x605, &Bench::commit_request(&want))));
    // abort 0x06090030 on the commit object
    assert_eq!(out[0], (0x585, vec![0x80, 0x05, 0x22, 0x00, 0x30, 0x00, 0x09, 0x06]));
    // EMCY 0x6320, error register 0 (no fault latched), code 3 (inconsistent), param 22 (0x16)
    assert_eq!(out[1], (0x085, vec![0x20, 0x63, 0x00, 0x03, 0x16, 0x00, 0x00, 0x00]));
    assert_eq!(b.node.params().raw(), &before);
    // error record 0x2201: code 3, param 0x0016, message names the parameter
    assert_eq!(b.sdo([0x40, 0x01, 0x22, 0x01, 0, 0, 0, 0]), vec![0x4F, 0x01, 0x22, 0x01, 3, 0, 0, 0]);
    assert_eq!(b.sdo([0x40, 0x01, 0x22, 0x02, 0, 0, 0, 0]), vec![0x4B, 0x01, 0x22, 0x02, 0x16, 0, 0, 0]);
    let msg = b.node.commit_error().unwrap().message.clone();
    assert!(msg.starts_with("controller_accel_cutoff"), "{msg}");
}

#[test]
fn heartbeat_loss_sends_emcy_and_fades_torque() {
    let mut b = Bench::new();
    b.run(Some((0x77F, &[0x05])));
    b.run(Some((0x000, &[NMT_START, ID])));
    // controller_heartbeat_timeout default 0.5 s: at 0.4 s still fine
    for _ in 0..400 {
        b.now += 1000;
        b.node.control(b.now, 0.0, 0.0, 0.0, 0.001);
        b.run(None);
    }
    b.run(Some((0x77F, &[0x05])));
    let mut emcy = Vec::new();
    for _ in 0..1000 {
        b.now += 1000;
        b.node.control(b.now, 0.0, 0.0, 0.0, 0.001);
        emcy.extend(b.run(None).into_iter().filter(|(id, _)| *id == 0x085));
    }
    // one EMCY 0x8130, error register generic + communication (0x11), faults = 0x0001
    assert_eq!(emcy, vec![(0x085, vec![0x30, 0x81, 0x11, 0x01, 0x00, 0x00, 0x00, 0x00])]);
    assert_eq!(b.node.safety().gain(), 0.0);
    // clear faults (0x2202) is refused without the host, accepted with it, then EMCY reset.
    assert_eq!(b.sdo([0x2F, 0x02, 0x22, 0x00, 1, 0, 0, 0]), vec![0x80, 0x02, 0x22, 0x00, 0x22, 0x00, 0x00, 0x08]);
    b.run(Some((0x77F, &[0x05])));
    let out = b.run(Some((0x605, &[0x2F, 0x02, 0x22, 0x00, 1, 0, 0, 0])));
    assert_eq!(out, vec![(0x585, vec![0x60, 0x02, 0x22, 0x00, 0, 0, 0, 0]), (0x085, vec![0, 0, 0, 0, 0, 0, 0, 0])]);
}

#[test]
fn rpdos_set_assist_command_and_other_angles() {
    let mut b = Bench::new();
    b.run(Some((0x000, &[NMT_START, ID])));
    // RPDO1 0x205: assist 0x2710 = 10000 × 0.01 = 100 N·m
    b.run(Some((0x205, &[0x10, 0x27])));
    assert_eq!(b.node.assist_cmd(), 100.0);
    // RPDO2 listens to joint 6's TPDO1 once its COB-ID (0x1401 sub 1) is set to 0x186.
    assert_eq!(b.sdo([0x23, 0x01, 0x14, 0x01, 0x86, 0x01, 0, 0])[0], 0x60);
    b.run(Some((0x186, &[0x88, 0x13, 0, 0, 0, 0, 0, 0])));
    assert_eq!(b.node.others()[0], 5000.0 * 1e-4);
    // too short for its mapping: EMCY 0x8210, value unchanged
    let out = b.run(Some((0x205, &[0x01])));
    assert_eq!(out, vec![(0x085, vec![0x10, 0x82, 0x00, 0x00, 0x01, 0, 0, 0])]);
    assert_eq!(b.node.assist_cmd(), 100.0);
}

#[test]
fn store_and_restore_signatures() {
    let mut b = Bench::new();
    let v = 2.5f32.to_le_bytes();
    b.sdo([0x23, 0x02, 0x20, 0x00, v[0], v[1], v[2], v[3]]); // friction_c
    let mut want = RawParams::defaults();
    want.set(ParamId::FrictionC, 2.5);
    b.sdo(Bench::commit_request(&want));
    // wrong signature: 0x08000020
    assert_eq!(b.sdo([0x23, 0x10, 0x10, 0x01, 1, 2, 3, 4]), vec![0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08]);
    assert_eq!(b.node.storage().saves, 0);
    // "save"
    assert_eq!(b.sdo([0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']), vec![0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0]);
    assert_eq!(b.node.storage().stored.as_ref().unwrap().get(ParamId::FrictionC), 2.5);
    // reset node: the stored set comes back, with a boot-up
    let out = b.run(Some((0x000, &[0x81, ID])));
    assert_eq!(out[0], (0x705, vec![0x00]));
    assert_eq!(b.node.params().get(ParamId::FrictionC), 2.5);
    // "load": stored set forgotten; the running set and the staged values stay until the reset
    // (CiA 301), so no later commit applies the defaults behind the user's back
    assert_eq!(b.sdo([0x23, 0x11, 0x10, 0x01, b'l', b'o', b'a', b'd']), vec![0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0]);
    assert!(b.node.storage().stored.is_none());
    assert_eq!(b.node.staged().get(ParamId::FrictionC), 2.5);
    assert_eq!(b.node.params().get(ParamId::FrictionC), 2.5);
    assert_eq!(b.sdo(Bench::commit_request(&want))[0], 0x60); // a commit changes nothing
    assert_eq!(b.node.params().get(ParamId::FrictionC), 2.5);
    b.run(Some((0x000, &[0x81, ID])));
    assert_eq!(b.node.params().get(ParamId::FrictionC), 0.0);
}

#[test]
fn sdo_timeout_aborts_a_stalled_transfer() {
    let mut b = Bench::new();
    b.sdo([0x21, 0x02, 0x21, 0x00, 12, 0, 0, 0]);
    let out = b.advance_ms(1001);
    assert!(out.contains(&(0x585, vec![0x80, 0x02, 0x21, 0x00, 0x00, 0x00, 0x04, 0x05])), "{out:02X?}");
}

/// A commit that names its set (0x2205 ← CRC of the staged set, readable at 0x2204:2) commits
/// only that set: a value staged in between (another master on the bus) makes it refuse, with
/// commit error 7, and nothing goes live. 0x2204:1 says which set runs.
#[test]
fn a_commit_by_crc_commits_only_the_named_set() {
    let mut b = Bench::new();
    let read_u32 = |b: &mut Bench, sub: u8| {
        let r = b.sdo([0x40, 0x04, 0x22, sub, 0, 0, 0, 0]);
        assert_eq!(r[0], 0x43, "{r:02X?}");
        u32::from_le_bytes([r[4], r[5], r[6], r[7]])
    };
    let active0 = read_u32(&mut b, 1);
    assert_eq!(read_u32(&mut b, 2), active0, "nothing staged: the two agree");
    let v = 2.5f32.to_le_bytes();
    b.sdo([0x23, 0x02, 0x20, 0x00, v[0], v[1], v[2], v[3]]); // friction_c
    let named = read_u32(&mut b, 2);
    assert_ne!(named, active0);
    // another master stages a value before the commit
    let w = 0.5f32.to_le_bytes();
    b.sdo([0x23, 0x01, 0x20, 0x00, w[0], w[1], w[2], w[3]]); // friction_b
    let c = named.to_le_bytes();
    let r = b.sdo([0x23, 0x05, 0x22, 0x00, c[0], c[1], c[2], c[3]]);
    assert_eq!(r, vec![0x80, 0x05, 0x22, 0x00, 0x22, 0x00, 0x00, 0x08], "refused: device state");
    assert_eq!(b.node.params().get(ParamId::FrictionC), 0.0, "nothing went live");
    assert_eq!(read_u32(&mut b, 1), active0);
    let r = b.sdo([0x40, 0x01, 0x22, 0x01, 0, 0, 0, 0]);
    assert_eq!(r[4], 7, "commit error 7: {r:02X?}");
    // naming what is staged now commits it, and 0x2204:1 says so
    let now = read_u32(&mut b, 2);
    let c = now.to_le_bytes();
    assert_eq!(b.sdo([0x23, 0x05, 0x22, 0x00, c[0], c[1], c[2], c[3]])[0], 0x60);
    assert_eq!(b.node.params().get(ParamId::FrictionC), 2.5);
    assert_eq!(read_u32(&mut b, 1), now);
    assert_eq!(now, joint_core::store::set_crc(b.node.params().raw()), "the host computes the same CRC");
}

/// A plain commit (0x2200 ← 1) named no set, so it made live whatever was staged: another
/// master's half-pushed values with one's own (issue 21, "33 old + 1 new"). It is refused with
/// 0x06010000 (unsupported access), EMCY 0x6320 and commit error 9 whose message says how to
/// commit; nothing goes live and the staged set stays for its master to commit by CRC or
/// discard (0x2200 ← 0, still served).
#[test]
fn a_plain_commit_is_refused_and_says_how_to_commit() {
    let mut b = Bench::new();
    let before = b.node.params().raw().clone();
    let v = 2.5f32.to_le_bytes();
    b.sdo([0x23, 0x02, 0x20, 0x00, v[0], v[1], v[2], v[3]]); // friction_c
    let out = b.run(Some((0x605, &[0x2F, 0x00, 0x22, 0x00, 1, 0, 0, 0])));
    assert_eq!(out[0], (0x585, vec![0x80, 0x00, 0x22, 0x00, 0x00, 0x00, 0x01, 0x06]));
    // EMCY 0x6320, error register 0, code 9, no parameter (0xFFFF)
    assert_eq!(out[1], (0x085, vec![0x20, 0x63, 0x00, 0x09, 0xFF, 0xFF, 0x00, 0x00]));
    assert_eq!(out.len(), 2);
    assert_eq!(b.node.params().raw(), &before, "nothing went live");
    assert_eq!(b.sdo([0x40, 0x03, 0x22, 0x00, 0, 0, 0, 0]), vec![0x4F, 0x03, 0x22, 0x00, 1, 0, 0, 0], "still staged");
    assert_eq!(b.sdo([0x40, 0x01, 0x22, 0x01, 0, 0, 0, 0]), vec![0x4F, 0x01, 0x22, 0x01, 9, 0, 0, 0]);
    let msg = b.node.commit_error().unwrap().message.clone();
    assert!(msg.contains("0x2205") && msg.contains("CRC"), "{msg}");
    // any other value than 0 or 1: invalid value
    assert_eq!(b.sdo([0x2F, 0x00, 0x22, 0x00, 2, 0, 0, 0]), vec![0x80, 0x00, 0x22, 0x00, 0x30, 0x00, 0x09, 0x06]);
    // the commit that names the set goes through
    let mut want = before.clone();
    want.set(ParamId::FrictionC, 2.5);
    assert_eq!(b.sdo(Bench::commit_request(&want)), vec![0x60, 0x05, 0x22, 0x00, 0, 0, 0, 0]);
    assert_eq!(b.node.params().raw(), &want);
}
