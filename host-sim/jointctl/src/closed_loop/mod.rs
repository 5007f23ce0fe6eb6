//! Closed-loop assistance trials (trunk paper §4, issue 7): the firmware core in the loop, its
//! parameters travelling over the simulated CAN bus, and an operator moving the trunk rod.
//!
//! One trial, end to end:
//! 1. an in-process [`SimBus`] at 1 Mbit/s carries one [`LoopJoint`]: the core's CANopen
//!    [`Node`] (controller, parameter table, heartbeat watchdog) around host-sim's [`Plant`];
//! 2. a [`Master`] pushes the model by SDO with the same code `jointctl push` uses
//!    ([`transfer::push`]: stage, read back, commit, in pre-operational because `fraction` is a
//!    safety parameter), then starts the node (NMT operational) and keeps its heartbeat going;
//! 3. the joint runs its control step at the committed rate (1 kHz): the angle is sensed like
//!    the board's encoder (the plant's `[delay]`, `q_noise`, `q_resolution`), the board's own
//!    loop (the core's `ControlLoop`: q̇ and q̈ from two `Differentiator`s at the board's
//!    cut-offs, the node's step) gives the torque, which is held on the plant for the
//!    period while the plant is integrated by RK4 at 10 kHz;
//! 4. an operator (the `hand` scenario's impedance `K_h·(q_ref − q) + B_h·(q̇_ref − q̇)`) pulls
//!    the rod toward a smooth random reference ([`RandomPath`]: minimum-jerk segments of
//!    0.8–2.5 s between random targets inside the joint range, 2° margin).
//!
//! What is scored (see docs/closed-loop.md): the desired support torque `K·β` (β = the true
//! joint angle q, K = `assist_k`) against the delivered torque, the torque the joint exerts on
//! the operator, `tau = −τ_ext = u − d` with `d = J·q̈ + D(q, q̇, …)` the plant's whole
//! disturbance: what a load cell between rod and hand reads, without its noise. The tracking
//! error is `tau − K·q = F·Ĉ_c − d`: the uncompensated share `(1 − F)·d` plus the model error.

pub mod svg;
pub mod workflow;

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, NMT_START};
use joint_core::canopen::{CanFrame, NmtState};
use joint_core::control_loop::ControlLoop;
use joint_core::params::{ParamId, RawParams};
use joint_core::vectors::velocity_cutoff_hz;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use host_sim::plant::{Operator, Plant, PlantFile, State};
use host_sim::scenario::RandomPath;
use joint_can::master::Master;
use joint_can::sim_bus::{SharedSimBus, SimBus, SimDevice};
use joint_can::transfer::{self, PushOptions};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

const DEG: f64 = std::f64::consts::PI / 180.0;
/// Node id of the simulated joint.
pub const NODE_ID: u8 = 5;
/// Plant RK4 steps per control period (10 kHz at the 1 kHz control rate), as `jointctl sim`.
const SUBSTEPS: usize = 10;
/// The paper's figures at F = 0.7 (trunk paper §4), N·m: mean ± sd over ten trials.
pub const PAPER_RIGHT: (f64, f64) = (2.04, 0.79);
pub const PAPER_LEFT: (f64, f64) = (2.51, 0.62);

/// Stability thresholds (see [`Stability`] and docs/closed-loop.md for why these values).
pub mod limits {
    /// q may leave the joint range by at most this much, rad (20°: the operator's hand alone
    /// keeps a stable loop within a few degrees of its reference, which stays inside the range)
    pub const RANGE_MARGIN: f64 = 0.35;
    /// largest plausible hand-moved speed, rad/s (the paper's fastest test: 90°/s ≈ 1.6 rad/s)
    pub const QD_MAX: f64 = 10.0;
    /// centred moving-average window separating hand motion from oscillation, s (its first
    /// notch is at 1/window = 5 Hz; a 0.8 s minimum-jerk segment has almost no power above 3 Hz)
    pub const OSC_WINDOW: f64 = 0.2;
    /// RMS of the torque the user feels above the hand-motion band, N·m, over the worst 1 s
    /// window of the trial's second half: above it the joint buzzes (a sustained oscillation)
    pub const OSC_TORQUE_RMS: f64 = 1.0;
}

/// Default operator: a hand holding the trunk rod. Human arm end-point impedance during
/// relaxed holding is about 300–800 N/m and 5–20 N·s/m (Mussa-Ivaldi et al. 1985, Tsuji et al.
/// 1995); at a 0.35 m lever (the trunk rod's handle) that is ≈ 40–100 N·m/rad and
/// 0.6–2.5 N·m·s/rad, so 60 N·m/rad and 2 N·m·s/rad. (The identification scenarios' operator of
/// `simulate --scenario hand`, 1.5 Hz and 0.7-damped on the joint's inertia, ≈ 217 N·m/rad and
/// 32 N·m·s/rad on the right joint, is a far stiffer, better damped grip: it masks the
/// instability of full compensation; pass it with --operator-stiffness/--operator-damping.)
pub const HAND_STIFFNESS: f64 = 60.0;
pub const HAND_DAMPING: f64 = 2.0;

/// Everything a set of trials needs besides the two files.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopConfig {
    /// overrides `[compensation] fraction` of the model
    pub fraction: Option<f64>,
    /// overrides `[compensation] assist_k` of the model, N·m/rad
    pub assist_k: Option<f64>,
    pub trials: usize,
    /// scored seconds per trial (after the settle time)
    pub seconds: f64,
    pub seed: u64,
    /// overrides (or adds) the plant's `[delay] seconds`
    pub delay: Option<f64>,
    /// keep the joint-log rows of every trial (for `--log` and the diagnose workflow)
    pub keep_log: bool,
    /// overrides the operator's stiffness K_h (N·m/rad) and damping B_h (N·m·s/rad)
    pub operator: Option<(f64, f64)>,
}

impl Default for LoopConfig {
    fn default() -> Self {
        LoopConfig {
            fraction: None,
            assist_k: None,
            trials: 10,
            seconds: 20.0,
            seed: 1,
            delay: None,
            keep_log: false,
            operator: None,
        }
    }
}

/// Seconds between NMT start and the scored part: the watchdog's soft start (0.2 s by
/// default) and the differentiators' settling.
pub const SETTLE_S: f64 = 0.5;

/// Why a trial counts as unstable, or that it did not.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stability {
    pub stable: bool,
    /// non-finite state or |q| beyond any joint (the plant was frozen)
    pub diverged: bool,
    /// largest excursion outside the joint range, rad (0 inside)
    pub range_excess_rad: f64,
    pub qd_max: f64,
    /// worst 1 s RMS of the delivered torque minus its 0.2 s moving average (second half), N·m
    pub osc_torque_rms: f64,
    /// share of scored samples where the torque or rate limit acted
    pub limited_share: f64,
    /// the reasons it is unstable (empty when stable)
    pub why: Vec<String>,
}

/// One trial's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Trial {
    pub seed: u64,
    /// scored control ticks (1 kHz)
    pub samples: usize,
    /// RMSE of delivered − desired support torque, N·m
    pub rmse: f64,
    pub stable: bool,
    pub stability: Stability,
    /// RMS of the desired support torque K·q, N·m
    pub rms_desired: f64,
    /// RMS of the delivered torque, N·m
    pub rms_delivered: f64,
    /// RMS of the plant's disturbance d = u − tau, N·m (what full compensation would cancel)
    pub rms_disturbance: f64,
    /// RMS of d − C_c, N·m: what the firmware's model misses of the disturbance in the loop
    /// (lagged q̇/q̈ estimates included); the tracking error full compensation (F = 1) would
    /// leave if it were stable
    pub model_error_rmse: f64,
    pub q_min: f64,
    pub q_max: f64,
    pub qd_rms: f64,
}

/// The push that configured a trial's joint.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PushInfo {
    pub sdo_transfers: usize,
    pub frames: u64,
    pub elapsed_us: u64,
}

/// The result of a set of trials.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LoopReport {
    pub plant: String,
    pub model: String,
    pub fraction: f64,
    pub assist_k: f64,
    pub seconds: f64,
    pub seed: u64,
    pub control_rate_hz: f64,
    pub sensor_delay_s: f64,
    pub vel_cutoff_hz: f64,
    pub accel_cutoff_hz: f64,
    pub operator_stiffness: f64,
    pub operator_damping: f64,
    pub unit: &'static str,
    pub tracking_rmse_mean: f64,
    /// sample standard deviation over trials (0 for one trial)
    pub tracking_rmse_sd: f64,
    /// every trial stable
    pub stable: bool,
    /// mean and sd over trials of [`Trial::model_error_rmse`], N·m
    pub model_error_rmse_mean: f64,
    pub model_error_rmse_sd: f64,
    pub push: PushInfo,
    pub trials: Vec<Trial>,
    #[serde(skip)]
    pub log: Option<JointLog>,
}

/// White Gaussian noise (0 = none).
fn gauss(sd: f64, rng: &mut ChaCha8Rng) -> f64 {
    let z: f64 = StandardNormal.sample(rng);
    if sd > 0.0 {
        sd * z
    } else {
        0.0
    }
}

fn quantise(x: f64, q: f64) -> f64 {
    if q > 0.0 {
        (x / q).round() * q
    } else {
        x
    }
}

/// One fine-step record: the state and the inputs in force from that instant (for the delayed
/// sensors and the log row of the sensed instant, as in `sim.rs`).
#[derive(Clone, Copy)]
struct Rec {
    t: f64,
    x: State,
    u: f64,
    op: Operator,
}

/// Samples of one trial, one per control tick.
#[derive(Clone, Debug, Default)]
struct Trace {
    t: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    tau: Vec<f64>,
    desired: Vec<f64>,
    disturbance: Vec<f64>,
    /// the firmware's estimate C_c of the disturbance
    c_c: Vec<f64>,
    limited: Vec<bool>,
    log: JointLog,
}

/// The simulated joint of a closed-loop trial: node + plant + operator + sensors. See the
/// module documentation.
pub struct LoopJoint {
    pub node: Node<MemoryStorage>,
    plant: Plant,
    x: State,
    hist: VecDeque<Rec>,
    delay_steps: usize,
    /// the board's loop (the core's): q̇, q̈ estimates, overrun check, the node's step
    ctl: ControlLoop,
    q_noise: f64,
    q_res: f64,
    sensors: host_sim::plant::Sensors,
    k_h: f64,
    b_h: f64,
    hold: f64,
    path: Option<(RandomPath, f64)>,
    /// the operator's path; sensor noise draws from `noise`, so logging (which draws the log
    /// columns' noise) never changes the motion
    rng: ChaCha8Rng,
    noise: ChaCha8Rng,
    record_from_us: Option<u64>,
    diverged: bool,
    keep_log: bool,
    trace: Trace,
}

impl LoopJoint {
    fn new(s: &Setup, hold: f64, seed: u64, keep_log: bool) -> LoopJoint {
        let pf = &s.plant;
        let u_max = f64::from(s.raw.get(ParamId::TorqueLimit)).max(1.0);
        let dt = 1.0e-3 / SUBSTEPS as f64;
        let node = Node::new(NodeConfig::new(NODE_ID), MemoryStorage::default(), 0);
        let ctl = ControlLoop::new(node.params());
        LoopJoint {
            node,
            plant: Plant::new(pf, dt, u_max),
            x: State::at_rest(hold),
            hist: VecDeque::new(),
            delay_steps: (s.delay / dt).round() as usize,
            ctl,
            q_noise: pf.sensors.q_noise,
            q_res: pf.sensors.q_resolution,
            sensors: pf.sensors.clone(),
            k_h: s.k_h,
            b_h: s.b_h,
            hold,
            path: None,
            rng: ChaCha8Rng::seed_from_u64(seed),
            noise: ChaCha8Rng::seed_from_u64(seed ^ 0x9E37_79B9_7F4A_7C15),
            record_from_us: None,
            diverged: false,
            keep_log,
            trace: Trace::default(),
        }
    }

    /// The operator starts moving the rod at `now_us` (random path from the held angle,
    /// inside `lo..hi`); samples are recorded from `SETTLE_S` later.
    fn start(&mut self, now_us: u64, lo: f64, hi: f64) {
        let margin = (2.0 * DEG).min((hi - lo) / 10.0);
        let t0 = now_us as f64 * 1e-6;
        let path = RandomPath::new(self.hold, lo + margin, hi - margin, 0.8, 2.5, &mut self.rng);
        self.path = Some((path, t0));
        self.record_from_us = Some(now_us + (SETTLE_S * 1e6) as u64);
    }

    fn operator(&mut self, t: f64) -> Operator {
        match self.path.as_mut() {
            Some((p, t0)) => {
                let (q_ref, qd_ref) = p.at(t - *t0, &mut self.rng);
                Operator { k: self.k_h, b: self.b_h, q_ref, qd_ref }
            }
            None => Operator { k: self.k_h, b: self.b_h, q_ref: self.hold, qd_ref: 0.0 },
        }
    }

    fn control_tick(&mut self, now_us: u64) {
        let t = now_us as f64 * 1e-6;
        // 1. the encoder reads the state of `t − delay`
        let past = if self.delay_steps > 0 {
            if self.hist.len() >= self.delay_steps {
                self.hist.get(self.hist.len() - self.delay_steps)
            } else {
                self.hist.front()
            }
            .copied()
        } else {
            None
        };
        let sensed = past.unwrap_or(Rec { t, x: self.x, u: 0.0, op: Operator::default() });
        let q_s = quantise(sensed.x.q + gauss(self.q_noise, &mut self.noise), self.q_res);
        // 2. the board's loop: its estimates and the node's control step (the core's
        // `ControlLoop`, what the G431 and G0B1 tasks run)
        let out = self.ctl.tick(&mut self.node, now_us, Ok::<f32, ()>(q_s as f32)).out;
        let u = f64::from(out.tau_out);
        let op = self.operator(t);
        // 3. what the operator feels now, and the log row of the sensed instant
        let tau_true = -op.torque(self.x.q, self.x.qd);
        let k = f64::from(self.node.params().get(ParamId::AssistK));
        if self.record_from_us.is_some_and(|r| now_us >= r) {
            let tr = &mut self.trace;
            tr.t.push(t);
            tr.q.push(self.x.q);
            tr.qd.push(self.x.qd);
            tr.tau.push(tau_true);
            tr.desired.push(k * self.x.q);
            tr.disturbance.push(u - tau_true);
            tr.c_c.push(f64::from(out.c_c));
            tr.limited.push(out.limited);
            if self.keep_log {
                let row = past.unwrap_or(Rec { t, x: self.x, u, op });
                let dx = self.plant.deriv(row.t, &row.x, row.u, &row.op, &[]);
                let s = &self.sensors;
                let noise = |sd: f64, rng: &mut ChaCha8Rng| gauss(sd, rng);
                let l = &mut tr.log;
                l.t.push(t);
                l.q.push(q_s);
                let qd = row.x.qd + noise(s.qd_noise, &mut self.noise);
                let qdd = dx.qd + noise(s.qdd_noise, &mut self.noise);
                let uu = u + noise(s.u_noise, &mut self.noise);
                let tau = -row.op.torque(row.x.q, row.x.qd) + noise(s.tau_noise, &mut self.noise);
                l.qd.get_or_insert_with(Vec::new).push(qd);
                l.qdd.get_or_insert_with(Vec::new).push(qdd);
                l.u.get_or_insert_with(Vec::new).push(uu);
                l.tau.get_or_insert_with(Vec::new).push(tau);
            }
        }
        // 4. the plant over the period, u and the operator held
        self.node.set_measurements(tau_true as f32, 30.0);
        if self.diverged {
            return;
        }
        let h = self.plant.dt;
        for i in 0..SUBSTEPS {
            let tf = t + i as f64 * h;
            self.hist.push_back(Rec { t: tf, x: self.x, u, op });
            self.x = self.plant.step(tf, &self.x, u, &op, &[]);
        }
        while self.hist.len() > self.delay_steps.max(1) {
            self.hist.pop_front();
        }
        if !(self.x.q.is_finite() && self.x.qd.is_finite()) || self.x.q.abs() > 1.0e3 || self.x.qd.abs() > 1.0e4 {
            // A runaway state would only produce NaNs from here on: freeze it and say so.
            self.diverged = true;
        }
    }
}

impl SimDevice for LoopJoint {
    fn on_frame(&mut self, t_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>) {
        self.node.process(t_us, Some(f), &mut |f| out.push(f));
    }
    fn tick(&mut self, t_us: u64, out: &mut Vec<CanFrame>) {
        self.control_tick(t_us);
        self.node.process(t_us, None, &mut |f| out.push(f));
    }
    fn period_us(&self) -> u64 {
        1000
    }
}

/// The inputs of a run, resolved once.
pub struct Setup {
    pub plant: PlantFile,
    pub raw: RawParams,
    pub fraction: f64,
    pub assist_k: f64,
    pub delay: f64,
    pub range: (f64, f64),
    pub k_h: f64,
    pub b_h: f64,
    pub plant_name: String,
    pub model_name: String,
}

#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    #[error("{0}")]
    Config(String),
    #[error("{0}")]
    Model(#[from] joint_formats::model_file::ModelError),
    #[error("trial {trial}: {msg}")]
    Bus { trial: usize, msg: String },
}

impl Setup {
    /// Resolves the flags against the files: the model's `[compensation]` with `fraction` and
    /// `assist_k` overridden, the plant's delay, range and operator.
    pub fn new(
        plant: &PlantFile,
        model: &ModelFile,
        cfg: &LoopConfig,
        plant_name: &str,
        model_name: &str,
    ) -> Result<Setup, LoopError> {
        let bad = |s: String| Err(LoopError::Config(s));
        let mut mf = model.clone();
        if let Some(f) = cfg.fraction {
            if !(f.is_finite() && (0.0..=1.0).contains(&f)) {
                return bad(format!("--fraction {f}: must lie in 0..=1"));
            }
            mf.set(ParamId::Fraction, f, None);
        }
        if let Some(k) = cfg.assist_k {
            if !k.is_finite() {
                return bad(format!("--assist-k {k}: must be finite"));
            }
            mf.set(ParamId::AssistK, k, None);
        }
        // Refuse here what the joint would refuse at commit, naming the file's key.
        mf.param_set()?;
        let raw = mf.raw_params()?;
        if cfg.trials == 0 {
            return bad("--trials must be at least 1".into());
        }
        if !(cfg.seconds.is_finite() && cfg.seconds >= 1.0 && cfg.seconds <= 3600.0) {
            return bad(format!("--seconds {}: must lie in 1..=3600", cfg.seconds));
        }
        let rate = f64::from(raw.get(ParamId::ControlRateHz));
        if (rate - 1000.0).abs() > 1e-6 {
            return bad(format!("{model_name}: controller.rate_hz = {rate}: closed-loop trials run the joint at 1000 Hz (the SimBus tick)"));
        }
        let mut plant = plant.clone();
        if let Some(d) = cfg.delay {
            if !(d.is_finite() && (0.0..=0.2).contains(&d)) {
                return bad(format!("--delay {d}: must lie in 0..=0.2 s"));
            }
            plant.effects.delay = if d > 0.0 { Some(host_sim::effects::Delay { seconds: d }) } else { None };
        }
        let delay = plant.effects.delay.as_ref().map_or(0.0, |d| d.seconds);
        let range = plant.range.as_ref().map_or((0.0, 116.5 * DEG), |r| (r.min, r.max));
        // The operator: the plant's [operator] if it has one, else a human grip on the rod
        // (see [`HAND_STIFFNESS`]).
        let (k_h, b_h) = match (cfg.operator, &plant.operator) {
            (Some(kb), _) => kb,
            (None, Some(o)) => (o.stiffness, o.damping),
            (None, None) => (HAND_STIFFNESS, HAND_DAMPING),
        };
        Ok(Setup {
            plant,
            fraction: short(raw.get(ParamId::Fraction)),
            assist_k: short(raw.get(ParamId::AssistK)),
            raw,
            delay,
            range,
            k_h,
            b_h,
            plant_name: plant_name.to_string(),
            model_name: model_name.to_string(),
        })
    }
}

/// An f32 parameter as the f64 with the same shortest decimal form (0.7f32 → 0.7, not
/// 0.699999988…), for reports.
fn short(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}

/// Centred moving average of `x` over `w` samples (edges: the available part).
fn moving_average(x: &[f64], w: usize) -> Vec<f64> {
    let n = x.len();
    let h = w / 2;
    let mut pre = Vec::with_capacity(n + 1);
    pre.push(0.0);
    let mut s = 0.0;
    for v in x {
        s += v;
        pre.push(s);
    }
    (0..n)
        .map(|i| {
            let a = i.saturating_sub(h);
            let b = (i + h + 1).min(n);
            (pre.get(b).copied().unwrap_or(0.0) - pre.get(a).copied().unwrap_or(0.0)) / (b - a).max(1) as f64
        })
        .collect()
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

fn stability(tr: &Trace, diverged: bool, range: (f64, f64), rate: f64) -> Stability {
    let n = tr.q.len();
    let mut why = Vec::new();
    let q_lo = tr.q.iter().copied().fold(f64::INFINITY, f64::min);
    let q_hi = tr.q.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let excess = (range.0 - q_lo).max(q_hi - range.1).max(0.0);
    let qd_max = tr.qd.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let limited_share = if n == 0 { 0.0 } else { tr.limited.iter().filter(|&&l| l).count() as f64 / n as f64 };
    // Oscillation: the delivered torque minus its 0.2 s centred moving average keeps what lies
    // above the hand-motion band; its RMS over 1 s windows of the second half, worst window.
    let w = ((limits::OSC_WINDOW * rate).round() as usize).max(3);
    let ma = moving_average(&tr.tau, w);
    let hp: Vec<f64> = tr.tau.iter().zip(&ma).map(|(a, b)| a - b).collect();
    let win = rate.round().max(1.0) as usize;
    let mut osc: f64 = 0.0;
    let mut i = n / 2;
    while i + win <= n {
        osc = osc.max(rms(hp.get(i..i + win).unwrap_or(&[]).iter().copied()));
        i += win / 2;
    }
    if n < 2 * win {
        osc = rms(hp.iter().copied());
    }
    if diverged {
        why.push("the state diverged (non-finite or beyond any joint)".to_string());
    }
    if excess > limits::RANGE_MARGIN {
        why.push(format!("q left the joint range by {:.2} rad (> {:.2})", excess, limits::RANGE_MARGIN));
    }
    if qd_max > limits::QD_MAX {
        why.push(format!("|q̇| reached {qd_max:.2} rad/s (> {})", limits::QD_MAX));
    }
    if osc > limits::OSC_TORQUE_RMS || !osc.is_finite() {
        why.push(format!(
            "sustained oscillation: {osc:.2} N·m RMS above the hand-motion band (> {})",
            limits::OSC_TORQUE_RMS
        ));
    }
    Stability {
        stable: why.is_empty(),
        diverged,
        range_excess_rad: excess,
        qd_max,
        osc_torque_rms: osc,
        limited_share,
        why,
    }
}

/// Runs one trial; returns the trial, the push figures and (with `keep_log`) its log.
pub fn run_trial(
    s: &Setup,
    seed: u64,
    seconds: f64,
    keep_log: bool,
    trial: usize,
) -> Result<(Trial, PushInfo, Option<JointLog>), LoopError> {
    let err = |msg: String| LoopError::Bus { trial, msg };
    let hold = 0.5 * (s.range.0 + s.range.1);
    let dev = Arc::new(Mutex::new(LoopJoint::new(s, hold, seed, keep_log)));
    let mut bus = SimBus::new(1_000_000);
    bus.attach(dev.clone());
    let shared = SharedSimBus(Arc::new(Mutex::new(bus)));
    let mut m = Master::new(Box::new(shared.clone()));
    m.listen(Duration::from_millis(5)).map_err(|e| err(e.to_string()))?;
    let r = transfer::push(&mut m, NODE_ID, &s.raw, PushOptions { pre_operational: true, save: false }, &mut |_| {})
        .map_err(|e| err(format!("push: {e}")))?;
    let push = PushInfo { sdo_transfers: r.sdo_transfers, frames: r.frames, elapsed_us: r.elapsed_us };
    m.nmt(NODE_ID, NMT_START).map_err(|e| err(e.to_string()))?;
    m.listen(Duration::from_millis(2)).map_err(|e| err(e.to_string()))?;
    {
        let mut d = dev.lock().map_err(|_| err("joint lock poisoned".into()))?;
        if d.node.nmt_state() != NmtState::Operational {
            return Err(err(format!("the joint did not go operational (state {})", d.node.nmt_state().name())));
        }
        let now = m.bus.now_us();
        d.start(now, s.range.0, s.range.1);
    }
    m.listen(Duration::from_secs_f64(SETTLE_S + seconds)).map_err(|e| err(e.to_string()))?;
    let mut d = dev.lock().map_err(|_| err("joint lock poisoned".into()))?;
    let faults: Vec<&str> = d.node.safety().faults().names().collect();
    if !faults.is_empty() {
        return Err(err(format!("the joint latched faults during the trial: {}", faults.join(", "))));
    }
    let tr = std::mem::take(&mut d.trace);
    let diverged = d.diverged;
    drop(d);
    let st = stability(&tr, diverged, s.range, 1000.0);
    let err_rms = rms(tr.tau.iter().zip(&tr.desired).map(|(a, b)| a - b));
    let rmse = if diverged || !err_rms.is_finite() { f64::INFINITY } else { err_rms };
    let trial_out = Trial {
        seed,
        samples: tr.t.len(),
        rmse,
        stable: st.stable,
        rms_desired: rms(tr.desired.iter().copied()),
        rms_delivered: rms(tr.tau.iter().copied()),
        rms_disturbance: rms(tr.disturbance.iter().copied()),
        model_error_rmse: rms(tr.disturbance.iter().zip(&tr.c_c).map(|(d, c)| d - c)),
        q_min: tr.q.iter().copied().fold(f64::INFINITY, f64::min),
        q_max: tr.q.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        qd_rms: rms(tr.qd.iter().copied()),
        stability: st,
    };
    Ok((trial_out, push, keep_log.then_some(tr.log)))
}

/// Mean and sample standard deviation.
pub fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let m = v.iter().sum::<f64>() / n as f64;
    let sd = if n > 1 { (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1) as f64).sqrt() } else { 0.0 };
    (m, sd)
}

/// Runs `cfg.trials` trials (seeds `seed`, `seed + 1`, …). `progress(done, total)` after each.
pub fn run(s: &Setup, cfg: &LoopConfig, progress: &mut dyn FnMut(usize, usize)) -> Result<LoopReport, LoopError> {
    let mut trials = Vec::with_capacity(cfg.trials);
    let mut push = None;
    let mut log: Option<JointLog> = None;
    for k in 0..cfg.trials {
        let seed = cfg.seed.wrapping_add(k as u64);
        let (t, p, l) = run_trial(s, seed, cfg.seconds, cfg.keep_log, k)?;
        trials.push(t);
        push.get_or_insert(p);
        if let Some(l) = l {
            append_log(&mut log, l);
        }
        progress(k + 1, cfg.trials);
    }
    let rm: Vec<f64> = trials.iter().map(|t| t.rmse).collect();
    let (mean, sd) = mean_sd(&rm);
    let me: Vec<f64> = trials.iter().map(|t| t.model_error_rmse).collect();
    let (me_mean, me_sd) = mean_sd(&me);
    let rate = f64::from(s.raw.get(ParamId::ControlRateHz));
    Ok(LoopReport {
        plant: s.plant_name.clone(),
        model: s.model_name.clone(),
        fraction: s.fraction,
        assist_k: s.assist_k,
        seconds: cfg.seconds,
        seed: cfg.seed,
        control_rate_hz: rate,
        sensor_delay_s: s.delay,
        vel_cutoff_hz: f64::from(velocity_cutoff_hz(rate as f32)),
        accel_cutoff_hz: f64::from(s.raw.get(ParamId::AccelCutoff)),
        operator_stiffness: s.k_h,
        operator_damping: s.b_h,
        unit: "N·m",
        tracking_rmse_mean: mean,
        tracking_rmse_sd: sd,
        stable: trials.iter().all(|t| t.stable),
        model_error_rmse_mean: me_mean,
        model_error_rmse_sd: me_sd,
        push: push.unwrap_or(PushInfo { sdo_transfers: 0, frames: 0, elapsed_us: 0 }),
        trials,
        log,
    })
}

/// Trials back to back in one log: each trial starts one second after the previous one's last
/// sample. The trials are separate runs (the joint restarts from another pose), so the log
/// has a gap between them and no analysis differentiates or integrates across a restart.
fn append_log(acc: &mut Option<JointLog>, l: JointLog) {
    const TRIAL_GAP_S: f64 = 1.0;
    let Some(a) = acc.as_mut() else {
        *acc = Some(l);
        return;
    };
    let (Some(&last), Some(&first)) = (a.t.last(), l.t.first()) else { return };
    let shift = last + TRIAL_GAP_S - first;
    a.t.extend(l.t.iter().map(|t| t + shift));
    a.q.extend(l.q);
    for (dst, src) in [(&mut a.qd, l.qd), (&mut a.qdd, l.qdd), (&mut a.u, l.u), (&mut a.tau, l.tau)] {
        if let (Some(d), Some(s)) = (dst.as_mut(), src) {
            d.extend(s);
        }
    }
}

/// One point of a fraction sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SweepPoint {
    pub fraction: f64,
    pub tracking_rmse_mean: f64,
    pub tracking_rmse_sd: f64,
    pub stable: bool,
    /// share of the point's trials that were stable
    pub stable_share: f64,
    /// worst oscillation measure over the point's trials, N·m
    pub osc_torque_rms_max: f64,
    pub trials: Vec<Trial>,
}

/// Fractions 0, step, 2·step … 1 (inclusive).
pub fn sweep_fractions(step: f64) -> Vec<f64> {
    let n = (1.0 / step).round().max(1.0) as usize;
    (0..=n).map(|i| (i as f64 / n as f64 * 1e6).round() / 1e6).collect()
}

/// Runs the trials at every fraction of `fractions` (the model's other values unchanged).
pub fn sweep(
    plant: &PlantFile,
    model: &ModelFile,
    cfg: &LoopConfig,
    fractions: &[f64],
    names: (&str, &str),
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<SweepPoint>, LoopError> {
    let mut out = Vec::with_capacity(fractions.len());
    for (i, &f) in fractions.iter().enumerate() {
        let c = LoopConfig { fraction: Some(f), keep_log: false, ..cfg.clone() };
        let s = Setup::new(plant, model, &c, names.0, names.1)?;
        let r = run(&s, &c, &mut |_, _| {})?;
        let stable_n = r.trials.iter().filter(|t| t.stable).count();
        out.push(SweepPoint {
            fraction: f,
            tracking_rmse_mean: r.tracking_rmse_mean,
            tracking_rmse_sd: r.tracking_rmse_sd,
            stable: r.stable,
            stable_share: stable_n as f64 / r.trials.len().max(1) as f64,
            osc_torque_rms_max: r.trials.iter().fold(0.0f64, |m, t| m.max(t.stability.osc_torque_rms)),
            trials: r.trials,
        });
        progress(i + 1, fractions.len());
    }
    Ok(out)
}

/// The smallest swept fraction from which on every point is unstable, if any.
pub fn instability_onset(points: &[SweepPoint]) -> Option<f64> {
    let mut onset = None;
    for p in points.iter().rev() {
        if p.stable {
            break;
        }
        onset = Some(p.fraction);
    }
    onset
}

/// The paper's figure for a model name (`…right…` / `…left…`).
pub fn paper_for(name: &str) -> Option<(&'static str, (f64, f64))> {
    let n = name.to_ascii_lowercase();
    if n.contains("right") {
        Some(("right", PAPER_RIGHT))
    } else if n.contains("left") {
        Some(("left", PAPER_LEFT))
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(f: f64, stable: bool) -> SweepPoint {
        SweepPoint {
            fraction: f,
            tracking_rmse_mean: 1.0,
            tracking_rmse_sd: 0.0,
            stable,
            stable_share: if stable { 1.0 } else { 0.0 },
            osc_torque_rms_max: 0.0,
            trials: Vec::new(),
        }
    }

    #[test]
    fn onset_is_where_the_unstable_tail_begins() {
        let pts: Vec<SweepPoint> = [(0.0, true), (0.5, false), (0.8, true), (0.9, false), (1.0, false)]
            .iter()
            .map(|&(f, s)| point(f, s))
            .collect();
        // an isolated unstable point below a stable one is not the onset
        assert_eq!(instability_onset(&pts), Some(0.9));
        assert_eq!(instability_onset(&pts[..3]), None);
    }

    #[test]
    fn sweep_fractions_are_exact_decimals() {
        let f = sweep_fractions(0.1);
        assert_eq!(f.len(), 11);
        assert_eq!(f[7], 0.7);
        assert_eq!(f[10], 1.0);
    }

    #[test]
    fn moving_average_keeps_a_slow_signal_and_removes_a_fast_one() {
        let rate = 1000.0;
        let slow: Vec<f64> = (0..4000).map(|i| (std::f64::consts::TAU * 0.5 * i as f64 / rate).sin()).collect();
        let fast: Vec<f64> = (0..4000).map(|i| (std::f64::consts::TAU * 15.0 * i as f64 / rate).sin()).collect();
        let w = (limits::OSC_WINDOW * rate) as usize;
        let hp = |x: &[f64]| {
            let ma = moving_average(x, w);
            rms(x.iter().zip(&ma).skip(w).take(x.len() - 2 * w).map(|(a, b)| a - b))
        };
        assert!(hp(&slow) < 0.05, "{}", hp(&slow));
        assert!(hp(&fast) > 0.6, "{}", hp(&fast));
    }

    #[test]
    fn mean_and_sample_sd() {
        let (m, s) = mean_sd(&[1.0, 2.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((s - 1.0).abs() < 1e-12);
        assert_eq!(mean_sd(&[4.0]), (4.0, 0.0));
    }
}
