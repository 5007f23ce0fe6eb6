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
///
/// Besides the values it returns what says whether the log determines each term: the
/// coefficients' covariance, each term's variance inflation factor against the other terms (how
/// far their columns explain the torque it contributes over the log; 1 = independent) and the
/// term it correlates with most, and the excitation the log offers (acceleration above its
/// noise, covered angle, speeds, reversals).
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
    /// covariance of the coefficients (correlation-inflated; 0 for a column not fitted)
    pub cov: [[f64; 7]; 7],
    /// per term (inertia, friction, weight): the inflation factor of its contribution against
    /// the other terms (0 when not fitted), and the other term whose contribution correlates
    /// most with it, with that correlation
    pub gvif: [f64; 3],
    pub partner: [(usize, f64); 3],
    /// columns fitted (allowed and not negative)
    pub free: [bool; 7],
    /// columns left out because they came out negative
    pub negative: [bool; 7],
    /// RMS of the filtered q̈ over the used samples, and of its noise in the fit's band, rad/s²
    pub acc_rms: f64,
    pub acc_noise: f64,
    /// span of q over the used samples, rad; 10th, 50th and 90th percentile of |q̇| where the
    /// joint moves, rad/s; both directions of motion
    pub q_span: f64,
    pub speeds: [f64; 3],
    pub both_ways: bool,
    /// RMS and r² of the filtered fit
    pub rms: f64,
    pub r2: f64,
    pub n: usize,
    pub cutoff_hz: f64,
}

/// The terms of [`JointLsFit`] and their columns.
pub const JOINT_LS_TERMS: [(&str, &[usize]); 3] = [("inertia", &[0]), ("friction", &[1, 2, 3]), ("weight", &[4, 5])];

/// The noise of q̈ within the fit's band (0 … `cutoff`), rad/s²: white noise on a logged q̈
/// keeps the share 2·f_c/f_s of its variance; a q̈ derived from q (noise σ_q) has the noise
/// spectrum of a double differentiator, σ_q²·(2πf)⁴ per unit bandwidth, almost all of it above
/// the cut-off.
pub fn acc_noise_in_band(p: &Prepared, cutoff: f64) -> f64 {
    let fc = cutoff.min(0.5 * p.fs);
    match p.prep.qdd.source {
        "logged" => p.prep.qdd.noise_sd * (2.0 * fc / p.fs).sqrt(),
        "derived from the logged qd" => {
            // white noise σ_v on q̇, differentiated once: σ_v²·(2πf)² per unit bandwidth
            let sv = p.prep.qd.noise_sd.max(p.prep.qd.logged_noise_sd.unwrap_or(0.0));
            sv * std::f64::consts::TAU * (fc.powi(3) / (3.0 * 0.5 * p.fs)).sqrt()
        }
        _ => p.prep.q_noise_sd * std::f64::consts::TAU.powi(2) * (fc.powi(5) / (5.0 * 0.5 * p.fs)).sqrt(),
    }
}

pub fn joint_ls(logs: &[&Prepared], band: f64, cutoff: f64, keep: &dyn Fn(usize, usize) -> bool) -> Option<JointLsFit> {
    let mut cols: [Vec<f64>; 7] = Default::default();
    let mut y = Vec::new();
    let mut tmp = Vec::new();
    let mut fs_min = f64::INFINITY;
    let (mut noise2, mut n_noise) = (0.0, 0usize);
    let (mut q_lo, mut q_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut moving_speeds = Vec::new();
    let (mut pos, mut neg) = (false, false);
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
        let an = acc_noise_in_band(p, cutoff);
        noise2 += an * an * sel.len() as f64;
        n_noise += sel.len();
        for &i in &sel {
            q_lo = q_lo.min(p.q[i]);
            q_hi = q_hi.max(p.q[i]);
            // a direction counts where the joint clearly moves that way
            pos |= p.qd_f[i] > 0.03;
            neg |= p.qd_f[i] < -0.03;
            if p.qd_f[i].abs() > 0.03 {
                moving_speeds.push(p.qd_f[i].abs());
            }
        }
    }
    if y.len() < 50 {
        return None;
    }
    // Non-negative by the parameter table: J, a, b, c (indices 0..=3).
    let mut active = [true; 7];
    let mut negative = [false; 7];
    loop {
        let idx: Vec<usize> = (0..7).filter(|&k| active[k]).collect();
        let x: Vec<&[f64]> = idx.iter().map(|&k| cols[k].as_slice()).collect();
        let lf = robust::ols(&x, &y)?;
        if let Some(pos) = idx.iter().zip(&lf.beta).position(|(&k, b)| k <= 3 && *b < 0.0) {
            active[idx[pos]] = false;
            negative[idx[pos]] = true;
            continue;
        }
        let p = idx.len();
        let mut beta = [0.0; 7];
        let mut se = [0.0; 7];
        let n_eff = (y.len() as f64 * (2.0 * cutoff / fs_min).min(1.0)).max(8.0);
        let inflate = (y.len() as f64 / n_eff).sqrt();
        for (j, &k) in idx.iter().enumerate() {
            beta[k] = lf.beta[j];
            se[k] = lf.se[j] * inflate;
        }
        let mut cov = [[0.0; 7]; 7];
        for (ja, &ka) in idx.iter().enumerate() {
            for (jb, &kb) in idx.iter().enumerate() {
                cov[ka][kb] = lf.sigma * lf.sigma * lf.xtx_inv[ja * p + jb] * inflate * inflate;
            }
        }
        let m = y.len() as f64;
        let (gvif, partner) = term_collinearity(&cols, &active, &beta);
        let acc_mean = cols[0].iter().sum::<f64>() / m;
        let acc_rms = (cols[0].iter().map(|v| (v - acc_mean).powi(2)).sum::<f64>() / m).sqrt();
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
            cov,
            gvif,
            partner,
            free: active,
            negative,
            acc_rms,
            acc_noise: (noise2 / n_noise.max(1) as f64).sqrt(),
            q_span: (q_hi - q_lo).max(0.0),
            speeds: percentiles(&mut moving_speeds),
            both_ways: pos && neg,
            rms,
            r2,
            n: y.len(),
            cutoff_hz: cutoff,
        });
    }
}

/// 10th, 50th and 90th percentile (0s when empty).
fn percentiles(v: &mut [f64]) -> [f64; 3] {
    if v.is_empty() {
        return [0.0; 3];
    }
    v.sort_by(f64::total_cmp);
    let at = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
    [at(0.1), at(0.5), at(0.9)]
}

/// Per term of [`JOINT_LS_TERMS`]: how far the other terms explain the torque this term
/// contributes over the log. The term's fitted contribution `Σ β_k·x_k` (its columns' sum when
/// every β is 0) is regressed on the other terms' columns and the constant; the inflation factor
/// is `1/(1 − R²)`, as a single column's VIF (for J it is exactly that). Judging the contribution
/// rather than each column lets a and b of one friction curve, or sin and cos of one weight,
/// trade off among themselves without calling the term undetermined. Also the other term whose
/// contribution correlates most with this one's, and that correlation.
fn term_collinearity(cols: &[Vec<f64>; 7], active: &[bool; 7], beta: &[f64; 7]) -> ([f64; 3], [(usize, f64); 3]) {
    let m = cols[0].len();
    let contribution = |tc: &[usize]| -> Vec<f64> {
        let used: Vec<usize> = tc.iter().copied().filter(|&k| active[k]).collect();
        let all_zero = used.iter().all(|&k| beta[k] == 0.0);
        (0..m).map(|i| used.iter().map(|&k| if all_zero { 1.0 } else { beta[k] } * cols[k][i]).sum()).collect()
    };
    let contrib: Vec<Vec<f64>> = JOINT_LS_TERMS.iter().map(|(_, tc)| contribution(tc)).collect();
    let one = vec![1.0; m];
    let mut gvif = [0.0; 3];
    let mut partner = [(0usize, 0.0f64); 3];
    for (t, (_, tc)) in JOINT_LS_TERMS.iter().enumerate() {
        if !tc.iter().any(|&k| active[k]) {
            continue;
        }
        let y = &contrib[t];
        let mut x: Vec<&[f64]> =
            (0..6).filter(|&k| active[k] && !tc.contains(&k)).map(|k| cols[k].as_slice()).collect();
        x.push(&one);
        let mean = y.iter().sum::<f64>() / m.max(1) as f64;
        let sst: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
        let r2 = match robust::ols(&x, y) {
            Some(lf) if sst > 0.0 => {
                let ssr: f64 =
                    (0..m).map(|i| (y[i] - x.iter().zip(&lf.beta).map(|(c, b)| b * c[i]).sum::<f64>()).powi(2)).sum();
                (1.0 - ssr / sst).clamp(0.0, 1.0)
            }
            _ => 0.0,
        };
        gvif[t] = if r2 < 1.0 { 1.0 / (1.0 - r2) } else { f64::INFINITY };
        for (o, (_, oc)) in JOINT_LS_TERMS.iter().enumerate() {
            if o == t || !oc.iter().any(|&k| active[k]) {
                continue;
            }
            let r = super::report::rmse_r2(y, &contrib[o]).1.sqrt();
            let (mx, mo) = (mean, contrib[o].iter().sum::<f64>() / m.max(1) as f64);
            let sign: f64 = y.iter().zip(&contrib[o]).map(|(a, b)| (a - mx) * (b - mo)).sum::<f64>().signum();
            if r.is_finite() && r > partner[t].1.abs() {
                partner[t] = (o, sign * r);
            }
        }
    }
    (gvif, partner)
}
