//! What one generated case is: its columns, the file's model, the truth, and the clean
//! signals kept for the tests (u − tau before noise, the true disturbance).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::effects::Effect;
use crate::joint::DrawnJoint;
use crate::model::ModelFile;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Torque,
    Trajectory,
}

/// The logged columns in file order; `t` is always among them.
#[derive(Debug, Clone, Default)]
pub struct Log {
    pub columns: Vec<(String, Vec<f64>)>,
}

impl Log {
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_slice())
    }

    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, |(_, v)| v.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn names(&self) -> Vec<String> {
        self.columns.iter().map(|(n, _)| n.clone()).collect()
    }

    /// CSV text: `t` with 6 decimals (µs stamps), the rest with 10 significant digits,
    /// far below any noise level the generator draws.
    pub fn to_csv(&self) -> String {
        let mut s = self.names().join(",");
        s.push('\n');
        for i in 0..self.len() {
            let row: Vec<String> = self
                .columns
                .iter()
                .map(|(n, v)| {
                    let x = v.get(i).copied().unwrap_or(f64::NAN);
                    if n == "t" {
                        format!("{x:.6}")
                    } else if x == 0.0 {
                        "0".to_string()
                    } else {
                        format!("{x:.9e}")
                    }
                })
                .collect();
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }
}

/// Noise-free signals at the sample times, for checks (not written).
#[derive(Debug, Clone, Default)]
pub struct Clean {
    /// Time since the first sample (the log's t is t0 + this).
    pub t_rel: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    /// True actuator torque and external load (torque mode), true input (trajectory mode).
    pub u: Vec<f64>,
    pub tau: Vec<f64>,
}

/// Everything recorded about a case, written as truth.json.
#[derive(Debug, Clone, Serialize)]
pub struct Truth {
    pub seed: u64,
    pub case: u64,
    pub mode: Mode,
    /// The withheld effect names (spec §3 vocabulary), or ["none"].
    pub effects: Vec<String>,
    /// The effects joined by '+', the family the scorer groups by.
    pub label: String,
    pub joint: DrawnJoint,
    pub file_model: ModelFile,
    pub effect_details: Vec<Effect>,
    pub trajectory_family: String,
    pub trajectory: serde_json::Value,
    pub rest_phases: bool,
    /// Share of samples where the true q̇ is exactly 0 (dwells, pauses, stuck joint): with
    /// pure-sign friction the file's c·sign(q̇) is then exactly 0 in the truth.
    pub rest_share: f64,
    pub rate_hz: f64,
    pub duration_s: f64,
    pub samples: usize,
    /// Peak-to-peak sample-time jitter as a fraction of the period (0: a clean grid).
    pub time_jitter: f64,
    pub t0: f64,
    pub external_load: serde_json::Value,
    pub sensors: serde_json::Value,
    pub columns: Vec<String>,
    /// RMS of the true disturbance (torque mode, N·m) or the swing (trajectory mode, rad).
    pub signal_scale: f64,
    /// RMS of what the withheld effect(s) add to the residual (u − tau − file model, or
    /// the logged-minus-file-model angle), before noise.
    pub effect_rms: f64,
    /// RMS of the noise on u − tau (torque mode) or on q (trajectory mode).
    pub noise_rms: f64,
    pub snr: f64,
    pub snr_unit: String,
    pub snr_per_effect: BTreeMap<String, f64>,
    /// snr ≥ 1: recorded as data, never used to relabel a case.
    pub detectable_hint: bool,
    pub notes: Vec<String>,
    /// What the draw guaranteed the log shows of each effect that needs it (backlash
    /// crossings, cable engaged share, ripple periods, friction reversals); see `shown`.
    #[serde(skip_serializing_if = "serde_json::Map::is_empty")]
    pub guarantees: serde_json::Map<String, serde_json::Value>,
}

/// A generated case.
#[derive(Debug, Clone)]
pub struct CaseData {
    pub truth: Truth,
    pub log: Log,
    pub model: ModelFile,
    pub clean: Clean,
}

/// Share of exact zeros in a velocity series.
pub fn zero_share(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.iter().filter(|x| **x == 0.0).count() as f64 / v.len() as f64
}

/// truth.json's effect list: the names, or ["none"].
pub fn truth_names(effects: &[&str]) -> Vec<String> {
    if effects.is_empty() {
        vec!["none".to_string()]
    } else {
        effects.iter().map(|s| s.to_string()).collect()
    }
}

/// Each effect's own RMS over the noise RMS.
pub fn snr_map(effects: &[Effect], rms: &[f64], sigma: f64) -> BTreeMap<String, f64> {
    effects.iter().zip(rms).map(|(e, r)| (e.name().to_string(), r / sigma.max(1e-300))).collect()
}

/// The label the scorer groups by: "none", one name, or names joined by '+'.
pub fn label_of(effects: &[&str]) -> String {
    if effects.is_empty() {
        "none".to_string()
    } else {
        effects.join("+")
    }
}

/// Whole scenes (joint, trajectory, effects) drawn again at most when the first effect
/// stays below 0.5× the noise for every noise level the scene allows: such a label is one
/// the log cannot show. Too large an effect is kept (the log shows it all the more).
pub const SCENE_REDRAWS: usize = 8;

/// The note of a case whose first effect never sized into the 0.5–5× band.
pub fn outside_band_note(snr: f64, redraws: usize) -> String {
    let mut s = format!("effect size outside the 0.5–5× noise band for every draw; SNR {snr:.3}");
    if redraws > 0 {
        s.push_str(&format!(" (scene redrawn {redraws} times)"));
    }
    s
}

/// Draws scenes until the first effect sizes into its band: `draw` returns the scene, whether
/// it sized, and its SNR. A scene whose effect came out too large is kept at once; one too
/// small (SNR < 0.5) is drawn again, at most [`SCENE_REDRAWS`] times, and the last is kept with
/// a note. A scene that sizes on its first draw uses no extra draws.
pub fn scene_that_sizes<T>(notes: &mut Vec<String>, mut draw: impl FnMut() -> (T, bool, f64)) -> T {
    let mut redraws = 0;
    loop {
        let (scene, in_band, snr) = draw();
        if in_band {
            return scene;
        }
        if snr >= 0.5 || redraws == SCENE_REDRAWS {
            notes.push(outside_band_note(snr, redraws));
            return scene;
        }
        redraws += 1;
    }
}
