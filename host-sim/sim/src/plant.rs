//! The simulated joint ("truth"), written independently of the core, in f64.
//!
//! A plant file is a model TOML (spec §2) plus optional sections: one per unmodelled effect (see
//! [`crate::effects`]), `[sensors]`, `[joint_range]` and `[operator]`. The dynamics are
//!
//! `J·q̈ = u + τ_ext − D(q, q̇, u, t)`,
//! `D = s(t)·(a·q̇|q̇| + b·q̇ + c·sgn(q̇)) + C_w0·sin(s·q + φ) + C_0 + K·(q − q0) + B·q̇ + table(q, …) + effects`
//!
//! with u the actuator torque at the output and τ_ext the torque of the environment/operator.
//! The load cell measures `tau = −τ_ext`, so the spec's disturbance `d = u − tau = J·q̈ + D`
//! holds exactly in a noise-free plant without effects.
//!
//! Sign smoothing: `sgn(v) = clamp(v/ε, −1, 1)` — the same shape as the core's friction band —
//! with ε the plant's own `[friction] v_band` (default of the parameter table), raised if needed
//! to `2·C·dt/J` (C all Coulomb-like levels, dt the integration step) so the stiff slope c/ε
//! stays well inside RK4's stability region. Near rest this acts as a very stiff viscous
//! damper: an unbalanced joint creeps at `|q̇| < ε` instead of sticking exactly.
//!
//! Pre-sliding friction (`[presliding] sigma > 0`, spec §2): the Coulomb terms `c·sgn(q̇)` of
//! `[friction]` and of a `[dry_friction]` effect become one Dahl state F of level
//! `c_D = s(t)·c + c_dry` (thermal drift scales the joint's own Coulomb level as it does
//! without the state), `dF/dq = σ·(1 − F/c_D·sign(dq))`, so
//! `D = s(t)·(a·q̇|q̇| + b·q̇) + F + …`. F is part of the [`State`]: RK4 integrates q and q̇
//! with F held over the fine step, then F is advanced in closed form over the step's travel
//! (`F → T + (F − T)·e^(−σ|Δq|/c_D)`, `T = c_D·sign(Δq)`), which keeps `|F| ≤ c_D` whatever the
//! step. The fine step's travel is tiny against a pre-sliding distance, so holding F for one
//! step costs nothing measurable; near a reversal F acts as a spring of stiffness up to 2σ,
//! whose period stays far above the plant step for any joint this simulator is given.
//! This is the plant's own f64 code; it shares nothing with the core's state.
//!
//! Backlash without a spring splits the inertia into a motor side `J_m = (1 − r)·J` and an output
//! side `J_o = r·J` (r = `output_inertia_share`): `J_m·q̈_m = u − τ_c`, `J_o·q̈ = τ_c + τ_ext − D`,
//! with the contact torque `τ_c = k_c·dz(q_m − q) + c_c·(q̇_m − q̇)` only while in contact (and
//! never pulling), `k_c`, `c_c` chosen for a 0.7-damped contact mode at plant_rate/40 so RK4
//! resolves it. The logged q is the output side.

use joint_formats::vocab::Effect;
use std::path::Path;

use serde::Deserialize;

use crate::effects::{self, Effects};
use joint_core::params::ParamId;
use joint_formats::model_file::{GravityTableToml, ModelError, ModelFile, Section};

/// Sensor models; every value is a standard deviation (white Gaussian) unless said otherwise.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    /// angle noise, rad
    #[serde(default)]
    pub q_noise: f64,
    /// encoder quantum, rad (0 = continuous)
    #[serde(default)]
    pub q_resolution: f64,
    /// velocity sensor noise, rad/s
    #[serde(default)]
    pub qd_noise: f64,
    /// acceleration estimate noise, rad/s² (logged qdd = true q̈ + this noise)
    #[serde(default)]
    pub qdd_noise: f64,
    /// load-cell torque noise, N·m
    #[serde(default)]
    pub tau_noise: f64,
    /// actuator torque measurement noise, N·m (the applied torque is the command)
    #[serde(default)]
    pub u_noise: f64,
    /// temperature noise, °C
    #[serde(default)]
    pub temp_noise: f64,
}

/// Joint range the scenarios move in, rad.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JointRange {
    pub min: f64,
    pub max: f64,
}

/// Operator impedance for the `hand` and `free` scenarios (default: derived from the plant).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OperatorCfg {
    /// N·m/rad
    pub stiffness: f64,
    /// N·m·s/rad
    pub damping: f64,
}

/// The plant's own sections (its effects, sensors, range, operator); the model sections of the
/// same file are read by [`ModelFile::parse_except`], which leaves these to this struct.
#[derive(Clone, Debug, Default, serde::Deserialize)]
struct PlantToml {
    #[serde(flatten)]
    effects: Effects,
    #[serde(default)]
    sensors: Option<Sensors>,
    #[serde(default)]
    joint_range: Option<JointRange>,
    #[serde(default)]
    operator: Option<OperatorCfg>,
}

/// The sections [`PlantToml`] reads (the rest of a plant file is its model): every effect term
/// of the vocabulary but the pre-sliding state (a model section the plant runs through the
/// model), and the plant's own sensors, range and operator.
fn plant_section(s: &str) -> bool {
    matches!(s, "sensors" | "joint_range" | "operator")
        || Effect::from_section(s).is_some_and(|e| e != Effect::PreslidingHysteresis)
}

/// A parsed plant file.
#[derive(Clone, Debug, PartialEq)]
pub struct PlantFile {
    pub model: ModelFile,
    pub effects: Effects,
    pub sensors: Sensors,
    pub range: Option<JointRange>,
    pub operator: Option<OperatorCfg>,
}

impl PlantFile {
    pub fn read_file(path: &Path) -> Result<PlantFile, ModelError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|e| ModelError::Io { file: file.clone(), msg: e.to_string() })?;
        Self::parse(&text, &file)
    }

    pub fn parse(text: &str, file: &str) -> Result<PlantFile, ModelError> {
        let model = ModelFile::parse_except(text, file, &plant_section)?;
        let t: PlantToml =
            toml::from_str(text).map_err(|e| ModelError::Toml { file: file.to_string(), msg: e.to_string() })?;
        if model.series.is_some() {
            return Err(ModelError::Toml {
                file: file.to_string(),
                msg:
                    "[gravity_series] is a model term the plant does not simulate (give the truth as a [gravity_table])"
                        .into(),
            });
        }
        // The model part must be a valid parameter set too (ranges, table shape).
        model.param_set()?;
        let effects = t.effects;
        let err = |msg: String| ModelError::Toml { file: file.to_string(), msg };
        effects.check().map_err(|e| err(e.to_string()))?;
        let sensors = t.sensors.unwrap_or_default();
        for (k, v) in [
            ("q_noise", sensors.q_noise),
            ("q_resolution", sensors.q_resolution),
            ("qd_noise", sensors.qd_noise),
            ("qdd_noise", sensors.qdd_noise),
            ("tau_noise", sensors.tau_noise),
            ("u_noise", sensors.u_noise),
            ("temp_noise", sensors.temp_noise),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(err(format!("[sensors] {k} = {v}: must be finite and ≥ 0")));
            }
        }
        if let Some(r) = &t.joint_range {
            if !(r.min.is_finite() && r.max.is_finite() && r.max > r.min) {
                return Err(err(format!(
                    "[joint_range] min = {}, max = {}: need finite min < max (rad)",
                    r.min, r.max
                )));
            }
        }
        if let Some(o) = &t.operator {
            if !(o.stiffness.is_finite() && o.stiffness > 0.0 && o.damping.is_finite() && o.damping >= 0.0) {
                return Err(err("[operator] stiffness must be > 0 and damping ≥ 0".into()));
            }
        }
        if model.value(ParamId::InertiaJ) <= 0.0 {
            return Err(err("[inertia] j must be > 0 in a plant (it is the simulated mass)".into()));
        }
        Ok(PlantFile { model, effects, sensors, range: t.joint_range, operator: t.operator })
    }
}

/// The gravity table of the truth, evaluated in f64 (multilinear, clamped at the grid edge).
#[derive(Clone, Debug)]
struct PlantTable {
    /// per axis: 0 = own q, 1.. = other joint slot
    sources: Vec<usize>,
    grid: Vec<Vec<f64>>,
    torque: Vec<f64>,
    sigma: Option<Vec<f64>>,
}

impl PlantTable {
    // Indexing is in bounds: the table's shape (axes = grid rows, ≥ 2 points each, values =
    // product of points) was validated when the file was read (ModelFile::raw_table + check).
    #[allow(clippy::indexing_slicing)]
    fn eval(values: &[f64], grid: &[Vec<f64>], x: &[f64]) -> f64 {
        // Multilinear interpolation: sum over the 2^n corners of the cell containing x.
        let n = grid.len();
        let mut lo = vec![0usize; n];
        let mut frac = vec![0.0; n];
        for a in 0..n {
            let g = &grid[a];
            let xa = x[a].clamp(g[0], g[g.len() - 1]);
            let mut i = 0;
            while i + 2 < g.len() && xa > g[i + 1] {
                i += 1;
            }
            lo[a] = i;
            frac[a] = (xa - g[i]) / (g[i + 1] - g[i]);
        }
        let mut sum = 0.0;
        for corner in 0..(1usize << n) {
            let mut w = 1.0;
            let mut idx = 0usize;
            for a in 0..n {
                let bit = (corner >> a) & 1;
                w *= if bit == 1 { frac[a] } else { 1.0 - frac[a] };
                idx = idx * grid[a].len() + lo[a] + bit;
            }
            sum += w * values[idx];
        }
        sum
    }
}

/// Two-mass transmission (backlash without a spring).
#[derive(Clone, Debug)]
struct TwoMass {
    jm: f64,
    jo: f64,
    k: f64,
    c: f64,
    width: f64,
}

/// The plant's state: output angle/velocity, with a two-mass transmission the motor side, and
/// the Dahl friction state (N·m; stays 0 without `[presliding]`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    pub q: f64,
    pub qd: f64,
    pub qm: f64,
    pub qdm: f64,
    pub dahl: f64,
}

impl State {
    /// At rest at angle q (both sides of a two-mass transmission), no friction state.
    pub fn at_rest(q: f64) -> State {
        State { q, qd: 0.0, qm: q, qdm: 0.0, dahl: 0.0 }
    }
}

/// The environment's torque on the output over one control period: an impedance toward a
/// reference (the operator's hand), zero when `k = b = 0`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Operator {
    pub k: f64,
    pub b: f64,
    pub q_ref: f64,
    pub qd_ref: f64,
}

impl Operator {
    pub fn torque(&self, q: f64, qd: f64) -> f64 {
        self.k * (self.q_ref - q) + self.b * (self.qd_ref - qd)
    }
}

/// The simulated joint.
#[derive(Clone, Debug)]
pub struct Plant {
    a: f64,
    b: f64,
    c: f64,
    amp: f64,
    s: f64,
    phi: f64,
    pub j: f64,
    c0: f64,
    k: f64,
    kb: f64,
    q0: f64,
    table: Option<PlantTable>,
    sigma_model: f64,
    clamp_k: f64,
    pub effects: Effects,
    /// sign smoothing band actually used, rad/s
    pub band: f64,
    two_mass: Option<TwoMass>,
    spring_backlash: Option<f64>,
    /// pre-sliding stiffness σ, N·m/rad (0: the Coulomb terms are c·sgn(q̇))
    dahl_sigma: f64,
    /// the dry friction effect's level, part of the Dahl level when σ > 0
    dahl_dry: f64,
    pub dt: f64,
}

impl Plant {
    /// Builds the truth from a plant file for integration step `dt`; `u_max` bounds the
    /// actuator torque (for the load-dependent friction's stability margin).
    pub fn new(pf: &PlantFile, dt: f64, u_max: f64) -> Plant {
        let m = &pf.model;
        let v = |id| m.value(id);
        let table = m.table.as_ref().map(|t| {
            let others = m.other_columns();
            PlantTable {
                sources: t
                    .axes
                    .iter()
                    .map(|a| if a == "q" { 0 } else { 1 + others.iter().position(|o| o == a).unwrap_or(0) })
                    .collect(),
                grid: t.grid.clone(),
                torque: t.torque.clone(),
                sigma: t.sigma.clone(),
            }
        });
        let j = v(ParamId::InertiaJ);
        let k = v(ParamId::SpringK);
        let e = pf.effects.clone();
        let (two_mass, spring_backlash) = match &e.backlash {
            Some(bl) if k > 0.0 => (None, Some(bl.width)),
            Some(bl) => {
                let jo = bl.output_inertia_share * j;
                let jm = j - jo;
                let jr = jm * jo / j;
                let w = std::f64::consts::TAU / dt / 40.0;
                (Some(TwoMass { jm, jo, k: jr * w * w, c: 2.0 * 0.7 * w * jr, width: bl.width }), None)
            }
            None => (None, None),
        };
        let c = v(ParamId::FrictionC);
        let dahl_sigma = v(ParamId::PreslidingSigma);
        let dahl_dry = e.dry_friction.as_ref().map_or(0.0, |d| d.c);
        let thermal_max = e
            .thermal_drift
            .as_ref()
            .map(|t| 1.0 + t.coefficient.abs() * ((t.t_ambient - t.t_ref).abs() + t.rise.abs()))
            .unwrap_or(1.0);
        // The levels that go through sgn(q̇): with a Dahl state, c and the dry friction do not.
        let c_tot = if dahl_sigma > 0.0 {
            e.coulomb_levels(u_max) - dahl_dry
        } else {
            c * thermal_max + e.coulomb_levels(u_max)
        };
        let j_min = two_mass.as_ref().map(|t| t.jo).unwrap_or(j);
        let band = v(ParamId::FrictionVBand).max(2.0 * c_tot * dt / j_min);
        Plant {
            a: v(ParamId::FrictionA),
            b: v(ParamId::FrictionB),
            c,
            amp: v(ParamId::WeightAmplitude),
            s: v(ParamId::WeightS),
            phi: v(ParamId::WeightPhi),
            j,
            c0: v(ParamId::OffsetC0),
            k,
            kb: v(ParamId::SpringB),
            q0: v(ParamId::SpringQ0),
            table,
            sigma_model: v(ParamId::TableSigmaModel),
            clamp_k: v(ParamId::TableClampK),
            effects: e,
            band,
            two_mass,
            spring_backlash,
            dahl_sigma,
            dahl_dry,
            dt,
        }
    }

    /// The plant has a Dahl friction state (`[presliding] sigma > 0`).
    pub fn has_presliding(&self) -> bool {
        self.dahl_sigma > 0.0
    }

    /// The Dahl state's level at plant time `t`, N·m.
    fn dahl_level(&self, t: f64) -> f64 {
        self.effects.friction_scale(t) * self.c + self.dahl_dry
    }

    /// The Dahl state `f` after a travel `dq` at plant time `t` (closed form, see the module
    /// documentation).
    fn dahl_after(&self, t: f64, f: f64, dq: f64) -> f64 {
        let level = self.dahl_level(t).max(0.0);
        if level == 0.0 {
            return 0.0;
        }
        let moved = if dq == 0.0 {
            f
        } else {
            let target = level * dq.signum();
            target + (f - target) * (-self.dahl_sigma * dq.abs() / level).exp()
        };
        moved.clamp(-level, level)
    }

    /// The plant's smoothed sign: the rule the joint's friction band follows (the core's, in
    /// f64), with the plant's own band. Only the rule is shared: the plant's effect torques are
    /// its own code.
    pub fn sgn(&self, v: f64) -> f64 {
        joint_core::math::sign_smooth_f64(v, self.band)
    }

    /// Weight plus gravity table (or their fusion when `sigma_model > 0`).
    fn gravity(&self, q: f64, others: &[f64]) -> f64 {
        let w = self.amp * (self.s * q + self.phi).sin();
        let Some(t) = &self.table else { return w };
        let x: Vec<f64> =
            t.sources.iter().map(|&s| if s == 0 { q } else { others.get(s - 1).copied().unwrap_or(0.0) }).collect();
        let tt = PlantTable::eval(&t.torque, &t.grid, &x);
        match (&t.sigma, self.sigma_model > 0.0) {
            (Some(sig), true) => {
                let st = PlantTable::eval(sig, &t.grid, &x);
                let (vm, vd) = (self.sigma_model * self.sigma_model, st * st);
                let fused = w + (tt - w) * vm / (vm + vd);
                let band = (self.clamp_k * self.sigma_model).abs();
                fused.clamp(w - band, w + band)
            }
            _ => w + tt,
        }
    }

    /// The disturbance D at plant time `t` (everything the output side's mechanics take), with
    /// the Dahl friction state `x.dahl` when the plant has one. `load`: the external torque the
    /// joint transmits (what its load cell measures), which a load-dependent friction grows with.
    pub fn disturbance(&self, t: f64, x: &State, load: f64, others: &[f64]) -> f64 {
        let (q, qd) = (x.q, x.qd);
        let sg = self.sgn(qd);
        let spring_x = match self.spring_backlash {
            Some(w) => effects::dead_zone(q - self.q0, w),
            None => q - self.q0,
        };
        let (friction, effects) = if self.has_presliding() {
            let viscous = self.a * qd * qd.abs() + self.b * qd;
            (self.effects.friction_scale(t) * viscous + x.dahl, self.effects.torque_without_dry(q, qd, load, sg))
        } else {
            let friction = self.a * qd * qd.abs() + self.b * qd + self.c * sg;
            (self.effects.friction_scale(t) * friction, self.effects.torque(q, qd, load, sg))
        };
        friction + self.gravity(q, others) + self.c0 + self.k * spring_x + self.kb * qd + effects
    }

    /// Time derivative of the state (the Dahl state's is 0: it moves with travel, in [`Plant::step`]).
    pub fn deriv(&self, t: f64, x: &State, u: f64, op: &Operator, others: &[f64]) -> State {
        let ext = op.torque(x.q, x.qd);
        let d = self.disturbance(t, x, ext, others);
        match &self.two_mass {
            None => State { q: x.qd, qd: (u + ext - d) / self.j, qm: x.qd, qdm: (u + ext - d) / self.j, dahl: 0.0 },
            Some(tm) => {
                let gap = x.qm - x.q;
                let dz = effects::dead_zone(gap, tm.width);
                let tc = if dz > 0.0 {
                    (tm.k * dz + tm.c * (x.qdm - x.qd)).max(0.0)
                } else if dz < 0.0 {
                    (tm.k * dz + tm.c * (x.qdm - x.qd)).min(0.0)
                } else {
                    0.0
                };
                State { q: x.qd, qd: (tc + ext - d) / tm.jo, qm: x.qdm, qdm: (u - tc) / tm.jm, dahl: 0.0 }
            }
        }
    }

    /// One RK4 step of length `self.dt` with u, the operator and the other joints held; the
    /// Dahl state held over the step, then advanced over its travel.
    pub fn step(&self, t: f64, x: &State, u: f64, op: &Operator, others: &[f64]) -> State {
        let h = self.dt;
        let add = |x: &State, k: &State, s: f64| State {
            q: x.q + s * k.q,
            qd: x.qd + s * k.qd,
            qm: x.qm + s * k.qm,
            qdm: x.qdm + s * k.qdm,
            dahl: x.dahl,
        };
        let k1 = self.deriv(t, x, u, op, others);
        let k2 = self.deriv(t + h / 2.0, &add(x, &k1, h / 2.0), u, op, others);
        let k3 = self.deriv(t + h / 2.0, &add(x, &k2, h / 2.0), u, op, others);
        let k4 = self.deriv(t + h, &add(x, &k3, h), u, op, others);
        let comb = |a: f64, b: f64, c: f64, d: f64| (a + 2.0 * b + 2.0 * c + d) * h / 6.0;
        let q = x.q + comb(k1.q, k2.q, k3.q, k4.q);
        State {
            q,
            qd: x.qd + comb(k1.qd, k2.qd, k3.qd, k4.qd),
            qm: x.qm + comb(k1.qm, k2.qm, k3.qm, k4.qm),
            qdm: x.qdm + comb(k1.qdm, k2.qdm, k3.qdm, k4.qdm),
            dahl: if self.has_presliding() { self.dahl_after(t + h, x.dahl, q - x.q) } else { 0.0 },
        }
    }

    pub fn has_spring(&self) -> bool {
        self.k > 0.0
    }

    /// Largest static torque scale of the plant (for default operator gains).
    pub fn stiffness_scale(&self) -> f64 {
        self.k + (self.amp * self.s).abs() + self.effects.cable_spring.as_ref().map(|c| c.k).unwrap_or(0.0)
    }
}

/// Keeps `Section`/`GravityTableToml` referenced for the macro expansion above.
#[allow(dead_code)]
fn _uses(_: Option<&Section>, _: Option<&GravityTableToml>) {}
