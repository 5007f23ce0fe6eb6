//! The gap diagnosis on measured data (`shared/data/real`), converted by `jointctl import`'s
//! converter as a user would, against the authors' own model. What is asserted is what physics
//! allows: a candidate whose fitted amplitude has the wrong sign for its effect (a "Stribeck"
//! term that makes friction *rise* towards rest, a drift that would reverse the friction) is
//! never the verdict, and a refit with a negative inertia is reported as a warning naming the
//! parameter. The figures are in docs/diagnosis.md. Without the data sets these tests say so on
//! stderr and check nothing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::path::PathBuf;

use joint_analysis::diagnose::{diagnose, Options};
use joint_formats::import::{convert, Format, ImportOpts};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

/// The authors' sys-id fit of the DFKI pendulum (their `Fc·atan(100 q̇)` as `c = Fc·π/2`).
const DFKI_MODEL: &str = "[friction]\nb = 0.04707\nc = 0.2889\nv_band = 0.02\n\n[weight]\namplitude = 1.0026\ns = 1.0\nphi = 0.0\n\n[inertia]\nj = 0.06259\n\n[offset]\nc0 = -0.07586\n";

fn import(rel: &str) -> Option<JointLog> {
    import_as(Format::DfkiPendulum, rel)
}

fn import_as(format: Format, rel: &str) -> Option<JointLog> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/real")).join(rel);
    let Ok(text) = std::fs::read_to_string(&p) else {
        eprintln!("skipped: {} not found", p.display());
        return None;
    };
    Some(convert(format, &text, rel, &ImportOpts::default()).unwrap().log)
}

/// Energy-shaping swing-up with a 1 kg payload (200 Hz, torque saturated at ±1.5 N·m, q̈
/// derived from a quantised velocity). Unconstrained, a thermal-drift term (time stand-in) that
/// would drive the friction negative within 20 s won here, with a negative-level Stribeck term
/// second: statistics of a chattering torque, not physics.
///
/// That ranking is the one split's (`cross_fit: false`): there the thermal term scores best and
/// only the sign rules keep it out. Cross-fitted (the default), the three folds' refits disagree
/// (one fold's puts the weight at 8.9 N·m and J at 0.47 kg·m², a direction the pendulum's
/// swings barely tell apart), every candidate scores worse than the file on the merged held-out
/// samples, and the verdict is the same: what holds in both is that no wrong-sign term and no
/// refit is named.
#[test]
fn wrong_sign_effects_are_never_the_verdict_on_the_dfki_payload_run() {
    let Some(log) = import("dfki_simple_pendulum/energy_shaping_1kg_measured.csv") else { return };
    let model = ModelFile::parse(DFKI_MODEL, "dfki.toml").unwrap();
    for cross_fit in [false, true] {
        let d = diagnose(&log, &model, &Options { cross_fit, ..Options::default() }).unwrap();
        let r = &d.report;
        let by = |name: &str| r.effects.iter().find(|e| e.effect == name).unwrap_or_else(|| panic!("no {name} entry"));

        // the data want a negative level: the bounded fit holds it at 0 (a candidate is fitted
        // as its best physical self) and it is marked, never named
        let stribeck = by("stribeck");
        assert!(
            stribeck.params["level"] <= 0.0,
            "the data's best Stribeck fit is no positive level: {:?}",
            stribeck.params
        );
        assert!(stribeck.implausible.is_some() && !stribeck.significant);
        let thermal = by("thermal_drift");
        let (coef, t_ref) = (thermal.params["coefficient"], thermal.params["t_ref"]);
        assert!(thermal.implausible.is_some() && !thermal.significant, "coefficient {coef}, t_ref {t_ref}");
        if !cross_fit {
            // it is the best-scoring candidate: without the sign rules it would be the verdict
            assert!(thermal.holdout_rmse_after < by("parameters").holdout_rmse_after);
        }

        // Nothing physical explains the gap, the bounded refit included (the weighted refit
        // takes 1.5 % of the one split's held-out RMSE and scores worse than the file in the
        // weighted MSE the selection reads; unweighted it did worse outright): the log is
        // called unexplained, not pinned on a term.
        assert_eq!(r.verdict.effect, "unexplained", "cross_fit {cross_fit}: {:?}", r.verdict);
        assert_eq!(r.split.cross_fitted, cross_fit.then_some(3));
        let refit = by("parameters");
        assert!(!refit.significant && refit.holdout_rmse_after >= 0.95 * r.verdict.holdout_rmse_before, "{refit:?}");
        for e in r.effects.iter().filter(|e| e.significant) {
            assert!(e.implausible.is_none(), "{} significant though implausible", e.effect);
        }
        let json = serde_json::to_value(r).unwrap();
        assert!(json["effects"].as_array().unwrap().iter().any(|e| e["implausible"].is_string()));
        // The folds' disagreement is reported by term (cross-fitted only: one split has no
        // second fit to compare): J and the weight, which the swings do not tell apart.
        let by_folds: Vec<&[String]> = r
            .not_determined
            .iter()
            .filter(|u| u.why.contains("cross-fitted folds"))
            .map(|u| u.params.as_slice())
            .collect();
        if cross_fit {
            for term in ["inertia.j", "weight.amplitude"] {
                assert!(
                    by_folds.iter().any(|p| p.iter().any(|x| x == term)),
                    "{term} not listed: {:?}",
                    r.not_determined
                );
            }
        } else {
            assert!(by_folds.is_empty(), "{by_folds:?}");
        }
    }
}

/// The hand-moved gravity-compensation run (1 kHz, 30 s): the file's weight is from another
/// configuration, so the refit closes 95 % of the gap; the wrong-sign terms stay out. The
/// logged torque is the commanded gravity torque alone (the hand that moved the joint is not
/// logged), so the rows want no inertia: the refit keeps the file's and says why.
#[test]
fn the_hand_moved_run_is_a_weight_refit_and_no_wrong_sign_term_is_kept() {
    let Some(log) = import("dfki_simple_pendulum/gravity_compensation_handmoved_measured.csv") else { return };
    let model = ModelFile::parse(DFKI_MODEL, "dfki.toml").unwrap();
    let d = diagnose(&log, &model, &Options::default()).unwrap();
    let r = &d.report;
    assert_eq!(r.verdict.effect, "parameters", "{:?}", r.verdict);
    assert!(r.verdict.shrink > 0.9, "{:?}", r.verdict);
    assert!(r.warnings.iter().any(|w| w.contains("inertia.j")), "{:?}", r.warnings);
    assert!(r.refit["inertia"]["j"] > 0.0);
    assert!(r
        .verdict
        .effects
        .first()
        .is_some_and(|e| e != "stribeck" && e != "cable_spring" && e != "load_dependent_friction"));
    let amp = r.refit["weight"]["amplitude"];
    assert!((3.0..3.6).contains(&amp), "refit weight amplitude {amp} N·m (README: the commanded m·g·l·sin q)");
}

/// Panda joint 1 (vertical axis) against a single-joint model with the authors' friction level
/// and the inertia identification finds on this log: the gap is the inertial coupling of six
/// moving links, which no effect of the vocabulary is. The diagnosis must not pin it on one:
/// `unexplained`, with a refit that agrees with the file's values (J ≈ 1.19, c ≈ 0.31; before the
/// preparation knew coloured noise, a ±2 ms q̈ diluted J to 0.25 and that refit was the verdict),
/// and residual evidence that shows the structure left (autocorrelation far outside the band).
/// The gap is 2.8× the floor (1.07 against 0.38 N·m) since the preparation models the angle's
/// falling noise (3.2× before, with a white-noise floor of 0.33).
/// A cable spring fitted as a physical one (stiffness ≥ 0: unconstrained the best was a
/// progressive spring with a negative linear stiffness, a double well no harness makes) does
/// not explain it significantly and is not named.
#[test]
fn panda_joint_1_coupling_is_not_blamed_on_a_single_joint_effect() {
    let p = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/real/panda_gaz2019/panda_exciting_traj1_measured.csv"
    ));
    let Ok(text) = std::fs::read_to_string(&p) else {
        eprintln!("skipped: {} not found", p.display());
        return;
    };
    let opts = ImportOpts { joint: Some(1), ..ImportOpts::default() };
    let log = convert(Format::PandaGaz, &text, "panda", &opts).unwrap().log;
    let model = ModelFile::parse("[inertia]\nj = 1.16\n[friction]\nc = 0.273\nv_band = 0.2\n", "panda1.toml").unwrap();
    let r = diagnose(&log, &model, &Options::default()).unwrap().report;
    assert!(r.gap.holdout_rmse > 2.0 * r.gap.noise_floor, "{:?}", r.gap);
    assert_eq!(r.verdict.effect, "unexplained", "a coupling gap named: {:?}", r.verdict);
    let cable = r.effects.iter().find(|e| e.effect == "cable_spring").unwrap();
    assert!(!cable.significant, "{:?}", cable.params);
    assert!(cable.params.get("k").or(cable.params.get("k3")).is_some_and(|k| *k >= 0.0), "{:?}", cable.params);
    assert!(r.effects.iter().all(|e| !e.significant), "nothing explains it");
    let p = &r.effects.iter().find(|e| e.effect == "parameters").unwrap().params;
    let (j, c) = (p["inertia.j"], p["friction.c"]);
    assert!((1.0..1.4).contains(&j) && (0.2..0.45).contains(&c), "refit J {j}, c {c}");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    let resid = r.resid.as_ref().unwrap();
    let after = &resid.autocorrelation_after;
    assert!(after.outside * 10 >= after.values.len() * 9, "{} of {} lags outside", after.outside, after.values.len());
}

/// The Jensen free swings (angle only, nominal 1 kHz) against a model guessed from the README's
/// period (weight 1.38 N·m at J = 0.01, b = 0.0002). Runs 1 and 3 start while the pendulum is
/// still driven (run 1 passes 136° after a release "from 90°"): their energy rises with no
/// input, so the diagnosis starts at its peak and says so; run 2's rise stays within what the
/// model's error allows. Whatever each run's verdict, the refitted restoring torque is the same
/// pendulum in all three (amplitude 1.19–1.24 N·m at J = 0.01, s within 5 % of 1), and it is
/// never `none`: the guessed model is far off.
#[test]
fn the_jensen_swings_refit_one_pendulum_after_the_release() {
    let model = ModelFile::parse(
        "[weight]\namplitude = 1.38\ns = 1.0\nphi = 0.0\n\n[inertia]\nj = 0.01\n\n[friction]\nb = 0.0002\n",
        "jensen.toml",
    )
    .unwrap();
    for (k, trimmed) in [(1, true), (2, false), (3, true)] {
        let Some(log) = import_as(Format::JensenFreeSwing, &format!("free_swing_pendulum_jensen/free_swing_0{k}.csv"))
        else {
            return;
        };
        let d = diagnose(&log, &model, &Options::default()).unwrap();
        let r = &d.report;
        let release = r.warnings.iter().find(|w| w.contains("energy rises"));
        eprintln!("Jensen run {k}: {:?}, refit {:?}\n  {release:?}", r.verdict, r.refit);
        assert_eq!(release.is_some(), trimmed, "run {k}: {:?}", r.warnings);
        assert!(!matches!(r.verdict.effect.as_str(), "none" | "unexplained"), "run {k}");
        let (a, s) = (r.refit["weight"]["amplitude"], r.refit["weight"]["s"]);
        assert!((1.1..1.35).contains(&a) && (0.95..1.05).contains(&s), "run {k}: amplitude {a}, s {s}");
    }
}
