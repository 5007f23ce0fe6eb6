//! `[presliding]` in the model TOML (strict keys, round trip) and the stateful prediction on a
//! log, which must be the joint controller's own numbers.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use joint_core::control::{self, Controller, Input, Mode};
use joint_core::params::{ParamId, RawParams};
use joint_formats::log::JointLog;
use joint_formats::model_file::{ModelError, ModelFile};
use joint_formats::predict;

const MODEL: &str = r#"
name = "harmonic-drive"

[friction]
a = 0.5
b = 2.0
c = 1.2
v_band = 0.01

[weight]
amplitude = 2.0
s = 1.0
phi = 0.1

[inertia]
j = 0.8

[dry_friction]
c = 0.3

[presliding]        # Dahl state instead of c·sign(qd)
sigma = 800.0
"#;

fn refused(text: &str) -> ModelError {
    match ModelFile::parse(text, "m.toml").and_then(|m| m.param_set().map(|_| ())) {
        Ok(()) => panic!("{text:?} must be refused"),
        Err(e) => e,
    }
}

#[test]
fn parses_into_the_core_parameter_and_the_dahl_level() {
    let m = ModelFile::parse(MODEL, "m.toml").unwrap();
    assert_eq!(m.explicit(ParamId::PreslidingSigma), Some(800.0));
    assert_eq!(m.get("presliding", "sigma"), Some(800.0));
    let p = m.param_set().unwrap();
    let pre = p.terms().presliding;
    assert!(pre.on);
    assert_eq!(pre.c, 1.5, "friction.c + dry_friction.c");
    // Without the section there is no state.
    let plain = ModelFile::parse(&MODEL.replace("[presliding]", "[offset]").replace("sigma", "c0"), "m").unwrap();
    assert!(!plain.param_set().unwrap().terms().presliding.on);
    assert_eq!(plain.explicit(ParamId::PreslidingSigma), None);
}

#[test]
fn unknown_keys_and_bad_values_are_named() {
    let e = refused("[presliding]\nsigma = 800.0\nstiffness = 3.0\n");
    match &e {
        ModelError::UnknownKey { line, section, key, known, .. } => {
            assert_eq!(
                (*line, section.as_str(), key.as_str(), known.as_str()),
                (3, "presliding", "stiffness", "sigma")
            );
        }
        other => panic!("{other:?}"),
    }
    let m = e.to_string();
    assert!(m.contains("m.toml: line 3") && m.contains("`stiffness`") && m.contains("[presliding]"), "{m}");

    let m = refused("[presliding]\nsigma = -5.0\n").to_string();
    assert!(m.contains("line 2") && m.contains("[presliding] sigma") && m.contains("outside"), "{m}");
    let m = refused("[presliding]\nsigma = 2.0e7\n").to_string();
    assert!(m.contains("[presliding] sigma") && m.contains("10000000"), "{m}");
    let m = refused("[presliding]\nsigma = \"stiff\"\n").to_string();
    assert!(m.contains("line 2"), "{m}");
    let m = refused("[presliding]\nsigma = nan\n").to_string();
    assert!(m.contains("[presliding] sigma") && m.contains("not a finite number"), "{m}");
    let m = refused("[pre_sliding]\nsigma = 800.0\n").to_string();
    assert!(m.contains("pre_sliding"), "{m}");
}

#[test]
fn round_trips_through_toml_text() {
    let m = ModelFile::parse(MODEL, "m.toml").unwrap();
    let raw = m.raw_params().unwrap();
    let text = ModelFile::from_raw(&raw, Some("harmonic-drive"), &[]).to_toml_string();
    assert!(text.contains("\n[presliding]\nsigma = 800.0  # N·m/rad\n"), "{text}");
    let back = ModelFile::parse(&text, "back.toml").unwrap();
    assert_eq!(back.raw_params().unwrap(), raw);
    // A set without presliding writes no section (0 is the table default: off).
    let mut off = raw.clone();
    off.set(ParamId::PreslidingSigma, 0.0);
    let text = ModelFile::from_raw(&off, None, &[]).to_toml_string();
    assert!(!text.contains("presliding"), "{text}");
    // The file as written keeps its explicit values.
    assert!(m.to_toml_string().contains("[presliding]\nsigma = 800.0"));
}

/// A torque-mode log of a joint swinging with reversals, a tremor inside the pre-sliding
/// distance and a pause; u − tau is 0 (only the prediction matters here).
fn swing_log(n: usize) -> JointLog {
    let mut log = JointLog {
        t: Vec::new(),
        q: Vec::new(),
        qd: Some(Vec::new()),
        qdd: Some(Vec::new()),
        u: Some(Vec::new()),
        tau: Some(Vec::new()),
        temp: None,
        others: Vec::new(),
        unknown: Vec::new(),
    };
    for i in 0..n {
        let t = i as f64 * 1e-3;
        let w = std::f64::consts::TAU * 0.8;
        let pause = (t % 2.0) > 1.7;
        let (q, qd, qdd) = if pause {
            (0.3, 0.0, 0.0)
        } else {
            let wt = std::f64::consts::TAU * 9.0 * t;
            (
                0.3 + 0.4 * (w * t).sin() + 4e-4 * wt.sin(),
                0.4 * w * (w * t).cos() + 4e-4 * std::f64::consts::TAU * 9.0 * wt.cos(),
                -0.4 * w * w * (w * t).sin(),
            )
        };
        log.t.push(t);
        log.q.push(q);
        log.qd.as_mut().unwrap().push(qd);
        log.qdd.as_mut().unwrap().push(qdd);
        log.u.as_mut().unwrap().push(0.0);
        log.tau.as_mut().unwrap().push(0.0);
    }
    log
}

#[test]
fn prediction_is_the_controllers_disturbance_to_the_bit() {
    let p = ModelFile::parse(MODEL, "m.toml").unwrap().param_set().unwrap();
    let log = swing_log(6000);
    let pred = predict::predicted(&log, &p, &[]).unwrap();
    let force = predict::presliding_force(&log, &p).unwrap();
    // The joint: the core's controller stepping through the same samples (mode Off: C_c is
    // computed and the Dahl state advanced in every mode).
    let mut ctl = Controller::new();
    for i in 0..log.len() {
        let inp = Input {
            q: log.q[i] as f32,
            qd: log.qd.as_ref().unwrap()[i] as f32,
            qdd: log.qdd.as_ref().unwrap()[i] as f32,
            others: [0.0; 3],
            assist_cmd: 0.0,
            tau_load: log.tau.as_ref().map_or(0.0, |t| t[i] as f32),
        };
        let out = ctl.step(&p, Mode::Off, &inp, 1e-3);
        assert_eq!(out.c_c.to_bits(), (pred[i] as f32).to_bits(), "sample {i}");
        assert_eq!(ctl.presliding().force().to_bits(), (force[i] as f32).to_bits(), "sample {i}");
    }
    // The state matters: the stateless sign model differs, by up to 2c right after reversals.
    let c = f64::from(p.terms().presliding.c);
    let worst = (0..log.len())
        .map(|i| {
            let s = control::disturbance(
                &p,
                log.q[i] as f32,
                log.qd.as_ref().unwrap()[i] as f32,
                log.qdd.as_ref().unwrap()[i] as f32,
                &[0.0; 3],
                0.0,
            );
            (f64::from(s) - pred[i]).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst > 1.5 * c, "{worst}");
    assert!(force.iter().all(|f| f.abs() <= c));
}

#[test]
fn without_presliding_the_prediction_is_the_stateless_model() {
    let p = ModelFile::parse(&MODEL.replace("sigma = 800.0", "sigma = 0.0"), "m").unwrap().param_set().unwrap();
    let log = swing_log(3000);
    let pred = predict::predicted(&log, &p, &[]).unwrap();
    for (i, &v) in pred.iter().enumerate() {
        let (q, qd, qdd) = (log.q[i] as f32, log.qd.as_ref().unwrap()[i] as f32, log.qdd.as_ref().unwrap()[i] as f32);
        assert_eq!(v, f64::from(control::disturbance(&p, q, qd, qdd, &[0.0; 3], 0.0)), "sample {i}");
    }
    assert!(predict::presliding_force(&log, &p).unwrap().iter().all(|&f| f == 0.0));
    // Defaults are off.
    assert_eq!(RawParams::defaults().get(ParamId::PreslidingSigma), 0.0);
}
