//! Measured accuracy of the core's math against f64 references, and of micromath (which we
//! chose not to use) against libm. The figures are printed (`cargo test -- --nocapture`) and
//! bounded by assertions; the README quotes them.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::math;

fn sweep(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f32> {
    (0..=n).map(move |i| (lo + (hi - lo) * i as f64 / n as f64) as f32)
}

#[test]
fn core_sin_cos_error() {
    let mut worst_sin = 0.0f64;
    let mut worst_cos = 0.0f64;
    for x in sweep(-200.0, 200.0, 2_000_000) {
        worst_sin = worst_sin.max((math::sin(x) as f64 - (x as f64).sin()).abs());
        worst_cos = worst_cos.max((math::cos(x) as f64 - (x as f64).cos()).abs());
    }
    println!("core sin: worst abs error {worst_sin:.3e} over |x| ≤ 200 rad; cos {worst_cos:.3e}");
    // A few f32 ulps of 1.0 (ulp = 1.19e-7).
    assert!(worst_sin < 6e-7, "{worst_sin}");
    assert!(worst_cos < 6e-7, "{worst_cos}");
    let libm_worst = sweep(-200.0, 200.0, 200_000).map(|x| (math::sin(x) - libm::sinf(x)).abs()).fold(0.0f32, f32::max);
    println!("core sin vs libm::sinf: worst {libm_worst:.3e}");
    assert!(libm_worst < 6e-7);
}

#[test]
fn micromath_error_against_libm() {
    use micromath::F32Ext;
    let mut sin_err = 0.0f32;
    for x in sweep(-7.0, 7.0, 200_000) {
        sin_err = sin_err.max((F32Ext::sin(x) - libm::sinf(x)).abs());
    }
    let mut sqrt_rel = 0.0f32;
    for x in sweep(1e-3, 1e3, 200_000) {
        sqrt_rel = sqrt_rel.max(((F32Ext::sqrt(x) - libm::sqrtf(x)) / libm::sqrtf(x)).abs());
    }
    let mut exp_rel = 0.0f32;
    for x in sweep(-10.0, 10.0, 200_000) {
        exp_rel = exp_rel.max(((F32Ext::exp(x) - libm::expf(x)) / libm::expf(x)).abs());
    }
    println!(
        "micromath vs libm: sin worst abs {sin_err:.3e}, sqrt worst rel {sqrt_rel:.3e}, exp worst rel {exp_rel:.3e}"
    );
    // These are why the core does not use micromath: each is far above a few ulps.
    assert!(sin_err > 1e-5 && sqrt_rel > 1e-4, "micromath got more accurate; revisit the choice");
}

#[test]
fn sign_smooth_and_clamp_edge_cases() {
    assert_eq!(math::sign_smooth(0.0, 0.01), 0.0);
    assert_eq!(math::sign_smooth(0.005, 0.01), 0.5);
    assert_eq!(math::sign_smooth(-1.0, 0.01), -1.0);
    assert_eq!(math::sign_smooth(1e-30, 0.0), 1.0);
    assert_eq!(math::clamp(f32::NAN, -1.0, 1.0), -1.0);
    assert!(!math::is_finite(f32::INFINITY) && !math::is_finite(f32::NAN) && math::is_finite(1e38));
    assert!(math::sin(1e30).is_finite() && math::sin(f32::MAX).is_finite());
}

/// The host's f64 sign (plant, identification, diagnosis) is the joint's rule: on f32 inputs it
/// gives the f32 result rounded once (an f64 quotient of two f32 values rounds to the correctly
/// rounded f32 quotient), sign(0) = 0 with and without a band, NaN to −1.
#[test]
fn the_f64_sign_is_the_f32_rule() {
    let mut rng = joint_core::vectors::XorShift32::new(17);
    for i in 0..200_000 {
        let v = rng.uniform(-0.05, 0.05) * if i % 3 == 0 { 100.0 } else { 1.0 };
        let band = match i % 4 {
            0 => 0.0,
            1 => -0.01,
            _ => rng.uniform(1.0e-4, 0.05),
        };
        let want = math::sign_smooth(v, band);
        let got = math::sign_smooth_f64(f64::from(v), f64::from(band)) as f32;
        assert_eq!(got.to_bits(), want.to_bits(), "v {v}, band {band}");
    }
    assert_eq!(math::sign_smooth_f64(0.0, 0.0), 0.0);
    assert_eq!(math::sign_smooth_f64(-0.0, 0.01), 0.0);
    assert_eq!(math::sign_smooth_f64(f64::NAN, 0.01), -1.0);
    assert_eq!(math::clamp_f64(f64::NAN, -1.0, 1.0), -1.0);
}

/// Beyond |x| ≈ 3.4e9 rad the quadrant count saturates; sin/cos then reduce modulo f32 2π
/// (`fmodf`, exact) instead of linking libm's large-argument sinf/cosf (4.3 KiB of flash):
/// finite, bounded, a consistent sin/cos pair, and the same as the wrapped argument gives.
#[test]
fn huge_arguments_stay_finite_bounded_and_consistent() {
    for &x in &[1.0e10f32, -1.0e10, 1.0e30, -1.0e30, f32::MAX, f32::MIN] {
        let (s, c) = (math::sin(x), math::cos(x));
        assert!(math::abs(s) <= 1.0 && math::abs(c) <= 1.0, "{x}: {s} {c}");
        assert!(math::abs(s * s + c * c - 1.0) < 1e-6, "{x}");
        let w = libm::fmodf(x, core::f32::consts::TAU);
        assert_eq!(s.to_bits(), math::sin(w).to_bits(), "{x}");
        assert_eq!(c.to_bits(), math::cos(w).to_bits(), "{x}");
    }
    assert!(math::sin(f32::INFINITY).is_nan() && math::cos(f32::NEG_INFINITY).is_nan() && math::sin(f32::NAN).is_nan());
}
