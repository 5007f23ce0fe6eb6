//! Every measured log in `shared/data/real` through the binary as a user would run it:
//! `jointctl import` then `jointctl identify --json`, with the outcome asserted (method,
//! statuses, held-out quality, written or refused and why). The reasons are in
//! docs/identification.md ("Results on measured data"). Files there that are not logs (licences,
//! READMEs, the authors' parameter files, the Panda trajectory coefficients, the UR5e summary)
//! are the references these outcomes are compared with. Without the data the tests say so and
//! check nothing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

use joint_formats::model_file::ModelFile;
use serde_json::Value;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn real(rel: &str) -> Option<PathBuf> {
    let p = PathBuf::from(ROOT).join("../shared/data/real").join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} not found", p.display());
        None
    }
}

fn jointctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_jointctl")).current_dir(ROOT).args(args).output().unwrap()
}

/// What one identify run said.
struct Outcome {
    written: bool,
    method: String,
    json: Value,
    stderr: String,
    model: PathBuf,
}

impl Outcome {
    fn status(&self, name: &str) -> String {
        let st = self.json["identified"]["status"].as_array().unwrap();
        let p = st
            .iter()
            .find(|p| format!("{}.{}", p["term"].as_str().unwrap(), p["param"].as_str().unwrap()) == name)
            .unwrap_or_else(|| panic!("no status for {name}"));
        p["status"].as_str().unwrap().to_string()
    }
    fn why(&self, name: &str) -> String {
        let st = self.json["identified"]["status"].as_array().unwrap();
        let p = st.iter().find(|p| format!("{}.{}", p["term"].as_str().unwrap(), p["param"].as_str().unwrap()) == name);
        p.map_or(String::new(), |p| p["why"].as_str().unwrap_or("").to_string())
    }
    fn determined(&self) -> Vec<String> {
        self.json["decision"]["params"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect()
    }
    fn quality(&self) -> Option<f64> {
        self.json["report"]["quality"]["value"].as_f64()
    }
}

/// import → identify --json; checks what every outcome must satisfy, whatever the log.
fn identify(dir: &Path, name: &str, format: &str, rel: &str, joint: Option<&str>, extra: &[&str]) -> Option<Outcome> {
    let input = real(rel)?;
    let log = dir.join(format!("{name}.csv"));
    let mut args =
        vec!["import", "--format", format, "--input", input.to_str().unwrap(), "--out", log.to_str().unwrap()];
    if let Some(j) = joint {
        args.extend(["--joint", j]);
    }
    let o = jointctl(&args);
    assert!(o.status.success(), "import {name}: {}", String::from_utf8_lossy(&o.stderr));
    let model = dir.join(format!("{name}.toml"));
    let mut args = vec!["identify", "--log", log.to_str().unwrap(), "--out", model.to_str().unwrap(), "--json"];
    args.extend(extra);
    let o = jointctl(&args);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let json: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{name}: {e}: {stderr}"));
    let out = Outcome {
        written: json["written"].as_bool().unwrap(),
        method: json["identified"]["method"].as_str().unwrap().to_string(),
        json,
        stderr,
        model,
    };
    eprintln!(
        "{name}: {} written={} determined={:?} quality={:?} {}",
        out.method,
        out.written,
        out.determined(),
        out.quality(),
        out.stderr.trim()
    );
    // The rules, on every log: exit status and file follow the decision; a written model holds
    // the determined parameters and passes the joint's check; a refusal says why; every
    // parameter not determined names the test that would pin it.
    assert_eq!(o.status.success(), out.written, "{name}");
    assert_eq!(out.model.exists(), out.written, "{name}");
    if out.written {
        let mf = ModelFile::read_file(&out.model).unwrap();
        mf.param_set().unwrap();
        assert!(!out.determined().is_empty());
        if let Some(q) = out.quality() {
            assert!(q >= 0.5 || extra.contains(&"--force"), "{name}: written below the threshold");
        }
    } else {
        assert!(out.stderr.contains("nothing written"), "{name}: {}", out.stderr);
    }
    for p in out.json["identified"]["status"].as_array().unwrap() {
        if p["status"] != "determined" {
            assert!(p["test"].is_string(), "{name}: {p}");
        }
    }
    Some(out)
}

const DFKI: &str = "dfki_simple_pendulum";

#[test]
fn dfki_simple_pendulum_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // sys-id swing-up: no papers' test, the regression; J and the weight collinear: nothing.
    let Some(o) = identify(d, "sysid", "dfki-pendulum", &format!("{DFKI}/sysid_pd_swingup_measured.csv"), None, &[])
    else {
        return;
    };
    assert_eq!(o.method, "joint-ls");
    assert!(!o.written && o.stderr.contains("determines no parameter"));
    for p in ["inertia.j", "weight.amplitude"] {
        assert!(o.status(p) == "weakly_determined" && o.why(p).contains("collinear"), "{p}: {}", o.why(p));
    }
    // energy shaping with and without 1 kg: refused on held-out quality
    let mut amp = Vec::new();
    for (n, f) in [("energy", "energy_shaping_measured.csv"), ("energy1kg", "energy_shaping_1kg_measured.csv")] {
        let o = identify(d, n, "dfki-pendulum", &format!("{DFKI}/{f}"), None, &[]).unwrap();
        assert!(!o.written && o.quality().unwrap() < 0.5 && o.stderr.contains("0.5"), "{n}: {}", o.stderr);
        assert_eq!(o.status("weight.amplitude"), "weakly_determined");
        amp.push(o.json["identified"]["weight"]["amplitude"].as_f64().unwrap());
    }
    assert!(amp[1] > amp[0], "the 1 kg run's weight {} is not above {}", amp[1], amp[0]);
    // --force writes the refused energy run: the determined parameters only
    let o = identify(
        d,
        "energy_forced",
        "dfki-pendulum",
        &format!("{DFKI}/energy_shaping_measured.csv"),
        None,
        &["--force"],
    )
    .unwrap();
    assert!(o.written && !o.json["decision"]["overridden"].as_array().unwrap().is_empty());
    let mf = ModelFile::read_file(&o.model).unwrap();
    assert!(mf.explicit(joint_core::params::ParamId::InertiaJ).is_none(), "a weakly determined J was written");
    // gravity compensation moved by hand: the commanded weight from the poses, written
    let o = identify(
        d,
        "gravcomp",
        "dfki-pendulum",
        &format!("{DFKI}/gravity_compensation_handmoved_measured.csv"),
        None,
        &[],
    )
    .unwrap();
    assert!(o.written && o.method == "papers");
    let a = o.json["identified"]["weight"]["amplitude"].as_f64().unwrap();
    assert!((a / (0.6755 * 9.81 * 0.5) - 1.0).abs() < 0.01, "{a}");
    assert_eq!(o.status("inertia.j"), "not_excited");
}

#[test]
fn panda_joints() {
    let dir = tempfile::tempdir().unwrap();
    let rel = "panda_gaz2019/panda_exciting_traj1_measured.csv";
    for j in 1..=7 {
        let js = j.to_string();
        let Some(o) = identify(dir.path(), &format!("panda{j}"), "panda-gaz", rel, Some(&js), &[]) else { return };
        // no static poses anywhere in the exciting trajectory
        assert!(o.json["identified"]["poses"].as_array().unwrap().is_empty(), "joint {j}");
        match j {
            // the wrist's friction: the torque is friction and little else
            7 => assert!(o.written && o.determined().iter().any(|p| p.starts_with("friction")), "joint 7"),
            // joint 1's J follows the arm's pose; joint 4's torque is the arm's gravity over
            // six other angles: a single-joint model predicts neither on held-out data
            1 | 4 => assert!(!o.written && o.quality().unwrap() < 0.5, "joint {j}"),
            _ => {}
        }
    }
}

#[test]
fn ur5e_friction_table() {
    let dir = tempfile::tempdir().unwrap();
    let rel = "ur5e_friction_calibration_aurt/ur5e_joint_friction_table.csv";
    for j in 0..=5 {
        let js = j.to_string();
        let Some(o) = identify(dir.path(), &format!("ur5e{j}"), "ur5e-friction", rel, Some(&js), &[]) else { return };
        assert!(o.written && o.method == "papers", "joint {j}");
        assert_eq!(o.determined(), ["friction.b", "friction.c"], "joint {j}");
        assert!(o.json["report"]["quality"]["metric"].as_str().unwrap().contains("friction points"));
    }
}

#[test]
fn jensen_free_swings() {
    let dir = tempfile::tempdir().unwrap();
    for k in 1..=3 {
        let rel = format!("free_swing_pendulum_jensen/free_swing_0{k}.csv");
        let Some(o) = identify(dir.path(), &format!("jensen{k}"), "jensen-free-swing", &rel, None, &[]) else { return };
        assert!(!o.written && o.stderr.contains("torque measured"), "run {k}: {}", o.stderr);
        assert!(o.why("inertia.j").contains("need K"));
    }
}

#[test]
fn dfki_double_pendulum_joints() {
    let dir = tempfile::tempdir().unwrap();
    let rel = "dfki_double_pendulum/sysid_design_C1_20230629-143339_trajectory.csv";
    for j in ["1", "2"] {
        let Some(o) = identify(dir.path(), &format!("dp{j}"), "dfki-double-pendulum", rel, Some(j), &[]) else {
            return;
        };
        assert_eq!(o.method, "joint-ls");
        // each link's J is collinear with its weight over the swinging record
        assert_eq!(o.status("inertia.j"), "weakly_determined", "joint {j}");
        if j == "1" {
            assert!(!o.written, "joint 1");
        }
    }
}
