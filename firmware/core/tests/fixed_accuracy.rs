//! The Q16.16 step's accuracy table: each term against f64 over the ranges the parameter table
//! allows (not only the papers' joints), and where Q16.16 saturates instead. Every sample draws
//! the term's parameters and inputs log-uniformly over their whole allowed magnitude (1e-3 up to
//! the table's limit, either sign where the table allows it), so small and large values weigh
//! alike. Printed as a table (`cargo test -p joint-core --test fixed_accuracy -- --nocapture`);
//! asserts that no saturated result ever wraps (it sits at the rail with the exact value's
//! sign) and bounds the worst unsaturated error.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::fixed::{friction_fx, fx, sin_fx, spring_fx, weight_fx, DahlFx, FixedParams, Fx, Gain};
use joint_core::fixed_gravity::{extra_fx, fuse_fx, series_fx, table_fx, ExtraFx};
use joint_core::series::RawSeries;
use joint_core::table::{Lut, RawTable};
use joint_core::vectors::XorShift32;

const N: usize = 200_000;
/// Q16.16's rails, N·m.
const RAIL: f64 = 32768.0;

struct Row {
    term: &'static str,
    params: &'static str,
    inputs: &'static str,
    worst_abs: f64,
    worst_rel: f64,
    saturated: usize,
    wrapped: usize,
    /// the largest |exact| with an unsaturated result
    largest_ok: f64,
    /// worst |error| against the values Q16.16 holds (the arithmetic alone)
    worst_held: f64,
}

/// Log-uniform magnitude in [1e-3, max] (0 when max is 0), with a random sign if `signed`.
fn draw(rng: &mut XorShift32, max: f64, signed: bool) -> f32 {
    let lo = 1e-3f64.ln();
    let m = (lo + (max.ln() - lo) * rng.unit() as f64).exp();
    let s = if signed && rng.next_u32() & 1 == 1 { -1.0 } else { 1.0 };
    (s * m) as f32
}

/// Runs `n` samples of `f`, which returns (fixed result, exact f64 value); fills a row.
fn measure(
    term: &'static str,
    params: &'static str,
    inputs: &'static str,
    mut f: impl FnMut(&mut XorShift32, &dyn Fn(f32) -> f64) -> (Fx, f64),
) -> Row {
    let mut row = Row {
        term,
        params,
        inputs,
        worst_abs: 0.0,
        worst_rel: 0.0,
        saturated: 0,
        wrapped: 0,
        largest_ok: 0.0,
        worst_held: 0.0,
    };
    // Against the f64 value of the parameters and inputs as drawn (f32)...
    let mut rng = XorShift32::new(0x5EED_0015);
    let mut worst_held = 0.0f64;
    for _ in 0..N {
        let (got, exact) = f(&mut rng, &|x| x as f64);
        let got = got.to_num::<f64>();
        if exact.abs() >= RAIL - 1.0 {
            // Out of the format's range: the result must sit at the rail with the right sign.
            row.saturated += 1;
            if got.signum() != exact.signum() || got.abs() < RAIL - 1.0 {
                row.wrapped += 1;
            }
        } else {
            let e = (got - exact).abs();
            row.worst_abs = row.worst_abs.max(e);
            if exact.abs() > 1.0 {
                row.worst_rel = row.worst_rel.max(e / exact.abs());
            }
            row.largest_ok = row.largest_ok.max(exact.abs());
        }
    }
    // ...and, same draws, against the f64 value of what Q16.16 holds of them: the arithmetic's
    // own error, without the format's resolution of parameters and inputs.
    let mut rng = XorShift32::new(0x5EED_0015);
    for _ in 0..N {
        let (got, exact) = f(&mut rng, &|x| fx(x).to_num::<f64>());
        if exact.abs() < RAIL - 1.0 {
            worst_held = worst_held.max((got.to_num::<f64>() - exact).abs());
        }
    }
    row.worst_held = worst_held;
    row
}

fn params_with(f: impl FnOnce(&mut FixedParams)) -> FixedParams {
    let mut p = FixedParams::default();
    f(&mut p);
    p
}

#[test]
fn accuracy_table_of_the_q16_terms_against_f64() {
    let rows = [
        measure("viscous b·q̇", "b ∈ [0, 1e3]", "q̇ ∈ ±1e3 rad/s", |r, h| {
            let (b, qd) = (draw(r, 1e3, false), draw(r, 1e3, true));
            let p = params_with(|p| p.fb = fx(b));
            (friction_fx(&p, fx(qd)), h(b) * h(qd))
        }),
        measure("quadratic a·q̇|q̇|", "a ∈ [0, 1e3]", "q̇ ∈ ±1e3 rad/s", |r, h| {
            let (a, qd) = (draw(r, 1e3, false), draw(r, 1e3, true));
            let p = params_with(|p| p.fa = fx(a));
            (friction_fx(&p, fx(qd)), h(a) * h(qd) * (h(qd)).abs())
        }),
        measure(
            "Coulomb c·sign(q̇) with band",
            "c ∈ [0, 1e3], band ∈ [1e-3, 1]",
            "q̇ ∈ ±1e3 rad/s",
            |r, h| {
                let (c, band, qd) = (draw(r, 1e3, false), draw(r, 1.0, false), draw(r, 1e3, true));
                let p = params_with(|p| {
                    p.fc = fx(c);
                    p.v_band = fx(band);
                    p.inv_band = Gain::new(1.0 / band);
                });
                (friction_fx(&p, fx(qd)), h(c) * (h(qd) / band as f64).clamp(-1.0, 1.0))
            },
        ),
        measure(
            "weight A·sin(s·q + φ)",
            "A ∈ ±1e3, s ∈ ±100, φ ∈ ±10",
            "q ∈ ±100 rad (s·q within ±1e4)",
            |r, h| {
                let (a, s, phi, q) =
                    (draw(r, 1e3, true), draw(r, 100.0, true), draw(r, 10.0, true), draw(r, 100.0, true));
                let p = params_with(|p| {
                    p.amplitude = fx(a);
                    p.s = fx(s);
                    p.phi = fx(phi);
                });
                // The angle the fixed path reaches is s·q + φ in Q16.16 (within range here).
                (weight_fx(&p, fx(q)), h(a) * (h(s) * h(q) + h(phi)).sin())
            },
        ),
        measure("sin alone (Q16.16 angle)", "-", "θ ∈ ±3e4 rad, exact in Q16.16", |r, _| {
            let t = fx(draw(r, 3e4, true));
            (sin_fx(t), t.to_num::<f64>().sin())
        }),
        measure("inertia J·q̈", "J ∈ [0, 1e3]", "q̈ ∈ ±3.2e4 rad/s²", |r, h| {
            let (j, qdd) = (draw(r, 1e3, false), draw(r, 32767.0, true));
            (Gain::new(j).times(fx(qdd)), j as f64 * h(qdd))
        }),
        measure(
            "spring K(q − q0) + B·q̇",
            "K ∈ [0, 1e4], q0 ∈ ±100, B ∈ [0, 1e3]",
            "q, q̇ ∈ ±1e3",
            |r, h| {
                let (k, q0, b) = (draw(r, 1e4, false), draw(r, 100.0, true), draw(r, 1e3, false));
                let (q, qd) = (draw(r, 1e3, true), draw(r, 1e3, true));
                let p = params_with(|p| {
                    p.k = fx(k);
                    p.q0 = fx(q0);
                    p.b = fx(b);
                });
                (spring_fx(&p, fx(q), fx(qd)), h(k) * (h(q) - h(q0)) + h(b) * h(qd))
            },
        ),
        measure(
            "Dahl state F, one step",
            "c ∈ [1e-3, 2e3], σ/c ∈ [1, 3.2e4]",
            "Δq ∈ ±0.1 rad, exact in Q16.16",
            |r, _| {
                let (c, k) = (draw(r, 2e3, false), draw(r, 32767.0, false).max(1.0));
                let p = params_with(|p| {
                    p.dahl_on = true;
                    p.dahl_c = fx(c);
                    p.dahl_k = fx(k);
                });
                let (c, k) = (p.dahl_c.to_num::<f64>(), p.dahl_k.to_num::<f64>());
                let mut d = DahlFx::new();
                // Prime at rest (F = 0), then one step of travel dq: F = T·(1 − exp(−k|dq|)).
                let q0 = fx(draw(r, 10.0, true));
                d.update(&p, q0, Fx::ZERO);
                let q1 = q0.saturating_add(fx(draw(r, 0.1, true)));
                let dq = (q1 - q0).to_num::<f64>();
                let exact = c * dq.signum() * (1.0 - (-k * dq.abs()).exp());
                (d.update(&p, q1, Fx::ZERO), exact)
            },
        ),
        measure("gravity table, 1-D, 16 points", "grid in ±100 rad, torque ±1e3", "q ∈ ±100 rad", |r, h| {
            let mut t = RawTable::EMPTY;
            t.n_axes = 1;
            t.points[0] = 16;
            let mut g = -100.0f32;
            for i in 0..16 {
                t.grid[0][i] = g;
                g += draw(r, 13.0, false).max(0.01);
                t.torque[i] = draw(r, 1e3, true);
            }
            let lut = Lut::new(&t);
            let q = draw(r, 100.0, true);
            let (got, _) = table_fx(&t, &lut, &[fx(q), Fx::ZERO, Fx::ZERO, Fx::ZERO], false);
            // f64 linear interpolation on the grid, clamped at its ends.
            let x = h(q).clamp(h(t.grid[0][0]), h(t.grid[0][15]));
            let i = (0..15).rfind(|&i| h(t.grid[0][i]) <= x).unwrap_or(0);
            let (a, b) = (h(t.grid[0][i]), h(t.grid[0][i + 1]));
            let f = ((x - a) / (b - a)).clamp(0.0, 1.0);
            (got, h(t.torque[i]) + f * (h(t.torque[i + 1]) - h(t.torque[i])))
        }),
        measure(
            "fusion, clamped to τ_m ± k·σ_m",
            "σ_m, σ_d ∈ [1e-3, 1e3], k ∈ [0, 100]",
            "τ_m, τ_d ∈ ±1e3 N·m",
            |r, h| {
                let (tm, td) = (draw(r, 1e3, true), draw(r, 1e3, true));
                let (sm, sd, k) = (draw(r, 1e3, false), draw(r, 1e3, false), draw(r, 100.0, false));
                let (vm, vd) = (h(sm) * h(sm), h(sd) * h(sd));
                let f = h(tm) + (h(td) - h(tm)) * vm / (vm + vd);
                let band = (h(k) * h(sm)).abs();
                (fuse_fx(fx(tm), fx(sm), fx(td), fx(sd), fx(k)), f.clamp(h(tm) - band, h(tm) + band))
            },
        ),
        measure(
            "series term a·sin(n·angles + φ)",
            "a ∈ ±1e4, n_j ∈ ±4, φ ∈ ±100",
            "angles ∈ ±1e3 rad",
            |r, h| {
                let mut s = RawSeries::EMPTY;
                s.n_terms = 1;
                s.amplitude[0] = draw(r, 1e4, true);
                s.phase[0] = draw(r, 100.0, true);
                let mut angles = [Fx::ZERO; 4];
                let mut arg = h(s.phase[0]);
                for (j, a) in angles.iter_mut().enumerate() {
                    s.mult[0][j] = (r.next_u32() % 9) as i8 - 4;
                    let x = draw(r, 1e3, true);
                    *a = fx(x);
                    arg += f64::from(s.mult[0][j]) * h(x);
                }
                (series_fx(&s, &angles), h(s.amplitude[0]) * arg.sin())
            },
        ),
        measure(
            "Stribeck level·exp(−(q̇/v)²)·sign",
            "level ∈ [0, 1e3], v ∈ [1e-4, 100]",
            "q̇ ∈ ±1e3 rad/s (no band)",
            |r, h| {
                let (level, speed, qd) = (draw(r, 1e3, false), draw(r, 100.0, false).max(1e-4), draw(r, 1e3, true));
                let e = ExtraFx {
                    any: true,
                    stribeck_level: fx(level),
                    stribeck_inv_speed: Gain::new(1.0 / speed),
                    ..ExtraFx::default()
                };
                let sgn = if qd > 0.0 { Fx::ONE } else { -Fx::ONE };
                let x = h(qd) / speed as f64;
                (extra_fx(&e, Fx::ZERO, fx(qd), sgn, 0.0), h(level) * (-(x * x)).exp() * h(qd).signum())
            },
        ),
        measure(
            "position ripple A·sin(2π·q/P + φ)",
            "A ∈ ±1e3, P ∈ [1e-3, 100], φ ∈ ±10",
            "q ∈ ±1e3 rad",
            |r, h| {
                let (amp, period, phase, q) =
                    (draw(r, 1e3, true), draw(r, 100.0, false), draw(r, 10.0, true), draw(r, 1e3, true));
                let k = 2.0 * core::f32::consts::PI / period;
                let e = ExtraFx {
                    any: true,
                    ripple_amplitude: fx(amp),
                    ripple_k: Gain::new(k),
                    ripple_phase: fx(phase),
                    ..ExtraFx::default()
                };
                (extra_fx(&e, fx(q), Fx::ZERO, Fx::ZERO, 0.0), h(amp) * (k as f64 * h(q) + h(phase)).sin())
            },
        ),
        measure(
            "cable spring (quadratic blend, then linear)",
            "k ∈ ±1e4, engage ∈ ±100, width ∈ [1e-3, 10]",
            "q ∈ ±1e3 rad",
            |r, h| {
                let (k, engage, width, q) =
                    (draw(r, 1e4, true), draw(r, 100.0, true), draw(r, 10.0, false), draw(r, 1e3, true));
                let e = ExtraFx {
                    any: true,
                    cable_k: fx(k),
                    cable_engage: fx(engage),
                    cable_width: fx(width),
                    cable_inv_2w: Gain::new(0.5 / width),
                    ..ExtraFx::default()
                };
                let x = h(q) - h(engage);
                let wd = h(width);
                let exact = if x <= 0.0 {
                    0.0
                } else if x < wd {
                    h(k) * x * x / (2.0 * width as f64)
                } else {
                    h(k) * (x - wd / 2.0)
                };
                (extra_fx(&e, fx(q), Fx::ZERO, Fx::ZERO, 0.0), exact)
            },
        ),
        measure(
            "load friction mu·|τ_load|·sign",
            "mu ∈ [0, 1]",
            "τ_load ∈ ±1e4 N·m, sign ±1 or in the band",
            |r, h| {
                let (mu, load) = (draw(r, 1.0, false), draw(r, 1e4, true));
                let sgn = match r.next_u32() % 3 {
                    0 => 1.0f32,
                    1 => -1.0,
                    _ => draw(r, 1.0, true),
                };
                let e = ExtraFx { any: true, load_mu: fx(mu), ..ExtraFx::default() };
                (extra_fx(&e, Fx::ZERO, Fx::ZERO, fx(sgn), load), h(mu) * h(load).abs() * h(sgn))
            },
        ),
        measure("1/(N − 1) (motor command)", "N ∈ [1.01, 1e4]", "τ ∈ ±1e4 N·m", |r, h| {
            let n = 1.01 + draw(r, 1e4, false);
            let tau = draw(r, 1e4, true);
            (Gain::new(1.0 / (n - 1.0)).times(fx(tau)), h(tau) / (n as f64 - 1.0))
        }),
    ];
    println!("Q16.16 terms against f64, {N} draws each (log-uniform magnitudes over the table's ranges):");
    println!(
        "  worst |err|: against the parameters and inputs as given (f32); held: against what Q16.16 holds of them"
    );
    println!(
        "  (the arithmetic alone); rel: worst |err|/|exact| where |exact| > 1 N·m; saturated: exact beyond ±32768"
    );
    println!(
        "{:<30} {:<38} {:<32} {:>11} {:>9} {:>10} {:>10} {:>8}",
        "term", "parameters", "inputs", "worst |err|", "held", "worst rel", "saturated", "wrapped"
    );
    for r in rows.iter() {
        println!(
            "{:<30} {:<38} {:<32} {:>11.2e} {:>9.1e} {:>10.1e} {:>9.1}% {:>8}",
            r.term,
            r.params,
            r.inputs,
            r.worst_abs,
            r.worst_held,
            r.worst_rel,
            100.0 * r.saturated as f64 / N as f64,
            r.wrapped
        );
    }
    for r in rows.iter() {
        assert_eq!(r.wrapped, 0, "{}: a saturated result wrapped", r.term);
        // The arithmetic on what Q16.16 holds is exact to the rounding of its results: a few LSB
        // of a product, times the other factor at its largest (an amplitude of 1e4 N·m times the
        // sine's 1.2e-5 is 0.12 N·m). What is left of the error against the given values is the
        // format's resolution of parameters and inputs (q = 1e-3 rad held to 7.6e-6 rad inside a
        // 1 mrad ripple period is 0.05 rad of phase), which the table shows and nothing bounds.
        assert!(r.worst_held < 0.5, "{}: arithmetic error {}", r.term, r.worst_held);
    }
}

/// Intermediates beyond the format do not saturate: the weight's angle s·q = 1e5 rad (the
/// table allows it; 16 000 turns) is carried in 64 bits and its sine is the right one, and a
/// spring torque K·(q − q0) far past the rails comes back in range when the damper cancels it.
/// Only a total beyond ±32768 N·m saturates, at the rail with its sign.
#[test]
fn intermediates_beyond_the_format_do_not_saturate_totals_do() {
    let p = FixedParams { amplitude: fx(1000.0), s: fx(100.0), ..FixedParams::default() };
    let w = weight_fx(&p, fx(1000.0)).to_num::<f64>();
    let exact = 1000.0 * (1.0e5f64).sin();
    // 2³²/(2π) is an integer constant: the phase is off by ~1e-10·θ, 6e-5 rad at 1e5 rad.
    assert!((w - exact).abs() < 0.1, "{w} vs {exact}");
    let p = FixedParams { k: fx(1.0e4), b: fx(1.0e3), ..FixedParams::default() };
    // 1e4·100 − 1e3·999.9 = 100 N·m, though each term is ~1e6.
    let s = spring_fx(&p, fx(100.0), fx(-999.9)).to_num::<f64>();
    assert!((s - 1.0e6 + 999.9 * 1.0e3).abs() < 0.1, "{s}");
    // An inertia torque past the rails is held at the rail with its sign, never wrapped.
    assert_eq!(Gain::new(1000.0).times(fx(1.0e6)), Fx::MAX);
    assert_eq!(Gain::new(1000.0).times(fx(-1.0e6)), Fx::MIN);
}
