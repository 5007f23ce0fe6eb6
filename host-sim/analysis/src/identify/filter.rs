//! Offline signal conditioning for identification: a zero-phase Butterworth low-pass and
//! numerical derivatives.
//!
//! Identification runs after the test, so it can afford a non-causal filter: a second-order
//! Butterworth section run forward and backward (`filtfilt`) has no phase lag at all, which
//! matters because the inertia fit pairs q̈ with the torque of the same instant; a causal filter
//! would shift q̈ by its group delay and bias J. The effective response is |H|² (fourth order,
//! −6 dB at the cut-off). Edges are padded by odd reflection and the filter starts in its
//! steady state, so the ends do not ring.
//!
//! Logs may be sampled unevenly (real loggers jitter); the filter assumes the median sample
//! period, and derivatives use the actual time stamps.

/// A second-order section `y = (b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²) x`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad {
    pub b0: f64,
    pub b1: f64,
    pub b2: f64,
    pub a1: f64,
    pub a2: f64,
}

impl Biquad {
    /// Second-order Butterworth low-pass with cut-off `fc` Hz at sample rate `fs` Hz (bilinear
    /// transform with pre-warping). A cut-off at or above Nyquist gives the identity.
    pub fn butter_lowpass(fc: f64, fs: f64) -> Biquad {
        if !(fc > 0.0 && fs > 0.0 && fc < 0.49 * fs) {
            return Biquad { b0: 1.0, b1: 0.0, b2: 0.0, a1: 0.0, a2: 0.0 };
        }
        let k = (std::f64::consts::PI * fc / fs).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Biquad { b0, b1: 2.0 * b0, b2: b0, a1: 2.0 * (k * k - 1.0) * norm, a2: (1.0 - k / q + k * k) * norm }
    }

    /// Runs the section over `x` in place (direct form II transposed), starting in the steady
    /// state of the first value.
    fn run(&self, x: &mut [f64]) {
        let Some(&x0) = x.first() else { return };
        let mut z2 = (self.b2 - self.a2) * x0;
        let mut z1 = (self.b1 - self.a1) * x0 + z2;
        for v in x.iter_mut() {
            let xi = *v;
            let y = self.b0 * xi + z1;
            z1 = self.b1 * xi - self.a1 * y + z2;
            z2 = self.b2 * xi - self.a2 * y;
            *v = y;
        }
    }
}

/// Zero-phase low-pass of `x` (Butterworth, second order each way) at `fc` Hz for sample rate `fs`.
pub fn filtfilt(x: &[f64], fc: f64, fs: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(x.len());
    filtfilt_into(x, fc, fs, &mut out);
    out
}

/// [`filtfilt`] into a caller's buffer (reused across calls to avoid allocations).
pub fn filtfilt_into(x: &[f64], fc: f64, fs: f64, out: &mut Vec<f64>) {
    out.clear();
    let n = x.len();
    if n == 0 {
        return;
    }
    let bq = Biquad::butter_lowpass(fc, fs);
    // Pad by odd reflection about the end values: about one cut-off period, so the start-up of
    // each pass has died out before the real data begins.
    let pad = ((fs / fc.max(1e-9)).ceil() as usize).clamp(6, 50_000).min(n - 1);
    let (first, last) = (x[0], x[n - 1]);
    out.reserve(n + 2 * pad);
    for i in (1..=pad).rev() {
        out.push(2.0 * first - x[i]);
    }
    out.extend_from_slice(x);
    for i in 1..=pad {
        out.push(2.0 * last - x[n - 1 - i]);
    }
    bq.run(out);
    out.reverse();
    bq.run(out);
    out.reverse();
    out.drain(..pad);
    out.truncate(n);
}

/// [`filtfilt`] run separately over each half-open range of `pieces` (the gap-free stretches of
/// a log), so nothing is smoothed across a gap; samples outside every range are copied.
pub fn filtfilt_pieces(x: &[f64], fc: f64, fs: f64, pieces: &[std::ops::Range<usize>]) -> Vec<f64> {
    let mut out = x.to_vec();
    let mut buf = Vec::new();
    for r in pieces {
        let r = r.start.min(x.len())..r.end.min(x.len());
        if r.is_empty() {
            continue;
        }
        filtfilt_into(&x[r.clone()], fc, fs, &mut buf);
        out[r].copy_from_slice(&buf);
    }
    out
}

/// Derivative of `x` over the time stamps `t`: central differences inside (exact for a parabola
/// on uneven steps), one-sided at the two ends.
pub fn derivative(t: &[f64], x: &[f64]) -> Vec<f64> {
    let n = t.len().min(x.len());
    let mut d = vec![0.0; n];
    if n < 2 {
        return d;
    }
    d[0] = (x[1] - x[0]) / (t[1] - t[0]);
    d[n - 1] = (x[n - 1] - x[n - 2]) / (t[n - 1] - t[n - 2]);
    for i in 1..n - 1 {
        let (h0, h1) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        let (s0, s1) = ((x[i] - x[i - 1]) / h0, (x[i + 1] - x[i]) / h1);
        d[i] = (s0 * h1 + s1 * h0) / (h0 + h1);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtfilt_passes_slow_sine_without_lag_and_removes_fast_one() {
        let fs = 1000.0;
        let t: Vec<f64> = (0..4000).map(|i| i as f64 / fs).collect();
        let slow: Vec<f64> = t.iter().map(|t| (std::f64::consts::TAU * 0.5 * t).sin()).collect();
        let x: Vec<f64> =
            t.iter().zip(&slow).map(|(t, s)| s + 0.3 * (std::f64::consts::TAU * 100.0 * t).sin()).collect();
        let y = filtfilt(&x, 5.0, fs);
        let err = slow.iter().zip(&y).skip(200).take(3600).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 0.01, "max error {err}");
    }

    #[test]
    fn derivative_exact_on_parabola_with_uneven_steps() {
        let t = [0.0, 0.1, 0.25, 0.3, 0.5];
        let x: Vec<f64> = t.iter().map(|t| 3.0 * t * t + 2.0 * t).collect();
        let d = derivative(&t, &x);
        for i in 1..4 {
            assert!((d[i] - (6.0 * t[i] + 2.0)).abs() < 1e-12);
        }
    }
}
