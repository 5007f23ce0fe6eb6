//! The simulation loop on virtual time: the plant integrated by RK4 at the fine step, the core's
//! `Controller::step` at the control rate with a zero-order hold on its torque, sensors sampled
//! once per control tick. Nothing sleeps; the same seed gives the same log, bit for bit.
//!
//! Per control tick k (t = k/rate):
//! 1. the sensors read the state of `t − delay` (no `[delay]`: the current state): angle with
//!    noise and quantisation, velocity with noise; the other joints' angles likewise;
//! 2. the controller gets that q and q̇, and q̈ from the core's `Differentiator` on the sensed q̇
//!    (cut-off `controller.accel_cutoff`), and returns the output torque u, applied at once;
//! 3. the log row: t, the sensed q, q̇, q̈ (true q̈ + `qdd_noise`, of the sensed instant), u (+
//!    `u_noise`), tau = −τ_ext (+ `tau_noise`), temp (thermal drift only), `q_<name>`;
//! 4. the plant advances `plant_rate/rate` RK4 steps with u and the operator held.
//!
//! Other joints named by the plant's gravity table follow smooth random paths inside their grid.

use std::collections::VecDeque;

use joint_core::control::{Controller, Differentiator, Input};
use joint_core::params::{ParamId, ParamSet};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::plant::{Operator, Plant, PlantFile, State};
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
    let dt = dt_ctrl / sub as f64;
    let u_max = f64::from(ctrl.get(ParamId::TorqueLimit));
    let plant = Plant::new(plant_file, dt, u_max);

    // Operator impedance: a 1.5 Hz, 0.7-damped hand on the joint's inertia, stiff enough to
    // dominate the joint's own springs and weight.
    let (k_h, b_h) = match &plant_file.operator {
        Some(o) => (o.stiffness, o.damping),
        None => {
            let w = std::f64::consts::TAU * 1.5;
            let k = plant.j * w * w + 3.0 * plant.stiffness_scale();
            (k, 2.0 * 0.7 * (k * plant.j).sqrt())
        }
    };
    let scfg =
        ScenarioCfg { lo, hi, k_h, b_h, free_start: cfg.free_start.unwrap_or(lo + 0.75 * (hi - lo)), sweep_accel: 3.0 };

    let mut rng_scn = ChaCha8Rng::seed_from_u64(cfg.seed);
    let mut rng_noise = ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x9E37_79B9_7F4A_7C15);
    let s = &plant_file.sensors;
    let (n_q, n_qd, n_qdd, n_tau, n_u, n_temp) = (
        normal(s.q_noise),
        normal(s.qd_noise),
        normal(s.qdd_noise),
        normal(s.tau_noise),
        normal(s.u_noise),
        normal(s.temp_noise),
    );

    // Other joints of the gravity table: random smooth paths inside their grid.
    let other_names = plant_file.model.other_columns();
    let mut other_paths: Vec<RandomPath> = other_names
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

    let delay_steps = plant_file.effects.delay.as_ref().map(|d| (d.seconds / dt).round() as usize).unwrap_or(0);
    let log_temp = plant_file.effects.thermal_drift.as_ref().map(|t| t.log_temp).unwrap_or(false);

    let first_kind = cfg.scenarios.first().copied().unwrap_or(ScenarioKind::Sweep);
    let q_init = Scenario::initial_angle(first_kind, &scfg);
    let mut x = State { q: q_init, qd: 0.0, qm: q_init, qdm: 0.0 };
    let ticks_per = (cfg.seconds * rate).round() as usize;
    let n_total = ticks_per * cfg.scenarios.len();

    let mut log = JointLog {
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

    let mut controller = Controller::new();
    let mut diff = Differentiator::new();
    let cutoff = ctrl.get(ParamId::AccelCutoff);
    let mut hist: VecDeque<Rec> = VecDeque::with_capacity(delay_steps + sub + 2);
    let mut others_now = vec![0.0; other_names.len()];
    let mut others_hist: VecDeque<Vec<f64>> = VecDeque::new();
    let mut tick = 0usize;
    for (si, kind) in cfg.scenarios.iter().enumerate() {
        let mut scenario: Option<Scenario> = None;
        for k in 0..ticks_per {
            let t = tick as f64 * dt_ctrl;
            tick += 1;
            let t_local = k as f64 * dt_ctrl;
            // Other joints' true angles now (held over the tick).
            for (o, p) in others_now.iter_mut().zip(other_paths.iter_mut()) {
                *o = p.at(t, &mut rng_scn).0;
            }
            // 1. sensors of the delayed state (its inputs are fixed below for the current entry)
            let lag_ticks_fine = delay_steps;
            let past: Option<Rec> =
                if hist.len() > lag_ticks_fine { hist.get(hist.len() - lag_ticks_fine) } else { hist.front() }.copied();
            let (xs, past_t) = match past {
                Some(r) if lag_ticks_fine > 0 => (r.x, r.t),
                _ => (x, t),
            };
            others_hist.push_back(others_now.clone());
            let lag_ticks = delay_steps.div_ceil(sub).min(others_hist.len().saturating_sub(1));
            while others_hist.len() > lag_ticks + 1 {
                others_hist.pop_front();
            }
            let others_seen = others_hist.front().cloned().unwrap_or_default();
            let q_s = quantise(xs.q + n_q.sample(&mut rng_noise), s.q_resolution);
            let qd_s = xs.qd + n_qd.sample(&mut rng_noise);
            let others_s: Vec<f64> =
                others_seen.iter().map(|o| quantise(o + n_q.sample(&mut rng_noise), s.q_resolution)).collect();

            // 2. controller
            let sc =
                scenario.get_or_insert_with(|| Scenario::start(*kind, cfg.seconds, &scfg, q_s, si == 0, &mut rng_scn));
            let cmd = sc.command(t_local, q_s, &mut rng_scn);
            let qdd_est = diff.update(qd_s as f32, dt_ctrl as f32, cutoff);
            let mut inp = Input { q: q_s as f32, qd: qd_s as f32, qdd: qdd_est, others: [0.0; 3], assist_cmd: 0.0 };
            for (dst, src) in inp.others.iter_mut().zip(others_s.iter()) {
                *dst = *src as f32;
            }
            let out = controller.step(ctrl, cmd.mode, &inp, dt_ctrl as f32);
            let u = f64::from(out.tau_out);
            hist.push_back(Rec { t, x, u, op: cmd.operator });

            // 3. the log row, from the sensed instant with the inputs in force then
            let rec = if lag_ticks_fine > 0 {
                match past {
                    Some(r) => r,
                    None => Rec { t, x, u, op: cmd.operator },
                }
            } else {
                Rec { t, x, u, op: cmd.operator }
            };
            let _ = past_t;
            let dx = plant.deriv(rec.t, &rec.x, rec.u, &rec.op, &others_seen);
            log.t.push(t);
            log.q.push(q_s);
            if let Some(c) = log.qd.as_mut() {
                c.push(qd_s);
            }
            if let Some(c) = log.qdd.as_mut() {
                c.push(dx.qd + n_qdd.sample(&mut rng_noise));
            }
            if let Some(c) = log.u.as_mut() {
                c.push(u + n_u.sample(&mut rng_noise));
            }
            if let Some(c) = log.tau.as_mut() {
                c.push(-rec.op.torque(rec.x.q, rec.x.qd) + n_tau.sample(&mut rng_noise));
            }
            if let Some(c) = log.temp.as_mut() {
                c.push(plant.effects.temperature(t).unwrap_or(0.0) + n_temp.sample(&mut rng_noise));
            }
            for ((_, col), v) in log.others.iter_mut().zip(others_s.iter()) {
                col.push(*v);
            }

            // 4. integrate
            for i in 0..sub {
                let tf = t + i as f64 * dt;
                if i > 0 {
                    hist.push_back(Rec { t: tf, x, u, op: cmd.operator });
                }
                x = plant.step(tf, &x, u, &cmd.operator, &others_now);
            }
            while hist.len() > delay_steps + 1 {
                hist.pop_front();
            }
            if !(x.q.is_finite() && x.qd.is_finite()) {
                return bad(format!("the simulation diverged at t = {t:.4} s (check the plant's parameters)"));
            }
        }
    }
    let info = RunInfo {
        rate_hz: rate,
        plant_rate_hz: cfg.plant_rate,
        range_rad: (lo, hi),
        sign_band: plant.band,
        operator_stiffness: k_h,
        operator_damping: b_h,
    };
    Ok((log, info))
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
