//! The user's fix-the-gap workflow, end to end (issue 7): run closed-loop trials on a joint
//! with an unmodelled effect and log them → `diagnose --emit-model` on that log → push the
//! emitted model (every trial pushes its model by SDO) → run the same trials again.
//!
//! The diagnosis sees only the log and the model, never the plant: what is pushed after the
//! fix is exactly the text `jointctl diagnose --emit-model` writes. When that text holds an
//! effect section the firmware has no term for (`load_dependent_friction`, `thermal_drift`,
//! `backlash`, `delay`) the joint's parameter table would refuse the file, and the refitted
//! model terms cannot be pushed without it either: they were fitted *together with* that
//! effect (in a closed-loop log `μ·|u|·sgn(q̇)` is nearly collinear with the friction terms,
//! since u ≈ F·d, and a refit beside it guts them). So nothing is pushed, the old model keeps
//! running, and the result names the effect. Separately, and labelled
//! as such, [`ceiling`] builds the model with the plant's *true* effect parameters: the best a
//! perfect diagnosis could reach.

use serde::Serialize;

use super::{run, LoopConfig, LoopError, LoopReport, Setup};
use host_sim::plant::PlantFile;
use joint_analysis::diagnose::{self, Options};
use joint_core::params::ParamId;
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

/// Effect sections present in a plant.
pub fn plant_effects(p: &PlantFile) -> Vec<String> {
    let e = &p.effects;
    let mut v = Vec::new();
    for (effect, on) in [
        (Effect::Stribeck, e.stribeck.is_some()),
        (Effect::AsymmetricFriction, e.asymmetric_friction.is_some()),
        (Effect::LoadDependentFriction, e.load_dependent_friction.is_some()),
        (Effect::ThermalDrift, e.thermal_drift.is_some()),
        (Effect::PositionRipple, e.position_ripple.is_some()),
        (Effect::CableSpring, e.cable_spring.is_some()),
        (Effect::Backlash, e.backlash.is_some()),
        (Effect::Delay, e.delay.is_some()),
        (Effect::DryFriction, e.dry_friction.is_some()),
    ] {
        if on {
            v.push(effect.name().to_string());
        }
    }
    v
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
    let e = &plant.effects;
    let mut m = model.clone();
    let mut any = false;
    let mut set = |id: ParamId, v: f64| {
        m.set(id, v, None);
        any = true;
    };
    if let Some(s) = &e.stribeck {
        set(ParamId::StribeckLevel, s.level);
        set(ParamId::StribeckSpeed, s.speed);
    }
    if let Some(s) = &e.asymmetric_friction {
        set(ParamId::AsymmetricDelta, s.delta);
    }
    if let Some(s) = &e.position_ripple {
        set(ParamId::RippleAmplitude, s.amplitude);
        set(ParamId::RipplePeriod, s.period);
        set(ParamId::RipplePhase, s.phase);
        set(ParamId::RippleAmplitude2, s.amplitude_2);
        set(ParamId::RipplePhase2, s.phase_2);
    }
    if let Some(s) = &e.cable_spring {
        set(ParamId::CableK, s.k);
        set(ParamId::CableEngage, s.engage);
        set(ParamId::CableWidth, s.width);
    }
    if let Some(s) = &e.dry_friction {
        set(ParamId::DryFrictionC, s.c);
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
