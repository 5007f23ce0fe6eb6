//! Two masters at once on one joint (issue 21): a tool pushing a parameter set while a
//! controller runs its own SDO transfers. SDO frames carry no client address, so on one
//! server channel each master takes the other's answers for its own (one's segments
//! acknowledged into the other's transfer). On the joint's second channel (0x1201, configured
//! by the tool through the default one) neither ever sees the other's transfer.
//!
//! Here on the simulated bus (virtual time: the same interleaving every run); over slcan with
//! the `jointctl` binary, `can_slcan.rs`.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::master::{Master, SdoCobs};
use joint_can::sim_bus::{SharedSimBus, SimBus, SimDevice};
use joint_can::transfer::{self, PushOptions};
use joint_can::Bus;
use joint_core::canopen::node::MemoryStorage;
use joint_core::canopen::od;
use joint_core::canopen::CanFrame;
use joint_core::params::RawParams;
use joint_formats::model_file::ModelFile;
use jointctl::sim_joint::{JointSim, SimStorage};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

const NODE: u8 = 5;

/// The trunk model with a two-axis gravity table, so the push holds segmented downloads.
fn set() -> RawParams {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/models/trunk-right.toml");
    let base = std::fs::read_to_string(root).unwrap();
    let torque: Vec<String> = (0..12).map(|i| format!("{}", 0.1 * f64::from(i))).collect();
    let text = format!(
        "{base}\n[gravity_table]\naxes = [\"q\", \"q_shoulder\"]\ngrid = [[0.0, 0.5, 1.0, 1.5], [-0.5, 0.0, 0.5]]\ntorque = [{}]\n",
        torque.join(", ")
    );
    ModelFile::parse(&text, "set.toml").unwrap().raw_params().unwrap()
}

/// A controller on the default channel: segmented uploads of the device name (0x1008, 10
/// bytes: an initiate and two segments), one after another, written here by hand so it shares
/// no code with the master under test. Every answer that is not the next step of its own
/// transfer is an error; a transfer not answered within 20 ms is one too.
#[derive(Default)]
struct Controller {
    step: Step,
    toggle: u8,
    got: Vec<u8>,
    sent_us: u64,
    done: u32,
    errors: u32,
}

#[derive(Default, PartialEq)]
enum Step {
    #[default]
    Idle,
    Initiated,
    Segment,
}

impl Controller {
    fn send(&mut self, t_us: u64, d: [u8; 8], out: &mut Vec<CanFrame>) {
        out.push(CanFrame::new(0x600 + u16::from(NODE), &d).unwrap());
        self.sent_us = t_us;
    }

    fn fail(&mut self) {
        self.errors += 1;
        self.step = Step::Idle;
    }
}

impl SimDevice for Controller {
    fn on_frame(&mut self, t_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>) {
        if f.id() != 0x580 + u16::from(NODE) {
            return;
        }
        let d = f.data();
        match self.step {
            Step::Idle => self.errors += 1,
            Step::Initiated => {
                // upload response, segmented (e = 0), size indicated, for 0x1008:0
                if d[0] & 0xE3 == 0x41 && d[1..4] == [0x08, 0x10, 0x00] {
                    self.got.clear();
                    self.toggle = 0;
                    self.step = Step::Segment;
                    self.send(t_us, [0x60, 0, 0, 0, 0, 0, 0, 0], out);
                } else {
                    self.fail();
                }
            }
            Step::Segment => {
                if d[0] >> 5 != 0 || (d[0] >> 4) & 1 != self.toggle {
                    return self.fail();
                }
                let n = 7 - usize::from((d[0] >> 1) & 7);
                self.got.extend_from_slice(&d[1..1 + n]);
                if d[0] & 1 == 1 {
                    if self.got == b"joint-node" {
                        self.done += 1;
                        self.step = Step::Idle;
                    } else {
                        self.fail();
                    }
                } else {
                    self.toggle ^= 1;
                    self.send(t_us, [0x60 | (self.toggle << 4), 0, 0, 0, 0, 0, 0, 0], out);
                }
            }
        }
    }

    fn tick(&mut self, t_us: u64, out: &mut Vec<CanFrame>) {
        if self.step != Step::Idle && t_us - self.sent_us > 20_000 {
            self.fail();
        }
        if self.step == Step::Idle {
            self.step = Step::Initiated;
            self.send(t_us, [0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0], out);
        }
    }

    fn period_us(&self) -> u64 {
        1000
    }
}

/// Counts the frames the tool sends, per COB-ID.
struct Counting {
    inner: Box<dyn Bus>,
    sent: Arc<Mutex<std::collections::BTreeMap<u16, u32>>>,
}

impl Bus for Counting {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        *self.sent.lock().unwrap().entry(f.id()).or_default() += 1;
        self.inner.send(f)
    }
    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        self.inner.recv(timeout)
    }
    fn now_us(&self) -> u64 {
        self.inner.now_us()
    }
    fn describe(&self) -> String {
        self.inner.describe()
    }
}

struct Outcome {
    ok: bool,
    retries: u32,
    pulled: bool,
    done: u32,
    errors: u32,
    tool_on_channel_1: u32,
}

/// The tool pushes the set and pulls it back while the controller runs its uploads; the tool
/// on `channel` (1 or 2). Channel 2 is configured before the controller starts, as it is
/// once on a bus (a later command finds it configured and writes nothing on channel 1).
fn two_masters(channel: u8) -> Outcome {
    let mut bus = SimBus::new(1_000_000);
    let joint = Arc::new(Mutex::new(JointSim::new(NODE, None, SimStorage::Memory(MemoryStorage::default()), 0)));
    bus.attach(joint.clone());
    let controller = Arc::new(Mutex::new(Controller::default()));
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    let sent = Arc::new(Mutex::new(std::collections::BTreeMap::new()));
    let mut m = Master::new(Box::new(Counting { inner: Box::new(bus.clone()), sent: sent.clone() }));
    m.sdo_timeout = Duration::from_millis(20);
    m.listen(Duration::from_millis(5)).unwrap();
    if channel == 2 {
        m.use_second_channel(NODE, SdoCobs::second_for(NODE).unwrap()).unwrap();
        assert_eq!(m.sdo_cobs(NODE), SdoCobs { rx: 0x645, tx: 0x5C5 });
    }
    bus.0.lock().unwrap().attach(controller.clone());
    m.listen(Duration::from_millis(10)).unwrap();
    let c0 = {
        let c = controller.lock().unwrap();
        (c.done, c.errors)
    };
    let want = set();
    let v = transfer::push_verified(&mut m, NODE, &want, PushOptions::default(), &mut |_| {});
    let pulled = transfer::pull(&mut m, NODE).map(|(raw, _)| raw == want).unwrap_or(false);
    let c = controller.lock().unwrap();
    let tool_on_channel_1 = sent.lock().unwrap().get(&0x605).copied().unwrap_or(0);
    eprintln!(
        "tool on channel {channel}: push ok {} ({} retries), pulled back {pulled}; controller: {} uploads, {} errors; \
         tool's frames on 0x605: {tool_on_channel_1}",
        v.ok(),
        v.retries,
        c.done - c0.0,
        c.errors - c0.1
    );
    Outcome { ok: v.ok(), retries: v.retries, pulled, done: c.done - c0.0, errors: c.errors - c0.1, tool_on_channel_1 }
}

#[test]
fn a_tool_on_the_second_channel_never_shares_a_transfer_with_a_controller() {
    let two = two_masters(2);
    assert!(two.ok && two.pulled, "the push on channel 2");
    assert_eq!(two.retries, 0, "no transfer of the tool was disturbed");
    assert_eq!(two.errors, 0, "no transfer of the controller was disturbed");
    assert!(two.done > 20, "the controller kept working: {} uploads", two.done);
    // channel 1 carried only the configuration: 0x1201 sub 1, 2 and 3
    assert_eq!(two.tool_on_channel_1, 3);

    // the same two masters on one channel: each takes the other's answers for its own
    let one = two_masters(1);
    assert!(one.errors > 0 || one.retries > 0, "sharing channel 1 went unnoticed");
}

/// The channel is configured as CiA 301 has it (0x1201: COB-IDs, client), left alone when it
/// already serves this master, configured again after the node resets (not valid then), and a
/// channel in use with other COB-IDs is refused without touching it.
#[test]
fn the_second_channel_is_configured_once_again_after_a_reset_and_never_taken_over() {
    let mut bus = SimBus::new(1_000_000);
    let joint = Arc::new(Mutex::new(JointSim::new(NODE, None, SimStorage::Memory(MemoryStorage::default()), 0)));
    bus.attach(joint);
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    let sent = Arc::new(Mutex::new(std::collections::BTreeMap::new()));
    let mut m = Master::new(Box::new(Counting { inner: Box::new(bus.clone()), sent: sent.clone() }));
    m.sdo_timeout = Duration::from_millis(20);
    m.listen(Duration::from_millis(5)).unwrap();
    let cobs = SdoCobs::second_for(NODE).unwrap();
    m.use_second_channel(NODE, cobs).unwrap();
    let mut plain = Master::new(Box::new(bus.clone()));
    plain.sdo_timeout = Duration::from_millis(20);
    assert_eq!(plain.read_u32(NODE, od::SDO_SERVER2, 1).unwrap(), 0x645);
    assert_eq!(plain.read_u32(NODE, od::SDO_SERVER2, 2).unwrap(), 0x5C5);
    assert_eq!(plain.read(NODE, od::SDO_SERVER2, 3).unwrap(), vec![0x7F]);
    // a second command (a new master) finds it configured: nothing written on channel 1
    sent.lock().unwrap().clear();
    let mut again = Master::new(Box::new(Counting { inner: Box::new(bus.clone()), sent: sent.clone() }));
    again.sdo_timeout = Duration::from_millis(20);
    again.use_second_channel(NODE, cobs).unwrap();
    assert_eq!(sent.lock().unwrap().get(&0x605), None);
    assert_eq!(again.read_string(NODE, 0x1008, 0).unwrap(), "joint-node");
    // NMT reset communication: 0x1201 is not valid again; the boot-up is heard and the next
    // transfer configures it first
    m.nmt(NODE, 0x82).unwrap();
    m.listen(Duration::from_millis(5)).unwrap();
    assert_eq!(plain.read_u32(NODE, od::SDO_SERVER2, 1).unwrap(), 0x8000_0000);
    assert_eq!(m.read_string(NODE, 0x1008, 0).unwrap(), "joint-node");
    assert_eq!(plain.read_u32(NODE, od::SDO_SERVER2, 1).unwrap(), 0x645);
    // another master's channel 2 at other COB-IDs: refused, left as it is
    let other = SdoCobs { rx: 0x6A0, tx: 0x6A1 };
    let e = plain.use_second_channel(NODE, other).unwrap_err().to_string();
    assert!(e.contains("in use with COB-IDs 0x645/0x5C5"), "{e}");
    assert_eq!(plain.read_u32(NODE, od::SDO_SERVER2, 1).unwrap(), 0x645);
    // COB-IDs that cannot be a second channel are refused before any traffic
    for bad in [SdoCobs { rx: 0x605, tx: 0x5C5 }, SdoCobs { rx: 0x645, tx: 0x645 }, SdoCobs { rx: 0x800, tx: 1 }] {
        assert!(plain.use_second_channel(NODE, bad).is_err(), "{bad:?}");
    }
    assert_eq!(SdoCobs::second_for(64), None);
}

/// Configuring the channel while a controller runs transfers on channel 1: the three
/// expedited writes may meet the controller's answers or the abort of its transfer they ended
/// (SDO frames name no client); they are tried again and the channel is configured.
#[test]
fn the_second_channel_is_configured_while_a_controller_works_on_the_first() {
    let mut bus = SimBus::new(1_000_000);
    let joint = Arc::new(Mutex::new(JointSim::new(NODE, None, SimStorage::Memory(MemoryStorage::default()), 0)));
    bus.attach(joint);
    let controller = Arc::new(Mutex::new(Controller::default()));
    bus.attach(controller.clone());
    let bus = SharedSimBus(Arc::new(Mutex::new(bus)));
    for k in 0..20u64 {
        let mut m = Master::new(Box::new(bus.clone()));
        m.sdo_timeout = Duration::from_millis(20);
        // a different phase against the controller's transfers each time
        m.listen(Duration::from_micros(5000 + 137 * k)).unwrap();
        m.nmt(NODE, 0x82).unwrap(); // reset communication: channel 2 not valid again
        m.listen(Duration::from_millis(2)).unwrap();
        m.use_second_channel(NODE, SdoCobs::second_for(NODE).unwrap()).unwrap();
        assert_eq!(m.read_string(NODE, 0x1008, 0).unwrap(), "joint-node", "phase {k}");
    }
    assert!(controller.lock().unwrap().done > 100);
}
