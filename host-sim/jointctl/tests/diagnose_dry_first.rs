//! A file without dry friction, a joint with it: the two torque logs of the independent bench
//! (`diag-bench`, seed 9053, cases 52 and 60) that were called `stribeck`. A Stribeck curve with
//! no Coulomb level under it, its speed wide enough to act as one, fitted them 3 % of the
//! held-out MSE better than the bare level while the refit's other terms bent with it; the
//! truth's own model left the same residual. A Stribeck curve or a pre-sliding state is a
//! shape of dry friction, so it is named first only when it beats `dry_friction` as a second
//! effect must beat the first (`select::dry_first`). The logs are the bench's, written as its
//! `gen` writes them and diagnosed as `jointctl diagnose` reads them.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use diag_bench::gen::{self, ModeSel};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

fn verdict(seed: u64, case: u64) -> (Vec<String>, String) {
    let c = gen::generate(seed, case, None, ModeSel::Any).expect("the bench draws the case");
    let dir = tempfile::tempdir().unwrap();
    gen::write_case(dir.path(), &c, false).unwrap();
    let log = JointLog::read_file(&dir.path().join("log.csv")).unwrap();
    let model = ModelFile::read_file(&dir.path().join("model.toml")).unwrap();
    let d = joint_analysis::diagnose::diagnose(&log, &model, &joint_analysis::diagnose::Options::default()).unwrap();
    let v = &d.report.verdict;
    println!(
        "seed {seed} case {case}: truth {:?}, verdict {} (held-out RMSE {:.4} → {:.4}, floor {:.4})",
        c.truth.effects, v.effect, v.holdout_rmse_before, v.holdout_rmse_after, d.report.gap.noise_floor
    );
    (c.truth.effects.clone(), v.effect.clone())
}

#[test]
fn dry_friction_the_file_lacks_is_not_named_a_stribeck_curve() {
    for case in [52, 60] {
        let (truth, said) = verdict(9053, case);
        assert_eq!(truth, vec!["dry_friction".to_string()], "the bench's case changed");
        assert_eq!(said, "dry_friction", "case {case}");
    }
}
