//! The effect terms the firmware core can compensate use exactly the plant's formulas, so a
//! model emitted by `jointctl diagnose --emit-model` cancels the effect it names.

use host_sim::effects::{
    AsymmetricFriction, CableSpring, DryFriction, Effects, LoadDependentFriction, PositionRipple, Stribeck,
};
use joint_formats::model_file::ModelFile;

const MODEL: &str = r#"
[friction]
c = 2.0
v_band = 0.01

[stribeck]
level = 1.1
speed = 0.03

[asymmetric_friction]
delta = 0.4

[position_ripple]
amplitude = 0.3
period = 0.1
phase = 0.5
amplitude_2 = 0.12
phase_2 = -0.7

[cable_spring]
k = 6.0
engage = 1.2
width = 0.02

[dry_friction]
c = 0.25

[load_dependent_friction]
mu = 0.08
"#;

#[test]
fn core_effect_terms_match_the_plant() {
    let mf = ModelFile::parse(MODEL, "model.toml").unwrap();
    let p = mf.param_set().unwrap();
    let effects = Effects {
        stribeck: Some(Stribeck { level: 1.1, speed: 0.03 }),
        asymmetric_friction: Some(AsymmetricFriction { delta: 0.4 }),
        position_ripple: Some(PositionRipple {
            amplitude: 0.3,
            period: 0.1,
            phase: 0.5,
            amplitude_2: 0.12,
            phase_2: -0.7,
        }),
        cable_spring: Some(CableSpring { k: 6.0, engage: 1.2, width: 0.02 }),
        dry_friction: Some(DryFriction { c: 0.25 }),
        load_dependent_friction: Some(LoadDependentFriction { mu: 0.08 }),
        ..Effects::default()
    };
    let t = p.terms();
    let mut worst = 0.0f64;
    for i in 0..=2000 {
        let q = -0.2 + 2.0 * i as f64 / 2000.0;
        for j in 0..=200 {
            let qd = -0.5 + 1.0 * j as f64 / 200.0;
            let sgn = (qd / 0.01).clamp(-1.0, 1.0);
            // the plant's external load τ_ext; the joint's load cell reads −τ_ext
            let load = 30.0 * ((i * 7 + j) % 13) as f64 / 13.0 - 15.0;
            let plant = effects.torque(q, qd, load, sgn);
            let core = t.extra_torque(q as f32, qd as f32, -load as f32) as f64;
            worst = worst.max((plant - core).abs());
        }
    }
    println!("core effect terms vs plant: worst |difference| {worst:.2e} N·m");
    assert!(worst < 2e-4, "{worst}");
}

#[test]
fn effect_sections_round_trip_and_unknown_keys_are_refused() {
    let mf = ModelFile::parse(MODEL, "model.toml").unwrap();
    let raw = mf.raw_params().unwrap();
    let text = ModelFile::from_raw(&raw, None, &[]).to_toml_string();
    assert!(text.contains("[stribeck]") && text.contains("[cable_spring]"), "{text}");
    let back = ModelFile::parse(&text, "back.toml").unwrap().raw_params().unwrap();
    assert_eq!(back, raw);
    let bad = "[stribeck]\nlevel = 1.0\nspeeed = 0.1\n";
    let e = ModelFile::parse(bad, "bad.toml").unwrap_err().to_string();
    assert!(e.contains("speeed") && e.contains("line 3"), "{e}");
}
