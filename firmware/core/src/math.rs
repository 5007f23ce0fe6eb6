//! The only door to floating-point functions in the core.
//!
//! IEEE-754 single precision `+ − × ÷` are correctly rounded on the Cortex-M4F and on x86-64,
//! and Rust never contracts `a*b + c` into an FMA, so code written only with those operations
//! gives the same bits on the MCU and the PC (checked under QEMU). Two consequences:
//! - `sin`/`cos` are our own single-precision Cephes-style routines (Cody–Waite reduction by π/2
//!   in three parts, degree-7/8 polynomials). `libm::sinf` would be exact to <1 ulp too, but it
//!   computes its kernel in `f64`, which the M4F has no hardware for: every call would pay for
//!   soft-float doubles. Measured error against `f64::sin`: see `tests/math_accuracy.rs`.
//! - everything else goes through `libm` (pure Rust, integer/f32 code paths).
//!
//! We do not use micromath: its `sin` has an absolute error around 1e-3 and its `sqrt` a
//! percent-level error (both measured in `tests/math_accuracy.rs`) — fine for graphics, not for
//! a torque that an identification on the PC must reproduce on the chip.
//!
//! Plain `x.sin()`, `x.abs()` etc. are banned in `firmware/` (a test greps for them): with std
//! linked on the PC they would resolve to std's implementations.

// Cephes' published decimal constants; rounding them to f32 is intended.
#![allow(clippy::excessive_precision)]

// π/2 split so that k·DP1 and k·DP2 are exact in f32 for |k| < 2^12 (Cephes sinf).
const DP1: f32 = 1.570_312_5;
const DP2: f32 = 4.837_512_969_970_703e-4;
const DP3: f32 = 7.549_789_948_768_648e-8;
const TWO_OVER_PI: f32 = core::f32::consts::FRAC_2_PI;
/// A reduced argument beyond π/4 (plus rounding slack) means the reduction itself failed.
const REDUCED_MAX: f32 = 0.8;

/// `(r, quadrant)` with `x = quadrant·π/2 + r`, `|r| ≤ π/4` (for |x| up to ~1e4; beyond that the
/// reduction loses accuracy but stays finite and deterministic, up to ~2e9, see [`sin_huge`]).
#[inline(always)]
fn reduce(x: f32) -> (f32, i32) {
    // `as i32` saturates and maps NaN to 0: never UB, never a panic.
    let kf = x * TWO_OVER_PI;
    let k = if kf >= 0.0 { (kf + 0.5) as i32 } else { (kf - 0.5) as i32 };
    let kf = k as f32;
    let r = ((x - kf * DP1) - kf * DP2) - kf * DP3;
    (r, k)
}

#[inline(always)]
fn sin_poly(r: f32) -> f32 {
    let z = r * r;
    ((-1.951_529_589_1e-4 * z + 8.332_160_873_6e-3) * z - 1.666_665_461_1e-1) * z * r + r
}

#[inline(always)]
fn cos_poly(r: f32) -> f32 {
    let z = r * r;
    ((2.443_315_711_809_948e-5 * z - 1.388_731_625_493_765e-3) * z + 4.166_664_568_298_827e-2) * z * z - 0.5 * z + 1.0
}

#[inline(always)]
fn sin_quadrant(r: f32, k: i32) -> f32 {
    match k & 3 {
        0 => sin_poly(r),
        1 => cos_poly(r),
        2 => -sin_poly(r),
        _ => -cos_poly(r),
    }
}

#[inline(always)]
fn cos_quadrant(r: f32, k: i32) -> f32 {
    match k & 3 {
        0 => cos_poly(r),
        1 => -sin_poly(r),
        2 => -cos_poly(r),
        _ => sin_poly(r),
    }
}

/// sin of an argument beyond the reduction's range (|x| ≳ 2e9 rad, the quadrant count
/// saturated): x is first taken modulo the f32 value of 2π (`fmodf` is exact and integer code,
/// so still the same bits everywhere). The result is finite and in [−1, 1] but no longer a
/// sine: 2π's rounding in f32 times |x|/2π swamps it. No input of the control step gets there
/// (angles are clamped); `libm::sinf`/`cosf`, exact there, cost 4.3 KiB of the board's flash
/// for that unreachable path. Out of line and cold, so the common path is a plain tail call.
#[cold]
#[inline(never)]
fn sin_huge(x: f32) -> f32 {
    let (r, k) = reduce(libm::fmodf(x, core::f32::consts::TAU));
    sin_quadrant(r, k)
}

/// cos of an argument beyond the reduction's range; see [`sin_huge`].
#[cold]
#[inline(never)]
fn cos_huge(x: f32) -> f32 {
    let (r, k) = reduce(libm::fmodf(x, core::f32::consts::TAU));
    cos_quadrant(r, k)
}

/// sin(x) in single precision, identical bits on every IEEE-754 target.
#[inline]
pub fn sin(x: f32) -> f32 {
    let (r, k) = reduce(x);
    if abs(r) > REDUCED_MAX {
        return sin_huge(x);
    }
    sin_quadrant(r, k)
}

/// cos(x) in single precision, identical bits on every IEEE-754 target.
#[inline]
pub fn cos(x: f32) -> f32 {
    let (r, k) = reduce(x);
    if abs(r) > REDUCED_MAX {
        return cos_huge(x);
    }
    cos_quadrant(r, k)
}

#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

#[inline(always)]
pub fn exp(x: f32) -> f32 {
    libm::expf(x)
}

/// `exp(x) − 1`, accurate for small |x| (where `exp(x) − 1` would cancel).
#[inline(always)]
pub fn expm1(x: f32) -> f32 {
    libm::expm1f(x)
}

#[inline(always)]
pub fn tanh(x: f32) -> f32 {
    libm::tanhf(x)
}

#[inline(always)]
pub fn atan2(y: f32, x: f32) -> f32 {
    libm::atan2f(y, x)
}

#[inline(always)]
pub fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}

#[inline(always)]
pub fn floor(x: f32) -> f32 {
    libm::floorf(x)
}

#[inline(always)]
pub fn copysign(magnitude: f32, sign: f32) -> f32 {
    libm::copysignf(magnitude, sign)
}

/// Declares a limit and the smoothed sign for one float type: written once, so the f32 the
/// joint runs and the f64 host tools evaluate the model with (the plant, the identification,
/// the diagnosis) follow one rule, sign(0) = 0 included.
macro_rules! limits_for {
    ($t:ty, $clamp:ident, $sign_smooth:ident) => {
        /// `x` limited to `[lo, hi]`; NaN maps to `lo` so a bad sample can never pass through a
        /// limit.
        #[inline(always)]
        pub fn $clamp(x: $t, lo: $t, hi: $t) -> $t {
            if x >= lo {
                if x <= hi {
                    x
                } else {
                    hi
                }
            } else {
                lo
            }
        }

        /// sign(v) smoothed linearly inside `|v| < band`, so a noisy zero velocity gives a small
        /// torque instead of a full ±c chatter. Odd, monotonic, and exactly ±1 outside the band.
        /// `band = 0` (or less) gives the hard sign with sign(0) = 0.
        #[inline(always)]
        pub fn $sign_smooth(v: $t, band: $t) -> $t {
            if band > 0.0 {
                $clamp(v / band, -1.0, 1.0)
            } else if v > 0.0 {
                1.0
            } else if v < 0.0 {
                -1.0
            } else {
                0.0
            }
        }
    };
}

limits_for!(f32, clamp, sign_smooth);
limits_for!(f64, clamp_f64, sign_smooth_f64);

/// `true` for finite numbers (not NaN, not ±∞).
#[inline(always)]
pub fn is_finite(x: f32) -> bool {
    // core's is_finite is a bit test, identical on every target.
    x.is_finite()
}
