//! Trajectories the diagnosis tests build their own logs from (not the simulator's or the
//! bench's): minimum-jerk moves between drawn targets, and Gaussian noise; and the verdicts the
//! diagnosis gives such logs.
#![allow(dead_code, clippy::indexing_slicing, clippy::expect_used)]

use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller, enough for a test's noise
    let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Minimum-jerk moves between drawn targets, some pairs the same way with no dwell between them
/// (the near stop), some after a dwell, sampled at `rate` Hz. Returns the clean (t, q, q̇, q̈).
pub fn moves(
    rng: &mut ChaCha8Rng,
    seconds: f64,
    rate: f64,
    dwell_min: f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = (seconds * rate) as usize;
    let (mut t, mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut at = 0.5;
    let mut now = 0.0;
    // (start, end, from, to); a dwell is a move of zero length
    let mut plan = Vec::new();
    while now < seconds {
        let dwell = rng.random::<f64>() < 0.2;
        let dur = if dwell { dwell_min + 0.4 * rng.random::<f64>() } else { 0.8 + 2.0 * rng.random::<f64>() };
        // small same-way steps after a move are what creep through a near stop
        let to = if dwell {
            at
        } else if rng.random::<f64>() < 0.4 {
            let last: f64 = plan.last().map_or(1.0, |&(_, _, a, b): &(f64, f64, f64, f64)| b - a);
            (at + last.signum() * (0.005 + 0.03 * rng.random::<f64>())).clamp(-0.2, 1.2)
        } else {
            -0.1 + 1.2 * rng.random::<f64>()
        };
        plan.push((now, now + dur, at, to));
        at = to;
        now += dur;
    }
    let mut k = 0;
    for i in 0..n {
        let ti = i as f64 / rate;
        while k + 1 < plan.len() && ti >= plan[k].1 {
            k += 1;
        }
        let (t0, t1, a, b) = plan[k];
        let (d, s) = (t1 - t0, ((ti - t0) / (t1 - t0)).clamp(0.0, 1.0));
        let (p, v, acc) = (
            10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5),
            (30.0 * s.powi(2) - 60.0 * s.powi(3) + 30.0 * s.powi(4)) / d,
            (60.0 * s - 180.0 * s.powi(2) + 120.0 * s.powi(3)) / (d * d),
        );
        t.push(ti);
        q.push(a + (b - a) * p);
        qd.push((b - a) * v);
        qdd.push((b - a) * acc);
    }
    (t, q, qd, qdd)
}

/// The verdict `jointctl diagnose` gives each `(seed, log)` against `model` (named `name`), each
/// printed with its held-out RMSE and floor.
pub fn verdicts(
    model: &str,
    name: &str,
    logs: impl IntoIterator<Item = (u64, joint_formats::log::JointLog)>,
) -> Vec<String> {
    verdicts_with(model, name, logs, &joint_analysis::diagnose::Options::default())
}

/// [`verdicts`] with the diagnosis' options.
pub fn verdicts_with(
    model: &str,
    name: &str,
    logs: impl IntoIterator<Item = (u64, joint_formats::log::JointLog)>,
    opts: &joint_analysis::diagnose::Options,
) -> Vec<String> {
    let m = joint_formats::model_file::ModelFile::parse(model, name).expect("the test's model parses");
    logs.into_iter()
        .map(|(seed, log)| {
            let d = joint_analysis::diagnose::diagnose(&log, &m, opts).expect("the test's log is diagnosed");
            let r = &d.report;
            println!(
                "seed {seed}: verdict {} (held-out RMSE {:.4}, floor {:.4})",
                r.verdict.effect, r.gap.holdout_rmse, r.gap.noise_floor
            );
            r.verdict.effect.clone()
        })
        .collect()
}
