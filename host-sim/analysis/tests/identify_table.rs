//! Gravity table (arm paper §3.2.2) from static poses of a joint whose gravity also depends on
//! a second joint's angle: the identified table, fused with the identified weight term through
//! the firmware core's own `gravity()`, must reproduce the plant's static torque.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig};
use joint_analysis::identify::{self, Options, Quiet, Term};
use joint_core::control;
use joint_core::params::ParamId;

/// A trunk-like joint without friction whose unbalanced torque also depends on `q_shoulder`.
const PLANT: &str = r#"
name = "arm-joint"
[weight]
amplitude = 2.79
s = 0.8021409131831525
phi = -0.027
[inertia]
j = 0.5
[offset]
c0 = -0.59
[gravity_table]
axes = ["q", "q_shoulder"]
grid = [[0.0, 1.0, 2.0], [0.0, 0.5, 1.0]]
torque = [0.0, 0.3, 0.6, 0.2, 0.6, 1.1, 0.4, 0.9, 1.4]
[sensors]
q_resolution = 9.587e-6
qd_noise = 0.002
qdd_noise = 0.05
tau_noise = 0.15
u_noise = 0.1
"#;

#[test]
fn table_over_two_joints_reproduces_the_static_torque() {
    let plant = PlantFile::parse(PLANT, "plant.toml").unwrap();
    let truth = plant.model.param_set().unwrap();
    let cfg = SimConfig { scenarios: vec![ScenarioKind::Poses], seconds: 120.0, seed: 9, ..SimConfig::default() };
    let (log, _) = sim::simulate(&plant, &truth, &cfg).unwrap();
    assert!(log.other("q_shoulder").is_some());

    let opts = Options { terms: vec![Term::Weight, Term::Offset, Term::GravityTable], ..Options::default() };
    let (_, id) = identify::identify(std::slice::from_ref(&log), &opts, &Quiet).unwrap();
    let t = id.table.as_ref().unwrap();
    assert_eq!(t.axes, vec!["q".to_string(), "q_shoulder".to_string()]);
    let sm = t.sigma_model.unwrap();
    let mf = identify::model_file(&id, Some("arm")).unwrap();
    let found = mf.param_set().unwrap();
    assert!((f64::from(found.get(ParamId::TableSigmaModel)) - sm).abs() < 1e-6 && sm > 0.0);
    // Weight term alone (no table): the analytic model the table corrects.
    let mut no_table = mf.clone();
    no_table.table = None;
    no_table.set(ParamId::TableSigmaModel, 0.0, None);
    let weight_only = no_table.param_set().unwrap();

    // Compare at the logged static samples (where the table has data), the truth noise-free.
    let static_torque = |p: &joint_core::params::ParamSet, q: f64, qs: f64| {
        f64::from(control::gravity(p, q as f32, &[qs as f32, 0.0, 0.0]) + p.terms().c0)
    };
    let qs_col = log.other("q_shoulder").unwrap();
    let (mut e_table, mut e_weight, mut n) = (0.0, 0.0, 0.0);
    for s in id.segments[0].iter().filter(|s| s.kind == joint_analysis::identify::segments::SegKind::Static) {
        for i in (s.start..s.end).step_by(20) {
            let (q, qs) = (log.q[i], qs_col[i]);
            let tr = static_torque(&truth, q, qs);
            e_table += (static_torque(&found, q, qs) - tr).powi(2);
            e_weight += (static_torque(&weight_only, q, qs) - tr).powi(2);
            n += 1.0;
        }
    }
    let (e_table, e_weight) = ((e_table / n).sqrt(), (e_weight / n).sqrt());
    eprintln!(
        "table {}×{}: static RMS error {e_table:.4} N·m (weight term alone {e_weight:.4}); σ_m {sm:.4}, table RMS {:.4}, empty cells {}",
        t.grid[0].len(),
        t.grid[1].len(),
        t.rms,
        t.empty_cells
    );
    assert!(e_table < 0.1, "table RMS error {e_table}");
    let dir = tempfile::tempdir().unwrap();
    let (data, _) = identify::identify(std::slice::from_ref(&log), &opts, &Quiet).unwrap();
    let rep = identify::report::validate(&data, &opts, &id).unwrap();
    identify::report::write_dir(dir.path(), &rep, &id, &data).unwrap();
    assert!(std::fs::read_to_string(dir.path().join("gravity_table.svg")).unwrap().contains("q_shoulder"));
    assert!(e_table < 0.5 * e_weight, "table {e_table} vs weight alone {e_weight}");
}
