//! Logs of the independent bench (`diag-bench`; its seeds 9051–9064 were unseen until each was
//! run once, in the seventh to tenth sessions) that the diagnosis got wrong, each pinned on what
//! was changed for it.
//! The logs are the bench's, written as its `gen` writes them and diagnosed as `jointctl
//! diagnose` reads them; a case whose truth is not what the test states fails as changed.
//!
//! - **A file without dry friction, a joint with it** (seed 9053, cases 52 and 60). A Stribeck
//!   curve with no Coulomb level under it, its speed wide enough to act as one, fitted them 3 %
//!   of the held-out MSE better than the bare level while the refit's other terms bent with it;
//!   the truth's own model left the same residual. A Stribeck curve or a pre-sliding state is a
//!   shape of dry friction, so it is named first only when it beats `dry_friction` as a second
//!   effect must beat the first (`select::dry_first`).
//! - **A floor read too high** (seed 9051 case 16; seed 9055 case 34). Where the file's residual
//!   is below the floor the floor is over-read (the derived q̈'s error through a large inertia,
//!   a friction sign near rest). There strong evidence now counts as it does at the floor,
//!   shown in the plain held-out MSE as well; before, only a 15 % gain did, and forward
//!   selection stopped: an asymmetric Coulomb level (10 % of the held-out MSE) was `none`, and
//!   a Stribeck curve under a ripple was missed.
//! - **A start that takes the log to the floor** (trajectory mode; seed 9052 case 9, seed 9057
//!   case 86: logs cut mid-swing). The file's model from the estimated start missed them by
//!   1.35–1.47× the floor and the freed start took them to 0.99–1.04× at p < 1e-11, yet the
//!   start counted only from 1.5×: `none`. It now counts from 1.3× when it reaches the floor
//!   (`trajectory::judge::START_MATTERS`).
//! - **A ripple fitted at its harmonic** (seed 9059 case 47, tenth session). The ripple's second
//!   harmonic was the stronger, the periodogram peaked there, and the fundamental left in the
//!   residual was named a cable spring after the true load-dependent friction. The fundamental at
//!   half the peak's frequency is tried as well (`candidates`, `Kind::Ripple`).
//! - **A delay in disguise** (seed 9054 case 2, tenth session). A trunk joint's state logged
//!   39 ms late reads as its inertia 61 % high (the viscous friction b·q̇ taken at the logged
//!   state adds b·d to it): the refit absorbed the delay and the verdict was `parameters`. The
//!   file's own values with one channel delayed now compete with the refit, and with every refit
//!   of one value (`select::delay_in_disguise`). Its other side, seed 9059 case 99: an elastic
//!   joint's file with its damping alone 35 % low, at 2 kHz, which a state delay of 3 samples
//!   fits as well as the refit does; freeing the damping alone does too, so the log cannot tell,
//!   and it stays `parameters`.
//! - **A start the logged q̈ sees before q does** (seed 9064 case 18, eleventh session). A
//!   model-exact trunk log with logged q̇ and q̈, point-to-point with dwells, was `unexplained`
//!   at 1.8 × the floor: at the end of each dwell the joint accelerates for 10 samples while q is
//!   still inside one encoder step, and the rest test (q̇ and q's own q̈ within their noise)
//!   zeroed a logged q̈ many σ off zero. The residual there was the Coulomb level plus J·q̈. A
//!   logged q̈ kept as white noise now ends a rest where it leaves its noise and its scatter at
//!   rest (`prep`); a logger's low-pass (development seed 9034, case 43) keeps its rests.
//! - **A two-harmonic ripple refined with one** (seed 9065 case 75, eleventh session). Two
//!   harmonics of near equal size (0.068 and 0.065 N·m) over 14 periods of travel: the period,
//!   refined with the fundamental alone and the second harmonic still in the residual, came
//!   out 0.7 % off, a phase error of a third of a radian at the travel's ends, and the residual
//!   after the ripple stayed at 3× the floor. It is refined again with both harmonics in place
//!   (`candidates`, `Kind::Ripple`); the period now comes out within 0.01 %.
//! - **A better fit short of the corrected level** (seed 9066 case 13, eleventh session). An
//!   arm's torque logged 32 ms late: the delay took 20 % of the held-out MSE at p = 9e-3, short of
//!   the Bonferroni level, and a pre-sliding state 17 % at 2e-3 was named alone. A candidate that
//!   explains more than the verdict and beats the file's model at the uncorrected 5 % is now named
//!   as its alternative: the verdict does not beat it, so the log cannot tell them apart.
//! - **Two mesh periods that are not harmonics** (seed 9102 case 29, trajectory mode, twentieth
//!   session). A released elastic joint with a ripple of periods 0.058 and 0.037 rad: the
//!   two-period fit started its second period on a 6-point grid (the nearest start 18 % off)
//!   and prefiltered the starts on the first 40 % of the training samples, where the right one
//!   lost; the verdict was the ripple plus a `dry_friction` that took part of the second mesh.
//!   Where the single ripple leaves the training residual above 1.5× the angle noise, the
//!   second period now starts on a 15 % grid prefiltered on the whole training part.
//! - **A noise sample is no start** (development seed 4 torque case 18, twenty-first session).
//!   One angle sample beyond a rest's 4σ band ended a start's undecided samples while the
//!   joint still stood; q now leaves (or reaches) a rest over three samples in a row.
//! - **A logged q̇'s lone noise sample is no move** (null seed 4242 case 459, the same
//!   session). A logged q̇ now signs a move from two samples in a row beyond 4σ, not one.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use diag_bench::gen::{self, ModeSel};
use joint_analysis::diagnose::Diagnosis;
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

/// The bench's case `(seed, case)`, written as its `gen` writes it and diagnosed as `jointctl
/// diagnose` reads it.
fn run_case(seed: u64, case: u64) -> (diag_bench::case::CaseData, Diagnosis) {
    run_case_in(seed, case, ModeSel::Any)
}

/// [`run_case`] for the bench drawn in one mode (`diag-bench gen --mode`).
fn run_case_in(seed: u64, case: u64, mode: ModeSel) -> (diag_bench::case::CaseData, Diagnosis) {
    run_case_of(seed, case, None, mode)
}

/// [`run_case_in`] for one effect family (`diag-bench gen --family`, e.g. `none`).
fn run_case_of(seed: u64, case: u64, family: Option<&str>, mode: ModeSel) -> (diag_bench::case::CaseData, Diagnosis) {
    let c = gen::generate(seed, case, family, mode).expect("the bench draws the case");
    let d = diagnose_written(&c);
    (c, d)
}

/// The diagnosis of a case as the tool reads it: its log and model written and read back.
fn diagnose_written(c: &diag_bench::case::CaseData) -> Diagnosis {
    let dir = tempfile::tempdir().unwrap();
    gen::write_case(dir.path(), c, false).unwrap();
    let log = JointLog::read_file(&dir.path().join("log.csv")).unwrap();
    let model = ModelFile::read_file(&dir.path().join("model.toml")).unwrap();
    joint_analysis::diagnose::diagnose(&log, &model, &joint_analysis::diagnose::Options::default()).unwrap()
}

/// A model-exact torque case of the null seed 4242 (`--family none --mode torque`) and its
/// logged q̇, for a test to change as a drive would.
fn null_case_with_logged_qd(case: u64) -> diag_bench::case::CaseData {
    let c = gen::generate(4242, case, Some("none"), ModeSel::Torque).expect("the bench draws the case");
    assert_eq!(c.truth.effects, strings(&["none"]), "the bench's case changed (seed 4242 case {case})");
    assert!(c.log.columns.iter().any(|(n, _)| n == "qd"), "seed 4242 case {case} has no logged qd");
    c
}

fn column<'a>(c: &'a mut diag_bench::case::CaseData, name: &str) -> &'a mut Vec<f64> {
    c.log.columns.iter_mut().find(|(n, _)| n == name).map(|(_, v)| v).expect("the column")
}

/// The bench's truth for `(seed, case)` and the effects the diagnosis reports (the verdict's
/// chain, or its one effect).
fn diagnosed(seed: u64, case: u64) -> (Vec<String>, Vec<String>) {
    diagnosed_in(seed, case, ModeSel::Any)
}

/// [`diagnosed`] for the bench drawn in one mode.
fn diagnosed_in(seed: u64, case: u64, mode: ModeSel) -> (Vec<String>, Vec<String>) {
    let (c, d) = run_case_in(seed, case, mode);
    let v = &d.report.verdict;
    let said = said(&d);
    println!(
        "seed {seed} case {case}: truth {:?}, said {said:?} (held-out RMSE {:.4} → {:.4}, floor {:.4})",
        c.truth.effects, v.holdout_rmse_before, v.holdout_rmse_after, d.report.gap.noise_floor
    );
    (c.truth.effects.clone(), said)
}

/// The effects a diagnosis reports: the verdict's chain, or its one effect.
fn said(d: &Diagnosis) -> Vec<String> {
    let v = &d.report.verdict;
    if v.effects.is_empty() {
        vec![v.effect.clone()]
    } else {
        v.effects.clone()
    }
}

/// The diagnosis of `(seed, case)`, whose truth is still `truth` and which reports exactly it.
fn found(seed: u64, case: u64, truth: &[&str]) -> Diagnosis {
    let (c, d) = run_case(seed, case);
    assert_eq!(c.truth.effects, strings(truth), "the bench's case changed (seed {seed} case {case})");
    assert_eq!(said(&d), strings(truth), "seed {seed} case {case}");
    d
}

/// The fitted values the report gives effect `name`.
fn params_of<'a>(d: &'a Diagnosis, name: &str) -> &'a std::collections::BTreeMap<String, f64> {
    &d.report.effects.iter().find(|e| e.effect == name).expect("the candidate").params
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// The bench's truth for `(seed, case)` is still `truth`, and the diagnosis reports exactly it.
fn reports_truth(seed: u64, case: u64, truth: &[&str]) {
    let (t, said) = diagnosed(seed, case);
    assert_eq!(t, strings(truth), "the bench's case changed (seed {seed} case {case})");
    assert_eq!(said, t, "seed {seed} case {case}");
}

#[test]
fn dry_friction_the_file_lacks_is_not_named_a_stribeck_curve() {
    for case in [52, 60] {
        reports_truth(9053, case, &["dry_friction"]);
    }
}

#[test]
fn an_asymmetric_level_under_an_over_read_floor_is_found() {
    reports_truth(9051, 16, &["asymmetric_friction"]);
}

#[test]
fn a_stribeck_curve_under_a_ripple_below_the_floor_is_found_second() {
    let (truth, said) = diagnosed(9055, 34);
    assert_eq!(truth, strings(&["stribeck", "position_ripple"]), "the bench's case changed");
    assert_eq!(said, strings(&["position_ripple", "stribeck"]));
}

#[test]
fn a_log_cut_mid_swing_whose_start_explains_it_is_initial_state() {
    for (seed, case) in [(9052, 9), (9057, 86)] {
        reports_truth(seed, case, &["initial_state"]);
    }
}

#[test]
fn a_ripple_whose_harmonic_is_the_stronger_leaves_no_cable_spring() {
    let (truth, mut said) = diagnosed(9059, 47);
    assert_eq!(truth, strings(&["load_dependent_friction", "position_ripple"]), "the bench's case changed");
    said.sort();
    assert_eq!(said, truth);
}

#[test]
fn a_state_logged_late_is_a_delay_not_an_inertia() {
    reports_truth(9054, 2, &["delay"]);
}

#[test]
fn a_damping_alone_off_that_a_delay_mimics_stays_parameters() {
    reports_truth(9059, 99, &["parameters"]);
}

#[test]
fn a_start_the_logged_acceleration_sees_before_the_angle_is_no_rest() {
    reports_truth(9064, 18, &["none"]);
    // a logged q̈ that is a logger's 15 Hz low-pass (it passes as white: its high-frequency
    // noise is small) scatters at rest by far more than that noise: its rests stay rests, or
    // the dwells that tell an asymmetric level from an offset are lost (development seed 9034)
    reports_truth(9034, 43, &["asymmetric_friction"]);
}

#[test]
fn a_two_harmonic_ripple_of_equal_parts_is_refined_with_both() {
    let (c, d) = run_case(9065, 75);
    assert_eq!(c.truth.effects, strings(&["stribeck", "position_ripple"]), "the bench's case changed");
    let details = serde_json::to_value(&c.truth.effect_details).unwrap();
    let truth = details
        .as_array()
        .and_then(|v| v.iter().find(|e| e["effect"] == "position_ripple"))
        .and_then(|e| e["harmonics"][0]["period"].as_f64())
        .expect("the ripple's period in the truth");
    let v = &d.report.verdict;
    assert_eq!(v.effect, "position_ripple", "{v:?}");
    let p = d.report.selected[0].params["period"];
    let floor = d.report.gap.noise_floor;
    // Since the fourteenth session the refit that scores worse than the file holds the term its
    // folds disagree on, no longer takes part of the Stribeck curve, and the curve is found
    // second (the truth's pair); before, the ripple alone reached 1.05× the floor. The chain's
    // last step is what reaches the floor now.
    let last = d.report.selected.last().unwrap().holdout_rmse_after;
    println!(
        "period {p:.6} ({truth:.6}); effects {:?}; held-out RMSE after the ripple {:.5}, after the chain {last:.5} N·m (floor {floor:.5})",
        v.effects, v.holdout_rmse_after
    );
    assert!((p / truth - 1.0).abs() < 1e-3, "period {p} ({truth})");
    assert_eq!(v.effects, strings(&["position_ripple", "stribeck"]), "{v:?}");
    assert!(last < 1.1 * floor, "held-out RMSE after the chain {last} (floor {floor})");
}

#[test]
fn a_candidate_that_explains_more_short_of_the_corrected_level_is_named_beside_the_verdict() {
    let (c, d) = run_case(9066, 13);
    assert_eq!(c.truth.effects, strings(&["delay"]), "the bench's case changed");
    let v = &d.report.verdict;
    let alts: Vec<&str> = v.alternatives.iter().map(|a| a.effect.as_str()).collect();
    println!("verdict {} ({:?}), alternatives {alts:?}", v.effect, v.effects);
    assert!(v.effect == "delay" || alts.contains(&"delay"), "verdict {}, alternatives {alts:?}", v.effect);
}

/// A 6 ms lag of a torque logged with 0.55 mN·m of white noise (trajectory mode, 460 samples
/// at 50 Hz, SNR 1.0): every noise jump of the logged input had counted as an edge the samples
/// leave unplaced, which gave the input half a sample (10 ms) of slack, and the delay, 20 % at
/// p = 7e-7, was ruled out as "within the time the samples leave open"; the log was `none`.
/// The noise is now read from the input, and only changes beyond it are edges.
#[test]
fn a_noisy_logged_input_is_not_read_as_edges() {
    reports_truth(9059, 43, &["delay"]);
}

/// Trajectory mode names beside the verdict what fits the held-out samples better and beats the
/// refit at the uncorrected level, as torque mode does: t9053/0062 (a ripple and an asymmetric
/// friction under a stepped torque, 5 000 samples) is `parameters`, and the asymmetry (4 % less
/// held-out MSE than the refit at p = 5e-3, short of the corrected level) was dropped; it is
/// now named beside it.
#[test]
fn a_trajectory_candidate_that_fits_better_than_the_verdict_is_named_beside_it() {
    let (c, d) = run_case(9053, 62);
    assert_eq!(c.truth.effects, strings(&["position_ripple", "asymmetric_friction"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    let v = &d.report.verdict;
    let alts: Vec<&str> = v.alternatives.iter().map(|a| a.effect.as_str()).collect();
    println!("verdict {} ({:?}), alternatives {alts:?}", v.effect, v.effects);
    let named = |e: &str| v.effect == e || v.effects.iter().any(|x| x == e) || alts.contains(&e);
    assert!(named("asymmetric_friction"), "verdict {} {:?}, alternatives {alts:?}", v.effect, v.effects);
}

/// A noisy angle at rest is not motion: t9072/0069 (a pendulum's weight 41 % high and its
/// inertia 36 % low, released from 1.1 rad at 95 Hz with 15 mrad of angle noise) swings for 3 s
/// of 25. Read against 2 % of the swing's range alone, the noise kept the rest "moving" to the
/// last sample, the held-out blocks held 0.6 s of the swing, and the log was `none`. The rest is
/// now read against the noise as well and cut, since the log rests where the model does.
#[test]
fn a_noisy_rest_after_a_swing_is_cut_where_log_and_model_rest_alike() {
    reports_truth(9072, 69, &["parameters"]);
}

/// ... and a noisy rest that holds the evidence is kept: t9058/0086 (a ripple whose well holds
/// the joint 5 mrad from the model's rest, 1.4 sd of the noise per sample over the tail) is found
/// from that tail; cut, it was `none`.
#[test]
fn a_noisy_rest_away_from_the_models_is_kept() {
    reports_truth(9058, 86, &["position_ripple"]);
}

/// ... but scored at one sample in m (and fitted in full), so it does not outweigh the motion in
/// the held-out part: t9063/0095 (a weight 31 % low, a 1.4 s swing and 12.6 s of rest 3.7 mrad
/// from the model's, 10 mrad of noise) was `none` with the whole rest read (nine in ten held-out
/// samples at rest, the file's model at 1.06× the floor over them), and t9057/0057 (pre-sliding
/// friction, the rest 0.6 sd per sample away) was `parameters` with the rest read in full and
/// `none` with it cut.
#[test]
fn a_long_rest_that_holds_evidence_is_scored_thinned_not_cut() {
    reports_truth(9063, 95, &["parameters"]);
    reports_truth(9057, 57, &["presliding_hysteresis"]);
}

/// A refit stuck where an effect's fit is not: t9061/0083 (an elastic joint's inertia 2.2× the
/// file's and its Coulomb level 30 % lower, a free release at 1 kHz). With the rest tail cut,
/// the refit from the file's values stopped at 2.6× the floor while a pre-sliding fit on top of
/// a refit, moving the model's terms as well, reached the floor (p = 3e-42 against the refit)
/// and was named. The refit is now restarted from where the effects' fits ended, their effect
/// dropped, and reaches the floor itself.
#[test]
fn a_refit_stuck_in_a_local_minimum_is_restarted_before_an_effect_is_named() {
    reports_truth(9061, 83, &["parameters"]);
}

/// Two ripples named with a pad beside them (unseen seed 9075, fourteenth session):
/// t9075/0012, a ripple of 0.056 rad over 0.119 rad of travel whose periodogram maximum sat in
/// its first bin, which the peak search skipped; t9075/0080, two ripples near 2:1 (0.0164 and
/// 0.0266 rad) read as one profile of 0.0327 rad with its harmonic. Both were
/// `position_ripple` + `cable_spring`; the edges of the periodogram count now, and the peak
/// alone with a second period is compared with the profile (`candidates`, `Kind::Ripple`).
#[test]
fn a_ripple_alone_leaves_no_pad_beside_it() {
    reports_truth(9075, 12, &["position_ripple"]);
    reports_truth(9075, 80, &["position_ripple"]);
}

/// A refit that overfits is not the base an effect is fitted on: t9076/0034 (a trunk joint
/// under a human's torque, 63 % at rest) refitted to 2.7× the file's held-out RMSE, its folds
/// putting the weight's cosine part at −25.7, 4.7 and 5.7 N·m, and every candidate on top of
/// that refit scored worse than the file's model: `unexplained`. The terms the folds disagree
/// on are now held at the file's values (as the emitted model keeps them) when the refit scores
/// worse than the file, and the asymmetric Coulomb level reaches the floor.
#[test]
fn terms_the_folds_disagree_on_are_held_when_the_refit_overfits() {
    reports_truth(9076, 34, &["asymmetric_friction"]);
}

/// A second effect that takes a clear share where the first left the floor (seed 9084 case 51,
/// an unseen set of the fifteenth session, seen since). A ripple left 0.70× the floor (read over
/// the samples whose direction of motion is uncertain) and friction growing with the load took
/// 38 % of the held-out MSE under it at p = 6e-4, short of the strong-evidence bar a further
/// effect at the floor had to meet, while a first effect that takes 15 % counts there (the floor
/// over-read); a further one now counts the same. (The two cases this test first used, seed 9051
/// case 73 and seed 9053 case 74 in torque mode, sat at 15.7 % and 18 %; with the jitter of their
/// clocks no longer read as noise, their q̈ windows and floors moved, and their second effects
/// fell under the bar: see `a_clock_that_jitters_and_says_so_is_no_effect`.)
#[test]
fn a_second_effect_that_takes_a_clear_share_at_the_floor_is_named() {
    let (t, s) = diagnosed(9084, 51);
    assert_eq!(t, strings(&["load_dependent_friction", "position_ripple"]), "the bench's case changed");
    assert_eq!(s, strings(&["position_ripple", "load_dependent_friction"]));
}

/// A kind pruned in one fold is fitted in all (seed 9051 case 9 in torque mode, sixteenth
/// session). A Stribeck curve at SNR 4 under a ripple at 18: the first fold's ripple left 80 times
/// the training RSS of the other two, the Stribeck curve lowered it by under 1 % there and was
/// pruned, and a kind one fold lacks was dropped from all three: `position_ripple` alone. Fitted
/// in every fold it takes 16 % of the held-out MSE at p = 3e-4.
#[test]
fn a_kind_pruned_in_one_fold_is_still_judged_on_all_of_them() {
    let (t, s) = diagnosed_in(9051, 9, ModeSel::Torque);
    assert_eq!(t, strings(&["stribeck", "position_ripple"]), "the bench's case changed");
    assert_eq!(s, strings(&["position_ripple", "stribeck"]));
}

/// A noise sample beyond a rest's band is no start (development seed 4, torque case 18, the
/// twenty-first session): a model-exact trunk log at 2 kHz, point-to-point with long dwells, a
/// pure Coulomb level of 17 N·m. One angle sample 4.2σ off the rest 45 ms after the rest
/// detector's end ended the undecided samples there while the joint stood for another 90 ms;
/// the q̇ estimate over them (its window reaching into the coming move) changed sign twice, and
/// the residual was ±c on 157 samples: `unexplained` at 1.8× the floor. q now leaves a rest
/// only when it stays beyond the band for three samples in a row.
#[test]
fn a_noise_sample_beyond_a_rests_band_is_no_start() {
    let (t, said) = diagnosed_in(4, 18, ModeSel::Torque);
    assert_eq!(t, strings(&["none"]), "the bench's case changed (seed 4 case 18)");
    assert_eq!(said, t, "development seed 4 case 18");
}

/// A logged q̇'s lone noise sample is no move (null seed 4242 case 459, the same session): a
/// model-exact arm log at 500 Hz with a white logged q̇, one sample of it 4.1σ off zero in a
/// dwell. It broke the rest, signed itself, and put the Coulomb level (5.2 N·m) on one sample:
/// `unexplained` at 2× the floor. A logged q̇ signs a move from two samples in a row now.
#[test]
fn a_logged_velocitys_lone_noise_sample_is_no_move() {
    let (c, d) = run_case_of(4242, 459, Some("none"), ModeSel::Any);
    assert_eq!(c.truth.effects, strings(&["none"]), "the bench's case changed (null seed 4242 case 459)");
    assert_eq!(d.report.verdict.effect, "none", "null seed 4242 case 459: {:?}", d.report.verdict);
}

/// Model-exact torque logs whose clock jitters by 5–14 % of the step, each row stamped with the
/// time its sample was taken (null seed 31, cases 174 and 227, `--family none --mode torque`).
/// The spectrum read the angle's differences over the median step, took the jitter for a noise
/// of q̇·δt up to 3.7 times the encoder's, chose a q̈ window that wide, and the refit took the
/// window's attenuation of a chirp's top (J·Δq̈) for `parameters`. Differences over each row's
/// own step (`prep::spectrum`) leave the encoder's noise, and both are `none`.
#[test]
fn a_clock_that_jitters_and_says_so_is_no_effect() {
    for case in [174, 227] {
        let (c, d) = run_case_of(31, case, Some("none"), ModeSel::Torque);
        assert!(c.truth.effects == ["none"] && c.truth.time_jitter > 0.04, "the bench's case changed (case {case})");
        assert_eq!(d.report.verdict.effect, "none", "null seed 31 case {case}: {:?}", d.report.verdict);
    }
}

/// A clear gain under the floor shows in the plain held-out MSE too (null seed 777 torque case
/// 19, the twenty-fifth session): a model-exact Fourier motion at 1 kHz on a 1.5 mrad encoder
/// with a Coulomb level of 11 N·m, its floor set by the sign's uncertainty (1.28 N·m against a
/// residual of 0.70). Once q̈'s local bias stopped being read from its noise the samples' weights
/// moved, and a ripple took 19 % of the weighted held-out MSE and 0.4 % of the plain one: over
/// the 15 % that counts at the floor, and named. Strong evidence below the floor already had to
/// show in the plain MSE; a clear gain now does too.
#[test]
fn a_clear_gain_below_the_floor_shows_in_the_plain_error_too() {
    let (c, d) = run_case_of(777, 19, Some("none"), ModeSel::Torque);
    assert_eq!(c.truth.effects, strings(&["none"]), "the bench's case changed (null seed 777 case 19)");
    assert_eq!(d.report.verdict.effect, "none", "null seed 777 case 19: {:?}", d.report.verdict);
}

/// A pre-sliding state whose travel is read from the angle's own steps (seed 9085 case 30, an
/// unseen set of the sixteenth session, seen since: an elastic joint point-to-point at 338 Hz,
/// a 0.05 mrad encoder without white noise, a Dahl friction of 0.45 mrad). The state integrated
/// the prepared q̇, whose ±92 ms window spreads each reversal: its distance came out at 1.29 mrad,
/// and a ripple of 4.7 mrad took the shape's error as a second effect. The travel from the
/// angle's own steps is searched beside it (`candidates::travel`); here it fits, the distance
/// comes out within 10 % of the truth, and nothing is named beside it.
#[test]
fn a_presliding_state_reads_its_travel_from_the_angle_where_that_fits() {
    let d = found(9085, 30, &["presliding_hysteresis"]);
    let distance = params_of(&d, "presliding_hysteresis")["distance"];
    assert!((distance / 0.000_452_7 - 1.0).abs() < 0.1, "pre-sliding distance {distance} rad against 0.4527 mrad");
}

/// A clean q̇ logged beside a noisy logged q̈ (seed 9082 case 61, an unseen set of the fourteenth
/// session, seen since: a point-to-point at 136 Hz whose viscous friction drifts with a logged
/// temperature). The q̇ column's difference from q's derivative spread 10 % beyond that
/// derivative's modelled error, and the excess was taken for the column's noise (3.3e-5 rad/s,
/// against its own spectrum's 1.4e-6): the q̈ from it then looked no better than the logged one,
/// whose white noise (1.6e-3 rad/s²) times the inertia took the residual to twice what it is,
/// and the verdict was `unexplained`. Within the estimate's error the excess is the estimate's:
/// the column keeps its own noise, q̈ is taken from it (error 3e-4 rad/s²), and the drift is
/// found.
#[test]
fn a_clean_logged_velocity_keeps_its_own_noise_and_gives_the_acceleration() {
    let d = found(9082, 61, &["thermal_drift"]);
    let prep = d.report.prep.as_ref().expect("the preparation's report");
    assert_eq!(prep.qd.source, "logged");
    assert!(prep.qd.noise_sd < 1e-5, "{:?}", prep.qd);
    assert_eq!(prep.qdd.source, "derived from the logged qd", "{:?}", prep.qdd);
}

/// Dry friction with a sign band the file does not state (seed 9091 case 5, an unseen set of
/// the seventeenth session, seen since: a pendulum released at 209 Hz, 23 mrad of angle noise,
/// its file without a Coulomb term; the plant's c = 3.06 N·m with a band of 0.030 rad/s). At
/// rest the band lets it creep towards its equilibrium, which the pure sign holds: the
/// candidate with the pure sign left 1.4× the floor and a ripple that fits the creep was named.
/// The band is searched with the level where the file states none; its values come out within
/// 5 % of the plant's and the emitted model carries the band.
#[test]
fn dry_friction_with_a_band_the_file_does_not_state_is_found_with_it() {
    let d = found(9091, 5, &["dry_friction"]);
    let p = params_of(&d, "dry_friction");
    let (level, band) = (p["c"], p["v_band"]);
    assert!((level / 3.055 - 1.0).abs() < 0.05, "c {level} N·m against 3.055");
    assert!((band / 0.02988 - 1.0).abs() < 0.05, "v_band {band} rad/s against 0.02988");
    assert!(d.emitted_model.contains("v_band = "), "{}", d.emitted_model);
}

/// A logged q̇ whose noise is coloured, as a drive's filtered velocity estimate's is: model-exact
/// torque logs of the null seed 4242 (cases 29, 35 and 168, each with a logged q̇) with an
/// AR(1) noise of ρ = 0.9 and 1 % of the q̇'s RMS added to it. Such a noise's top quarter of the
/// spectrum reads it at √((1 − ρ)/(1 + ρ)) = 0.23× its size; read so, the column passed as
/// nearly clean, a reversal's sign was taken as known where the noise had flipped it, the
/// residual there was twice the Coulomb level, and all three were `unexplained`. A column
/// whose spectrum rises towards low frequencies now has its noise bounded by its difference
/// from the derivative of q, which holds the slow part the spectrum cannot see under the
/// motion, and all three are `none`.
#[test]
fn a_logged_velocity_with_coloured_noise_leaves_a_model_exact_log_explained() {
    for (case, sigma) in [(29, 1.8e-3), (35, 6.8e-4), (168, 7.7e-4)] {
        let mut c = null_case_with_logged_qd(case);
        let qd = column(&mut c, "qd");
        let mut rng = diag_bench::rngs::stream(4242, case, 0xC01);
        let e = diag_bench::noise::ar1(&mut rng, qd.len(), sigma, 0.9);
        qd.iter_mut().zip(&e).for_each(|(v, e)| *v += e);
        let d = diagnose_written(&c);
        let prep = d.report.prep.as_ref().expect("the preparation's report");
        println!("case {case}: qd {:?}; said {:?}", prep.qd, said(&d));
        assert_eq!(said(&d), strings(&["none"]), "seed 4242 case {case}");
    }
}

/// A logged q̇ late by less than a sample: a drive's first-order low-pass at 30 Hz on its
/// velocity estimate, on a model-exact torque log of a trunk joint at 100 Hz with a viscous
/// friction of 87 N·m·s/rad (null seed 4242, case 128). The filter is 1.79 ms late; no shift by
/// whole samples explains it, and its error, −τ·q̈, is under the column's noise figure. Read as
/// the q̇, the viscous term took it for an inertia off by b·τ, and the log was `parameters`
/// with J refitted 2.2× high. The lag is now measured and counted with the column's noise: the
/// derivative of q is used, the preparation says why, and the log is `none`.
#[test]
fn a_logged_velocity_late_by_less_than_a_sample_is_not_taken_for_the_velocity() {
    let mut c = null_case_with_logged_qd(128);
    let t = column(&mut c, "t").clone();
    let dt = t[1] - t[0];
    let qd = column(&mut c, "qd");
    *qd = diag_bench::noise::causal_lowpass(&t, qd, 30.0);
    let d = diagnose_written(&c);
    let prep = d.report.prep.as_ref().expect("the preparation's report");
    println!("qd {:?}; notes {:?}; said {:?}", prep.qd, prep.notes, said(&d));
    // the filter's lag at low frequency: (1 − α)/α samples
    let alpha = 1.0 - (-std::f64::consts::TAU * 30.0 * dt).exp();
    let lag_ms = 1e3 * dt * (1.0 - alpha) / alpha;
    let note = prep.notes.iter().find(|n| n.contains("lags the derivative of q")).expect("a note on the lag");
    let said_ms: f64 =
        note.split(" by ").nth(1).and_then(|r| r.split(" ms").next()).and_then(|x| x.parse().ok()).unwrap();
    assert!((said_ms / lag_ms - 1.0).abs() < 0.1, "{note} against {lag_ms:.2} ms");
    assert_eq!(said(&d), strings(&["none"]));
}

#[test]
fn two_mesh_periods_that_are_not_harmonics_are_one_ripple() {
    let (c, d) = run_case(9102, 29);
    assert_eq!(c.truth.effects, strings(&["position_ripple"]), "the bench's case changed");
    let details = serde_json::to_value(&c.truth.effect_details).unwrap();
    let periods: Vec<f64> = details[0]["harmonics"]
        .as_array()
        .expect("the ripple's harmonics in the truth")
        .iter()
        .filter_map(|h| h["period"].as_f64())
        .collect();
    assert_eq!(said(&d), strings(&["position_ripple"]), "{:?}", d.report.verdict);
    let params = &d.report.selected[0].params;
    let mut got = [params["period"], params.get("period_2").copied().expect("a second period fitted")];
    got.sort_by(f64::total_cmp);
    let mut want = [periods[0], periods[1]];
    want.sort_by(f64::total_cmp);
    for (g, w) in got.iter().zip(&want) {
        assert!((g / w - 1.0).abs() < 0.02, "periods {got:?}, truth {want:?}");
    }
    // (cross-fitted since the twenty-seventh session: every fold's refit scored on its own
    // held-out blocks, 1.115× the floor over 1 448 samples, where the first fold alone read
    // 1.092× over 482)
    let v = &d.report.verdict;
    assert!(v.holdout_rmse_after < 1.15 * d.report.gap.noise_floor, "{v:?}, floor {}", d.report.gap.noise_floor);
}

/// A short log's floor is not read from a residual that holds the effect (development seed 8,
/// trajectory mode, case 113: an input read 32 ms late, 61 samples at 100 Hz, 14 mrad of angle
/// noise). The floor came from the best fit's training residual, 2.9× the angle noise since no
/// refit absorbs the delay; the held-out RMSE sat under it and the log was `none`. Where that
/// reading is significantly above q's own fourth differences', the differences' is the floor.
#[test]
fn a_short_logs_floor_is_not_read_from_a_residual_that_holds_the_effect() {
    let (c, d) = run_case_in(8, 113, ModeSel::Trajectory);
    assert_eq!(c.truth.effects, strings(&["delay"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    let noise = c.truth.noise_rms;
    let floor = d.report.gap.noise_floor;
    println!("floor {floor:.4} against the angle noise {noise:.4}; verdict {:?}", d.report.verdict);
    assert!(floor < 1.5 * noise, "floor {floor} against the angle noise {noise}");
    assert_eq!(said(&d), strings(&["delay"]));
}

/// A start the file's model cannot follow is tested against the first angle's noise (seed 9103,
/// case 61, trajectory mode: a pendulum whose Coulomb level exceeds its weight, pushed at
/// 0.84 rad/s from 1.00 rad, sticks 37 mrad on within 0.1 s and stays there for 26 s). The
/// freed start took the log from 35× the floor to the floor at p = 0, but the test's width for
/// the angle was the fits' prior, which spans the distance to the start that makes the model
/// follow the first samples: the 37 mrad read as 1.2 of it, and the log was `none`.
/// The report gives the χ² that decided beside the wide one: the wide test's χ² is under its
/// bar on this log, and shown alone it contradicted the verdict.
#[test]
fn a_start_the_model_cannot_follow_is_read_against_the_angles_noise() {
    let (c, d) = run_case(9103, 61);
    assert_eq!(c.truth.effects, strings(&["initial_state"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    assert_eq!(said(&d), strings(&["initial_state"]));
    let p = params_of(&d, "initial_state");
    // χ² with 2 degrees of freedom at p = 0.001, the start test's bar
    let bar = -2.0 * 0.001f64.ln();
    println!("initial_state params {p:?}");
    assert!(p["chi2"] <= bar, "the wide test alone decides this start now: {p:?}");
    assert!(p["chi2_angle_noise"] > bar, "{p:?}");
    assert!(p["q_noise_sd"] > 0.0 && p["q_noise_sd"] < p["q_estimate_sd"], "{p:?}");
}

/// A file whose offset is wrong shifts its rests as it shifts the motion, and that is no creep
/// (seed 9114, case 1, torque mode: a point-to-point log with dwells, the offset 0.47 N·m off
/// under a pure Coulomb level of 0.75 N·m). Read from the file's model alone, 2 178 of the 3 280
/// rest samples stood at ±c and were left out as creeps; the rests that stayed pulled the
/// refit's offset, and an asymmetric friction took what that left (p = 6e-19): the verdict was
/// `asymmetric_friction`. A creep is now a rest at ±c from the file's model and from the model's
/// terms refitted on the motion.
#[test]
fn a_wrong_offset_at_rest_is_no_creep() {
    let (c, d) = run_case(9114, 1);
    assert_eq!(c.truth.effects, strings(&["parameters"]), "the bench's case changed");
    assert_eq!(d.report.mode, "torque");
    let creeps = d.report.gap.rest_creep_samples.unwrap_or(0);
    println!("creep samples {creeps}; verdict {:?}", d.report.verdict);
    assert!(creeps < 300, "{creeps} rest samples left out as creeps");
    assert_eq!(said(&d), strings(&["parameters"]));
}

/// A trajectory floor is never above what a fit of the file's terms leaves held out (seed 9114,
/// case 9: an elastic joint with asymmetric friction driven by a smooth random input at 100 Hz).
/// The spread of reading the input between its samples put the floor at 7.2e-4 rad, where the
/// refit left 1.7e-4 held out; the file's model at 5.1e-4 was "at the floor", and the log
/// `none` though the refit took 67 % off it at p = 2e-11. With the floor at the best held-out
/// fit's, the refit is the verdict, and the asymmetry it cannot be told from while the joint
/// moves is named beside it.
#[test]
fn a_trajectory_floor_is_not_above_what_the_refit_leaves() {
    let (c, d) = run_case(9114, 9);
    assert_eq!(c.truth.effects, strings(&["asymmetric_friction"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    let v = &d.report.verdict;
    let alts: Vec<&str> = v.alternatives.iter().map(|a| a.effect.as_str()).collect();
    let floor = d.report.gap.noise_floor;
    println!("floor {floor:.3e}; verdict {} ({:?}), alternatives {alts:?}", v.effect, v.effects);
    assert!(floor < 3e-4, "floor {floor}");
    assert_ne!(v.effect, "none");
    assert!(v.effect == "asymmetric_friction" || alts.contains(&"asymmetric_friction"), "{} {alts:?}", v.effect);
}

/// A short trajectory window is cross-fitted (development seed 9107, case 61: a 1.9 s free
/// release of an elastic joint at 100 Hz, a Stribeck rise at 4.2× the angle noise). On one split
/// its 37 held-out samples tested the curve's 48 % at p = 0.04 against the file's model, short of
/// the corrected level, and the log was `unexplained` with `stribeck` first among the closest;
/// over three folds every inner block is held out once, and the curve is the verdict.
#[test]
fn a_short_free_releases_stribeck_rise_is_found_over_three_folds() {
    let (c, d) = run_case(9107, 61);
    assert_eq!(c.truth.effects, strings(&["stribeck"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    let split = &d.report.split;
    println!("split {split:?}; verdict {:?}", d.report.verdict);
    assert_eq!(split.cross_fitted, Some(3));
    // every inner block held out once: about 90 % of the window, against 30 % on one split
    let scored = split.holdout_scored.expect("the held-out samples over the folds");
    assert!(scored > 2 * split.holdout, "{scored} scored, {} in the first fold", split.holdout);
    assert_eq!(said(&d), strings(&["stribeck"]));
}

/// A start the freed start explains is no effect that the freed start beats (unseen seed 9117,
/// case 40, traced after its run: an elastic joint's log cut mid-swing at 9.6 rad/s, 62 samples
/// at 50 Hz). From the assumed rest the file's model is far off, and cross-fitted, a harness
/// that bends the first swing took 39 % off it at p = 3e-7 and was the verdict, where the freed
/// start takes 84.5 %: the log is `initial_state`.
#[test]
fn a_start_cut_mid_swing_is_no_harness_that_bends_its_first_swing() {
    let (c, d) = run_case(9117, 40);
    assert_eq!(c.truth.effects, strings(&["initial_state"]), "the bench's case changed");
    assert_eq!(d.report.mode, "trajectory");
    println!("verdict {:?}", d.report.verdict);
    assert_eq!(said(&d), strings(&["initial_state"]));
    assert!(d.report.verdict.shrink > 0.8, "{:?}", d.report.verdict);
}
