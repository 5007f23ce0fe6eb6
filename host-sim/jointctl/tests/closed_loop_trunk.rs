//! Closed-loop trials of both trunk joints at F = 0.7 through the `jointctl closed-loop` binary:
//! the JSON's structure, stability, and a tracking RMSE in the range the physics allows.
//!
//! Why the range: with the node's law `u = K·q + F·C_c` the delivered torque is `tau = u − d`,
//! so the tracking error is `tau − K·q = −(1 − F)·d − F·(d − C_c)`. When the model matches the
//! plant (these plants are the paper's Table 1 values) the second term is small, so each trial's
//! RMSE must lie close to `(1 − F)·RMS(d)` — not at a number tuned to the paper.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

fn run(joint: &str, out: &std::path::Path) -> serde_json::Value {
    let st = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args(["closed-loop", "--plant", &format!("examples/plants/trunk-{joint}.toml"), "--model"])
        .arg(format!("examples/models/trunk-{joint}.toml"))
        .args(["--fraction", "0.7", "--trials", "4", "--seconds", "10", "--seed", "3", "--json"])
        .arg(out)
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
}

#[test]
fn both_trunk_joints_at_f07() {
    let dir = tempfile::tempdir().unwrap();
    for (joint, paper) in [("right", (2.04, 0.79)), ("left", (2.51, 0.62))] {
        let j = run(joint, &dir.path().join(format!("{joint}.json")));
        assert_eq!(j["fraction"].as_f64(), Some(0.7), "{joint}");
        assert_eq!(j["paper"]["this_joint"].as_str(), Some(joint));
        assert_eq!(j["paper"][joint]["tracking_rmse_mean"].as_f64(), Some(paper.0));
        assert_eq!(j["paper"][joint]["tracking_rmse_sd"].as_f64(), Some(paper.1));
        assert!(j["push"]["sdo_transfers"].as_u64().unwrap() > 40, "the model went over the bus: {}", j["push"]);
        assert_eq!(j["stable"].as_bool(), Some(true), "{joint}: {}", j["trials"]);
        let trials = j["trials"].as_array().unwrap();
        assert_eq!(trials.len(), 4);
        let mut rm = Vec::new();
        for t in trials {
            let rmse = t["rmse"].as_f64().unwrap();
            let d = t["rms_disturbance"].as_f64().unwrap();
            assert_eq!(t["stable"].as_bool(), Some(true));
            assert_eq!(t["samples"].as_u64(), Some(10_000));
            // the operator really moved the joint (hand speeds of tens of °/s)
            assert!(t["qd_rms"].as_f64().unwrap() > 0.2, "{t}");
            let share = rmse / (0.3 * d);
            assert!((0.8..1.3).contains(&share), "{joint}: RMSE {rmse} vs (1 − F)·RMS(d) = {}", 0.3 * d);
            // and the model in the loop misses little of d (lagged q̇/q̈ only)
            assert!(t["model_error_rmse"].as_f64().unwrap() < 0.1 * d, "{t}");
            rm.push(rmse);
        }
        let mean = rm.iter().sum::<f64>() / rm.len() as f64;
        let sd = (rm.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (rm.len() - 1) as f64).sqrt();
        assert!((j["tracking_rmse_mean"].as_f64().unwrap() - mean).abs() < 1e-9);
        assert!((j["tracking_rmse_sd"].as_f64().unwrap() - sd).abs() < 1e-9);
    }
}

#[test]
fn bad_fraction_is_refused_with_the_flag_named() {
    let o = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args([
            "closed-loop",
            "--plant",
            "examples/plants/trunk-right.toml",
            "--model",
            "examples/models/trunk-right.toml",
            "--fraction",
            "1.5",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    // refused by the option's parser with the parameter table's range, before the files are read
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("'1.5' for '--fraction") && err.contains("0 ≤ x ≤ 1"), "{err}");
}
