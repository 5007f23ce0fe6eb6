//! The CAN subcommands of `jointctl` end to end on `--bus sim` (the in-process bus with
//! simulated joints): JSON output, files that the spec's readers accept, errors that name what
//! is wrong.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn jointctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(ROOT)
        .env_remove("JOINTCTL_BUS")
        .args(args)
        .output()
        .unwrap()
}

fn json(o: &std::process::Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn push_json_reports_timing_within_budget() {
    let v = json(&jointctl(&["push", "examples/models/trunk-right.toml", "--node", "5", "--bus", "sim", "--json"]));
    assert_eq!(v["node"], 5);
    let ratio = v["ratio"].as_f64().unwrap();
    assert!((1.0..=1.2).contains(&ratio), "{v}");
    assert_eq!((v["time_basis"].as_str(), v["bitrate"].as_u64()), (Some("bus"), Some(1_000_000)), "{v}");
    assert_eq!(v["frames"].as_u64().unwrap(), 2 * v["sdo_transfers"].as_u64().unwrap());
    // the simulated bus has a bit-timing model: the human line compares with the wire
    let o =
        jointctl(&["push", "examples/models/trunk-right.toml", "--node", "5", "--bus", "sim", "--bitrate", "500000"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && out.contains("wire minimum of those frames at 500 kbit/s"), "{out}");
    // --real-bus means an slcan adapter: anywhere else it is refused before any traffic
    let o = jointctl(&["push", "examples/models/trunk-right.toml", "--node", "5", "--bus", "sim", "--real-bus"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--real-bus is for slcan"), "{err}");
}

#[test]
fn push_of_an_invalid_model_names_the_key_and_sends_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, "[compensation]\nfraction = 1.5\n").unwrap();
    let o = jointctl(&["push", p.to_str().unwrap(), "--node", "5", "--bus", "sim"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("fraction"), "{err}");
}

#[test]
fn log_writes_a_joint_log_the_spec_reader_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("can.csv");
    let v = json(&jointctl(&[
        "log",
        "--node",
        "5",
        "--bus",
        "sim",
        "--seconds",
        "0.5",
        "--start",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    // TPDOs every 10 ms
    let rows = v["rows"].as_u64().unwrap();
    assert!((48..=52).contains(&rows), "{v}");
    let log = joint_formats::log::JointLog::read_file(&out).unwrap();
    assert_eq!(log.len() as u64, rows);
    // fault bits and NMT state ride along as optional columns; nothing before the first TPDO2
    // (whose q̈ and temperature a row would otherwise hold as placeholders)
    assert_eq!(log.unknown, vec!["faults".to_string(), "nmt".to_string()]);
    let text = std::fs::read_to_string(&out).unwrap();
    // the NMT cell is empty until the node's first heartbeat, then its last state byte (0 is the
    // boot-up message)
    assert!(
        text.lines().skip(1).all(|l| l.ends_with(',') || l.ends_with(",0") || l.ends_with(",5") || l.ends_with(",127")),
        "{text}"
    );
    assert!(v["tpdo1_before_first_tpdo2"].as_u64().is_some(), "{v}");
}

#[test]
fn log_without_start_says_why_nothing_came() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("none.csv");
    let o = jointctl(&["log", "--node", "5", "--bus", "sim", "--seconds", "0.2", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("operational"));
    assert!(!out.exists());
}

#[test]
fn scan_and_watch_json() {
    let v =
        json(&jointctl(&["scan", "--bus", "sim", "--sim-node", "3", "--sim-node", "4", "--seconds", "0.3", "--json"]));
    let nodes: Vec<u64> = v["nodes"].as_array().unwrap().iter().map(|n| n["node"].as_u64().unwrap()).collect();
    assert_eq!(nodes, vec![3, 4]);
    assert_eq!(v["nodes"][0]["device_name"], "joint-node");
    let o = jointctl(&["watch", "--bus", "sim", "--sim-node", "3", "--seconds", "0.5", "--start", "--json"]);
    let last = String::from_utf8_lossy(&o.stdout).lines().last().unwrap().to_string();
    let w: serde_json::Value = serde_json::from_str(&last).unwrap();
    assert_eq!(w["nodes"][0]["state"], "operational");
    assert_eq!(w["nodes"][0]["faults"].as_array().unwrap().len(), 0);
}

#[test]
fn bus_budget_matches_hand_counted_frames() {
    // 1 joint at 1000 Hz, classic 1 Mbit/s, worst case 47 + 8n + ⌊(34 + 8n − 1)/4⌋ bits: two
    // 8-byte frames (135 bits) and one 2-byte frame (47 + 16 + 12 = 75) per ms, plus two 1-byte
    // heartbeats (47 + 8 + 10 = 65) at 10 Hz: (270 + 75)·1000 + 2·65·10 = 346 300 bit/s.
    let v = json(&jointctl(&["bus-budget", "--joints", "1", "--rate", "1000", "--json"]));
    let w = v["load_worst"].as_f64().unwrap();
    assert!((w - 0.3463).abs() < 1e-6, "{w}");
    assert!(v["load_typical"].as_f64().unwrap() < w);
    let o = jointctl(&["bus-budget", "--joints", "0", "--rate", "100"]);
    assert!(!o.status.success());
}

#[test]
fn eds_is_written_and_lists_every_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("joint.eds");
    let o = jointctl(&["eds", "--out", p.to_str().unwrap()]);
    assert!(o.status.success());
    let text = std::fs::read_to_string(&p).unwrap();
    for d in joint_core::params::PARAMS.iter() {
        assert!(text.contains(&format!("ParameterName={}\n", d.name)), "{}", d.name);
    }
    assert!(text.contains("DefaultValue=$NODEID+0x180"));
}

#[test]
fn sim_refuses_the_in_process_bus_and_bad_node_ids() {
    let o = jointctl(&["sim", "--bus", "sim", "--node", "5"]);
    assert!(!o.status.success());
    let o = jointctl(&["sim", "--bus", "slcan:/nonexistent/tty", "--node", "0"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("1..=127"));
    let o = jointctl(&["sim", "--bus", "slcan:/nonexistent/tty", "--node", "5", "--seconds", "0.1"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/tty"));
}

/// Issue 21's first reproduction: `push`, `pull` and `save` without `--bus` used to run on the
/// simulated bus and print "pushed … saved", exit 0, with nothing leaving the machine. Now every
/// CAN command refuses without a bus, a configured default (`JOINTCTL_BUS`) must name a real one,
/// and on `--bus sim` every output says it is simulated.
#[test]
fn can_commands_need_a_bus_and_the_simulation_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.toml");
    let o_s = out.to_str().unwrap();
    for args in [
        vec!["push", "examples/models/trunk-right.toml", "--node", "5", "--save"],
        vec!["pull", "--node", "5", "--out", o_s],
        vec!["save", "--node", "5"],
        vec!["scan", "--seconds", "0.1"],
        vec!["watch", "--seconds", "0.1"],
        vec!["log", "--node", "5", "--seconds", "0.1", "--out", o_s],
    ] {
        let o = jointctl(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} ran without a bus");
        assert!(err.contains("no bus given") && err.contains("--bus sim"), "{args:?}: {err}");
        let o = Command::new(env!("CARGO_BIN_EXE_jointctl"))
            .current_dir(ROOT)
            .env("JOINTCTL_BUS", "sim")
            .args(&args)
            .output()
            .unwrap();
        assert!(!o.status.success(), "{args:?} ran on JOINTCTL_BUS=sim");
        assert!(String::from_utf8_lossy(&o.stderr).contains("must name a real bus"));
    }
    assert!(!out.exists(), "a refused command wrote its output");
    let o = jointctl(&["push", "examples/models/trunk-right.toml", "--node", "5", "--bus", "sim", "--save"]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("[simulated bus: in-process joints, not hardware]"));
    let v = json(&jointctl(&["pull", "--node", "5", "--bus", "sim", "--out", o_s, "--json"]));
    assert_eq!(v["simulated"], true);
    let o = jointctl(&["save", "--node", "5", "--bus", "sim"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("simulated bus"));
    // a configured real bus is taken (and fails here for want of the adapter, naming it)
    let o = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(ROOT)
        .env("JOINTCTL_BUS", "slcan:/nonexistent/tty")
        .args(["save", "--node", "5"])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("/nonexistent/tty"));
}
