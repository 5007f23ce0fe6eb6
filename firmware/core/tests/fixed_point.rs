//! The fixed-point path against the f32 path over the operating range of the papers' joints.

mod common;
use common::*;
use joint_core::fixed::{disturbance_fx, sin_fx, FixedParams, Fx};
use joint_core::params::{check, ParamId};

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
