//! `jointctl simulate` end to end: a log and a summary on success; on bad input a message that
//! names the file and key, a non-zero exit and no output file.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn jointctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_jointctl")).current_dir(ROOT).args(args).output().unwrap()
}

#[test]
fn simulate_writes_a_log_and_a_json_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("log.csv");
    let o = jointctl(&[
        "simulate",
        "--plant",
        "examples/plants/trunk-right.toml",
        "--controller",
        "examples/models/trunk-right.toml",
        "--scenario",
        "sweep,hand",
        "--seconds",
        "2",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["summary"]["samples"], 4000);
    assert_eq!(v["summary"]["mode"], "torque");
    let r = v["summary"]["rms_residual"].as_f64().unwrap();
    let f = v["summary"]["noise_floor"].as_f64().unwrap();
    assert!(r < 1.5 * f, "residual {r} floor {f}");
    let log = joint_formats::log::JointLog::read_file(&out).unwrap();
    assert_eq!(log.len(), 4000);
}

#[test]
fn bad_input_names_the_problem_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[inertia]\nj = 1.0\n[friction]\nc = 1.0\nwobble = 2.0\n").unwrap();
    let out = dir.path().join("log.csv");
    let o = jointctl(&[
        "simulate",
        "--plant",
        bad.to_str().unwrap(),
        "--controller",
        "examples/models/trunk-right.toml",
        "--scenario",
        "sweep",
        "--seconds",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.toml") && err.contains("wobble") && err.contains("line 5"), "{err}");
    assert!(!out.exists());
    let o = jointctl(&[
        "simulate",
        "--plant",
        "examples/plants/trunk-right.toml",
        "--controller",
        "examples/models/trunk-right.toml",
        "--scenario",
        "sweep,dance",
        "--seconds",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("dance"));
    assert!(!out.exists());
}

#[test]
fn help_explains_the_scenarios() {
    let o = jointctl(&["simulate", "--help"]);
    let h = String::from_utf8_lossy(&o.stdout);
    for w in ["--plant", "--controller", "sweep", "poses", "free", "hand", "--seed", "--json"] {
        assert!(h.contains(w), "help lacks {w}");
    }
}
