//! A scripted CANopen session through the core's [`Node`], the same on QEMU and on the PC.
//!
//! The session is what a master and the board's tasks do to a joint node, in virtual time:
//! boot-up; NMT pre-operational; the host's heartbeats; SDO downloads of every trunk-joint
//! parameter that differs from the table default, an out-of-range write that must abort
//! (0x06090031) and change nothing, a malformed (short) SDO request; a plain commit, refused
//! (0x06010000: a commit names its set), then the commit by the set's CRC; a read back;
//! "save" (0x1010); NMT start; RPDO assist commands (one of them too short: EMCY 0x8210); a
//! safety parameter written while operational (0x08000022); then the host falls silent and
//! the watchdog fades the torque (EMCY 0x8130). Between frames the board's 1 kHz loop runs
//! `node.poll` and `node.control` with a joint angle moving on a sine (computed through
//! `joint_core::math`, so both sides feed identical inputs).
//!
//! Every frame the node sends and every control output becomes one text [`Line`], labelled
//! with the step that caused it; the QEMU image prints them, the host test computes them
//! natively and compares the text line by line (tests/tests/qemu_parity.rs), so a single
//! different byte or bit fails with the step named. f32 values are printed as bit patterns.
//!
//! [`run_fd_with`] is a second, shorter session on a node configured for CAN FD: SDO in FD
//! frames (answered in FD), the host's shared FD command frame (one of them too short for the
//! node's slot: EMCY 0x8210), and the 32-byte TPDO3 with bit-rate switch every 5 ms.
//!
//! This file is compiled into the `firmware-qemu` crate and, by path, into the host test:
//! it may use `core` and `joint_core` only.

use core::fmt::{self, Write};

use joint_core::canopen::{od, CanFrame, ControlStep, MemoryStorage, Node, NodeConfig};
use joint_core::control::Output;
use joint_core::control_loop::ControlLoop;
use joint_core::math;
use joint_core::params::{ParamId, RawParams, PARAMS};
use joint_core::vectors::trunk_right;

pub const NODE_ID: u8 = 5;
/// The master's node id, whose heartbeat the node watches (the node's default).
pub const HOST_ID: u8 = 0x7F;
/// Control period of the session, µs (the trunk set's 1 kHz).
pub const PERIOD_US: u64 = 1000;
/// Control steps in the session.
pub const STEPS: u32 = 1600;
/// Steps at which the scripted frames arrive (before that step's control).
const T_PREOP: u32 = 2;
const T_PARAMS: u32 = 5;
const T_START: u32 = 60;
const T_RPDO: u32 = 200;
const T_SAFETY_WRITE: u32 = 700;
/// The host's last heartbeat; the watchdog (0.5 s) then trips and fades.
const T_HOST_SILENT: u32 = 900;

/// One output of the session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Line {
    /// A frame the node sent while handling `step`'s event.
    Tx { step: u32, what: &'static str, frame: CanFrame },
    /// A control output at `step`.
    Control { step: u32, out: Output },
}

impl Line {
    /// The line as printed: `T step what id dlc bytes` or `C step tau u_motor c_c assist
    /// limited` (f32 as 8 hex digits of their bits). An FD frame's DLC is written as slcan
    /// does: `b` + hex digit with bit-rate switch, `d` + hex digit without.
    pub fn write<W: Write>(&self, w: &mut W) -> fmt::Result {
        match self {
            Line::Tx { step, what, frame } => {
                write!(w, "T {step:05} {what} {:03x} ", frame.id())?;
                match (frame.is_fd(), frame.brs()) {
                    (false, _) => write!(w, "{}", frame.dlc())?,
                    (true, true) => write!(w, "b{:x}", frame.dlc())?,
                    (true, false) => write!(w, "d{:x}", frame.dlc())?,
                }
                for b in frame.data() {
                    write!(w, " {b:02x}")?;
                }
                writeln!(w)
            }
            Line::Control { step, out } => writeln!(
                w,
                "C {step:05} {:08x} {:08x} {:08x} {:08x} {}",
                out.tau_out.to_bits(),
                out.u_motor.to_bits(),
                out.c_c.to_bits(),
                out.assist.to_bits(),
                u8::from(out.limited)
            ),
        }
    }
}

/// What the session saw, for the host test's own checks (beyond "same on both sides").
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    pub lines: u32,
    pub frames: u32,
    /// SDO aborts the node sent, and the codes the script expected that it did send.
    pub aborts: u32,
    pub expected_aborts_seen: u32,
    pub emcy: u32,
    pub tpdo: u32,
    /// Largest |τ| while operational with the host present, N·m.
    pub max_tau: f32,
    pub final_tau: f32,
    /// The committed set equals the trunk-joint set the script pushed.
    pub committed_trunk_set: bool,
    /// The refused writes left the staged value as it was.
    pub refused_writes_changed_nothing: bool,
    pub saves: u32,
    /// FD session: frames sent as FD, of them TPDO3, SDO replies in FD frames
    pub fd_frames: u32,
    pub fd_tpdo: u32,
    pub fd_sdo_replies: u32,
    /// FD session: the assist command the node took from its slot of the shared frame, in
    /// 0.01 N·m, and whether the short shared frame left it unchanged
    pub fd_assist_centi: i32,
    pub fd_short_kept: bool,
}

fn f(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::new(id, data).unwrap_or_default()
}

fn sdo_download_f32(index: u16, v: f32) -> CanFrame {
    let b = v.to_bits().to_le_bytes();
    let i = index.to_le_bytes();
    f(0x600 + u16::from(NODE_ID), &[0x23, i[0], i[1], 0, b[0], b[1], b[2], b[3]])
}

fn sdo_download_u32(index: u16, sub: u8, v: u32) -> CanFrame {
    let b = v.to_le_bytes();
    let i = index.to_le_bytes();
    f(0x600 + u16::from(NODE_ID), &[0x23, i[0], i[1], sub, b[0], b[1], b[2], b[3]])
}

fn sdo_download_u8(index: u16, sub: u8, v: u8) -> CanFrame {
    let i = index.to_le_bytes();
    f(0x600 + u16::from(NODE_ID), &[0x2F, i[0], i[1], sub, v, 0, 0, 0])
}

fn sdo_upload(index: u16, sub: u8) -> CanFrame {
    let i = index.to_le_bytes();
    f(0x600 + u16::from(NODE_ID), &[0x40, i[0], i[1], sub, 0, 0, 0, 0])
}

fn param_index(p: ParamId) -> u16 {
    0x2000 + p.index() as u16
}

/// The abort code in an SDO response, if it is one.
fn abort_code(frame: &CanFrame) -> Option<u32> {
    let d = frame.data();
    if frame.id() != 0x580 + u16::from(NODE_ID) || d.first() != Some(&0x80) {
        return None;
    }
    let c: [u8; 4] = d.get(4..8)?.try_into().ok()?;
    Some(u32::from_le_bytes(c))
}

/// One frame the node sent, into the summary and out as a line.
fn record<E: FnMut(&Line)>(
    s: &mut Summary,
    emit: &mut E,
    step: u32,
    what: &'static str,
    expected_abort: Option<u32>,
    fr: &CanFrame,
) {
    s.frames += 1;
    if let Some(code) = abort_code(fr) {
        s.aborts += 1;
        if Some(code) == expected_abort {
            s.expected_aborts_seen += 1;
        }
    }
    if fr.id() == 0x80 + u16::from(NODE_ID) {
        s.emcy += 1;
    }
    if fr.id() == 0x180 + u16::from(NODE_ID) || fr.id() == 0x280 + u16::from(NODE_ID) {
        s.tpdo += 1;
    }
    if fr.is_fd() {
        s.fd_frames += 1;
        if fr.id() == 0x380 + u16::from(NODE_ID) {
            s.fd_tpdo += 1;
        }
        if fr.id() == 0x580 + u16::from(NODE_ID) {
            s.fd_sdo_replies += 1;
        }
    }
    s.lines += 1;
    emit(&Line::Tx { step, what, frame: *fr });
}

struct Run<'a, E: FnMut(&Line), C: ControlStep> {
    node: Node<MemoryStorage, C>,
    /// the boards' loop (the core's): q̇, q̈ from the angle, the node's step
    ctl: ControlLoop,
    emit: &'a mut E,
    s: Summary,
    step: u32,
}

impl<E: FnMut(&Line), C: ControlStep> Run<'_, E, C> {
    fn now(&self) -> u64 {
        u64::from(self.step) * PERIOD_US
    }

    /// One received frame, with what the node sends in answer.
    fn rx(&mut self, what: &'static str, frame: CanFrame, expect_abort: Option<u32>) {
        self.rx_opt(what, Some(frame), expect_abort);
    }

    fn rx_opt(&mut self, what: &'static str, frame: Option<CanFrame>, expect_abort: Option<u32>) {
        let now = self.now();
        let step = self.step;
        // each frame is recorded as the node sends it: no buffer of 68-byte frames on the stack
        let Run { node, emit, s, .. } = self;
        node.process(now, frame.as_ref(), &mut |o| record(s, &mut **emit, step, what, expect_abort, &o));
    }

    /// The board's 1 ms tick: timers, then the control step.
    fn tick(&mut self) {
        let now = self.now();
        let step = self.step;
        {
            let Run { node, emit, s, .. } = self;
            node.poll(now, &mut |o| record(s, &mut **emit, step, "poll", None, &o));
        }
        // A joint swinging ±0.6 rad at 0.5 Hz, through the boards' own loop (its estimates of
        // q̇ and q̈, its overrun check, the node's step).
        let t = self.step as f32 * (PERIOD_US as f32 * 1.0e-6);
        let w = 2.0 * core::f32::consts::PI * 0.5;
        let q = 0.6 * math::sin(w * t);
        let out = self.ctl.tick(&mut self.node, now, Ok::<f32, ()>(q)).out;
        if self.step < T_HOST_SILENT {
            self.s.max_tau = self.s.max_tau.max(math::abs(out.tau_out));
        }
        self.s.final_tau = out.tau_out;
        self.s.lines += 1;
        (self.emit)(&Line::Control { step: self.step, out });
    }

    fn script(&mut self) {
        let me = NODE_ID;
        let hb = 0x700 + u16::from(HOST_ID);
        let trunk = trunk_right();
        let defaults = RawParams::defaults();
        match self.step {
            T_PREOP => self.rx("nmt-preop", f(0x000, &[0x80, me]), None),
            T_PARAMS => {
                for d in PARAMS.iter() {
                    let v = trunk.get(d.id);
                    if v.to_bits() != defaults.get(d.id).to_bits() {
                        self.rx(d.name, sdo_download_f32(param_index(d.id), v), None);
                    }
                }
                // Above its maximum: abort 0x06090031, the staged value stays.
                let p = ParamId::FrictionA;
                let before = self.node.staged().get(p);
                self.rx(
                    "sdo-out-of-range",
                    sdo_download_f32(param_index(p), p.desc().max * 2.0 + 1.0),
                    Some(0x0609_0031),
                );
                let kept = self.node.staged().get(p).to_bits() == before.to_bits();
                // A 3-byte SDO request is malformed: abort, nothing written.
                self.rx("sdo-short", f(0x600 + u16::from(me), &[0x23, 0x00, 0x20]), Some(0x0504_0001));
                // A plain commit names no set: refused (0x06010000, EMCY 0x6320 code 9). The
                // commit names the set it means by its CRC-32 (0x2205).
                self.rx("commit-plain", sdo_download_u8(od::COMMIT, 0, 1), Some(0x0601_0000));
                self.rx("commit", sdo_download_u32(od::COMMIT_CRC, 0, joint_core::store::set_crc(&trunk)), None);
                self.s.committed_trunk_set = self.node.params().raw() == &trunk;
                self.rx("read-back", sdo_upload(param_index(ParamId::WeightAmplitude), 0), None);
                self.rx("save", sdo_download_u32(0x1010, 1, od::SAVE_SIGNATURE), None);
                self.s.saves = self.node.storage().saves;
                self.s.refused_writes_changed_nothing = kept;
            }
            T_START => self.rx("nmt-start", f(0x000, &[0x01, me]), None),
            T_SAFETY_WRITE => {
                let p = ParamId::TorqueLimit;
                let before = self.node.staged().get(p);
                self.rx("sdo-safety-while-operational", sdo_download_f32(param_index(p), 1.0), Some(0x0800_0022));
                self.s.refused_writes_changed_nothing &= self.node.staged().get(p).to_bits() == before.to_bits();
            }
            _ => {}
        }
        if self.step < T_HOST_SILENT && self.step % 100 == 1 {
            self.rx("host-heartbeat", f(hb, &[0x05]), None);
        }
        if self.step >= T_RPDO && self.step % 50 == 0 {
            // Assist command ramping in 0.05 N·m steps (0.01 N·m per LSB).
            let k = ((self.step - T_RPDO) / 50) as i16;
            let cmd = (5 * k).to_le_bytes();
            self.rx("rpdo-assist", f(0x200 + u16::from(me), &cmd), None);
        }
        if self.step == T_RPDO + 25 {
            // One byte short of the mapping: not processed, EMCY 0x8210.
            self.rx("rpdo-short", f(0x200 + u16::from(me), &[0x01]), None);
        }
    }
}

/// Steps of the FD session.
pub const STEPS_FD: u32 = 200;

impl<E: FnMut(&Line), C: ControlStep> Run<'_, E, C> {
    fn script_fd(&mut self) {
        let me = NODE_ID;
        let sdo = 0x600 + u16::from(me);
        match self.step {
            2 => {
                self.rx("nmt-preop", f(0x000, &[0x80, me]), None);
                // identity product code, asked in an FD frame with BRS, then without, then classic
                let req = f(sdo, &[0x40, 0x18, 0x10, 2, 0, 0, 0, 0]);
                self.rx("sdo-fd-brs", req.into_fd(true), None);
                self.rx("sdo-fd", req.into_fd(false), None);
                self.rx("sdo-classic", req, None);
                // TPDO3 every 5 ms
                self.rx("tpdo3-event-5ms", f(sdo, &[0x2B, 0x02, 0x18, 5, 5, 0, 0, 0]), None);
            }
            10 => self.rx("nmt-start", f(0x000, &[0x01, me]), None),
            _ => {}
        }
        if self.step % 100 == 1 {
            self.rx("host-heartbeat", f(0x700 + u16::from(HOST_ID), &[0x05]), None);
        }
        if self.step >= 20 && self.step % 20 == 0 && self.step != 160 {
            // six joints' commands; ours (node 5) at bytes 8..10: 5 × 7k (0.01 N·m), k = step / 20
            let k = (self.step / 20) as i16;
            let mut cmd = [0u8; 12];
            for (j, c) in cmd.chunks_exact_mut(2).enumerate() {
                let v = (j as i16 + 1) * if j + 1 == usize::from(me) { 7 * k } else { 1 };
                c.copy_from_slice(&v.to_le_bytes());
            }
            let shared = CanFrame::new_fd(od::SHARED_CMD_COB, &cmd, true).unwrap_or_default();
            self.rx("shared-command", shared, None);
            self.s.fd_assist_centi = math::floor(self.node.assist_cmd() * 100.0 + 0.5) as i32;
        }
        if self.step == 160 {
            // too short for node 5's slot: not processed (EMCY 0x8210), the command stays
            let before = self.node.assist_cmd().to_bits();
            self.rx("shared-command-short", f(od::SHARED_CMD_COB, &[1, 0, 2, 0]), None);
            self.s.fd_short_kept = self.node.assist_cmd().to_bits() == before;
        }
    }
}

/// Runs the FD session on a fresh node configured for CAN FD; `emit` gets every line.
/// Called after [`run_with`] returned, so the two nodes never share the stack.
pub fn run_fd_with<C: ControlStep>(emit: &mut impl FnMut(&Line)) -> Summary {
    let mut r = Run {
        node: Node::<MemoryStorage, C>::with_step(NodeConfig::new(NODE_ID).with_fd(true), MemoryStorage::default(), 0),
        ctl: ControlLoop::new(&joint_core::params::ParamSet::defaults()),
        emit,
        s: Summary::default(),
        step: 0,
    };
    r.rx_opt("boot", None, None);
    for step in 0..STEPS_FD {
        r.step = step;
        r.script_fd();
        r.tick();
    }
    r.s
}

/// Runs the session; `emit` gets every line in order.
/// `C` is the node's control step: the session is the same for a node whose step runs in Q16.16 (what the FPU-less
/// board image runs); only its control outputs differ.
///
/// The node is built straight into the session's state: a node moved from a local (≈ 9 KiB)
/// can cost the stack the image measures a second copy.
pub fn run_with<C: ControlStep>(emit: &mut impl FnMut(&Line)) -> Summary {
    let mut r = Run {
        node: Node::<MemoryStorage, C>::with_step(NodeConfig::new(NODE_ID), MemoryStorage::default(), 0),
        ctl: ControlLoop::new(&joint_core::params::ParamSet::defaults()),
        emit,
        s: Summary::default(),
        step: 0,
    };
    // The first process call sends the boot-up message.
    r.rx_opt("boot", None, None);
    for step in 0..STEPS {
        r.step = step;
        r.script();
        r.tick();
    }
    r.s
}

impl Summary {
    /// The FD session's summary line (`# canopen-fd …`).
    pub fn write_fd<W: Write>(&self, w: &mut W) -> fmt::Result {
        writeln!(
            w,
            "# canopen-fd lines={} frames={} fd_frames={} fd_tpdo={} fd_sdo_replies={} emcy={} assist_centi={} short_kept={}",
            self.lines,
            self.frames,
            self.fd_frames,
            self.fd_tpdo,
            self.fd_sdo_replies,
            self.emcy,
            self.fd_assist_centi,
            u8::from(self.fd_short_kept)
        )
    }

    pub fn write<W: Write>(&self, w: &mut W) -> fmt::Result {
        writeln!(
            w,
            "# canopen lines={} frames={} aborts={} expected_aborts={} emcy={} tpdo={} max_tau={:08x} final_tau={:08x} committed={} refused_unchanged={} saves={}",
            self.lines,
            self.frames,
            self.aborts,
            self.expected_aborts_seen,
            self.emcy,
            self.tpdo,
            self.max_tau.to_bits(),
            self.final_tau.to_bits(),
            u8::from(self.committed_trunk_set),
            u8::from(self.refused_writes_changed_nothing),
            self.saves
        )
    }
}
