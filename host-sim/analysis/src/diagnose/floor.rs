//! The noise floor: how small a residual can get when the model is right.
//!
//! Two parts add up (in variance):
//! - **measurement noise** on the torques, white or coloured. It is read from the residual's
//!   robust variogram `V(k) = Var(r(t+k) − r(t))` over lags k = 1…K: noise with lag-k
//!   correlation ρ^k contributes `2σ²(1 − ρ^k)`, a smooth model error `c·k²`, so a fit of
//!   `2σ²(1 − ρ^k) + c·k²` gives σ whatever the noise colour (AR(1) up to ρ = 0.95), where the
//!   second-difference estimator used before read a ρ = 0.9 noise as a quarter of its size.
//!   Robust (median-based) differences ignore the sparse jumps a friction sign makes.
//! - **signal uncertainty**: the error of the q̇ and q̈ the model is evaluated with (from the
//!   preparation stage), carried through the model's own terms: `J·σ(q̈)`, the viscous slope
//!   times `σ(q̇)`, and near rest the Coulomb level times the sign's spread (`c²·(1 − E[sgn]²)`).
//!   No model can take this part out of the residual, so it is part of the floor.

thread_local! {
    static DIFFS: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Measurement-noise RMS of a residual from its robust variogram (see the module doc), and the
/// lag-1 correlation it found.
pub fn variogram_noise(r: &[f64]) -> (f64, f64) {
    let n = r.len();
    if n < 8 {
        return (0.0, 0.0);
    }
    let max_lag = (n / 4).clamp(2, 30);
    let stride = (n / 200_000).max(1);
    // each lag on its own (up to 30 medians of 200 000 differences): on the available cores
    let lags: Vec<usize> = (1..=max_lag).collect();
    let threads = super::par::cores(8);
    let v: Vec<f64> = super::par::costliest_first(
        &lags,
        threads,
        |_| 0,
        |&k| {
            // one buffer per thread for all its lags (fresh 1.6 MB vectors per lag were page
            // faults on a 1 M-sample log, a variogram being read several times per diagnosis)
            DIFFS.with(|cell| {
                let mut d = cell.borrow_mut();
                d.clear();
                d.extend((0..n - k).step_by(stride).map(|i| (r[i + k] - r[i]).abs()));
                let mid = d.len() / 2;
                let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
                let s = 1.4826 * *m;
                s * s
            })
        },
    );
    // For each ρ on a grid, V(k) = s2·2(1 − ρ^k) + c·k² is linear in (s2, c) ≥ 0.
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for step in 0..=95 {
        let rho = step as f64 / 100.0;
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (i, &vk) in v.iter().enumerate() {
            let k = (i + 1) as f64;
            let x1 = 2.0 * (1.0 - rho.powf(k));
            let x2 = k * k;
            a11 += x1 * x1;
            a12 += x1 * x2;
            a22 += x2 * x2;
            b1 += x1 * vk;
            b2 += x2 * vk;
        }
        let det = a11 * a22 - a12 * a12;
        let (mut s2, mut c) = if det.abs() > 1e-300 {
            ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det)
        } else {
            (b1 / a11.max(1e-300), 0.0)
        };
        if c < 0.0 {
            c = 0.0;
            s2 = b1 / a11.max(1e-300);
        }
        if s2 < 0.0 {
            s2 = 0.0;
            c = b2 / a22.max(1e-300);
        }
        let sse: f64 = v
            .iter()
            .enumerate()
            .map(|(i, &vk)| {
                let k = (i + 1) as f64;
                let e = vk - s2 * 2.0 * (1.0 - rho.powf(k)) - c * k * k;
                e * e
            })
            .sum();
        if sse < best.0 {
            best = (sse, s2.max(0.0).sqrt(), rho);
        }
    }
    (best.1, best.2)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr_shim::normal;

    mod rand_distr_shim {
        use rand::Rng;
        /// Box–Muller, enough for a test.
        pub fn normal(rng: &mut impl Rng) -> f64 {
            let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    #[test]
    fn coloured_noise_is_measured_at_its_size_under_a_smooth_error() {
        for &rho in &[0.0, 0.5, 0.9] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
            let sigma = 0.1;
            let innov = sigma * (1.0f64 - rho * rho).sqrt();
            let mut e = 0.0;
            let r: Vec<f64> = (0..50_000)
                .map(|i| {
                    e = rho * e + innov * normal(&mut rng);
                    // a slow model error ten times the noise, plus a friction-like jump every second
                    let t = i as f64 * 1e-3;
                    e + 1.0 * (0.7 * t).sin() + if (t as usize) % 2 == 0 { 0.3 } else { -0.3 }
                })
                .collect();
            let (s, rho_hat) = variogram_noise(&r);
            assert!((s / sigma - 1.0).abs() < 0.1, "rho {rho}: {s} vs {sigma} (rho_hat {rho_hat})");
        }
    }
}
