//! The two seams between the control loop and the hardware: where the joint angle comes
//! from and where the torque command goes. The loop only sees these traits, so it runs the
//! same against the board's timers, a simulated plant or a test double.
//!
//! Both calls must return within a few microseconds: the loop never waits on I/O.

/// Joint angle source.
pub trait Encoder {
    /// Joint output angle in rad. Errors are reported, not hidden: a failed read makes the
    /// loop hold the output at zero for that step.
    fn position(&mut self) -> Result<f32, EncoderError>;
}

/// Why a position read failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncoderError {
    /// The sensor reported a fault (magnet lost, parity error, index mismatch...).
    Sensor,
    /// The count jumped further in one sample than the joint can physically move.
    Implausible,
}

/// Torque command sink.
pub trait TorqueOutput {
    /// Applies a motor-side torque command in N·m (the core's `u_motor`). Implementations
    /// clamp to what their hardware can do and must treat a non-finite value as zero.
    fn set_motor_torque(&mut self, u_motor: f32);
    /// Removes drive (all switches off). Called on faults and before the loop stops.
    fn disable(&mut self);
}

/// Turns a wrapping 16-bit quadrature counter into an unbounded joint angle.
///
/// A timer in encoder mode counts ±1 per edge and wraps at 2^16; reading it at least once
/// per 32 767 counts keeps the unwrapped total exact. At 10 kHz and a 4096-count encoder
/// that is 80 000 motor revolutions per second, far beyond any joint.
#[derive(Debug, Clone, Copy)]
pub struct QuadratureUnwrap {
    last: u16,
    total: i64,
    rad_per_count: f32,
}

impl QuadratureUnwrap {
    /// `counts_per_motor_rev`: edges per motor revolution (4 × lines for x4 decoding);
    /// `ratio`: gear ratio motor:joint. Both must be positive and finite; otherwise the
    /// scale is zero and every reading is 0 rad, which the caller's checks will notice
    /// as a joint that never moves, rather than a NaN fed into the controller.
    pub fn new(first_count: u16, counts_per_motor_rev: u32, ratio: f32) -> Self {
        Self { last: first_count, total: 0, rad_per_count: Self::scale(counts_per_motor_rev, ratio) }
    }

    fn scale(counts_per_motor_rev: u32, ratio: f32) -> f32 {
        let denom = counts_per_motor_rev as f32 * ratio;
        if joint_core::math::is_finite(denom) && denom > 0.0 {
            2.0 * core::f32::consts::PI / denom
        } else {
            0.0
        }
    }

    /// A new gear ratio was committed (only possible in pre-operational, where no torque
    /// is applied): the counts so far are re-read with it.
    pub fn set_ratio(&mut self, counts_per_motor_rev: u32, ratio: f32) {
        self.rad_per_count = Self::scale(counts_per_motor_rev, ratio);
    }

    /// Feeds the current counter value and returns the joint angle in rad since start.
    pub fn update(&mut self, count: u16) -> f32 {
        // The signed 16-bit difference is the shortest way round the wrap.
        let delta = count.wrapping_sub(self.last) as i16;
        self.last = count;
        self.total = self.total.saturating_add(i64::from(delta));
        self.total as f32 * self.rad_per_count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwraps_across_the_16_bit_boundary_both_ways() {
        // 4 counts per rev, ratio 1: one count is a quarter turn.
        let mut u = QuadratureUnwrap::new(65_534, 4, 1.0);
        let q = u.update(1); // +3 counts through the wrap
        assert!(joint_core::math::abs(q - 3.0 * core::f32::consts::FRAC_PI_2) < 1e-6);
        let q = u.update(65_535); // -2 counts back through the wrap
        assert!(joint_core::math::abs(q - core::f32::consts::FRAC_PI_2) < 1e-6);
    }

    #[test]
    fn gear_ratio_scales_down() {
        let mut u = QuadratureUnwrap::new(0, 4096, 160.0);
        let q = u.update(4096);
        assert!(joint_core::math::abs(q - 2.0 * core::f32::consts::PI / 160.0) < 1e-7);
    }

    #[test]
    fn a_new_ratio_rescales_the_counts_so_far() {
        let mut u = QuadratureUnwrap::new(0, 4, 1.0);
        u.update(2);
        u.set_ratio(4, 2.0);
        // 2 counts of 4 per motor turn, 2 motor turns per joint turn: a quarter joint turn.
        assert!(joint_core::math::abs(u.update(2) - core::f32::consts::FRAC_PI_2) < 1e-7);
    }

    #[test]
    fn bad_scale_gives_zero_not_nan() {
        let mut u = QuadratureUnwrap::new(0, 0, 160.0);
        assert_eq!(u.update(100), 0.0);
        let mut u = QuadratureUnwrap::new(0, 4096, f32::NAN);
        assert_eq!(u.update(100), 0.0);
    }
}
