//! Bounded property versions of the fuzz targets `joint_log` and `model_toml`
//! (`fuzz/fuzz_targets/`, run long by `scripts/fuzz-all.sh`): arbitrary bytes, and CSV/TOML
//! built from the formats' own pieces (so most cases get past the header), never panic; what
//! is accepted holds the reader's promises and reads back the same after writing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use proptest::prelude::*;

fn check_log(bytes: &[u8]) {
    let Ok(log) = JointLog::parse(bytes, "prop.csv") else { return };
    let n = log.t.len();
    assert!(n > 0 && log.q.len() == n);
    for c in [&log.qd, &log.qdd, &log.u, &log.tau, &log.temp].into_iter().flatten() {
        assert_eq!(c.len(), n);
        assert!(c.iter().all(|x| x.is_finite()));
    }
    assert!(log.t.windows(2).all(|w| w[1] > w[0]));
    let mut out = Vec::new();
    log.write_csv(&mut out).unwrap();
    let back = JointLog::parse(&out, "again.csv").expect("a written log reads back");
    assert_eq!((back.t, back.q, back.tau), (log.t, log.q, log.tau));
}

fn check_model(text: &str) {
    let Ok(model) = ModelFile::parse(text, "prop.toml") else { return };
    let Ok(set) = model.param_set() else { return };
    assert!(joint_core::params::check(set.raw()).is_ok());
    let again = ModelFile::parse(&model.to_toml_string(), "again.toml").expect("a written model reads back");
    assert_eq!(again.param_set().expect("and gives a set").raw(), set.raw());
}

/// A cell: mostly numbers, sometimes the things loggers write instead.
fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (-1e3f64..1e3).prop_map(|x| format!("{x}")),
        1 => Just(String::new()),
        1 => prop::sample::select(vec!["nan", "inf", "-inf", "1e309", "0x10", " 1 ", "\"2\"", "1,5", "1e300", "-0"])
            .prop_map(str::to_string),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn any_bytes_give_a_log_or_an_error(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        check_log(&bytes);
    }

    #[test]
    fn csv_shaped_input_gives_a_log_or_an_error(
        cols in prop::sample::subsequence(vec!["t", "q", "qd", "qdd", "u", "tau", "temp", "q_hip", "note", "t"], 1..8),
        rows in prop::collection::vec(prop::collection::vec(cell(), 0..9), 0..30),
        crlf in any::<bool>(),
        increasing in any::<bool>(),
    ) {
        let end = if crlf { "\r\n" } else { "\n" };
        let mut s = cols.join(",") + end;
        for (i, r) in rows.iter().enumerate() {
            let mut r = r.clone();
            if increasing && !r.is_empty() {
                r[0] = format!("{}", i as f64 * 1e-3);
            }
            s += &r.join(",");
            s += end;
        }
        check_log(s.as_bytes());
    }

    #[test]
    fn any_text_gives_a_model_or_an_error(text in ".{0,300}") {
        check_model(&text);
    }

    #[test]
    fn toml_shaped_input_gives_a_model_or_an_error(
        lines in prop::collection::vec(
            prop_oneof![
                prop::sample::select(vec!["[friction]", "[weight]", "[inertia]", "[offset]", "[spring]", "[table]", "[x]", "[friction"])
                    .prop_map(str::to_string),
                (
                    prop::sample::select(vec!["a", "b", "c", "v_band", "amplitude", "s", "phi", "j", "c0", "k", "q0", "name", "zz"]),
                    prop_oneof![
                        (-1e4f64..1e4).prop_map(|x| format!("{x}")),
                        prop::sample::select(vec!["nan", "inf", "1e40", "\"x\"", "[1, 2]", "true", "-0.0", ""]).prop_map(str::to_string),
                    ],
                )
                    .prop_map(|(k, v)| format!("{k} = {v}")),
            ],
            0..14,
        ),
    ) {
        check_model(&lines.join("\n"));
    }

    /// The generators above reach the accepting paths: a well-formed log of the same pieces is
    /// always accepted (so the invariants above are exercised, not vacuous).
    #[test]
    fn a_well_formed_log_is_accepted_and_reads_back(
        extra in prop::sample::subsequence(vec!["qd", "qdd", "u", "tau", "temp", "q_hip", "note"], 0..7),
        rows in prop::collection::vec(prop::collection::vec(-1e3f64..1e3, 8), 1..30),
    ) {
        let cols: Vec<&str> = ["t", "q"].into_iter().chain(extra.iter().copied()).collect();
        let mut s = cols.join(",") + "\n";
        for (i, r) in rows.iter().enumerate() {
            let cells: Vec<String> = std::iter::once(format!("{}", i as f64 * 1e-3))
                .chain(r.iter().take(cols.len() - 1).map(|x| format!("{x}")))
                .collect();
            s += &cells.join(",");
            s += "\n";
        }
        prop_assert!(JointLog::parse(s.as_bytes(), "ok.csv").is_ok(), "{}", s);
        check_log(s.as_bytes());
    }

    #[test]
    fn a_well_formed_model_is_accepted_and_reads_back(
        b in 0.0f64..10.0, c in 0.0f64..5.0, j in 1e-3f64..2.0, amp in -20.0f64..20.0, c0 in -3.0f64..3.0,
    ) {
        let text = format!(
            "name = \"p\"\n[friction]\nb = {b}\nc = {c}\n[inertia]\nj = {j}\n[weight]\namplitude = {amp}\ns = 1.0\nphi = 0.1\n[offset]\nc0 = {c0}\n"
        );
        let m = ModelFile::parse(&text, "ok.toml");
        prop_assert!(m.as_ref().is_ok_and(|m| m.param_set().is_ok()), "{:?}", m.err());
        check_model(&text);
    }
}
