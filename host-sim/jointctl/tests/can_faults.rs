//! Pushes on a bus that fails (issue 16): frames lost at 0.1 %, 1 % and 10 % and in bursts, a
//! joint that resets in the middle of a segmented download or of the commit, an adapter that
//! stops answering. What must hold every time: the joint runs the old set or the new one, never
//! a mix, and `push_verified` says which (or that it cannot know) — it never claims the new set
//! when the joint does not run it. The loss table is printed (measured 2026-11-25, 100 pushes
//! each of a trunk set with a 2-axis gravity table, save and pre-operational, 8 tries per SDO
//! transfer, the read-back by the joint's CRC of its set in force): 0 %, 0.1 % and 1 % all
//! succeed; 1 % in bursts of 8: 89 succeed, 11 fail on the previous set (measured again
//! 2026-11-28, before and after the plain commit was refused: 90/10 was an older figure);
//! 10 %: none succeed, all 100 on the previous set (the table's segmented transfers need ~40
//! frames in a row). Mixed sets: 0. Wrong reports: 0. After every failed push the joint is
//! asked what it holds staged: nothing (every failed push so far discarded what it staged), or
//! what a second master cannot commit (checked by trying, `left_after_failed_push`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::master::Master;
use joint_can::sim_bus::{Faults, ResetOn, SharedSimBus, SimBus};
use joint_can::transfer::{self, InForce, PushOptions};
use joint_core::canopen::node::MemoryStorage;
use joint_core::canopen::od;
use joint_core::canopen::Abort;
use joint_core::params::{ParamId, RawParams, PARAMS};
use joint_core::store::set_crc;
use joint_formats::model_file::ModelFile;
use jointctl::sim_joint::{JointSim, SimStorage};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

const NODE: u8 = 5;

/// A trunk model with a two-axis gravity table (so a push holds segmented downloads too),
/// `k` shifting every value so two sets differ everywhere.
fn set(file: &str, k: f64) -> RawParams {
    let base = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/models").join(file))
        .unwrap();
    let torque: Vec<String> = (0..12).map(|i| format!("{}", 0.1 * i as f64 + k)).collect();
    let text = format!(
        "{base}\n[gravity_table]\naxes = [\"q\", \"q_shoulder\"]\ngrid = [[0.0, 0.5, 1.0, 1.5], [-0.5, 0.0, 0.5]]\ntorque = [{}]\n",
        torque.join(", ")
    );
    ModelFile::parse(&text, "set.toml").unwrap().raw_params().unwrap()
}

struct Rig {
    bus: SharedSimBus,
    joint: Arc<Mutex<JointSim>>,
    m: Master,
}

fn rig() -> Rig {
    let mut bus = SimBus::new(1_000_000);
    let joint = Arc::new(Mutex::new(JointSim::new(NODE, None, SimStorage::Memory(MemoryStorage::default()), 0)));
    bus.attach(joint.clone());
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    let mut m = Master::new(Box::new(bus.clone()));
    // a joint answers an SDO within a fraction of a millisecond at 1 Mbit/s: 20 ms is ample
    m.sdo_timeout = Duration::from_millis(20);
    m.listen(Duration::from_millis(5)).unwrap();
    Rig { bus, joint, m }
}

impl Rig {
    fn running(&self) -> RawParams {
        self.joint.lock().unwrap().node.params().raw().clone()
    }
    fn staged(&self) -> RawParams {
        self.joint.lock().unwrap().node.staged().clone()
    }
    fn faults(&self, f: Faults) {
        self.bus.0.lock().unwrap().faults = f;
    }

    /// Another master on the same bus (a second tool, the controller), once the bus is quiet:
    /// what the first one's transfers left in the inbox is dropped, so no stale answer is read
    /// as this master's.
    fn second_master(&self) -> Master {
        {
            let mut b = self.bus.0.lock().unwrap();
            b.run_for(Duration::from_millis(30));
            b.drain_inbox();
        }
        let mut m = Master::new(Box::new(self.bus.clone()));
        m.sdo_timeout = Duration::from_millis(20);
        m
    }
}

/// What a failed push left staged on the joint.
#[derive(Debug, PartialEq)]
enum Left {
    /// nothing: staged == running (the push discarded what it staged)
    Nothing,
    /// the whole pushed set (its commit was lost): committing it is no mix
    Whole,
    /// part of the pushed set: proven uncommittable by a second master
    Part,
}

/// After a failed push: the joint holds nothing staged, or the whole pushed set, or a part of
/// it that no master can make live. A second master tries what another tool on the bus would:
/// a plain commit (refused: it names no set), a commit naming the set in force or the pushed
/// set (refused: the part staged is neither). The set in force must not change; the master then
/// discards the part, as `jointctl discard` does.
fn left_after_failed_push(r: &Rig, before: &RawParams, pushed: &RawParams) -> Left {
    let (staged, running) = (r.staged(), r.running());
    if staged == running {
        return Left::Nothing;
    }
    if staged == *pushed {
        return Left::Whole;
    }
    let mut m = r.second_master();
    let plain = m.write(NODE, od::COMMIT, 0, &[1]);
    assert_eq!(plain.map_err(|e| e.abort_code()), Err(Some(Abort::Unsupported.code())), "a plain commit");
    for set in [before, pushed] {
        let named = m.write(NODE, od::COMMIT_CRC, 0, &set_crc(set).to_le_bytes());
        assert_eq!(named.map_err(|e| e.abort_code()), Err(Some(Abort::DeviceState.code())), "a commit by CRC");
    }
    assert_eq!(r.running(), running, "a part of a push went live");
    m.write(NODE, od::COMMIT, 0, &[0]).unwrap();
    assert_eq!(r.staged(), running);
    Left::Part
}

const OPTS: PushOptions = PushOptions { pre_operational: true, save: true };

#[derive(Default, Debug)]
struct Tally {
    ok: u32,
    failed_previous: u32,
    failed_unknown: u32,
    mixed: u32,
    wrong: u32,
    retries: u32,
    attempts: u32,
    /// failed pushes that left part of their set staged (none committable: see
    /// [`left_after_failed_push`])
    left_part: u32,
    /// failed pushes that left the whole pushed set staged (its commit lost)
    left_whole: u32,
}

/// `n` pushes alternating between two sets under `faults(seed)`; what the joint runs is read
/// from the joint itself after each push and compared with the report.
fn run(n: u32, faults: &dyn Fn(u64) -> Faults) -> Tally {
    let (a, b) = (set("trunk-right.toml", 0.0), set("trunk-left.toml", 5.0));
    let mut r = rig();
    let first = transfer::push_verified(&mut r.m, NODE, &a, OPTS, &mut |_| {});
    assert!(first.ok(), "{first:?}");
    let mut t = Tally::default();
    for k in 0..n {
        let before = r.running();
        let want = if before == a { &b } else { &a };
        r.faults(faults(u64::from(k) + 1));
        let v = transfer::push_verified(&mut r.m, NODE, want, OPTS, &mut |_| {});
        r.faults(Faults::default());
        let after = r.running();
        t.retries += v.retries;
        t.attempts += v.attempts;
        if after != before && after != *want {
            t.mixed += 1;
        }
        if !v.ok() && std::env::var_os("FAULT_DEBUG").is_some() {
            eprintln!("  push {k}: {:?} {:?}", v.in_force, v.error);
        }
        match v.in_force {
            InForce::New if v.ok() => t.ok += 1,
            InForce::Unknown(_) => t.failed_unknown += 1,
            _ => t.failed_previous += 1,
        }
        if !v.ok() {
            match left_after_failed_push(&r, &before, want) {
                Left::Nothing => {}
                Left::Whole => t.left_whole += 1,
                Left::Part => t.left_part += 1,
            }
        }
        let claimed_new = v.in_force == InForce::New;
        let claimed_old = v.in_force == InForce::Previous;
        if (claimed_new && after != *want) || (claimed_old && after == *want) {
            t.wrong += 1;
        }
    }
    t
}

#[test]
fn pushes_under_frame_loss_never_leave_a_mixed_set_and_always_say_which_runs() {
    let cases: [(&str, f64, u32); 5] =
        [("0 %", 0.0, 0), ("0.1 %", 0.001, 0), ("1 %", 0.01, 0), ("10 %", 0.10, 0), ("1 %, bursts of 8", 0.01, 7)];
    eprintln!(
        "loss               pushes  succeeded  failed (previous set)  failed (unknown)  mixed  wrong report  SDO retries  left staged (part/whole)"
    );
    let mut rows = Vec::new();
    for (name, loss, burst) in cases {
        let t = run(100, &|seed| Faults::lossy(loss, burst, seed * 7919 + (loss * 1e6) as u64));
        eprintln!(
            "{name:18} {:6}  {:9}  {:21}  {:16}  {:5}  {:12}  {:11}  {}/{}",
            100, t.ok, t.failed_previous, t.failed_unknown, t.mixed, t.wrong, t.retries, t.left_part, t.left_whole
        );
        rows.push((name, loss, t));
    }
    for (name, loss, t) in &rows {
        assert_eq!(t.mixed, 0, "{name}: a mixed set on the joint");
        assert_eq!(t.wrong, 0, "{name}: a push said the wrong set runs");
        if *loss <= 0.01 && !name.contains("burst") {
            assert_eq!(t.ok, 100, "{name}: {t:?}");
        }
    }
    // Bursts: most pushes get through on retries. At 10 % a segmented transfer of the table
    // (~40 frames, all of which must arrive: CiA 301 segments cannot be resent alone) almost
    // never completes in 8 tries, so those pushes fail — and say which set runs, or that the
    // joint could not be read back.
    let bursts = &rows[4].2;
    assert!(bursts.ok >= 50 && bursts.retries > 100, "{bursts:?}");
    let ten = &rows[3].2;
    assert_eq!(ten.ok + ten.failed_previous + ten.failed_unknown, 100);
}

/// A joint that resets (brown-out) when a download segment or the commit reaches it, before or
/// after handling it: it boots with its stored set, the push sees the boot-up, pushes again and
/// reads the new set back.
#[test]
fn a_joint_that_resets_mid_push_is_pushed_again_and_read_back() {
    let (a, b) = (set("trunk-right.toml", 0.0), set("trunk-left.toml", 5.0));
    let segment = |f: &joint_core::canopen::CanFrame| {
        f.id() == 0x600 + u16::from(NODE) && f.data().first().is_some_and(|c| c >> 5 == 0)
    };
    let commit = |f: &joint_core::canopen::CanFrame| {
        f.id() == 0x600 + u16::from(NODE) && f.data().get(1..3) == Some(&[0x05, 0x22][..]) && f.data()[0] >> 5 == 1
    };
    type Pick = fn(&joint_core::canopen::CanFrame) -> bool;
    for (name, pick, before) in [
        ("segment, before", segment as Pick, true),
        ("segment, after", segment, false),
        ("commit, before", commit, true),
        ("commit, after", commit, false),
    ] {
        let mut r = rig();
        assert!(transfer::push_verified(&mut r.m, NODE, &a, OPTS, &mut |_| {}).ok());
        let mut fired = false;
        let mut f = Faults::default();
        f.reset = Some(ResetOn {
            device: 0,
            when: Box::new(move |fr| {
                let hit = !fired && pick(fr);
                fired |= hit;
                hit
            }),
            before,
            done: 0,
        });
        r.faults(f);
        let v = transfer::push_verified(&mut r.m, NODE, &b, OPTS, &mut |_| {});
        let resets = r.bus.0.lock().unwrap().faults.reset.as_ref().unwrap().done;
        eprintln!("reset at a {name}: {:?} after {} pushes, {} retries", v.in_force, v.attempts, v.retries);
        assert_eq!(resets, 1, "{name}: the reset fired");
        assert!(v.ok(), "{name}: {v:?}");
        assert_eq!(v.attempts, 2, "{name}: pushed again after the boot-up");
        assert_eq!(r.running(), b, "{name}");
    }
}

/// The adapter goes away in the middle of a push: nothing can be read back, so the push says it
/// cannot know, and the joint runs one whole set.
#[test]
fn an_adapter_that_stops_answering_gives_unknown_not_a_guess() {
    let (a, b) = (set("trunk-right.toml", 0.0), set("trunk-left.toml", 5.0));
    for after in [10u64, 60, 140] {
        let mut r = rig();
        assert!(transfer::push_verified(&mut r.m, NODE, &a, OPTS, &mut |_| {}).ok());
        let mut f = Faults::default();
        f.adapter_dies_after = Some(after);
        r.faults(f);
        let v = transfer::push_verified(&mut r.m, NODE, &b, OPTS, &mut |_| {});
        assert!(matches!(v.in_force, InForce::Unknown(_)), "dies after {after}: {v:?}");
        assert!(!v.ok() && v.error.is_some());
        let running = r.running();
        assert!(running == a || running == b, "dies after {after}: a mixed set");
    }
}

/// Issue 21: a push interrupted by Ctrl-C left its values staged, so reads returned them and
/// any later plain commit (another master's) made them live. Interrupted after k transfers (the
/// flag Ctrl-C sets), the push discards what it staged and reads back which set runs.
#[test]
fn an_interrupted_push_leaves_nothing_staged_and_says_the_previous_set_runs() {
    let (a, b) = (set("trunk-right.toml", 0.0), set("trunk-left.toml", 5.0));
    for k in [1usize, 20, 45, 80] {
        let mut r = rig();
        assert!(transfer::push_verified(&mut r.m, NODE, &a, OPTS, &mut |_| {}).ok());
        let cancel = std::sync::atomic::AtomicBool::new(false);
        let v = transfer::push_verified_until(
            &mut r.m,
            NODE,
            &b,
            OPTS,
            &mut |p| {
                if p.done == k {
                    cancel.store(true, std::sync::atomic::Ordering::SeqCst);
                }
            },
            &cancel,
        );
        assert_eq!(v.in_force, InForce::Previous, "after {k}: {v:?}");
        assert!(v.error.as_deref().is_some_and(|e| e.contains("interrupted")), "after {k}: {v:?}");
        let j = r.joint.lock().unwrap();
        assert_eq!(j.node.params().raw(), &a, "after {k}: the old set runs");
        assert_eq!(j.node.staged(), &a, "after {k}: something stayed staged");
    }
}

/// Issue 21's "33 old + 1 new": master A's push to a joint running set `a` dies half-way (the
/// cable is cut after `cut` of its frames, so its discard and read-back are lost too) and
/// leaves part of set `b` staged; master B then stages one value of its own and commits. A
/// plain commit made A's part and B's value live as one set. Now B's plain commit is refused,
/// B's commit naming the set it means (`a` with its value) is refused because the staged set
/// is not that set, and nothing changes on the joint until B discards and stages again.
#[test]
fn a_half_staged_set_and_another_masters_value_never_go_live_as_a_mix() {
    let (a, b) = (set("trunk-right.toml", 0.0), set("trunk-left.toml", 5.0));
    let friction_c = od::PARAM_BASE + ParamId::FrictionC.index() as u16;
    for cut in [4u64, 30, 50] {
        let mut r = rig();
        assert!(transfer::push_verified(&mut r.m, NODE, &a, OPTS, &mut |_| {}).ok());
        r.bus.0.lock().unwrap().cut_master_after_more(cut);
        let v = transfer::push_verified(&mut r.m, NODE, &b, OPTS, &mut |_| {});
        assert!(matches!(v.in_force, InForce::Unknown(_)), "cut after {cut}: {v:?}");
        r.bus.0.lock().unwrap().cut_master_after = None;
        let staged = r.staged();
        let new = PARAMS.iter().filter(|d| staged.get(d.id) == b.get(d.id) && a.get(d.id) != b.get(d.id)).count();
        let differ = PARAMS.iter().filter(|d| a.get(d.id) != b.get(d.id)).count();
        let old_table = staged.table == a.table;
        eprintln!(
            "cut after {cut} frames: {new} of the {differ} differing values of the new set staged, the gravity table \
             still the old one: {old_table}"
        );
        assert!(staged != a && staged != b, "cut after {cut}: the push did not die half-way");
        assert_eq!(r.running(), a);

        // master B: one value of its own, then a plain commit
        let mut mb = r.second_master();
        let x = a.get(ParamId::FrictionC) + 0.25;
        mb.write(NODE, friction_c, 0, &x.to_le_bytes()).unwrap();
        let plain = mb.write(NODE, od::COMMIT, 0, &[1]);
        assert_eq!(plain.map_err(|e| e.abort_code()), Err(Some(Abort::Unsupported.code())), "cut after {cut}");
        assert_eq!(r.running(), a, "cut after {cut}: a plain commit made a mix live");
        assert_eq!(mb.read(NODE, od::COMMIT_ERROR, 1).unwrap(), vec![9]);
        // B names the set it means: the old set with its one value. The staged set is not that.
        let mut mine = a.clone();
        mine.set(ParamId::FrictionC, x);
        let named = mb.write(NODE, od::COMMIT_CRC, 0, &set_crc(&mine).to_le_bytes());
        assert_eq!(named.map_err(|e| e.abort_code()), Err(Some(Abort::DeviceState.code())), "cut after {cut}");
        assert_eq!(r.running(), a, "cut after {cut}: a commit by CRC made a mix live");
        assert_eq!(mb.read(NODE, od::COMMIT_ERROR, 1).unwrap(), vec![7]);
        // B's way out: discard, stage again, commit by name; exactly B's set runs
        mb.write(NODE, od::COMMIT, 0, &[0]).unwrap();
        mb.write(NODE, friction_c, 0, &x.to_le_bytes()).unwrap();
        mb.write(NODE, od::COMMIT_CRC, 0, &set_crc(&mine).to_le_bytes()).unwrap();
        assert_eq!(r.running(), mine, "cut after {cut}");
    }
}
