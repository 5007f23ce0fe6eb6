//! jointctl as the master over slcan: `jointctl sim` serves two joints on one end of a
//! `socat` pty pair, `jointctl scan/push/pull` talk to them from the other end, so the Rust
//! slcan transport is exercised in both roles with wall-clock timing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn wait_for(p: &Path) {
    let t = Instant::now();
    while !p.exists() {
        assert!(t.elapsed() < Duration::from_secs(5), "{} never appeared", p.display());
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn jointctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_jointctl")).current_dir(ROOT).args(args).output().unwrap()
}

#[test]
fn scan_push_pull_over_a_socat_pty_pair() {
    if Command::new("socat").arg("-V").output().is_err() {
        panic!("socat missing: apt-get install socat");
    }
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("A"), dir.path().join("B"));
    let _socat = Kill(
        Command::new("socat")
            .args([
                "-d",
                "-d",
                &format!("pty,raw,echo=0,link={}", a.display()),
                &format!("pty,raw,echo=0,link={}", b.display()),
            ])
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    wait_for(&a);
    wait_for(&b);
    let _sim = Kill(
        Command::new(env!("CARGO_BIN_EXE_jointctl"))
            .current_dir(ROOT)
            .args(["sim", "--bus", &format!("slcan:{}", b.display()), "--node", "5", "--node", "6", "--seconds", "30"])
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let bus = format!("slcan:{}", a.display());
    let o = jointctl(&["scan", "--bus", &bus, "--seconds", "0.6", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let nodes: Vec<u64> = v["nodes"].as_array().unwrap().iter().map(|n| n["node"].as_u64().unwrap()).collect();
    assert_eq!(nodes, vec![5, 6]);

    let o = jointctl(&["push", "examples/models/trunk-right.toml", "--node", "6", "--bus", &bus, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    println!("push over slcan/pty: {v}");

    let out = dir.path().join("pulled.toml");
    let o = jointctl(&["pull", "--node", "6", "--bus", &bus, "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want =
        joint_formats::model_file::ModelFile::read_file(&Path::new(ROOT).join("examples/models/trunk-right.toml"))
            .unwrap()
            .raw_params()
            .unwrap();
    let got = joint_formats::model_file::ModelFile::read_file(&out).unwrap().raw_params().unwrap();
    assert_eq!(got, want);
}
