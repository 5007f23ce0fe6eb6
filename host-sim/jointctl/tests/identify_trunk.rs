//! Identification of the trunk joints (trunk paper Table 1, both joints) from simulated logs
//! with the example plant's sensor noise: one log with a speed sweep, static poses and hand
//! motion, identified in-process and through the `jointctl` binary.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig};
use joint_analysis::identify::{self, Options, Quiet};
use joint_core::params::ParamId;
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
const DEG: f64 = std::f64::consts::PI / 180.0;
const SPEEDS_DEG: [f64; 10] = [5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0];

fn read(rel: &str) -> String {
    std::fs::read_to_string(format!("{ROOT}/{rel}")).unwrap()
}

/// The right plant as shipped; the left plant is the left model with the right plant's sensors
/// (the examples ship no left plant file).
fn plant_text(side: &str) -> String {
    match side {
        "right" => read("examples/plants/trunk-right.toml"),
        _ => {
            let right = read("examples/plants/trunk-right.toml");
            let sensors = &right[right.find("[sensors]").unwrap()..];
            format!("{}\n{}", read("examples/models/trunk-left.toml"), sensors)
        }
    }
}

fn simulate(side: &str, seed: u64) -> (JointLog, ModelFile) {
    let plant = PlantFile::parse(&plant_text(side), "plant.toml").unwrap();
    let ctrl = ModelFile::parse(&read(&format!("examples/models/trunk-{side}.toml")), "model.toml").unwrap();
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Poses, ScenarioKind::Hand],
        seconds: 40.0,
        seed,
        ..SimConfig::default()
    };
    let (log, _) = sim::simulate(&plant, &ctrl.param_set().unwrap(), &cfg).unwrap();
    (log, plant.model)
}

struct Errors {
    friction_rel: Vec<(f64, f64)>,
    static_rms: f64,
    j_rel: f64,
}

/// Compares an identified model with the truth: friction at every swept speed, the static
/// curve (weight + offset) over the angles the poses covered, the inertia.
fn errors(found: &ModelFile, truth: &ModelFile, q_lo: f64, q_hi: f64) -> Errors {
    let f = |m: &ModelFile, v: f64| {
        m.value(ParamId::FrictionA) * v * v + m.value(ParamId::FrictionB) * v + m.value(ParamId::FrictionC)
    };
    let st = |m: &ModelFile, q: f64| {
        m.value(ParamId::WeightAmplitude) * (m.value(ParamId::WeightS) * q + m.value(ParamId::WeightPhi)).sin()
            + m.value(ParamId::OffsetC0)
    };
    let friction_rel = SPEEDS_DEG.iter().map(|d| (*d, (f(found, d * DEG) / f(truth, d * DEG) - 1.0).abs())).collect();
    let n = 200;
    let static_rms = ((0..=n)
        .map(|k| q_lo + (q_hi - q_lo) * k as f64 / n as f64)
        .map(|q| (st(found, q) - st(truth, q)).powi(2))
        .sum::<f64>()
        / (n + 1) as f64)
        .sqrt();
    let j_rel = (found.value(ParamId::InertiaJ) / truth.value(ParamId::InertiaJ) - 1.0).abs();
    Errors { friction_rel, static_rms, j_rel }
}

fn check_side(side: &str) {
    let (log, truth) = simulate(side, 11);
    let (_, id) = identify::identify(std::slice::from_ref(&log), &Options::default(), &Quiet).unwrap();
    let found = identify::model_file(&id, Some("found")).unwrap();
    let (q_lo, q_hi) = id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
    assert!(id.poses.len() >= 8, "{side}: only {} poses found", id.poses.len());
    let e = errors(&found, &truth, q_lo, q_hi);
    let worst = e.friction_rel.iter().fold(0.0f64, |m, (_, r)| m.max(*r));
    eprintln!(
        "{side}: friction worst {:.2} %, static RMS {:.4} N·m, J {:.4} (true {}) {:.2} %",
        worst * 100.0,
        e.static_rms,
        found.value(ParamId::InertiaJ),
        truth.value(ParamId::InertiaJ),
        e.j_rel * 100.0
    );
    for (d, rel) in &e.friction_rel {
        assert!(*rel < 0.03, "{side}: friction at {d} deg/s off by {:.2} %", rel * 100.0);
    }
    assert!(e.static_rms < 0.1, "{side}: static curve RMS error {:.4} N·m", e.static_rms);
    assert!(e.j_rel < 0.03, "{side}: inertia off by {:.2} %", e.j_rel * 100.0);
    // The true friction coefficients lie inside (or within a hair of) the reported 95 % CIs'
    // neighbourhood: the CI must at least be finite and ordered.
    let fr = id.friction.as_ref().unwrap();
    for (lo, hi) in fr.ci95 {
        assert!(lo.is_finite() && hi.is_finite() && lo <= hi);
    }
}

#[test]
fn trunk_right_table1_recovered() {
    check_side("right");
}

#[test]
fn trunk_left_table1_recovered() {
    check_side("left");
}

#[test]
fn validation_report_scores_held_out_data_and_draws_plots() {
    let (log, _) = simulate("right", 5);
    let opts = Options::default();
    let (data, id) = identify::identify(std::slice::from_ref(&log), &opts, &Quiet).unwrap();
    let rep = identify::report::validate(&data, &opts, &id).unwrap();
    assert!(rep.refit_error.is_none(), "{:?}", rep.refit_error);
    let overall = rep.scores.iter().find(|s| s.what.starts_with("overall")).unwrap();
    assert!(overall.held_out && overall.n > 10_000);
    // The paper's validation bound (RMSE < 1.6 N·m, r² > 0.98); the sensor noise alone is
    // ≈ 0.33 N·m here.
    assert!(overall.rmse < 0.6 && overall.r2 > 0.98, "{overall:?}");
    let dir = tempfile::tempdir().unwrap();
    identify::report::write_dir(dir.path(), &rep, &id, &data).unwrap();
    for f in ["report.md", "report.json", "friction.svg", "static.svg", "inertia.svg", "overall.svg"] {
        let text = std::fs::read_to_string(dir.path().join(f)).unwrap();
        assert!(!text.is_empty(), "{f}");
    }
    assert!(std::fs::read_to_string(dir.path().join("friction.svg")).unwrap().starts_with("<svg"));
}

/// The "must show": `jointctl identify --log LOG.csv --out MODEL.toml` on one log with
/// sweeps, poses and hand motion made by `jointctl simulate`.
#[test]
fn cli_identify_one_log_must_show() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("trunk.csv");
    let model = dir.path().join("identified.toml");
    let bin = env!("CARGO_BIN_EXE_jointctl");
    let st = std::process::Command::new(bin)
        .args(["simulate", "--plant", &format!("{ROOT}/examples/plants/trunk-right.toml")])
        .args(["--controller", &format!("{ROOT}/examples/models/trunk-right.toml")])
        .args(["--scenario", "sweep,poses,hand", "--seconds", "40", "--seed", "3", "--out"])
        .arg(&log)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let out = std::process::Command::new(bin)
        .args(["identify", "--log"])
        .arg(&log)
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let found = ModelFile::read_file(&model).unwrap();
    found.param_set().unwrap();
    let truth = PlantFile::parse(&plant_text("right"), "plant.toml").unwrap().model;
    // The poses cover the scenario's range: 0…116.5° less a 2° margin.
    let e = errors(&found, &truth, 2.0 * DEG, 114.5 * DEG);
    let worst = e.friction_rel.iter().fold(0.0f64, |m, (_, r)| m.max(*r));
    eprintln!(
        "cli: friction worst {:.2} %, static RMS {:.4} N·m, J {:.2} %",
        worst * 100.0,
        e.static_rms,
        e.j_rel * 100.0
    );
    for (d, rel) in &e.friction_rel {
        assert!(*rel < 0.05, "friction at {d} deg/s off by {:.2} %", rel * 100.0);
    }
    assert!(e.static_rms < 0.15, "static curve RMS error {:.4} N·m", e.static_rms);
    assert!(e.j_rel < 0.05, "inertia off by {:.2} %", e.j_rel * 100.0);
}

#[test]
fn cli_refuses_a_bad_log_naming_row_and_column_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("bad.csv");
    std::fs::write(&log, "t,q,qd,u,tau\n0,0,0,1,0\n0.001,0,NaN,1,0\n").unwrap();
    let model = dir.path().join("m.toml");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .args(["identify", "--log"])
        .arg(&log)
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 3") && err.contains("`qd`"), "{err}");
    assert!(!model.exists());
}

fn hand_only(log: &JointLog) -> JointLog {
    // Keep only the hand motion (the last third): no matched ± plateaus, no held poses.
    let n = log.len();
    let cut = |v: &Vec<f64>| v[2 * n / 3..].to_vec();
    JointLog {
        t: cut(&log.t),
        q: cut(&log.q),
        qd: log.qd.as_ref().map(cut),
        qdd: log.qdd.as_ref().map(cut),
        u: log.u.as_ref().map(cut),
        tau: log.tau.as_ref().map(cut),
        ..JointLog::default()
    }
}

/// `--method papers` on a log without plateaus: friction is `not excited`, with the test that
/// would pin it, and nothing is written (the decision names `--method joint-ls`).
#[test]
fn a_log_without_plateaus_gets_friction_not_excited_and_the_test() {
    use joint_analysis::identify::status::Status;
    let (log, _) = simulate("right", 2);
    let hand = hand_only(&log);
    let opts =
        Options { terms: vec![identify::Term::Friction], method: identify::Method::Papers, ..Options::default() };
    let (data, id) = identify::identify(&[hand], &opts, &Quiet).unwrap();
    let c = id.status_of("friction", "c").unwrap();
    assert_eq!(c.status, Status::NotExcited, "{c:?}");
    assert!(c.why.contains("plateau") && c.test.unwrap().contains("plateaus"), "{c:?}");
    let rep = identify::report::validate(&data, &opts, &id).unwrap();
    let d = identify::decide::decide(&data, &id, &rep.quality, None, true).unwrap();
    assert!(!d.written && d.refused[0].contains("--method joint-ls"), "{:?}", d.refused);
}

/// `--method auto` on the same log chooses the whole-log regression and says why; the hand
/// motion (torque off in the scenario? no: the plant's controller runs) pins friction there.
#[test]
fn auto_chooses_the_regression_for_a_log_without_tests_and_names_it() {
    let (log, truth) = simulate("right", 2);
    let hand = hand_only(&log);
    let (_, id) = identify::identify(&[hand], &Options::default(), &Quiet).unwrap();
    assert_eq!(id.method, identify::Method::JointLs);
    assert!(id.method_why.contains("no test of the papers' procedures"), "{}", id.method_why);
    let j = id.status_of("inertia", "j").unwrap();
    eprintln!("hand motion only, joint-ls: {}", identify::status::text(&id.status));
    if j.determined() {
        let rel = j.value.unwrap() / truth.value(ParamId::InertiaJ) - 1.0;
        assert!(rel.abs() < 0.05, "J off by {:.1} %", 100.0 * rel);
    }
}

/// `--window START:END:motion` restricts the inertia fit to the hand-moved third (the paper's
/// §3.4 data); the inertia stays within 3 %.
#[test]
fn motion_window_uses_only_the_hand_motion() {
    use joint_analysis::identify::segments::{SegKind, Window};
    let (log, truth) = simulate("right", 11);
    let opts =
        Options { windows: vec![Window { start: 80.0, end: 120.0, kind: SegKind::Motion }], ..Options::default() };
    let (_, id) = identify::identify(std::slice::from_ref(&log), &opts, &Quiet).unwrap();
    let inr = id.inertia.as_ref().unwrap();
    let rel = inr.j / truth.value(ParamId::InertiaJ) - 1.0;
    eprintln!("motion window: J {:.4} ({:+.2} %), {} samples", inr.j, rel * 100.0, inr.n);
    assert!(rel.abs() < 0.03 && inr.n < 40_000, "J {} from {} samples", inr.j, inr.n);
}

/// Without the logged `qdd` (and then without `qd` too) the accelerations come from the
/// zero-phase filtered derivative; the Table 1 bounds still hold.
#[test]
fn derived_velocity_and_acceleration_suffice() {
    let (mut log, truth) = simulate("right", 11);
    for drop_qd in [false, true] {
        log.qdd = None;
        if drop_qd {
            log.qd = None;
        }
        let (_, id) = identify::identify(std::slice::from_ref(&log), &Options::default(), &Quiet).unwrap();
        let found = identify::model_file(&id, Some("found")).unwrap();
        let (q_lo, q_hi) =
            id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
        let e = errors(&found, &truth, q_lo, q_hi);
        let worst = e.friction_rel.iter().fold(0.0f64, |m, (_, r)| m.max(*r));
        eprintln!(
            "no qdd{}: friction worst {:.2} %, static RMS {:.4} N·m, J {:.2} %",
            if drop_qd { ", no qd" } else { "" },
            worst * 100.0,
            e.static_rms,
            e.j_rel * 100.0
        );
        assert!(worst < 0.03 && e.static_rms < 0.1 && e.j_rel < 0.03);
    }
}

/// The preparation stage's refusals are identification's: a log in milliseconds and a `qd` in
/// degrees per second are refused with the reason, nothing is written; a good log's output
/// names the smoother.
#[test]
fn cli_refuses_what_the_preparation_refuses_and_names_the_smoother() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_jointctl");
    let write_log = |name: &str, ms: bool, deg: bool| {
        let mut s = String::from("t,q,qd,u,tau\n");
        for i in 0..3000 {
            let t = i as f64 * 1e-3;
            let (q, qd) = ((2.0 * t).sin(), 2.0 * (2.0 * t).cos());
            let qd = if deg { qd.to_degrees() } else { qd };
            s += &format!("{},{q},{qd},{},0\n", if ms { t * 1000.0 } else { t }, 3.0 * q.sin());
        }
        let p = dir.path().join(name);
        std::fs::write(&p, s).unwrap();
        p
    };
    for (name, ms, deg, why) in [("ms.csv", true, false, "milliseconds"), ("deg.csv", false, true, "degrees")] {
        let log = write_log(name, ms, deg);
        let model = dir.path().join("m.toml");
        let o = std::process::Command::new(bin)
            .args(["identify", "--log"])
            .arg(&log)
            .arg("--out")
            .arg(&model)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(why), "{name}: {err}");
        assert!(!model.exists());
    }
    let (log, _) = simulate("right", 3);
    let path = dir.path().join("trunk.csv");
    log.write_file(&path).unwrap();
    let o = std::process::Command::new(bin)
        .args(["identify", "--log"])
        .arg(&path)
        .arg("--out")
        .arg(dir.path().join("m.toml"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && out.contains("smoother: local cubic") && out.contains("method: papers"), "{out}");
}
