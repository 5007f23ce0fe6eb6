//! Friction from constant-velocity plateaus (trunk paper §3.2).
//!
//! On a plateau the joint does not accelerate, so the disturbance is
//! `d = friction(q̇) + weight(q) + C_0`. A plateau in one direction is paired with the plateau
//! of the closest speed in the other direction that covers the same angles; inside the common
//! angle range the samples are binned by angle and, per bin, `(d₊ − d₋)/2` is the friction at
//! the mean speed: the weight and the offset are the same at the same angle and cancel, the
//! friction is odd in q̇ and doubles. The points are fitted with `a·v² + b·v + c` by the robust
//! bisquare regression, with 95 % confidence intervals.
//!
//! When the inertia is already known (second pass), `J·q̈` is taken off `d` first, so plateaus
//! whose velocity still drifts a little do not bias the friction.

use super::robust::{self, LinFit};
use super::segments::{Prepared, SegKind, Segment};

/// One friction measurement: speed (> 0) and friction torque.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FrictionPoint {
    pub v: f64,
    pub f: f64,
    /// samples behind it (both directions)
    pub n: usize,
    /// log index and time of the positive plateau's start (for hold-out splits and plots)
    pub log: usize,
    pub t: f64,
}

/// The fitted curve `F(v) = a·v² + b·v + c` for v > 0.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FrictionFit {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub se: [f64; 3],
    pub ci95: [(f64, f64); 3],
    /// robust residual scale, N·m
    pub sigma: f64,
    pub points: Vec<FrictionPoint>,
    /// bisquare weight of each point (0 = rejected as an outlier)
    pub weights: Vec<f64>,
    /// per coefficient (a, b, c): fitted, or 0 because left out; and left out because it came
    /// out negative (rather than because the speeds cannot tell it apart or it was not asked for)
    pub free: [bool; 3],
    pub negative: [bool; 3],
    /// covariance of (a, b, c) (0 for a coefficient not fitted)
    pub cov: [[f64; 3]; 3],
}

impl FrictionFit {
    pub fn eval(&self, v: f64) -> f64 {
        self.a * v * v + self.b * v + self.c
    }

    /// The curve's value at speed `v` and the half-width of its CI with quantile `tq`.
    pub fn curve_ci(&self, v: f64, tq: f64) -> (f64, f64) {
        let g = [v * v, v, 1.0];
        let var: f64 =
            (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| g[i] * g[j] * self.cov[i][j]).sum();
        (self.eval(v), tq * var.max(0.0).sqrt())
    }
}

struct Plateau {
    log: usize,
    start: usize,
    end: usize,
    dir: f64,
    speed: f64,
    q_lo: f64,
    q_hi: f64,
}

/// Friction points from the plateaus of all logs. `accel` gives, per log, the q̈ to take off
/// with the inertia `j`; without it (first pass) only the samples of a plateau whose filtered
/// |q̈| is below `strict.0 + strict.1·|q̇|` are used, so the unknown `J·q̈` stays negligible.
pub fn points(
    logs: &[(&Prepared, &[Segment])],
    accel: Option<(&[Vec<f64>], f64)>,
    strict: (f64, f64),
) -> Vec<FrictionPoint> {
    let mut plateaus = Vec::new();
    for (li, (p, segs)) in logs.iter().enumerate() {
        if p.d.is_none() {
            continue;
        }
        for s in segs.iter().filter(|s| s.kind == SegKind::Plateau && s.len() >= 2) {
            let v = &p.qd_f[s.start..s.end];
            let mean_v = v.iter().sum::<f64>() / v.len() as f64;
            let q = &p.q[s.start..s.end];
            let (q_lo, q_hi) = q.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            plateaus.push(Plateau {
                log: li,
                start: s.start,
                end: s.end,
                dir: mean_v.signum(),
                speed: mean_v.abs(),
                q_lo,
                q_hi,
            });
        }
    }
    let mut out = Vec::new();
    for pos in plateaus.iter().filter(|p| p.dir > 0.0) {
        // Closest-speed negative plateau (within 10 %) sharing at least a third of the angles.
        let mut best: Option<(&Plateau, f64)> = None;
        for neg in plateaus.iter().filter(|p| p.dir < 0.0) {
            let rel = (neg.speed - pos.speed).abs() / pos.speed.max(1e-9);
            let (lo, hi) = (pos.q_lo.max(neg.q_lo), pos.q_hi.min(neg.q_hi));
            let shorter = (pos.q_hi - pos.q_lo).min(neg.q_hi - neg.q_lo);
            if rel > 0.10 || hi - lo < (shorter / 10.0).max(0.02) {
                continue;
            }
            if best.as_ref().is_none_or(|(_, r)| rel < *r) {
                best = Some((neg, rel));
            }
        }
        let Some((neg, _)) = best else { continue };
        let (lo, hi) = (pos.q_lo.max(neg.q_lo), pos.q_hi.min(neg.q_hi));
        // Bins of about 0.02 rad, 1..=10 per pair.
        let nb = (((hi - lo) / 0.02).floor() as usize).clamp(1, 10);
        let w = (hi - lo) / nb as f64;
        let mut acc = vec![[0.0f64; 6]; nb]; // sum d+, n+, sum |v+|, sum d−, n−, sum |v−|
        for (pl, off) in [(pos, 0usize), (neg, 3usize)] {
            let (p, _) = logs[pl.log];
            let Some(d) = p.d.as_ref() else { continue };
            let acc_col = accel.and_then(|(a, j)| a.get(pl.log).map(|c| (c, j)));
            for i in pl.start..pl.end {
                let q = p.q[i];
                if q < lo || q > hi {
                    continue;
                }
                if acc_col.is_none() && p.qdd_f[i].abs() > strict.0 + strict.1 * p.qd_f[i].abs() {
                    continue;
                }
                let b = (((q - lo) / w) as usize).min(nb - 1);
                let mut di = d[i];
                if let Some((c, j)) = acc_col {
                    di -= j * c[i];
                }
                acc[b][off] += di;
                acc[b][off + 1] += 1.0;
                acc[b][off + 2] += p.qd_f[i].abs();
            }
        }
        let (p0, _) = logs[pos.log];
        for a in acc {
            if a[1] < 3.0 || a[4] < 3.0 {
                continue;
            }
            let f = 0.5 * (a[0] / a[1] - a[3] / a[4]);
            let v = 0.5 * (a[2] / a[1] + a[5] / a[4]);
            out.push(FrictionPoint { v, f, n: (a[1] + a[4]) as usize, log: pos.log, t: p0.t[pos.start] });
        }
    }
    out
}

/// Robust fit of `a·v² + b·v + c` to the points; `None` with fewer than 4 points or a
/// degenerate speed spread. The joint's parameter table requires a, b, c ≥ 0 (friction never
/// drives the joint), so a coefficient that comes out negative is fixed at 0 and the others
/// are refitted (its CI is then reported as [0, 0]).
pub fn fit(points: &[FrictionPoint]) -> Option<FrictionFit> {
    fit_with(points, [true; 3])
}

/// The number of distinct speeds among the points: speeds closer than 10 % are one (the
/// bins of one plateau pair share a speed). a·v² + b·v + c needs three to be told apart, b·v + c two.
pub fn distinct_speeds(points: &[FrictionPoint]) -> usize {
    let mut v: Vec<f64> = points.iter().map(|p| p.v).collect();
    v.sort_by(f64::total_cmp);
    let mut n = 0;
    let mut last = f64::NEG_INFINITY;
    for x in v {
        if x > last * 1.1 {
            n += 1;
            last = x;
        }
    }
    n
}

/// [`fit`] with only the coefficients `allowed` (a, b, c) free; the others are 0. A coefficient
/// the points' speeds cannot tell apart (fewer than three distinct speeds for a, two for b) is
/// left out too.
pub fn fit_with(points: &[FrictionPoint], allowed: [bool; 3]) -> Option<FrictionFit> {
    if points.len() < 4 {
        return None;
    }
    let k = distinct_speeds(points);
    let allowed = [allowed[0] && k >= 3, allowed[1] && k >= 2, allowed[2]];
    let v: Vec<f64> = points.iter().map(|p| p.v).collect();
    let v2: Vec<f64> = v.iter().map(|v| v * v).collect();
    let one = vec![1.0; v.len()];
    let y: Vec<f64> = points.iter().map(|p| p.f).collect();
    let cols: [&[f64]; 3] = [&v2, &v, &one];
    let mut active = allowed;
    let mut negative = [false; 3];
    loop {
        let idx: Vec<usize> = (0..3).filter(|&k| active[k]).collect();
        if idx.is_empty() {
            // Every coefficient came out negative (or none was allowed): a fit of nothing, so
            // the caller can say why rather than find no fit.
            let sigma = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
            return Some(FrictionFit {
                a: 0.0,
                b: 0.0,
                c: 0.0,
                se: [0.0; 3],
                ci95: [(0.0, 0.0); 3],
                sigma,
                points: points.to_vec(),
                weights: vec![1.0; points.len()],
                free: active,
                negative,
                cov: [[0.0; 3]; 3],
            });
        }
        let x: Vec<&[f64]> = idx.iter().map(|&k| cols[k]).collect();
        let LinFit { beta, se, ci95, sigma, weights, xtx_inv, .. } = robust::bisquare(&x, &y)?;
        if let Some(pos) = beta.iter().position(|b| *b < 0.0) {
            active[idx[pos]] = false;
            negative[idx[pos]] = true;
            continue;
        }
        let mut full = [0.0; 3];
        let mut fse = [0.0; 3];
        let mut fci = [(0.0, 0.0); 3];
        let mut cov = [[0.0; 3]; 3];
        let p = idx.len();
        for (j, &k) in idx.iter().enumerate() {
            full[k] = beta[j];
            fse[k] = se[j];
            fci[k] = ci95[j];
            for (i, &l) in idx.iter().enumerate() {
                cov[k][l] = sigma * sigma * xtx_inv[j * p + i];
            }
        }
        return Some(FrictionFit {
            a: full[0],
            b: full[1],
            c: full[2],
            se: fse,
            ci95: fci,
            sigma,
            points: points.to_vec(),
            weights,
            free: active,
            negative,
            cov,
        });
    }
}
