//! The elastic joint (elastic-joint paper): K from the static torque–angle slope, J and B from
//! the free oscillation.
//!
//! **K** (paper §3, Fig. 5): the static poses' torques against their angles form two straight
//! branches, one for positive and one for negative torque; a gearbox dead zone separates them
//! (the torque stays near zero while the angle moves). Each branch is fitted by least squares,
//! K is the mean of the two slopes as in the paper, the rest angle q0 is the midpoint of the two
//! zero crossings and the dead-zone width their distance. Without a dead zone both branches lie
//! on one line and the width comes out ≈ 0.
//!
//! **J, B** (paper eq. 5–12): the released joint obeys `J·q̈ + B·q̇ + K·dz(q − q0) = 0`. The
//! response is simulated (RK4, dead zone included) and fitted to the logged angle by
//! Levenberg–Marquardt over `K/J`, `B/J` and the initial angle and velocity (the state at the
//! start of the fitted stretch is not assumed, it is estimated), from several starts spread
//! around the frequency seen in the zero crossings. With K known, `J = K/(K/J)` and
//! `B = (B/J)·J`.

use super::nls;
use super::robust;
use super::segments::{Prepared, Segment};
use super::weight::Pose;

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StaticSpring {
    pub k: f64,
    pub q0: f64,
    /// total dead-zone width, rad (0 when the branches coincide)
    pub dead_zone: f64,
    /// slopes of the positive- and negative-torque branches
    pub k_pos: f64,
    pub k_neg: f64,
    pub poses_pos: usize,
    pub poses_neg: usize,
}

/// K, q0 and the dead zone from static poses.
pub fn static_fit(poses: &[Pose]) -> Option<StaticSpring> {
    let dmax = poses.iter().fold(0.0f64, |m, p| m.max(p.d.abs()));
    // Inside the dead zone the torque is noise and the creep's friction: leave out the poses
    // below 10 % of the largest torque.
    let thr = 0.1 * dmax;
    let branch = |sign: f64| -> Option<(f64, f64, usize)> {
        let sel: Vec<&Pose> = poses.iter().filter(|p| sign * p.d > thr).collect();
        if sel.len() < 2 {
            return None;
        }
        let q: Vec<f64> = sel.iter().map(|p| p.q).collect();
        let d: Vec<f64> = sel.iter().map(|p| p.d).collect();
        let one = vec![1.0; q.len()];
        let (k, c) = if sel.len() == 2 {
            let k = (d[1] - d[0]) / (q[1] - q[0]);
            (k, d[0] - k * q[0])
        } else {
            let lf = robust::ols(&[&q, &one], &d)?;
            (lf.beta[0], lf.beta[1])
        };
        (k.is_finite() && k > 0.0).then_some((k, -c / k, sel.len()))
    };
    match (branch(1.0), branch(-1.0)) {
        (Some((kp, xp, np)), Some((kn, xn, nn))) => Some(StaticSpring {
            k: 0.5 * (kp + kn),
            q0: 0.5 * (xp + xn),
            dead_zone: (xp - xn).max(0.0),
            k_pos: kp,
            k_neg: kn,
            poses_pos: np,
            poses_neg: nn,
        }),
        (Some((k, x, n)), None) | (None, Some((k, x, n))) => {
            Some(StaticSpring { k, q0: x, dead_zone: 0.0, k_pos: k, k_neg: k, poses_pos: n, poses_neg: 0 })
        }
        (None, None) => None,
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FreeFit {
    /// K/J, 1/s²
    pub k_over_j: f64,
    /// B/J, 1/s
    pub b_over_j: f64,
    pub q_start: f64,
    pub qd_start: f64,
    /// rest angle used (given, or estimated when no static data gave one)
    pub q0: f64,
    /// natural frequency √(K/J), rad/s, and damping ratio
    pub omega_n: f64,
    pub zeta: f64,
    /// RMS of the angle residual, rad
    pub rms: f64,
    pub n: usize,
    /// index of the log, first and last sample time of the fitted stretch
    pub log: usize,
    pub t0: f64,
    pub t1: f64,
}

fn dz(x: f64, w: f64) -> f64 {
    let h = 0.5 * w;
    if x > h {
        x - h
    } else if x < -h {
        x + h
    } else {
        0.0
    }
}

#[allow(clippy::too_many_arguments)] // the model's parameters and state, each a plain number
/// Simulates q̈ = −kj·dz(q − q0) − bj·q̇ at the sample times `t` from (x0, v0), into `out`.
pub fn simulate(t: &[f64], kj: f64, bj: f64, q0: f64, w: f64, x0: f64, v0: f64, out: &mut [f64]) {
    let acc = |x: f64, v: f64| -kj * dz(x - q0, w) - bj * v;
    let (mut x, mut v) = (x0, v0);
    let Some(&t_first) = t.first() else { return };
    let mut tc = t_first;
    // Sub-steps: at least 20 per undamped period and no longer than the sample spacing.
    let h_max = (std::f64::consts::TAU / kj.abs().max(1e-9).sqrt() / 20.0).min(0.005);
    for (o, &ti) in out.iter_mut().zip(t) {
        let span = ti - tc;
        if span > 0.0 {
            let steps = (span / h_max).ceil().max(1.0) as usize;
            let h = span / steps as f64;
            for _ in 0..steps {
                let (k1x, k1v) = (v, acc(x, v));
                let (k2x, k2v) = (v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
                let (k3x, k3v) = (v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
                let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v));
                x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
            tc = ti;
        }
        *o = x;
    }
}

/// Fits the free oscillation of `seg` in `p` around rest angle `q0` (None: estimated too,
/// from the last fifth of the stretch as a start) with dead zone `w`.
pub fn free_fit(p: &Prepared, log: usize, seg: &Segment, q0: Option<f64>, w: f64) -> Option<FreeFit> {
    let t = &p.t[seg.start..seg.end];
    let q = &p.q[seg.start..seg.end];
    let n = t.len();
    if n < 20 {
        return None;
    }
    // Frequency guess from the zero crossings of the (filtered) velocity: two per period.
    let v = &p.qd_f[seg.start..seg.end];
    // Only while the oscillation is well above the velocity noise: once it has died, the noise
    // crosses zero at random and would fake a high frequency.
    let vmax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let live = v.iter().rposition(|x| x.abs() > 0.1 * vmax).unwrap_or(n - 1) + 1;
    let crossings: Vec<f64> =
        v[..live].windows(2).zip(t.windows(2)).filter(|(v, _)| v[0] * v[1] < 0.0).map(|(_, t)| t[0]).collect();
    let omega0 = if crossings.len() >= 3 {
        let span = crossings[crossings.len() - 1] - crossings[0];
        std::f64::consts::PI * (crossings.len() - 1) as f64 / span.max(1e-9)
    } else {
        std::f64::consts::TAU / (t[n - 1] - t[0]).max(1e-3)
    };
    // The logged velocity (not the classification filter's, which attenuates the oscillation).
    let (x0, v0) = (q[0], p.qd[seg.start]);
    let tail = &q[n - n / 5..];
    let q_rest = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
    let mut starts = Vec::new();
    for f in [0.7, 0.85, 1.0, 1.15, 1.3] {
        for zeta in [0.02, 0.1, 0.3] {
            let wn = omega0 * f;
            let mut s = vec![wn * wn, 2.0 * zeta * wn, x0, v0];
            if q0.is_none() {
                s.push(q_rest);
            }
            starts.push(s);
        }
    }
    let t0 = t[0];
    let tt: Vec<f64> = t.iter().map(|x| x - t0).collect();
    let resid = |m: usize| {
        let mut sim = vec![0.0; m];
        let (tt, q) = (&tt[..m], &q[..m]);
        move |pp: &[f64], r: &mut [f64]| {
            let rest = q0.unwrap_or_else(|| pp.get(4).copied().unwrap_or(0.0));
            simulate(tt, pp[0], pp[1], rest, w, pp[2], pp[3], &mut sim);
            for ((ri, s), q) in r.iter_mut().zip(&sim).zip(q) {
                *ri = s - q;
            }
        }
    };
    // Stage 1 on the first two periods, where a wrong frequency cannot yet hide behind a
    // wrapped phase; stage 2 refines the best start on the whole stretch.
    let period = std::f64::consts::TAU / omega0.max(1e-9);
    let m1 = tt.partition_point(|&x| x < 2.0 * period).clamp(20.min(n), n);
    let first = nls::multi_start(resid(m1), &starts, m1, 100)?;
    let fit = nls::levenberg_marquardt(resid(n), &first.params, n, 100);
    let (kj, bj) = (fit.params[0], fit.params[1]);
    if !(kj > 0.0 && bj >= 0.0) {
        return None;
    }
    let omega_n = kj.sqrt();
    Some(FreeFit {
        k_over_j: kj,
        b_over_j: bj,
        q_start: fit.params[2],
        qd_start: fit.params[3],
        q0: q0.unwrap_or_else(|| fit.params.get(4).copied().unwrap_or(0.0)),
        omega_n,
        zeta: bj / (2.0 * omega_n),
        rms: (fit.cost / n as f64).sqrt(),
        n,
        log,
        t0,
        t1: t[n - 1],
    })
}
