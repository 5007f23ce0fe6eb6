//! A measured load's own noise is not load-dependent friction. In torque mode the residual is
//! `u − tau − model`, so it holds −tau's noise; a load-dependent friction regressor built from
//! the same sample's |tau| shares that noise wherever the load keeps a sign against the motion
//! (a contact dragging on the link), and "explains" part of it on held-out samples as well.
//! Unseen bench t9025/case-0011 (an exact elastic-joint model, a payload in contact) was named
//! `load_dependent_friction` at 4.9 % shrink that way.
//!
//! The log is built here from its own motion and the model's law (not the simulator, not the
//! bench): exact model, a drag load against the motion measured with white noise.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use joint_analysis::diagnose::{diagnose, Options};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const MODEL: &str = "[friction]\nc = 0.0036\n[inertia]\nj = 0.011\n[spring]\nk = 6.35\nb = 0.052\nq0 = 0.0\n";

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Two sines at 100 Hz for 40 s, q̇ logged clean; the load `tau` drags against the motion
/// (0.01–0.09 N·m, slowly varying, smooth in q̇), its cell adds white noise of 0.017 N·m;
/// `u` = model + load + noise.
fn log(seed: u64, with_mu: f64) -> JointLog {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (rate, secs) = (100.0, 40.0);
    let n = (rate * secs) as usize;
    let (j, k, b, c) = (0.011, 6.35, 0.052, 0.0036);
    let w = [std::f64::consts::TAU * 0.31, std::f64::consts::TAU * 0.73];
    let (a1, a2) = (0.25, 0.08);
    let mut l = JointLog::default();
    let (mut qd_col, mut u, mut tau) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        let t = i as f64 / rate;
        let q = a1 * (w[0] * t).sin() + a2 * (w[1] * t).sin();
        let v = a1 * w[0] * (w[0] * t).cos() + a2 * w[1] * (w[1] * t).cos();
        let acc = -a1 * w[0] * w[0] * (w[0] * t).sin() - a2 * w[1] * w[1] * (w[1] * t).sin();
        let load = -0.05 * (1.0 + 0.8 * (std::f64::consts::TAU * 0.05 * t).sin()) * (v / 0.05).tanh();
        let sign = v.signum();
        // a load-dependent friction μ·|load|·sign(q̇) when the test puts one in
        let model = j * acc + b * v + k * q + (c + with_mu * load.abs()) * sign;
        l.t.push(t);
        l.q.push(q + 2e-5 * gauss(&mut rng));
        qd_col.push(v);
        tau.push(load + 0.017 * gauss(&mut rng));
        u.push(model + load + 0.009 * gauss(&mut rng));
    }
    l.qd = Some(qd_col);
    l.u = Some(u);
    l.tau = Some(tau);
    l
}

#[test]
fn a_noisy_load_against_the_motion_is_not_load_dependent_friction() {
    let m = ModelFile::parse(MODEL, "elastic").unwrap();
    let mut named = Vec::new();
    for seed in 1..=6 {
        let d = diagnose(&log(seed, 0.0), &m, &Options::default()).unwrap();
        let r = &d.report;
        println!(
            "seed {seed}: {} (held out {:.4}, floor {:.4})",
            r.verdict.effect, r.gap.holdout_rmse, r.gap.noise_floor
        );
        if r.verdict.effect != "none" {
            named.push((seed, r.verdict.effect.clone()));
        }
    }
    assert!(named.is_empty(), "exact-model logs named: {named:?}");
}

/// The same log with a real load-dependent friction (μ = 0.6: up to 0.054 N·m at the largest
/// load, three times the cell's noise) is still found: reading the load around the sample loses
/// nothing a load that varies with the motion carries.
#[test]
fn a_real_load_dependent_friction_is_still_found() {
    let m = ModelFile::parse(MODEL, "elastic").unwrap();
    let d = diagnose(&log(1, 0.6), &m, &Options::default()).unwrap();
    println!("μ = 0.6: {:?}", d.report.verdict);
    assert_eq!(d.report.verdict.effect, "load_dependent_friction");
}
