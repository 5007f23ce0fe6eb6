//! The whole control step in Q16.16 ([`ControllerFx`]) against the f32 step, every term and
//! every mode, and a Q16.16 node: its identity, and that it takes every set an f32 node takes.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::canopen::node::{MemoryStorage, Node, NodeConfig, PRODUCT_CODE_Q16};
use joint_core::canopen::{od, Abort, ControlStep};
use joint_core::control::{Controller, Input, Mode};
use joint_core::fixed::{Arithmetic, ControllerFx};
use joint_core::params::{check, ParamId, RawParams, PARAMS};
use joint_core::safety::Faults;
use joint_core::vectors::{self, XorShift32 as Rng};

type F32Node = Node<MemoryStorage, Controller>;
type Q16Node = Node<MemoryStorage, ControllerFx>;

fn node<C: ControlStep>(stored: Option<RawParams>) -> Node<MemoryStorage, C> {
    // The config says f32: the node's step type decides (and names itself in the identity).
    Node::with_step(NodeConfig::new(5), MemoryStorage { stored, saves: 0, pdo: None, lss: None }, 0)
}

fn param_index(id: ParamId) -> u16 {
    od::PARAM_BASE + PARAMS.iter().position(|d| d.id == id).unwrap() as u16
}

/// Commit what the test staged, named by its CRC (0x2205; a plain commit is refused).
fn commit<C: ControlStep>(n: &mut Node<MemoryStorage, C>) -> Result<(), Abort> {
    let crc = joint_core::store::set_crc(n.staged());
    n.write(od::COMMIT_CRC, 0, &crc.to_le_bytes())
}

#[test]
fn the_identity_names_the_arithmetic() {
    let mut b = [0u8; 32];
    let f: F32Node = node(None);
    let q: Q16Node = node(None);
    f.read(od::IDENTITY, 2, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes([b[0], b[1], b[2], b[3]]), 0x4A4E_0001);
    q.read(od::IDENTITY, 2, &mut b).unwrap();
    assert_eq!(u32::from_le_bytes([b[0], b[1], b[2], b[3]]), PRODUCT_CODE_Q16);
    let k = q.read(od::DEVICE_NAME, 0, &mut b).unwrap();
    assert_eq!(&b[..k], b"joint-node q16.16");
    // The f32 node is the one every board had before: same identity, same name.
    assert_eq!(NodeConfig::new(5).with_arithmetic(Arithmetic::F32), NodeConfig::new(5));
    assert_eq!(NodeConfig::new(5).with_arithmetic(Arithmetic::Q16).identity.product_code, PRODUCT_CODE_Q16);
}

/// Every term, switched on through the SDO server, commits on a Q16.16 node as on an f32 one:
/// the Q16.16 step has them all (nothing is refused for want of a term).
#[test]
fn a_q16_node_commits_every_term() {
    let cases = [
        (ParamId::StribeckLevel, 0.5f32),
        (ParamId::AsymmetricDelta, 0.2),
        (ParamId::RippleAmplitude, 0.1),
        (ParamId::RippleAmplitude2, 0.05),
        (ParamId::CableK, 3.0),
        (ParamId::DryFrictionC, 0.4),
        (ParamId::PreslidingSigma, 800.0),
        // σ_m > 0 without a table with σ: inconsistent, refused by both alike
        (ParamId::TableSigmaModel, 0.3),
    ];
    for (id, v) in cases {
        let mut q: Q16Node = node(Some(vectors::trunk_right()));
        let mut f: F32Node = node(Some(vectors::trunk_right()));
        q.write(param_index(id), 0, &v.to_le_bytes()).unwrap();
        f.write(param_index(id), 0, &v.to_le_bytes()).unwrap();
        let r = commit(&mut q);
        assert_eq!(r, commit(&mut f), "{id:?}");
        assert_eq!(r.is_ok(), id != ParamId::TableSigmaModel, "{id:?}");
    }
}

#[test]
fn a_q16_node_boots_on_a_stored_table_or_series_set() {
    for raw in [vectors::trunk_table_fused(), vectors::arm_series_residual(), vectors::presliding_fused()] {
        let q: Q16Node = node(Some(raw.clone()));
        assert!(!q.safety().faults().contains(Faults::PARAMS_REJECTED));
        assert!(q.params().raw() == &raw);
    }
}

/// The Q16.16 step follows the f32 step in every mode on the trunk joint with a spring, the
/// Dahl state on and off, over random inputs inside the operating range, with the limits
/// acting (torque limit 40 N·m, rate limit 2000 N·m/s at 1 kHz).
#[test]
fn the_q16_step_follows_the_f32_step_in_every_mode() {
    let mut sets = vec![("trunk+spring", vectors::trunk_spring())];
    let mut pre = vectors::trunk_spring();
    pre.set(ParamId::PreslidingSigma, 800.0);
    sets.push(("trunk+spring+Dahl", pre));
    sets.push(("2-D table, fused", vectors::trunk_table_fused()));
    sets.push(("arm: series+residual", vectors::arm_series_residual()));
    sets.push(("table+Dahl", vectors::presliding_fused()));
    let mut fx_effects = vectors::trunk_spring();
    for (id, v) in [
        (ParamId::StribeckLevel, 0.8),
        (ParamId::StribeckSpeed, 0.05),
        (ParamId::AsymmetricDelta, 0.3),
        (ParamId::RippleAmplitude, 0.2),
        (ParamId::RipplePeriod, 0.05),
        (ParamId::RippleAmplitude2, 0.1),
        (ParamId::RipplePhase2, -1.0),
        (ParamId::CableK, 6.0),
        (ParamId::CableEngage, 0.4),
        (ParamId::CableWidth, 0.1),
        (ParamId::DryFrictionC, 0.5),
        (ParamId::LoadFrictionMu, 0.08),
    ] {
        fx_effects.set(id, v);
    }
    sets.push(("effect terms", fx_effects));
    sets.push(("load friction", vectors::trunk_load_friction()));
    let modes = [Mode::Assist, Mode::Velocity(0.8), Mode::Position(0.6), Mode::Off];
    println!("{:<20} {:<14} {:>12} {:>12}", "set", "mode", "worst |Δτ|", "worst |ΔC_c|");
    for (name, raw) in sets {
        let p = check(&raw).unwrap();
        for mode in modes {
            let mut c = Controller::new();
            let mut x = ControllerFx::new(&p);
            let mut rng = Rng::new(7);
            let (mut worst_tau, mut worst_cc) = (0.0f64, 0.0f64);
            let mut q = 0.5f32;
            // Inputs exact in Q16.16, as an encoder's counts and their differences give them:
            // the comparison is then of the arithmetic, not of the format's input resolution
            // (which costs up to c/band·2⁻¹⁶ = 3.5e-3 N·m inside the friction band, and
            // 2σ·2⁻¹⁶ right after a reversal of the Dahl state: tests/fixed_point.rs).
            let r = |x: f32| (x * 65536.0).round() / 65536.0;
            for _ in 0..20_000 {
                // A joint that moves: small steps with the odd reversal, velocities ±2 rad/s.
                q = r(q + rng.uniform(-2e-3, 2e-3));
                let inp = Input {
                    q,
                    qd: r(rng.uniform(-2.0, 2.0)),
                    qdd: r(rng.uniform(-20.0, 20.0)),
                    others: [r(rng.uniform(-1.2, 2.2)), r(rng.uniform(-1.0, 1.0)), r(rng.uniform(-1.0, 1.0))],
                    assist_cmd: r(rng.uniform(-1.0, 1.0)),
                    tau_load: r(rng.uniform(-40.0, 40.0)),
                };
                let a = c.step(&p, mode, &inp, 1e-3);
                let b = x.step(&p, mode, &inp, 1e-3);
                assert_eq!(a.bad_input, b.bad_input);
                worst_tau = worst_tau.max((a.tau_out as f64 - b.tau_out as f64).abs());
                worst_cc = worst_cc.max((a.c_c as f64 - b.c_c as f64).abs());
            }
            println!("{name:<20} {:<14} {worst_tau:>12.2e} {worst_cc:>12.2e}", format!("{mode:?}"));
            // Velocity mode integrates its error; a few LSB of difference per step add up.
            assert!(worst_tau < 5e-3, "{name} {mode:?}: {worst_tau}");
            assert!(worst_cc < 5e-3, "{name} {mode:?}: {worst_cc}");
        }
    }
}

#[test]
fn the_q16_step_drives_zero_on_bad_input_and_never_exceeds_the_limit() {
    let p = check(&vectors::trunk_right()).unwrap();
    let mut x = ControllerFx::new(&p);
    for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let o = x.step(&p, Mode::Assist, &Input { q: v, ..Input::default() }, 1e-3);
        assert!(o.bad_input);
        assert_eq!(o.tau_out, 0.0);
    }
    // Inputs far outside Q16.16's range saturate (never wrap): the torque goes to the limit
    // with the sign of the disturbance, one rate step at a time.
    let mut last = 0.0f32;
    for _ in 0..100 {
        let o = x.step(&p, Mode::Assist, &Input { q: 0.3, qd: 1.0e9, qdd: 1.0e9, ..Input::default() }, 1e-3);
        assert!(o.tau_out >= last && o.tau_out <= 40.0, "{}", o.tau_out);
        last = o.tau_out;
    }
    assert_eq!(last, 40.0);
}
