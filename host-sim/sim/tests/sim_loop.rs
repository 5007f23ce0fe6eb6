//! The offline simulator runs the boards' loop: the core's `ControlLoop`, ticked on what the
//! simulated sensors read. Replaying a log's readings through that loop gives back the log's
//! torque bit for bit; the angle-only estimate (an encoder-only board) would not.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig, SimError};
use joint_core::control::{Controller, Input, Mode, Output};
use joint_core::control_loop::{ControlLoop, LoopTarget};
use joint_core::params::ParamSet;
use joint_core::safety::Faults;
use joint_formats::model_file::ModelFile;

/// The controller in assist, the load cell's reading set before each tick.
struct Assist {
    p: ParamSet,
    c: Controller,
    tau_load: f32,
}

impl LoopTarget for Assist {
    fn params(&self) -> &ParamSet {
        &self.p
    }
    fn control(&mut self, _now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output {
        let inp = Input { q, qd, qdd, others: [0.0; 3], assist_cmd: 0.0, tau_load: self.tau_load };
        self.c.step(&self.p, Mode::Assist, &inp, dt)
    }
    fn raise(&mut self, _f: Faults) {}
    fn faults(&self) -> Faults {
        Faults::NONE
    }
    fn drive(&self) -> bool {
        true
    }
}

/// The trunk joint with a load-dependent friction the controller compensates too (so the load
/// cell's reading reaches the step), noisy sensors, no noise on the logged torque.
fn plant_and_model() -> (PlantFile, ParamSet) {
    let ldf = "\n[load_dependent_friction]\nmu = 0.1\n";
    let model_text = format!("{}{ldf}", common::trunk_model());
    let plant_text = format!(
        "{model_text}\n[sensors]\nq_noise = 1e-4\nqd_noise = 0.002\nqdd_noise = 0.05\ntau_noise = 0.15\nu_noise = 0.0\n"
    );
    let plant = PlantFile::parse(&plant_text, "plant.toml").unwrap();
    let p = ModelFile::parse(&model_text, "model.toml").unwrap().param_set().unwrap();
    (plant, p)
}

#[test]
fn the_logged_torque_is_the_core_loops_output_on_the_logged_readings() {
    let (plant, p) = plant_and_model();
    let cfg = SimConfig { scenarios: vec![ScenarioKind::Hand], seconds: 4.0, seed: 3, ..SimConfig::default() };
    let (log, _) = sim::simulate(&plant, &p, &cfg).unwrap();
    let (qd, u, tau) = (log.qd.as_ref().unwrap(), log.u.as_ref().unwrap(), log.tau.as_ref().unwrap());
    let replay = |sensed_velocity: bool| -> Vec<f64> {
        let mut target = Assist { p: p.clone(), c: Controller::new(), tau_load: 0.0 };
        let mut l = ControlLoop::new(&p);
        (0..log.len())
            .map(|i| {
                target.tau_load = tau[i] as f32;
                let now_us = (log.t[i] * 1.0e6).round() as u64;
                let q = Ok::<f32, ()>(log.q[i] as f32);
                let r = if sensed_velocity {
                    l.tick_sensed(&mut target, now_us, q, Ok(qd[i] as f32))
                } else {
                    l.tick(&mut target, now_us, q)
                };
                f64::from(r.out.tau_out)
            })
            .collect()
    };
    let same = replay(true);
    assert!(log.len() > 3000);
    for (i, (a, b)) in u.iter().zip(&same).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "row {i}: logged u {a} against the loop's {b}");
    }
    // An encoder-only board's loop (q̇ from the angle) on the same readings is another sensor:
    // its torque differs from the log's by far more than rounding.
    let angle_only = replay(false);
    let d: Vec<f64> = u.iter().zip(&angle_only).map(|(a, b)| a - b).collect();
    assert!(common::rms(&d) > 0.05, "angle-only replay differs by only {} N·m rms", common::rms(&d));
}

#[test]
fn a_rate_the_controllers_set_refuses_is_refused_with_its_reason() {
    let (plant, p) = plant_and_model();
    // A rate the joint's parameter set cannot hold: refused by the simulator as the board
    // refuses the set, naming the rate and the parameter.
    let cfg = SimConfig { rate: Some(100.0), seconds: 1.0, plant_rate: 10_000.0, ..SimConfig::default() };
    assert!(sim::simulate(&plant, &p, &cfg).is_ok());
    let cfg = SimConfig { rate: Some(30.0), seconds: 1.0, plant_rate: 3_000.0, ..SimConfig::default() };
    let SimError::Config(e) = sim::simulate(&plant, &p, &cfg).unwrap_err();
    assert!(e.contains("control rate 30 Hz") && e.contains("rate_hz"), "{e}");
    // in range, but with the acceleration filter's cut-off above the loop's Nyquist rate
    let mut raw = p.raw().clone();
    raw.set(joint_core::params::ParamId::AccelCutoff, 80.0);
    let p80 = joint_core::params::check(&raw).unwrap();
    let cfg = SimConfig { rate: Some(150.0), seconds: 1.0, plant_rate: 3_000.0, ..SimConfig::default() };
    let SimError::Config(e) = sim::simulate(&plant, &p80, &cfg).unwrap_err();
    assert!(e.contains("control rate 150 Hz") && e.contains("accel_cutoff"), "{e}");
}
