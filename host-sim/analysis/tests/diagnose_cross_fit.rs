//! Cross-fitting (`Split::cross_fitted`): on a short torque log the held-out 30 % of one split
//! leaves the tests short of power. A viscous friction that drifts as the joint warms took 59 % of
//! a 1 000-sample log's held-out MSE at p = 5e-3, not significant against 0.05/11, and the verdict
//! was `parameters` (development seed 9041, case 36). Scored over three folds, every sample held
//! out once, the same drift is found; one split alone (`Options::cross_fit` off, the CLI's
//! `--single-split`) finds it less often, and the twins without the drift stay `none` both ways.
//!
//! The logs are built here from their own moves and the model's law (not by the simulator or the
//! bench).
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

mod common;

use common::gauss;
use joint_analysis::diagnose::Options;
use joint_formats::log::JointLog;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const MODEL: &str = "[friction]\nb = 6.0\nc = 5.0\nv_band = 0.03\n\
                     [weight]\namplitude = 30.0\ns = 1.0\nphi = -2.0\n[inertia]\nj = 1.25\n";

/// 12 s of a two-sine excitation at 100 Hz (an arm joint's model, as in the seed-9041 case);
/// `u − tau` is the model's torque with its viscous friction scaled by `1 + drift·(1 − e^(−t/6 s))`,
/// white noise on both torques, the angle read by a 4096-count encoder, q̇ logged with white
/// noise, q̈ left to the diagnosis.
fn log(seed: u64, drift: f64) -> JointLog {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (rate, seconds) = (100.0, 12.0);
    let (b, c, band) = (6.0, 5.0, 0.03);
    let (amp, s, phi, j) = (30.0, 1.0, -2.0, 1.25);
    let n = (rate * seconds) as usize;
    let w = [std::f64::consts::TAU * 0.31, std::f64::consts::TAU * 0.73];
    let (a, ph) = ([0.4, 0.15], [0.0, 0.5 + rng.random::<f64>()]);
    let (mut t, mut q, mut qd) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut u, mut tau) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let ti = i as f64 / rate;
        let (mut x, mut v, mut acc) = (0.5, 0.0, 0.0);
        for k in 0..2 {
            x += a[k] * (w[k] * ti + ph[k]).sin();
            v += a[k] * w[k] * (w[k] * ti + ph[k]).cos();
            acc -= a[k] * w[k] * w[k] * (w[k] * ti + ph[k]).sin();
        }
        let warm = 1.0 + drift * (1.0 - (-ti / 6.0).exp());
        let friction = b * warm * v + c * (v / band).tanh();
        let load = 2.0 * (0.7 * ti).sin();
        let model = j * acc + friction + amp * (s * x + phi).sin();
        tau.push(load + 0.1 * gauss(&mut rng));
        u.push(model + load + 0.1 * gauss(&mut rng));
        t.push(ti);
        q.push(x);
        qd.push(v);
    }
    let step = std::f64::consts::TAU / 4096.0;
    let q: Vec<f64> = q.iter().map(|x| (x / step).round() * step).collect();
    let qd: Vec<f64> = qd.iter().map(|x| x + 0.002 * gauss(&mut rng)).collect();
    JointLog { t, q, qd: Some(qd), u: Some(u), tau: Some(tau), ..JointLog::default() }
}

fn verdicts(drift: f64, cross_fit: bool) -> Vec<String> {
    let opts = Options { cross_fit, ..Options::default() };
    common::verdicts_with(MODEL, "cross-fit", (1..9).map(|seed| (seed, log(seed, drift))), &opts)
}

#[test]
fn a_drift_in_a_short_log_is_found_over_three_folds_more_often_than_on_one_split() {
    // (measured: 8 of 8 over three folds, 2 of 8 on one split, the others `unexplained`)
    let drift = 0.1;
    let folds = verdicts(drift, true);
    let one = verdicts(drift, false);
    let found = |v: &[String]| v.iter().filter(|e| *e == "thermal_drift").count();
    println!("three folds {folds:?}\none split {one:?}");
    assert!(found(&folds) >= 6, "drift found in {} of 8 logs over three folds: {folds:?}", found(&folds));
    assert!(found(&folds) >= found(&one) + 3, "three folds {folds:?}, one split {one:?}");
}

#[test]
fn the_same_logs_without_the_drift_are_none_both_ways() {
    for cross_fit in [true, false] {
        let v = verdicts(0.0, cross_fit);
        assert!(v.iter().all(|e| e == "none"), "cross-fitted {cross_fit}: {v:?}");
    }
}
