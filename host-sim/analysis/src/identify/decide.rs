//! Whether an identified model is worth writing, and what goes in it.
//!
//! 1. Only **determined** parameters are written ([`super::model_file`]); the others are listed
//!    with the test that would pin them.
//! 2. A log that determines nothing writes nothing (`--force` cannot make a model out of no
//!    data).
//! 3. The **held-out quality** ([`super::report::Quality`]) must reach
//!    [`super::report::MIN_HELDOUT_R2`]: below it nothing is written without `--force`.
//! 4. The **plausibility gate** ([`crate::plausible`]) with the logs at hand: a model that fails
//!    it is not written without `--force`.
//! 5. The joint's own `check()` refuses what no `--force` can pass (out-of-range values).

use joint_formats::model_file::ModelFile;

use super::report::Quality;
use super::status::Status;
use super::{Data, Identified, IdentifyError, Method};
use crate::plausible;

/// What to write and why.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Decision {
    /// the model to write; `None` = nothing is written
    #[serde(skip)]
    pub model: Option<ModelFile>,
    pub written: bool,
    /// the parameters in the model (`section.key`)
    pub params: Vec<String>,
    /// why nothing is written (empty when it is)
    pub refused: Vec<String>,
    /// refusals `--force` overrode
    pub overridden: Vec<String>,
    /// things the user should know that do not stop the write
    pub warnings: Vec<String>,
    pub plausibility: plausible::Verdict,
}

/// Decides on `id` (identified from `data`, validated to `quality`).
pub fn decide(
    data: &Data,
    id: &Identified,
    quality: &Quality,
    name: Option<&str>,
    force: bool,
) -> Result<Decision, IdentifyError> {
    let mf = super::model_file(id, name)?;
    let params: Vec<String> = id.status.iter().filter(|p| p.determined()).map(|p| p.name()).collect();
    let mut d = Decision {
        model: None,
        written: false,
        params: params.clone(),
        refused: Vec::new(),
        overridden: Vec::new(),
        warnings: Vec::new(),
        plausibility: plausible::Verdict::default(),
    };
    if params.is_empty() {
        let mut why = "the log determines no parameter: nothing to write".to_string();
        let tests: Vec<&str> =
            id.status.iter().filter(|p| p.status != Status::Determined).filter_map(|p| p.test).collect();
        let mut uniq: Vec<&str> = Vec::new();
        for t in tests {
            if !uniq.contains(&t) {
                uniq.push(t);
            }
        }
        if !uniq.is_empty() {
            why.push_str(&format!(" (tests that would pin them: {})", uniq.join("; ")));
        }
        if id.method == Method::Papers && id.terms.iter().any(|t| super::RIGID_TERMS.contains(t)) {
            why.push_str("; `--method joint-ls` fits every rigid term from the whole log instead");
        }
        d.refused.push(why);
        if quality.passed == Some(false) {
            d.refused.push(format!(
                "and the fit does not predict held-out data: {} = {:.4} (threshold {})",
                quality.metric,
                quality.value.unwrap_or(f64::NAN),
                quality.threshold
            ));
        }
        return Ok(d);
    }
    let mut forceable = Vec::new();
    match quality.passed {
        Some(false) => forceable.push(format!(
            "{} = {:.4} is below {} ({}): the model does not predict data it was not fitted to",
            quality.metric,
            quality.value.unwrap_or(f64::NAN),
            quality.threshold,
            quality.why
        )),
        None => d.warnings.push(format!("held-out quality not measured: {}", quality.why)),
        Some(true) => {}
    }
    d.plausibility = plausible::check_data(&mf, Some(data));
    forceable.extend(d.plausibility.reasons().into_iter().map(|r| format!("implausible: {r}")));
    if forceable.is_empty() || force {
        d.overridden = forceable;
        d.written = true;
        d.model = Some(mf);
    } else {
        d.refused = forceable;
    }
    Ok(d)
}
