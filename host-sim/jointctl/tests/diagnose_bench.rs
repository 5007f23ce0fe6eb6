//! The withheld-effect bench in small: logs whose effect the model lacks, diagnosed blind.
//! The target, ≥ 95 % accuracy with no over-claim on `none`, is asserted on 52 cases
//! (four of every kind) of 20 s logs. The measured figures of the larger runs, 10 s logs among
//! them, are in docs/diagnosis.md; the misses there are mostly asymmetric friction, which in
//! torque mode differs from a constant offset only while the joint stands still.

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
    assert!(rep.accuracy >= 0.95, "accuracy {:.3}, confusion {:?}", rep.accuracy, rep.confusion);
    // What the diagnosis keeps shrinks the gap as much as the true effect's own candidate.
    assert!(rep.mean_shrink >= 0.9 * rep.mean_true_shrink, "{} vs {}", rep.mean_shrink, rep.mean_true_shrink);
    assert!(rep.mean_shrink > 0.2);
}
