//! Pre-sliding (Dahl) friction in the core: the exact update against an independent f64
//! integration, its bounds for any step, the controller's use of it, and the off path.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;
use common::*;
use joint_core::control::{
    disturbance, disturbance_dahl, disturbance_stateful, presliding_forces, Controller, Dahl, Input, Mode,
};
use joint_core::model::Presliding;
use joint_core::params::{check, ParamId, ParamSet, RawParams};
use proptest::prelude::*;

fn trunk_dahl(sigma: f32) -> ParamSet {
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::FrictionVBand, 0.01);
    raw.set(ParamId::PreslidingSigma, sigma);
    check(&raw).unwrap()
}

/// dF/dq = σ(1 − F/c·sign(dq)) integrated by RK4 in q with `n` steps over `dq`: a method that
/// shares nothing with the core's closed form.
fn rk4(f: f64, dq: f64, sigma: f64, c: f64, n: usize) -> f64 {
    let s = dq.signum();
    let g = |f: f64| sigma * (1.0 - f / c * s);
    let h = dq / n as f64;
    let mut f = f;
    for _ in 0..n {
        let k1 = g(f);
        let k2 = g(f + 0.5 * h * k1);
        let k3 = g(f + 0.5 * h * k2);
        let k4 = g(f + h * k3);
        f += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    f
}

#[test]
fn advance_is_the_solution_of_the_dahl_equation() {
    let (sigma, c) = (800.0f32, 2.32f32);
    let pre = Presliding::new(sigma, c);
    let mut worst = 0.0f64;
    for &f0 in &[-2.32f32, -1.0, 0.0, 0.7, 2.32] {
        for &dq in &[1.0e-6f32, -3.0e-5, 4.0e-4, -1.0e-3, 2.9e-3, -8.0e-3, 0.03] {
            let got = pre.advance(f0, dq) as f64;
            let want = rk4(f64::from(f0), f64::from(dq), f64::from(sigma), f64::from(c), 4000);
            worst = worst.max((got - want).abs());
        }
    }
    println!("Dahl update vs RK4 in f64: worst |error| {worst:.2e} N·m");
    assert!(worst < 2.0e-6, "{worst}");
}

#[test]
fn travel_splits_like_the_equation() {
    // Two steps in the same direction are one step of their sum (the flow property).
    let pre = Presliding::new(800.0, 2.32);
    for &f0 in &[-2.0f32, 0.0, 1.5] {
        for &(a, b) in &[(1.0e-3f32, 2.0e-3f32), (-5.0e-4, -5.0e-4), (1.0e-5, 3.0e-3)] {
            let two = pre.advance(pre.advance(f0, a), b);
            let one = pre.advance(f0, a + b);
            assert!((two - one).abs() < 2.0e-6, "{f0} {a} {b}: {two} vs {one}");
        }
    }
}

#[test]
fn zero_level_zero_travel_and_long_travel() {
    let zero = Presliding::new(800.0, 0.0);
    assert_eq!(zero.advance(0.0, 0.01), 0.0);
    assert_eq!(zero.advance(0.3, -0.01), 0.0, "a state above a zero level is pulled in");
    let pre = Presliding::new(800.0, 2.32);
    assert_eq!(pre.advance(1.234, 0.0), 1.234);
    assert_eq!(pre.advance(-2.32, 1.0), 2.32, "far beyond c/σ: exactly +c");
    assert_eq!(pre.advance(2.32, -1.0e3), -2.32);
    // A state from a larger level is limited to the new one.
    assert_eq!(pre.advance(5.0, 0.0), 2.32);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn bounded_for_any_step(
        sigma in prop_oneof![0.0f32..=1.0e7, Just(1.0e7f32), Just(1.0e-30f32)],
        c in prop_oneof![0.0f32..=2.0e3, Just(0.0f32), Just(1.0e-40f32)],
        u in -1.0f32..=1.0,
        dq in prop_oneof![any::<f32>().prop_filter("finite", |x| x.is_finite()), -1.0e-3f32..1.0e-3],
    ) {
        let pre = Presliding::new(sigma, c);
        let f = pre.advance(u * c, dq);
        prop_assert!(f.is_finite(), "{f}");
        prop_assert!(f.abs() <= c, "|{f}| > {c}");
        // F moves toward c·sign(dq), never away.
        if dq > 0.0 { prop_assert!(f >= u * c); }
        if dq < 0.0 { prop_assert!(f <= u * c); }
    }

    #[test]
    fn off_path_is_the_stateless_model_to_the_bit(
        q in -3.0f32..3.0, qd in -5.0f32..5.0, qdd in -50.0f32..50.0, o in -1.0f32..1.0,
    ) {
        let mut raw = raw_from(&LEFT);
        raw.set(ParamId::DryFrictionC, 0.4);
        raw.set(ParamId::StribeckLevel, 0.5);
        let p = check(&raw).unwrap();
        let mut d = Dahl::new();
        let a = disturbance_stateful(&p, &mut d, q, qd, qdd, &[o, 0.0, 0.0], 0.0);
        let b = disturbance(&p, q, qd, qdd, &[o, 0.0, 0.0], 0.0);
        prop_assert_eq!(a.to_bits(), b.to_bits());
        prop_assert_eq!(d, Dahl::new());
    }
}

#[test]
fn primed_with_the_coulomb_terms_own_value() {
    let p = trunk_dahl(800.0);
    let c = p.terms().presliding.c;
    let first = |qd: f32| Dahl::new().update(&p, 0.3, qd);
    assert_eq!(first(0.0), 0.0, "at rest");
    assert_eq!(first(0.5), c, "sliding forward");
    assert_eq!(first(-0.5), -c, "sliding backward");
    assert_eq!(first(0.005), 0.5 * c, "inside the band, as sign_smooth");
    // A non-finite sample neither primes nor moves the state.
    let mut d = Dahl::new();
    assert_eq!(d.update(&p, f32::NAN, 0.5), 0.0);
    assert_eq!(d.update(&p, 0.3, 0.0), 0.0);
    assert_eq!(d.update(&p, f32::INFINITY, 0.0), 0.0);
    assert!(d.update(&p, 0.301, 0.0) > 0.0);
}

#[test]
fn dry_friction_joins_the_dahl_level() {
    let mut raw = RawParams::defaults();
    raw.set(ParamId::DryFrictionC, 0.5);
    raw.set(ParamId::FrictionC, 0.25);
    let off = check(&raw).unwrap();
    raw.set(ParamId::PreslidingSigma, 500.0);
    let on = check(&raw).unwrap();
    assert!(off.terms().extra.any && off.terms().extra.dry_c == 0.5);
    assert!(!on.terms().extra.any && on.terms().extra.dry_c == 0.0, "no jump left beside the state");
    assert_eq!(on.terms().presliding.c, 0.75);
    // Sliding far forward: the stateful model is the sign model of the whole level, bit for bit.
    let mut d = Dahl::new();
    let mut last = 0.0;
    for i in 0..200 {
        last = disturbance_stateful(&on, &mut d, 0.01 * i as f32, 0.5, 0.0, &[0.0; 3], 0.0);
    }
    assert_eq!(d.force(), 0.75);
    assert_eq!(last.to_bits(), disturbance(&on, 1.99, 0.5, 0.0, &[0.0; 3], 0.0).to_bits());
    assert_eq!(disturbance(&on, 1.99, 0.5, 0.0, &[0.0; 3], 0.0), disturbance(&off, 1.99, 0.5, 0.0, &[0.0; 3], 0.0));
}

#[test]
fn small_oscillation_stays_in_pre_sliding() {
    // ±0.3 mrad against c/σ = 2.9 mrad: a hysteresis loop well inside ±c, almost a spring σ.
    let p = trunk_dahl(800.0);
    let c = p.terms().presliding.c;
    let mut d = Dahl::new();
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for i in 0..400 {
        let q = 1.0 + 3.0e-4 * joint_core::math::sin(2.0 * std::f32::consts::PI * i as f32 / 40.0);
        let f = d.update(&p, q, 0.0);
        if i >= 200 {
            lo = lo.min(f);
            hi = hi.max(f);
        }
    }
    assert!(hi < 0.3 * c && lo > -0.3 * c, "{lo}..{hi} of ±{c}");
    // The settled loop of a swing ±A: F between ±c·tanh(σA/c) (0.239 N·m here, close to the
    // spring σ·A = 0.24 N·m).
    let edge = c * (800.0f32 / c * 3.0e-4).tanh();
    assert!((hi - edge).abs() < 2e-3 && (lo + edge).abs() < 2e-3, "{lo}..{hi} vs ±{edge}");
}

#[test]
fn controller_runs_the_state_the_host_helper_computes() {
    let p = trunk_dahl(800.0);
    let n = 300;
    let qs: Vec<f32> = (0..n).map(|i| 0.5 + 0.02 * joint_core::math::sin(0.05 * i as f32)).collect();
    let qds: Vec<f32> = (0..n).map(|i| 0.02 * 0.05 * 1000.0 * joint_core::math::cos(0.05 * i as f32)).collect();
    let mut fs = vec![0.0f32; n];
    presliding_forces(&p, &qs, &qds, &mut fs);
    let mut ctl = Controller::new();
    for (i, ((&q, &qd), &f)) in qs.iter().zip(&qds).zip(&fs).enumerate() {
        // Mode changes do not touch the state: it is the joint's friction.
        let mode = if i % 50 < 10 { Mode::Off } else { Mode::Assist };
        if i % 50 == 10 {
            ctl.reset();
        }
        let out = ctl.step(&p, mode, &Input { q, qd, qdd: 0.0, others: [0.0; 3], ..Input::default() }, 1e-3);
        assert_eq!(ctl.presliding().force().to_bits(), f.to_bits(), "sample {i}");
        assert_eq!(out.c_c.to_bits(), disturbance_dahl(&p, q, qd, 0.0, &[0.0; 3], 0.0, f).to_bits(), "sample {i}");
    }
    // A bad sample leaves the state; a new parameter set starts it afresh.
    let before = *ctl.presliding();
    let out = ctl.step(&p, Mode::Assist, &Input { q: f32::NAN, ..Input::default() }, 1e-3);
    assert!(out.bad_input);
    assert_eq!(*ctl.presliding(), before);
    ctl.reset_presliding();
    assert_eq!(*ctl.presliding(), Dahl::new());
}

#[test]
fn velocity_feed_forward_uses_the_state() {
    // In velocity mode at the target speed the command is the feed-forward alone: with the
    // state at −c (last travel backward) the Coulomb part is −c, not c·sign(v).
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::PreslidingSigma, 800.0);
    raw.set(ParamId::TorqueLimit, 1.0e3);
    raw.set(ParamId::RateLimit, 1.0e6);
    let p = check(&raw).unwrap();
    let mut sign_raw = raw.clone();
    sign_raw.set(ParamId::PreslidingSigma, 0.0);
    let s = check(&sign_raw).unwrap();
    let inp = |q: f32| Input { q, qd: 0.2, qdd: 0.0, others: [0.0; 3], ..Input::default() };
    let mut ctl = Controller::new();
    ctl.step(&p, Mode::Off, &inp(0.5), 1e-3);
    ctl.step(&p, Mode::Off, &inp(0.4), 1e-3); // 100 mrad backward: F = −c
    assert_eq!(ctl.presliding().force(), -2.32);
    let with_state = ctl.step(&p, Mode::Velocity(0.2), &inp(0.4), 1e-3).tau_out;
    let with_sign = Controller::new().step(&s, Mode::Velocity(0.2), &inp(0.4), 1e-3).tau_out;
    assert!((with_sign - with_state - 2.0 * 2.32).abs() < 1e-4, "{with_sign} vs {with_state}");
}
