//! One tick of the control loop, without the hardware: position in, motor command out.
//!
//! Per tick: q from the encoder; q̇ and q̈ from two of the core's [`Differentiator`]s at
//! the nominal period; the core's [`Controller::step`]; then the core's [`Safety`] layer
//! (heartbeat watchdog, fault latch, fade to zero), whose output becomes the motor command
//! `τ/(N − 1)`. The embassy task around it only waits for the ticker, reads the encoder and
//! writes the PWM. Nothing here allocates or blocks.

use joint_core::control::{Controller, Differentiator, Input, Mode, Output};
use joint_core::params::{ParamId, ParamSet};
use joint_core::safety::{Faults, Safety, SafetyConfig};
use joint_core::vectors::velocity_cutoff_hz;

use crate::io::EncoderError;

/// What the host asks of the loop (set by the protocol layer; defaults to the product's
/// normal mode, gated by the heartbeat watchdog and the soft start).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    pub mode: Mode,
    pub assist_cmd: f32,
    pub others: [f32; 3],
}

impl Default for Command {
    fn default() -> Self {
        Command { mode: Mode::Assist, assist_cmd: 0.0, others: [0.0; 3] }
    }
}

/// Result of a tick, for the output stage and the status report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickOutput {
    /// Motor torque command after the safety layer, N·m (motor side).
    pub u_motor: f32,
    /// Output torque after the safety layer, N·m.
    pub tau: f32,
    pub q: f32,
    pub qd: f32,
    /// The controller's own output before the safety layer.
    pub step: Output,
    pub faults: Faults,
    pub gain: f32,
}

/// The loop's state between ticks.
pub struct ControlLoop {
    ctl: Controller,
    dq: Differentiator,
    dqd: Differentiator,
    safety: Safety,
    dt: f32,
    period_us: u64,
    vel_cutoff: f32,
    accel_cutoff: f32,
    last_tick_us: Option<u64>,
    last_q: f32,
}

impl ControlLoop {
    pub fn new(p: &ParamSet, now_us: u64) -> Self {
        let mut s = ControlLoop {
            ctl: Controller::new(),
            dq: Differentiator::new(),
            dqd: Differentiator::new(),
            safety: Safety::new(SafetyConfig::from_params(p), now_us),
            dt: 0.0,
            period_us: 0,
            vel_cutoff: 0.0,
            accel_cutoff: 0.0,
            last_tick_us: None,
            last_q: 0.0,
        };
        s.apply_params(p);
        s
    }

    /// Loop period for a parameter set, µs (the set is validated: 100..=10 000 Hz).
    pub fn period_us(p: &ParamSet) -> u64 {
        let hz = p.get(ParamId::ControlRateHz);
        // Validated range keeps this within 100..=10_000 µs; the clamp is belt and braces.
        ((1.0e6 / hz + 0.5) as u64).clamp(100, 10_000)
    }

    /// A new parameter set is in force: new period, filters and safety limits. The
    /// controller's memory is kept so that a parameter change is not a torque step (the
    /// rate limit then moves the torque to the new target).
    pub fn apply_params(&mut self, p: &ParamSet) {
        self.period_us = Self::period_us(p);
        self.dt = self.period_us as f32 * 1.0e-6;
        let rate = p.get(ParamId::ControlRateHz);
        self.vel_cutoff = velocity_cutoff_hz(rate);
        self.accel_cutoff = p.get(ParamId::AccelCutoff);
        self.safety.configure(SafetyConfig::from_params(p));
    }

    pub fn nominal_period_us(&self) -> u64 {
        self.period_us
    }

    /// The gap before the next tick is known not to be a stall (a flash operation the
    /// parameter task made while the torque was off): do not count it as an overrun.
    pub fn excuse_gap(&mut self) {
        self.last_tick_us = None;
    }

    /// A valid host heartbeat arrived at `now_us`.
    pub fn on_heartbeat(&mut self, now_us: u64) {
        self.safety.on_heartbeat(now_us);
    }

    /// Latch a fault found outside the loop (store corrupt at boot, CAN bus-off...).
    pub fn raise(&mut self, f: Faults) {
        self.safety.raise(f);
    }

    pub fn clear_faults(&mut self, now_us: u64) -> Result<Faults, joint_core::safety::ClearError> {
        self.safety.clear_faults(now_us)
    }

    pub fn take_new_faults(&mut self) -> Faults {
        self.safety.take_new_faults()
    }

    /// One tick at `now_us` with the encoder's reading.
    pub fn tick(&mut self, p: &ParamSet, now_us: u64, position: Result<f32, EncoderError>, cmd: &Command) -> TickOutput {
        // A tick that comes more than three periods late means the loop was stalled (a
        // flash erase, a runaway task): latch it, the safety layer fades the torque.
        if let Some(last) = self.last_tick_us {
            if now_us.wrapping_sub(last) > 3 * self.period_us {
                self.safety.raise(Faults::LOOP_OVERRUN);
            }
        }
        self.last_tick_us = Some(now_us);

        let (mode, q) = match position {
            Ok(q) => {
                self.last_q = q;
                (cmd.mode, q)
            }
            // No fresh angle: hold the last one for the filters and ask for zero torque.
            Err(_) => (Mode::Off, self.last_q),
        };
        let qd = self.dq.update(q, self.dt, self.vel_cutoff);
        let qdd = self.dqd.update(qd, self.dt, self.accel_cutoff);
        let input = Input { q, qd, qdd, others: cmd.others, assist_cmd: cmd.assist_cmd };
        let step = self.ctl.step(p, mode, &input, self.dt);
        let tau = self.safety.update(now_us, step.tau_out);
        TickOutput {
            u_motor: tau * p.inv_ratio_m1(),
            tau,
            q,
            qd,
            step,
            faults: self.safety.faults(),
            gain: self.safety.gain(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use joint_core::params::check;
    use joint_core::vectors::trunk_right;

    fn set() -> ParamSet {
        check(&trunk_right()).unwrap()
    }

    /// Runs `ms` ticks of 1 ms at a fixed angle, heartbeat every 100 ms while `host` says so.
    fn run(l: &mut ControlLoop, p: &ParamSet, t0: u64, ms: u64, host: impl Fn(u64) -> bool) -> (u64, TickOutput) {
        let mut out = TickOutput::default();
        let mut t = t0;
        for i in 0..ms {
            t = t0 + i * 1000;
            if i % 100 == 0 && host(t) {
                l.on_heartbeat(t);
            }
            out = l.tick(p, t, Ok(1.0), &Command::default());
        }
        (t, out)
    }

    #[test]
    fn torque_reaches_the_law_with_host_and_fades_to_zero_without() {
        let p = set();
        let mut l = ControlLoop::new(&p, 0);
        assert_eq!(l.nominal_period_us(), 1000);
        let (t, out) = run(&mut l, &p, 0, 2000, |_| true);
        assert!(out.faults.is_empty());
        assert!(out.tau > 0.5, "gravity compensation should push: {out:?}");
        let ratio = p.get(ParamId::Ratio);
        assert!(joint_core::math::abs(out.u_motor - out.tau / (ratio - 1.0)) < 1e-6);
        // Host gone: timeout 0.5 s + ramp 0.2 s, so zero within 0.7 s and latched.
        let (_, out) = run(&mut l, &p, t + 1000, 800, |_| false);
        assert_eq!(out.tau, 0.0);
        assert!(out.faults.contains(Faults::HEARTBEAT_LOST));
    }

    #[test]
    fn encoder_error_commands_zero_torque_through_the_rate_limit() {
        let p = set();
        let mut l = ControlLoop::new(&p, 0);
        let (t, out) = run(&mut l, &p, 0, 1000, |_| true);
        assert!(out.tau > 0.5);
        l.on_heartbeat(t);
        let mut last = out.tau;
        for i in 1..200 {
            let o = l.tick(&p, t + i * 1000, Err(EncoderError::Sensor), &Command::default());
            assert!(o.tau <= last + 1e-6);
            last = o.tau;
        }
        assert_eq!(last, 0.0);
    }

    #[test]
    fn a_stalled_loop_latches_an_overrun() {
        let p = set();
        let mut l = ControlLoop::new(&p, 0);
        l.on_heartbeat(0);
        l.tick(&p, 1000, Ok(0.0), &Command::default());
        let o = l.tick(&p, 10_000, Ok(0.0), &Command::default());
        assert!(o.faults.contains(Faults::LOOP_OVERRUN));
    }

    #[test]
    fn period_follows_the_rate_parameter() {
        let mut raw = trunk_right();
        raw.set(ParamId::ControlRateHz, 10_000.0);
        raw.set(ParamId::AccelCutoff, 20.0);
        assert_eq!(ControlLoop::period_us(&check(&raw).unwrap()), 100);
        raw.set(ParamId::ControlRateHz, 100.0);
        assert_eq!(ControlLoop::period_us(&check(&raw).unwrap()), 10_000);
    }
}
