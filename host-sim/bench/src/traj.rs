//! Prescribed joint trajectories for torque mode, each with exact q, q̇, q̈ at any t.
//!
//! Torque-mode logs assume ideal position control, so the kinematics are known exactly and
//! the disturbance can be computed sample by sample; analytic derivatives (not finite
//! differences) keep the "none" cases free of any error the model file cannot explain.

use serde::Serialize;

use crate::rngs::{chance, int, log_uniform, normal, uniform, Rng64};

/// q, q̇, q̈ at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Kin {
    pub q: f64,
    pub qd: f64,
    pub qdd: f64,
}

/// One point-to-point move: min-jerk from q0 at t0 to q1 at t1, rest outside.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Move {
    pub t0: f64,
    pub t1: f64,
    pub q0: f64,
    pub q1: f64,
}

/// The trajectory families of the brief.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "family", rename_all = "snake_case")]
pub enum Shape {
    /// Swevers-style identification excitation: Σ a_l/(ωl)·sin(ωlt) − b_l/(ωl)·cos(ωlt).
    Fourier { f_base: f64, a: Vec<f64>, b: Vec<f64> },
    /// sin of a linearly swept phase, ramped in and out so it starts and ends at rest.
    LinearChirp { f0: f64, f1: f64, t_end: f64, ramp: f64 },
    /// Same with an exponential sweep.
    LogChirp { f0: f64, f1: f64, t_end: f64, ramp: f64 },
    /// Min-jerk moves separated by dwells (q̇ exactly 0 while dwelling).
    PointToPoint { moves: Vec<Move> },
    /// Uniform cubic B-spline through a random walk; four equal knots make an exact pause.
    HandMoved { t_start: f64, dt_knot: f64, knots: Vec<f64>, pauses: usize },
}

/// q(t) = center + scale·(shape(t) − mid).
#[derive(Debug, Clone, Serialize)]
pub struct Trajectory {
    pub shape: Shape,
    pub center: f64,
    pub scale: f64,
    pub mid: f64,
    /// True when the truth has stretches with q̇ exactly 0.
    pub rest_phases: bool,
}

/// Speed, acceleration and range the drawn trajectory is shrunk into.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub v_max: f64,
    pub a_max: f64,
    pub half_range: f64,
    pub center: f64,
}

impl Shape {
    pub fn family(&self) -> &'static str {
        match self {
            Shape::Fourier { .. } => "fourier",
            Shape::LinearChirp { .. } => "linear_chirp",
            Shape::LogChirp { .. } => "log_chirp",
            Shape::PointToPoint { .. } => "point_to_point",
            Shape::HandMoved { .. } => "hand_moved",
        }
    }

    pub fn eval(&self, t: f64) -> Kin {
        match self {
            Shape::Fourier { f_base, a, b } => fourier(*f_base, a, b, t),
            Shape::LinearChirp { f0, f1, t_end, ramp } => {
                let k = (f1 - f0) / t_end;
                let tau = std::f64::consts::TAU;
                let ph = (tau * (f0 * t + 0.5 * k * t * t), tau * (f0 + k * t), tau * k);
                chirp(ph, ramp_window(t, *t_end, *ramp))
            }
            Shape::LogChirp { f0, f1, t_end, ramp } => {
                let lk = (f1 / f0).ln();
                let tau = std::f64::consts::TAU;
                let g = (lk * t / t_end).exp();
                let p1 = tau * f0 * g;
                let ph = (tau * f0 * t_end / lk * (g - 1.0), p1, p1 * lk / t_end);
                chirp(ph, ramp_window(t, *t_end, *ramp))
            }
            Shape::PointToPoint { moves } => point_to_point(moves, t),
            Shape::HandMoved { t_start, dt_knot, knots, .. } => bspline(*t_start, *dt_knot, knots, t),
        }
    }

    /// Highest frequency the shape contains (Hz), used to size sensor filters.
    pub fn f_max(&self) -> f64 {
        match self {
            Shape::Fourier { f_base, a, .. } => f_base * a.len() as f64,
            Shape::LinearChirp { f0, f1, .. } | Shape::LogChirp { f0, f1, .. } => f0.max(*f1),
            Shape::PointToPoint { moves } => moves.iter().map(|m| 1.0 / (m.t1 - m.t0).max(1e-3)).fold(0.2, f64::max),
            Shape::HandMoved { dt_knot, .. } => 1.0 / dt_knot,
        }
    }
}

impl Trajectory {
    pub fn eval(&self, t: f64) -> Kin {
        let k = self.shape.eval(t);
        Kin { q: self.center + self.scale * (k.q - self.mid), qd: self.scale * k.qd, qdd: self.scale * k.qdd }
    }
}

fn fourier(f_base: f64, a: &[f64], b: &[f64], t: f64) -> Kin {
    let w = std::f64::consts::TAU * f_base;
    let mut k = Kin::default();
    for (l, (al, bl)) in a.iter().zip(b).enumerate() {
        let wl = w * (l + 1) as f64;
        let (s, c) = (wl * t).sin_cos();
        k.q += al / wl * s - bl / wl * c;
        k.qd += al * c + bl * s;
        k.qdd += -al * wl * s + bl * wl * c;
    }
    k
}

/// Quintic smoothstep and its first two derivatives on x ∈ [0, 1].
fn smoothstep5(x: f64) -> (f64, f64, f64) {
    let x = x.clamp(0.0, 1.0);
    let x2 = x * x;
    (x2 * x * (10.0 - 15.0 * x + 6.0 * x2), 30.0 * x2 * (1.0 - 2.0 * x + x2), 60.0 * x * (1.0 - 3.0 * x + 2.0 * x2))
}

/// Window w(t) that rises over `ramp`, holds 1 and falls over the last `ramp` before t_end.
fn ramp_window(t: f64, t_end: f64, ramp: f64) -> (f64, f64, f64) {
    if t <= 0.0 || t >= t_end {
        (0.0, 0.0, 0.0)
    } else if t < ramp {
        let (s, s1, s2) = smoothstep5(t / ramp);
        (s, s1 / ramp, s2 / (ramp * ramp))
    } else if t > t_end - ramp {
        let (s, s1, s2) = smoothstep5((t_end - t) / ramp);
        (s, -s1 / ramp, s2 / (ramp * ramp))
    } else {
        (1.0, 0.0, 0.0)
    }
}

/// w·sin(φ) and its derivatives by the product rule; `ph` = (φ, φ', φ'').
fn chirp(ph: (f64, f64, f64), w: (f64, f64, f64)) -> Kin {
    let (s, c) = ph.0.sin_cos();
    Kin {
        q: w.0 * s,
        qd: w.1 * s + w.0 * c * ph.1,
        qdd: w.2 * s + 2.0 * w.1 * c * ph.1 + w.0 * (c * ph.2 - s * ph.1 * ph.1),
    }
}

fn point_to_point(moves: &[Move], t: f64) -> Kin {
    let i = moves.partition_point(|m| m.t1 <= t);
    let Some(m) = moves.get(i) else {
        return Kin { q: moves.last().map_or(0.0, |m| m.q1), ..Kin::default() };
    };
    if t <= m.t0 {
        // Dwelling before this move: exactly at rest.
        return Kin { q: m.q0, ..Kin::default() };
    }
    let d = m.t1 - m.t0;
    let (s, s1, s2) = smoothstep5((t - m.t0) / d);
    let dq = m.q1 - m.q0;
    Kin { q: m.q0 + dq * s, qd: dq * s1 / d, qdd: dq * s2 / (d * d) }
}

/// Uniform cubic B-spline; derivatives from the control-point differences so that four
/// equal points give q̇ = q̈ = 0 exactly, not a rounding residue.
fn bspline(t_start: f64, dt: f64, p: &[f64], t: f64) -> Kin {
    let segments = p.len().saturating_sub(3);
    if segments == 0 {
        return Kin::default();
    }
    let x = ((t - t_start) / dt).clamp(0.0, segments as f64 - 1e-12);
    let i = x.floor() as usize;
    let u = x - i as f64;
    let get = |k: usize| p.get(i + k).copied().unwrap_or(0.0);
    let (p0, p1, p2, p3) = (get(0), get(1), get(2), get(3));
    let u2 = u * u;
    let u3 = u2 * u;
    let q = ((1.0 - u).powi(3) * p0
        + (3.0 * u3 - 6.0 * u2 + 4.0) * p1
        + (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) * p2
        + u3 * p3)
        / 6.0;
    let (d0, d1, d2) = (p1 - p0, p2 - p1, p3 - p2);
    let qd = (0.5 * (1.0 - u).powi(2) * d0 + (-u2 + u + 0.5) * d1 + 0.5 * u2 * d2) / dt;
    let qdd = ((d1 - d0) * (1.0 - u) + (d2 - d1) * u) / (dt * dt);
    Kin { q, qd, qdd }
}

/// Draws a trajectory of the given family over [0, duration] and shrinks it into `lim`.
pub fn draw(rng: &mut Rng64, family: &str, duration: f64, lim: Limits, want_rest: bool) -> Trajectory {
    let shape = match family {
        "linear_chirp" | "log_chirp" => draw_chirp(rng, family, duration, lim),
        "point_to_point" => draw_p2p(rng, duration, lim, want_rest),
        "hand_moved" => draw_hand(rng, duration, want_rest),
        _ => draw_fourier(rng),
    };
    let rest_phases = match &shape {
        // The log starts at rest before the first move, and dwells add more.
        Shape::PointToPoint { moves } => !moves.is_empty(),
        Shape::HandMoved { pauses, .. } => *pauses > 0,
        _ => false,
    };
    fit(shape, duration, lim, rest_phases)
}

fn draw_fourier(rng: &mut Rng64) -> Shape {
    let n = int(rng, 3, 6);
    let f_base = uniform(rng, 0.05, 0.3);
    // Coefficients fall off with the harmonic so the velocity spectrum stays plausible.
    let decay = uniform(rng, 0.0, 1.0);
    let mut a = Vec::with_capacity(n);
    let mut b = Vec::with_capacity(n);
    for l in 1..=n {
        let g = (l as f64).powf(-decay);
        a.push(normal(rng) * g);
        b.push(normal(rng) * g);
    }
    Shape::Fourier { f_base, a, b }
}

fn draw_chirp(rng: &mut Rng64, family: &str, duration: f64, lim: Limits) -> Shape {
    let f0 = uniform(rng, 0.03, 0.2);
    // The top frequency is bounded by what the acceleration limit allows at ≥ 0.05 rad.
    let f_top = (lim.a_max / 0.05).sqrt() / std::f64::consts::TAU;
    let f1 = uniform(rng, 0.5, 3.0).min(f_top.max(0.3));
    let ramp = uniform(rng, 0.5, 2.0).min(0.2 * duration);
    if family == "log_chirp" {
        Shape::LogChirp { f0, f1, t_end: duration, ramp }
    } else {
        Shape::LinearChirp { f0, f1, t_end: duration, ramp }
    }
}

fn draw_p2p(rng: &mut Rng64, duration: f64, lim: Limits, want_rest: bool) -> Shape {
    let mut moves = Vec::new();
    let mut t = uniform(rng, 0.2, 2.0);
    let mut q = lim.center + uniform(rng, -1.0, 1.0) * lim.half_range;
    let no_dwell = !want_rest && chance(rng, 0.4);
    while t < duration - 0.5 {
        let target = lim.center + uniform(rng, -1.0, 1.0) * lim.half_range;
        let dq = (target - q).abs().max(1e-3);
        // Min-jerk peaks: v = 1.875·Δ/D, a = 5.77·Δ/D².
        let d_min = (1.875 * dq / lim.v_max).max((5.78 * dq / lim.a_max).sqrt());
        let d = uniform(rng, 0.5, 3.0).max(d_min);
        if t + d > duration {
            break;
        }
        moves.push(Move { t0: t, t1: t + d, q0: q, q1: target });
        q = target;
        t += d + if no_dwell { 0.0 } else { uniform(rng, 0.2, 3.0) };
    }
    Shape::PointToPoint { moves }
}

fn draw_hand(rng: &mut Rng64, duration: f64, want_rest: bool) -> Shape {
    let dt_knot = uniform(rng, 0.25, 1.0);
    let t_start = -3.0 * dt_knot;
    let n = ((duration + 6.0 * dt_knot) / dt_knot).ceil() as usize + 3;
    let pause_p = if want_rest || chance(rng, 0.4) { uniform(rng, 0.05, 0.15) } else { 0.0 };
    let mut knots = Vec::with_capacity(n + 8);
    let mut x = 0.0;
    let mut pauses = 0;
    while knots.len() < n {
        if chance(rng, pause_p) {
            // Four equal control points: one whole segment exactly at rest.
            let len = int(rng, 4, 6);
            knots.extend(std::iter::repeat_n(x, len));
            pauses += 1;
        } else {
            // Reflecting random walk in [−1, 1].
            x += 0.5 * normal(rng);
            x = if x > 1.0 {
                2.0 - x
            } else if x < -1.0 {
                -2.0 - x
            } else {
                x
            };
            knots.push(x.clamp(-1.0, 1.0));
        }
    }
    Shape::HandMoved { t_start, dt_knot, knots, pauses }
}

/// Scales the shape about its mid-range so it respects range, speed and acceleration.
fn fit(shape: Shape, duration: f64, lim: Limits, rest_phases: bool) -> Trajectory {
    let dt = (0.02 / shape.f_max().max(0.05)).min(0.005);
    let n = (duration / dt).ceil() as usize;
    let (mut lo, mut hi, mut vm, mut am) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64, 0.0f64);
    for i in 0..=n {
        let k = shape.eval(i as f64 * dt);
        lo = lo.min(k.q);
        hi = hi.max(k.q);
        vm = vm.max(k.qd.abs());
        am = am.max(k.qdd.abs());
    }
    let half = (0.5 * (hi - lo)).max(1e-9);
    let scale = (lim.half_range / half).min(lim.v_max / vm.max(1e-12)).min(lim.a_max / am.max(1e-12));
    Trajectory { shape, center: lim.center, scale, mid: 0.5 * (hi + lo), rest_phases }
}

/// Picks a family name with equal odds (the brief's four families, chirps split in two).
pub fn draw_family(rng: &mut Rng64, want_rest: bool) -> &'static str {
    if want_rest {
        return if chance(rng, 0.6) { "point_to_point" } else { "hand_moved" };
    }
    crate::rngs::pick(rng, &["fourier", "linear_chirp", "log_chirp", "point_to_point", "hand_moved"])
        .unwrap_or("fourier")
}

/// Limits for a joint kind: range within ±1.5 rad, speeds and accelerations of its use.
pub fn limits_for(rng: &mut Rng64, kind: &str) -> Limits {
    let (v, a, r) = match kind {
        "trunk" => (1.6, 8.0, 1.0),
        "arm" => (2.5, 15.0, 1.2),
        _ => (4.0, 80.0, 0.6),
    };
    let half_range = uniform(rng, 0.3, 1.0) * r;
    let center = uniform(rng, -1.0, 1.0) * (1.5 - half_range).min(0.5);
    Limits { v_max: v * uniform(rng, 0.3, 1.0), a_max: a * log_uniform(rng, 0.2, 1.0), half_range, center }
}
