//! Fixed-point path for boards without an FPU: the whole control step in Q16.16 ([`I16F16`]:
//! ±32768 range, 1.5e-5 resolution), [`ControllerFx`]: friction + weight + spring here, with the
//! pre-sliding (Dahl) friction state when `presliding.sigma > 0` ([`DahlFx`],
//! [`disturbance_stateful_fx`]); the gravity table with fusion, the gravity series and the effect
//! terms in [`crate::fixed_gravity`]; inertia, offset, the assist law, the modes, the limits
//! and 1/(N − 1) in [`ControllerFx::step`]. A board picks it or the f32 step when its image is
//! built ([`Arithmetic`], the node's type parameter) and names it in its identity.
//!
//! Terms are Q16.16 values carried in an i64 and saturated once, on the total: nothing wraps,
//! and no intermediate saturates (`tests/fixed_accuracy.rs` measures every term against f64
//! over the parameter table's ranges). The sine uses a quarter-wave
//! table of 257 points built at compile time, indexed by the angle converted to a 32-bit phase
//! (full turn = 2³²) with 64-bit arithmetic, so large angles lose no precision in the range
//! reduction; linear interpolation between points bounds its error to ~5e-6.
//!
//! Worst error against the f32 path over the trunk-joint operating range (q ∈ [−0.2, 2.2] rad,
//! q̇ ∈ [−2, 2] rad/s, Table 1 parameters of both joints, spring of the elastic joint):
//! measured by `tests/fixed_point.rs`, which asserts ≤ 0.002 N·m (the target is
//! 0.01 N·m); the README quotes the printed figure.
//!
//! The Dahl state follows the f32 path ([`crate::model::Presliding`]): the same exact
//! exponential update over each step's travel, `F' = T + (F − T)·exp(−(σ/c)·|Δq|)` with
//! `T = c·sign(Δq)`, its level the whole Coulomb level `friction.c + dry_friction.c` (outside
//! a Dahl state dry friction is one of the effect terms). `exp(−x)` is
//! `2^(−n)·exp(−g)` with `x·log₂e = n + g/ln 2`: a shift and a 10-term Taylor series in 64-bit
//! integers (error < 4e-8). F is carried with 24 fractional bits and handed out in Q16.16, never
//! outside `[−c, c]`. Limits of the format: σ/c saturates at 32767 1/rad (a pre-sliding
//! distance below 31 µrad acts as 31 µrad), and an angle is resolved to 15 µrad: F's slope
//! right after a reversal is 2σ, so when the angle itself is rounded F can differ from the f32
//! path's by up to 2σ·2⁻¹⁶ there (on angles both paths hold exactly, by Q16.16's resolution);
//! `tests/fixed_point.rs` measures both.

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
    /// 1/v_band (0 when the band is 0: the hard sign)
    pub inv_band: Gain,
    pub amplitude: Fx,
    pub s: Fx,
    pub phi: Fx,
    pub k: Fx,
    pub b: Fx,
    pub q0: Fx,
    /// presliding on: the Coulomb term is a [`DahlFx`] state
    pub dahl_on: bool,
    /// the Dahl state's level c = friction.c + dry_friction.c, N·m
    pub dahl_c: Fx,
    /// σ/c, 1/rad (saturated at Q16.16's maximum)
    pub dahl_k: Fx,
}

impl FixedParams {
    pub fn from_set(p: &ParamSet) -> Self {
        let f = |id: ParamId| Fx::saturating_from_num(p.get(id));
        let pre = p.terms().presliding;
        FixedParams {
            fa: f(ParamId::FrictionA),
            fb: f(ParamId::FrictionB),
            fc: f(ParamId::FrictionC),
            v_band: f(ParamId::FrictionVBand),
            inv_band: {
                let b = p.get(ParamId::FrictionVBand);
                Gain::new(if b > 0.0 { 1.0 / b } else { 0.0 })
            },
            amplitude: f(ParamId::WeightAmplitude),
            s: f(ParamId::WeightS),
            phi: f(ParamId::WeightPhi),
            k: f(ParamId::SpringK),
            b: f(ParamId::SpringB),
            q0: f(ParamId::SpringQ0),
            dahl_on: pre.on,
            // k is finite or +∞ (never NaN: σ and c are finite, c > 0 when divided by), and
            // saturating_from_num saturates ±∞.
            dahl_c: Fx::saturating_from_num(pre.c),
            dahl_k: Fx::saturating_from_num(pre.k),
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
/// 2⁴⁸/(2π), rounded: radians in Q16.16 → phase in turns·2³² after `>> 32`. With 16 bits more
/// than 2³²/(2π) its rounding moves the phase by ~1e-14·θ instead of ~1e-10·θ (6e-4 rad at the
/// ripple term's 6e6 rad); the wrapping product keeps every bit the phase needs.
const RAD_TO_PHASE: i64 = 44_798_133_900_177;

/// sin of a Q16.16 angle in radians, Q16.16 result.
pub fn sin_fx(theta: Fx) -> Fx {
    sin_wide(w(theta))
}

/// sin of a Q16.16 angle carried in an i64: the phase (turns·2³²) is bits 32..64 of
/// `θ·2⁴⁸/(2π)`, which a wrapping 64-bit product keeps exactly, so no angle the i64 holds
/// loses precision to the range reduction.
pub(crate) fn sin_wide(theta: Wide) -> Fx {
    let phase = (theta.wrapping_mul(RAD_TO_PHASE) >> 32) as u32;
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

/// A Q16.16 value carried in an i64 between the terms. Every term's product and the sum of the
/// terms stay far inside it, so nothing saturates on the way and only the total is saturated
/// back to Q16.16 ([`sat`]): a total beyond ±32768 N·m sits at the rail with its sign, and one
/// inside is exact to the terms' rounding even when a term alone (K·(q − q0) at q = 1000 rad)
/// or a factor (q̇|q̇| at 1000 rad/s) is beyond the format.
pub(crate) type Wide = i64;

#[inline(always)]
pub(crate) fn w(x: Fx) -> Wide {
    i64::from(x.to_bits())
}

#[inline(always)]
pub(crate) fn sat(x: Wide) -> Fx {
    Fx::from_bits(sat32(x))
}

/// Q16.16 × Q16.16 (both in range: the product is below 2⁶²), floor.
#[inline(always)]
pub(crate) fn mul(c: Fx, x: Fx) -> Wide {
    (w(c) * w(x)) >> 16
}

/// Q16.16 coefficient × a wide value (|x| < 2⁴⁷), floor: split so no product passes 2⁶².
#[inline(always)]
pub(crate) fn mul_wide(c: Fx, x: Wide) -> Wide {
    w(c) * (x >> 16) + ((w(c) * (x & 0xffff)) >> 16)
}

/// sign(v) smoothed inside the band: `v·(1/band)` clamped to ±1, by the band's inverse kept as
/// a [`Gain`] (a 64-bit division is a library call of hundreds of instructions on a Cortex-M0+).
pub(crate) fn sign_smooth_fx(v: Fx, band: Fx, inv_band: Gain) -> Fx {
    let one = Fx::ONE;
    if band > Fx::ZERO {
        clamp_fx(inv_band.times(v), -one, one)
    } else if v > Fx::ZERO {
        one
    } else if v < Fx::ZERO {
        -one
    } else {
        Fx::ZERO
    }
}

pub(crate) fn viscous_w(p: &FixedParams, qd: Fx) -> Wide {
    // q̇|q̇| < 2³⁰ in Q32, < 2⁴⁶ in Q16.
    let q2 = (w(qd) * i64::abs(w(qd))) >> 16; // integer |x|: a path call, not a float method
    mul_wide(p.fa, q2) + mul(p.fb, qd)
}

pub(crate) fn friction_w(p: &FixedParams, qd: Fx) -> Wide {
    viscous_w(p, qd) + mul(p.fc, sign_smooth_fx(qd, p.v_band, p.inv_band))
}

pub(crate) fn weight_w(p: &FixedParams, q: Fx) -> Wide {
    mul(p.amplitude, sin_wide(mul(p.s, q) + w(p.phi)))
}

pub(crate) fn spring_w(p: &FixedParams, q: Fx, qd: Fx) -> Wide {
    mul_wide(p.k, w(q) - w(p.q0)) + mul(p.b, qd)
}

fn disturbance_w(p: &FixedParams, q: Fx, qd: Fx) -> Wide {
    friction_w(p, qd) + weight_w(p, q) + spring_w(p, q, qd)
}

/// Friction `a·q̇|q̇| + b·q̇ + c·sign(q̇)` in fixed point.
pub fn friction_fx(p: &FixedParams, qd: Fx) -> Fx {
    sat(friction_w(p, qd))
}

/// Weight `C_w0·sin(s·q + φ)` in fixed point.
pub fn weight_fx(p: &FixedParams, q: Fx) -> Fx {
    sat(weight_w(p, q))
}

/// Spring-damper `K(q − q0) + B·q̇` in fixed point.
pub fn spring_fx(p: &FixedParams, q: Fx, qd: Fx) -> Fx {
    sat(spring_w(p, q, qd))
}

/// friction + weight + spring: the disturbance terms an FPU-less board compensates.
pub fn disturbance_fx(p: &FixedParams, q: Fx, qd: Fx) -> Fx {
    sat(disturbance_w(p, q, qd))
}

/// The velocity terms `a·q̇|q̇| + b·q̇` in fixed point (the friction a Dahl state completes).
pub fn viscous_fx(p: &FixedParams, qd: Fx) -> Fx {
    sat(viscous_w(p, qd))
}

fn disturbance_stateful_w(p: &FixedParams, dahl: &mut DahlFx, q: Fx, qd: Fx) -> Wide {
    if p.dahl_on {
        let f = dahl.update(p, q, qd);
        viscous_w(p, qd) + w(f) + weight_w(p, q) + spring_w(p, q, qd)
    } else {
        disturbance_w(p, q, qd)
    }
}

/// [`disturbance_fx`], or with presliding on the same terms with the Dahl state `dahl`, advanced
/// to this sample, as the Coulomb torque: the fixed-point twin of
/// [`crate::control::disturbance_stateful`]. `dahl` is untouched when presliding is off.
pub fn disturbance_stateful_fx(p: &FixedParams, dahl: &mut DahlFx, q: Fx, qd: Fx) -> Fx {
    sat(disturbance_stateful_w(p, dahl, q, qd))
}

/// The Dahl friction state in fixed point: F and the angle it was advanced to (see the module
/// documentation and [`crate::control::Dahl`], whose rules it follows). F is carried with 24
/// fractional bits, so its rounding does not pile up over the hundreds of tiny steps of an
/// oscillation inside the pre-sliding distance (each step then contracts an error by only a
/// few per cent); it is handed out in Q16.16.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DahlFx {
    /// F·2²⁴
    f: i64,
    q_prev: Fx,
    primed: bool,
}

/// Fractional bits of [`DahlFx`]'s F.
const F_FRAC: u32 = 24;

impl DahlFx {
    /// A state with no history: its first update primes it.
    pub const fn new() -> Self {
        DahlFx { f: 0, q_prev: Fx::ZERO, primed: false }
    }

    /// F, N·m (rounded to Q16.16).
    pub fn force(&self) -> Fx {
        // |F| ≤ c < 2^15 N·m: the Q16.16 value fits.
        Fx::from_bits(((self.f + (1 << (F_FRAC - 17))) >> (F_FRAC - 16)) as i32)
    }

    /// Advance to the sample (q, q̇) and return F. The first sample primes F with
    /// `c·sign(q̇)` (band included); after that `F' = T + (F − T)·exp(−k·|Δq|)`, `T = c·sign(Δq)`,
    /// limited to `[−c, c]`.
    pub fn update(&mut self, p: &FixedParams, q: Fx, qd: Fx) -> Fx {
        let c = i64::from(p.dahl_c.to_bits()) << (F_FRAC - 16);
        let moved = if self.primed {
            let dq = q.saturating_sub(self.q_prev);
            if dq == Fx::ZERO {
                self.f
            } else {
                let target = if dq > Fx::ZERO { c } else { -c };
                // k·|Δq| with all 32 fractional bits of the product (Q16.16 · Q16.16).
                let x = i64::from(p.dahl_k.to_bits()) * i64::from(dq.saturating_abs().to_bits());
                let e = exp_neg_q26(x);
                // c ≤ 2000 N·m (friction.c + dry_friction.c, by the parameter table): |F − T| ≤ 2c
                // < 2^36 in Q24, and with e ≤ 2^26 the product stays below 2^62.
                target + (((self.f - target) * e + (1 << 25)) >> 26)
            }
        } else {
            self.primed = true;
            i64::from(p.dahl_c.saturating_mul(sign_smooth_fx(qd, p.v_band, p.inv_band)).to_bits()) << (F_FRAC - 16)
        };
        self.q_prev = q;
        self.f = moved.clamp(-c, c);
        self.force()
    }
}

/// log₂(e) in Q8.24.
const LOG2E_Q24: i64 = 24_204_406;
/// ln 2 in Q2.30.
const LN2_Q30: i64 = 744_261_118;
/// 1/i! for i = 0..=10 in Q2.30 (the last terms are coarse, but they weigh < 3e-7).
const INV_FACTORIAL_Q30: [i64; 11] = [
    1_073_741_824,
    1_073_741_824,
    536_870_912,
    178_956_971,
    44_739_243,
    8_947_849,
    1_491_308,
    213_044,
    26_631,
    2_959,
    296,
];

/// exp(−x) in Q6.26 for `x_q32` ≥ 0, x with 32 fractional bits: `2^(−n)·exp(−g)` with
/// `x·log₂e = n + f`, `g = f·ln 2 ∈ [0, ln 2)`, and exp(−g) by its Taylor series to g¹⁰
/// (truncation < 4e-10) in Horner form, all in 64-bit integers.
pub(crate) fn exp_neg_q26(x_q32: i64) -> i64 {
    // exp(−32) < 2^-46 is 0 in Q26, and x < 2^37 keeps x·log₂e (Q56) below 2^62.
    if x_q32 >= 32 << 32 {
        return 0;
    }
    let y = x_q32.max(0) * LOG2E_Q24;
    let n = y >> 56;
    let f = (y >> 26) & ((1 << 30) - 1);
    let g = (f * LN2_Q30) >> 30;
    let mut acc = 0i64;
    for c in INV_FACTORIAL_Q30.iter().rev() {
        // acc ← 1/i! − g·acc: Horner for Σ (−g)^i/i!, every value within ±1 (Q30).
        acc = c - ((acc * g) >> 30);
    }
    ((acc + 8) >> 4) >> n
}

// ---- the whole control step in Q16.16 ------------------------------------------------------

/// Which arithmetic a board's control step runs: chosen when the board image is built (a cargo
/// feature of the board crate), named in the node's identity (0x1018 product code, 0x1008
/// device name) so a host knows which numbers the joint computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Arithmetic {
    /// [`crate::control::Controller`]: f32, on an FPU or in soft-float
    F32,
    /// [`ControllerFx`]: Q16.16 integers
    Q16,
}

impl Arithmetic {
    /// Short name, as printed by tools and logs.
    pub const fn name(self) -> &'static str {
        match self {
            Arithmetic::F32 => "f32",
            Arithmetic::Q16 => "Q16.16",
        }
    }
}

/// A positive coefficient as `m·2^(−s)` with `m < 2³¹`: products with a Q16.16 value keep 31
/// significant bits of the coefficient whatever its size, where a Q16.16 coefficient would
/// saturate at 32767 (gains up to 1e5, rate limits up to 1e6) or keep only a few bits
/// (1/(N − 1) = 1e-4 is 6.5 Q16.16 steps).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Gain {
    /// < 2³⁰; an i32 so a table of per-cell gains stays 8 bytes a cell
    m: i32,
    s: u32,
}

impl Gain {
    /// From a finite f32 ≥ 0 (others give 0), exactly: an f32 has 24 significant bits.
    pub fn new(x: f32) -> Gain {
        if !(x > 0.0 && crate::math::is_finite(x)) {
            return Gain::default();
        }
        let bits = x.to_bits();
        let exp = ((bits >> 23) & 0xff) as i32;
        let (mant, e2) = if exp == 0 { (bits & 0x7f_ffff, -149) } else { ((bits & 0x7f_ffff) | 0x80_0000, exp - 150) };
        // x = mant·2^e2, mant < 2^24; shift mant up to 30 bits so small values keep them.
        let up = (mant as u64).leading_zeros() as i32 - 34;
        let m = (mant as i64) << up;
        let s = -(e2 - up);
        if s < 0 {
            // x ≥ 2^30: larger than anything a Q16.16 product can hold; saturate the gain.
            Gain { m: (1 << 30) - 1, s: 0 }
        } else if s > 62 {
            Gain { m: (m >> (s - 62).min(63)) as i32, s: 62 }
        } else {
            // m < 2^30 (shifted up to 30 bits at most)
            Gain { m: m as i32, s: s as u32 }
        }
    }

    /// `self·x`, saturated to Q16.16.
    #[inline]
    pub fn times(self, x: Fx) -> Fx {
        Fx::from_bits(sat32(self.mul_wide(x.to_bits())))
    }

    /// `self·x` for a Q-anything integer, in the same format, rounded to nearest, as i64.
    #[inline]
    pub(crate) fn mul_wide(self, x: i32) -> i64 {
        self.mul_i64(i64::from(x))
    }

    /// `self·d` as a fraction in Q8.24 for 0 ≤ d < 2³² (a distance into a grid cell times the
    /// cell's 1/span), limited to [0, 1].
    #[inline]
    pub(crate) fn frac_q24(self, d: i64) -> i64 {
        // m < 2³⁰, d < 2³²: the product stays below 2⁶².
        let p = i64::from(self.m) * d.clamp(0, (1 << 32) - 1);
        let f = if self.s >= 8 {
            p >> (self.s - 8)
        } else if p == 0 {
            0
        } else {
            // s < 8 is a gain ≥ 2²², a span below 2⁻²² rad: any d ≥ 2⁻¹⁶ is past it.
            1 << 24
        };
        f.min(1 << 24)
    }

    /// [`Gain::mul_wide`] for |x| < 2³³ (the product stays below 2⁶³).
    #[inline]
    pub(crate) fn mul_i64(self, x: i64) -> i64 {
        let p = i64::from(self.m) * x;
        if self.s == 0 {
            p
        } else {
            (p + (1 << (self.s - 1))) >> self.s
        }
    }
}

/// `lo ≤ x ≤ hi` without `Ord::clamp`'s panic on `lo > hi` (which the callers never pass).
#[inline]
fn clamp_fx(x: Fx, lo: Fx, hi: Fx) -> Fx {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

#[inline]
fn sat32(x: i64) -> i32 {
    x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// The parameters of the whole Q16.16 step, converted once when a set is put in force.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepParams {
    pub terms: FixedParams,
    pub j: Gain,
    pub c0: Fx,
    pub fraction: Gain,
    /// signed: assist_k may be negative
    pub assist_k: Fx,
    pub torque_limit: Fx,
    pub rate_limit: Gain,
    pub vel_kp: Gain,
    pub vel_ki: Gain,
    pub pos_kp: Gain,
    pub pos_kd: Gain,
    pub inv_ratio_m1: Gain,
    /// σ_m of the gravity model (> 0: the table is fused with it)
    pub table_sigma_model: Fx,
    /// k of the fusion clamp τ_m ± k·σ_m
    pub table_clamp_k: Fx,
    /// the effect terms ([`crate::model::Extra`])
    pub extra: crate::fixed_gravity::ExtraFx,
    /// the gravity table's grid and per-cell 1/span as Q16.16 holds them
    pub table: crate::fixed_gravity::TableFx,
}

impl StepParams {
    pub fn from_set(p: &ParamSet) -> Self {
        let f = |id: ParamId| Fx::saturating_from_num(p.get(id));
        let g = |id: ParamId| Gain::new(p.get(id));
        StepParams {
            terms: FixedParams::from_set(p),
            j: g(ParamId::InertiaJ),
            c0: f(ParamId::OffsetC0),
            fraction: g(ParamId::Fraction),
            assist_k: f(ParamId::AssistK),
            torque_limit: f(ParamId::TorqueLimit),
            rate_limit: g(ParamId::RateLimit),
            vel_kp: g(ParamId::VelKp),
            vel_ki: g(ParamId::VelKi),
            pos_kp: g(ParamId::PosKp),
            pos_kd: g(ParamId::PosKd),
            inv_ratio_m1: Gain::new(p.inv_ratio_m1()),
            table_sigma_model: f(ParamId::TableSigmaModel),
            table_clamp_k: f(ParamId::TableClampK),
            extra: crate::fixed_gravity::ExtraFx::new(&p.terms().extra),
            table: crate::fixed_gravity::TableFx::new(p.table(), p.lut()),
        }
    }
}

/// `x·2^frac` rounded to nearest (halves away from zero), from the f32's bits alone: a
/// handful of integer instructions where the `fixed` crate's generic conversion (or a float
/// multiply, a library call on the M0+) costs tens to hundreds. Magnitudes saturate at 2⁶²;
/// NaN and ±∞ give 0 (the step has refused them before). `frac` ≤ 32.
#[inline]
fn scaled(x: f32, frac: i32) -> i64 {
    let b = x.to_bits();
    let exp = ((b >> 23) & 0xff) as i32;
    if exp == 0xff {
        return 0;
    }
    // A normal x is mant·2^(exp − 150); a subnormal (exp 0) is below 2^-126: rounds to 0.
    let mant = (b & 0x7f_ffff) | 0x80_0000;
    let sh = exp - 150 + frac;
    let mag = if exp == 0 || sh < -25 {
        0
    } else if sh < 0 {
        // Rounded in 32 bits: mant < 2²⁴ and the half < 2²⁴. A shift by a variable count is one
        // instruction there and a library call in 64 bits on the M0+ (two per conversion, and
        // the step converts every input, the table's corner values and the series' terms).
        i64::from((mant + (1 << (-sh - 1))) >> -sh)
    } else if sh <= 38 {
        i64::from(mant) << sh
    } else {
        1 << 62
    };
    if b >> 31 == 1 {
        -mag
    } else {
        mag
    }
}

/// f32 → Q16.16 as the step converts its inputs and the table's values: rounded to nearest
/// with halves away from zero (the `fixed` crate rounds them to even), saturating, NaN → 0.
#[inline]
pub fn fx(x: f32) -> Fx {
    Fx::from_bits(sat32(scaled(x, 16)))
}

/// Q16.16 → f32: exact below 256 in magnitude (24 significant bits), rounded to nearest above;
/// an integer conversion and a multiply by a power of two, both correctly rounded everywhere.
#[inline]
fn to_f32(x: Fx) -> f32 {
    x.to_bits() as f32 * (1.0 / 65536.0)
}

/// The Q16.16 twin of [`crate::control::Controller`]: the same law, modes, limits and terms
/// (gravity table and fusion, series and effect terms in [`crate::fixed_gravity`]), in integers only (f32 only at the edges: the inputs and
/// the [`crate::control::Output`] are converted, so the node and the board glue stay the same).
/// Every operation saturates; none wraps. Out of range for Q16.16 (±32768): an input q̈ beyond
/// 32767 rad/s² is taken as 32767 (the f32 step clamps at 1e6), and every torque saturates at
/// ±32768 N·m before the torque limit (≤ 1e4 N·m) applies, so a saturated term still drives the
/// output to the limit with the right sign (`tests/fixed_point.rs` measures where).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControllerFx {
    p: StepParams,
    prev_tau: Fx,
    integ: Fx,
    dahl: DahlFx,
}

impl ControllerFx {
    pub fn new(p: &ParamSet) -> Self {
        ControllerFx { p: StepParams::from_set(p), prev_tau: Fx::ZERO, integ: Fx::ZERO, dahl: DahlFx::new() }
    }

    /// Put a new set in force: its parameters, and a fresh Dahl state (as the f32 step's
    /// `reset_presliding`). The integrator and the last output stay, as in the f32 node.
    pub fn configure(&mut self, p: &ParamSet) {
        self.p = StepParams::from_set(p);
        self.dahl = DahlFx::new();
    }

    pub fn params(&self) -> &StepParams {
        &self.p
    }

    /// Forget the integrator and the last output; the Dahl state stays (it is the joint's).
    pub fn reset(&mut self) {
        self.prev_tau = Fx::ZERO;
        self.integ = Fx::ZERO;
    }

    /// The Dahl state (F stays 0 while presliding is off).
    pub fn presliding(&self) -> &DahlFx {
        &self.dahl
    }

    /// Gravity: the weight term plus the series (the model side τ_m), with the table added or
    /// fused ([`crate::control::gravity`]).
    fn gravity_w(&self, p: &ParamSet, angles: &[Fx; 4]) -> Wide {
        use crate::fixed_gravity::{fuse_w, series_w, table_w};
        let [q, ..] = *angles;
        let wgt = weight_w(&self.p.terms, q);
        let s = p.series();
        let tau_m = if s.n_terms == 0 { wgt } else { wgt + series_w(s, angles) };
        let lut = p.lut();
        if lut.n_axes() == 0 {
            return tau_m;
        }
        let sigma_m = self.p.table_sigma_model;
        let fused = sigma_m > Fx::ZERO;
        let (tau_t, sigma_t) = table_w(p.table(), &self.p.table, lut, angles, fused);
        if fused {
            let data = if lut.residual() { tau_m + tau_t } else { tau_t };
            fuse_w(tau_m, sigma_m, data, sigma_t, self.p.table_clamp_k)
        } else {
            tau_m + tau_t
        }
    }

    /// The effect terms at (q, q̇) with the measured load `load` (the load cell's f32, N·m),
    /// which only their out-of-line sum converts and reads: without effect terms it is not used.
    #[inline]
    fn extra_w(&self, q: Fx, qd: Fx, load: f32) -> Wide {
        if !self.p.extra.any {
            return 0;
        }
        let t = &self.p.terms;
        self.p.extra.torque_w(q, qd, sign_smooth_fx(qd, t.v_band, t.inv_band), load)
    }

    /// `C_c` of the Q16.16 step: `J·q̈ + friction (or viscous + Dahl) + gravity + C_0 + spring +
    /// effect terms`, every term of [`crate::control::disturbance_stateful`]; `extra` is the
    /// effect terms' sum at (q, q̇) ([`ControllerFx::extra_w`]).
    #[inline]
    fn disturbance(&mut self, p: &ParamSet, angles: &[Fx; 4], qd: Fx, qdd: Fx, extra: Wide) -> Fx {
        let [q, ..] = *angles;
        let t = &self.p.terms;
        let fric = if t.dahl_on { viscous_w(t, qd) + w(self.dahl.update(t, q, qd)) } else { friction_w(t, qd) };
        sat(fric
            + self.gravity_w(p, angles)
            + spring_w(&self.p.terms, q, qd)
            + extra
            + self.p.j.mul_wide(qdd.to_bits())
            + w(self.p.c0))
    }

    /// One step of length `dt` s, with f32 inputs and outputs like
    /// [`crate::control::Controller::step`].
    pub fn step(
        &mut self,
        p: &ParamSet,
        mode: crate::control::Mode,
        inp: &crate::control::Input,
        dt: f32,
    ) -> crate::control::Output {
        use crate::control::{Mode, Output};
        use crate::math::is_finite;
        // dt in Q1.31: 0 < dt ≤ 1 s, else the rate limiter freezes for this step (as in f32).
        // 0 < dt ≤ 1 in one unsigned compare of the bits, as the f32 step does.
        let dt_q31: i64 = if dt.to_bits().wrapping_sub(1) < 1.0f32.to_bits() { scaled(dt, 31) } else { 0 };
        let finite = is_finite(inp.q)
            && is_finite(inp.qd)
            && is_finite(inp.qdd)
            && is_finite(inp.assist_cmd)
            && inp.others.iter().all(|&o| is_finite(o));
        let limit = self.p.torque_limit;
        let mut out = Output { bad_input: !finite, ..Output::default() };
        let target = if !finite {
            self.integ = Fx::ZERO;
            Fx::ZERO
        } else {
            let (q, qd, qdd) = (fx(inp.q), fx(inp.qd), fx(inp.qdd));
            // The effect terms first, where the inputs are read: the load is read inside their
            // branch only, and only their sum goes on through the step (staged in the parameters
            // behind a branch of its own, it cost a step without effect terms that branch, 4
            // instructions on the M0+, and the registers it moved).
            let extra = self.extra_w(q, qd, inp.tau_load);
            let [o0, o1, o2] = inp.others;
            let angles = [q, fx(o0), fx(o1), fx(o2)];
            let c_c = self.disturbance(p, &angles, qd, qdd, extra);
            out.c_c = to_f32(c_c);
            match mode {
                Mode::Off => {
                    self.integ = Fx::ZERO;
                    Fx::ZERO
                }
                Mode::Assist => {
                    self.integ = Fx::ZERO;
                    let assist = self.p.assist_k.saturating_mul(q).saturating_add(fx(inp.assist_cmd));
                    out.assist = to_f32(assist);
                    assist.saturating_add(self.p.fraction.times(c_c))
                }
                Mode::Velocity(v) => {
                    let t = &self.p.terms;
                    let v = fx(v);
                    let err = v.saturating_sub(qd);
                    let ki_err = sat32(self.p.vel_ki.mul_wide(err.to_bits()));
                    let di = (i64::from(ki_err) * dt_q31 + (1 << 30)) >> 31;
                    let integ = Fx::from_bits(sat32(i64::from(self.integ.to_bits()) + di));
                    self.integ = clamp_fx(integ, -limit, limit);
                    let fric = if t.dahl_on { viscous_w(t, v) + w(self.dahl.force()) } else { friction_w(t, v) };
                    let ff = sat(fric
                        + self.gravity_w(p, &angles)
                        + w(self.p.c0)
                        + spring_w(t, q, v)
                        + self.extra_w(q, v, inp.tau_load));
                    self.p.vel_kp.times(err).saturating_add(self.integ).saturating_add(ff)
                }
                Mode::Position(x) => {
                    self.integ = Fx::ZERO;
                    let t = &self.p.terms;
                    let x = if is_finite(x) { fx(x) } else { q };
                    let ff = sat(self.gravity_w(p, &angles)
                        + w(self.p.c0)
                        + spring_w(t, q, Fx::ZERO)
                        + self.extra_w(q, Fx::ZERO, inp.tau_load));
                    self.p.pos_kp.times(x.saturating_sub(q)).saturating_sub(self.p.pos_kd.times(qd)).saturating_add(ff)
                }
            }
        };
        let limited_target = clamp_fx(target, -limit, limit);
        // rate·dt: the gain's mantissa (< 2³¹) times dt (Q31) fits an i64; then to Q16.16.
        let rl = self.p.rate_limit;
        let step_wide = (i64::from(rl.m) * dt_q31) >> 15;
        let step_max = Fx::from_bits(sat32(step_wide >> rl.s.min(63)));
        let up = self.prev_tau.saturating_add(step_max);
        let down = self.prev_tau.saturating_sub(step_max);
        let tau = clamp_fx(limited_target, down, up);
        out.limited = tau != target;
        self.prev_tau = tau;
        out.tau_out = to_f32(tau);
        out.u_motor = to_f32(self.p.inv_ratio_m1.times(tau));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_matches_f64() {
        let mut worst = 0.0f64;
        for i in 0..400_000i64 {
            let bits = i * 350_000; // x from 0 to ~32.6 (Q32)
            let x = bits as f64 / 4294967296.0;
            let got = exp_neg_q26(bits) as f64 / 67108864.0;
            // libm in f64, not std: the no-std-float scan covers test modules in src/ too.
            worst = worst.max(libm::fabs(got - libm::exp(-x)));
        }
        // The Q26 result's own resolution is 1.5e-8.
        assert!(worst < 4e-8, "{worst}");
        assert_eq!(exp_neg_q26(0), 1 << 26);
    }

    #[test]
    fn gain_keeps_31_bits_of_any_coefficient() {
        for &g in &[2.37f32, 1.0, 0.7, 1.0 / 159.0, 1.0e-4, 1.0e5, 1.0e6, 3.0e-9] {
            for &x in &[1.0f32, -3.25, 10.0, 0.001] {
                let got = Gain::new(g).times(Fx::from_num(x)).to_num::<f64>();
                let want = (g as f64 * Fx::from_num(x).to_num::<f64>()).clamp(-32768.0, 32767.99998);
                assert!(libm::fabs(got - want) <= 1.6e-5, "{g} * {x}: {got} vs {want}");
            }
        }
        assert_eq!(Gain::new(0.0), Gain::default());
    }

    #[test]
    fn scaled_rounds_like_the_fixed_crate_except_on_ties() {
        let mut rng = crate::vectors::XorShift32::new(3);
        for _ in 0..100_000 {
            let x = f32::from_bits(rng.next_u32());
            if !crate::math::is_finite(x) {
                assert_eq!(scaled(x, 16), 0);
                continue;
            }
            let want = Fx::saturating_from_num(x);
            let got = fx(x);
            // The fixed crate rounds ties to even, `scaled` away from zero: one LSB at most.
            assert!(i64::abs(i64::from(got.to_bits()) - i64::from(want.to_bits())) <= 1, "{x}: {got} vs {want}");
        }
        assert_eq!(fx(1.5), Fx::from_num(1.5));
        assert_eq!(fx(-40000.0), Fx::MIN);
        assert_eq!(fx(1.0e30), Fx::MAX);
        assert_eq!(scaled(1.0, 31), 1 << 31);
        assert_eq!(scaled(0.001, 31), 2_147_484);
        assert_eq!(Gain::new(f32::NAN), Gain::default());
        assert_eq!(exp_neg_q26(i64::MAX), 0);
    }

    #[test]
    fn scaled_rounds_in_32_bits_as_in_64() {
        // The 64-bit rounding `scaled` had before its right shifts moved to 32 bits.
        fn wide(x: f32, frac: i32) -> i64 {
            let b = x.to_bits();
            let exp = ((b >> 23) & 0xff) as i32;
            let mant = i64::from((b & 0x7f_ffff) | 0x80_0000);
            let sh = exp - 150 + frac;
            let mag = if exp == 0xff || exp == 0 || sh < -25 {
                0
            } else if sh < 0 {
                (mant + (1 << (-sh - 1))) >> -sh
            } else if sh <= 38 {
                mant << sh
            } else {
                1 << 62
            };
            if b >> 31 == 1 {
                -mag
            } else {
                mag
            }
        }
        let mut rng = crate::vectors::XorShift32::new(7);
        for exp in 0..=255u32 {
            for k in 0..1000u32 {
                // the smallest, the largest and a middle mantissa, then random ones
                let mant = match k {
                    0 => 0,
                    1 => 0x7f_ffff,
                    2 => 0x40_0000,
                    _ => rng.next_u32() & 0x7f_ffff,
                };
                for sign in [0, 1u32 << 31] {
                    let x = f32::from_bits(sign | exp << 23 | mant);
                    for frac in [16, 31] {
                        assert_eq!(scaled(x, frac), wide(x, frac), "{x:e} ({:#010x}), frac {frac}", x.to_bits());
                    }
                }
            }
        }
    }
}
