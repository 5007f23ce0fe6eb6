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
//! segments are left out too; plateaus stay (they carry q̈ ≈ 0 and pin ΔC_0).

use super::filter;
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
pub fn data(
    logs: &[(&Prepared, &[Segment])],
    model: &dyn Fn(f64, f64) -> f64,
    cutoff: f64,
    v_min: f64,
) -> InertiaData {
    let mut out = InertiaData { acc: Vec::new(), y: Vec::new(), mask: Vec::new() };
    let mut tmp = Vec::new();
    for (p, segs) in logs {
        let n = p.len();
        let acc = match &p.qdd_logged {
            Some(a) => filter::filtfilt(a, cutoff, p.fs),
            None => {
                filter::filtfilt_into(&p.qd, cutoff, p.fs, &mut tmp);
                filter::derivative(&p.t, &tmp)
            }
        };
        let (y, mask) = match &p.d {
            Some(d) => {
                tmp.clear();
                tmp.extend((0..n).map(|i| d[i] - model(p.q[i], p.qd_f[i])));
                let y = filter::filtfilt(&tmp, cutoff, p.fs);
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
