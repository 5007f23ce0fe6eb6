//! Torque-mode cases: a prescribed trajectory under ideal position control, the true
//! disturbance d = J·q̈ + friction + weight + offset + spring + effect, u = d + tau, then
//! the sensor chain.

use serde::Serialize;
use serde_json::json;

use crate::case::{label_of, scene_that_sizes, snr_map, truth_names, zero_share, CaseData, Clean, Log, Mode, Truth};
use crate::effects::{dahl_step, draw_additive, Delayed, Effect, Scene};
use crate::joint::{self, DrawnJoint, JointKind, Needs};
use crate::model::ModelFile;
use crate::noise::{self, rms, TorqueNoise};
use crate::rngs::{chance, int, log_uniform, pick, uniform, weighted, Rng64};
use crate::traj::{self, Kin, Trajectory};

/// Internal time from which stateful effects (the Dahl state) are integrated: before the
/// first sample, so a delayed sweep and the plain sweep share one history.
const T_HISTORY: f64 = -1.0;

/// Smooth external load (human or payload torque): bias + Σ A·sin(2πft + φ).
#[derive(Debug, Clone, Serialize)]
pub struct Load {
    pub kind: &'static str,
    pub bias: f64,
    /// (amplitude N·m, frequency Hz, phase rad)
    pub components: Vec<(f64, f64, f64)>,
}

impl Load {
    pub fn at(&self, t: f64) -> f64 {
        self.bias + self.components.iter().map(|(a, f, p)| a * (std::f64::consts::TAU * f * t + p).sin()).sum::<f64>()
    }
}

/// The drawn scene of a case before any effect is drawn.
struct Setup {
    joint: DrawnJoint,
    traj: Trajectory,
    load: Load,
    times: Vec<f64>,
    t0: f64,
    rate: f64,
    duration: f64,
    jitter: f64,
}

/// Signals of one sweep over a list of times.
struct Series {
    kin: Vec<Kin>,
    tau: Vec<f64>,
    /// The true joint's own terms.
    base: Vec<f64>,
    /// One torque series per effect (zeros for the non-additive ones).
    deltas: Vec<Vec<f64>>,
}

/// One complete draw of effects and the clean logged signals it produces.
struct Attempt {
    effects: Vec<Effect>,
    file: ModelFile,
    series: Series,
    u_log: Vec<f64>,
    tau_log: Vec<f64>,
    kin_log: Vec<Kin>,
    residual: Vec<f64>,
    per_effect: Vec<f64>,
}

pub fn generate(rng: &mut Rng64, seed: u64, case: u64, effects: &[&'static str]) -> anyhow::Result<CaseData> {
    let mut notes = Vec::new();
    // An effect too small for every noise level its scene allows (SNR < 0.5) gives a label
    // the log cannot show: the whole scene is drawn again, at most `SCENE_REDRAWS` times
    // (`scene_that_sizes`).
    // A scene that sizes (or comes out too large) on its first draw uses no extra draws.
    let (setup, scale, mut att, sigma) = scene_that_sizes(&mut notes, || {
        let setup = draw_setup(rng, case, effects);
        let first = draw_attempt(rng, &setup, effects);
        let scale = rms(&sum_signals(&first.series));
        let (att, sigma, in_band) = size_effects(rng, &setup, effects, first, scale);
        let snr = att.per_effect.first().copied().unwrap_or(0.0) / sigma;
        ((setup, scale, att, sigma), in_band, snr)
    });
    let truth_model = &setup.joint.model;
    if effects.len() > 1 {
        att = size_second(rng, &setup, att, sigma, &mut notes);
    }
    let n = setup.times.len();
    let q_clean: Vec<f64> = att.series.kin.iter().map(|k| k.q).collect();
    let qd_clean: Vec<f64> = att.series.kin.iter().map(|k| k.qd).collect();
    let guarantees = crate::shown::check_all(&att.effects, &q_clean, &qd_clean).unwrap_or_else(|e| {
        notes.push(format!("not shown: {e}"));
        serde_json::Map::new()
    });
    let (u, tau, mut sensors) = noisy_torques(rng, &att, sigma);
    let mut log = Log::default();
    log.columns.push(("t".into(), setup.times.iter().map(|t| setup.t0 + t).collect()));
    let kin_cols =
        sensor_kinematics(rng, (seed, case), &setup, &att.kin_log, truth_model.j(), sigma, &mut sensors, &mut notes);
    log.columns.extend(kin_cols);
    log.columns.push(("u".into(), u));
    log.columns.push(("tau".into(), tau));
    if let Some(temp) = temp_column(rng, &setup, &att.effects, &mut sensors) {
        log.columns.push(("temp".into(), temp));
    }
    shuffle_columns(rng, &mut log);
    let effect_rms = rms(&att.residual);
    let snr = if sigma > 0.0 { effect_rms / sigma } else { 0.0 };
    let snr_per_effect = snr_map(&att.effects, &att.per_effect, sigma);
    let clean = Clean {
        t_rel: setup.times.clone(),
        q: att.series.kin.iter().map(|k| k.q).collect(),
        qd: att.series.kin.iter().map(|k| k.qd).collect(),
        qdd: att.series.kin.iter().map(|k| k.qdd).collect(),
        u: att.u_log.clone(),
        tau: att.tau_log.clone(),
    };
    let truth = Truth {
        seed,
        case,
        mode: Mode::Torque,
        effects: truth_names(effects),
        label: label_of(effects),
        joint: setup.joint.clone(),
        file_model: att.file.clone(),
        effect_details: att.effects.clone(),
        trajectory_family: setup.traj.shape.family().to_string(),
        trajectory: serde_json::to_value(&setup.traj)?,
        rest_phases: setup.traj.rest_phases,
        rest_share: zero_share(&clean.qd),
        rate_hz: setup.rate,
        duration_s: setup.duration,
        samples: n,
        time_jitter: setup.jitter,
        t0: setup.t0,
        external_load: serde_json::to_value(&setup.load)?,
        sensors,
        columns: log.names(),
        signal_scale: scale,
        effect_rms,
        noise_rms: sigma,
        snr,
        snr_unit: "N·m / N·m".into(),
        snr_per_effect,
        detectable_hint: !effects.is_empty() && snr >= 1.0,
        notes,
        guarantees,
    };
    Ok(CaseData { truth, log, model: att.file, clean })
}

/// Adds the u and tau noise (σ² split at random between them, each white or AR(1)).
fn noisy_torques(rng: &mut Rng64, att: &Attempt, sigma: f64) -> (Vec<f64>, Vec<f64>, serde_json::Value) {
    let n = att.u_log.len();
    let f_u = uniform(rng, 0.2, 0.8);
    let un = draw_colour(rng, sigma * f_u.sqrt());
    let tn = draw_colour(rng, sigma * (1.0 - f_u).sqrt());
    let u_noise = noise::coloured(rng, n, un);
    let tau_noise = noise::coloured(rng, n, tn);
    let u = att.u_log.iter().zip(&u_noise).map(|(a, b)| a + b).collect();
    let tau = att.tau_log.iter().zip(&tau_noise).map(|(a, b)| a + b).collect();
    let sensors = json!({
        "u_noise": un, "tau_noise": tn,
        "u_noise_lag1_estimate": noise::lag1(&u_noise), "tau_noise_lag1_estimate": noise::lag1(&tau_noise),
    });
    (u, tau, sensors)
}

fn draw_kind(rng: &mut Rng64, effects: &[&str]) -> JointKind {
    if effects.contains(&"backlash") {
        return JointKind::Elastic;
    }
    // Thermal drift scales the friction section's b, which the elastic joint lacks.
    let elastic_ok = !effects.contains(&"thermal_drift");
    let w = if elastic_ok { 0.16 } else { 0.0 };
    weighted(rng, &[(JointKind::Trunk, 0.42), (JointKind::Arm, 0.42), (JointKind::Elastic, w)])
        .unwrap_or(JointKind::Trunk)
}

fn draw_setup(rng: &mut Rng64, case: u64, effects: &[&str]) -> Setup {
    let kind = draw_kind(rng, effects);
    let coulomb = effects.iter().any(|e| {
        matches!(
            *e,
            "stribeck"
                | "asymmetric_friction"
                | "dry_friction"
                | "presliding_hysteresis"
                | "thermal_drift"
                | "load_dependent_friction"
        )
    });
    let name = format!("bench-{}-{case:04}", kind.name());
    let joint = joint::draw(rng, kind, &name, Needs { coulomb, spring: false });
    let rate = if chance(rng, 0.5) {
        pick(rng, &[100.0, 200.0, 250.0, 500.0, 1000.0, 2000.0]).unwrap_or(500.0)
    } else {
        log_uniform(rng, 100.0, 2000.0)
    };
    let duration = log_uniform(rng, 10.0, 120.0);
    // Asymmetric friction is only told from an offset where the joint rests.
    let want_rest = effects.contains(&"asymmetric_friction") || chance(rng, 0.15);
    let family = traj::draw_family(rng, want_rest);
    let lim = traj::limits_for(rng, kind.name());
    let mut traj = traj::draw(rng, family, duration, lim, want_rest);
    let jitter = if chance(rng, 0.25) { uniform(rng, 0.01, 0.15) } else { 0.0 };
    let times = sample_times(rng, rate, duration, jitter);
    // A trajectory that cannot show the effect is redrawn, family included (a short
    // point-to-point log may hold too few moves).
    for _ in 0..20 {
        if shows_effects(&mut traj, &times, effects, &joint.model) {
            break;
        }
        let family = traj::draw_family(rng, want_rest);
        traj = traj::draw(rng, family, duration, lim, want_rest);
    }
    let t0 = if chance(rng, 0.25) { (uniform(rng, 0.0, 1000.0) * 1e3).round() / 1e3 } else { 0.0 };
    let needs_load = effects.contains(&"load_dependent_friction");
    let load = draw_load(rng, kind, needs_load);
    Setup { joint, traj, load, times, t0, rate, duration, jitter }
}

/// Whether the trajectory (at the sample times) can show the effects: backlash after
/// `around_spring` places it; asymmetric friction needs motion both ways (one way only it
/// is a Coulomb level error of the file).
fn shows_effects(traj: &mut Trajectory, times: &[f64], effects: &[&str], joint: &ModelFile) -> bool {
    effects.iter().all(|e| match *e {
        "backlash" => around_spring(traj, times, joint.spring.map_or(0.0, |s| s.q0)),
        "asymmetric_friction" => {
            let qd: Vec<f64> = times.iter().map(|t| traj.eval(*t).qd).collect();
            crate::shown::reversals(&qd) >= crate::shown::MIN_REVERSALS
        }
        _ => true,
    })
}

/// Backlash lives in the spring around q0, while the trajectory is drawn on its own: shifts
/// the trajectory so q0 sits at a level it crosses, on a quantile near its median (the
/// first of 50, 45, 55 … 30, 70 % that crosses the ±20 mrad band of any zone ≥ 3 times each
/// way with ≥ 10 % of the samples on each side). Without such a level the joint stays on
/// one side or barely passes, and the dead zone is only a constant −k·lo or −k·hi there:
/// an offset / q0 error of the file. False when no level fits (the caller redraws).
fn around_spring(traj: &mut Trajectory, times: &[f64], q0: f64) -> bool {
    let q: Vec<f64> = times.iter().map(|t| traj.eval(*t).q).collect();
    for p in [0.5, 0.45, 0.55, 0.4, 0.6, 0.35, 0.65, 0.3, 0.7] {
        let shift = q0 - crate::shown::quantile(&q, p);
        let moved: Vec<f64> = q.iter().map(|x| x + shift).collect();
        if crate::shown::backlash_band_ok(&moved, q0) {
            traj.center += shift;
            return true;
        }
    }
    false
}

/// Sample times from 0, period 1/rate, optionally jittered; stamped to the microsecond so
/// the log's t is exactly the time the physics was evaluated at.
fn sample_times(rng: &mut Rng64, rate: f64, duration: f64, jitter: f64) -> Vec<f64> {
    let dt = 1.0 / rate;
    let n = (duration * rate).floor() as usize;
    (0..n)
        .map(|k| {
            let j = if k > 0 { jitter * uniform(rng, -0.5, 0.5) } else { 0.0 };
            ((k as f64 + j) * dt * 1e6).round() / 1e6
        })
        .collect()
}

fn draw_load(rng: &mut Rng64, kind: JointKind, needed: bool) -> Load {
    if !needed && chance(rng, 0.25) {
        return Load { kind: "zero", bias: 0.0, components: Vec::new() };
    }
    let (lo, hi) = match kind {
        JointKind::Trunk => (2.0, 30.0),
        JointKind::Arm | JointKind::Pendulum => (1.0, 20.0),
        JointKind::Elastic => (0.05, 1.0),
    };
    let amp = log_uniform(rng, lo, hi);
    let n = int(rng, 2, 5);
    let components = (0..n)
        .map(|_| {
            (
                amp * uniform(rng, 0.2, 1.0) / n as f64 * 2.0,
                log_uniform(rng, 0.02, 0.8),
                uniform(rng, 0.0, std::f64::consts::TAU),
            )
        })
        .collect();
    let kind_name = if kind == JointKind::Trunk { "human_torque" } else { "payload_contact" };
    Load { kind: kind_name, bias: amp * uniform(rng, -0.5, 0.5), components }
}

/// Evaluates kinematics, load, the true joint's terms and every effect's torque at `times`.
fn sweep(setup: &Setup, effects: &[Effect], times: &[f64]) -> Series {
    let truth = &setup.joint.model;
    let dahl = effects.iter().find_map(|e| match e {
        Effect::PreslidingHysteresis { sigma, c, .. } => Some((*sigma, *c)),
        _ => None,
    });
    let mut f = 0.0;
    let mut tp = T_HISTORY;
    let mut qp = setup.traj.eval(tp).q;
    let n = times.len();
    let mut s = Series {
        kin: Vec::with_capacity(n),
        tau: Vec::with_capacity(n),
        base: Vec::with_capacity(n),
        deltas: vec![Vec::with_capacity(n); effects.len()],
    };
    for &t in times {
        if let Some((sigma, c)) = dahl {
            // Sub-steps of ≤ 0.5 ms keep each travel monotone to well under a µrad.
            let m = ((t - tp) / 5e-4).ceil().max(1.0) as usize;
            for i in 1..=m {
                let ti = tp + (t - tp) * i as f64 / m as f64;
                let qi = setup.traj.eval(ti).q;
                f = dahl_step(f, qi - qp, sigma, c);
                qp = qi;
            }
            tp = t;
        }
        let k = setup.traj.eval(t);
        let tau = setup.load.at(t);
        let x = crate::effects::Ctx { t_rel: t, q: k.q, qd: k.qd, tau_ext: tau, dahl: f };
        for (d, e) in s.deltas.iter_mut().zip(effects) {
            d.push(e.delta(&x, truth));
        }
        s.base.push(truth.torque(k.q, k.qd, k.qdd));
        s.kin.push(k);
        s.tau.push(tau);
    }
    s
}

/// The true disturbance d = base + Σ effect torques.
fn sum_signals(s: &Series) -> Vec<f64> {
    let mut d = s.base.clone();
    for delta in &s.deltas {
        d.iter_mut().zip(delta).for_each(|(a, b)| *a += b);
    }
    d
}

/// Draws the effects of the case and computes the clean logged signals.
fn draw_attempt(rng: &mut Rng64, setup: &Setup, names: &[&str]) -> Attempt {
    let truth = &setup.joint.model;
    let plain = sweep(setup, &[], &setup.times);
    let q: Vec<f64> = plain.kin.iter().map(|k| k.q).collect();
    let scene = scene_of(&plain, setup, &q);
    let mut file = truth.clone();
    let mut effects = Vec::new();
    for name in names {
        match *name {
            "parameters" => {
                let (f, changes) = joint::perturb(rng, &file);
                file = f;
                effects.push(Effect::Parameters { changes });
            }
            "dry_friction" => {
                file = joint::without_coulomb(&file);
                effects.push(Effect::DryFriction { c: truth.c() });
            }
            "delay" => {
                let moving_load = !setup.load.components.is_empty();
                let signal = weighted(
                    rng,
                    &[(Delayed::U, 0.6), (Delayed::Tau, if moving_load { 0.2 } else { 0.0 }), (Delayed::Q, 0.2)],
                )
                .unwrap_or(Delayed::U);
                effects.push(Effect::Delay { signal, seconds: uniform(rng, 0.005, 0.04) });
            }
            other => {
                if let Some(e) = draw_additive(rng, other, truth, &scene) {
                    effects.push(e);
                }
            }
        }
    }
    evaluate(setup, effects, file)
}

fn scene_of<'a>(plain: &Series, setup: &Setup, q_samples: &'a [f64]) -> Scene<'a> {
    let q = plain.kin.iter().map(|k| k.q);
    let q_lo = q.clone().fold(f64::INFINITY, f64::min);
    let q_hi = q.fold(f64::NEG_INFINITY, f64::max);
    let v: Vec<f64> = plain.kin.iter().map(|k| k.qd).collect();
    Scene { torque_scale: rms(&plain.base), q_lo, q_hi, duration: setup.duration, v_rms: rms(&v), q: q_samples }
}

/// Clean logged signals for a fixed draw of effects, the residual the file's model leaves,
/// and each effect's share of it.
fn evaluate(setup: &Setup, effects: Vec<Effect>, file: ModelFile) -> Attempt {
    let series = sweep(setup, &effects, &setup.times);
    let d = sum_signals(&series);
    let mut u_log: Vec<f64> = d.iter().zip(&series.tau).map(|(a, b)| a + b).collect();
    let mut tau_log = series.tau.clone();
    let mut kin_log = series.kin.clone();
    for e in &effects {
        if let Effect::Delay { signal, seconds } = e {
            let shifted: Vec<f64> = setup.times.iter().map(|t| t - seconds).collect();
            match signal {
                Delayed::U => {
                    let s2 = sweep(setup, &effects, &shifted);
                    u_log = sum_signals(&s2).iter().zip(&s2.tau).map(|(a, b)| a + b).collect();
                }
                Delayed::Tau => tau_log = shifted.iter().map(|t| setup.load.at(*t)).collect(),
                Delayed::Q => kin_log = shifted.iter().map(|t| setup.traj.eval(*t)).collect(),
            }
        }
    }
    let residual: Vec<f64> =
        u_log.iter().zip(&tau_log).zip(&kin_log).map(|((u, t), k)| u - t - file.torque(k.q, k.qd, k.qdd)).collect();
    let per_effect = shares(&series, &effects, &file, &residual);
    Attempt { effects, file, series, u_log, tau_log, kin_log, residual, per_effect }
}

/// RMS of each effect's own part of the residual.
fn shares(s: &Series, effects: &[Effect], file: &ModelFile, residual: &[f64]) -> Vec<f64> {
    let file_gap: Vec<f64> = s.base.iter().zip(&s.kin).map(|(b, k)| b - file.torque(k.q, k.qd, k.qdd)).collect();
    let mut rest = residual.to_vec();
    for (e, d) in effects.iter().zip(&s.deltas) {
        if !matches!(e, Effect::Delay { .. }) {
            let part = if matches!(e, Effect::Parameters { .. } | Effect::DryFriction { .. }) { &file_gap } else { d };
            rest.iter_mut().zip(part).for_each(|(r, p)| *r -= p);
        }
    }
    effects
        .iter()
        .zip(&s.deltas)
        .map(|(e, d)| match e {
            Effect::Parameters { .. } | Effect::DryFriction { .. } => rms(&file_gap),
            Effect::Delay { .. } => rms(&rest),
            _ => rms(d),
        })
        .collect()
}

/// Noise relative to the torque scale that a real joint log plausibly has.
const NOISE_REL: (f64, f64) = (0.001, 0.15);

/// Picks the noise so the (first) effect's RMS is 0.5–5× it, redrawing the effect when no
/// noise level in the plausible band allows that. Returns the attempt, σ and whether it
/// sized into that band (false: the last draw with σ as close to RMS / 2 as the band
/// allows; the caller notes it).
fn size_effects(rng: &mut Rng64, setup: &Setup, names: &[&str], first: Attempt, scale: f64) -> (Attempt, f64, bool) {
    if names.is_empty() {
        let sigma = log_uniform(rng, 0.002, 0.05) * scale;
        return (first, sigma, true);
    }
    let mut att = first;
    for attempt in 0..16 {
        let r = att.per_effect.first().copied().unwrap_or(0.0);
        let lo = 0.5f64.max(r / (NOISE_REL.1 * scale));
        let hi = 5.0f64.min(r / (NOISE_REL.0 * scale));
        if lo <= hi && r > 0.0 {
            let snr = log_uniform(rng, lo, hi);
            return (att, r / snr, true);
        }
        if attempt == 15 {
            // Out of the band whatever the draw: the caller keeps it (or redraws the scene).
            return (att, (r / 2.0).clamp(NOISE_REL.0 * scale, NOISE_REL.1 * scale), false);
        }
        att = draw_attempt(rng, setup, names);
    }
    (att, NOISE_REL.1 * scale, false)
}

/// Scales the second effect of a compound so its own SNR is drawn in 0.5–5 too.
fn size_second(rng: &mut Rng64, setup: &Setup, att: Attempt, sigma: f64, notes: &mut Vec<String>) -> Attempt {
    let r2 = att.per_effect.get(1).copied().unwrap_or(0.0);
    if r2 <= 0.0 {
        return att;
    }
    let target = log_uniform(rng, 0.5, 5.0);
    let (k_lo, k_hi) = att.effects.get(1).map_or((1.0, 1.0), |e| e.scale_bounds(setup.joint.model.c()));
    let k = (target * sigma / r2).clamp(k_lo, k_hi.max(k_lo));
    let mut effects = att.effects.clone();
    if let Some(e) = effects.get_mut(1) {
        *e = e.scaled(k);
    }
    notes.push(format!("second effect scaled by {k:.3} towards SNR {target:.2}"));
    evaluate(setup, effects, att.file)
}

fn draw_colour(rng: &mut Rng64, sigma: f64) -> TorqueNoise {
    let rho = if chance(rng, 0.5) { 0.0 } else { uniform(rng, 0.3, 0.9) };
    TorqueNoise { sigma, rho }
}

/// q, and optionally qd and qdd, through the encoder and the logger's processing.
#[allow(clippy::too_many_arguments)]
fn sensor_kinematics(
    rng: &mut Rng64,
    (seed, case): (u64, u64),
    setup: &Setup,
    kin: &[Kin],
    j: f64,
    sigma: f64,
    sensors: &mut serde_json::Value,
    notes: &mut Vec<String>,
) -> Vec<(String, Vec<f64>)> {
    let tau = std::f64::consts::TAU;
    let step =
        pick(rng, &[tau / (4096.0 * 160.0), tau / (4096.0 * 100.0), tau / 131072.0, tau / 16384.0, tau / 4096.0])
            .unwrap_or(0.0);
    let q_white = if chance(rng, 0.4) { log_uniform(rng, 1e-6, 2e-4) } else { 0.0 };
    let q: Vec<f64> = kin.iter().map(|k| noise::quantise(k.q + q_white * crate::rngs::normal(rng), step)).collect();
    let mut cols = vec![("q".to_string(), q.clone())];
    let v_true: Vec<f64> = kin.iter().map(|k| k.qd).collect();
    let a_true: Vec<f64> = kin.iter().map(|k| k.qdd).collect();
    let v_rms = rms(&v_true).max(1e-3);
    let qd_mode = weighted(rng, &[("absent", 0.35), ("clean", 0.2), ("white", 0.45)]).unwrap_or("absent");
    let qd_sigma = if qd_mode == "white" { v_rms * log_uniform(rng, 0.001, 0.02) } else { 0.0 };
    let qd: Vec<f64> = v_true.iter().map(|v| v + qd_sigma * crate::rngs::normal(rng)).collect();
    // A drive's logged velocity is seldom white: an observer's noise is coloured (most of its
    // power under the motion's band) and a low-pass on it makes it late by a fraction of a
    // sample or more. Drawn from a stream of their own, so every other draw of a case keeps
    // its value.
    let (qd, drive) =
        drive_velocity(&mut crate::rngs::stream(seed, case, 0xD71E), qd_mode, qd, &v_true, qd_sigma, &setup.times);
    if qd_mode != "absent" {
        cols.push(("qd".to_string(), qd.clone()));
    }
    let qdd_mode = weighted(rng, &[("absent", 0.6), ("white", 0.2), ("filtered", 0.2)]).unwrap_or("absent");
    let (qdd, qdd_info) = match qdd_mode {
        "white" => {
            // J·σ_qdd at most the torque noise: a worse accelerometer would not be logged.
            let s = (rms(&a_true) * log_uniform(rng, 0.002, 0.05)).min(sigma / j.max(1e-9));
            (Some(a_true.iter().map(|a| a + s * crate::rngs::normal(rng)).collect::<Vec<f64>>()), json!({"white": s}))
        }
        "filtered" => filtered_qdd(setup, &q, &qd, qd_mode != "absent", &a_true, j, sigma, notes),
        _ => (None, json!("absent")),
    };
    if let Some(a) = qdd {
        cols.push(("qdd".to_string(), a));
    }
    if let Some(obj) = sensors.as_object_mut() {
        obj.insert("q_step".into(), json!(step));
        obj.insert("q_white".into(), json!(q_white));
        obj.insert("qd".into(), drive.unwrap_or_else(|| json!({"mode": qd_mode, "sigma": qd_sigma})));
        obj.insert("qdd".into(), qdd_info);
    }
    cols
}

/// A noisy logged velocity as a drive gives it: half the time the white noise as drawn, else an
/// AR(1) noise of the same size (ρ 0.8–0.98), or the white column through a causal first-order
/// low-pass at 10–100 Hz (the discrete filter's lag at low frequency is `(1 − α)/α` samples).
/// The column and what the truth says of it; `None`: unchanged.
fn drive_velocity(
    side: &mut Rng64,
    qd_mode: &str,
    qd: Vec<f64>,
    v_true: &[f64],
    sigma: f64,
    times: &[f64],
) -> (Vec<f64>, Option<serde_json::Value>) {
    if qd_mode != "white" || qd.len() < 2 {
        return (qd, None);
    }
    match weighted(side, &[("white", 0.5), ("ar1", 0.3), ("lowpass", 0.2)]).unwrap_or("white") {
        "ar1" => {
            let rho = uniform(side, 0.8, 0.98);
            let e = noise::ar1(side, v_true.len(), sigma, rho);
            let col = v_true.iter().zip(&e).map(|(v, e)| v + e).collect();
            (col, Some(json!({"mode": "ar1", "sigma": sigma, "rho": rho})))
        }
        "lowpass" => {
            let fc = log_uniform(side, 10.0, 100.0);
            let col = noise::causal_lowpass(times, &qd, fc);
            let dt = match (times.first(), times.last()) {
                (Some(a), Some(b)) => (b - a) / (times.len() - 1).max(1) as f64,
                _ => 0.0,
            };
            let alpha = 1.0 - (-std::f64::consts::TAU * fc * dt).exp();
            let lag_ms = 1e3 * dt * (1.0 - alpha) / alpha.max(1e-12);
            (col, Some(json!({"mode": "lowpass", "sigma": sigma, "cutoff_hz": fc, "lag_ms": lag_ms})))
        }
        _ => (qd, None),
    }
}

/// A logger's acceleration: differentiate the logged velocity (or q twice), then a
/// zero-phase low-pass. The cutoff is raised until J·(error) is under half the torque
/// noise, so the column does not itself become an unmodelled effect; else it is dropped.
#[allow(clippy::too_many_arguments)]
fn filtered_qdd(
    setup: &Setup,
    q: &[f64],
    qd: &[f64],
    has_qd: bool,
    a_true: &[f64],
    j: f64,
    sigma: f64,
    notes: &mut Vec<String>,
) -> (Option<Vec<f64>>, serde_json::Value) {
    let t = &setup.times;
    let v = if has_qd { qd.to_vec() } else { noise::derivative(t, q) };
    let raw = noise::derivative(t, &v);
    let mut fc = (10.0 * setup.traj.shape.f_max()).max(5.0);
    while fc <= 0.2 * setup.rate {
        let a = noise::zero_phase(t, &raw, fc);
        let err: Vec<f64> = a.iter().zip(a_true).map(|(x, y)| j * (x - y)).collect();
        let e = rms(&err);
        if e <= 0.5 * sigma {
            return (
                Some(a),
                json!({"filtered": {"cutoff_hz": fc, "source": if has_qd {"qd"} else {"q"}, "torque_error_rms": e}}),
            );
        }
        fc *= 1.5;
    }
    notes.push("filtered qdd dropped: no cutoff kept J·error under half the torque noise".into());
    (None, json!("absent"))
}

/// The temp column: the thermal effect's temperature when it is logged, otherwise
/// sometimes an unrelated slow warm-up, so the column's presence tells nothing.
fn temp_column(
    rng: &mut Rng64,
    setup: &Setup,
    effects: &[Effect],
    sensors: &mut serde_json::Value,
) -> Option<Vec<f64>> {
    let thermal = effects.iter().find(|e| matches!(e, Effect::ThermalDrift { .. }));
    let (temp0, profile): (f64, Box<dyn Fn(f64) -> f64>) = match thermal {
        Some(e @ Effect::ThermalDrift { temp0, temp_logged, .. }) => {
            if !temp_logged {
                return None;
            }
            let e = e.clone();
            (*temp0, Box::new(move |t| e.temp_rise(t)))
        }
        _ => {
            if !chance(rng, 0.25) {
                return None;
            }
            let rise = uniform(rng, 0.0, 5.0);
            let tau_th = uniform(rng, 0.3, 2.0) * setup.duration;
            (uniform(rng, 18.0, 35.0), Box::new(move |t: f64| rise * (1.0 - (-t / tau_th).exp())))
        }
    };
    let res = 0.1;
    let temp: Vec<f64> = setup
        .times
        .iter()
        .map(|t| noise::quantise(temp0 + profile(*t) + 0.05 * crate::rngs::normal(rng), res))
        .collect();
    if let Some(obj) = sensors.as_object_mut() {
        obj.insert("temp".into(), json!({"resolution": res, "white": 0.05, "drives_effect": thermal.is_some()}));
    }
    Some(temp)
}

/// Column order is free (spec §1): a fifth of the logs put them in a random order.
fn shuffle_columns(rng: &mut Rng64, log: &mut Log) {
    if chance(rng, 0.2) {
        use rand::seq::SliceRandom;
        log.columns.shuffle(rng);
    }
}
