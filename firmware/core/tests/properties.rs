//! Property tests of the core: finite outputs, friction symmetry, table and fusion bounds, and
//! all-or-nothing parameter replacement.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;
use common::*;
use joint_core::control::{disturbance, Controller, Input, Mode};
use joint_core::fixed::ControllerFx;
use joint_core::params::{check, ActiveParams, ParamError, ParamId, RawParams, PARAMS, PARAM_COUNT};
use joint_core::table::{fuse, interpolate, validate, RawTable, AXES_MAX, CELLS_MAX};
use proptest::prelude::*;

/// Any finite f32, including huge and subnormal values.
fn any_finite() -> impl Strategy<Value = f32> {
    any::<f32>().prop_filter("finite", |x| x.is_finite())
}

/// A random but valid parameter set: every scalar drawn inside its declared range.
fn valid_raw() -> impl Strategy<Value = RawParams> {
    proptest::collection::vec(0.0f64..=1.0, PARAM_COUNT).prop_map(|u| {
        let mut r = RawParams::defaults();
        for (d, x) in PARAMS.iter().zip(u) {
            let v = d.min as f64 + (d.max as f64 - d.min as f64) * x;
            r.set(d.id, v as f32);
        }
        // Keep the one cross-parameter rule satisfied.
        let rate = r.get(ParamId::ControlRateHz);
        if r.get(ParamId::AccelCutoff) * 2.0 >= rate {
            r.set(ParamId::AccelCutoff, rate / 4.0);
        }
        r.set(ParamId::TableSigmaModel, 0.0);
        r
    })
}

fn table_2d(g0: Vec<f32>, g1: Vec<f32>, vals: Vec<f32>, sig: Vec<f32>) -> RawTable {
    let mut t = RawTable::EMPTY;
    t.n_axes = 2;
    t.axis_source = [0, 1, 0, 0];
    t.points = [g0.len() as u8, g1.len() as u8, 0, 0];
    for (i, g) in g0.iter().enumerate() {
        t.grid[0][i] = *g;
    }
    for (i, g) in g1.iter().enumerate() {
        t.grid[1][i] = *g;
    }
    for (i, v) in vals.iter().enumerate() {
        t.torque[i] = *v;
    }
    for (i, s) in sig.iter().enumerate() {
        t.sigma[i] = *s;
    }
    t.has_sigma = !sig.is_empty();
    t
}

/// Strictly increasing grid of n points from increments.
fn grid(n: usize) -> impl Strategy<Value = Vec<f32>> {
    (-3.0f32..3.0, proptest::collection::vec(0.01f32..1.0, n - 1)).prop_map(|(start, incs)| {
        let mut g = vec![start];
        for d in incs {
            let last = *g.last().unwrap();
            g.push(last + d);
        }
        g
    })
}

fn random_table() -> impl Strategy<Value = RawTable> {
    (2usize..6, 2usize..6).prop_flat_map(|(n0, n1)| {
        (
            grid(n0),
            grid(n1),
            proptest::collection::vec(-50.0f32..50.0, n0 * n1),
            proptest::collection::vec(0.01f32..5.0, n0 * n1),
        )
            .prop_map(|(g0, g1, v, s)| table_2d(g0, g1, v, s))
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn step_output_is_finite_and_limited_for_any_finite_input(
        raw in valid_raw(), q in any_finite(), qd in any_finite(), qdd in any_finite(),
        o in any_finite(), cmd in any_finite(), dt in any_finite(), mode in 0u8..4, target in any_finite(),
        load in any_finite(),
    ) {
        let p = check(&raw).unwrap();
        let mode = match mode { 0 => Mode::Off, 1 => Mode::Assist, 2 => Mode::Velocity(target), _ => Mode::Position(target) };
        let mut c = Controller::new();
        let inp = Input { q, qd, qdd, others: [o, -o, o], assist_cmd: cmd, tau_load: load };
        for _ in 0..3 {
            let out = c.step(&p, mode, &inp, dt);
            prop_assert!(out.tau_out.is_finite() && out.u_motor.is_finite() && out.c_c.is_finite(), "{out:?}");
            prop_assert!(out.tau_out.abs() <= p.get(ParamId::TorqueLimit));
        }
    }

    #[test]
    fn non_finite_input_drives_zero(raw in valid_raw(), bad in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)], which in 0usize..4) {
        let p = check(&raw).unwrap();
        let mut inp = Input { q: 0.5, qd: 0.1, others: [0.0; 3], ..Input::default() };
        match which { 0 => inp.q = bad, 1 => inp.qd = bad, 2 => inp.qdd = bad, _ => inp.others[1] = bad }
        let mut c = Controller::new();
        let out = c.step(&p, Mode::Assist, &inp, 1e-3);
        prop_assert!(out.bad_input);
        prop_assert_eq!(out.tau_out, 0.0);
    }

    /// A failed load cell (a non-finite load) is no load: the step runs on, with the load
    /// friction at 0, in both arithmetics; a load past the input limit counts as the limit.
    #[test]
    fn a_non_finite_load_is_no_load(raw in valid_raw(), mu in 0.0f32..=1.0, bad in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)]) {
        let mut raw = raw;
        raw.set(ParamId::LoadFrictionMu, mu);
        let p = check(&raw).unwrap();
        let at = |load: f32| Input { q: 0.5, qd: 0.3, others: [0.0; 3], tau_load: load, ..Input::default() };
        let (mut a, mut b) = (Controller::new(), Controller::new());
        let bad_out = a.step(&p, Mode::Assist, &at(bad), 1e-3);
        prop_assert!(!bad_out.bad_input);
        prop_assert_eq!(bad_out, b.step(&p, Mode::Assist, &at(0.0), 1e-3));
        let (mut a, mut b) = (ControllerFx::new(&p), ControllerFx::new(&p));
        prop_assert_eq!(a.step(&p, Mode::Assist, &at(bad), 1e-3), b.step(&p, Mode::Assist, &at(0.0), 1e-3));
        let t = p.terms();
        prop_assert_eq!(t.extra_torque(0.5, 0.3, 3.0e4), t.extra_torque(0.5, 0.3, 1.0e4));
    }

    #[test]
    fn friction_is_odd_and_monotonic(raw in valid_raw(), v1 in 0.0f32..100.0, dv in 0.0f32..100.0) {
        let p = check(&raw).unwrap();
        let f = p.terms().friction;
        prop_assert_eq!(f.torque(-v1), -f.torque(v1));
        let v2 = v1 + dv;
        prop_assert!(f.torque(v2) >= f.torque(v1), "f({v2}) = {} < f({v1}) = {}", f.torque(v2), f.torque(v1));
        prop_assert!(f.torque(v1) >= 0.0);
    }

    #[test]
    fn table_is_exact_at_grid_points(t in random_table()) {
        prop_assert!(validate(&t).is_ok());
        let (n0, n1) = (t.points[0] as usize, t.points[1] as usize);
        for i in 0..n0 {
            for j in 0..n1 {
                let x = [t.grid[0][i], t.grid[1][j], 0.0, 0.0];
                let v = interpolate(&t, &t.torque, &x);
                let want = t.torque[i * n1 + j];
                prop_assert!((v - want).abs() <= 1e-5 * want.abs().max(1.0), "({i},{j}): {v} vs {want}");
            }
        }
    }

    #[test]
    fn table_is_bounded_by_its_cell_corners(t in random_table(), u0 in -0.5f32..1.5, u1 in -0.5f32..1.5) {
        let (n0, n1) = (t.points[0] as usize, t.points[1] as usize);
        let span0 = t.grid[0][n0 - 1] - t.grid[0][0];
        let span1 = t.grid[1][n1 - 1] - t.grid[1][0];
        let x0 = t.grid[0][0] + u0 * span0;
        let x1 = t.grid[1][0] + u1 * span1;
        let v = interpolate(&t, &t.torque, &[x0, x1, 0.0, 0.0]);
        // Locate the cell (after clamping to the grid) and its four corners.
        let c0 = x0.clamp(t.grid[0][0], t.grid[0][n0 - 1]);
        let c1 = x1.clamp(t.grid[1][0], t.grid[1][n1 - 1]);
        let i = (0..n0 - 1).rev().find(|&i| t.grid[0][i] <= c0).unwrap_or(0);
        let j = (0..n1 - 1).rev().find(|&j| t.grid[1][j] <= c1).unwrap_or(0);
        let corners = [t.torque[i * n1 + j], t.torque[i * n1 + j + 1], t.torque[(i + 1) * n1 + j], t.torque[(i + 1) * n1 + j + 1]];
        let lo = corners.iter().cloned().fold(f32::INFINITY, f32::min);
        let hi = corners.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
        prop_assert!(v >= lo - 1e-4 && v <= hi + 1e-4, "{v} outside [{lo}, {hi}]");
    }

    #[test]
    fn fusion_never_leaves_the_clamp(tm in -100.0f32..100.0, sm in 1e-3f32..20.0, td in -1e4f32..1e4, sd in 1e-3f32..20.0, k in 0.0f32..5.0) {
        let f = fuse(tm, sm, td, sd, k);
        prop_assert!(f >= tm - k * sm - 1e-3 && f <= tm + k * sm + 1e-3, "{f} outside {tm} ± {k}·{sm}");
        // Between the two estimates, too.
        prop_assert!(f >= tm.min(td) - 1e-3 && f <= tm.max(td) + 1e-3);
    }

    #[test]
    fn refused_set_leaves_old_in_force(good in valid_raw(), which in 0usize..PARAM_COUNT, kind in 0u8..3) {
        let mut active = ActiveParams::new(check(&good).unwrap());
        let before = active.current().clone();
        let mut bad = good.clone();
        let d = &PARAMS[which];
        let value = match kind { 0 => f32::NAN, 1 => d.max + 1.0 + d.max.abs(), _ => d.min - 1.0 - d.min.abs() };
        bad.set(d.id, value);
        // Change every other parameter too, so a half-applied set would show.
        for e in PARAMS.iter() { if e.id != d.id { bad.set(e.id, e.min); } }
        let err = active.replace(&bad).unwrap_err();
        prop_assert_eq!(err.param(), Some(d.id));
        prop_assert_eq!(active.current(), &before);
    }
}

#[test]
fn table_rules_name_the_axis_and_index() {
    let mut t = table_2d(vec![0.0, 0.5, 1.0], vec![0.0, 0.4, 0.3], vec![0.0; 9], vec![]);
    assert_eq!(validate(&t), Err(joint_core::table::TableError::GridNotIncreasing { axis: 1, index: 2 }));
    t.grid[1][2] = 0.8;
    assert_eq!(validate(&t), Ok(()));
    t.torque[4] = f32::NAN;
    assert_eq!(validate(&t), Err(joint_core::table::TableError::TorqueNotFinite { index: 4 }));
    t.torque[4] = 0.0;
    t.points[0] = 1;
    assert!(matches!(validate(&t), Err(joint_core::table::TableError::Points { axis: 0, points: 1 })));
    t.points = [16, 16, 2, 0];
    t.n_axes = 3;
    for a in 0..3 {
        for i in 0..16 {
            t.grid[a][i] = i as f32;
        }
    }
    assert!(matches!(validate(&t), Err(joint_core::table::TableError::TooManyCells { cells: 512 })));
    const { assert!(CELLS_MAX >= 128 && AXES_MAX == 4) };
}

#[test]
fn fusion_needs_sigma_and_a_table() {
    let mut raw = raw_from(&RIGHT);
    raw.set(ParamId::TableSigmaModel, 0.3);
    assert!(matches!(check(&raw), Err(ParamError::Inconsistent { param: ParamId::TableSigmaModel, .. })));
    raw.table = table_2d(vec![0.0, 1.0], vec![0.0, 1.0], vec![1.0, 2.0, 3.0, 4.0], vec![]);
    assert!(matches!(check(&raw), Err(ParamError::Inconsistent { param: ParamId::TableSigmaModel, .. })));
    raw.table.has_sigma = true;
    raw.table.sigma[..4].copy_from_slice(&[0.1; 4]);
    let p = check(&raw).unwrap();
    // Fused gravity stays within weight ± clamp_k·σ_m even though the table says otherwise.
    let w = p.terms().weight.torque(0.5);
    let g = joint_core::control::gravity(&p, 0.5, &[0.5, 0.0, 0.0]);
    assert!((g - w).abs() <= 0.3 + 1e-5, "{g} vs {w}");
    let plain = disturbance(&p, 0.5, 0.0, 0.0, &[0.5, 0.0, 0.0], 0.0);
    assert!(plain.is_finite());
}

#[test]
fn accel_cutoff_must_respect_nyquist() {
    let mut raw = RawParams::defaults();
    raw.set(ParamId::ControlRateHz, 100.0);
    raw.set(ParamId::AccelCutoff, 60.0);
    let e = check(&raw).unwrap_err();
    assert!(matches!(e, ParamError::Inconsistent { param: ParamId::AccelCutoff, .. }));
    assert!(e.to_string().contains("controller_accel_cutoff"), "{e}");
}

#[test]
fn table_declares_every_id_in_order_and_defaults_pass() {
    for (i, d) in PARAMS.iter().enumerate() {
        assert_eq!(d.id.index(), i, "{} out of order", d.name);
        assert!(d.min <= d.default && d.default <= d.max, "{} default outside range", d.name);
        assert_eq!(d.name, format!("{}_{}", d.section, d.key), "{} is not section_key", d.name);
        assert_eq!(ParamId::from_name(d.name), Some(d.id));
    }
    assert!(check(&RawParams::defaults()).is_ok());
}

#[test]
fn sections_are_listed_once_each_with_every_key() {
    let sections: Vec<&str> = joint_core::params::sections().collect();
    assert_eq!(&sections[..3], ["friction", "weight", "inertia"]);
    for (i, s) in sections.iter().enumerate() {
        assert!(!sections[..i].contains(s), "{s} listed twice");
    }
    let keyed: usize = sections.iter().map(|s| joint_core::params::section_params(s).count()).sum();
    assert_eq!(keyed, PARAMS.len(), "every parameter belongs to exactly one listed section");
    assert!(sections.contains(&"presliding") && sections.contains(&"dry_friction"));
}

/// An n-axis table (1..=4) with random grids, uniform or not.
fn random_nd_table() -> impl Strategy<Value = RawTable> {
    (1usize..=4, any::<bool>())
        .prop_flat_map(|(n, uniform)| {
            let pts = proptest::collection::vec(2usize..4, n);
            (Just(n), Just(uniform), pts).prop_flat_map(|(n, uniform, pts)| {
                let cells: usize = pts.iter().product();
                let grids: Vec<_> = pts.iter().map(|&p| grid(p)).collect();
                (
                    Just(n),
                    Just(uniform),
                    Just(pts),
                    grids,
                    proptest::collection::vec(-50.0f32..50.0, cells),
                    proptest::collection::vec(0.01f32..5.0, cells),
                )
            })
        })
        .prop_map(|(n, uniform, pts, grids, vals, sig)| {
            let mut t = RawTable::EMPTY;
            t.n_axes = n as u8;
            for (a, (p, g)) in pts.iter().zip(grids.iter()).enumerate() {
                t.points[a] = *p as u8;
                t.axis_source[a] = a.min(3) as u8;
                for (i, v) in g.iter().enumerate() {
                    t.grid[a][i] = if uniform { g[0] + 0.25 * i as f32 } else { *v };
                }
            }
            t.torque[..vals.len()].copy_from_slice(&vals);
            t.sigma[..sig.len()].copy_from_slice(&sig);
            t.has_sigma = true;
            t
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// The control step's precomputed lookup gives the reference interpolation's numbers.
    #[test]
    fn fast_lookup_matches_reference(t in random_nd_table(), u in proptest::collection::vec(-0.3f32..1.3, 4)) {
        prop_assert!(validate(&t).is_ok());
        let lut = joint_core::table::Lut::new(&t);
        let mut x = [0.0f32; AXES_MAX];
        for a in 0..t.n_axes as usize {
            let n = t.points[a] as usize;
            x[a] = t.grid[a][0] + u[a] * (t.grid[a][n - 1] - t.grid[a][0]);
        }
        let (v, s) = lut.eval(&t, &x, true);
        let v_ref = interpolate(&t, &t.torque, &x);
        let s_ref = interpolate(&t, &t.sigma, &x);
        prop_assert!((v - v_ref).abs() <= 1e-4 * v_ref.abs().max(1.0), "{v} vs {v_ref}");
        prop_assert!((s - s_ref).abs() <= 1e-4 * s_ref.abs().max(1.0), "{s} vs {s_ref}");
    }
}

/// The ripple's second harmonic is the term its doc gives, on top of the first, and costs
/// nothing when it is 0 (the first harmonic alone is the term it was before).
#[test]
fn ripple_second_harmonic_is_the_documented_term() {
    let mut raw = RawParams::defaults();
    for (id, v) in [
        (ParamId::RippleAmplitude, 0.2f32),
        (ParamId::RipplePeriod, 0.05),
        (ParamId::RipplePhase, 0.3),
        (ParamId::RippleAmplitude2, 0.1),
        (ParamId::RipplePhase2, -1.0),
    ] {
        raw.set(id, v);
    }
    let with = check(&raw).unwrap();
    raw.set(ParamId::RippleAmplitude2, 0.0);
    let without = check(&raw).unwrap();
    let tau = std::f64::consts::TAU;
    let mut worst = 0.0f64;
    for i in 0..2000 {
        let q = -1.0 + i as f32 * 1e-3;
        let one = 0.2 * (tau * f64::from(q) / 0.05 + 0.3).sin();
        let two = one + 0.1 * (2.0 * tau * f64::from(q) / 0.05 - 1.0).sin();
        let a = f64::from(with.terms().extra.torque(q, 0.0, 0.0, 0.0));
        let b = f64::from(without.terms().extra.torque(q, 0.0, 0.0, 0.0));
        worst = worst.max((a - two).abs()).max((b - one).abs());
    }
    // f32 phase of 2π·q/period at |q| ≤ 1 rad (≈ 250 rad of phase): a few 1e-5 of rounding
    assert!(worst < 1e-4, "{worst}");
}
