//! Golden values worked out by hand from the trunk paper's Table 1 (in degrees, as the paper
//! gives them) and from the elastic-joint paper, compared with the core evaluating the same
//! model from SI parameters. This checks the formulas and the unit conversion at once.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;
use common::*;
use joint_core::control::{disturbance, Controller, Input, Mode};
use joint_core::params::{check, ParamId, RawParams};

fn close(got: f32, want: f64, tol: f64, what: &str) {
    assert!(((got as f64) - want).abs() <= tol, "{what}: got {got}, want {want} (±{tol})");
}

// Each row: (β deg, β̇ deg/s, β̈ rad/s², friction, weight, C_c), worked out as
// friction = a·β̇|β̇| + b·β̇ + c·sign(β̇) with β̇ in deg/s, weight = C_w0·sin(s·β + φ) with β in deg,
// C_c = I_a·β̈ + friction + weight + C_0.
// Right joint, e.g. row 1: 5.77e-4·30·30 + 0.156·30 + 2.32 = 0.5193 + 4.68 + 2.32 = 7.5193;
// 2.79·sin(0.014·45 − 0.027) = 2.79·sin(0.603) = 1.582253; 2.37·2 + 7.5193 + 1.582253 − 0.59.
const RIGHT_ROWS: [(f64, f64, f64, f64, f64, f64); 4] = [
    (45.0, 30.0, 2.0, 7.519300, 1.582253, 13.251553),
    (0.0, -90.0, -5.0, -21.033700, -0.075321, -33.549021),
    (116.5, 5.0, 0.0, 3.114425, 2.788462, 5.312887),
    (80.0, -60.0, 1.5, -13.757200, 2.477549, -8.314651),
];
const LEFT_ROWS: [(f64, f64, f64, f64, f64, f64); 4] = [
    (45.0, 30.0, 2.0, 8.446800, -1.501913, 13.564887),
    (0.0, -90.0, -5.0, -22.981200, -0.086989, -38.918189),
    (116.5, 5.0, 0.0, 3.776300, -2.589333, 1.386967),
    (80.0, -60.0, 1.5, -15.127200, -2.276402, -12.388602),
];

fn check_rows(t: &Table1, rows: &[(f64, f64, f64, f64, f64, f64)]) {
    let p = set_from(t);
    for &(qdeg, vdeg, acc, fric, w, cc) in rows {
        let q = (qdeg * DEG) as f32;
        let qd = (vdeg * DEG) as f32;
        let terms = p.terms();
        close(terms.friction.torque(qd), fric, 2e-4 * fric.abs().max(1.0), "friction");
        close(terms.weight.torque(q), w, 2e-5 * 3.0, "weight");
        close(disturbance(&p, q, qd, acc as f32, &[0.0; 3], 0.0), cc, 3e-4 * cc.abs().max(1.0), "C_c");
    }
}

#[test]
fn trunk_right_joint_table1() {
    check_rows(&RIGHT, &RIGHT_ROWS);
}

#[test]
fn trunk_left_joint_table1() {
    check_rows(&LEFT, &LEFT_ROWS);
}

#[test]
fn spec_si_values_match_the_conversion() {
    // The spec's example TOML gives a = 1.894, b = 8.938, s = 0.802 for the right joint.
    let p = set_from(&RIGHT);
    close(p.get(ParamId::FrictionA), 1.894, 5e-4, "a");
    close(p.get(ParamId::FrictionB), 8.938, 5e-4, "b");
    close(p.get(ParamId::WeightS), 0.802, 5e-4, "s");
}

#[test]
fn compensation_law_eq8() {
    // C_m = (K·β + 0.7·C_c)/(N − 1) at the first right-joint row, K = 10 N·m/rad, N = 160:
    // K·β = 10·0.785398 = 7.853982; 0.7·13.251553 = 9.276087; sum 17.130069; /159 = 0.107736.
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::AssistK, 10.0);
    raw.set(ParamId::Fraction, 0.7);
    raw.set(ParamId::TorqueLimit, 40.0);
    raw.set(ParamId::RateLimit, 1.0e6);
    let p = check(&raw).unwrap();
    let mut c = Controller::new();
    let inp = Input { q: (45.0 * DEG) as f32, qd: (30.0 * DEG) as f32, qdd: 2.0, ..Input::default() };
    let out = c.step(&p, Mode::Assist, &inp, 1e-3);
    close(out.tau_out, 17.130069, 5e-3, "output torque");
    close(out.u_motor, 0.107736, 3e-5, "motor torque");
    assert!(!out.limited);
    // The same step with a 10 N·m limit saturates and says so.
    raw.set(ParamId::TorqueLimit, 10.0);
    let p = check(&raw).unwrap();
    let out = Controller::new().step(&p, Mode::Assist, &inp, 1e-3);
    assert_eq!(out.tau_out, 10.0);
    assert!(out.limited);
}

#[test]
fn elastic_joint_spring_damper() {
    // Elastic-joint paper Table 1: K = 7.3035 N·m/rad, B = 0.0416 N·m·s/rad, J = 0.0085 kg·m².
    // At q = 0.3 rad, q̇ = −0.5 rad/s, q̈ = 4 rad/s²: K·q + B·q̇ = 2.19105 − 0.0208 = 2.17025;
    // plus J·q̈ = 0.034 gives 2.20425.
    let mut raw = RawParams::defaults();
    raw.set(ParamId::SpringK, 7.3035);
    raw.set(ParamId::SpringB, 0.0416);
    raw.set(ParamId::InertiaJ, 0.0085);
    let p = check(&raw).unwrap();
    close(p.terms().spring.torque(0.3, -0.5), 2.17025, 1e-5, "spring");
    close(disturbance(&p, 0.3, -0.5, 4.0, &[0.0; 3], 0.0), 2.20425, 1e-5, "J·q̈ + spring");
}

#[test]
fn rate_limit_bounds_each_step() {
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::Fraction, 1.0);
    raw.set(ParamId::TorqueLimit, 40.0);
    raw.set(ParamId::RateLimit, 500.0);
    let p = check(&raw).unwrap();
    let mut c = Controller::new();
    let inp = Input { q: 1.0, qd: 1.0, qdd: 0.0, ..Input::default() };
    let mut prev = 0.0f32;
    for _ in 0..100 {
        let out = c.step(&p, Mode::Assist, &inp, 1e-3);
        assert!((out.tau_out - prev).abs() <= 0.5 + 1e-5, "step {prev} → {}", out.tau_out);
        prev = out.tau_out;
    }
    // After 100 ms it has reached the (unlimited by torque) target.
    let cc = disturbance(&p, 1.0, 1.0, 0.0, &[0.0; 3], 0.0);
    assert!((prev - cc).abs() < 1e-3, "{prev} vs {cc}");
}
