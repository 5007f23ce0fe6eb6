//! The joint model file (spec §2), written and read with serde, and the torque its terms
//! state. Only the sections and keys of spec §2 that a plain joint uses exist here: the
//! struct refuses anything else on reading, so a test can prove we never write more.
//!
//! The same evaluator gives the true joint's own terms and the file's terms: the withheld
//! effect is always something added on top (see `effects`) or a difference between the
//! true and the file's term values, never a change of what a term means.

use serde::{Deserialize, Serialize};

/// `a·qd·|qd| + b·qd + c·sign(qd)`, sign banded when `v_band` is present.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub a: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub b: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v_band: Option<f64>,
}

/// `amplitude·sin(s·q + phi)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weight {
    pub amplitude: f64,
    pub s: f64,
    pub phi: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inertia {
    pub j: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Offset {
    pub c0: f64,
}

/// `k·(q − q0) + b·qd`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spring {
    pub k: f64,
    pub b: f64,
    pub q0: f64,
}

/// A joint model as spec §2 writes it (the subset a single joint without tables uses).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<Friction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weight: Option<Weight>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia: Option<Inertia>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<Offset>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spring: Option<Spring>,
}

/// How `sign(qd)` is read: spec §2 says a file without `v_band` means exactly `sign`,
/// with `sign(0) = 0`; with a band it is `clamp(qd/v_band, −1, 1)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SignLaw {
    Pure,
    Band(f64),
}

impl SignLaw {
    pub fn of(self, v: f64) -> f64 {
        match self {
            SignLaw::Pure => sgn(v),
            SignLaw::Band(vb) => (v / vb).clamp(-1.0, 1.0),
        }
    }
}

/// sign with sign(0) = 0 (rest phases of the truth have qd exactly 0).
pub fn sgn(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl ModelFile {
    pub fn sign_law(&self) -> SignLaw {
        match self.friction.and_then(|f| f.v_band) {
            Some(vb) if vb > 0.0 => SignLaw::Band(vb),
            _ => SignLaw::Pure,
        }
    }

    pub fn j(&self) -> f64 {
        self.inertia.map_or(0.0, |i| i.j)
    }

    /// The Coulomb level c (0 when the file has none).
    pub fn c(&self) -> f64 {
        self.friction.and_then(|f| f.c).unwrap_or(0.0)
    }

    /// The viscous coefficient b of the friction section (0 when absent).
    pub fn b(&self) -> f64 {
        self.friction.and_then(|f| f.b).unwrap_or(0.0)
    }

    /// Velocity terms that are smooth in qd: a·qd|qd| + b·qd + spring damping.
    pub fn smooth_friction(&self, v: f64) -> f64 {
        let f = self.friction.unwrap_or_default();
        let damping = self.spring.map_or(0.0, |s| s.b);
        f.a.unwrap_or(0.0) * v * v.abs() + f.b.unwrap_or(0.0) * v + damping * v
    }

    /// c·sign(qd) under the file's sign law.
    pub fn coulomb(&self, v: f64) -> f64 {
        self.c() * self.sign_law().of(v)
    }

    /// Position terms: weight, offset and the spring's elastic part.
    pub fn position_terms(&self, q: f64) -> f64 {
        let w = self.weight.map_or(0.0, |w| w.amplitude * (w.s * q + w.phi).sin());
        let o = self.offset.map_or(0.0, |o| o.c0);
        let k = self.spring.map_or(0.0, |s| s.k * (q - s.q0));
        w + o + k
    }

    /// The disturbance the file's terms state: J·qdd + friction + weight + offset + spring.
    pub fn torque(&self, q: f64, qd: f64, qdd: f64) -> f64 {
        self.j() * qdd + self.smooth_friction(qd) + self.coulomb(qd) + self.position_terms(q)
    }

    pub fn to_toml(&self) -> anyhow::Result<String> {
        Ok(toml::to_string(self)?)
    }
}
