//! The plausibility gate every model passes before it is written or pushed: `identify`,
//! `diagnose --emit-model` and `push` all call [`check`] (or [`check_data`]), so a model with a
//! negative inertia or a weight pointing the wrong way cannot reach a joint by any of them
//! without `--force`.
//!
//! What it checks, each only for a term the file states (a missing key is an absent term,
//! spec §2):
//! - **inertia** `j > 0`: a joint has mass; a J the data do not determine is left out, not 0;
//! - **friction** `a, b, c ≥ 0` (and `[dry_friction] c`): friction never feeds energy in;
//! - **spring** `k ≥ 0` (a spring stores energy) and `b ≥ 0` (its damper dissipates);
//! - **weight** against the log's static samples, when a log is at hand: at a pose where the
//!   model's weight is larger than what friction can hold, the joint must supply its torque; a
//!   measured static torque that falls short of it in the weight's direction by more than
//!   friction, a tenth of the amplitude and the pose's noise contradicts the weight. A weight with
//!   the wrong sign or phase fails at most such poses, a right one at none.
//!
//! The joint's own `check()` (parameter ranges, table shape) stays the last line of defence;
//! this gate is about physics the ranges cannot see, and names the parameter and why.

use joint_core::params::ParamId;
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

use crate::identify::{self, weight};

/// One reason a model is implausible.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Problem {
    /// the TOML parameter, `section.key`
    pub param: String,
    pub reason: String,
}

/// The gate's answer: the problems (empty = plausible) and what was checked.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Verdict {
    pub problems: Vec<Problem>,
    pub checked: Vec<String>,
}

impl Verdict {
    pub fn plausible(&self) -> bool {
        self.problems.is_empty()
    }

    /// One line per problem, `section.key: reason`.
    pub fn reasons(&self) -> Vec<String> {
        self.problems.iter().map(|p| format!("{}: {}", p.param, p.reason)).collect()
    }
}

/// Checks `model`; `logs` (may be empty) are prepared and searched for static poses to check
/// the weight's sign against. A log the preparation refuses is skipped for the weight check
/// (and said so): the gate judges the model, not the log.
pub fn check(model: &ModelFile, logs: &[JointLog]) -> Verdict {
    if logs.is_empty() {
        return check_data(model, None);
    }
    match identify::Data::new(logs, &identify::Options::default()) {
        Ok(data) => check_data(model, Some(&data)),
        Err(e) => {
            let mut v = check_data(model, None);
            v.checked.push(format!("weight: not checked against the log ({e})"));
            v
        }
    }
}

/// [`check`] on logs already prepared and segmented by identification.
pub fn check_data(model: &ModelFile, data: Option<&identify::Data>) -> Verdict {
    let mut v = Verdict::default();
    let stated = |id: ParamId| model.explicit(id);
    let mut need = |id: ParamId, ok: fn(f64) -> bool, rule: &str, why: &str| {
        let d = id.desc();
        let name = format!("{}.{}", d.section, d.key);
        if let Some(x) = stated(id) {
            v.checked.push(format!("{name} {rule}"));
            if !ok(x) {
                v.problems.push(Problem { param: name, reason: format!("{x} is not {rule}: {why}") });
            }
        }
    };
    need(
        ParamId::InertiaJ,
        |x| x > 0.0,
        "> 0",
        "a joint has mass; if the data do not determine J, leave [inertia] out instead of writing 0",
    );
    for id in [ParamId::FrictionA, ParamId::FrictionB, ParamId::FrictionC, ParamId::DryFrictionC] {
        need(id, |x| x >= 0.0, "≥ 0", "friction never feeds energy into the joint");
    }
    need(ParamId::SpringK, |x| x >= 0.0, "≥ 0", "a spring stores energy: a negative stiffness pushes the joint away");
    need(ParamId::SpringB, |x| x >= 0.0, "≥ 0", "a damper dissipates energy");
    weight_vs_static(model, data, &mut v);
    v
}

/// The weight against the log's static poses (see the module documentation).
fn weight_vs_static(model: &ModelFile, data: Option<&identify::Data>, v: &mut Verdict) {
    let Some(amp) = model.explicit(ParamId::WeightAmplitude) else { return };
    let Some(data) = data else {
        v.checked.push("weight: no log at hand, its sign not checked".into());
        return;
    };
    if model.table.is_some() || model.series.is_some() {
        v.checked.push("weight: the model also has a gravity table or series; the weight alone is not checked".into());
        return;
    }
    let (s, phi) = (model.value(ParamId::WeightS), model.value(ParamId::WeightPhi));
    let c0 = model.value(ParamId::OffsetC0);
    let (fa, fb, fc) =
        (model.value(ParamId::FrictionA), model.value(ParamId::FrictionB), model.value(ParamId::FrictionC));
    let band = model.explicit(ParamId::FrictionVBand).unwrap_or(0.0);
    let friction = move |qd: f64| fa * qd * qd.abs() + fb * qd + fc * identify::sign_band(qd, band);
    let spring = |q: f64| model.value(ParamId::SpringK) * (q - model.value(ParamId::SpringQ0));
    let poses = weight::poses(&data.pairs(), &friction);
    // Friction can hold up to its Coulomb level at rest; a tenth of the amplitude is left for a
    // model that is right in sign but not exact in size.
    let hold = fc + model.value(ParamId::DryFrictionC) + model.value(ParamId::StribeckLevel).max(0.0);
    let mut testable = 0;
    let mut against = Vec::new();
    for p in &poses {
        let w = amp * (s * p.q + phi).sin();
        // What friction can hold, a tenth of the amplitude for a weight right in sign but not
        // in size, and the pose mean's noise (its samples are correlated: at most 20 count).
        let allowance = hold + 0.1 * amp.abs() + 3.0 * p.sd / (p.n.min(20) as f64).sqrt();
        if w.abs() <= allowance {
            // friction alone could hold this weight: the pose says nothing about its sign
            continue;
        }
        testable += 1;
        // The joint must supply the weight's torque (less what friction holds): the measured
        // static torque falling short of it in the weight's direction contradicts the weight.
        let m = p.d - c0 - spring(p.q);
        if (m - w) * w.signum() < -allowance {
            against.push((p.q, m, w, allowance));
        }
    }
    if testable == 0 {
        v.checked.push(format!(
            "weight: none of the log's {} static poses is where the weight exceeds what friction can hold; its sign not \
             checked",
            poses.len()
        ));
        return;
    }
    v.checked.push(format!("weight against {testable} static poses of the log"));
    if 2 * against.len() > testable {
        let list: Vec<String> = against
            .iter()
            .take(3)
            .map(|(q, m, w, a)| {
                format!("at q = {q:.3} rad the joint holds {m:+.3} N·m, the weight gives {w:+.3} (± {a:.3})")
            })
            .collect();
        v.problems.push(Problem {
            param: "weight.amplitude".into(),
            reason: format!(
                "the weight disagrees with the log's static samples at {} of {testable} poses (opposite sign, or far \
                 larger than the torque held): {}",
                against.len(),
                list.join("; ")
            ),
        });
    }
}
