//! Over a short arc a weight is a straight line plus a constant: the refit can trade its
//! amplitude against the offset without the log noticing, and a model with hundreds of N·m on
//! the pair would push those torques as soon as the joint left the arc. `--emit-model` writes
//! a refitted weight only where the log determines it apart from the offset, and says so
//! otherwise; where the arc is long it writes the refit's weight.
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{simulate, SimConfig};
use joint_analysis::diagnose::{diagnose, Options};
use joint_core::params::ParamId;
use joint_formats::model_file::ModelFile;

const FRICTION: &str =
    "[friction]\na = 0.5\nb = 2.0\nc = 1.0\nv_band = 0.01\n[inertia]\nj = 0.4\n[offset]\nc0 = -0.3\n";

/// The file's weight is 2.5 N·m; the joint's is 4.0 (a heavier limb than the model says).
fn run(lo: f64, hi: f64, seed: u64) -> (f64, f64, Vec<String>, String) {
    let model_text = format!("{FRICTION}[weight]\namplitude = 2.5\ns = 0.802\nphi = 0.3\n");
    let plant_text = format!(
        "{FRICTION}[weight]\namplitude = 4.0\ns = 0.802\nphi = 0.3\n[sensors]\ntau_noise = 0.1\n[joint_range]\nmin = {lo}\nmax = {hi}\n"
    );
    let plant = PlantFile::parse(&plant_text, "plant").unwrap();
    let model = ModelFile::parse(&model_text, "model").unwrap();
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Hand],
        seconds: 10.0,
        seed,
        rate: Some(1000.0),
        range: Some((lo, hi)),
        ..SimConfig::default()
    };
    let (log, _) = simulate(&plant, &model.param_set().unwrap(), &cfg).unwrap();
    let d = diagnose(&log, &model, &Options::default()).unwrap();
    let emitted = ModelFile::parse(&d.emitted_model, "emitted").unwrap();
    let refit_amp = d.report.refit.get("weight").and_then(|w| w.get("amplitude")).copied().unwrap_or(f64::NAN);
    (emitted.value(ParamId::WeightAmplitude), refit_amp, d.report.warnings.clone(), d.emitted_model)
}

#[test]
fn a_weight_the_arc_does_not_determine_is_not_emitted() {
    // 0.15 rad of travel: 0.12 rad of the weight's phase
    let (emitted, refit, warnings, text) = run(0.60, 0.75, 5);
    println!("short arc: refit amplitude {refit:.3}, emitted {emitted:.3}\n{warnings:#?}");
    let said = warnings.iter().any(|w| w.contains("does not determine the weight apart from the offset"));
    assert!((refit - 2.5).abs() > 1e-6, "the refit did not move the weight ({refit}): nothing to test");
    assert!(said, "no warning: {warnings:?}");
    assert_eq!(emitted, 2.5, "the emitted model took the refit's weight {refit}:\n{text}");
    assert!(text.contains("# [weight] and [offset] are the file's"), "{text}");
}

#[test]
fn a_weight_the_arc_determines_is_emitted_refitted() {
    // 2 rad of travel: the weight's sine and cosine are told apart from the offset
    let (emitted, refit, warnings, _) = run(0.0, 2.0, 5);
    println!("long arc: refit amplitude {refit:.3}, emitted {emitted:.3}");
    assert!(!warnings.iter().any(|w| w.contains("does not determine the weight")), "{warnings:?}");
    assert!((emitted - 4.0).abs() < 0.2, "emitted amplitude {emitted} (the joint's 4.0)");
}
