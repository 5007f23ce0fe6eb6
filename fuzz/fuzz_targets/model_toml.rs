//! Fuzz the model TOML loader (spec §2): any text must give a model or an error naming the
//! place, never a panic; a model that gives a parameter set gives one the joint accepts
//! (`params::check`), and its TOML written out reads back to the same set.
#![no_main]

use joint_core::params::check;
use joint_formats::model_file::ModelFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(model) = ModelFile::parse(text, "fuzz.toml") else { return };
    let Ok(set) = model.param_set() else { return };
    assert!(check(set.raw()).is_ok(), "a parameter set the joint would refuse");
    let again = ModelFile::parse(&model.to_toml_string(), "again.toml").expect("a written model reads back");
    let set2 = again.param_set().expect("and gives a parameter set");
    assert_eq!(set.raw(), set2.raw());
});
