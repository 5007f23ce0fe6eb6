//! Inertia and offset from moving samples (trunk paper §3.4, eq. 5).
//!
//! With friction and weight known, `y = d − friction(q̇) − weight(q) − C_0,static = J·q̈ + ΔC_0`
//! is linear in (J, ΔC_0) and solved by least squares. q̈ is the logged acceleration when the
//! log has one, else the derivative of the velocity. The paper low-passed at 2 Hz before
//! differentiating; here *both sides* of the equation go through the same zero-phase
//! Butterworth low-pass (default 5 Hz): the filter is linear, so the filtered equation holds
//! with the same J and C_0, while a filter on q̈ alone would attenuate q̈ against the torque
//! and bias J low, and a causal filter would shift it in time. The cut-off then only sets how
//! much sensor noise is kept, which must stay small against the excitation: noise on the
//! regressor q̈ biases J low by var(noise)/var(q̈).
//!
//! Samples near zero velocity are left out (|q̇| < `v_min`, widened by half a filter period):
//! there the smoothed Coulomb sign is least certain and its error would leak into J. Static
//! segments are left out too; plateaus stay (they carry q̈ ≈ 0 and pin ΔC_0). With
//! `--window START:END:motion` only the given stretches are used.

use super::robust::{self, t_quantile_975};
use super::segments::{Prepared, SegKind, Segment};

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct InertiaFit {
    pub j: f64,
    /// offset found on top of the static curve's constant, N·m
    pub dc0: f64,
    pub se: [f64; 2],
    pub ci95: [(f64, f64); 2],
    /// RMS of the filtered residual on the used samples, N·m
    pub rms: f64,
    pub n: usize,
    pub cutoff_hz: f64,
}

/// Per log: the filtered acceleration used (full length) and the mask of used samples.
pub struct InertiaData {
    pub acc: Vec<Vec<f64>>,
    pub y: Vec<Vec<f64>>,
    pub mask: Vec<Vec<bool>>,
}

/// The filtered regression data of every log. `model(q, qd)` is the known part (friction,
/// weight, static offset).
pub fn data(logs: &[(&Prepared, &[Segment])], model: &dyn Fn(f64, f64) -> f64, cutoff: f64, v_min: f64) -> InertiaData {
    let mut out = InertiaData { acc: Vec::new(), y: Vec::new(), mask: Vec::new() };
    let mut tmp = Vec::new();
    for (p, segs) in logs {
        let n = p.len();
        let acc = p.lowpass(&p.qdd, cutoff);
        let (y, mask) = match &p.d {
            Some(d) => {
                tmp.clear();
                tmp.extend((0..n).map(|i| d[i] - model(p.q[i], p.qd_f[i])));
                let y = p.lowpass(&tmp, cutoff);
                // Mask: moving, away from low-speed samples by half a filter period, not static.
                let h = ((0.5 * p.fs / cutoff).ceil() as usize).max(1);
                let slow: Vec<u32> = p.qd_f.iter().map(|v| u32::from(v.abs() < v_min)).collect();
                let mut pre = vec![0u32; n + 1];
                for i in 0..n {
                    pre[i + 1] = pre[i] + slow[i];
                }
                let mut mask: Vec<bool> = (0..n).map(|i| pre[(i + h + 1).min(n)] == pre[i.saturating_sub(h)]).collect();
                for s in segs.iter().filter(|s| s.kind == SegKind::Static) {
                    for m in &mut mask[s.start.min(n)..s.end.min(n)] {
                        *m = false;
                    }
                }
                // `--window …:motion` given: only those stretches are motion.
                let motion: Vec<&Segment> = segs.iter().filter(|s| s.kind == SegKind::Motion).collect();
                if !motion.is_empty() {
                    let mut inside = vec![false; n];
                    for s in motion {
                        for x in &mut inside[s.start.min(n)..s.end.min(n)] {
                            *x = true;
                        }
                    }
                    for (m, i) in mask.iter_mut().zip(inside) {
                        *m &= i;
                    }
                }
                (y, mask)
            }
            None => (vec![0.0; n], vec![false; n]),
        };
        out.acc.push(acc);
        out.y.push(y);
        out.mask.push(mask);
    }
    out
}

/// Least squares of y = J·q̈ + ΔC_0 over the masked samples; `keep(log, i)` can drop samples
/// (hold-out). `None` with too few samples or no q̈ excitation.
pub fn fit(dat: &InertiaData, fs: f64, cutoff: f64, keep: &dyn Fn(usize, usize) -> bool) -> Option<InertiaFit> {
    let mut a = Vec::new();
    let mut y = Vec::new();
    for (li, ((acc, yy), mask)) in dat.acc.iter().zip(&dat.y).zip(&dat.mask).enumerate() {
        for i in 0..acc.len() {
            if mask[i] && keep(li, i) {
                a.push(acc[i]);
                y.push(yy[i]);
            }
        }
    }
    if a.len() < 50 {
        return None;
    }
    let one = vec![1.0; a.len()];
    let lf = robust::ols(&[&a, &one], &y)?;
    // Filtered samples are correlated: about 2·f_c/f_s of them are independent, so the
    // standard errors are scaled up accordingly.
    let n_eff = (a.len() as f64 * (2.0 * cutoff / fs).min(1.0)).max(3.0);
    let inflate = (a.len() as f64 / n_eff).sqrt();
    let tq = t_quantile_975(n_eff - 2.0) / t_quantile_975(a.len() as f64 - 2.0);
    let se = [lf.se[0] * inflate, lf.se[1] * inflate];
    let ci = |k: usize| {
        let h = (lf.ci95[k].1 - lf.ci95[k].0) * 0.5 * inflate * tq;
        (lf.beta[k] - h, lf.beta[k] + h)
    };
    Some(InertiaFit {
        j: lf.beta[0],
        dc0: lf.beta[1],
        se,
        ci95: [ci(0), ci(1)],
        rms: lf.sigma,
        n: a.len(),
        cutoff_hz: cutoff,
    })
}

/// All rigid-joint terms in one least-squares fit on every sample (no plateaus or poses
/// needed): `d = J·q̈ + a·q̇|q̇| + b·q̇ + c·sgn(q̇) + α·sin q + β·cos q + C_0`, every column and
/// `d` through the same zero-phase low-pass. This is the regression the DFKI pendulum authors
/// used on their swing-up run (with s = 1: the weight of a pendulum is `m·g·c·sin(q + φ)`,
/// `C_w0 = √(α² + β²)`, `φ = atan2(β, α)`). Coefficients that the joint's parameter table
/// requires ≥ 0 (a, b, c, J) and that come out negative are dropped and the rest refitted.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct JointLsFit {
    pub j: f64,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub alpha: f64,
    pub beta: f64,
    pub c0: f64,
    /// standard errors (correlation-inflated) in the order j, a, b, c, α, β, C_0
    pub se: [f64; 7],
    /// RMS and r² of the filtered fit
    pub rms: f64,
    pub r2: f64,
    pub n: usize,
    pub cutoff_hz: f64,
}

pub fn joint_ls(logs: &[&Prepared], band: f64, cutoff: f64, keep: &dyn Fn(usize, usize) -> bool) -> Option<JointLsFit> {
    let mut cols: [Vec<f64>; 7] = Default::default();
    let mut y = Vec::new();
    let mut tmp = Vec::new();
    let mut fs_min = f64::INFINITY;
    for (li, p) in logs.iter().enumerate() {
        let Some(d) = &p.d else { continue };
        fs_min = fs_min.min(p.fs);
        let n = p.len();
        // Leave out the first and last half filter period (edge transients).
        let h = ((0.5 * p.fs / cutoff).ceil() as usize).min(n / 4);
        let sel: Vec<usize> = (h..n.saturating_sub(h)).filter(|&i| keep(li, i)).collect();
        let acc = p.lowpass(&p.qdd, cutoff);
        let raw: [Box<dyn Fn(usize) -> f64>; 6] = [
            Box::new(|i| p.qd[i] * p.qd[i].abs()),
            Box::new(|i| p.qd[i]),
            Box::new(|i| super::sign_band(p.qd_f[i], band)),
            Box::new(|i| p.q[i].sin()),
            Box::new(|i| p.q[i].cos()),
            Box::new(|_| 1.0),
        ];
        cols[0].extend(sel.iter().map(|&i| acc[i]));
        for (k, f) in raw.iter().enumerate() {
            tmp.clear();
            tmp.extend((0..n).map(f));
            let buf = p.lowpass(&tmp, cutoff);
            cols[k + 1].extend(sel.iter().map(|&i| buf[i]));
        }
        let buf = p.lowpass(d, cutoff);
        y.extend(sel.iter().map(|&i| buf[i]));
    }
    if y.len() < 50 {
        return None;
    }
    // Non-negative by the parameter table: J, a, b, c (indices 0..=3).
    let mut active = [true; 7];
    loop {
        let idx: Vec<usize> = (0..7).filter(|&k| active[k]).collect();
        let x: Vec<&[f64]> = idx.iter().map(|&k| cols[k].as_slice()).collect();
        let lf = robust::ols(&x, &y)?;
        if let Some(pos) = idx.iter().zip(&lf.beta).position(|(&k, b)| k <= 3 && *b < 0.0) {
            active[idx[pos]] = false;
            continue;
        }
        let mut beta = [0.0; 7];
        let mut se = [0.0; 7];
        let n_eff = (y.len() as f64 * (2.0 * cutoff / fs_min).min(1.0)).max(8.0);
        let inflate = (y.len() as f64 / n_eff).sqrt();
        for (j, &k) in idx.iter().enumerate() {
            beta[k] = lf.beta[j];
            se[k] = lf.se[j] * inflate;
        }
        let pred: Vec<f64> = (0..y.len()).map(|i| (0..7).map(|k| beta[k] * cols[k][i]).sum()).collect();
        let (rms, r2) = super::report::rmse_r2(&y, &pred);
        return Some(JointLsFit {
            j: beta[0],
            a: beta[1],
            b: beta[2],
            c: beta[3],
            alpha: beta[4],
            beta: beta[5],
            c0: beta[6],
            se,
            rms,
            r2,
            n: y.len(),
            cutoff_hz: cutoff,
        });
    }
}
