//! Trajectory mode simulates the model file's gravity table (one axis, the joint's own angle,
//! added to the weight as the joint adds it). Before, the table was silently left out of the
//! simulation: a model that carried its padding as a table (what `--emit-model` writes for one)
//! was compared with the log as if it had none.
//!
//! The log is the elastic-joint paper's joint released from rest with an extra torque of the
//! angle (a biweight bump, this test's own shape, through 16 points joined by straight lines: the
//! torque the table states, so the table is the exact model), integrated here (RK4, 20 kHz),
//! sampled at 200 Hz through a 12-bit encoder.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use joint_analysis::diagnose::{diagnose, Options};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

const K: f64 = 7.3035;
const B: f64 = 0.0416;
const J: f64 = 0.0085;
const STEP: f64 = std::f64::consts::TAU / 4096.0;

/// The extra torque: a biweight bump of 0.4 N·m over 0.1 ± 0.2 rad.
fn bump(q: f64) -> f64 {
    let z = (q - 0.1) / 0.2;
    if z.abs() < 1.0 {
        0.4 * (1.0 - z * z).powi(2)
    } else {
        0.0
    }
}

/// The table's 16 points over the bump's support.
fn points() -> (Vec<f64>, Vec<f64>) {
    let grid: Vec<f64> = (0..16).map(|i| -0.1 + 0.4 * i as f64 / 15.0).collect();
    let torque = grid.iter().map(|&q| bump(q)).collect();
    (grid, torque)
}

/// The points joined by straight lines, the end values beyond them.
fn stated(q: f64) -> f64 {
    let (g, t) = points();
    if q <= g[0] {
        return t[0];
    }
    for i in 0..15 {
        if q <= g[i + 1] {
            return t[i] + (q - g[i]) / (g[i + 1] - g[i]) * (t[i + 1] - t[i]);
        }
    }
    t[15]
}

fn release(q0: f64, secs: f64) -> JointLog {
    let acc = |q: f64, v: f64| -(B * v + K * q + stated(q)) / J;
    let (rate, sub) = (200.0, 100);
    let h = 1.0 / (rate * sub as f64);
    let (mut q, mut v) = (q0, 0.0);
    let (mut t, mut qs) = (Vec::new(), Vec::new());
    for i in 0..(secs * rate) as usize {
        t.push(i as f64 / rate);
        qs.push((q / STEP).round() * STEP);
        for _ in 0..sub {
            let (k1q, k1v) = (v, acc(q, v));
            let (k2q, k2v) = (v + 0.5 * h * k1v, acc(q + 0.5 * h * k1q, v + 0.5 * h * k1v));
            let (k3q, k3v) = (v + 0.5 * h * k2v, acc(q + 0.5 * h * k2q, v + 0.5 * h * k2v));
            let (k4q, k4v) = (v + h * k3v, acc(q + h * k3q, v + h * k3v));
            q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
    }
    JointLog { t, q: qs, ..JointLog::default() }
}

fn model(table: &str) -> ModelFile {
    ModelFile::parse(&format!("[spring]\nk = {K}\nb = {B}\nq0 = 0.0\n[inertia]\nj = {J}\n{table}"), "m").unwrap()
}

/// The bump as a 16-point table over its support (its own angle, or `axis`).
fn table(axis: &str) -> String {
    let (grid, torque) = points();
    format!("[gravity_table]\naxes = [\"{axis}\"]\ngrid = [{grid:?}]\ntorque = {torque:?}\n")
}

#[test]
fn a_gravity_table_over_the_joint_angle_is_simulated() {
    let log = release(0.45, 3.0);
    let with = diagnose(&log, &model(&table("q")), &Options::default()).unwrap();
    let without = diagnose(&log, &model(""), &Options::default()).unwrap();
    let (w, wo) = (&with.report, &without.report);
    println!(
        "with the table: {} (held-out {:.5}, floor {:.5}); without: {} (held-out {:.5})",
        w.verdict.effect, w.gap.holdout_rmse, w.gap.noise_floor, wo.verdict.effect, wo.gap.holdout_rmse
    );
    assert_eq!(w.verdict.effect, "none", "{:?}", w.warnings);
    assert!(w.warnings.iter().all(|s| !s.contains("gravity table")), "{:?}", w.warnings);
    // the table's torque is what the log shows: leaving it out leaves a gap several floors high
    assert_ne!(wo.verdict.effect, "none");
    assert!(wo.gap.holdout_rmse > 3.0 * w.gap.holdout_rmse);
    // Found as padding without it, the bump is emitted as a table, and the emitted model takes
    // most of the gap (the biweight is no Gaussian: a ripple with a second harmonic takes the
    // rest in the fit, and the section holds one harmonic, the second is a comment).
    assert_eq!(wo.verdict.effect, "cable_spring");
    let emitted = ModelFile::parse(&without.emitted_model, "emitted").unwrap();
    assert!(emitted.table.is_some(), "{}", without.emitted_model);
    let again = diagnose(&log, &emitted, &Options::default()).unwrap();
    let (after, promised) = (again.report.gap.holdout_rmse, wo.verdict.holdout_rmse_after);
    println!(
        "against the emitted model: {} (held-out {after:.5}, promised {promised:.5})",
        again.report.verdict.effect
    );
    assert!(after < 0.1 * wo.gap.holdout_rmse, "{after} vs {promised}: {}", without.emitted_model);
}

#[test]
fn a_table_over_another_joint_is_left_out_and_said() {
    let mut log = release(0.45, 3.0);
    // (without the column the log is refused, naming it)
    let e = diagnose(&log, &model(&table("q_hip")), &Options::default()).map(|_| ()).unwrap_err();
    assert!(e.to_string().contains("q_hip"), "{e}");
    log.others.push(("q_hip".into(), vec![0.2; log.t.len()]));
    let d = diagnose(&log, &model(&table("q_hip")), &Options::default()).unwrap();
    assert!(
        d.report.warnings.iter().any(|s| s.contains("gravity table") && s.contains("q_hip")),
        "{:?}",
        d.report.warnings
    );
}
