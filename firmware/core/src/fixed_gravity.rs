//! The Q16.16 step's gravity and effect terms: the N-D gravity table with inverse-variance
//! fusion, the analytic gravity series, and the effect terms (Stribeck, asymmetric and dry
//! friction, position ripple, cable spring), the integer twins of [`crate::table`],
//! [`crate::series`] and [`crate::model::Extra`].
//!
//! The table's values and the series are read from the set in force (their f32 values
//! converted as they are used: a few integer instructions each, and no second copy of the
//! table's 1 KiB of values in the node);
//! everything is carried as [`Wide`] Q16.16 values and saturated only in the step's total.
//! - Table: each axis's cell is found by binary search on the grid (converted), the fraction
//!   is `(x − g_i)·(1/span)` in Q8.24 with the Lut's 1/span, corners are weighted in Q8.24.
//! - Fusion: `τ_m + (τ_d − τ_m)·σ_m²/(σ_m² + σ_d²)`, the weight in Q2.30 by one 64-bit
//!   division (the only one in the step, and only with fusion), clamped to `τ_m ± k·σ_m`.
//! - Series: each term's argument `Σ n_j·angle_j + φ` in 64 bits (no wrap, no saturation),
//!   its sine by the same table as the weight term.

use crate::fixed::{exp_neg_q26, fx, mul, mul_wide, sat, sin_wide, w, Fx, Gain, Wide};
use crate::model::Extra;
use crate::series::RawSeries;
use crate::table::{Lut, RawTable, AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};

/// `Σ a_k·sin(n_k·angles + φ_k)`, `angles = [q, o0, o1, o2]`.
pub(crate) fn series_w(s: &RawSeries, angles: &[Fx; 4]) -> Wide {
    let n = (s.n_terms as usize).min(crate::series::TERMS_MAX);
    let mut acc: Wide = 0;
    for ((a, p), m) in s.amplitude.iter().zip(s.phase.iter()).zip(s.mult.iter()).take(n) {
        let mut arg: Wide = 0;
        for (&k, &x) in m.iter().zip(angles.iter()) {
            arg += i64::from(k) * w(x);
        }
        acc += mul(fx(*a), sin_wide(arg + w(fx(*p))));
    }
    acc
}

/// The table's grid and the reciprocal of each cell's span as Q16.16 holds the grid, computed
/// when a set is put in force so the step neither converts the grid nor divides.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TableFx {
    grid: [[Fx; AXIS_POINTS_MAX]; AXES_MAX],
    inv_span: [[Gain; AXIS_POINTS_MAX]; AXES_MAX],
}

impl TableFx {
    pub fn new(t: &RawTable, lut: &Lut) -> TableFx {
        let mut tf = TableFx::default();
        let n = (lut.n_axes() as usize).min(AXES_MAX);
        for ((g, inv), src) in tf.grid.iter_mut().zip(tf.inv_span.iter_mut()).zip(t.grid.iter()).take(n) {
            for (d, &x) in g.iter_mut().zip(src.iter()) {
                *d = fx(x);
            }
            // 1/span of the held grid: the fraction is 0 and (to 2⁻²⁴) 1 at the held points, so
            // the interpolation has no step at a cell edge (the f32 Lut's 1/span of the f32
            // grid would leave one of up to 2⁻¹⁶/span).
            for (i, r) in inv.iter_mut().enumerate() {
                let (a, b) = (g.get(i).copied().unwrap_or(Fx::ZERO), g.get(i + 1).copied().unwrap_or(Fx::ZERO));
                let span = b.to_bits() as f32 - a.to_bits() as f32;
                *r = Gain::new(if span > 0.0 { 65536.0 / span } else { 0.0 });
            }
        }
        tf
    }
}

/// Cell and fraction (Q8.24) of `x` along `axis`, clamped to the grid.
fn locate(tf: &TableFx, lut: &Lut, axis: usize, x: Fx) -> (usize, i64) {
    let (points, _) = lut.shape(axis);
    let last = points.saturating_sub(1).max(1);
    let empty = [Fx::ZERO; AXIS_POINTS_MAX];
    let grid = tf.grid.get(axis).unwrap_or(&empty);
    let g = |i: usize| grid.get(i).copied().unwrap_or(Fx::ZERO);
    let (g0, gl) = (g(0), g(last));
    let x = if x < g0 {
        g0
    } else if x > gl {
        gl
    } else {
        x
    };
    let (mut lo, mut hi) = (0usize, last);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if g(mid) <= x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let inv = tf.inv_span.get(axis).and_then(|r| r.get(lo)).copied().unwrap_or_default();
    (lo, inv.frac_q24(w(x) - w(g(lo))))
}

/// Torque and (with `with_sigma`) σ of the table at `angles = [q, o0, o1, o2]`, each axis
/// reading its own source; multilinear over the cell's 2ⁿ corners.
pub(crate) fn table_w(t: &RawTable, tf: &TableFx, lut: &Lut, angles: &[Fx; 4], with_sigma: bool) -> (Wide, Wide) {
    let n = (lut.n_axes() as usize).min(AXES_MAX);
    if n == 0 {
        return (0, 0);
    }
    let mut frac = [0i64; AXES_MAX];
    let mut stride = [0usize; AXES_MAX];
    let mut origin = 0usize;
    for axis in 0..n {
        let x = angles.get(lut.source(axis)).copied().unwrap_or(Fx::ZERO);
        let (i, f) = locate(tf, lut, axis, x);
        let (_, st) = lut.shape(axis);
        origin += i * st;
        if let (Some(fr), Some(s)) = (frac.get_mut(axis), stride.get_mut(axis)) {
            *fr = f;
            *s = st;
        }
    }
    let value = |a: &[f32; CELLS_MAX], i: usize| w(fx(a.get(i).copied().unwrap_or(0.0)));
    let (mut acc_v, mut acc_s): (Wide, Wide) = (0, 0);
    for corner in 0..(1usize << n) {
        let mut weight: i64 = 1 << 24;
        let mut idx = origin;
        for axis in 0..n {
            let f = frac.get(axis).copied().unwrap_or(0);
            if corner & (1 << axis) != 0 {
                weight = (weight * f) >> 24;
                idx += stride.get(axis).copied().unwrap_or(0);
            } else {
                weight = (weight * ((1 << 24) - f)) >> 24;
            }
        }
        acc_v += (weight * value(&t.torque, idx)) >> 24;
        if with_sigma {
            acc_s += (weight * value(&t.sigma, idx)) >> 24;
        }
    }
    (acc_v, acc_s)
}

/// Inverse-variance fusion clamped to `τ_m ± k·σ_m` ([`crate::table::fuse`]).
pub(crate) fn fuse_w(tau_m: Wide, sigma_m: Fx, data: Wide, sigma_d: Wide, k: Fx) -> Wide {
    let sm = w(sigma_m);
    let sd = sigma_d.clamp(-(1 << 31), 1 << 31);
    // Variances in Q32 (σ = 1e-3 N·m is 65 in Q16.16, its square 4225 in Q32: a Q16 variance
    // would be 0), scaled down together until both fit 30 bits for the division.
    let (mut vm, mut vd) = (sm * sm, sd * sd);
    let big = vm.max(vd);
    if big >= 1 << 30 {
        let sh = 34 - big.leading_zeros(); // big < 2^(64 − lz); shift it below 2^30
        vm >>= sh;
        vd >>= sh;
    }
    let sum = vm + vd;
    let w_data = if sum > 0 { (vm << 30) / sum } else { 1 << 29 };
    let diff = (data - tau_m).clamp(-(1 << 32), 1 << 32);
    let fused = tau_m + ((diff * w_data) >> 30);
    let band = i64::abs(mul(k, sigma_m)); // an integer|x|, spelt as a path so the float-method scan cannot mistake it
    fused.clamp(tau_m - band, tau_m + band)
}

/// The effect terms' parameters in the forms the integer code uses, from [`Extra`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExtraFx {
    pub any: bool,
    pub stribeck_level: Fx,
    pub stribeck_inv_speed: Gain,
    pub asym_delta: Fx,
    pub ripple_amplitude: Fx,
    pub ripple_k: Gain,
    pub ripple_phase: Fx,
    pub ripple_amplitude_2: Fx,
    pub ripple_phase_2: Fx,
    pub cable_k: Fx,
    pub cable_engage: Fx,
    pub cable_width: Fx,
    /// 1/(2·width)
    pub cable_inv_2w: Gain,
    pub dry_c: Fx,
    pub load_mu: Fx,
}

/// The largest measured load the load-dependent friction takes, N·m ([`crate::model::INPUT_LIMITS`]).
const LOAD_MAX: Fx = Fx::from_bits((crate::model::INPUT_LIMITS.tau as i32) << 16);

impl ExtraFx {
    pub fn new(e: &Extra) -> ExtraFx {
        ExtraFx {
            any: e.any,
            stribeck_level: fx(e.stribeck_level),
            stribeck_inv_speed: Gain::new(e.stribeck_inv_speed),
            asym_delta: fx(e.asym_delta),
            ripple_amplitude: fx(e.ripple_amplitude),
            ripple_k: Gain::new(e.ripple_k),
            ripple_phase: fx(e.ripple_phase),
            ripple_amplitude_2: fx(e.ripple_amplitude_2),
            ripple_phase_2: fx(e.ripple_phase_2),
            cable_k: fx(e.cable_k),
            cable_engage: fx(e.cable_engage),
            cable_width: fx(e.cable_width),
            cable_inv_2w: Gain::new(if e.cable_width > 0.0 { 0.5 / e.cable_width } else { 0.0 }),
            dry_c: fx(e.dry_c),
            load_mu: fx(e.load_mu),
        }
    }

    /// Sum of the terms at (q, q̇), `sgn` the smoothed sign of q̇, `load` the measured load (N·m,
    /// converted here: NaN and ±∞ become 0, no load) ([`Extra::torque`]).
    /// Out of line like its f32 twin: inlined, its registers cost the step without effect terms.
    #[inline(never)]
    #[cold]
    pub(crate) fn torque_w(&self, q: Fx, qd: Fx, sgn: Fx, load: f32) -> Wide {
        if !self.any {
            return 0;
        }
        // Stribeck: level·exp(−r²)·sgn, r = q̇/speed; |r| ≥ 8 gives exp(−64) = 0 in Q26.
        let r = self.stribeck_inv_speed.mul_wide(qd.to_bits()).clamp(-(8 << 16), 8 << 16);
        let e = exp_neg_q26(r * r);
        let stribeck = (mul(self.stribeck_level, sgn) * e) >> 26;
        let asym = mul(self.asym_delta, sgn.saturating_abs());
        let theta = self.ripple_k.mul_wide(q.to_bits());
        let mut ripple = mul(self.ripple_amplitude, sin_wide(theta + w(self.ripple_phase)));
        if self.ripple_amplitude_2 != Fx::ZERO {
            ripple += mul(self.ripple_amplitude_2, sin_wide(2 * theta + w(self.ripple_phase_2)));
        }
        let x = w(q) - w(self.cable_engage);
        let cable = if x <= 0 {
            0
        } else if x < w(self.cable_width) {
            // x·(x/(2·width)): x < width ≤ 10 rad (< 2²⁰ in Q16), x/(2·width) < ½; squaring x
            // first would drop a small x's bits (x = 1e-3 rad is 65, x² in Q16 is 0).
            mul_wide(self.cable_k, (x * self.cable_inv_2w.mul_i64(x)) >> 16)
        } else {
            mul_wide(self.cable_k, x - w(self.cable_width) / 2)
        };
        // mu ≤ 1 times |load| ≤ 1e4 N·m: a Q16 product below 2³¹, then times |sgn| ≤ 1
        let load_friction = mul_wide(sgn, mul(self.load_mu, fx(load).saturating_abs().min(LOAD_MAX)));
        stribeck + asym + ripple + cable + mul(self.dry_c, sgn) + load_friction
    }
}

/// [`fuse_w`] on Q16.16 values, saturated (for tests and hosts that want one term).
pub fn fuse_fx(tau_m: Fx, sigma_m: Fx, data: Fx, sigma_d: Fx, k: Fx) -> Fx {
    sat(fuse_w(w(tau_m), sigma_m, w(data), w(sigma_d), k))
}

/// [`table_w`] saturated: torque and σ of a table at `angles`.
pub fn table_fx(t: &RawTable, lut: &Lut, angles: &[Fx; 4], with_sigma: bool) -> (Fx, Fx) {
    let (v, s) = table_w(t, &TableFx::new(t, lut), lut, angles, with_sigma);
    (sat(v), sat(s))
}

/// [`series_w`] saturated.
pub fn series_fx(s: &RawSeries, angles: &[Fx; 4]) -> Fx {
    sat(series_w(s, angles))
}

/// The effect terms' total saturated to Q16.16 (for tests and hosts that want one term).
pub fn extra_fx(e: &ExtraFx, q: Fx, qd: Fx, sgn: Fx, load: f32) -> Fx {
    sat(e.torque_w(q, qd, sgn, load))
}
