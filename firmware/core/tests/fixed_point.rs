//! The fixed-point path against the f32 path over the operating range of the papers' joints,
//! and its pre-sliding (Dahl) state against the f32 one over a joint's motion.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;
use common::*;
use joint_core::control::Dahl;
use joint_core::fixed::{disturbance_fx, disturbance_stateful_fx, sin_fx, DahlFx, FixedParams, Fx};
use joint_core::math;
use joint_core::params::{check, ParamId};
use joint_core::vectors::to_fx;

fn worst_error(raw: joint_core::params::RawParams) -> f64 {
    let p = check(&raw).unwrap();
    let fp = FixedParams::from_set(&p);
    let t = p.terms();
    let mut worst = 0.0f64;
    for i in 0..=480 {
        let q = -0.2 + 2.4 * i as f32 / 480.0;
        for j in 0..=400 {
            let qd = -2.0 + 4.0 * j as f32 / 400.0;
            let f = t.friction.torque(qd) + t.weight.torque(q) + t.spring.torque(q, qd);
            let x = disturbance_fx(&fp, Fx::from_num(q), Fx::from_num(qd));
            worst = worst.max((x.to_num::<f64>() - f as f64).abs());
        }
    }
    worst
}

#[test]
fn fixed_point_within_target_for_the_papers_joints() {
    let mut results = Vec::new();
    for (name, t) in [("trunk right", &RIGHT), ("trunk left", &LEFT)] {
        let mut raw = raw_from(t);
        raw.set(ParamId::FrictionVBand, 0.01);
        results.push((name, worst_error(raw)));
    }
    let mut raw = joint_core::params::RawParams::defaults();
    raw.set(ParamId::SpringK, 7.3035);
    raw.set(ParamId::SpringB, 0.0416);
    raw.set(ParamId::FrictionVBand, 0.01);
    results.push(("elastic joint", worst_error(raw)));
    for (name, w) in &results {
        println!("fixed-point worst |error| vs f32, {name}: {w:.2e} N·m");
        assert!(*w <= 0.002, "{name}: {w}");
    }
}

#[test]
fn fixed_sine_error() {
    let mut worst = 0.0f64;
    for i in 0..=100_000 {
        let x = -100.0 + 200.0 * i as f64 / 100_000.0;
        let fx = Fx::from_num(x);
        let exact = fx.to_num::<f64>().sin();
        worst = worst.max((sin_fx(fx).to_num::<f64>() - exact).abs());
    }
    println!("fixed-point sin worst abs error over ±100 rad: {worst:.2e}");
    assert!(worst < 3e-5, "{worst}");
}

#[test]
fn fixed_point_saturates_instead_of_overflowing() {
    let mut raw = joint_core::params::RawParams::defaults();
    raw.set(ParamId::FrictionA, 1000.0);
    raw.set(ParamId::SpringK, 10000.0);
    let p = check(&raw).unwrap();
    let fp = FixedParams::from_set(&p);
    let x = disturbance_fx(&fp, Fx::MAX, Fx::MAX);
    assert_eq!(x, Fx::MAX);
    let y = disturbance_fx(&fp, Fx::MIN, Fx::MIN);
    assert_eq!(y, Fx::MIN);
}

/// Worst |error| of the fixed path with its Dahl state against the f32 path over 20 s at 1 kHz
/// of a swing (±0.6 rad, 0.5 Hz) with a ±1.5 mrad, 7 Hz tremor on it (a reversal every
/// ~70 ms, most of them inside the pre-sliding distance) and a few 0.3 rad jumps. `exact_angles`:
/// both paths get angles that Q16.16 holds exactly (an encoder's), else the f32 path gets the
/// unrounded angle. Returns (F error, friction + weight + spring error), N·m.
fn dahl_worst(sigma: f32, exact_angles: bool) -> (f64, f64) {
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::FrictionVBand, 0.01);
    raw.set(ParamId::SpringK, 7.3035);
    raw.set(ParamId::SpringB, 0.0416);
    raw.set(ParamId::PreslidingSigma, sigma);
    let p = check(&raw).unwrap();
    let fp = FixedParams::from_set(&p);
    let t = p.terms();
    let (mut d32, mut dfx) = (Dahl::new(), DahlFx::new());
    let (mut worst_f, mut worst_d) = (0.0f64, 0.0f64);
    let tau = 2.0 * std::f32::consts::PI;
    for i in 0..20_000 {
        let s = i as f32 * 1.0e-3;
        let jump = if (i / 2500) % 2 == 1 { 0.3 } else { 0.0 };
        let mut q = 0.9 + jump + 0.6 * math::sin(tau * 0.5 * s) + 1.5e-3 * math::sin(tau * 7.0 * s);
        let qd = 0.6 * tau * 0.5 * math::cos(tau * 0.5 * s) + 1.5e-3 * tau * 7.0 * math::cos(tau * 7.0 * s);
        if exact_angles {
            q = to_fx(q).to_num::<f32>();
        }
        let f = d32.update(&p, q, qd);
        let d = t.friction.viscous(qd) + f + t.weight.torque(q) + t.spring.torque(q, qd);
        let x = disturbance_stateful_fx(&fp, &mut dfx, to_fx(q), to_fx(qd));
        worst_f = worst_f.max((dfx.force().to_num::<f64>() - f as f64).abs());
        worst_d = worst_d.max((x.to_num::<f64>() - d as f64).abs());
    }
    (worst_f, worst_d)
}

#[test]
fn fixed_point_dahl_state_against_f32() {
    for sigma in [800.0f32, 8000.0] {
        let (f_exact, d_exact) = dahl_worst(sigma, true);
        let (f_round, d_round) = dahl_worst(sigma, false);
        println!(
            "fixed-point Dahl state vs f32, trunk right + spring, sigma = {sigma} N·m/rad: worst |F error| \
             {f_exact:.2e} N·m, friction + weight + spring {d_exact:.2e} N·m on the same (Q16.16) angles; \
             {f_round:.2e} / {d_round:.2e} N·m when the f32 path sees the unrounded angle"
        );
        // Same angles: only the arithmetic differs (exp series, Q16.16 products and output).
        assert!(f_exact <= 1.0e-4 && d_exact <= 1.0e-3, "{f_exact} {d_exact}");
        // Rounded angles: F's slope dF/dq is up to 2σ (right after a reversal from ±c), the
        // travel since the reversal is off by up to two half-LSBs (2^-16 rad).
        let bound = 2.0 * f64::from(sigma) * 2.0f64.powi(-16) + 1.0e-3;
        assert!(f_round <= bound && d_round <= bound + 1.0e-3, "{f_round} {d_round} > {bound}");
    }
}

#[test]
fn fixed_point_dahl_state_stays_within_its_level() {
    let mut raw = joint_core::params::RawParams::defaults();
    raw.set(ParamId::FrictionA, 1000.0);
    raw.set(ParamId::SpringK, 10000.0);
    raw.set(ParamId::FrictionC, 1000.0);
    raw.set(ParamId::DryFrictionC, 1000.0);
    raw.set(ParamId::PreslidingSigma, 1.0e7);
    let fp = FixedParams::from_set(&check(&raw).unwrap());
    let c = fp.dahl_c;
    let mut d = DahlFx::new();
    for q in [Fx::MAX, Fx::MIN, Fx::ZERO, Fx::from_bits(1), Fx::MIN, Fx::MAX, Fx::from_num(0.001)] {
        let f = d.update(&fp, q, Fx::MAX);
        assert!(f <= c && f >= -c, "{f} outside ±{c}");
    }
    assert_eq!(disturbance_stateful_fx(&fp, &mut d, Fx::MAX, Fx::MAX), Fx::MAX);
    assert_eq!(disturbance_stateful_fx(&fp, &mut d, Fx::MIN, Fx::MIN), Fx::MIN);
}
