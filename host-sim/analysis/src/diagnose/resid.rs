//! MATLAB-`resid`-style evidence: the residual's autocorrelation and its cross-correlation with
//! an input, normalised, with the 99 % band ±2.576/√N of a white residual that is independent of
//! the input. A residual that is not white shows structure the model misses; a cross-correlation
//! peak at lag k > 0 means the residual follows the input k samples later, which is what a delay
//! between actuation and measurement looks like.

use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct Correlation {
    /// lags in samples
    pub lags: Vec<i64>,
    pub values: Vec<f64>,
    /// ± this is the 99 % band for a white residual
    pub band99: f64,
    /// lags whose value lies outside the band
    pub outside: usize,
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt();
    (m, s)
}

/// Normalised cross-correlation `corr(r[i], x[i − lag])` for lag in `-max..=max` (`x = r` gives
/// the autocorrelation for `0..=max`).
pub fn xcorr(r: &[f64], x: &[f64], max_lag: usize, auto: bool) -> Correlation {
    let n = r.len().min(x.len());
    let (mr, sr) = mean_sd(&r[..n]);
    let (mx, sx) = mean_sd(&x[..n]);
    let den = (sr * sx * n as f64).max(1e-300);
    let max_lag = max_lag.min(n.saturating_sub(2));
    let lo: i64 = if auto { 0 } else { -(max_lag as i64) };
    let mut lags = Vec::new();
    let mut values = Vec::new();
    let rc: Vec<f64> = r[..n].iter().map(|v| v - mr).collect();
    let xc: Vec<f64> = x[..n].iter().map(|v| v - mx).collect();
    for lag in lo..=(max_lag as i64) {
        // pairs (r[i], x[i − lag]) over the overlap
        let l = lag.unsigned_abs() as usize;
        let (a, b) = if lag >= 0 { (&rc[l..], &xc[..n - l]) } else { (&rc[..n - l], &xc[l..]) };
        let s: f64 = a.iter().zip(b).map(|(p, q)| p * q).sum();
        lags.push(lag);
        values.push(s / den);
    }
    let band99 = 2.576 / (n.max(1) as f64).sqrt();
    let outside = values.iter().zip(&lags).filter(|(v, &l)| !(auto && l == 0) && v.abs() > band99).count();
    Correlation { lags, values, band99, outside }
}
