//! The withheld effects: their parameters, how they are drawn, and the torque each adds.
//!
//! Every additive effect is written as the torque it adds to the true joint's own terms
//! (`delta`), in f64, from the physics in the brief. `parameters` and `dry_friction` are
//! not additive: they are differences between the true joint and the file's joint, and
//! `delay` / `initial_state` act on the sensor chain or the start, so their `delta` is 0.

use serde::Serialize;

use crate::model::{sgn, ModelFile};
use crate::rngs::{chance, int, log_uniform, pick, sign, uniform, Rng64};

/// One parameter that the file states wrongly.
#[derive(Debug, Clone, Serialize)]
pub struct ParamChange {
    pub name: String,
    pub true_value: f64,
    pub file_value: f64,
}

/// One harmonic of a position ripple.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Ripple {
    pub amplitude: f64,
    pub period: f64,
    pub phase: f64,
}

/// The shapes a harness / cable / padding torque takes.
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum CableShape {
    /// Taut past q_e on the `side` of it: side·k·max(0, side·(q − q_e)), softplus-smoothed
    /// over `smooth` rad when smooth > 0.
    OneSided { k: f64, q_e: f64, side: f64, smooth: f64 },
    /// k1·x + k3·x³ with x = q − q_s.
    Progressive { k1: f64, k3: f64, q_s: f64 },
    /// amplitude·exp(−½((q − q_b)/width)²): padding pressed over a stretch of angle.
    Bump { amplitude: f64, q_b: f64, width: f64 },
}

/// Which logged signal lags its true value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Delayed {
    U,
    Tau,
    Q,
}

#[derive(Debug, Clone, Serialize)]
#[serde(tag = "effect", rename_all = "snake_case")]
pub enum Effect {
    Parameters {
        changes: Vec<ParamChange>,
    },
    /// level·exp(−(|v|/v_s)^delta)·sign(v), on top of c·sign(v).
    Stribeck {
        level: f64,
        v_s: f64,
        delta: f64,
    },
    /// c_plus·sign(v) for v > 0, c_minus·sign(v) for v < 0, instead of c·sign(v).
    AsymmetricFriction {
        c: f64,
        c_plus: f64,
        c_minus: f64,
    },
    /// mu·|tau_external|·sign(v).
    LoadDependentFriction {
        mu: f64,
    },
    /// b·(1 + alpha_b·ΔT) and c·(1 + alpha_c·ΔT), ΔT = rise·(1 − exp(−t/tau_th)).
    ThermalDrift {
        alpha_b: f64,
        alpha_c: f64,
        temp0: f64,
        rise: f64,
        tau_th: f64,
        temp_logged: bool,
    },
    PositionRipple {
        harmonics: Vec<Ripple>,
    },
    CableSpring {
        cable: CableShape,
    },
    /// Spring torque k·dz(q − q0) with the dead zone [lo, hi], instead of k·(q − q0).
    Backlash {
        k: f64,
        q0: f64,
        lo: f64,
        hi: f64,
    },
    Delay {
        signal: Delayed,
        seconds: f64,
    },
    DryFriction {
        c: f64,
    },
    /// Dahl state F replaces c·sign(v): dF/dq = sigma·(1 − F/c·sign(dq)).
    PreslidingHysteresis {
        sigma: f64,
        c: f64,
        presliding_distance: f64,
    },
    /// variant "cut_mid_swing" (released `detail` s before the first sample) or
    /// "pushed" (released with velocity `detail` rad/s at the first sample).
    InitialState {
        variant: String,
        detail: f64,
    },
}

/// What an effect's torque may depend on at one instant.
#[derive(Debug, Clone, Copy, Default)]
pub struct Ctx {
    /// Time since the log's first sample.
    pub t_rel: f64,
    pub q: f64,
    pub qd: f64,
    /// The external measured load (tau column, noise-free).
    pub tau_ext: f64,
    /// The Dahl state, when a presliding effect is present.
    pub dahl: f64,
}

impl Effect {
    /// The spec §3 vocabulary name.
    pub fn name(&self) -> &'static str {
        match self {
            Effect::Parameters { .. } => "parameters",
            Effect::Stribeck { .. } => "stribeck",
            Effect::AsymmetricFriction { .. } => "asymmetric_friction",
            Effect::LoadDependentFriction { .. } => "load_dependent_friction",
            Effect::ThermalDrift { .. } => "thermal_drift",
            Effect::PositionRipple { .. } => "position_ripple",
            Effect::CableSpring { .. } => "cable_spring",
            Effect::Backlash { .. } => "backlash",
            Effect::Delay { .. } => "delay",
            Effect::DryFriction { .. } => "dry_friction",
            Effect::PreslidingHysteresis { .. } => "presliding_hysteresis",
            Effect::InitialState { .. } => "initial_state",
        }
    }

    /// The torque this effect adds to the true joint's own terms (`joint`).
    pub fn delta(&self, x: &Ctx, joint: &ModelFile) -> f64 {
        let s = joint.sign_law().of(x.qd);
        match self {
            Effect::Stribeck { level, v_s, delta } => stribeck(*level, *v_s, *delta, x.qd) * s,
            Effect::AsymmetricFriction { c, c_plus, c_minus } => {
                let cd = if s > 0.0 { c_plus } else { c_minus };
                (cd - c) * s
            }
            Effect::LoadDependentFriction { mu } => mu * x.tau_ext.abs() * s,
            Effect::ThermalDrift { alpha_b, alpha_c, .. } => {
                let dt = self.temp_rise(x.t_rel);
                joint.b() * alpha_b * dt * x.qd + joint.c() * alpha_c * dt * s
            }
            Effect::PositionRipple { .. } | Effect::CableSpring { .. } | Effect::Backlash { .. } => {
                self.position_delta(x.q)
            }
            Effect::PreslidingHysteresis { c, .. } => x.dahl - c * s,
            _ => 0.0,
        }
    }

    /// The part of the effect that depends on q alone (0 for the others).
    pub fn position_delta(&self, q: f64) -> f64 {
        match self {
            Effect::PositionRipple { harmonics } => {
                harmonics.iter().map(|h| h.amplitude * (std::f64::consts::TAU * q / h.period + h.phase).sin()).sum()
            }
            Effect::CableSpring { cable } => cable_torque(cable, q),
            Effect::Backlash { k, q0, lo, hi } => {
                let x = q - q0;
                k * (dead_zone(x, *lo, *hi) - x)
            }
            _ => 0.0,
        }
    }

    /// Temperature rise above `temp0` at time t_rel (0 for non-thermal effects).
    pub fn temp_rise(&self, t_rel: f64) -> f64 {
        match self {
            Effect::ThermalDrift { rise, tau_th, .. } => rise * (1.0 - (-t_rel.max(0.0) / tau_th).exp()),
            _ => 0.0,
        }
    }

    /// The factors k for which `scaled(k)` stays inside the family's drawn range (c is the
    /// joint's Coulomb level). Shapes without a hard range get a decade either way.
    pub fn scale_bounds(&self, c: f64) -> (f64, f64) {
        let within = |x: f64, lo: f64, hi: f64| {
            if x > 0.0 {
                (lo / x, hi / x)
            } else {
                (1.0, 1.0)
            }
        };
        match self {
            Effect::Stribeck { level, .. } => within(*level, 0.1 * c, 0.8 * c),
            Effect::AsymmetricFriction { c_plus, c_minus, .. } => within(c_plus - c_minus, 0.1 * c, 0.5 * c),
            Effect::LoadDependentFriction { mu } => within(*mu, 0.02, 0.2),
            Effect::ThermalDrift { alpha_b, alpha_c, .. } => {
                let a = alpha_b.abs().max(alpha_c.abs());
                within(a, 0.004, 0.025)
            }
            Effect::PositionRipple { .. } => (0.2, 5.0),
            _ => (0.1, 10.0),
        }
    }

    /// Multiplies the effect's size by k (used to size the second effect of a compound).
    pub fn scaled(&self, k: f64) -> Effect {
        let mut e = self.clone();
        match &mut e {
            Effect::Stribeck { level, .. } => *level *= k,
            Effect::AsymmetricFriction { c, c_plus, c_minus } => {
                *c_plus = *c + (*c_plus - *c) * k;
                *c_minus = *c + (*c_minus - *c) * k;
            }
            Effect::LoadDependentFriction { mu } => *mu *= k,
            Effect::ThermalDrift { alpha_b, alpha_c, .. } => {
                *alpha_b *= k;
                *alpha_c *= k;
            }
            Effect::PositionRipple { harmonics } => harmonics.iter_mut().for_each(|h| h.amplitude *= k),
            Effect::CableSpring { cable } => match cable {
                CableShape::OneSided { k: ks, .. } => *ks *= k,
                CableShape::Progressive { k1, k3, .. } => {
                    *k1 *= k;
                    *k3 *= k;
                }
                CableShape::Bump { amplitude, .. } => *amplitude *= k,
            },
            _ => {}
        }
        e
    }
}

/// level·exp(−(|v|/v_s)^δ): the Stribeck excess at speed v.
pub fn stribeck(level: f64, v_s: f64, delta: f64, v: f64) -> f64 {
    level * (-(v.abs() / v_s).powf(delta)).exp()
}

/// x shifted by the dead zone [lo, hi]: 0 inside, x − hi above, x − lo below.
pub fn dead_zone(x: f64, lo: f64, hi: f64) -> f64 {
    if x > hi {
        x - hi
    } else if x < lo {
        x - lo
    } else {
        0.0
    }
}

/// ln(1 + eˣ) without overflow.
fn softplus(x: f64) -> f64 {
    if x > 0.0 {
        x + (-x).exp().ln_1p()
    } else {
        x.exp().ln_1p()
    }
}

pub fn cable_torque(c: &CableShape, q: f64) -> f64 {
    match *c {
        CableShape::OneSided { k, q_e, side, smooth } => {
            let x = side * (q - q_e);
            let stretch = if smooth > 0.0 { smooth * softplus(x / smooth) } else { x.max(0.0) };
            side * k * stretch
        }
        CableShape::Progressive { k1, k3, q_s } => {
            let x = q - q_s;
            k1 * x + k3 * x * x * x
        }
        CableShape::Bump { amplitude, q_b, width } => {
            let z = (q - q_b) / width;
            amplitude * (-0.5 * z * z).exp()
        }
    }
}

/// Exact Dahl update over a monotone travel dq: F → c·sign(dq) exponentially in |dq|
/// with length c/σ; |F| ≤ c is kept whatever the step size.
pub fn dahl_step(f: f64, dq: f64, sigma: f64, c: f64) -> f64 {
    if dq == 0.0 || c <= 0.0 {
        return f;
    }
    let target = c * sgn(dq);
    target + (f - target) * (-sigma * dq.abs() / c).exp()
}

/// What the draws of an effect may look at.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// RMS of the file's disturbance over the log (N·m), the joint's torque scale.
    pub torque_scale: f64,
    pub q_lo: f64,
    pub q_hi: f64,
    pub duration: f64,
    /// RMS speed over the log (rad/s).
    pub v_rms: f64,
    /// The angle at the sample times, before any effect (what the log will cover).
    pub q: &'a [f64],
}

/// Draws one additive effect of `family` (not parameters / dry_friction / delay /
/// initial_state, which the mode modules draw because they change files or signals).
pub fn draw_additive(rng: &mut Rng64, family: &str, joint: &ModelFile, sc: &Scene) -> Option<Effect> {
    let c = joint.c();
    Some(match family {
        "stribeck" => Effect::Stribeck {
            level: uniform(rng, 0.1, 0.8) * c,
            v_s: log_uniform(rng, 0.005, 0.2),
            delta: uniform(rng, 0.5, 2.0),
        },
        "asymmetric_friction" => {
            let d = uniform(rng, 0.1, 0.5) * c;
            let w = uniform(rng, 0.0, 1.0);
            Effect::AsymmetricFriction { c, c_plus: c + w * d, c_minus: c - (1.0 - w) * d }
        }
        "load_dependent_friction" => Effect::LoadDependentFriction { mu: uniform(rng, 0.02, 0.2) },
        "thermal_drift" => draw_thermal(rng, sc),
        "position_ripple" => draw_ripple(rng, sc),
        "cable_spring" => Effect::CableSpring { cable: draw_cable(rng, joint, sc) },
        "backlash" => draw_backlash(rng, joint)?,
        "presliding_hysteresis" => {
            let x = log_uniform(rng, 1e-4, 5e-3);
            Effect::PreslidingHysteresis { sigma: c / x, c, presliding_distance: x }
        }
        _ => return None,
    })
}

fn draw_thermal(rng: &mut Rng64, sc: &Scene) -> Effect {
    // Warm grease: friction falls as the joint heats; viscous, Coulomb or both.
    let which = int(rng, 0, 2);
    let ab = if which != 1 { -uniform(rng, 0.004, 0.025) } else { 0.0 };
    let ac = if which != 0 { -uniform(rng, 0.004, 0.025) } else { 0.0 };
    Effect::ThermalDrift {
        alpha_b: ab,
        alpha_c: ac,
        temp0: uniform(rng, 18.0, 30.0),
        rise: uniform(rng, 10.0, 30.0),
        tau_th: uniform(rng, 0.2, 1.0) * sc.duration,
        temp_logged: chance(rng, 0.6),
    }
}

/// A ripple period of 0.01–0.3 rad, redrawn below half the span when fewer than two
/// periods would fit: over a shorter stretch a sine is mostly a slope and an offset, which
/// the file's spring, weight and offset terms absorb.
fn ripple_period(rng: &mut Rng64, span: f64) -> f64 {
    let p = log_uniform(rng, 0.01, 0.3);
    if p * crate::shown::MIN_PERIODS <= span {
        return p;
    }
    let hi = span / crate::shown::MIN_PERIODS;
    log_uniform(rng, 0.01f64.min(0.5 * hi), hi)
}

fn draw_ripple(rng: &mut Rng64, sc: &Scene) -> Effect {
    let span = sc.q_hi - sc.q_lo;
    let p = ripple_period(rng, span);
    let mut harmonics = vec![Ripple {
        amplitude: uniform(rng, 0.02, 0.2) * sc.torque_scale,
        period: p,
        phase: uniform(rng, 0.0, std::f64::consts::TAU),
    }];
    if chance(rng, 0.5) {
        // A second line: the mesh's own harmonic or an unrelated period (two stages).
        let p2 = if chance(rng, 0.5) { 0.5 * p } else { ripple_period(rng, span) };
        harmonics.push(Ripple {
            amplitude: uniform(rng, 0.02, 0.2) * sc.torque_scale,
            period: p2,
            phase: uniform(rng, 0.0, std::f64::consts::TAU),
        });
    }
    Effect::PositionRipple { harmonics }
}

fn draw_cable(rng: &mut Rng64, joint: &ModelFile, sc: &Scene) -> CableShape {
    let span = (sc.q_hi - sc.q_lo).max(1e-3);
    // Torque at the far end of the range is 5–50 % of the torque scale: visible, not dominant.
    let target = uniform(rng, 0.05, 0.5) * sc.torque_scale;
    match pick(rng, &[0u8, 1, 2]).unwrap_or(0) {
        0 => {
            let side = sign(rng);
            let frac = uniform(rng, 0.5, 0.9);
            let drawn = if side > 0.0 { sc.q_lo + frac * span } else { sc.q_hi - frac * span };
            let q_e = engage_within(sc.q, drawn, side);
            let reach = if q_e == drawn {
                (1.0 - frac) * span
            } else if side > 0.0 {
                (sc.q_hi - q_e).max(1e-6)
            } else {
                (q_e - sc.q_lo).max(1e-6)
            };
            let smooth = if chance(rng, 0.5) { uniform(rng, 0.1, 0.5) * reach } else { 0.0 };
            CableShape::OneSided { k: target / reach, q_e, side, smooth }
        }
        1 => {
            let q_s = 0.5 * (sc.q_lo + sc.q_hi) + uniform(rng, -0.2, 0.2) * span;
            let x = span * 0.6;
            // A linear part would be a spring-parameter error on a joint that has a spring.
            let lin = if joint.spring.is_some() { 0.0 } else { uniform(rng, 0.0, 0.3) };
            CableShape::Progressive { k1: lin * target / x, k3: (1.0 - lin) * target / (x * x * x), q_s }
        }
        _ => CableShape::Bump {
            amplitude: sign(rng) * target,
            q_b: sc.q_lo + uniform(rng, 0.2, 0.8) * span,
            width: uniform(rng, 0.05, 0.25) * span,
        },
    }
}

/// Moves a one-sided cable's engage angle so it is taut for 5–95 % of the samples: never
/// taut it adds nothing, always taut it is a linear spring plus an offset (a parameter
/// error of the file). Inside that band the drawn angle is kept.
fn engage_within(q: &[f64], q_e: f64, side: f64) -> f64 {
    if q.is_empty() {
        return q_e;
    }
    let (lo, hi) = crate::shown::CABLE_SHARE;
    let engaged = crate::shown::share(q, |x| side * (x - q_e) > 0.0);
    // The nearest share inside the band, a little inside so ties at sample values hold.
    let target = if engaged < lo {
        lo + 0.01
    } else if engaged > hi {
        hi - 0.01
    } else {
        return q_e;
    };
    let p = if side > 0.0 { 1.0 - target } else { target };
    crate::shown::quantile(q, p)
}

fn draw_backlash(rng: &mut Rng64, joint: &ModelFile) -> Option<Effect> {
    let s = joint.spring?;
    let w = uniform(rng, 0.002, 0.02);
    let (lo, hi) = match int(rng, 0, 2) {
        0 => (-0.5 * w, 0.5 * w),
        1 => (0.0, w),
        _ => (-w, 0.0),
    };
    Some(Effect::Backlash { k: s.k, q0: s.q0, lo, hi })
}
