//! Errors in variables: white noise on a logged q̈ shrinks a least-squares inertia by
//! `var(q̈)/(var(q̈) + σ²)`, and the shrunk value predicts the same noisy q̈ a little better. On a
//! long log of an exact model that small, consistent gain used to pass for `parameters`. The
//! diagnosis now estimates σ² from the q̈ column and removes it from the fits' normal equations.
#![allow(clippy::unwrap_used)]

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{simulate, SimConfig};
use joint_analysis::diagnose::{candidates::white_noise_var, diagnose, Options};
use joint_formats::model_file::ModelFile;

const MODEL: &str = "[friction]\na = 0.5\nb = 2.0\nc = 1.0\nv_band = 0.01\n[weight]\namplitude = 2.5\ns = 0.802\nphi = 0.0\n[inertia]\nj = 0.4\n[offset]\nc0 = -0.3\n";
const QDD_NOISE: f64 = 0.8;

fn log(seconds: f64) -> joint_formats::log::JointLog {
    let plant = PlantFile::parse(
        &format!("{MODEL}[sensors]\nq_noise = 0.0001\nqd_noise = 0.002\nqdd_noise = {QDD_NOISE}\ntau_noise = 0.08\n[joint_range]\nmin = 0.0\nmax = 2.0\n"),
        "eiv-plant",
    )
    .unwrap();
    let model = ModelFile::parse(MODEL, "eiv-model").unwrap();
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Poses, ScenarioKind::Hand],
        seconds: seconds / 3.0,
        rate: Some(1000.0),
        range: Some((0.0, 2.0)),
        ..SimConfig::default()
    };
    simulate(&plant, &model.param_set().unwrap(), &cfg).unwrap().0
}

#[test]
fn qdd_noise_is_estimated_from_the_column() {
    let l = log(30.0);
    let v = white_noise_var(l.qdd.as_deref().unwrap());
    let ratio = v / (QDD_NOISE * QDD_NOISE);
    println!("estimated q̈ noise variance {v:.4} against {:.4} (ratio {ratio:.3})", QDD_NOISE * QDD_NOISE);
    assert!((0.85..1.15).contains(&ratio), "ratio {ratio}");
}

#[test]
fn an_exact_model_on_a_long_noisy_log_is_not_a_parameter_change() {
    let l = log(90.0);
    let m = ModelFile::parse(MODEL, "eiv-model").unwrap();
    let d = diagnose(&l, &m, &Options::default()).unwrap();
    let r = &d.report;
    let refit = r.effects.iter().find(|e| e.effect == "parameters").unwrap();
    println!(
        "verdict {} ; refit {:?} (shrink {:.2} %, p {:.2e})",
        r.verdict.effect,
        refit.params,
        100.0 * refit.shrink,
        refit.p_value
    );
    assert_eq!(r.verdict.effect, "none", "{:?}", r.verdict);
    // The preparation stage measured the logged q̈'s noise and, that column being the noisier,
    // took q̈ from q (or the logged q̇) instead; the report says both (optional `prep` field), and
    // the noise it corrected the fits for is the q̈ actually used (`gap.qdd_noise_sd`).
    let prep = r.prep.as_ref().unwrap();
    let logged = prep.qdd.logged_noise_sd.unwrap();
    assert!((logged / QDD_NOISE - 1.0).abs() < 0.1, "logged q̈ noise sd {logged}");
    assert_ne!(prep.qdd.source, "logged");
    let sd = r.gap.qdd_noise_sd.unwrap();
    assert!(sd < 0.1 * QDD_NOISE && (sd - prep.qdd.noise_sd).abs() < 0.5 * prep.qdd.noise_sd, "q̈ noise sd {sd}");
    // The refitted inertia is not pulled towards zero by the noise (uncorrected: ≈ 5 % low here).
    if let Some(j) = refit.params.get("inertia.j").or_else(|| refit.params.get("j")) {
        assert!((j - 0.4).abs() < 0.01, "refit inertia {j}");
    }
}
