//! The plant's effect sections are the vocabulary's: each field of `Effects` is read from the
//! section the vocabulary names for its effect, `Effects::section` maps every entry, and the
//! sections of the terms the joint compensates carry exactly the parameter table's keys (so
//! the true-parameter model of the closed-loop workflow takes them key by key).

use std::collections::BTreeSet;

use host_sim::effects::*;
use host_sim::plant::PlantFile;
use joint_core::params;
use joint_formats::vocab::Effect;

/// Every effect the plant simulates, each with values off its defaults.
fn every_effect() -> Effects {
    Effects {
        stribeck: Some(Stribeck { level: 0.7, speed: 0.04 }),
        asymmetric_friction: Some(AsymmetricFriction { delta: 0.2 }),
        load_dependent_friction: Some(LoadDependentFriction { mu: 0.05 }),
        thermal_drift: Some(ThermalDrift {
            coefficient: 0.01,
            t_ambient: 20.0,
            rise: 15.0,
            time_constant: 300.0,
            t_ref: 25.0,
            log_temp: false,
        }),
        position_ripple: Some(PositionRipple {
            amplitude: 0.3,
            period: 0.1,
            phase: 0.5,
            amplitude_2: 0.1,
            phase_2: -0.2,
        }),
        cable_spring: Some(CableSpring { k: 6.0, engage: 1.2, width: 0.03 }),
        backlash: Some(Backlash { width: 0.01, output_inertia_share: 0.2 }),
        delay: Some(Delay { seconds: 0.002 }),
        dry_friction: Some(DryFriction { c: 0.25 }),
    }
}

#[test]
fn plant_sections_are_the_vocabularys() {
    let e = every_effect();
    let written = toml::Table::try_from(&e).unwrap();
    let sections: BTreeSet<&str> = written.keys().map(String::as_str).collect();
    // every effect term but the pre-sliding state, which is a section of the model
    let want: BTreeSet<&str> =
        Effect::terms().filter(|&v| v != Effect::PreslidingHysteresis).filter_map(Effect::section).collect();
    assert_eq!(sections, want);
    for v in Effect::ALL.iter().copied() {
        let mine = e.section(v);
        let file = v.section().and_then(|s| written.get(s)).and_then(|t| t.as_table());
        assert_eq!(mine.as_ref(), file, "{v}");
    }
    assert_eq!(e.present().count(), want.len());
    // a plant file holding these sections reads back the same effects
    let text = format!("[inertia]\nj = 1.0\n{}", toml::to_string(&e).unwrap());
    let pf = PlantFile::parse(&text, "plant.toml").unwrap();
    assert_eq!(pf.effects, e);
}

#[test]
fn compensable_plant_sections_have_the_parameter_tables_keys() {
    let e = every_effect();
    for v in Effect::terms().filter(|v| v.compensable()) {
        let Some(values) = e.section(v) else { continue };
        let plant: BTreeSet<&str> = values.keys().map(String::as_str).collect();
        let table: BTreeSet<&str> = params::section_params(v.section().unwrap()).map(|d| d.key).collect();
        assert_eq!(plant, table, "[{}]", v.section().unwrap());
    }
}
