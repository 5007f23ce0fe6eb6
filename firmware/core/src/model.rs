//! The compensation models, each a small value type with the paper's formula.
//!
//! - friction, trunk paper eq. 3: `a·q̇|q̇| + b·q̇ + c·sign(q̇)`, with sign() smoothed inside a
//!   velocity band so a noisy zero velocity does not chatter between ±c;
//! - weight, trunk paper eq. 4: `C_w0·sin(s·q + φ)`;
//! - spring-damper, elastic-joint paper eq. 1–2: `K·(q − q0) + B·q̇`;
//! - inertia `J·q̈` and constant offset `C_0` (trunk paper eq. 2, 5).
//!
//! All are odd/even in the way the physics says and finite for inputs inside [`INPUT_LIMITS`]
//! with parameters inside the parameter table's ranges.

use crate::math;

/// Plausibility bounds the control step clamps its inputs to before any model sees them. With
/// every parameter inside its table range no intermediate can overflow an f32.
pub struct InputLimits {
    pub q: f32,
    pub qd: f32,
    pub qdd: f32,
}

pub const INPUT_LIMITS: InputLimits = InputLimits { q: 1.0e3, qd: 1.0e3, qdd: 1.0e6 };

/// Friction polynomial (trunk paper eq. 3). All coefficients are ≥ 0 (checked by the parameter
/// table), so the torque is odd in q̇ and grows monotonically with |q̇|.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Friction {
    /// N·m·s²/rad²
    pub a: f32,
    /// N·m·s/rad
    pub b: f32,
    /// Coulomb level, N·m
    pub c: f32,
    /// half-width of the band where sign() is linear, rad/s (0 = hard sign)
    pub v_band: f32,
}

impl Friction {
    #[inline]
    pub fn torque(&self, qd: f32) -> f32 {
        self.a * qd * math::abs(qd) + self.b * qd + self.c * math::sign_smooth(qd, self.v_band)
    }
}

/// Unbalanced weight (trunk paper eq. 4).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Weight {
    /// C_w0, N·m
    pub amplitude: f32,
    /// s, 1 (q in rad)
    pub s: f32,
    /// φ, rad
    pub phi: f32,
}

impl Weight {
    #[inline]
    pub fn torque(&self, q: f32) -> f32 {
        self.amplitude * math::sin(self.s * q + self.phi)
    }
}

/// Spring-damper of an elastic joint (elastic-joint paper eq. 1–2).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spring {
    /// N·m/rad
    pub k: f32,
    /// N·m·s/rad
    pub b: f32,
    /// rest angle, rad
    pub q0: f32,
}

impl Spring {
    #[inline]
    pub fn torque(&self, q: f32, qd: f32) -> f32 {
        self.k * (q - self.q0) + self.b * qd
    }
}

/// The rigid-body and transmission terms of the joint model, copied out of a validated
/// parameter set so the control step reads plain fields.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terms {
    pub friction: Friction,
    pub weight: Weight,
    pub spring: Spring,
    /// apparent inertia at the joint output, kg·m²
    pub j: f32,
    /// constant torque offset C_0, N·m
    pub c0: f32,
    /// effect terms a diagnosis can add (Stribeck, asymmetric and dry friction, position
    /// ripple, cable spring)
    pub extra: Extra,
}

impl Terms {
    /// Torque of the effect terms; 0 without any (one branch on the hot path).
    #[inline]
    pub fn extra_torque(&self, q: f32, qd: f32) -> f32 {
        if self.extra.any {
            self.extra.torque(q, qd, math::sign_smooth(qd, self.friction.v_band))
        } else {
            0.0
        }
    }
}

/// The effect terms of the spec's vocabulary that a joint can compensate by feed-forward,
/// with the same formulas as host-sim's plant (`host-sim/sim/src/effects.rs`):
/// - Stribeck: `level·exp(−(q̇/speed)²)·sgn`;
/// - asymmetric friction: `delta·|sgn|` (Coulomb c + delta forward, c − delta backward);
/// - position ripple: `amplitude·sin(2π·q/period + phase)`;
/// - cable spring: 0 below `engage`, `k·x²/(2·width)` in the blend, `k·(x − width/2)` above,
///   `x = q − engage`;
/// - dry friction: `c·sgn`.
///
/// Load-dependent friction, thermal drift, backlash and delay are not here: the first two need
/// a measured load torque or temperature the loop does not have, the last two change the
/// plant's structure rather than add a torque (see the README).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Extra {
    /// any term non-zero
    pub any: bool,
    pub stribeck_level: f32,
    pub stribeck_inv_speed: f32,
    pub asym_delta: f32,
    pub ripple_amplitude: f32,
    /// 2π/period
    pub ripple_k: f32,
    pub ripple_phase: f32,
    pub cable_k: f32,
    pub cable_engage: f32,
    pub cable_width: f32,
    pub dry_c: f32,
}

impl Extra {
    /// Sum of the terms, `sgn` the smoothed sign of q̇. Kept out of line: inlined, its
    /// registers cost the common step (no effect terms) about ten instructions.
    #[inline(never)]
    pub fn torque(&self, q: f32, qd: f32, sgn: f32) -> f32 {
        let r = qd * self.stribeck_inv_speed;
        let stribeck = self.stribeck_level * math::exp(-(r * r)) * sgn;
        let asym = self.asym_delta * math::abs(sgn);
        let ripple = self.ripple_amplitude * math::sin(self.ripple_k * q + self.ripple_phase);
        let x = q - self.cable_engage;
        let cable = if x <= 0.0 {
            0.0
        } else if x < self.cable_width {
            self.cable_k * x * x / (2.0 * self.cable_width)
        } else {
            self.cable_k * (x - 0.5 * self.cable_width)
        };
        stribeck + asym + ripple + cable + self.dry_c * sgn
    }
}
