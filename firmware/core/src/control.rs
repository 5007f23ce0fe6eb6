//! The control step: the compensation law of the trunk paper (eq. 6–8), plus the velocity and
//! position modes the characterisation tests need, torque and rate limits, and a filtered
//! differentiator for the encoder.
//!
//! `C_c = J·q̈ + C_β(q̇) + gravity(q, …) + C_0 + spring(q, q̇)`, where gravity is the model
//! (weight term plus the analytic gravity series), the model plus the table, or the model fused
//! with the table (see [`gravity`]).
//! In assist mode the output torque is `assist_k·q + assist_cmd + fraction·C_c`, limited to
//! ±torque_limit and to rate_limit·dt per step; the motor command is that torque / (N − 1).
//!
//! With `presliding.sigma > 0` the controller carries one Dahl friction state ([`Dahl`], see
//! [`crate::model::Presliding`]) that stands in for the Coulomb terms: it is advanced to every
//! valid sample in every mode (it is the joint's friction, not the controller's intent), so a
//! mode change keeps it; it starts afresh when a parameter set is put in force
//! ([`Controller::reset_presliding`]: σ or c may have changed, and a state from before
//! presliding was switched on would be stale), primed at its first sample with the value the
//! Coulomb term itself has there. [`disturbance_stateful`] is the controller's own `C_c`, for
//! hosts that evaluate a model sample by sample on a log.
//!
//! The step is sans-IO and allocation-free: time (dt) and samples in, torques out. It clamps
//! its inputs to [`INPUT_LIMITS`] and treats a non-finite input as a fault that drives the
//! command to zero, so no input can produce a NaN or an unbounded torque.

use crate::math;
use crate::model::{Presliding, INPUT_LIMITS};
use crate::params::{ParamId, ParamSet};
use crate::series;
use crate::table;

/// Largest host assist command accepted as is, N·m (larger finite values are clamped to it).
const CMD_MAX: f32 = 1.0e6;
/// Longest step accepted, s; a longer or non-finite dt freezes the rate limiter for a step.
const DT_MAX: f32 = 1.0;
const Q_BITS: u32 = INPUT_LIMITS.q.to_bits();
const QD_BITS: u32 = INPUT_LIMITS.qd.to_bits();
const QDD_BITS: u32 = INPUT_LIMITS.qdd.to_bits();
const CMD_BITS: u32 = CMD_MAX.to_bits();
const DT_MAX_BITS: u32 = DT_MAX.to_bits();

/// `|x| ≤ limit` for a positive finite limit given as bits; false for NaN and ±∞. Branch-free.
#[inline(always)]
fn within(x: f32, limit_bits: u32) -> bool {
    (x.to_bits() & 0x7fff_ffff) <= limit_bits
}

/// What the joint is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// zero torque
    Off,
    /// the compensation law (the product's normal mode)
    Assist,
    /// PI velocity control with model feed-forward, rad/s (friction sweeps, trunk paper §3.2)
    Velocity(f32),
    /// PD position hold with gravity feed-forward, rad (static poses, trunk paper §3.3)
    Position(f32),
}

/// One sample of the joint's state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Input {
    /// joint angle, rad
    pub q: f32,
    /// joint velocity, rad/s
    pub qd: f32,
    /// joint acceleration, rad/s²
    pub qdd: f32,
    /// angles of other joints feeding a multi-joint gravity table, rad
    pub others: [f32; 3],
    /// extra support torque from the host, N·m at the output
    pub assist_cmd: f32,
    /// the load the joint transmits as its load cell measures it, N·m at the output (0 without
    /// one); only the load-dependent friction reads it
    pub tau_load: f32,
}

/// Result of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Output {
    /// torque at the joint output after torque and rate limits, N·m
    pub tau_out: f32,
    /// motor torque command `tau_out/(N − 1)`, N·m
    pub u_motor: f32,
    /// the modelled disturbance C_c at this sample, N·m
    pub c_c: f32,
    /// the desired support torque, N·m
    pub assist: f32,
    /// the torque or rate limit was active
    pub limited: bool,
    /// an input was NaN/∞ and the command was driven to zero
    pub bad_input: bool,
}

/// Gravity torque. The model side `τ_m` is the weight term plus the analytic gravity series
/// ([`crate::series`], over `[q, others…]`); with a table present it is combined with the table:
/// - `sigma_model = 0`: `τ_m + table` (the table as a term);
/// - `sigma_model > 0`: inverse-variance fusion with the clamp `τ_m ± k·σ_m` (arm paper
///   §3.2.3), where the data estimate is the table itself, or `τ_m + table` when the table is
///   declared the model's residual ([`crate::table::RawTable::residual`]).
///
/// An empty series adds nothing (not even `+ 0.0`, which would turn a −0 weight torque into +0),
/// so sets without one keep their exact bits.
#[inline(always)]
pub fn gravity(p: &ParamSet, q: f32, others: &[f32; 3]) -> f32 {
    let w = p.terms().weight.torque(q);
    let [o0, o1, o2] = *others;
    let s = p.series();
    let tau_m = if s.n_terms == 0 { w } else { w + series::eval(s, &[q, o0, o1, o2]) };
    // The table's shape and flags come from the Lut (precomputed next to what the lookup reads).
    let lut = p.lut();
    if lut.n_axes() == 0 {
        return tau_m;
    }
    let sigma_m = p.get(ParamId::TableSigmaModel);
    let fused = sigma_m > 0.0;
    let (tau_t, sigma_t) = lut.eval_sources(p.table(), &[q, o0, o1, o2], fused);
    if fused {
        let data = if lut.residual() { tau_m + tau_t } else { tau_t };
        table::fuse(tau_m, sigma_m, data, sigma_t, p.get(ParamId::TableClampK))
    } else {
        tau_m + tau_t
    }
}

/// The modelled disturbance `C_c` (trunk paper eq. 7, with spring and table terms): the torque
/// the joint's own mechanics take at this state, `load` the measured load (N·m; a
/// load-dependent friction grows with it). In torque-mode logs this is `u − tau`, and `load`
/// is `tau`. Stateless: with presliding on, the Coulomb terms are `c·sign(q̇)` with the Dahl
/// level c (`friction.c + dry_friction.c`), the value the Dahl state reaches after a travel
/// well beyond `c/σ`; the controller uses [`disturbance_stateful`].
#[inline]
pub fn disturbance(p: &ParamSet, q: f32, qd: f32, qdd: f32, others: &[f32; 3], load: f32) -> f32 {
    let t = p.terms();
    let c = if t.presliding.on { t.presliding.c } else { t.friction.c };
    with_coulomb(p, q, qd, qdd, others, load, c * math::sign_smooth(qd, t.friction.v_band))
}

/// The modelled disturbance with a Dahl friction state `f` (N·m) in place of the Coulomb
/// terms `friction.c·sign(q̇)` and `dry_friction.c·sign(q̇)`: what the model is when
/// presliding is on (`p`'s effect terms then hold no dry friction). `f` comes from a [`Dahl`]
/// advanced to this sample.
#[inline]
pub fn disturbance_dahl(p: &ParamSet, q: f32, qd: f32, qdd: f32, others: &[f32; 3], load: f32, f: f32) -> f32 {
    with_coulomb(p, q, qd, qdd, others, load, f)
}

/// `C_c` exactly as [`Controller::step`] computes it: with presliding off [`disturbance`] (and
/// `dahl` untouched), else `dahl` advanced to this sample and [`disturbance_dahl`]. Feed the
/// samples of a log in order through one `Dahl` (from [`Dahl::new`]) and the numbers are the
/// joint's, bit for bit; the state makes the prediction depend on every earlier sample.
#[inline]
pub fn disturbance_stateful(
    p: &ParamSet,
    dahl: &mut Dahl,
    q: f32,
    qd: f32,
    qdd: f32,
    others: &[f32; 3],
    load: f32,
) -> f32 {
    let t = p.terms();
    // One branch when off (the full step's instruction budget has no room for more): only the
    // Coulomb torque differs between the two models.
    let coulomb =
        if t.presliding.on { dahl.update(p, q, qd) } else { t.friction.c * math::sign_smooth(qd, t.friction.v_band) };
    with_coulomb(p, q, qd, qdd, others, load, coulomb)
}

/// `C_c` with the Coulomb torque `coulomb` (c·sign(q̇) or a Dahl state) given. `viscous +
/// coulomb` is the friction polynomial's own association, so with `c·sign(q̇)` the bits are
/// [`crate::model::Friction::torque`]'s.
#[inline(always)]
fn with_coulomb(p: &ParamSet, q: f32, qd: f32, qdd: f32, others: &[f32; 3], load: f32, coulomb: f32) -> f32 {
    let t = p.terms();
    t.j * qdd
        + (t.friction.viscous(qd) + coulomb)
        + gravity(p, q, others)
        + t.c0
        + t.spring.torque(q, qd)
        + t.extra_torque(q, qd, load)
}

/// The Dahl friction state between samples: F and the angle it was advanced to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dahl {
    f: f32,
    q_prev: f32,
    primed: bool,
}

impl Dahl {
    /// A state with no history: its first [`Dahl::update`] primes it.
    pub const fn new() -> Self {
        Dahl { f: 0.0, q_prev: 0.0, primed: false }
    }

    /// F, N·m (0 before the first update).
    #[inline]
    pub fn force(&self) -> f32 {
        self.f
    }

    /// Advance to the sample (q, q̇) with `p`'s presliding parameters and return F. The first
    /// sample primes the state with the Coulomb term's own value there, `c·sign(q̇)` with the
    /// friction band: 0 at rest, ±c while sliding, so a state switched on or reset while the
    /// joint moves starts where the sign model stands instead of at 0. After that only the
    /// angle counts (see [`Presliding::advance`]). A non-finite sample leaves the state as is.
    /// Out of line: inlined, its registers would cost the common step (presliding off).
    #[inline(never)]
    pub fn update(&mut self, p: &ParamSet, q: f32, qd: f32) -> f32 {
        let t = p.terms();
        self.update_with(&t.presliding, t.friction.v_band, q, qd)
    }

    /// [`Dahl::update`] with the parameters given directly.
    pub fn update_with(&mut self, pre: &Presliding, v_band: f32, q: f32, qd: f32) -> f32 {
        if !(math::is_finite(q) && math::is_finite(qd)) {
            return self.f;
        }
        self.f = if self.primed {
            pre.advance(self.f, q - self.q_prev)
        } else {
            self.primed = true;
            math::clamp(pre.c * math::sign_smooth(qd, v_band), -pre.c, pre.c)
        };
        self.q_prev = q;
        self.f
    }
}

/// The Dahl state over a sequence of samples from a fresh start: `out[i]` is F after
/// `(q[i], qd[i])`. Stops at the shortest of the three slices. The same [`Dahl::update`] the
/// controller runs, so the numbers are the joint's.
pub fn presliding_forces(p: &ParamSet, q: &[f32], qd: &[f32], out: &mut [f32]) {
    let mut d = Dahl::new();
    for ((o, &x), &v) in out.iter_mut().zip(q).zip(qd) {
        *o = d.update(p, x, v);
    }
}

/// The controller's memory between steps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Controller {
    prev_tau: f32,
    integ: f32,
    dahl: Dahl,
}

impl Controller {
    pub const fn new() -> Self {
        Controller { prev_tau: 0.0, integ: 0.0, dahl: Dahl::new() }
    }

    /// Forget the integrator and the last output (after a fault or a mode change). The Dahl
    /// friction state stays: it describes the joint, which a mode change does not touch.
    pub fn reset(&mut self) {
        self.prev_tau = 0.0;
        self.integ = 0.0;
    }

    /// Start the Dahl friction state afresh (primed again at the next step): call it when a
    /// new parameter set is put in force, whose σ or Coulomb level may differ.
    pub fn reset_presliding(&mut self) {
        self.dahl = Dahl::new();
    }

    /// The Dahl friction state (F stays 0 while presliding is off).
    pub fn presliding(&self) -> &Dahl {
        &self.dahl
    }

    /// The output torque of the previous step, N·m.
    pub fn last_output(&self) -> f32 {
        self.prev_tau
    }

    /// One control step of length `dt` seconds.
    pub fn step(&mut self, p: &ParamSet, mode: Mode, inp: &Input, dt: f32) -> Output {
        // 0 < dt ≤ DT_MAX in one unsigned compare: positive floats order like their bits, and a
        // negative or NaN dt has bits above DT_MAX's.
        let dt = if dt.to_bits().wrapping_sub(1) < DT_MAX_BITS { dt } else { 0.0 };
        let limit = p.get(ParamId::TorqueLimit);

        // Fast path: one integer compare per input proves it finite and inside the limits
        // (|x|'s bit pattern orders like |x|, and NaN/∞ sort above every finite limit).
        let [o0, o1, o2] = inp.others;
        let in_range = within(inp.q, Q_BITS)
            & within(inp.qd, QD_BITS)
            & within(inp.qdd, QDD_BITS)
            & within(o0, Q_BITS)
            & within(o1, Q_BITS)
            & within(o2, Q_BITS)
            & within(inp.assist_cmd, CMD_BITS);
        let sane = if in_range {
            Some(*inp)
        } else if math::is_finite(inp.q)
            && math::is_finite(inp.qd)
            && math::is_finite(inp.qdd)
            && math::is_finite(inp.assist_cmd)
            && inp.others.iter().all(|&o| math::is_finite(o))
        {
            let lim = &INPUT_LIMITS;
            Some(Input {
                q: math::clamp(inp.q, -lim.q, lim.q),
                qd: math::clamp(inp.qd, -lim.qd, lim.qd),
                qdd: math::clamp(inp.qdd, -lim.qdd, lim.qdd),
                others: [
                    math::clamp(o0, -lim.q, lim.q),
                    math::clamp(o1, -lim.q, lim.q),
                    math::clamp(o2, -lim.q, lim.q),
                ],
                assist_cmd: math::clamp(inp.assist_cmd, -CMD_MAX, CMD_MAX),
                tau_load: inp.tau_load,
            })
        } else {
            None
        };

        let bad_input = sane.is_none();
        let (target, c_c, assist) = match sane {
            None => {
                self.integ = 0.0;
                (0.0, 0.0, 0.0)
            }
            Some(Input { q, qd, qdd, others, assist_cmd, tau_load }) => {
                let c_c = disturbance_stateful(p, &mut self.dahl, q, qd, qdd, &others, tau_load);
                match mode {
                    Mode::Off => {
                        self.integ = 0.0;
                        (0.0, c_c, 0.0)
                    }
                    Mode::Assist => {
                        self.integ = 0.0;
                        let assist = p.get(ParamId::AssistK) * q + assist_cmd;
                        (assist + p.get(ParamId::Fraction) * c_c, c_c, assist)
                    }
                    Mode::Velocity(v) => {
                        let v =
                            if math::is_finite(v) { math::clamp(v, -INPUT_LIMITS.qd, INPUT_LIMITS.qd) } else { 0.0 };
                        let t = p.terms();
                        let err = v - qd;
                        // Anti-windup: the integrator alone can never ask for more than the limit.
                        self.integ = math::clamp(self.integ + p.get(ParamId::VelKi) * err * dt, -limit, limit);
                        // With presliding the Coulomb part of the feed-forward is the Dahl state.
                        let fric = if t.presliding.on {
                            t.friction.viscous(v) + self.dahl.force()
                        } else {
                            t.friction.torque(v)
                        };
                        let ff = fric
                            + gravity(p, q, &others)
                            + t.c0
                            + t.spring.torque(q, v)
                            + t.extra_torque(q, v, tau_load);
                        (p.get(ParamId::VelKp) * err + self.integ + ff, c_c, 0.0)
                    }
                    Mode::Position(x) => {
                        self.integ = 0.0;
                        let x = if math::is_finite(x) { math::clamp(x, -INPUT_LIMITS.q, INPUT_LIMITS.q) } else { q };
                        let t = p.terms();
                        let ff =
                            gravity(p, q, &others) + t.c0 + t.spring.torque(q, 0.0) + t.extra_torque(q, 0.0, tau_load);
                        (p.get(ParamId::PosKp) * (x - q) - p.get(ParamId::PosKd) * qd + ff, c_c, 0.0)
                    }
                }
            }
        };

        let limited_target = math::clamp(target, -limit, limit);
        let step_max = p.get(ParamId::RateLimit) * dt;
        // The previous output and the limited target both lie within ±limit, and a rate-limited
        // step stops short of the target (rounding to nearest cannot cross a representable
        // bound), so the result needs no second clamp.
        let up = self.prev_tau + step_max;
        let down = self.prev_tau - step_max;
        let tau = if limited_target > up {
            up
        } else if limited_target < down {
            down
        } else {
            limited_target
        };
        self.prev_tau = tau;
        // Built once, here, from the law's values (zeroed first and filled in as the law ran, it
        // cost the M4F step 2 instructions more). The output differs from the law's target
        // exactly when a limit acted: a torque-limited target lies outside ±limit where the
        // output cannot be, and a rate-limited output stops short of the (possibly limited)
        // target.
        Output { tau_out: tau, u_motor: tau * p.inv_ratio_m1(), c_c, assist, limited: tau != target, bad_input }
    }
}

/// Derivative of a sampled signal through a first-order low-pass (a "dirty derivative"):
/// `y ← y + α·((x − x_prev)/dt − y)`, `α = dt/(dt + 1/(2π·f_c))`. Used for q̇ from encoder
/// counts and for q̈ from q̇; the cut-off trades noise for lag (the trunk paper low-passed at
/// 2 Hz offline; online the default is 20 Hz).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Differentiator {
    prev: f32,
    y: f32,
    primed: bool,
}

impl Differentiator {
    pub const fn new() -> Self {
        Differentiator { prev: 0.0, y: 0.0, primed: false }
    }

    /// Feed the next sample `x` taken `dt` s after the previous one; returns the filtered
    /// derivative. The first sample only primes the filter (returns 0). Non-finite samples or a
    /// non-positive dt leave the state unchanged and return the last estimate.
    pub fn update(&mut self, x: f32, dt: f32, cutoff_hz: f32) -> f32 {
        if !(math::is_finite(x) && math::is_finite(dt) && dt > 0.0) {
            return self.y;
        }
        if !self.primed {
            self.prev = x;
            self.primed = true;
            return self.y;
        }
        let raw = (x - self.prev) / dt;
        self.prev = x;
        let tau = 1.0 / (2.0 * core::f32::consts::PI * math::clamp(cutoff_hz, 1.0e-3, 1.0e6));
        let alpha = dt / (dt + tau);
        let y = self.y + alpha * (raw - self.y);
        if math::is_finite(y) {
            self.y = y;
        }
        self.y
    }

    pub fn value(&self) -> f32 {
        self.y
    }

    pub fn reset(&mut self) {
        *self = Self::new();
    }
}
