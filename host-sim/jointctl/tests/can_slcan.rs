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

/// A `socat` pty pair in a temporary folder: (folder, socat, end A, end B); both ends exist.
fn pty_pair() -> (tempfile::TempDir, Kill, std::path::PathBuf, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let (socat, a, b) = pty_pair_in(dir.path(), "");
    (dir, socat, a, b)
}

/// A `socat` pty pair as `dir/A<tag>` and `dir/B<tag>`: (socat, end A, end B); both ends exist.
fn pty_pair_in(dir: &std::path::Path, tag: &str) -> (Kill, std::path::PathBuf, std::path::PathBuf) {
    if Command::new("socat").arg("-V").output().is_err() {
        panic!("socat missing: apt-get install socat");
    }
    let (a, b) = (dir.join(format!("A{tag}")), dir.join(format!("B{tag}")));
    let socat = Kill(
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
    (socat, a, b)
}

fn jointctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_jointctl")).current_dir(ROOT).args(args).output().unwrap()
}

#[test]
fn scan_push_pull_over_a_socat_pty_pair() {
    let (dir, _socat, a, b) = pty_pair();
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
    // Issue 21: a pty has no bit timing, yet a "wire minimum" and a ratio of 0.484 were printed.
    // Over slcan the time is host/transport time unless the user says the adapter is on a real
    // bus at its @BITRATE.
    assert_eq!(v["time_basis"], "host", "{v}");
    assert!(v["wire_minimum_us"].is_null() && v["ratio"].is_null(), "{v}");
    let o = jointctl(&["push", "examples/models/trunk-right.toml", "--node", "6", "--bus", &bus]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("host/transport time, not bus time") && !out.contains("ratio"), "{out}");
    let o =
        jointctl(&["push", "examples/models/trunk-right.toml", "--node", "6", "--bus", &bus, "--real-bus", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((v["time_basis"].as_str(), v["bitrate"].as_u64()), (Some("bus"), Some(1_000_000)), "{v}");
    assert!(v["ratio"].as_f64().is_some(), "{v}");

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

    // status names the set in force by its CRC and says whether the pushed model is it
    let model = "examples/models/trunk-right.toml";
    let st = |node: &str| {
        let o = jointctl(&["status", "--node", node, "--bus", &bus, "--model", model, "--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let v = st("6");
    assert_eq!((v["model_in_force"].as_bool(), v["staged_pending"].as_bool()), (Some(true), Some(false)), "{v}");
    let crc6 = v["active_crc"].as_str().unwrap().to_string();
    assert_eq!(st("5")["model_in_force"], false);

    // Issue 21: a push refused at commit (a safety-relevant value on an operational joint)
    // used to leave its values staged, so reads returned them and a later commit by anyone
    // made them live. Now the push says which set runs and leaves nothing staged.
    let o = jointctl(&["watch", "--bus", &bus, "--sim-node", "6", "--seconds", "0.2", "--start"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let unsafe_model = dir.path().join("ratio.toml");
    let text = std::fs::read_to_string(Path::new(ROOT).join(model)).unwrap();
    std::fs::write(&unsafe_model, text.replace("fraction = 0.7", "fraction = 0.35")).unwrap();
    let o = jointctl(&["push", unsafe_model.to_str().unwrap(), "--node", "6", "--bus", &bus]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a safety-relevant change went through on an operational joint");
    assert!(err.contains("runs its previous set"), "{err}");
    let v = st("6");
    assert_eq!(v["active_crc"].as_str().unwrap(), crc6, "{v}");
    assert_eq!(v["staged_pending"], false, "the refused push left a staged set: {v}");

    // a staged set another tool left (written here by hand over the same pty): status shows
    // it, discard drops it, the set in force never changed
    {
        let spec: joint_can::BusSpec = bus.parse().unwrap();
        let mut m = joint_can::master::Master::new(joint_can::open(&spec).unwrap());
        m.write(6, 0x2002, 0, &3.0f32.to_le_bytes()).unwrap(); // friction_c, staged only
    }
    let v = st("6");
    assert_eq!(v["staged_pending"], true, "{v}");
    let o = jointctl(&["discard", "--node", "6", "--bus", &bus, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!((d["dropped"].as_bool(), d["active_crc"].as_str()), (Some(true), Some(crc6.as_str())), "{d}");
    assert_eq!(st("6")["staged_pending"], false);
}

/// Issue 21: `jointctl sim` exited ("Operation timed out") when the master stopped reading the
/// pty. Here the master starts the joint (so it streams TPDOs at 100 Hz) and then never reads:
/// the pty and socat's buffers fill, the simulated joint drops what the bus will not take,
/// counts it, and serves to the end.
#[test]
fn sim_keeps_serving_when_the_master_stops_reading() {
    use std::io::Write as _;
    let (_dir, _socat, a, b) = pty_pair();
    let sim = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(ROOT)
        .args(["sim", "--bus", &format!("slcan:{}", b.display()), "--node", "5", "--seconds", "8", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    // TPDO1 and TPDO2 every 1 ms (event timers 0x1800/0x1801 sub 5), NMT start for node 5, as
    // slcan "t" frames; then silence: nothing on this side ever reads
    let mut pa = std::fs::OpenOptions::new().write(true).open(&a).unwrap();
    pa.write_all(b"t60582B00180501000000\rt60582B01180501000000\rt00020105\r").unwrap();
    let o = sim.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "sim died under a stalled master: {err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    println!("sim under a stalled master: {v}");
    assert!(v["frames_dropped"].as_u64().unwrap() > 0, "the buffers never filled: {v}");
    assert!(v["seconds"].as_f64().unwrap() >= 7.9, "{v}");
}

/// A push killed mid-transfer (SIGKILL: no Ctrl-C handler runs, nothing is discarded by the
/// tool) used to leave its values staged on the joint, waiting for anyone's next commit. Now
/// the joint discards a staged set whose master went quiet (3 s, firmware/core
/// canopen/node/stage_owner.rs), says so in 0x2201, and the set in force never changed.
#[test]
fn a_killed_push_leaves_nothing_staged_and_the_set_in_force_unchanged() {
    let (dir, _socat, a, b) = pty_pair();
    let _sim = Kill(
        Command::new(env!("CARGO_BIN_EXE_jointctl"))
            .current_dir(ROOT)
            .args(["sim", "--bus", &format!("slcan:{}", b.display()), "--node", "5", "--seconds", "60"])
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let bus = format!("slcan:{}", a.display());
    let st = || {
        let o = jointctl(&["status", "--node", "5", "--bus", &bus, "--json"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    // two models, pushed in turn, so every push changes the set
    let model = Path::new(ROOT).join("examples/models/trunk-right.toml");
    let other = dir.path().join("other.toml");
    let text = std::fs::read_to_string(&model).unwrap();
    std::fs::write(&other, text.replace("fraction = 0.7", "fraction = 0.65")).unwrap();
    assert_ne!(std::fs::read_to_string(&other).unwrap(), text);
    // A push over a pty is done some 15 ms after it starts (measured; ~10 ms of it staging):
    // kill it after a delay stepped across that, until a kill lands while it stages.
    let mut staged = None;
    for k in 0..100u64 {
        let before = st()["active_crc"].as_str().unwrap().to_string();
        let m = if k % 2 == 0 { &other } else { &model };
        let mut push = Command::new(env!("CARGO_BIN_EXE_jointctl"))
            .current_dir(ROOT)
            .args(["push", m.to_str().unwrap(), "--node", "5", "--bus", &bus, "--pre-operational"])
            .stderr(Stdio::null())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_micros(500 * (k % 50)));
        push.kill().unwrap(); // SIGKILL
        push.wait().unwrap();
        let v = st();
        if v["staged_pending"] == true {
            assert_eq!(v["active_crc"].as_str().unwrap(), before, "staged and committed? {v}");
            staged = Some((v, before, k));
            break;
        }
    }
    let (v, before, k) = staged.expect("no kill landed while the push was staging");
    println!("right after the kill (attempt {k}): {v}");
    std::thread::sleep(Duration::from_millis(3500));
    let v = st();
    assert_eq!(v["staged_pending"], false, "the killed push's values are still staged: {v}");
    assert_eq!(v["active_crc"].as_str().unwrap(), before, "{v}");
    let spec: joint_can::BusSpec = bus.parse().unwrap();
    let mut m = joint_can::master::Master::new(joint_can::open(&spec).unwrap());
    assert_eq!(m.read(5, 0x2201, 1).unwrap(), vec![8], "commit error code 8: staged set discarded");
    let why = m.read_string(5, 0x2201, 3).unwrap();
    assert!(why.contains("discarded") && why.contains(&before), "{why}");
}

/// A CAN bus between slcan ptys: every frame line one port writes goes to all the others, as a
/// bus delivers a frame to every node; commands and acknowledgements stay with their port.
/// Each port is written by a thread of its own, fed through a queue: a port nobody drains (the
/// pty of a `jointctl push` that has exited, whose buffer fills) must not hold up the frames to
/// the others, as a node that left a bus does not stop it. With one writer for all, the sim's
/// answers to the controller waited behind a write to the exited push's full pty, and the
/// controller's upload in flight timed out some 170 ms after every push (half of the runs on an
/// idle machine). The threads end when socat goes (their reads and writes fail).
fn hub(ports: &[std::path::PathBuf]) {
    use std::io::{Read, Write};
    use std::sync::mpsc;
    let files: Vec<std::fs::File> =
        ports.iter().map(|p| std::fs::OpenOptions::new().read(true).write(true).open(p).unwrap()).collect();
    let senders: Vec<mpsc::Sender<Vec<u8>>> = files
        .iter()
        .map(|f| {
            let (tx, rx) = mpsc::channel::<Vec<u8>>();
            let mut writer = f.try_clone().unwrap();
            std::thread::spawn(move || {
                while let Ok(line) = rx.recv() {
                    if writer.write_all(&line).is_err() {
                        return;
                    }
                }
            });
            tx
        })
        .collect();
    for (i, f) in files.into_iter().enumerate() {
        let mut reader = f;
        let others: Vec<_> = senders.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, o)| o.clone()).collect();
        std::thread::spawn(move || {
            let (mut line, mut buf) = (Vec::new(), [0u8; 256]);
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 {
                    return;
                }
                for &b in &buf[..n] {
                    if b != b'\r' {
                        line.push(b);
                        continue;
                    }
                    if matches!(line.first(), Some(b't' | b'b' | b'd')) {
                        line.push(b'\r');
                        for o in &others {
                            let _ = o.send(line.clone());
                        }
                    }
                    line.clear();
                }
            }
        });
    }
}

/// What one run of two masters beside each other saw.
struct TwoMasters {
    /// `jointctl push --json`'s output and whether it exited 0
    push: (bool, serde_json::Value, String),
    /// the controller's uploads done and its errors
    done: u32,
    errors: Vec<String>,
    /// 0x1201 sub 1, 2, 3 as the controller read them at the end
    cobs: (u32, u32, Vec<u8>),
    /// frames `jointctl sim` dropped because the pty would not take them (host too loaded)
    dropped: u64,
}

/// Three slcan ptys joined into one bus (a hub): `jointctl sim` serves node 5, a controller
/// (a master in this process) runs segmented uploads on channel 1 without pause, and
/// `jointctl push` with `push_args` pushes a set at the same time.
fn two_masters_over_slcan(push_args: &[&str]) -> TwoMasters {
    let dir = tempfile::tempdir().unwrap();
    let mut pairs = Vec::new();
    for k in 0..3 {
        pairs.push(pty_pair_in(dir.path(), &k.to_string()));
    }
    hub(&pairs.iter().map(|(_, a, _)| a.clone()).collect::<Vec<_>>());
    let sim = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .current_dir(ROOT)
        .args(["sim", "--bus", &format!("slcan:{}", pairs[0].2.display()), "--node", "5", "--seconds", "60", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let tool = format!("slcan:{}", pairs[1].2.display());
    // channel 2 configured once (through channel 1, before the controller starts)
    let o = jointctl(&["status", "--node", "5", "--bus", &tool, "--sdo-channel", "2", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let spec: joint_can::BusSpec = format!("slcan:{}", pairs[2].2.display()).parse().unwrap();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let controller = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut m = joint_can::master::Master::new(joint_can::open(&spec).unwrap());
            m.heartbeat_us = 0;
            // what the pty buffered before this end was opened (the status command's answers)
            // is no answer to this master: heard and dropped first
            m.listen(Duration::from_millis(300)).unwrap();
            let (mut done, mut errors) = (0u32, Vec::new());
            while !stop.load(std::sync::atomic::Ordering::SeqCst) {
                match m.read_string(5, 0x1008, 0) {
                    Ok(s) if s == "joint-node" => done += 1,
                    other => errors.push(format!("{other:?}")),
                }
            }
            let cobs = (m.read_u32(5, 0x1201, 1), m.read_u32(5, 0x1201, 2), m.read(5, 0x1201, 3));
            (done, errors, cobs)
        })
    };
    std::thread::sleep(Duration::from_millis(500));
    let mut args = vec!["push", "examples/models/trunk-right.toml", "--node", "5", "--bus", &tool, "--json"];
    args.extend_from_slice(push_args);
    let o = jointctl(&args);
    std::thread::sleep(Duration::from_millis(200));
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    let (done, errors, cobs) = controller.join().unwrap();
    // SIGTERM: the sim stops cleanly and prints its summary (frames dropped included)
    Command::new("kill").args(["-TERM", &sim.id().to_string()]).status().unwrap();
    let summary = sim.wait_with_output().unwrap();
    let sv: serde_json::Value = serde_json::from_slice(&summary.stdout).unwrap_or_default();
    TwoMasters {
        push: (
            o.status.success(),
            serde_json::from_slice(&o.stdout).unwrap_or_default(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        ),
        done,
        errors,
        cobs: (cobs.0.unwrap_or(0), cobs.1.unwrap_or(0), cobs.2.unwrap_or_default()),
        dropped: sv["frames_dropped"].as_u64().unwrap_or(u64::MAX),
    }
}

/// Issue 21: jointctl always used the joint's default SDO channel, so a tool and a controller
/// shared one transfer. `jointctl push --sdo-channel 2` beside a controller's uploads on channel
/// 1 (three slcan ptys on one bus): neither disturbs the other (no retries, no errors), the set
/// runs, and 0x1201 holds the COB-IDs jointctl gave it. Without the option the same run fails.
/// A run in which the simulated joint had to drop frames (the host too loaded to drain its
/// pty: a lost frame, not a shared transfer) is run again, up to three times.
#[test]
fn push_on_the_second_sdo_channel_beside_a_controller_on_the_first() {
    let mut run = None;
    for attempt in 1..=3 {
        let r = two_masters_over_slcan(&["--sdo-channel", "2"]);
        println!(
            "attempt {attempt}: controller beside the push: {} uploads, errors {:?}; sim dropped {} frames",
            r.done, r.errors, r.dropped
        );
        // A run where the joint dropped frames, or the controller only timed out (a loaded
        // host stalls one of the five processes past the 1 s SDO timeout; transfers that share
        // a channel show up as aborts and wrong answers, not only as timeouts), is run again.
        let only_timeouts = !r.errors.is_empty() && r.errors.iter().all(|e| e.contains("Timeout"));
        if r.dropped == 0 && !only_timeouts {
            run = Some(r);
            break;
        }
    }
    let r = run.expect("every attempt dropped frames or timed out: the host is too loaded for this test");
    let (ok, v, err) = &r.push;
    assert!(ok, "{err}");
    assert_eq!((v["ok"].as_bool(), v["retries"].as_u64()), (Some(true), Some(0)), "{v}");
    assert!(r.errors.is_empty(), "the push disturbed the controller: {:?}", r.errors);
    assert!(r.done > 20, "the controller ran beside the push: {} uploads", r.done);
    assert_eq!(r.cobs, (0x645, 0x5C5, vec![0x7F]));
}

/// A node id of 64 or more has no default COB-IDs for channel 2: they are named, or the command
/// is refused before any SDO transfer.
#[test]
fn the_second_channel_needs_named_cob_ids_from_node_64() {
    let o = jointctl(&["pull", "--node", "70", "--bus", "sim", "--sdo-channel", "2", "--out", "/dev/null"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--sdo-cob-ids"), "{err}");
    let o = jointctl(&[
        "pull",
        "--node",
        "70",
        "--bus",
        "sim",
        "--sdo-channel",
        "2",
        "--sdo-cob-ids",
        "0x6A0,0x6A1",
        "--json",
        "--out",
        "/dev/null",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
