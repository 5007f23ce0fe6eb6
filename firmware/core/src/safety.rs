//! Heartbeat watchdog, torque fade and the latched fault word.
//!
//! The control loop passes every torque command through [`Safety::update`] last, after the
//! controller's own torque and rate limits. When the host's heartbeat has been missing for
//! longer than `HeartbeatTimeout`, or when any other fault of the stop mask is latched (a
//! corrupt parameter store at boot, a non-finite or over-limit command), the output is faded
//! linearly to zero within `FaultRampTime` and stays at zero until the host clears the faults
//! with [`Safety::clear_faults`] while its heartbeat is present. Clearing fades the torque back
//! in over the same time, so neither a fault nor its acknowledgement is a torque step.
//!
//! Design choices, and why:
//! - **Latching**: a heartbeat that comes back mid-fade does not bring the torque back; the
//!   fade continues to zero. A flaky link must not make the joint pulse, and the operator must
//!   see (and acknowledge) that the host was gone.
//! - **Scaling, not freezing**: the output is `gain · τ_cmd` with `gain` falling linearly from
//!   its current value to 0. The compensation keeps tracking the joint's own sensors during the
//!   fade instead of holding a stale torque while the joint moves.
//! - **Soft start**: the gain starts at 0 at boot and rises over `FaultRampTime` when no stop
//!   fault is latched, so a fault raised right after boot (e.g. the store's) never lets a burst
//!   of torque out first.
//! - **Integer ramp**: the gain is an integer in `0..=GAIN_ONE` moved by `dt·GAIN_ONE/ramp`
//!   per update with the remainder carried, so after a fade of `t` µs it is exactly
//!   `1 − floor(t·GAIN_ONE/ramp)/GAIN_ONE`: it reaches 0 exactly `FaultRampTime` after the
//!   fault (never one step late through float round-off), and reconfiguring the ramp time
//!   mid-fade keeps the gain continuous.
//! - **Virtual time**: time is a `u64` of microseconds passed in by the caller; nothing sleeps.
//!   Time that goes backwards counts as no time passing (the heartbeat age is kept as an
//!   accumulated age, not as a timestamp, so a clock reset cannot blind the watchdog for
//!   longer than it was already counting), and `u64` wrap-around is handled by wrapping
//!   subtraction. A huge forward jump (a stalled loop) times out and fades at once — the safe
//!   side.
//!
//! Cost per [`Safety::update`] in steady state (no fault, full gain): a handful of integer
//! compares and one float clamp; a `u64` division only while the gain is moving.

use crate::math;

/// Latched fault bits, reported to the host as a `u16` (e.g. in an EMCY frame or a status
/// object). A small hand-written bitflags type: the core has no dependency for it.
#[derive(Clone, Copy, PartialEq, Eq, Default, Debug, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Faults(u16);

impl Faults {
    /// No fault.
    pub const NONE: Faults = Faults(0);
    /// The host heartbeat was missing for longer than `HeartbeatTimeout`.
    pub const HEARTBEAT_LOST: Faults = Faults(1 << 0);
    /// The parameter store held no valid record but was not blank (damaged, interrupted
    /// first save, or foreign data): defaults are in use.
    pub const PARAMS_CORRUPT: Faults = Faults(1 << 1);
    /// The stored parameter set was intact but failed `params::check()`: defaults are in use.
    pub const PARAMS_REJECTED: Faults = Faults(1 << 2);
    /// The stored parameter set was written in a format this firmware cannot read (a newer
    /// firmware wrote it, or its table does not fit): defaults are in use, the record is kept.
    pub const PARAMS_VERSION: Faults = Faults(1 << 3);
    /// The CAN controller went bus-off (reported; recovery is the CAN task's job).
    pub const CAN_BUS_OFF: Faults = Faults(1 << 4);
    /// A torque command beyond `TorqueLimit` reached the safety layer (the controller limits
    /// its output, so this means a bug or a corrupted command): clamped and faded out.
    pub const OVER_TORQUE: Faults = Faults(1 << 5);
    /// A non-finite (NaN/∞) torque command reached the safety layer: output 0 at once.
    pub const COMMAND_INVALID: Faults = Faults(1 << 6);
    /// Saving the parameters to flash failed (the previous stored set is still intact).
    pub const STORE_WRITE: Faults = Faults(1 << 7);
    /// The control loop missed its deadline.
    pub const LOOP_OVERRUN: Faults = Faults(1 << 8);

    /// Every bit defined above.
    pub const ALL: Faults = Faults(0x01FF);

    /// The faults that fade the torque to zero unless the caller configures otherwise
    /// ([`SafetyConfig::stop_mask`]). Bus-off, overrun and a failed save are reported only:
    /// the heartbeat covers a host that cannot reach us, and a late loop or a failed save does
    /// not make the torque wrong.
    pub const DEFAULT_STOP: Faults = Faults(
        Self::HEARTBEAT_LOST.0
            | Self::PARAMS_CORRUPT.0
            | Self::PARAMS_REJECTED.0
            | Self::PARAMS_VERSION.0
            | Self::OVER_TORQUE.0
            | Self::COMMAND_INVALID.0,
    );

    const NAMES: [(&'static str, Faults); 9] = [
        ("heartbeat_lost", Self::HEARTBEAT_LOST),
        ("params_corrupt", Self::PARAMS_CORRUPT),
        ("params_rejected", Self::PARAMS_REJECTED),
        ("params_version", Self::PARAMS_VERSION),
        ("can_bus_off", Self::CAN_BUS_OFF),
        ("over_torque", Self::OVER_TORQUE),
        ("command_invalid", Self::COMMAND_INVALID),
        ("store_write", Self::STORE_WRITE),
        ("loop_overrun", Self::LOOP_OVERRUN),
    ];

    /// The raw bits, as sent to the host.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// From raw bits; unknown bits are dropped.
    pub const fn from_bits_truncate(bits: u16) -> Faults {
        Faults(bits & Self::ALL.0)
    }
    /// No bit set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Every bit of `other` is set in `self`.
    pub const fn contains(self, other: Faults) -> bool {
        self.0 & other.0 == other.0
    }
    /// At least one bit of `other` is set in `self`.
    pub const fn intersects(self, other: Faults) -> bool {
        self.0 & other.0 != 0
    }
    /// Bits set in either.
    pub const fn union(self, other: Faults) -> Faults {
        Faults(self.0 | other.0)
    }
    /// Bits set in both.
    pub const fn intersection(self, other: Faults) -> Faults {
        Faults(self.0 & other.0)
    }
    /// Bits of `self` not in `other`.
    pub const fn difference(self, other: Faults) -> Faults {
        Faults(self.0 & !other.0)
    }
    /// Set the bits of `other`.
    pub fn insert(&mut self, other: Faults) {
        self.0 |= other.0;
    }
    /// Clear the bits of `other`.
    pub fn remove(&mut self, other: Faults) {
        self.0 &= !other.0;
    }
    /// The snake_case names of the set bits (for logs and the host tool), in bit order.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES.into_iter().filter(move |(_, f)| self.contains(*f)).map(|(n, _)| n)
    }
}

/// Fixed-point one for the output gain. `2^24` and every integer below it are exact in `f32`,
/// so the gain converts to a float without rounding.
pub const GAIN_ONE: u32 = 1 << 24;

/// Timing and limits of the safety layer, usually built from the validated parameter set
/// with [`SafetyConfig::from_params`].
#[derive(Clone, Copy, PartialEq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyConfig {
    /// Heartbeat timeout in µs; 0 disables the heartbeat watchdog.
    pub heartbeat_timeout_us: u64,
    /// Time for a full fade (gain 1 → 0 or 0 → 1) in µs; 0 switches at once.
    pub ramp_us: u64,
    /// Largest |τ| accepted from the controller, N·m (`f32::INFINITY` for none).
    pub torque_limit: f32,
    /// Which latched faults fade the torque to zero.
    pub stop_mask: Faults,
}

impl SafetyConfig {
    /// From seconds, as the parameter table stores them. Negative or NaN times count as 0
    /// (watchdog off / immediate switch); the parameter check keeps them out anyway.
    pub fn from_seconds(heartbeat_timeout_s: f32, ramp_time_s: f32, torque_limit: f32) -> Self {
        SafetyConfig {
            heartbeat_timeout_us: seconds_to_us(heartbeat_timeout_s),
            ramp_us: seconds_to_us(ramp_time_s),
            torque_limit,
            stop_mask: Faults::DEFAULT_STOP,
        }
    }

    /// `HeartbeatTimeout`, `FaultRampTime` and `TorqueLimit` of a validated set.
    pub fn from_params(p: &crate::params::ParamSet) -> Self {
        use crate::params::ParamId;
        Self::from_seconds(p.get(ParamId::HeartbeatTimeout), p.get(ParamId::FaultRampTime), p.get(ParamId::TorqueLimit))
    }
}

/// Seconds to whole microseconds, rounded to nearest. `as` saturates (∞ → `u64::MAX`) and
/// maps NaN to 0, so this never panics.
fn seconds_to_us(s: f32) -> u64 {
    if s > 0.0 {
        (s * 1.0e6 + 0.5) as u64
    } else {
        0
    }
}

/// Why [`Safety::clear_faults`] refused.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ClearError {
    /// The heartbeat is still missing: faults can only be cleared by a host that is there.
    HeartbeatMissing {
        /// Age of the last heartbeat (or of boot, if none came yet), µs.
        since_us: u64,
        /// The configured timeout, µs.
        timeout_us: u64,
    },
}

/// A snapshot for status reports.
#[derive(Clone, Copy, PartialEq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyStatus {
    /// Latched faults.
    pub faults: Faults,
    /// Output gain in `[0, 1]`.
    pub gain: f32,
    /// The heartbeat is present (or the watchdog is disabled).
    pub heartbeat_ok: bool,
}

/// The watchdog and fault latch. One instance, owned by the control loop.
#[derive(Clone, Debug)]
pub struct Safety {
    cfg: SafetyConfig,
    /// Time of the last call that passed a timestamp.
    last_now_us: u64,
    /// Age of the last heartbeat (counted from construction until the first one), µs.
    since_heartbeat_us: u64,
    faults: Faults,
    /// Faults latched since the last [`Safety::take_new_faults`].
    new_faults: Faults,
    /// Time advanced but not yet applied to the gain, µs.
    pending_us: u64,
    /// Remainder of the last gain step's division (see `step_for`), and its direction.
    ramp_rem: u64,
    ramp_down: bool,
    /// Output gain, `0..=GAIN_ONE`.
    gain: u32,
}

impl Safety {
    /// A fresh watchdog at boot time `now_us`: no faults, gain 0 rising (soft start), the
    /// heartbeat timeout counting from now (a host that never appears times out too).
    pub fn new(cfg: SafetyConfig, now_us: u64) -> Self {
        let mut s = Safety {
            cfg,
            last_now_us: now_us,
            since_heartbeat_us: 0,
            faults: Faults::NONE,
            new_faults: Faults::NONE,
            pending_us: 0,
            ramp_rem: 0,
            ramp_down: false,
            gain: 0,
        };
        if cfg.ramp_us == 0 {
            s.gain = GAIN_ONE;
        }
        s
    }

    /// Replace timing and limits (e.g. after a new parameter set was committed). The gain and
    /// the latched faults are kept; a fade in progress continues at the new rate.
    pub fn configure(&mut self, cfg: SafetyConfig) {
        self.cfg = cfg;
        self.ramp_rem = 0;
    }

    /// The configuration in force.
    pub fn config(&self) -> &SafetyConfig {
        &self.cfg
    }

    /// Advance the clock to `now_us`. Backwards steps count as zero; `wrapping_sub` keeps a
    /// `u64` wrap-around a small forward step. The elapsed time ages the heartbeat at once and
    /// is banked for the gain, which only [`Safety::settle`] moves.
    fn advance(&mut self, now_us: u64) {
        let dt = now_us.wrapping_sub(self.last_now_us);
        self.last_now_us = now_us;
        if dt > u64::MAX / 2 {
            // Went backwards (no real clock runs 2^63 µs between two calls).
            return;
        }
        self.since_heartbeat_us = self.since_heartbeat_us.saturating_add(dt);
        self.pending_us = self.pending_us.saturating_add(dt);
    }

    /// Detect a heartbeat timeout and move the gain by the banked time. Called before
    /// anything that changes the state the fade depends on (heartbeat, clear) and by every
    /// update, so no time is lost or counted twice whatever the order of calls.
    fn settle(&mut self) {
        let dt = core::mem::take(&mut self.pending_us);
        // A stop fault that was already latched owns the whole `dt`; a heartbeat that expired
        // inside this `dt` owns only the time since its deadline, so the torque reaches zero
        // exactly `FaultRampTime` after `last heartbeat + timeout`, whatever the loop period.
        let stopping_before = self.faults.intersects(self.cfg.stop_mask);
        let mut fade_dt = dt;
        if self.heartbeat_missing() && !self.faults.contains(Faults::HEARTBEAT_LOST) {
            self.latch(Faults::HEARTBEAT_LOST);
            if !stopping_before {
                let overdue = self.since_heartbeat_us - self.cfg.heartbeat_timeout_us;
                fade_dt = dt.min(overdue);
            }
        }
        if self.faults.intersects(self.cfg.stop_mask) {
            let step = self.step_for(fade_dt, true);
            self.gain = self.gain.saturating_sub(step);
        } else {
            let step = self.step_for(dt, false);
            self.gain = self.gain.saturating_add(step).min(GAIN_ONE);
        }
    }

    fn heartbeat_missing(&self) -> bool {
        self.cfg.heartbeat_timeout_us != 0 && self.since_heartbeat_us > self.cfg.heartbeat_timeout_us
    }

    fn latch(&mut self, f: Faults) {
        self.new_faults.insert(f.difference(self.faults));
        self.faults.insert(f);
    }

    /// A heartbeat from the host arrived at `now_us`. Cheap: callable from any task that has
    /// the `Safety` (or forward the event to the loop's owner).
    /// A heartbeat that comes after the timeout has expired still latches the loss.
    pub fn on_heartbeat(&mut self, now_us: u64) {
        self.advance(now_us);
        self.settle();
        self.since_heartbeat_us = 0;
    }

    /// Latch a fault detected elsewhere (store at boot, CAN bus-off, loop overrun). If it is in
    /// the stop mask the fade starts with the next [`Safety::update`].
    pub fn raise(&mut self, f: Faults) {
        self.latch(Faults::from_bits_truncate(f.bits()));
    }

    /// Gain step for `dt` µs in direction `down`: `dt·GAIN_ONE/ramp` with the division's
    /// remainder carried to the next step, so the gain after any sequence of steps is exactly
    /// `floor(total time · GAIN_ONE / ramp)` — no drift, whatever the loop period.
    fn step_for(&mut self, dt: u64, down: bool) -> u32 {
        if down != self.ramp_down {
            self.ramp_down = down;
            self.ramp_rem = 0;
        }
        let ramp = self.cfg.ramp_us;
        if ramp == 0 || dt >= ramp {
            self.ramp_rem = 0;
            return GAIN_ONE;
        }
        // dt < ramp and rem < ramp, so the quotient is at most GAIN_ONE. The product
        // overflows only for ramps beyond ~12 days; saturating then gives a slower fade,
        // never a panic.
        let num = dt.saturating_mul(u64::from(GAIN_ONE)).saturating_add(self.ramp_rem);
        self.ramp_rem = num % ramp;
        u32::try_from(num / ramp).unwrap_or(GAIN_ONE)
    }

    /// Pass the controller's torque command `tau_cmd` (N·m) at time `now_us` through the
    /// watchdog; returns the torque to apply. Never panics; returns exactly `0.0` while the
    /// output is faded out or the command is not finite.
    pub fn update(&mut self, now_us: u64, tau_cmd: f32) -> f32 {
        self.advance(now_us);

        // Command sanity first, so a fault found here fades from this very update.
        let mut tau = tau_cmd;
        if !math::is_finite(tau) {
            self.latch(Faults::COMMAND_INVALID);
            tau = 0.0;
        } else if math::abs(tau) > self.cfg.torque_limit {
            self.latch(Faults::OVER_TORQUE);
            tau = math::clamp(tau, -self.cfg.torque_limit, self.cfg.torque_limit);
        }
        self.settle();

        if self.gain == 0 {
            0.0
        } else if self.gain >= GAIN_ONE {
            tau
        } else {
            tau * (self.gain as f32 / GAIN_ONE as f32)
        }
    }

    /// Clear every latched fault, refused while the heartbeat is missing. The torque then
    /// fades back in over `FaultRampTime` from wherever the gain is. Returns the bits that
    /// were cleared. A fault whose cause persists (bus-off, say) must be raised again by its
    /// owner.
    pub fn clear_faults(&mut self, now_us: u64) -> Result<Faults, ClearError> {
        self.advance(now_us);
        self.settle();
        if self.heartbeat_missing() {
            return Err(ClearError::HeartbeatMissing {
                since_us: self.since_heartbeat_us,
                timeout_us: self.cfg.heartbeat_timeout_us,
            });
        }
        let cleared = self.faults;
        self.faults = Faults::NONE;
        self.new_faults = Faults::NONE;
        Ok(cleared)
    }

    /// Latched faults.
    pub fn faults(&self) -> Faults {
        self.faults
    }

    /// Faults latched since the previous call (to send one EMCY per new fault).
    pub fn take_new_faults(&mut self) -> Faults {
        core::mem::take(&mut self.new_faults)
    }

    /// Output gain in `[0, 1]`.
    pub fn gain(&self) -> f32 {
        self.gain as f32 / GAIN_ONE as f32
    }

    /// Age of the last heartbeat as of the latest call, µs (since construction if none yet).
    pub fn since_heartbeat_us(&self) -> u64 {
        self.since_heartbeat_us
    }

    /// The heartbeat is present (or the watchdog is disabled), as of the latest call.
    pub fn heartbeat_ok(&self) -> bool {
        !self.heartbeat_missing()
    }

    /// Everything a status report needs.
    pub fn status(&self) -> SafetyStatus {
        SafetyStatus { faults: self.faults, gain: self.gain(), heartbeat_ok: self.heartbeat_ok() }
    }
}
