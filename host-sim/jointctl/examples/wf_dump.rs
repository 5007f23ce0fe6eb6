//! Development aid: runs the closed-loop fix workflow on one effect plant and keeps its log and
//! diagnosis for a look by hand.   cargo run --release -p jointctl --example wf_dump -- stribeck
#![allow(clippy::unwrap_used)]
use host_sim::plant::PlantFile;
use joint_formats::model_file::ModelFile;
use jointctl::closed_loop::workflow::run_workflow;
use jointctl::closed_loop::LoopConfig;
fn main() {
    let f = std::env::args().nth(1).unwrap();
    let plant = PlantFile::read_file(std::path::Path::new(&format!("examples/plants/trunk-right-{f}.toml"))).unwrap();
    let model = ModelFile::read_file(std::path::Path::new("examples/models/trunk-right.toml")).unwrap();
    let cfg = LoopConfig { fraction: Some(0.7), trials: 4, seconds: 10.0, seed: 1, ..LoopConfig::default() };
    let o = run_workflow(&plant, &model, &cfg, (&f, "trunk-right")).unwrap();
    o.log.write_file(std::path::Path::new(&format!("/tmp/wf/{f}.csv"))).unwrap();
    std::fs::write(format!("/tmp/wf/{f}.json"), o.diagnosis_json).unwrap();
}
