//! jointctl's CAN side against simulated joints on the in-process bus (virtual time, real
//! frame lengths): push/pull round trips, a push cut off halfway, heartbeat loss, scan, and
//! the push timing against the wire-time minimum of its SDO frames.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::master::Master;
use joint_can::sim_bus::{SharedSimBus, SimBus};
use joint_can::transfer::{self, PushOptions};
use joint_core::canopen::node::{MemoryStorage, NmtState, ParamStorage, EMCY_HEARTBEAT, NMT_START};
use joint_core::canopen::pdo::Tpdo1;
use joint_core::params::{ParamId, RawParams};
use joint_core::safety::Faults;
use joint_formats::model_file::ModelFile;
use jointctl::sim_joint::{JointSim, SimStorage};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

fn root() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn model(name: &str) -> RawParams {
    ModelFile::read_file(&root().join("examples/models").join(name)).unwrap().raw_params().unwrap()
}

struct Rig {
    bus: SharedSimBus,
    joints: Vec<Arc<Mutex<JointSim>>>,
    m: Master,
}

fn rig(bitrate: u32, nodes: &[u8]) -> Rig {
    let mut bus = SimBus::new(bitrate);
    let mut joints = Vec::new();
    for &n in nodes {
        let j = Arc::new(Mutex::new(JointSim::new(n, None, SimStorage::Memory(MemoryStorage::default()), 0)));
        bus.attach(j.clone());
        joints.push(j);
    }
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    let mut m = Master::new(Box::new(bus.clone()));
    m.listen(Duration::from_millis(5)).unwrap();
    Rig { bus, joints, m }
}

fn running(j: &Arc<Mutex<JointSim>>) -> RawParams {
    j.lock().unwrap().node.params().raw().clone()
}

#[test]
fn push_then_pull_round_trips_the_trunk_model() {
    let mut r = rig(1_000_000, &[5]);
    let want = model("trunk-right.toml");
    let rep =
        transfer::push(&mut r.m, 5, &want, PushOptions { save: true, ..Default::default() }, &mut |_| {}).unwrap();
    assert!(rep.saved);
    // running on the joint, bit for bit, and stored
    assert_eq!(running(&r.joints[0]), want);
    assert_eq!(r.joints[0].lock().unwrap().node.storage_mut().load().unwrap(), want);
    let (pulled, pending) = transfer::pull(&mut r.m, 5).unwrap();
    assert!(!pending);
    assert_eq!(pulled, want);
    // and through the model TOML text: the same values again
    let text = ModelFile::from_raw(&pulled, Some("trunk-right"), &[]).to_toml_string();
    let back = ModelFile::parse(&text, "pulled.toml").unwrap().raw_params().unwrap();
    assert_eq!(back, want);
}

#[test]
fn push_then_pull_round_trips_a_two_axis_gravity_table_with_sigma() {
    let text = r#"
name = "arm-elbow"
[weight]
amplitude = 1.5
[gravity_table]
axes = ["q", "q_shoulder"]
grid = [[0.0, 0.5, 1.0, 1.5], [-0.5, 0.0, 0.5]]
torque = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1]
sigma = [0.1, 0.1, 0.1, 0.2, 0.2, 0.2, 0.3, 0.3, 0.3, 0.4, 0.4, 0.4]
sigma_model = 0.3
clamp_k = 2.0
[compensation]
fraction = 0.5
"#;
    let mf = ModelFile::parse(text, "arm.toml").unwrap();
    let want = mf.raw_params().unwrap();
    let mut r = rig(1_000_000, &[3]);
    transfer::push(&mut r.m, 3, &want, PushOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(running(&r.joints[0]), want);
    let (pulled, _) = transfer::pull(&mut r.m, 3).unwrap();
    assert_eq!(pulled, want);
    let back = ModelFile::from_raw(&pulled, Some("arm-elbow"), &mf.other_columns());
    assert_eq!(back.table, mf.table);
}

#[test]
fn push_then_pull_round_trips_presliding() {
    // The trunk model with its Coulomb friction as a Dahl state (dry friction joining the level).
    let text = format!(
        "{}\n[dry_friction]\nc = 0.4\n\n[presliding]\nsigma = 1250.0\n",
        std::fs::read_to_string(root().join("examples/models/trunk-right.toml")).unwrap()
    );
    let mf = ModelFile::parse(&text, "dahl.toml").unwrap();
    let want = mf.raw_params().unwrap();
    assert_eq!(want.get(ParamId::PreslidingSigma), 1250.0);
    let mut r = rig(1_000_000, &[4]);
    transfer::push(&mut r.m, 4, &want, PushOptions { save: true, ..Default::default() }, &mut |_| {}).unwrap();
    let j = running(&r.joints[0]);
    assert_eq!(j, want);
    {
        let mut joint = r.joints[0].lock().unwrap();
        let p = joint.node.params();
        assert!(p.terms().presliding.on && p.terms().presliding.c == 2.72, "the joint runs the Dahl state");
        assert_eq!(joint.node.storage_mut().load().unwrap(), want, "and stores it");
    }
    let (pulled, pending) = transfer::pull(&mut r.m, 4).unwrap();
    assert!(!pending);
    assert_eq!(pulled, want);
    let written = ModelFile::from_raw(&pulled, Some("dahl"), &[]).to_toml_string();
    assert!(written.contains("[presliding]\nsigma = 1250.0"), "{written}");
    assert_eq!(ModelFile::parse(&written, "pulled.toml").unwrap().raw_params().unwrap(), want);
    // A file without the section switches the state off on the joint again.
    let plain = model("trunk-right.toml");
    transfer::push(&mut r.m, 4, &plain, PushOptions::default(), &mut |_| {}).unwrap();
    assert!(!r.joints[0].lock().unwrap().node.params().terms().presliding.on);
    assert_eq!(transfer::pull(&mut r.m, 4).unwrap().0.get(ParamId::PreslidingSigma), 0.0);
}

#[test]
fn eds_lists_presliding_after_every_older_object() {
    let eds = joint_can::eds::generate();
    let entry = "[2025]\nParameterName=presliding_sigma\nObjectType=0x7\nDataType=0x0008\nAccessType=rw\n\
                 DefaultValue=0\nLowLimit=0\nHighLimit=10000000\n";
    assert!(eds.contains(entry), "no presliding entry at 0x2025:\n{eds}");
    // The objects before it keep their indices.
    assert!(eds.contains("[2000]\nParameterName=friction_a\n"));
    assert!(eds.contains("[2024]\nParameterName=dry_friction_c\n"));
}

#[test]
fn a_push_cut_off_halfway_leaves_the_old_set_running() {
    let mut r = rig(1_000_000, &[5]);
    let old = model("trunk-right.toml");
    transfer::push(&mut r.m, 5, &old, PushOptions::default(), &mut |_| {}).unwrap();
    let new = model("trunk-left.toml");
    assert_ne!(old, new);
    // the cable is pulled after 15 more master frames: 15 expedited writes (one request each)
    {
        let mut b = r.bus.0.lock().unwrap();
        b.cut_master_after_more(15);
    }
    r.m.sdo_timeout = Duration::from_millis(200);
    // the master's own heartbeat counts against the cut too: keep it off for this test
    r.m.heartbeat_us = 0;
    let mut steps = 0;
    let err = transfer::push(&mut r.m, 5, &new, PushOptions::default(), &mut |_| steps += 1).unwrap_err();
    assert!(err.to_string().contains("no answer"), "{err}");
    assert_eq!(steps, 15, "15 parameters staged, then silence");
    let j = r.joints[0].lock().unwrap();
    assert_eq!(j.node.params().raw(), &old, "the old set must still run");
    assert_ne!(j.node.staged(), &old, "the cut push did stage some values");
    assert_eq!(j.node.staged().get(ParamId::FrictionA), new.get(ParamId::FrictionA));
}

#[test]
fn heartbeat_loss_trips_the_watchdog_and_is_reported() {
    let mut r = rig(1_000_000, &[5]);
    r.m.keep_other = true;
    r.m.listen(Duration::from_millis(200)).unwrap();
    // the joint booted before our heartbeat: acknowledge, start, and run for a second
    r.m.write(5, 0x2202, 0, &[1]).unwrap();
    r.m.nmt(5, NMT_START).unwrap();
    r.m.listen(Duration::from_secs(1)).unwrap();
    assert_eq!(r.m.seen[&5].state, Some(NmtState::Operational));
    assert!(r.m.emcy.iter().all(|(_, _, d)| u16::from_le_bytes([d[0], d[1]]) != EMCY_HEARTBEAT));
    {
        let j = r.joints[0].lock().unwrap();
        assert!(j.node.safety().faults().is_empty());
        assert_eq!(j.node.safety().gain(), 1.0);
    }
    // the host goes silent
    r.m.heartbeat_us = 0;
    r.m.other.clear();
    r.m.listen(Duration::from_secs(1)).unwrap();
    let emcy: Vec<_> =
        r.m.emcy.iter().filter(|(n, _, d)| *n == 5 && u16::from_le_bytes([d[0], d[1]]) == EMCY_HEARTBEAT).collect();
    assert_eq!(emcy.len(), 1, "{:?}", r.m.emcy);
    let j = r.joints[0].lock().unwrap();
    assert!(j.node.safety().faults().contains(Faults::HEARTBEAT_LOST));
    assert_eq!(j.node.safety().gain(), 0.0, "faded out within fault_ramp_time (0.2 s)");
    // and the TPDOs say so
    let last = r.m.other.iter().rev().find(|(_, f)| f.id() == 0x185).unwrap();
    assert_eq!(
        Tpdo1::decode(last.1.data()).unwrap().faults & Faults::HEARTBEAT_LOST.bits(),
        Faults::HEARTBEAT_LOST.bits()
    );
}

#[test]
fn scan_finds_every_node_by_heartbeat() {
    let mut r = rig(500_000, &[2, 7, 9]);
    r.m.listen(Duration::from_millis(300)).unwrap();
    let nodes: Vec<u8> = r.m.seen.keys().copied().collect();
    assert_eq!(nodes, vec![2, 7, 9]);
    for n in nodes {
        assert_eq!(r.m.read_string(n, 0x1008, 0).unwrap(), "joint-node");
    }
}

#[test]
fn push_of_the_trunk_set_takes_at_most_1_2_times_its_wire_minimum_at_1_mbit() {
    let mut r = rig(1_000_000, &[5]);
    let want = model("trunk-right.toml");
    let rep = transfer::push(&mut r.m, 5, &want, PushOptions::default(), &mut |_| {}).unwrap();
    let wire = transfer::wire_minimum_us(&rep, 1_000_000);
    let ratio = rep.elapsed_us as f64 / wire;
    println!(
        "push trunk-right at 1 Mbit/s: {} SDO transfers, {} frames, {} bits; elapsed {:.3} ms, wire minimum {:.3} ms, ratio {:.3}",
        rep.sdo_transfers,
        rep.frames,
        rep.bits,
        rep.elapsed_us as f64 / 1000.0,
        wire / 1000.0,
        ratio
    );
    assert_eq!(rep.frames, 2 * rep.sdo_transfers as u64, "expedited only: one request, one response each");
    assert!(ratio >= 1.0, "cannot beat the wire: {ratio}");
    assert!(ratio <= 1.2, "push took {ratio:.3}× its wire minimum");
}

#[test]
fn push_to_an_operational_joint_needs_pre_operational_only_for_changed_safety_values() {
    let mut r = rig(1_000_000, &[5]);
    let mut set = model("trunk-right.toml");
    transfer::push(&mut r.m, 5, &set, PushOptions::default(), &mut |_| {}).unwrap();
    r.m.nmt(5, NMT_START).unwrap();
    r.m.listen(Duration::from_millis(200)).unwrap();
    assert_eq!(r.m.seen[&5].state, Some(NmtState::Operational));
    // friction retuned live: safety values unchanged, so the push goes through while running
    set.set(ParamId::FrictionC, 2.5);
    transfer::push(&mut r.m, 5, &set, PushOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(running(&r.joints[0]).get(ParamId::FrictionC), 2.5);
    // a new compensation fraction is refused while operational, with the way out named
    let mut unsafe_set = set.clone();
    unsafe_set.set(ParamId::Fraction, 0.5);
    let err = transfer::push(&mut r.m, 5, &unsafe_set, PushOptions::default(), &mut |_| {}).unwrap_err();
    assert!(
        err.to_string().contains("compensation_fraction") && err.to_string().contains("--pre-operational"),
        "{err}"
    );
    assert_eq!(running(&r.joints[0]), set);
    let opts = PushOptions { pre_operational: true, ..Default::default() };
    transfer::push(&mut r.m, 5, &unsafe_set, opts, &mut |_| {}).unwrap();
    assert_eq!(running(&r.joints[0]), unsafe_set);
}

#[test]
fn a_joint_reads_another_joints_angle_from_its_tpdo() {
    // Joint 5 moves (trunk plant under the simulated operator); joint 6's gravity-table input
    // slot 1 listens to joint 5's TPDO1 once RPDO2's COB-ID (0x1401:1) points at 0x185.
    let pf = host_sim::plant::PlantFile::read_file(&root().join("examples/plants/trunk-right.toml")).unwrap();
    let mut bus = SimBus::new(1_000_000);
    let j5 = Arc::new(Mutex::new(JointSim::new(5, Some(&pf), SimStorage::Memory(MemoryStorage::default()), 0)));
    let j6 = Arc::new(Mutex::new(JointSim::new(6, None, SimStorage::Memory(MemoryStorage::default()), 0)));
    bus.attach(j5.clone());
    bus.attach(j6.clone());
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    let mut m = Master::new(Box::new(bus.clone()));
    m.listen(Duration::from_millis(10)).unwrap();
    m.write(6, 0x1401, 1, &0x185u32.to_le_bytes()).unwrap();
    m.nmt(0, NMT_START).unwrap();
    let mut worst: f32 = 0.0;
    let mut moved: f32 = 0.0;
    for _ in 0..40 {
        m.listen(Duration::from_millis(50)).unwrap();
        let q5 = j5.lock().unwrap().node.joint_state().q;
        let seen = j6.lock().unwrap().node.others()[0];
        // one TPDO period (10 ms) of motion plus the 1e-4 rad resolution
        worst = worst.max((q5 - seen).abs());
        moved = moved.max(q5.abs());
    }
    assert!(moved > 0.05, "joint 5 should move: {moved}");
    assert!(worst < 0.02, "joint 6 saw joint 5's angle within {worst} rad");
}

/// Issue 21's reproduction: a damaged `--store-dir` file (truncated, garbage, an unknown
/// section, a value the table refuses) booted the joint on the defaults with no fault and no
/// EMCY. Now it boots on the defaults with PARAMS_CORRUPT raised (PARAMS_REJECTED for a set the
/// table refuses) and its EMCY sent; a missing file is simply nothing stored. Files the joint
/// saves carry a CRC line first, so one cut short is caught.
#[test]
fn a_damaged_store_file_boots_on_defaults_with_its_fault_and_emcy() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(root().join("examples/models/trunk-right.toml")).unwrap();
    // a store file as the joint writes it (with its CRC line), by a save on a file store
    let saved_path = dir.path().join("saved.toml");
    {
        let mut st = SimStorage::file(saved_path.clone());
        let set = ModelFile::parse(&good, "m").unwrap().param_set().unwrap();
        st.save(&set).unwrap();
    }
    let saved = std::fs::read_to_string(&saved_path).unwrap();
    let cases: [(&str, Option<String>, bool); 6] = [
        ("missing", None, false),
        ("truncated", Some(saved[..saved.len() / 2].to_string()), true),
        ("garbage", Some("\u{0}\u{1}[[[ not toml".into()), true),
        ("unknown section", Some(format!("{good}\n[flux_capacitor]\nk = 1\n")), true),
        ("refused value", Some("[friction]\nc = 1e30\n".into()), true),
        ("a saved file edited", Some(saved.replace("c = ", "c = 1")), true),
    ];
    for (name, text, damaged) in cases {
        let path = dir.path().join(format!("{}.toml", name.replace(' ', "_")));
        if let Some(t) = &text {
            std::fs::write(&path, t).unwrap();
        }
        let mut bus = SimBus::new(1_000_000);
        let j = Arc::new(Mutex::new(JointSim::new(7, None, SimStorage::file(path), 0)));
        bus.attach(j.clone());
        let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
        let mut m = Master::new(Box::new(bus.clone()));
        m.listen(Duration::from_millis(50)).unwrap();
        let faults = j.lock().unwrap().node.safety().faults();
        // unreadable: PARAMS_CORRUPT; read but refused by the table's check: PARAMS_REJECTED
        let want = if name == "refused value" { Faults::PARAMS_REJECTED } else { Faults::PARAMS_CORRUPT };
        assert_eq!(faults.contains(want), damaged, "{name}: {faults:?}");
        let emcy = m.emcy.iter().any(|(n, _, d)| *n == 7 && u16::from_le_bytes([d[0], d[1]]) != 0);
        assert_eq!(emcy, damaged, "{name}: EMCY {:?}", m.emcy);
        assert_eq!(j.lock().unwrap().node.params().raw(), &RawParams::defaults(), "{name}: not on the defaults");
    }
    // and the intact saved file boots its set, no fault
    let j = JointSim::new(7, None, SimStorage::file(saved_path), 0);
    assert!(j.node.safety().faults().is_empty());
    assert_eq!(j.node.params().raw(), &ModelFile::parse(&good, "m").unwrap().raw_params().unwrap());
}

/// A rig whose joint watches the host every 60 ms (parameter controller.heartbeat_timeout, which
/// 0x1016 reports), faults acknowledged.
fn fast_watchdog_rig(node: u8) -> Rig {
    let mut r = rig(1_000_000, &[node]);
    let mut p = model("trunk-right.toml");
    p.set(ParamId::HeartbeatTimeout, 0.06);
    transfer::push(&mut r.m, node, &p, PushOptions::default(), &mut |_| {}).unwrap();
    r.m.write(node, 0x2202, 0, &[1]).unwrap();
    r
}

#[test]
fn the_master_beats_as_fast_as_the_joint_consumes_it() {
    // a master at the default 100 ms faults a joint that expects 60 ms
    let r = fast_watchdog_rig(5);
    let mut slow = Master::new(Box::new(r.bus.clone()));
    slow.listen(Duration::from_millis(10)).unwrap();
    slow.nmt(5, NMT_START).unwrap();
    slow.listen(Duration::from_millis(400)).unwrap();
    assert!(r.joints[0].lock().unwrap().node.safety().faults().contains(Faults::HEARTBEAT_LOST), "100 ms > 60 ms");

    // one that reads 0x1016 first beats at half of it, and the joint stays healthy
    let mut r = fast_watchdog_rig(5);
    assert_eq!(r.m.match_consumer(5).unwrap(), Some(60));
    assert_eq!(r.m.heartbeat_us, 30_000, "half the consumer time");
    // (the push's commit made the watchdog faster than the 100 ms we were sending: acknowledge)
    r.m.listen(Duration::from_millis(100)).unwrap();
    r.m.write(5, 0x2202, 0, &[1]).unwrap();
    r.m.nmt(5, NMT_START).unwrap();
    r.m.listen(Duration::from_secs(2)).unwrap();
    let j = r.joints[0].lock().unwrap();
    assert!(j.node.safety().faults().is_empty(), "{:?}", j.node.safety().faults());
    drop(j);
    // a joint that does not watch us (timeout 0) leaves the default
    let mut r = rig(1_000_000, &[6]);
    let mut p = model("trunk-right.toml");
    p.set(ParamId::HeartbeatTimeout, 0.0);
    transfer::push(&mut r.m, 6, &p, PushOptions::default(), &mut |_| {}).unwrap();
    assert_eq!(r.m.match_consumer(6).unwrap(), None);
    assert_eq!(r.m.heartbeat_us, joint_can::master::DEFAULT_HEARTBEAT_US);
}
