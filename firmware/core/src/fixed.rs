//! Fixed-point path for boards without an FPU: friction + weight + spring in Q16.16
//! ([`I16F16`]: ±32768 range, 1.5e-5 resolution).
//!
//! Every operation saturates instead of wrapping or panicking. The sine uses a quarter-wave
//! table of 257 points built at compile time, indexed by the angle converted to a 32-bit phase
//! (full turn = 2³²) with 64-bit arithmetic, so large angles lose no precision in the range
//! reduction; linear interpolation between points bounds its error to ~5e-6.
//!
//! Worst error against the f32 path over the trunk-joint operating range (q ∈ [−0.2, 2.2] rad,
//! q̇ ∈ [−2, 2] rad/s, Table 1 parameters of both joints, spring of the elastic joint):
//! measured by `tests/fixed_point.rs`, which asserts ≤ 0.002 N·m (the target is
//! 0.01 N·m); the README quotes the printed figure.

use crate::params::{ParamId, ParamSet};
use fixed::types::I16F16;

pub type Fx = I16F16;

/// Fixed-point copy of the parameters the fixed path uses, converted once per parameter change.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FixedParams {
    pub fa: Fx,
    pub fb: Fx,
    pub fc: Fx,
    pub v_band: Fx,
    pub amplitude: Fx,
    pub s: Fx,
    pub phi: Fx,
    pub k: Fx,
    pub b: Fx,
    pub q0: Fx,
}

impl FixedParams {
    pub fn from_set(p: &ParamSet) -> Self {
        let f = |id: ParamId| Fx::saturating_from_num(p.get(id));
        FixedParams {
            fa: f(ParamId::FrictionA),
            fb: f(ParamId::FrictionB),
            fc: f(ParamId::FrictionC),
            v_band: f(ParamId::FrictionVBand),
            amplitude: f(ParamId::WeightAmplitude),
            s: f(ParamId::WeightS),
            phi: f(ParamId::WeightPhi),
            k: f(ParamId::SpringK),
            b: f(ParamId::SpringB),
            q0: f(ParamId::SpringQ0),
        }
    }
}

const QUARTER_POINTS: usize = 256;

/// sin over [0, π/2] at 257 points in Q1.30, by Taylor series in f64 at compile time
/// (terms to x^25: truncation error < 1e-20 on [0, π/2]).
const SIN_TABLE: [i32; QUARTER_POINTS + 1] = build_sin_table();

const fn build_sin_table() -> [i32; QUARTER_POINTS + 1] {
    let mut t = [0i32; QUARTER_POINTS + 1];
    let mut i = 0;
    while i <= QUARTER_POINTS {
        let x = (i as f64) * (core::f64::consts::FRAC_PI_2 / QUARTER_POINTS as f64);
        let mut term = x;
        let mut sum = x;
        let mut n = 1;
        while n < 13 {
            term = -term * x * x / (((2 * n) * (2 * n + 1)) as f64);
            sum += term;
            n += 1;
        }
        let scaled = sum * 1073741824.0; // 2^30
                                         // const fn: no iterators; i ≤ QUARTER_POINTS by the loop condition.
        #[allow(clippy::indexing_slicing)]
        {
            t[i] = (scaled + 0.5) as i32;
        }
        i += 1;
    }
    t
}

/// 2³²/(2π): radians in Q16.16 → phase in turns·2³² after `>> 16`.
const RAD_TO_PHASE: i64 = 683_565_276;

/// sin of a Q16.16 angle in radians, Q16.16 result.
pub fn sin_fx(theta: Fx) -> Fx {
    let phase = ((theta.to_bits() as i64).wrapping_mul(RAD_TO_PHASE) >> 16) as u32;
    let quadrant = phase >> 30;
    let mut pos = phase & 0x3FFF_FFFF;
    if quadrant & 1 == 1 {
        pos = 0x4000_0000 - pos;
    }
    let idx = (pos >> 22) as usize;
    let frac = (pos & 0x3F_FFFF) as i64;
    let a = SIN_TABLE.get(idx).copied().unwrap_or(1 << 30) as i64;
    let b = SIN_TABLE.get(idx + 1).copied().unwrap_or(1 << 30) as i64;
    let v = a + (((b - a) * frac) >> 22);
    let v = if quadrant >= 2 { -v } else { v };
    // Q1.30 → Q16.16 with rounding.
    Fx::from_bits(((v + (1 << 13)) >> 14) as i32)
}

fn sign_smooth_fx(v: Fx, band: Fx) -> Fx {
    let one = Fx::ONE;
    if band > Fx::ZERO {
        let r = ((v.to_bits() as i64) << 16) / (band.to_bits() as i64);
        Fx::from_bits(r.clamp(-(one.to_bits() as i64), one.to_bits() as i64) as i32)
    } else if v > Fx::ZERO {
        one
    } else if v < Fx::ZERO {
        -one
    } else {
        Fx::ZERO
    }
}

/// Friction `a·q̇|q̇| + b·q̇ + c·sign(q̇)` in fixed point.
pub fn friction_fx(p: &FixedParams, qd: Fx) -> Fx {
    let quad = p.fa.saturating_mul(qd.saturating_mul(qd.saturating_abs()));
    let visc = p.fb.saturating_mul(qd);
    let coul = p.fc.saturating_mul(sign_smooth_fx(qd, p.v_band));
    quad.saturating_add(visc).saturating_add(coul)
}

/// Weight `C_w0·sin(s·q + φ)` in fixed point.
pub fn weight_fx(p: &FixedParams, q: Fx) -> Fx {
    p.amplitude.saturating_mul(sin_fx(p.s.saturating_mul(q).saturating_add(p.phi)))
}

/// Spring-damper `K(q − q0) + B·q̇` in fixed point.
pub fn spring_fx(p: &FixedParams, q: Fx, qd: Fx) -> Fx {
    p.k.saturating_mul(q.saturating_sub(p.q0)).saturating_add(p.b.saturating_mul(qd))
}

/// friction + weight + spring: the disturbance terms an FPU-less board compensates.
pub fn disturbance_fx(p: &FixedParams, q: Fx, qd: Fx) -> Fx {
    friction_fx(p, qd).saturating_add(weight_fx(p, q)).saturating_add(spring_fx(p, q, qd))
}
