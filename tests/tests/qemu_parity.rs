//! The core on an emulated Cortex-M4F computes the same bits as on the PC.
//!
//! `firmware-qemu`'s `qemu-parity` image runs `joint_core::vectors::session` under
//! `qemu-system-arm -M mps2-an386` and prints every record (f32 values as bit patterns);
//! this test runs the same session natively and compares every word. The first
//! difference fails the test with the record index and field named.
//!
//! Where the image's output comes from: `QEMU_PARITY_LOG=FILE` (scripts/qemu-test.sh runs
//! QEMU once and passes its stdout), otherwise the test builds the image itself (own
//! target dir under `target/`, so it does not wait on the outer cargo's lock) and runs
//! QEMU. Without qemu-system-arm or the thumbv7em target the test fails and says what is
//! missing: it never passes without having compared.

use joint_core::vectors::{self, first_mismatch, Mismatch, Record};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TARGET: &str = "thumbv7em-none-eabihf";
const QEMU_TIMEOUT: Duration = Duration::from_secs(60);

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

fn build_image() -> PathBuf {
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
        .args(["build", "--release", "-p", "firmware-qemu", "--bin", "qemu-parity", "--target", TARGET])
        .status()
        .expect("running cargo to build the QEMU parity image");
    assert!(
        status.success(),
        "building the QEMU parity image failed ({status}); is the target installed? \
         (rustup target add {TARGET})"
    );
    target_dir.join(TARGET).join("release").join("qemu-parity")
}

fn run_qemu(elf: &Path) -> String {
    let mut child = Command::new("qemu-system-arm")
        .args(["-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=7", "-kernel"])
        .arg(elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting qemu-system-arm (apt-get install qemu-system-arm)");
    let start = Instant::now();
    loop {
        match child.try_wait().expect("waiting for qemu-system-arm") {
            Some(_) => break,
            None if start.elapsed() > QEMU_TIMEOUT => {
                let _ = child.kill();
                panic!("qemu-system-arm did not finish within {QEMU_TIMEOUT:?}");
            }
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    let out = child.wait_with_output().expect("reading qemu-system-arm output");
    assert!(
        out.status.success(),
        "the parity image exited with {} (1 = panic, 2 = check failed, 3 = CPU fault); stderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("QEMU output is not UTF-8")
}

fn qemu_output() -> String {
    if let Some(path) = std::env::var_os("QEMU_PARITY_LOG") {
        return std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("reading QEMU_PARITY_LOG {}: {e}", Path::new(&path).display()));
    }
    run_qemu(&build_image())
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
    let (qemu, qemu_summary) = parse(&qemu_output());
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
    assert_eq!((summary.accepted, summary.rejected), (3, 5));
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
    let victim = other.iter().position(|r| r.index == 300).expect("session has a record 300");
    other[victim].words[1] ^= 1;
    let m = first_mismatch(&host, &other).expect("a flipped bit must be noticed");
    let text = describe(m, &host);
    assert!(text.starts_with("record 300 (u_motor)"), "{text}");
}
