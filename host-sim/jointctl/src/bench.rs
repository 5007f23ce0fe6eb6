//! `diagnose-bench`: logs whose effect is known but withheld from the model, diagnosed blind.
//!
//! Each case draws a joint (a rigid trunk-like joint; an elastic joint for backlash, which in
//! torque mode only shows in a spring; a joint without Coulomb term for dry friction), sensor
//! noise, the order and length of the scenarios, and the effect's size from ranges chosen so the
//! effect's torque is comparable to or larger than the noise (an effect far below the noise is
//! indistinguishable from `none`, and a bench full of them would measure nothing). The plant
//! file gets the effect; the model file the diagnosis sees is the same joint without it. Case
//! kinds cycle through `none`, `parameters` (the model's values off), every effect, and pairs,
//! so any `--cases` ≥ 13 covers them all. The diagnosis gets only the log and the model: it does
//! not know the case kind, the plant, or the noise.
//!
//! `--mode trajectory` draws free responses instead: an elastic joint of the elastic-joint
//! paper's size released from 0.2–0.4 rad, only angles logged, with one of the effects a free
//! response can show (see [`TRAJ_KINDS`]) or none, or its damping and stiffness off.
//!
//! Scoring: a case is correct when the set of effects the diagnosis reports (forward selection,
//! or `parameters`, or `none`) equals the withheld set. An over-claim is a `none` case reported
//! as anything else.

// Cases index fixed tables modulo their length and per-sample series built to the log's
// length, like the diagnosis kernels this bench was split from.
#![allow(clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::io::Write as _;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{simulate, SimConfig};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

/// Case kinds in the order they cycle.
pub const KINDS: [&str; 13] = [
    "none",
    "stribeck",
    "asymmetric_friction",
    "load_dependent_friction",
    "thermal_drift",
    "position_ripple",
    "cable_spring",
    "backlash",
    "delay",
    "dry_friction",
    "parameters",
    "pair",
    "none",
];

/// Case kinds of the trajectory-mode bench (free responses: no `u`/`tau` columns), in the order
/// they cycle. Effects that need an input or a load (load-dependent friction, delay) or a
/// temperature are not among them: a free response with `u = 0` carries no trace of them.
pub const TRAJ_KINDS: [&str; 9] = [
    "none",
    "stribeck",
    "asymmetric_friction",
    "position_ripple",
    "cable_spring",
    "backlash",
    "dry_friction",
    "parameters",
    "none",
];

/// Which mode the bench's logs are diagnosed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// joints driven through sweeps, holds and hand motion, with `u` and `tau` logged
    Torque,
    /// an elastic joint released from an angle, only `q`, `qd`, `qdd` logged
    Trajectory,
}

/// Effects that pairs are drawn from (each identifiable in torque mode on a rigid joint).
const PAIRABLE: [&str; 6] =
    ["stribeck", "load_dependent_friction", "position_ripple", "cable_spring", "delay", "thermal_drift"];

#[derive(Clone, Debug, Serialize)]
pub struct CaseResult {
    pub case: usize,
    pub truth: String,
    pub predicted: String,
    pub correct: bool,
    pub joint: &'static str,
    pub scenarios: String,
    /// the log's noise level: torque noise (N·m) in torque mode, angle noise (rad) in trajectory mode
    pub tau_noise: f64,
    pub effect_sections: String,
    pub holdout_rmse_before: f64,
    /// shrink of what the diagnosis selected
    pub shrink: f64,
    /// shrink of the candidate carrying the true effect's name (single-effect cases)
    pub true_shrink: Option<f64>,
    pub seconds: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub cases: Vec<CaseResult>,
    /// truth → predicted → count
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    pub accuracy: f64,
    pub none_cases: usize,
    pub overclaims: usize,
    pub overclaim_rate: f64,
    pub mean_shrink: f64,
    pub mean_true_shrink: f64,
}

struct Joint {
    name: &'static str,
    model: String,
    /// the plant's own parameters when they differ from the model's (`parameters` cases)
    plant_model: Option<String>,
    range: (f64, f64),
}

fn rigid(rng: &mut ChaCha8Rng, coulomb: bool) -> Joint {
    let a = rng.random_range(0.3..1.0);
    let b = rng.random_range(1.5..3.0);
    let c = if coulomb { rng.random_range(0.6..1.4) } else { 0.0 };
    let amp = rng.random_range(1.5..3.0);
    let phi = rng.random_range(-0.1..0.1);
    let j = rng.random_range(0.3..0.6);
    let c0 = rng.random_range(-0.5..0.5);
    // The simulated plant smooths its friction sign over 0.01 rad/s (its default band): a model
    // that is exact says so (spec §2: without `v_band` a file means the pure sign).
    let mut m = format!("[friction]\na = {a}\nb = {b}\nv_band = 0.01\n");
    if coulomb {
        m += &format!("c = {c}\n");
    }
    m += &format!(
        "\n[weight]\namplitude = {amp}\ns = 0.802\nphi = {phi}\n\n[inertia]\nj = {j}\n\n[offset]\nc0 = {c0}\n"
    );
    Joint { name: if coulomb { "rigid" } else { "rigid_no_coulomb" }, model: m, plant_model: None, range: (0.0, 2.0) }
}

fn elastic(rng: &mut ChaCha8Rng) -> Joint {
    let k = rng.random_range(6.0..12.0);
    let kb = rng.random_range(0.03..0.08);
    let j = rng.random_range(0.15..0.3);
    let b = rng.random_range(0.3..0.8);
    let c = rng.random_range(0.2..0.5);
    let m = format!(
        "[friction]\nb = {b}\nc = {c}\nv_band = 0.01\n\n[inertia]\nj = {j}\n\n[spring]\nk = {k}\nb = {kb}\nq0 = 0.0\n\n[offset]\nc0 = 0.1\n"
    );
    Joint { name: "elastic", model: m, plant_model: None, range: (-0.5, 0.5) }
}

/// The plant section of one effect with a drawn size.
fn effect_section(kind: &str, rng: &mut ChaCha8Rng, range: (f64, f64), rate: f64) -> String {
    match kind {
        "stribeck" => {
            format!("[stribeck]\nlevel = {}\nspeed = {}\n", rng.random_range(0.5..1.2), rng.random_range(0.02..0.08))
        }
        "asymmetric_friction" => {
            let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            format!("[asymmetric_friction]\ndelta = {}\n", s * rng.random_range(0.25..0.6))
        }
        "load_dependent_friction" => format!("[load_dependent_friction]\nmu = {}\n", rng.random_range(0.06..0.15)),
        "thermal_drift" => format!(
            "[thermal_drift]\ncoefficient = {}\nt_ambient = 25.0\nrise = {}\ntime_constant = {}\nt_ref = 25.0\n",
            rng.random_range(0.008..0.02),
            rng.random_range(20.0..30.0),
            rng.random_range(5.0..15.0)
        ),
        "position_ripple" => format!(
            "[position_ripple]\namplitude = {}\nperiod = {}\nphase = {}\n",
            rng.random_range(0.2..0.5),
            rng.random_range(0.02..0.1),
            rng.random_range(-3.0..3.0)
        ),
        "cable_spring" => {
            let e = range.0 + (range.1 - range.0) * rng.random_range(0.45..0.7);
            format!("[cable_spring]\nk = {}\nengage = {e}\n", rng.random_range(3.0..8.0))
        }
        "backlash" => format!("[backlash]\nwidth = {}\n", rng.random_range(0.03..0.08)),
        "delay" => {
            // whole control ticks, 4…12 ms
            let ticks = rng.random_range(4..=12) as f64;
            format!("[delay]\nseconds = {}\n", ticks / rate)
        }
        "dry_friction" => format!("[dry_friction]\nc = {}\n", rng.random_range(0.4..1.0)),
        _ => String::new(),
    }
}

/// The case's plant (the joint's own values, the effects, the sensors, the range), the model the
/// diagnosis sees, and that model as the controller's parameter set.
fn files(
    case: usize,
    joint: &Joint,
    effects: &str,
    sensors: &str,
) -> Result<(PlantFile, ModelFile, joint_core::params::ParamSet), String> {
    let plant_text = format!(
        "{}\n{effects}{sensors}\n[joint_range]\nmin = {}\nmax = {}\n",
        joint.plant_model.as_ref().unwrap_or(&joint.model),
        joint.range.0,
        joint.range.1
    );
    let plant = PlantFile::parse(&plant_text, "bench-plant").map_err(|e| format!("case {case}: {e}\n{plant_text}"))?;
    let model = ModelFile::parse(&joint.model, "bench-model").map_err(|e| format!("case {case}: {e}"))?;
    let ctrl = model.param_set().map_err(|e| e.to_string())?;
    Ok((plant, model, ctrl))
}

/// `text` (a model TOML) with every `key = v` line's value multiplied by `f`.
fn scaled(text: &str, key: &str, f: f64) -> String {
    text.lines()
        .map(|l| match l.strip_prefix(&format!("{key} = ")) {
            Some(v) => format!("{key} = {}", v.parse::<f64>().unwrap_or(0.0) * f),
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

/// An elastic joint of the elastic-joint paper's size, for free responses: `J·q̈ + B·q̇ +
/// c·sgn(q̇) + K·q = 0` (ω ≈ 20–40 rad/s). `coulomb = false`: no Coulomb term in the model.
fn free_joint(rng: &mut ChaCha8Rng, coulomb: bool) -> (Joint, f64) {
    let k = rng.random_range(5.0..10.0);
    let kb = rng.random_range(0.02..0.06);
    let j = rng.random_range(0.006..0.012);
    let c = rng.random_range(0.005..0.015);
    let mut m = format!("[inertia]\nj = {j}\n\n[spring]\nk = {k}\nb = {kb}\nq0 = 0.0\n");
    // the plant's sign band, stated (see `rigid`)
    if coulomb {
        m += &format!("\n[friction]\nc = {c}\nv_band = 0.01\n");
    } else {
        m += "\n[friction]\nv_band = 0.01\n";
    }
    (
        Joint {
            name: if coulomb { "free" } else { "free_no_coulomb" },
            model: m,
            plant_model: None,
            range: (-0.5, 0.5),
        },
        c,
    )
}

/// The plant section of one effect in a free response, sized against the joint's Coulomb level
/// `c` and spring torque (K·0.3 rad ≈ 1.5–3 N·m).
fn free_effect_section(kind: &str, rng: &mut ChaCha8Rng, c: f64) -> String {
    match kind {
        "stribeck" => {
            format!("[stribeck]\nlevel = {}\nspeed = {}\n", c * rng.random_range(1.0..3.0), rng.random_range(0.1..0.5))
        }
        "asymmetric_friction" => {
            let s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            format!("[asymmetric_friction]\ndelta = {}\n", s * c * rng.random_range(0.5..1.0))
        }
        "position_ripple" => format!(
            "[position_ripple]\namplitude = {}\nperiod = {}\nphase = {}\n",
            rng.random_range(0.02..0.06),
            rng.random_range(0.03..0.1),
            rng.random_range(-3.0..3.0)
        ),
        "cable_spring" => {
            format!("[cable_spring]\nk = {}\nengage = {}\n", rng.random_range(1.0..3.0), rng.random_range(0.05..0.2))
        }
        "backlash" => format!("[backlash]\nwidth = {}\n", rng.random_range(0.02..0.06)),
        "dry_friction" => format!("[dry_friction]\nc = {}\n", rng.random_range(0.01..0.03)),
        _ => String::new(),
    }
}

/// One trajectory-mode case: the joint released from 0.2–0.4 rad, 2–4 s logged at 1 kHz.
fn run_traj_case(case: usize, seed: u64) -> Result<(CaseResult, JointLog, ModelFile), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ case as u64);
    let kind = TRAJ_KINDS[case % TRAJ_KINDS.len()];
    let (mut joint, c) = free_joint(&mut rng, kind != "dry_friction");
    if kind == "parameters" {
        let t = scaled(&joint.model, "b", rng.random_range(1.5..2.0));
        joint.plant_model = Some(scaled(&t, "k", rng.random_range(0.9..0.95)));
    }
    let q_noise = rng.random_range(0.0001..0.0005);
    let sensors =
        format!("[sensors]\nq_noise = {q_noise}\nqd_noise = {}\nqdd_noise = 0.5\n", rng.random_range(0.002..0.01));
    let effects = free_effect_section(kind, &mut rng, c);
    let (plant, model, ctrl) = files(case, &joint, &effects, &sensors)?;
    let start = rng.random_range(0.2..0.4) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Free],
        seconds: rng.random_range(2.0..4.0),
        seed: seed ^ (case as u64).wrapping_mul(7919),
        rate: Some(1000.0),
        plant_rate: 10_000.0,
        range: Some(joint.range),
        free_start: Some(start),
        torque_columns: false,
    };
    let (log, _) = simulate(&plant, &ctrl, &cfg).map_err(|e| format!("case {case}: {e}"))?;
    score_case(case, kind, vec![kind.to_string()], joint.name, "free".into(), q_noise, effects, log, model)
}

/// Builds and runs one case; `Err` only for a bench bug (a plant that does not parse).
pub fn run_case_in(
    mode: Mode,
    case: usize,
    seed: u64,
    seconds: f64,
) -> Result<(CaseResult, JointLog, ModelFile), String> {
    match mode {
        Mode::Torque => run_case(case, seed, seconds),
        Mode::Trajectory => run_traj_case(case, seed),
    }
}

/// Builds and runs one torque-mode case; `Err` only for a bench bug (a plant that does not parse).
pub fn run_case(case: usize, seed: u64, seconds: f64) -> Result<(CaseResult, JointLog, ModelFile), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ case as u64);
    let kind = KINDS[case % KINDS.len()];
    let truth: Vec<String> = match kind {
        "pair" => {
            let a = rng.random_range(0..PAIRABLE.len());
            let mut b = rng.random_range(0..PAIRABLE.len() - 1);
            if b >= a {
                b += 1;
            }
            let mut v = vec![PAIRABLE[a].to_string(), PAIRABLE[b].to_string()];
            v.sort();
            v
        }
        k => vec![k.to_string()],
    };
    let mut joint = match kind {
        "backlash" => elastic(&mut rng),
        "dry_friction" => rigid(&mut rng, false),
        "none" if rng.random_bool(0.3) => elastic(&mut rng),
        _ => rigid(&mut rng, true),
    };
    if kind == "parameters" {
        // The plant's viscous and Coulomb levels and inertia differ from the model's.
        let t = scaled(&joint.model, "b", rng.random_range(1.3..1.6));
        joint.plant_model = Some(scaled(&t, "c", rng.random_range(0.5..0.75)));
    }
    let rate = 1000.0;
    let tau_noise = rng.random_range(0.03..0.15);
    let sensors = format!(
        "[sensors]\nq_noise = 0.0001\nqd_noise = {}\nqdd_noise = {}\ntau_noise = {tau_noise}\nu_noise = 0.01\ntemp_noise = 0.05\n",
        rng.random_range(0.001..0.004),
        rng.random_range(0.1..0.6)
    );
    let effects: String = if kind == "none" || kind == "parameters" {
        String::new()
    } else {
        truth.iter().map(|k| effect_section(k, &mut rng, joint.range, rate) + "\n").collect()
    };
    let orders = [
        vec![ScenarioKind::Sweep, ScenarioKind::Poses, ScenarioKind::Hand],
        vec![ScenarioKind::Hand, ScenarioKind::Sweep, ScenarioKind::Poses],
        vec![ScenarioKind::Poses, ScenarioKind::Hand, ScenarioKind::Sweep],
        vec![ScenarioKind::Sweep, ScenarioKind::Hand, ScenarioKind::Poses],
    ];
    let scenarios = orders[rng.random_range(0..orders.len())].clone();
    let secs = seconds * rng.random_range(0.8..1.2);
    let (plant, model, ctrl) = files(case, &joint, &effects, &sensors)?;
    let cfg = SimConfig {
        scenarios: scenarios.clone(),
        seconds: secs,
        seed: seed ^ (case as u64).wrapping_mul(7919),
        rate: Some(rate),
        plant_rate: 10_000.0,
        range: Some(joint.range),
        free_start: None,
        torque_columns: true,
    };
    let (log, _) = simulate(&plant, &ctrl, &cfg).map_err(|e| format!("case {case}: {e}"))?;
    let scen = scenarios.iter().map(|s| format!("{s:?}").to_lowercase()).collect::<Vec<_>>().join(",");
    score_case(case, kind, truth, joint.name, scen, tau_noise, effects, log, model)
}

/// Diagnoses one case's log blind and scores it against the withheld set.
#[allow(clippy::too_many_arguments)]
fn score_case(
    case: usize,
    kind: &str,
    truth: Vec<String>,
    joint: &'static str,
    scenarios: String,
    noise: f64,
    effects: String,
    log: JointLog,
    model: ModelFile,
) -> Result<(CaseResult, JointLog, ModelFile), String> {
    let t0 = std::time::Instant::now();
    let d = joint_analysis::diagnose::diagnose(&log, &model, &joint_analysis::diagnose::Options::default())
        .map_err(|e| format!("case {case}: {e}"))?;
    let seconds_taken = t0.elapsed().as_secs_f64();
    let r = &d.report;
    let mut predicted = r.verdict.effects.clone();
    predicted.sort();
    let truth_label = truth.join("+");
    let pred_label = predicted.join("+");
    let shrink = r.selected.last().map(|s| s.shrink).unwrap_or(r.verdict.shrink);
    let true_shrink = if truth.len() == 1 && kind != "none" {
        r.effects.iter().find(|e| e.effect == truth[0]).map(|e| e.shrink)
    } else {
        None
    };
    let res = CaseResult {
        case,
        correct: truth_label == pred_label,
        truth: truth_label,
        predicted: pred_label,
        joint,
        scenarios,
        tau_noise: noise,
        effect_sections: effects.replace('\n', " ").trim().to_string(),
        holdout_rmse_before: r.verdict.holdout_rmse_before,
        shrink,
        true_shrink,
        seconds: seconds_taken,
    };
    Ok((res, log, model))
}

/// Runs `work(0..n)` on as many threads as the machine has cores and hands the results to
/// `each` on the calling thread in index order, so the output is the same as a sequential run's
/// (each case seeds its own generator). Stops at the first error `each` returns; workers finish
/// the case they are on. The cases are independent: on two cores the in-house bench's 52
/// torque cases (`tests/diagnose_bench.rs`) took 57.6 s against 70.1 s one after the other (the
/// diagnosis itself keeps the second core busy only part of the time).
fn in_parallel<T: Send>(
    n: usize,
    work: impl Fn(usize) -> T + Sync,
    each: &mut dyn FnMut(T) -> Result<(), String>,
) -> Result<(), String> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get()).clamp(1, n.max(1));
    let (next, stop) = (AtomicUsize::new(0), AtomicBool::new(false));
    let (tx, rx) = std::sync::mpsc::channel::<(usize, T)>();
    std::thread::scope(|s| {
        for _ in 0..threads {
            let (tx, next, stop, work) = (tx.clone(), &next, &stop, &work);
            s.spawn(move || loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= n || stop.load(Ordering::Relaxed) || tx.send((i, work(i))).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        // early arrivals wait for their turn
        let mut held = BTreeMap::new();
        let mut want = 0;
        for (i, r) in rx {
            held.insert(i, r);
            while let Some(r) = held.remove(&want) {
                want += 1;
                if let Err(e) = each(r) {
                    stop.store(true, Ordering::Relaxed);
                    return Err(e);
                }
            }
        }
        Ok(())
    })
}

/// Runs `cases` torque-mode cases with `seed`; `seconds` per scenario (three scenarios per log).
pub fn run(
    cases: usize,
    seed: u64,
    seconds: f64,
    dump: Option<&std::path::Path>,
    progress: impl FnMut(&CaseResult),
) -> Result<BenchReport, String> {
    run_mode(Mode::Torque, cases, seed, seconds, dump, progress)
}

/// Runs `cases` cases of `mode` with `seed` (`seconds` only applies to torque mode).
pub fn run_mode(
    mode: Mode,
    cases: usize,
    seed: u64,
    seconds: f64,
    dump: Option<&std::path::Path>,
    mut progress: impl FnMut(&CaseResult),
) -> Result<BenchReport, String> {
    let mut out = Vec::with_capacity(cases);
    let mut on_case = |res: Result<(CaseResult, JointLog, ModelFile), String>| -> Result<(), String> {
        let (r, log, model) = res?;
        let c = r.case;
        if let Some(dir) = dump {
            log.write_file(&dir.join(format!("case-{c}.csv"))).map_err(|e| e.to_string())?;
            let text =
                format!("# bench case {c}: withheld {} ({})\n{}", r.truth, r.effect_sections, model.to_toml_string());
            joint_formats::output::write_file(&dir.join(format!("case-{c}.toml")), |w| w.write_all(text.as_bytes()))
                .map_err(|e| e.to_string())?;
        }
        progress(&r);
        out.push(r);
        Ok(())
    };
    in_parallel(cases, |c| run_case_in(mode, c, seed, seconds), &mut on_case)?;
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    for r in &out {
        *confusion.entry(r.truth.clone()).or_default().entry(r.predicted.clone()).or_default() += 1;
    }
    let correct = out.iter().filter(|r| r.correct).count();
    let none_cases = out.iter().filter(|r| r.truth == "none").count();
    let overclaims = out.iter().filter(|r| r.truth == "none" && r.predicted != "none").count();
    let eff: Vec<&CaseResult> = out.iter().filter(|r| r.true_shrink.is_some()).collect();
    let mean = |v: Vec<f64>| if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 };
    Ok(BenchReport {
        accuracy: correct as f64 / out.len().max(1) as f64,
        none_cases,
        overclaims,
        overclaim_rate: overclaims as f64 / none_cases.max(1) as f64,
        mean_shrink: mean(eff.iter().map(|r| r.shrink).collect()),
        mean_true_shrink: mean(eff.iter().filter_map(|r| r.true_shrink).collect()),
        confusion,
        cases: out,
    })
}
