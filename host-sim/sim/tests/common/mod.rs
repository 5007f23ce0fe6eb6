//! Helpers shared by the simulator's and jointctl's integration tests: build a plant from the trunk-right model
//! plus extra TOML, simulate, and compute the residual against the unchanged model.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

pub const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

pub fn example(rel: &str) -> String {
    std::fs::read_to_string(format!("{ROOT}/{rel}")).unwrap()
}

/// The trunk-right model text without its [compensation] section (plants do not need it).
pub fn trunk_model() -> String {
    example("examples/models/trunk-right.toml")
}

pub struct Run {
    pub log: JointLog,
    pub resid: Vec<f64>,
    pub floor: Option<f64>,
}

/// Simulates `plant_text` under the model `ctrl_text`, scenarios `scn`, `secs` each.
pub fn run_with(plant_text: &str, ctrl_text: &str, scn: &[ScenarioKind], secs: f64, seed: u64) -> Run {
    let plant = PlantFile::parse(plant_text, "plant.toml").unwrap();
    let model = ModelFile::parse(ctrl_text, "model.toml").unwrap();
    let p = model.param_set().unwrap();
    let cfg = SimConfig { scenarios: scn.to_vec(), seconds: secs, seed, ..SimConfig::default() };
    let (log, _) = sim::simulate(&plant, &p, &cfg).unwrap();
    let resid = joint_formats::predict::residual(&log, &p, &model.other_columns()).unwrap();
    let floor = sim::noise_floor(&log, &p, &model.other_columns(), &plant.sensors, seed);
    Run { log, resid, floor }
}

/// Trunk-right plant (noise-free unless `extra` has [sensors]) plus `extra` sections.
pub fn trunk(extra: &str, scn: &[ScenarioKind], secs: f64) -> Run {
    let plant = format!("{}\n{}\n", trunk_model(), extra);
    run_with(&plant, &trunk_model(), scn, secs, 7)
}

pub fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x;
        n += 1;
    }
    assert!(n > 20, "too few samples ({n}) in a bin");
    s / n as f64
}

pub fn rms(v: &[f64]) -> f64 {
    joint_formats::predict::rms(v)
}

pub fn sign(x: f64) -> f64 {
    if x >= 0.0 {
        1.0
    } else {
        -1.0
    }
}
