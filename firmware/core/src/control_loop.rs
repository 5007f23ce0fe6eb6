//! One tick of the control loop, without the hardware: position in, motor command out.
//!
//! Per tick: q from the encoder; q̇ and q̈ from two of the core's [`Differentiator`]s at
//! the nominal period; then the CANopen node's [`Node::control`], which steps the core's
//! controller with the committed parameter set, the NMT state's mode and the host's RPDO
//! commands, passes the torque through the heartbeat watchdog and records the state for the
//! TPDOs. What the node cannot know stays here: the loop period and filter cut-offs that
//! follow the committed `controller_rate_hz`, and overrun detection (a tick more than three
//! periods late latches `LOOP_OVERRUN` in the node's fault word). The embassy task around it
//! only waits for the ticker, reads the encoder, takes the node's lock for the tick and
//! writes the PWM. Nothing here allocates or blocks.
//!
//! The one loop of every user of the core: the boards' control tasks, the closed-loop
//! experiments of `jointctl` and another firmware built on the core (docs/porting.md). The
//! encoder's error type is the caller's: any error is a tick without a fresh angle.
//!
//! What the loop steps is a [`LoopTarget`]: on a board the CANopen [`Node`] (the committed set,
//! the NMT state's mode, the host's commands, the safety layer); in host-sim's offline
//! simulator a bare controller under the scenario's mode (velocity sweeps and position holds
//! that a test rig commands and the node does not offer). A joint whose sensor also gives the
//! velocity (a tachometer, an encoder chip's own estimate, the simulator's velocity sensor)
//! ticks with [`ControlLoop::tick_sensed`]: q̇ is that reading and q̈ its filtered derivative,
//! by the same differentiator and cut-off as the angle-only path.

use crate::canopen::{ControlStep, NmtState, Node, ParamStorage};
use crate::control::{Differentiator, Output};
use crate::params::{ParamId, ParamSet};
use crate::safety::Faults;
use crate::vectors::velocity_cutoff_hz;

/// Result of a tick, for the output stage and the status report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickOutput {
    /// The node's output: `tau_out`/`u_motor` after the safety layer.
    pub out: Output,
    pub q: f32,
    pub qd: f32,
    pub faults: Faults,
    /// Drive the bridge (operational and the watchdog's gain above zero); otherwise the
    /// switches are opened.
    pub drive: bool,
}

/// What a [`ControlLoop`] steps each tick.
pub trait LoopTarget {
    /// The parameter set in force: the loop's period and filter cut-offs follow its
    /// `controller_rate_hz` and `accel_cutoff`.
    fn params(&self) -> &ParamSet;
    /// One control step on the estimated state; returns the output to apply.
    fn control(&mut self, now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output;
    /// Latches a fault the loop detected (an overrun, a tick without a fresh reading).
    fn raise(&mut self, f: Faults);
    /// The faults latched now.
    fn faults(&self) -> Faults;
    /// Whether the output stage drives the bridge after this tick.
    fn drive(&self) -> bool;
}

impl<S: ParamStorage, C: ControlStep> LoopTarget for Node<S, C> {
    #[inline]
    fn params(&self) -> &ParamSet {
        Node::params(self)
    }
    #[inline]
    fn control(&mut self, now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output {
        Node::control(self, now_us, q, qd, qdd, dt)
    }
    #[inline]
    fn raise(&mut self, f: Faults) {
        self.safety_mut().raise(f);
    }
    #[inline]
    fn faults(&self) -> Faults {
        self.safety().faults()
    }
    /// Operational and the watchdog's gain above zero; otherwise the switches are opened.
    #[inline]
    fn drive(&self) -> bool {
        self.nmt_state() == NmtState::Operational && self.safety().gain() > 0.0
    }
}

/// The loop's state between ticks.
pub struct ControlLoop {
    dq: Differentiator,
    dqd: Differentiator,
    dt: f32,
    period_us: u64,
    /// The committed rate the period was derived from (bits, so any change is seen).
    rate_bits: u32,
    vel_cutoff: f32,
    accel_cutoff: f32,
    last_tick_us: Option<u64>,
    last_q: f32,
    /// The last valid reading of a velocity sensor ([`ControlLoop::tick_sensed`]).
    last_qd: f32,
}

impl ControlLoop {
    pub fn new(p: &ParamSet) -> Self {
        let mut s = ControlLoop {
            dq: Differentiator::new(),
            dqd: Differentiator::new(),
            dt: 0.0,
            period_us: 0,
            rate_bits: 0,
            vel_cutoff: 0.0,
            accel_cutoff: 0.0,
            last_tick_us: None,
            last_q: 0.0,
            last_qd: 0.0,
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

    /// Period and filters for a committed set. The filters' memory is kept so that a
    /// parameter change is not a step in q̇/q̈.
    fn apply_params(&mut self, p: &ParamSet) {
        self.period_us = Self::period_us(p);
        self.dt = self.period_us as f32 * 1.0e-6;
        let rate = p.get(ParamId::ControlRateHz);
        self.rate_bits = rate.to_bits();
        self.vel_cutoff = velocity_cutoff_hz(rate);
        self.accel_cutoff = p.get(ParamId::AccelCutoff);
    }

    pub fn nominal_period_us(&self) -> u64 {
        self.period_us
    }

    /// The gap before the next tick is known not to be a stall (a flash operation the
    /// parameter task made while the torque was off): do not count it as an overrun.
    pub fn excuse_gap(&mut self) {
        self.last_tick_us = None;
    }

    /// One tick at `now_us` with the encoder's reading: q̇ and q̈ estimated from the angle.
    /// Returns the target's output; the caller restarts its ticker when
    /// [`ControlLoop::nominal_period_us`] changed (a commit of a new `controller_rate_hz`).
    pub fn tick<T: LoopTarget, E>(&mut self, target: &mut T, now_us: u64, position: Result<f32, E>) -> TickOutput {
        self.run(target, now_us, position, None)
    }

    /// One tick with the angle and a velocity sensor's reading: q̇ is the reading, q̈ its
    /// derivative through the acceleration filter. A velocity error is handled as an angle
    /// error is: `COMMAND_INVALID` latches and the last valid reading stands in.
    pub fn tick_sensed<T: LoopTarget, E>(
        &mut self,
        target: &mut T,
        now_us: u64,
        position: Result<f32, E>,
        velocity: Result<f32, E>,
    ) -> TickOutput {
        self.run(target, now_us, position, Some(velocity))
    }

    #[inline(always)]
    fn run<T: LoopTarget, E>(
        &mut self,
        target: &mut T,
        now_us: u64,
        position: Result<f32, E>,
        velocity: Option<Result<f32, E>>,
    ) -> TickOutput {
        if target.params().get(ParamId::ControlRateHz).to_bits() != self.rate_bits {
            self.apply_params(target.params());
        }
        // A tick that comes more than three periods late means the loop was stalled (a
        // flash erase, a runaway task): latch it, the safety layer fades the torque.
        if let Some(last) = self.last_tick_us {
            if now_us.wrapping_sub(last) > 3 * self.period_us {
                target.raise(Faults::LOOP_OVERRUN);
            }
        }
        self.last_tick_us = Some(now_us);

        let q = match position {
            Ok(q) => {
                self.last_q = q;
                q
            }
            // No fresh angle: the compensation would push on a stale one. The node has no
            // "sensor" fault bit; COMMAND_INVALID (the loop's input is not valid) latches, is
            // reported by EMCY and fades the torque to zero until the host clears it.
            Err(_) => {
                target.raise(Faults::COMMAND_INVALID);
                self.last_q
            }
        };
        let qd = match velocity {
            None => self.dq.update(q, self.dt, self.vel_cutoff),
            Some(Ok(v)) => {
                self.last_qd = v;
                v
            }
            Some(Err(_)) => {
                target.raise(Faults::COMMAND_INVALID);
                self.last_qd
            }
        };
        let qdd = self.dqd.update(qd, self.dt, self.accel_cutoff);
        let out = target.control(now_us, q, qd, qdd, self.dt);
        TickOutput { out, q, qd, faults: target.faults(), drive: target.drive() }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::canopen::{CanFrame, MemoryStorage, NodeConfig};
    use crate::params::check;
    use crate::vectors::trunk_right;

    const NODE: u8 = 5;

    fn frame(id: u16, d: &[u8]) -> CanFrame {
        CanFrame::new(id, d).unwrap()
    }

    /// A node on the trunk-paper set, operational.
    fn node() -> Node<MemoryStorage> {
        let storage = MemoryStorage { stored: Some(trunk_right()), saves: 0, pdo: None, lss: None };
        let mut n = Node::new(NodeConfig::new(NODE), storage, 0);
        let mut sink = |_f: CanFrame| {};
        n.process(0, Some(&frame(0x000, &[0x01, NODE])), &mut sink);
        assert_eq!(n.nmt_state(), NmtState::Operational);
        n
    }

    /// Runs `ms` ticks of 1 ms at a fixed angle, host heartbeat every 100 ms while `host`.
    fn run(l: &mut ControlLoop, n: &mut Node<MemoryStorage>, t0: u64, ms: u64, host: bool) -> (u64, TickOutput) {
        let mut out = TickOutput::default();
        let mut t = t0;
        let mut sink = |_f: CanFrame| {};
        for i in 0..ms {
            t = t0 + i * 1000;
            if i % 100 == 0 && host {
                n.process(t, Some(&frame(0x77F, &[0x05])), &mut sink);
            }
            out = l.tick(n, t, Ok::<f32, &str>(1.0));
        }
        (t, out)
    }

    #[test]
    fn torque_reaches_the_law_with_host_and_fades_to_zero_without() {
        let mut n = node();
        let mut l = ControlLoop::new(n.params());
        assert_eq!(l.nominal_period_us(), 1000);
        let (t, r) = run(&mut l, &mut n, 0, 2000, true);
        assert!(r.faults.is_empty(), "{r:?}");
        assert!(r.drive);
        assert!(r.out.tau_out > 0.5, "gravity compensation should push: {r:?}");
        let ratio = n.params().get(ParamId::Ratio);
        assert!(joint_core::math::abs(r.out.u_motor - r.out.tau_out / (ratio - 1.0)) < 1e-6);
        assert_eq!(n.joint_state().tau_cmd, r.out.tau_out, "the TPDO state is the applied torque");
        // Host gone: timeout 0.5 s + ramp 0.2 s, so zero within 0.7 s and latched.
        let (_, r) = run(&mut l, &mut n, t + 1000, 800, false);
        assert_eq!(r.out.tau_out, 0.0);
        assert!(!r.drive);
        assert!(r.faults.contains(Faults::HEARTBEAT_LOST));
    }

    #[test]
    fn no_torque_outside_operational() {
        let mut n = Node::new(
            NodeConfig::new(NODE),
            MemoryStorage { stored: Some(trunk_right()), saves: 0, pdo: None, lss: None },
            0,
        );
        let mut l = ControlLoop::new(n.params());
        let (_, r) = run(&mut l, &mut n, 0, 1000, true);
        assert_eq!(n.nmt_state(), NmtState::PreOperational);
        assert_eq!(r.out.tau_out, 0.0);
        assert!(!r.drive);
    }

    #[test]
    fn encoder_error_latches_and_fades_to_zero() {
        let mut n = node();
        let mut l = ControlLoop::new(n.params());
        let (t, r) = run(&mut l, &mut n, 0, 1000, true);
        assert!(r.out.tau_out > 0.5);
        let mut last = r.out.tau_out;
        let mut r = r;
        for i in 1..300 {
            r = l.tick(&mut n, t + i * 1000, Err("sensor"));
            assert!(r.out.tau_out <= last + 1e-6);
            last = r.out.tau_out;
        }
        assert_eq!(last, 0.0);
        assert!(r.faults.contains(Faults::COMMAND_INVALID));
    }

    #[test]
    fn a_stalled_loop_latches_an_overrun_unless_excused() {
        let mut n = node();
        let mut l = ControlLoop::new(n.params());
        l.tick(&mut n, 1000, Ok::<f32, &str>(0.0));
        l.excuse_gap();
        let r = l.tick(&mut n, 50_000, Ok::<f32, &str>(0.0));
        assert!(!r.faults.contains(Faults::LOOP_OVERRUN));
        let r = l.tick(&mut n, 60_000, Ok::<f32, &str>(0.0));
        assert!(r.faults.contains(Faults::LOOP_OVERRUN));
    }

    /// A bare target: the controller in a fixed mode, what the offline simulator steps.
    struct Bare {
        p: ParamSet,
        c: crate::control::Controller,
        faults: Faults,
        seen: Option<(f32, f32, f32, f32)>,
    }

    impl LoopTarget for Bare {
        fn params(&self) -> &ParamSet {
            &self.p
        }
        fn control(&mut self, _now_us: u64, q: f32, qd: f32, qdd: f32, dt: f32) -> Output {
            self.seen = Some((q, qd, qdd, dt));
            let inp = crate::control::Input { q, qd, qdd, others: [0.0; 3], assist_cmd: 0.0, tau_load: 0.0 };
            self.c.step(&self.p, crate::control::Mode::Assist, &inp, dt)
        }
        fn raise(&mut self, f: Faults) {
            self.faults.insert(f);
        }
        fn faults(&self) -> Faults {
            self.faults
        }
        fn drive(&self) -> bool {
            self.faults.is_empty()
        }
    }

    #[test]
    fn a_sensed_velocity_is_used_as_read_and_differentiated_once() {
        let p = check(&trunk_right()).unwrap();
        let mut b = Bare { p: p.clone(), c: crate::control::Controller::new(), faults: Faults::NONE, seen: None };
        let mut l = ControlLoop::new(&p);
        // the same readings through a lone differentiator at the loop's period and cut-off
        let mut d = Differentiator::new();
        let dt = l.nominal_period_us() as f32 * 1.0e-6;
        for k in 0..200u64 {
            let t = k as f32 * dt;
            let (q, v) = (0.3 * joint_core::math::sin(2.0 * t), 0.6 * joint_core::math::cos(2.0 * t) + 0.01);
            let r = l.tick_sensed(&mut b, k * 1000, Ok::<f32, ()>(q), Ok(v));
            let qdd = d.update(v, dt, p.get(ParamId::AccelCutoff));
            assert_eq!(b.seen, Some((q, v, qdd, dt)), "tick {k}");
            assert_eq!(r.qd, v);
            assert!(r.drive && r.faults.is_empty());
        }
        // a failed velocity reading: the last valid one stands in and the fault latches
        let r = l.tick_sensed(&mut b, 200_000, Ok::<f32, ()>(0.1), Err(()));
        assert!(r.faults.contains(Faults::COMMAND_INVALID));
        assert_eq!(r.qd, b.seen.unwrap().1);
        assert!(!r.drive);
    }

    #[test]
    fn period_follows_the_committed_rate() {
        let mut raw = trunk_right();
        raw.set(ParamId::ControlRateHz, 10_000.0);
        raw.set(ParamId::AccelCutoff, 20.0);
        assert_eq!(ControlLoop::period_us(&check(&raw).unwrap()), 100);
        raw.set(ParamId::ControlRateHz, 100.0);
        assert_eq!(ControlLoop::period_us(&check(&raw).unwrap()), 10_000);
        // Through the node: a committed rate change is picked up at the next tick.
        let mut n =
            Node::new(NodeConfig::new(NODE), MemoryStorage { stored: Some(raw), saves: 0, pdo: None, lss: None }, 0);
        let mut l = ControlLoop::new(&ParamSet::defaults());
        l.tick(&mut n, 0, Ok::<f32, &str>(0.0));
        assert_eq!(l.nominal_period_us(), 10_000);
    }
}
