//! Core checks on the emulated Cortex-M4F: facts about the core that must hold on the
//! target itself (not only on the PC), printed one per line, then the plain
//! `N passed, M failed` line the test scripts count. Exit status 0 when all pass, 2 when
//! any fails, 1 on panic.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

#[cfg(target_os = "none")]
fn run() -> i32 {
    use core::fmt::Write;
    use joint_core::control::{Controller, Differentiator, Input, Mode};
    use joint_core::params::{check, ActiveParams, ParamId, ParamSet, RawParams};
    use joint_core::{table, vectors};

    let Some(mut out) = firmware_qemu::LineOut::stdout() else {
        return firmware_qemu::EXIT_CHECK_FAILED;
    };
    let (mut passed, mut failed) = (0u32, 0u32);
    let mut check_that = |name: &str, ok: bool, out: &mut firmware_qemu::LineOut| {
        let _ = writeln!(out, "{} {}", if ok { "ok  " } else { "FAIL" }, name);
        if ok {
            passed += 1;
        } else {
            failed += 1;
        }
    };

    let s = vectors::session(&mut |_| {});
    check_that("session: 6 sets accepted, 7 refused", s.accepted == 6 && s.rejected == 7, &mut out);
    check_that("session: a refused set never changes the set in force", s.rejected_but_changed == 0, &mut out);
    check_that("session: every result as expected", s.unexpected_results == 0, &mut out);
    check_that("session: outputs finite and within the torque limit", s.unsafe_outputs == 0, &mut out);

    check_that("defaults pass check()", check(&RawParams::defaults()).is_ok(), &mut out);

    // Refusal keeps the old set, field for field.
    let mut active = ActiveParams::default();
    let trunk_ok = active.replace(&vectors::trunk_right()).is_ok();
    let before = active.current().clone();
    let mut all_refused = true;
    for (_, bad) in vectors::rejected_sets().iter() {
        all_refused &= active.replace(bad).is_err();
    }
    check_that("every rejected set is refused", trunk_ok && all_refused, &mut out);
    check_that("the old set stays in force after refusals", *active.current() == before, &mut out);

    // The table reproduces its own grid values (multilinear interpolation is exact there).
    let fused = vectors::trunk_table_fused();
    let t = &fused.table;
    let mut exact = true;
    let mut cell = 0usize;
    for &g0 in vectors::TABLE_GRID_Q.iter() {
        for &g1 in vectors::TABLE_GRID_OTHER.iter() {
            let v = table::interpolate(t, &t.torque, &[g0, g1, 0.0, 0.0]);
            exact &= Some(v) == t.torque.get(cell).copied();
            cell += 1;
        }
    }
    check_that("gravity table is exact at its grid points", exact, &mut out);

    // Fusion stays inside tau_model ± k·sigma_model however far the data is.
    let f = table::fuse(1.0, 0.3, 100.0, 0.01, 1.0);
    check_that("fusion is clamped to the model band", (0.7..=1.3).contains(&f), &mut out);

    // A bad input drives the command to zero, never NaN.
    let p = ParamSet::defaults();
    let mut c = Controller::new();
    let o = c.step(&p, Mode::Assist, &Input { qd: f32::NAN, ..Input::default() }, 0.001);
    check_that("non-finite input gives a zero command", o.bad_input && o.tau_out == 0.0, &mut out);

    // The torque limit holds under a saturating command.
    let set = match check(&vectors::trunk_right()) {
        Ok(s) => s,
        Err(_) => ParamSet::defaults(),
    };
    let mut c = Controller::new();
    let mut worst = 0.0f32;
    for _ in 0..1000 {
        let o = c.step(&set, Mode::Assist, &Input { q: 1.0, qd: 50.0, assist_cmd: 1.0e6, ..Input::default() }, 0.001);
        let a = joint_core::math::abs(o.tau_out);
        if a > worst {
            worst = a;
        }
    }
    check_that("output never exceeds torque_limit", worst <= set.get(ParamId::TorqueLimit), &mut out);

    // The Dahl friction state never leaves ±c, whatever the steps, and reaches ±c exactly
    // after a travel far beyond the pre-sliding distance.
    let dahl_set = match check(&vectors::presliding_fused()) {
        Ok(s) => s,
        Err(_) => ParamSet::defaults(),
    };
    let pre = dahl_set.terms().presliding;
    let mut dahl = joint_core::control::Dahl::new();
    let mut rng = vectors::XorShift32::new(7);
    let mut bounded = pre.on;
    let mut q = 0.0f32;
    for _ in 0..4000 {
        let r = rng.unit();
        q += if r < 0.1 { rng.uniform(-2.0, 2.0) } else { rng.uniform(-3.0e-3, 3.0e-3) };
        let f = dahl.update(&dahl_set, q, 0.0);
        bounded &= joint_core::math::abs(f) <= pre.c;
    }
    let far = dahl.update(&dahl_set, q + 1.0, 0.0) == pre.c && dahl.update(&dahl_set, q - 1.0, 0.0) == -pre.c;
    check_that("Dahl state within ±c, exactly ±c after a long travel", bounded && far, &mut out);

    // The differentiator recovers a ramp's slope.
    let mut d = Differentiator::new();
    let mut v = 0.0;
    for i in 0..2000 {
        v = d.update(0.5 * i as f32 * 0.001, 0.001, 20.0);
    }
    check_that("differentiator settles on a ramp's slope", joint_core::math::abs(v - 0.5) < 1.0e-3, &mut out);

    let _ = writeln!(out, "{passed} passed, {failed} failed");
    if failed == 0 {
        0
    } else {
        firmware_qemu::EXIT_CHECK_FAILED
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-core-checks")
}
