//! Thin hardware adapters, and what each one honestly does. Shared by the board images: the
//! G0B1 crate includes this file by path; each board's `hal` module names the timers and the
//! flash page size, its `main` the pins. The pins below are the B-G431B-ESC1's.
//!
//! - [`QeiEncoder`]: TIM4 in x4 quadrature mode on PB6/PB7 (the board's encoder/Hall
//!   connector J8, A+ and B+), unwrapped to a joint angle with [`QuadratureUnwrap`].
//!   No index pulse, no absolute reference: angle 0 is wherever the joint was at boot.
//! - [`HBridgeTorque`]: TIM1 at 20 kHz, centre-aligned, complementary outputs with dead
//!   time on phase legs U (PA8/PC13) and V (PA9/PA12), driven as a bipolar H-bridge for a
//!   BRUSHED DC motor across U–V: duty_U = ½ + ½·x, duty_V = ½ − ½·x with
//!   x = u_motor / `full_scale_nm`. This is open-loop voltage proportional to the torque
//!   command: no current loop, no commutation. A BLDC motor needs a FOC current loop in
//!   its place (not part of this firmware yet). Phase W stays off.
//! - [`ParamFlash`]: the last flash pages (memory.x's PARAMS region): the core's `Region` window
//!   over embassy's blocking flash driver (`embedded-storage` `NorFlash`), for the core's
//!   power-loss-safe store.
//!
//! Pin choices follow ST's UM2516 (B-G431B-ESC1 user manual); check them against the
//! board revision's schematic before driving a motor.

use crate::hal::{EncoderTimer as TIM4, PwmTimer as TIM1};
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::timer::complementary_pwm::ComplementaryPwm;
use embassy_stm32::timer::qei::Qei;
use embassy_stm32::timer::Channel;
use firmware::io::{Encoder, EncoderError, QuadratureUnwrap, TorqueOutput};
use joint_core::math;
use joint_core::store::NorFlash;

/// Quadrature encoder on TIM4.
pub struct QeiEncoder {
    qei: Qei<'static, TIM4>,
    unwrap: QuadratureUnwrap,
}

impl QeiEncoder {
    pub fn new(qei: Qei<'static, TIM4>, counts_per_motor_rev: u32, ratio: f32) -> Self {
        let first = qei.count();
        QeiEncoder { qei, unwrap: QuadratureUnwrap::new(first, counts_per_motor_rev, ratio) }
    }
}

impl QeiEncoder {
    /// A new gear ratio was committed: rescale (see [`QuadratureUnwrap::set_ratio`]).
    pub fn set_ratio(&mut self, counts_per_motor_rev: u32, ratio: f32) {
        self.unwrap.set_ratio(counts_per_motor_rev, ratio);
    }
}

impl Encoder for QeiEncoder {
    fn position(&mut self) -> Result<f32, EncoderError> {
        // A bare A/B encoder has no fault signal; reading the counter cannot fail.
        Ok(self.unwrap.update(self.qei.count()))
    }
}

/// Brushed-DC H-bridge on TIM1 phases U and V (see the module doc for its limits).
pub struct HBridgeTorque {
    pwm: ComplementaryPwm<'static, TIM1>,
    max_duty: u32,
    /// Motor torque at 100 % duty, N·m (motor constant × stall current at supply voltage).
    full_scale_nm: f32,
    enabled: bool,
}

impl HBridgeTorque {
    pub fn new(mut pwm: ComplementaryPwm<'static, TIM1>, full_scale_nm: f32) -> Self {
        let max_duty = pwm.get_max_duty();
        // ~500 ns dead time at 170 MHz timer clock (DTG = 85 counts), so the high and low
        // switches of a leg never conduct together.
        pwm.set_dead_time(85);
        let mut s = HBridgeTorque { pwm, max_duty, full_scale_nm, enabled: false };
        s.disable();
        s
    }

    fn duty(&self, fraction: f32) -> u32 {
        (math::clamp(fraction, 0.0, 1.0) * self.max_duty as f32) as u32
    }
}

impl TorqueOutput for HBridgeTorque {
    fn set_motor_torque(&mut self, u_motor: f32) {
        let x = if math::is_finite(u_motor) && self.full_scale_nm > 0.0 {
            math::clamp(u_motor / self.full_scale_nm, -1.0, 1.0)
        } else {
            0.0
        };
        let du = self.duty(0.5 + 0.5 * x);
        let dv = self.duty(0.5 - 0.5 * x);
        self.pwm.set_duty(Channel::Ch1, du);
        self.pwm.set_duty(Channel::Ch2, dv);
        if !self.enabled {
            self.pwm.enable(Channel::Ch1);
            self.pwm.enable(Channel::Ch2);
            self.enabled = true;
        }
    }

    fn disable(&mut self) {
        self.pwm.set_duty(Channel::Ch1, 0);
        self.pwm.set_duty(Channel::Ch2, 0);
        self.pwm.disable(Channel::Ch1);
        self.pwm.disable(Channel::Ch2);
        self.pwm.disable(Channel::Ch3);
        self.enabled = false;
    }
}

extern "C" {
    // From memory.x: the parameter region at the end of flash.
    static __param_start: u8;
    static __param_end: u8;
}

/// Start of the flash in the address map; embassy's flash driver takes offsets from here.
pub const FLASH_BASE: u32 = 0x0800_0000;

/// The parameter pages (memory.x's PARAMS region) of the chip's flash: the core's generic window
/// ([`joint_core::store::Region`]) over embassy's blocking driver, which implements
/// `embedded-storage`'s `NorFlash` as every HAL's flash does. No board adapter of its own.
pub type ParamFlash = joint_core::store::Region<Flash<'static, Blocking>>;

// The driver's erase unit is the page memory.x's `__param_page_size` and the board's `hal` give.
const _: () = assert!(<Flash<'static, Blocking> as NorFlash>::ERASE_SIZE == crate::hal::PARAM_PAGE);

/// The parameter window of `flash`, from memory.x's symbols.
pub fn param_flash(flash: Flash<'static, Blocking>) -> ParamFlash {
    // Only the addresses of the linker symbols are taken, never their contents.
    let (start, end) = (&raw const __param_start as u32, &raw const __param_end as u32);
    joint_core::store::Region::new(flash, start.wrapping_sub(FLASH_BASE), end.saturating_sub(start))
}
