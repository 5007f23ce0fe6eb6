//! The model file's sections follow from the core's parameter table: every key of every section
//! the table has is read, at its line, and nothing else is a section.

use joint_core::params::{self, PARAMS};
use joint_formats::model_file::{ModelError, ModelFile};

#[test]
fn every_key_of_the_table_is_read_from_its_section() {
    let mut text = String::from("name = \"all\"\n");
    for section in params::sections() {
        text.push_str(&format!("\n[{section}]\n"));
        if section == "gravity_table" {
            // its scalar keys sit beside the table itself
            text.push_str("axes = [\"q\"]\ngrid = [[0.0, 1.0]]\ntorque = [0.0, 0.5]\n");
        }
        for d in params::section_params(section) {
            text.push_str(&format!("{} = {:?}\n", d.key, f64::from(d.default)));
        }
    }
    let mf = ModelFile::parse(&text, "all.toml").expect("every table key parses");
    for d in PARAMS.iter() {
        assert_eq!(mf.explicit(d.id), Some(f64::from(d.default)), "{} was not read from the file", d.name);
    }
}

#[test]
fn an_unknown_section_is_refused_with_the_known_ones() {
    let e = ModelFile::parse("[friction]\nc = 0.1\n\n[flux_capacitor]\nk = 1\n", "m.toml").unwrap_err();
    let ModelError::Toml { file, msg } = &e else { panic!("{e:?}") };
    assert_eq!(file, "m.toml");
    assert!(msg.contains("unknown section `flux_capacitor`"), "{msg}");
    for s in params::sections() {
        assert!(msg.contains(s), "{s} missing from {msg}");
    }
    // a plant's own section is no model section either
    assert!(ModelFile::parse("[thermal_drift]\nalpha_b = 0.01\n", "m.toml").is_err());
    // unless the caller owns it
    let mf = ModelFile::parse_except("[thermal_drift]\nalpha_b = 0.01\n[friction]\nc = 0.2\n", "p.toml", &|s| {
        s == "thermal_drift"
    })
    .expect("owned section skipped");
    assert_eq!(mf.explicit(params::ParamId::FrictionC), Some(0.2));
}
