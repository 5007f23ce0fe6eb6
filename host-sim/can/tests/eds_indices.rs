//! CANopen indices of existing parameters never move: the EDS committed when the parameter
//! table became one declaration (`tests/data/joint-2026-11.eds`, `jointctl eds` of that day)
//! is compared object by object with the EDS generated now. Every parameter object it holds
//! (0x2000 + table position) must be generated with the same text; new terms may only take
//! indices after the last one it has.

use std::collections::BTreeMap;

/// `[section]` → its lines, for every object section (hex index, optionally `sub`).
fn objects(eds: &str) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    let mut cur: Option<String> = None;
    for line in eds.lines() {
        let line = line.trim_end();
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            cur = Some(name.to_string());
            out.insert(name.to_string(), Vec::new());
        } else if let Some(c) = &cur {
            if !line.is_empty() {
                out.get_mut(c).expect("section inserted").push(line.to_string());
            }
        }
    }
    out
}

fn parameter_objects(eds: &str) -> BTreeMap<u16, Vec<String>> {
    objects(eds)
        .into_iter()
        .filter_map(|(k, v)| {
            let idx = u16::from_str_radix(&k, 16).ok()?;
            v.iter().any(|l| l.starts_with("ParameterName=")).then_some(())?;
            (0x2000..0x2100).contains(&idx).then_some((idx, v))
        })
        .collect()
}

#[test]
fn every_committed_parameter_object_is_generated_unchanged() {
    let committed = parameter_objects(include_str!("data/joint-2026-11.eds"));
    let now = parameter_objects(&joint_can::eds::generate());
    assert!(committed.len() >= 38, "the committed EDS holds the parameter objects ({})", committed.len());
    for (idx, lines) in &committed {
        let Some(gen) = now.get(idx) else { panic!("parameter object {idx:#06x} is gone from the EDS") };
        assert_eq!(gen, lines, "parameter object {idx:#06x} changed (a term moved or was redefined)");
    }
    let last = *committed.keys().last().expect("non-empty");
    for idx in now.keys().filter(|i| !committed.contains_key(i)) {
        assert!(*idx > last, "new parameter object {idx:#06x} sits among the committed ones (append new terms)");
    }
    assert_eq!(now.len(), joint_core::params::PARAM_COUNT, "one object per parameter of the table");
}

#[test]
fn the_comparison_sees_a_moved_term() {
    // Swapping two objects' names, as a term inserted mid-table would, must be caught.
    let text = include_str!("data/joint-2026-11.eds");
    let moved = text.replacen("ParameterName=friction_a", "ParameterName=friction_x", 1);
    assert_ne!(parameter_objects(text), parameter_objects(&moved));
}
