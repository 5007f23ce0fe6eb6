//! The candidate terms of torque mode: every effect of the vocabulary as regressor columns added
//! to the model's own (refittable) terms, with the parametrisation of the plant's effect sections (the shapes
//! themselves are this crate's own, [`super::shapes`]) so a fitted candidate is a plant section as it is.
//!
//! The model's prediction of `d = u − tau` splits into a part linear in the model's coefficients
//! (`J·q̈`, `a·q̇|q̇|`, `b·q̇`, `c·sgn(q̇)`, the weight as `α·sin(s·q) + β·cos(s·q)` at the model's
//! `s`, `k·q`, a constant for `c0 − k·q0`) and a fixed rest (gravity table, rounding of the f32
//! core): `y = d − rest` is what every fit explains. A term the model does not have (its value
//! is 0) is not refitted: `parameters` means "the model's own terms with other values".
//!
//! Effects with a shape parameter (Stribeck speed, ripple period, cable engagement, backlash
//! width, delay, thermal time constant) have it searched on a grid over a thinned training set,
//! then refined by golden section; the amplitudes are linear and solved exactly each time.

use super::fit::{golden, Gram};
use joint_formats::vocab::Effect as Vocab;

/// The log columns and derived series one torque-mode diagnosis works on.
#[derive(Clone, Debug)]
pub struct Data {
    pub n: usize,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub u: Vec<f64>,
    /// the measured load (zeros when the log's `tau` is zero)
    pub tau: Vec<f64>,
    /// `d − rest`, what the linear part explains
    pub y: Vec<f64>,
    pub temp: Option<Vec<f64>>,
    /// median sample interval, s
    pub dt: f64,
    /// the model's sign band (rad/s) and `sgn(q̇)` with it
    pub band: f64,
    pub sgn: Vec<f64>,
    /// the model's spring rest angle (centre of a backlash dead zone)
    pub q0: f64,
    /// `sin(s·q)`, `cos(s·q)` at the model's weight scale `ws`, computed once: every fit and
    /// every score reads them
    pub ws: f64,
    pub wsin: Vec<f64>,
    pub wcos: Vec<f64>,
    /// the transmitted load a load-dependent friction grows with: `|tau|`, or when the log's
    /// `tau` is absent or zero the model's own non-friction torque (never `u`: it holds the
    /// friction being explained, and its noise would explain itself)
    pub load: Vec<f64>,
    /// variance of the noise part of the q̈ used (the logged column's white noise, or the
    /// estimate's), averaged over the log: the report's figure, and 0 where q̈ has none. The
    /// fits remove the noise in their regressor from the q̈ column's Gram diagonal row by row
    /// (`qdd_nv`), so the inertia is not shrunk by it (errors in variables)
    pub qdd_noise_var: f64,
    /// per sample, the variance of the noise part of the q̈ used (empty: `qdd_noise_var` for
    /// every sample). A fit removes the noise of its own rows, each at its fit weight
    /// ([`Data::row_noise`]): a log's shortest windows (next to its rests) carry most of its
    /// q̈ noise, and the average over the log put 90 times the noise of the fitted rows on the
    /// Gram of a point-to-point log (bench 9103/35), whose inertia then doubled with any column
    /// added
    pub qdd_nv: Vec<f64>,
    /// variance of the noise on q and on the q̇ used (the preparation's), for the excitation
    /// check: a model column that varies over the rows only within its noise is not excited
    pub q_noise_var: f64,
    pub qd_noise_var: f64,
    /// per sample, the square root of its weight in every fit (empty: all alike): the inverse
    /// of the error variance it is expected to carry, scaled to a mean of 1 over the training
    /// samples. Fits only: held-out residuals and their sums stay unweighted.
    pub sw: Vec<f64>,
}

impl Data {
    /// Scales a fit row `x` and its target `y` by sample `i`'s fit weight ([`Data::sw`]; as
    /// they are without weights) and returns the target.
    #[inline]
    pub fn weigh_row(&self, i: usize, x: &mut [f64], y: f64) -> f64 {
        match self.sw.get(i) {
            Some(&w) => {
                x.iter_mut().for_each(|v| *v *= w);
                y * w
            }
            None => y,
        }
    }

    /// What sample `i`, fitted, adds to the q̈ column's Gram entry as noise ([`Gram::eiv`]): its
    /// q̈ noise variance times its fit weight.
    #[inline]
    pub fn row_noise(&self, i: usize) -> f64 {
        let v = self.qdd_nv.get(i).copied().unwrap_or(self.qdd_noise_var);
        let w = self.sw.get(i).map_or(1.0, |s| s * s);
        v * w
    }
}

/// The log has a `temp` column whose range is below 0.1 °C: no temperature change to
/// test a thermal drift against.
pub fn constant_temp(d: &Data) -> bool {
    d.temp.as_ref().is_some_and(|t| {
        let (lo, hi) = t.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
        hi - lo < 0.1
    })
}

/// Variance of white noise on a sampled signal from its first differences, robustly:
/// `(1.4826·median|Δx|)² / 2`. A smooth signal adds almost nothing to the differences at the
/// sampling rate, so what is left is the noise; coloured (filtered) noise differs less from
/// sample to sample and is under-estimated, so the correction it feeds errs on the small side.
pub fn white_noise_var(x: &[f64]) -> f64 {
    let mut d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|v| v.is_finite()).collect();
    if d.len() < 10 {
        return 0.0;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    let sigma = 1.4826 * *m;
    sigma * sigma / 2.0
}

/// Where a thermal candidate reads its temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThermSrc {
    /// the log's `temp` column, centred on `mean`
    Temp { mean: f64 },
    /// no `temp`: a first-order warm-up `1 − e^(−(t−t0)/tau)` as a stand-in, centred on `mean`
    Time { tau: f64, t0: f64, mean: f64 },
}

/// One regressor column.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Col {
    Qdd,
    QdAbsQd,
    Qd,
    Sgn,
    SinSq(f64),
    CosSq(f64),
    Q,
    DeadZone {
        q0: f64,
        w: f64,
    },
    Const,
    Stribeck(f64),
    AbsSgn,
    LoadSgn,
    Thermal {
        a: f64,
        b: f64,
        c: f64,
        src: ThermSrc,
    },
    RipSin(f64),
    RipCos(f64),
    Cable {
        engage: f64,
        width: f64,
    },
    /// the Dahl state in place of `Sgn` (values held by the design, see [`Design::dahl`])
    Dahl {
        kappa: f64,
    },
    /// a Stribeck curve of another exponent than 2
    StribeckExp {
        speed: f64,
        exponent: f64,
    },
    /// a cable taut below `engage`: −spring(engage − q)
    CableBelow {
        engage: f64,
        width: f64,
    },
    /// (q − centre) and (q − centre)³ of a progressive spring
    Lin {
        centre: f64,
    },
    Cubic {
        centre: f64,
    },
    /// a pad pressing over `centre ± half` ([`super::shapes::pad`])
    Pad {
        centre: f64,
        half: f64,
    },
}

impl Col {
    /// A friction column (velocity-dependent dissipation of the model's own terms).
    pub fn is_friction(&self) -> bool {
        matches!(self, Col::QdAbsQd | Col::Qd | Col::Sgn | Col::Stribeck(_) | Col::AbsSgn | Col::StribeckExp { .. })
    }

    /// An amplitude no joint has negative: inertia, friction that dissipates (viscous,
    /// Coulomb, a Dahl state's level, a Stribeck level, a load-dependent μ), a spring's
    /// stiffness, a cable or harness that pulls back (either side, a progressive spring's k1 and
    /// k3). Fits hold such a column at 0 rather than let it go negative, so a shape is searched,
    /// and a candidate scored, as the best *physical* fit of its effect: a one-sided cable that
    /// only fits pushing on one side is the same cable pulling on the other plus a linear term
    /// the weight takes, and must be found as that.
    pub fn nonneg(&self) -> bool {
        matches!(
            self,
            Col::Qdd
                | Col::QdAbsQd
                | Col::Qd
                | Col::Sgn
                | Col::Q
                | Col::DeadZone { .. }
                | Col::Dahl { .. }
                | Col::Stribeck(_)
                | Col::StribeckExp { .. }
                | Col::LoadSgn
                | Col::Cable { .. }
                | Col::CableBelow { .. }
                | Col::Lin { .. }
                | Col::Cubic { .. }
        )
    }

    #[inline]
    pub fn eval(&self, d: &Data, i: usize) -> f64 {
        let qd = d.qd[i];
        match *self {
            Col::Qdd => d.qdd[i],
            Col::QdAbsQd => qd * qd.abs(),
            Col::Qd => qd,
            Col::Sgn => d.sgn[i],
            Col::SinSq(s) if s == d.ws && !d.wsin.is_empty() => d.wsin[i],
            Col::CosSq(s) if s == d.ws && !d.wcos.is_empty() => d.wcos[i],
            Col::SinSq(s) => (s * d.q[i]).sin(),
            Col::CosSq(s) => (s * d.q[i]).cos(),
            Col::Q => d.q[i],
            Col::DeadZone { q0, w } => super::shapes::dead_zone(d.q[i] - d.q0 - q0, w),
            Col::Const => 1.0,
            Col::Stribeck(v) => {
                let r = qd / v;
                (-r * r).exp() * d.sgn[i]
            }
            Col::AbsSgn => d.sgn[i].abs(),
            Col::LoadSgn => d.load[i] * d.sgn[i],
            Col::Thermal { a, b, c, src } => {
                let f = a * qd * qd.abs() + b * qd + c * d.sgn[i];
                let temp = match src {
                    ThermSrc::Temp { mean } => d.temp.as_ref().map(|t| t[i]).unwrap_or(mean) - mean,
                    ThermSrc::Time { tau, t0, mean } => 1.0 - (-(d.t[i] - t0) / tau).exp() - mean,
                };
                f * temp
            }
            Col::RipSin(p) => (std::f64::consts::TAU * d.q[i] / p).sin(),
            Col::RipCos(p) => (std::f64::consts::TAU * d.q[i] / p).cos(),
            Col::Cable { engage, width } => super::shapes::engaged_spring(1.0, engage, width, d.q[i]),
            // a state, not a function of the sample: the design holds its values
            Col::Dahl { .. } => 0.0,
            Col::StribeckExp { speed, exponent } => (-(qd.abs() / speed).powf(exponent)).exp() * d.sgn[i],
            Col::CableBelow { engage, width } => -super::shapes::engaged_spring(1.0, -engage, width, -d.q[i]),
            Col::Lin { centre } => d.q[i] - centre,
            Col::Cubic { centre } => (d.q[i] - centre).powi(3),
            Col::Pad { centre, half } => super::shapes::pad(centre, half, d.q[i]),
        }
    }
}

/// The angle travelled from sample `i − 1` to `i`, what a Dahl state integrates: the prepared
/// q̇ over the step, or (`raw`) the logged angle's own step, outside rests (where the prepared
/// q̇ is 0 on both sides, a still joint's noise is no travel). The prepared q̇ comes through a
/// window sized for q̇'s noise and bias: at a point-to-point move's reversal (q̈ jumps) it
/// spreads the reversal over the window, and the state's fitted pre-sliding distance came out
/// 2.8 times the true one on a clean encoder (unseen u9085/0030: 1.29 against 0.45 mrad, the
/// shape's error then taken by a ripple of 4.7 mrad). The angle's own steps carry its noise
/// instead, which a state whose distance is a few noise steps cannot take. Which one holds is
/// the log's to say: both are searched ([`search_in`]), as any other shape value.
fn travel(d: &Data, i: usize, raw: bool) -> f64 {
    if raw {
        if d.qd[i] == 0.0 && d.qd[i - 1] == 0.0 {
            return 0.0;
        }
        return d.q[i] - d.q[i - 1];
    }
    0.5 * (d.qd[i] + d.qd[i - 1]) * (d.t[i] - d.t[i - 1])
}

/// The Dahl state z along the log for inverse pre-sliding distance `kappa`, driven by the
/// [`travel`] of the prepared q̇ (trapezoid; at rest q̇ = 0, so encoder noise does not move it)
/// or (`raw`) of the angle's own steps. Each step is the exact solution of
/// dz/dq = κ·(1 − z·sign(dq)) over its travel, so z stays in [−1, 1] whatever the step; it
/// starts at the expected friction sign of the first sample.
pub fn dahl_state(d: &Data, kappa: f64, raw: bool) -> Vec<f64> {
    let mut z = Vec::with_capacity(d.n);
    let mut s = d.sgn.first().copied().unwrap_or(0.0).clamp(-1.0, 1.0);
    z.push(s);
    for i in 1..d.n {
        s = super::shapes::dahl_step(s, kappa, travel(d, i, raw));
        z.push(s);
    }
    z
}

/// The effect kinds of torque mode, in the spec's vocabulary order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kind {
    Stribeck,
    Asymmetric,
    Load,
    Thermal,
    Ripple,
    Cable,
    Backlash,
    Delay,
    Dry,
    Presliding,
}

impl Kind {
    pub const ALL: [Kind; 10] = [
        Kind::Stribeck,
        Kind::Asymmetric,
        Kind::Load,
        Kind::Thermal,
        Kind::Ripple,
        Kind::Cable,
        Kind::Backlash,
        Kind::Delay,
        Kind::Dry,
        Kind::Presliding,
    ];

    /// The vocabulary entry the kind fits.
    pub fn effect(self) -> Vocab {
        match self {
            Kind::Stribeck => Vocab::Stribeck,
            Kind::Asymmetric => Vocab::AsymmetricFriction,
            Kind::Load => Vocab::LoadDependentFriction,
            Kind::Thermal => Vocab::ThermalDrift,
            Kind::Ripple => Vocab::PositionRipple,
            Kind::Cable => Vocab::CableSpring,
            Kind::Backlash => Vocab::Backlash,
            Kind::Delay => Vocab::Delay,
            Kind::Dry => Vocab::DryFriction,
            Kind::Presliding => Vocab::PreslidingHysteresis,
        }
    }

    /// The spec §3 name.
    pub fn name(self) -> &'static str {
        self.effect().name()
    }
}

/// A fitted-shape effect (its linear amplitudes come from the joint solve).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Effect {
    /// `exp(−(|q̇|/speed)^exponent)·sgn`: the classic Gaussian curve is exponent 2, real joints
    /// show 0.5–2
    Stribeck {
        speed: f64,
        exponent: f64,
    },
    Asymmetric,
    Load,
    Thermal {
        a: f64,
        b: f64,
        c: f64,
        src: ThermSrc,
    },
    /// one or two harmonics of the period, and (`second` > 0) a ripple of an independent
    /// second period: a gear train's mesh and its motor's cogging seen through the ratio
    Ripple {
        period: f64,
        harmonics: u8,
        second: f64,
    },
    /// a cable or harness taut past `engage` (side +1: above it, −1: below), with `side` 0 a
    /// progressive spring `k1·x + k3·x³` about `engage`, with `side` 2 a pad that presses over
    /// `engage ± width` only (either way)
    Cable {
        engage: f64,
        width: f64,
        side: i8,
    },
    /// the spring's dead zone of `width`, its centre `offset` from the spring's rest angle
    Backlash {
        width: f64,
        offset: f64,
    },
    /// a time shift of one logged channel against the others: `lag` samples (whole), positive
    /// when that channel lags (its value at t belongs to t − lag)
    Delay {
        lag: f64,
        channel: Channel,
    },
    Dry,
    /// the Coulomb sign replaced by a Dahl state z ∈ [−1, 1] that moves with travel:
    /// dz/dq = κ·(1 − z·sign(dq)); κ = σ/c, the inverse pre-sliding distance (rad⁻¹)
    Presliding {
        kappa: f64,
        /// the travel read from the logged angle's own steps (outside rests) instead of the
        /// prepared q̇ ([`travel`])
        raw: bool,
    },
}

impl Effect {
    pub fn kind(&self) -> Kind {
        match self {
            Effect::Stribeck { .. } => Kind::Stribeck,
            Effect::Asymmetric => Kind::Asymmetric,
            Effect::Load => Kind::Load,
            Effect::Thermal { .. } => Kind::Thermal,
            Effect::Ripple { .. } => Kind::Ripple,
            Effect::Cable { .. } => Kind::Cable,
            Effect::Backlash { .. } => Kind::Backlash,
            Effect::Delay { .. } => Kind::Delay,
            Effect::Dry => Kind::Dry,
            Effect::Presliding { .. } => Kind::Presliding,
        }
    }

    /// Extra columns (backlash and delay change the base instead).
    pub fn cols(&self) -> Vec<Col> {
        match *self {
            Effect::Stribeck { speed, exponent: 2.0 } => vec![Col::Stribeck(speed)],
            Effect::Stribeck { speed, exponent } => vec![Col::StribeckExp { speed, exponent }],
            Effect::Asymmetric => vec![Col::AbsSgn],
            Effect::Load => vec![Col::LoadSgn],
            Effect::Thermal { a, b, c, src } => vec![Col::Thermal { a, b, c, src }],
            Effect::Ripple { period, harmonics, second } => {
                let mut v = vec![Col::RipSin(period), Col::RipCos(period)];
                if harmonics >= 2 {
                    v.extend([Col::RipSin(period / 2.0), Col::RipCos(period / 2.0)]);
                }
                if second > 0.0 {
                    v.extend([Col::RipSin(second), Col::RipCos(second)]);
                }
                v
            }
            Effect::Cable { engage, width, side: 1 } => vec![Col::Cable { engage, width }],
            Effect::Cable { engage, width, side: -1 } => vec![Col::CableBelow { engage, width }],
            Effect::Cable { engage, width, side: 2 } => vec![Col::Pad { centre: engage, half: width }],
            // the cubic first: its stiffening is what the sign rule checks
            Effect::Cable { engage, .. } => vec![Col::Cubic { centre: engage }, Col::Lin { centre: engage }],
            Effect::Backlash { .. } | Effect::Delay { .. } | Effect::Presliding { .. } => vec![],
            Effect::Dry => vec![Col::Sgn],
        }
    }
}

/// The model's own refittable terms and their values in the model file.
#[derive(Clone, Debug)]
pub struct Base {
    pub cols: Vec<Col>,
    pub beta0: Vec<f64>,
    /// per column: held at its file value in every fit (the selection sets it for an inertia
    /// the refit had to hold, so no candidate wins by freeing it)
    pub fixed: Vec<bool>,
}

/// Which logged channel a delay shifts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// the actuator torque `u` (a reported motor torque that lags, a bus delay)
    U,
    /// the measured load `tau` (a filtered load cell)
    Tau,
    /// the joint's state (q and its derivatives) against both torques: an encoder or a state
    /// estimate that lags, or an actuation delay seen the other way
    State,
}

impl Channel {
    pub const ALL: [Channel; 3] = [Channel::U, Channel::Tau, Channel::State];
    pub fn name(self) -> &'static str {
        match self {
            Channel::U => "u",
            Channel::Tau => "tau",
            Channel::State => "state",
        }
    }
}

/// A full design: base columns (possibly with the spring replaced by a dead zone), the effect
/// columns, and a time shift of one channel.
#[derive(Clone, Debug)]
pub struct Design {
    pub cols: Vec<Col>,
    pub lag: f64,
    pub channel: Channel,
    /// the Dahl state's values when a pre-sliding candidate replaces the Coulomb sign
    pub dahl: Option<std::sync::Arc<Vec<f64>>>,
    /// per effect of the spec: the range of its columns
    pub spans: Vec<(usize, usize)>,
    /// per column, the value a fit keeps where the rows do not determine it: the file's value
    /// for the model's own terms (also where an effect replaced the column), 0 for an effect's
    pub prior: Vec<f64>,
    /// per column, held at `prior` in every fit ([`Base::fixed`])
    pub fixed: Vec<bool>,
}

impl Design {
    /// No columns: the design of a score that is not a linear fit (trajectory mode's
    /// simulations, a test's residuals).
    pub fn empty() -> Design {
        Design { cols: vec![], lag: 0.0, channel: Channel::U, dahl: None, spans: vec![], prior: vec![], fixed: vec![] }
    }

    pub fn new(d: &Data, base: &Base, effects: &[Effect]) -> Design {
        let mut cols = base.cols.clone();
        let mut lag = 0.0;
        let mut channel = Channel::U;
        let mut dahl = None;
        for e in effects {
            match *e {
                Effect::Backlash { width, offset } => {
                    for c in cols.iter_mut() {
                        if let Col::Q = c {
                            *c = Col::DeadZone { q0: offset, w: width };
                        }
                    }
                }
                Effect::Delay { lag: l, channel: c } => {
                    lag = l;
                    channel = c;
                }
                Effect::Presliding { kappa, raw } => {
                    for c in cols.iter_mut() {
                        if let Col::Sgn = c {
                            *c = Col::Dahl { kappa };
                        }
                    }
                    dahl = Some(std::sync::Arc::new(dahl_state(d, kappa, raw)));
                }
                _ => {}
            }
        }
        let mut spans = Vec::new();
        for e in effects {
            let s = cols.len();
            cols.extend(e.cols());
            spans.push((s, cols.len()));
        }
        let mut prior = base.beta0.clone();
        prior.resize(cols.len(), 0.0);
        let mut fixed = base.fixed.clone();
        fixed.resize(cols.len(), false);
        Design { cols, lag, channel, dahl, spans, prior, fixed }
    }

    /// Fills `x` with the row of sample `i` and returns its target.
    #[inline]
    pub fn row(&self, d: &Data, i: usize, x: &mut [f64]) -> f64 {
        for (xk, c) in x.iter_mut().zip(&self.cols) {
            *xk = match c {
                Col::DeadZone { q0, w } => super::shapes::dead_zone(d.q[i] - d.q0 - q0, *w),
                Col::Dahl { .. } => self.dahl.as_ref().map_or(0.0, |z| z[i]),
                _ => c.eval(d, i),
            };
        }
        self.target(d, i)
    }

    /// The target of sample `i`: `d − rest` with the delayed channel read `lag` samples away.
    /// A channel that lags holds at `i + lag` what belongs to `i`; the state lagging is both
    /// torques leading, so they are read `lag` samples back.
    #[inline]
    pub fn target(&self, d: &Data, i: usize) -> f64 {
        if self.lag == 0.0 {
            return d.y[i];
        }
        let at = |v: &[f64], off: f64| {
            let pos = (i as f64 + off).clamp(0.0, (d.n - 1) as f64);
            let k = pos.floor() as usize;
            let f = pos - k as f64;
            let a = v[k.min(d.n - 1)];
            let b = v[(k + 1).min(d.n - 1)];
            a + f * (b - a)
        };
        match self.channel {
            Channel::U => d.y[i] + at(&d.u, self.lag) - d.u[i],
            Channel::Tau => d.y[i] - at(&d.tau, self.lag) + d.tau[i],
            Channel::State => d.y[i] + at(&d.u, -self.lag) - d.u[i] - at(&d.tau, -self.lag) + d.tau[i],
        }
    }

    pub fn gram(&self, d: &Data, idx: &[u32]) -> Gram {
        let p = self.cols.len();
        let mut g = Gram::new(p);
        g.prior.clone_from(&self.prior);
        let mut x = vec![0.0; p];
        for &i in idx {
            let y = self.row(d, i as usize, &mut x);
            let y = d.weigh_row(i as usize, &mut x, y);
            g.add(&x, y);
            g.add_noise(d.row_noise(i as usize));
        }
        g
    }

    /// Training RSS on `idx`.
    pub fn rss(&self, d: &Data, idx: &[u32]) -> f64 {
        self.gram(d, idx).solve().1
    }
}

/// Every `stride`-th index so at most `max` remain.
pub fn thin_idx(idx: &[u32], max: usize) -> Vec<u32> {
    let stride = idx.len().div_ceil(max.max(1)).max(1);
    idx.iter().step_by(stride).copied().collect()
}

fn quantile(mut v: Vec<f64>, p: f64) -> f64 {
    crate::prep::quantile::at_rounded(&mut v, p).unwrap_or(0.0)
}

/// The current design evaluated once on a set of rows (the thinned training rows of a grid
/// search, or the fit rows of a round of candidates), so a candidate only costs its own
/// column(s): the Gram matrix is bordered instead of rebuilt (Frisch–Waugh in effect). The
/// bordered matrix adds the same products in the same order as [`Design::gram`] on the full
/// design, so a fit through here gives the same numbers as one that rebuilds everything.
pub struct GridCtx<'a> {
    d: &'a Data,
    idx: &'a [u32],
    pub(crate) des: Design,
    pub(crate) p: usize,
    /// rows × p, the design's columns at `idx`
    pub(crate) x: Vec<f64>,
    /// the design's target at `idx`
    pub(crate) y: Vec<f64>,
    pub(crate) g: Gram,
    /// the Dahl state's steps to these rows, from the prepared q̇ and from the angle's own
    /// steps (built on first use, see [`dahl_plan`])
    dahl: [std::sync::OnceLock<DahlPlan>; 2],
    /// grid searches evaluate the Dahl state from the compressed plan (equal to the sample-by-
    /// sample state but for rounding); fits and scores keep the exact state
    pub(crate) compose_dahl: bool,
    /// per column of `des`: held ≥ 0 in every fit ([`crate::diagnose::select::physical_signs`])
    signs: Vec<bool>,
    /// per column of `des`: the value a term that would go negative is held at
    holds: Vec<f64>,
    /// these rows are fitted (and carry their fit weights, [`Data::sw`]), not only scored
    fitted: bool,
}

/// The starting state and the steps of [`dahl_plan`].
type DahlPlan = (f64, Vec<(f64, bool)>);

/// The Dahl state's travel compressed for the rows `idx` (ascending): the starting state and
/// the steps, each the summed travel of a run of samples moving one way, marked where a row's
/// value is to be read. Steps one way compose exactly (`exp(−κa)·exp(−κb) = exp(−κ(a+b))`),
/// so evaluating the state at the rows costs one step per row and per reversal, not per sample.
fn dahl_plan(d: &Data, idx: &[u32], raw: bool) -> DahlPlan {
    let z0 = d.sgn.first().copied().unwrap_or(0.0).clamp(-1.0, 1.0);
    let mut plan = Vec::with_capacity(2 * idx.len() + 16);
    let mut k = 0;
    while k < idx.len() && idx[k] == 0 {
        plan.push((0.0, true));
        k += 1;
    }
    let mut acc = 0.0;
    for i in 1..d.n {
        let dq = travel(d, i, raw);
        if dq != 0.0 && acc != 0.0 && (dq > 0.0) != (acc > 0.0) {
            plan.push((acc, false));
            acc = 0.0;
        }
        acc += dq;
        while k < idx.len() && idx[k] as usize == i {
            plan.push((acc, true));
            acc = 0.0;
            k += 1;
        }
    }
    (z0, plan)
}

/// How a candidate changes the current design (see [`GridCtx::delta`]).
pub struct Delta {
    /// the base column a backlash dead zone replaces in place, with its values on the rows
    pub replace: Option<(usize, Vec<f64>)>,
    /// the effect's own columns on the rows, appended
    pub extra: Vec<Vec<f64>>,
    /// another target (a delay shifts `u`)
    pub y_alt: Option<Vec<f64>>,
}

impl<'a> GridCtx<'a> {
    pub fn new(d: &'a Data, base: &Base, chosen: &[Effect], idx: &'a [u32]) -> GridCtx<'a> {
        Self::build(d, base, chosen, idx, true)
    }

    /// The design's rows and targets only (no Gram): for rows that are scored, never fitted.
    pub fn rows(d: &'a Data, base: &Base, chosen: &[Effect], idx: &'a [u32]) -> GridCtx<'a> {
        Self::build(d, base, chosen, idx, false)
    }

    fn build(d: &'a Data, base: &Base, chosen: &[Effect], idx: &'a [u32], gram: bool) -> GridCtx<'a> {
        let des = Design::new(d, base, chosen);
        let p = des.cols.len();
        let mut x = vec![0.0; idx.len() * p];
        let mut y = Vec::with_capacity(idx.len());
        let mut g = Gram::new(p);
        g.prior.clone_from(&des.prior);
        for (r, &i) in idx.iter().enumerate() {
            let row = &mut x[r * p..(r + 1) * p];
            let mut yi = des.row(d, i as usize, row);
            // fitted rows carry their weights, scored rows none
            if gram {
                yi = d.weigh_row(i as usize, row, yi);
                g.add(row, yi);
                g.add_noise(d.row_noise(i as usize));
            }
            y.push(yi);
        }
        let signs = super::select::physical_signs(&des);
        let holds = super::select::physical_holds(&des);
        GridCtx {
            d,
            idx,
            des,
            p,
            x,
            y,
            g,
            dahl: [std::sync::OnceLock::new(), std::sync::OnceLock::new()],
            compose_dahl: false,
            signs,
            holds,
            fitted: gram,
        }
    }

    /// What effect `e` changes on these rows: a replaced column, extra columns or a new target
    /// (weighted as the rows are).
    pub fn delta(&self, e: &Effect) -> Delta {
        let mut delta = self.delta_unweighted(e);
        if self.fitted && !self.d.sw.is_empty() {
            let sw = &self.d.sw;
            let weigh = |v: &mut Vec<f64>| v.iter_mut().zip(self.idx).for_each(|(x, &i)| *x *= sw[i as usize]);
            if let Some((_, z)) = delta.replace.as_mut() {
                weigh(z);
            }
            delta.extra.iter_mut().for_each(weigh);
            if let Some(y) = delta.y_alt.as_mut() {
                weigh(y);
            }
        }
        delta
    }

    fn delta_unweighted(&self, e: &Effect) -> Delta {
        let (d, idx) = (self.d, self.idx);
        match *e {
            Effect::Backlash { width, offset } => {
                let at = self.des.cols.iter().position(|c| matches!(c, Col::Q));
                let z =
                    || idx.iter().map(|&i| super::shapes::dead_zone(d.q[i as usize] - d.q0 - offset, width)).collect();
                Delta { replace: at.map(|j| (j, z())), extra: Vec::new(), y_alt: None }
            }
            Effect::Presliding { kappa, raw } => {
                let at = self.des.cols.iter().position(|c| matches!(c, Col::Sgn));
                let (z0, plan) = self.dahl[usize::from(raw)].get_or_init(|| {
                    if self.compose_dahl {
                        dahl_plan(d, idx, raw)
                    } else {
                        (0.0, Vec::new())
                    }
                });
                let rows = || {
                    if !self.compose_dahl || plan.iter().filter(|s| s.1).count() != idx.len() {
                        // rows not in ascending order: the state sample by sample
                        let z = dahl_state(d, kappa, raw);
                        return idx.iter().map(|&i| z[i as usize]).collect();
                    }
                    let mut z = *z0;
                    let mut out = Vec::with_capacity(idx.len());
                    for &(dq, read) in plan {
                        z = super::shapes::dahl_step(z, kappa, dq);
                        if read {
                            out.push(z);
                        }
                    }
                    out
                };
                Delta { replace: at.map(|j| (j, rows())), extra: Vec::new(), y_alt: None }
            }
            Effect::Delay { lag, channel } => {
                let mut des = self.des.clone();
                des.lag = lag;
                des.channel = channel;
                let y = idx.iter().map(|&i| des.target(d, i as usize)).collect();
                Delta { replace: None, extra: Vec::new(), y_alt: Some(y) }
            }
            Effect::Ripple { period, harmonics: 1, second: 0.0 } => {
                // both columns from one sin_cos per row (the same values as Col::RipSin/RipCos)
                let (zs, zc) =
                    idx.iter().map(|&i| (std::f64::consts::TAU * d.q[i as usize] / period).sin_cos()).unzip();
                Delta { replace: None, extra: vec![zs, zc], y_alt: None }
            }
            _ => Delta { replace: None, extra: e.cols().into_iter().map(|c| self.column(c)).collect(), y_alt: None },
        }
    }

    /// Normal equations of the design with `delta` applied, bordered onto the stored Gram.
    /// Column order is [`Design::new`]'s: a replaced column stays where it was, extras follow.
    pub fn gram_with(&self, delta: &Delta) -> Gram {
        let p = self.p;
        let extra = &delta.extra;
        let q = p + extra.len();
        let rep = delta.replace.as_ref().map(|(j, z)| (*j, z.as_slice()));
        let y_alt = delta.y_alt.as_deref();
        let mut g = Gram::new(q);
        for a in 0..p {
            for b in a..p {
                g.g[a * q + b] = self.g.g[a * p + b];
            }
            g.b[a] = self.g.b[a];
            g.prior[a] = self.g.prior.get(a).copied().unwrap_or(0.0);
        }
        g.yy = self.g.yy;
        g.eiv = self.g.eiv;
        let n = self.idx.len();
        // Cross products that change: with the extra columns, with a replaced column, and
        // with another target. Each sum runs over the rows in order, as `Gram::add` does.
        let mut xz = vec![0.0; p * extra.len()];
        let mut xr = vec![0.0; p];
        let mut xy_alt = vec![0.0; p];
        let mut yy_alt = 0.0;
        for r in 0..n {
            let row = &self.x[r * p..(r + 1) * p];
            for (e, z) in extra.iter().enumerate() {
                let zr = z[r];
                if zr != 0.0 {
                    for j in 0..p {
                        xz[e * p + j] += row[j] * zr;
                    }
                }
            }
            if let Some((jr, z)) = rep {
                let zr = z[r];
                for (j, &xj) in row.iter().enumerate() {
                    let xj = if j == jr { zr } else { xj };
                    if xj != 0.0 {
                        xr[j] += xj * zr;
                    }
                }
            }
            if let Some(ya) = y_alt {
                let yr = ya[r];
                for j in 0..p {
                    xy_alt[j] += row[j] * yr;
                }
                yy_alt += yr * yr;
            }
        }
        if y_alt.is_some() {
            g.b[..p].copy_from_slice(&xy_alt);
            g.yy = yy_alt;
        }
        let y_of = |r: usize| y_alt.map_or(self.y[r], |ya| ya[r]);
        if let Some((jr, z)) = rep {
            for (a, &v) in xr.iter().enumerate() {
                let (lo, hi) = if a <= jr { (a, jr) } else { (jr, a) };
                g.g[lo * q + hi] = v;
            }
            g.b[jr] = (0..n).map(|r| z[r] * y_of(r)).sum();
        }
        for (e, z) in extra.iter().enumerate() {
            for a in 0..p {
                g.g[a * q + p + e] = match rep {
                    Some((jr, zrep)) if jr == a => zrep.iter().zip(z).map(|(a, b)| a * b).sum(),
                    _ => xz[e * p + a],
                };
            }
            for (f, z2) in extra.iter().enumerate().skip(e) {
                g.g[(p + e) * q + p + f] = z.iter().zip(z2).map(|(a, b)| a * b).sum();
            }
            g.b[p + e] = (0..n).map(|r| z[r] * y_of(r)).sum();
        }
        g.n = n;
        g
    }

    fn column(&self, c: Col) -> Vec<f64> {
        self.idx.iter().map(|&i| c.eval(self.d, i as usize)).collect()
    }

    /// RSS of the current design plus effect `e`, fitted with the sign bounds every final fit
    /// keeps (a shape is chosen for its best physical fit, not for one its effect cannot have).
    pub fn rss_effect(&self, e: &Effect) -> f64 {
        let g = self.gram_with(&self.delta(e));
        let extra = match e {
            Effect::Backlash { .. } | Effect::Delay { .. } | Effect::Presliding { .. } => Vec::new(),
            _ => e.cols(),
        };
        let mut signs = self.signs.clone();
        signs.extend(extra.iter().map(Col::nonneg));
        let mut holds = self.holds.clone();
        holds.resize(g.p, 0.0);
        g.solve_held(&signs, &holds, &[]).1
    }
}

/// Searches an effect's shape parameter on the thinned training set `idx`, given the effects
/// already chosen; `None` when the effect cannot apply to this model/log (dry friction in a
/// model that has a Coulomb term, backlash without a spring, thermal drift without friction).
pub fn search(kind: Kind, d: &Data, base: &Base, chosen: &[Effect], idx: &[u32]) -> Option<Effect> {
    let mut grid = GridCtx::new(d, base, chosen, idx);
    grid.compose_dahl = true;
    search_in(kind, &grid, base, chosen)
}

/// [`search`] on a grid context already built for `chosen` (one per round, shared by every
/// kind).
pub fn search_in(kind: Kind, ctx: &GridCtx<'_>, base: &Base, chosen: &[Effect]) -> Option<Effect> {
    let (d, idx) = (ctx.d, ctx.idx);
    let has = |c: Col| base.cols.contains(&c);
    let applicable = match kind {
        Kind::Dry => !has(Col::Sgn) && !chosen.iter().any(|e| matches!(e, Effect::Dry)),
        Kind::Backlash => has(Col::Q),
        // it replaces the model's own Coulomb sign
        Kind::Presliding => has(Col::Sgn),
        // a term the model already carries is refitted with the model's own, not added twice
        Kind::Load => !has(Col::LoadSgn),
        Kind::Asymmetric => !has(Col::AbsSgn),
        _ => true,
    };
    if !applicable || chosen.iter().any(|e| e.kind() == kind) {
        return None;
    }
    let rss_of = |e: Effect| ctx.rss_effect(&e);
    // Search in log space over [lo, hi]: a grid, then golden section around the best point.
    let log_search = |lo: f64, hi: f64, k: usize, make: &dyn Fn(f64) -> Effect| -> Effect {
        let (l0, l1) = (lo.ln(), hi.ln());
        let pts: Vec<f64> = (0..k).map(|j| l0 + (l1 - l0) * j as f64 / (k - 1) as f64).collect();
        let vals: Vec<f64> = pts.iter().map(|&x| rss_of(make(x.exp()))).collect();
        let best = vals.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map(|(i, _)| i).unwrap_or(0);
        let a = pts[best.saturating_sub(1)];
        let b = pts[(best + 1).min(k - 1)];
        let (x, _) = golden(a, b, 18, |x| rss_of(make(x.exp())));
        make(x.exp())
    };
    match kind {
        Kind::Stribeck => {
            let aq: Vec<f64> = idx.iter().map(|&i| d.qd[i as usize].abs()).collect();
            let v95 = quantile(aq, 0.95).max(1e-3);
            // A Stribeck curve narrower than the sign band cannot be told from the band itself
            // (and from velocity noise at rest), so the search starts at 1.5 bands.
            let lo = (1.5 * d.band).max(1e-4).min(0.05 * v95);
            // the curve's speed for each exponent of the family (0.5, 1, 2), then the best
            // exponent refined between its neighbours
            let mut best: Option<(f64, Effect)> = None;
            let mut classic: Option<(f64, Effect)> = None;
            for exponent in [2.0, 1.0, 0.5] {
                let e = log_search(lo, 0.6 * v95, 24, &|v| Effect::Stribeck { speed: v, exponent });
                let r = rss_of(e);
                if exponent == 2.0 {
                    classic = Some((r, e));
                }
                if best.as_ref().map(|(b, _)| r < *b).unwrap_or(true) {
                    best = Some((r, e));
                }
            }
            let (_, e) = best?;
            let Effect::Stribeck { speed, exponent } = e else { return Some(e) };
            if exponent == 2.0 {
                return Some(e);
            }
            let (x, r) = golden(exponent.ln() - 0.7, exponent.ln() + 0.7, 12, |le| {
                rss_of(Effect::Stribeck { speed, exponent: le.exp().clamp(0.3, 3.0) })
            });
            // The exponent is one more value to defend: the classic curve (exponent 2) stays
            // unless another takes at least a twentieth of what the curve explains on top of it.
            if let Some((r2, e2)) = classic {
                let explained = ctx.g.solve().1 - r2;
                if r2 - r < 0.05 * explained.max(0.0) {
                    return Some(e2);
                }
            }
            Some(Effect::Stribeck { speed, exponent: x.exp().clamp(0.3, 3.0) })
        }
        Kind::Asymmetric => Some(Effect::Asymmetric),
        Kind::Load => Some(Effect::Load),
        Kind::Dry => Some(Effect::Dry),
        // pre-sliding distances c/σ from 20 µrad to 20 mrad
        Kind::Presliding => {
            // the travel from the prepared q̇ and from the angle's own steps ([`travel`]): the
            // one whose best state fits the rows better
            let by = |raw: bool| {
                let e = log_search(50.0, 5.0e4, 20, &|k| Effect::Presliding { kappa: k, raw });
                (rss_of(e), e)
            };
            let (smooth, raw) = (by(false), by(true));
            Some(if raw.0 < smooth.0 { raw.1 } else { smooth.1 })
        }
        Kind::Thermal => {
            // The shape of the friction that scales: the model's friction refitted first.
            let (beta, _) = ctx.g.solve();
            let coef = |c: Col| ctx.des.cols.iter().position(|x| *x == c).map(|k| beta[k]).unwrap_or(0.0);
            let (a, b, c) = (coef(Col::QdAbsQd), coef(Col::Qd), coef(Col::Sgn));
            if a == 0.0 && b == 0.0 && c == 0.0 {
                return None;
            }
            // The drift may scale all of the friction, or its velocity-dependent part (oil
            // viscosity; with or without the quadratic term, which churning losses may not
            // share) or its Coulomb part (seals, preload) alone: each is tried, the best kept.
            let parts = [(a, b, c), (a, b, 0.0), (0.0, b, 0.0), (0.0, 0.0, c)];
            let mut shapes: Vec<(f64, f64, f64)> = Vec::with_capacity(parts.len());
            for p in parts {
                // a part the model lacks (a = 0) leaves two of the shapes the same
                if (p.0 != 0.0 || p.1 != 0.0 || p.2 != 0.0) && !shapes.contains(&p) {
                    shapes.push(p);
                }
            }
            let mut best: Option<(f64, Effect)> = None;
            if constant_temp(d) {
                // a logged temperature that does not change excites no thermal term
                return None;
            }
            for (a, b, c) in shapes {
                let e = match &d.temp {
                    Some(tp) => {
                        let mean = idx.iter().map(|&i| tp[i as usize]).sum::<f64>() / idx.len().max(1) as f64;
                        Effect::Thermal { a, b, c, src: ThermSrc::Temp { mean } }
                    }
                    None => {
                        let (t0, t1) = (d.t[0], d.t[d.n - 1]);
                        let span = (t1 - t0).max(1e-6);
                        let mk = |tau: f64| {
                            let mean = idx.iter().map(|&i| 1.0 - (-(d.t[i as usize] - t0) / tau).exp()).sum::<f64>()
                                / idx.len().max(1) as f64;
                            Effect::Thermal { a, b, c, src: ThermSrc::Time { tau, t0, mean } }
                        };
                        log_search(0.05 * span, 20.0 * span, 12, &mk)
                    }
                };
                let r = rss_of(e);
                if best.as_ref().map(|(bst, _)| r < *bst).unwrap_or(true) {
                    best = Some((r, e));
                }
            }
            best.map(|(_, e)| e)
        }
        Kind::Ripple => {
            // Periodogram of the current residual binned over q, then refinement of the best
            // peaks on the real criterion.
            let (beta, rss_now) = ctx.g.solve();
            let p = ctx.p;
            let qs: Vec<f64> = idx.iter().map(|&i| d.q[i as usize]).collect();
            let qmin = qs.iter().copied().fold(f64::INFINITY, f64::min);
            let qmax = qs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let range = qmax - qmin;
            if !(range > 1e-3) {
                return None;
            }
            let nb = 2048usize;
            let mut sum = vec![0.0; nb];
            let mut cnt = vec![0.0; nb];
            for (r, &i) in idx.iter().enumerate() {
                let row = &ctx.x[r * p..(r + 1) * p];
                let y = ctx.y[r];
                let res = y - row.iter().zip(&beta).map(|(a, b)| a * b).sum::<f64>();
                let b = (((d.q[i as usize] - qmin) / range * nb as f64) as usize).min(nb - 1);
                sum[b] += res;
                cnt[b] += 1.0;
            }
            // Bin b's centre is q_b = qmin + (b + ½)·h, so at frequency w its phase advances by
            // w·h per bin: e^{i·w·q_b} comes from a complex rotation, re-anchored on an exact
            // sin_cos every 64 bins so rounding cannot build up (relative error ~1e-14, far
            // below any difference between neighbouring powers that picks a peak).
            // An empty bin's sum is 0 and adds nothing.
            let h = range / nb as f64;
            let p_min = (8.0 * h).max(2e-3);
            // at least two periods over the angles travelled (one is a bump a smooth term can take)
            let p_max = range / 2.0;
            if p_max <= p_min {
                return None;
            }
            // Frequencies (cycles/rad) on a grid 4× finer than 1/range.
            let (f_lo, f_hi) = (1.0 / p_max, 1.0 / p_min);
            let df = 0.25 / range;
            let nf = ((f_hi - f_lo) / df).ceil() as usize + 1;
            let wsum: f64 = cnt.iter().sum();
            const ANCHOR: usize = 64;
            let spectrum = |sum: &[f64]| -> Vec<(f64, f64)> {
                let mut power: Vec<(f64, f64)> = Vec::with_capacity(nf);
                for k in 0..nf {
                    let f = f_lo + k as f64 * df;
                    let w = std::f64::consts::TAU * f;
                    let (step_s, step_c) = (w * h).sin_cos();
                    let (mut s, mut c) = (0.0, 0.0);
                    for (chunk, ws) in sum.chunks(ANCHOR).enumerate() {
                        let (mut zs, mut zc) = (w * (qmin + ((chunk * ANCHOR) as f64 + 0.5) * h)).sin_cos();
                        for &m in ws {
                            s += m * zs;
                            c += m * zc;
                            (zs, zc) = (zs * step_c + zc * step_s, zc * step_c - zs * step_s);
                        }
                    }
                    power.push((f, (s * s + c * c) / wsum.max(1.0)));
                }
                power
            };
            let power = spectrum(&sum);
            // The three strongest local maxima, refined by golden section in frequency.
            let one = |f: f64| Effect::Ripple { period: 1.0 / f, harmonics: 1, second: 0.0 };
            // A maximum at either end of the grid counts too, refined inside the grid: a ripple
            // whose period is just under half the travel has its maximum in the first bin, and
            // without it the search took a harmonic of the profile at a wrong period and a pad
            // fitted the rest, named as a second effect (unseen t9075/0012: 2.1 periods of
            // 0.056 rad over 0.119 rad of travel). Not once a cable or pad is chosen: two
            // periods over the travel then fit what the pad's shape left (a strap's plateau left
            // to a raised cosine was named a pad and a ripple, `diagnose_pad.rs`). (Whether the
            // spectrum falls beyond the end cannot tell the two apart: over two periods the main
            // lobe is eight bins wide, and a fold missed the true ripple with that test.)
            let f_top = f_lo + (nf - 1) as f64 * df;
            let ends = !chosen.iter().any(|e| matches!(e, Effect::Cable { .. }));
            let peaks_of = |power: &[(f64, f64)]| {
                let m = power.len();
                let mut peaks: Vec<(f64, f64)> = (0..m)
                    .filter(|&k| {
                        let inner = k > 0 && k + 1 < m;
                        (inner || ends)
                            && (k == 0 || power[k].1 >= power[k - 1].1)
                            && (k + 1 == m || power[k].1 >= power[k + 1].1)
                    })
                    .map(|k| power[k])
                    .collect();
                peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
                peaks
            };
            let around = |f: f64, w: f64| ((f - w).max(f_lo), (f + w).min(f_top));
            let mut best: Option<(f64, f64)> = None;
            for &(f, _) in peaks_of(&power).iter().take(3) {
                let (lo, hi) = around(f, df);
                let (fx, r) = golden(lo, hi, 16, |f| rss_of(one(f)));
                if best.map(|(_, rb)| r < rb).unwrap_or(true) {
                    best = Some((fx, r));
                }
            }
            // a second harmonic (a mesh's tooth profile, a cogging shape) when it lowers the
            // training RSS by more than its two values cost (BIC on the thinned rows)
            let (f, r1) = best?;
            let f0 = f;
            let n = idx.len().max(2) as f64;
            let two = |f: f64| Effect::Ripple { period: 1.0 / f, harmonics: 2, second: 0.0 };
            let r2 = rss_of(two(f));
            // The peak may be the profile's second harmonic (a tooth shape, a cogging profile
            // whose half-period component is the stronger one): then the fundamental is at half
            // its frequency, the peak its harmonic, the same four values. Tried where the travel
            // holds two of those longer periods, refined on the real criterion. Without it a
            // ripple whose fundamental spans two periods of a short travel was fitted at its
            // harmonic, 5 % off in period, and the phase error it left across the travel was
            // named a cable spring and a load-dependent friction (unseen t9059/0047).
            let (fh, r2, half) = if 2.0 / f <= p_max {
                let (fx, rs) = golden(0.5 * (f - df), 0.5 * (f + df), 16, |x| rss_of(two(x)));
                if rs < r2 {
                    (fx, rs, true)
                } else {
                    (f, r2, false)
                }
            } else {
                (f, r2, false)
            };
            let both = n * (r1 / r2).ln() > 2.0 * n.ln();
            let (f, first, r_first) = if both { (fh, two(fh), r2) } else { (f, one(f), r1) };
            // Two harmonics at the period refined with one, the profile's second still in the
            // residual, which biases it: where no second period joins them (that pair is refined
            // together below), the period is refined again with both in place (the half
            // period's search already had both). Two harmonics of near equal size over 14
            // periods of travel were fitted 0.7 % off in period, a phase error of a third of a
            // radian at the travel's ends, and that residual (3× the floor) kept a second effect
            // from being tried (unseen t9065/0075).
            let alone = || {
                if !both || half {
                    return first;
                }
                let (fx, rs) = golden(f - 0.5 * df, f + 0.5 * df, 16, |x| rss_of(two(x)));
                if rs < r_first {
                    two(fx)
                } else {
                    first
                }
            };
            // A ripple of an independent second period (a gear train has a mesh and its motor's
            // cogging): the periodogram again, of the binned residual with the first ripple's
            // least-squares sinusoids taken out, its strongest peak away from the first's
            // harmonics refined on the real criterion, and kept when it pays its three values
            // (period and two amplitudes) by BIC.
            let Effect::Ripple { harmonics, .. } = first else { return Some(first) };
            // (not when the first period takes under 1 % of the residual: there is no ripple to
            // look further into, and the search costs as much again)
            if r_first > 0.99 * rss_now {
                return Some(alone());
            }
            // The second period searched on top of a first one (frequency f, its harmonics):
            // the pair and its training RSS where it pays its three values, else None. `sub`:
            // not at half of f either (the peak as a ripple of its own: a second period at half
            // its frequency is the profile again, tried already, with a value more).
            let pair = |f: f64, harmonics: u8, r_first: f64, sub: bool| -> Option<(Effect, f64)> {
                let mut left = sum.clone();
                for hk in 1..=u32::from(harmonics) {
                    let w = std::f64::consts::TAU * f * f64::from(hk);
                    let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
                    for (b, (&m, &c)) in left.iter().zip(&cnt).enumerate() {
                        let (zs, zc) = (w * (qmin + (b as f64 + 0.5) * h)).sin_cos();
                        ss += c * zs * zs;
                        sc += c * zs * zc;
                        cc += c * zc * zc;
                        ys += m * zs;
                        yc += m * zc;
                    }
                    let det = ss * cc - sc * sc;
                    if !(det > 0.0) {
                        return None;
                    }
                    let (a, bb) = ((ys * cc - yc * sc) / det, (yc * ss - ys * sc) / det);
                    for (b, (m, &c)) in left.iter_mut().zip(&cnt).enumerate() {
                        let (zs, zc) = (w * (qmin + (b as f64 + 0.5) * h)).sin_cos();
                        *m -= c * (a * zs + bb * zc);
                    }
                }
                let near = |g: f64| {
                    (1..=2).any(|k| (g - f * f64::from(k)).abs() < 2.0 * df) || sub && (g - 0.5 * f).abs() < 2.0 * df
                };
                let make = |f: f64, g: f64| Effect::Ripple { period: 1.0 / f, harmonics, second: 1.0 / g };
                let mut best2: Option<(f64, f64)> = None;
                for &(g, _) in peaks_of(&spectrum(&left)).iter().filter(|(g, _)| !near(*g)).take(3) {
                    let (lo, hi) = around(g, df);
                    let (gx, r) = golden(lo, hi, 16, |g| rss_of(make(f, g)));
                    if best2.map(|(_, rb)| r < rb).unwrap_or(true) {
                        best2 = Some((gx, r));
                    }
                }
                match best2 {
                    Some((g, r)) if !near(g) && n * (r_first / r).ln() > 3.0 * n.ln() => {
                        // The first period was refined alone, with the second one's sinusoid
                        // still in the residual, which biases it (two periods 1.8 apart: 0.7 %
                        // off, a phase error of a third of a radian across the travel, enough
                        // residual to hide a second effect). Refined again with the second in
                        // place, then the second with the first's new value; each step kept
                        // only where it lowers the training RSS.
                        let (mut fb, mut gb, mut rb) = (f, g, r);
                        for _ in 0..2 {
                            let (fx, rf) = golden(fb - 0.5 * df, fb + 0.5 * df, 16, |x| rss_of(make(x, gb)));
                            if rf < rb {
                                (fb, rb) = (fx, rf);
                            }
                            let (gx, rg) = golden(gb - 0.5 * df, gb + 0.5 * df, 16, |x| rss_of(make(fb, x)));
                            if rg < rb {
                                (gb, rb) = (gx, rg);
                            }
                        }
                        Some(if near(gb) { (make(f, g), r) } else { (make(fb, gb), rb) })
                    }
                    _ => None,
                }
            };
            let main = pair(f, harmonics, r_first, false);
            // Where the fundamental was taken at half the peak (the peak its second harmonic),
            // the peak may instead be a ripple of its own beside one of another period: a mesh
            // and a cogging whose periods are near 2:1 read as one profile with a fundamental
            // that is not there, and the other period's ripple, left half fitted, was named a
            // pad (unseen t9075/0080: 0.0164 and 0.0266 rad, fitted as 0.0327 with its harmonic
            // and a second period at 0.0417). The peak alone with a second period is tried too,
            // and the better by BIC is kept (the peak and a second period, not at the profile's
            // fundamental: six values; the profile: five, eight with its own second period).
            if half {
                if let Some((other, r_other)) = pair(f0, 1, r1, true) {
                    let (k, r) = main.as_ref().map_or((5.0, r_first), |(_, r)| (8.0, *r));
                    if n * r_other.ln() + 6.0 * n.ln() < n * r.ln() + k * n.ln() {
                        return Some(other);
                    }
                }
            }
            Some(main.map_or_else(alone, |(e, _)| e))
        }
        Kind::Cable => {
            // A harness taut past an angle (either side), or a progressive spring about one.
            let mut sorted: Vec<f64> = idx.iter().map(|&i| d.q[i as usize]).collect();
            sorted.sort_by(|a, b| a.total_cmp(b));
            let qat = |p: f64| sorted[((sorted.len() - 1) as f64 * p).round() as usize];
            let width = 0.01;
            let k = 40;
            let pts: Vec<f64> = (0..k).map(|j| qat(0.02 + 0.9 * j as f64 / (k - 1) as f64)).collect();
            let mut best: Option<(f64, Effect)> = None;
            let mut keep = |e: Effect, r: f64| {
                if best.as_ref().map(|(b, _)| r < *b).unwrap_or(true) {
                    best = Some((r, e));
                }
            };
            for side in [1i8, -1] {
                let vals: Vec<f64> = pts.iter().map(|&e| rss_of(Effect::Cable { engage: e, width, side })).collect();
                let b = vals.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map(|(i, _)| i).unwrap_or(0);
                let (lo, hi) = (pts[b.saturating_sub(1)], pts[(b + 1).min(k - 1)]);
                let (e, r) = golden(lo, hi, 20, |e| rss_of(Effect::Cable { engage: e, width, side }));
                keep(Effect::Cable { engage: e, width, side }, r);
            }
            // progressive: centred on the spring's rest angle when the model has a spring, else
            // on the middle of the angles travelled
            let centre = if has(Col::Q) { d.q0 } else { qat(0.5) };
            let prog = Effect::Cable { engage: centre, width, side: 0 };
            keep(prog, rss_of(prog));
            // A pad or strap that presses over part of the travel only (a cuff against the
            // thigh, padding at one end): centre and reach searched on a grid over the angles
            // travelled, then refined. One searched value more than the shapes above, so it is
            // taken only where it lowers the training RSS by more than that buys (the test
            // the two-period ripple passes): a taut cable stays a cable, which a model file holds.
            // Its reach is at least a tenth of the travel and its centre inside the middle 80 %
            // of the angles: a narrow spike, or one at a turning point of the motion, fits what
            // happens where the joint reverses (a friction transition, a ripple's lobe) as
            // well as any pad (development seeds: a ripple's lobe named a second effect).
            let span = (qat(0.98) - qat(0.02)).max(1e-6);
            let (h_lo, h_hi) = (0.1 * span, span);
            let halves: Vec<f64> = (0..6).map(|j| h_lo * (8f64).powf(j as f64 / 5.0)).collect();
            let centres: Vec<f64> = (0..24).map(|j| qat(0.1 + 0.8 * j as f64 / 23.0)).collect();
            let pad = |c: f64, h: f64| Effect::Cable { engage: c, width: h, side: 2 };
            let mut pb: Option<(f64, f64, f64)> = None;
            for &h in &halves {
                for &c in &centres {
                    let r = rss_of(pad(c, h));
                    if pb.map(|(_, _, b)| r < b).unwrap_or(true) {
                        pb = Some((c, h, r));
                    }
                }
            }
            if let (Some((c, h, _)), Some((r_other, _))) = (pb, best) {
                let dc = 0.8 * span / 23.0;
                let (c, _) = golden((c - dc).max(qat(0.1)), (c + dc).min(qat(0.9)), 16, |x| rss_of(pad(x, h)));
                let (lh, r) =
                    golden((h / 1.5).max(h_lo).ln(), (h * 1.5).min(h_hi).ln(), 16, |x| rss_of(pad(c, x.exp())));
                let n = idx.len() as f64;
                if r > 0.0 && n * (r_other / r).ln() > 2.0 * n.ln() {
                    best = Some((r, pad(c, lh.exp())));
                }
            }
            best.map(|(_, e)| e)
        }
        Kind::Backlash => {
            let qs: Vec<f64> = idx.iter().map(|&i| (d.q[i as usize] - d.q0).abs()).collect();
            let reach = quantile(qs, 0.9).max(1e-3);
            // centred on the spring's rest angle, or all on one side of it
            let mut best: Option<(f64, Effect)> = None;
            for side in [0.0, 0.5, -0.5] {
                let e = log_search(1e-3 * reach, 1.5 * reach, 24, &|w| Effect::Backlash { width: w, offset: side * w });
                let r = rss_of(e);
                if best.as_ref().map(|(b, _)| r < *b).unwrap_or(true) {
                    best = Some((r, e));
                }
            }
            best.map(|(_, e)| e)
        }
        Kind::Delay => best_delay(d, &rss_of),
    }
}

/// The delay (channel and whole-sample lag) with the lowest `rss_of`.
pub fn best_delay(d: &Data, rss_of: &dyn Fn(Effect) -> f64) -> Option<Effect> {
    // Each channel (u, tau, the state) shifted by whole samples either way, from two
    // samples up to 100 ms (at most 200 samples). No fractional lag: interpolating a
    // noisy channel between two samples averages its noise away, which scores as a
    // "delay" of half a sample on any noisy log. No lag of one sample: a torque held over
    // the sample period (zero-order hold) already puts the q̈ seen from q half a sample
    // off the logged u, whichever way the logger stamps it, so one sample is the
    // logging convention, not a delay. A coarse pass (every other lag) then the best
    // lag's neighbours.
    let max_lag = ((0.1 / d.dt).round() as i64).clamp(4, 200);
    let channels: Vec<Channel> =
        Channel::ALL.into_iter().filter(|c| *c != Channel::Tau || d.tau.iter().any(|t| *t != 0.0)).collect();
    let consider = |best: &mut Option<(f64, Effect)>, e: Effect| {
        let r = rss_of(e);
        if best.as_ref().map(|(b, _)| r < *b).unwrap_or(true) {
            *best = Some((r, e));
        }
    };
    // coarse lags about 15 % apart (every lag up to 8), then every lag around the best
    let mut coarse: Vec<i64> = (2..=8).collect();
    while let Some(&l) = coarse.last() {
        let next = ((l as f64) * 1.15).ceil() as i64;
        if next > max_lag {
            break;
        }
        coarse.push(next);
    }
    let mut best: Option<(f64, Effect)> = None;
    for &channel in &channels {
        for &l in &coarse {
            for sgn in [1.0, -1.0] {
                consider(&mut best, Effect::Delay { lag: sgn * l as f64, channel });
            }
        }
    }
    if let Some((_, Effect::Delay { lag, channel })) = best {
        let reach = (lag.abs() * 0.15).ceil().max(1.0);
        let mut off = -reach;
        while off <= reach {
            let l = lag + off;
            if off != 0.0 && l.abs() >= 2.0 && l.abs() <= max_lag as f64 {
                consider(&mut best, Effect::Delay { lag: l, channel });
            }
            off += 1.0;
        }
    }
    best.map(|(_, e)| e)
}

/// The model's refittable terms from its parameter values. A term is the model's when the file
/// states it (spec §2: a term written as 0 is a term with value 0, a missing key is absent).
pub fn base_from_model(m: &joint_formats::model_file::ModelFile) -> Base {
    use joint_core::params::ParamId as P;
    let v = |id| m.value(id);
    let has = |id| m.explicit(id).is_some();
    let mut cols = Vec::new();
    let mut beta0 = Vec::new();
    let mut push = |c: Col, b: f64| {
        cols.push(c);
        beta0.push(b);
    };
    if has(P::InertiaJ) {
        push(Col::Qdd, v(P::InertiaJ));
    }
    if has(P::FrictionA) {
        push(Col::QdAbsQd, v(P::FrictionA));
    }
    if has(P::FrictionB) || has(P::SpringB) {
        push(Col::Qd, v(P::FrictionB) + v(P::SpringB));
    }
    if has(P::FrictionC) {
        push(Col::Sgn, v(P::FrictionC));
    }
    if has(P::WeightAmplitude) {
        let (amp, s, phi) = (v(P::WeightAmplitude), v(P::WeightS), v(P::WeightPhi));
        // A·sin(s·q + φ) = A·cos φ·sin(s·q) + A·sin φ·cos(s·q)
        push(Col::SinSq(s), amp * phi.cos());
        push(Col::CosSq(s), amp * phi.sin());
    }
    let k = v(P::SpringK);
    if has(P::SpringK) {
        push(Col::Q, k);
    }
    if has(P::OffsetC0) || has(P::SpringK) {
        push(Col::Const, v(P::OffsetC0) - k * v(P::SpringQ0));
    }
    // Effect terms the model already carries (the core compensates them) are its own terms too:
    // refitted with the rest, shapes kept.
    if has(P::StribeckLevel) {
        push(Col::Stribeck(v(P::StribeckSpeed)), v(P::StribeckLevel));
    }
    if has(P::AsymmetricDelta) {
        push(Col::AbsSgn, v(P::AsymmetricDelta));
    }
    if has(P::RippleAmplitude) {
        let (ra, ph) = (v(P::RippleAmplitude), v(P::RipplePhase));
        push(Col::RipSin(v(P::RipplePeriod)), ra * ph.cos());
        push(Col::RipCos(v(P::RipplePeriod)), ra * ph.sin());
        if has(P::RippleAmplitude2) {
            let (ra2, ph2) = (v(P::RippleAmplitude2), v(P::RipplePhase2));
            push(Col::RipSin(v(P::RipplePeriod) / 2.0), ra2 * ph2.cos());
            push(Col::RipCos(v(P::RipplePeriod) / 2.0), ra2 * ph2.sin());
        }
    }
    if has(P::CableK) {
        push(Col::Cable { engage: v(P::CableEngage), width: v(P::CableWidth) }, v(P::CableK));
    }
    if has(P::DryFrictionC) && !has(P::FrictionC) {
        push(Col::Sgn, v(P::DryFrictionC));
    }
    if has(P::LoadFrictionMu) {
        push(Col::LoadSgn, v(P::LoadFrictionMu));
    }
    let fixed = vec![false; cols.len()];
    Base { cols, beta0, fixed }
}
