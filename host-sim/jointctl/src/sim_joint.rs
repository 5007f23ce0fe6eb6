//! A simulated joint on a CAN bus: the core's CANopen [`Node`] (with its controller and
//! watchdog) around host-sim's [`Plant`], ticking at 1 kHz. The same object serves the
//! in-process [`super::sim_bus::SimBus`] (virtual time) and real buses in `jointctl sim`
//! (wall-clock time), so any CANopen master can talk to the simulated joints.
//!
//! Without a plant file the joint is held at rest (q = q̇ = 0): the node, its parameters and
//! its watchdog work, the telemetry is flat. With one, the plant is integrated at 10 kHz with
//! the node's torque, and a gentle "operator" (a 20 N·m/rad, 2 N·m·s/rad impedance toward a
//! 0.25 Hz, 0.4 rad sine) moves it so the telemetry shows motion.

use host_sim::plant::{Operator, Plant, PlantFile, State};
use joint_can::sim_bus::SimDevice;
use joint_core::canopen::lss::LssConfig;
use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, ParamStorage, StorageError};
use joint_core::canopen::pdo_map::PDO_MAPS_BYTES;
use joint_core::canopen::CanFrame;
use joint_core::control_loop::ControlLoop;
use joint_core::params::{ParamId, ParamSet, RawParams};
use joint_formats::model_file::ModelFile;
use std::io::Write as _;
use std::path::PathBuf;

/// Parameter storage of a simulated joint: in memory, or a model TOML file (the host-side
/// stand-in for the board's flash).
// Memory holds a whole RawParams; boxing it would only move the same bytes to the heap.
#[allow(clippy::large_enum_variant)]
pub enum SimStorage {
    Memory(MemoryStorage),
    /// a model TOML; `damaged` is set when the last load found the file but could not read a
    /// parameter set from it (truncated, garbage, a value the table refuses)
    File {
        path: PathBuf,
        damaged: bool,
    },
}

impl SimStorage {
    /// Storage in the model TOML at `path` (absent: nothing stored yet).
    pub fn file(path: PathBuf) -> SimStorage {
        SimStorage::File { path, damaged: false }
    }
}

impl ParamStorage for SimStorage {
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        match self {
            SimStorage::Memory(m) => m.save(set),
            SimStorage::File { path: p, .. } => {
                let body = ModelFile::from_raw(set.raw(), None, &[]).to_toml_string();
                // a CRC over the rest, first: a file cut short keeps this line and fails it
                let text = format!("{STORE_HEADER}{:08x}\n{body}", joint_core::store::crc32(body.as_bytes()));
                // replaced atomically, like the board's A/B records: a crash mid-save keeps the old set
                joint_formats::output::write_file(p, |w| w.write_all(text.as_bytes())).map_err(|_| StorageError::Failed)
            }
        }
    }
    fn load(&mut self) -> Option<RawParams> {
        match self {
            SimStorage::Memory(m) => m.load(),
            SimStorage::File { path, damaged } => {
                // a missing file is nothing stored; a file that does not read is a damaged store,
                // which boots on the defaults with PARAMS_CORRUPT raised (and its EMCY), never silently
                *damaged = false;
                if !path.exists() {
                    return None;
                }
                let name = path.display().to_string();
                let raw = std::fs::read_to_string(&*path).ok().and_then(|text| {
                    // a file the joint saved carries its CRC; one written by hand need not
                    if let Some(rest) = text.strip_prefix(STORE_HEADER) {
                        let (crc, body) = rest.split_once('\n')?;
                        if u32::from_str_radix(crc.trim(), 16).ok()? != joint_core::store::crc32(body.as_bytes()) {
                            return None;
                        }
                    }
                    ModelFile::parse(&text, &name).ok()?.raw_params().ok()
                });
                *damaged = raw.is_none();
                raw
            }
        }
    }
    fn save_pdo(&mut self, maps: &[u8; PDO_MAPS_BYTES]) -> Result<(), StorageError> {
        match self {
            SimStorage::Memory(m) => m.save_pdo(maps),
            SimStorage::File { path, .. } => {
                // next to the model file: the PDO mappings as hex, after their CRC-32
                let hex: String = maps.iter().map(|b| format!("{b:02x}")).collect();
                let text = format!("{:08x}\n{hex}\n", joint_core::store::crc32(maps));
                joint_formats::output::write_file(&pdo_path(path), |w| w.write_all(text.as_bytes()))
                    .map_err(|_| StorageError::Failed)
            }
        }
    }
    fn load_pdo(&mut self) -> Option<[u8; PDO_MAPS_BYTES]> {
        match self {
            SimStorage::Memory(m) => m.load_pdo(),
            SimStorage::File { path, .. } => {
                let text = std::fs::read_to_string(pdo_path(path)).ok()?;
                let (crc, hex) = text.split_once('\n')?;
                let mut b = [0u8; PDO_MAPS_BYTES];
                let hex = hex.trim();
                if hex.len() != 2 * PDO_MAPS_BYTES {
                    return None;
                }
                for (k, d) in b.iter_mut().enumerate() {
                    *d = u8::from_str_radix(hex.get(2 * k..2 * k + 2)?, 16).ok()?;
                }
                (u32::from_str_radix(crc.trim(), 16).ok()? == joint_core::store::crc32(&b)).then_some(b)
            }
        }
    }
    fn load_fault(&self) -> joint_core::safety::Faults {
        match self {
            SimStorage::File { damaged: true, .. } => joint_core::safety::Faults::PARAMS_CORRUPT,
            _ => joint_core::safety::Faults::NONE,
        }
    }
    fn load_lss(&mut self) -> Option<LssConfig> {
        match self {
            SimStorage::Memory(m) => m.load_lss(),
            SimStorage::File { path, .. } => {
                let text = std::fs::read_to_string(lss_file(path)).ok()?;
                let field = |k: &str| {
                    text.lines().find_map(|l| l.strip_prefix(k)?.trim().strip_prefix('=')?.trim().parse::<u8>().ok())
                };
                Some(LssConfig { node_id: field("node_id")?, bit_timing: field("bit_timing")? })
            }
        }
    }
    fn save_lss(&mut self, c: LssConfig) -> Result<(), StorageError> {
        match self {
            SimStorage::Memory(m) => m.save_lss(c),
            SimStorage::File { path, .. } => {
                let text =
                    format!("# LSS configuration (CiA 305)\nnode_id = {}\nbit_timing = {}\n", c.node_id, c.bit_timing);
                joint_formats::output::write_file(&lss_file(path), |w| w.write_all(text.as_bytes()))
                    .map_err(|_| StorageError::Failed)
            }
        }
    }
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        match self {
            SimStorage::Memory(m) => m.restore_defaults(),
            SimStorage::File { path: p, .. } => {
                for f in [p.clone(), pdo_path(p)] {
                    match std::fs::remove_file(f) {
                        Ok(()) => {}
                        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                        Err(_) => return Err(StorageError::Failed),
                    }
                }
                Ok(())
            }
        }
    }
}

/// Where a file-backed joint keeps its PDO mappings: `node-N.toml` → `node-N.pdo`.
fn pdo_path(p: &std::path::Path) -> PathBuf {
    p.with_extension("pdo")
}

/// Where a file-stored joint keeps its LSS configuration: beside its parameters (`.lss`).
fn lss_file(params: &std::path::Path) -> PathBuf {
    params.with_extension("lss")
}

/// First line of a store file the simulated joint wrote: its CRC-32 over the rest follows.
const STORE_HEADER: &str = "# joint parameter store, crc32 ";

/// Plant integration steps per millisecond (RK4 at 10 kHz).
const PLANT_SUBSTEPS: u32 = 10;

/// See the module documentation.
pub struct JointSim {
    pub node: Node<SimStorage>,
    plant: Option<(Plant, State)>,
    op: Operator,
    /// the boards' loop (the core's `ControlLoop`): q̇, q̈ estimated from the encoder's angle,
    /// the node's step, the period of the committed `controller_rate_hz`
    ctl: ControlLoop,
}

impl JointSim {
    pub fn new(node_id: u8, plant: Option<&PlantFile>, storage: SimStorage, now_us: u64) -> JointSim {
        Self::with_config(NodeConfig::new(node_id), plant, storage, now_us)
    }

    /// A joint whose node is built from `cfg` (a CAN FD node: `NodeConfig::new(id).with_fd(true)`;
    /// an unconfigured LSS node: id 0xFF, told apart by its serial number).
    pub fn with_config(cfg: NodeConfig, plant: Option<&PlantFile>, storage: SimStorage, now_us: u64) -> JointSim {
        let node = Node::new(cfg, storage, now_us);
        let plant = plant.map(|pf| {
            let limit = f64::from(node.params().get(ParamId::TorqueLimit));
            (Plant::new(pf, 1.0e-3 / f64::from(PLANT_SUBSTEPS), limit.max(1.0)), State::default())
        });
        let ctl = ControlLoop::new(node.params());
        JointSim { node, plant, op: Operator { k: 20.0, b: 2.0, q_ref: 0.0, qd_ref: 0.0 }, ctl }
    }

    /// One control period at `now_us`: the board's loop (encoder angle in, the node's step),
    /// the plant over the period, the node's timers.
    pub fn step(&mut self, now_us: u64, out: &mut Vec<CanFrame>) {
        let q = self.plant.as_ref().map_or(0.0, |(_, x)| x.q);
        // A late tick here is the host's scheduler (a busy machine running `jointctl sim`), not
        // the joint's: it is not latched as the board's LOOP_OVERRUN would be.
        self.ctl.excuse_gap();
        let o = self.ctl.tick(&mut self.node, now_us, Ok::<f32, ()>(q as f32)).out;
        let period_us = self.ctl.nominal_period_us();
        if let Some((plant, x)) = self.plant.as_mut() {
            let t = now_us as f64 * 1e-6;
            let w = 2.0 * std::f64::consts::PI * 0.25;
            self.op.q_ref = 0.4 * (w * t).sin();
            self.op.qd_ref = 0.4 * w * (w * t).cos();
            // the plant over one period of the committed rate, in steps of 0.1 ms
            let n = ((period_us * u64::from(PLANT_SUBSTEPS) + 500) / 1000).max(1);
            for k in 0..n {
                *x = plant.step(t + k as f64 * plant.dt, x, f64::from(o.tau_out), &self.op, &[]);
            }
            if !x.q.is_finite() || !x.qd.is_finite() {
                *x = State::default();
            }
            let tau_meas = -self.op.torque(x.q, x.qd);
            self.node.set_measurements(tau_meas as f32, 30.0);
        }
        self.node.process(now_us, None, &mut |f| out.push(f));
    }

    /// The control period of the committed `controller_rate_hz`, µs.
    pub fn control_period_us(&self) -> u64 {
        self.ctl.nominal_period_us()
    }

    pub fn receive(&mut self, now_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>) {
        self.node.process(now_us, Some(f), &mut |f| out.push(f));
    }
}

impl SimDevice for JointSim {
    fn on_frame(&mut self, t_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>) {
        self.receive(t_us, f, out);
    }
    fn tick(&mut self, t_us: u64, out: &mut Vec<CanFrame>) {
        self.step(t_us, out);
    }
    fn period_us(&self) -> u64 {
        self.control_period_us()
    }
}
