//! The fix workflow on plants with one unmodelled effect each: closed-loop trials with the
//! log kept → `diagnose` (the library call `jointctl diagnose --emit-model` makes) → the emitted
//! model pushed by SDO → the same trials again. Nothing here passes the plant's true effect
//! parameters to the joint; the ceiling runs do, and are only compared against.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use host_sim::plant::PlantFile;
use joint_formats::model_file::ModelFile;
use jointctl::closed_loop::workflow::{ceiling, run_workflow};
use jointctl::closed_loop::LoopConfig;
use std::path::Path;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The trunk joint's plant with `effect_file`'s effect, the paper's model, the law at F = 0.7.
fn setup(effect_file: &str, trials: usize, seconds: f64) -> (PlantFile, ModelFile, LoopConfig) {
    let plant = PlantFile::read_file(&root().join(format!("examples/plants/trunk-right-{effect_file}.toml"))).unwrap();
    let model = ModelFile::read_file(&root().join("examples/models/trunk-right.toml")).unwrap();
    let cfg = LoopConfig { fraction: Some(0.7), trials, seconds, seed: 1, ..LoopConfig::default() };
    (plant, model, cfg)
}

fn case(effect_file: &str) -> (jointctl::closed_loop::workflow::Outcome, jointctl::closed_loop::workflow::Figures) {
    let (plant, model, cfg) = setup(effect_file, 4, 10.0);
    let o = run_workflow(&plant, &model, &cfg, (effect_file, "trunk-right")).unwrap();
    let c = ceiling(&plant, &model, &cfg, (effect_file, "trunk-right")).unwrap().unwrap();
    (o, c)
}

/// The ≤ 60 % target holds for the model error (d − C_c: the tracking error relative to what
/// the law targets at this fraction, and the whole tracking error at F = 1) on the cable
/// spring; the paper's tracking RMSE moves far less at F = 0.7 because the 30 % left
/// uncompensated by design dominates it (see docs/closed-loop.md for the figures).
///
/// Stribeck misses it narrowly (≈ 0.62; the true parameters reach ≈ 0.57): the dip lives within
/// 0.05 rad/s of a reversal, where the diagnosis leaves out the samples whose direction the log
/// cannot tell, so the refit sees the curve's tail and puts its level at ≈ 1.1 N·m (truth 1.5).
/// A sharper velocity estimate near reversals fitted 1.4 but over-claimed on model-exact logs,
/// and a log that cannot show the dip should not claim it: the bound here is the honest figure.
#[test]
fn stribeck_and_cable_spring_fixed() {
    for (file, effect, target, of_ceiling) in
        [("stribeck", "stribeck", 0.65, 1.12), ("cable-spring", "cable_spring", 0.6, 1.05)]
    {
        let (o, c) = case(file);
        eprintln!("{file}: emitted\n{}\nceiling {c:?}", o.emitted_model);
        assert!(o.selected.iter().any(|e| e == effect), "{file}: diagnose selected {:?}", o.selected);
        assert!(o.pushed_effects.iter().any(|e| e == effect), "{file}: pushed {:?}", o.pushed_effects);
        assert!(o.before.stable && o.after.stable);
        assert!(o.model_error_ratio <= target, "{file}: model error {:?} → {:?}", o.before, o.after);
        assert!(o.after.tracking_rmse_mean < o.before.tracking_rmse_mean, "{file}: {:?} → {:?}", o.before, o.after);
        // the diagnosis came close to the true-parameter ceiling
        assert!(
            o.after.model_error_rmse_mean <= of_ceiling * c.model_error_rmse_mean,
            "{file}: {:?} vs ceiling {c:?}",
            o.after
        );
    }
}

/// Position ripple: diagnose finds it and the fix reaches the ceiling, but the ripple (0.6 N·m
/// amplitude) is close to the loop's own estimation floor (≈ 0.3 N·m, the lag of the filtered
/// q̈), so the model error only falls to about two thirds: the 60 % target is NOT met here.
#[test]
fn position_ripple_found_but_short_of_60_percent() {
    let (o, c) = case("position-ripple");
    assert!(o.selected.iter().any(|e| e == "position_ripple"), "{:?}", o.selected);
    assert!(o.model_error_ratio < 0.8, "{:?} → {:?}", o.before, o.after);
    assert!(o.after.model_error_rmse_mean <= 1.05 * c.model_error_rmse_mean);
    assert!(o.after.tracking_rmse_mean <= o.before.tracking_rmse_mean);
}

/// Load-dependent friction is a term the joint runs on its load cell: the emitted model holds
/// it and is pushed, nothing is dropped, and the joint's model error falls.
#[test]
fn load_dependent_friction_is_pushed() {
    let (plant, model, cfg) = setup("load-dependent-friction", 2, 8.0);
    let o = run_workflow(&plant, &model, &cfg, ("ldf", "trunk-right")).unwrap();
    eprintln!("emitted\n{}\nbefore {:?}\nafter {:?}", o.emitted_model, o.before, o.after);
    assert!(o.emitted_model.contains("[load_dependent_friction]"), "{}", o.emitted_model);
    assert!(o.dropped_effects.is_empty() && o.pushed, "{:?}", o.dropped_effects);
    assert!(o.pushed_effects.iter().any(|e| e == "load_dependent_friction"), "{:?}", o.pushed_effects);
    assert!(o.pushed_model.explicit(joint_core::params::ParamId::LoadFrictionMu).is_some_and(|mu| mu > 0.0));
    assert!(o.before.stable && o.after.stable);
    assert!(o.model_error_ratio < 0.9, "{:?} → {:?}", o.before, o.after);
}

/// Padding that presses over part of the travel (the plant's table: a flat top with ramps, not
/// the candidate's raised cosine): diagnose finds a `cable_spring` pad, the emitted model holds
/// it as a gravity table over q (no section holds a pad), that table is pushed, and the joint's
/// model error falls.
#[test]
fn padding_is_pushed_as_a_table() {
    // (no ceiling: the plant's padding is a table, not an effect section with true parameters)
    let (plant, model, cfg) = setup("padding", 4, 10.0);
    let o = run_workflow(&plant, &model, &cfg, ("padding", "trunk-right")).unwrap();
    eprintln!("emitted\n{}\nbefore {:?}\nafter {:?}", o.emitted_model, o.before, o.after);
    assert!(o.selected.iter().any(|e| e == "cable_spring"), "{:?}", o.selected);
    assert!(o.emitted_model.contains("[gravity_table]"), "{}", o.emitted_model);
    assert!(o.dropped_effects.is_empty() && o.pushed, "{:?}", o.dropped_effects);
    assert!(o.pushed_model.table.is_some());
    assert!(o.before.stable && o.after.stable);
    assert!(o.model_error_ratio < 0.6, "{:?} → {:?}", o.before, o.after);
}
