//! A clean encoder staircase under a pure Coulomb sign. Point-to-point moves that join without a
//! dwell slow to a near stop and go on the same way; a 14-bit encoder without noise then holds
//! one count for a tenth of a second or more. The q̇ estimated from q (a local polynomial, whose
//! derivative weights change sign across the window) can come out the wrong way there, at three
//! or four times its stated error, and a pure sign turns that into 2·c of residual. A few such
//! samples made an arm joint's exact-model log `unexplained` (unseen bench seed 9023, case 53).
//! The same holds next to a dwell too short for the rest detector, where the estimate carries
//! the coming move into the still joint.
//!
//! The log here is built in the test from its own moves and the model's law, not by the
//! simulator or the bench: the exact model must come out `none`, and the preparation must mark
//! every wrongly signed estimate as a sample whose sign is unknown.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

mod common;

use common::{gauss, moves};
use joint_analysis::diagnose::{diagnose, Options};
use joint_analysis::prep;
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const MODEL: &str = "[friction]\nb = 6.2\nc = 5.7\n[weight]\namplitude = 25.3\ns = 1.0\nphi = 1.306\n\
                     [inertia]\nj = 1.16\n[offset]\nc0 = 0.63\n";
const RATE: f64 = 1000.0;
const STEP: f64 = std::f64::consts::TAU / 16384.0;

/// How the log is made: the shortest dwell between moves (s), and the white noise on the angle
/// before the encoder reads it (rad; 0: a clean staircase, else dither across its counts).
#[derive(Clone, Copy)]
struct Make {
    dwell_min: f64,
    dither: f64,
}

const LONG_DWELLS: Make = Make { dwell_min: 0.6, dither: 0.0 };

/// The log the model explains exactly: `u − tau` is the model's torque (sign(0) = 0 where the
/// joint stands) plus white noise on both torques; q is read by a 14-bit encoder.
fn log(seed: u64, make: Make) -> (JointLog, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (t, q, qd, qdd) = moves(&mut rng, 60.0, RATE, make.dwell_min);
    let (b, c, a, phi, j, c0) = (6.2, 5.7, 25.3, 1.306, 1.16, 0.63);
    let mut u = Vec::with_capacity(t.len());
    let mut tau = Vec::with_capacity(t.len());
    for i in 0..t.len() {
        let sign = if qd[i] > 0.0 {
            1.0
        } else if qd[i] < 0.0 {
            -1.0
        } else {
            0.0
        };
        // an external load on the measured `tau`, slow, as a payload in contact
        let load = 0.4 * (0.6 * t[i]).sin() + 0.3 * (1.7 * t[i] + 1.0).sin();
        let model = j * qdd[i] + b * qd[i] + c * sign + a * (q[i] + phi).sin() + c0;
        let tau_meas = load + 0.05 * gauss(&mut rng);
        u.push(model + load + 0.03 * gauss(&mut rng));
        tau.push(tau_meas);
    }
    let q_log: Vec<f64> = q.iter().map(|x| ((x + make.dither * gauss(&mut rng)) / STEP).round() * STEP).collect();
    (JointLog { t, q: q_log, u: Some(u), tau: Some(tau), ..JointLog::default() }, qd)
}

#[test]
fn a_wrongly_signed_estimate_on_a_clean_staircase_is_a_sign_the_data_do_not_give() {
    let (l, qd_true) = log(7, LONG_DWELLS);
    let p = prep::prepare(&l).unwrap();
    let (mut wrong, mut as_known) = (0, 0);
    for (i, &truth) in qd_true.iter().enumerate() {
        let est = p.qd()[i];
        // an estimate the other way from the motion, by more than a count over a second
        if !p.rest[i] && p.direction[i] == 0 && est * truth < 0.0 && est.abs() > STEP {
            wrong += 1;
            // ... that the preparation hands on as a sign it knows (clear of 3σ, not marked)
            if !p.sign_unknown[i] && est.abs() > 3.0 * p.qd_err[i] {
                as_known += 1;
            }
        }
    }
    println!("{wrong} samples estimated against the motion, {as_known} of them handed on as a known sign");
    // the log does have them (else the test shows nothing) ...
    assert!(wrong > 0, "no wrongly signed estimate: the log does not exercise the near stop");
    // ... and none is a sign the data give
    assert_eq!(as_known, 0);
}

fn all_none(make: Make, seeds: std::ops::Range<u64>) {
    let m = ModelFile::parse(MODEL, "staircase").unwrap();
    let (mut named, mut above) = (Vec::new(), Vec::new());
    for seed in seeds {
        let (l, _) = log(seed, make);
        let d = diagnose(&l, &m, &Options::default()).unwrap();
        let r = &d.report;
        println!(
            "seed {seed}: verdict {}, held-out RMSE {:.4} against floor {:.4} (all {:.4})",
            r.verdict.effect, r.gap.holdout_rmse, r.gap.noise_floor, r.gap.rmse
        );
        if r.verdict.effect != "none" {
            named.push((seed, r.verdict.effect.clone()));
        }
        // and not by the luck of the split: every sample scored is at the floor, held out or
        // not (a wrong sign on a few training samples would not show in the held-out figure)
        if r.gap.rmse > 1.1 * r.gap.noise_floor {
            above.push((seed, r.gap.rmse / r.gap.noise_floor));
        }
    }
    assert!(named.is_empty(), "exact-model logs named: {named:?}");
    assert!(above.is_empty(), "exact-model logs whose scored samples stand above the floor: {above:?}");
}

#[test]
fn an_exact_pure_sign_model_on_a_clean_staircase_is_none() {
    all_none(LONG_DWELLS, 7..13);
}

/// Dwells of 0.15–0.55 s, shorter than the rest detector's run (twice the derivative window),
/// on a dithered encoder (noise of a quarter count before it reads): the estimate next to a
/// dwell carries the move's start into the still joint at three or more times the error the
/// noise formula gives it, and a log that starts as a move starts or ends in a dwell gets an
/// extrapolated q̇ of either sign at its ends. Before the estimator's step response bounded the
/// error and q had to confirm the sign at the ends, 9 of 30 such logs were `unexplained` (4 of
/// seeds 100–111), and 3 of 30 on a clean staircase.
#[test]
fn an_exact_pure_sign_model_with_short_dwells_on_a_dithered_encoder_is_none() {
    all_none(Make { dwell_min: 0.15, dither: 1.0e-4 }, 100..112);
}
