//! The user's fix-the-gap workflow, end to end (issue 7): run closed-loop trials on a joint
//! with an unmodelled effect and log them → `diagnose --emit-model` on that log → push the
//! emitted model (every trial pushes its model by SDO) → run the same trials again.
//!
//! The diagnosis sees only the log and the model, never the plant: what is pushed after the
//! fix is exactly the text `jointctl diagnose --emit-model` writes. When that text holds an
//! effect section the firmware has no term for ([`not_compensable`]: the vocabulary's terms
//! whose section the core's parameter table lacks) the joint's parameter table would refuse the
//! file, and the refitted model terms cannot be pushed without it either: they were fitted
//! *together with* that effect (and may have given it what they lost). So nothing is pushed,
//! the old model keeps running, and the result names the effect. Separately, and labelled
//! as such, [`ceiling`] builds the model with the plant's *true* effect parameters: the best a
//! perfect diagnosis could reach.

use serde::Serialize;

use super::{run, LoopConfig, LoopError, LoopReport, Setup};
use host_sim::plant::PlantFile;
use joint_analysis::diagnose::{self, Options};
use joint_core::params;
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use joint_formats::vocab::Effect;

/// Effect sections the firmware core compensates by feed-forward (the vocabulary's terms whose
/// section the core's parameter table has), with their section names.
pub fn compensable() -> impl Iterator<Item = Effect> {
    Effect::terms().filter(|e| e.compensable())
}

/// Effect terms it cannot, and why (also in docs/closed-loop.md).
pub fn not_compensable() -> impl Iterator<Item = (Effect, &'static str)> {
    Effect::terms().filter_map(|e| e.why_not_compensable().map(|w| (e, w)))
}

/// Figures of one set of trials.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Figures {
    pub tracking_rmse_mean: f64,
    pub tracking_rmse_sd: f64,
    pub stable: bool,
    pub model_error_rmse_mean: f64,
    pub model_error_rmse_sd: f64,
}

impl From<&LoopReport> for Figures {
    fn from(r: &LoopReport) -> Self {
        Figures {
            tracking_rmse_mean: r.tracking_rmse_mean,
            tracking_rmse_sd: r.tracking_rmse_sd,
            stable: r.stable,
            model_error_rmse_mean: r.model_error_rmse_mean,
            model_error_rmse_sd: r.model_error_rmse_sd,
        }
    }
}

/// The result of the workflow on one plant.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// effect sections the plant has (the truth)
    pub plant_effects: Vec<String>,
    pub before: Figures,
    /// diagnose's verdict and the effects its forward selection kept
    pub verdict: String,
    pub selected: Vec<String>,
    /// effect sections of the emitted model that were pushed
    pub pushed_effects: Vec<String>,
    /// effect sections of the emitted model the firmware cannot take
    pub dropped_effects: Vec<String>,
    /// the emitted model was pushed (false: it needs a term the firmware lacks, the old model
    /// stayed)
    pub pushed: bool,
    pub after: Figures,
    /// after / before (tracking RMSE means)
    pub ratio: f64,
    /// after / before (model-error RMSE means: the tracking error at F = 1)
    pub model_error_ratio: f64,
    /// the emitted model's text, as diagnose wrote it
    #[serde(skip)]
    pub emitted_model: String,
    /// the model that was pushed after the fix
    #[serde(skip)]
    pub pushed_model: ModelFile,
    #[serde(skip)]
    pub log: JointLog,
    #[serde(skip)]
    pub diagnosis_json: String,
}

/// Effect sections present in a plant, in the vocabulary's order (the plant's own list:
/// `host_sim::effects::Effects::section` names every entry of the vocabulary).
pub fn plant_effects(p: &PlantFile) -> Vec<String> {
    p.effects.present().map(|e| e.name().to_string()).collect()
}

/// Parses an emitted model: the effect sections the firmware cannot take are removed first
/// (returned by name, third), everything else must parse as a model file; the compensable
/// effect sections it holds come second.
pub fn pushable_model(text: &str, file: &str) -> Result<(ModelFile, Vec<String>, Vec<String>), LoopError> {
    let mut table: toml::Table =
        toml::from_str(text).map_err(|e| LoopError::Config(format!("{file}: the emitted model is not TOML: {e}")))?;
    let mut dropped = Vec::new();
    for (effect, _) in not_compensable() {
        let Some(section) = effect.section() else { continue };
        if table.remove(section).is_some() {
            dropped.push(effect.name().to_string());
        }
    }
    let pushed: Vec<String> = compensable()
        .filter(|e| e.section().is_some_and(|s| table.contains_key(s)))
        .map(|e| e.name().to_string())
        .collect();
    let clean = toml::to_string(&table).map_err(|e| LoopError::Config(format!("{file}: {e}")))?;
    let mf = ModelFile::parse(&clean, file)?;
    Ok((mf, pushed, dropped))
}

/// Runs the workflow (see the module documentation). `cfg.keep_log` is forced on for the
/// "before" run, whose log is what diagnose sees.
pub fn run_workflow(
    plant: &PlantFile,
    model: &ModelFile,
    cfg: &LoopConfig,
    names: (&str, &str),
) -> Result<Outcome, LoopError> {
    let c_before = LoopConfig { keep_log: true, ..cfg.clone() };
    let before = run(&Setup::new(plant, model, &c_before, names.0, names.1)?, &c_before, &mut |_, _| {})?;
    let log = before.log.clone().ok_or_else(|| LoopError::Config("the before run kept no log".into()))?;
    let d = diagnose::diagnose(&log, model, &Options::default())
        .map_err(|e| LoopError::Config(format!("diagnose: {e}")))?;
    let (emitted, pushed, dropped) = pushable_model(&d.emitted_model, "emitted model")?;
    let push_it = dropped.is_empty();
    let fixed = if push_it { emitted } else { model.clone() };
    let c_after = LoopConfig { keep_log: false, ..cfg.clone() };
    let after = run(&Setup::new(plant, &fixed, &c_after, names.0, "emitted model")?, &c_after, &mut |_, _| {})?;
    let pushed = if push_it { pushed } else { Vec::new() };
    let ratio = after.tracking_rmse_mean / before.tracking_rmse_mean;
    Ok(Outcome {
        plant_effects: plant_effects(plant),
        before: Figures::from(&before),
        verdict: d.report.verdict.effect.clone(),
        selected: d.report.verdict.effects.clone(),
        pushed_effects: pushed,
        dropped_effects: dropped,
        pushed: push_it,
        after: Figures::from(&after),
        ratio,
        model_error_ratio: after.model_error_rmse_mean / before.model_error_rmse_mean,
        emitted_model: d.emitted_model.clone(),
        pushed_model: fixed,
        log,
        diagnosis_json: serde_json::to_string_pretty(&d.report).unwrap_or_default(),
    })
}

/// The model with the plant's true parameters for its compensable effects (labelled a ceiling
/// wherever it is reported: no diagnosis was involved). `None` when the plant has none.
pub fn true_effect_model(plant: &PlantFile, model: &ModelFile) -> Option<ModelFile> {
    let mut m = model.clone();
    let mut any = false;
    // Each compensable term's section in the plant, key by key into the parameter of the same
    // place: the plant's effect sections use the model's keys (a test in host-sim checks them).
    for e in compensable() {
        let (Some(section), Some(values)) = (e.section(), plant.effects.section(e)) else { continue };
        for d in params::section_params(section) {
            let v = values.get(d.key).and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)));
            if let Some(v) = v {
                m.set(d.id, v, None);
                any = true;
            }
        }
    }
    any.then_some(m)
}

/// Trials with the true-parameter model ([`true_effect_model`]): the ceiling of the fix.
pub fn ceiling(
    plant: &PlantFile,
    model: &ModelFile,
    cfg: &LoopConfig,
    names: (&str, &str),
) -> Result<Option<Figures>, LoopError> {
    let Some(m) = true_effect_model(plant, model) else { return Ok(None) };
    let c = LoopConfig { keep_log: false, ..cfg.clone() };
    let r = run(&Setup::new(plant, &m, &c, names.0, "true effect parameters")?, &c, &mut |_, _| {})?;
    Ok(Some(Figures::from(&r)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use joint_core::params::ParamId;

    /// The truth the workflow reports and the ceiling's model follow from the plant's sections:
    /// every effect the plant has is named, every compensable one's values (defaults included)
    /// land in the model, and the others do not.
    #[test]
    fn the_true_model_takes_every_compensable_section_of_the_plant() {
        let text = "[inertia]\nj = 1.0\n[friction]\nc = 1.0\n[stribeck]\nlevel = 0.7\nspeed = 0.04\n\
            [asymmetric_friction]\ndelta = 0.2\n[position_ripple]\namplitude = 0.3\nperiod = 0.1\nphase = 0.5\n\
            [cable_spring]\nk = 6.0\nengage = 1.2\n[dry_friction]\nc = 0.25\n[backlash]\nwidth = 0.01\n";
        let plant = PlantFile::parse(text, "plant.toml").unwrap();
        let model = ModelFile::parse("[inertia]\nj = 1.0\n[friction]\nc = 1.0\n", "model.toml").unwrap();
        let m = true_effect_model(&plant, &model).unwrap();
        assert_eq!(
            plant_effects(&plant),
            ["stribeck", "asymmetric_friction", "position_ripple", "cable_spring", "backlash", "dry_friction"]
        );
        assert_eq!(m.value(ParamId::StribeckLevel), 0.7);
        assert_eq!(m.value(ParamId::StribeckSpeed), 0.04);
        assert_eq!(m.value(ParamId::AsymmetricDelta), 0.2);
        assert_eq!(m.value(ParamId::RipplePhase), 0.5);
        assert_eq!(m.value(ParamId::RippleAmplitude2), 0.0);
        assert_eq!(m.value(ParamId::CableWidth), 0.01, "the plant's default width");
        assert_eq!(m.value(ParamId::DryFrictionC), 0.25);
        for e in compensable() {
            let Some(values) = plant.effects.section(e) else { continue };
            for (k, v) in &values {
                let d = params::param_at(e.section().unwrap(), k).unwrap();
                assert_eq!(m.explicit(d.id), v.as_float(), "{e}.{k}");
            }
        }
        let plain = PlantFile::parse("[inertia]\nj = 1.0\n[backlash]\nwidth = 0.01\n", "plant.toml").unwrap();
        assert!(true_effect_model(&plain, &model).is_none(), "backlash is no term the joint runs");
    }

    #[test]
    fn non_compensable_sections_are_named_and_compensable_ones_kept() {
        let text =
            "name = \"x\"\n[friction]\nc = 1.0\n[stribeck]\nlevel = 1.0\nspeed = 0.05\n[backlash]\nwidth = 0.01\n";
        let (m, pushed, dropped) = pushable_model(text, "t.toml").unwrap();
        assert_eq!(pushed, vec!["stribeck".to_string()]);
        assert_eq!(dropped, vec!["backlash".to_string()]);
        assert_eq!(m.value(ParamId::StribeckLevel), 1.0);
        assert_eq!(m.value(ParamId::FrictionC), 1.0);
    }

    #[test]
    fn an_unknown_key_is_still_an_error() {
        let e = pushable_model("[friction]\nz = 1.0\n", "t.toml").unwrap_err().to_string();
        assert!(e.contains('z'), "{e}");
    }
}
