//! Printed benchmark of `identify` on a 1 M-sample log (issue 5: under 2 s on the 2-core
//! machine). `cargo bench -p host-sim --bench identify`. The log (sweep, poses and hand motion
//! of the trunk-right plant, 1 kHz) is simulated once and written as CSV; then reading it,
//! identifying, and the validation report's hold-out refit are each timed (best and median
//! of 5 runs).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::time::Instant;

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig};
use joint_analysis::identify::{self, Options, Quiet};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn stats(name: &str, mut v: Vec<f64>) {
    v.sort_by(f64::total_cmp);
    println!("{name:<32} best {:>7.3} s   median {:>7.3} s", v[0], v[v.len() / 2]);
}

fn main() {
    let plant =
        PlantFile::read_file(std::path::Path::new(&format!("{ROOT}/examples/plants/trunk-right.toml"))).unwrap();
    let ctrl = ModelFile::read_file(std::path::Path::new(&format!("{ROOT}/examples/models/trunk-right.toml"))).unwrap();
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Poses, ScenarioKind::Hand],
        seconds: 1_000_000.0 / 3.0 / 1000.0,
        seed: 1,
        ..SimConfig::default()
    };
    let (log, _) = sim::simulate(&plant, &ctrl.param_set().unwrap(), &cfg).unwrap();
    let dir = std::env::temp_dir().join(format!("identify-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("big.csv");
    log.write_file(&path).unwrap();
    println!("log: {} samples, {:.1} MB CSV", log.len(), std::fs::metadata(&path).unwrap().len() as f64 / 1e6);

    let opts = Options::default();
    let (mut read, mut ident, mut valid, mut total) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for _ in 0..5 {
        let t0 = Instant::now();
        let l = JointLog::read_file(&path).unwrap();
        let t1 = Instant::now();
        let (data, id) = identify::identify(std::slice::from_ref(&l), &opts, &Quiet).unwrap();
        identify::model_file(&id, Some("bench")).unwrap();
        let t2 = Instant::now();
        identify::report::validate(&data, &opts, &id).unwrap();
        let t3 = Instant::now();
        read.push((t1 - t0).as_secs_f64());
        ident.push((t2 - t1).as_secs_f64());
        valid.push((t3 - t2).as_secs_f64());
        total.push((t2 - t0).as_secs_f64());
    }
    stats("read CSV", read);
    stats("identify (4 terms)", ident);
    stats("read + identify", total);
    stats("validation refit (--report)", valid);
    let _ = std::fs::remove_dir_all(&dir);
}
