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

/// Identifier of a scalar parameter; its value is the index into [`PARAMS`] and into
/// [`RawParams::values`], and the CANopen sub-index base of its manufacturer object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u16)]
pub enum ParamId {
    FrictionA,
    FrictionB,
    FrictionC,
    FrictionVBand,
    WeightAmplitude,
    WeightS,
    WeightPhi,
    InertiaJ,
    OffsetC0,
    SpringK,
    SpringB,
    SpringQ0,
    TableSigmaModel,
    TableClampK,
    Ratio,
    Fraction,
    AssistK,
    TorqueLimit,
    RateLimit,
    ControlRateHz,
    HeartbeatTimeout,
    FaultRampTime,
    AccelCutoff,
    VelKp,
    VelKi,
    PosKp,
    PosKd,
    StribeckLevel,
    StribeckSpeed,
    AsymmetricDelta,
    RippleAmplitude,
    RipplePeriod,
    RipplePhase,
    CableK,
    CableEngage,
    CableWidth,
    DryFrictionC,
    PreslidingSigma,
}

pub const PARAM_COUNT: usize = 38;

impl ParamId {
    /// All ids in table order.
    pub const ALL: [ParamId; PARAM_COUNT] = [
        ParamId::FrictionA,
        ParamId::FrictionB,
        ParamId::FrictionC,
        ParamId::FrictionVBand,
        ParamId::WeightAmplitude,
        ParamId::WeightS,
        ParamId::WeightPhi,
        ParamId::InertiaJ,
        ParamId::OffsetC0,
        ParamId::SpringK,
        ParamId::SpringB,
        ParamId::SpringQ0,
        ParamId::TableSigmaModel,
        ParamId::TableClampK,
        ParamId::Ratio,
        ParamId::Fraction,
        ParamId::AssistK,
        ParamId::TorqueLimit,
        ParamId::RateLimit,
        ParamId::ControlRateHz,
        ParamId::HeartbeatTimeout,
        ParamId::FaultRampTime,
        ParamId::AccelCutoff,
        ParamId::VelKp,
        ParamId::VelKi,
        ParamId::PosKp,
        ParamId::PosKd,
        ParamId::StribeckLevel,
        ParamId::StribeckSpeed,
        ParamId::AsymmetricDelta,
        ParamId::RippleAmplitude,
        ParamId::RipplePeriod,
        ParamId::RipplePhase,
        ParamId::CableK,
        ParamId::CableEngage,
        ParamId::CableWidth,
        ParamId::DryFrictionC,
        ParamId::PreslidingSigma,
    ];

    pub const fn index(self) -> usize {
        self as usize
    }

    pub fn from_index(i: usize) -> Option<ParamId> {
        Self::ALL.get(i).copied()
    }

    #[allow(clippy::indexing_slicing)]
    pub fn desc(self) -> &'static ParamDesc {
        // PARAMS is declared in ParamId order (a test checks it), so the index always exists.
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

macro_rules! p {
    ($id:ident, $name:literal, $section:literal, $key:literal, $unit:literal, $min:expr, $max:expr, $default:expr, $safety:expr, $doc:literal) => {
        ParamDesc {
            id: ParamId::$id,
            name: $name,
            section: $section,
            key: $key,
            unit: $unit,
            min: $min,
            max: $max,
            default: $default,
            doc: $doc,
            safety: $safety,
        }
    };
}

/// The parameter table. Order must equal [`ParamId`] order.
pub static PARAMS: [ParamDesc; PARAM_COUNT] = [
    p!(FrictionA, "friction_a", "friction", "a", "N·m·s²/rad²", 0.0, 1.0e3, 0.0, false,
       "quadratic friction coefficient a of a·q̇|q̇| (trunk paper eq. 3)"),
    p!(FrictionB, "friction_b", "friction", "b", "N·m·s/rad", 0.0, 1.0e3, 0.0, false,
       "viscous friction coefficient b of b·q̇"),
    p!(FrictionC, "friction_c", "friction", "c", "N·m", 0.0, 1.0e3, 0.0, false,
       "Coulomb friction level c of c·sign(q̇)"),
    p!(FrictionVBand, "friction_v_band", "friction", "v_band", "rad/s", 0.0, 1.0, 0.01, false,
       "velocity band around zero where sign(q̇) is linear (q̇/band), so a noisy zero velocity does not chatter"),
    p!(WeightAmplitude, "weight_amplitude", "weight", "amplitude", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "weight torque amplitude C_w0 of C_w0·sin(s·q + φ) (trunk paper eq. 4)"),
    p!(WeightS, "weight_s", "weight", "s", "1", -100.0, 100.0, 1.0, false,
       "angle scale s of sin(s·q + φ), q in rad"),
    p!(WeightPhi, "weight_phi", "weight", "phi", "rad", -10.0, 10.0, 0.0, false,
       "phase φ of sin(s·q + φ)"),
    p!(InertiaJ, "inertia_j", "inertia", "j", "kg·m²", 0.0, 1.0e3, 0.0, false,
       "apparent inertia at the joint output (I_a of trunk paper eq. 2)"),
    p!(OffsetC0, "offset_c0", "offset", "c0", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "constant torque offset C_0"),
    p!(SpringK, "spring_k", "spring", "k", "N·m/rad", 0.0, 1.0e4, 0.0, false,
       "spring stiffness K of K·(q − q0) (elastic-joint paper eq. 1)"),
    p!(SpringB, "spring_b", "spring", "b", "N·m·s/rad", 0.0, 1.0e3, 0.0, false,
       "spring damping B of B·q̇ (elastic-joint paper eq. 2)"),
    p!(SpringQ0, "spring_q0", "spring", "q0", "rad", -100.0, 100.0, 0.0, false,
       "spring rest angle q0"),
    p!(TableSigmaModel, "gravity_table_sigma_model", "gravity_table", "sigma_model", "N·m", 0.0, 1.0e3, 0.0, false,
       "σ_m of the analytic gravity model (arm paper eq. 6); > 0 fuses the table with the weight term, 0 adds the table as a term"),
    p!(TableClampK, "gravity_table_clamp_k", "gravity_table", "clamp_k", "1", 0.0, 100.0, 1.0, false,
       "k of the fusion clamp τ_model ± k·σ_model (arm paper eq. 8)"),
    p!(Ratio, "compensation_ratio", "compensation", "ratio", "1", 1.01, 1.0e4, 160.0, true,
       "transmission ratio N; the motor command is the output torque / (N − 1) (trunk paper eq. 6)"),
    p!(Fraction, "compensation_fraction", "compensation", "fraction", "1", 0.0, 1.0, 0.0, true,
       "share of the disturbance C_c that is compensated (the paper used 0.7; 1 is undamped)"),
    p!(AssistK, "compensation_assist_k", "compensation", "assist_k", "N·m/rad", -1.0e3, 1.0e3, 0.0, false,
       "desired support torque K·q (trunk paper eq. 8)"),
    p!(TorqueLimit, "compensation_torque_limit", "compensation", "torque_limit", "N·m", 0.0, 1.0e4, 10.0, true,
       "output torque limit, applied after the compensation law"),
    p!(RateLimit, "compensation_rate_limit", "compensation", "rate_limit", "N·m/s", 0.1, 1.0e6, 2000.0, true,
       "largest change of the output torque per second"),
    p!(ControlRateHz, "controller_rate_hz", "controller", "rate_hz", "Hz", 100.0, 10000.0, 1000.0, true,
       "control loop rate"),
    p!(HeartbeatTimeout, "controller_heartbeat_timeout", "controller", "heartbeat_timeout", "s", 0.0, 60.0, 0.5, true,
       "host heartbeat timeout before the torque ramps to zero (0 = no host watchdog)"),
    p!(FaultRampTime, "controller_fault_ramp_time", "controller", "fault_ramp_time", "s", 0.001, 10.0, 0.2, true,
       "time in which the torque ramps to zero after a fault"),
    p!(AccelCutoff, "controller_accel_cutoff", "controller", "accel_cutoff", "Hz", 0.1, 1000.0, 20.0, false,
       "cut-off of the low-pass filter on the estimated acceleration (must be below half the control rate)"),
    p!(VelKp, "controller_vel_kp", "controller", "vel_kp", "N·m·s/rad", 0.0, 1.0e4, 20.0, false,
       "velocity mode proportional gain (characterisation sweeps)"),
    p!(VelKi, "controller_vel_ki", "controller", "vel_ki", "N·m/rad", 0.0, 1.0e5, 100.0, false,
       "velocity mode integral gain"),
    p!(PosKp, "controller_pos_kp", "controller", "pos_kp", "N·m/rad", 0.0, 1.0e5, 100.0, false,
       "position mode stiffness (static poses)"),
    p!(PosKd, "controller_pos_kd", "controller", "pos_kd", "N·m·s/rad", 0.0, 1.0e4, 10.0, false,
       "position mode damping"),
    // The effect terms below share the names and formulas of host-sim's plant effect sections
    // (spec §3 vocabulary), so `jointctl diagnose --emit-model` output runs on the joint as is.
    p!(StribeckLevel, "stribeck_level", "stribeck", "level", "N·m", 0.0, 1.0e3, 0.0, false,
       "Stribeck friction above the Coulomb level at rest: level·exp(−(q̇/speed)²)·sign(q̇)"),
    p!(StribeckSpeed, "stribeck_speed", "stribeck", "speed", "rad/s", 1.0e-4, 100.0, 0.05, false,
       "speed over which the Stribeck excess decays"),
    p!(AsymmetricDelta, "asymmetric_friction_delta", "asymmetric_friction", "delta", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "direction-dependent Coulomb level: c + delta forward, c − delta backward (delta·|sign(q̇)|)"),
    p!(RippleAmplitude, "position_ripple_amplitude", "position_ripple", "amplitude", "N·m", -1.0e3, 1.0e3, 0.0, false,
       "torque ripple periodic in position: amplitude·sin(2π·q/period + phase)"),
    p!(RipplePeriod, "position_ripple_period", "position_ripple", "period", "rad", 1.0e-3, 100.0, 1.0, false,
       "period of the position ripple (gear mesh, cogging)"),
    p!(RipplePhase, "position_ripple_phase", "position_ripple", "phase", "rad", -10.0, 10.0, 0.0, false,
       "phase of the position ripple"),
    p!(CableK, "cable_spring_k", "cable_spring", "k", "N·m/rad", -1.0e4, 1.0e4, 0.0, false,
       "stiffness of a one-sided cable/harness spring, engaged above `engage`"),
    p!(CableEngage, "cable_spring_engage", "cable_spring", "engage", "rad", -100.0, 100.0, 0.0, false,
       "angle where the cable spring engages"),
    p!(CableWidth, "cable_spring_width", "cable_spring", "width", "rad", 1.0e-4, 10.0, 0.01, false,
       "width of the quadratic blend into the cable spring's slope"),
    p!(DryFrictionC, "dry_friction_c", "dry_friction", "c", "N·m", 0.0, 1.0e3, 0.0, false,
       "extra Coulomb torque c·sign(q̇); with presliding on it joins friction_c as the Dahl state's level"),
    // Appended last so every CANopen index above keeps its place (0x2000 + table position).
    p!(PreslidingSigma, "presliding_sigma", "presliding", "sigma", "N·m/rad", 0.0, 1.0e7, 0.0, false,
       "pre-sliding stiffness σ of a Dahl friction state F that replaces c·sign(q̇): dF/dq = σ·(1 − F/c·sign(dq)), |F| ≤ c = friction_c + dry_friction_c (0 = off)"),
];

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
                || g(ParamId::CableK) != 0.0
                || dry_c != 0.0,
            stribeck_level: g(ParamId::StribeckLevel),
            stribeck_inv_speed: 1.0 / g(ParamId::StribeckSpeed),
            asym_delta: g(ParamId::AsymmetricDelta),
            ripple_amplitude: g(ParamId::RippleAmplitude),
            ripple_k: 2.0 * core::f32::consts::PI / g(ParamId::RipplePeriod),
            ripple_phase: g(ParamId::RipplePhase),
            cable_k: g(ParamId::CableK),
            cable_engage: g(ParamId::CableEngage),
            cable_width: g(ParamId::CableWidth),
            dry_c,
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
