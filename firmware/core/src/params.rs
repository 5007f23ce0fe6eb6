//! The one parameter table, and the only way from raw values to a usable parameter set.
//!
//! Every scalar parameter is declared once in [`PARAMS`]: its id, name, TOML place, unit, range,
//! default, doc and whether it is safety-relevant. CAN object indices, the host tool's names,
//! the EDS and validation all derive from this table. Raw values ([`RawParams`], from a TOML
//! file, SDO writes or flash) become a [`ParamSet`] only through [`check`], which refuses NaN,
//! out-of-range and inconsistent values with the parameter named. [`ActiveParams::replace`]
//! swaps the set in force only after a successful check: a refused set leaves the old one
//! running, never half of each.

use crate::math;
use crate::model::{Extra, Friction, Presliding, Spring, Terms, Weight};
pub use crate::series::RawSeries;
use crate::series::{self, SeriesError};
pub use crate::table::RawTable;
use crate::table::{self, Lut, TableError};

/// Declares the parameter table once: the [`ParamId`] enum (explicit discriminants, so a
/// term's CANopen sub-index base can never move), [`ParamId::ALL`], [`PARAM_COUNT`] and
/// [`PARAMS`] all come from the one list below. A compile-time check refuses a list whose
/// numbers are not 0, 1, 2, … in order, so a new term is appended with the next number and
/// everything that follows from the table (object dictionary, EDS, TOML sections and keys,
/// push/pull, `jointctl` help) picks it up.
macro_rules! param_table {
    ($($id:ident = $idx:literal : $name:literal, $section:literal, $key:literal, $unit:literal,
       $min:expr, $max:expr, $default:expr, $safety:expr, $doc:literal;)*) => {
        /// Identifier of a scalar parameter; its value is the index into [`PARAMS`] and into
        /// [`RawParams::values`], and the CANopen sub-index base of its manufacturer object.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        #[repr(u16)]
        pub enum ParamId {
            $($id = $idx,)*
        }

        /// Number of scalar parameters.
        pub const PARAM_COUNT: usize = [$($idx),*].len();

        // The numbers are the table positions: 0, 1, 2, … (checked when the crate compiles).
        #[allow(clippy::indexing_slicing)]
        const _: () = {
            let idx: [usize; PARAM_COUNT] = [$($idx),*];
            let mut i = 0;
            while i < PARAM_COUNT {
                assert!(idx[i] == i, "parameter numbers must run 0, 1, 2, … in table order (append new terms)");
                i += 1;
            }
        };

        impl ParamId {
            /// All ids in table order.
            pub const ALL: [ParamId; PARAM_COUNT] = [$(ParamId::$id,)*];
        }

        /// The parameter table, in [`ParamId`] order.
        pub static PARAMS: [ParamDesc; PARAM_COUNT] = [
            $(ParamDesc {
                id: ParamId::$id,
                name: $name,
                section: $section,
                key: $key,
                unit: $unit,
                min: $min,
                max: $max,
                default: $default,
                #[cfg(feature = "param-docs")]
                doc: $doc,
                safety: $safety,
            },)*
        ];
    };
}

param_table! {
    // id = number: name, TOML section, key, unit, min, max, default, safety-relevant, doc;
    FrictionA = 0: "friction_a", "friction", "a", "N·m·s²/rad²", 0.0, 1.0e3, 0.0, false,
       "quadratic friction coefficient a of a·q̇|q̇| (trunk paper eq. 3)";
    FrictionB = 1: "friction_b", "friction", "b", "N·m·s/rad", 0.0, 1.0e3, 0.0, false,
       "viscous friction coefficient b of b·q̇";
    FrictionC = 2: "friction_c", "friction", "c", "N·m", 0.0, 1.0e3, 0.0, false,
       "Coulomb friction level c of c·sign(q̇)";
    FrictionVBand = 3: "friction_v_band", "friction", "v_band", "rad/s", 0.0, 1.0, 0.01, false,
       "velocity band around zero where sign(q̇) is linear (q̇/band), so a noisy zero velocity does not chatter";
    WeightAmplitude = 4: "weight_amplitude", "weight", "amplitude", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "weight torque amplitude C_w0 of C_w0·sin(s·q + φ) (trunk paper eq. 4)";
    WeightS = 5: "weight_s", "weight", "s", "1", -100.0, 100.0, 1.0, false,
       "angle scale s of sin(s·q + φ), q in rad";
    WeightPhi = 6: "weight_phi", "weight", "phi", "rad", -10.0, 10.0, 0.0, false,
       "phase φ of sin(s·q + φ)";
    InertiaJ = 7: "inertia_j", "inertia", "j", "kg·m²", 0.0, 1.0e3, 0.0, false,
       "apparent inertia at the joint output (I_a of trunk paper eq. 2)";
    OffsetC0 = 8: "offset_c0", "offset", "c0", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "constant torque offset C_0";
    SpringK = 9: "spring_k", "spring", "k", "N·m/rad", 0.0, 1.0e4, 0.0, false,
       "spring stiffness K of K·(q − q0) (elastic-joint paper eq. 1)";
    SpringB = 10: "spring_b", "spring", "b", "N·m·s/rad", 0.0, 1.0e3, 0.0, false,
       "spring damping B of B·q̇ (elastic-joint paper eq. 2)";
    SpringQ0 = 11: "spring_q0", "spring", "q0", "rad", -100.0, 100.0, 0.0, false,
       "spring rest angle q0";
    TableSigmaModel = 12: "gravity_table_sigma_model", "gravity_table", "sigma_model", "N·m", 0.0, 1.0e3, 0.0, false,
       "σ_m of the analytic gravity model (arm paper eq. 6); > 0 fuses the table with the weight term, 0 adds the table as a term";
    TableClampK = 13: "gravity_table_clamp_k", "gravity_table", "clamp_k", "1", 0.0, 100.0, 1.0, false,
       "k of the fusion clamp τ_model ± k·σ_model (arm paper eq. 8)";
    Ratio = 14: "compensation_ratio", "compensation", "ratio", "1", 1.01, 1.0e4, 160.0, true,
       "transmission ratio N; the motor command is the output torque / (N − 1) (trunk paper eq. 6)";
    Fraction = 15: "compensation_fraction", "compensation", "fraction", "1", 0.0, 1.0, 0.0, true,
       "share of the disturbance C_c that is compensated (the paper used 0.7; 1 is undamped)";
    AssistK = 16: "compensation_assist_k", "compensation", "assist_k", "N·m/rad", -1.0e3, 1.0e3, 0.0, false,
       "desired support torque K·q (trunk paper eq. 8)";
    TorqueLimit = 17: "compensation_torque_limit", "compensation", "torque_limit", "N·m", 0.0, 1.0e4, 10.0, true,
       "output torque limit, applied after the compensation law";
    RateLimit = 18: "compensation_rate_limit", "compensation", "rate_limit", "N·m/s", 0.1, 1.0e6, 2000.0, true,
       "largest change of the output torque per second";
    ControlRateHz = 19: "controller_rate_hz", "controller", "rate_hz", "Hz", 100.0, 10000.0, 1000.0, true,
       "control loop rate";
    HeartbeatTimeout = 20: "controller_heartbeat_timeout", "controller", "heartbeat_timeout", "s", 0.0, 60.0, 0.5, true,
       "host heartbeat timeout before the torque ramps to zero (0 = no host watchdog)";
    FaultRampTime = 21: "controller_fault_ramp_time", "controller", "fault_ramp_time", "s", 0.001, 10.0, 0.2, true,
       "time in which the torque ramps to zero after a fault";
    AccelCutoff = 22: "controller_accel_cutoff", "controller", "accel_cutoff", "Hz", 0.1, 1000.0, 20.0, false,
       "cut-off of the low-pass filter on the estimated acceleration (must be below half the control rate)";
    VelKp = 23: "controller_vel_kp", "controller", "vel_kp", "N·m·s/rad", 0.0, 1.0e4, 20.0, false,
       "velocity mode proportional gain (characterisation sweeps)";
    VelKi = 24: "controller_vel_ki", "controller", "vel_ki", "N·m/rad", 0.0, 1.0e5, 100.0, false,
       "velocity mode integral gain";
    PosKp = 25: "controller_pos_kp", "controller", "pos_kp", "N·m/rad", 0.0, 1.0e5, 100.0, false,
       "position mode stiffness (static poses)";
    PosKd = 26: "controller_pos_kd", "controller", "pos_kd", "N·m·s/rad", 0.0, 1.0e4, 10.0, false,
       "position mode damping";
    // The effect terms below share the names and formulas of host-sim's plant effect sections
    // (spec §3 vocabulary), so `jointctl diagnose --emit-model` output runs on the joint as is.
    StribeckLevel = 27: "stribeck_level", "stribeck", "level", "N·m", 0.0, 1.0e3, 0.0, false,
       "Stribeck friction above the Coulomb level at rest: level·exp(−(q̇/speed)²)·sign(q̇)";
    StribeckSpeed = 28: "stribeck_speed", "stribeck", "speed", "rad/s", 1.0e-4, 100.0, 0.05, false,
       "speed over which the Stribeck excess decays";
    AsymmetricDelta = 29: "asymmetric_friction_delta", "asymmetric_friction", "delta", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "direction-dependent Coulomb level: c + delta forward, c − delta backward (delta·|sign(q̇)|)";
    RippleAmplitude = 30: "position_ripple_amplitude", "position_ripple", "amplitude", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "torque ripple periodic in position: amplitude·sin(2π·q/period + phase)";
    RipplePeriod = 31: "position_ripple_period", "position_ripple", "period", "rad", 1.0e-3, 100.0, 1.0, false,
       "period of the position ripple (gear mesh, cogging)";
    RipplePhase = 32: "position_ripple_phase", "position_ripple", "phase", "rad", -10.0, 10.0, 0.0, false,
       "phase of the position ripple";
    CableK = 33: "cable_spring_k", "cable_spring", "k", "N·m/rad", -1.0e4, 1.0e4, 0.0, false,
       "stiffness of a one-sided cable/harness spring, engaged above `engage`";
    CableEngage = 34: "cable_spring_engage", "cable_spring", "engage", "rad", -100.0, 100.0, 0.0, false,
       "angle where the cable spring engages";
    CableWidth = 35: "cable_spring_width", "cable_spring", "width", "rad", 1.0e-4, 10.0, 0.01, false,
       "width of the quadratic blend into the cable spring's slope";
    DryFrictionC = 36: "dry_friction_c", "dry_friction", "c", "N·m", 0.0, 1.0e3, 0.0, false,
       "extra Coulomb torque c·sign(q̇); with presliding on it joins friction_c as the Dahl state's level";
    // Appended last so every CANopen index above keeps its place (0x2000 + table position).
    PreslidingSigma = 37: "presliding_sigma", "presliding", "sigma", "N·m/rad", 0.0, 1.0e7, 0.0, false,
       "pre-sliding stiffness σ of a Dahl friction state F that replaces c·sign(q̇): dF/dq = σ·(1 − F/c·sign(dq)), |F| ≤ c = friction_c + dry_friction_c (0 = off)";
    RippleAmplitude2 = 38: "position_ripple_amplitude_2", "position_ripple", "amplitude_2", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "second harmonic of the position ripple: amplitude_2·sin(4π·q/period + phase_2) (a wave generator's or a tooth's half-period)";
    RipplePhase2 = 39: "position_ripple_phase_2", "position_ripple", "phase_2", "rad", -10.0, 10.0, 0.0, false,
       "phase of the ripple's second harmonic";
    LoadFrictionMu = 40: "load_dependent_friction_mu", "load_dependent_friction", "mu", "1", 0.0, 1.0, 0.0, false,
       "friction growing with the transmitted torque: mu·|τ_load|·sign(q̇), τ_load the joint's measured load (its load cell; 0 without one)";
}

impl ParamId {
    pub const fn index(self) -> usize {
        self as usize
    }

    pub fn from_index(i: usize) -> Option<ParamId> {
        Self::ALL.get(i).copied()
    }

    #[allow(clippy::indexing_slicing)]
    pub fn desc(self) -> &'static ParamDesc {
        // PARAMS is declared in ParamId order (checked at compile time), so the index exists.
        &PARAMS[self.index() % PARAM_COUNT]
    }

    pub fn name(self) -> &'static str {
        self.desc().name
    }

    /// Look a parameter up by its name (`friction_a`) or TOML place (`friction.a`).
    pub fn from_name(name: &str) -> Option<ParamId> {
        PARAMS.iter().find(|d| d.name == name || d.toml_path_eq(name)).map(|d| d.id)
    }
}

/// The TOML sections of the table, each once, in the order they first appear. The model
/// file's parser and the list of terms the joint compensates follow from this, so a term added
/// to the table (appended, even to a section declared earlier) is in the model file at once.
pub fn sections() -> impl Iterator<Item = &'static str> {
    PARAMS.iter().enumerate().filter_map(|(i, d)| {
        let first = !PARAMS.iter().take(i).any(|e| e.section == d.section);
        first.then_some(d.section)
    })
}

/// The parameter at a TOML place (`friction`, `c`), if one lives there.
pub fn param_at(section: &str, key: &str) -> Option<&'static ParamDesc> {
    PARAMS.iter().find(|d| d.section == section && d.key == key)
}

/// The parameters of one TOML section, in table order.
pub fn section_params(section: &str) -> impl Iterator<Item = &'static ParamDesc> + '_ {
    PARAMS.iter().filter(move |d| d.section == section)
}

/// Declaration of one scalar parameter.
#[derive(Debug)]
pub struct ParamDesc {
    pub id: ParamId,
    /// name used on CAN, in the EDS and by `jointctl` (`friction_a`)
    pub name: &'static str,
    /// section of the model TOML (`friction`)
    pub section: &'static str,
    /// key inside that section (`a`)
    pub key: &'static str,
    pub unit: &'static str,
    pub min: f32,
    pub max: f32,
    pub default: f32,
    /// what the parameter means (the EDS's description); host builds only (feature
    /// `param-docs`): the strings are 4 KiB of flash the joint never reads
    #[cfg(feature = "param-docs")]
    pub doc: &'static str,
    /// safety-relevant: may only change while the node is pre-operational
    pub safety: bool,
}

impl ParamDesc {
    fn toml_path_eq(&self, path: &str) -> bool {
        let (s, k) = match path.split_once('.') {
            Some(x) => x,
            None => return false,
        };
        s == self.section && k == self.key
    }
}

/// A parameter set as received; nothing here is trusted until [`check`] says so.
#[derive(Clone, Debug, PartialEq)]
pub struct RawParams {
    pub values: [f32; PARAM_COUNT],
    pub table: RawTable,
    /// the analytic multi-angle gravity term (empty: none)
    pub series: RawSeries,
}

impl RawParams {
    /// Every parameter at its table default, no gravity table.
    pub fn defaults() -> Self {
        let mut values = [0.0; PARAM_COUNT];
        for (v, d) in values.iter_mut().zip(PARAMS.iter()) {
            *v = d.default;
        }
        RawParams { values, table: RawTable::EMPTY, series: RawSeries::EMPTY }
    }

    pub fn get(&self, id: ParamId) -> f32 {
        self.values.get(id.index()).copied().unwrap_or(f32::NAN)
    }

    pub fn set(&mut self, id: ParamId, value: f32) {
        if let Some(v) = self.values.get_mut(id.index()) {
            *v = value;
        }
    }
}

impl Default for RawParams {
    fn default() -> Self {
        Self::defaults()
    }
}

/// Why a parameter set was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamError {
    NotFinite { param: ParamId },
    OutOfRange { param: ParamId, value: f32, min: f32, max: f32 },
    Inconsistent { param: ParamId, what: &'static str },
    Table(TableError),
    Series(SeriesError),
}

impl ParamError {
    /// The scalar parameter at fault, if any (table errors name their cell instead).
    pub fn param(&self) -> Option<ParamId> {
        match *self {
            ParamError::NotFinite { param }
            | ParamError::OutOfRange { param, .. }
            | ParamError::Inconsistent { param, .. } => Some(param),
            ParamError::Table(_) | ParamError::Series(_) => None,
        }
    }
}

impl ParamError {
    /// The error named without its numbers: formatting floats costs the MCU ~13 KiB of flash,
    /// and the limits are in the EDS and the parameter table anyway.
    pub fn write_brief<W: core::fmt::Write>(&self, w: &mut W) -> core::fmt::Result {
        match *self {
            ParamError::NotFinite { param } => write!(w, "{} is not a finite number", param.name()),
            ParamError::OutOfRange { param, value, max, .. } => {
                let side = if value > max { "above its maximum" } else { "below its minimum" };
                write!(w, "{} is {side}", param.name())
            }
            ParamError::Inconsistent { param, what } => write!(w, "{}: {what}", param.name()),
            ParamError::Table(e) => write!(w, "{e}"),
            ParamError::Series(e) => write!(w, "{e}"),
        }
    }
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            ParamError::NotFinite { param } => {
                let d = param.desc();
                write!(f, "{} ({}.{}) is not a finite number", d.name, d.section, d.key)
            }
            ParamError::OutOfRange { param, value, min, max } => {
                let d = param.desc();
                write!(f, "{} ({}.{}) = {} is outside {}..={} {}", d.name, d.section, d.key, value, min, max, d.unit)
            }
            ParamError::Inconsistent { param, what } => {
                let d = param.desc();
                write!(f, "{} ({}.{}): {}", d.name, d.section, d.key, what)
            }
            ParamError::Table(e) => write!(f, "{e}"),
            ParamError::Series(e) => write!(f, "{e}"),
        }
    }
}

/// A validated parameter set. Only [`check`] makes one, so holding a `ParamSet` proves every
/// value is finite, in range and consistent.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSet {
    raw: RawParams,
    terms: Terms,
    /// 1/(N − 1), precomputed for the control step
    inv_ratio_m1: f32,
    /// the gravity table's precomputed lookup data
    lut: Lut,
}

impl ParamSet {
    pub fn raw(&self) -> &RawParams {
        &self.raw
    }

    #[inline]
    pub fn get(&self, id: ParamId) -> f32 {
        self.raw.get(id)
    }

    #[inline]
    pub fn terms(&self) -> &Terms {
        &self.terms
    }

    #[inline]
    pub fn table(&self) -> &RawTable {
        &self.raw.table
    }

    #[inline]
    pub fn series(&self) -> &RawSeries {
        &self.raw.series
    }

    #[inline]
    pub fn lut(&self) -> &Lut {
        &self.lut
    }

    #[inline]
    pub fn inv_ratio_m1(&self) -> f32 {
        self.inv_ratio_m1
    }

    /// The defaults, which always pass [`check`] (a unit test proves it), built without the
    /// check's copies: this runs at boot on a 32 KiB MCU.
    pub fn defaults() -> ParamSet {
        build(RawParams::defaults())
    }

    /// Put `raw`, already validated, in force in place: no parameter-set-sized temporaries on
    /// the stack (a set is ~2.9 KiB, and the board's boot and SDO paths run on ~18 KiB).
    fn assign(&mut self, raw: &RawParams) {
        self.raw.clone_from(raw);
        self.derive();
    }

    /// Reset to the defaults in place.
    fn assign_defaults(&mut self) {
        for (v, d) in self.raw.values.iter_mut().zip(PARAMS.iter()) {
            *v = d.default;
        }
        // A const: copied from flash straight into place, no stack temporary.
        self.raw.table = RawTable::EMPTY;
        self.raw.series = RawSeries::EMPTY;
        self.derive();
    }

    fn derive(&mut self) {
        self.terms = terms_of(&self.raw);
        self.inv_ratio_m1 = 1.0 / (self.raw.get(ParamId::Ratio) - 1.0);
        self.lut = Lut::new(&self.raw.table);
    }
}

impl Default for ParamSet {
    fn default() -> Self {
        Self::defaults()
    }
}

fn terms_of(raw: &RawParams) -> Terms {
    let g = |id: ParamId| raw.get(id);
    // With presliding on, dry friction is part of the Dahl state's level, not an effect term:
    // the effect terms then hold no dry friction and the step's common path stays as it is.
    let dahl = g(ParamId::PreslidingSigma) > 0.0;
    let dry_c = if dahl { 0.0 } else { g(ParamId::DryFrictionC) };
    Terms {
        friction: Friction {
            a: g(ParamId::FrictionA),
            b: g(ParamId::FrictionB),
            c: g(ParamId::FrictionC),
            v_band: g(ParamId::FrictionVBand),
        },
        weight: Weight { amplitude: g(ParamId::WeightAmplitude), s: g(ParamId::WeightS), phi: g(ParamId::WeightPhi) },
        spring: Spring { k: g(ParamId::SpringK), b: g(ParamId::SpringB), q0: g(ParamId::SpringQ0) },
        j: g(ParamId::InertiaJ),
        c0: g(ParamId::OffsetC0),
        extra: Extra {
            any: g(ParamId::StribeckLevel) != 0.0
                || g(ParamId::AsymmetricDelta) != 0.0
                || g(ParamId::RippleAmplitude) != 0.0
                || g(ParamId::RippleAmplitude2) != 0.0
                || g(ParamId::CableK) != 0.0
                || dry_c != 0.0
                || g(ParamId::LoadFrictionMu) != 0.0,
            stribeck_level: g(ParamId::StribeckLevel),
            stribeck_inv_speed: 1.0 / g(ParamId::StribeckSpeed),
            asym_delta: g(ParamId::AsymmetricDelta),
            ripple_amplitude: g(ParamId::RippleAmplitude),
            ripple_k: 2.0 * core::f32::consts::PI / g(ParamId::RipplePeriod),
            ripple_phase: g(ParamId::RipplePhase),
            ripple_amplitude_2: g(ParamId::RippleAmplitude2),
            ripple_phase_2: g(ParamId::RipplePhase2),
            cable_k: g(ParamId::CableK),
            cable_engage: g(ParamId::CableEngage),
            cable_width: g(ParamId::CableWidth),
            dry_c,
            load_mu: g(ParamId::LoadFrictionMu),
        },
        presliding: Presliding::new(g(ParamId::PreslidingSigma), g(ParamId::FrictionC) + g(ParamId::DryFrictionC)),
    }
}

fn build(raw: RawParams) -> ParamSet {
    let mut set = ParamSet { raw, terms: Terms::default(), inv_ratio_m1: 0.0, lut: Lut::default() };
    set.derive();
    set
}

/// Validate a raw set. The first problem found is returned, scalar parameters in table order,
/// then cross-parameter rules, then the gravity table and the gravity series.
pub fn check(raw: &RawParams) -> Result<ParamSet, ParamError> {
    validate(raw)?;
    Ok(build(raw.clone()))
}

/// The rules of [`check`] without building a set (no copy of the parameters).
pub fn validate(raw: &RawParams) -> Result<(), ParamError> {
    for d in PARAMS.iter() {
        let v = raw.get(d.id);
        if !math::is_finite(v) {
            return Err(ParamError::NotFinite { param: d.id });
        }
        if v < d.min || v > d.max {
            return Err(ParamError::OutOfRange { param: d.id, value: v, min: d.min, max: d.max });
        }
    }
    if raw.get(ParamId::AccelCutoff) * 2.0 >= raw.get(ParamId::ControlRateHz) {
        return Err(ParamError::Inconsistent {
            param: ParamId::AccelCutoff,
            what: "acceleration filter cut-off must be below half the control rate",
        });
    }
    table::validate(&raw.table).map_err(ParamError::Table)?;
    series::validate(&raw.series).map_err(ParamError::Series)?;
    if raw.get(ParamId::TableSigmaModel) > 0.0 {
        if raw.table.n_axes == 0 {
            return Err(ParamError::Inconsistent {
                param: ParamId::TableSigmaModel,
                what: "fusion (sigma_model > 0) needs a gravity table",
            });
        }
        if !raw.table.has_sigma {
            return Err(ParamError::Inconsistent {
                param: ParamId::TableSigmaModel,
                what: "fusion (sigma_model > 0) needs the table's per-cell sigma",
            });
        }
    }
    Ok(())
}

/// The parameter set in force. Replacing it is all or nothing.
#[derive(Clone, Debug, Default)]
pub struct ActiveParams {
    current: ParamSet,
}

impl ActiveParams {
    pub fn new(set: ParamSet) -> Self {
        ActiveParams { current: set }
    }

    #[inline]
    pub fn current(&self) -> &ParamSet {
        &self.current
    }

    /// Check `raw` and put it in force, in place; on error the previous set stays, untouched.
    pub fn replace(&mut self, raw: &RawParams) -> Result<(), ParamError> {
        validate(raw)?;
        self.current.assign(raw);
        Ok(())
    }

    /// Put the table defaults in force, in place.
    pub fn reset_to_defaults(&mut self) {
        self.current.assign_defaults();
    }
}
