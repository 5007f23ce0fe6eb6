//! Cost benchmark: instructions per compensation step on the emulated Cortex-M4F.
//!
//! Under `qemu-system-arm -icount shift=7` every instruction advances virtual time by
//! 128 ns and SysTick (25 MHz on mps2-an386) becomes an exact, repeatable instruction
//! counter. The image first measures ticks per instruction with a loop of known length
//! (two instructions per iteration, two lengths so the fixed cost of reading the counter
//! cancels), then times each configuration over the same inputs and subtracts the cost of
//! the bare loop. Output: a table on semihosting stdout, one `bench` line per row for
//! scripts. Exit status 0 when the full step (2-D fused table, presliding off) is within
//! `STEP_BUDGET_INSTRUCTIONS`, 2 when it is not, 1 on panic. The full step with pre-sliding
//! (Dahl) friction is its own row, timed on inputs whose angle moves in small steps with
//! reversals (random angles would make every step a jump that saturates the exponential),
//! beside the step without it on those same inputs.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
firmware_qemu::entry!(run);

/// The target for the full compensation step (Cortex-M4F: the f32 step with the fused
/// 2-D gravity table).
#[cfg(all(target_os = "none", not(armv6m)))]
const STEP_BUDGET_INSTRUCTIONS: f32 = 400.0;
/// The budget on the FPU-less Cortex-M0+ instruction set, for the step that board runs: the
/// Q16.16 full step (trunk joint + spring), measured at 1952 instructions (31 µs at the
/// G0B1's 64 MHz if every instruction took one cycle; the M0+ takes 1–2, plus flash wait
/// states: a 1 kHz loop has ample room, 10 kHz is tight). 2500 leaves 28 % for what is still
/// to be ported and fails a change that makes it much slower.
#[cfg(all(target_os = "none", armv6m))]
const STEP_BUDGET_INSTRUCTIONS: f32 = 2500.0;
#[cfg(all(target_os = "none", not(armv6m)))]
const CORE: &str = "Cortex-M4F (thumbv7em-none-eabihf, hard float)";
#[cfg(all(target_os = "none", armv6m))]
const CORE: &str = "Cortex-M0+ instruction set (thumbv6m-none-eabi, soft-float f32)";

#[cfg(target_os = "none")]
mod bench {
    use core::hint::black_box;
    use firmware_qemu::systick;
    use joint_core::control::{Controller, Differentiator, Input, Mode};
    use joint_core::fixed::{self, ControllerFx, DahlFx, FixedParams, Fx};
    use joint_core::params::{check, ParamId, ParamSet, RawParams};
    use joint_core::vectors::{self, XorShift32};

    pub const INPUTS: usize = 128;

    /// `n` iterations of a two-instruction loop (`subs`, `bne`).
    #[inline(never)]
    pub fn spin(n: u32) {
        if n == 0 {
            return;
        }
        // SAFETY: register-only countdown loop; touches no memory and no stack.
        unsafe {
            core::arch::asm!(
                "1:",
                "subs {0}, {0}, #1",
                "bne 1b",
                inout(reg) n => _,
                options(nomem, nostack),
            );
        }
    }

    /// SysTick ticks taken by `f`.
    #[inline(always)]
    pub fn ticks<F: FnMut()>(mut f: F) -> u32 {
        let a = systick::now();
        f();
        let b = systick::now();
        systick::elapsed(a, b)
    }

    /// Trunk-joint working range, no special values: the cost of a normal step.
    pub fn inputs() -> [Input; INPUTS] {
        let mut rng = XorShift32::new(vectors::SESSION_SEED ^ 0xBE7C_0000);
        let mut v = [Input::default(); INPUTS];
        for i in v.iter_mut() {
            *i = Input {
                q: rng.uniform(-0.3, 2.3),
                qd: rng.uniform(-2.5, 2.5),
                qdd: rng.uniform(-20.0, 20.0),
                others: [rng.uniform(-1.2, 2.2), 0.0, 0.0],
                assist_cmd: rng.uniform(-5.0, 5.0),
                tau_load: 0.0,
            };
        }
        v
    }

    /// The same inputs with a measured load (a load cell's working range), for the
    /// load-dependent friction; a generator of its own, so the other rows' inputs stay as they were.
    pub fn load_inputs(inp: &[Input; INPUTS]) -> [Input; INPUTS] {
        let mut rng = XorShift32::new(vectors::SESSION_SEED ^ 0x10AD_0000);
        let mut v = *inp;
        for i in v.iter_mut() {
            i.tau_load = rng.uniform(-30.0, 30.0);
        }
        v
    }

    /// The same inputs with the three other joints' angles all varied (the series reads them).
    pub fn arm_inputs(inp: &[Input; INPUTS]) -> [Input; INPUTS] {
        let mut rng = XorShift32::new(vectors::SESSION_SEED ^ 0x0A4E_0000);
        let mut v = *inp;
        for i in v.iter_mut() {
            i.others = [rng.uniform(-1.2, 2.2), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
        }
        v
    }

    /// The same inputs with the angle on a walk: steps of up to 3 mrad (about the pre-sliding
    /// distance of `vectors::presliding_fused`), reversing every 12 steps, so the Dahl state's
    /// exponential works on the travel it meets in a real joint at 1 kHz.
    pub fn walk_inputs(inp: &[Input; INPUTS]) -> [Input; INPUTS] {
        let mut v = *inp;
        let mut q = 0.9f32;
        for (k, i) in v.iter_mut().enumerate() {
            q += 3.0e-3 * joint_core::math::sin(2.0 * core::f32::consts::PI * k as f32 / 24.0);
            i.q = q;
        }
        v
    }

    pub fn set(raw: &RawParams) -> Option<ParamSet> {
        check(raw).ok()
    }

    /// Ticks for the empty loop over the inputs (what every measured loop also pays).
    pub fn baseline(inp: &[Input; INPUTS]) -> u32 {
        ticks(|| {
            for i in inp.iter() {
                black_box(i);
                black_box(0.0f32);
            }
        })
    }

    /// Out of line (with [`steps_fx`] and [`loop_body`]): inlined into `run`, the loop around
    /// the step took its registers and stack offsets from whatever else `run` held, so a row's
    /// loop overhead moved with the size of an unrelated local (the parameter set) by up to
    /// 14 instructions a step on the M0+; out of line, every row pays the same loop.
    #[inline(never)]
    pub fn steps(p: &ParamSet, inp: &[Input; INPUTS]) -> u32 {
        let mut ctl = Controller::new();
        let dt = 1.0 / p.get(ParamId::ControlRateHz);
        ticks(|| {
            for i in inp.iter() {
                let o = ctl.step(black_box(p), Mode::Assist, black_box(i), dt);
                black_box(o.u_motor);
            }
        })
    }

    /// The Q16.16 full step (what an FPU-less board's node runs), same inputs and interface.
    #[inline(never)]
    pub fn steps_fx(p: &ParamSet, inp: &[Input; INPUTS]) -> u32 {
        let mut ctl = ControllerFx::new(p);
        let dt = 1.0 / p.get(ParamId::ControlRateHz);
        ticks(|| {
            for i in inp.iter() {
                let o = ctl.step(black_box(p), Mode::Assist, black_box(i), dt);
                black_box(o.u_motor);
            }
        })
    }

    /// What the firmware's loop does per tick: q̇ and q̈ from the position by two
    /// differentiators, then the step.
    #[inline(never)]
    pub fn loop_body(p: &ParamSet, inp: &[Input; INPUTS]) -> u32 {
        let mut ctl = Controller::new();
        let mut dq = Differentiator::new();
        let mut dqd = Differentiator::new();
        let rate = p.get(ParamId::ControlRateHz);
        let dt = 1.0 / rate;
        let vc = vectors::velocity_cutoff_hz(rate);
        let ac = p.get(ParamId::AccelCutoff);
        ticks(|| {
            for i in inp.iter() {
                let i = black_box(i);
                let qd = dq.update(i.q, dt, vc);
                let qdd = dqd.update(qd, dt, ac);
                let x = Input { q: i.q, qd, qdd, ..*i };
                let o = ctl.step(black_box(p), Mode::Assist, &x, dt);
                black_box(o.u_motor);
            }
        })
    }

    /// Ticks for `f(input)` over every input, the result kept alive.
    pub fn each<F: FnMut(&Input) -> f32>(inp: &[Input; INPUTS], mut f: F) -> u32 {
        ticks(|| {
            for i in inp.iter() {
                black_box(f(black_box(i)));
            }
        })
    }

    pub fn fixed_path(p: &ParamSet, inp: &[Input; INPUTS]) -> u32 {
        let fp = FixedParams::from_set(p);
        let mut q = [Fx::ZERO; INPUTS];
        let mut qd = [Fx::ZERO; INPUTS];
        for ((a, b), i) in q.iter_mut().zip(qd.iter_mut()).zip(inp.iter()) {
            *a = vectors::to_fx(i.q);
            *b = vectors::to_fx(i.qd);
        }
        ticks(|| {
            for (a, b) in q.iter().zip(qd.iter()) {
                let d = fixed::disturbance_fx(black_box(&fp), black_box(*a), black_box(*b));
                black_box(d);
            }
        })
    }

    /// The fixed path with its Dahl state (presliding on in `p`).
    pub fn fixed_path_dahl(p: &ParamSet, inp: &[Input; INPUTS]) -> u32 {
        let fp = FixedParams::from_set(p);
        let mut q = [Fx::ZERO; INPUTS];
        let mut qd = [Fx::ZERO; INPUTS];
        for ((a, b), i) in q.iter_mut().zip(qd.iter_mut()).zip(inp.iter()) {
            *a = vectors::to_fx(i.q);
            *b = vectors::to_fx(i.qd);
        }
        let mut dahl = DahlFx::new();
        ticks(|| {
            for (a, b) in q.iter().zip(qd.iter()) {
                let d = fixed::disturbance_stateful_fx(black_box(&fp), &mut dahl, black_box(*a), black_box(*b));
                black_box(d);
            }
        })
    }
}

#[cfg(target_os = "none")]
fn run() -> i32 {
    use bench::*;
    use core::fmt::Write;
    use firmware_qemu::{systick, EXIT_CHECK_FAILED};
    use joint_core::params::ParamId;
    use joint_core::vectors;

    let Some(mut out) = firmware_qemu::LineOut::stdout() else {
        return EXIT_CHECK_FAILED;
    };
    systick::start();

    // Ticks per instruction from two loop lengths: the difference removes the fixed cost
    // of the call and of reading the counter.
    const N1: u32 = 10_000;
    const N2: u32 = 110_000;
    let t1 = ticks(|| spin(core::hint::black_box(N1)));
    let t2 = ticks(|| spin(core::hint::black_box(N2)));
    let tpi = (t2 - t1) as f32 / (2 * (N2 - N1)) as f32;
    let _ = writeln!(
        out,
        "calibration: {} loop instructions took {} SysTick ticks: {:.4} ticks/instruction (expected 3.2 at shift=7)",
        2 * (N2 - N1),
        t2 - t1,
        tpi
    );
    if !joint_core::math::is_finite(tpi) || tpi <= 0.0 {
        let _ = writeln!(out, "calibration failed: SysTick did not advance (is -icount set?)");
        return EXIT_CHECK_FAILED;
    }

    let inp = inputs();
    let base = baseline(&inp);
    let per = |t: u32| (t.saturating_sub(base)) as f32 / tpi / INPUTS as f32;

    let configs = [
        ("friction+weight", vectors::friction_weight_only()),
        ("+ inertia/offset", vectors::trunk_right()),
        ("+ spring", vectors::trunk_spring()),
        ("+ 2-D gravity table, fused", vectors::trunk_table_fused()),
    ];
    let _ = writeln!(out, "core: {CORE}");
    let _ = writeln!(out, "{:<44} {:>14}", "configuration", "instr/step");
    let mut full = f32::INFINITY;
    for (name, raw) in configs.iter() {
        let Some(p) = set(raw) else {
            let _ = writeln!(out, "parameter set '{name}' was refused by check()");
            return EXIT_CHECK_FAILED;
        };
        let n = per(steps(&p, &inp));
        full = n;
        let _ = writeln!(out, "{:<44} {:>14.1}", name, n);
        let _ = writeln!(out, "bench step \"{name}\" {n:.1}");
    }
    // The arm joint: weight + 9-term series over four angles + residual table, fused. Not the
    // budgeted step (the trunk joint's full step is); printed so its cost is known.
    let Some(arm) = set(&vectors::arm_series_residual()) else {
        let _ = writeln!(out, "parameter set 'arm series' was refused by check()");
        return EXIT_CHECK_FAILED;
    };
    let arm_inp = arm_inputs(&inp);
    let n = per(steps(&arm, &arm_inp));
    let _ = writeln!(out, "{:<44} {:>14.1}", "arm: 9-term series (4 angles) + residual table", n);
    let _ = writeln!(out, "bench step \"arm: 9-term series + residual table\" {n:.1}");
    // Pre-sliding (Dahl) friction on the full step, on inputs whose angle walks in small steps
    // with reversals; the step without it on the same inputs beside it, for the difference.
    let Some(dahl) = set(&vectors::presliding_fused()) else {
        let _ = writeln!(out, "parameter set 'presliding' was refused by check()");
        return EXIT_CHECK_FAILED;
    };
    let walk = walk_inputs(&inp);
    let n = per(steps(&dahl, &walk));
    let _ = writeln!(out, "{:<44} {:>14.1}", "+ presliding: Dahl state (walk, reversals)", n);
    let _ = writeln!(out, "bench step \"+ presliding: Dahl state\" {n:.1}");
    let Some(fused) = set(&vectors::trunk_table_fused()) else {
        return EXIT_CHECK_FAILED;
    };
    let n = per(steps(&fused, &walk));
    let _ = writeln!(out, "{:<44} {:>14.1}", "  the same inputs, presliding off", n);
    let _ = writeln!(out, "bench step \"same walk, presliding off\" {n:.1}");
    let Some(spring) = set(&vectors::trunk_spring()) else {
        return EXIT_CHECK_FAILED;
    };
    let n = per(fixed_path(&spring, &inp));
    let _ = writeln!(out, "{:<44} {:>14.1}", "fixed-point friction+weight+spring (Q16.16)", n);
    let _ = writeln!(out, "bench fixed \"fixed-point friction+weight+spring\" {n:.1}");
    let n = per(fixed_path_dahl(&dahl, &walk));
    let _ = writeln!(out, "{:<44} {:>14.1}", "fixed-point + Dahl state (Q16.16, walk)", n);
    let _ = writeln!(out, "bench fixed \"fixed-point + Dahl state\" {n:.1}");
    let n = per(fixed_path(&spring, &walk));
    let _ = writeln!(out, "{:<44} {:>14.1}", "  the same inputs, presliding off", n);
    let _ = writeln!(out, "bench fixed \"same walk, presliding off\" {n:.1}");
    // The full step each arithmetic has, side by side: the trunk joint with a spring (every
    // term the Q16.16 step computes), and the same with the Dahl state on the walk.
    let mut spring_dahl_raw = vectors::trunk_spring();
    spring_dahl_raw.set(ParamId::PreslidingSigma, 800.0);
    let Some(spring_dahl) = set(&spring_dahl_raw) else {
        return EXIT_CHECK_FAILED;
    };
    let _ = writeln!(
        out,
        "full step, f32 vs Q16.16 (trunk joint + inertia/offset + spring, assist mode; then with gravity):"
    );
    let f32_full = per(steps(&spring, &inp));
    let fx_full = per(steps_fx(&spring, &inp));
    let f32_dahl = per(steps(&spring_dahl, &walk));
    let fx_dahl = per(steps_fx(&spring_dahl, &walk));
    let Some(fused) = set(&vectors::trunk_table_fused()) else {
        return EXIT_CHECK_FAILED;
    };
    let f32_table = per(steps(&fused, &inp));
    let fx_table = per(steps_fx(&fused, &inp));
    let f32_arm = per(steps(&arm, &arm_inp));
    let fx_arm = per(steps_fx(&arm, &arm_inp));
    // Load-dependent friction on the load cell's reading (with a Stribeck dip: the effect terms'
    // out-of-line sum), the trunk joint with a spring otherwise.
    let Some(load) = set(&vectors::trunk_load_friction()) else {
        return EXIT_CHECK_FAILED;
    };
    let load_inp = load_inputs(&inp);
    let f32_load = per(steps(&load, &load_inp));
    let fx_load = per(steps_fx(&load, &load_inp));
    for (name, n) in [
        ("f32 full step", f32_full),
        ("Q16.16 full step", fx_full),
        ("f32 full step + Dahl state (walk)", f32_dahl),
        ("Q16.16 full step + Dahl state (walk)", fx_dahl),
        ("f32 full step + 2-D table, fused", f32_table),
        ("Q16.16 full step + 2-D table, fused", fx_table),
        ("f32 full step, arm: series + residual table", f32_arm),
        ("Q16.16 full step, arm: series + residual table", fx_arm),
        ("f32 full step + load friction", f32_load),
        ("Q16.16 full step + load friction", fx_load),
    ] {
        let _ = writeln!(out, "  {:<42} {:>14.1}", name, n);
        let _ = writeln!(out, "bench full \"{name}\" {n:.1}");
    }
    let Some(table) = set(&vectors::trunk_table_fused()) else {
        return EXIT_CHECK_FAILED;
    };
    let n = per(loop_body(&table, &inp));
    let _ = writeln!(out, "{:<44} {:>14.1}", "loop body: 2 differentiators + full step", n);
    let _ = writeln!(out, "bench loop \"2 differentiators + full step\" {n:.1}");

    // Where a step's instructions go: the pieces the step is made of, timed alone.
    let _ = writeln!(out, "components (same inputs, same subtraction):");
    let t = table.terms();
    let tbl = table.table();
    let comps: [(&str, u32); 8] = [
        ("math::sin (core f32 routine)", each(&inp, |i| joint_core::math::sin(i.q))),
        ("Friction::torque", each(&inp, |i| t.friction.torque(i.qd))),
        ("Weight::torque", each(&inp, |i| t.weight.torque(i.q))),
        (
            "table::interpolate (2-D, one value array)",
            each(&inp, |i| joint_core::table::interpolate(tbl, &tbl.torque, &[i.q, i.others[0], 0.0, 0.0])),
        ),
        ("table::fuse", each(&inp, |i| joint_core::table::fuse(i.q, 0.3, i.qd, 0.2, 1.0))),
        (
            "control::gravity (weight + 2 interpolations + fuse)",
            each(&inp, |i| joint_core::control::gravity(&table, i.q, &i.others)),
        ),
        ("Differentiator::update", {
            let mut d = joint_core::control::Differentiator::new();
            each(&inp, |i| d.update(i.q, 0.001, 100.0))
        }),
        ("Dahl::update (walk)", {
            let mut d = joint_core::control::Dahl::new();
            each(&walk, |i| d.update(&dahl, i.q, i.qd))
        }),
    ];
    for (name, tk) in comps.iter() {
        let n = per(*tk);
        let _ = writeln!(out, "  {:<52} {:>8.1}", name, n);
        let _ = writeln!(out, "bench component \"{name}\" {n:.1}");
    }
    // The budgeted step: the f32 step with the fused table on the M4F, the Q16.16 step on the
    // FPU-less core (the step that board runs).
    let full = if cfg!(armv6m) { fx_full } else { full };
    let _ = writeln!(
        out,
        "full step {:.1} instructions, budget {:.0}: {}",
        full,
        STEP_BUDGET_INSTRUCTIONS,
        if full <= STEP_BUDGET_INSTRUCTIONS { "within budget" } else { "OVER BUDGET" }
    );
    if full <= STEP_BUDGET_INSTRUCTIONS {
        0
    } else {
        EXIT_CHECK_FAILED
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    firmware_qemu::host_main("qemu-bench")
}
