//! The shared preparation stage against a known q̈ (issue 20): a three-tone motion sampled at
//! 100 Hz–2 kHz with 1 mrad of angle noise, `t, q` only, the noise white or coloured (AR(1) at a
//! fixed coefficient per sample, first-order noise at a fixed corner in hertz, and noise
//! filtered twice). Printed per case: the smoother's half-window, the derived q̈'s RMS error
//! against the truth (interior samples) and the error the report states. Asserted: the derived
//! q̈ is within 10 % of the motion's q̈ (RMS; 15 % for the twice-filtered noise), and the stated
//! error is within a factor of three of the real one either way, so a report's floor built on
//! it neither hides nor invents a gap.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use joint_analysis::log::JointLog;
use joint_analysis::prep;
use rand::{Rng, SeedableRng};

/// (amplitude rad, frequency Hz)
const TONES: [(f64, f64); 3] = [(0.6, 0.3), (0.3, 0.8), (0.1, 1.7)];
const RATES: [f64; 5] = [100.0, 250.0, 500.0, 1000.0, 2000.0];
const NOISE_SD: f64 = 1e-3;

/// The angle noise's colour.
#[derive(Clone, Copy, Debug)]
enum Noise {
    White,
    /// AR(1) with this coefficient per sample (its corner moves with the rate)
    Ar1(f64),
    /// white noise through `order` first-order low-passes with this corner, Hz
    LowPass {
        order: usize,
        corner_hz: f64,
    },
}

fn normal(rng: &mut impl Rng) -> f64 {
    let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// `n` samples of the noise at `rate`, scaled to [`NOISE_SD`].
fn noise(kind: Noise, rate: f64, n: usize, seed: u64) -> Vec<f64> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (phi, stages) = match kind {
        Noise::White => (0.0, 0),
        Noise::Ar1(phi) => (phi, 1),
        Noise::LowPass { order, corner_hz } => ((-std::f64::consts::TAU * corner_hz / rate).exp(), order),
    };
    let mut state = vec![0.0; stages];
    // a second of warm-up, so the filters start in their steady state
    let warm = rate as usize;
    let mut e: Vec<f64> = (0..n + warm)
        .map(|_| {
            let mut x = normal(&mut rng);
            for s in state.iter_mut() {
                *s = phi * *s + (1.0 - phi) * x;
                x = *s;
            }
            x
        })
        .skip(warm)
        .collect();
    let sd = rms(&e);
    e.iter_mut().for_each(|x| *x *= NOISE_SD / sd);
    e
}

/// The log at `rate` Hz over `secs` s with the noise, and the true q̈ at its samples.
fn case(rate: f64, secs: f64, kind: Noise, seed: u64) -> (JointLog, Vec<f64>) {
    let n = (rate * secs) as usize;
    let e = noise(kind, rate, n, seed);
    let mut log = JointLog::default();
    let mut qdd = Vec::with_capacity(n);
    for (i, ei) in e.iter().enumerate() {
        let t = i as f64 / rate;
        let (mut q, mut a) = (0.0, 0.0);
        for (amp, f) in TONES {
            let w = std::f64::consts::TAU * f;
            q += amp * (w * t).sin();
            a -= amp * w * w * (w * t).sin();
        }
        log.t.push(t);
        log.q.push(q + ei);
        qdd.push(a);
    }
    (log, qdd)
}

/// (real q̈ error / motion's q̈ RMS, stated / real) at one rate, printed.
fn one(kind: Noise, rate: f64) -> (f64, f64) {
    let (log, truth) = case(rate, 20.0, kind, rate as u64);
    let p = prep::prepare(&log).unwrap();
    assert_eq!(p.log.len(), truth.len(), "{rate} Hz {kind:?}: samples dropped");
    // interior: the smoother's one-sided ends are reported as worse and left out here
    let h = (p.report.qdd.half_window_s * rate).ceil() as usize;
    let err: Vec<f64> = (h..truth.len() - h).map(|i| p.qdd()[i] - truth[i]).collect();
    let (e, scale) = (rms(&err), rms(&truth[h..truth.len() - h]));
    let stated = p.report.qdd.error_sd;
    eprintln!(
        "{rate:7.0} | {:38} | {:14.1} | {e:.4} ({stated:.4}) | {:.2} %",
        format!("{kind:?}"),
        p.report.qdd.half_window_s * 1e3,
        100.0 * e / scale
    );
    (e / scale, stated / e)
}

/// Every rate for every noise in `kinds`: asserts the error within `limit` of the motion's
/// q̈ and the stated error within 3× of the real one.
fn check(kinds: &[Noise], limit: f64) {
    eprintln!("rate Hz | noise                                  | half-window ms | q̈ error rad/s² (stated) | of q̈ RMS");
    let mut worst: f64 = 0.0;
    let mut failures = Vec::new();
    for &kind in kinds {
        for rate in RATES {
            let (rel, stated) = one(kind, rate);
            worst = worst.max(rel);
            if !(rel < limit && stated < 3.0 && stated > 1.0 / 3.0) {
                failures.push(format!("{rate} Hz {kind:?}: error {:.1} %, stated/real {stated:.2}", 100.0 * rel));
            }
        }
    }
    eprintln!("worst q̈ error: {:.2} % of the motion's q̈", 100.0 * worst);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// White angle noise (1 mrad): 2.5–4.8 % of the motion's q̈, stated within 12 %.
#[test]
fn derived_qdd_against_the_truth_from_100_hz_to_2_khz_white_noise() {
    check(&[Noise::White], 0.10);
}

/// First-order coloured angle noise, whose spectrum falls with frequency (f⁻² above its
/// corner): AR(1) at 0.5, 0.9 and 0.99 per sample, and corners fixed at 5, 20 and 60 Hz.
/// Before the preparation modelled a falling noise (measured 2026-11-25, AR(1) 0.9): 20 % at
/// 100 Hz, 133 % at 250 Hz, 531 % at 500 Hz (a ±4 ms window), 16–17 % at 1–2 kHz with the
/// stated error 10× below the real one. Now: 2.6–5.7 %, stated within 20 %.
#[test]
fn derived_qdd_against_the_truth_from_100_hz_to_2_khz_coloured_noise() {
    let kinds = [
        Noise::Ar1(0.5),
        Noise::Ar1(0.9),
        Noise::Ar1(0.99),
        Noise::LowPass { order: 1, corner_hz: 5.0 },
        Noise::LowPass { order: 1, corner_hz: 20.0 },
        Noise::LowPass { order: 1, corner_hz: 60.0 },
    ];
    check(&kinds, 0.10);
}

/// Noise filtered twice (an angle from a tracking observer) falls as steeply as motion (f⁻⁴),
/// and the spectrum alone takes it for motion; a 50 ms window's view of the motion tells them
/// apart (`prep::prepare`). Corners at 20 and 60 Hz: 4.6–5.8 % (before: up to 3000 % with a
/// ±1 ms window). A corner within two octaves of the motion (5 Hz against tones up to 1.7 Hz)
/// is not separated at 100 Hz–1 kHz (15–65 %, the stated error within 25 % of the real one, so
/// a report's floor says so): printed, not asserted.
#[test]
fn derived_qdd_against_the_truth_with_a_twice_filtered_noise() {
    check(&[Noise::LowPass { order: 2, corner_hz: 20.0 }, Noise::LowPass { order: 2, corner_hz: 60.0 }], 0.15);
    eprintln!("not separated (printed only):");
    for rate in RATES {
        one(Noise::LowPass { order: 2, corner_hz: 5.0 }, rate);
    }
}

/// A log too short for a spectrum (40 samples at 85 Hz of a 4.4 Hz decaying swing, 0.2 mrad
/// of angle noise): the derivative sizes come from a pilot window, not from nothing. With
/// sizes of 0 every window was its widest (±247 ms, two periods of the swing) and q̇ was off by
/// 1.4 rad/s, so a clean logged q̇ was judged the noisy one (unseen t9075/0040). Asserted: the
/// derived q̇ and q̈ within 10 % of the motion's (RMS, interior samples).
#[test]
fn a_log_too_short_for_a_spectrum_gets_windows_its_motion_allows() {
    let (rate, n, f, zeta) = (85.0, 40usize, 4.4, 0.05);
    let w = std::f64::consts::TAU * f;
    let e = noise(Noise::White, rate, n, 40);
    let mut log = JointLog::default();
    let (mut qd, mut qdd) = (Vec::new(), Vec::new());
    for (i, ei) in e.iter().enumerate() {
        let t = i as f64 / rate;
        // q = A·e^(−ζwt)·cos(wt) and its derivatives
        let (a, k) = (0.3, zeta * w);
        let (c, s, x) = ((w * t).cos(), (w * t).sin(), (-k * t).exp());
        log.t.push(t);
        log.q.push(a * x * c + 0.2 * ei);
        qd.push(a * x * (-k * c - w * s));
        qdd.push(a * x * ((k * k - w * w) * c + 2.0 * k * w * s));
    }
    let p = prep::prepare(&log).unwrap();
    let h = 4;
    let rel = |est: &[f64], truth: &[f64]| {
        let err: Vec<f64> = (h..n - h).map(|i| est[i] - truth[i]).collect();
        rms(&err) / rms(&truth[h..n - h])
    };
    let (e1, e2) = (rel(p.qd(), &qd), rel(p.qdd(), &qdd));
    eprintln!(
        "half-windows q̇ {:.1} ms, q̈ {:.1} ms; errors {:.2} % and {:.2} % of the motion's",
        p.report.qd.half_window_s * 1e3,
        p.report.qdd.half_window_s * 1e3,
        100.0 * e1,
        100.0 * e2
    );
    assert!(e1 < 0.10 && e2 < 0.10, "q̇ error {:.1} %, q̈ error {:.1} %", 100.0 * e1, 100.0 * e2);
}

/// Slow moves out of rests under a coarse encoder: 1 kHz, 0.0015 rad per count, each move
/// creeping out of its rest (q̇ rising as t², 0.1 rad/s after 0.5 s), so q takes ~0.2 s to
/// leave its noise band (4 × step/√12). A logged q̇ with white noise of 2e-4 rad/s signs the
/// motion where it stands clear of that noise: those samples are not left out as of unknown
/// direction (a Stribeck curve lives at those speeds). A q̇ derived from q has no such reading
/// there, and its samples stay out.
#[test]
fn a_logged_velocity_signs_a_creep_out_of_rest_before_the_angle_does() {
    let (rate, step, sd) = (1000.0, 0.0015, 2e-4);
    let e = noise(Noise::White, rate, 12_000, 7);
    let mut log = JointLog::default();
    let mut v_true = Vec::new();
    let mut q = 0.0;
    for i in 0..12_000 {
        let t = i as f64 / rate;
        // 1 s rest, then 2 s of a move whose speed rises and falls as sin², each way in turn
        let (k, s) = ((t / 3.0).floor(), t % 3.0);
        let dir = if k as i64 % 2 == 0 { 1.0 } else { -1.0 };
        let v = if s < 1.0 { 0.0 } else { dir * 0.2 * (std::f64::consts::PI * (s - 1.0) / 2.0).sin().powi(2) };
        q += v / rate;
        log.t.push(t);
        log.q.push((q / step).floor() * step);
        v_true.push(v);
    }
    let clear = |v: f64| v.abs() > 20.0 * sd;
    let left_out = |log: &JointLog| {
        let p = prep::prepare(log).unwrap();
        let moving: Vec<usize> = (0..v_true.len()).filter(|&i| clear(v_true[i])).collect();
        let out = moving.iter().filter(|&&i| p.ambiguous[i]).count();
        let wrong = moving.iter().filter(|&&i| !p.ambiguous[i] && p.qd()[i] * v_true[i] < 0.0).count();
        (out as f64 / moving.len() as f64, wrong)
    };
    let (derived, _) = left_out(&log);
    log.qd = Some(v_true.iter().zip(&e).map(|(v, ei)| v + sd / NOISE_SD * ei).collect());
    let (logged, wrong) = left_out(&log);
    eprintln!(
        "moving samples (|q̇| > 20σ) left out: {:.1} % with q̇ derived from q, {:.2} % with it logged ({wrong} signed wrong)",
        100.0 * derived,
        100.0 * logged
    );
    assert!(derived > 0.02, "the derived q̇ left {:.2} % out: the case does not creep", 100.0 * derived);
    assert!(logged < 0.002 && wrong == 0, "logged: {:.2} % left out, {wrong} signed wrong", 100.0 * logged);
}
