//! The compensation models, each a small value type with the paper's formula.
//!
//! - friction, trunk paper eq. 3: `a·q̇|q̇| + b·q̇ + c·sign(q̇)`, with sign() smoothed inside a
//!   velocity band so a noisy zero velocity does not chatter between ±c;
//! - weight, trunk paper eq. 4: `C_w0·sin(s·q + φ)`;
//! - spring-damper, elastic-joint paper eq. 1–2: `K·(q − q0) + B·q̇`;
//! - inertia `J·q̈` and constant offset `C_0` (trunk paper eq. 2, 5);
//! - pre-sliding (Dahl) friction, [`Presliding`]: with `presliding.sigma > 0` a state F replaces
//!   the Coulomb terms `(c + c_dry)·sign(q̇)`, `dF/dq = σ·(1 − F/c·sign(dq))`, `|F| ≤ c`.
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
    /// measured load torque, N·m (read only by the load-dependent friction, which limits it)
    pub tau: f32,
}

pub const INPUT_LIMITS: InputLimits = InputLimits { q: 1.0e3, qd: 1.0e3, qdd: 1.0e6, tau: 1.0e4 };

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

    /// The velocity terms alone, `a·q̇|q̇| + b·q̇`: the friction left when a Dahl state stands
    /// in for the Coulomb term.
    #[inline]
    pub fn viscous(&self, qd: f32) -> f32 {
        self.a * qd * math::abs(qd) + self.b * qd
    }
}

/// Pre-sliding (Dahl) friction: a state F, carried between steps, in place of the Coulomb
/// terms `c·sign(q̇)` of the friction polynomial and of `[dry_friction]` (sign band included).
///
/// F evolves over the travelled angle, `dF/dq = σ·(1 − F/c·sign(dq))`: after a reversal the
/// friction builds up over a pre-sliding distance of about `c/σ` instead of jumping with
/// sign(q̇), and a small oscillation inside that distance meets a spring of stiffness σ, not a
/// ±c square wave. Between two samples the travel `Δq` is taken as monotone and the equation
/// solved exactly ([`Presliding::advance`]): an exponential approach to `c·sign(Δq)`, so
/// `|F| ≤ c` for any step size. Stribeck, asymmetric friction and the velocity terms keep
/// their sign-based form.
///
/// The level c is the model's whole Coulomb level, `friction.c + dry_friction.c`: both are the
/// same physical torque (the diagnosis emits `[dry_friction]` for a model that lacks
/// `friction.c`), and a Dahl state beside a remaining `c_dry·sign(q̇)` would still jump at
/// every reversal.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Presliding {
    /// `presliding.sigma > 0`: the Dahl state replaces the Coulomb terms
    pub on: bool,
    /// Coulomb level c = friction.c + dry_friction.c, N·m
    pub c: f32,
    /// σ/c, 1/rad (the inverse of the pre-sliding distance); 0 when c = 0
    pub k: f32,
}

impl Presliding {
    /// From the parameters: stiffness σ (N·m/rad), Coulomb level c (N·m).
    pub fn new(sigma: f32, c: f32) -> Self {
        // c/σ under ~1e-45 rad makes k infinite: exp(−∞) = 0, F jumps to ±c (still bounded).
        Presliding { on: sigma > 0.0, c, k: if c > 0.0 { sigma / c } else { 0.0 } }
    }

    /// F after a travel `dq` from F = `f`: the exact solution of `dF/dq = σ·(1 − F/c·sign(dq))`
    /// over a monotone `dq`, `F' = F + (c·sign(dq) − F)·(1 − exp(−σ|dq|/c))` (written with
    /// `expm1`, so a tiny step keeps its increment's precision), limited to `[−c, c]` (which it
    /// can leave only by a rounding, or when c shrank under F). `dq = 0` keeps F. A NaN `dq`
    /// gives −c (the limit's NaN rule); the controller never passes one.
    #[inline]
    pub fn advance(&self, f: f32, dq: f32) -> f32 {
        let c = self.c;
        let moved = if dq == 0.0 {
            f
        } else {
            let target = math::copysign(c, dq);
            f - (target - f) * math::expm1(-(self.k * math::abs(dq)))
        };
        math::clamp(moved, -c, c)
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
// 8-aligned, as the table's `Lut`: the parameter set in front of both grows by 4 bytes with
// each appended parameter, and the soft-float step (M0+) measured 3 to 7 instructions apart
// between the two alignments (scripts/fw-bench.sh); aligned, a new term no longer moves them.
#[repr(align(8))]
pub struct Terms {
    pub friction: Friction,
    pub weight: Weight,
    pub spring: Spring,
    /// apparent inertia at the joint output, kg·m²
    pub j: f32,
    /// constant torque offset C_0, N·m
    pub c0: f32,
    /// the effect terms of the vocabulary the joint compensates ([`Extra`])
    pub extra: Extra,
    /// the Dahl friction state's parameters (off unless `presliding.sigma > 0`)
    pub presliding: Presliding,
}

impl Terms {
    /// Torque of the effect terms at (q, q̇) with the measured load `load` (N·m, the joint's
    /// load cell); 0 without any (one branch on the hot path).
    #[inline]
    pub fn extra_torque(&self, q: f32, qd: f32, load: f32) -> f32 {
        if self.extra.any {
            self.extra.torque(q, qd, math::sign_smooth(qd, self.friction.v_band), load)
        } else {
            0.0
        }
    }
}

/// The effect terms of the spec's vocabulary that a joint can compensate by feed-forward,
/// with the same formulas as host-sim's plant (`host-sim/sim/src/effects.rs`):
/// - Stribeck: `level·exp(−(q̇/speed)²)·sgn`;
/// - asymmetric friction: `delta·|sgn|` (Coulomb c + delta forward, c − delta backward);
/// - position ripple: `amplitude·sin(2π·q/period + phase) + amplitude_2·sin(4π·q/period + phase_2)`;
/// - cable spring: 0 below `engage`, `k·x²/(2·width)` in the blend, `k·(x − width/2)` above,
///   `x = q − engage`;
/// - dry friction: `c·sgn`;
/// - load-dependent friction: `mu·|τ_load|·sgn`, τ_load the measured load ([`INPUT_LIMITS`]
///   bounds it; a non-finite one counts as no load).
///
/// Thermal drift, backlash and delay are not here: the first needs a temperature the loop does
/// not have, the last two change the plant's structure rather than add a torque (see the
/// README).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Extra {
    /// any term non-zero (dry friction counted only outside a Dahl state)
    pub any: bool,
    pub stribeck_level: f32,
    pub stribeck_inv_speed: f32,
    pub asym_delta: f32,
    pub ripple_amplitude: f32,
    /// 2π/period
    pub ripple_k: f32,
    pub ripple_phase: f32,
    /// the ripple's second harmonic (period/2)
    pub ripple_amplitude_2: f32,
    pub ripple_phase_2: f32,
    pub cable_k: f32,
    pub cable_engage: f32,
    pub cable_width: f32,
    /// the dry friction level outside a Dahl state: `dry_friction.c`, or 0 with presliding on
    /// (the level has moved into [`Presliding::c`])
    pub dry_c: f32,
    /// load-dependent friction: the share of the measured load that is friction
    pub load_mu: f32,
}

impl Extra {
    /// Sum of the terms, `sgn` the smoothed sign of q̇, `load` the measured load (N·m). Kept
    /// out of line: inlined, its registers cost the common step (no effect terms) about ten
    /// instructions.
    #[inline(never)]
    #[cold]
    pub fn torque(&self, q: f32, qd: f32, sgn: f32, load: f32) -> f32 {
        let r = qd * self.stribeck_inv_speed;
        let stribeck = self.stribeck_level * math::exp(-(r * r)) * sgn;
        let asym = self.asym_delta * math::abs(sgn);
        let mut ripple = self.ripple_amplitude * math::sin(self.ripple_k * q + self.ripple_phase);
        if self.ripple_amplitude_2 != 0.0 {
            ripple += self.ripple_amplitude_2 * math::sin(2.0 * self.ripple_k * q + self.ripple_phase_2);
        }
        let x = q - self.cable_engage;
        let cable = if x <= 0.0 {
            0.0
        } else if x < self.cable_width {
            self.cable_k * x * x / (2.0 * self.cable_width)
        } else {
            self.cable_k * (x - 0.5 * self.cable_width)
        };
        // |τ_load| within the input limit; NaN or ±∞ (a failed load cell) is no load
        let load = if math::is_finite(load) { math::clamp(math::abs(load), 0.0, INPUT_LIMITS.tau) } else { 0.0 };
        stribeck + asym + ripple + cable + self.dry_c * sgn + self.load_mu * load * sgn
    }
}
