//! A deterministic scripted session: parameter sets → control steps → commands, the same
//! on the PC and on the MCU.
//!
//! The QEMU parity image runs [`session`] on an emulated Cortex-M4F and prints every
//! [`Record`]; the host runs the same function natively and compares every word to the
//! last bit. Inputs come from a fixed-seed xorshift generator using only integer ops and
//! exact f32 scaling, so both sides feed the core identical bits; any difference in the
//! records is then a difference in what the core computes on the two targets.
//!
//! The script loads the trunk-paper right joint, then the same joint with the elastic
//! joint's spring, then a 2-D gravity table fused with the weight model; it tries parameter
//! sets that must be refused (NaN, out of range, non-increasing grid, inconsistent filter)
//! and keeps stepping to show the old set stays in force; then an arm joint whose gravity is
//! a 9-term sine series over four joint angles with the table as its residual, and a series
//! that must be refused while it is in force; it also runs a stretch where
//! q̇ and q̈ come from the core's [`Differentiator`] fed with encoder-like positions, and
//! the fixed-point path. Last, pre-sliding (Dahl) friction: the fused-table joint with
//! `presliding.sigma` and dry friction joining the Dahl level, driven through reversals, small
//! oscillations inside the pre-sliding distance, zero travel, large and clamped steps, bad
//! samples and mode changes, then a refused σ while the state runs on. The parameter builders
//! are reused by the cost benchmark.

use crate::control::{Controller, Differentiator, Input, Mode, Output};
use crate::fixed::{self, ControllerFx, DahlFx, FixedParams, Fx};
use crate::math;
use crate::params::{ActiveParams, ParamError, ParamId, RawParams};
use crate::series::SeriesError;
use crate::table::{RawTable, TableError};

/// Seed of the session's generator (any non-zero value works; this one is the contract
/// between the QEMU image and the host, both read it from here).
pub const SESSION_SEED: u32 = 0x1234_5678;

/// Steps run after each accepted or refused parameter set.
pub const STEPS_PER_PHASE: u32 = 96;
/// Steps of the differentiator stretch.
pub const DIFF_STEPS: u32 = 256;

/// Marsaglia's xorshift32: tiny, integer-only, identical on every target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XorShift32 {
    state: u32,
}

impl XorShift32 {
    /// A zero seed would stay zero forever; it is replaced by [`SESSION_SEED`].
    pub const fn new(seed: u32) -> Self {
        XorShift32 { state: if seed == 0 { SESSION_SEED } else { seed } }
    }

    pub fn next_u32(&mut self) -> u32 {
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        x
    }

    /// Uniform in [0, 1): the top 24 bits scaled by 2^-24, exact in f32.
    pub fn unit(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// The right trunk joint of the trunk-exoskeleton paper (Table 1, converted to rad), at
/// the paper's 70 % compensation, ratio 160, 40 N·m limit.
pub fn trunk_right() -> RawParams {
    let mut p = RawParams::defaults();
    p.set(ParamId::FrictionA, 1.894);
    p.set(ParamId::FrictionB, 8.938);
    p.set(ParamId::FrictionC, 2.32);
    p.set(ParamId::WeightAmplitude, 2.79);
    p.set(ParamId::WeightS, 0.802);
    p.set(ParamId::WeightPhi, -0.027);
    p.set(ParamId::InertiaJ, 2.37);
    p.set(ParamId::OffsetC0, -0.59);
    p.set(ParamId::Ratio, 160.0);
    p.set(ParamId::Fraction, 0.7);
    p.set(ParamId::TorqueLimit, 40.0);
    p
}

/// Friction and weight only (inertia and offset zeroed): the cheapest analytic step.
pub fn friction_weight_only() -> RawParams {
    let mut p = trunk_right();
    p.set(ParamId::InertiaJ, 0.0);
    p.set(ParamId::OffsetC0, 0.0);
    p
}

/// The trunk joint plus the elastic joint's spring-damper (elastic-joint paper).
pub fn trunk_spring() -> RawParams {
    let mut p = trunk_right();
    p.set(ParamId::SpringK, 7.3035);
    p.set(ParamId::SpringB, 0.0416);
    p.set(ParamId::SpringQ0, 0.0);
    p
}

/// Axis 0 of the gravity table: the joint's own angle.
pub const TABLE_GRID_Q: [f32; 5] = [-0.5, 0.0, 0.5, 1.0, 1.5];
/// Axis 1: the first other joint's angle (slot 1).
pub const TABLE_GRID_OTHER: [f32; 4] = [-1.0, 0.0, 1.0, 2.0];

/// Calls `f(cell, q, other)` for every cell of the 5 × 4 test grid, row-major, last axis fastest.
fn for_each_cell(mut f: impl FnMut(usize, f32, f32)) {
    let mut cell = 0usize;
    for &g0 in TABLE_GRID_Q.iter() {
        for &g1 in TABLE_GRID_OTHER.iter() {
            f(cell, g0, g1);
            cell += 1;
        }
    }
}

/// A 5 × 4 gravity table over (own q, other joint) with per-cell σ, fused with the weight
/// model (σ_m = 0.3 N·m, clamp k = 1), on top of [`trunk_spring`].
pub fn trunk_table_fused() -> RawParams {
    let mut p = trunk_spring();
    let mut t = RawTable::EMPTY;
    t.n_axes = 2;
    t.axis_source = [0, 1, 0, 0];
    t.points = [TABLE_GRID_Q.len() as u8, TABLE_GRID_OTHER.len() as u8, 0, 0];
    for (dst, src) in t.grid[0].iter_mut().zip(TABLE_GRID_Q.iter()) {
        *dst = *src;
    }
    for (dst, src) in t.grid[1].iter_mut().zip(TABLE_GRID_OTHER.iter()) {
        *dst = *src;
    }
    // A smooth two-joint gravity field near the weight model, with per-cell σ that varies
    // so fusion weights differ from cell to cell.
    for_each_cell(|cell, g0, g1| {
        if let (Some(tq), Some(sg)) = (t.torque.get_mut(cell), t.sigma.get_mut(cell)) {
            *tq = 2.9 * math::sin(0.8 * g0 + 0.25 * g1 - 0.03) + 0.1 * g1;
            *sg = 0.1 + 0.05 * (cell % 3) as f32;
        }
    });
    t.has_sigma = true;
    p.table = t;
    p.set(ParamId::TableSigmaModel, 0.3);
    p.set(ParamId::TableClampK, 1.0);
    p
}

/// Terms of [`arm_series_residual`]'s gravity series: `(a, φ, [n_q, n_o0, n_o1, n_o2])`, the
/// shape of an arm joint's Appendix A torque expanded into sines (own angle, sums and
/// differences with the other joints' angles, one harmonic).
pub const ARM_SERIES_TERMS: [(f32, f32, [i8; 4]); 9] = [
    (3.1, 0.0, [1, 0, 0, 0]),
    (-1.2, 0.4, [1, 1, 0, 0]),
    (0.8, -0.3, [1, 1, 1, 0]),
    (0.45, 1.2, [1, 1, 1, 1]),
    (-0.6, 0.0, [1, 0, -1, 0]),
    (0.25, 2.5, [2, 0, 0, -1]),
    (0.15, -1.0, [0, 1, 2, 0]),
    (-0.3, 0.7, [1, -1, 1, -1]),
    (0.2, 0.1, [3, 0, 0, 0]),
];

/// An arm joint (arm paper): the trunk joint's friction and spring with a 9-term gravity
/// series over its own and three other joints' angles as the analytic model, and the 5 × 4
/// table of [`trunk_table_fused`] refilled with a small residual and declared the residual
/// of that model, fused with σ_m = 0.6 N·m, clamp k = 1.
pub fn arm_series_residual() -> RawParams {
    let mut p = trunk_table_fused();
    for (k, (a, ph, m)) in ARM_SERIES_TERMS.iter().enumerate() {
        if let (Some(da), Some(dp), Some(dm)) =
            (p.series.amplitude.get_mut(k), p.series.phase.get_mut(k), p.series.mult.get_mut(k))
        {
            *da = *a;
            *dp = *ph;
            *dm = *m;
        }
    }
    p.series.n_terms = ARM_SERIES_TERMS.len() as u8;
    for_each_cell(|cell, g0, g1| {
        if let Some(tq) = p.table.torque.get_mut(cell) {
            *tq = 0.4 * math::sin(1.3 * g0 - 0.5 * g1) + 0.05 * g1 - 0.2;
        }
    });
    p.table.residual = true;
    p.set(ParamId::TableSigmaModel, 0.6);
    p
}

/// [`arm_series_residual`] with one multiplier beyond ±[`crate::series::MULT_MAX`]: refused,
/// and the series in force must stay.
pub fn arm_series_bad_multiplier() -> RawParams {
    let mut p = arm_series_residual();
    if let Some(m) = p.series.mult.get_mut(4).and_then(|m| m.get_mut(2)) {
        *m = 5;
    }
    p
}

/// Pre-sliding stiffness of [`presliding_fused`], N·m/rad: with its Coulomb level
/// 2.32 + 0.3 N·m a pre-sliding distance c/σ of 3.3 mrad, a harmonic-drive-like figure.
pub const PRESLIDING_SIGMA: f32 = 800.0;

/// [`trunk_table_fused`] (the full step) with pre-sliding friction: a Dahl state of stiffness
/// [`PRESLIDING_SIGMA`] in place of c·sign(q̇), and 0.3 N·m of dry friction that joins its level.
pub fn presliding_fused() -> RawParams {
    let mut p = trunk_table_fused();
    p.set(ParamId::PreslidingSigma, PRESLIDING_SIGMA);
    p.set(ParamId::DryFrictionC, 0.3);
    p
}

/// [`presliding_fused`] with σ above its range: refused, the running set and its state stay.
pub fn presliding_sigma_out_of_range() -> RawParams {
    let mut p = presliding_fused();
    p.set(ParamId::PreslidingSigma, 2.0e7);
    p
}

/// [`trunk_spring`] with load-dependent friction (`mu·|τ_load|·sign(q̇)`, the joint's load cell
/// as the load) and a Stribeck dip beside it, so the effect terms' sum is exercised too.
pub fn trunk_load_friction() -> RawParams {
    let mut p = trunk_spring();
    p.set(ParamId::LoadFrictionMu, 0.08);
    p.set(ParamId::StribeckLevel, 0.6);
    p.set(ParamId::StribeckSpeed, 0.05);
    p
}

/// Parameter sets the core must refuse, each with a name for messages.
pub fn rejected_sets() -> [(&'static str, RawParams); 4] {
    let mut nan = trunk_right();
    nan.set(ParamId::FrictionB, f32::NAN);
    let mut range = trunk_right();
    range.set(ParamId::Fraction, 1.5);
    let mut grid = trunk_table_fused();
    // grid[1][2] = grid[1][1]: not strictly increasing.
    grid.table.grid[1][2] = grid.table.grid[1][1];
    let mut filter = trunk_right();
    filter.set(ParamId::ControlRateHz, 100.0);
    filter.set(ParamId::AccelCutoff, 60.0);
    [
        ("friction_b = NaN", nan),
        ("compensation_fraction = 1.5", range),
        ("gravity table grid not increasing", grid),
        ("accel cut-off above half the control rate", filter),
    ]
}

/// What a record is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tag {
    /// A parameter set was offered to `ActiveParams::replace`.
    Replace,
    /// One control step.
    Step,
    /// The same step through the Q16.16 controller ([`crate::fixed::ControllerFx`]), which a
    /// board built for it runs instead.
    Fixed,
}

impl Tag {
    pub const fn letter(self) -> char {
        match self {
            Tag::Replace => 'R',
            Tag::Step => 'S',
            Tag::Fixed => 'Q',
        }
    }
}

/// Words per record.
pub const WORDS: usize = 8;

/// Names of the words of a step record, for messages naming the first difference.
pub const STEP_FIELDS: [&str; WORDS] =
    ["tau_out", "u_motor", "c_c", "assist", "flags", "fixed_disturbance", "qd", "qdd"];
/// Names of the words of a Q16.16 step record.
pub const FIXED_FIELDS: [&str; WORDS] =
    ["fx_tau_out", "fx_u_motor", "fx_c_c", "fx_assist", "fx_flags", "fx_dahl_force", "unused", "unused"];
/// Names of the words of a replace record.
pub const REPLACE_FIELDS: [&str; WORDS] =
    ["result", "detail", "old_set_kept", "unused", "unused", "unused", "unused", "unused"];

/// One line of the session: a tag, a running index, and eight 32-bit words (f32 bits for
/// values, small integers for flags and error codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    pub tag: Tag,
    pub index: u32,
    pub words: [u32; WORDS],
}

impl Record {
    /// `S 000012 3f800000 ...`: the format the QEMU image prints and the host parses.
    pub fn write_line<W: core::fmt::Write>(&self, w: &mut W) -> core::fmt::Result {
        write!(w, "{} {:06}", self.tag.letter(), self.index)?;
        for word in self.words.iter() {
            write!(w, " {word:08x}")?;
        }
        w.write_char('\n')
    }

    /// Parses a line written by [`Record::write_line`] (without the newline); `None` for
    /// anything else, so stray output is noticed by the caller rather than misread.
    pub fn parse_line(line: &str) -> Option<Record> {
        let mut it = line.split_ascii_whitespace();
        let tag = match it.next()? {
            "R" => Tag::Replace,
            "S" => Tag::Step,
            "Q" => Tag::Fixed,
            _ => return None,
        };
        let index = it.next()?.parse().ok()?;
        let mut words = [0u32; WORDS];
        for w in words.iter_mut() {
            let s = it.next()?;
            if s.len() != 8 {
                return None;
            }
            *w = u32::from_str_radix(s, 16).ok()?;
        }
        if it.next().is_some() {
            return None;
        }
        Some(Record { tag, index, words })
    }

    /// Name of word `i` for this record's tag.
    pub fn field_name(&self, i: usize) -> &'static str {
        let names = match self.tag {
            Tag::Replace => &REPLACE_FIELDS,
            Tag::Step => &STEP_FIELDS,
            Tag::Fixed => &FIXED_FIELDS,
        };
        names.get(i).copied().unwrap_or("?")
    }

    fn fixed_step(index: u32, out: &Output, dahl: Fx) -> Record {
        Record { tag: Tag::Fixed, index, words: step_words(out, [dahl.to_bits() as u32, 0, 0]) }
    }

    fn step(index: u32, out: &Output, fixed: Fx, qd: f32, qdd: f32) -> Record {
        Record { tag: Tag::Step, index, words: step_words(out, [fixed.to_bits() as u32, qd.to_bits(), qdd.to_bits()]) }
    }
}

/// A step's outputs as record words: τ_out, u_motor, C_c, assist, the flags, then `rest`.
fn step_words(out: &Output, rest: [u32; 3]) -> [u32; 8] {
    let flags = u32::from(out.limited) | (u32::from(out.bad_input) << 1);
    let [a, b, c] = rest;
    [out.tau_out.to_bits(), out.u_motor.to_bits(), out.c_c.to_bits(), out.assist.to_bits(), flags, a, b, c]
}

/// Compact code of a replace result: 0 = accepted, otherwise 1 + the error kind.
pub fn result_code(r: &Result<(), ParamError>) -> (u32, u32) {
    match r {
        Ok(()) => (0, 0),
        Err(ParamError::NotFinite { param }) => (1, *param as u32),
        Err(ParamError::OutOfRange { param, .. }) => (2, *param as u32),
        Err(ParamError::Inconsistent { param, .. }) => (3, *param as u32),
        Err(ParamError::Table(e)) => (4, table_error_code(e)),
        Err(ParamError::Series(e)) => (5, series_error_code(e)),
    }
}

fn series_error_code(e: &SeriesError) -> u32 {
    match *e {
        SeriesError::TooManyTerms { n_terms } => 0x100 | u32::from(n_terms),
        SeriesError::Amplitude { term } => 0x200 | u32::from(term),
        SeriesError::Phase { term } => 0x300 | u32::from(term),
        SeriesError::Multiplier { term, slot } => 0x400 | (u32::from(term) << 4) | u32::from(slot),
    }
}

fn table_error_code(e: &TableError) -> u32 {
    match *e {
        TableError::AxisCount { .. } => 1,
        TableError::AxisSource { .. } => 2,
        TableError::Points { .. } => 3,
        TableError::TooManyCells { .. } => 4,
        TableError::GridNotFinite { .. } => 5,
        TableError::GridNotIncreasing { axis, index } => 0x600 | (u32::from(axis) << 4) | u32::from(index),
        TableError::TorqueNotFinite { .. } => 7,
        TableError::SigmaNotPositive { .. } => 8,
    }
}

/// What the session saw, beyond the records: the facts the checks assert.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    pub records: u32,
    pub steps: u32,
    pub accepted: u32,
    pub rejected: u32,
    /// Refused sets after which the set in force was not exactly the previous one.
    pub rejected_but_changed: u32,
    /// Sets that should have been accepted but were refused (or vice versa).
    pub unexpected_results: u32,
    /// Steps whose outputs were not finite or exceeded the torque limit.
    pub unsafe_outputs: u32,
}

/// One random step input. Mostly the trunk joint's working range, with occasional
/// standstill, huge and non-finite samples to exercise the clamps and the bad-input path.
pub fn random_input(rng: &mut XorShift32) -> (Mode, Input) {
    let mut inp = Input {
        q: rng.uniform(-0.3, 2.3),
        qd: rng.uniform(-2.5, 2.5),
        qdd: rng.uniform(-20.0, 20.0),
        others: [rng.uniform(-1.2, 2.2), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)],
        assist_cmd: rng.uniform(-5.0, 5.0),
        tau_load: 0.0,
    };
    match rng.next_u32() % 32 {
        0 => inp.qd = 0.0,
        1 => inp.qd = rng.uniform(-0.01, 0.01), // inside the friction sign band
        2 => inp.q = 1.0e4,                     // beyond the input clamp
        3 => inp.qd = f32::NAN,
        4 => inp.qdd = f32::INFINITY,
        _ => {}
    }
    let mode = match rng.next_u32() % 8 {
        0 => Mode::Off,
        1 => Mode::Velocity(rng.uniform(-1.0, 1.0)),
        2 => Mode::Position(rng.uniform(0.0, 2.0)),
        _ => Mode::Assist,
    };
    (mode, inp)
}

struct Runner<'a, F: FnMut(&Record)> {
    sink: &'a mut F,
    rng: XorShift32,
    active: ActiveParams,
    ctl: Controller,
    ctl_fx: ControllerFx,
    fixed: FixedParams,
    fixed_dahl: DahlFx,
    summary: Summary,
}

impl<F: FnMut(&Record)> Runner<'_, F> {
    fn emit(&mut self, r: Record) {
        self.summary.records = self.summary.records.saturating_add(1);
        (self.sink)(&r);
    }

    fn offer(&mut self, raw: &RawParams, expect_ok: bool) {
        let before = self.active.current().clone();
        let result = self.active.replace(raw);
        let (code, detail) = result_code(&result);
        let kept = *self.active.current() == before;
        match result {
            Ok(()) => {
                self.summary.accepted += 1;
                self.fixed = FixedParams::from_set(self.active.current());
                self.fixed_dahl = DahlFx::new();
                self.ctl.reset();
                self.ctl.reset_presliding();
                self.ctl_fx.configure(self.active.current());
                self.ctl_fx.reset();
            }
            Err(_) => {
                self.summary.rejected += 1;
                if !kept {
                    self.summary.rejected_but_changed += 1;
                }
            }
        }
        if result.is_ok() != expect_ok {
            self.summary.unexpected_results += 1;
        }
        let index = self.summary.records;
        self.emit(Record { tag: Tag::Replace, index, words: [code, detail, u32::from(kept), 0, 0, 0, 0, 0] });
    }

    fn step(&mut self, mode: Mode, inp: &Input) {
        let p = self.active.current();
        let dt = 1.0 / p.get(ParamId::ControlRateHz);
        let out = self.ctl.step(p, mode, inp, dt);
        let limit = p.get(ParamId::TorqueLimit);
        if !(math::is_finite(out.tau_out) && math::is_finite(out.u_motor) && math::abs(out.tau_out) <= limit) {
            self.summary.unsafe_outputs += 1;
        }
        let fx = fixed::disturbance_stateful_fx(&self.fixed, &mut self.fixed_dahl, to_fx(inp.q), to_fx(inp.qd));
        self.summary.steps += 1;
        let index = self.summary.records;
        self.emit(Record::step(index, &out, fx, inp.qd, inp.qdd));
        let out = self.ctl_fx.step(self.active.current(), mode, inp, dt);
        let index = self.summary.records;
        self.emit(Record::fixed_step(index, &out, self.ctl_fx.presliding().force()));
    }

    fn random_steps(&mut self, n: u32) {
        for _ in 0..n {
            let (mode, inp) = random_input(&mut self.rng);
            self.step(mode, &inp);
        }
    }

    /// Random steps with a measured load: the load cell's working range, a load at rest, and
    /// the values a failed load cell gives (non-finite: no load; beyond the input limit).
    fn load_steps(&mut self, n: u32) {
        for _ in 0..n {
            let (mode, mut inp) = random_input(&mut self.rng);
            inp.tau_load = match self.rng.next_u32() % 16 {
                0 => 0.0,
                1 => f32::NAN,
                2 => f32::NEG_INFINITY,
                3 => 3.0e4,
                _ => self.rng.uniform(-60.0, 60.0),
            };
            self.step(mode, &inp);
        }
    }

    /// Encoder-like positions (a slow swing plus quantisation-sized noise) differentiated
    /// twice by the core's filter, as the firmware's loop does.
    fn differentiated_steps(&mut self, n: u32) {
        let p = self.active.current();
        let rate = p.get(ParamId::ControlRateHz);
        let dt = 1.0 / rate;
        let accel_cutoff = p.get(ParamId::AccelCutoff);
        let vel_cutoff = velocity_cutoff_hz(rate);
        let mut dq = Differentiator::new();
        let mut dqd = Differentiator::new();
        for i in 0..n {
            let t = i as f32 * dt;
            let q = 0.9 + 0.8 * math::sin(2.0 * core::f32::consts::PI * 0.7 * t) + self.rng.uniform(-2.0e-4, 2.0e-4);
            let qd = dq.update(q, dt, vel_cutoff);
            let qdd = dqd.update(qd, dt, accel_cutoff);
            let others = [self.rng.uniform(-1.0, 2.0), 0.0, 0.0];
            let inp = Input { q, qd, qdd, others, ..Input::default() };
            self.step(Mode::Assist, &inp);
        }
    }

    /// Steps that exercise the Dahl state: `q(i)` with its exact derivative `qd(i)`, in `mode`.
    fn path(&mut self, n: u32, mode: Mode, q: impl Fn(f32) -> f32, qd: impl Fn(f32) -> f32) {
        for i in 0..n {
            let x = i as f32;
            let inp = Input { q: q(x), qd: qd(x), others: [0.4, 0.0, 0.0], ..Input::default() };
            self.step(mode, &inp);
        }
    }

    /// The presliding phase's motions, in order (the state carries over from one to the next).
    fn presliding_steps(&mut self) {
        const TAU: f32 = 2.0 * core::f32::consts::PI;
        // Primed while sliding (F starts at +c), then a swing of ±50 mrad, period 64 steps:
        // up to 4.9 mrad per step against a pre-sliding distance of 3.3 mrad, four reversals.
        let w = TAU / 64.0;
        self.path(128, Mode::Assist, |i| 0.9 + 0.05 * math::sin(w * i), |i| 0.05 * w * 1000.0 * math::cos(w * i));
        // Oscillation of ±0.5 mrad inside the pre-sliding distance: F on a hysteresis loop,
        // never reaching ±c; a few steps without travel in between.
        let w = TAU / 16.0;
        self.path(48, Mode::Assist, |i| 0.95 + 5.0e-4 * math::sin(w * i), |i| 5.0e-4 * w * 1000.0 * math::cos(w * i));
        self.path(4, Mode::Assist, |_| 0.95, |_| 0.0);
        // The state runs on in the other modes.
        self.path(8, Mode::Off, |i| 0.95 - 1.0e-3 * i, |_| -1.0);
        self.path(8, Mode::Velocity(0.5), |i| 0.942 + 1.0e-3 * i, |_| 1.0);
        self.path(8, Mode::Position(1.0), |i| 0.95 + 2.0e-4 * i, |_| 0.2);
        // Large steps (F at ±c at once, never beyond), the input clamp, bad samples that leave
        // the state as it is.
        let big = [1.5, -0.2, -0.2, 2.1, 1.0e4, 2.1, f32::NAN, 2.0999, 2.1001, -1.0e4, 0.3];
        for (k, &q) in big.iter().enumerate() {
            let qd = if k == 4 { f32::INFINITY } else { 0.0 };
            self.step(Mode::Assist, &Input { q, qd, others: [0.4, 0.0, 0.0], ..Input::default() });
        }
        self.random_steps(STEPS_PER_PHASE / 2);
    }
}

/// f32 → Q16.16 for the fixed path's inputs. `saturating_from_num` panics on NaN, so a
/// non-finite sample becomes 0 here, as a board without an FPU would never produce one.
pub fn to_fx(x: f32) -> Fx {
    if math::is_finite(x) {
        Fx::saturating_from_num(x)
    } else {
        Fx::ZERO
    }
}

/// Cut-off of the velocity estimate from encoder positions: 100 Hz, but always below a
/// fifth of the loop rate so the filter stays well inside Nyquist at slow rates. The
/// firmware's loop uses this same function.
pub fn velocity_cutoff_hz(rate_hz: f32) -> f32 {
    math::clamp(0.2 * rate_hz, 1.0, 100.0)
}

/// Runs the scripted session, handing every record to `sink` in order.
pub fn session<F: FnMut(&Record)>(sink: &mut F) -> Summary {
    let mut r = Runner {
        sink,
        rng: XorShift32::new(SESSION_SEED),
        active: ActiveParams::default(),
        ctl: Controller::new(),
        ctl_fx: ControllerFx::default(),
        fixed: FixedParams::default(),
        fixed_dahl: DahlFx::new(),
        summary: Summary::default(),
    };
    // Defaults first: fraction 0, so only limits and the velocity/position modes act.
    r.random_steps(STEPS_PER_PHASE / 4);
    r.offer(&trunk_right(), true);
    r.random_steps(STEPS_PER_PHASE);
    for (_, bad) in rejected_sets().iter() {
        r.offer(bad, false);
        r.random_steps(STEPS_PER_PHASE / 4);
    }
    r.offer(&trunk_spring(), true);
    r.random_steps(STEPS_PER_PHASE);
    r.offer(&trunk_table_fused(), true);
    r.random_steps(STEPS_PER_PHASE);
    // A refused set while the table is in force: the table must stay.
    if let Some((_, grid)) = rejected_sets().get(2) {
        r.offer(grid, false);
    }
    r.random_steps(STEPS_PER_PHASE / 4);
    // The arm joint: gravity series over four angles, the table as its residual.
    r.offer(&arm_series_residual(), true);
    r.random_steps(STEPS_PER_PHASE);
    r.offer(&arm_series_bad_multiplier(), false);
    r.random_steps(STEPS_PER_PHASE / 4);
    r.differentiated_steps(DIFF_STEPS);
    // Pre-sliding friction: the Dahl state, then a refused σ while it runs.
    r.offer(&presliding_fused(), true);
    r.presliding_steps();
    r.offer(&presliding_sigma_out_of_range(), false);
    r.path(32, Mode::Assist, |i| 0.3 + 1.0e-3 * math::sin(0.4 * i), |i| 0.4 * math::cos(0.4 * i));
    // Load-dependent friction on the load cell's reading (appended: the phases above keep their
    // random draws).
    r.offer(&trunk_load_friction(), true);
    r.load_steps(STEPS_PER_PHASE);
    r.summary
}

/// The first place two record streams differ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mismatch {
    /// Record `index` differs in word `word` (named by [`Record::field_name`]).
    Word { index: u32, word: usize, expected: u32, actual: u32 },
    /// Tags or indices differ at position `position`.
    Shape { position: usize },
    /// One stream is shorter.
    Length { expected: usize, actual: usize },
}

/// Compares two record streams word by word; `None` when identical.
pub fn first_mismatch(expected: &[Record], actual: &[Record]) -> Option<Mismatch> {
    for (pos, (e, a)) in expected.iter().zip(actual.iter()).enumerate() {
        if e.tag != a.tag || e.index != a.index {
            return Some(Mismatch::Shape { position: pos });
        }
        for (w, (ew, aw)) in e.words.iter().zip(a.words.iter()).enumerate() {
            if ew != aw {
                return Some(Mismatch::Word { index: e.index, word: w, expected: *ew, actual: *aw });
            }
        }
    }
    if expected.len() != actual.len() {
        return Some(Mismatch::Length { expected: expected.len(), actual: actual.len() });
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::check;

    struct Buf {
        s: [u8; 128],
        n: usize,
    }
    impl core::fmt::Write for Buf {
        fn write_str(&mut self, s: &str) -> core::fmt::Result {
            let end = self.n + s.len();
            self.s.get_mut(self.n..end).ok_or(core::fmt::Error)?.copy_from_slice(s.as_bytes());
            self.n = end;
            Ok(())
        }
    }

    #[test]
    fn session_facts() {
        let s = session(&mut |_| {});
        assert_eq!(s.accepted, 6);
        assert_eq!(s.rejected, 7);
        assert_eq!(s.rejected_but_changed, 0);
        assert_eq!(s.unexpected_results, 0);
        assert_eq!(s.unsafe_outputs, 0);
        assert_eq!(s.records, 2 * s.steps + 13);
    }

    #[test]
    fn session_is_deterministic_and_uses_every_path() {
        let mut a = [0u64; 4];
        let mut first = None;
        let mut saw = (false, false, false, false); // limited, bad input, replace ok, replace err
        session(&mut |r: &Record| {
            a[0] = a[0].wrapping_mul(31).wrapping_add(r.words.iter().map(|&w| w as u64).sum::<u64>());
            if first.is_none() {
                first = Some(*r);
            }
            match r.tag {
                Tag::Step => {
                    saw.0 |= r.words[4] & 1 != 0;
                    saw.1 |= r.words[4] & 2 != 0;
                }
                Tag::Fixed => {}
                Tag::Replace => {
                    saw.2 |= r.words[0] == 0;
                    saw.3 |= r.words[0] != 0;
                }
            }
        });
        let mut b = 0u64;
        session(&mut |r: &Record| {
            b = b.wrapping_mul(31).wrapping_add(r.words.iter().map(|&w| w as u64).sum::<u64>());
        });
        assert_eq!(a[0], b);
        assert_eq!(saw, (true, true, true, true));
    }

    #[test]
    fn arm_phase_runs_the_series_and_the_residual_table() {
        let arm = check(&arm_series_residual()).unwrap();
        let plain = check(&trunk_table_fused()).unwrap();
        let g = |p, o2: f32| crate::control::gravity(p, 0.8, &[0.3, -0.4, o2]);
        // Only the series reads the third other joint; the table differs as well.
        assert!(g(&arm, 0.7) != g(&arm, -0.2));
        assert_eq!(g(&plain, 0.7).to_bits(), g(&plain, -0.2).to_bits());
        assert!(arm.table().residual && !plain.table().residual);
    }

    #[test]
    fn builders_pass_check_and_rejects_fail() {
        for raw in [
            trunk_right(),
            friction_weight_only(),
            trunk_spring(),
            trunk_table_fused(),
            arm_series_residual(),
            presliding_fused(),
        ] {
            assert!(check(&raw).is_ok());
        }
        assert!(check(&arm_series_bad_multiplier()).is_err());
        assert!(check(&presliding_sigma_out_of_range()).is_err());
        for (name, raw) in rejected_sets().iter() {
            assert!(check(raw).is_err(), "{name} was accepted");
        }
    }

    #[test]
    fn line_round_trip_and_refusals() {
        let r = Record { tag: Tag::Step, index: 42, words: [1, 0xdeadbeef, 3, 4, 5, 6, 7, 0xffffffff] };
        let mut buf = Buf { s: [0; 128], n: 0 };
        r.write_line(&mut buf).unwrap();
        let line = core::str::from_utf8(&buf.s[..buf.n]).unwrap();
        assert_eq!(Record::parse_line(line.trim_end()), Some(r));
        assert_eq!(Record::parse_line("S 000001 00000001"), None);
        assert_eq!(Record::parse_line("X 000001 0 0 0 0 0 0 0 0"), None);
        assert_eq!(Record::parse_line(&line.replace("deadbeef", "deadbeeg")), None);
    }

    #[test]
    fn mismatch_names_the_first_difference() {
        let mut exp = [Record { tag: Tag::Step, index: 0, words: [0; WORDS] }; 3];
        for (i, r) in exp.iter_mut().enumerate() {
            r.index = i as u32;
        }
        let mut act = exp;
        assert_eq!(first_mismatch(&exp, &act), None);
        act[1].words[2] ^= 1;
        act[2].words[0] ^= 1;
        assert_eq!(first_mismatch(&exp, &act), Some(Mismatch::Word { index: 1, word: 2, expected: 0, actual: 1 }));
        assert_eq!(act[1].field_name(2), "c_c");
        assert_eq!(first_mismatch(&exp, &exp[..2]), Some(Mismatch::Length { expected: 3, actual: 2 }));
    }

    #[test]
    fn xorshift_known_sequence() {
        // Reference values of Marsaglia's xorshift32 (13, 17, 5) from seed 1.
        let mut g = XorShift32::new(1);
        assert_eq!(g.next_u32(), 270_369);
        assert_eq!(g.next_u32(), 67_634_689);
        let u = XorShift32::new(7).unit();
        assert!((0.0..1.0).contains(&u));
    }
}
