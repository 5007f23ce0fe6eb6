//! The core on an emulated Cortex-M4F computes the same bits as on the PC.
//!
//! `firmware-qemu`'s `qemu-parity` image runs `joint_core::vectors::session` under
//! `qemu-system-arm -M mps2-an386` and prints every record (f32 values as bit patterns);
//! this test runs the same session natively and compares every word. The first
//! difference fails the test with the record index and field named.
//!
//! The `qemu-canopen` image runs a scripted CANopen session through the core's node
//! (`firmware/qemu/src/canopen_session.rs`, included here by path so both sides run the one
//! script): every frame the node sends and every control output, compared as text line by
//! line; the first different byte fails the test with the step and its event named.
//!
//! Where an image's output comes from: `QEMU_PARITY_LOG=FILE` / `QEMU_CANOPEN_LOG=FILE`
//! (scripts/qemu-test.sh runs QEMU once and passes its stdout), otherwise the test builds
//! the image itself (own target dir under `target/`, so it does not wait on the outer
//! cargo's lock) and runs QEMU. Without qemu-system-arm or the thumbv7em target the test
//! fails and says what is missing: it never passes without having compared.

#[path = "../../firmware/qemu/src/canopen_session.rs"]
mod canopen_session;

use joint_core::canopen::ControlStep;
use joint_core::control::Controller;
use joint_core::fixed::ControllerFx;
use joint_core::vectors::{self, first_mismatch, Mismatch, Record};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TARGET: &str = "thumbv7em-none-eabihf";
const QEMU_TIMEOUT: Duration = Duration::from_secs(60);

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

fn build_image(bin: &str) -> PathBuf {
    let root = workspace_root();
    let target_dir = match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => PathBuf::from(d).join("qemu-parity"),
        None => root.join("target").join("qemu-parity"),
    };
    let target_dir = if target_dir.is_absolute() { target_dir } else { root.join(target_dir) };
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .current_dir(&root)
        .env("CARGO_TARGET_DIR", &target_dir)
        // the images are a workspace of their own (firmware/qemu/Cargo.toml)
        .args(["build", "--profile", "fw", "--manifest-path", "firmware/qemu/Cargo.toml", "--bin", bin])
        .args(["--target", TARGET])
        .status()
        .expect("running cargo to build the QEMU parity image");
    assert!(
        status.success(),
        "building the QEMU image {bin} failed ({status}); is the target installed? \
         (rustup target add {TARGET})"
    );
    target_dir.join(TARGET).join("fw").join(bin)
}

fn run_qemu(elf: &Path) -> String {
    use std::io::Read;
    let mut child = Command::new("qemu-system-arm")
        .args(["-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=7", "-kernel"])
        .arg(elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting qemu-system-arm (apt-get install qemu-system-arm)");
    // Drain both pipes while QEMU runs: an image printing more than a pipe buffer (64 KiB)
    // would otherwise block in its semihosting write until the timeout.
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            let _ = r.read_to_end(&mut v);
            v
        })
    };
    let stdout = drain(Box::new(child.stdout.take().expect("piped stdout")));
    let stderr = drain(Box::new(child.stderr.take().expect("piped stderr")));
    let start = Instant::now();
    let status = loop {
        match child.try_wait().expect("waiting for qemu-system-arm") {
            Some(st) => break st,
            None if start.elapsed() > QEMU_TIMEOUT => {
                let _ = child.kill();
                panic!("qemu-system-arm did not finish within {QEMU_TIMEOUT:?}");
            }
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    let out_stdout = stdout.join().expect("stdout reader");
    let out_stderr = stderr.join().expect("stderr reader");
    assert!(
        status.success(),
        "the QEMU image exited with {} (1 = panic, 2 = check failed, 3 = CPU fault); stderr:\n{}",
        status,
        String::from_utf8_lossy(&out_stderr)
    );
    String::from_utf8(out_stdout).expect("QEMU output is not UTF-8")
}

fn qemu_output(log_var: &str, bin: &str) -> String {
    if let Some(path) = std::env::var_os(log_var) {
        return std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("reading {log_var} {}: {e}", Path::new(&path).display()));
    }
    run_qemu(&build_image(bin))
}

/// Records and the summary line of the image's output; any other line is an error.
fn parse(text: &str) -> (Vec<Record>, String) {
    let mut records = Vec::new();
    let mut summary = String::new();
    for (n, line) in text.lines().enumerate() {
        if let Some(s) = line.strip_prefix("# summary ") {
            summary = s.to_string();
        } else {
            let r = Record::parse_line(line)
                .unwrap_or_else(|| panic!("QEMU output line {}: not a record: {line:?}", n + 1));
            records.push(r);
        }
    }
    (records, summary)
}

fn host_session() -> (Vec<Record>, vectors::Summary) {
    let mut v = Vec::new();
    let s = vectors::session(&mut |r: &Record| v.push(*r));
    (v, s)
}

fn describe(m: Mismatch, expected: &[Record]) -> String {
    match m {
        Mismatch::Word { index, word, expected: e, actual: a } => {
            let name = expected.iter().find(|r| r.index == index).map(|r| r.field_name(word)).unwrap_or("?");
            format!(
                "record {index} ({name}): host {e:08x} ({}), QEMU {a:08x} ({})",
                f32::from_bits(e),
                f32::from_bits(a)
            )
        }
        Mismatch::Shape { position } => format!("record {position}: tag or index differ"),
        Mismatch::Length { expected, actual } => format!("host has {expected} records, QEMU {actual}"),
    }
}

#[test]
fn qemu_matches_host_to_the_last_bit() {
    let (host, summary) = host_session();
    let (qemu, qemu_summary) = parse(&qemu_output("QEMU_PARITY_LOG", "qemu-parity"));
    let expected_summary = format!(
        "records={} steps={} accepted={} rejected={} rejected_but_changed={} unexpected={} unsafe={}",
        summary.records,
        summary.steps,
        summary.accepted,
        summary.rejected,
        summary.rejected_but_changed,
        summary.unexpected_results,
        summary.unsafe_outputs
    );
    if let Some(m) = first_mismatch(&host, &qemu) {
        panic!("QEMU and host differ, first difference at {}", describe(m, &host));
    }
    assert_eq!(qemu_summary, expected_summary, "session summary line");
    // The session itself must have exercised what it claims (old set kept on refusal...).
    assert_eq!((summary.accepted, summary.rejected), (6, 7));
    assert_eq!(summary.rejected_but_changed, 0);
    assert_eq!(summary.unexpected_results, 0);
    assert_eq!(summary.unsafe_outputs, 0);
    println!("QEMU parity: {} records, {} steps, every word identical", qemu.len(), summary.steps);
}

/// The comparison catches a single flipped bit and names where: what a firmware computing
/// one different number would look like.
#[test]
fn a_single_bit_difference_is_caught_and_named() {
    let (host, _) = host_session();
    let mut other = host.clone();
    let victim = other.iter().position(|r| r.index >= 300 && r.tag == vectors::Tag::Step).expect("a step record");
    let index = other[victim].index;
    other[victim].words[1] ^= 1;
    let m = first_mismatch(&host, &other).expect("a flipped bit must be noticed");
    let text = describe(m, &host);
    assert!(text.starts_with(&format!("record {index} (u_motor)")), "{text}");
    // and in the Q16.16 step's records
    let mut other = host.clone();
    let victim = other.iter().position(|r| r.index >= 300 && r.tag == vectors::Tag::Fixed).expect("a Q16.16 record");
    let index = other[victim].index;
    other[victim].words[0] ^= 1;
    let text = describe(first_mismatch(&host, &other).expect("noticed"), &host);
    assert!(text.starts_with(&format!("record {index} (fx_tau_out)")), "{text}");
}

/// The CANopen session natively: its lines as the image prints them, and the summary.
fn host_canopen() -> (Vec<String>, canopen_session::Summary) {
    host_canopen_with::<Controller>()
}

fn host_canopen_with<C: ControlStep>() -> (Vec<String>, canopen_session::Summary) {
    let (lines, summary, _) = host_canopen_fd_with::<C>();
    (lines, summary)
}

/// Both sessions as the image prints them: the classic one, then the CAN FD one.
fn host_canopen_fd_with<C: ControlStep>() -> (Vec<String>, canopen_session::Summary, canopen_session::Summary) {
    let mut lines = Vec::new();
    let mut emit = |l: &canopen_session::Line| {
        let mut s = String::new();
        l.write(&mut s).expect("formatting into a String");
        lines.push(s.trim_end().to_string());
    };
    let summary = canopen_session::run_with::<C>(&mut emit);
    let fd = canopen_session::run_fd_with::<C>(&mut emit);
    (lines, summary, fd)
}

/// The first line where QEMU's output differs from the host's, described with the step,
/// its event and the first differing field.
fn canopen_mismatch(host: &[String], qemu: &[&str]) -> Option<String> {
    for (n, (h, q)) in host.iter().zip(qemu).enumerate() {
        if h != q {
            let hw: Vec<&str> = h.split(' ').collect();
            let qw: Vec<&str> = q.split(' ').collect();
            let field = hw.iter().zip(&qw).position(|(a, b)| a != b).unwrap_or(hw.len().min(qw.len()));
            let kind = if h.starts_with("T ") {
                match field {
                    0..=2 => "kind/step/event".to_string(),
                    3 => "COB-ID".to_string(),
                    4 => "DLC".to_string(),
                    k => format!("data byte {}", k - 5),
                }
            } else {
                ["kind", "step", "tau_out", "u_motor", "c_c", "assist", "limited"]
                    .get(field)
                    .unwrap_or(&"field")
                    .to_string()
            };
            let step = hw.get(1).copied().unwrap_or("?");
            let what = if h.starts_with("T ") { hw.get(2).copied().unwrap_or("?") } else { "control" };
            return Some(format!("line {} (step {step}, {what}), {kind} differs:\n  host: {h}\n  QEMU: {q}", n + 1));
        }
    }
    if host.len() != qemu.len() {
        return Some(format!("host has {} lines, QEMU {}", host.len(), qemu.len()));
    }
    None
}

#[test]
fn canopen_session_on_qemu_matches_host_byte_for_byte() {
    canopen_session_matches::<Controller>("QEMU_CANOPEN_LOG", "qemu-canopen");
}

/// The same session on a node whose control step runs in Q16.16 (the FPU-less board's).
#[test]
fn canopen_session_q16_on_qemu_matches_host_byte_for_byte() {
    canopen_session_matches::<ControllerFx>("QEMU_CANOPEN_Q16_LOG", "qemu-canopen-q16");
}

fn canopen_session_matches<C: ControlStep>(log_var: &str, bin: &str) {
    let (host, summary, fd) = host_canopen_fd_with::<C>();
    let text = qemu_output(log_var, bin);
    let qemu: Vec<&str> = text.lines().filter(|l| !l.starts_with("# ")).collect();
    let qemu_summary =
        text.lines().find_map(|l| l.strip_prefix("# canopen ")).expect("the image printed no summary line");
    if let Some(m) = canopen_mismatch(&host, &qemu) {
        panic!("CANopen session: QEMU and host differ at {m}");
    }
    let mut expected_summary = String::new();
    summary.write(&mut expected_summary).expect("formatting into a String");
    assert_eq!(format!("# canopen {qemu_summary}"), expected_summary.trim_end(), "summary line");
    let qemu_fd = text.lines().find(|l| l.starts_with("# canopen-fd ")).expect("the image printed no FD summary");
    let mut expected_fd = String::new();
    fd.write_fd(&mut expected_fd).expect("formatting into a String");
    assert_eq!(qemu_fd, expected_fd.trim_end(), "FD summary line");

    // The FD session: TPDO3 every 5 ms while operational (steps 10..200), SDO answered in FD
    // for both FD requests, the shared command's slot (joint 5's value 5 × 7k at k = 9 → 3.15
    // N·m) taken and the
    // short frame refused with its EMCY.
    assert!((36..=39).contains(&fd.fd_tpdo), "{fd:?}");
    assert_eq!(fd.fd_sdo_replies, 2, "{fd:?}");
    assert_eq!(fd.fd_frames, fd.fd_tpdo + 2, "{fd:?}");
    assert_eq!(fd.fd_assist_centi, 315, "{fd:?}");
    assert!(fd.fd_short_kept && fd.emcy >= 1, "{fd:?}");
    assert!(host.iter().any(|l| l.contains(" poll 385 bd ")), "TPDO3 lines, FD with BRS, 32 bytes");

    // The session exercised what its script claims.
    assert_eq!(
        (summary.aborts, summary.expected_aborts_seen),
        (4, 4),
        "out-of-range, short SDO, plain commit, safety write while operational"
    );
    assert!(summary.committed_trunk_set, "the pushed trunk-joint set is committed whole");
    assert!(summary.refused_writes_changed_nothing);
    assert_eq!(summary.saves, 1);
    assert!(summary.emcy >= 2, "short RPDO and heartbeat loss each send an EMCY: {summary:?}");
    assert!(summary.tpdo > 100, "{summary:?}");
    assert!(summary.max_tau > 0.5, "torque while operational with the host: {summary:?}");
    assert_eq!(summary.final_tau, 0.0, "the watchdog faded the torque after the host went silent");
    println!(
        "QEMU CANopen session ({} node): {} lines ({} frames, {} control steps), every byte identical",
        C::ARITHMETIC.name(),
        host.len(),
        summary.frames,
        canopen_session::STEPS
    );
}

/// One changed byte in one frame, or one bit of one output, is caught and named.
#[test]
fn a_single_different_byte_in_the_canopen_session_is_caught_and_named() {
    let (host, _) = host_canopen();
    let n = host.iter().position(|l| l.starts_with("T ") && l.contains(" read-back ")).expect("a read-back line");
    let mut other: Vec<String> = host.clone();
    let last = other[n].len() - 1;
    let flipped = if other[n].ends_with('0') { '1' } else { '0' };
    other[n].replace_range(last.., &flipped.to_string());
    let refs: Vec<&str> = other.iter().map(String::as_str).collect();
    let m = canopen_mismatch(&host, &refs).expect("a changed byte must be noticed");
    assert!(m.contains("(step 00005, read-back), data byte 7 differs"), "{m}");

    let c = host.iter().position(|l| l.starts_with("C 00300 ")).expect("a control line at step 300");
    let mut other = host.clone();
    let mut w: Vec<String> = other[c].split(' ').map(str::to_string).collect();
    let bits = u32::from_str_radix(&w[2], 16).unwrap() ^ 1;
    w[2] = format!("{bits:08x}");
    other[c] = w.join(" ");
    let refs: Vec<&str> = other.iter().map(String::as_str).collect();
    let m = canopen_mismatch(&host, &refs).expect("a flipped bit must be noticed");
    assert!(m.contains("(step 00300, control), tau_out differs"), "{m}");

    let refs: Vec<&str> = host.iter().take(host.len() - 1).map(String::as_str).collect();
    assert!(canopen_mismatch(&host, &refs).unwrap().contains("lines"));
}
