//! What a sampled signal's spectrum says about it: the level of its white noise and how large
//! its higher derivatives are, the two numbers a derivative estimator's window trades off.
//!
//! The spectrum is Welch's (Hann windows, half overlap) of the signal's first difference over
//! `dt` (a rough derivative, so the large slow part of a position does not leak into the high
//! frequencies through the window). White noise of standard deviation σ on the signal puts
//! `2·dt·σ²·(2·sin(π·f·dt)/dt)²` into that spectrum, highest near Nyquist, where smooth motion
//! has none: σ² is read from the top quarter of the band (median, so a few tones do not count).
//! The motion is what stands clearly above that noise, from the lowest frequencies up to the
//! first octave that is all noise; the RMS of the k-th derivative of the signal is
//! `√(Σ (2πf)^(2k−2)·P_motion(f)·df)` over those bins.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

/// The noise level and the motion's derivative sizes of one signal.
#[derive(Clone, Debug, PartialEq)]
pub struct SignalSpectrum {
    /// white noise on the signal (standard deviation, the signal's unit)
    pub noise_sd: f64,
    /// RMS of the signal's k-th derivative, k = 1..=6 (index k − 1), from the motion bins
    pub deriv_rms: [f64; 6],
    /// highest frequency where the motion stands above the noise, Hz
    pub bandwidth_hz: f64,
}

/// Fewer samples than this: no spectrum (the caller uses its fallbacks).
pub const MIN_SAMPLES: usize = 64;

/// The spectrum of `x` sampled every `dt` seconds (nearly uniformly), or `None` for fewer
/// than [`MIN_SAMPLES`] samples.
pub fn analyse(x: &[f64], dt: f64) -> Option<SignalSpectrum> {
    if x.len() < MIN_SAMPLES || !(dt > 0.0) {
        return None;
    }
    let d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
    let (freqs, psd) = welch(&d, dt);
    let nyq = 0.5 / dt;
    // The rough derivative's noise shape at frequency f, per unit σ².
    let shape = |f: f64| {
        let s = 2.0 * (std::f64::consts::PI * f * dt).sin() / dt;
        2.0 * dt * s * s
    };
    let mut ratios: Vec<f64> =
        freqs.iter().zip(&psd).filter(|(f, _)| **f >= 0.75 * nyq).map(|(f, p)| p / shape(*f).max(1e-300)).collect();
    if ratios.is_empty() {
        return None;
    }
    let mid = ratios.len() / 2;
    let (_, m, _) = ratios.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    let sigma2 = m.max(0.0);
    let df = freqs.get(1).copied().unwrap_or(nyq);
    // Motion: bins clearly above the noise (3×), from the lowest frequency up to where a whole
    // octave stays below it. Energy above that is not motion but the tones an encoder's
    // quantisation makes (a joint moving at v crosses steps of size Δ at v/Δ Hz).
    let above: Vec<bool> = freqs.iter().zip(&psd).map(|(&f, &p)| f > 0.0 && p > 3.0 * sigma2 * shape(f)).collect();
    let mut end = freqs.len();
    for (k, &f) in freqs.iter().enumerate() {
        if f <= 0.0 || above[k] {
            continue;
        }
        let octave_clear = freqs.iter().zip(&above).skip(k).take_while(|(g, _)| **g <= 2.0 * f).all(|(_, a)| !*a);
        if octave_clear && 2.0 * f <= nyq {
            end = k;
            break;
        }
    }
    let end = end.min(coloured_noise_edge(&freqs, &psd, nyq));
    let mut sums = [0.0f64; 6];
    let mut bandwidth = 0.0f64;
    for k in 0..end {
        let (f, p) = (freqs[k], psd[k]);
        if !above[k] {
            continue;
        }
        let noise = sigma2 * shape(f);
        // The first difference attenuates by sinc(f·dt): undo it for the derivative's spectrum.
        let sinc = {
            let a = std::f64::consts::PI * f * dt;
            if a > 1e-9 {
                a.sin() / a
            } else {
                1.0
            }
        };
        let pm = (p - noise) / (sinc * sinc).max(1e-6);
        let w2 = (std::f64::consts::TAU * f).powi(2);
        let mut g = 1.0;
        for s in sums.iter_mut() {
            *s += g * pm * df;
            g *= w2;
        }
        bandwidth = bandwidth.max(f);
    }
    let deriv_rms = sums.map(f64::sqrt);
    Some(SignalSpectrum { noise_sd: sigma2.sqrt(), deriv_rms, bandwidth_hz: bandwidth })
}

/// Where a noise that is not white begins, as a bin index (`freqs.len()` when there is none).
///
/// The noise model above is white noise on the signal, whose rough derivative's spectrum peaks
/// at Nyquist. A logged velocity filtered inside the drive, or samples on a jittering clock,
/// have a noise that rises from a few hertz and flattens (or falls) towards Nyquist: measured
/// against the white shape it stands "above the noise" up to hundreds of hertz, and a window
/// fitted to that "motion" is the narrowest, with an error several times the one estimated
/// (the Panda's joint 1: q̈ ≈ 4 rad/s² of error against a 1.7 rad/s² motion). A joint's motion
/// falls with frequency. So when the spectrum, averaged over octaves, has a valley in the lower
/// quarter of the band and then rises more than tenfold, with its top quarter within a factor of
/// three of that rise's peak (noise that does not decay, unlike a resonance), the motion ends at
/// the valley.
fn coloured_noise_edge(freqs: &[f64], psd: &[f64], nyq: f64) -> usize {
    let df = freqs.get(1).copied().unwrap_or(nyq);
    // octave bands from the second bin up: (lower edge, upper edge, mean density)
    let mut bands: Vec<(f64, f64, f64)> = Vec::new();
    let mut lo = df;
    while lo < nyq {
        let hi = (2.0 * lo).min(nyq);
        let (sum, n) = freqs
            .iter()
            .zip(psd)
            .filter(|(f, _)| **f >= lo && **f < hi)
            .fold((0.0, 0usize), |(s, n), (_, p)| (s + p, n + 1));
        if n > 0 {
            bands.push((lo, hi, sum / n as f64));
        }
        lo = hi;
    }
    let top: Vec<f64> = freqs.iter().zip(psd).filter(|(f, _)| **f >= 0.75 * nyq).map(|(_, p)| *p).collect();
    if bands.len() < 4 || top.is_empty() {
        return freqs.len();
    }
    let top_mean = top.iter().sum::<f64>() / top.len() as f64;
    let Some((k, valley)) = bands
        .iter()
        .enumerate()
        .filter(|(_, b)| b.1 <= 0.25 * nyq)
        .min_by(|a, b| a.1 .2.total_cmp(&b.1 .2))
        .map(|(k, b)| (k, *b))
    else {
        return freqs.len();
    };
    let peak = bands[k + 1..].iter().map(|b| b.2).fold(0.0f64, f64::max);
    if valley.2 > 0.0 && peak > 10.0 * valley.2 && top_mean * 3.0 >= peak {
        freqs.iter().position(|&f| f >= valley.1).unwrap_or(freqs.len())
    } else {
        freqs.len()
    }
}

/// One-sided power spectral density by Welch's method: Hann windows of the largest power of two
/// up to 4096 that gives at least 4 segments (else the whole signal, one segment), half overlap,
/// each segment's mean removed. Returns (frequencies in Hz, density).
fn welch(x: &[f64], dt: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut len = 4096usize;
    while len > 32 && len * 5 / 2 > n {
        len /= 2;
    }
    let len = len.min(n);
    let step = (len / 2).max(1);
    let win: Vec<f64> = (0..len)
        .map(|i| {
            let s = (std::f64::consts::PI * i as f64 / len as f64).sin();
            s * s
        })
        .collect();
    let wpow: f64 = win.iter().map(|w| w * w).sum();
    let fft = FftPlanner::new().plan_fft_forward(len);
    let bins = len / 2 + 1;
    let mut psd = vec![0.0; bins];
    let mut count = 0usize;
    let mut start = 0usize;
    let mut buf = vec![Complex::new(0.0, 0.0); len];
    while start + len <= n {
        let seg = &x[start..start + len];
        let mean = seg.iter().sum::<f64>() / len as f64;
        for ((b, &v), &w) in buf.iter_mut().zip(seg).zip(&win) {
            *b = Complex::new((v - mean) * w, 0.0);
        }
        fft.process(&mut buf);
        for (k, p) in psd.iter_mut().enumerate() {
            let c = buf[k];
            let scale = if k == 0 || 2 * k == len { 1.0 } else { 2.0 };
            *p += scale * c.norm_sqr() * dt / wpow;
        }
        count += 1;
        start += step;
    }
    if count > 0 {
        for p in psd.iter_mut() {
            *p /= count as f64;
        }
    }
    let freqs = (0..bins).map(|k| k as f64 / (len as f64 * dt)).collect();
    (freqs, psd)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn noise_and_derivatives_of_a_known_signal() {
        let dt = 1e-3;
        let n = 60_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let sigma = 2e-4;
        let (a, w) = (0.5, std::f64::consts::TAU * 0.7);
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let g: f64 = (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0;
                a * (w * i as f64 * dt).sin() + sigma * g
            })
            .collect();
        let s = analyse(&x, dt).unwrap();
        assert!((s.noise_sd / sigma - 1.0).abs() < 0.1, "noise {} vs {sigma}", s.noise_sd);
        // RMS of the k-th derivative of a sine: a·w^k/√2. The window's leakage spreads the tone
        // over neighbouring bins, which weigh a high derivative more: within 10 % up to q̈, 40 %
        // for the 3rd and 4th derivatives of a pure tone (the window choice scales with the
        // 2/9th power of them: ~8 %; broadband motion leaks less).
        for k in 1..=4 {
            let want = a * w.powi(k as i32) / 2f64.sqrt();
            let got = s.deriv_rms[k - 1];
            let tol = if k <= 2 { 0.1 } else { 0.4 };
            assert!((got / want - 1.0).abs() < tol, "k = {k}: {got} vs {want}");
        }
        // the tone's window leakage stands above the noise for a few Hz
        assert!(s.bandwidth_hz > 0.5 && s.bandwidth_hz < 5.0, "bandwidth {}", s.bandwidth_hz);
    }

    /// A velocity logged through a drive's filter: the motion (two slow tones) plus white noise
    /// low-passed at 150 Hz. Against the white-noise shape that noise stands "above the noise"
    /// up to hundreds of hertz; the motion ends at the spectrum's valley instead, so the
    /// derivative the window is chosen from is the motion's, not the noise's.
    #[test]
    fn a_coloured_noise_is_not_taken_for_motion() {
        let dt = 1e-3;
        let n = 40_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let alpha = 1.0 - (-std::f64::consts::TAU * 150.0 * dt).exp();
        let mut state = 0.0;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                let g: f64 = (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0;
                state += alpha * (0.02 * g - state);
                0.8 * (std::f64::consts::TAU * 0.3 * t).sin() + 0.3 * (std::f64::consts::TAU * 1.1 * t).cos() + state
            })
            .collect();
        let s = analyse(&x, dt).unwrap();
        assert!(s.bandwidth_hz < 10.0, "bandwidth {} Hz", s.bandwidth_hz);
        // the motion's 2nd derivative: √((0.8·w1²)² + (0.3·w2²)²)/√2
        let (w1, w2) = (std::f64::consts::TAU * 0.3, std::f64::consts::TAU * 1.1);
        let want = ((0.8 * w1 * w1).powi(2) + (0.3 * w2 * w2).powi(2)).sqrt() / 2f64.sqrt();
        assert!((s.deriv_rms[1] / want - 1.0).abs() < 0.3, "q̈ rms {} vs {want}", s.deriv_rms[1]);
    }
}
