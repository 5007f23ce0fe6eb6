//! What a sampled signal's spectrum says about it: the level of its white noise and how large
//! its higher derivatives are, the two numbers a derivative estimator's window trades off.
//!
//! The spectrum is Welch's (Hann windows, half overlap) of the signal's first difference over
//! its time step (a rough derivative, so the large slow part of a position does not leak into
//! the high frequencies through the window). White noise of standard deviation σ on the signal puts
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
    /// white noise on the signal (standard deviation, the signal's unit): the level of its top
    /// quarter of the band
    pub noise_sd: f64,
    /// the noise's spectrum over the whole band: white at `noise_sd`, or coloured (see
    /// [`NoiseModel`])
    pub noise: NoiseModel,
    /// RMS of the signal's k-th derivative, k = 1..=6 (index k − 1), from the motion bins
    pub deriv_rms: [f64; 6],
    /// highest frequency where the motion stands above the noise, Hz
    pub bandwidth_hz: f64,
}

/// Fewer samples than this: no spectrum (the caller uses its fallbacks).
pub const MIN_SAMPLES: usize = 64;

/// The spectrum of `x` stamped at `t`, `dt` seconds apart (the median step; nearly uniformly),
/// or `None` for fewer than [`MIN_SAMPLES`] samples.
pub fn analyse(t: &[f64], x: &[f64], dt: f64) -> Option<SignalSpectrum> {
    analyse_below(t, x, dt, None)
}

/// The rough derivative of `x` stamped at `t`: each first difference over the median step `dt`
/// where the stamps are even ([`super::lpr::evenly_stamped`], as the local fits take them), else
/// over the sample's own step. A log whose stamps say when each sample was taken, on a clock
/// that jitters, holds the motion exactly: a difference over the median step reads the
/// jitter as a noise of `q̇·δt` on the angle, largest where the joint moves fastest (model-exact
/// null seed 31, case 174: a chirp at 100 Hz with 13 % jitter read as a noise of 3.7 times the
/// encoder's, a window for q̈ that wide attenuated the chirp's top by 5 %, and the refit took
/// J·Δq̈ for `parameters`).
fn rough_derivative(t: &[f64], x: &[f64], dt: f64) -> Vec<f64> {
    if t.len() != x.len() || super::lpr::evenly_stamped(t, dt) {
        x.windows(2).map(|w| (w[1] - w[0]) / dt).collect()
    } else {
        x.windows(2).zip(t.windows(2)).map(|(w, s)| (w[1] - w[0]) / (s[1] - s[0])).collect()
    }
}

/// As [`analyse`], told that the motion ends at `motion_edge_hz` (when given): everything
/// above it is noise, whatever its slope (a noise filtered twice before it was logged falls as
/// steeply as a motion does, and only another view of the motion can tell them apart; see
/// `prep::prepare`).
pub fn analyse_below(t: &[f64], x: &[f64], dt: f64, motion_edge_hz: Option<f64>) -> Option<SignalSpectrum> {
    if x.len() < MIN_SAMPLES || !(dt > 0.0) {
        return None;
    }
    let d = rough_derivative(t, x, dt);
    let (freqs, psd) = welch(&d, dt);
    let nyq = 0.5 / dt;
    let shape = |f: f64| white_shape(f, dt);
    let mut ratios: Vec<f64> =
        freqs.iter().zip(&psd).filter(|(f, _)| **f >= 0.75 * nyq).map(|(f, p)| p / shape(*f).max(1e-300)).collect();
    if ratios.is_empty() {
        return None;
    }
    let mid = ratios.len() / 2;
    let (_, m, _) = ratios.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    let sigma2 = m.max(0.0);
    let df = freqs.get(1).copied().unwrap_or(nyq);
    let noise = noise_model(&freqs, &psd, dt, sigma2, x, motion_edge_hz);
    // the noise in the rough derivative's spectrum at f
    let noise_at = |f: f64| noise.level(f) * shape(f);
    // Motion: bins clearly above the noise (3×), from the lowest frequency up to where a whole
    // octave stays below it. Energy above that is not motion but the tones an encoder's
    // quantisation makes (a joint moving at v crosses steps of size Δ at v/Δ Hz).
    let above: Vec<bool> = freqs.iter().zip(&psd).map(|(&f, &p)| f > 0.0 && p > 3.0 * noise_at(f)).collect();
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
    let end = motion_edge_hz.map_or(end, |e| end.min(freqs.partition_point(|&f| f <= e)));
    let mut sums = [0.0f64; 6];
    let mut bandwidth = 0.0f64;
    for k in 0..end {
        let (f, p) = (freqs[k], psd[k]);
        if !above[k] {
            continue;
        }
        let noise = noise_at(f);
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
    Some(SignalSpectrum { noise_sd: sigma2.sqrt(), noise, deriv_rms, bandwidth_hz: bandwidth })
}

/// The noise on a signal as a spectrum: its level `R(f)` in the units of a white noise's
/// variance (a white noise of standard deviation σ has `R = σ²` at every frequency), given at a
/// few frequencies and interpolated between them on log–log axes, flat beyond them.
///
/// White noise is one level. A noise that was filtered before it was logged (an angle
/// interpolated or low-passed by the drive, a slow mechanical wobble) has more power at low
/// frequencies than its top quarter shows: read as white, its slope looks like motion up to
/// tens of hertz, the derivative window chosen for that "motion" is a few samples wide, and the
/// q̈ it gives is mostly noise (measured: 5× the motion's q̈ at 500 Hz with an AR(1) angle
/// noise). The coloured model keeps that slope as noise.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseModel {
    /// (frequency Hz, level), increasing in frequency; never empty
    points: Vec<(f64, f64)>,
    dt: f64,
}

impl NoiseModel {
    /// White noise of standard deviation `sd`, sampled every `dt` seconds.
    pub fn white(sd: f64, dt: f64) -> Self {
        Self { points: vec![(0.0, sd * sd)], dt }
    }

    /// Whether the model is one level.
    pub fn is_white(&self) -> bool {
        self.points.len() == 1
    }

    /// The level `R(f)` (variance units of a white noise).
    pub fn level(&self, f: f64) -> f64 {
        let p = &self.points;
        let (Some(first), Some(last)) = (p.first(), p.last()) else {
            return 0.0;
        };
        if p.len() == 1 || f <= first.0 {
            return first.1;
        }
        if f >= last.0 {
            return last.1;
        }
        let k = p.partition_point(|(g, _)| *g <= f).clamp(1, p.len() - 1);
        let ((f0, l0), (f1, l1)) = (p[k - 1], p[k]);
        if !(f0 > 0.0 && l0 > 0.0 && l1 > 0.0) {
            return l0.max(l1);
        }
        let u = (f / f0).ln() / (f1 / f0).ln();
        (l0.ln() + u * (l1.ln() - l0.ln())).exp()
    }

    /// The noise's autocovariance at lags `0..=max_lag` samples: the inverse Fourier transform
    /// of its one-sided density `2·dt·R(f)` on a grid of at least 4096 points.
    pub fn autocovariance(&self, max_lag: usize) -> Vec<f64> {
        let len = (4 * max_lag + 4).next_power_of_two().max(4096);
        let df = 1.0 / (len as f64 * self.dt);
        // two-sided density dt·R(|f|) at every grid point, summed with e^{+i2πkm/len}
        let mut buf: Vec<Complex<f64>> =
            (0..len).map(|k| Complex::new(self.dt * self.level(k.min(len - k) as f64 * df), 0.0)).collect();
        FftPlanner::new().plan_fft_inverse(len).process(&mut buf);
        buf.iter().take(max_lag + 1).map(|c| c.re * df).collect()
    }

    /// The variance this noise gives a linear filter with weights `w` (consecutive samples),
    /// from its autocovariance `r` (at least `w.len()` lags).
    pub fn filtered_variance(r: &[f64], w: &[f64]) -> f64 {
        let mut var = 0.0;
        for (i, wi) in w.iter().enumerate() {
            for (j, wj) in w.iter().enumerate() {
                var += wi * wj * r.get(i.abs_diff(j)).copied().unwrap_or(0.0);
            }
        }
        var
    }

    /// The noise's standard deviation (all of the band).
    pub fn total_sd(&self) -> f64 {
        if self.is_white() {
            return self.level(0.0).sqrt();
        }
        self.autocovariance(0).first().copied().unwrap_or(0.0).max(0.0).sqrt()
    }
}

/// A noise falls with frequency by at most this factor per octave (in `R`) before it is taken
/// for motion: a once-filtered noise falls by 4 (f⁻²); a moving joint's angle, whose q̈ is
/// bounded, by 16 or more (f⁻⁴: a q̇ that jumps at an impact; smooth motion falls faster still).
const NOISE_SLOPE_PER_OCTAVE: f64 = 5.5;

/// The noise's spectrum (see [`NoiseModel`]): the median level `R` of each octave, walked down
/// from Nyquist while it rises no faster than a filtered noise can; the first octave that rises
/// faster is motion, and the noise below it is held at the last level. The model is coloured
/// only when that walk rises above three times the top quarter's level over at least two
/// octaves that each rise (one jump is the edge of a broadband motion, not a noise's slope),
/// and the coloured noise is at most 1 % of the signal's variance (a motion of steps has an f⁻²
/// spectrum too, and is all of the signal); otherwise it is white at the top quarter's level.
///
/// Told where the motion ends, every octave above that edge is noise and the model is coloured
/// whenever they rise above three times the top quarter's level (still within the 1 % bound).
fn noise_model(freqs: &[f64], psd: &[f64], dt: f64, sigma2: f64, x: &[f64], edge: Option<f64>) -> NoiseModel {
    let white = NoiseModel { points: vec![(0.0, sigma2)], dt };
    let nyq = 0.5 / dt;
    let shape = |f: f64| white_shape(f, dt);
    // octave medians of R, from the top down: (centre Hz, median)
    let mut octaves: Vec<(f64, f64)> = Vec::new();
    let mut hi = nyq;
    loop {
        let lo = 0.5 * hi;
        let mut r: Vec<f64> = freqs
            .iter()
            .zip(psd)
            .filter(|(f, _)| **f >= lo && **f < hi && **f > 0.0)
            .map(|(f, p)| p / shape(*f).max(1e-300))
            .collect();
        if r.len() < 4 {
            break;
        }
        let mid = r.len() / 2;
        let (_, m, _) = r.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        octaves.push(((lo * hi).sqrt(), *m));
        hi = lo;
    }
    if !(sigma2 > 0.0) || octaves.len() < 3 {
        return white;
    }
    let mut kept: Vec<(f64, f64)> = vec![(0.875 * nyq, sigma2)];
    let mut rises = 0usize;
    let mut prev = sigma2;
    for &(f, m) in &octaves {
        match edge {
            Some(e) if f < e * std::f64::consts::SQRT_2 => break,
            None if m > NOISE_SLOPE_PER_OCTAVE * prev => break,
            _ => {}
        }
        if m > 1.5 * prev {
            rises += 1;
        }
        kept.push((f, m));
        prev = m;
    }
    let peak = kept.iter().map(|p| p.1).fold(0.0f64, f64::max);
    if peak <= 3.0 * sigma2 || (rises < 2 && edge.is_none()) {
        return white;
    }
    kept.reverse();
    let model = NoiseModel { points: kept, dt };
    let n = x.len().max(1) as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    let total = model.total_sd();
    if total * total > 0.01 * var {
        return white;
    }
    model
}

/// The rough derivative's (first difference over `dt`) spectrum at `f` for white noise of unit
/// variance on the signal: `2·dt·(2·sin(π·f·dt)/dt)²`.
fn white_shape(f: f64, dt: f64) -> f64 {
    let s = 2.0 * (std::f64::consts::PI * f * dt).sin() / dt;
    2.0 * dt * s * s
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

    /// A standard normal draw (the sum of twelve uniforms, centred).
    fn gauss(rng: &mut impl Rng) -> f64 {
        (0..12).map(|_| rng.random::<f64>()).sum::<f64>() - 6.0
    }

    /// `n` stamps `dt` apart.
    fn even(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 * dt).collect()
    }

    #[test]
    fn noise_and_derivatives_of_a_known_signal() {
        let dt = 1e-3;
        let n = 60_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let sigma = 2e-4;
        let (a, w) = (0.5, std::f64::consts::TAU * 0.7);
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let g = gauss(&mut rng);
                a * (w * i as f64 * dt).sin() + sigma * g
            })
            .collect();
        let s = analyse(&even(x.len(), dt), &x, dt).unwrap();
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

    /// A chirp-like motion sampled on a clock that jitters by ±7 % of the step, each sample
    /// stamped with the time it was taken, and a white noise on it: read over each sample's own
    /// step, the noise is the sensor's; read over the median step, the jitter is taken for a
    /// noise of `q̇·δt` several times larger (null seed 31, case 174 of the bench).
    #[test]
    fn a_clock_that_jitters_and_says_so_adds_no_noise() {
        let dt = 1e-2;
        let n = 6_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let sigma = 2e-5;
        let t: Vec<f64> = (0..n).map(|i| (i as f64 + 0.14 * (rng.random::<f64>() - 0.5)) * dt).collect();
        let (a, w) = (0.06, std::f64::consts::TAU * 1.5);
        let x: Vec<f64> = t
            .iter()
            .map(|&t| {
                let g = gauss(&mut rng);
                a * (w * t).sin() + sigma * g
            })
            .collect();
        let s = analyse(&t, &x, dt).unwrap();
        assert!((s.noise_sd / sigma - 1.0).abs() < 0.2, "noise {} vs {sigma}", s.noise_sd);
        let blind = analyse(&even(n, dt), &x, dt).unwrap();
        assert!(blind.noise_sd > 3.0 * sigma, "the jitter read as noise: {} vs {sigma}", blind.noise_sd);
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
                let g = gauss(&mut rng);
                state += alpha * (0.02 * g - state);
                0.8 * (std::f64::consts::TAU * 0.3 * t).sin() + 0.3 * (std::f64::consts::TAU * 1.1 * t).cos() + state
            })
            .collect();
        let s = analyse(&even(x.len(), dt), &x, dt).unwrap();
        assert!(s.bandwidth_hz < 10.0, "bandwidth {} Hz", s.bandwidth_hz);
        // the motion's 2nd derivative: √((0.8·w1²)² + (0.3·w2²)²)/√2
        let (w1, w2) = (std::f64::consts::TAU * 0.3, std::f64::consts::TAU * 1.1);
        let want = ((0.8 * w1 * w1).powi(2) + (0.3 * w2 * w2).powi(2)).sqrt() / 2f64.sqrt();
        assert!((s.deriv_rms[1] / want - 1.0).abs() < 0.3, "q̈ rms {} vs {want}", s.deriv_rms[1]);
    }

    #[test]
    fn white_noise_model_is_its_variance_at_lag_zero_only() {
        let m = NoiseModel::white(2e-3, 1e-3);
        let r = m.autocovariance(8);
        assert!((r[0] / 4e-6 - 1.0).abs() < 1e-9, "{}", r[0]);
        assert!(r[1..].iter().all(|x| x.abs() < 1e-15), "{r:?}");
        let w = [0.5, -1.0, 2.0];
        let var = NoiseModel::filtered_variance(&r, &w);
        assert!((var / (4e-6 * 5.25) - 1.0).abs() < 1e-9, "{var}");
        assert!((m.total_sd() - 2e-3).abs() < 1e-12);
    }

    /// AR(1) angle noise (0.95 per sample, 1 ms steps: a corner near 8 Hz) under a slow motion:
    /// the model is coloured, its total matches the noise's standard deviation, its lag-one
    /// correlation is the coefficient, and the motion's q̈ is the tone's, not the noise's.
    #[test]
    fn an_ar1_noise_is_modelled_as_a_falling_spectrum() {
        let dt = 1e-3;
        let n = 60_000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let (phi, sd) = (0.95f64, 1e-3);
        let innov = sd * (1.0 - phi * phi).sqrt();
        let mut e = 0.0;
        let (a, w) = (0.4, std::f64::consts::TAU * 0.5);
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let g = gauss(&mut rng);
                e = phi * e + innov * g;
                a * (w * i as f64 * dt).sin() + e
            })
            .collect();
        let s = analyse(&even(x.len(), dt), &x, dt).unwrap();
        assert!(!s.noise.is_white());
        assert!((s.noise.total_sd() / sd - 1.0).abs() < 0.25, "total {}", s.noise.total_sd());
        let r = s.noise.autocovariance(1);
        assert!((r[1] / r[0] - phi).abs() < 0.05, "lag-one correlation {}", r[1] / r[0]);
        let want = a * w * w / 2f64.sqrt();
        assert!((s.deriv_rms[1] / want - 1.0).abs() < 0.1, "q̈ rms {} vs {want}", s.deriv_rms[1]);
        // read as white, the noise's slope was motion: q̈ many times the tone's
        assert!(s.bandwidth_hz < 5.0, "bandwidth {}", s.bandwidth_hz);
    }
}
