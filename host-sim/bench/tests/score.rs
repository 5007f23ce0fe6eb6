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

#[test]
fn an_effect_a_compound_does_not_show_is_optional() {
    use diag_bench::score::{classify_shown, optional_effects};
    let truth = s(&["cable_spring", "stribeck"]);
    // the Stribeck curve at 4 % of the noise: optional; both at 0.5 or more: both required
    let optional = optional_effects(&truth, &json!({"cable_spring": 4.4, "stribeck": 0.04}));
    assert_eq!(optional, s(&["stribeck"]));
    assert!(optional_effects(&truth, &json!({"cable_spring": 4.4, "stribeck": 0.6})).is_empty());
    // a single effect is never optional, nor both of a compound that shows neither
    assert!(optional_effects(&s(&["stribeck"]), &json!({"stribeck": 0.1})).is_empty());
    assert!(optional_effects(&truth, &json!({"cable_spring": 0.3, "stribeck": 0.1})).is_empty());
    let one = json!({"effect": "cable_spring"});
    let both = json!({"effect": "cable_spring", "effects": ["cable_spring", "stribeck"]});
    let other = json!({"effect": "stribeck"});
    let extra = json!({"effect": "cable_spring", "effects": ["cable_spring", "delay"]});
    let none = json!({"effect": "none"});
    assert_eq!(classify_shown(&truth, &optional, Some(&one)).0, Outcome::Correct);
    assert_eq!(classify_shown(&truth, &optional, Some(&both)).0, Outcome::Correct);
    assert_eq!(classify_shown(&truth, &optional, Some(&other)).0, Outcome::Wrong);
    assert_eq!(classify_shown(&truth, &optional, Some(&extra)).0, Outcome::Wrong);
    assert_eq!(classify_shown(&truth, &optional, Some(&none)).0, Outcome::Wrong);
    // strict: the one shown effect alone is not the drawn set
    assert_eq!(classify(&truth, Some(&one)).0, Outcome::Wrong);
}
