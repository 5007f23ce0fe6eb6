//! The fraction sweep with sensor delay and filtering: full compensation must go unstable,
//! the paper's F = 0.7 must not.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

#[test]
fn sweep_finds_instability_at_high_fraction_with_delay() {
    let dir = tempfile::tempdir().unwrap();
    let (json, svg) = (dir.path().join("sweep.json"), dir.path().join("sweep.svg"));
    let o = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .args([
            "closed-loop",
            "--plant",
            "examples/plants/trunk-right-delay.toml",
            "--model",
            "examples/models/trunk-right.toml",
        ])
        .args(["--sweep-fraction", "--trials", "2", "--seconds", "8", "--json"])
        .arg(&json)
        .arg("--svg")
        .arg(&svg)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["sensor_delay_s"].as_f64(), Some(0.01));
    let pts = j["sweep"].as_array().unwrap();
    assert_eq!(pts.len(), 11);
    let at = |f: f64| pts.iter().find(|p| (p["fraction"].as_f64().unwrap() - f).abs() < 1e-9).unwrap();
    for f in [0.0, 0.3, 0.5, 0.7] {
        assert_eq!(at(f)["stable"].as_bool(), Some(true), "F = {f}: {}", at(f));
    }
    assert_eq!(at(1.0)["stable"].as_bool(), Some(false), "full compensation with 10 ms delay should oscillate");
    let onset = j["instability_onset_fraction"].as_f64().expect("an onset");
    assert!(onset > 0.7 && onset <= 1.0, "onset {onset}");
    // while stable, more compensation tracks better
    let r = |f: f64| at(f)["tracking_rmse_mean"].as_f64().unwrap();
    assert!(r(0.0) > r(0.3) && r(0.3) > r(0.5) && r(0.5) > r(0.7));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
    assert_eq!(text.matches("<title>F = ").count(), 11, "one marker per point");
    assert!(text.contains("N·m, unstable ("), "the unstable points are marked as such");
}
