//! Nothing the user has is lost, and outputs go where the user points and nowhere else: the
//! real binary against the users' reproductions (an output onto an input, `--out /dev/null` as
//! root), FIFOs, read-only targets, report folders, stdout, and a write that fails midway.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::fs;
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
const BIN: &str = env!("CARGO_BIN_EXE_jointctl");

fn jointctl(dir: &Path, args: &[&str]) -> Output {
    Command::new(BIN).current_dir(dir).args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The names in `dir`, sorted (temporary files start with a dot and would show here).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    v.sort();
    v
}

/// A folder with `run.csv` (a 3 s simulated log) and `m.toml` (the model it ran with).
fn workspace() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    fs::copy(format!("{EXAMPLES}/models/trunk-right.toml"), d.path().join("m.toml")).unwrap();
    let o = simulate(d.path(), "run.csv", "3");
    assert!(o.status.success(), "{}", stderr(&o));
    d
}

fn simulate(dir: &Path, out: &str, seconds: &str) -> Output {
    let plant = format!("{EXAMPLES}/plants/trunk-right.toml");
    let model = format!("{EXAMPLES}/models/trunk-right.toml");
    jointctl(dir, &["simulate", "--plant", &plant, "--controller", &model, "--seconds", seconds, "--out", out])
}

/// `diagnose --log run.csv --model m.toml --emit-model OUT`: refused, the log byte for byte as
/// before, no file added.
fn emit_model_onto_the_log_is_refused(out: &str, how: &str) {
    let d = workspace();
    if out == "link.csv" {
        std::os::unix::fs::symlink("run.csv", d.path().join(out)).unwrap();
    }
    if out == "hard.csv" {
        fs::hard_link(d.path().join("run.csv"), d.path().join(out)).unwrap();
    }
    let before = fs::read(d.path().join("run.csv")).unwrap();
    let listing = names(d.path());
    let o = jointctl(d.path(), &["diagnose", "--log", "run.csv", "--model", "m.toml", "--emit-model", out]);
    let err = stderr(&o);
    assert!(!o.status.success(), "exit 0: {err}");
    assert!(err.contains(&format!("--emit-model {out}")) && err.contains("--log run.csv"), "{err}");
    assert!(err.contains(how), "{err}");
    assert_eq!(fs::read(d.path().join("run.csv")).unwrap(), before, "the log changed");
    assert_eq!(names(d.path()), listing);
    assert!(o.stdout.is_empty(), "the diagnosis ran before the refusal");
}

#[test]
fn emit_model_onto_the_log_is_refused_and_the_log_kept() {
    emit_model_onto_the_log_is_refused("run.csv", "the same file");
}

#[test]
fn emit_model_onto_a_symlink_to_the_log_is_refused() {
    emit_model_onto_the_log_is_refused("link.csv", "symbolic link");
}

#[test]
fn emit_model_onto_a_hard_link_to_the_log_is_refused() {
    emit_model_onto_the_log_is_refused("hard.csv", "hard link");
}

#[test]
fn two_outputs_of_one_run_onto_one_file_or_one_stdout_are_refused() {
    let d = workspace();
    let args = |a: &str, b: &str| {
        jointctl(d.path(), &["diagnose", "--log", "run.csv", "--model", "m.toml", "--json", a, "--emit-model", b])
    };
    let o = args("x.out", "./x.out");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--json x.out") && stderr(&o).contains("--emit-model ./x.out"), "{}", stderr(&o));
    let o = args("-", "-");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("stdout"), "{}", stderr(&o));
    assert_eq!(names(d.path()), ["m.toml", "run.csv"]);
    // simulate's --json summary and --out - would share stdout
    let plant = format!("{EXAMPLES}/plants/trunk-right.toml");
    let o = jointctl(d.path(), &["simulate", "--plant", &plant, "--controller", "m.toml", "--out", "-", "--json"]);
    assert!(!o.status.success() && stderr(&o).contains("--json (stdout)"), "{}", stderr(&o));
    // the controller model as the output
    let o = jointctl(d.path(), &["simulate", "--plant", &plant, "--controller", "m.toml", "--out", "m.toml"]);
    assert!(!o.status.success() && stderr(&o).contains("--controller m.toml"), "{}", stderr(&o));
    assert_eq!(
        fs::read(d.path().join("m.toml")).unwrap(),
        fs::read(format!("{EXAMPLES}/models/trunk-right.toml")).unwrap()
    );
}

#[test]
fn out_dev_null_stays_a_character_device() {
    let d = tempfile::tempdir().unwrap();
    let before = fs::metadata("/dev/null").unwrap();
    let dev_listing = names(Path::new("/dev"));
    let o = simulate(d.path(), "/dev/null", "1");
    assert!(o.status.success(), "{}", stderr(&o));
    let after = fs::metadata("/dev/null").unwrap();
    assert!(after.file_type().is_char_device(), "/dev/null is no longer a device");
    assert_eq!((after.ino(), after.rdev()), (before.ino(), before.rdev()));
    assert_eq!(after.len(), 0);
    let left: Vec<String> = names(Path::new("/dev")).into_iter().filter(|n| n.starts_with(".null")).collect();
    assert!(left.is_empty(), "temporary files left in /dev: {left:?}");
    assert!(names(Path::new("/dev")).len() <= dev_listing.len() + 1);
}

#[test]
fn a_fifo_is_written_in_place_and_stays_a_fifo() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("pipe");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success(), "mkfifo failed");
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let mut text = String::new();
            fs::File::open(&fifo).unwrap().read_to_string(&mut text).unwrap();
            text
        })
    };
    let o = simulate(d.path(), "pipe", "1");
    if !reader.is_finished() {
        // the command never opened the FIFO: open it once without blocking so the reader ends
        use std::os::unix::fs::OpenOptionsExt;
        const O_NONBLOCK: i32 = 0o4000; // Linux
        let _ = fs::OpenOptions::new().write(true).custom_flags(O_NONBLOCK).open(&fifo);
    }
    let text = reader.join().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(text.starts_with("t,q,qd,qdd,u,tau\n") && text.lines().count() == 1001, "{} bytes", text.len());
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "the FIFO was replaced");
    assert_eq!(names(d.path()), ["pipe"]);
}

#[test]
fn a_read_only_target_is_refused_and_unchanged() {
    let d = workspace();
    let ro = d.path().join("run.csv");
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o444)).unwrap();
    let before = fs::read(&ro).unwrap();
    let o = simulate(d.path(), "run.csv", "1");
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("--out run.csv") && err.contains("read-only"), "{err}");
    assert_eq!(fs::read(&ro).unwrap(), before);
    assert_eq!(fs::metadata(&ro).unwrap().permissions().mode() & 0o777, 0o444);
    assert_eq!(names(d.path()), ["m.toml", "run.csv"]);
}

#[test]
fn a_folder_or_a_missing_parent_as_the_target_is_refused() {
    let d = workspace();
    fs::create_dir(d.path().join("sub")).unwrap();
    let o = simulate(d.path(), "sub", "1");
    assert!(!o.status.success() && stderr(&o).contains("is a folder"), "{}", stderr(&o));
    let o = simulate(d.path(), "nowhere/log.csv", "1");
    assert!(!o.status.success() && stderr(&o).contains("the folder nowhere does not exist"), "{}", stderr(&o));
    assert_eq!(names(d.path()), ["m.toml", "run.csv", "sub"]);
    assert!(names(&d.path().join("sub")).is_empty());
}

#[test]
fn out_dash_writes_the_log_to_stdout_and_the_summary_to_stderr() {
    let d = tempfile::tempdir().unwrap();
    let o = simulate(d.path(), "-", "1");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.starts_with("t,q,qd,qdd,u,tau\n") && text.lines().count() == 1001);
    let err = String::from_utf8(o.stderr).unwrap();
    assert!(err.contains("wrote - (1000 samples"), "{err}");
    assert!(names(d.path()).is_empty());
}

/// `sh -c`: run jointctl with writes beyond `blocks` 512-byte blocks failing (RLIMIT_FSIZE,
/// EFBIG; SIGXFSZ ignored so the write returns an error instead of killing the process). Works
/// as root, where a read-only folder would not stop anything.
fn jointctl_with_file_size_limit(dir: &Path, blocks: u32, args: &[&str]) -> Output {
    Command::new("sh")
        .current_dir(dir)
        .arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {blocks} && exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_write_failing_midway_leaves_the_old_file_and_no_temporary_file() {
    let d = workspace();
    let before = fs::read(d.path().join("run.csv")).unwrap();
    let plant = format!("{EXAMPLES}/plants/trunk-right.toml");
    let args = ["simulate", "--plant", &plant, "--controller", "m.toml", "--seconds", "20", "--out"];
    // the 3 s log is ~300 KB; a 20 s one does not fit under 1 MB
    let o = jointctl_with_file_size_limit(d.path(), 2048, &[&args[..], &["run.csv"]].concat());
    let err = stderr(&o);
    assert!(!o.status.success(), "the write did not fail: {err}");
    assert!(err.contains("--out run.csv") && err.to_lowercase().contains("too large"), "{err}");
    assert_eq!(fs::read(d.path().join("run.csv")).unwrap(), before, "the old log changed");
    assert_eq!(names(d.path()), ["m.toml", "run.csv"], "a temporary file stayed");
    // and a new path is not created at all
    let o = jointctl_with_file_size_limit(d.path(), 2048, &[&args[..], &["new.csv"]].concat());
    assert!(!o.status.success());
    assert_eq!(names(d.path()), ["m.toml", "run.csv"]);
}

/// A log identify can work on (sweep, poses, hand), written once per test.
fn identify_workspace() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    let plant = format!("{EXAMPLES}/plants/trunk-right.toml");
    let model = format!("{EXAMPLES}/models/trunk-right.toml");
    let o = jointctl(
        d.path(),
        &[
            "simulate",
            "--plant",
            &plant,
            "--controller",
            &model,
            "--scenario",
            "sweep,poses,hand",
            "--seconds",
            "40",
            "--seed",
            "3",
            "--out",
            "t.csv",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    d
}

fn identify(dir: &Path, out: &str, report: &str) -> Output {
    jointctl(dir, &["identify", "--log", "t.csv", "--out", out, "--report", report, "--quiet"])
}

#[test]
fn a_report_folder_is_replaced_whole_and_a_foreign_folder_refused() {
    let d = identify_workspace();
    let o = identify(d.path(), "m.toml", "rep");
    assert!(o.status.success(), "{}", stderr(&o));
    let first = names(&d.path().join("rep"));
    assert!(first.contains(&"report.md".to_string()) && first.contains(&"friction.svg".to_string()), "{first:?}");
    // a second run replaces the previous report as a whole (a stale plot would not survive)
    fs::write(d.path().join("rep/gravity_table.svg"), "<svg>stale</svg>").unwrap();
    let o = identify(d.path(), "m.toml", "rep");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(names(&d.path().join("rep")), first);
    assert_eq!(names(d.path()), ["m.toml", "rep", "t.csv"]);
    // a folder holding something identify does not write is refused before any work
    fs::write(d.path().join("rep/notes.md"), "mine").unwrap();
    let model_before = fs::read(d.path().join("m.toml")).unwrap();
    let o = identify(d.path(), "m2.toml", "rep");
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("--report rep") && err.contains("notes.md"), "{err}");
    assert_eq!(fs::read_to_string(d.path().join("rep/notes.md")).unwrap(), "mine");
    assert_eq!(fs::read(d.path().join("m.toml")).unwrap(), model_before);
    assert_eq!(names(d.path()), ["m.toml", "rep", "t.csv"]);
    // an input inside the report folder
    fs::remove_file(d.path().join("rep/notes.md")).unwrap();
    let o = jointctl(d.path(), &["identify", "--log", "rep/report.md", "--out", "m3.toml", "--report", "rep"]);
    assert!(!o.status.success() && stderr(&o).contains("inside --report rep"), "{}", stderr(&o));
}

#[test]
fn a_report_failing_midway_leaves_the_old_report_and_no_model() {
    let d = identify_workspace();
    let o = identify(d.path(), "m.toml", "rep");
    assert!(o.status.success(), "{}", stderr(&o));
    let old: Vec<(String, Vec<u8>)> = names(&d.path().join("rep"))
        .into_iter()
        .map(|n| (n.clone(), fs::read(d.path().join("rep").join(&n)).unwrap()))
        .collect();
    fs::remove_file(d.path().join("m.toml")).unwrap();
    // 8 blocks (4 KiB): the model fits, the report's plots do not
    let o = jointctl_with_file_size_limit(
        d.path(),
        8,
        &["identify", "--log", "t.csv", "--out", "m.toml", "--report", "rep", "--quiet", "--name", "second"],
    );
    assert!(!o.status.success(), "the report did not fail: {}", stderr(&o));
    assert!(stderr(&o).contains("--report rep"), "{}", stderr(&o));
    let now: Vec<(String, Vec<u8>)> = names(&d.path().join("rep"))
        .into_iter()
        .map(|n| (n.clone(), fs::read(d.path().join("rep").join(&n)).unwrap()))
        .collect();
    assert_eq!(now, old, "the old report changed");
    assert_eq!(names(d.path()), ["rep", "t.csv"], "a model, a temporary file or folder stayed");
}

#[test]
fn folder_outputs_of_other_commands_refuse_foreign_folders_before_any_work() {
    let d = workspace();
    fs::create_dir(d.path().join("out")).unwrap();
    fs::write(d.path().join("out/keep.txt"), "mine").unwrap();
    let plant = format!("{EXAMPLES}/plants/trunk-right.toml");
    let t0 = std::time::Instant::now();
    for args in [
        vec!["diagnose-bench", "--cases", "50", "--dump", "out"],
        vec!["closed-loop", "--plant", &plant, "--model", "m.toml", "--workflow", "out"],
        vec!["arm-gravity", "--json", "a.json", "--tables", "out"],
    ] {
        let o = jointctl(d.path(), &args);
        assert!(!o.status.success() && stderr(&o).contains("keep.txt"), "{args:?}: {}", stderr(&o));
    }
    assert!(t0.elapsed().as_secs_f64() < 5.0, "refused only after the work");
    assert_eq!(names(d.path()), ["m.toml", "out", "run.csv"]);
    assert_eq!(names(&d.path().join("out")), ["keep.txt"]);
}

#[test]
fn a_bench_dump_lands_whole_in_a_new_folder() {
    let d = tempfile::tempdir().unwrap();
    let o =
        jointctl(d.path(), &["diagnose-bench", "--cases", "1", "--seconds", "3", "--dump", "dump", "--json", "b.json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(names(&d.path().join("dump")), ["case-0.csv", "case-0.toml"]);
    assert_eq!(names(d.path()), ["b.json", "dump"]);
}

#[test]
fn sim_refuses_a_store_file_that_is_the_plant() {
    let d = tempfile::tempdir().unwrap();
    let plant: PathBuf = d.path().join("node-5.toml");
    fs::copy(format!("{EXAMPLES}/plants/trunk-right.toml"), &plant).unwrap();
    let before = fs::read(&plant).unwrap();
    let o = jointctl(
        d.path(),
        &["sim", "--bus", "slcan:/nonexistent/tty", "--node", "5", "--plant", "node-5.toml", "--store-dir", "."],
    );
    let err = stderr(&o);
    assert!(!o.status.success() && err.contains("--store-dir") && err.contains("--plant node-5.toml"), "{err}");
    assert_eq!(fs::read(&plant).unwrap(), before);
}

#[test]
fn eds_and_pull_write_through_the_same_rules() {
    let d = tempfile::tempdir().unwrap();
    let o = jointctl(d.path(), &["eds", "--out", "-"]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("[DeviceInfo]"));
    fs::write(d.path().join("j.eds"), "keep").unwrap();
    fs::set_permissions(d.path().join("j.eds"), fs::Permissions::from_mode(0o444)).unwrap();
    let o = jointctl(d.path(), &["eds", "--out", "j.eds"]);
    assert!(!o.status.success() && stderr(&o).contains("read-only"), "{}", stderr(&o));
    assert_eq!(fs::read_to_string(d.path().join("j.eds")).unwrap(), "keep");
    let o = jointctl(d.path(), &["pull", "--node", "5", "--bus", "sim", "--name", "j5", "--out", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("name = \"j5\""));
    assert!(stderr(&o).contains("pulled node 5 into -"), "{}", stderr(&o));
    let o = jointctl(d.path(), &["pull", "--node", "5", "--bus", "sim", "--out", "-", "--json"]);
    assert!(!o.status.success() && stderr(&o).contains("both write to stdout"), "{}", stderr(&o));
}
