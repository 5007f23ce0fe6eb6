//! Free-response integrator for trajectory mode: J·q̈ = u − friction − weight − offset −
//! spring − effects, RK4 on fine sub-steps, with Karnopp stick-slip for pure Coulomb
//! friction: a velocity zero crossing is located by bisection, and the joint sticks there
//! while the net non-friction torque stays within the static level.

use serde::Serialize;

use crate::effects::{stribeck, CableShape, Effect};
use crate::model::{sgn, ModelFile, SignLaw};

/// A known input torque u(t), zero before `t_on`.
#[derive(Debug, Clone, Serialize)]
pub struct Input {
    pub kind: &'static str,
    pub t_on: f64,
    pub ramp: f64,
    pub level: f64,
    /// Pulse end (∞ for a step).
    pub t_off: f64,
    /// (amplitude, frequency Hz, phase) for the smooth random kind.
    pub components: Vec<(f64, f64, f64)>,
}

impl Input {
    pub fn zero() -> Input {
        Input { kind: "none", t_on: f64::INFINITY, ramp: 1.0, level: 0.0, t_off: f64::INFINITY, components: Vec::new() }
    }

    pub fn at(&self, t: f64) -> f64 {
        let up = edge((t - self.t_on) / self.ramp);
        let down = edge((t - self.t_off) / self.ramp);
        let waves: f64 =
            self.components.iter().map(|(a, f, p)| a * (std::f64::consts::TAU * f * (t - self.t_on) + p).sin()).sum();
        (self.level * (up - down)) + up * waves
    }
}

/// Smooth 0→1 edge (quintic) so the RK4 sub-steps see no jump.
fn edge(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
}

/// How the Coulomb part of friction acts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coulomb {
    None,
    /// c·sign(v) with stick-slip; levels per direction.
    Pure {
        c_plus: f64,
        c_minus: f64,
    },
    /// c·clamp(v/v_band): smooth, no sticking.
    Band {
        vb: f64,
        c_plus: f64,
        c_minus: f64,
    },
    /// Dahl state replaces the Coulomb term.
    Dahl {
        sigma: f64,
        c: f64,
    },
}

/// Everything the integrator needs: the joint's terms, the additive effects, the input.
#[derive(Debug, Clone)]
pub struct Dynamics {
    pub model: ModelFile,
    pub coulomb: Coulomb,
    /// (level, v_s, δ) of a Stribeck excess.
    pub stribeck: Option<(f64, f64, f64)>,
    /// Effects that add a torque of q alone (ripple, cable, backlash).
    pub position_effects: Vec<Effect>,
    pub input: Input,
    /// The input acts as u(t − shift) (a file model fed the delayed logged u).
    pub input_shift: f64,
}

/// Integrator state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    pub q: f64,
    pub v: f64,
    /// Dahl friction state (unused otherwise).
    pub f: f64,
}

impl State {
    fn plus(self, d: State, h: f64) -> State {
        State { q: self.q + h * d.q, v: self.v + h * d.v, f: self.f + h * d.f }
    }
}

impl Dynamics {
    /// Builds the dynamics of `model` with the given effects (friction effects folded into
    /// the Coulomb law, position effects kept as extra torques).
    pub fn new(model: &ModelFile, effects: &[Effect], input: Input, input_shift: f64) -> Dynamics {
        let c = model.c();
        let (mut cp, mut cm) = (c, c);
        let mut stribeck_p = None;
        let mut dahl = None;
        let mut position_effects = Vec::new();
        for e in effects {
            match e {
                Effect::AsymmetricFriction { c_plus, c_minus, .. } => {
                    cp = *c_plus;
                    cm = *c_minus;
                }
                Effect::Stribeck { level, v_s, delta } => stribeck_p = Some((*level, *v_s, *delta)),
                Effect::PreslidingHysteresis { sigma, c, .. } => dahl = Some((*sigma, *c)),
                Effect::PositionRipple { .. } | Effect::CableSpring { .. } | Effect::Backlash { .. } => {
                    position_effects.push(e.clone())
                }
                _ => {}
            }
        }
        let coulomb = match (dahl, model.sign_law()) {
            (Some((sigma, c)), _) => Coulomb::Dahl { sigma, c },
            _ if cp <= 0.0 && cm <= 0.0 && stribeck_p.is_none() => Coulomb::None,
            (None, SignLaw::Pure) => Coulomb::Pure { c_plus: cp, c_minus: cm },
            (None, SignLaw::Band(vb)) => Coulomb::Band { vb, c_plus: cp, c_minus: cm },
        };
        Dynamics { model: model.clone(), coulomb, stribeck: stribeck_p, position_effects, input, input_shift }
    }

    /// Net torque that does not depend on velocity: input minus position terms.
    pub fn non_friction(&self, t: f64, q: f64) -> f64 {
        let extra: f64 = self.position_effects.iter().map(|e| e.position_delta(q)).sum();
        self.input.at(t - self.input_shift) - self.model.position_terms(q) - extra
    }

    fn excess(&self, v: f64) -> f64 {
        self.stribeck.map_or(0.0, |(l, vs, d)| stribeck(l, vs, d, v))
    }

    /// The Coulomb-like friction force; `dir` is the sliding direction for the pure law.
    fn coulomb_force(&self, v: f64, f: f64, dir: f64) -> f64 {
        match self.coulomb {
            Coulomb::None => 0.0,
            Coulomb::Pure { c_plus, c_minus } => {
                let c = if dir > 0.0 { c_plus } else { c_minus };
                (c + self.excess(v)) * dir
            }
            Coulomb::Band { vb, c_plus, c_minus } => {
                let c = if v > 0.0 { c_plus } else { c_minus };
                (c + self.excess(v)) * (v / vb).clamp(-1.0, 1.0)
            }
            Coulomb::Dahl { .. } => f,
        }
    }

    fn deriv(&self, t: f64, y: State, dir: f64) -> State {
        let fr = self.model.smooth_friction(y.v) + self.coulomb_force(y.v, y.f, dir);
        let dv = (self.non_friction(t, y.q) - fr) / self.model.j();
        let df = match self.coulomb {
            Coulomb::Dahl { sigma, c } if c > 0.0 => sigma * (y.v - y.v.abs() * y.f / c),
            _ => 0.0,
        };
        State { q: y.v, v: dv, f: df }
    }

    fn rk4(&self, y: State, t: f64, h: f64, dir: f64) -> State {
        let k1 = self.deriv(t, y, dir);
        let k2 = self.deriv(t + 0.5 * h, y.plus(k1, 0.5 * h), dir);
        let k3 = self.deriv(t + 0.5 * h, y.plus(k2, 0.5 * h), dir);
        let k4 = self.deriv(t + h, y.plus(k3, h), dir);
        let d = State {
            q: (k1.q + 2.0 * k2.q + 2.0 * k3.q + k4.q) / 6.0,
            v: (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v) / 6.0,
            f: (k1.f + 2.0 * k2.f + 2.0 * k3.f + k4.f) / 6.0,
        };
        y.plus(d, h)
    }

    /// Breakaway levels (+, −) at rest: Coulomb plus the full Stribeck excess.
    fn static_levels(&self) -> (f64, f64) {
        let ex = self.excess(0.0);
        match self.coulomb {
            Coulomb::Pure { c_plus, c_minus } => (c_plus + ex, c_minus + ex),
            _ => (0.0, 0.0),
        }
    }

    /// Advances the state by h from t.
    pub fn step(&self, y: State, t: f64, h: f64) -> State {
        match self.coulomb {
            Coulomb::Pure { .. } => self.step_stick_slip(y, t, h),
            _ => self.rk4(y, t, h, 0.0),
        }
    }

    fn step_stick_slip(&self, mut y: State, t: f64, h: f64) -> State {
        let end = t + h;
        let mut t = t;
        // Each pass either finishes the step or stops at a velocity zero; a few suffice.
        for _ in 0..8 {
            let left = end - t;
            if left <= 0.0 {
                break;
            }
            let dir = if y.v != 0.0 {
                sgn(y.v)
            } else {
                let tn = self.non_friction(t, y.q) - self.model.smooth_friction(0.0);
                let (sp, sm) = self.static_levels();
                if tn <= sp && tn >= -sm {
                    // Stuck: stays put until a later sub-step's torque exceeds the level.
                    break;
                }
                sgn(tn)
            };
            let next = self.rk4(y, t, left, dir);
            if next.v * dir > 0.0 {
                return next;
            }
            let (mut lo, mut hi) = (0.0, left);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if self.rk4(y, t, mid, dir).v * dir > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let at = self.rk4(y, t, hi, dir);
            y = State { q: at.q, v: 0.0, f: at.f };
            t += hi;
        }
        y
    }

    /// The largest sub-step that keeps RK4 accurate here: a fraction of the fastest
    /// oscillation period, of the band's and the damping's time constants, and of the
    /// Dahl state's travel length at speed `v`.
    pub fn max_step(&self, v: f64, span: f64) -> f64 {
        let j = self.model.j().max(1e-12);
        let mut stiff =
            self.model.spring.map_or(0.0, |s| s.k) + self.model.weight.map_or(0.0, |w| (w.amplitude * w.s).abs());
        stiff += self.position_effects.iter().map(|e| effect_stiffness(e, span)).sum::<f64>();
        let mut h = f64::INFINITY;
        if let Coulomb::Dahl { sigma, c } = self.coulomb {
            stiff += sigma;
            h = h.min(0.2 * c / (sigma * v.abs()).max(1e-12));
        }
        h = h.min(0.03 / (stiff / j).sqrt().max(1e-9));
        let f = self.model.friction.unwrap_or_default();
        let damp =
            f.b.unwrap_or(0.0) + self.model.spring.map_or(0.0, |s| s.b) + 2.0 * f.a.unwrap_or(0.0).abs() * v.abs();
        h = h.min(0.5 * j / damp.max(1e-12));
        if let Coulomb::Band { vb, c_plus, c_minus } = self.coulomb {
            let c = c_plus.max(c_minus) + self.excess(0.0);
            h = h.min(0.5 * j * vb / c.max(1e-12));
        }
        h
    }
}

/// Local stiffness bound (N·m/rad) of a position effect over an angle span.
fn effect_stiffness(e: &Effect, span: f64) -> f64 {
    match e {
        Effect::PositionRipple { harmonics } => {
            harmonics.iter().map(|h| h.amplitude.abs() * std::f64::consts::TAU / h.period).sum()
        }
        Effect::CableSpring { cable } => match *cable {
            CableShape::OneSided { k, smooth, .. } => k.abs() * if smooth > 0.0 { 1.0 } else { 1.5 },
            CableShape::Progressive { k1, k3, .. } => k1.abs() + 3.0 * k3.abs() * span * span,
            CableShape::Bump { amplitude, width, .. } => amplitude.abs() / (width * width),
        },
        Effect::Backlash { k, .. } => k.abs(),
        _ => 0.0,
    }
}

/// Integrates from (t_start, y0) and returns the state at each of `times` (≥ t_start),
/// with at least `min_sub` sub-steps per sample interval.
pub fn simulate(dy: &Dynamics, t_start: f64, y0: State, times: &[f64], min_sub: usize, span: f64) -> Vec<State> {
    let mut y = y0;
    let mut t = t_start;
    let mut out = Vec::with_capacity(times.len());
    for &ts in times {
        let gap = ts - t;
        if gap > 0.0 {
            let accel = dy.deriv(t, y, if y.v != 0.0 { sgn(y.v) } else { 1.0 }).v.abs();
            let v_bound = y.v.abs() + accel * gap;
            let h = dy.max_step(v_bound, span);
            let n = ((gap / h).ceil() as usize).clamp(min_sub.max(1), 200_000);
            let hs = gap / n as f64;
            for i in 0..n {
                y = dy.step(y, t + i as f64 * hs, hs);
            }
            t = ts;
        }
        out.push(y);
    }
    out
}
