//! The sim-to-real gap (issue 6): where it lies, which effect causes it, how far it shrinks.
//!
//! `diagnose` compares a joint log with a model. Torque mode (log with `u` and `tau`) works
//! sample by sample on `d = u − tau`; trajectory mode (no torques) integrates the model and
//! compares angles ([`trajectory`]). In both, every fit reads training samples only and every
//! number called "held-out" comes from samples no fit has seen (see [`select`] for the split and
//! the test). The JSON follows spec §3 and only adds optional fields.
//!
//! Modules: [`regimes`] tags samples, [`candidates`] builds the effect terms, [`fit`] holds the
//! numerics, [`select`] scores and selects, [`resid`] the correlation evidence, [`trajectory`]
//! the simulation mode, [`report_html`] the HTML report, [`bench`] the withheld-effect bench.

// The numeric kernels index series whose lengths are fixed when `Data` is built (every column
// has the log's length, every index comes from `0..n` or from the split built on it), so the
// indexing lint would only repeat that invariant at each of a few hundred sites.
#![allow(clippy::indexing_slicing)]

pub mod candidates;
pub mod evidence;
pub mod fit;
pub mod floor;
mod par;
pub mod regimes;
pub mod report_html;
pub mod resid;
pub mod select;
pub mod shapes;
pub mod trajectory;

use joint_formats::vocab::Effect as Vocab;
use std::collections::BTreeMap;

use joint_core::params::ParamId;
use serde::Serialize;

use candidates::{base_from_model, Base, Col, Data, Effect, ThermSrc};
use joint_formats::log::{JointLog, LogMode};
use joint_formats::model_file::ModelFile;
use regimes::Regimes;
use select::{Outcome, Scored, Selection, Split};

/// Why a diagnosis could not run (the log and model parsed, but do not fit together).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DiagError {
    #[error("{0}")]
    Input(String),
}

/// Settings of one diagnosis.
#[derive(Clone, Debug)]
pub struct Options {
    /// at most this many effects reported by forward selection
    pub max_effects: usize,
    /// cross-fit torque logs up to [`CROSS_FIT_MAX`] samples and trajectory windows up to
    /// [`trajectory::CROSS_FIT_MAX`] (false: one split, as longer logs have; a third of the
    /// selection's time in torque mode, about three quarters in trajectory mode, and less power)
    pub cross_fit: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options { max_effects: 3, cross_fit: true }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct SplitInfo {
    pub method: &'static str,
    pub train: usize,
    pub holdout: usize,
    /// optional: how the blocks were laid out
    pub blocks: usize,
    pub held_blocks: Vec<usize>,
    pub guard_samples: usize,
    pub test_units: usize,
    /// optional (trajectory mode): a trailing stretch where neither the log nor the model moves,
    /// left out of the split so the held-out part is motion, not rest
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest_tail: Option<RestTail>,
    /// optional (torque mode, logs up to [`CROSS_FIT_MAX`] samples; trajectory mode, windows up
    /// to [`trajectory::CROSS_FIT_MAX`]): the scores are cross-fitted over this many folds, each
    /// holding out its own blocks, so every inner sample is held out once; `train`, `holdout`
    /// and `held_blocks` describe the first fold (the one the coefficients and `--emit-model`
    /// come from), as without cross-fitting
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cross_fitted: Option<usize>,
    /// optional (with `cross_fitted`): held-out samples the scores read, over every fold
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_scored: Option<usize>,
}

/// The trailing rest left out of a trajectory-mode analysis.
#[derive(Clone, Debug, Serialize)]
pub struct RestTail {
    /// time of the first sample left out, s
    pub from_t: f64,
    pub samples: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct Gap {
    pub rmse: f64,
    pub holdout_rmse: f64,
    pub noise_floor: f64,
    pub unit: &'static str,
    /// optional: the held-out RMSE after the selected effects is at the floor (within 5 %, or
    /// 2 % when the log's own q̈ noise is corrected for)
    pub at_noise_floor: bool,
    /// optional (torque mode with a logged `qdd`): the white noise estimated on q̈, rad/s²,
    /// whose variance the fits remove from the inertia's normal equation
    #[serde(skip_serializing_if = "Option::is_none")]
    pub qdd_noise_sd: Option<f64>,
    /// optional: the samples `rmse` and the regimes are computed on, when some are left out of
    /// fits and scores (samples whose direction of motion is unknown; with a pure Coulomb sign
    /// also the rests and their edges, where the model's friction is set-valued)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scored_samples: Option<usize>,
    /// optional (pure Coulomb sign): samples inside rests taken for a creep below the q̇
    /// resolution (left out, see [`rest_creep`])
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest_creep_samples: Option<usize>,
}

#[derive(Clone, Debug, Serialize)]
pub struct RegimeOut {
    pub name: String,
    pub family: &'static str,
    #[serde(rename = "where")]
    pub where_: String,
    pub share: f64,
    pub rmse: f64,
    pub samples: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct RegimeShrink {
    pub name: String,
    pub holdout_rmse_before: f64,
    pub holdout_rmse_after: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct EffectOut {
    pub effect: String,
    pub holdout_rmse_before: f64,
    pub holdout_rmse_after: f64,
    pub shrink: f64,
    pub significant: bool,
    pub params: BTreeMap<String, f64>,
    /// optional: what the candidate was tested against ("model" or "parameters")
    pub reference: &'static str,
    pub t_stat: f64,
    pub p_value: f64,
    /// optional: relative held-out MSE gain over the reference
    pub gain: f64,
    /// optional: set when the fitted term has the wrong sign for its physics (never selected)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub implausible: Option<&'static str>,
    pub regimes: Vec<RegimeShrink>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Verdict {
    pub effect: String,
    pub holdout_rmse_before: f64,
    pub holdout_rmse_after: f64,
    pub shrink: f64,
    /// optional: all effects forward selection kept, in order
    pub effects: Vec<String>,
    /// optional: explanations this log cannot tell apart from the verdict (held-out difference
    /// within its standard error), each with the test that would separate them
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub alternatives: Vec<Alternative>,
    /// optional (`unexplained`): the candidates that came closest, best first
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub closest: Vec<String>,
}

/// An explanation the log cannot tell apart from the verdict.
#[derive(Clone, Debug, Serialize)]
pub struct Alternative {
    pub effect: String,
    /// what log would tell them apart
    pub test: String,
}

/// What would separate effect `a` from effect `b` (either order): the pairs a log confuses most
/// have their own test; any other pair gets each effect's signature, the motion that shows it.
pub fn separating_test(a: Vocab, b: Vocab) -> String {
    use Vocab as V;
    let pair = |x: Vocab, y: Vocab| (a == x && b == y) || (a == y && b == x);
    let own = if pair(V::AsymmetricFriction, V::Parameters) {
        "a log with the joint at rest after moving each way: while it moves, a direction-dependent friction level is a constant offset"
    } else if pair(V::Stribeck, V::PreslidingHysteresis) || pair(V::Stribeck, V::DryFriction) {
        "slow constant-velocity plateaus near rest in both directions, and small reversals: the friction curve against speed and after a reversal"
    } else if pair(V::CableSpring, V::Parameters) || pair(V::CableSpring, V::PositionRipple) {
        "static poses across the whole range: a position-dependent torque shows as a curve against q"
    } else if pair(V::ThermalDrift, V::Parameters) || pair(V::ThermalDrift, V::LoadDependentFriction) {
        "a log with a logged temperature that changes, or the same motion repeated cold and warm"
    } else if pair(V::Delay, V::Parameters) {
        "motion with fast torque changes (steps, a chirp to higher frequency): a lag shows against the torque's changes"
    } else if pair(V::LoadDependentFriction, V::Parameters) {
        "the same speeds under different external loads (or with and without a payload)"
    } else if pair(V::InitialState, V::Parameters) {
        "a log whose first state is known (samples at rest before the motion, or q̇ logged from the first sample) and that runs at least one full swing: a start off bends the first swing only, a term off every one"
    } else if pair(V::DryFriction, V::Parameters) {
        "a free decay to rest, or slow moves each way: a Coulomb level takes the same amount off every swing (a straight envelope) and stops the joint off its rest angle, a viscous one the same ratio (an exponential envelope)"
    } else {
        return format!("for {a}: {}; for {b}: {}", signature(a), signature(b));
    };
    own.to_string()
}

/// The motion that shows effect `v` apart from the others (what a log must contain to pin it).
pub fn signature(v: Vocab) -> &'static str {
    use Vocab as V;
    match v {
        V::Parameters => "a log spanning the speeds, accelerations and angles the model's terms scale with",
        V::Stribeck => "constant-speed plateaus at several slow speeds each way (friction rising towards rest)",
        V::AsymmetricFriction => {
            "rests after moving each way (a direction-dependent level; while moving it is an offset)"
        }
        V::LoadDependentFriction => "the same speeds under different external loads",
        V::ThermalDrift => "a logged temperature that changes, or the same motion cold and warm",
        V::PositionRipple => "a slow constant-speed sweep across the range (a torque repeating with the angle)",
        V::CableSpring => "static poses across the whole range (a torque curve against the angle)",
        V::Backlash => "slow reversals under a steady load (no torque transmitted across the dead zone)",
        V::Delay => "fast torque changes, steps or a chirp (a lag against the torque's changes)",
        V::DryFriction => "a free decay to rest (a straight envelope, a stop off the rest angle)",
        V::PreslidingHysteresis => "small reversals of a few mrad (friction building up over the angle after each)",
        V::InitialState => "a log that starts at rest, or with its first state logged",
        V::None | V::Unexplained => "a longer log",
    }
}

/// The verdict's company: explanations the held-out data cannot tell from it (alternatives),
/// and, for `unexplained`, the candidates that came closest.
fn verdict_company(sel: &Selection, verdict: Vocab) -> (Vec<Alternative>, Vec<String>) {
    let all: Vec<&Outcome> = std::iter::once(&sel.refit).chain(&sel.candidates).collect();
    if verdict == Vocab::Unexplained {
        let mut v: Vec<&&Outcome> = all.iter().filter(|o| o.implausible.is_none() && o.gain > 0.0).collect();
        v.sort_by(|a, b| a.scored.mse().total_cmp(&b.scored.mse()));
        return (Vec::new(), v.iter().take(3).map(|o| o.name.to_string()).collect());
    }
    let chosen = match sel.chosen.first() {
        Some(c) => c,
        None if verdict == Vocab::Parameters => &sel.refit,
        None => return (Vec::new(), Vec::new()),
    };
    let alts = all
        .iter()
        .filter(|o| o.name != chosen.name && o.implausible.is_none())
        .filter(|o| {
            // it explains the gap too (beats the file's model) and the verdict does not beat it;
            // or it explains more of it than the verdict, short of the corrected level only
            // (unseen t9066/0013: a 32 ms delay of u took 20 % of the held-out MSE at p = 9e-3,
            // a pre-sliding state 17 % at 2e-3 and was named alone)
            let (_, p0, g0) = select::compare(&sel.m0, &o.scored);
            let (_, p, g) = select::compare(&o.scored, &chosen.scored);
            let not_beaten = !(p < sel.alpha_each && g >= select::MIN_GAIN);
            let explains = p0 < sel.alpha_each || p0 < select::ALPHA && o.scored.mse() < chosen.scored.mse();
            explains && g0 >= select::MIN_GAIN && not_beaten
        })
        .map(|o| Alternative { effect: o.name.to_string(), test: separating_test(chosen.name, o.name) })
        .collect();
    (alts, Vec::new())
}

#[derive(Clone, Debug, Serialize)]
pub struct Step {
    pub effect: String,
    pub params: BTreeMap<String, f64>,
    pub holdout_rmse_after: f64,
    pub shrink: f64,
    pub p_value: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Resid {
    pub input: Vec<&'static str>,
    pub autocorrelation_before: resid::Correlation,
    pub autocorrelation_after: resid::Correlation,
    pub xcorr_before: Vec<resid::Correlation>,
    pub xcorr_after: Vec<resid::Correlation>,
}

#[derive(Clone, Debug, Serialize)]
pub struct TestInfo {
    pub method: &'static str,
    pub alpha: f64,
    pub alpha_each: f64,
    pub min_gain: f64,
}

/// The diagnosis report (spec §3 plus optional fields).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub mode: &'static str,
    pub samples: usize,
    pub split: SplitInfo,
    pub gap: Gap,
    pub regimes: Vec<RegimeOut>,
    pub effects: Vec<EffectOut>,
    pub verdict: Verdict,
    pub selected: Vec<Step>,
    pub refit: BTreeMap<String, BTreeMap<String, f64>>,
    pub test: TestInfo,
    pub resid: Option<Resid>,
    pub unknown_columns: Vec<String>,
    /// optional: vocabulary effects that were not tried on this model/log, and why
    pub not_applicable: Vec<NotApplicable>,
    /// optional: the model's terms this log does not excite (no motion, one speed or direction,
    /// one angle): every refit keeps them at the file's values; with the test that would pin them
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_determined: Vec<NotDetermined>,
    /// optional: physically impossible values in the refit of the model's own terms, each
    /// naming the parameter (the log does not determine it; the verdict is read with care)
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// optional: what the shared preparation stage did to the log (stale samples, gaps,
    /// how q̇ and q̈ were obtained and how good they are)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prep: Option<crate::prep::PrepReport>,
}

/// Warnings for refit values no joint can have: negative inertia, friction that feeds energy
/// in, negative stiffness. A least-squares refit gets them when the log does not separate a
/// term from the others (q̈ noise-dominated, a saturated or chattering torque, too little
/// excitation); the numbers still lower the held-out error, so they are reported, not hidden.
pub(crate) fn refit_warnings(effects: &[EffectOut]) -> Vec<String> {
    let Some(p) = effects.iter().find(|e| e.effect == "parameters") else { return Vec::new() };
    let mut w = Vec::new();
    for (key, what) in [
        ("inertia.j", "inertia cannot be negative: the log's q̈ does not determine it (noise-dominated or too little acceleration; give a filtered `qdd` column)"),
        ("friction.a", "friction cannot feed energy in: the log does not separate friction from the other terms"),
        ("friction.b", "friction cannot feed energy in: the log does not separate friction from the other terms"),
        ("friction.c", "friction cannot feed energy in: the log does not separate friction from the other terms"),
        ("spring.k", "a negative stiffness: the log does not determine the spring"),
    ] {
        if let Some(&v) = p.params.get(key) {
            if v < 0.0 {
                w.push(format!("refit {key} = {v:.4} is negative; {what}"));
            }
        }
    }
    w
}

/// A model term the log does not determine ([`select::unexcited`]).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NotDetermined {
    /// the model's parameters (`friction.b`, `weight.amplitude`, …)
    pub params: Vec<String>,
    pub why: String,
    /// what log would pin it
    pub test: &'static str,
}

/// The model's own terms the rows of the refit do not excite, as the report lists them.
fn not_determined(d: &Data, sel: &Selection, split: &Split) -> Vec<NotDetermined> {
    use candidates::Col;
    let des = &sel.refit.scored.design;
    let idx = candidates::thin_idx(&split.train, select::FIT_ROWS);
    let g = des.gram(d, &idx);
    let flags = select::unexcited(des, d, &g);
    let p = g.p;
    let range = {
        let mut q: Vec<f64> = idx.iter().filter_map(|&i| d.q.get(i as usize).copied()).collect();
        q.sort_by(f64::total_cmp);
        let at = |f: f64| q.get(((q.len().max(1) - 1) as f64 * f) as usize).copied().unwrap_or(0.0);
        at(0.99) - at(0.01)
    };
    let mut out: Vec<NotDetermined> = Vec::new();
    for (k, col) in des.cols.iter().enumerate() {
        if !flags.get(k).copied().unwrap_or(false) {
            continue;
        }
        let zero = !(g.g.get(k * p + k).copied().unwrap_or(0.0) > 0.0);
        let Some((params, test)) = term_of(col) else { continue };
        let why = match col {
            Col::Qdd if zero => "the joint does not accelerate in this log".into(),
            Col::Qdd => {
                "q̈ stays within its noise here (no acceleration), or is a combination of the other terms".into()
            }
            Col::SinSq(_) | Col::CosSq(_) => {
                format!("q spans {range:.3} rad: the weight's sine is a constant there, the offset's")
            }
            Col::Q | Col::DeadZone { .. } => {
                format!("q spans {range:.3} rad: the spring's torque is a constant there, the offset's")
            }
            _ if zero => "the joint does not move in this log".into(),
            _ => "q̇ takes one speed or one direction here: the term is a constant, the offset's".into(),
        };
        let params: Vec<String> = params.iter().map(|s| s.to_string()).collect();
        if out.iter().any(|o| o.params == params) {
            continue;
        }
        out.push(NotDetermined { params, why, test });
    }
    out
}

/// The model's parameters a design column carries, and what log would pin them; `None` for the
/// offset and the model's own effect terms.
fn term_of(col: &candidates::Col) -> Option<(&'static [&'static str], &'static str)> {
    use candidates::Col;
    const SWEEP: &str =
        "constant-velocity plateaus at several speeds both ways (a speed sweep over the working range, trunk §3.2)";
    Some(match col {
        Col::Qdd => {
            (&["inertia.j"], "move the joint back and forth with strong accelerations for several seconds (trunk §3.4)")
        }
        Col::QdAbsQd => (&["friction.a"], SWEEP),
        Col::Qd => (&["friction.b"], SWEEP),
        Col::Sgn | Col::Dahl { .. } => (&["friction.c"], SWEEP),
        Col::SinSq(_) | Col::CosSq(_) => (
            &["weight.amplitude", "weight.phi"],
            "hold the joint still at 5+ angles spread over its range (static poses, trunk §3.3)",
        ),
        Col::Q | Col::DeadZone { .. } => (
            &["spring.k"],
            "hold the joint at angles on both sides of its rest with the torque measured (elastic joint, Fig. 5)",
        ),
        _ => return None,
    })
}

/// The model's terms the cross-fitted folds' refits ([`select::Split::cross_fitted`]) disagree
/// on: each fold fits the model's terms on its own 70 % of the log, and a term whose values
/// differ by more than a factor of two between folds (the spread above half the largest) and by
/// more torque than the noise floor (the spread times the column's RMS over the held-out samples)
/// is not pinned by this log, whatever its standard error says (those assume white residuals).
/// The DFKI 1 kg swing-up's folds put J at 0.02, 0.05 and 0.46 kg·m² and the weight's sine at
/// 0.4, 1.1 and 8.7 N·m: its swings hardly tell J·q̈ from the weight. The folds share 40 % of
/// their rows, so a disagreement this large is no sampling scatter. Nothing without folds.
fn fold_undetermined(d: &Data, refit: &Scored, split: &Split, floor: f64) -> Vec<NotDetermined> {
    let des = &refit.design;
    let mut out: Vec<NotDetermined> = Vec::new();
    for (k, values, spread) in fold_unsettled(d, refit, split, floor) {
        let Some(col) = des.cols.get(k) else { continue };
        let Some((params, test)) = term_of(col) else { continue };
        let params: Vec<String> = params.iter().map(|s| s.to_string()).collect();
        if out.iter().any(|o| o.params == params) {
            continue;
        }
        let shown: Vec<String> = values.iter().map(|v| format!("{v:.4}")).collect();
        let what = match col {
            Col::SinSq(_) => "the weight's sine part",
            Col::CosSq(_) => "the weight's cosine part",
            _ => "it",
        };
        out.push(NotDetermined {
            params,
            why: format!(
                "the {} cross-fitted folds' refits put {what} at {} (its term's RMS over the held-out samples differs by {spread:.3} N·m between folds, the other terms offsetting it): the log does not separate it from them",
                values.len(),
                shown.join(", "),
            ),
            test,
        });
    }
    out
}

/// The model's own columns (those [`term_of`] names) the cross-fitted folds' refits disagree
/// on, by [`fold_undetermined`]'s rule: per column its index, the values (the merged refit's,
/// then each fold's) and their spread in torque (N·m over the held-out samples).
pub(crate) fn fold_unsettled(d: &Data, refit: &Scored, split: &Split, floor: f64) -> Vec<(usize, Vec<f64>, f64)> {
    let des = &refit.design;
    if refit.folds.is_empty() {
        return Vec::new();
    }
    let base_end = des.spans.first().map_or(des.cols.len(), |s| s.0).min(refit.beta.len());
    let idx = candidates::thin_idx(&split.holdout_all(), 20_000);
    let mut ss = vec![0.0; base_end];
    let mut x = vec![0.0; des.cols.len()];
    for &i in &idx {
        des.row(d, i as usize, &mut x);
        for (a, v) in ss.iter_mut().zip(&x) {
            *a += v * v;
        }
    }
    let mut out = Vec::new();
    for (k, col) in des.cols.iter().enumerate().take(base_end) {
        if term_of(col).is_none() {
            continue;
        }
        let values: Vec<f64> = std::iter::once(refit.beta[k])
            .chain(
                refit
                    .folds
                    .iter()
                    .filter_map(|f| (f.design.cols.get(k) == Some(col)).then(|| f.beta.get(k)).flatten().copied()),
            )
            .collect();
        let (lo, hi) = values.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let big = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let rms = (ss[k] / idx.len().max(1) as f64).sqrt();
        if values.len() < 2 || !(hi - lo > 0.5 * big && (hi - lo) * rms > floor) {
            continue;
        }
        out.push((k, values, (hi - lo) * rms));
    }
    out
}

#[derive(Clone, Debug, Serialize)]
pub struct NotApplicable {
    pub effect: &'static str,
    pub why: &'static str,
}

/// Torque-mode effects the selection skipped for this model.
fn torque_not_applicable(base: &Base, d: &Data, tried: &[Vocab]) -> Vec<NotApplicable> {
    let mut v = vec![NotApplicable {
        effect: Vocab::InitialState.name(),
        why: "trajectory mode only (torque mode has no state to integrate)",
    }];
    for k in Vocab::terms().filter_map(torque_kind) {
        if tried.contains(&k.effect()) {
            continue;
        }
        let why = match k {
            candidates::Kind::Dry => "the model has a Coulomb term, so a missing Coulomb torque is `parameters`",
            candidates::Kind::Backlash => {
                "torque mode sees a dead zone only in a spring (elastic joint); this model has no [spring]"
            }
            candidates::Kind::Thermal if candidates::constant_temp(d) => {
                "the logged temperature does not change (range below 0.1 °C): this log cannot test a thermal drift"
            }
            candidates::Kind::Thermal => "the model has no friction term to scale",
            candidates::Kind::Load | candidates::Kind::Asymmetric
                if base.cols.iter().any(|c| matches!(c, Col::LoadSgn | Col::AbsSgn)) =>
            {
                "the model carries this term already: it is refitted with the model's own (`parameters`)"
            }
            _ => "its shape search found no usable range in this log",
        };
        v.push(NotApplicable { effect: k.name(), why });
    }
    v
}

/// Thinned series for the HTML plots.
#[derive(Clone, Debug, Default)]
pub struct PlotData {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// measured quantity (d − rest in torque mode, q in trajectory mode)
    pub measured: Vec<f64>,
    pub before: Vec<f64>,
    pub after: Vec<f64>,
    /// speed regime index per point (0 static, 1 low, 2 high)
    pub speed_regime: Vec<u8>,
    pub held: Vec<bool>,
    pub unit: &'static str,
    pub measured_label: &'static str,
    /// the verdict's evidence in each named effect's coordinate (empty for `none`)
    pub evidence: Vec<evidence::Evidence>,
}

/// A diagnosis: the report, the model text `--emit-model` writes, and plot data.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    pub report: Report,
    pub emitted_model: String,
    pub plots: PlotData,
}

/// Runs the diagnosis in the mode the log's columns give, on the log as the shared
/// preparation stage ([`crate::prep`]) leaves it.
pub fn diagnose(log: &JointLog, model: &ModelFile, opts: &Options) -> Result<Diagnosis, DiagError> {
    diagnose_cow(std::borrow::Cow::Borrowed(log), model, opts)
}

/// [`diagnose`], taking the log: its columns are moved into the analysis instead of copied (on
/// a 1 M-sample log 32 MB less to allocate and fill).
pub fn diagnose_owned(log: JointLog, model: &ModelFile, opts: &Options) -> Result<Diagnosis, DiagError> {
    diagnose_cow(std::borrow::Cow::Owned(log), model, opts)
}

fn diagnose_cow(
    log: std::borrow::Cow<'_, JointLog>,
    model: &ModelFile,
    opts: &Options,
) -> Result<Diagnosis, DiagError> {
    let params = model.param_set().map_err(|e| DiagError::Input(e.to_string()))?;
    let others = model.other_columns();
    for o in &others {
        if log.other(o).is_none() {
            return Err(DiagError::Input(format!(
                "the model's gravity table uses column `{o}`, which the log does not have (columns: {})",
                log.column_names().join(", ")
            )));
        }
    }
    let min = if log.mode() == LogMode::Trajectory { trajectory::min_samples(model) } else { 100 };
    if log.len() < min {
        return Err(DiagError::Input(format!("the log has {} samples; the diagnosis needs at least {min}", log.len())));
    }
    let clock = std::time::Instant::now();
    let mode = log.mode();
    let mut prep = crate::prep::prepare_cow(log).map_err(|e| DiagError::Input(e.to_string()))?;
    if std::env::var_os("DIAG_TIMING").is_some() {
        eprintln!("[diagnose] preparation stage: {:.3} s", clock.elapsed().as_secs_f64());
    }
    let mut d = match mode {
        LogMode::Torque => torque_mode(&mut prep, model, &params, &others, opts)?,
        LogMode::Trajectory => trajectory::diagnose(&prep, model, &params, opts)?,
    };
    d.report.prep = Some(prep.report);
    Ok(d)
}

/// Robust white-noise level of a residual from its second differences (smooth parts cancel,
/// sparse jumps are ignored by the median).
pub fn noise_floor(r: &[f64]) -> f64 {
    if r.len() < 3 {
        return 0.0;
    }
    let stride = (r.len() / 200_000).max(1);
    let mut v: Vec<f64> = (1..r.len() - 1).step_by(stride).map(|i| (r[i + 1] - 2.0 * r[i] + r[i - 1]).abs()).collect();
    let k = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *m / (0.674_489_75 * 6f64.sqrt())
}

/// Torque-mode logs up to this many samples are cross-fitted ([`select::Split::cross_fitted`]):
/// every score tests every sample held out once, on three fits, not 30 % of them on one. The
/// tests gain the power of three times the held-out samples where power is short (an effect
/// taking 59 % of a 1 000-sample log's held-out MSE came out at p = 5e-3, development seed 9041,
/// case 36); the selection costs three times as much, so the longest logs, whose held-out part
/// alone is plenty, keep the one split.
pub const CROSS_FIT_MAX: usize = 250_000;

/// Takes the prepared log's columns (no copy of a log that can be millions of samples); the
/// rest of `prep` is read.
fn torque_mode(
    prep: &mut crate::prep::Prepared,
    model: &ModelFile,
    params: &joint_core::params::ParamSet,
    others: &[String],
    opts: &Options,
) -> Result<Diagnosis, DiagError> {
    let n = prep.log.len();
    let clock = std::time::Instant::now();
    let timing = std::env::var_os("DIAG_TIMING").is_some();
    let lap = |what: &str| {
        if timing {
            eprintln!("[diagnose] {what}: {:.3} s", clock.elapsed().as_secs_f64());
        }
    };
    let dt = crate::prep::median_step(&prep.log.t);
    let pred0 = joint_formats::predict::predicted(&prep.log, params, others)
        .ok_or_else(|| DiagError::Input("cannot evaluate the model on this log".into()))?;
    lap("the model's prediction");
    let log = &mut prep.log;
    let (u, tau) = match (log.u.take(), log.tau.take()) {
        (Some(u), Some(t)) => (u, t),
        _ => return Err(DiagError::Input("torque mode needs `u` and `tau`".into())),
    };
    let (t, q, temp) = (std::mem::take(&mut log.t), std::mem::take(&mut log.q), log.temp.take());
    let (qd, qdd) = (log.qd.take().unwrap_or_default(), log.qdd.take().unwrap_or_default());
    let prep = &*prep;
    let base = base_from_model(model);
    // The file's friction law (spec §2): its `v_band` when it states one, else the pure sign.
    let band = model.explicit(ParamId::FrictionVBand).unwrap_or(0.0);
    // The core evaluates the sign with the band it runs (its default when the file has none):
    // that is what `pred0` holds and what the fixed rest must take off again.
    let core_band = f64::from(params.get(ParamId::FrictionVBand));
    let core_sgn: Vec<f64> = qd.iter().map(|&v| sgn_band(v, core_band)).collect();
    // What the model predicts given the estimated q̇ (its error from the preparation stage):
    // the sign's expectation, so rest and reversals are not a random ±c from velocity noise.
    let sgn: Vec<f64> = par::per_sample(n, |i| {
        let v = qd[i];
        match (prep.rest[i], prep.direction[i]) {
            (true, _) => 0.0,
            // next to a rest the way q goes says the direction the estimate cannot
            (false, d) if d != 0 => {
                if band > 0.0 {
                    crate::prep::expected_sign(f64::from(d) * v.abs(), band, prep.qd_err[i])
                } else {
                    f64::from(d)
                }
            }
            _ => crate::prep::expected_sign(v, band, prep.qd_err[i]),
        }
    });
    // the joint's own load (its load cell), what a model's load-dependent friction reads in
    // the prediction: the fixed rest below takes that term off with it
    let own_load: Vec<f64> = tau.iter().map(|t| t.abs()).collect();
    let mut data = Data {
        n,
        t,
        q,
        qd,
        qdd,
        u,
        tau,
        y: Vec::new(),
        temp,
        dt,
        band,
        sgn: core_sgn,
        q0: model.value(ParamId::SpringQ0),
        ws: model.value(ParamId::WeightS),
        wsin: Vec::new(),
        wcos: Vec::new(),
        load: own_load,
        qdd_noise_var: prep.qdd_noise_var(),
        // at rest q̈ is 0, not an estimate: no noise in the regressor there
        qdd_nv: prep.qdd_noise.iter().zip(&prep.rest).map(|(s, &still)| if still { 0.0 } else { s * s }).collect(),
        q_noise_var: prep.report.q_noise_sd.powi(2),
        qd_noise_var: prep.qd_err.iter().map(|e| e * e).sum::<f64>() / prep.qd_err.len().max(1) as f64,
        sw: Vec::new(),
    };
    if model.explicit(ParamId::WeightAmplitude).is_some() {
        let (ws, wc): (Vec<f64>, Vec<f64>) =
            par::per_sample(n, |i| (data.ws * data.q[i]).sin_cos()).into_iter().unzip();
        data.wsin = ws;
        data.wcos = wc;
    }
    // y = d − rest: the rest is what the model predicts outside its linear terms (gravity table,
    // the core's f32 rounding), the prediction less the linear part at the core's own sign.
    let des0 = candidates::Design::new(&data, &base, &[]);
    let p0 = des0.cols.len();
    data.y = vec![0.0; n];
    let y = par::per_sample(n, |i| {
        par::with_row(p0, |x| {
            des0.row(&data, i, x);
            let lin: f64 = x.iter().zip(&base.beta0).map(|(a, b)| a * b).sum();
            data.u[i] - data.tau[i] - (pred0[i] - lin)
        })
    });
    data.y = y;
    // From here on every model sees the expected sign; the file's residual r0 too.
    data.sgn = sgn;
    let (r0, non_friction): (Vec<f64>, Vec<f64>) = par::per_sample(n, |i| {
        par::with_row(p0, |x| {
            des0.row(&data, i, x);
            let lin: f64 = x.iter().zip(&base.beta0).map(|(a, b)| a * b).sum();
            let fric: f64 = x
                .iter()
                .zip(&base.beta0)
                .zip(&des0.cols)
                .filter(|(_, c)| c.is_friction())
                .map(|((a, b), _)| a * b)
                .sum();
            // the model's torque less its friction: inertia, weight, springs, offset, table
            // (d − y is the fixed rest: gravity table, the core's rounding)
            (data.y[i] - lin, data.u[i] - data.tau[i] - data.y[i] + lin - fric)
        })
    })
    .into_iter()
    .unzip();
    data.load = transmitted_load(&data.tau, &data.u, &non_friction, dt);
    lap("expected sign, design, file residual");
    let regimes = Regimes::build(&data.t, &data.q, &data.qd, &data.qdd, data.temp.as_deref(), dt);
    lap("regimes");
    // Test units long against the residual's correlation: the noise's (AR(1) from the
    // variogram: (1 + ρ)/(1 − ρ) samples) and the derivative estimates' windows, twice over, at
    // least 20 samples (the 50 of a fixed rule left a 3000-sample log 12 units).
    let (noise0, rho) = floor::variogram_noise(&r0);
    let unit_min = {
        let noise_corr = (1.0 + rho) / (1.0 - rho).max(0.05);
        let window = |i: &crate::prep::DerivInfo| if i.white { 0.0 } else { i.half_window_s / dt };
        let corr = noise_corr.max(window(&prep.report.qd)).max(window(&prep.report.qdd));
        ((2.0 * corr).ceil() as usize).clamp(20, 50)
    };
    let mut split = select::make_split_units(n, unit_min);
    if opts.cross_fit && n <= CROSS_FIT_MAX {
        split = split.cross_fitted(n, unit_min);
    }
    split.leave_out(&prep.ambiguous);
    // With a pure Coulomb sign (no band in the file) a sample whose direction the data cannot
    // tell predicts ±c by a coin toss: it says nothing about the model and is left out too.
    let pure_sign = band == 0.0 && base.cols.contains(&Col::Sgn);
    if pure_sign {
        split.leave_out(&prep.sign_unknown);
        split.leave_out(&prep.rest_edge);
    }
    if split.train.len() < 30 || split.holdout.len() < 30 {
        return Err(DiagError::Input("too few samples for a training/held-out split".into()));
    }
    // (a fold too short to fit or to test on: the one split alone)
    if split.folds.iter().any(|f| f.train.len() < 30 || f.holdout.len() < 30) {
        split.folds.clear();
    }
    // The floor is the noise a right model would leave. The file's own terms can raise it: an
    // inertia several times too large multiplies the q̈ estimate's error, and no effect is
    // measured against that. So it is also taken with the model's terms refitted (bounded,
    // errors in variables removed) on the training rows, and the lower of the two counts.
    let floor = {
        // (compared with scores on every fold's held-out samples: averaged over them all)
        let held = split.holdout_all();
        let at_file = torque_floor_with(noise0, &data, (&base.cols, &base.beta0), prep, &held);
        // (on at most 150 000 training rows, as the selection's fits)
        let fit_idx = candidates::thin_idx(&split.train, select::FIT_ROWS);
        let rs = select::fit_and_score(&data, &base, &[], &fit_idx, &split, &regimes.bits, regimes.defs.len());
        let p1 = rs.design.cols.len();
        let r1: Vec<f64> =
            par::per_sample(n, |i| par::with_row(p1, |x| select::residual_at(&data, &rs.design, &rs.beta, i, x)));
        at_file.min(torque_floor(&r1, &data, (&rs.design.cols, &rs.beta), prep, &held))
    };
    // A pure sign jumps to ±c at any motion, however slow: inside a rest, a creep below the
    // q̇ resolution shows as the residual stepping by ±c. Those samples' direction is unknown.
    let creep = if pure_sign {
        let c = base.cols.iter().position(|x| *x == Col::Sgn).map_or(0.0, |k| base.beta0[k].abs());
        // at ±c from the file's model and from its terms as the motion has them (see
        // [`rest_creep`]): either alone reads a model error as a creep (the refit only where
        // the file's model marks a rest)
        let mut creep = rest_creep(&r0, &prep.rest, c, floor);
        if creep.contains(&true) {
            if let Some(r) = rest_residual(&data, &base, prep, (&split, &regimes), &creep) {
                creep.iter_mut().zip(rest_creep(&r, &prep.rest, c, floor)).for_each(|(a, b)| *a &= b);
            }
        }
        let k = creep.iter().filter(|&&b| b).count();
        split.leave_out(&creep);
        (k > 0).then_some(k)
    } else {
        None
    };
    // Every sample weighs by the inverse of the variance it is expected to carry: the noise,
    // and what the estimates' errors make of the file's terms (as the floor counts them). A log
    // of fast moves and slow creeps has its friction sign uncertain in the creeps (bench seed
    // 9029, case 52: an RMSE of 0.57 N·m below 0.01 rad/s beside 0.03 N·m at speed), and an
    // effect at speed (a viscous friction drifting with temperature, 0.12 N·m) was lost in the
    // creeps' scatter unweighted: the verdict was `none`. The held-out weights go to the
    // projection test, the gains and the weighted floor ([`select::Split::weigh`]); the fits
    // weigh their training rows alike (weighted least squares), or the effect is fitted to the
    // scatter (that log's thermal candidate took the shape that scales the Coulomb sign too, at
    // a sixth of its coefficient).
    let terms = EstimateTerms::new((&base.cols, &base.beta0), prep);
    // (once per sample, on both cores: the held-out weights and the fit weights read it)
    let var = par::per_sample(n, |i| noise0 * noise0 + terms.var(&data, prep, i));
    split.weigh(|i| var[i]);
    data.sw = fit_weights(&var, &split.train);
    lap("prepared (velocities, model prediction, regimes, split, noise floor)");
    // the floor a fit's residual says (the selection reads it again where a fit shows structure)
    let held = split.holdout_all();
    let reread = |s: &Scored| {
        let p = s.design.cols.len();
        let r: Vec<f64> =
            par::per_sample(n, |i| par::with_row(p, |x| select::residual_at(&data, &s.design, &s.beta, i, x)));
        torque_floor(&r, &data, (&s.design.cols, &s.beta), prep, &held)
    };
    let sel = select::select(&data, &base, &split, &regimes.bits, regimes.defs.len(), floor, &reread, opts.max_effects);
    let floor = sel.floor;
    lap("candidates and forward selection");
    let mut report = build_report("torque", &data, &base, model, &regimes, &split, &sel, &r0, floor, creep, &prep.log);
    lap("report");
    let final_s =
        sel.chosen.last().map(|o| &o.scored).unwrap_or(if sel.refit.significant { &sel.refit.scored } else { &sel.m0 });
    let weight_kept = weight_undetermined(model, final_s, &data, &split);
    if let Some(why) = &weight_kept {
        report.warnings.push(format!("{why}: --emit-model keeps the file's weight and offset"));
    }
    // the terms the log does not pin (unexcited, or the folds disagree): the file's values
    let pinned_not: Vec<(ParamId, &str)> = report
        .not_determined
        .iter()
        .flat_map(|u| &u.params)
        .filter_map(|p| {
            let desc = p.split_once('.').and_then(|(sec, k)| joint_core::params::param_at(sec, k))?;
            Some((desc.id, p.as_str()))
        })
        .collect();
    // What is emitted is the final fit solved again with those terms held at the file's values,
    // so the terms it writes are fitted around the ones it keeps (on a short arc the offset
    // takes the constant a held weight leaves; the report's `refit` stays the free fit's).
    let held_s;
    let emit_s = if std::ptr::eq(final_s, &sel.m0) || pinned_not.is_empty() {
        final_s
    } else {
        let mut b = base.clone();
        for (k, col) in b.cols.iter().enumerate() {
            // (and what the selection held: an inertia the rows want negative stays held)
            let kept = term_of(col)
                .is_some_and(|(names, _)| names.iter().any(|n| pinned_not.iter().any(|(_, p)| p == n)))
                || final_s.design.fixed.get(k).copied().unwrap_or(false);
            if kept {
                if let Some(f) = b.fixed.get_mut(k) {
                    *f = true;
                }
            }
        }
        let idx = candidates::thin_idx(&split.train, select::FIT_ROWS);
        held_s = select::fit_and_score(&data, &b, &final_s.effects, &idx, &split, &regimes.bits, regimes.defs.len());
        &held_s
    };
    let emitted_model = emit_model(model, &base, emit_s, &data, weight_kept.as_deref(), &pinned_not);
    let mut plots = plot_data(&data, &sel.m0, final_s, &regimes, &split);
    plots.evidence = torque_evidence(&data, &sel.m0, final_s, &split, &report.verdict.effects);
    Ok(Diagnosis { report, emitted_model, plots })
}

/// The rest samples whose residual `r0` stands at ±`c` (within a quarter of `c` or 3 floors,
/// the larger), where the model predicts 0: the step a pure Coulomb sign makes when the joint
/// creeps at a speed no estimate resolves (or rests at its breakaway, where a creep is as
/// likely). Nothing is marked when `c` is under 4 floors (the step is then lost in the noise).
/// Rest samples inside ±c are kept: leaving every sample static friction could hold out as well
/// (the set-valued sign) cost 13 of 300 development cases, asymmetric friction and delays among
/// them, and fixed no model-exact log.
/// The caller marks a sample where both the file's residual and that of the model's own terms
/// refitted on the moving samples ([`rest_residual`]) stand there. A file whose offset is wrong
/// shifts the rests and the motion alike, and read from the file's model alone that shift was a
/// creep (bench 9114/1: the offset 0.47 N·m off, c = 0.75 N·m, 2 178 of 3 280 rest samples left
/// out; the rests that stayed pulled the refit's offset and an asymmetric friction was named).
/// Read from the refit alone, an error of the motion the file's terms cannot take (a viscous
/// drift at speed, 9101/34) moved the refit's offset and weight, and still rests became steps.
pub fn rest_creep(r0: &[f64], rest: &[bool], c: f64, floor: f64) -> Vec<bool> {
    if !(c > 4.0 * floor) {
        return vec![false; r0.len()];
    }
    let tol = (0.25 * c).max(3.0 * floor);
    r0.iter().zip(rest).map(|(&r, &still)| still && r.abs() > 0.5 * c && (r.abs() - c).abs() < tol).collect()
}

/// The residual at the samples `at` (0 elsewhere) of the model's own terms refitted on the
/// moving training samples ([`rest_creep`] reads it at the rests): what the model's terms, as
/// the motion has them, leave at a rest is the rest's own (a creep's ±c), not an offset or a
/// weight the file has wrong. `None` with under 30 moving training samples.
fn rest_residual(
    d: &Data,
    base: &Base,
    prep: &crate::prep::Prepared,
    (split, regimes): (&Split, &Regimes),
    at: &[bool],
) -> Option<Vec<f64>> {
    let moving: Vec<u32> = split.train.iter().copied().filter(|&i| !prep.rest[i as usize]).collect();
    let idx = candidates::thin_idx(&moving, select::FIT_ROWS);
    if idx.len() < 30 {
        return None;
    }
    let rm = select::fit_and_score(d, base, &[], &idx, split, &regimes.bits, regimes.defs.len());
    let p = rm.design.cols.len();
    Some(par::per_sample(d.n, |i| {
        if at[i] {
            par::with_row(p, |x| select::residual_at(d, &rm.design, &rm.beta, i, x))
        } else {
            0.0
        }
    }))
}

/// The torque-mode noise floor ([`floor`]): the measurement noise in the file's residual (any
/// colour) and, in variance, what the error of the estimated q̇/q̈ makes of the model's own
/// inertia, viscous and Coulomb terms (a logged column's white noise is already in the
/// residual's noise and is not counted twice).
///
/// The noise is taken as stationary (the whole residual's variogram); the estimates' share is
/// averaged over `idx`, the samples the floor is compared on (the held-out ones): a log of
/// moves and rests has its derivative errors in the moves, and held-out blocks that hold more
/// moves than the log on average must be compared with their own floor.
fn torque_floor(
    r0: &[f64],
    d: &Data,
    (cols, beta): (&[Col], &[f64]),
    prep: &crate::prep::Prepared,
    idx: &[u32],
) -> f64 {
    torque_floor_with(floor::variogram_noise(r0).0, d, (cols, beta), prep, idx)
}

/// [`torque_floor`] with the residual's noise already read from its variogram.
fn torque_floor_with(
    noise: f64,
    d: &Data,
    (cols, beta): (&[Col], &[f64]),
    prep: &crate::prep::Prepared,
    idx: &[u32],
) -> f64 {
    let terms = EstimateTerms::new((cols, beta), prep);
    let pure_sign = d.band == 0.0;
    let used: Vec<usize> = idx
        .iter()
        .map(|&i| i as usize)
        .filter(|&i| i < d.n && !(prep.ambiguous[i] || pure_sign && (prep.sign_unknown[i] || prep.rest_edge[i])))
        .collect();
    let n = used.len().max(1) as f64;
    let prop2: f64 = used.iter().map(|&i| terms.var(d, prep, i)).sum::<f64>() / n;
    if std::env::var_os("DIAG_TRACE").is_some() {
        let mut parts = [0.0; 3];
        for &i in &used {
            let p = terms.parts(d, prep, i);
            for k in 0..3 {
                parts[k] += p[k] / n;
            }
        }
        eprintln!(
            "[trace] floor: residual noise {noise:.5}, estimates' share {:.5} (J {:.4}; RMS from q̈ {:.5}, q̇ {:.5}, sign {:.5})",
            prop2.sqrt(),
            terms.j,
            parts[0].sqrt(),
            parts[1].sqrt(),
            parts[2].sqrt()
        );
    }
    (noise * noise + prop2).sqrt()
}

/// Square roots of the fit weights `1/var` per sample ([`Data::sw`]), scaled to a mean weight
/// of 1 over the training samples `train`; empty (all alike) when any variance there is not a
/// positive finite number.
fn fit_weights(var: &[f64], train: &[u32]) -> Vec<f64> {
    let on_train = || train.iter().filter_map(|&i| var.get(i as usize).map(|v| 1.0 / v));
    if train.is_empty() || !on_train().all(|x| x.is_finite() && x > 0.0) {
        return Vec::new();
    }
    let mean = on_train().sum::<f64>() / train.len() as f64;
    // samples outside the training set (left out, held out) are never fitted: any finite value
    var.iter().map(|v| 1.0 / v).map(|x| if x.is_finite() && x > 0.0 { (x / mean).sqrt() } else { 0.0 }).collect()
}

/// What the q̇/q̈ estimates' errors reach a sample's residual through: the model's inertia `j`,
/// friction `a`·q̇|q̇|, `b`·q̇ and Coulomb `c` (0 where it has none), and whether q̇ and q̈ are
/// estimates (white noise on a logged column is already in the residual's noise; an estimate's
/// or a filter's error follows the motion and is not).
struct EstimateTerms {
    j: f64,
    a: f64,
    b: f64,
    c: f64,
    qd_derived: bool,
    qdd_derived: bool,
}

impl EstimateTerms {
    fn new((cols, beta): (&[Col], &[f64]), prep: &crate::prep::Prepared) -> EstimateTerms {
        let coef = |c: Col| cols.iter().position(|x| *x == c).map_or(0.0, |k| beta.get(k).copied().unwrap_or(0.0));
        EstimateTerms {
            j: coef(Col::Qdd),
            a: coef(Col::QdAbsQd),
            b: coef(Col::Qd),
            c: coef(Col::Sgn),
            qd_derived: !prep.report.qd.white,
            qdd_derived: !prep.report.qdd.white,
        }
    }

    /// The variance the estimates' errors add to sample `i`'s residual (see [`torque_floor`]).
    fn var(&self, d: &Data, prep: &crate::prep::Prepared, i: usize) -> f64 {
        self.parts(d, prep, i).iter().sum()
    }

    /// [`EstimateTerms::var`]'s three parts: through the inertia, the friction's slope and the
    /// Coulomb sign.
    fn parts(&self, d: &Data, prep: &crate::prep::Prepared, i: usize) -> [f64; 3] {
        let EstimateTerms { j, a, b, c, qd_derived, qdd_derived } = *self;
        let pure_sign = d.band == 0.0;
        let slope = b + 2.0 * a * d.qd[i].abs();
        let sv = if qd_derived { prep.qd_err[i] } else { 0.0 };
        let sa = if qdd_derived { prep.qdd_err[i] } else { 0.0 };
        // at rest the sign is 0; a known direction settles a pure sign, but inside a band
        // the sign's value is q̇/band and carries q̇'s error whichever way the joint goes.
        // Counted for a logged q̇ too: its white noise reaches the residual through the
        // band's steep slope only near rest, a few samples the (robust) variogram ignores.
        let dir = prep.direction[i];
        // the speed with the way q goes where that is known
        let v = if dir != 0 { f64::from(dir) * d.qd[i].abs() } else { d.qd[i] };
        let sgn_var = if prep.rest[i] && !pure_sign {
            // a rest is |q̇| within the estimate's noise, not q̇ = 0: a joint that creeps
            // inside the band there (held by friction c·q̇/band) has a friction anywhere in
            // ±c·(noise/band), which q̇ = 0 cannot predict
            crate::prep::sign_variance(0.0, d.band, prep.report.qd.error_sd)
        } else if prep.rest[i] || dir != 0 && pure_sign {
            0.0
        } else {
            crate::prep::sign_variance(v, d.band, prep.qd_err[i])
        };
        [j * j * sa * sa, slope * slope * sv * sv, c * c * sgn_var]
    }
}

/// What a load-dependent friction grows with: the measured load `|tau|`; when the log's `tau`
/// is zero (a joint without a load cell logs 0) the magnitude of the model's non-friction
/// torque, which the joint transmits too. Never `u`: in such a log `u` is the very friction
/// to be explained, and a column built from it fits its noise as well.
fn transmitted_load(tau: &[f64], u: &[f64], non_friction: &[f64], dt: f64) -> Vec<f64> {
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    if rms(tau) > 0.01 * rms(u) {
        // The residual holds −tau's noise, so |tau| itself as a regressor explains part of its
        // own noise wherever the load keeps a sign against the motion, on held-out samples as
        // well (unseen t9025/case-0011: an exact model named `load_dependent_friction` at 4.9 %
        // shrink). The load is read from the samples around each one, not the sample itself
        // (±10 ms, at least two either side): white noise then shares nothing with the residual.
        let m = ((0.01 / dt).round() as usize).max(2);
        let n = tau.len();
        let mut sums = Vec::with_capacity(n + 1);
        sums.push(0.0);
        let mut acc = 0.0;
        for &t in tau {
            acc += t;
            sums.push(acc);
        }
        (0..n)
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(m), (i + m + 1).min(n));
                let k = (hi - lo - 1).max(1) as f64;
                ((sums[hi] - sums[lo] - tau[i]) / k).abs()
            })
            .collect()
    } else {
        non_friction.iter().map(|t| t.abs()).collect()
    }
}

/// Half-width of the zero-phase moving average applied to q̇ before any model sees it, s.
pub const VELOCITY_SMOOTHING_S: f64 = 0.005;

/// The core's smoothed sign in f64 (one rule for the joint, the identification and the plant).
pub(crate) use joint_core::math::sign_smooth_f64 as sgn_band;

fn coef(s: &Scored, c: Col) -> Option<f64> {
    s.design.cols.iter().position(|x| *x == c).map(|k| s.beta[k])
}

/// The section parameters of effect `k` of a scored model (same names as the plant sections).
pub(crate) fn effect_params(s: &Scored, k: usize, d: &Data) -> BTreeMap<String, f64> {
    let mut p = BTreeMap::new();
    let Some(e) = s.effects.get(k) else { return p };
    let (a, b) = s.design.spans.get(k).copied().unwrap_or((0, 0));
    let beta = |j: usize| s.beta.get(a + j).copied().unwrap_or(0.0);
    let mut put = |k: &str, v: f64| {
        p.insert(k.to_string(), v);
    };
    match *e {
        Effect::Stribeck { speed, exponent } => {
            put("level", beta(0));
            put("speed", speed);
            put("exponent", exponent);
        }
        Effect::Asymmetric => put("delta", beta(0)),
        Effect::Load => put("mu", beta(0)),
        Effect::Thermal { src, .. } => {
            put("coefficient", beta(0));
            match src {
                ThermSrc::Temp { mean } => put("t_ref", mean),
                ThermSrc::Time { tau, mean, .. } => {
                    put("time_constant", tau);
                    put("t_ref", mean);
                }
            }
        }
        Effect::Ripple { period, harmonics, second } => {
            let (bs, bc) = (beta(0), beta(1));
            put("amplitude", bs.hypot(bc));
            put("period", period);
            put("phase", bc.atan2(bs));
            if harmonics >= 2 {
                let (bs2, bc2) = (beta(2), beta(3));
                put("amplitude_2", bs2.hypot(bc2));
                put("phase_2", bc2.atan2(bs2));
            }
            if second > 0.0 {
                let k = if harmonics >= 2 { 4 } else { 2 };
                let (bs3, bc3) = (beta(k), beta(k + 1));
                put("period_b", second);
                put("amplitude_b", bs3.hypot(bc3));
                put("phase_b", bc3.atan2(bs3));
            }
        }
        Effect::Cable { engage, side: 0, .. } => {
            put("k3", beta(0));
            put("k1", beta(1));
            put("centre", engage);
        }
        Effect::Cable { engage, width, side: 2 } => {
            put("amplitude", beta(0));
            put("centre", engage);
            put("half_width", width);
        }
        Effect::Cable { engage, width, side } => {
            put("k", beta(0));
            put("engage", engage);
            put("width", width);
            put("side", f64::from(side));
        }
        Effect::Backlash { width, offset } => {
            put("width", width);
            put("offset", offset);
            if let Some(k) = s.design.cols.iter().position(|c| matches!(c, Col::DeadZone { .. })) {
                put("spring_k", s.beta[k]);
            }
        }
        Effect::Delay { lag, channel } => {
            // how long the channel lags (negative: it leads); `seconds` is that size
            put(&format!("{}_lag_s", channel.name()), lag * d.dt);
            put("seconds", lag.abs() * d.dt);
        }
        Effect::Dry => put("c", beta(0)),
        Effect::Presliding { kappa, .. } => {
            // the Dahl column's coefficient is the Coulomb level c; σ = κ·c
            let c = s.design.cols.iter().position(|c| matches!(c, Col::Dahl { .. })).map_or(0.0, |k| s.beta[k]);
            put("sigma", kappa * c);
            put("distance", 1.0 / kappa);
            put("c", c);
        }
    }
    let _ = b;
    p
}

/// The model's own terms at a scored model's values, by TOML section and key.
fn refit_values(model: &ModelFile, s: &Scored) -> BTreeMap<String, BTreeMap<String, f64>> {
    let mut out: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    let mut put = |sec: &str, k: &str, v: f64| {
        out.entry(sec.to_string()).or_default().insert(k.to_string(), v);
    };
    let v = |id| model.value(id);
    if let Some(j) = coef(s, Col::Qdd) {
        put("inertia", "j", j);
    }
    if let Some(a) = coef(s, Col::QdAbsQd) {
        put("friction", "a", a);
    }
    if let Some(bt) = coef(s, Col::Qd) {
        if v(ParamId::FrictionB) != 0.0 || v(ParamId::SpringB) == 0.0 {
            put("friction", "b", bt - v(ParamId::SpringB));
        } else {
            put("spring", "b", bt);
        }
    }
    let coulomb = coef(s, Col::Sgn)
        .or_else(|| s.design.cols.iter().position(|c| matches!(c, Col::Dahl { .. })).map(|k| s.beta[k]));
    if let Some(c) = coulomb {
        if v(ParamId::FrictionC) == 0.0 && v(ParamId::DryFrictionC) != 0.0 {
            put("dry_friction", "c", c);
        } else {
            put("friction", "c", c);
        }
    }
    // the model's own effect terms (base columns come first, so `coef` finds them)
    if v(ParamId::StribeckLevel) != 0.0 {
        if let Some(l) = coef(s, Col::Stribeck(v(ParamId::StribeckSpeed))) {
            put("stribeck", "level", l);
        }
    }
    if v(ParamId::AsymmetricDelta) != 0.0 {
        if let Some(dl) = coef(s, Col::AbsSgn) {
            put("asymmetric_friction", "delta", dl);
        }
    }
    if v(ParamId::RippleAmplitude) != 0.0 {
        let per = v(ParamId::RipplePeriod);
        if let (Some(bs), Some(bc)) = (coef(s, Col::RipSin(per)), coef(s, Col::RipCos(per))) {
            put("position_ripple", "amplitude", bs.hypot(bc));
            put("position_ripple", "phase", bc.atan2(bs));
        }
        let half = Col::RipSin(per / 2.0);
        if let (Some(bs), Some(bc)) = (coef(s, half), coef(s, Col::RipCos(per / 2.0))) {
            put("position_ripple", "amplitude_2", bs.hypot(bc));
            put("position_ripple", "phase_2", bc.atan2(bs));
        }
    }
    if v(ParamId::CableK) != 0.0 {
        let c = Col::Cable { engage: v(ParamId::CableEngage), width: v(ParamId::CableWidth) };
        if let Some(kc) = coef(s, c) {
            put("cable_spring", "k", kc);
        }
    }
    // in the base whenever the file states it (0 included), so refitted whenever it is there
    if model.explicit(ParamId::LoadFrictionMu).is_some() {
        if let Some(mu) = coef(s, Col::LoadSgn) {
            put("load_dependent_friction", "mu", mu);
        }
    }
    let ws = v(ParamId::WeightS);
    if let (Some(bs), Some(bc)) = (coef(s, Col::SinSq(ws)), coef(s, Col::CosSq(ws))) {
        put("weight", "amplitude", bs.hypot(bc));
        put("weight", "phi", bc.atan2(bs));
    }
    let dz = s.design.cols.iter().position(|c| matches!(c, Col::DeadZone { .. })).map(|k| s.beta[k]);
    let k_new = coef(s, Col::Q).or(dz);
    if let Some(k) = k_new {
        put("spring", "k", k);
    }
    if let Some(cst) = coef(s, Col::Const) {
        let k = k_new.unwrap_or(0.0);
        let shift = if dz.is_some() { 0.0 } else { k * v(ParamId::SpringQ0) };
        if v(ParamId::OffsetC0) != 0.0 || k == 0.0 {
            put("offset", "c0", cst + shift);
        } else {
            // No offset in the model: the constant moves the spring's rest angle.
            put("spring", "q0", if dz.is_some() { v(ParamId::SpringQ0) - cst / k } else { -cst / k });
        }
    }
    out
}

fn effect_out(
    o: &Outcome,
    reference: &'static str,
    m0: &Scored,
    regimes: &Regimes,
    d: &Data,
    model: &ModelFile,
) -> EffectOut {
    let before = m0.rmse();
    let after = o.scored.rmse();
    let params = if o.scored.effects.is_empty() {
        refit_values(model, &o.scored)
            .into_iter()
            .flat_map(|(s, kv)| kv.into_iter().map(move |(k, v)| (format!("{s}.{k}"), v)))
            .collect()
    } else {
        effect_params(&o.scored, o.scored.effects.len() - 1, d)
    };
    EffectOut {
        effect: o.name.to_string(),
        holdout_rmse_before: before,
        holdout_rmse_after: after,
        shrink: shrink(before, after),
        significant: o.significant,
        params,
        reference,
        t_stat: finite_or(o.t, 1e9),
        p_value: o.p,
        gain: o.gain,
        implausible: o.implausible,
        regimes: regime_shrinks(m0, &o.scored, regimes),
    }
}

fn finite_or(x: f64, big: f64) -> f64 {
    if x.is_finite() {
        x
    } else if x > 0.0 {
        big
    } else {
        -big
    }
}

pub(crate) fn shrink(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        1.0 - after / before
    } else {
        0.0
    }
}

fn regime_shrinks(m0: &Scored, s: &Scored, regimes: &Regimes) -> Vec<RegimeShrink> {
    regimes
        .defs
        .iter()
        .enumerate()
        .filter(|(j, _)| m0.regime_n[*j] > 0.0)
        .map(|(j, r)| RegimeShrink {
            name: r.name.clone(),
            holdout_rmse_before: (m0.regime_sse[j] / m0.regime_n[j]).sqrt(),
            holdout_rmse_after: (s.regime_sse[j] / s.regime_n[j].max(1.0)).sqrt(),
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn build_report(
    mode: &'static str,
    d: &Data,
    base: &Base,
    model: &ModelFile,
    regimes: &Regimes,
    split: &Split,
    sel: &Selection,
    r0: &[f64],
    floor: f64,
    creep: Option<usize>,
    log: &JointLog,
) -> Report {
    let nreg = regimes.defs.len();
    let mut sse = vec![0.0; nreg];
    let mut cnt = vec![0usize; nreg];
    let mut total = 0.0;
    let mut scored = 0usize;
    for (i, r) in r0.iter().enumerate() {
        if split.left_out.get(i).copied().unwrap_or(false) {
            continue;
        }
        scored += 1;
        let r2 = r * r;
        total += r2;
        let mut b = regimes.bits[i];
        while b != 0 {
            let j = b.trailing_zeros() as usize;
            sse[j] += r2;
            cnt[j] += 1;
            b &= b - 1;
        }
    }
    let regimes_out: Vec<RegimeOut> = regimes
        .defs
        .iter()
        .enumerate()
        .map(|(j, r)| RegimeOut {
            name: r.name.clone(),
            family: r.family,
            where_: r.where_.clone(),
            share: if total > 0.0 { sse[j] / total } else { 0.0 },
            rmse: if cnt[j] > 0 { (sse[j] / cnt[j] as f64).sqrt() } else { 0.0 },
            samples: cnt[j],
        })
        .collect();
    let before = sel.m0.rmse();
    let mut effects: Vec<EffectOut> = vec![effect_out(&sel.refit, "model", &sel.m0, regimes, d, model)];
    effects.extend(sel.candidates.iter().map(|o| effect_out(o, "parameters", &sel.m0, regimes, d, model)));
    effects.sort_by(|a, b| a.holdout_rmse_after.total_cmp(&b.holdout_rmse_after));
    let mut warnings = refit_warnings(&effects);
    let mut unexcited = not_determined(d, sel, split);
    for f in fold_undetermined(d, sel.free_refit.as_ref().unwrap_or(&sel.refit.scored), split, floor) {
        if !unexcited.iter().any(|u| u.params == f.params) {
            unexcited.push(f);
        }
    }
    let inertia_unexcited = unexcited.iter().any(|u| u.params.iter().any(|p| p == "inertia.j"));
    if select::inertia_held(&sel.refit.scored) && !inertia_unexcited {
        let noise = if d.qdd_noise_var > 0.0 {
            format!(" (its white noise ≈ {:.3} rad/s²)", d.qdd_noise_var.sqrt())
        } else {
            String::new()
        };
        warnings.push(format!(
            "refit inertia.j is kept at the file's value: the rows want none or a negative one, which no joint has, or \
             q̈{noise} is too noisy to tell the inertia from its noise. The logged torque may not be what moved the \
             joint (a hand, an unlogged load), or give a filtered `qdd` column"
        ));
    }
    let selected: Vec<Step> = sel
        .chosen
        .iter()
        .map(|o| Step {
            effect: o.name.to_string(),
            params: effect_params(&o.scored, o.scored.effects.len() - 1, d),
            holdout_rmse_after: o.scored.rmse(),
            shrink: shrink(before, o.scored.rmse()),
            p_value: o.p,
        })
        .collect();
    let (verdict_effect, vafter) = match sel.chosen.first() {
        Some(o) => (o.name, o.scored.rmse()),
        None if sel.refit.significant => (Vocab::Parameters, sel.refit.scored.rmse()),
        None if before > select::UNEXPLAINED * floor => (Vocab::Unexplained, before),
        None => (Vocab::None, before),
    };
    let vname = verdict_effect.name().to_string();
    let final_s =
        sel.chosen.last().map(|o| &o.scored).unwrap_or(if sel.refit.significant { &sel.refit.scored } else { &sel.m0 });
    let (alternatives, closest) = verdict_company(sel, verdict_effect);
    let verdict = Verdict {
        effect: vname.clone(),
        holdout_rmse_before: before,
        holdout_rmse_after: vafter,
        shrink: shrink(before, vafter),
        effects: if sel.chosen.is_empty() {
            vec![vname]
        } else {
            sel.chosen.iter().map(|o| o.name.to_string()).collect()
        },
        alternatives,
        closest,
    };
    // resid evidence on the first held-out samples (at most 50 000).
    let resid = {
        let mut idx: Vec<usize> = Vec::new();
        for &i in split.holdout.iter().take(50_000) {
            idx.push(i as usize);
        }
        let mut x0 = vec![0.0; sel.m0.design.cols.len()];
        let mut x1 = vec![0.0; final_s.design.cols.len()];
        let rb: Vec<f64> =
            idx.iter().map(|&i| select::residual_at(d, &sel.m0.design, &sel.m0.beta, i, &mut x0)).collect();
        let ra: Vec<f64> =
            idx.iter().map(|&i| select::residual_at(d, &final_s.design, &final_s.beta, i, &mut x1)).collect();
        let qd: Vec<f64> = idx.iter().map(|&i| d.qd[i]).collect();
        let u: Vec<f64> = idx.iter().map(|&i| d.u[i]).collect();
        let lag = ((0.1 / d.dt).round() as usize).clamp(10, 100);
        // the six correlations on the available cores (the cross-correlations, twice the lags,
        // first)
        let jobs: [(&[f64], &[f64], bool); 6] = [
            (&rb, &rb, true),
            (&ra, &ra, true),
            (&rb, &qd, false),
            (&rb, &u, false),
            (&ra, &qd, false),
            (&ra, &u, false),
        ];
        let c = par::costliest_first(
            &jobs,
            par::cores(8),
            |j| u8::from(j.2),
            |&(r, x, auto)| resid::xcorr(r, x, lag, auto),
        );
        <[resid::Correlation; 6]>::try_from(c).ok().map(|[auto_b, auto_a, qd_b, u_b, qd_a, u_a]| Resid {
            input: vec!["qd", "u"],
            autocorrelation_before: auto_b,
            autocorrelation_after: auto_a,
            xcorr_before: vec![qd_b, u_b],
            xcorr_after: vec![qd_a, u_a],
        })
    };
    let final_rmse = final_s.rmse();
    Report {
        mode,
        samples: d.n,
        split: SplitInfo {
            method: "interleaved_blocks",
            train: split.train.len(),
            holdout: split.holdout.len(),
            blocks: split.blocks,
            held_blocks: (0..split.blocks).filter(|b| matches!(b % 10, 2 | 5 | 8)).map(|b| b + 1).collect(),
            guard_samples: split.guard,
            test_units: split.n_units,
            rest_tail: None,
            cross_fitted: (!split.folds.is_empty()).then_some(1 + split.folds.len()),
            holdout_scored: (!split.folds.is_empty()).then(|| split.holdout_total()),
        },
        gap: Gap {
            rmse: (total / scored.max(1) as f64).sqrt(),
            holdout_rmse: before,
            noise_floor: floor,
            unit: "N·m",
            at_noise_floor: final_rmse <= select::at_floor_factor(d) * floor,
            qdd_noise_sd: (d.qdd_noise_var > 0.0).then(|| d.qdd_noise_var.sqrt()),
            scored_samples: (scored < d.n).then_some(scored),
            rest_creep_samples: creep,
        },
        regimes: regimes_out,
        effects,
        verdict,
        selected,
        refit: refit_values(model, if sel.refit.significant || !sel.chosen.is_empty() { final_s } else { &sel.m0 }),
        test: TestInfo {
            method: "one-sided t-test on the per-unit log ratio of held-out MSE and a projection test of the held-out MSE difference (its variance from the units, Satterthwaite degrees of freedom), p = 2·min (up to 60 held-out units of at least twice the residual's correlation time); Bonferroni over candidates, a 2 % minimum gain against the refit and the file's model, nothing but a 15 % gain tested once the file's model is within 10 % of the noise floor; the floor read again from the residual of each fit that is significant but for it",
            alpha: select::ALPHA,
            alpha_each: sel.alpha_each,
            min_gain: select::MIN_GAIN,
        },
        resid,
        unknown_columns: log.unknown.clone(),
        not_applicable: torque_not_applicable(base, d, &sel.candidates.iter().map(|o| o.name).collect::<Vec<_>>()),
        not_determined: unexcited,
        warnings,
        prep: None,
    }
}

/// The verdict's evidence plots ([`evidence`]) on the held-out samples (at most 200 000).
fn torque_evidence(d: &Data, m0: &Scored, fin: &Scored, split: &Split, names: &[String]) -> Vec<evidence::Evidence> {
    use evidence::Coord;
    let named: Vec<Vocab> = names
        .iter()
        .filter_map(|n| Vocab::from_name(n))
        .filter(|e| !matches!(e, Vocab::None | Vocab::Unexplained))
        .collect();
    if named.is_empty() {
        return Vec::new();
    }
    let stride = (split.holdout.len() / 200_000).max(1);
    let idx: Vec<usize> = split.holdout.iter().step_by(stride).map(|&i| i as usize).collect();
    let (mut before, mut after) = (vec![f64::NAN; d.n], vec![f64::NAN; d.n]);
    let mut x0 = vec![0.0; m0.design.cols.len()];
    let mut x1 = vec![0.0; fin.design.cols.len()];
    for &i in &idx {
        before[i] = select::residual_at(d, &m0.design, &m0.beta, i, &mut x0);
        after[i] = select::residual_at(d, &fin.design, &fin.beta, i, &mut x1);
    }
    let rate = evidence::rate(&d.u, &d.t);
    // A ripple lives in q but repeats every period: over the phase q mod P its shape shows,
    // where bins over the whole travel would average it away.
    let period = fin.effects.iter().find_map(|e| match e {
        Effect::Ripple { period, .. } => Some(*period).filter(|p| *p > 0.0),
        _ => None,
    });
    let phase: Vec<f64> = period.map(|p| d.q.iter().map(|q| q.rem_euclid(p)).collect()).unwrap_or_default();
    named
        .iter()
        .filter_map(|name| {
            let (name, c) = (*name, Coord::of(*name, d.temp.is_some()));
            let x: &[f64] = match c {
                Coord::Velocity => &d.qd,
                Coord::Position if name == Vocab::PositionRipple && !phase.is_empty() => &phase,
                Coord::Position => &d.q,
                Coord::Time => &d.t,
                Coord::Temperature => d.temp.as_deref().unwrap_or(&d.t),
                Coord::Load => &d.load,
                Coord::TorqueRate => &rate,
            };
            let label = match period {
                Some(p) if name == Vocab::PositionRipple => format!("q mod P (rad), P = {p:.4} rad"),
                _ => c.label("N·m"),
            };
            evidence::binned(name.name(), &label, x, &before, &after, &idx, 30)
        })
        .collect()
}

fn plot_data(d: &Data, m0: &Scored, fin: &Scored, regimes: &Regimes, split: &Split) -> PlotData {
    // Every sample up to 400 000: the plots draw long series as their per-pixel envelope and
    // the report's zoomable view needs the detail (the old 4000-point stride aliased).
    let stride = (d.n / 400_000).max(1);
    let mut held = vec![false; d.n];
    for &i in &split.holdout {
        held[i as usize] = true;
    }
    let mut p = PlotData { unit: "N·m", measured_label: "d − rest (N·m)", ..PlotData::default() };
    let mut x0 = vec![0.0; m0.design.cols.len()];
    let mut x1 = vec![0.0; fin.design.cols.len()];
    for i in (0..d.n).step_by(stride) {
        let y = m0.design.target(d, i);
        let rb = select::residual_at(d, &m0.design, &m0.beta, i, &mut x0);
        let ra = select::residual_at(d, &fin.design, &fin.beta, i, &mut x1);
        p.t.push(d.t[i]);
        p.q.push(d.q[i]);
        p.qd.push(d.qd[i]);
        p.measured.push(y);
        p.before.push(rb);
        p.after.push(ra);
        let b = regimes.bits[i];
        p.speed_regime.push(if b & 1 != 0 {
            0
        } else if b & 2 != 0 {
            1
        } else {
            2
        });
        p.held.push(held[i]);
    }
    p
}

/// Why the log does not determine the final fit's weight apart from the offset, if it does not.
/// Over a short arc `A·sin(s·q + φ)` and `c0` trade against each other (a 0.4 rad arc is
/// nearly a straight line plus a constant): the refit may put hundreds of N·m on the pair that
/// cancel where the joint went and not elsewhere. The weight's sine and cosine coefficients'
/// standard errors come from the energy of each column the others do not explain on the
/// training rows (thinned to 20 000) and the held-out residual variance; the weight counts as
/// determined when both are within a quarter of the file's amplitude (a 95 % interval within
/// half of it; the errors assume white residuals and are optimistic for correlated ones). A
/// model without a weight, or a fit that kept the file's weight, has nothing to say.
fn weight_undetermined(model: &ModelFile, fin: &Scored, d: &Data, split: &Split) -> Option<String> {
    let des = &fin.design;
    let ks = des.cols.iter().position(|c| *c == Col::SinSq(d.ws))?;
    let kc = des.cols.iter().position(|c| *c == Col::CosSq(d.ws))?;
    let (bs, bc) = (fin.beta[ks], fin.beta[kc]);
    // the fit kept the file's weight (the design's prior: the file's own coefficients)
    if bs == des.prior[ks] && bc == des.prior[kc] {
        return None;
    }
    let idx = candidates::thin_idx(&split.train, 20_000);
    let stride = split.train.len() as f64 / idx.len().max(1) as f64;
    let g = des.gram(d, &idx);
    // (the Gram is weighted as the fits are, so the residual variance is the weighted one)
    let sigma2 = fin.wmse() / stride;
    let se = select::coef_se(&g, ks, sigma2).max(select::coef_se(&g, kc, sigma2));
    let (a0, s) = (model.value(ParamId::WeightAmplitude).abs(), model.value(ParamId::WeightS));
    if se <= 0.25 * a0 && se.is_finite() {
        return None;
    }
    let (lo, hi) =
        idx.iter().map(|&i| d.q[i as usize]).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| (a.min(q), b.max(q)));
    Some(format!(
        "the log does not determine the weight apart from the offset: over q in [{lo:.3}, {hi:.3}] rad ({:.2} rad of the weight's phase) the refit's weight (amplitude {:.4} N·m, c0 {:.4} N·m; the file's {a0:.4} and {:.4}) is known to ±{se:.3} N·m per part",
        s.abs() * (hi - lo),
        bs.hypot(bc),
        coef(fin, Col::Const).unwrap_or(0.0),
        model.value(ParamId::OffsetC0),
    ))
}

/// The model TOML with the final model's refitted values and its effect sections, in the plant
/// file's section names, so `jointctl simulate --plant` runs it.
/// `weight_kept`: why the log does not determine the weight ([`weight_undetermined`]); the
/// file's weight and offset are written then, with that reason. `not_pinned`: the parameters
/// the report lists as not determined ([`Report::not_determined`]), written as the file's.
fn emit_model(
    model: &ModelFile,
    base: &Base,
    fin: &Scored,
    d: &Data,
    weight_kept: Option<&str>,
    not_pinned: &[(ParamId, &str)],
) -> String {
    let _ = base;
    let mut mf = model.clone();
    let vals = refit_values(model, fin);
    let kept = [ParamId::WeightAmplitude, ParamId::WeightPhi, ParamId::WeightS, ParamId::OffsetC0];
    for (sec, kv) in &vals {
        for (k, v) in kv {
            if let Some(desc) = joint_core::params::param_at(sec, k) {
                if weight_kept.is_some() && kept.contains(&desc.id) || not_pinned.iter().any(|(id, _)| *id == desc.id) {
                    continue;
                }
                // Keep the file loadable: the table forbids negative coefficients.
                let v = v.clamp(f64::from(desc.min), f64::from(desc.max));
                mf.set(desc.id, v, None);
            }
        }
    }
    let mut out = String::from("# written by `jointctl diagnose --emit-model`: the model refitted on the training part of the log,\n# plus the selected effects as plant sections (readable by `jointctl simulate --plant`).\n");
    if let Some(why) = weight_kept {
        out.push_str(&format!("# [weight] and [offset] are the file's: {why}.\n"));
    }
    if !not_pinned.is_empty() {
        let names: Vec<&str> = not_pinned.iter().map(|(_, name)| *name).collect();
        out.push_str(&format!(
            "# the file's values, not the refit's (the log does not determine them; the report's not_determined says why): {}\n",
            names.join(", ")
        ));
    }
    // A pad has no section of its own, but it is a torque of the angle alone: where the file has
    // no gravity table, it is written as one over q (additive: no σ_model, so the joint adds the
    // table to the weight), which the joint compensates. 16 points over centre ± half width (the
    // core's most per axis; the raised cosine's linear interpolation is within 0.6 % of its
    // amplitude), 0 at both ends, so the clamped table is 0 beyond them.
    // (the pad's index among the effects, its amplitude, centre and half width)
    let pad_table =
        fin.effects.iter().position(|e| matches!(e, Effect::Cable { side: 2, .. })).filter(|_| mf.table.is_none()).map(
            |k| {
                let p = effect_params(fin, k, d);
                let get = |key: &str| p.get(key).copied().unwrap_or(0.0);
                (k, get("amplitude"), get("centre"), get("half_width"))
            },
        );
    if let Some((_, amp, centre, half)) = pad_table {
        mf.table = Some(position_table(centre - half, centre + half, |q| amp * shapes::pad(centre, half, q)));
    }
    let model_text = mf.to_toml_string();
    out.push_str(&model_text);
    for k in 0..fin.effects.len() {
        if let Some((_, amp, centre, half)) = pad_table.filter(|p| p.0 == k) {
            out.push_str(&format!(
                "\n# cable_spring: a pad pressing over q = {centre:?} ± {half:?} rad (a raised cosine of amplitude \
                 {amp:?} N·m), written as the [gravity_table] above\n"
            ));
            continue;
        }
        let name = section_name(fin.effects[k].kind());
        if model_text.lines().any(|l| l.trim() == format!("[{name}]")) {
            // The model already carries this term as a section of its own: a second table of
            // the same name would make the file invalid TOML, so the fitted extra is a comment.
            out.push_str(&format!("\n# diagnose: the [{name}] term above needs, on top of it:\n"));
            out.push_str(&effect_section(fin, k, d).lines().skip(2).map(|l| format!("#   {l}\n")).collect::<String>());
            continue;
        }
        out.push_str(&effect_section(fin, k, d));
    }
    out
}

/// A torque of the joint's own angle over `lo..=hi`, 0 beyond, as the additive gravity table the
/// core compensates: the most points an axis holds, evenly spaced, the ends set to 0 so the
/// table (clamped to its grid) is 0 outside.
pub(crate) fn position_table(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> joint_formats::model_file::TableSpec {
    let n = joint_core::table::AXIS_POINTS_MAX;
    let grid: Vec<f64> = (0..n).map(|j| lo + (hi - lo) * j as f64 / (n - 1) as f64).collect();
    let torque: Vec<f64> =
        grid.iter().enumerate().map(|(j, &q)| if j == 0 || j == n - 1 { 0.0 } else { f(q) }).collect();
    joint_formats::model_file::TableSpec { axes: vec!["q".into()], grid: vec![grid], torque, sigma: None }
}

fn effect_section(s: &Scored, k: usize, d: &Data) -> String {
    use std::fmt::Write as _;
    let p = effect_params(s, k, d);
    let Some(e) = s.effects.get(k) else { return String::new() };
    let section = section_name(e.kind());
    // Sections the core also knows as model terms are clamped into its parameter ranges, so the
    // emitted file stays a loadable model (a negative Stribeck level, say, is not one).
    let g = |key: &str| {
        let v = p.get(key).copied().unwrap_or(0.0);
        match joint_core::params::param_at(section, key) {
            Some(d) => v.clamp(f64::from(d.min), f64::from(d.max)),
            None => v,
        }
    };
    let mut o = String::new();
    let _ = writeln!(o, "\n[{section}]");
    match *e {
        Effect::Stribeck { exponent, .. } => {
            let _ = writeln!(o, "level = {:?}\nspeed = {:?}", g("level"), g("speed"));
            if exponent != 2.0 {
                let _ = writeln!(
                    o,
                    "# fitted exponent {exponent:.2}: the section's curve is exp(−(q̇/speed)²); level and speed are the fit's"
                );
            }
        }
        Effect::Asymmetric => {
            let _ = writeln!(o, "delta = {:?}", g("delta"));
        }
        Effect::Load => {
            let _ = writeln!(o, "mu = {:?}", g("mu").max(0.0));
        }
        Effect::Thermal { src, .. } => {
            let (t_amb, rise, tc, log_temp) = match src {
                ThermSrc::Temp { .. } => {
                    let (a, r, tc) = fit_warmup(d);
                    (a, r, tc, true)
                }
                // Without a temp column the drift is expressed on a virtual 1 °C warm-up.
                ThermSrc::Time { tau, .. } => (0.0, 1.0, tau, false),
            };
            let _ = writeln!(
                o,
                "coefficient = {:?}\nt_ambient = {:?}\nrise = {:?}\ntime_constant = {:?}\nt_ref = {:?}\nlog_temp = {}",
                g("coefficient"),
                t_amb,
                rise,
                tc,
                g("t_ref"),
                log_temp
            );
        }
        Effect::Ripple { harmonics, second, .. } => {
            let _ =
                writeln!(o, "amplitude = {:?}\nperiod = {:?}\nphase = {:?}", g("amplitude"), g("period"), g("phase"));
            if harmonics >= 2 {
                let _ = writeln!(o, "amplitude_2 = {:?}\nphase_2 = {:?}", g("amplitude_2"), g("phase_2"));
            }
            if second > 0.0 {
                let _ = writeln!(
                    o,
                    "# a second ripple of its own period, not a section key (the joint compensates one): period_b = {:?}, amplitude_b = {:?}, phase_b = {:?}",
                    g("period_b"),
                    g("amplitude_b"),
                    g("phase_b")
                );
            }
        }
        Effect::Cable { side: 1, .. } => {
            let _ = writeln!(o, "k = {:?}\nengage = {:?}\nwidth = {:?}", g("k").max(0.0), g("engage"), g("width"));
        }
        Effect::Cable { side, .. } => {
            // Not a shape the section holds (it is taut above `engage`): written as a comment.
            o.clear();
            let _ = if side == 2 {
                writeln!(
                    o,
                    "\n# cable_spring (a pad pressing over q = {:?} ± {:?} rad, a raised cosine of amplitude {:?} N·m); no model section holds this shape",
                    g("centre"),
                    g("half_width"),
                    g("amplitude")
                )
            } else if side == 0 {
                writeln!(
                    o,
                    "\n# cable_spring (progressive, k3·x³ + k1·x with x = q − {:?}): k3 = {:?}, k1 = {:?}; no model section holds this shape",
                    g("centre"),
                    g("k3"),
                    g("k1")
                )
            } else {
                writeln!(
                    o,
                    "\n# cable_spring taut below engage = {:?} (k = {:?}, width = {:?}); the section holds one taut above its angle",
                    g("engage"),
                    g("k"),
                    g("width")
                )
            };
        }
        Effect::Backlash { .. } => {
            let _ = writeln!(o, "width = {:?}", g("width"));
            if g("offset") != 0.0 {
                let _ = writeln!(o, "# the dead zone's centre is {:?} rad from the spring's rest angle", g("offset"));
            }
        }
        Effect::Delay { .. } => {
            let _ = writeln!(o, "seconds = {:?}", g("seconds").clamp(0.0, 1.0));
        }
        Effect::Dry => {
            let _ = writeln!(o, "c = {:?}", g("c").max(0.0));
        }
        Effect::Presliding { .. } => {
            let _ = writeln!(o, "sigma = {:?}", g("sigma").max(0.0));
        }
    }
    o
}

/// The model/plant file section an effect is written as: its vocabulary entry's (spec §2).
pub(crate) fn section_name(k: candidates::Kind) -> &'static str {
    k.effect().section().unwrap_or_else(|| k.name())
}

/// The torque-mode kind that fits vocabulary term `v`. The match names every entry, so a term
/// added to the vocabulary does not compile here until the diagnosis fits it (a kind, in
/// [`candidates::Kind::ALL`]: a test checks the two agree) or says it cannot.
pub(crate) fn torque_kind(v: Vocab) -> Option<candidates::Kind> {
    use candidates::Kind as K;
    match v {
        Vocab::Stribeck => Some(K::Stribeck),
        Vocab::AsymmetricFriction => Some(K::Asymmetric),
        Vocab::LoadDependentFriction => Some(K::Load),
        Vocab::ThermalDrift => Some(K::Thermal),
        Vocab::PositionRipple => Some(K::Ripple),
        Vocab::CableSpring => Some(K::Cable),
        Vocab::Backlash => Some(K::Backlash),
        Vocab::Delay => Some(K::Delay),
        Vocab::DryFriction => Some(K::Dry),
        Vocab::PreslidingHysteresis => Some(K::Presliding),
        // verdicts and the trajectory mode's start state: no torque-mode candidate
        Vocab::Parameters | Vocab::InitialState | Vocab::None | Vocab::Unexplained => None,
    }
}

/// Fits `T(t) = t_ambient + rise·(1 − e^(−t/τ))` to the temp column (τ by golden section).
fn fit_warmup(d: &Data) -> (f64, f64, f64) {
    let Some(tp) = &d.temp else { return (0.0, 0.0, 1.0) };
    let idx: Vec<usize> = (0..d.n).step_by((d.n / 20_000).max(1)).collect();
    let span = (d.t[d.n - 1] - d.t[0]).max(1e-6);
    let solve = |tau: f64| {
        let mut g = fit::Gram::new(2);
        for &i in &idx {
            g.add(&[1.0, 1.0 - (-d.t[i] / tau).exp()], tp[i]);
        }
        g.solve()
    };
    let (lt, _) = fit::golden((0.01 * span).ln(), (100.0 * span).ln(), 40, |l| solve(l.exp()).1);
    let tau = lt.exp();
    let (b, _) = solve(tau);
    (b[0], b[1], tau)
}

#[cfg(test)]
mod vocabulary_tests {
    use super::*;

    /// Every pair a verdict can have as alternatives gets a test that says what log separates
    /// them (never a generic "a longer log"), the same either way round.
    #[test]
    fn every_pair_of_explanations_has_a_separating_test() {
        let all: Vec<Vocab> = Vocab::terms().chain([Vocab::Parameters, Vocab::InitialState]).collect();
        for &a in &all {
            for &b in &all {
                if a == b {
                    continue;
                }
                let t = separating_test(a, b);
                assert!(!t.contains("a longer log"), "{a} vs {b}: {t}");
                let u = separating_test(b, a);
                assert!(t == u || (t.contains(a.name()) && u.contains(a.name())), "{a} vs {b}: {t} / {u}");
            }
        }
        assert!(separating_test(Vocab::DryFriction, Vocab::Parameters).contains("envelope"));
        assert!(separating_test(Vocab::InitialState, Vocab::Parameters).contains("first swing only"));
    }

    /// Torque mode tries every effect term of the vocabulary, each as one kind, in the
    /// vocabulary's order, and writes it as the vocabulary's section.
    #[test]
    fn torque_mode_kinds_are_the_vocabularys_terms() {
        let from_vocab: Vec<candidates::Kind> = Vocab::terms().filter_map(torque_kind).collect();
        assert_eq!(candidates::Kind::ALL.to_vec(), from_vocab);
        for v in Vocab::terms() {
            let k = torque_kind(v).unwrap_or_else(|| panic!("{v} has no torque-mode kind"));
            assert_eq!(k.effect(), v);
            assert_eq!(Some(section_name(k)), v.section());
        }
        assert_eq!(section_name(candidates::Kind::Presliding), "presliding");
    }
}

#[cfg(test)]
mod creep_tests {
    use super::rest_creep;

    /// The rest samples at ±c are marked, those inside are kept, and a c under 4 floors marks
    /// nothing.
    #[test]
    fn a_rest_at_plus_or_minus_c_is_a_creep() {
        let (c, floor) = (0.75, 0.1);
        let r0 = [0.0, 0.74, -0.8, 0.3, 0.74, 1.6];
        let rest = [true, true, true, true, false, true];
        assert_eq!(rest_creep(&r0, &rest, c, floor), vec![false, true, true, false, false, false]);
        assert_eq!(rest_creep(&r0, &rest, c, 0.2), vec![false; 6]);
    }
}
