//! The joint-log reader is strict (row and column named on every refusal, nothing half-read)
//! and tolerant of harmless variants; the writer round-trips exactly.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use joint_formats::log::{JointLog, LogError, LogMode};

fn parse(s: &str) -> Result<JointLog, LogError> {
    JointLog::parse(s.as_bytes(), "x.csv")
}

fn err(s: &str) -> String {
    let e = parse(s).expect_err("must be refused");
    e.to_string()
}

#[test]
fn minimal_trajectory_log() {
    let l = parse("t,q\n0,0.1\n0.001,0.2\n").unwrap();
    assert_eq!(l.len(), 2);
    assert_eq!(l.mode(), LogMode::Trajectory);
    assert_eq!(l.q, vec![0.1, 0.2]);
}

#[test]
fn harmless_variants_are_accepted() {
    // BOM, CRLF, free column order, spaces, quoted header, unknown columns, q_<name>, trailing blank lines.
    let text = "\u{feff}\"tau\", q ,t,u,note,q_shoulder,temp\r\n1.5, 0.1 ,0,2.0,abc,0.3,25\r\n1.25,0.2,0.5,2.5,x,0.4,26\r\n\r\n\n";
    let l = parse(text).unwrap();
    assert_eq!(l.mode(), LogMode::Torque);
    assert_eq!(l.t, vec![0.0, 0.5]);
    assert_eq!(l.tau.as_deref(), Some(&[1.5, 1.25][..]));
    assert_eq!(l.other("q_shoulder"), Some(&[0.3, 0.4][..]));
    assert_eq!(l.unknown, vec!["note".to_string()]);
    assert_eq!(l.temp.as_deref(), Some(&[25.0, 26.0][..]));
    assert!(l.qd.is_none());
}

#[test]
fn torque_mode_needs_both_u_and_tau() {
    assert_eq!(parse("t,q,u\n0,0,1\n").unwrap().mode(), LogMode::Trajectory);
    assert_eq!(parse("t,q,u,tau\n0,0,1,1\n").unwrap().mode(), LogMode::Torque);
}

#[test]
fn bad_files_name_line_and_column() {
    let cases: &[(&str, &[&str])] = &[
        ("q,u\n0,1\n", &["line 1", "`t`"]),
        ("t,u\n0,1\n", &["line 1", "`q`"]),
        ("t,q,u\n0,0,1\n0.1,abc,2\n", &["line 3", "`q`", "abc"]),
        ("t,q,u\n0,0,1\n0.1,0,NaN\n", &["line 3", "`u`"]),
        ("t,q,u\n0,0,1\n0.1,0,inf\n", &["line 3", "`u`"]),
        ("t,q,u\n0,0,1\n0.1,,2\n", &["line 3", "`q`", "empty"]),
        ("t,q\n0,0\n0.1,0\n0.1,0\n", &["line 4", "`t`"]),
        ("t,q\n0,0\n0.2,0\n0.1,0\n", &["line 4", "`t`"]),
        ("t,q,u\n0,0,1\n0.1,0\n", &["line 3", "2 cells"]),
        ("t,q\n0,0,5\n", &["line 2", "3 cells"]),
        ("t,q,t\n0,0,0\n", &["line 1", "twice"]),
        ("t,q\n", &["no data"]),
        ("", &["empty"]),
        ("t,q\n0,0\n\n0.1,0\n", &["line 3"]),
        ("t,q,q_shoulder\n0,0,x\n", &["line 2", "`q_shoulder`"]),
        // another delimiter: said, not taken for a missing `t`
        ("t;q;u;tau\n0;0;1;1\n", &["line 1", "`t;q;u;tau`", "separated by `;`", "not by commas"]),
        ("t\tq\n0\t0\n", &["line 1", "separated by `tab`"]),
    ];
    for (text, needles) in cases {
        let msg = err(text);
        assert!(msg.starts_with("x.csv"), "{msg}");
        for n in *needles {
            assert!(msg.contains(n), "error for {text:?} should contain {n:?}: {msg}");
        }
    }
}

#[test]
fn unknown_column_cells_are_not_interpreted() {
    let l = parse("t,q,comment\n0,0,hello world\n").unwrap();
    assert_eq!(l.unknown, vec!["comment".to_string()]);
}

#[test]
fn write_then_read_gives_the_same_values() {
    let l = JointLog {
        t: vec![0.0, 0.001, 0.002],
        q: vec![1e-9, -0.5, 3.0e20],
        qd: Some(vec![0.1, 0.2, 1.0 / 3.0]),
        qdd: None,
        u: Some(vec![1.0, -2.0, 5e-5]),
        tau: Some(vec![0.0, 0.0, -0.0]),
        temp: None,
        others: vec![("q_hip".into(), vec![0.1, 0.2, 0.3])],
        unknown: vec![],
    };
    let mut buf = Vec::new();
    l.write_csv(&mut buf).unwrap();
    let back = JointLog::parse(&buf, "mem").unwrap();
    assert_eq!(back, l);
}

#[test]
fn a_million_rows_parse_quickly() {
    // Timing is asserted loosely (debug builds, shared CI cores); the point is "no per-cell
    // allocation", which would take many seconds.
    let n = 1_000_000;
    let mut s = String::with_capacity(n * 48);
    s.push_str("t,q,qd,u,tau\n");
    for i in 0..n {
        let t = i as f64 * 1e-3;
        s.push_str(&format!("{t},{},{},{},{}\n", (t * 0.7).sin(), (t * 0.7).cos(), 1.5 * t, -0.25));
    }
    let start = std::time::Instant::now();
    let l = parse(&s).unwrap();
    let el = start.elapsed();
    assert_eq!(l.len(), n);
    assert!(el.as_secs_f64() < 5.0, "1 M rows took {el:?}");
    eprintln!("1 M rows × 5 columns parsed in {el:?}");
}

#[test]
fn write_file_is_atomic_and_complete() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("log.csv");
    let l = parse("t,q\n0,1\n1,2\n").unwrap();
    l.write_file(&p).unwrap();
    assert_eq!(JointLog::read_file(&p).unwrap(), l);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left behind");
}
