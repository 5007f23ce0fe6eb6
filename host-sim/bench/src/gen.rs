//! `diag-bench gen`: which family and mode each case gets, and writing the case folders.

use std::path::Path;

use anyhow::{bail, Context};
use serde_json::json;

use crate::case::{CaseData, Mode};
use crate::rngs::{chance, stream, weighted, Rng64};

/// Effect families each mode can produce.
pub const TORQUE_FAMILIES: &[&str] = &[
    "parameters",
    "stribeck",
    "asymmetric_friction",
    "load_dependent_friction",
    "thermal_drift",
    "position_ripple",
    "cable_spring",
    "backlash",
    "delay",
    "dry_friction",
    "presliding_hysteresis",
];
pub const TRAJECTORY_FAMILIES: &[&str] = &[
    "parameters",
    "stribeck",
    "asymmetric_friction",
    "position_ripple",
    "cable_spring",
    "backlash",
    "delay",
    "dry_friction",
    "presliding_hysteresis",
    "initial_state",
];
/// Two-effect compounds; the second effect is the one re-sized to its own SNR.
pub const TORQUE_COMPOUNDS: &[[&str; 2]] = &[
    ["stribeck", "position_ripple"],
    ["load_dependent_friction", "position_ripple"],
    ["thermal_drift", "cable_spring"],
    ["asymmetric_friction", "cable_spring"],
    ["delay", "stribeck"],
];
pub const TRAJECTORY_COMPOUNDS: &[[&str; 2]] =
    &[["backlash", "stribeck"], ["cable_spring", "stribeck"], ["position_ripple", "asymmetric_friction"]];

/// Which modes `gen` may draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeSel {
    Torque,
    Trajectory,
    Any,
}

/// The per-case choice: mode and withheld effects (empty = none).
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub mode: Mode,
    pub effects: Vec<&'static str>,
}

fn static_name(name: &str) -> Option<&'static str> {
    TORQUE_FAMILIES.iter().chain(TRAJECTORY_FAMILIES).copied().find(|f| *f == name)
}

fn allowed(mode: Mode, name: &str) -> bool {
    match mode {
        Mode::Torque => TORQUE_FAMILIES.contains(&name),
        Mode::Trajectory => TRAJECTORY_FAMILIES.contains(&name),
    }
}

/// `none` in at least 30 % of every block of ten cases: 3 fixed slots out of 10 and a
/// fourth with even odds (35 % expected), placed by a per-block shuffle so the case
/// number says nothing.
fn is_none_slot(seed: u64, case: u64, rng: &mut Rng64) -> bool {
    use rand::seq::SliceRandom;
    let mut block = stream(seed, case / 10, 0xB10C);
    let mut slots: Vec<u64> = (0..10).collect();
    slots.shuffle(&mut block);
    let pos = slots.iter().position(|s| *s == case % 10).unwrap_or(9);
    pos < 3 || (pos == 3 && chance(rng, 0.5))
}

fn draw_mode(rng: &mut Rng64, sel: ModeSel) -> Mode {
    match sel {
        ModeSel::Torque => Mode::Torque,
        ModeSel::Trajectory => Mode::Trajectory,
        ModeSel::Any => {
            if chance(rng, 0.7) {
                Mode::Torque
            } else {
                Mode::Trajectory
            }
        }
    }
}

/// The default mix for one mode: every family, `parameters` a little more, compounds as
/// a group, initial_state a little less (it has one mode only).
fn draw_effects(rng: &mut Rng64, mode: Mode) -> Vec<&'static str> {
    let (fams, comps) = match mode {
        Mode::Torque => (TORQUE_FAMILIES, TORQUE_COMPOUNDS),
        Mode::Trajectory => (TRAJECTORY_FAMILIES, TRAJECTORY_COMPOUNDS),
    };
    let mut items: Vec<(usize, f64)> =
        fams.iter().enumerate().map(|(i, f)| (i, if *f == "parameters" { 1.5 } else { 1.0 })).collect();
    items.push((usize::MAX, 1.2));
    match weighted(rng, &items) {
        Some(usize::MAX) | None => compound(rng, comps),
        Some(i) => fams.get(i).map(|f| vec![*f]).unwrap_or_default(),
    }
}

fn compound(rng: &mut Rng64, comps: &[[&'static str; 2]]) -> Vec<&'static str> {
    crate::rngs::pick(rng, comps).map(|c| c.to_vec()).unwrap_or_default()
}

/// The plan of case `case` for (seed, options); deterministic per (seed, case, options).
pub fn plan(seed: u64, case: u64, family: Option<&str>, sel: ModeSel) -> anyhow::Result<Plan> {
    let mut rng = stream(seed, case, 0x91A);
    match family {
        None => {
            let none = is_none_slot(seed, case, &mut rng);
            let mode = draw_mode(&mut rng, sel);
            let effects = if none { Vec::new() } else { draw_effects(&mut rng, mode) };
            Ok(Plan { mode, effects })
        }
        Some(f) => plan_family(&mut rng, f, sel),
    }
}

fn plan_family(rng: &mut Rng64, f: &str, sel: ModeSel) -> anyhow::Result<Plan> {
    if f == "none" {
        return Ok(Plan { mode: draw_mode(rng, sel), effects: Vec::new() });
    }
    if f == "compound" {
        let mode = draw_mode(rng, sel);
        let comps = if mode == Mode::Torque { TORQUE_COMPOUNDS } else { TRAJECTORY_COMPOUNDS };
        return Ok(Plan { mode, effects: compound(rng, comps) });
    }
    let mut effects = Vec::new();
    for part in f.split('+') {
        match static_name(part) {
            Some(s) => effects.push(s),
            None => bail!("unknown family {part:?}"),
        }
    }
    let fits = |m: Mode| effects.iter().all(|e| allowed(m, e));
    let mode = match sel {
        ModeSel::Any => {
            let m = draw_mode(rng, sel);
            if fits(m) {
                m
            } else if m == Mode::Torque {
                Mode::Trajectory
            } else {
                Mode::Torque
            }
        }
        _ => draw_mode(rng, sel),
    };
    if !fits(mode) {
        bail!("family {f:?} cannot be drawn in {mode:?} mode");
    }
    Ok(Plan { mode, effects })
}

/// Generates one case in memory.
pub fn generate(seed: u64, case: u64, family: Option<&str>, sel: ModeSel) -> anyhow::Result<CaseData> {
    let p = plan(seed, case, family, sel)?;
    let mut rng = stream(seed, case, 0xCA5E);
    match p.mode {
        Mode::Torque => crate::torque::generate(&mut rng, seed, case, &p.effects),
        Mode::Trajectory => crate::trajmode::generate(&mut rng, seed, case, &p.effects),
    }
}

pub fn case_dir_name(case: u64) -> String {
    format!("case-{case:04}")
}

/// Writes log.csv, model.toml and truth.json of one case into `dir`, and with `clean` also
/// clean.csv: the noise-free signals at the sample times (t, q, qd, qdd, u, tau), for checks
/// of a tool's signal preparation against the truth. The tool under test must never read it.
pub fn write_case(dir: &Path, c: &CaseData, clean: bool) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    std::fs::write(dir.join("log.csv"), c.log.to_csv())?;
    std::fs::write(dir.join("model.toml"), c.model.to_toml()?)?;
    std::fs::write(dir.join("truth.json"), serde_json::to_string_pretty(&c.truth)?)?;
    if clean {
        std::fs::write(dir.join("clean.csv"), clean_csv(c))?;
    }
    Ok(())
}

fn clean_csv(c: &CaseData) -> String {
    let k = &c.clean;
    let t0 = c.truth.t0;
    let mut s = String::from("t,q,qd,qdd,u,tau\n");
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
    for i in 0..k.t_rel.len() {
        s.push_str(&format!(
            "{:.6},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e}\n",
            t0 + at(&k.t_rel, i),
            at(&k.q, i),
            at(&k.qd, i),
            at(&k.qdd, i),
            at(&k.u, i),
            at(&k.tau, i)
        ));
    }
    s
}

/// Generates `cases` cases into `out` (case-0000 …) and the manifest.
pub fn run_gen(
    seed: u64,
    cases: u64,
    out: &Path,
    family: Option<&str>,
    sel: ModeSel,
    clean: bool,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(out)?;
    let mut list = Vec::new();
    for k in 0..cases {
        let c = generate(seed, k, family, sel).with_context(|| format!("case {k}"))?;
        let name = case_dir_name(k);
        write_case(&out.join(&name), &c, clean)?;
        let t = &c.truth;
        list.push(json!({
            "case": k, "dir": name, "mode": t.mode, "effects": t.effects, "label": t.label,
            "joint": t.joint.kind, "trajectory_family": t.trajectory_family, "rate_hz": t.rate_hz,
            "samples": t.samples, "snr": t.snr, "detectable_hint": t.detectable_hint,
        }));
    }
    let manifest = json!({
        "seed": seed,
        "seed_class": seed_class(seed),
        "cases": list,
        "family": family,
        "mode": format!("{sel:?}").to_lowercase(),
        "generator": concat!("diag-bench ", env!("CARGO_PKG_VERSION")),
    });
    std::fs::write(out.join("manifest.json"), serde_json::to_string_pretty(&manifest)?)?;
    Ok(())
}

/// Development seeds may be looked at while tuning the diagnosis; 9001–9010 never.
pub fn seed_class(seed: u64) -> &'static str {
    match seed {
        1..=20 => "development",
        9001..=9010 => "unseen",
        _ => "other",
    }
}
