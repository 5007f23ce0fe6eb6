//! The withheld-effect bench in small: logs of the in-house plant whose effect the model lacks,
//! diagnosed blind, 52 cases (four of every kind) of 20 s logs. No `none` case may be named an
//! effect. The accuracy bar is 85 %, not the 95 % this bench once showed: since the diagnosis
//! answers `none` when an effect does not beat the simpler explanation on held-out data, and
//! the simpler `parameters` when a refit explains the gap as well, measured 45/52 (86.5 %);
//! the misses are a 10 ms delay and a small Stribeck dip left at `none` (3), thermal drift
//! refitted as `parameters`, backlash named pre-sliding hysteresis (both a lag of the friction
//! behind a reversal), and one effect of two pairs missed or mistaken. The bench that counts,
//! drawn from shapes and joints the candidates do not share, is `diag-bench` (docs/diagnosis.md).

use jointctl::bench;

#[test]
fn withheld_effects_are_named_and_none_is_not_overclaimed() {
    let rep = bench::run(52, 1, 20.0, None, |r| {
        eprintln!(
            "case {:>2}: {:<40} → {:<40} {}",
            r.case,
            r.truth,
            r.predicted,
            if r.correct { "ok" } else { "WRONG" }
        )
    })
    .unwrap();
    assert_eq!(rep.overclaims, 0, "a none case was diagnosed as an effect: {:?}", rep.confusion.get("none"));
    assert!(rep.none_cases >= 8);
    assert!(rep.accuracy >= 0.85, "accuracy {:.3}, confusion {:?}", rep.accuracy, rep.confusion);
    // What the diagnosis keeps shrinks the gap as much as the true effect's own candidate.
    assert!(rep.mean_shrink >= 0.9 * rep.mean_true_shrink, "{} vs {}", rep.mean_shrink, rep.mean_true_shrink);
    assert!(rep.mean_shrink > 0.2);
}
