//! The analytic gravity series in the core: residual fusion in the control law, the CANopen
//! objects 0x2104/0x2105 and the residual flag (staged, committed whole, refused sets leave
//! the old one), and the store's model block (exact round trip, older records unchanged).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig};
use joint_core::canopen::od;
use joint_core::canopen::storage::FlashStorage;
use joint_core::control::gravity;
use joint_core::params::{check, ParamError, ParamId, RawParams};
use joint_core::series::{self, RawSeries, SeriesError, TERMS_MAX, TERM_BYTES};
use joint_core::store::{Store, RECORD_LEN};
use joint_core::table::fuse;

fn series_2dof() -> RawSeries {
    let mut s = RawSeries::EMPTY;
    // 3·sin(q) − 1.5·sin(q + o0 + π/2) + 0.25·sin(2·o1 − q)
    let terms: [(f32, f32, [i8; 4]); 3] =
        [(3.0, 0.0, [1, 0, 0, 0]), (-1.5, core::f32::consts::FRAC_PI_2, [1, 1, 0, 0]), (0.25, 0.0, [-1, 0, 2, 0])];
    for (k, (a, p, m)) in terms.iter().enumerate() {
        s.amplitude[k] = *a;
        s.phase[k] = *p;
        s.mult[k] = *m;
    }
    s.n_terms = 3;
    s
}

/// A set with weight term, series and a 1-axis residual table over `others[0]`.
fn residual_set(residual: bool) -> RawParams {
    let mut raw = RawParams::defaults();
    raw.set(ParamId::WeightAmplitude, 0.5);
    raw.series = series_2dof();
    raw.set(ParamId::TableSigmaModel, 0.4);
    raw.set(ParamId::TableClampK, 1.5);
    let t = &mut raw.table;
    t.n_axes = 1;
    t.axis_source = [1, 0, 0, 0];
    t.points = [3, 0, 0, 0];
    t.grid[0][..3].copy_from_slice(&[-1.0, 0.0, 1.0]);
    t.torque[..3].copy_from_slice(&[0.2, -0.3, 0.9]);
    t.sigma[..3].copy_from_slice(&[0.1, 0.2, 0.1]);
    t.has_sigma = true;
    t.residual = residual;
    raw
}

#[test]
fn residual_table_fuses_around_the_model() {
    let set = check(&residual_set(true)).unwrap();
    let plain = check(&residual_set(false)).unwrap();
    for i in 0..50 {
        let q = -1.2 + 0.05 * i as f32;
        let others = [0.7 - 0.03 * i as f32, -0.2, 0.4];
        let angles = [q, others[0], others[1], others[2]];
        let tau_m = set.terms().weight.torque(q) + series::eval(set.series(), &angles);
        let (r, sr) = set.lut().eval_sources(set.table(), &angles, true);
        // residual: data estimate = τ_m + table
        let want = fuse(tau_m, 0.4, tau_m + r, sr, 1.5);
        assert_eq!(gravity(&set, q, &others).to_bits(), want.to_bits(), "q = {q}");
        // the fused torque never leaves τ_m ± k·σ_m (as the core rounds the band's edges)
        let g = gravity(&set, q, &others);
        assert!(g >= tau_m - 1.5 * 0.4 && g <= tau_m + 1.5 * 0.4);
        // not residual: the table is a torque of its own, fused with τ_m as before
        let want_plain = fuse(tau_m, 0.4, r, sr, 1.5);
        assert_eq!(gravity(&plain, q, &others).to_bits(), want_plain.to_bits());
    }
}

#[test]
fn empty_series_keeps_the_old_bits() {
    // A weight torque of −0.0 stays −0.0: the empty series adds nothing, not even +0.0.
    let mut raw = RawParams::defaults();
    raw.set(ParamId::WeightAmplitude, -1.0);
    let set = check(&raw).unwrap();
    let g = gravity(&set, 0.0, &[0.0; 3]);
    assert_eq!(g.to_bits(), set.terms().weight.torque(0.0).to_bits());
}

#[test]
fn check_refuses_a_bad_series_naming_the_term() {
    let mut raw = residual_set(true);
    raw.series.mult[1][3] = 9;
    assert_eq!(check(&raw).unwrap_err(), ParamError::Series(SeriesError::Multiplier { term: 1, slot: 3 }));
    let mut raw = residual_set(true);
    raw.series.n_terms = TERMS_MAX as u8 + 1;
    let e = check(&raw).unwrap_err();
    assert_eq!(e, ParamError::Series(SeriesError::TooManyTerms { n_terms: 17 }));
    assert!(e.to_string().contains("17 terms"), "{e}");
}

fn terms_domain(s: &RawSeries) -> Vec<u8> {
    (0..s.n_terms as usize).flat_map(|k| s.term_bytes(k)).collect()
}

fn node() -> Node<MemoryStorage> {
    let mut n = Node::new(NodeConfig::new(3), MemoryStorage::default(), 0);
    n.process(0, None, &mut |_| {});
    n
}

/// Commit what this test staged, named by its CRC (0x2205; a plain commit is refused).
fn commit<S: joint_core::canopen::ParamStorage>(n: &mut Node<S>) -> Result<(), joint_core::canopen::Abort> {
    let crc = joint_core::store::set_crc(n.staged());
    n.write(od::COMMIT_CRC, 0, &crc.to_le_bytes())
}

#[test]
fn series_objects_stage_and_commit_whole() {
    let mut n = node();
    let good = series_2dof();
    n.write(od::SERIES_COUNT, 0, &[good.n_terms]).unwrap();
    n.write(od::SERIES_TERMS, 0, &terms_domain(&good)).unwrap();
    n.write(od::TABLE_SHAPE, 11, &[1]).unwrap();
    assert_eq!(n.params().series().n_terms, 0, "nothing runs before the commit");
    commit(&mut n).unwrap();
    assert_eq!(*n.params().series(), good);
    assert!(n.params().table().residual);
    let mut buf = [0u8; 256];
    let len = n.read(od::SERIES_TERMS, 0, &mut buf).unwrap();
    assert_eq!(&buf[..len], &terms_domain(&good)[..]);

    // NaN amplitude: refused at the write, the staged and committed sets unchanged.
    let mut bad = good.clone();
    bad.amplitude[2] = f32::NAN;
    assert!(n.write(od::SERIES_TERMS, 0, &terms_domain(&bad)).is_err());
    assert_eq!(n.staged().series, good);
    // Too many terms: the count and an over-long domain are refused.
    assert!(n.write(od::SERIES_COUNT, 0, &[TERMS_MAX as u8 + 1]).is_err());
    assert!(n.write(od::SERIES_TERMS, 0, &vec![0u8; TERM_BYTES * (TERMS_MAX + 1)]).is_err());
    assert!(n.write(od::SERIES_TERMS, 0, &[0u8; TERM_BYTES + 4]).is_err(), "whole terms only");
    // A multiplier out of range passes the write and is refused by the commit, naming the term.
    let mut bad = good.clone();
    bad.mult[0][0] = 7;
    n.write(od::SERIES_TERMS, 0, &terms_domain(&bad)).unwrap();
    assert!(commit(&mut n).is_err());
    let e = n.commit_error().unwrap();
    assert_eq!(e.code, 6);
    assert!(e.message.contains("term 0"), "{}", e.message);
    assert_eq!(*n.params().series(), good, "the old series stays in force");
}

const PAGE: usize = 2048;

// The shared NOR-flash double (the core's `mock-flash` feature).
use joint_core::store::mock::MemFlash;

#[test]
fn store_round_trips_the_series_and_the_residual_flag() {
    let mut s = Store::new(MemFlash::blank(4 * PAGE)).unwrap();
    let mut raw = residual_set(true);
    for k in 3..TERMS_MAX {
        raw.series.amplitude[k] = k as f32 * 0.5;
        raw.series.phase[k] = -(k as f32) * 0.1;
        raw.series.mult[k] = [1, -1, 2, -(k as i8 % 4)];
    }
    raw.series.n_terms = TERMS_MAX as u8;
    let set = check(&raw).unwrap();
    s.save_blocking(&set).unwrap();
    let mem = s.into_flash();
    let len = u32::from_le_bytes(mem.mem[12..16].try_into().unwrap()) as usize;
    assert!(24 + len > RECORD_LEN, "the record carries the model block");
    let mut s = Store::new(mem).unwrap();
    let l = s.load().unwrap();
    assert_eq!(l.params, set, "bit for bit, series and residual flag included");

    // Through the node: save, power cycle, the series is back.
    let mut n = Node::new(NodeConfig::new(3), FlashStorage::new(Store::new(MemFlash::blank(4 * PAGE)).unwrap()), 0);
    n.process(0, None, &mut |_| {});
    let good = series_2dof();
    n.write(od::SERIES_COUNT, 0, &[good.n_terms]).unwrap();
    n.write(od::SERIES_TERMS, 0, &terms_domain(&good)).unwrap();
    commit(&mut n).unwrap();
    n.write(od::STORE_PARAMETERS, 1, &od::SAVE_SIGNATURE.to_le_bytes()).unwrap();
    let storage = n.into_storage();
    let n = Node::new(NodeConfig::new(3), storage, 0);
    assert_eq!(*n.params().series(), good);
}

#[test]
fn a_set_without_series_is_stored_as_before() {
    let mut s = Store::new(MemFlash::blank(4 * PAGE)).unwrap();
    let mut raw = residual_set(false);
    raw.series = RawSeries::EMPTY;
    s.save_blocking(&check(&raw).unwrap()).unwrap();
    let mem = s.into_flash();
    let len = u32::from_le_bytes(mem.mem[12..16].try_into().unwrap()) as usize;
    assert_eq!(24 + len, RECORD_LEN, "no model block");
    assert_eq!(&mem.mem[24 + 4..24 + 8], &[0, 0, 0, 0], "the word that marks the block reads 0");
}
