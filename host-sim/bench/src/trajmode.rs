//! Trajectory-mode cases: free (or known-input) responses of an elastic joint or a
//! pendulum-like arm joint, integrated by `integrate`, logged as t, q and optionally qd / u.

use serde_json::json;

use crate::case::{label_of, scene_that_sizes, snr_map, truth_names, zero_share, CaseData, Clean, Log, Mode, Truth};
use crate::effects::{draw_additive, Delayed, Effect, Scene};
use crate::integrate::{simulate, Dynamics, Input, State};
use crate::joint::{self, DrawnJoint, JointKind, Needs};
use crate::model::ModelFile;
use crate::noise::{self, rms};
use crate::rngs::{chance, int, log_uniform, normal, pick, sign, uniform, weighted, Rng64};

/// Sub-steps per sample interval at least (the brief asks for ≥ 10).
const MIN_SUB: usize = 12;

/// The drawn scene before any effect.
struct Setup {
    joint: DrawnJoint,
    times: Vec<f64>,
    rate: f64,
    /// Release time (≤ 0: before the first sample when the log was cut).
    t_release: f64,
    y_release: State,
    input: Input,
    q_eq: f64,
    t0: f64,
    jitter: f64,
}

/// One draw of effects with both responses.
struct Attempt {
    effects: Vec<Effect>,
    file: ModelFile,
    truth: Vec<State>,
    deviation: Vec<f64>,
    per_effect: Vec<f64>,
    shift: f64,
}

pub fn generate(rng: &mut Rng64, seed: u64, case: u64, effects: &[&'static str]) -> anyhow::Result<CaseData> {
    let mut notes = Vec::new();
    // An effect too small for every noise level its scene allows (SNR < 0.5) gives a label
    // the log cannot show: the whole scene is drawn again, at most `SCENE_REDRAWS` times
    // (`scene_that_sizes`).
    // A scene that sizes (or comes out too large) on its first draw uses no extra draws.
    let (setup, scale, mut att, sigma) = scene_that_sizes(&mut notes, || {
        let setup = draw_scene(rng, case, effects);
        let plain = simulate_truth(&setup, &[]);
        let scale = swing(&setup, &plain);
        let (att, sigma, in_band) = size(rng, &setup, effects, scale);
        let snr = att.per_effect.first().copied().unwrap_or(0.0) / sigma;
        ((setup, scale, att, sigma), in_band, snr)
    });
    if effects.len() > 1 {
        att = size_second(rng, &setup, att, sigma, &mut notes);
    }
    let n = setup.times.len();
    let guarantees = shown_by(&att).unwrap_or_else(|e| {
        notes.push(format!("not shown: {e}"));
        serde_json::Map::new()
    });
    let (step, white) = encoder_for(rng, sigma);
    let q: Vec<f64> = att.truth.iter().map(|y| noise::quantise(y.q + white * normal(rng), step)).collect();
    let mut log = Log::default();
    log.columns.push(("t".into(), setup.times.iter().map(|t| setup.t0 + t).collect()));
    log.columns.push(("q".into(), q));
    let qd_info = qd_column(rng, &setup, effects, &att, &mut log);
    let u_true: Vec<f64> = setup.times.iter().map(|t| setup.input.at(*t)).collect();
    let u_logged: Vec<f64> = setup.times.iter().map(|t| setup.input.at(t - att.shift)).collect();
    let u_info = if setup.input.kind != "none" {
        let su = if chance(rng, 0.5) { 0.0 } else { rms(&u_true) * log_uniform(rng, 1e-4, 3e-3) };
        log.columns.push(("u".into(), u_logged.iter().map(|u| u + su * normal(rng)).collect()));
        json!({"white": su})
    } else {
        json!("absent")
    };
    let effect_rms = rms(&att.deviation);
    let snr = effect_rms / sigma;
    let snr_per_effect = snr_map(&att.effects, &att.per_effect, sigma);
    let clean = Clean {
        t_rel: setup.times.clone(),
        q: att.truth.iter().map(|y| y.q).collect(),
        qd: att.truth.iter().map(|y| y.v).collect(),
        qdd: Vec::new(),
        u: u_logged,
        tau: Vec::new(),
    };
    let truth = Truth {
        seed,
        case,
        mode: Mode::Trajectory,
        effects: truth_names(effects),
        label: label_of(effects),
        joint: setup.joint.clone(),
        file_model: att.file.clone(),
        effect_details: att.effects.clone(),
        trajectory_family: response_family(&setup),
        trajectory: json!({
            "t_release": setup.t_release, "q_release": setup.y_release.q, "v_release": setup.y_release.v,
            "q_equilibrium": setup.q_eq, "input": setup.input,
        }),
        rest_phases: clean.qd.contains(&0.0),
        rest_share: zero_share(&clean.qd),
        rate_hz: setup.rate,
        duration_s: setup.times.last().copied().unwrap_or(0.0),
        samples: n,
        time_jitter: setup.jitter,
        t0: setup.t0,
        external_load: json!("none"),
        sensors: json!({"q_step": step, "q_white": white, "qd": qd_info, "u": u_info}),
        columns: log.names(),
        signal_scale: scale,
        effect_rms,
        noise_rms: sigma,
        snr,
        snr_unit: "rad / rad".into(),
        snr_per_effect,
        detectable_hint: !effects.is_empty() && snr >= 1.0,
        notes,
        guarantees,
    };
    Ok(CaseData { truth, log, model: att.file, clean })
}

/// The scene before any effect: a setup whose effect-free response moves. A joint that
/// never leaves its release angle (stuck pendulum) says nothing, and one that never shows
/// what the effect needs (see `moves_enough`) mislabels it: redraw.
fn draw_scene(rng: &mut Rng64, case: u64, effects: &[&str]) -> Setup {
    let mut setup = draw_setup(rng, case, effects);
    let tries = if effects.iter().any(|e| needs_motion(e)) { 40 } else { 10 };
    for _ in 0..tries {
        let plain = simulate_truth(&setup, &[]);
        if swing(&setup, &plain) > 2e-3 && moves_enough(&setup, &plain, effects) {
            break;
        }
        setup = draw_setup(rng, case, effects);
    }
    setup
}

/// Families whose label needs the response itself to move a certain way.
fn needs_motion(name: &str) -> bool {
    matches!(name, "backlash" | "asymmetric_friction")
}

/// The effect-free response already shows what the effect needs: backlash lives around the
/// spring's q0, so the joint must cross the band of any zone there repeatedly, with samples
/// on both sides; asymmetric friction needs motion both ways (one way only it is a Coulomb
/// level error of the file).
fn moves_enough(s: &Setup, plain: &[State], effects: &[&str]) -> bool {
    let q: Vec<f64> = plain.iter().map(|y| y.q).collect();
    let v: Vec<f64> = plain.iter().map(|y| y.v).collect();
    effects.iter().all(|e| match *e {
        "backlash" => crate::shown::backlash_band_ok(&q, s.joint.model.spring.map_or(s.q_eq, |sp| sp.q0)),
        "asymmetric_friction" => crate::shown::reversals(&v) >= crate::shown::MIN_REVERSALS,
        _ => true,
    })
}

/// What the true response shows of the drawn effects (see `shown`).
fn shown_by(att: &Attempt) -> Result<serde_json::Map<String, serde_json::Value>, String> {
    let q: Vec<f64> = att.truth.iter().map(|y| y.q).collect();
    let v: Vec<f64> = att.truth.iter().map(|y| y.v).collect();
    crate::shown::check_all(&att.effects, &q, &v)
}

fn response_family(s: &Setup) -> String {
    let base = if s.input.kind != "none" {
        format!("input_{}", s.input.kind)
    } else if s.y_release.v != 0.0 {
        "free_pushed".to_string()
    } else {
        "free_release".to_string()
    };
    if s.times.len() <= 60 {
        format!("{base}_short")
    } else {
        base
    }
}

fn draw_setup(rng: &mut Rng64, case: u64, effects: &[&str]) -> Setup {
    let kind =
        if effects.contains(&"backlash") || chance(rng, 0.55) { JointKind::Elastic } else { JointKind::Pendulum };
    let coulomb = effects
        .iter()
        .any(|e| matches!(*e, "stribeck" | "asymmetric_friction" | "dry_friction" | "presliding_hysteresis"));
    let name = format!("bench-{}-{case:04}", kind.name());
    let joint = joint::draw(rng, kind, &name, Needs { coulomb, spring: kind == JointKind::Elastic });
    let m = &joint.model;
    let q_eq = match (m.spring, m.weight) {
        (Some(s), _) => s.q0,
        (None, Some(w)) => -w.phi / w.s,
        _ => 0.0,
    };
    let stiff = m.spring.map_or(0.0, |s| s.k) + m.weight.map_or(0.0, |w| w.amplitude * w.s);
    let omega = (stiff / m.j().max(1e-9)).sqrt();
    let period = std::f64::consts::TAU / omega.max(1e-3);
    let rate = if chance(rng, 0.5) {
        pick(rng, &[50.0, 100.0, 200.0, 500.0, 1000.0]).unwrap_or(100.0)
    } else {
        log_uniform(rng, 50.0, 1000.0)
    };
    let n = if chance(rng, 0.25) {
        int(rng, 20, 60)
    } else {
        let periods = uniform(rng, 3.0, 25.0);
        ((periods * period * rate) as usize).clamp(61, 5000)
    };
    let jitter = if chance(rng, 0.15) { uniform(rng, 0.01, 0.1) } else { 0.0 };
    let times: Vec<f64> = (0..n)
        .map(|k| {
            let j = if k > 0 { jitter * uniform(rng, -0.5, 0.5) } else { 0.0 };
            ((k as f64 + j) / rate * 1e6).round() / 1e6
        })
        .collect();
    let amp = if kind == JointKind::Elastic { uniform(rng, 0.05, 0.5) } else { uniform(rng, 0.2, 1.2) };
    let q_rel = (q_eq + sign(rng) * amp).clamp(-1.5, 1.5);
    let pushed = effects.is_empty() && chance(rng, 0.2);
    let v0 = if pushed { sign(rng) * uniform(rng, 0.2, 1.0) * amp * omega } else { 0.0 };
    let (t_release, v_release, input) = if effects.contains(&"initial_state") {
        if chance(rng, 0.6) {
            (-uniform(rng, 0.1, 0.6) * period, 0.0, Input::zero())
        } else {
            (0.0, sign(rng) * uniform(rng, 0.2, 1.0) * amp * omega, Input::zero())
        }
    } else {
        let want_input = effects.contains(&"delay") || chance(rng, 0.35);
        (
            0.0,
            v0,
            if want_input { draw_input(rng, m, stiff, times.last().copied().unwrap_or(1.0)) } else { Input::zero() },
        )
    };
    let t0 = if chance(rng, 0.2) { (uniform(rng, 0.0, 500.0) * 1e3).round() / 1e3 } else { 0.0 };
    Setup {
        joint,
        times,
        rate,
        t_release,
        y_release: State { q: q_rel, v: v_release, f: 0.0 },
        input,
        q_eq,
        t0,
        jitter,
    }
}

/// A known input: a smooth step, a pulse, or a smooth random torque, sized like the
/// restoring torque of a 0.05–0.3 rad deflection.
fn draw_input(rng: &mut Rng64, m: &ModelFile, stiff: f64, t_end: f64) -> Input {
    let level = sign(rng) * uniform(rng, 0.05, 0.3) * stiff + m.c() * sign(rng);
    let t_on = uniform(rng, 0.05, 0.3) * t_end;
    let ramp = uniform(rng, 0.01, 0.08);
    match pick(rng, &[0u8, 1, 2]).unwrap_or(0) {
        0 => Input { kind: "step", t_on, ramp, level, t_off: f64::INFINITY, components: Vec::new() },
        1 => Input {
            kind: "pulse",
            t_on,
            ramp,
            level,
            t_off: t_on + uniform(rng, 0.1, 0.5) * t_end,
            components: Vec::new(),
        },
        _ => {
            let comps = (0..int(rng, 2, 4))
                .map(|_| {
                    (
                        level * uniform(rng, 0.3, 1.0),
                        log_uniform(rng, 0.2, 3.0),
                        uniform(rng, 0.0, std::f64::consts::TAU),
                    )
                })
                .collect();
            Input { kind: "smooth_random", t_on, ramp, level: 0.0, t_off: f64::INFINITY, components: comps }
        }
    }
}

fn span_of(s: &Setup) -> f64 {
    (s.y_release.q - s.q_eq).abs() * 2.0 + 0.1
}

fn simulate_truth(s: &Setup, effects: &[Effect]) -> Vec<State> {
    let dy = Dynamics::new(&s.joint.model, effects, s.input.clone(), 0.0);
    simulate(&dy, s.t_release, s.y_release, &s.times, MIN_SUB, span_of(s))
}

/// Peak-to-peak of the response: the angle scale noise is sized against.
fn swing(_s: &Setup, ys: &[State]) -> f64 {
    let lo = ys.iter().map(|y| y.q).fold(f64::INFINITY, f64::min);
    let hi = ys.iter().map(|y| y.q).fold(f64::NEG_INFINITY, f64::max);
    (hi - lo).max(0.0)
}

fn draw_attempt(rng: &mut Rng64, s: &Setup, names: &[&str], plain: &[State]) -> Attempt {
    let truth_m = &s.joint.model;
    let q_lo = plain.iter().map(|y| y.q).fold(f64::INFINITY, f64::min);
    let q_hi = plain.iter().map(|y| y.q).fold(f64::NEG_INFINITY, f64::max);
    let stiff = truth_m.spring.map_or(0.0, |sp| sp.k) + truth_m.weight.map_or(0.0, |w| w.amplitude * w.s);
    let q: Vec<f64> = plain.iter().map(|y| y.q).collect();
    let scene =
        Scene { torque_scale: stiff * (q_hi - q_lo).max(1e-3) / 2.0, q_lo, q_hi, duration: 1.0, v_rms: 0.0, q: &q };
    let mut file = truth_m.clone();
    let mut effects = Vec::new();
    let mut shift = 0.0;
    for name in names {
        match *name {
            "parameters" => {
                let (f, changes) = joint::perturb(rng, &file);
                file = f;
                effects.push(Effect::Parameters { changes });
            }
            "dry_friction" => {
                file = joint::without_coulomb(&file);
                effects.push(Effect::DryFriction { c: truth_m.c() });
            }
            "delay" => {
                shift = uniform(rng, 0.005, 0.04);
                effects.push(Effect::Delay { signal: Delayed::U, seconds: shift });
            }
            "initial_state" => {
                let variant = if s.t_release < 0.0 { "cut_mid_swing" } else { "pushed" };
                let detail = if s.t_release < 0.0 { -s.t_release } else { s.y_release.v };
                effects.push(Effect::InitialState { variant: variant.into(), detail });
            }
            other => {
                if let Some(e) = draw_additive(rng, other, truth_m, &scene) {
                    effects.push(e);
                }
            }
        }
    }
    evaluate(s, effects, file, shift)
}

/// Integrates the truth and the file's model (from the state the tool is meant to assume)
/// and measures how far apart they are at the samples.
fn evaluate(s: &Setup, effects: Vec<Effect>, file: ModelFile, shift: f64) -> Attempt {
    let truth = simulate_truth(s, &effects);
    let first = truth.first().copied().unwrap_or_default();
    let initial = effects.iter().any(|e| matches!(e, Effect::InitialState { .. }));
    // The file's model starts where the log starts; with initial_state the tool can only
    // assume rest at the first logged angle.
    let y0 = if initial { State { q: first.q, v: 0.0, f: 0.0 } } else { State { f: 0.0, ..first } };
    let t_first = s.times.first().copied().unwrap_or(0.0);
    let dy = Dynamics::new(&file, &[], s.input.clone(), shift);
    let model = simulate(&dy, t_first, y0, &s.times, MIN_SUB, span_of(s));
    let deviation: Vec<f64> = truth.iter().zip(&model).map(|(a, b)| a.q - b.q).collect();
    let per_effect = effects
        .iter()
        .map(|e| {
            if effects.len() == 1 {
                return rms(&deviation);
            }
            // In a compound, an effect's share is the deviation it causes on its own.
            let alone = simulate_truth(s, std::slice::from_ref(e));
            rms(&alone.iter().zip(&model).map(|(a, b)| a.q - b.q).collect::<Vec<f64>>())
        })
        .collect();
    Attempt { effects, file, truth, deviation, per_effect, shift }
}

/// Angle noise band relative to the swing, with the finest encoder's floor.
fn noise_band(scale: f64) -> (f64, f64) {
    let floor = std::f64::consts::TAU / 131072.0 / 12f64.sqrt();
    ((1e-4 * scale).max(floor), (0.03 * scale).max(2.0 * floor))
}

/// Draws the effects (up to 12 times) and the noise σ so the first effect's RMS is 0.5–5×
/// σ with σ in `noise_band`. Returns the attempt, σ and whether it sized into that band
/// (false: the last draw with σ as close to RMS / 2 as the band allows; the caller notes it).
fn size(rng: &mut Rng64, s: &Setup, names: &[&str], scale: f64) -> (Attempt, f64, bool) {
    let plain = simulate_truth(s, &[]);
    let (lo_n, hi_n) = noise_band(scale);
    let mut att = draw_attempt(rng, s, names, &plain);
    if names.is_empty() {
        let sigma = (log_uniform(rng, 3e-4, 0.01) * scale).clamp(lo_n, hi_n);
        return (att, sigma, true);
    }
    for attempt in 0..12 {
        let r = att.per_effect.first().copied().unwrap_or(0.0);
        let lo = 0.5f64.max(r / hi_n);
        let hi = 5.0f64.min(r / lo_n);
        // The effect must show on the true response too (the effect-free one placed it).
        if lo <= hi && r > 0.0 && shown_by(&att).is_ok() {
            let snr = log_uniform(rng, lo, hi);
            return (att, r / snr, true);
        }
        if attempt == 11 {
            return (att, (r / 2.0).clamp(lo_n, hi_n), false);
        }
        att = draw_attempt(rng, s, names, &plain);
    }
    (att, hi_n, false)
}

/// Steps of the search for the second effect's scale (each re-simulates the attempt).
const SECOND_STEPS: usize = 6;

/// In a compound the noise is sized on the first effect; the second is then scaled (within
/// its family's range, `Effect::scale_bounds`) so its own SNR, the RMS of the deviation it
/// causes alone over σ (as `evaluate` records it in `per_effect`), lands near a target
/// drawn log-uniformly in 0.5–5. The response is not linear, nor always monotone, in the
/// effect's size (sticking, a changed swing), so k is refined by re-simulating, and the draw
/// closest to the target that still shows every effect (`shown_by`) is kept, the unscaled
/// one included. The one random draw is the target, made on this compound path only, after
/// every draw of `size`.
fn size_second(rng: &mut Rng64, s: &Setup, att: Attempt, sigma: f64, notes: &mut Vec<String>) -> Attempt {
    let (Some(second), Some(&r0)) = (att.effects.get(1).cloned(), att.per_effect.get(1)) else {
        return att;
    };
    let target = log_uniform(rng, 0.5, 5.0);
    let name = second.name();
    if !(r0 > 0.0 && sigma > 0.0) {
        notes.push(format!("second effect not sized: {name} causes no deviation on its own"));
        return att;
    }
    let (k_lo, k_hi) = second.scale_bounds(s.joint.model.c());
    let k_hi = k_hi.max(k_lo);
    let miss = |r: f64| if r > 0.0 { (r / sigma / target).ln().abs() } else { f64::INFINITY };
    // The scaled draw closest to the target so far (None: the unscaled one, when shown).
    let mut best: Option<(f64, Attempt)> = None;
    let mut best_miss = if shown_by(&att).is_ok() { miss(r0) } else { f64::INFINITY };
    let (mut tried, mut unshown, mut at_end) = (0, 0, false);
    let (mut k, mut r) = (1.0, r0);
    for _ in 0..SECOND_STEPS {
        let next = (k * target * sigma / r).clamp(k_lo, k_hi);
        if (next - k).abs() <= 1e-6 * k {
            break;
        }
        k = next;
        at_end |= k <= k_lo || k >= k_hi;
        let mut effects = att.effects.clone();
        if let Some(e) = effects.get_mut(1) {
            *e = e.scaled(k);
        }
        let cand = evaluate(s, effects, att.file.clone(), att.shift);
        r = cand.per_effect.get(1).copied().unwrap_or(0.0);
        tried += 1;
        if shown_by(&cand).is_err() {
            unshown += 1;
        } else if miss(r) < best_miss {
            best_miss = miss(r);
            best = Some((k, cand));
        }
        if r <= 0.0 || miss(r) < 0.05 {
            break;
        }
    }
    let (k, out, kept) = match best {
        Some((k, scaled)) => (k, scaled, "scaled"),
        None => (1.0, att, "kept unscaled"),
    };
    let snr = out.per_effect.get(1).copied().unwrap_or(0.0) / sigma;
    notes.push(format!("second effect {kept} (k = {k:.3}) towards SNR {target:.2}: SNR {snr:.3}"));
    if !(0.5..=5.0).contains(&snr) {
        let why = if tried > 0 && unshown == tried {
            "not shown after scaling"
        } else if at_end {
            "bounded by its range"
        } else {
            "response not proportional to its size"
        };
        notes.push(format!("second effect not sized: {name} {why}, SNR {snr:.3} outside 0.5–5"));
    }
    out
}

/// An encoder step and white noise whose combined RMS is σ: a coarse encoder when σ
/// allows it (like the elastic-joint paper's magnetic one), else a finer one plus noise.
fn encoder_for(rng: &mut Rng64, sigma: f64) -> (f64, f64) {
    let tau = std::f64::consts::TAU;
    let steps = [tau / 4096.0, tau / 16384.0, tau / 131072.0];
    let fits: Vec<f64> = steps.iter().copied().filter(|s| s / 12f64.sqrt() <= sigma).collect();
    let step = if chance(rng, 0.5) { fits.first().copied() } else { pick(rng, &fits) }.unwrap_or(0.0);
    let white = (sigma * sigma - step * step / 12.0).max(0.0).sqrt();
    (step, white)
}

/// qd: absent when the tool must assume rest (initial_state) or sometimes for releases
/// from rest; present (clean or noisy) whenever the true start moves, so a `none` case
/// never hides its initial velocity.
fn qd_column(rng: &mut Rng64, s: &Setup, names: &[&str], att: &Attempt, log: &mut Log) -> serde_json::Value {
    if names.contains(&"initial_state") {
        return json!({"mode": "absent"});
    }
    let moving = s.y_release.v != 0.0;
    let w = if moving { 0.0 } else { 0.5 };
    let mode = weighted(rng, &[("absent", w), ("clean", 0.25), ("white", 0.25)]).unwrap_or("clean");
    if mode == "absent" {
        return json!({"mode": "absent"});
    }
    let v: Vec<f64> = att.truth.iter().map(|y| y.v).collect();
    let sd = if mode == "white" { rms(&v).max(1e-3) * log_uniform(rng, 1e-3, 2e-2) } else { 0.0 };
    log.columns.push(("qd".into(), v.iter().map(|x| x + sd * normal(rng)).collect()));
    json!({"mode": mode, "sigma": sd})
}
