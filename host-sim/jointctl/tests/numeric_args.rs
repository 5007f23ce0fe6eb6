//! Every numeric option of every subcommand, with its allowed range: bad values are refused by
//! the real binary at parse time (exit 2, the option and the range named, nothing run), the
//! boundary values are accepted. The table is checked against `jointctl --help` itself, so a
//! new numeric option without a row fails here. docs/outputs.md lists the same ranges.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use clap::{CommandFactory, Parser};
use joint_analysis::identify::segments::Window;
use joint_can::master::SdoCobs;
use joint_can::BusSpec;
use jointctl::cli::Cli;
use std::any::TypeId;
use std::collections::BTreeSet;
use std::process::Command;

/// (subcommand, option, accepted values, refused values, what the refusal must say)
type Row = (&'static str, &'static str, &'static [&'static str], &'static [&'static str], &'static str);

const SEED: &[&str] = &["-1", "1.5", "x"];
const NODE_OK: &[&str] = &["1", "127"];
const NODE_BAD: &[&str] = &["0", "128", "-1", "x"];
const BITRATE_OK: &[&str] = &["10000", "1000000"];
const BITRATE_BAD: &[&str] = &["0", "9999", "1000001", "4294967295"];
// `--bus slcan:PATH@BITRATE` carries a bitrate too: slcan's nine
const BUS_OK: &[&str] = &["sim", "slcan:/dev/x@10000", "slcan:/dev/x@1000000", "socketcan:can0"];
const BUS_BAD: &[&str] = &["slcan:/dev/x@0", "slcan:/dev/x@123", "slcan:/dev/x@nan"];
const SDO_CHANNEL_OK: &[&str] = &["1", "2"];
const SDO_CHANNEL_BAD: &[&str] = &["0", "3", "-1", "x"];
// the second SDO channel's COB-IDs: two different 11-bit ids
const COB_IDS_OK: &[&str] = &["0x640,0x5C0", "1,2047"];
const COB_IDS_BAD: &[&str] = &["0,5", "0x800,1", "x,1", "5", "0x645,0x645", "1,-1"];

const TABLE: &[Row] = &[
    ("simulate", "seconds", &["1e-3", "86400"], &["nan", "inf", "0", "-1", "86401"], "0 < x ≤ 86400 s"),
    ("simulate", "seed", &["0", "18446744073709551615"], SEED, ""),
    ("simulate", "rate", &["100", "10000"], &["nan", "99", "10001", "0"], "100 ≤ x ≤ 10000 Hz"),
    ("simulate", "plant-rate", &["1000", "1000000"], &["4294967295", "nan", "0", "999"], "1000 ≤ x ≤ 1e6 Hz"),
    ("simulate", "range", &["-360,360", "0,116.5"], &["nan,1", "1,0", "-400,0", "0,inf"], "-360 ≤ MIN < MAX ≤ 360"),
    ("simulate", "free-start", &["-360", "360"], &["nan", "361", "-inf"], "-360 ≤ x ≤ 360 deg"),
    ("diagnose", "max-effects", &["1", "10"], &["0", "11", "-1"], "1..=10"),
    ("diagnose-bench", "cases", &["1", "10000"], &["0", "10001"], "1..=10000"),
    ("diagnose-bench", "seed", &["0"], SEED, ""),
    ("diagnose-bench", "seconds", &["3", "600"], &["nan", "2.9", "601"], "3 ≤ x ≤ 600 s"),
    ("identify", "accel-cutoff", &["1e-3", "10000"], &["nan", "0", "-5", "10001", "inf"], "0 < x ≤ 10000 Hz"),
    ("identify", "window", &["0:1:plateau", "2.5:3:static"], &["-1:2:plateau", "nan:1:static", "2:1:motion"], ""),
    ("import", "joint", &["0", "7"], &["8", "-1"], "0..=7"),
    ("import", "gear-ratio", &["1e-3", "1000"], &["0", "nan", "1001"], "0 < x ≤ 1000"),
    ("import", "hold", &["1e-3", "3600"], &["0", "nan", "3601"], "0 < x ≤ 3600 s"),
    ("import", "rate", &["1", "100000"], &["0", "inf", "100001"], "0 < x ≤ 1e5 Hz"),
    ("import", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("push", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("push", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("push", "bus", BUS_OK, BUS_BAD, ""),
    ("pull", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("pull", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("pull", "bus", BUS_OK, BUS_BAD, ""),
    ("save", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("save", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("save", "bus", BUS_OK, BUS_BAD, ""),
    ("scan", "seconds", &["1e-3", "3600"], &["nan", "0", "-1", "3601"], "0 < x ≤ 3600 s"),
    ("scan", "sim-node", NODE_OK, NODE_BAD, "1..=127"),
    ("scan", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("scan", "bus", BUS_OK, BUS_BAD, ""),
    ("watch", "seconds", &["1e-3", "1e7"], &["nan", "0", "1.1e7"], "0 < x ≤ 1e7 s"),
    ("watch", "sim-node", NODE_OK, NODE_BAD, "1..=127"),
    ("watch", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("watch", "bus", BUS_OK, BUS_BAD, ""),
    ("status", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("status", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("status", "bus", BUS_OK, BUS_BAD, ""),
    ("discard", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("discard", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("discard", "bus", BUS_OK, BUS_BAD, ""),
    ("log", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("log", "seconds", &["1e-3", "3600"], &["nan", "0", "3601"], "0 < x ≤ 3600 s"),
    ("log", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("log", "bus", BUS_OK, BUS_BAD, ""),
    ("push", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("push", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("pull", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("pull", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("save", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("save", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("status", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("status", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("discard", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("discard", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("log", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("log", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("watch", "sdo-channel", SDO_CHANNEL_OK, SDO_CHANNEL_BAD, "1..=2"),
    ("watch", "sdo-cob-ids", COB_IDS_OK, COB_IDS_BAD, "1..=0x7FF"),
    ("sim", "node", NODE_OK, NODE_BAD, "1..=127"),
    ("sim", "seconds", &["1e-3", "1e7"], &["nan", "0", "-1"], "0 < x ≤ 1e7 s"),
    ("sim", "bus", &["slcan:/dev/x@125000", "socketcan:can0"], BUS_BAD, ""),
    ("sim", "data-bitrate", &["10000", "8000000"], &["0", "8000001"], "10000..=8000000"),
    ("bus-budget", "joints", &["1", "127"], &["0", "128"], "1..=127"),
    ("bus-budget", "rate", &["1e-3", "10000"], &["nan", "0", "inf", "10001"], "0 < x ≤ 10000 Hz"),
    ("bus-budget", "bitrate", BITRATE_OK, BITRATE_BAD, "10000..=1000000"),
    ("bus-budget", "data-bitrate", &["10000", "8000000"], &["0", "8000001"], "10000..=8000000"),
    ("closed-loop", "fraction", &["0", "1"], &["nan", "1.5", "-0.1"], "0 ≤ x ≤ 1"),
    ("closed-loop", "assist-k", &["-1000", "1000"], &["nan", "1001", "-inf"], "-1000 ≤ x ≤ 1000 N·m/rad"),
    ("closed-loop", "trials", &["1", "1000"], &["0", "1001"], "1..=1000"),
    ("closed-loop", "seconds", &["1", "3600"], &["nan", "0.5", "3601"], "1 ≤ x ≤ 3600 s"),
    ("closed-loop", "seed", &["0"], SEED, ""),
    ("closed-loop", "delay", &["0", "0.2"], &["nan", "-0.01", "0.21"], "0 ≤ x ≤ 0.2 s"),
    ("closed-loop", "operator-stiffness", &["1e-3", "1e5"], &["0", "nan", "100001"], "0 < x ≤ 1e5 N·m/rad"),
    ("closed-loop", "operator-damping", &["0", "1e4"], &["-1", "nan", "10001"], "0 ≤ x ≤ 10000 N·m·s/rad"),
    ("closed-loop", "sweep-step", &["0.01", "1"], &["0", "nan", "0.009", "1.1"], "0.01 ≤ x ≤ 1"),
    ("arm-gravity", "seed", &["0"], SEED, ""),
    ("arm-gravity", "configs", &["1", "1000"], &["0", "1001"], "1..=1000"),
    ("arm-gravity", "out-configs", &["0", "1000"], &["1001", "-1"], "0..=1000"),
    ("arm-gravity", "clamp-k", &["1e-3", "100"], &["0", "nan", "100.5"], "0 < x ≤ 100"),
    ("arm-gravity", "cycles", &["1", "100000"], &["0", "100001"], "1..=100000"),
];

/// The other arguments a subcommand needs to parse (not to run).
fn base(sub: &str) -> Vec<&'static str> {
    match sub {
        "simulate" => vec!["--plant", "p.toml", "--controller", "m.toml", "--out", "o.csv"],
        "diagnose" => vec!["--log", "l.csv", "--model", "m.toml"],
        "identify" => vec!["--log", "l.csv", "--out", "m.toml"],
        "import" => vec!["--format", "dfki-pendulum", "--input", "i.csv", "--out", "o.csv"],
        "push" => vec!["m.toml", "--node", "5"],
        "pull" => vec!["--node", "5", "--out", "m.toml"],
        "save" | "status" | "discard" => vec!["--node", "5"],
        "log" => vec!["--node", "5", "--seconds", "1", "--out", "o.csv"],
        "sim" => vec!["--bus", "slcan:/dev/x", "--node", "5"],
        "bus-budget" => vec!["--joints", "1", "--rate", "100"],
        "closed-loop" => vec!["--plant", "p.toml", "--model", "m.toml"],
        "arm-gravity" => vec!["--json", "a.json"],
        _ => vec![],
    }
}

/// `base(sub)` with `--opt=value` in place of any `--opt X` it has.
fn args(sub: &'static str, opt: &str, value: &str) -> Vec<String> {
    let flag = format!("--{opt}");
    let mut v: Vec<String> = vec!["jointctl".into(), sub.into()];
    let b = base(sub);
    let mut i = 0;
    while i < b.len() {
        if b[i] == flag {
            i += 2;
            continue;
        }
        v.push(b[i].into());
        i += 1;
    }
    v.push(format!("{flag}={value}"));
    // the operator's stiffness and damping go together
    match opt {
        "operator-stiffness" => v.push("--operator-damping=1".into()),
        "operator-damping" => v.push("--operator-stiffness=1".into()),
        _ => {}
    }
    v
}

/// The options whose values are numbers (or hold numbers: ranges, windows, bus bitrates).
fn numeric_options() -> BTreeSet<(String, String)> {
    let numeric = [
        TypeId::of::<f64>(),
        TypeId::of::<u8>(),
        TypeId::of::<u16>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
        TypeId::of::<i32>(),
        TypeId::of::<i64>(),
        TypeId::of::<(f64, f64)>(),
        TypeId::of::<Window>(),
        TypeId::of::<BusSpec>(),
        TypeId::of::<SdoCobs>(),
    ];
    let mut set = BTreeSet::new();
    for sub in Cli::command().get_subcommands() {
        for a in sub.get_arguments() {
            let t = a.get_value_parser().type_id();
            if numeric.iter().any(|id| t == *id) {
                let long = a.get_long().unwrap_or_else(|| panic!("{}: positional numeric argument", sub.get_name()));
                set.insert((sub.get_name().to_string(), long.to_string()));
            }
        }
    }
    set
}

#[test]
fn the_table_covers_every_numeric_option_of_every_subcommand() {
    let found = numeric_options();
    let listed: BTreeSet<(String, String)> = TABLE.iter().map(|r| (r.0.to_string(), r.1.to_string())).collect();
    let missing: Vec<_> = found.difference(&listed).collect();
    let stale: Vec<_> = listed.difference(&found).collect();
    assert!(missing.is_empty(), "numeric options without a row in TABLE: {missing:?}");
    assert!(stale.is_empty(), "rows for options that are not numeric (or gone): {stale:?}");
    assert!(found.len() >= 50, "the introspection found only {} options", found.len());
}

#[test]
fn boundary_values_parse() {
    for (sub, opt, ok, _, _) in TABLE {
        for v in *ok {
            let a = args(sub, opt, v);
            if let Err(e) = Cli::try_parse_from(&a) {
                panic!("{a:?} refused: {e}");
            }
        }
    }
}

#[test]
fn bad_values_are_refused_by_the_binary_naming_the_option_and_range() {
    for (sub, opt, _, bad, range) in TABLE {
        for v in *bad {
            let a = args(sub, opt, v);
            let o = Command::new(env!("CARGO_BIN_EXE_jointctl")).args(&a[1..]).output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{a:?} was not refused at parse time: {err}");
            assert!(err.contains(&format!("'--{opt}")), "{a:?}: the option is not named: {err}");
            assert!(err.contains(range), "{a:?}: the range `{range}` is not given: {err}");
            assert!(o.stdout.is_empty(), "{a:?} printed on stdout");
        }
    }
}

fn run(args: &[&str]) -> (Option<i32>, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_jointctl")).args(args).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// The users' reproductions, exactly as reported.
#[test]
fn the_reported_numbers_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("log.csv");
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples");
    let (plant, model) = (format!("{root}/plants/trunk-right.toml"), format!("{root}/models/trunk-right.toml"));
    let t0 = std::time::Instant::now();
    let (code, err) = run(&[
        "simulate",
        "--plant",
        &plant,
        "--controller",
        &model,
        "--plant-rate",
        "4294967295",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--plant-rate") && err.contains("1e6 Hz"), "{err}");
    assert!(t0.elapsed().as_secs_f64() < 5.0, "refused only after running");
    assert!(!out.exists());

    let (code, err) = run(&["scan", "--seconds", "nan"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--seconds") && err.contains("0 < x ≤ 3600 s"), "{err}");

    let (code, err) = run(&["bus-budget", "--joints", "1", "--rate", "100", "--bitrate", "0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--bitrate") && !err.contains("inf %"), "{err}");
}

#[test]
fn products_of_options_beyond_the_budgets_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("log.csv");
    let o = out.to_str().unwrap();
    // the files do not even exist: the budget is checked first
    let (code, err) = run(&[
        "simulate",
        "--plant",
        "p.toml",
        "--controller",
        "m.toml",
        "--plant-rate",
        "1e6",
        "--seconds",
        "86400",
        "--out",
        o,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--plant-rate 1000000 × --seconds 86400") && err.contains("plant steps"), "{err}");
    let (code, err) = run(&[
        "simulate",
        "--plant",
        "p.toml",
        "--controller",
        "m.toml",
        "--rate",
        "10000",
        "--seconds",
        "2000",
        "--out",
        o,
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--rate 10000 × --seconds 2000") && err.contains("log samples"), "{err}");
    let (code, err) =
        run(&["bus-budget", "--joints", "2", "--rate", "100", "--bitrate", "1000000", "--data-bitrate", "500000"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--data-bitrate 500000") && err.contains("--bitrate 1000000"), "{err}");
    let (code, err) = run(&[
        "import",
        "--format",
        "ur5e-friction",
        "--input",
        "i.csv",
        "--out",
        o,
        "--joint",
        "1",
        "--hold",
        "3600",
        "--rate",
        "1000",
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("--hold 3600 × --rate 1000"), "{err}");
    assert!(!out.exists());
}
