//! Draws of the true joint: a trunk-exoskeleton joint, a harmonic-drive arm joint, an
//! elastic joint, and (trajectory mode) a pendulum-like arm joint.
//!
//! Bases: trunk from the trunk paper's Table 1 (as `examples/models/trunk-*.toml` write it in
//! SI), arm from typical harmonic-drive arm joints, elastic from the elastic-joint paper.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::model::{Friction, Inertia, ModelFile, Offset, Spring, Weight};
use crate::rngs::{chance, log_uniform, pick, sign, uniform, Rng64};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    Trunk,
    Arm,
    Elastic,
    Pendulum,
}

impl JointKind {
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Trunk => "trunk",
            JointKind::Arm => "arm",
            JointKind::Elastic => "elastic",
            JointKind::Pendulum => "pendulum",
        }
    }
}

/// The true joint's own terms and how they were drawn.
#[derive(Debug, Clone, Serialize)]
pub struct DrawnJoint {
    pub kind: JointKind,
    pub model: ModelFile,
    /// Factor applied to each base value (trunk) or the range it was drawn from (others).
    pub draws: BTreeMap<String, f64>,
}

/// What the effect needs from the joint (e.g. a Coulomb term to build Stribeck on).
#[derive(Debug, Clone, Copy, Default)]
pub struct Needs {
    pub coulomb: bool,
    pub spring: bool,
}

/// A friction section's `v_band`: absent (pure sign) or a band of 2–50 mrad/s.
fn draw_band(rng: &mut Rng64) -> Option<f64> {
    chance(rng, 0.4).then(|| log_uniform(rng, 0.002, 0.05))
}

pub fn draw(rng: &mut Rng64, kind: JointKind, name: &str, needs: Needs) -> DrawnJoint {
    match kind {
        JointKind::Trunk => trunk(rng, name),
        JointKind::Arm => arm(rng, name, false),
        JointKind::Pendulum => arm(rng, name, true),
        JointKind::Elastic => elastic(rng, name, needs),
    }
}

fn trunk(rng: &mut Rng64, name: &str) -> DrawnJoint {
    // (a, b, c, C_w0, s, φ, I_a, C_0) of the right and left joints, SI.
    let right = [1.8941792639567765, 8.938141604040842, 2.32, 2.79, 0.8021409131831525, -0.027, 2.37, -0.59];
    let left = [2.1403897402076573, 9.396507840145501, 2.94, 2.59, 0.7448451336700702, -3.108, 3.21, 0.20];
    let base = if chance(rng, 0.5) { right } else { left };
    let [a, b, c, cw, s, phi, j, c0] = base;
    let mut draws = BTreeMap::new();
    let mut f = |key: &str, rng: &mut Rng64| {
        let k = log_uniform(rng, 0.1, 10.0);
        draws.insert(key.to_string(), k);
        k
    };
    let fa = f("a", rng);
    let fb = f("b", rng);
    let fc = f("c", rng);
    let fw = f("amplitude", rng);
    let fj = f("j", rng);
    let f0 = f("c0", rng);
    let model = ModelFile {
        name: name.to_string(),
        friction: Some(Friction { a: Some(a * fa), b: Some(b * fb), c: Some(c * fc), v_band: draw_band(rng) }),
        // s and φ are geometry, not magnitudes: perturbed a little rather than by decades.
        weight: Some(Weight { amplitude: cw * fw, s: s * uniform(rng, 0.8, 1.25), phi: phi + uniform(rng, -0.3, 0.3) }),
        inertia: Some(Inertia { j: j * fj }),
        offset: Some(Offset { c0: c0 * f0 }),
        spring: None,
    };
    DrawnJoint { kind: JointKind::Trunk, model, draws }
}

fn arm(rng: &mut Rng64, name: &str, pendulum: bool) -> DrawnJoint {
    let mut draws = BTreeMap::new();
    let j = uniform(rng, 0.2, 1.5);
    // A free-swinging pendulum needs friction well below gravity to swing at all.
    let fr = if pendulum { log_uniform(rng, 0.05, 1.0) } else { 1.0 };
    draws.insert("friction_factor".to_string(), fr);
    let b = uniform(rng, 1.0, 10.0) * fr;
    let c = uniform(rng, 1.0, 8.0) * fr;
    let amp = uniform(rng, 5.0, 40.0);
    let phi = if pendulum { uniform(rng, -0.4, 0.4) } else { uniform(rng, -3.0, 3.0) };
    let offset = (!pendulum && chance(rng, 0.5)).then(|| Offset { c0: uniform(rng, -1.0, 1.0) });
    let model = ModelFile {
        name: name.to_string(),
        friction: Some(Friction { a: None, b: Some(b), c: Some(c), v_band: draw_band(rng) }),
        weight: Some(Weight { amplitude: amp, s: 1.0, phi }),
        inertia: Some(Inertia { j }),
        offset,
        spring: None,
    };
    let kind = if pendulum { JointKind::Pendulum } else { JointKind::Arm };
    DrawnJoint { kind, model, draws }
}

fn elastic(rng: &mut Rng64, name: &str, needs: Needs) -> DrawnJoint {
    let j = uniform(rng, 0.006, 0.012);
    let k = uniform(rng, 5.0, 10.0);
    let b = uniform(rng, 0.02, 0.06);
    let q0 = if chance(rng, 0.5) { 0.0 } else { uniform(rng, -0.05, 0.05) };
    // Small Coulomb friction of the bearings, when present.
    let friction = (needs.coulomb || chance(rng, 0.6)).then(|| Friction {
        a: None,
        b: None,
        c: Some(log_uniform(rng, 0.003, 0.04)),
        v_band: draw_band(rng),
    });
    let model = ModelFile {
        name: name.to_string(),
        friction,
        weight: None,
        inertia: Some(Inertia { j }),
        offset: None,
        spring: Some(Spring { k, b, q0 }),
    };
    DrawnJoint { kind: JointKind::Elastic, model, draws: BTreeMap::new() }
}

/// Draws which file values are off for a `parameters` case: one to three of J, weight
/// amplitude, friction b/c, offset c0, spring k and damping b, each by ±20–60 %.
pub fn perturb(rng: &mut Rng64, truth: &ModelFile) -> (ModelFile, Vec<crate::effects::ParamChange>) {
    let mut file = truth.clone();
    let mut keys: Vec<&str> = Vec::new();
    if truth.inertia.is_some() {
        keys.push("j");
    }
    if truth.weight.is_some() {
        keys.push("amplitude");
    }
    if truth.b() > 0.0 {
        keys.push("b");
    }
    if truth.c() > 0.0 {
        keys.push("c");
    }
    if truth.offset.is_some_and(|o| o.c0.abs() > 0.05 * truth.c().max(0.01)) {
        keys.push("c0");
    }
    if truth.spring.is_some() {
        keys.push("k");
        keys.push("spring_b");
    }
    let n = crate::rngs::int(rng, 1, 3.min(keys.len()));
    let mut changes = Vec::new();
    for _ in 0..n {
        let Some(key) = pick(rng, &keys) else { break };
        keys.retain(|k| *k != key);
        let factor = 1.0 + sign(rng) * uniform(rng, 0.2, 0.6);
        if let Some((t, f)) = set_param(&mut file, key, factor) {
            changes.push(crate::effects::ParamChange { name: key.to_string(), true_value: t, file_value: f });
        }
    }
    (file, changes)
}

/// Multiplies one parameter of the file by `factor`; returns (true, file) values.
fn set_param(m: &mut ModelFile, key: &str, factor: f64) -> Option<(f64, f64)> {
    let slot: &mut f64 = match key {
        "j" => &mut m.inertia.as_mut()?.j,
        "amplitude" => &mut m.weight.as_mut()?.amplitude,
        "b" => m.friction.as_mut()?.b.as_mut()?,
        "c" => m.friction.as_mut()?.c.as_mut()?,
        "c0" => &mut m.offset.as_mut()?.c0,
        "k" => &mut m.spring.as_mut()?.k,
        "spring_b" => &mut m.spring.as_mut()?.b,
        _ => return None,
    };
    let t = *slot;
    *slot = t * factor;
    Some((t, *slot))
}

/// The file without its Coulomb term (dry_friction): c removed, and the band with it,
/// since a band without a Coulomb level would say nothing.
pub fn without_coulomb(truth: &ModelFile) -> ModelFile {
    let mut file = truth.clone();
    if let Some(f) = file.friction.as_mut() {
        f.c = None;
        f.v_band = None;
    }
    if file.friction.is_some_and(|f| f.a.is_none() && f.b.is_none()) {
        file.friction = None;
    }
    file
}
