//! Model TOML: the examples load, errors name the key (and line), conversion goes through the
//! core's parameter table, and model → TOML → model round-trips.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

mod common;

use host_sim::plant::PlantFile;
use joint_core::params::{ParamId, RawParams};
use joint_formats::model_file::ModelFile;

fn err(text: &str) -> String {
    match ModelFile::parse(text, "m.toml").and_then(|m| m.param_set().map(|_| ())) {
        Ok(()) => panic!("{text:?} must be refused"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn examples_load_with_the_papers_values() {
    let m = ModelFile::parse(&common::example("examples/models/trunk-right.toml"), "r").unwrap();
    let p = m.param_set().unwrap();
    let deg = 180.0 / std::f32::consts::PI;
    assert!((p.get(ParamId::FrictionA) - 5.77e-4 * deg * deg).abs() < 1e-5);
    assert!((p.get(ParamId::FrictionB) - 0.156 * deg).abs() < 1e-5);
    assert!((p.get(ParamId::WeightS) - 0.014 * deg).abs() < 1e-6);
    assert_eq!(p.get(ParamId::InertiaJ), 2.37);
    assert_eq!(p.get(ParamId::Ratio), 160.0);
    let l = ModelFile::parse(&common::example("examples/models/trunk-left.toml"), "l").unwrap().param_set().unwrap();
    assert!((l.get(ParamId::FrictionA) - 6.52e-4 * deg * deg).abs() < 1e-5);
    assert_eq!(l.get(ParamId::WeightPhi), -3.108);
    let e = ModelFile::parse(&common::example("examples/models/elastic-joint.toml"), "e").unwrap().param_set().unwrap();
    assert_eq!((e.get(ParamId::SpringK), e.get(ParamId::SpringB), e.get(ParamId::InertiaJ)), (7.3035, 0.0416, 0.0085));
}

#[test]
fn every_example_plant_loads() {
    let dir = format!("{}/examples/plants", common::ROOT);
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        PlantFile::read_file(&p).unwrap_or_else(|e| panic!("{e}"));
        n += 1;
    }
    assert!(n >= 11);
}

#[test]
fn errors_name_the_key() {
    let m = err("[friction]\na = 1.0\nd = 2.0\n");
    assert!(m.contains("line 3") && m.contains("`d`") && m.contains("[friction]") && m.contains("v_band"), "{m}");
    let m = err("[frition]\na = 1.0\n");
    assert!(m.contains("frition") && m.contains("line 1"), "{m}");
    let m = err("[friction]\nc = -1.0\n");
    assert!(m.contains("[friction] c") && m.contains("line 2"), "{m}");
    let m = err("[friction]\nc = \"x\"\n");
    assert!(m.contains("line 2"), "{m}");
    let m = err("[compensation]\nfraction = 1.5\n");
    assert!(m.contains("[compensation] fraction"), "{m}");
    let m = err("[controller]\naccel_cutoff = 600.0\n");
    assert!(m.contains("[controller] accel_cutoff"), "{m}");
    let m = err("[gravity_table]\naxes = [\"q\"]\ngrid = [[0.0, 1.0]]\ntorque = [1.0]\n");
    assert!(m.contains("[gravity_table] torque") && m.contains("line 2"), "{m}");
    let m = err("[gravity_table]\naxes = [\"q\"]\ngrid = [[1.0, 0.0]]\ntorque = [1.0, 2.0]\n");
    assert!(m.contains("gravity_table") && m.contains("increasing"), "{m}");
    let m = err(
        "[gravity_table]\naxes = [\"q\", \"hip\"]\ngrid = [[0.0, 1.0], [0.0, 1.0]]\ntorque = [1.0, 2.0, 3.0, 4.0]\n",
    );
    assert!(m.contains("`hip`"), "{m}");
    let m = err("[gravity_table]\naxes = [\"q\"]\ngrid = [[0.0, 1.0]]\ntorque = [1.0, 2.0]\nextra = 1\n");
    assert!(m.contains("extra"), "{m}");
}

#[test]
fn plant_errors_name_the_section() {
    let bad = |t: &str| PlantFile::parse(t, "p.toml").expect_err("refused").to_string();
    let base = "[inertia]\nj = 1.0\n";
    assert!(bad(&format!("{base}[stribeck]\nlevel = 1.0\nspeed = 0.0\n")).contains("[stribeck] speed"));
    assert!(bad(&format!("{base}[stribeck]\nlevel = 1.0\nspeed = 0.1\nfoo = 1\n")).contains("foo"));
    assert!(bad(&format!("{base}[sensors]\nq_noise = -1.0\n")).contains("q_noise"));
    assert!(bad(&format!("{base}[unknown_effect]\nx = 1\n")).contains("unknown_effect"));
    assert!(bad("[friction]\nc = 1.0\n").contains("[inertia] j"));
}

#[test]
fn gravity_table_axes_map_to_slots_in_order_of_first_appearance() {
    let m = ModelFile::parse(
        "[gravity_table]\naxes = [\"q_elbow\", \"q\", \"q_shoulder\"]\ngrid = [[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]]\ntorque = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]\n",
        "g",
    )
    .unwrap();
    assert_eq!(m.other_columns(), vec!["q_elbow".to_string(), "q_shoulder".to_string()]);
    let raw = m.raw_params().unwrap();
    assert_eq!(&raw.table.axis_source[..3], &[1, 0, 2]);
    m.param_set().unwrap();
}

#[test]
fn round_trip_through_toml() {
    for f in ["trunk-right", "trunk-left", "elastic-joint"] {
        let m = ModelFile::parse(&common::example(&format!("examples/models/{f}.toml")), f).unwrap();
        let raw = m.raw_params().unwrap();
        let text = ModelFile::from_raw(&raw, Some(f), &[]).to_toml_string();
        let back = ModelFile::parse(&text, "gen").unwrap().raw_params().unwrap();
        assert_eq!(back, raw, "{text}");
    }
    // With a table, fusion and every section.
    let mut raw = RawParams::defaults();
    raw.set(ParamId::FrictionC, 1.25);
    raw.set(ParamId::SpringQ0, -0.1);
    raw.set(ParamId::VelKp, 3.5);
    let m = ModelFile::parse(
        "[gravity_table]\naxes = [\"q\", \"q_hip\"]\ngrid = [[0.0, 0.5, 1.0], [0.0, 1.0]]\ntorque = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]\nsigma = [0.1, 0.1, 0.1, 0.2, 0.2, 0.2]\nsigma_model = 0.3\n",
        "t",
    )
    .unwrap();
    let t = m.raw_params().unwrap();
    raw.table = t.table.clone();
    raw.set(ParamId::TableSigmaModel, 0.3);
    let text = ModelFile::from_raw(&raw, Some("arm"), &m.other_columns()).to_toml_string();
    let back = ModelFile::parse(&text, "gen").unwrap();
    assert_eq!(back.raw_params().unwrap(), raw, "{text}");
    assert_eq!(back.other_columns(), vec!["q_hip".to_string()]);
    assert!(!text.contains("[weight]") && !text.contains("[inertia]"), "all-default sections are left out:\n{text}");
}
