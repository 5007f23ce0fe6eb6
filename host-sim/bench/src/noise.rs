//! Sensor chain: white and AR(1) noise, encoder quantisation, zero-phase filtering and
//! derivatives of logged signals.

use serde::Serialize;

use crate::rngs::{normal, Rng64};

/// How one logged torque signal's noise is coloured.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TorqueNoise {
    /// Stationary standard deviation (N·m).
    pub sigma: f64,
    /// AR(1) coefficient; 0 is white.
    pub rho: f64,
}

/// White Gaussian noise of standard deviation sigma.
pub fn white(rng: &mut Rng64, n: usize, sigma: f64) -> Vec<f64> {
    (0..n).map(|_| sigma * normal(rng)).collect()
}

/// Stationary AR(1): e_k = ρ·e_{k−1} + σ·√(1−ρ²)·w_k, started from the stationary law so
/// the whole log has the requested σ, not only its tail.
pub fn ar1(rng: &mut Rng64, n: usize, sigma: f64, rho: f64) -> Vec<f64> {
    let g = sigma * (1.0 - rho * rho).max(0.0).sqrt();
    let mut e = sigma * normal(rng);
    (0..n)
        .map(|i| {
            if i > 0 {
                e = rho * e + g * normal(rng);
            }
            e
        })
        .collect()
}

pub fn coloured(rng: &mut Rng64, n: usize, tn: TorqueNoise) -> Vec<f64> {
    if tn.rho == 0.0 {
        white(rng, n, tn.sigma)
    } else {
        ar1(rng, n, tn.sigma, tn.rho)
    }
}

/// Rounds to the encoder's step (step 0 leaves x as it is).
pub fn quantise(x: f64, step: f64) -> f64 {
    if step > 0.0 {
        (x / step).round() * step
    } else {
        x
    }
}

/// Lag-one autocorrelation estimate (used by the tests and recorded for the AR noise).
pub fn lag1(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n.max(1.0);
    let num: f64 = x.iter().zip(x.iter().skip(1)).map(|(a, b)| (a - m) * (b - m)).sum();
    let den: f64 = x.iter().map(|a| (a - m) * (a - m)).sum();
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// A causal first-order low-pass at `fc` over (possibly uneven) samples, as a drive filters
/// its velocity estimate: late by `(1 − α)/α` samples at low frequency, `α = 1 − e^(−2π·fc·dt)`.
pub fn causal_lowpass(t: &[f64], x: &[f64], fc: f64) -> Vec<f64> {
    lowpass_pass(t.iter(), x.iter(), fc)
}

/// One first-order low-pass pass over (possibly uneven) samples.
fn lowpass_pass<'a>(t: impl Iterator<Item = &'a f64>, x: impl Iterator<Item = &'a f64>, fc: f64) -> Vec<f64> {
    let wc = std::f64::consts::TAU * fc;
    let mut y: Option<f64> = None;
    let mut t_prev: Option<f64> = None;
    t.zip(x)
        .map(|(&ti, &xi)| {
            let yi = match (y, t_prev) {
                (Some(yp), Some(tp)) => {
                    let a = 1.0 - (-wc * (ti - tp).abs()).exp();
                    yp + a * (xi - yp)
                }
                _ => xi,
            };
            y = Some(yi);
            t_prev = Some(ti);
            yi
        })
        .collect()
}

/// Zero-phase low-pass: a first-order pass forward and one backward, twice (4th order
/// magnitude, no lag), as an offline logger's post-processing would apply.
pub fn zero_phase(t: &[f64], x: &[f64], fc: f64) -> Vec<f64> {
    let mut y = x.to_vec();
    for _ in 0..2 {
        let f = lowpass_pass(t.iter(), y.iter(), fc);
        let mut b = lowpass_pass(t.iter().rev(), f.iter().rev(), fc);
        b.reverse();
        y = b;
    }
    y
}

/// Central differences on uneven samples (one-sided at the ends).
pub fn derivative(t: &[f64], x: &[f64]) -> Vec<f64> {
    let n = x.len().min(t.len());
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(1);
            let hi = (i + 1).min(n.saturating_sub(1));
            match (t.get(lo), t.get(hi), x.get(lo), x.get(hi)) {
                (Some(t0), Some(t1), Some(x0), Some(x1)) if t1 > t0 => (x1 - x0) / (t1 - t0),
                _ => 0.0,
            }
        })
        .collect()
}
