//! The CANopen joint node: NMT, heartbeat producer/consumer, SDO server, EMCY, PDOs, and the
//! staged/committed parameter sets — sans-IO.
//!
//! The caller hands in time (µs) and received frames and gets frames out through a callback:
//! `node.process(now_us, Some(&frame), &mut |f| tx.push(f))`, and calls `process(now_us, None,
//! …)` at least every millisecond for the timers (heartbeat, TPDO event timer, SDO timeout).
//! The control loop runs through [`Node::control`], which steps the core controller with the
//! committed parameter set and the host's commands and passes the torque through the heartbeat
//! watchdog ([`crate::safety::Safety`]) the node feeds from the host's heartbeats.
//!
//! # Parameters: staged, committed, stored
//! SDO writes to the parameter objects change the **staged** [`RawParams`] only. A commit
//! names the set it commits: writing the staged set's CRC-32 ([`crate::store::set_crc`]) to
//! `params_commit_crc` (0x2205) runs [`params::check`] on the whole staged set and swaps it in
//! as one; if the CRC is not the staged set's, or the check fails, the committed set stays, the
//! write is aborted and the error is readable at 0x2201 and sent as EMCY 0x6320 naming the
//! parameter. So a half-pushed set never runs, and neither does a mix of two masters' values:
//! the CRC a master computes from the set it means cannot match a set another master also
//! wrote to. A plain commit (0x2200 ← 1), which named nothing, is refused (abort 0x06010000,
//! 0x2201 code 9); 0x2200 ← 0 discards the staged set. `save` (0x1010) persists the committed set through the
//! [`ParamStorage`] the firmware's flash task (or host-sim) implements; `load` (0x1011) makes
//! the stored set the defaults (CiA 301: in force after the next reset) and stages them.
//!
//! A staged set belongs to the SDO channel that wrote it and is discarded (0x2201 code 8,
//! EMCY 0x6320) when that channel carries nothing for 3 s: see `node/stage_owner.rs`.
//!
//! Safety-relevant parameters (`ParamDesc::safety`) are writable, and a commit that changes
//! them is accepted, only in pre-operational (abort 0x08000022 otherwise).
//!
//! # NMT
//! Boot-up (0x700 + id, `00`) on the first `process` call, then pre-operational. SDO and EMCY
//! run in pre-operational and operational, PDOs only in operational; stopped answers only NMT
//! and keeps its heartbeat. The torque is produced only in operational (mode Assist); every
//! other state commands zero torque.
//!
//! Nothing here panics or allocates, whatever the frames: the fuzz tests throw random frames
//! at it.

mod block;
mod channel;
#[cfg(feature = "lss")]
mod lss_slave;
mod stage_owner;

use super::frame::CanFrame;
use super::lss::LssConfig;
use super::od::{self, Access, DataType, Key, SubInfo};
use super::pdo::{self, from_i16, to_i16};
use super::pdo_map::{PdoMaps, PDO_MAPS_BYTES};
use super::sdo::{self, Abort};
use crate::control::{Controller, Input, Mode, Output};
use crate::fixed::{Arithmetic, ControllerFx};

/// A control step the node can run: what it needs of [`Controller`] and [`ControllerFx`].
pub trait ControlStep: Default {
    /// named in the node's identity
    const ARITHMETIC: Arithmetic;
    /// A new set is in force (the pre-sliding state starts afresh).
    fn configure(&mut self, p: &ParamSet);
    /// Forget the integrator and the last output.
    fn reset(&mut self);
    fn step(&mut self, p: &ParamSet, mode: Mode, inp: &Input, dt: f32) -> Output;
}

impl ControlStep for Controller {
    const ARITHMETIC: Arithmetic = Arithmetic::F32;
    fn configure(&mut self, _: &ParamSet) {
        self.reset_presliding();
    }
    fn reset(&mut self) {
        Controller::reset(self);
    }
    #[inline]
    fn step(&mut self, p: &ParamSet, mode: Mode, inp: &Input, dt: f32) -> Output {
        Controller::step(self, p, mode, inp, dt)
    }
}

impl ControlStep for ControllerFx {
    const ARITHMETIC: Arithmetic = Arithmetic::Q16;
    fn configure(&mut self, p: &ParamSet) {
        ControllerFx::configure(self, p);
    }
    fn reset(&mut self) {
        ControllerFx::reset(self);
    }
    #[inline]
    fn step(&mut self, p: &ParamSet, mode: Mode, inp: &Input, dt: f32) -> Output {
        ControllerFx::step(self, p, mode, inp, dt)
    }
}
use crate::math;
use crate::params::{ActiveParams, ParamError, ParamId, ParamSet, RawParams, PARAMS};
use crate::safety::{Faults, Safety, SafetyConfig};
use crate::series::{RawSeries, TERMS_MAX, TERM_BYTES};
use crate::table::{AXES_MAX, AXIS_POINTS_MAX, AXIS_SOURCE_MAX, CELLS_MAX};

/// NMT command specifiers (byte 0 of a 0x000 frame).
pub const NMT_START: u8 = 0x01;
pub const NMT_STOP: u8 = 0x02;
pub const NMT_PRE_OPERATIONAL: u8 = 0x80;
pub const NMT_RESET_NODE: u8 = 0x81;
pub const NMT_RESET_COMMUNICATION: u8 = 0x82;

/// COB-ID bases.
pub const EMCY_BASE: u16 = 0x080;
pub const HEARTBEAT_BASE: u16 = 0x700;
pub const TPDO1_BASE: u16 = 0x180;
pub const RPDO1_BASE: u16 = 0x200;
/// COB-ID bit 31: the PDO does not exist / is disabled.
pub const COB_INVALID: u32 = 0x8000_0000;

/// The node id `jointctl` uses for its own heartbeat, the default the node watches.
pub const DEFAULT_HOST_ID: u8 = 0x7F;
/// Default producer heartbeat period, ms.
pub const DEFAULT_HEARTBEAT_MS: u16 = 100;
/// Default TPDO event timer, ms (100 Hz telemetry).
pub const DEFAULT_TPDO_MS: u16 = 10;
/// 0x1005 default: the SYNC at COB-ID 0x80 (CiA 301), consumed only.
pub const DEFAULT_SYNC_COB: u32 = 0x80;
/// 0x1029 sub 1 default: 1, the NMT state stays where it is on a communication error. CiA 301's
/// default is 0 (pre-operational); a joint keeps operational because its safety layer already
/// fades the torque on a lost heartbeat or bus-off, and its TPDOs keep reporting why (the
/// fault bits). A master that wants the CiA behaviour writes 0 (or 2: stopped).
pub const DEFAULT_ERROR_BEHAVIOUR: u8 = 1;
/// A segmented transfer with no segment for this long is aborted (0x05040000).
pub const SDO_TIMEOUT_US: u64 = 1_000_000;
/// Largest segmented download the node buffers: the gravity table's torque array.
pub const SDO_BUFFER: usize = 4 * CELLS_MAX;

/// EMCY error codes (CiA 301 table 21).
pub const EMCY_RESET: u16 = 0x0000;
pub const EMCY_HEARTBEAT: u16 = 0x8130;
pub const EMCY_BUS_OFF: u16 = 0x8140;
pub const EMCY_PARAMS: u16 = 0x6320;
pub const EMCY_SOFTWARE: u16 = 0x6100;
pub const EMCY_PDO_LENGTH: u16 = 0x8210;
pub const EMCY_DEVICE: u16 = 0xFF00;

/// NMT state, with the heartbeat byte of each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NmtState {
    Initialising,
    PreOperational,
    Operational,
    Stopped,
}

impl NmtState {
    pub const fn heartbeat_byte(self) -> u8 {
        match self {
            NmtState::Initialising => 0x00,
            NmtState::Stopped => 0x04,
            NmtState::Operational => 0x05,
            NmtState::PreOperational => 0x7F,
        }
    }

    pub fn from_heartbeat_byte(b: u8) -> Option<NmtState> {
        match b & 0x7F {
            0x00 => Some(NmtState::Initialising),
            0x04 => Some(NmtState::Stopped),
            0x05 => Some(NmtState::Operational),
            0x7F => Some(NmtState::PreOperational),
            _ => None,
        }
    }

    pub const fn name(self) -> &'static str {
        match self {
            NmtState::Initialising => "initialising",
            NmtState::PreOperational => "pre-operational",
            NmtState::Operational => "operational",
            NmtState::Stopped => "stopped",
        }
    }
}

/// Identity object 0x1018.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identity {
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub serial: u32,
}

/// Fixed facts about a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// 1..=127; anything else is clamped into that range by [`Node::new`].
    pub node_id: u8,
    pub identity: Identity,
    /// 0x1008
    pub device_name: &'static str,
    /// 0x100A
    pub software_version: &'static str,
    /// The control step's arithmetic, named in the identity by [`NodeConfig::with_arithmetic`].
    /// [`Node::new`] sets it (and the identity) from the node's step type, so it cannot lie;
    /// a host sets it to describe a board (the EDS).
    pub arithmetic: Arithmetic,
    /// The bus is CAN FD (nominal and data bit rate, BRS): TPDO3 (the whole state in REAL32,
    /// 32 bytes, [`od::TPDO_FD`]) is valid and the classic TPDO1/2 start invalid; PDOs longer
    /// than 8 bytes go out as FD frames with bit-rate switch. SDO, NMT, heartbeat and EMCY
    /// stay 8-byte CiA 301 frames (SDO replies in the format of the request).
    pub fd: bool,
}

/// Identity of this project's joint node. The vendor id is 0 ("unassigned" in CiA's list):
/// we hold no CiA vendor id; a product shipping to others must get one.
pub const DEFAULT_IDENTITY: Identity =
    Identity { vendor_id: 0x0000_0000, product_code: 0x4A4E_0001, revision: 0x0001_0000, serial: 0 };

/// Product code (0x1018 sub 2) of a joint node whose control step runs in Q16.16: the host
/// reads which numbers the joint computes from the identity (and the EDS names it).
pub const PRODUCT_CODE_Q16: u32 = 0x4A4E_0002;

impl NodeConfig {
    pub const fn new(node_id: u8) -> NodeConfig {
        NodeConfig {
            node_id,
            identity: DEFAULT_IDENTITY,
            device_name: "joint-node",
            software_version: env!("CARGO_PKG_VERSION"),
            arithmetic: Arithmetic::F32,
            fd: false,
        }
    }

    /// The same node on a CAN FD bus (see [`NodeConfig::fd`]).
    pub const fn with_fd(self, fd: bool) -> NodeConfig {
        let mut c = self;
        c.fd = fd;
        c
    }

    /// The same node with its control step in `a`: a Q16.16 node has its own product code
    /// ([`PRODUCT_CODE_Q16`]) and device name, so a master (and its EDS) tells them apart.
    pub const fn with_arithmetic(self, a: Arithmetic) -> NodeConfig {
        let mut c = self;
        c.arithmetic = a;
        match a {
            Arithmetic::F32 => {
                c.identity.product_code = DEFAULT_IDENTITY.product_code;
                c.device_name = "joint-node";
            }
            Arithmetic::Q16 => {
                c.identity.product_code = PRODUCT_CODE_Q16;
                c.device_name = "joint-node q16.16";
            }
        }
        c
    }
}

/// Why a store operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StorageError {
    /// A save is already running, or the flash is busy.
    Busy,
    /// The medium failed.
    Failed,
    /// This node has no persistent storage.
    Unsupported,
}

/// Persistent parameter storage, implemented by whoever owns the flash (or a file).
pub trait ParamStorage {
    /// Persist the committed set. `Ok` means accepted: a firmware flash task may finish the
    /// write later and raise [`Faults::STORE_WRITE`] should it fail.
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError>;
    /// Keep the PDO mappings (0x1010 saves them with the parameters; [`PdoMaps::to_bytes`]).
    /// A storage that does not keep them says [`StorageError::Unsupported`]: the parameters
    /// are saved all the same and the mappings return to their defaults at reset.
    fn save_pdo(&mut self, _maps: &[u8; PDO_MAPS_BYTES]) -> Result<(), StorageError> {
        Err(StorageError::Unsupported)
    }
    /// The stored PDO mappings, if any (read at every reset of communication).
    fn load_pdo(&mut self) -> Option<[u8; PDO_MAPS_BYTES]> {
        None
    }
    /// The stored set, read at boot and on NMT reset-node; `None` when nothing is stored.
    fn load(&mut self) -> Option<RawParams>;
    /// The fault the last [`ParamStorage::load`] found (a damaged or unreadable store), raised
    /// by the node after it; none by default.
    fn load_fault(&self) -> Faults {
        Faults::NONE
    }
    /// Forget the stored set, so the next reset runs the table defaults (0x1011 "load").
    fn restore_defaults(&mut self) -> Result<(), StorageError>;
    /// LSS: the stored node id and bit timing, read at power-on and on reset node; none by
    /// default.
    fn load_lss(&mut self) -> Option<LssConfig> {
        None
    }
    /// LSS store configuration; not supported by default (the master gets error 1).
    fn save_lss(&mut self, _c: LssConfig) -> Result<(), StorageError> {
        Err(StorageError::Unsupported)
    }
}

/// A node without persistent storage: `save` and `load` are refused with 0x08000020.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoStorage;

impl ParamStorage for NoStorage {
    fn save(&mut self, _set: &ParamSet) -> Result<(), StorageError> {
        Err(StorageError::Unsupported)
    }
    fn load(&mut self) -> Option<RawParams> {
        None
    }
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        Err(StorageError::Unsupported)
    }
}

/// Storage in RAM (host-sim and tests): survives NMT resets, not the process.
#[derive(Clone, Debug, Default)]
pub struct MemoryStorage {
    pub stored: Option<RawParams>,
    pub saves: u32,
    /// the PDO mappings saved with the set
    pub pdo: Option<[u8; PDO_MAPS_BYTES]>,
    /// the LSS configuration stored
    pub lss: Option<LssConfig>,
}

impl ParamStorage for MemoryStorage {
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        self.stored = Some(set.raw().clone());
        self.saves = self.saves.saturating_add(1);
        Ok(())
    }
    fn load(&mut self) -> Option<RawParams> {
        self.stored.clone()
    }
    fn save_pdo(&mut self, maps: &[u8; PDO_MAPS_BYTES]) -> Result<(), StorageError> {
        self.pdo = Some(*maps);
        Ok(())
    }
    fn load_pdo(&mut self) -> Option<[u8; PDO_MAPS_BYTES]> {
        self.pdo
    }
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        self.stored = None;
        self.pdo = None;
        Ok(())
    }
    fn load_lss(&mut self) -> Option<LssConfig> {
        self.lss
    }
    fn save_lss(&mut self, c: LssConfig) -> Result<(), StorageError> {
        self.lss = Some(c);
        Ok(())
    }
}

/// The last refused commit, readable at 0x2201.
#[derive(Clone, Debug, PartialEq)]
pub struct CommitError {
    /// 1 not finite, 2 out of range, 3 inconsistent, 4 gravity table, 5 safety parameter
    /// changed outside pre-operational, 6 gravity series, 7 the named CRC is not the staged
    /// set's, 8 the staged set was discarded because its master stopped (not a refused
    /// commit: the node says so the same way, 0x2201 and EMCY 0x6320), 9 a plain commit
    /// (0x2200 ← 1), which names no set
    pub code: u8,
    /// index into `PARAMS` (object 0x2000 + index), 0xFFFF for table and series errors
    pub param: u16,
    pub message: heapless::String<120>,
}

/// The measured part of the joint state, set by the control loop for the TPDOs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointState {
    pub q: f32,
    pub qd: f32,
    pub qdd: f32,
    /// torque applied (after the safety layer), N·m at the output
    pub tau_cmd: f32,
    /// load-cell torque, N·m (0 without a load cell)
    pub tau_measured: f32,
    /// °C
    pub temperature: f32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Tpdo {
    cob_id: u32,
    transmission: u8,
    /// 100 µs units
    inhibit: u16,
    /// ms
    event_ms: u16,
    next_us: u64,
    last_us: Option<u64>,
    /// SYNCs counted since the last synchronous transmission (types 1..=240)
    syncs: u8,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Big {
    DeviceName,
    SoftwareVersion,
    ErrorMessage,
    Grid,
    Torque,
    Sigma,
    Series,
}

enum Value {
    Small([u8; 4], usize),
    Big(Big),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Transfer {
    Idle,
    Download { info: SubInfo, toggle: bool, len: usize, expected: Option<usize>, last_us: u64 },
    Upload { index: u16, sub: u8, src: Big, toggle: bool, offset: usize, total: usize, last_us: u64 },
    BlockDownload(block::Down),
    BlockUpload(block::Up),
}

/// The joint's CANopen node. See the module documentation.
///
/// `C` is the control step: [`Controller`] (f32, the default) or [`ControllerFx`] (Q16.16),
/// a type rather than a flag so a board image links only the step it runs (both in the G431's
/// 64 KiB cost it 10 KiB of flash).
pub struct Node<S: ParamStorage, C: ControlStep = Controller> {
    cfg: NodeConfig,
    /// the node id given at construction: in force after reset node unless LSS stored one
    #[cfg_attr(not(feature = "lss"), allow(dead_code))]
    boot_id: u8,
    #[cfg(feature = "lss")]
    lss: super::lss::Lss,
    storage: S,
    nmt: NmtState,
    boot_sent: bool,
    active: ActiveParams,
    staged: RawParams,
    commit_error: Option<CommitError>,
    safety: Safety,
    controller: C,
    heartbeat_ms: u16,
    next_heartbeat_us: u64,
    host_id: u8,
    rpdo_cob: [u32; od::RPDO_COUNT as usize],
    tpdo: [Tpdo; od::TPDO_COUNT as usize],
    /// the PDO mappings in force (0x1600.., 0x1A00..)
    maps: PdoMaps,
    assist_cmd: f32,
    others: [f32; 3],
    state: JointState,
    transfer: Transfer,
    buf: [u8; SDO_BUFFER],
    /// the second SDO server channel (0x1201)
    sdo2: channel::Server2,
    /// the SDO channel being served: 0 default, 1 the second
    chan: u8,
    last_faults: Faults,
    /// 0x1003: the last EMCY codes (code | error register << 16), newest first
    error_history: [u32; od::ERROR_HISTORY_LEN],
    error_count: u8,
    /// 0x1005 (consumer only: bit 30 never set)
    sync_cob: u32,
    /// 0x1029 sub 1
    error_behaviour: u8,
    /// a refused commit waits for its EMCY
    pending_commit_emcy: bool,
    /// the SDO channel whose master wrote to the staged set since the last commit or discard
    staged_by: Option<u8>,
    /// when that channel last carried a request
    stage_seen_us: u64,
    now_us: u64,
    /// frames ignored because they were malformed (wrong length), for diagnostics
    pub dropped: u32,
}

fn put_u32(v: u32) -> Value {
    Value::Small(v.to_le_bytes(), 4)
}
fn put_u16(v: u16) -> Value {
    let b = v.to_le_bytes();
    Value::Small([b[0], b[1], 0, 0], 2)
}
fn put_i16(v: i16) -> Value {
    put_u16(v as u16)
}
fn put_u8(v: u8) -> Value {
    Value::Small([v, 0, 0, 0], 1)
}

fn le_u32(d: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    for (dst, src) in b.iter_mut().zip(d) {
        *dst = *src;
    }
    u32::from_le_bytes(b)
}

fn frame(id: u16, data: [u8; 8], len: u8) -> CanFrame {
    CanFrame::from_parts(id, data, len)
}

impl<S: ParamStorage> Node<S> {
    /// A node with the f32 control step at boot time `now_us`: the stored set if it passes the
    /// check, else the defaults (with [`Faults::PARAMS_REJECTED`] latched when a stored set was
    /// refused). [`Node::with_step`] builds one with another step.
    #[inline(always)]
    pub fn new(cfg: NodeConfig, storage: S, now_us: u64) -> Self {
        Self::with_step(cfg, storage, now_us)
    }
}

impl<S: ParamStorage, C: ControlStep> Node<S, C> {
    /// A node whose control step is `C` (`Node::<_, ControllerFx>::with_step` for Q16.16); see
    /// [`Node::new`].
    ///
    /// Always inlined: out of line, the ≈ 9 KiB node is built in this function's frame and
    /// then copied into the caller's, which doubles the stack building it takes (measured
    /// in the QEMU CANopen image, scripts/qemu-test.sh); inlined, it is built in place.
    #[inline(always)]
    pub fn with_step(cfg: NodeConfig, storage: S, now_us: u64) -> Self {
        let mut node = Self::with_step_cold(cfg, storage, now_us);
        node.reset_node(now_us);
        node
    }

    /// [`Node::with_step`] without its reset (reading the storage, building the set): for a
    /// node constructed into a static, as the boards do, whose reset then runs in place
    /// ([`Node::reset_in_place`]). The construction's stack then holds the node and nothing
    /// else, the reset's the set's temporaries and not the node: the peak is the larger of
    /// the two, not their sum (on the G431, 7.5 KiB against 19.5 KiB).
    pub fn with_step_cold(cfg: NodeConfig, storage: S, now_us: u64) -> Self {
        // The identity names the step the node really runs, whatever the config said.
        let mut cfg = cfg.with_arithmetic(C::ARITHMETIC);
        // with LSS, 0xFF is a node waiting for its id (CiA 305)
        if !(cfg!(feature = "lss") && cfg.node_id == super::lss::UNCONFIGURED) {
            cfg.node_id = cfg.node_id.clamp(1, 127);
        }
        Node {
            cfg,
            boot_id: cfg.node_id,
            #[cfg(feature = "lss")]
            lss: super::lss::Lss::new(LssConfig { node_id: cfg.node_id, bit_timing: 0 }),
            storage,
            nmt: NmtState::Initialising,
            boot_sent: false,
            staged: RawParams::defaults(),
            active: ActiveParams::new(ParamSet::defaults()),
            commit_error: None,
            safety: Safety::new(SafetyConfig::from_seconds(0.0, 0.0, 0.0), now_us),
            controller: C::default(),
            heartbeat_ms: DEFAULT_HEARTBEAT_MS,
            next_heartbeat_us: now_us,
            host_id: DEFAULT_HOST_ID,
            rpdo_cob: [0; od::RPDO_COUNT as usize],
            maps: PdoMaps::EMPTY,
            tpdo: [Tpdo { cob_id: 0, transmission: 0, inhibit: 0, event_ms: 0, next_us: 0, last_us: None, syncs: 0 };
                od::TPDO_COUNT as usize],
            error_history: [0; od::ERROR_HISTORY_LEN],
            error_count: 0,
            sync_cob: DEFAULT_SYNC_COB,
            error_behaviour: DEFAULT_ERROR_BEHAVIOUR,
            assist_cmd: 0.0,
            others: [0.0; 3],
            state: JointState::default(),
            transfer: Transfer::Idle,
            buf: [0; SDO_BUFFER],
            sdo2: channel::Server2::new(),
            chan: 0,
            last_faults: Faults::NONE,
            pending_commit_emcy: false,
            staged_by: None,
            stage_seen_us: now_us,
            now_us,
            dropped: 0,
        }
    }

    /// The reset [`Node::with_step`] ends with, for a node built by [`Node::with_step_cold`]:
    /// an NMT reset node (stored set, LSS configuration and mappings read, boot-up next).
    pub fn reset_in_place(&mut self, now_us: u64) {
        self.reset_node(now_us);
    }

    /// NMT reset node: parameters from storage, communication objects to defaults, a fresh
    /// watchdog (soft start), boot-up on the next `process`.
    fn reset_node(&mut self, now_us: u64) {
        // In place throughout: a parameter set is ~2.9 KiB and this runs at boot on the MCU.
        #[cfg(feature = "lss")]
        self.lss_boot();
        let mut faults = Faults::NONE;
        match self.storage.load() {
            Some(raw) => {
                if self.active.replace(&raw).is_err() {
                    faults = Faults::PARAMS_REJECTED;
                    self.active.reset_to_defaults();
                }
            }
            None => self.active.reset_to_defaults(),
        }
        faults.insert(self.storage.load_fault());
        self.staged.clone_from(self.active.current().raw());
        self.staged_by = None;
        self.safety = Safety::new(SafetyConfig::from_params(self.active.current()), now_us);
        self.safety.raise(faults);
        self.commit_error = None;
        self.controller.reset();
        self.controller.configure(self.active.current());
        self.assist_cmd = 0.0;
        self.others = [0.0; 3];
        self.reset_communication(now_us);
    }

    /// NMT reset communication: COB-IDs, timers and the SDO server to defaults.
    fn reset_communication(&mut self, now_us: u64) {
        // CiA 305: the node id configured by LSS goes live here
        #[cfg(feature = "lss")]
        {
            self.cfg.node_id = self.lss.pending.node_id;
        }
        let id = u16::from(self.cfg.node_id);
        self.heartbeat_ms = DEFAULT_HEARTBEAT_MS;
        self.host_id = DEFAULT_HOST_ID;
        // an FD node with a slot takes its command from the host's shared command frame
        let rpdo1 =
            if self.cfg.fd && id <= u16::from(od::SHARED_CMD_IDS) { od::SHARED_CMD_COB } else { RPDO1_BASE + id };
        self.rpdo_cob = [u32::from(rpdo1), COB_INVALID, COB_INVALID, COB_INVALID];
        let fd = self.cfg.fd;
        for (n, t) in self.tpdo.iter_mut().enumerate() {
            // an FD node sends the whole state in TPDO3, a classic one in TPDO1/2
            let off = if (n as u8 == od::TPDO_FD) == fd { 0 } else { COB_INVALID };
            *t = Tpdo {
                cob_id: u32::from(TPDO1_BASE + 0x100 * n as u16 + id) | off,
                transmission: 0xFE,
                inhibit: 0,
                event_ms: DEFAULT_TPDO_MS,
                next_us: now_us,
                last_us: None,
                syncs: 0,
            };
        }
        // the stored mappings (0x1010), else the dictionary's
        self.maps.reset(self.cfg.node_id, fd);
        self.load_stored_maps();
        self.sync_cob = DEFAULT_SYNC_COB;
        self.error_behaviour = DEFAULT_ERROR_BEHAVIOUR;
        self.transfer = Transfer::Idle;
        self.sdo2.reset();
        self.nmt = NmtState::Initialising;
        self.boot_sent = false;
        self.next_heartbeat_us = now_us;
    }

    // ---- accessors for the control loop and the host ------------------------------------

    /// The node id in force (0xFF: unconfigured, waiting for LSS).
    pub fn node_id(&self) -> u8 {
        self.cfg.node_id
    }
    /// The node's fixed facts (identity, names) with the node id in force.
    pub fn config(&self) -> &NodeConfig {
        &self.cfg
    }
    pub fn nmt_state(&self) -> NmtState {
        self.nmt
    }
    /// The committed, validated parameter set the control loop runs.
    pub fn params(&self) -> &ParamSet {
        self.active.current()
    }
    /// The staged set (what SDO writes changed since the last commit).
    pub fn staged(&self) -> &RawParams {
        &self.staged
    }
    pub fn commit_error(&self) -> Option<&CommitError> {
        self.commit_error.as_ref()
    }
    pub fn safety(&self) -> &Safety {
        &self.safety
    }
    /// For faults detected outside the node (bus-off, loop overrun, store write failure).
    pub fn safety_mut(&mut self) -> &mut Safety {
        &mut self.safety
    }
    pub fn storage(&self) -> &S {
        &self.storage
    }
    pub fn storage_mut(&mut self) -> &mut S {
        &mut self.storage
    }
    /// Give the storage back (a power cycle in tests: build a new node on it).
    pub fn into_storage(self) -> S {
        self.storage
    }
    /// The host's assist command (RPDO1), N·m.
    pub fn assist_cmd(&self) -> f32 {
        self.assist_cmd
    }
    /// The other joints' angles (RPDO2..4), rad.
    pub fn others(&self) -> [f32; 3] {
        self.others
    }
    pub fn joint_state(&self) -> &JointState {
        &self.state
    }
    /// Sensor values: the load cell's torque (the step's load-dependent friction reads it at
    /// the next [`Node::control`]) and the temperature (reported only).
    pub fn set_measurements(&mut self, tau_measured: f32, temperature: f32) {
        self.state.tau_measured = tau_measured;
        self.state.temperature = temperature;
    }

    /// The controller mode the NMT state allows: assist only while operational.
    pub fn mode(&self) -> Mode {
        if self.nmt == NmtState::Operational {
            Mode::Assist
        } else {
            Mode::Off
        }
    }

    /// One control step: the core controller with the committed set, the host's commands and
    /// the NMT mode, then the heartbeat watchdog. Returns the controller's output with
    /// `tau_out`/`u_motor` after the safety layer; records the state for the TPDOs.
    pub fn control(&mut self, now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output {
        let mode = self.mode();
        let inp =
            Input { q, qd, qdd, others: self.others, assist_cmd: self.assist_cmd, tau_load: self.state.tau_measured };
        let p = self.active.current();
        let mut out = self.controller.step(p, mode, &inp, dt);
        let tau = self.safety.update(now_us, out.tau_out);
        out.tau_out = tau;
        out.u_motor = tau * p.inv_ratio_m1();
        self.state.q = q;
        self.state.qd = qd;
        self.state.qdd = qdd;
        self.state.tau_cmd = tau;
        out
    }

    // ---- frame processing -----------------------------------------------------------------

    /// Handle one received frame (if any) and run the timers up to `now_us`; every frame the
    /// node sends goes through `tx`, in order.
    pub fn process(&mut self, now_us: u64, rx: Option<&CanFrame>, tx: &mut impl FnMut(CanFrame)) {
        self.now_us = now_us;
        self.boot_up(now_us, tx);
        if let Some(f) = rx {
            self.on_frame(now_us, f, tx);
            // an NMT reset boots again at once
            self.boot_up(now_us, tx);
        }
        self.poll(now_us, tx);
    }

    fn boot_up(&mut self, now_us: u64, tx: &mut impl FnMut(CanFrame)) {
        // an unconfigured node (LSS) stays silent: no boot-up, no heartbeat, until it has an id
        let unconfigured = cfg!(feature = "lss") && self.cfg.node_id == super::lss::UNCONFIGURED;
        if !self.boot_sent && !unconfigured {
            self.boot_sent = true;
            self.nmt = NmtState::PreOperational;
            tx(frame(HEARTBEAT_BASE + u16::from(self.cfg.node_id), [0; 8], 1));
            self.next_heartbeat_us = now_us.saturating_add(u64::from(self.heartbeat_ms) * 1000);
        }
    }

    fn on_frame(&mut self, now_us: u64, f: &CanFrame, tx: &mut impl FnMut(CanFrame)) {
        let id = f.id();
        let me = u16::from(self.cfg.node_id);
        let d = f.data();
        #[cfg(feature = "lss")]
        if id == super::lss::LSS_MASTER {
            self.lss_frame(now_us, d, tx);
            return;
        }
        #[cfg(feature = "lss")]
        if self.cfg.node_id == super::lss::UNCONFIGURED {
            return;
        }
        if id == 0 {
            // NMT: exactly 2 bytes, addressed to us or to all (0).
            if let [cs, target] = *d {
                if target == 0 || target == self.cfg.node_id {
                    self.nmt_command(now_us, cs);
                }
            } else {
                self.dropped = self.dropped.saturating_add(1);
            }
            return;
        }
        if id == HEARTBEAT_BASE + u16::from(self.host_id) && self.host_id != 0 && self.host_id != self.cfg.node_id {
            // Any state byte counts: the host is alive. Boot-up (0) too.
            if d.len() == 1 {
                self.safety.on_heartbeat(now_us);
            } else {
                self.dropped = self.dropped.saturating_add(1);
            }
            return;
        }
        match self.nmt {
            NmtState::Stopped | NmtState::Initialising => return,
            NmtState::PreOperational | NmtState::Operational => {}
        }
        if u32::from(id) == self.sync_cob & 0x7FF {
            // SYNC: 0 bytes, or 1 with the producer's counter
            if d.len() <= 1 {
                if self.nmt == NmtState::Operational {
                    self.on_sync(now_us, tx);
                }
            } else {
                self.dropped = self.dropped.saturating_add(1);
            }
            return;
        }
        if id == sdo::RX_BASE + me {
            // classic SDO in FD frames too (no CiA 1301 USDO): a reply takes its request's format
            let brs = f.is_fd().then(|| f.brs());
            self.sdo_serve(now_us, d, sdo::TX_BASE + me, &mut |r: CanFrame| {
                tx(match brs {
                    Some(b) => r.into_fd(b),
                    None => r,
                })
            });
            return;
        }
        if self.sdo2_frame(now_us, f, tx) {
            return;
        }
        if self.nmt == NmtState::Operational {
            for n in 0..od::RPDO_COUNT {
                let cob = self.rpdo_cob.get(n as usize).copied().unwrap_or(COB_INVALID);
                if cob & COB_INVALID == 0 && u32::from(id) == cob & 0x7FF {
                    self.rpdo(n, d, tx);
                }
            }
        }
    }

    fn rpdo(&mut self, n: u8, d: &[u8], tx: &mut impl FnMut(CanFrame)) {
        let mut copy = [0u32; od::MAP_MAX];
        let src = self.maps.get(false, n);
        for (c, s) in copy.iter_mut().zip(src) {
            *c = *s;
        }
        let map = copy.get(..src.len()).unwrap_or(&[]);
        let need: usize = map.iter().map(|m| (m & 0xFF) as usize / 8).sum();
        if d.len() < need {
            // CiA 301: a PDO shorter than its mapping is not processed; EMCY 0x8210.
            self.emcy(EMCY_PDO_LENGTH, [n, d.len() as u8, 0, 0, 0], tx);
            return;
        }
        let mut off = 0usize;
        for m in map {
            let bytes = (m & 0xFF) as usize / 8;
            let index = (m >> 16) as u16;
            let sub = ((m >> 8) & 0xFF) as u8;
            // dummy entries (data-type indices) only skip their bytes
            if let (Some(chunk), Ok(info), true) = (d.get(off..off + bytes), od::sub_info(index, sub), index >= 0x1000)
            {
                // Mapped objects are plain RW integers: the write cannot be refused.
                let _ = self.write_value(&info, chunk, false);
            }
            off += bytes;
        }
    }

    fn nmt_command(&mut self, now_us: u64, cs: u8) {
        match cs {
            NMT_START => self.go(NmtState::Operational, now_us),
            NMT_STOP => self.go(NmtState::Stopped, now_us),
            NMT_PRE_OPERATIONAL => self.go(NmtState::PreOperational, now_us),
            NMT_RESET_NODE => self.reset_node(now_us),
            NMT_RESET_COMMUNICATION => self.reset_communication(now_us),
            _ => self.dropped = self.dropped.saturating_add(1),
        }
    }

    fn go(&mut self, s: NmtState, now_us: u64) {
        if self.nmt == NmtState::Initialising {
            return;
        }
        if s == NmtState::Operational && self.nmt != NmtState::Operational {
            for t in self.tpdo.iter_mut() {
                t.next_us = now_us;
            }
            self.controller.reset();
        }
        if s != NmtState::Operational {
            self.assist_cmd = 0.0;
        }
        self.nmt = s;
    }

    /// Timers: heartbeat, EMCY for new faults, TPDOs, SDO timeout.
    pub fn poll(&mut self, now_us: u64, tx: &mut impl FnMut(CanFrame)) {
        self.now_us = now_us;
        if !self.boot_sent {
            return;
        }
        let me = u16::from(self.cfg.node_id);
        if self.heartbeat_ms != 0 && now_us >= self.next_heartbeat_us {
            tx(frame(HEARTBEAT_BASE + me, [self.nmt.heartbeat_byte(), 0, 0, 0, 0, 0, 0, 0], 1));
            let period = u64::from(self.heartbeat_ms) * 1000;
            // Catch up without a burst after a stall.
            self.next_heartbeat_us = self.next_heartbeat_us.saturating_add(period).max(now_us.saturating_add(1));
        }

        // Advance the watchdog clock so a lost heartbeat is noticed even without control steps.
        let faults = self.safety.faults();
        let new = self.safety.take_new_faults();
        self.stage_watch(now_us);
        if self.nmt != NmtState::Stopped {
            if !new.is_empty() {
                let b = faults.bits().to_le_bytes();
                self.emcy(emcy_code(new), [b[0], b[1], 0, 0, 0], tx);
                // 0x1029: a communication error (host heartbeat lost, bus-off) and the NMT state
                let comm = new.intersects(Faults::HEARTBEAT_LOST) || new.intersects(Faults::CAN_BUS_OFF);
                if comm && self.nmt == NmtState::Operational {
                    match self.error_behaviour {
                        0 => self.go(NmtState::PreOperational, now_us),
                        2 => self.go(NmtState::Stopped, now_us),
                        _ => {}
                    }
                }
            } else if faults.is_empty() && !self.last_faults.is_empty() {
                self.emcy(EMCY_RESET, [0; 5], tx);
            }
        }
        self.last_faults = faults;
        if self.pending_commit_emcy && self.nmt != NmtState::Stopped {
            self.pending_commit_emcy = false;
            let (code, param) = self.commit_error.as_ref().map_or((0, 0xFFFF), |e| (e.code, e.param));
            let p = param.to_le_bytes();
            let f = faults.bits().to_le_bytes();
            // manufacturer bytes: commit error code, parameter index (0x2000 + it is the object), faults
            self.emcy(EMCY_PARAMS, [code, p[0], p[1], f[0], f[1]], tx);
        }

        self.sdo_timers(now_us, sdo::TX_BASE + me, tx);
        self.sdo2_poll(now_us, tx);

        if self.nmt == NmtState::Operational {
            for n in 0..od::TPDO_COUNT {
                self.tpdo_timer(n, now_us, tx);
            }
        }
    }

    /// The SDO transfer's timeout (0x05040000 to `cob`) and a block upload's next burst.
    fn sdo_timers(&mut self, now_us: u64, cob: u16, tx: &mut impl FnMut(CanFrame)) {
        let (index, sub, last_us) = match self.transfer {
            Transfer::Idle => return,
            Transfer::Download { info, last_us, .. } => (info.index, info.sub, last_us),
            Transfer::Upload { index, sub, last_us, .. } => (index, sub, last_us),
            Transfer::BlockDownload(b) => b.timer(),
            Transfer::BlockUpload(b) => b.timer(),
        };
        if now_us.saturating_sub(last_us) > SDO_TIMEOUT_US {
            self.transfer = Transfer::Idle;
            tx(frame(cob, sdo::abort_payload(index, sub, Abort::Timeout), 8));
        } else {
            self.block_pump(cob, tx);
        }
    }

    /// A SYNC while operational: each synchronous TPDO (type N in 1..=240) goes out on every
    /// Nth SYNC, with the state as it is now.
    fn on_sync(&mut self, now_us: u64, tx: &mut impl FnMut(CanFrame)) {
        for n in 0..od::TPDO_COUNT {
            let Some(t) = self.tpdo.get_mut(n as usize) else { continue };
            if t.cob_id & COB_INVALID != 0 || !(1..=240).contains(&t.transmission) {
                continue;
            }
            t.syncs = t.syncs.saturating_add(1);
            if t.syncs < t.transmission {
                continue;
            }
            t.syncs = 0;
            t.last_us = Some(now_us);
            let cob = (t.cob_id & 0x7FF) as u16;
            tx(self.tpdo_frame(n, cob));
        }
    }

    fn tpdo_timer(&mut self, n: u8, now_us: u64, tx: &mut impl FnMut(CanFrame)) {
        let Some(t) = self.tpdo.get(n as usize).copied() else {
            return;
        };
        // the event timer drives event-driven types only; synchronous ones wait for SYNC
        if t.cob_id & COB_INVALID != 0 || t.event_ms == 0 || now_us < t.next_us || t.transmission < 0xFE {
            return;
        }
        if let Some(last) = t.last_us {
            if now_us.saturating_sub(last) < u64::from(t.inhibit) * 100 {
                return;
            }
        }
        tx(self.tpdo_frame(n, (t.cob_id & 0x7FF) as u16));
        if let Some(t) = self.tpdo.get_mut(n as usize) {
            let period = u64::from(t.event_ms) * 1000;
            t.next_us = t.next_us.saturating_add(period).max(now_us.saturating_add(1));
            t.last_us = Some(now_us);
        }
    }

    /// The current payload of TPDO `n` (0-based) as far as a classic frame holds it: its first
    /// 8 bytes and its length, at most 8 ([`Node::tpdo_frame`] has the whole of an FD TPDO).
    pub fn tpdo_payload(&self, n: u8) -> ([u8; 8], u8) {
        let f = self.tpdo_frame(n, 0);
        (*f.raw_data(), f.len().min(8) as u8)
    }

    /// TPDO `n` (0-based) as it goes out with COB-ID `cob`: a classic frame if its mapping
    /// holds ≤ 8 bytes, else an FD frame with bit-rate switch (only an FD node validates such
    /// a TPDO).
    pub fn tpdo_frame(&self, n: u8, cob: u16) -> CanFrame {
        let mut data = [0u8; crate::canopen::frame::FD_MAX_LEN];
        let mut off = 0usize;
        for m in self.maps.get(true, n) {
            let bytes = (m & 0xFF) as usize / 8;
            let index = (m >> 16) as u16;
            let sub = ((m >> 8) & 0xFF) as u8;
            if let Ok(info) = od::sub_info(index, sub) {
                if let Ok(Value::Small(v, l)) = self.read_value(&info) {
                    for (dst, src) in data.iter_mut().skip(off).zip(v.iter().take(l.min(bytes))) {
                        *dst = *src;
                    }
                }
            }
            off += bytes;
        }
        let d = data.get(..off).unwrap_or(&data);
        if off <= 8 { CanFrame::new(cob, d) } else { CanFrame::new_fd(cob, d, true) }.unwrap_or_default()
    }

    fn emcy(&mut self, code: u16, mfr: [u8; 5], tx: &mut impl FnMut(CanFrame)) {
        if code != EMCY_RESET {
            // 0x1003: newest first, the oldest falls off
            let entry = u32::from(code) | (u32::from(self.error_register()) << 16);
            self.error_history.rotate_right(1);
            if let Some(first) = self.error_history.first_mut() {
                *first = entry;
            }
            self.error_count = self.error_count.saturating_add(1).min(od::ERROR_HISTORY_LEN as u8);
        }
        let c = code.to_le_bytes();
        let d = [c[0], c[1], self.error_register(), mfr[0], mfr[1], mfr[2], mfr[3], mfr[4]];
        tx(frame(EMCY_BASE + u16::from(self.cfg.node_id), d, 8));
    }

    /// 0x1001: bit 0 any fault, bit 4 communication (heartbeat lost, bus-off), bit 7
    /// manufacturer-specific (every other fault bit).
    pub fn error_register(&self) -> u8 {
        let f = self.safety.faults();
        let mut r = 0u8;
        if !f.is_empty() {
            r |= 0x01;
        }
        if f.intersects(Faults::HEARTBEAT_LOST.union(Faults::CAN_BUS_OFF)) {
            r |= 0x10;
        }
        if !f.difference(Faults::HEARTBEAT_LOST.union(Faults::CAN_BUS_OFF)).is_empty() {
            r |= 0x80;
        }
        r
    }

    // ---- SDO server -----------------------------------------------------------------------

    fn sdo_request(&mut self, now_us: u64, d: &[u8]) -> Option<[u8; 8]> {
        let b = |i: usize| d.get(i).copied().unwrap_or(0);
        let index = u16::from_le_bytes([b(1), b(2)]);
        let sub = b(3);
        if d.len() != 8 {
            // CiA 301 SDO frames always carry 8 bytes.
            self.dropped = self.dropped.saturating_add(1);
            self.transfer = Transfer::Idle;
            return Some(sdo::abort_payload(index, sub, Abort::Command));
        }
        let cmd = b(0);
        match cmd >> 5 {
            sdo::CCS_INITIATE_DOWNLOAD => {
                self.transfer = Transfer::Idle;
                Some(
                    self.initiate_download(now_us, index, sub, cmd, d)
                        .unwrap_or_else(|a| sdo::abort_payload(index, sub, a)),
                )
            }
            sdo::CCS_DOWNLOAD_SEGMENT => self.download_segment(now_us, cmd, d),
            sdo::CCS_INITIATE_UPLOAD => {
                self.transfer = Transfer::Idle;
                Some(self.initiate_upload(now_us, index, sub).unwrap_or_else(|a| sdo::abort_payload(index, sub, a)))
            }
            sdo::CCS_UPLOAD_SEGMENT => self.upload_segment(now_us, cmd),
            sdo::CCS_ABORT => {
                self.transfer = Transfer::Idle;
                None
            }
            _ => {
                self.transfer = Transfer::Idle;
                Some(sdo::abort_payload(index, sub, Abort::Command))
            }
        }
    }

    fn initiate_download(&mut self, now_us: u64, index: u16, sub: u8, cmd: u8, d: &[u8]) -> Result<[u8; 8], Abort> {
        let info = od::sub_info(index, sub)?;
        if !info.access.writable() {
            return Err(Abort::ReadOnly);
        }
        let expedited = cmd & 0x02 != 0;
        let sized = cmd & 0x01 != 0;
        let ok = [0x60, d.get(1).copied().unwrap_or(0), d.get(2).copied().unwrap_or(0), sub, 0, 0, 0, 0];
        if expedited {
            let len = if sized { 4 - ((cmd >> 2) & 0x03) as usize } else { info.dtype.size().unwrap_or(4).min(4) };
            let data = d.get(4..4 + len).ok_or(Abort::TypeLength)?;
            self.write_value(&info, data, true)?;
            return Ok(ok);
        }
        let expected = if sized { Some(le_u32(d.get(4..8).unwrap_or(&[])) as usize) } else { None };
        if let Some(n) = expected {
            check_len(&info, n)?;
        }
        self.transfer = Transfer::Download { info, toggle: false, len: 0, expected, last_us: now_us };
        Ok(ok)
    }

    fn download_segment(&mut self, now_us: u64, cmd: u8, d: &[u8]) -> Option<[u8; 8]> {
        let Transfer::Download { info, toggle, len, expected, .. } = self.transfer else {
            return Some(sdo::abort_payload(0, 0, Abort::Command));
        };
        let abort = |s: &mut Self, a: Abort| {
            s.transfer = Transfer::Idle;
            Some(sdo::abort_payload(info.index, info.sub, a))
        };
        let t = cmd & 0x10 != 0;
        if t != toggle {
            return abort(self, Abort::Toggle);
        }
        let n = ((cmd >> 1) & 0x07) as usize;
        let seg = d.get(1..8 - n).unwrap_or(&[]);
        let end = len + seg.len();
        let Some(dst) = self.sdo_buf().get_mut(len..end) else {
            return abort(self, Abort::TooLong);
        };
        dst.copy_from_slice(seg);
        if expected.is_some_and(|e| end > e) {
            return abort(self, Abort::TooLong);
        }
        let resp = [0x20 | (u8::from(t) << 4), 0, 0, 0, 0, 0, 0, 0];
        if cmd & 0x01 == 0 {
            self.transfer = Transfer::Download { info, toggle: !toggle, len: end, expected, last_us: now_us };
            return Some(resp);
        }
        self.transfer = Transfer::Idle;
        if expected.is_some_and(|e| end != e) {
            return abort(self, Abort::TypeLength);
        }
        match self.write_from_buf(&info, end) {
            Ok(()) => Some(resp),
            Err(a) => abort(self, a),
        }
    }

    /// Write the first `len` bytes of the channel's transfer buffer to the object: the end
    /// of a segmented or block download. The buffer is copied out so the write can borrow
    /// the node; out of line, so that copy is on the stack only during this call, not in
    /// the frame of every SDO request (the QEMU image measures the node's peak stack).
    #[inline(never)]
    fn write_from_buf(&mut self, info: &SubInfo, len: usize) -> Result<(), Abort> {
        let tmp = *self.sdo_buf();
        let data = tmp.get(..len).ok_or(Abort::TooLong)?;
        self.write_value(info, data, true)
    }

    fn initiate_upload(&mut self, now_us: u64, index: u16, sub: u8) -> Result<[u8; 8], Abort> {
        let info = od::sub_info(index, sub)?;
        if !info.access.readable() {
            return Err(Abort::WriteOnly);
        }
        let i = index.to_le_bytes();
        match self.read_value(&info)? {
            Value::Small(v, n) => Ok([0x43 | (((4 - n.min(4)) as u8) << 2), i[0], i[1], sub, v[0], v[1], v[2], v[3]]),
            Value::Big(src) => {
                let total = self.big_len(src);
                if total <= 4 {
                    let mut v = [0u8; 4];
                    for (k, x) in v.iter_mut().enumerate().take(total) {
                        *x = self.big_byte(src, k);
                    }
                    // An empty value still needs one byte on the wire for expedited; use a
                    // segmented upload of 0 bytes instead.
                    if total > 0 {
                        return Ok([0x43 | (((4 - total) as u8) << 2), i[0], i[1], sub, v[0], v[1], v[2], v[3]]);
                    }
                }
                self.transfer = Transfer::Upload { index, sub, src, toggle: false, offset: 0, total, last_us: now_us };
                let s = (total as u32).to_le_bytes();
                Ok([0x41, i[0], i[1], sub, s[0], s[1], s[2], s[3]])
            }
        }
    }

    fn upload_segment(&mut self, now_us: u64, cmd: u8) -> Option<[u8; 8]> {
        let Transfer::Upload { index, sub, src, toggle, offset, total, .. } = self.transfer else {
            return Some(sdo::abort_payload(0, 0, Abort::Command));
        };
        let t = cmd & 0x10 != 0;
        if t != toggle {
            self.transfer = Transfer::Idle;
            return Some(sdo::abort_payload(index, sub, Abort::Toggle));
        }
        let n = (total - offset.min(total)).min(7);
        let mut resp = [0u8; 8];
        for k in 0..n {
            if let Some(x) = resp.get_mut(1 + k) {
                *x = self.big_byte(src, offset + k);
            }
        }
        let last = offset + n >= total;
        resp[0] = (u8::from(t) << 4) | (((7 - n) as u8) << 1) | u8::from(last);
        self.transfer = if last {
            Transfer::Idle
        } else {
            Transfer::Upload { index, sub, src, toggle: !toggle, offset: offset + n, total, last_us: now_us }
        };
        Some(resp)
    }

    // ---- values ---------------------------------------------------------------------------

    fn big_len(&self, src: Big) -> usize {
        let t = &self.staged.table;
        match src {
            Big::DeviceName => self.cfg.device_name.len(),
            Big::SoftwareVersion => self.cfg.software_version.len(),
            Big::ErrorMessage => self.commit_error.as_ref().map_or(0, |e| e.message.len()),
            Big::Grid => 4 * AXIS_POINTS_MAX * (t.n_axes as usize).min(AXES_MAX),
            Big::Torque | Big::Sigma => 4 * t.cells().min(CELLS_MAX),
            Big::Series => TERM_BYTES * (self.staged.series.n_terms as usize).min(TERMS_MAX),
        }
    }

    fn big_byte(&self, src: Big, i: usize) -> u8 {
        let t = &self.staged.table;
        let f = |v: Option<&f32>| v.map_or(0, |x| x.to_le_bytes().get(i % 4).copied().unwrap_or(0));
        match src {
            Big::DeviceName => self.cfg.device_name.as_bytes().get(i).copied().unwrap_or(0),
            Big::SoftwareVersion => self.cfg.software_version.as_bytes().get(i).copied().unwrap_or(0),
            Big::ErrorMessage => {
                self.commit_error.as_ref().and_then(|e| e.message.as_bytes().get(i).copied()).unwrap_or(0)
            }
            Big::Grid => {
                let k = i / 4;
                f(t.grid.get(k / AXIS_POINTS_MAX).and_then(|r| r.get(k % AXIS_POINTS_MAX)))
            }
            Big::Torque => f(t.torque.get(i / 4)),
            Big::Sigma => f(t.sigma.get(i / 4)),
            Big::Series => self.staged.series.term_bytes(i / TERM_BYTES).get(i % TERM_BYTES).copied().unwrap_or(0),
        }
    }

    fn read_value(&self, info: &SubInfo) -> Result<Value, Abort> {
        let t = &self.staged.table;
        Ok(match info.key {
            Key::DeviceType => put_u32(0),
            Key::ErrorRegister => put_u8(self.error_register()),
            Key::ErrorHistoryCount => put_u8(self.error_count),
            Key::ErrorHistory(s) => put_u32(if s <= self.error_count {
                self.error_history.get((s as usize).wrapping_sub(1)).copied().unwrap_or(0)
            } else {
                0
            }),
            Key::SyncCobId => put_u32(self.sync_cob),
            Key::EmcyCobId => put_u32(u32::from(EMCY_BASE + u16::from(self.cfg.node_id))),
            Key::ErrorBehaviour => put_u8(self.error_behaviour),
            Key::DeviceName => Value::Big(Big::DeviceName),
            Key::SoftwareVersion => Value::Big(Big::SoftwareVersion),
            Key::Count(n) => put_u8(n),
            // bit 0: saves on command
            Key::StoreAll | Key::RestoreAll => put_u32(1),
            Key::ConsumerHeartbeat => put_u32((u32::from(self.host_id) << 16) | self.heartbeat_timeout_ms()),
            Key::ProducerHeartbeat => put_u16(self.heartbeat_ms),
            Key::SdoServer(c, s) => self.sdo_server_value(c, s),
            Key::Identity(s) => put_u32(match s {
                1 => self.cfg.identity.vendor_id,
                2 => self.cfg.identity.product_code,
                3 => self.cfg.identity.revision,
                _ => self.cfg.identity.serial,
            }),
            Key::RpdoCobId(n) => put_u32(self.rpdo_cob.get(n as usize).copied().unwrap_or(COB_INVALID)),
            Key::RpdoType(_) => put_u8(0xFE),
            Key::RpdoMap(n, s) => put_u32(self.maps.read(false, n, s)),
            Key::MapCount(tx, n) => put_u8(self.maps.read(tx, n, 0) as u8),
            Key::TpdoCobId(n) => put_u32(self.tpdo.get(n as usize).map_or(COB_INVALID, |t| t.cob_id)),
            Key::TpdoType(n) => put_u8(self.tpdo.get(n as usize).map_or(0xFE, |t| t.transmission)),
            Key::TpdoInhibit(n) => put_u16(self.tpdo.get(n as usize).map_or(0, |t| t.inhibit)),
            Key::TpdoEvent(n) => put_u16(self.tpdo.get(n as usize).map_or(0, |t| t.event_ms)),
            Key::TpdoMap(n, s) => put_u32(self.maps.read(true, n, s)),
            Key::Param(p) => put_u32(self.staged.get(p).to_bits()),
            Key::TableShape(s) => put_u8(match s {
                1 => t.n_axes,
                2..=5 => t.axis_source.get(s as usize - 2).copied().unwrap_or(0),
                6..=9 => t.points.get(s as usize - 6).copied().unwrap_or(0),
                10 => u8::from(t.has_sigma),
                _ => u8::from(t.residual),
            }),
            Key::TableGrid => Value::Big(Big::Grid),
            Key::TableTorque => Value::Big(Big::Torque),
            Key::TableSigma => Value::Big(Big::Sigma),
            Key::SeriesCount => put_u8(self.staged.series.n_terms),
            Key::SeriesTerms => Value::Big(Big::Series),
            Key::Commit | Key::ClearFaults | Key::CommitCrc => return Err(Abort::WriteOnly),
            Key::ActiveCrc => put_u32(crate::store::set_crc(self.active.current().raw())),
            Key::StagedCrc => put_u32(crate::store::set_crc(&self.staged)),
            Key::ErrorCode => put_u8(self.commit_error.as_ref().map_or(0, |e| e.code)),
            Key::ErrorParam => put_u16(self.commit_error.as_ref().map_or(0xFFFF, |e| e.param)),
            Key::ErrorMessage => Value::Big(Big::ErrorMessage),
            Key::Pending => put_u8(u8::from(self.staged != *self.active.current().raw())),
            Key::JointState(s) => {
                let st = &self.state;
                match s {
                    od::JS_Q => put_i16(to_i16(st.q, pdo::Q_LSB)),
                    od::JS_QD => put_i16(to_i16(st.qd, pdo::QD_LSB)),
                    od::JS_TAU => put_i16(to_i16(st.tau_cmd, pdo::TAU_LSB)),
                    od::JS_FAULTS => put_u16(self.safety.faults().bits()),
                    od::JS_QDD => put_i16(to_i16(st.qdd, pdo::QDD_LSB)),
                    od::JS_TAU_MEAS => put_i16(to_i16(st.tau_measured, pdo::TAU_LSB)),
                    od::JS_TEMP => put_i16(to_i16(st.temperature, pdo::TEMP_LSB)),
                    _ => put_u16((self.safety.gain() * 1000.0 + 0.5) as u16),
                }
            }
            Key::JointStateF32(s) => {
                let st = &self.state;
                let f = match s {
                    od::JF_Q => st.q,
                    od::JF_QD => st.qd,
                    od::JF_QDD => st.qdd,
                    od::JF_TAU => st.tau_cmd,
                    od::JF_TAU_MEAS => st.tau_measured,
                    od::JF_U_MOTOR => st.tau_cmd * self.active.current().inv_ratio_m1(),
                    od::JF_TEMP => st.temperature,
                    od::JF_MODE => return Ok(put_u8(u8::from(self.mode() == Mode::Assist))),
                    od::JF_GAIN => self.safety.gain(),
                    _ => self.assist_cmd,
                };
                put_u32(f.to_bits())
            }
            Key::AssistCmd => put_i16(to_i16(self.assist_cmd, pdo::TAU_LSB)),
            Key::OtherAngle(s) => {
                put_i16(to_i16(self.others.get((s as usize).wrapping_sub(1)).copied().unwrap_or(0.0), pdo::Q_LSB))
            }
        })
    }

    fn heartbeat_timeout_ms(&self) -> u32 {
        let s = self.active.current().get(ParamId::HeartbeatTimeout);
        ((s * 1000.0 + 0.5) as u32).min(0xFFFF)
    }

    fn in_preop(&self) -> bool {
        self.nmt == NmtState::PreOperational
    }

    /// Every write, from SDO or RPDO. Checks come first; a refused write changes nothing.
    /// Dispatched by what the object is: the store, communication settings, the staged
    /// parameter set, commands, and process data.
    fn write_value(&mut self, info: &SubInfo, data: &[u8], from_sdo: bool) -> Result<(), Abort> {
        if !info.access.writable() {
            return Err(Abort::ReadOnly);
        }
        check_len(info, data.len())?;
        let u = le_u32(data);
        // a staged set belongs to the master (channel) that wrote to it: see stage_owner.rs
        // (the parameters, the gravity table and series: 0x2000..=0x2105)
        let staging = (od::PARAM_BASE..=od::SERIES_TERMS).contains(&info.index);
        let r = match info.key {
            Key::StoreAll | Key::RestoreAll => self.write_store(info.key, u),
            Key::ConsumerHeartbeat
            | Key::ProducerHeartbeat
            | Key::RpdoCobId(_)
            | Key::TpdoCobId(_)
            | Key::TpdoType(_)
            | Key::TpdoInhibit(_)
            | Key::TpdoEvent(_)
            | Key::SyncCobId
            | Key::ErrorBehaviour => self.write_comm(info.key, u),
            Key::MapCount(..) | Key::RpdoMap(..) | Key::TpdoMap(..) => self.write_map(info.key, u),
            Key::SdoServer(c, s) => self.write_sdo_server(c, s, u),
            Key::ErrorHistoryCount => {
                // CiA 301: only 0 may be written, and it clears the history
                if u != 0 {
                    return Err(Abort::InvalidValue);
                }
                self.error_count = 0;
                self.error_history = [0; od::ERROR_HISTORY_LEN];
                Ok(())
            }
            Key::Param(p) => self.stage_param(p, u),
            Key::TableShape(s) => self.write_shape(s, u as u8),
            Key::TableGrid | Key::TableTorque | Key::TableSigma => self.stage_table(info.key, data),
            Key::SeriesCount | Key::SeriesTerms => self.stage_series(info.key, u, data),
            Key::CommitCrc => {
                let staged = crate::store::set_crc(&self.staged);
                if u != staged {
                    self.set_commit_error(
                        7,
                        0xFFFF,
                        format_args!(
                            "the staged set is {staged:08x}, not the {u:08x} named: written to since (another master?)"
                        ),
                    );
                    return Err(Abort::DeviceState);
                }
                self.commit()
            }
            Key::Commit => match u {
                // A plain commit would make whatever is staged live, another master's leftovers
                // included: a commit must name its set (0x2205, the set's CRC-32).
                1 => {
                    self.set_commit_error(
                        9,
                        0xFFFF,
                        format_args!("plain commit refused: a commit names its set, write its CRC-32 to 0x2205"),
                    );
                    Err(Abort::Unsupported)
                }
                0 => {
                    self.staged = self.active.current().raw().clone();
                    self.staged_by = None;
                    Ok(())
                }
                _ => Err(Abort::InvalidValue),
            },
            Key::ClearFaults => {
                if u != 1 {
                    return Err(Abort::InvalidValue);
                }
                self.safety.clear_faults(self.now_us).map(|_| ()).map_err(|_| Abort::DeviceState)
            }
            Key::AssistCmd => {
                if from_sdo && self.nmt != NmtState::Operational {
                    // The command only means something while the torque is on.
                    self.assist_cmd = 0.0;
                    return Err(Abort::DeviceState);
                }
                self.assist_cmd = from_i16(u as u16 as i16, pdo::TAU_LSB);
                Ok(())
            }
            Key::OtherAngle(s) => {
                if let Some(o) = self.others.get_mut((s as usize).wrapping_sub(1)) {
                    *o = from_i16(u as u16 as i16, pdo::Q_LSB);
                }
                Ok(())
            }
            _ => Err(Abort::ReadOnly),
        };
        if staging && r.is_ok() {
            self.stage_touched();
        }
        r
    }

    /// 0x1010 save / 0x1011 restore, each behind its signature.
    fn write_store(&mut self, key: Key, u: u32) -> Result<(), Abort> {
        if key == Key::StoreAll {
            if u != od::SAVE_SIGNATURE {
                return Err(Abort::CannotStore);
            }
            // the mappings first: a storage that keeps them in the set's record (the flash
            // store) writes both with the set
            let mut r = self.save_maps();
            if r.is_ok() {
                r = self.storage.save(self.active.current());
            }
            if r == Err(StorageError::Failed) {
                self.safety.raise(Faults::STORE_WRITE);
            }
            return r.map_err(|_| Abort::CannotStore);
        }
        if u != od::LOAD_SIGNATURE {
            return Err(Abort::CannotStore);
        }
        // CiA 301: the defaults take effect at the next reset. The running set stays, and so
        // does what is staged (staging the defaults let the next commit, anyone's, apply them).
        self.storage.restore_defaults().map_err(|_| Abort::CannotStore)?;
        Ok(())
    }

    /// The stored PDO mappings, if the storage has some this firmware accepts. Out of line:
    /// the 455-byte image lives on the stack only during this call.
    #[inline(never)]
    fn load_stored_maps(&mut self) {
        if let Some(b) = self.storage.load_pdo() {
            self.maps.load(&b);
        }
    }

    /// The PDO mappings to the storage with the parameters (0x1010); a storage without room
    /// for them keeps the parameters only.
    #[inline(never)]
    fn save_maps(&mut self) -> Result<(), StorageError> {
        let mut b = [0u8; PDO_MAPS_BYTES];
        self.maps.to_bytes(&mut b);
        self.storage.save_pdo(&b).or_else(|e| if e == StorageError::Unsupported { Ok(()) } else { Err(e) })
    }

    /// A write to a PDO mapping (see [`super::pdo_map`]): only while the PDO is invalid.
    fn write_map(&mut self, key: Key, u: u32) -> Result<(), Abort> {
        let (tx, n, sub) = match key {
            Key::MapCount(tx, n) => (tx, n, 0),
            Key::RpdoMap(n, s) => (false, n, s),
            Key::TpdoMap(n, s) => (true, n, s),
            _ => return Err(Abort::ReadOnly),
        };
        let cob = if tx { self.tpdo.get(n as usize).map(|t| t.cob_id) } else { self.rpdo_cob.get(n as usize).copied() };
        let valid = cob.is_some_and(|c| c & COB_INVALID == 0);
        let max = if self.cfg.fd { crate::canopen::frame::FD_MAX_LEN } else { 8 };
        self.maps.write(tx, n, sub, u, valid, max)
    }

    /// Heartbeat consumer/producer and the PDO communication parameters.
    fn write_comm(&mut self, key: Key, u: u32) -> Result<(), Abort> {
        match key {
            Key::ConsumerHeartbeat => {
                let node = ((u >> 16) & 0xFF) as u8;
                let ms = u & 0xFFFF;
                if u >> 24 != 0 || node > 127 || node == self.cfg.node_id {
                    return Err(Abort::InvalidValue);
                }
                // One source of truth for the timeout: the parameter controller_heartbeat_timeout.
                if ms != 0 && ms != self.heartbeat_timeout_ms() {
                    return Err(Abort::InvalidValue);
                }
                self.host_id = node;
            }
            Key::ProducerHeartbeat => {
                self.heartbeat_ms = u as u16;
                self.next_heartbeat_us = self.now_us;
            }
            Key::RpdoCobId(n) => {
                let v = check_cob(u)?;
                if let Some(c) = self.rpdo_cob.get_mut(n as usize) {
                    *c = v;
                }
            }
            Key::TpdoCobId(n) => {
                let v = check_cob(u)?;
                // a classic frame holds 8 bytes: a longer TPDO exists only on an FD bus
                if v & COB_INVALID == 0 && self.maps.bytes(true, n) > 8 && !self.cfg.fd {
                    return Err(Abort::MapLength);
                }
                if let Some(t) = self.tpdo.get_mut(n as usize) {
                    t.cob_id = v;
                }
            }
            Key::TpdoType(n) => {
                // event-driven (254/255) or synchronous, every 1st..240th SYNC; acyclic (0) and
                // RTR-only (252/253) types are not served
                if !(u == 0xFE || u == 0xFF || (1..=240).contains(&u)) {
                    return Err(Abort::InvalidValue);
                }
                if let Some(t) = self.tpdo.get_mut(n as usize) {
                    t.transmission = u as u8;
                    t.syncs = 0;
                }
            }
            Key::SyncCobId => {
                // a consumer: 11-bit id, no producer bit (30), no extended frame (29)
                if u & !0x7FF != 0 {
                    return Err(Abort::InvalidValue);
                }
                self.sync_cob = u;
            }
            Key::ErrorBehaviour => {
                if u > 2 {
                    return Err(Abort::InvalidValue);
                }
                self.error_behaviour = u as u8;
            }
            Key::TpdoInhibit(n) => {
                if let Some(t) = self.tpdo.get_mut(n as usize) {
                    t.inhibit = u as u16;
                }
            }
            Key::TpdoEvent(n) => {
                let now = self.now_us;
                if let Some(t) = self.tpdo.get_mut(n as usize) {
                    t.event_ms = u as u16;
                    t.next_us = now;
                }
            }
            _ => return Err(Abort::ReadOnly),
        }
        Ok(())
    }

    /// One scalar parameter into the staged set: safety-relevant ones only in pre-operational,
    /// finite and inside the table's range.
    fn stage_param(&mut self, p: ParamId, u: u32) -> Result<(), Abort> {
        let v = f32::from_bits(u);
        let d = p.desc();
        if d.safety && !self.in_preop() {
            return Err(Abort::DeviceState);
        }
        if !math::is_finite(v) {
            return Err(Abort::InvalidValue);
        }
        if v < d.min {
            return Err(Abort::TooLow);
        }
        if v > d.max {
            return Err(Abort::TooHigh);
        }
        self.staged.set(p, v);
        Ok(())
    }

    /// The gravity table's grid, torques or σ into the staged set, all values finite.
    fn stage_table(&mut self, key: Key, data: &[u8]) -> Result<(), Abort> {
        if key == Key::TableGrid {
            let mut grid = [[0.0f32; AXIS_POINTS_MAX]; AXES_MAX];
            for (k, c) in data.chunks_exact(4).enumerate() {
                let v = f32::from_bits(le_u32(c));
                if !math::is_finite(v) {
                    return Err(Abort::InvalidValue);
                }
                if let Some(x) = grid.get_mut(k / AXIS_POINTS_MAX).and_then(|r| r.get_mut(k % AXIS_POINTS_MAX)) {
                    *x = v;
                }
            }
            self.staged.table.grid = grid;
            return Ok(());
        }
        let mut vals = [0.0f32; CELLS_MAX];
        for (x, c) in vals.iter_mut().zip(data.chunks_exact(4)) {
            let v = f32::from_bits(le_u32(c));
            if !math::is_finite(v) {
                return Err(Abort::InvalidValue);
            }
            *x = v;
        }
        if key == Key::TableTorque {
            self.staged.table.torque = vals;
        } else {
            self.staged.table.sigma = vals;
        }
        Ok(())
    }

    /// The gravity series' term count or terms into the staged set.
    fn stage_series(&mut self, key: Key, u: u32, data: &[u8]) -> Result<(), Abort> {
        if key == Key::SeriesCount {
            if u as usize > TERMS_MAX {
                return Err(Abort::TooHigh);
            }
            self.staged.series.n_terms = u as u8;
            return Ok(());
        }
        // Whole terms only (check_len); NaN/∞ refused here like the table's values, the
        // ranges of amplitude, phase and multipliers at commit (series::validate).
        let mut series = RawSeries::EMPTY;
        series.n_terms = self.staged.series.n_terms;
        for (k, c) in data.chunks_exact(TERM_BYTES).enumerate() {
            series.set_term_bytes(k, c);
            let bad = |x: Option<&f32>| !x.is_some_and(|&v| math::is_finite(v));
            if bad(series.amplitude.get(k)) || bad(series.phase.get(k)) {
                return Err(Abort::InvalidValue);
            }
        }
        self.staged.series = series;
        Ok(())
    }

    fn write_shape(&mut self, s: u8, v: u8) -> Result<(), Abort> {
        let t = &mut self.staged.table;
        let (limit, slot) = match s {
            1 => (AXES_MAX as u8, &mut t.n_axes),
            2..=5 => (AXIS_SOURCE_MAX, t.axis_source.get_mut(s as usize - 2).ok_or(Abort::NoSubIndex)?),
            6..=9 => (AXIS_POINTS_MAX as u8, t.points.get_mut(s as usize - 6).ok_or(Abort::NoSubIndex)?),
            _ => {
                if v > 1 {
                    return Err(Abort::TooHigh);
                }
                if s == 10 {
                    t.has_sigma = v == 1;
                } else {
                    t.residual = v == 1;
                }
                return Ok(());
            }
        };
        if v > limit {
            return Err(Abort::TooHigh);
        }
        *slot = v;
        Ok(())
    }

    /// Check the staged set as a whole and swap it in; on failure the committed set stays.
    fn commit(&mut self) -> Result<(), Abort> {
        let old = self.active.current().raw();
        if !self.in_preop() {
            let changed =
                PARAMS.iter().find(|d| d.safety && self.staged.get(d.id).to_bits() != old.get(d.id).to_bits());
            if let Some(d) = changed {
                self.set_commit_error(
                    5,
                    d.id.index() as u16,
                    format_args!("{} is safety-relevant: commit it in pre-operational", d.name),
                );
                return Err(Abort::DeviceState);
            }
        }
        match self.active.replace(&self.staged) {
            Ok(()) => {
                self.staged_by = None;
                self.safety.configure(SafetyConfig::from_params(self.active.current()));
                // The Dahl friction state belongs to the set that made it (its σ and level).
                self.controller.configure(self.active.current());
                self.commit_error = None;
                Ok(())
            }
            Err(e) => {
                let (code, abort) = match e {
                    ParamError::NotFinite { .. } => (1, Abort::InvalidValue),
                    ParamError::OutOfRange { value, max, .. } => {
                        (2, if value > max { Abort::TooHigh } else { Abort::TooLow })
                    }
                    ParamError::Inconsistent { .. } => (3, Abort::InvalidValue),
                    ParamError::Table(_) => (4, Abort::InvalidValue),
                    ParamError::Series(_) => (6, Abort::InvalidValue),
                };
                let param = e.param().map_or(0xFFFF, |p| p.index() as u16);
                self.set_commit_error(code, param, format_args!("{}", Brief(&e)));
                Err(abort)
            }
        }
    }

    fn set_commit_error(&mut self, code: u8, param: u16, msg: core::fmt::Arguments<'_>) {
        let mut message = heapless::String::<120>::new();
        // A message longer than the buffer is cut; the code and param index stay exact.
        let _ = core::fmt::write(&mut Truncate(&mut message), msg);
        self.commit_error = Some(CommitError { code, param, message });
        self.pending_commit_emcy = true;
    }

    // ---- local access (host tools, tests, EDS defaults) ------------------------------------

    /// Read an object as the SDO server would (no NMT-state check), into `out`; returns the
    /// length. Values longer than `out` are cut.
    pub fn read(&self, index: u16, sub: u8, out: &mut [u8]) -> Result<usize, Abort> {
        let info = od::sub_info(index, sub)?;
        if !info.access.readable() {
            return Err(Abort::WriteOnly);
        }
        match self.read_value(&info)? {
            Value::Small(v, n) => {
                let n = n.min(out.len());
                for (d, s) in out.iter_mut().zip(v.iter().take(n)) {
                    *d = *s;
                }
                Ok(n)
            }
            Value::Big(src) => {
                let n = self.big_len(src).min(out.len());
                for (k, d) in out.iter_mut().enumerate().take(n) {
                    *d = self.big_byte(src, k);
                }
                Ok(n)
            }
        }
    }

    /// Write an object as the SDO server would, with every check.
    pub fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), Abort> {
        let info = od::sub_info(index, sub)?;
        self.write_value(&info, data, true)
    }
}

/// `fmt::Write` into a heapless string that drops what does not fit instead of failing.
struct Truncate<'a, const N: usize>(&'a mut heapless::String<N>);

impl<const N: usize> core::fmt::Write for Truncate<'_, N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for c in s.chars() {
            if self.0.push(c).is_err() {
                break;
            }
        }
        Ok(())
    }
}

/// Length rules of a write: fixed-size types exactly their size; domains up to their array,
/// a whole number of f32.
fn check_len(info: &SubInfo, n: usize) -> Result<(), Abort> {
    match info.dtype.size() {
        Some(s) if n > s => Err(Abort::TooLong),
        Some(s) if n < s => Err(Abort::TooShort),
        Some(_) => Ok(()),
        None => {
            let max = match info.key {
                Key::TableGrid => 4 * AXES_MAX * AXIS_POINTS_MAX,
                Key::TableTorque | Key::TableSigma => 4 * CELLS_MAX,
                Key::SeriesTerms => TERM_BYTES * TERMS_MAX,
                _ => 0,
            };
            let unit = if info.key == Key::SeriesTerms { TERM_BYTES } else { 4 };
            // `%` rather than `is_multiple_of` (Rust 1.87): the workspace declares 1.85.
            #[allow(clippy::manual_is_multiple_of)]
            let ragged = n % unit != 0;
            if n > max {
                Err(Abort::TooLong)
            } else if ragged {
                Err(Abort::TypeLength)
            } else {
                Ok(())
            }
        }
    }
}

/// A PDO COB-ID write: 11-bit id, bit 31 = disabled; extended frames (bit 29) and ids in the
/// NMT/SYNC slot are refused.
fn check_cob(u: u32) -> Result<u32, Abort> {
    if u & 0x3FFF_F800 != 0 || u & 0x7FF == 0 {
        return Err(Abort::InvalidValue);
    }
    Ok(u & (COB_INVALID | 0x7FF))
}

/// The EMCY code for a set of newly latched faults (the most important bit decides).
fn emcy_code(new: Faults) -> u16 {
    if new.contains(Faults::HEARTBEAT_LOST) {
        EMCY_HEARTBEAT
    } else if new.intersects(Faults::PARAMS_CORRUPT.union(Faults::PARAMS_REJECTED).union(Faults::PARAMS_VERSION)) {
        EMCY_PARAMS
    } else if new.contains(Faults::CAN_BUS_OFF) {
        EMCY_BUS_OFF
    } else if new.intersects(Faults::COMMAND_INVALID.union(Faults::LOOP_OVERRUN)) {
        EMCY_SOFTWARE
    } else {
        EMCY_DEVICE
    }
}

impl Access {
    /// Convenience for the EDS: does the access allow PDO mapping direction `tx`?
    pub const fn pdo_dir(self, tx: bool) -> bool {
        if tx {
            self.readable()
        } else {
            self.writable()
        }
    }
}

impl DataType {
    pub const fn code(self) -> u16 {
        self as u16
    }
}

/// A [`ParamError`] shown without its numbers (see [`ParamError::write_brief`]).
struct Brief<'a>(&'a ParamError);

impl core::fmt::Display for Brief<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.0.write_brief(f)
    }
}
