//! The scorer's verdict classification.

use diag_bench::score::{classify, Outcome};
use serde_json::json;

fn s(v: &[&str]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

#[test]
fn verdicts_are_scored_by_sets() {
    let v = json!({"effect": "stribeck"});
    assert_eq!(classify(&s(&["stribeck"]), Some(&v)).0, Outcome::Correct);
    assert_eq!(classify(&s(&["none"]), Some(&v)).0, Outcome::OverClaim);
    assert_eq!(classify(&s(&["delay"]), Some(&v)).0, Outcome::Wrong);
    let v = json!({"effect": "none"});
    assert_eq!(classify(&s(&["none"]), Some(&v)).0, Outcome::Correct);
    assert_eq!(classify(&s(&["stribeck"]), Some(&v)).0, Outcome::Wrong);
    let v = json!({"effect": "unexplained"});
    assert_eq!(classify(&s(&["stribeck"]), Some(&v)).0, Outcome::Unsure);
    assert_eq!(classify(&s(&["none"]), Some(&v)).0, Outcome::OverClaim);
    let v = json!({"effect": "parameters", "alternatives": ["stribeck"]});
    assert_eq!(classify(&s(&["stribeck"]), Some(&v)).0, Outcome::Unsure);
    // A compound is correct only when both are reported, in any order.
    let v = json!({"effect": "position_ripple", "effects": [{"effect": "position_ripple"}, {"effect": "stribeck"}]});
    assert_eq!(classify(&s(&["stribeck", "position_ripple"]), Some(&v)).0, Outcome::Correct);
    let v = json!({"effect": "stribeck"});
    assert_eq!(classify(&s(&["stribeck", "position_ripple"]), Some(&v)).0, Outcome::Wrong);
    assert_eq!(classify(&s(&["none"]), None).0, Outcome::Refused);
    assert_eq!(classify(&s(&["none"]), Some(&json!({}))).0, Outcome::Refused);
}
