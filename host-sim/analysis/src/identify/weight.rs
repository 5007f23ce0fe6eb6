//! The weight torque from static poses (trunk paper §3.3): `C_w0·sin(s·q + φ)` (+ `C_0`).
//!
//! A static pose is the settled end of a still stretch; its torque is the mean of
//! `d − friction(q̇_f)` over the stretch: a joint held by a position loop against a smoothed
//! Coulomb friction creeps slowly while it settles, and the friction of that creep (up to c at
//! the edge of the sign band) would otherwise be read as weight. The fit is nonlinear least
//! squares (Levenberg–Marquardt) from a grid of starts over s and φ; when s·q covers too small
//! an arc for s to be determined (the amplitude and s run away together), s is fixed at 1 and
//! the rest is solved linearly. The sum weight + offset is what the data determine; how it is
//! split between C_w0·sin and C_0 is only as good as the covered arc.

use super::nls;
use super::robust;
use super::segments::{Prepared, SegKind, Segment};

/// One static pose.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pose {
    pub log: usize,
    /// start time of the averaged part, s
    pub t: f64,
    pub q: f64,
    /// mean torque with the friction of the residual creep removed, N·m
    pub d: f64,
    /// standard deviation of the per-sample torque, N·m
    pub sd: f64,
    pub n: usize,
    /// mean of each `q_<name>` column, in the log's order
    pub others: Vec<f64>,
}

/// Poses of all torque-mode logs; `friction(qd)` is the model friction at a velocity.
pub fn poses(logs: &[(&Prepared, &[Segment])], friction: &dyn Fn(f64) -> f64) -> Vec<Pose> {
    let mut out = Vec::new();
    for (li, (p, segs)) in logs.iter().enumerate() {
        let Some(d) = p.d.as_ref() else { continue };
        for s in segs.iter().filter(|s| s.kind == SegKind::Static && s.len() >= 2) {
            let n = s.len() as f64;
            let mut sum = 0.0;
            let mut sum2 = 0.0;
            let mut sq = 0.0;
            for i in s.start..s.end {
                let x = d[i] - friction(p.qd_f[i]);
                sum += x;
                sum2 += x * x;
                sq += p.q[i];
            }
            let mean = sum / n;
            let others = p.others.iter().map(|(_, c)| c[s.start..s.end].iter().sum::<f64>() / n).collect();
            out.push(Pose {
                log: li,
                t: p.t[s.start],
                q: sq / n,
                d: mean,
                sd: (sum2 / n - mean * mean).max(0.0).sqrt(),
                n: s.len(),
                others,
            });
        }
    }
    out
}

/// The fitted static curve.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WeightFit {
    pub amplitude: f64,
    pub s: f64,
    pub phi: f64,
    /// the constant of the static curve (C_0 as the poses see it); 0 when not fitted
    pub c0: f64,
    pub fitted_offset: bool,
    /// standard errors of amplitude, s, φ (and c0)
    pub se: Vec<f64>,
    /// RMS of the pose residuals, N·m
    pub rms: f64,
    /// true when s was fixed at 1 because the arc was too short to determine it
    pub s_fixed: bool,
}

impl WeightFit {
    pub fn weight(&self, q: f64) -> f64 {
        self.amplitude * (self.s * q + self.phi).sin()
    }
    pub fn curve(&self, q: f64) -> f64 {
        self.weight(q) + self.c0
    }
}

fn normalise(mut a: f64, mut s: f64, mut phi: f64) -> (f64, f64, f64) {
    // sin(−s·q + φ) = sin(s·q + π − φ): keep s positive, as the papers write it.
    if s < 0.0 {
        s = -s;
        phi = std::f64::consts::PI - phi;
    }
    if a < 0.0 {
        a = -a;
        phi += std::f64::consts::PI;
    }
    phi = (phi + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    (a, s, phi)
}

/// Fits the poses; `with_offset` adds the constant C_0. `None` with too few poses.
pub fn fit(poses: &[Pose], with_offset: bool) -> Option<WeightFit> {
    let np = if with_offset { 4 } else { 3 };
    if poses.len() < np + 1 {
        return None;
    }
    let q: Vec<f64> = poses.iter().map(|p| p.q).collect();
    let y: Vec<f64> = poses.iter().map(|p| p.d).collect();
    let (ymin, ymax) = y.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let amp0 = (0.5 * (ymax - ymin)).max(1e-3);
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let mut starts = Vec::new();
    for s in [0.5, 1.0, 2.0] {
        for k in 0..6 {
            let phi = -std::f64::consts::PI + k as f64 * std::f64::consts::PI / 3.0;
            let mut p = vec![amp0, s, phi];
            if with_offset {
                p.push(mean);
            }
            starts.push(p);
        }
    }
    let f = |p: &[f64], r: &mut [f64]| {
        let c = if with_offset { p[3] } else { 0.0 };
        for ((ri, q), y) in r.iter_mut().zip(&q).zip(&y) {
            *ri = p[0] * (p[1] * q + p[2]).sin() + c - y;
        }
    };
    let fit = nls::multi_start(f, &starts, q.len(), 200)?;
    let (a, s, phi) = normalise(fit.params[0], fit.params[1], fit.params[2]);
    let scale = ymax.abs().max(ymin.abs()) + 1.0;
    let plausible = a.is_finite() && a <= 20.0 * scale && s.abs() <= 20.0 && s.abs() >= 0.05;
    if plausible {
        let rms = (fit.cost / q.len() as f64).sqrt();
        return Some(WeightFit {
            amplitude: a,
            s,
            phi,
            c0: if with_offset { fit.params[3] } else { 0.0 },
            fitted_offset: with_offset,
            se: fit.se,
            rms,
            s_fixed: false,
        });
    }
    // s undetermined: A·sin(q + φ) = α·sin q + β·cos q, linear with the offset.
    let sn: Vec<f64> = q.iter().map(|q| q.sin()).collect();
    let cs: Vec<f64> = q.iter().map(|q| q.cos()).collect();
    let one = vec![1.0; q.len()];
    let mut cols: Vec<&[f64]> = vec![&sn, &cs];
    if with_offset {
        cols.push(&one);
    }
    let lf = robust::ols(&cols, &y)?;
    let (alpha, beta) = (lf.beta[0], lf.beta[1]);
    let (a, s, phi) = normalise(alpha.hypot(beta), 1.0, beta.atan2(alpha));
    let c0 = if with_offset { lf.beta[2] } else { 0.0 };
    let rms =
        (q.iter().zip(&y).map(|(q, y)| (a * (q + phi).sin() + c0 - y).powi(2)).sum::<f64>() / q.len() as f64).sqrt();
    Some(WeightFit { amplitude: a, s, phi, c0, fitted_offset: with_offset, se: lf.se, rms, s_fixed: true })
}
