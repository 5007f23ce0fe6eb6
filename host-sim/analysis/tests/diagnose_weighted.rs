//! A log whose samples carry very different errors: point-to-point moves under a model with a
//! narrow sign band and a large Coulomb level. Where a move starts or ends, q̇ crosses the band
//! at speeds the estimate only resolves to a fraction of the band, and the model's friction there
//! is uncertain by up to ±c; at speed it is predicted to the sensor noise. Unweighted, the held-out
//! MSE is the creeps' scatter, and an effect at speed (a viscous friction that falls as the joint
//! warms, unseen bench seed 9029, case 52) took 4 % of it, not significant: the verdict was
//! `none`. The fits and the test now weigh each sample by the inverse of its expected variance.
//!
//! The logs are built here from their own moves and the model's law (not by the simulator or the
//! bench); the twin without the drift must stay `none`.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

mod common;

use common::{gauss, moves};
use joint_formats::log::JointLog;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const MODEL: &str = "[friction]\na = 3.8\nb = 1.4\nc = 2.9\nv_band = 0.003\n\
                     [weight]\namplitude = 13.45\ns = 0.72\nphi = -3.32\n[inertia]\nj = 0.95\n\
                     [offset]\nc0 = 0.02\n";
const RATE: f64 = 400.0;

/// 40 s of moves; `u − tau` is the model's torque (viscous part `b·(1 + alpha·ΔT)`, the sign
/// clamped linear inside the band as the core computes it) plus white noise; `temp` rises by
/// 19 °C with a 12 s time constant, read to 0.1 °C; the angle carries encoder noise.
fn log(seed: u64, alpha: f64) -> JointLog {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (t, q, qd, qdd) = moves(&mut rng, 40.0, RATE, 0.6);
    let (a, b, c, band) = (3.8, 1.4, 2.9, 0.003);
    let (amp, s, phi, j, c0) = (13.45, 0.72, -3.32, 0.95, 0.02);
    let n = t.len();
    let (mut u, mut tau, mut temp) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let warm = 19.0 * (1.0 - (-t[i] / 12.0).exp());
        let sign = (qd[i] / band).clamp(-1.0, 1.0);
        let friction = a * qd[i] * qd[i].abs() + b * (1.0 + alpha * warm) * qd[i] + c * sign;
        let load = 0.8 * (0.5 * t[i]).sin() + 0.3 * (1.9 * t[i] + 0.4).sin();
        let model = j * qdd[i] + friction + amp * (s * q[i] + phi).sin() + c0;
        tau.push(load + 0.02 * gauss(&mut rng));
        u.push(model + load + 0.015 * gauss(&mut rng));
        temp.push(((26.0 + warm) * 10.0).round() / 10.0);
    }
    let q: Vec<f64> = q.iter().map(|x| ((x + 1.5e-5 * gauss(&mut rng)) / 1e-5).round() * 1e-5).collect();
    JointLog { t, q, u: Some(u), tau: Some(tau), temp: Some(temp), ..JointLog::default() }
}

fn verdicts(alpha: f64, seeds: std::ops::Range<u64>) -> Vec<String> {
    common::verdicts(MODEL, "weighted", seeds.map(|seed| (seed, log(seed, alpha))))
}

#[test]
fn a_viscous_drift_at_speed_is_found_beside_creeps_of_uncertain_sign() {
    let v = verdicts(-0.012, 1..5);
    let found = v.iter().filter(|e| *e == "thermal_drift").count();
    assert!(found >= 3, "thermal drift found in {found} of 4 logs: {v:?}");
}

#[test]
fn the_same_logs_without_the_drift_are_none() {
    let v = verdicts(0.0, 1..5);
    assert!(v.iter().all(|e| e == "none"), "{v:?}");
}
