//! The shared preparation stage against a known q̈ (issue 20): a three-tone motion sampled at
//! 100 Hz–2 kHz, with white or AR(1)-coloured angle noise, `t, q` only. Printed per case: the
//! smoother's half-window, the derived q̈'s RMS error against the truth (interior samples) and
//! the error the report states. Asserted: the derived q̈ is within 10 % of the motion's q̈
//! (RMS), and the stated error is within a factor of three of the real one either way, so a
//! report's floor built on it neither hides nor invents a gap. White noise holds; coloured
//! noise does not yet (its test is ignored, with the figures).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use joint_analysis::log::JointLog;
use joint_analysis::prep;
use rand::{Rng, SeedableRng};

/// (amplitude rad, frequency Hz)
const TONES: [(f64, f64); 3] = [(0.6, 0.3), (0.3, 0.8), (0.1, 1.7)];

fn normal(rng: &mut impl Rng) -> f64 {
    let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The log at `rate` Hz over `secs` s with noise of standard deviation `sd`, AR(1) with
/// coefficient `phi` (0: white), and the true q̈ at its samples.
fn case(rate: f64, secs: f64, sd: f64, phi: f64, seed: u64) -> (JointLog, Vec<f64>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = (rate * secs) as usize;
    let innov = sd * (1.0 - phi * phi).sqrt();
    let mut e = sd * normal(&mut rng);
    let mut log = JointLog::default();
    let mut qdd = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f64 / rate;
        let (mut q, mut a) = (0.0, 0.0);
        for (amp, f) in TONES {
            let w = std::f64::consts::TAU * f;
            q += amp * (w * t).sin();
            a -= amp * w * w * (w * t).sin();
        }
        e = phi * e + innov * normal(&mut rng);
        log.t.push(t);
        log.q.push(q + e);
        qdd.push(a);
    }
    (log, qdd)
}

/// Prints one row per rate and asserts it (see the module's doc).
fn check(name: &str, phi: f64) {
    let mut worst: f64 = 0.0;
    eprintln!("rate Hz | noise       | half-window ms | q̈ error rad/s² (stated) | of q̈ RMS");
    for rate in [100.0, 250.0, 500.0, 1000.0, 2000.0] {
        let (log, truth) = case(rate, 20.0, 1e-3, phi, rate as u64);
        let p = prep::prepare(&log).unwrap();
        assert_eq!(p.log.len(), truth.len(), "{rate} Hz {name}: samples dropped");
        // interior: the smoother's one-sided ends are reported as worse and left out here
        let h = (p.report.qdd.half_window_s * rate).ceil() as usize;
        let err: Vec<f64> = (h..truth.len() - h).map(|i| p.qdd()[i] - truth[i]).collect();
        let (e, scale) = (rms(&err), rms(&truth[h..truth.len() - h]));
        let stated = p.report.qdd.error_sd;
        eprintln!(
            "{rate:7.0} | {name:11} | {:14.1} | {e:.4} ({stated:.4}) | {:.2} %",
            p.report.qdd.half_window_s * 1e3,
            100.0 * e / scale
        );
        assert!(e < 0.1 * scale, "{rate} Hz {name}: q̈ error {e} of {scale}");
        assert!(stated < 3.0 * e && e < 3.0 * stated, "{rate} Hz {name}: stated {stated}, real {e}");
        worst = worst.max(e / scale);
    }
    eprintln!("worst q̈ error ({name}): {:.2} % of the motion's q̈", 100.0 * worst);
}

/// White angle noise (1 mrad): 2.5–4.8 % of the motion's q̈, stated within 12 %.
#[test]
fn derived_qdd_against_the_truth_from_100_hz_to_2_khz_white_noise() {
    check("white", 0.0);
}

/// AR(1) angle noise (coefficient 0.9, 1 mrad): a noise whose spectrum falls with frequency.
/// Measured 2026-11-25: 20 % (100 Hz), 133 % (250 Hz, half-window 8 ms), 531 % (500 Hz, 4 ms),
/// 16–17 % at 1–2 kHz with the stated error 10× below the real one. The spectrum's noise
/// estimate takes this noise's slope for motion; not fixed yet, so this test is ignored and
/// the gap is named in issue 20's note. Run it with `--ignored`.
#[test]
#[ignore = "fails: AR(1)-coloured angle noise is read as motion at 250-500 Hz (issue 20 open)"]
fn derived_qdd_against_the_truth_from_100_hz_to_2_khz_coloured_noise() {
    check("AR(1) 0.9", 0.9);
}
