#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
// Shared by the core's integration tests (each test file includes it with `mod common;`).
#![allow(dead_code)]

use joint_core::params::{check, ParamId, ParamSet, RawParams};

pub const DEG: f64 = std::f64::consts::PI / 180.0;

/// Trunk paper Table 1, in the paper's own units (degrees), converted to SI exactly as the spec
/// says: a·(180/π)², b·(180/π), s·(180/π).
pub struct Table1 {
    pub a_deg: f64,
    pub b_deg: f64,
    pub c: f64,
    pub cw0: f64,
    pub s_deg: f64,
    pub phi: f64,
    pub ia: f64,
    pub c0: f64,
}

pub const RIGHT: Table1 =
    Table1 { a_deg: 5.77e-4, b_deg: 0.156, c: 2.32, cw0: 2.79, s_deg: 0.014, phi: -0.027, ia: 2.37, c0: -0.59 };
pub const LEFT: Table1 =
    Table1 { a_deg: 6.52e-4, b_deg: 0.164, c: 2.94, cw0: 2.59, s_deg: 0.013, phi: -3.108, ia: 3.21, c0: 0.20 };

pub fn raw_from(t: &Table1) -> RawParams {
    let mut r = RawParams::defaults();
    r.set(ParamId::FrictionA, (t.a_deg / (DEG * DEG)) as f32);
    r.set(ParamId::FrictionB, (t.b_deg / DEG) as f32);
    r.set(ParamId::FrictionC, t.c as f32);
    // Hard sign for the golden values: the paper's eq. 3 has no band.
    r.set(ParamId::FrictionVBand, 0.0);
    r.set(ParamId::WeightAmplitude, t.cw0 as f32);
    r.set(ParamId::WeightS, (t.s_deg / DEG) as f32);
    r.set(ParamId::WeightPhi, t.phi as f32);
    r.set(ParamId::InertiaJ, t.ia as f32);
    r.set(ParamId::OffsetC0, t.c0 as f32);
    r.set(ParamId::Ratio, 160.0);
    r
}

pub fn set_from(t: &Table1) -> ParamSet {
    check(&raw_from(t)).expect("Table 1 parameters are valid")
}
