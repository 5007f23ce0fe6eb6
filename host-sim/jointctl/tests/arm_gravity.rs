//! Arm gravity fusion end to end (issue 7, arm paper): the Appendix A CAD model as each joint's
//! series, residual tables identified on the paper's grid, four joint nodes on the simulated
//! bus exchanging angles by PDO. Checks the issue's claims on the measured numbers, the clamp
//! beyond the table's range, that a bad series is refused over CAN with the old set still in
//! force, and the optional `[gravity_series]` model TOML section.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_can::transfer::{self, PushOptions};
use joint_core::series::TERMS_MAX;
use joint_formats::model_file::{ModelError, ModelFile};
use jointctl::arm::{self, bus::node_id, cad, ArmConfig, Method};

#[test]
fn fused_beats_cad_on_every_joint_and_the_clamp_holds_beyond_the_range() {
    let (r, _) = arm::run(&ArmConfig::default(), &mut |_| {}).unwrap();
    let (cad, table, fused) = (&r.in_range.cad, &r.in_range.table, &r.in_range.fused);
    for j in 0..4 {
        assert!(
            fused.rrmse_pct[j] < cad.rrmse_pct[j],
            "joint {}: fused RRMSE {:.2} % not below CAD {:.2} %",
            j + 1,
            fused.rrmse_pct[j],
            cad.rrmse_pct[j]
        );
        // the CAD model's errors are of the paper's size (Table 6 CAD: 0.44–1.49 N·m)
        assert!(cad.max_abs[j] > 0.3 && cad.max_abs[j] < 2.5, "joint {}: CAD max error {}", j + 1, cad.max_abs[j]);
    }
    // Table only (the data estimate) is the closer fit, fusion the conservative one (paper §4.4).
    let better = (0..4).filter(|&j| table.rrmse_pct[j] <= fused.rrmse_pct[j]).count();
    assert!(better >= 3, "table-only RRMSE ≤ fused on {better} joints: {table:?} vs {fused:?}");

    let o = &r.out_of_range;
    assert!(o.clamp_bound_holds, "fused torque left τ_m ± k·σ_m beyond the range");
    assert!(o.max_deviation_over_band <= 1.0 + 1e-6, "{}", o.max_deviation_over_band);
    // the clamp had something to do: without it the data pulls past the band
    assert!(o.max_unclamped_over_band > 1.0, "{}", o.max_unclamped_over_band);
    assert!(o.clamp_active_share > 0.0);

    // The sweep across joint 1's range edge: the table's error grows beyond S_1 while the
    // fused torque stays at most k·σ_m from the model.
    let w = &r.sweep;
    let s1 = r.range_deg[w.joint - 1];
    let err = |v: &[f64], i: usize| (v[i] - w.measured[i]).abs();
    let edge = w.q_deg.iter().position(|&q| q >= s1).unwrap();
    let last = w.q_deg.len() - 1;
    assert!(w.q_deg[last] > s1 + 20.0);
    assert!(err(&w.table, last) > err(&w.table, edge) + 0.5, "table-only error does not grow beyond the range");
    for i in 0..w.q_deg.len() {
        assert!((w.fused[i] - w.cad[i]).abs() <= w.band * (1.0 + 1e-6), "sweep point {i}");
    }

    // The Appendix A check: τ1 verbatim is the gradient, the others measurably are not.
    assert!(r.appendix_a.literal_vs_gradient[0] < 1e-9);
    assert!(r.appendix_a.literal_vs_gradient[1] > 0.1);
    assert_eq!(r.poses, 11_700);
}

#[test]
fn a_bad_series_is_refused_over_can_and_the_old_set_stays() {
    let cfg = ArmConfig { id_cycles: 10, ..ArmConfig::default() };
    let plant = arm::plant::ArmPlant::default();
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let data = arm::identify::collect(&plant, cfg.id_cycles, &mut rng);
    let id = arm::identify(&cad::CadModel::paper(), &data).unwrap();
    let mut b = arm::bus::ArmBus::new().unwrap();
    let sets: Vec<_> = (0..4).map(|j| arm::joint_params(&id, j, Method::Fused(1.0))).collect();
    b.push(&sets).unwrap();
    let q = [0.5, 0.6, 0.7, 0.8];
    let (before, _) = b.hold(&q).unwrap();
    let good = sets[0].clone();
    let pushed = b.joints[0].lock().unwrap().node.params().raw().clone();
    assert_eq!(pushed, good, "the push put the whole set in force, series included");
    // pulled back over SDO, and through the model TOML, it is the same set
    let (pulled, pending) = transfer::pull(&mut b.master, node_id(0)).unwrap();
    assert!(!pending);
    assert_eq!(pulled, good);
    let cols = vec!["q_j2".to_string(), "q_j3".to_string(), "q_j4".to_string()];
    let text = ModelFile::from_raw(&good, Some("joint 1"), &cols).to_toml_string();
    assert!(text.contains("[gravity_series]") && text.contains("table_residual = true"), "{text}");
    assert_eq!(ModelFile::parse(&text, "j1.toml").unwrap().raw_params().unwrap(), good);

    let refuse = |b: &mut arm::bus::ArmBus, raw: &joint_core::params::RawParams, want: &str| {
        let e = transfer::push(
            &mut b.master,
            node_id(0),
            raw,
            PushOptions { pre_operational: true, save: false },
            &mut |_| {},
        )
        .expect_err("a bad series must be refused");
        let msg = e.to_string();
        assert!(msg.contains(want), "{msg}");
        assert_eq!(*b.joints[0].lock().unwrap().node.params().raw(), good, "old set in force after: {msg}");
    };
    let mut nan = good.clone();
    nan.series.amplitude[1] = f32::NAN;
    refuse(&mut b, &nan, "gravity_series_terms");
    let mut many = good.clone();
    many.series.n_terms = TERMS_MAX as u8 + 1;
    refuse(&mut b, &many, "gravity_series_count");
    let mut mult = good.clone();
    mult.series.mult[2][1] = 6;
    refuse(&mut b, &mult, "term 2");

    // still running the old set: same torques after restarting the joints
    b.master.nmt(0, joint_core::canopen::node::NMT_START).unwrap();
    let (after, _) = b.hold(&q).unwrap();
    assert_eq!(before[0].to_bits(), after[0].to_bits());
}

#[test]
fn gravity_series_toml_is_optional_strict_and_round_trips() {
    let text = r#"
[gravity_series]
angles = ["q", "q_j2", "q_j3", "q_j4"]
amplitude = [2.5, -1.25]
phase = [0.0, 1.5707964]
mult = [[1, 0, 0, 0], [1, -1, 1, 1]]
"#;
    let mf = ModelFile::parse(text, "m.toml").unwrap();
    let raw = mf.raw_params().unwrap();
    assert_eq!(raw.series.n_terms, 2);
    assert_eq!(raw.series.mult[1], [1, -1, 1, 1]);
    let back =
        ModelFile::parse(&ModelFile::from_raw(&raw, None, &mf.other_columns()).to_toml_string(), "b.toml").unwrap();
    assert_eq!(back.raw_params().unwrap(), raw);

    let unknown = text.replace("mult =", "bogus = 1\nmult =");
    let e = ModelFile::parse(&unknown, "m.toml").unwrap_err();
    assert!(e.to_string().contains("bogus"), "{e}");
    let nan = text.replace("-1.25", "nan");
    let e = ModelFile::parse(&nan, "m.toml").unwrap_err();
    assert!(matches!(e, ModelError::Series { .. }) && e.to_string().contains("term 1"), "{e}");
    let big = text.replace("[1, -1, 1, 1]", "[1, -9, 1, 1]");
    let e = ModelFile::parse(&big, "m.toml").unwrap_err();
    assert!(e.to_string().contains("term 1") && e.to_string().contains("mult[1]"), "{e}");
    let residual_without_table = format!("{text}table_residual = true\n");
    assert!(ModelFile::parse(&residual_without_table, "m.toml").unwrap_err().to_string().contains("gravity_table"));
    // a model without the section is unchanged
    assert_eq!(ModelFile::parse("[weight]\namplitude = 1.0\n", "m.toml").unwrap().series, None);
}
