//! The unmodelled effects a plant can have (the vocabulary of spec §3), each a TOML section of
//! the plant file with the parameters a later diagnosis reports under the same names.
//!
//! Notation: `sgn(v)` is the plant's smoothed sign, `tanh(v/ε)` with the plant's sign band ε
//! (see [`crate::plant`]); q, q̇ are the output angle and velocity, u the actuator torque at the
//! output, T the temperature. A torque listed here is added to the plant's disturbance D in
//! `J·q̈ = u + τ_ext − D` (so it opposes motion when positive along q̇).
//!
//! | section | keys | torque / behaviour |
//! |---|---|---|
//! | `[stribeck]` | `level` N·m, `speed` rad/s | `level·exp(−(q̇/speed)²)·sgn(q̇)` |
//! | `[asymmetric_friction]` | `delta` N·m | Coulomb level `c+delta` for q̇>0 and `c−delta` for q̇<0, i.e. `+delta·|sgn(q̇)|` |
//! | `[load_dependent_friction]` | `mu` (1) | `mu·|τ_ext|·sgn(q̇)`: the external load the joint transmits (what its load cell logs as `tau`) |
//! | `[thermal_drift]` | `coefficient` 1/°C, `t_ambient` °C, `rise` °C, `time_constant` s, `t_ref` °C, `log_temp` (bool, default true) | the plant's own friction `a·q̇|q̇| + b·q̇ + c·sgn(q̇)` is multiplied by `1 + coefficient·(T − t_ref)` with `T(t) = t_ambient + rise·(1 − e^(−t/time_constant))`; the log gets a `temp` column unless `log_temp = false` |
//! | `[position_ripple]` | `amplitude` N·m, `period` rad, `phase` rad (default 0), `amplitude_2` N·m and `phase_2` rad (default 0) | `amplitude·sin(2π·q/period + phase) + amplitude_2·sin(4π·q/period + phase_2)` |
//! | `[cable_spring]` | `k` N·m/rad, `engage` rad, `width` rad (default 0.01) | with `x = q − engage`: 0 for x ≤ 0, `k·x²/(2·width)` for 0 < x < width, `k·(x − width/2)` above: exactly zero below `engage`, slope exactly `k` above `engage + width`, C¹ in between |
//! | `[backlash]` | `width` rad (total), `output_inertia_share` (default 0.1) | a dead zone of total width `width`: with a spring in the plant (`[spring] k ≠ 0`, elastic joint) the spring force becomes `k·dz(q − q0)` (the damper `b·q̇` stays); without a spring the transmission is split in two masses, see [`crate::plant`] |
//! | `[delay]` | `seconds` s | sensors (q, qd, qdd, tau, others) are seen and logged `seconds` after the state they measure; the controller sees the same late sensors; u is logged when it is applied |
//! | `[dry_friction]` | `c` N·m | `c·sgn(q̇)`; in a plant with `[presliding]` its level joins the Dahl state instead (see [`crate::plant`]) |
//!
//! `dz(x) = x − w/2` for `x > w/2`, `x + w/2` for `x < −w/2`, `0` inside.

use joint_formats::vocab::Effect;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Stribeck {
    pub level: f64,
    pub speed: f64,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AsymmetricFriction {
    pub delta: f64,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadDependentFriction {
    pub mu: f64,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ThermalDrift {
    pub coefficient: f64,
    pub t_ambient: f64,
    pub rise: f64,
    pub time_constant: f64,
    pub t_ref: f64,
    #[serde(default = "yes")]
    pub log_temp: bool,
}

fn yes() -> bool {
    true
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PositionRipple {
    pub amplitude: f64,
    pub period: f64,
    #[serde(default)]
    pub phase: f64,
    /// second harmonic (period/2)
    #[serde(default)]
    pub amplitude_2: f64,
    #[serde(default)]
    pub phase_2: f64,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CableSpring {
    pub k: f64,
    pub engage: f64,
    #[serde(default = "cable_width")]
    pub width: f64,
}

fn cable_width() -> f64 {
    0.01
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    pub width: f64,
    #[serde(default = "inertia_share")]
    pub output_inertia_share: f64,
}

fn inertia_share() -> f64 {
    0.1
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Delay {
    pub seconds: f64,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DryFriction {
    pub c: f64,
}

/// All effect sections of one plant file; `None` = effect absent. Each field is read from (and
/// written as) the TOML section of its name, which is the vocabulary's section of the effect
/// ([`Effects::section`] maps the two; a test checks every name).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
pub struct Effects {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stribeck: Option<Stribeck>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub asymmetric_friction: Option<AsymmetricFriction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_dependent_friction: Option<LoadDependentFriction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal_drift: Option<ThermalDrift>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_ripple: Option<PositionRipple>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cable_spring: Option<CableSpring>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backlash: Option<Backlash>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay: Option<Delay>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dry_friction: Option<DryFriction>,
}

/// A parameter of an effect that makes no physical sense.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("[{section}] {key} = {value}: {why}")]
pub struct EffectError {
    pub section: &'static str,
    pub key: &'static str,
    pub value: f64,
    pub why: &'static str,
}

fn need(section: &'static str, key: &'static str, value: f64, ok: bool, why: &'static str) -> Result<(), EffectError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(EffectError { section, key, value, why })
    }
}

impl Effects {
    /// The plant's section of vocabulary entry `e` as its keys and values (defaults filled in),
    /// or `None` when the plant does not have the effect. The match names every entry of the
    /// vocabulary, so a term added there does not compile here until the plant says whether it
    /// simulates it: whatever lists a plant's effects (the closed-loop workflow's truth, the
    /// true-parameter model) follows from this.
    pub fn section(&self, e: Effect) -> Option<toml::Table> {
        fn table<T: Serialize>(x: &Option<T>) -> Option<toml::Table> {
            x.as_ref().and_then(|v| toml::Table::try_from(v).ok())
        }
        match e {
            Effect::Stribeck => table(&self.stribeck),
            Effect::AsymmetricFriction => table(&self.asymmetric_friction),
            Effect::LoadDependentFriction => table(&self.load_dependent_friction),
            Effect::ThermalDrift => table(&self.thermal_drift),
            Effect::PositionRipple => table(&self.position_ripple),
            Effect::CableSpring => table(&self.cable_spring),
            Effect::Backlash => table(&self.backlash),
            Effect::Delay => table(&self.delay),
            Effect::DryFriction => table(&self.dry_friction),
            // a section of the model, which the plant runs through its model (see crate::plant)
            Effect::PreslidingHysteresis => None,
            // verdicts, no term
            Effect::Parameters | Effect::InitialState | Effect::None | Effect::Unexplained => None,
        }
    }

    /// The vocabulary's effect terms this plant has, in the vocabulary's order.
    pub fn present(&self) -> impl Iterator<Item = Effect> + '_ {
        Effect::terms().filter(|&e| self.section(e).is_some())
    }

    /// Refuses values that would make the plant meaningless (negative widths, zero speeds…).
    pub fn check(&self) -> Result<(), EffectError> {
        if let Some(e) = &self.stribeck {
            need("stribeck", "level", e.level, true, "must be finite")?;
            need("stribeck", "speed", e.speed, e.speed > 0.0, "must be > 0 rad/s")?;
        }
        if let Some(e) = &self.asymmetric_friction {
            need("asymmetric_friction", "delta", e.delta, true, "must be finite")?;
        }
        if let Some(e) = &self.load_dependent_friction {
            need("load_dependent_friction", "mu", e.mu, e.mu >= 0.0, "must be ≥ 0")?;
        }
        if let Some(e) = &self.thermal_drift {
            need("thermal_drift", "coefficient", e.coefficient, true, "must be finite")?;
            need("thermal_drift", "t_ambient", e.t_ambient, true, "must be finite")?;
            need("thermal_drift", "rise", e.rise, true, "must be finite")?;
            need("thermal_drift", "time_constant", e.time_constant, e.time_constant > 0.0, "must be > 0 s")?;
            need("thermal_drift", "t_ref", e.t_ref, true, "must be finite")?;
        }
        if let Some(e) = &self.position_ripple {
            need("position_ripple", "amplitude", e.amplitude, true, "must be finite")?;
            need("position_ripple", "period", e.period, e.period > 0.0, "must be > 0 rad")?;
            need("position_ripple", "phase", e.phase, true, "must be finite")?;
            need("position_ripple", "amplitude_2", e.amplitude_2, true, "must be finite")?;
            need("position_ripple", "phase_2", e.phase_2, true, "must be finite")?;
        }
        if let Some(e) = &self.cable_spring {
            need("cable_spring", "k", e.k, e.k >= 0.0, "must be ≥ 0")?;
            need("cable_spring", "engage", e.engage, true, "must be finite")?;
            need("cable_spring", "width", e.width, e.width > 0.0, "must be > 0 rad")?;
        }
        if let Some(e) = &self.backlash {
            need("backlash", "width", e.width, e.width >= 0.0, "must be ≥ 0 rad")?;
            let s = e.output_inertia_share;
            need("backlash", "output_inertia_share", s, s > 0.0 && s < 1.0, "must lie in (0, 1)")?;
        }
        if let Some(e) = &self.delay {
            need("delay", "seconds", e.seconds, (0.0..=1.0).contains(&e.seconds), "must lie in [0, 1] s")?;
        }
        if let Some(e) = &self.dry_friction {
            need("dry_friction", "c", e.c, e.c >= 0.0, "must be ≥ 0")?;
        }
        Ok(())
    }

    /// Temperature at plant time `t` (°C), if the plant has thermal drift.
    pub fn temperature(&self, t: f64) -> Option<f64> {
        self.thermal_drift.as_ref().map(|e| e.t_ambient + e.rise * (1.0 - (-t / e.time_constant).exp()))
    }

    /// Factor on the plant's own friction at time `t` (1 without thermal drift).
    pub fn friction_scale(&self, t: f64) -> f64 {
        match (&self.thermal_drift, self.temperature(t)) {
            (Some(e), Some(temp)) => 1.0 + e.coefficient * (temp - e.t_ref),
            _ => 1.0,
        }
    }

    /// Sum of the additive effect torques (everything except thermal scaling, backlash and
    /// delay, which change the plant's structure). `sgn` is the plant's smoothed sign of q̇.
    /// `load`: the external torque the joint transmits (a load-dependent friction grows with it).
    pub fn torque(&self, q: f64, qd: f64, load: f64, sgn: f64) -> f64 {
        let tau = self.torque_without_dry(q, qd, load, sgn);
        match &self.dry_friction {
            Some(e) => tau + e.c * sgn,
            None => tau,
        }
    }

    /// [`Effects::torque`] without `[dry_friction]`, whose level a Dahl state carries in a plant
    /// with `[presliding]`.
    pub fn torque_without_dry(&self, q: f64, qd: f64, load: f64, sgn: f64) -> f64 {
        let mut tau = 0.0;
        if let Some(e) = &self.stribeck {
            let r = qd / e.speed;
            tau += e.level * (-r * r).exp() * sgn;
        }
        if let Some(e) = &self.asymmetric_friction {
            tau += e.delta * sgn.abs();
        }
        if let Some(e) = &self.load_dependent_friction {
            tau += e.mu * load.abs() * sgn;
        }
        if let Some(e) = &self.position_ripple {
            let x = std::f64::consts::TAU * q / e.period;
            tau += e.amplitude * (x + e.phase).sin() + e.amplitude_2 * (2.0 * x + e.phase_2).sin();
        }
        if let Some(e) = &self.cable_spring {
            tau += cable_spring(e, q);
        }
        tau
    }

    /// Sum of the Coulomb-like levels (N·m) that multiply `sgn(q̇)`; the plant uses it to keep
    /// its smoothed sign numerically stable.
    pub fn coulomb_levels(&self, u_max: f64) -> f64 {
        let mut c = 0.0;
        if let Some(e) = &self.stribeck {
            c += e.level.abs();
        }
        if let Some(e) = &self.asymmetric_friction {
            c += e.delta.abs();
        }
        if let Some(e) = &self.load_dependent_friction {
            c += e.mu * u_max;
        }
        if let Some(e) = &self.dry_friction {
            c += e.c;
        }
        c
    }
}

/// The cable-spring torque (see the module table).
pub fn cable_spring(e: &CableSpring, q: f64) -> f64 {
    let x = q - e.engage;
    if x <= 0.0 {
        0.0
    } else if x < e.width {
        e.k * x * x / (2.0 * e.width)
    } else {
        e.k * (x - e.width / 2.0)
    }
}

/// Dead zone of total width `w` centred on 0.
pub fn dead_zone(x: f64, w: f64) -> f64 {
    let h = w / 2.0;
    if x > h {
        x - h
    } else if x < -h {
        x + h
    } else {
        0.0
    }
}
