//! Trajectory mode (a log without `u`/`tau`, e.g. the free oscillation of an elastic joint):
//! the model `J·q̈ = u − D(q, q̇)` is integrated (RK4, up to 4 sub-steps per sample, `u` held; `u` = 0
//! when the log has none) and the simulated angle is compared with the logged one.
//!
//! Initial state, explicitly: the file's model starts from the first sample's logged angle and
//! velocity (velocity derived from q when not logged). The `initial_state` candidate frees both.
//! Every other candidate keeps that assumed start, so a wrong start is reported as such and not
//! absorbed by friction or stiffness.
//!
//! Split: the run is one trajectory, so the held-out part is its last 30 % in time: fits see
//! the first 70 % only, and the held-out score is how well the fitted model predicts the rest of
//! the motion by simulation alone. Fits: Levenberg–Marquardt on the training residual (at most
//! 4000 samples), multi-start over the shape parameters (period, engagement, width, speed). J is
//! fixed (a free response scales with D/J only); the model's other terms are refitted with every
//! candidate. Significance: the held-out part is cut into 20 units and tested as in torque mode.

use std::collections::BTreeMap;

use joint_core::params::{ParamId, ParamSet};

use super::candidates::{base_from_model, Col};
use super::fit::levenberg_marquardt;
use super::regimes::Regimes;
use super::select::{compare, Scored, ALPHA, AT_FLOOR, MIN_GAIN};
use super::{
    DiagError, Diagnosis, EffectOut, Gap, Options, PlotData, RegimeOut, RegimeShrink, Report, SplitInfo, Step,
    TestInfo, Verdict,
};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

#[derive(Clone, Copy, Debug, PartialEq)]
enum TKind {
    Parameters,
    InitialState,
    Stribeck,
    Asymmetric,
    Thermal,
    Ripple,
    Cable,
    Backlash,
    Dry,
}

impl TKind {
    fn name(self) -> &'static str {
        match self {
            TKind::Parameters => "parameters",
            TKind::InitialState => "initial_state",
            TKind::Stribeck => "stribeck",
            TKind::Asymmetric => "asymmetric_friction",
            TKind::Thermal => "thermal_drift",
            TKind::Ripple => "position_ripple",
            TKind::Cable => "cable_spring",
            TKind::Backlash => "backlash",
            TKind::Dry => "dry_friction",
        }
    }
}

struct Sim<'a> {
    t: &'a [f64],
    u: Option<&'a [f64]>,
    j: f64,
    band: f64,
    q0: f64,
    cols: Vec<Col>,
    init: (f64, f64),
    /// the model's fastest rate away from rest, 1/s (see [`fastest_rate`])
    rate: f64,
}

fn sgn(v: f64, band: f64) -> f64 {
    super::sgn_band(v, band)
}

impl Sim<'_> {
    fn disturbance(&self, kind: TKind, th: &[f64], t: f64, q: f64, qd: f64) -> f64 {
        let nb = self.cols.len();
        let e = &th[nb..];
        let s = sgn(qd, self.band);
        let mut fr = 0.0;
        let mut rest = 0.0;
        // The weight's sin and cos share one argument: one sin_cos serves both columns (the
        // same values; the sin and cos calls were most of a simulation's time).
        let mut weight: Option<(f64, (f64, f64))> = None;
        let mut sc = |w: f64| match weight {
            Some((wa, v)) if wa == w => v,
            _ => {
                let v = (w * q).sin_cos();
                weight = Some((w, v));
                v
            }
        };
        for (c, b) in self.cols.iter().zip(th) {
            let v = match c {
                Col::QdAbsQd => qd * qd.abs(),
                Col::Qd => qd,
                Col::Sgn => s,
                Col::SinSq(w) => sc(*w).0,
                Col::CosSq(w) => sc(*w).1,
                Col::Q => match kind {
                    TKind::Backlash => super::shapes::dead_zone(q - self.q0, e[0].exp()) + self.q0,
                    _ => q,
                },
                Col::Const => 1.0,
                // the model's own effect terms (the core compensates them)
                Col::Stribeck(v) => {
                    let r = qd / v;
                    (-r * r).exp() * s
                }
                Col::AbsSgn => s.abs(),
                Col::RipSin(p) => (std::f64::consts::TAU * q / p).sin(),
                Col::RipCos(p) => (std::f64::consts::TAU * q / p).cos(),
                Col::Cable { engage, width } => super::shapes::engaged_spring(1.0, *engage, *width, q),
                _ => 0.0,
            };
            if matches!(c, Col::QdAbsQd | Col::Qd | Col::Sgn) {
                fr += b * v;
            } else {
                rest += b * v;
            }
        }
        let extra = match kind {
            TKind::Stribeck => {
                let r = qd / e[1].exp();
                e[0] * (-r * r).exp() * s
            }
            TKind::Asymmetric => e[0] * s.abs(),
            TKind::Dry => e[0] * s,
            TKind::Thermal => e[0] * (1.0 - (-(t - self.t[0]) / e[1].exp()).exp()) * fr,
            TKind::Ripple => {
                let w = std::f64::consts::TAU * q / e[2].exp();
                e[0] * w.sin() + e[1] * w.cos()
            }
            TKind::Cable => super::shapes::engaged_spring(e[0], e[1], 0.01, q),
            _ => 0.0,
        };
        fr + rest + extra
    }

    /// Simulated q at samples 0..n; `None` if the integration diverges.
    fn run(&self, kind: TKind, th: &[f64], n: usize) -> Option<Vec<f64>> {
        let (mut q, mut qd) = if kind == TKind::InitialState {
            let nb = self.cols.len();
            (th[nb], th[nb + 1])
        } else {
            self.init
        };
        let mut out = Vec::with_capacity(n);
        out.push(q);
        // Highest spatial frequency (rad⁻¹) of a term periodic in q: a torque that varies in time
        // at κ·|q̇| however soft it is.
        let nb = self.cols.len();
        let ripple =
            if kind == TKind::Ripple { th.get(nb + 2).map_or(0.0, |lp| std::f64::consts::TAU / lp.exp()) } else { 0.0 };
        let kappa = self
            .cols
            .iter()
            .map(|c| match *c {
                Col::SinSq(w) | Col::CosSq(w) => w.abs(),
                Col::RipSin(p) | Col::RipCos(p) => std::f64::consts::TAU / p.abs(),
                _ => 0.0,
            })
            .fold(ripple, f64::max);
        // Around rest the friction changes steeply where the model (or this candidate) has it:
        // inside the sign band of a Coulomb-like term (a kink at its edge) and over a Stribeck
        // curve (three of its speeds).
        let signed = matches!(kind, TKind::Stribeck | TKind::Asymmetric | TKind::Dry)
            || self.cols.iter().any(|c| matches!(c, Col::Sgn | Col::AbsSgn | Col::Stribeck(_)));
        let stribeck = if kind == TKind::Stribeck { th.get(nb + 1).map_or(0.0, |lv| lv.exp()) } else { 0.0 };
        let band = if signed { 2.0 * self.band } else { 0.0 };
        // A candidate's own stiffness (its fitted cable k, or a ripple's A·2π/P) adds to the
        // model's when the fastest mode is judged.
        let e = th.get(nb..).unwrap_or(&[]);
        let extra_k = match (kind, e) {
            (TKind::Cable, [k, ..]) => k.abs(),
            (TKind::Ripple, [a, b, lp, ..]) => a.hypot(*b) * std::f64::consts::TAU / lp.exp(),
            _ => 0.0,
        };
        let rate = self.rate.max(3.0 * (extra_k / self.j).sqrt());
        let near_rest = self
            .cols
            .iter()
            .map(|c| if let Col::Stribeck(v) = *c { 3.0 * v.abs() } else { 0.0 })
            .fold(band.max(3.0 * stribeck), f64::max);
        for i in 1..n {
            let (t0, t1) = (self.t[i - 1], self.t[i]);
            let u = self.u.map(|u| u[i - 1]).unwrap_or(0.0);
            let f = |t: f64, q: f64, qd: f64| (qd, (u - self.disturbance(kind, th, t, q, qd)) / self.j);
            // The first RK4 stage is the same for any number of sub-steps; its q̈ says how far
            // q̇ can move during this sample.
            let first = f(t0, q, qd);
            // RK4 sub-steps: four (what every sample used before) where q̇ may come near rest
            // during the sample, since the friction there is steep or has a kink that costs RK4
            // its order; elsewhere enough that the fastest mode, or a periodic term at this
            // speed, advances ≤ 0.1 per step.
            let dt = t1 - t0;
            let sub = if qd.abs() - 1.5 * first.1.abs() * dt < near_rest {
                4
            } else {
                (dt * rate.max(kappa * qd.abs()) / 0.1).ceil().clamp(1.0, 4.0) as usize
            };
            let h = dt / sub as f64;
            for k in 0..sub {
                let t = t0 + k as f64 * h;
                let (a1, b1) = if k == 0 { first } else { f(t, q, qd) };
                let (a2, b2) = f(t + 0.5 * h, q + 0.5 * h * a1, qd + 0.5 * h * b1);
                let (a3, b3) = f(t + 0.5 * h, q + 0.5 * h * a2, qd + 0.5 * h * b2);
                let (a4, b4) = f(t + h, q + h * a3, qd + h * b3);
                q += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                qd += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
            }
            if !(q.is_finite() && qd.is_finite()) || q.abs() > 1e6 {
                return None;
            }
            out.push(q);
        }
        Some(out)
    }
}

struct Fitted {
    kind: TKind,
    theta: Vec<f64>,
    sim: Vec<f64>,
    scored: Scored,
}

#[allow(clippy::too_many_arguments)]
fn score_traj(
    sim_q: &[f64],
    q: &[f64],
    hold_from: usize,
    units: usize,
    bits: &[u32],
    nreg: usize,
    theta: Vec<f64>,
) -> Scored {
    let n = q.len();
    let len = (n - hold_from).div_ceil(units).max(1);
    let mut s = Scored {
        effects: vec![],
        design: super::candidates::Design {
            cols: vec![],
            lag: 0.0,
            channel: super::candidates::Channel::U,
            dahl: None,
            spans: vec![],
            prior: vec![],
        },
        beta: theta,
        sse: 0.0,
        n: n - hold_from,
        unit_sse: vec![0.0; units],
        unit_n: vec![0.0; units],
        regime_sse: vec![0.0; nreg],
        regime_n: vec![0.0; nreg],
    };
    for i in hold_from..n {
        let r = q[i] - sim_q[i];
        let r2 = r * r;
        s.sse += r2;
        let u = ((i - hold_from) / len).min(units - 1);
        s.unit_sse[u] += r2;
        s.unit_n[u] += 1.0;
        let mut b = bits[i];
        while b != 0 {
            let j = b.trailing_zeros() as usize;
            if j < nreg {
                s.regime_sse[j] += r2;
                s.regime_n[j] += 1.0;
            }
            b &= b - 1;
        }
    }
    s
}

/// Index after which neither `a` nor `b` moves any more: both stay within 2 % of their own range
/// of their final value (the median of the last 2 %); `len` when either moves to the end.
fn settled_from(a: &[f64], b: &[f64]) -> usize {
    let last_moving = |x: &[f64]| -> usize {
        let n = x.len();
        let k = (n / 50).max(10).min(n);
        let mut tail: Vec<f64> = x[n - k..].to_vec();
        tail.sort_by(|p, q| p.total_cmp(q));
        let end = tail[k / 2];
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        let thr = 0.02 * (hi - lo);
        if !(thr > 0.0) {
            return 0;
        }
        x.iter().rposition(|&v| (v - end).abs() > thr).map_or(0, |i| i + 1)
    };
    last_moving(a).max(last_moving(b))
}

/// Trajectory mode. A free response usually ends at rest; when the last stretch of the log is
/// rest in the data **and** in the model's simulation (≥ 30 % of the log), it carries nothing
/// to test and would make the held-out part (the last 30 %) empty of motion, so the analysis
/// keeps the samples up to the end of motion plus a margin (10 % of that or 0.25 s, whichever
/// is longer, so where each comes to rest still counts) and says so in `split.rest_tail`.
pub fn diagnose(log: &JointLog, model: &ModelFile, params: &ParamSet, opts: &Options) -> Result<Diagnosis, DiagError> {
    let n = log.len();
    let m0_sim = model_free_response(log, model);
    if let Some(sim) = &m0_sim {
        let moving_until = settled_from(&log.q, sim);
        let dt = super::median_dt(&log.t);
        let margin = ((0.1 * moving_until as f64) as usize).max((0.25 / dt).round() as usize);
        let keep = moving_until.saturating_add(margin);
        if moving_until >= 100 && keep < n && (n - keep) as f64 >= 0.3 * n as f64 {
            // The simulation is step by step from the first sample: its prefix is the cut log's.
            let cut = truncated(log, keep);
            let mut d = diagnose_window(&cut, model, params, opts, sim.get(..keep).map(<[f64]>::to_vec))?;
            d.report.samples = n;
            d.report.split.rest_tail = Some(super::RestTail { from_t: log.t[keep], samples: n - keep });
            return Ok(d);
        }
    }
    diagnose_window(log, model, params, opts, m0_sim)
}

/// The first `keep` samples of a log.
fn truncated(log: &JointLog, keep: usize) -> JointLog {
    let cut = |v: &Option<Vec<f64>>| v.as_ref().map(|x| x[..keep].to_vec());
    JointLog {
        t: log.t[..keep].to_vec(),
        q: log.q[..keep].to_vec(),
        qd: cut(&log.qd),
        qdd: cut(&log.qdd),
        u: cut(&log.u),
        tau: cut(&log.tau),
        temp: cut(&log.temp),
        others: log.others.iter().map(|(k, v)| (k.clone(), v[..keep].to_vec())).collect(),
        unknown: log.unknown.clone(),
    }
}

/// The file's model integrated over the whole log from its first sample (`None` if it cannot be).
fn model_free_response(log: &JointLog, model: &ModelFile) -> Option<Vec<f64>> {
    let j = model.value(ParamId::InertiaJ);
    if !(j > 0.0) || log.len() < 3 {
        return None;
    }
    let dt = super::median_dt(&log.t);
    let (qd_raw, _) = super::velocities(log, dt);
    let (sim, beta0) = model_sim(log, model, j, qd_raw[0]);
    sim.run(TKind::Parameters, &beta0, log.len())
}

/// The simulator of the model's own terms (q̈ is its integrated state, not a regressor) from the
/// log's first angle and `qd0`, and the model's values of those terms.
fn model_sim<'a>(log: &'a JointLog, model: &ModelFile, j: f64, qd0: f64) -> (Sim<'a>, Vec<f64>) {
    let base = base_from_model(model);
    let cols: Vec<Col> = base.cols.iter().copied().filter(|c| *c != Col::Qdd).collect();
    let beta0: Vec<f64> = base.cols.iter().zip(&base.beta0).filter(|(c, _)| **c != Col::Qdd).map(|(_, b)| *b).collect();
    let sim = Sim {
        t: &log.t,
        u: log.u.as_deref(),
        j,
        band: model.value(ParamId::FrictionVBand),
        q0: model.value(ParamId::SpringQ0),
        rate: fastest_rate(&cols, &beta0, j),
        cols,
        init: (log.q[0], qd0),
    };
    (sim, beta0)
}

/// The fastest rate of the model's dynamics away from rest, 1/s, with a factor 3 of room for
/// what a fit may do to its values: viscous damping decays at b/J, the stiffness of the spring,
/// weight, ripple and cable terms oscillates at √(k/J). (Near rest, where the Coulomb band and
/// a Stribeck curve are steep, and how fast a periodic term varies at the current speed, are
/// handled per sample in [`Sim::run`].)
fn fastest_rate(cols: &[Col], beta: &[f64], j: f64) -> f64 {
    let (mut damping, mut stiffness) = (0.0, 0.0);
    for (c, b) in cols.iter().zip(beta) {
        let b = b.abs();
        match *c {
            Col::Qd => damping += b,
            Col::Q | Col::Cable { .. } => stiffness += b,
            Col::SinSq(w) | Col::CosSq(w) => stiffness += b * w.abs(),
            Col::RipSin(p) | Col::RipCos(p) => stiffness += b * std::f64::consts::TAU / p.abs().max(1e-9),
            _ => {}
        }
    }
    3.0 * (damping / j).max((stiffness / j).sqrt())
}

/// One window's analysis, step by step: [`Window::prepare`] (velocities, the model's simulator,
/// the split, the regimes and the file's model's response), [`Window::fit_candidates`] (every
/// candidate fitted from its starts), [`Window::judge`] (significance and the verdict), then the
/// report, the emitted model and the plots from what those steps found.
fn diagnose_window(
    log: &JointLog,
    model: &ModelFile,
    params: &ParamSet,
    opts: &Options,
    m0_sim: Option<Vec<f64>>,
) -> Result<Diagnosis, DiagError> {
    let _ = (params, opts);
    let w = Window::prepare(log, model, m0_sim)?;
    let refit = w
        .fit(TKind::Parameters, vec![w.beta0.clone()])
        .ok_or_else(|| DiagError::Input("the refit of the model's own terms diverged".into()))?;
    let fitted = w.fit_candidates(&refit.theta);
    let judged = w.judge(&refit, &fitted);
    let final_fit = match judged.best {
        Some(k) => Some(judged.outcomes[k].fitted),
        None if judged.refit_sig => Some(&refit),
        None => None,
    };
    let final_sim: &[f64] = final_fit.map(|f| f.sim.as_slice()).unwrap_or(&w.m0_sim);
    let ra: Vec<f64> = log.q.iter().zip(final_sim).map(|(a, b)| a - b).collect();
    let report = w.report(&refit, &judged, final_fit, &ra);
    let emitted_model = emitted_model(model, &w.cols, final_fit);
    let plots = w.plots(&ra);
    Ok(Diagnosis { report, emitted_model, plots })
}

/// What every step of one window's analysis reads.
struct Window<'a> {
    log: &'a JointLog,
    model: &'a ModelFile,
    n: usize,
    dt: f64,
    /// q̇ as logged or derived (the start of the file's model)
    qd_raw: Vec<f64>,
    /// q̇ smoothed, for the regimes, the evidence and the plots
    qd: Vec<f64>,
    sim: Sim<'a>,
    /// the model's own values of `cols`
    beta0: Vec<f64>,
    cols: Vec<Col>,
    /// first held-out sample: the last 30 % are held out
    hold_from: usize,
    units: usize,
    regimes: Regimes,
    nreg: usize,
    /// training samples the fits see (thinned to ≤ ~2000)
    train_idx: Vec<usize>,
    /// the file's model integrated over the window, its held-out score and its residual
    m0_sim: Vec<f64>,
    m0: Scored,
    r0: Vec<f64>,
    floor: f64,
    /// training angles: lowest, and the range travelled
    qmin: f64,
    span: f64,
    /// longest ripple period searched
    ripple_max: f64,
}

/// A candidate's test against its reference.
struct Outcome<'f> {
    fitted: &'f Fitted,
    t: f64,
    p: f64,
    gain: f64,
    significant: bool,
}

/// What [`Window::judge`] decided.
struct Judged<'f> {
    alpha_each: f64,
    /// the refit against the file's model: t, p, gain
    refit_test: (f64, f64, f64),
    refit_sig: bool,
    outcomes: Vec<Outcome<'f>>,
    /// index into `outcomes` of the verdict, if an effect is it
    best: Option<usize>,
}

impl<'a> Window<'a> {
    fn prepare(log: &'a JointLog, model: &'a ModelFile, m0_sim: Option<Vec<f64>>) -> Result<Window<'a>, DiagError> {
        let n = log.len();
        let dt = super::median_dt(&log.t);
        let (qd_raw, qdd) = super::velocities(log, dt);
        let qd = super::smooth(&qd_raw, ((super::VELOCITY_SMOOTHING_S / dt).round() as usize).min(25));
        let j = model.value(ParamId::InertiaJ);
        if !(j > 0.0) {
            return Err(DiagError::Input(
                "trajectory mode integrates the model: its [inertia] j must be > 0 (the log has no u/tau for torque mode)"
                    .into(),
            ));
        }
        let (sim, beta0) = model_sim(log, model, j, qd_raw[0]);
        let cols = sim.cols.clone();
        let hold_from = (0.7 * n as f64).round() as usize;
        let units = 20usize.min((n - hold_from) / 5).max(3);
        let regimes = Regimes::build(&log.t, &log.q, &qd, &qdd, log.temp.as_deref(), dt);
        let nreg = regimes.defs.len();
        let train_idx: Vec<usize> = (0..hold_from).step_by(hold_from.div_ceil(2000).max(1)).collect();
        let m0_sim = match m0_sim {
            Some(s) => s,
            None => sim.run(TKind::Parameters, &beta0, n).ok_or_else(|| {
                DiagError::Input("the model diverges when integrated from the log's first sample".into())
            })?,
        };
        let m0 = score_traj(&m0_sim, &log.q, hold_from, units, &regimes.bits, nreg, beta0.clone());
        let r0: Vec<f64> = log.q.iter().zip(&m0_sim).map(|(a, b)| a - b).collect();
        let floor = super::noise_floor(&r0);
        let qmin = log.q.iter().take(hold_from).copied().fold(f64::INFINITY, f64::min);
        let qmax = log.q.iter().take(hold_from).copied().fold(f64::NEG_INFINITY, f64::max);
        let span = (qmax - qmin).max(1e-3);
        // Ripple periods searched: short (gear mesh, cogging, wave generator: ≤ 0.2 rad) and at
        // least three periods inside the angles travelled, as in torque mode.
        let ripple_max = (span / 3.0).min(0.2);
        Ok(Window {
            log,
            model,
            n,
            dt,
            qd_raw,
            qd,
            sim,
            beta0,
            cols,
            hold_from,
            units,
            regimes,
            nreg,
            train_idx,
            m0_sim,
            m0,
            r0,
            floor,
            qmin,
            span,
            ripple_max,
        })
    }

    fn has(&self, c: Col) -> bool {
        self.cols.contains(&c)
    }

    /// LM fit of one kind from one start; residuals on the training samples only.
    fn lm(&self, kind: TKind, th0: &[f64], iters: usize) -> Option<(Vec<f64>, f64)> {
        let steps: Vec<f64> = th0.iter().map(|v| 1e-6 * v.abs().max(1e-3)).collect();
        levenberg_marquardt(th0, &steps, iters, |th| {
            let s = self.sim.run(kind, th, self.hold_from)?;
            Some(self.train_idx.iter().map(|&i| s[i] - self.log.q[i]).collect())
        })
    }

    /// The best LM fit of one kind over its starts, scored on the held-out part. With many
    /// starts (a searched period) each gets 4 iterations first and only the 3 best go on.
    fn fit(&self, kind: TKind, starts: Vec<Vec<f64>>) -> Option<Fitted> {
        let starts = if starts.len() > 4 {
            let mut pre: Vec<(Vec<f64>, f64)> = starts.iter().filter_map(|th0| self.lm(kind, th0, 4)).collect();
            pre.sort_by(|a, b| a.1.total_cmp(&b.1));
            pre.into_iter().take(3).map(|(th, _)| th).collect()
        } else {
            starts
        };
        let mut best: Option<(Vec<f64>, f64)> = None;
        for th0 in starts {
            if let Some((th, c)) = self.lm(kind, &th0, 30) {
                if best.as_ref().map(|b| c < b.1).unwrap_or(true) {
                    best = Some((th, c));
                }
            }
        }
        let (theta, _) = best?;
        // A period that ran off its range is no ripple (a huge period is a constant torque).
        if kind == TKind::Ripple
            && !theta.get(self.cols.len() + 2).is_some_and(|lp| (0.01..=1.5 * self.ripple_max).contains(&lp.exp()))
        {
            return None;
        }
        let s = self.sim.run(kind, &theta, self.n)?;
        let scored =
            score_traj(&s, &self.log.q, self.hold_from, self.units, &self.regimes.bits, self.nreg, theta.clone());
        Some(Fitted { kind, theta, sim: s, scored })
    }

    /// Each candidate kind with its starts: the refitted model's values `bp` plus the effect's.
    fn candidate_starts(&self, bp: &[f64]) -> Vec<(TKind, Vec<Vec<f64>>)> {
        let with = |e: &[f64]| -> Vec<f64> {
            let mut v = bp.to_vec();
            v.extend_from_slice(e);
            v
        };
        let (log, n, qmin, span) = (self.log, self.n, self.qmin, self.span);
        let mut kinds: Vec<(TKind, Vec<Vec<f64>>)> = vec![
            (TKind::InitialState, vec![with(&[log.q[0], self.qd_raw[0]])]),
            (TKind::Stribeck, [0.02f64, 0.1, 0.5].iter().map(|v| with(&[0.0, v.ln()])).collect()),
            (TKind::Asymmetric, vec![with(&[0.0])]),
            (
                TKind::Thermal,
                [0.3f64, 3.0].iter().map(|f| with(&[0.0, (f * (log.t[n - 1] - log.t[0])).ln()])).collect(),
            ),
            // The period is where the fit is multimodal (a start more than ~10 % off locks onto a
            // wrong period): starts every 15 % from 0.015 rad to `ripple_max`.
            (
                TKind::Ripple,
                (0..40)
                    .map(|i| 0.015 * 1.15f64.powi(i))
                    .take_while(|p| *p <= self.ripple_max)
                    .map(|p| with(&[0.01, 0.01, p.ln()]))
                    .collect(),
            ),
            (TKind::Cable, [0.3f64, 0.5, 0.7].iter().map(|f| with(&[0.0, qmin + f * span])).collect()),
        ];
        if self.has(Col::Q) {
            kinds.push((TKind::Backlash, [0.01f64, 0.05].iter().map(|w| with(&[(w * span).ln()])).collect()));
        }
        if !self.has(Col::Sgn) {
            kinds.push((TKind::Dry, vec![with(&[0.0])]));
        }
        kinds.into_iter().filter(|(_, s)| !s.is_empty()).collect()
    }

    /// Every candidate fitted on top of the refit `bp`; they are independent, so two threads.
    fn fit_candidates(&self, bp: &[f64]) -> Vec<Fitted> {
        let kinds = self.candidate_starts(bp);
        let half = kinds.len().div_ceil(2);
        let (ka, kb) = kinds.split_at(half);
        std::thread::scope(|sc| {
            let h = sc.spawn(move || kb.iter().filter_map(|(k, s)| self.fit(*k, s.clone())).collect::<Vec<_>>());
            let mut v: Vec<Fitted> = ka.iter().filter_map(|(k, s)| self.fit(*k, s.clone())).collect();
            v.extend(h.join().unwrap_or_default());
            v
        })
    }

    /// Significance of the refit and every candidate, and the verdict among them.
    fn judge<'f>(&self, refit: &'f Fitted, fitted: &'f [Fitted]) -> Judged<'f> {
        let m_tests = (fitted.len() + 1) as f64;
        let alpha_each = ALPHA / m_tests;
        let at_floor = self.m0.rmse() <= AT_FLOOR * self.floor;
        let refit_test = compare(&self.m0, &refit.scored);
        let refit_sig = !at_floor && refit_test.1 < alpha_each && refit_test.2 >= MIN_GAIN;
        // initial_state is judged against the file's model (it keeps the model's values); every
        // effect against the refit.
        let outcomes: Vec<Outcome> = fitted
            .iter()
            .map(|f| {
                let reference = if f.kind == TKind::InitialState { &self.m0 } else { &refit.scored };
                let (t, p, gain) = compare(reference, &f.scored);
                // and, like in torque mode, better than the file's model itself
                let (_, p0, g0) = compare(&self.m0, &f.scored);
                let ok = implausible(self.cols.len(), f).is_none();
                let significant =
                    ok && !at_floor && p < alpha_each && gain >= MIN_GAIN && p0 < alpha_each && g0 >= MIN_GAIN;
                Outcome { fitted: f, t, p, gain, significant }
            })
            .collect();
        let best = (0..outcomes.len())
            .filter(|&k| outcomes[k].significant)
            .min_by(|&a, &b| outcomes[a].fitted.scored.mse().total_cmp(&outcomes[b].fitted.scored.mse()));
        // initial_state is tested against the file's model, not the refit; but its fit refits the
        // model's values too (it nests the refit), so when the refit is significant on its own the
        // start must also beat the refit: otherwise the values are what is wrong, not the start.
        let beats_refit = |f: &Fitted| {
            let (_, p, g) = compare(&refit.scored, &f.scored);
            p < alpha_each && g >= MIN_GAIN
        };
        let best = best.filter(|&k| {
            let f = outcomes[k].fitted;
            !(f.kind == TKind::InitialState && refit_sig && !beats_refit(f))
        });
        Judged { alpha_each, refit_test, refit_sig, outcomes, best }
    }

    /// Held-out RMSE per regime before (the file's model) and after `s`.
    fn regime_shrinks(&self, s: &Scored) -> Vec<RegimeShrink> {
        let m0 = &self.m0;
        self.regimes
            .defs
            .iter()
            .enumerate()
            .filter(|(k, _)| m0.regime_n[*k] > 0.0)
            .map(|(k, r)| RegimeShrink {
                name: r.name.clone(),
                holdout_rmse_before: (m0.regime_sse[k] / m0.regime_n[k]).sqrt(),
                holdout_rmse_after: (s.regime_sse[k] / s.regime_n[k].max(1.0)).sqrt(),
            })
            .collect()
    }

    /// The refit first, then every candidate, best held-out RMSE first.
    fn effects_out(&self, refit: &Fitted, j: &Judged) -> Vec<EffectOut> {
        let before = self.m0.rmse();
        let (rt, rp, rg) = j.refit_test;
        let mut effects: Vec<EffectOut> = vec![EffectOut {
            effect: "parameters".into(),
            holdout_rmse_before: before,
            holdout_rmse_after: refit.scored.rmse(),
            shrink: super::shrink(before, refit.scored.rmse()),
            significant: j.refit_sig,
            params: effect_params(self.model, &self.cols, refit),
            reference: "model",
            t_stat: rt.clamp(-1e9, 1e9),
            p_value: rp,
            gain: rg,
            implausible: None,
            regimes: self.regime_shrinks(&refit.scored),
        }];
        for o in &j.outcomes {
            let f = o.fitted;
            effects.push(EffectOut {
                effect: f.kind.name().into(),
                holdout_rmse_before: before,
                holdout_rmse_after: f.scored.rmse(),
                shrink: super::shrink(before, f.scored.rmse()),
                significant: o.significant,
                params: effect_params(self.model, &self.cols, f),
                reference: if f.kind == TKind::InitialState { "model" } else { "parameters" },
                t_stat: o.t.clamp(-1e9, 1e9),
                p_value: o.p,
                gain: o.gain,
                implausible: implausible(self.cols.len(), f),
                regimes: self.regime_shrinks(&f.scored),
            });
        }
        effects.sort_by(|a, b| a.holdout_rmse_after.total_cmp(&b.holdout_rmse_after));
        effects
    }

    /// Where the file's model's residual lies over the whole window, per regime.
    fn regimes_out(&self) -> (f64, Vec<RegimeOut>) {
        let total: f64 = self.r0.iter().map(|r| r * r).sum();
        let nreg = self.nreg;
        let mut sse = vec![0.0; nreg];
        let mut cnt = vec![0usize; nreg];
        for (i, r) in self.r0.iter().enumerate() {
            let mut b = self.regimes.bits[i];
            while b != 0 {
                let k = b.trailing_zeros() as usize;
                sse[k] += r * r;
                cnt[k] += 1;
                b &= b - 1;
            }
        }
        let out = self
            .regimes
            .defs
            .iter()
            .enumerate()
            .map(|(k, r)| RegimeOut {
                name: r.name.clone(),
                family: r.family,
                where_: r.where_.clone(),
                share: if total > 0.0 { sse[k] / total } else { 0.0 },
                rmse: if cnt[k] > 0 { (sse[k] / cnt[k] as f64).sqrt() } else { 0.0 },
                samples: cnt[k],
            })
            .collect();
        (total, out)
    }

    /// MATLAB-`resid`-style evidence on the held-out part: before and after (residual `ra`).
    fn resid(&self, ra: &[f64]) -> super::Resid {
        let lag = ((0.1 / self.dt).round() as usize).clamp(10, 100);
        let h = self.hold_from;
        let (hold_r0, hold_ra, hold_qd) = (&self.r0[h..], &ra[h..], &self.qd[h..]);
        super::Resid {
            input: vec!["qd"],
            autocorrelation_before: super::resid::xcorr(hold_r0, hold_r0, lag, true),
            autocorrelation_after: super::resid::xcorr(hold_ra, hold_ra, lag, true),
            xcorr_before: vec![super::resid::xcorr(hold_r0, hold_qd, lag, false)],
            xcorr_after: vec![super::resid::xcorr(hold_ra, hold_qd, lag, false)],
        }
    }

    fn not_applicable(&self) -> Vec<super::NotApplicable> {
        let mut v = vec![
            super::NotApplicable {
                effect: "delay",
                why: "a free response has no input to lag: a time shift is an initial state",
            },
            super::NotApplicable {
                effect: "load_dependent_friction",
                why: "trajectory mode has no measured transmitted torque",
            },
        ];
        if !self.has(Col::Q) {
            v.push(super::NotApplicable {
                effect: "backlash",
                why: "the model has no [spring] whose dead zone could be fitted",
            });
        }
        if self.has(Col::Sgn) {
            v.push(super::NotApplicable {
                effect: "dry_friction",
                why: "the model has a Coulomb term, so a missing Coulomb torque is `parameters`",
            });
        }
        v
    }

    /// The report (spec §3): `final_fit` is what the verdict kept, `ra` its residual.
    fn report(&self, refit: &Fitted, j: &Judged, final_fit: Option<&Fitted>, ra: &[f64]) -> Report {
        let (n, hold_from) = (self.n, self.hold_from);
        let before = self.m0.rmse();
        let best = j.best.map(|k| &j.outcomes[k]);
        let (vname, vafter) = match best {
            Some(o) => (o.fitted.kind.name().to_string(), o.fitted.scored.rmse()),
            None if j.refit_sig => ("parameters".to_string(), refit.scored.rmse()),
            None => ("none".to_string(), before),
        };
        let effects = self.effects_out(refit, j);
        let selected: Vec<Step> = match best {
            Some(o) => vec![Step {
                effect: o.fitted.kind.name().into(),
                params: effect_params(self.model, &self.cols, o.fitted),
                holdout_rmse_after: o.fitted.scored.rmse(),
                shrink: super::shrink(before, o.fitted.scored.rmse()),
                p_value: o.p,
            }],
            None => vec![],
        };
        let refit_out = match final_fit {
            Some(f) if f.kind != TKind::InitialState => nest(refit_values(self.model, &self.cols, &f.theta)),
            _ => nest(refit_values(self.model, &self.cols, &self.beta0)),
        };
        let warnings = super::refit_warnings(&effects);
        let (total, regimes) = self.regimes_out();
        Report {
            mode: "trajectory",
            samples: n,
            split: SplitInfo {
                method: "blocked_last_30_percent",
                train: hold_from,
                holdout: n - hold_from,
                blocks: 1,
                held_blocks: vec![],
                guard_samples: 0,
                test_units: self.units,
                rest_tail: None,
            },
            gap: Gap {
                rmse: (total / n as f64).sqrt(),
                holdout_rmse: before,
                noise_floor: self.floor,
                unit: "rad",
                at_noise_floor: vafter <= AT_FLOOR * self.floor,
                qdd_noise_sd: None,
                scored_samples: None,
                rest_creep_samples: None,
            },
            regimes,
            effects,
            verdict: Verdict {
                effect: vname.clone(),
                holdout_rmse_before: before,
                holdout_rmse_after: vafter,
                shrink: super::shrink(before, vafter),
                effects: vec![vname],
                alternatives: Vec::new(),
                closest: Vec::new(),
            },
            selected,
            refit: refit_out,
            test: TestInfo {
                method: "one-sided t-tests on the per-unit log ratio and difference of held-out MSE (20 units of the last 30 %; p = 2·min), Bonferroni over candidates, a 2 % minimum gain, nothing tested once the model is within 5 % of the noise floor",
                alpha: ALPHA,
                alpha_each: j.alpha_each,
                min_gain: MIN_GAIN,
            },
            resid: Some(self.resid(ra)),
            unknown_columns: self.log.unknown.clone(),
            not_applicable: self.not_applicable(),
            warnings,
            prep: None,
        }
    }

    /// Every thinned sample for the HTML report: before (file's model) and after (`ra`).
    fn plots(&self, ra: &[f64]) -> PlotData {
        let (log, n) = (self.log, self.n);
        let stride = (n / 4000).max(1);
        let mut plots = PlotData { unit: "rad", measured_label: "q (rad)", ..PlotData::default() };
        for i in (0..n).step_by(stride) {
            plots.t.push(log.t[i]);
            plots.q.push(log.q[i]);
            plots.qd.push(self.qd[i]);
            plots.measured.push(log.q[i]);
            plots.before.push(self.r0[i]);
            plots.after.push(ra[i]);
            let b = self.regimes.bits[i];
            plots.speed_regime.push(if b & 1 != 0 {
                0
            } else if b & 2 != 0 {
                1
            } else {
                2
            });
            plots.held.push(i >= self.hold_from);
        }
        plots
    }
}

/// The same sign rules as torque mode (`select::implausible`): the first effect parameter is
/// the amplitude. `nb`: how many of the model's own terms precede it.
fn implausible(nb: usize, f: &Fitted) -> Option<&'static str> {
    let amp = f.theta.get(nb).copied()?;
    match f.kind {
        TKind::Stribeck if amp <= 0.0 => {
            Some("fitted Stribeck level is not positive: friction rising towards rest is no Stribeck effect")
        }
        TKind::Cable if amp <= 0.0 => Some("fitted cable stiffness is not positive: a cable cannot push"),
        TKind::Dry if amp <= 0.0 => Some("fitted dry friction level is not positive: friction cannot drive the motion"),
        _ => None,
    }
}

/// A fit's parameters as the report names them: the model's terms for `parameters`, the
/// effect's own for a candidate.
fn effect_params(model: &ModelFile, cols: &[Col], f: &Fitted) -> BTreeMap<String, f64> {
    let e = &f.theta[cols.len()..];
    let mut p = BTreeMap::new();
    let mut put = |k: &str, v: f64| {
        p.insert(k.to_string(), v);
    };
    match f.kind {
        TKind::Parameters => {
            for (k, v) in refit_values(model, cols, &f.theta) {
                put(&k, v);
            }
        }
        TKind::InitialState => {
            put("q", e[0]);
            put("qd", e[1]);
        }
        TKind::Stribeck => {
            put("level", e[0]);
            put("speed", e[1].exp());
        }
        TKind::Asymmetric => put("delta", e[0]),
        TKind::Dry => put("c", e[0]),
        TKind::Thermal => {
            put("coefficient", e[0]);
            put("time_constant", e[1].exp());
        }
        TKind::Ripple => {
            put("amplitude", e[0].hypot(e[1]));
            put("phase", e[1].atan2(e[0]));
            put("period", e[2].exp());
        }
        TKind::Cable => {
            put("k", e[0]);
            put("engage", e[1]);
            put("width", 0.01);
        }
        TKind::Backlash => put("width", e[0].exp()),
    }
    p
}

/// The emitted model: the file's model with the refitted values (clamped into the parameter
/// table's ranges) plus the winning effect's section.
fn emitted_model(model: &ModelFile, cols: &[Col], final_fit: Option<&Fitted>) -> String {
    let mut mf = model.clone();
    if let Some(f) = final_fit {
        if f.kind != TKind::InitialState {
            for (k, v) in refit_values(model, cols, &f.theta) {
                if let Some((sec, key)) = k.split_once('.') {
                    if let Some(d) = joint_core::params::PARAMS.iter().find(|p| p.section == sec && p.key == key) {
                        mf.set(d.id, v.clamp(f64::from(d.min), f64::from(d.max)), None);
                    }
                }
            }
        }
    }
    let mut emitted = String::from("# written by `jointctl diagnose --emit-model` (trajectory mode)\n");
    emitted.push_str(&mf.to_toml_string());
    if let Some(f) = final_fit {
        emitted.push_str(&effect_section(&effect_params(model, cols, f), f.kind));
    }
    emitted
}

/// The plant/model section of a trajectory-mode effect with parameters `p`.
fn effect_section(p: &BTreeMap<String, f64>, kind: TKind) -> String {
    let g = |k: &str| p.get(k).copied().unwrap_or(0.0);
    match kind {
        TKind::Stribeck => format!("\n[stribeck]\nlevel = {:?}\nspeed = {:?}\n", g("level"), g("speed")),
        TKind::Asymmetric => format!("\n[asymmetric_friction]\ndelta = {:?}\n", g("delta")),
        TKind::Dry => format!("\n[dry_friction]\nc = {:?}\n", g("c").max(0.0)),
        TKind::Thermal => format!(
            "\n[thermal_drift]\ncoefficient = {:?}\nt_ambient = 0.0\nrise = 1.0\ntime_constant = {:?}\nt_ref = 0.0\nlog_temp = false\n",
            g("coefficient"),
            g("time_constant")
        ),
        TKind::Ripple => format!(
            "\n[position_ripple]\namplitude = {:?}\nperiod = {:?}\nphase = {:?}\n",
            g("amplitude"),
            g("period"),
            g("phase")
        ),
        TKind::Cable => format!("\n[cable_spring]\nk = {:?}\nengage = {:?}\nwidth = 0.01\n", g("k").max(0.0), g("engage")),
        TKind::Backlash => format!("\n[backlash]\nwidth = {:?}\n", g("width")),
        TKind::InitialState => format!(
            "\n# initial_state: the run starts at q = {:?} rad, qd = {:?} rad/s (not a model section)\n",
            g("q"),
            g("qd")
        ),
        TKind::Parameters => String::new(),
    }
}

fn nest(flat: Vec<(String, f64)>) -> BTreeMap<String, BTreeMap<String, f64>> {
    let mut out: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for (k, v) in flat {
        if let Some((s, key)) = k.split_once('.') {
            out.entry(s.to_string()).or_default().insert(key.to_string(), v);
        }
    }
    out
}

/// The model's terms at coefficient vector `th` (columns `cols`), as "section.key".
fn refit_values(model: &ModelFile, cols: &[Col], th: &[f64]) -> Vec<(String, f64)> {
    let v = |id| model.value(id);
    let mut out = Vec::new();
    let c = |want: Col| cols.iter().position(|x| *x == want).map(|k| th[k]);
    if let Some(a) = c(Col::QdAbsQd) {
        out.push(("friction.a".to_string(), a));
    }
    if let Some(bt) = c(Col::Qd) {
        if v(ParamId::FrictionB) != 0.0 || v(ParamId::SpringB) == 0.0 {
            out.push(("friction.b".into(), bt - v(ParamId::SpringB)));
        } else {
            out.push(("spring.b".into(), bt));
        }
    }
    if let Some(cc) = c(Col::Sgn) {
        let key = if v(ParamId::FrictionC) == 0.0 && v(ParamId::DryFrictionC) != 0.0 {
            "dry_friction.c"
        } else {
            "friction.c"
        };
        out.push((key.into(), cc));
    }
    if let Some(l) = c(Col::Stribeck(v(ParamId::StribeckSpeed))) {
        out.push(("stribeck.level".into(), l));
    }
    if let Some(dl) = c(Col::AbsSgn) {
        out.push(("asymmetric_friction.delta".into(), dl));
    }
    let per = v(ParamId::RipplePeriod);
    if let (Some(bs), Some(bc)) = (c(Col::RipSin(per)), c(Col::RipCos(per))) {
        out.push(("position_ripple.amplitude".into(), bs.hypot(bc)));
        out.push(("position_ripple.phase".into(), bc.atan2(bs)));
    }
    if let Some(kc) = c(Col::Cable { engage: v(ParamId::CableEngage), width: v(ParamId::CableWidth) }) {
        out.push(("cable_spring.k".into(), kc));
    }
    let ws = v(ParamId::WeightS);
    if let (Some(bs), Some(bc)) = (c(Col::SinSq(ws)), c(Col::CosSq(ws))) {
        out.push(("weight.amplitude".into(), bs.hypot(bc)));
        out.push(("weight.phi".into(), bc.atan2(bs)));
    }
    let k = c(Col::Q);
    if let Some(k) = k {
        out.push(("spring.k".into(), k));
    }
    if let Some(cst) = c(Col::Const) {
        let k = k.unwrap_or(0.0);
        if v(ParamId::OffsetC0) != 0.0 || k == 0.0 {
            out.push(("offset.c0".into(), cst + k * v(ParamId::SpringQ0)));
        } else {
            out.push(("spring.q0".into(), -cst / k));
        }
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    /// Sub-steps chosen from the model's fastest rate, the speed and how near rest the joint is
    /// give the same free response as four sub-steps on every sample, to far below any angle
    /// noise floor (≥ 1e-4 rad in practice): elastic joints (plain, with a Stribeck curve, with
    /// a short-period ripple) and a pendulum that swings through its friction band fast.
    #[test]
    fn adaptive_sub_steps_match_four_per_sample() {
        let t: Vec<f64> = (0..4000).map(|i| i as f64 * 1e-3).collect();
        let cases = [
            (vec![Col::Qd, Col::Sgn, Col::Q, Col::Const], vec![0.04, 0.012, 7.0, 0.0], 0.008, -0.3),
            (vec![Col::Qd, Col::Sgn, Col::Q, Col::Stribeck(0.05)], vec![0.04, 0.012, 7.0, 0.01], 0.008, -0.3),
            (
                vec![Col::Qd, Col::Sgn, Col::Q, Col::RipSin(0.03), Col::RipCos(0.03)],
                vec![0.04, 0.012, 7.0, 0.02, 0.01],
                0.008,
                -0.3,
            ),
            (vec![Col::Qd, Col::Sgn, Col::SinSq(1.0), Col::CosSq(1.0)], vec![0.0002, 0.003, 1.38, 0.0], 0.01, 0.8),
            (vec![Col::Qd, Col::SinSq(1.0), Col::CosSq(1.0)], vec![0.0002, 1.38, 0.0], 0.01, 0.8),
        ];
        for (cols, beta, j, q0) in cases {
            let rate = fastest_rate(&cols, &beta, j);
            let sim =
                |rate: f64| Sim { t: &t, u: None, j, band: 0.01, q0: 0.0, cols: cols.clone(), init: (q0, 0.0), rate };
            let fine = sim(f64::INFINITY).run(TKind::Parameters, &beta, t.len()).unwrap();
            let adaptive = sim(rate).run(TKind::Parameters, &beta, t.len()).unwrap();
            let worst = fine.iter().zip(&adaptive).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let travel = fine.iter().fold(0.0f64, |m, q| m.max(q.abs()));
            assert!(travel > 0.2, "the response must move: {travel}");
            assert!(worst < 1e-6, "{cols:?}: rate {rate:.0}/s, worst difference {worst:e} rad");
            eprintln!("{cols:?}: rate {rate:.0}/s, worst difference {worst:.1e} rad");
        }
    }
}
