//! A simulated joint with pre-sliding (Dahl) friction: the plant's own f64 state behaves as the
//! Dahl equation says, the matching model predicts its log to the noise floor, and the c·sign
//! model leaves a residual that sits right after the reversals.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

mod common;

use common::{example, rms, trunk_model};
use host_sim::plant::{Operator, Plant, PlantFile, State};
use host_sim::scenario::ScenarioKind::{Hand, Sweep};
use host_sim::sim::{self, SimConfig};
use joint_formats::model_file::ModelFile;
use joint_formats::predict;

const SIGMA: f64 = 800.0;

fn with_presliding(text: &str) -> String {
    format!("{text}\n[presliding]\nsigma = {SIGMA:?}\n")
}

#[test]
fn plant_state_follows_the_dahl_equation() {
    // A noise-free plant pushed back and forth by a stiff operator: the state never leaves
    // ±c, reaches c after a long travel, and right after a reversal changes with slope 2σ.
    let pf = PlantFile::parse(&with_presliding(&trunk_model()), "p.toml").unwrap();
    let plant = Plant::new(&pf, 1e-4, 40.0);
    assert!(plant.has_presliding());
    let c = 2.32;
    let mut x = State::at_rest(0.5);
    let mut f_at_reversal = None;
    let (mut q_rev, mut slope) = (0.0, 0.0);
    for k in 0..40_000 {
        let t = k as f64 * 1e-4;
        let q_ref = 0.5 + 0.2 * (std::f64::consts::TAU * 0.5 * t).sin();
        let op = Operator { k: 3000.0, b: 150.0, q_ref, qd_ref: 0.0 };
        let prev = x;
        x = plant.step(t, &x, 0.0, &op, &[]);
        assert!(x.dahl.abs() <= c + 1e-12, "F = {} at t = {t}", x.dahl);
        // First reversal from forward sliding (F = +c): note where it happened, then the slope
        // over the first 0.2 mrad back.
        if f_at_reversal.is_none() && t > 0.2 && prev.qd > 0.0 && x.qd <= 0.0 {
            f_at_reversal = Some(x.dahl);
            q_rev = x.q;
        }
        if let Some(f0) = f_at_reversal {
            if slope == 0.0 && q_rev - x.q > 2e-4 {
                slope = (f0 - x.dahl) / (q_rev - x.q);
            }
        }
    }
    let f0 = f_at_reversal.expect("the joint reversed");
    assert!((f0 - c).abs() < 1e-4, "sliding forward F = {f0}");
    // The exact solution's mean slope over 0.2 mrad from F = c: 2c·(1 − e^(−σ·2e-4/c))/2e-4.
    let want = 2.0 * c * (1.0 - (-SIGMA * 2e-4 / c).exp()) / 2e-4;
    assert!((slope - want).abs() < 0.03 * want, "slope {slope} vs {want}");
}

/// Reversals of the logged angle (turning points of q, with a hysteresis above the encoder
/// quantum) and, per sample, the angle travelled since the last one.
fn travel_since_reversal(q: &[f64]) -> Vec<f64> {
    let h = 5e-5;
    let (mut dir, mut ext, mut rev) = (0.0, q[0], q[0]);
    q.iter()
        .map(|&x| {
            if dir > 0.0 {
                if x > ext {
                    ext = x;
                } else if x < ext - h {
                    (dir, rev, ext) = (-1.0, ext, x);
                }
            } else if dir < 0.0 {
                if x < ext {
                    ext = x;
                } else if x > ext + h {
                    (dir, rev, ext) = (1.0, ext, x);
                }
            } else if (x - rev).abs() > h {
                (dir, ext) = (if x > rev { 1.0 } else { -1.0 }, x);
            }
            (x - rev).abs()
        })
        .collect()
}

#[test]
fn matching_model_reaches_the_noise_floor_and_the_sign_model_misses_after_reversals() {
    let plant = PlantFile::parse(&example("examples/plants/trunk-right-presliding.toml"), "p.toml").unwrap();
    let dahl_model = ModelFile::parse(&with_presliding(&trunk_model()), "dahl.toml").unwrap();
    let sign_model = ModelFile::parse(&trunk_model(), "sign.toml").unwrap();
    let (pd, ps) = (dahl_model.param_set().unwrap(), sign_model.param_set().unwrap());
    let cfg = SimConfig { scenarios: vec![Sweep, Hand], seconds: 20.0, seed: 11, ..SimConfig::default() };
    let (log, _) = sim::simulate(&plant, &pd, &cfg).unwrap();
    let rd = predict::residual(&log, &pd, &[]).unwrap();
    let rs = predict::residual(&log, &ps, &[]).unwrap();
    let floor = sim::noise_floor(&log, &pd, &[], &plant.sensors, 11).unwrap();
    let travel = travel_since_reversal(&log.q);
    let qd = log.qd.as_ref().unwrap();
    // Three places: within three pre-sliding distances (c/σ = 2.9 mrad) of a reversal; at
    // standstill elsewhere (|q̇| < 2·v_band); sliding.
    let place = |i: usize| {
        if travel[i] < 3.0 * 2.32 / SIGMA {
            0
        } else if qd[i].abs() < 0.02 {
            1
        } else {
            2
        }
    };
    let excess_all: f64 = rs.iter().zip(&rd).map(|(s, d)| s * s - d * d).sum();
    let mut stats = [(0.0, 0.0, 0.0, 0.0); 3]; // (samples share, sign rms, matching rms, excess share)
    for (k, st) in stats.iter_mut().enumerate() {
        let idx: Vec<usize> = (0..log.len()).filter(|&i| place(i) == k).collect();
        let pick = |r: &[f64]| rms(&idx.iter().map(|&i| r[i]).collect::<Vec<_>>());
        let excess: f64 = idx.iter().map(|&i| rs[i] * rs[i] - rd[i] * rd[i]).sum();
        *st = (idx.len() as f64 / log.len() as f64, pick(&rs), pick(&rd), excess / excess_all);
    }
    let (d_all, s_all) = (rms(&rd), rms(&rs));
    println!(
        "Dahl joint (sigma = {SIGMA} N·m/rad, c = 2.32 N·m, sweep + hand, {} samples), noise floor {floor:.3} N·m; \
         residual RMS under the matching model {d_all:.3}, under the c·sign model {s_all:.3}",
        log.len()
    );
    for (name, (share, s, d, ex)) in
        ["within 3·c/sigma of a reversal", "standstill elsewhere", "sliding"].iter().zip(stats)
    {
        println!(
            "  {name}: {:.1} % of samples, residual RMS sign model {s:.3} / matching {d:.3} N·m, \
             {:.1} % of the sign model's excess squared residual",
            100.0 * share,
            100.0 * ex
        );
    }
    let [near, still, sliding] = stats;
    assert!(d_all / floor > 0.85 && d_all / floor < 1.15, "matching model {d_all} vs floor {floor}");
    assert!(
        near.2 < 1.2 * floor && still.2 < 1.2 * floor,
        "matching model near reversals / at rest: {near:?} {still:?}"
    );
    assert!(s_all > 2.0 * floor, "the sign model must miss: {s_all} vs floor {floor}");
    assert!(near.1 > 5.0 * floor && sliding.1 < 1.1 * floor, "near {near:?}, sliding {sliding:?}, floor {floor}");
    assert!(near.0 < 0.2 && near.3 > 0.7, "the sign model's miss sits after reversals: {near:?}");
}
