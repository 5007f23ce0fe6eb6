//! Heartbeat watchdog and fault latch on virtual time: ramp shape, deadline, latch, clear,
//! heartbeat back mid-ramp, time going backwards and u64 wrap-around.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use joint_core::params::{check, ParamId, RawParams};
use joint_core::safety::{ClearError, Faults, Safety, SafetyConfig, GAIN_ONE};
use proptest::prelude::*;

const MS: u64 = 1_000;
const S: u64 = 1_000_000;

/// Timeout 100 ms, ramp 500 ms, limit 50 N·m.
fn cfg() -> SafetyConfig {
    SafetyConfig::from_seconds(0.1, 0.5, 50.0)
}

/// A watchdog at `t0` with heartbeats every 10 ms until `t0 + 1 s`, driven every 1 ms with
/// τ = 10: past the soft start, full output.
fn running(t0: u64) -> Safety {
    let mut s = Safety::new(cfg(), t0);
    let mut t = t0;
    while t <= t0 + S {
        if (t - t0) % (10 * MS) == 0 {
            s.on_heartbeat(t);
        }
        s.update(t, 10.0);
        t += MS;
    }
    assert_eq!(s.update(t0 + S, 10.0), 10.0, "full output after the soft start");
    assert!(s.faults().is_empty());
    s
}

#[test]
fn config_from_params_and_seconds() {
    let mut raw = RawParams::defaults();
    raw.set(ParamId::HeartbeatTimeout, 0.25);
    raw.set(ParamId::FaultRampTime, 0.1);
    raw.set(ParamId::TorqueLimit, 12.5);
    let set = check(&raw).expect("valid set");
    let c = SafetyConfig::from_params(&set);
    assert_eq!(c.heartbeat_timeout_us, 250_000);
    assert_eq!(c.ramp_us, 100_000);
    assert_eq!(c.torque_limit, 12.5);
    assert_eq!(c.stop_mask, Faults::DEFAULT_STOP);
    // NaN and negative times mean "off"/"immediate", never a panic.
    let c = SafetyConfig::from_seconds(f32::NAN, -1.0, 1.0);
    assert_eq!((c.heartbeat_timeout_us, c.ramp_us), (0, 0));
    assert_eq!(SafetyConfig::from_seconds(f32::INFINITY, 0.0, 1.0).heartbeat_timeout_us, u64::MAX);
}

#[test]
fn soft_start_is_a_linear_ramp_from_zero() {
    let mut s = Safety::new(cfg(), 0);
    s.on_heartbeat(0);
    assert_eq!(s.update(0, 10.0), 0.0);
    let mut prev = 0.0;
    for k in 1..=600u64 {
        let t = k * MS;
        if k % 10 == 0 {
            s.on_heartbeat(t);
        }
        let out = s.update(t, 10.0);
        let want = 10.0 * (t as f32 / 500_000.0).min(1.0);
        assert!((out - want).abs() <= 1e-4, "t={t}: {out} vs {want}");
        assert!(out >= prev);
        prev = out;
    }
    assert_eq!(prev, 10.0);
}

#[test]
fn heartbeat_loss_ramps_linearly_to_zero_within_ramp_time() {
    let mut s = running(0);
    let last_hb = S; // running() sent the last heartbeat at exactly 1 s
    let deadline = last_hb + 100 * MS;
    let end = deadline + 500 * MS;
    let mut prev = 10.0;
    let mut t = last_hb;
    while t <= end + 200 * MS {
        let out = s.update(t, 10.0);
        if t <= deadline {
            assert_eq!(out, 10.0, "t={t}: full torque until the timeout has passed");
            assert!(s.faults().is_empty());
        } else {
            assert!(s.faults().contains(Faults::HEARTBEAT_LOST));
            let want = 10.0 * (1.0 - (t - deadline) as f32 / 500_000.0).max(0.0);
            assert!((out - want).abs() <= 1e-4, "t={t}: {out} vs linear {want}");
            assert!(out <= prev, "t={t}: never increases while faulted");
        }
        if t >= end {
            assert_eq!(out, 0.0, "t={t}: zero once FaultRampTime has passed");
        }
        if t + MS < end {
            assert!(out > 0.0, "t={t}: not zero long before the ramp ends");
        }
        prev = out;
        t += MS;
    }
    assert_eq!(s.take_new_faults(), Faults::HEARTBEAT_LOST);
    assert_eq!(s.take_new_faults(), Faults::NONE, "reported once");
    assert!(!s.heartbeat_ok());
    assert_eq!(s.status().gain, 0.0);
}

#[test]
fn ramp_ends_on_time_with_an_irregular_loop_period() {
    // Steps of 3.7 ms do not line up with the deadline; the fade must still end at
    // deadline + ramp, not one step late.
    let mut s = running(0);
    let end = S + 600 * MS;
    let mut t = S;
    let mut last_nonzero = 0;
    while t < end + 50 * MS {
        let out = s.update(t, -7.0);
        assert!((-7.0..=0.0).contains(&out));
        if out != 0.0 {
            last_nonzero = t;
        }
        t += 3_700;
    }
    assert!(last_nonzero < end, "{last_nonzero} ≥ {end}");
    assert!(last_nonzero + 3_700 >= end - 10, "ramp ended early at {last_nonzero}");
}

#[test]
fn heartbeat_back_mid_ramp_keeps_fading_and_stays_latched() {
    let mut s = running(0);
    let deadline = S + 100 * MS;
    let mut t = S;
    while t <= deadline + 200 * MS {
        s.update(t, 10.0);
        t += MS;
    }
    let mid = s.update(t, 10.0);
    assert!(mid > 5.0 && mid < 7.0, "{mid}");
    // The host is back, sending heartbeats again: the fade goes on to zero regardless.
    let mut prev = mid;
    for _ in 0..1000 {
        t += MS;
        if t % (10 * MS) == 0 {
            s.on_heartbeat(t);
        }
        let out = s.update(t, 10.0);
        assert!(out <= prev);
        prev = out;
    }
    assert_eq!(prev, 0.0);
    assert!(s.heartbeat_ok());
    assert!(s.faults().contains(Faults::HEARTBEAT_LOST), "still latched");

    // Clearing brings the torque back, ramped in linearly over FaultRampTime.
    assert_eq!(s.clear_faults(t), Ok(Faults::HEARTBEAT_LOST));
    assert!(s.faults().is_empty());
    let t_clear = t;
    for _ in 0..600 {
        t += MS;
        if t % (10 * MS) == 0 {
            s.on_heartbeat(t);
        }
        let out = s.update(t, 10.0);
        let want = 10.0 * ((t - t_clear) as f32 / 500_000.0).min(1.0);
        assert!((out - want).abs() <= 1e-4, "t={t}: {out} vs {want}");
    }
}

#[test]
fn clear_is_refused_while_the_heartbeat_is_missing() {
    let mut s = running(0);
    let t = S + 300 * MS;
    s.update(t, 1.0);
    assert_eq!(s.clear_faults(t), Err(ClearError::HeartbeatMissing { since_us: 300 * MS, timeout_us: 100 * MS }));
    assert!(s.faults().contains(Faults::HEARTBEAT_LOST));
    s.on_heartbeat(t + MS);
    assert_eq!(s.clear_faults(t + MS), Ok(Faults::HEARTBEAT_LOST));
}

#[test]
fn clearing_mid_fade_resumes_from_the_current_gain_without_a_step() {
    let mut s = running(0);
    let mut t = S;
    while t <= S + 300 * MS {
        s.update(t, 10.0);
        t += MS;
    }
    s.on_heartbeat(t);
    let before = s.update(t, 10.0);
    s.clear_faults(t).expect("heartbeat present");
    let mut prev = before;
    for _ in 0..600 {
        t += MS;
        if t % (10 * MS) == 0 {
            s.on_heartbeat(t);
        }
        let out = s.update(t, 10.0);
        assert!(out >= prev && out - prev <= 10.0 * 0.002 + 1e-4, "step {prev} → {out}");
        prev = out;
    }
    assert_eq!(prev, 10.0);
}

#[test]
fn no_host_at_all_times_out_from_boot() {
    let mut s = Safety::new(cfg(), 5 * S);
    for k in 0..=100u64 {
        s.update(5 * S + k * MS, 1.0);
    }
    assert!(s.faults().is_empty());
    s.update(5 * S + 101 * MS, 1.0);
    assert_eq!(s.faults(), Faults::HEARTBEAT_LOST);
}

#[test]
fn timeout_zero_disables_the_watchdog() {
    let mut s = Safety::new(SafetyConfig::from_seconds(0.0, 0.2, 50.0), 0);
    let mut out = 0.0;
    for k in 0..100_000u64 {
        out = s.update(k * MS, 3.0);
    }
    assert_eq!(out, 3.0);
    assert!(s.faults().is_empty());
    assert!(s.heartbeat_ok());
    assert_eq!(s.clear_faults(100 * S), Ok(Faults::NONE));
}

#[test]
fn time_going_backwards_counts_as_no_time_and_never_blinds_the_watchdog() {
    let mut s = running(10 * S);
    let out = s.update(11 * S, 4.0); // heartbeat last at 11 s (end of running)
    assert_eq!(out, 4.0);
    // The clock is reset to 2 s (e.g. a timer restart). No time passes for that call...
    assert_eq!(s.update(2 * S, 4.0), 4.0);
    assert_eq!(s.since_heartbeat_us(), 0);
    // ...and the timeout counts from there: it fires 100 ms later, not after 11.1 s.
    assert_eq!(s.update(2 * S + 100 * MS, 4.0), 4.0);
    assert!(s.faults().is_empty());
    s.update(2 * S + 101 * MS, 4.0);
    assert!(s.faults().contains(Faults::HEARTBEAT_LOST));
    // A heartbeat stamped in the past is still a heartbeat.
    s.on_heartbeat(S);
    assert_eq!(s.since_heartbeat_us(), 0);
}

#[test]
fn u64_wrap_around_is_a_small_forward_step() {
    let t0 = u64::MAX - 2 * S; // wraps 2 s in
    let mut s = running(t0);
    let mut t = t0.wrapping_add(S);
    for k in 0..3000 {
        t = t.wrapping_add(MS);
        if k % 10 == 0 {
            s.on_heartbeat(t);
        }
        assert_eq!(s.update(t, 2.0), 2.0, "t={t}");
    }
    assert!(t < 3 * S, "the clock wrapped");
    assert!(s.faults().is_empty());
    // Stop the heartbeats after the wrap: fault after exactly the timeout.
    s.on_heartbeat(t);
    s.update(t + 100 * MS, 2.0);
    assert!(s.faults().is_empty());
    s.update(t + 100 * MS + 1, 2.0);
    assert_eq!(s.faults(), Faults::HEARTBEAT_LOST);
}

#[test]
fn a_stalled_loop_fades_at_once() {
    let mut s = running(0);
    assert_eq!(s.update(S + 10 * S, 10.0), 0.0);
    assert!(s.faults().contains(Faults::HEARTBEAT_LOST));
}

#[test]
fn non_finite_command_gives_zero_at_once_and_latches() {
    let mut s = running(0);
    s.on_heartbeat(S);
    assert_eq!(s.update(S + MS, f32::NAN), 0.0);
    assert!(s.faults().contains(Faults::COMMAND_INVALID));
    // Fading out from there: a later finite command is scaled down, then zero.
    s.on_heartbeat(S + 2 * MS);
    let out = s.update(S + 2 * MS, 10.0);
    assert!(out < 10.0 && out > 9.0, "{out}");
    assert_eq!(s.update(3 * S, 10.0), 0.0);
}

#[test]
fn over_limit_command_is_clamped_and_latched() {
    let mut s = running(0);
    s.on_heartbeat(S);
    let out = s.update(S + MS, 80.0);
    assert!(out <= 50.0 && out > 49.0, "{out}");
    assert!(s.faults().contains(Faults::OVER_TORQUE));
    let out = s.update(S + 2 * MS, -80.0);
    assert!((-50.0..-49.0).contains(&out), "{out}");
    // Exactly at the limit is fine.
    let mut s = running(0);
    s.on_heartbeat(S);
    assert_eq!(s.update(S + MS, -50.0), -50.0);
    assert!(s.faults().is_empty());
}

#[test]
fn a_boot_fault_never_lets_torque_out() {
    let mut s = Safety::new(cfg(), 0);
    s.raise(Faults::PARAMS_CORRUPT);
    for k in 0..2000u64 {
        if k % 10 == 0 {
            s.on_heartbeat(k * MS);
        }
        assert_eq!(s.update(k * MS, 10.0), 0.0);
    }
    assert_eq!(s.clear_faults(2 * S), Ok(Faults::PARAMS_CORRUPT));
    s.on_heartbeat(2 * S);
    assert!(s.update(2 * S + 10 * MS, 10.0) > 0.0);
}

#[test]
fn report_only_faults_do_not_fade() {
    let mut s = running(0);
    s.raise(Faults::CAN_BUS_OFF.union(Faults::LOOP_OVERRUN).union(Faults::STORE_WRITE));
    s.on_heartbeat(S + MS);
    assert_eq!(s.update(S + MS, 10.0), 10.0);
    assert_eq!(s.faults().bits(), (1 << 4) | (1 << 8) | (1 << 7));
    let names: Vec<&str> = s.faults().names().collect();
    assert_eq!(names, ["can_bus_off", "store_write", "loop_overrun"]);
    // A custom stop mask can make them fade.
    let mut c = cfg();
    c.stop_mask = Faults::CAN_BUS_OFF;
    s.configure(c);
    s.on_heartbeat(S + 2 * MS);
    assert!(s.update(S + 2 * MS, 10.0) < 10.0);
}

#[test]
fn zero_ramp_switches_at_once() {
    let mut s = Safety::new(SafetyConfig::from_seconds(0.1, 0.0, 50.0), 0);
    s.on_heartbeat(0);
    assert_eq!(s.update(0, 5.0), 5.0);
    assert_eq!(s.update(100 * MS, 5.0), 5.0);
    assert_eq!(s.update(100 * MS + 1, 5.0), 0.0);
}

#[test]
fn fault_bits_are_stable() {
    // These numbers go over CAN to the host tool: changing them breaks the protocol.
    assert_eq!(Faults::HEARTBEAT_LOST.bits(), 0x0001);
    assert_eq!(Faults::PARAMS_CORRUPT.bits(), 0x0002);
    assert_eq!(Faults::PARAMS_REJECTED.bits(), 0x0004);
    assert_eq!(Faults::PARAMS_VERSION.bits(), 0x0008);
    assert_eq!(Faults::CAN_BUS_OFF.bits(), 0x0010);
    assert_eq!(Faults::OVER_TORQUE.bits(), 0x0020);
    assert_eq!(Faults::COMMAND_INVALID.bits(), 0x0040);
    assert_eq!(Faults::STORE_WRITE.bits(), 0x0080);
    assert_eq!(Faults::LOOP_OVERRUN.bits(), 0x0100);
    assert_eq!(Faults::from_bits_truncate(0xFFFF), Faults::ALL);
    assert_eq!(Faults::ALL.names().count(), 9);
}

#[derive(Clone, Debug)]
enum Ev {
    Update { dt: i64, tau: f32 },
    Heartbeat { dt: i64 },
    Clear,
    Raise(u16),
}

fn ev() -> impl Strategy<Value = Ev> {
    prop_oneof![
        6 => (-2_000i64..20_000, prop_oneof![-100.0f32..100.0, Just(f32::NAN), Just(f32::INFINITY)])
            .prop_map(|(dt, tau)| Ev::Update { dt, tau }),
        3 => (-2_000i64..20_000).prop_map(|dt| Ev::Heartbeat { dt }),
        1 => Just(Ev::Clear),
        1 => any::<u16>().prop_map(Ev::Raise),
    ]
}

proptest! {
    /// Whatever happens: no panic, the output is finite, never larger than the command or the
    /// limit, and never grows while a stop fault is latched.
    #[test]
    fn random_event_sequences_stay_safe(
        t0 in any::<u64>(),
        timeout_ms in 0u32..200,
        ramp_ms in 0u32..300,
        evs in proptest::collection::vec(ev(), 1..300),
    ) {
        let c = SafetyConfig::from_seconds(timeout_ms as f32 * 1e-3, ramp_ms as f32 * 1e-3, 50.0);
        let mut s = Safety::new(c, t0);
        let mut t = t0;
        let mut prev_gain = s.gain();
        for e in evs {
            match e {
                Ev::Update { dt, tau } => {
                    t = t.wrapping_add_signed(dt);
                    let stopping = s.faults().intersects(Faults::DEFAULT_STOP);
                    let out = s.update(t, tau);
                    prop_assert!(out.is_finite());
                    prop_assert!(out.abs() <= 50.0);
                    if tau.is_finite() {
                        prop_assert!(out.abs() <= tau.abs());
                    } else {
                        prop_assert_eq!(out, 0.0);
                    }
                    if stopping {
                        prop_assert!(s.gain() <= prev_gain);
                    }
                    if s.faults().contains(Faults::HEARTBEAT_LOST) && c.ramp_us == 0 {
                        prop_assert_eq!(out, 0.0);
                    }
                }
                Ev::Heartbeat { dt } => {
                    t = t.wrapping_add_signed(dt);
                    s.on_heartbeat(t);
                }
                Ev::Clear => {
                    let had = s.faults();
                    match s.clear_faults(t) {
                        Ok(cleared) => { prop_assert_eq!(cleared, had); prop_assert!(s.faults().is_empty()); }
                        Err(ClearError::HeartbeatMissing { .. }) => prop_assert_eq!(s.faults(), had),
                    }
                }
                Ev::Raise(bits) => s.raise(Faults::from_bits_truncate(bits)),
            }
            let g = s.gain();
            prop_assert!((0.0..=1.0).contains(&g));
            prop_assert!(g * GAIN_ONE as f32 == (g * GAIN_ONE as f32).round());
            prev_gain = g;
        }
    }
}
