//! The simulation loop on virtual time: the plant integrated by RK4 at the fine step, the core's
//! `Controller::step` at the control rate with a zero-order hold on its torque, sensors sampled
//! once per control tick. Nothing sleeps; the same seed gives the same log, bit for bit.
//!
//! Per control tick k (t = k/rate):
//! 1. the sensors read the state of `t − delay` (no `[delay]`: the current state): angle with
//!    noise and quantisation, velocity with noise; the other joints' angles likewise;
//! 2. the boards' loop, the core's [`ControlLoop`], ticks on that angle and velocity
//!    ([`ControlLoop::tick_sensed`]: q̇ as the velocity sensor reads it, q̈ its derivative
//!    through the `controller.accel_cutoff` filter, at the loop's whole-µs period) and steps the
//!    core's controller under the scenario's mode with the other joints' angles and the load
//!    cell's reading of the same instant (the row's `tau`; 0 in a log without torque columns, a
//!    joint without a load cell); its output torque u is applied at once;
//! 3. the log row: t, the sensed q, q̇, q̈ (true q̈ + `qdd_noise`, of the sensed instant), u (+
//!    `u_noise`), tau = −τ_ext (+ `tau_noise`), temp (thermal drift only), `q_<name>`;
//! 4. the plant advances `plant_rate/rate` RK4 steps with u and the operator held.
//!
//! Other joints named by the plant's gravity table follow smooth random paths inside their grid.
//!
//! The loop is the one every user of the core runs (the boards, the QEMU images, `jointctl sim`,
//! the closed-loop experiments); what differs is what it reads and steps. A plant file describes
//! the sensors its logs carry, a velocity sensor among them, so the simulated joint ticks with
//! the velocity it reads, as a board with a velocity sensor would; the boards' encoder-only
//! estimate (q̇ from the angle) is `jointctl sim` and the closed-loop experiments. Tried in issue
//! 18: the encoder-only estimate on these plants' white angle noise (`q_noise` 1e-4 rad at 1 kHz)
//! made the torque change by 0.77 N·m rms per tick instead of 0.053, and the exact model's log
//! was no longer at its noise floor; that is a different sensor, not the same loop. And the
//! loop steps a bare controller ([`LoopTarget`] for `Rig`), not the CANopen node: the scenarios
//! command velocity sweeps and position holds, a test rig's modes the node does not offer.

use std::collections::VecDeque;

use joint_core::control::{Controller, Input, Mode, Output};
use joint_core::control_loop::{ControlLoop, LoopTarget};
use joint_core::params::{check, ParamId, ParamSet};
use joint_core::safety::Faults;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::plant::{Operator, Plant, PlantFile, Sensors, State};
use crate::scenario::{RandomPath, Scenario, ScenarioCfg, ScenarioKind};
use joint_formats::log::JointLog;
use joint_formats::predict::{predicted, residual, rms};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Everything `simulate` needs besides the two files.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    pub scenarios: Vec<ScenarioKind>,
    /// seconds per scenario
    pub seconds: f64,
    pub seed: u64,
    /// control rate, Hz (None: the controller model's `controller.rate_hz`)
    pub rate: Option<f64>,
    /// plant integration rate, Hz (≥ 10× the control rate)
    pub plant_rate: f64,
    /// joint range in rad (None: the plant's `[joint_range]`, else 0…116.5°)
    pub range: Option<(f64, f64)>,
    /// start angle of `free`, rad (None: 75 % of the range)
    pub free_start: Option<f64>,
    /// write `u` and `tau` (false: a trajectory-mode log)
    pub torque_columns: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            scenarios: vec![ScenarioKind::Sweep],
            seconds: 10.0,
            seed: 1,
            rate: None,
            plant_rate: 10_000.0,
            range: None,
            free_start: None,
            torque_columns: true,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SimError {
    #[error("{0}")]
    Config(String),
}

/// One fine-step record: state and the inputs in force from that instant.
#[derive(Clone, Copy)]
struct Rec {
    t: f64,
    x: State,
    u: f64,
    op: Operator,
}

/// White Gaussian noise of a standard deviation (0 = none; no draw is wasted either way, so
/// the random stream does not depend on which sensors are noisy).
#[derive(Clone, Copy)]
struct Noise(f64);

impl Noise {
    fn sample(&self, rng: &mut ChaCha8Rng) -> f64 {
        let z: f64 = StandardNormal.sample(rng);
        self.0 * z
    }
}

fn normal(sd: f64) -> Noise {
    Noise(if sd.is_finite() { sd.max(0.0) } else { 0.0 })
}

fn quantise(x: f64, q: f64) -> f64 {
    if q > 0.0 {
        (x / q).round() * q
    } else {
        x
    }
}

/// Resolved run settings (after defaults), reported in summaries.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunInfo {
    pub rate_hz: f64,
    pub plant_rate_hz: f64,
    pub range_rad: (f64, f64),
    pub sign_band: f64,
    pub operator_stiffness: f64,
    pub operator_damping: f64,
}

/// Runs the scenarios back to back and returns the log.
pub fn simulate(plant_file: &PlantFile, ctrl: &ParamSet, cfg: &SimConfig) -> Result<(JointLog, RunInfo), SimError> {
    let timing = Timing::check(plant_file, ctrl, cfg)?;
    let (lo, hi) = timing.range;
    let plant = Plant::new(plant_file, timing.dt_fine, f64::from(ctrl.get(ParamId::TorqueLimit)));
    let (k_h, b_h) = operator_impedance(plant_file, &plant);
    let scfg =
        ScenarioCfg { lo, hi, k_h, b_h, free_start: cfg.free_start.unwrap_or(lo + 0.75 * (hi - lo)), sweep_accel: 3.0 };
    let rig = Rig::new(loop_params(ctrl, timing.rate)?);
    let mut run = Run::new(plant_file, &plant, rig, cfg, &timing, &scfg);
    for (si, kind) in cfg.scenarios.iter().enumerate() {
        let mut scenario: Option<Scenario> = None;
        for k in 0..timing.ticks_per_scenario {
            run.tick(*kind, si, k, &mut scenario)?;
        }
    }
    let info = RunInfo {
        rate_hz: timing.rate,
        plant_rate_hz: cfg.plant_rate,
        range_rad: (lo, hi),
        sign_band: plant.band,
        operator_stiffness: k_h,
        operator_damping: b_h,
    };
    Ok((run.log, info))
}

/// The controller's set with `controller_rate_hz` at the run's rate (the loop's period and
/// filters follow it, as on a board after that set is committed); refused as a board would
/// refuse it.
fn loop_params(ctrl: &ParamSet, rate: f64) -> Result<ParamSet, SimError> {
    let hz = rate as f32;
    if ctrl.get(ParamId::ControlRateHz).to_bits() == hz.to_bits() {
        return Ok(ctrl.clone());
    }
    let mut raw = ctrl.raw().clone();
    raw.set(ParamId::ControlRateHz, hz);
    check(&raw)
        .map_err(|e| SimError::Config(format!("control rate {rate} Hz with the controller's parameter set: {e}")))
}

/// What the loop steps in a simulated run: the core's controller under the scenario's mode,
/// with the other joints' sensed angles and the load cell's reading of this tick.
struct Rig {
    params: ParamSet,
    controller: Controller,
    mode: Mode,
    others: [f32; 3],
    tau_load: f32,
    faults: Faults,
}

impl Rig {
    fn new(params: ParamSet) -> Rig {
        Rig {
            params,
            controller: Controller::new(),
            mode: Mode::Off,
            others: [0.0; 3],
            tau_load: 0.0,
            faults: Faults::NONE,
        }
    }
}

impl LoopTarget for Rig {
    fn params(&self) -> &ParamSet {
        &self.params
    }
    fn control(&mut self, _now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output {
        let inp = Input { q, qd, qdd, others: self.others, assist_cmd: 0.0, tau_load: self.tau_load };
        self.controller.step(&self.params, self.mode, &inp, dt)
    }
    fn raise(&mut self, f: Faults) {
        self.faults.insert(f);
    }
    fn faults(&self) -> Faults {
        self.faults
    }
    /// The rig applies the controller's torque; a latched fault stops the run instead.
    fn drive(&self) -> bool {
        true
    }
}

/// The rates, step sizes and range of a run, checked.
struct Timing {
    /// control rate, Hz
    rate: f64,
    /// plant steps per control tick
    sub: usize,
    dt_ctrl: f64,
    dt_fine: f64,
    range: (f64, f64),
    ticks_per_scenario: usize,
}

impl Timing {
    fn check(plant_file: &PlantFile, ctrl: &ParamSet, cfg: &SimConfig) -> Result<Timing, SimError> {
        let bad = |s: String| Err(SimError::Config(s));
        let rate = cfg.rate.unwrap_or(f64::from(ctrl.get(ParamId::ControlRateHz)));
        if !(rate.is_finite() && rate > 0.0) {
            return bad(format!("control rate {rate} Hz must be > 0"));
        }
        if !(cfg.plant_rate.is_finite() && cfg.plant_rate >= 10.0 * rate - 1e-9) {
            return bad(format!("plant rate {} Hz must be at least 10× the control rate {rate} Hz", cfg.plant_rate));
        }
        let sub = (cfg.plant_rate / rate).round() as usize;
        if ((sub as f64) * rate - cfg.plant_rate).abs() > 1e-6 * cfg.plant_rate {
            return bad(format!(
                "plant rate {} Hz must be an integer multiple of the control rate {rate} Hz",
                cfg.plant_rate
            ));
        }
        if !(cfg.seconds.is_finite() && cfg.seconds > 0.0 && cfg.seconds * rate <= 5.0e7) {
            return bad(format!("--seconds {} must be > 0 (and at most 5e7 samples)", cfg.seconds));
        }
        if cfg.scenarios.is_empty() {
            return bad("no scenario given".into());
        }
        let (lo, hi) = cfg.range.or(plant_file.range.as_ref().map(|r| (r.min, r.max))).unwrap_or((0.0, 116.5 * DEG));
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return bad(format!("joint range {lo}..{hi} rad must have min < max"));
        }
        let dt_ctrl = 1.0 / rate;
        Ok(Timing {
            rate,
            sub,
            dt_ctrl,
            dt_fine: dt_ctrl / sub as f64,
            range: (lo, hi),
            ticks_per_scenario: (cfg.seconds * rate).round() as usize,
        })
    }
}

/// The operator's impedance: the plant file's, or a 1.5 Hz, 0.7-damped hand on the joint's
/// inertia, stiff enough to dominate the joint's own springs and weight.
fn operator_impedance(plant_file: &PlantFile, plant: &Plant) -> (f64, f64) {
    match &plant_file.operator {
        Some(o) => (o.stiffness, o.damping),
        None => {
            let w = std::f64::consts::TAU * 1.5;
            let k = plant.j * w * w + 3.0 * plant.stiffness_scale();
            (k, 2.0 * 0.7 * (k * plant.j).sqrt())
        }
    }
}

/// The sensors' noise, one generator each.
struct SensorNoise {
    q: Noise,
    qd: Noise,
    qdd: Noise,
    tau: Noise,
    u: Noise,
    temp: Noise,
    q_resolution: f64,
}

impl SensorNoise {
    fn new(s: &Sensors) -> SensorNoise {
        SensorNoise {
            q: normal(s.q_noise),
            qd: normal(s.qd_noise),
            qdd: normal(s.qdd_noise),
            tau: normal(s.tau_noise),
            u: normal(s.u_noise),
            temp: normal(s.temp_noise),
            q_resolution: s.q_resolution,
        }
    }
}

/// What the sensors read in one control tick (of the delayed state when the plant has a delay).
struct Sensed {
    /// the fine-step record the readings come from, if the delay reaches back to one
    past: Option<Rec>,
    q: f64,
    qd: f64,
    others_true: Vec<f64>,
    others: Vec<f64>,
}

/// The noise of one log row, drawn before the controller runs (in the row's column order, each
/// only when the log has its column, as the row takes them), so the controller reads the same
/// load cell the log holds and the random stream is the one it was before the controller read it.
#[derive(Clone, Copy, Default)]
struct RowNoise {
    qdd: f64,
    u: f64,
    tau: f64,
    temp: f64,
}

/// The state of one simulation run between control ticks.
struct Run<'a> {
    plant: &'a Plant,
    cfg: &'a SimConfig,
    timing: &'a Timing,
    scfg: &'a ScenarioCfg,
    noise: SensorNoise,
    rng_scn: ChaCha8Rng,
    rng_noise: ChaCha8Rng,
    /// other joints of the gravity table: random smooth paths inside their grid
    other_paths: Vec<RandomPath>,
    others_now: Vec<f64>,
    others_hist: VecDeque<Vec<f64>>,
    /// fine steps of sensor delay (the plant's `[delay]`)
    delay_steps: usize,
    x: State,
    /// the boards' loop and what it steps
    ctl: ControlLoop,
    rig: Rig,
    hist: VecDeque<Rec>,
    tick: usize,
    log: JointLog,
}

impl<'a> Run<'a> {
    fn new(
        plant_file: &PlantFile,
        plant: &'a Plant,
        rig: Rig,
        cfg: &'a SimConfig,
        timing: &'a Timing,
        scfg: &'a ScenarioCfg,
    ) -> Run<'a> {
        let mut rng_scn = ChaCha8Rng::seed_from_u64(cfg.seed);
        let rng_noise = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x9E37_79B9_7F4A_7C15);
        let other_names = plant_file.model.other_columns();
        let other_paths: Vec<RandomPath> = other_names
            .iter()
            .map(|name| {
                let (glo, ghi) = plant_file
                    .model
                    .table
                    .as_ref()
                    .and_then(|t| t.axes.iter().position(|a| a == name).and_then(|i| t.grid.get(i)))
                    .and_then(|g| Some((*g.first()?, *g.last()?)))
                    .unwrap_or((0.0, 1.0));
                RandomPath::new(0.5 * (glo + ghi), glo, ghi, 1.0, 4.0, &mut rng_scn)
            })
            .collect();
        let delay_steps =
            plant_file.effects.delay.as_ref().map(|d| (d.seconds / timing.dt_fine).round() as usize).unwrap_or(0);
        let log_temp = plant_file.effects.thermal_drift.as_ref().map(|t| t.log_temp).unwrap_or(false);
        let first_kind = cfg.scenarios.first().copied().unwrap_or(ScenarioKind::Sweep);
        let q_init = Scenario::initial_angle(first_kind, scfg);
        let n_total = timing.ticks_per_scenario * cfg.scenarios.len();
        let log = JointLog {
            t: Vec::with_capacity(n_total),
            q: Vec::with_capacity(n_total),
            qd: Some(Vec::with_capacity(n_total)),
            qdd: Some(Vec::with_capacity(n_total)),
            u: cfg.torque_columns.then(|| Vec::with_capacity(n_total)),
            tau: cfg.torque_columns.then(|| Vec::with_capacity(n_total)),
            temp: log_temp.then(|| Vec::with_capacity(n_total)),
            others: other_names.iter().map(|n| (n.clone(), Vec::with_capacity(n_total))).collect(),
            unknown: Vec::new(),
        };
        Run {
            plant,
            cfg,
            timing,
            scfg,
            noise: SensorNoise::new(&plant_file.sensors),
            rng_scn,
            rng_noise,
            others_now: vec![0.0; other_names.len()],
            other_paths,
            others_hist: VecDeque::new(),
            delay_steps,
            x: State::at_rest(q_init),
            ctl: ControlLoop::new(&rig.params),
            rig,
            hist: VecDeque::with_capacity(delay_steps + timing.sub + 2),
            tick: 0,
            log,
        }
    }

    /// One control tick (k-th of scenario `si`): sense, control, log, integrate.
    fn tick(
        &mut self,
        kind: ScenarioKind,
        si: usize,
        k: usize,
        scenario: &mut Option<Scenario>,
    ) -> Result<(), SimError> {
        let dt_ctrl = self.timing.dt_ctrl;
        let t = self.tick as f64 * dt_ctrl;
        self.tick += 1;
        // Other joints' true angles now (held over the tick).
        for (o, p) in self.others_now.iter_mut().zip(self.other_paths.iter_mut()) {
            *o = p.at(t, &mut self.rng_scn).0;
        }
        let sensed = self.sense();
        let sc = scenario.get_or_insert_with(|| {
            Scenario::start(kind, self.cfg.seconds, self.scfg, sensed.q, si == 0, &mut self.rng_scn)
        });
        let cmd = sc.command(k as f64 * dt_ctrl, sensed.q, &mut self.rng_scn);
        let noise = self.row_noise();
        // the load cell at the sensed instant (the operator in force then), as the row logs it
        let now = Rec { t, x: self.x, u: 0.0, op: cmd.operator };
        let at = self.sensed_rec(&sensed, now);
        let tau = self.log.tau.is_some().then(|| -at.op.torque(at.x.q, at.x.qd) + noise.tau);
        let u = self.control(t, &sensed, cmd.mode, tau.unwrap_or(0.0))?;
        self.hist.push_back(Rec { t, x: self.x, u, op: cmd.operator });
        self.log_row(t, &sensed, Rec { u, ..now }, noise, tau);
        self.integrate(t, u, &cmd.operator)
    }

    /// 1. The sensors, of the delayed state (its inputs are fixed when the tick's record is
    ///    pushed), with noise and quantisation.
    fn sense(&mut self) -> Sensed {
        let lag = self.delay_steps;
        let hist = &self.hist;
        let past: Option<Rec> = if hist.len() > lag { hist.get(hist.len() - lag) } else { hist.front() }.copied();
        let xs = match past {
            Some(r) if lag > 0 => r.x,
            _ => self.x,
        };
        self.others_hist.push_back(self.others_now.clone());
        let lag_ticks = lag.div_ceil(self.timing.sub).min(self.others_hist.len().saturating_sub(1));
        while self.others_hist.len() > lag_ticks + 1 {
            self.others_hist.pop_front();
        }
        let others_true = self.others_hist.front().cloned().unwrap_or_default();
        let (n, rng) = (&self.noise, &mut self.rng_noise);
        let q = quantise(xs.q + n.q.sample(rng), n.q_resolution);
        let qd = xs.qd + n.qd.sample(rng);
        let others: Vec<f64> = others_true.iter().map(|o| quantise(o + n.q.sample(rng), n.q_resolution)).collect();
        Sensed { past, q, qd, others_true, others }
    }

    /// The noise of this tick's log row (see [`RowNoise`]).
    fn row_noise(&mut self) -> RowNoise {
        let (n, rng, log) = (&self.noise, &mut self.rng_noise, &self.log);
        let mut draw = |on: bool, noise: &Noise| if on { noise.sample(rng) } else { 0.0 };
        RowNoise {
            qdd: draw(log.qdd.is_some(), &n.qdd),
            u: draw(log.u.is_some(), &n.u),
            tau: draw(log.tau.is_some(), &n.tau),
            temp: draw(log.temp.is_some(), &n.temp),
        }
    }

    /// The record the sensors read this tick: the delayed one, or `now` without a delay.
    fn sensed_rec(&self, s: &Sensed, now: Rec) -> Rec {
        match s.past {
            Some(r) if self.delay_steps > 0 => r,
            _ => now,
        }
    }

    /// 2. The core's control loop on what was sensed (`tau`: the load cell's reading);
    ///    returns the output torque.
    fn control(&mut self, t: f64, s: &Sensed, mode: Mode, tau: f64) -> Result<f64, SimError> {
        let rig = &mut self.rig;
        rig.mode = mode;
        rig.tau_load = tau as f32;
        rig.others = [0.0; 3];
        for (dst, src) in rig.others.iter_mut().zip(s.others.iter()) {
            *dst = *src as f32;
        }
        let now_us = (t * 1.0e6).round() as u64;
        let r = self.ctl.tick_sensed(rig, now_us, Ok::<f32, ()>(s.q as f32), Ok(s.qd as f32));
        if r.faults != Faults::NONE {
            return Err(SimError::Config(format!(
                "the control loop latched fault bits {:#06x} at t = {t:.4} s",
                r.faults.bits()
            )));
        }
        Ok(f64::from(r.out.tau_out))
    }

    /// 3. The log row, from the sensed instant with the inputs in force then (`now`: this
    ///    tick's record, used when there is no delay), with the row's noise and the load cell's
    ///    reading `tau` the controller had.
    fn log_row(&mut self, t: f64, s: &Sensed, now: Rec, noise: RowNoise, tau: Option<f64>) {
        let rec = self.sensed_rec(s, now);
        let dx = self.plant.deriv(rec.t, &rec.x, rec.u, &rec.op, &s.others_true);
        let log = &mut self.log;
        log.t.push(t);
        log.q.push(s.q);
        if let Some(c) = log.qd.as_mut() {
            c.push(s.qd);
        }
        if let Some(c) = log.qdd.as_mut() {
            c.push(dx.qd + noise.qdd);
        }
        if let Some(c) = log.u.as_mut() {
            c.push(now.u + noise.u);
        }
        if let (Some(c), Some(tau)) = (log.tau.as_mut(), tau) {
            c.push(tau);
        }
        if let Some(c) = log.temp.as_mut() {
            c.push(self.plant.effects.temperature(t).unwrap_or(0.0) + noise.temp);
        }
        for ((_, col), v) in log.others.iter_mut().zip(s.others.iter()) {
            col.push(*v);
        }
    }

    /// 4. The plant over one control tick, `u` and the operator held.
    fn integrate(&mut self, t: f64, u: f64, op: &Operator) -> Result<(), SimError> {
        let dt = self.timing.dt_fine;
        for i in 0..self.timing.sub {
            let tf = t + i as f64 * dt;
            if i > 0 {
                self.hist.push_back(Rec { t: tf, x: self.x, u, op: *op });
            }
            self.x = self.plant.step(tf, &self.x, u, op, &self.others_now);
        }
        while self.hist.len() > self.delay_steps + 1 {
            self.hist.pop_front();
        }
        if !(self.x.q.is_finite() && self.x.qd.is_finite()) {
            return Err(SimError::Config(format!(
                "the simulation diverged at t = {t:.4} s (check the plant's parameters)"
            )));
        }
        Ok(())
    }
}

/// The residual RMS that the sensor noise alone produces: `tau_noise² + u_noise²` plus the
/// spread of the model's prediction when its inputs are disturbed by the sensor noise (q: noise
/// and a uniform quantisation error; qd; qdd), estimated by redrawing that noise once per
/// sample on the logged samples (seeded, so deterministic). Nonlinear terms (the friction sign
/// near zero velocity) are covered because the model is evaluated, not linearised.
pub fn noise_floor(
    log: &JointLog,
    p: &ParamSet,
    other_columns: &[String],
    s: &crate::plant::Sensors,
    seed: u64,
) -> Option<f64> {
    let base = predicted(log, p, other_columns)?;
    let mut noisy = log.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5DEE_CE66_D1CE_4E5B);
    let (n_q, n_qd, n_qdd) = (normal(s.q_noise), normal(s.qd_noise), normal(s.qdd_noise));
    let quant = s.q_resolution;
    let mut jitter = |v: &mut Vec<f64>, n: &Noise, with_quant: bool| {
        for x in v.iter_mut() {
            *x += n.sample(&mut rng);
            if with_quant && quant > 0.0 {
                *x += (rand::Rng::random::<f64>(&mut rng) - 0.5) * quant;
            }
        }
    };
    jitter(&mut noisy.q, &n_q, true);
    for (_, col) in noisy.others.iter_mut() {
        jitter(col, &n_q, true);
    }
    if let Some(c) = noisy.qd.as_mut() {
        jitter(c, &n_qd, false);
    }
    if let Some(c) = noisy.qdd.as_mut() {
        jitter(c, &n_qdd, false);
    }
    let pert = predicted(&noisy, p, other_columns)?;
    let spread: Vec<f64> = base.iter().zip(&pert).map(|(a, b)| a - b).collect();
    let m = rms(&spread);
    Some((s.tau_noise * s.tau_noise + s.u_noise * s.u_noise + m * m).sqrt())
}

/// Short numbers about a log, for the CLI summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    pub samples: usize,
    pub duration_s: f64,
    pub mode: joint_formats::log::LogMode,
    pub q_min: f64,
    pub q_max: f64,
    pub rms_u: Option<f64>,
    pub rms_tau: Option<f64>,
    pub rms_residual: Option<f64>,
    pub noise_floor: Option<f64>,
    pub columns: Vec<String>,
}

pub fn summarize(
    log: &JointLog,
    p: &ParamSet,
    other_columns: &[String],
    sensors: Option<(&crate::plant::Sensors, u64)>,
) -> Summary {
    let q_min = log.q.iter().copied().fold(f64::INFINITY, f64::min);
    let q_max = log.q.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let duration_s = match (log.t.first(), log.t.last()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    Summary {
        samples: log.len(),
        duration_s,
        mode: log.mode(),
        q_min,
        q_max,
        rms_u: log.u.as_deref().map(rms),
        rms_tau: log.tau.as_deref().map(rms),
        rms_residual: residual(log, p, other_columns).map(|r| rms(&r)),
        noise_floor: match (log.mode(), sensors) {
            (joint_formats::log::LogMode::Torque, Some((s, seed))) => noise_floor(log, p, other_columns, s, seed),
            _ => None,
        },
        columns: log.column_names().iter().map(|s| s.to_string()).collect(),
    }
}
