//! One preparation stage for identification and diagnosis: the log's samples made fit to be
//! compared with a model, and a record of everything done to them.
//!
//! In order:
//! 1. **Stale samples**: a row whose every measured value repeats the row before it (a logger
//!    that wrote its last sample again, as the Panda's ~6 %) is dropped and counted.
//! 2. **Gaps**: a time step longer than [`GAP_FACTOR`] median steps splits the log into
//!    segments; nothing is differentiated (or, in trajectory mode, integrated) across a gap.
//! 3. **Rate and units**: a median rate below [`MIN_RATE_HZ`] is refused (a joint log in
//!    milliseconds reads as 1 Hz); a logged `qd` (or `qdd`) that is the derivative of `q` (or
//!    `qd`) times a unit factor (180/π, 1000, 2π, and their inverses, or −1) is refused naming
//!    the factor.
//! 4. **Derivatives**: `qd` and `qdd` are estimated from `q` by local cubic fits whose window
//!    follows from the data ([`lpr`], [`spectrum`]): the noise on `q` and the size of the
//!    motion's higher derivatives, read from the spectrum, fix the window that minimises the
//!    estimate's error. A logged `qd`/`qdd` is checked against that estimate; its own noise is
//!    measured from the difference, and the one with the smaller error is used (`qdd` may then
//!    also come from the logged `qd`).
//! 5. **Uncertainty**: the error (noise and bias) of the `qd` and `qdd` used is kept, so a
//!    model can be evaluated as what it predicts *given* these estimates (e.g. the expected
//!    friction sign near rest, [`expected_sign`]) and the errors-in-variables share of `qdd`
//!    removed from fits.
//!
//! The report ([`PrepReport`]) names every choice; `identify` and `diagnose` print it.

// Numeric kernels over per-sample series whose lengths are fixed when the log is read (every
// index comes from `0..n`, a segment range inside it, or a window clipped to one), like the
// diagnosis's kernels: the indexing lint would only repeat that invariant at each site.
#![allow(clippy::indexing_slicing)]

pub mod lpr;
pub(crate) mod quantile;
pub mod spectrum;

use crate::identify::robust::{chi2_ratio, Z_P001};
use joint_formats::log::JointLog;
use serde::Serialize;

/// A step longer than this many median steps is a gap.
pub const GAP_FACTOR: f64 = 10.0;
/// Below this median rate a log cannot resolve a joint's dynamics (and is most likely in ms).
pub const MIN_RATE_HZ: f64 = 5.0;
/// The longest window half-width a derivative may use, seconds.
pub const MAX_HALF_WINDOW_S: f64 = 0.25;

/// Why a log cannot be prepared.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PrepError {
    #[error("{0}")]
    Refused(String),
}

impl PrepReport {
    /// One line: samples kept, rate, stretches, and where q̇ and q̈ come from with their errors.
    pub fn summary(&self) -> String {
        let what = |d: &DerivInfo| {
            if d.source == "logged" {
                format!("logged (noise {:.2e})", d.error_sd)
            } else {
                format!("{}, local cubic ±{:.1} ms (error {:.2e})", d.source, 1e3 * d.half_window_s, d.error_sd)
            }
        };
        format!(
            "{} of {} samples, {:.1} Hz, {} stretch(es); q̇ {} rad/s; q̈ {} rad/s²",
            self.samples,
            self.samples_in,
            self.median_rate_hz,
            self.segments.len(),
            what(&self.qd),
            what(&self.qdd)
        )
    }
}

/// One stretch of the log without a gap (indices into the prepared arrays).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SegmentInfo {
    pub from_t: f64,
    pub to_t: f64,
    pub samples: usize,
}

/// How one derivative was obtained.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DerivInfo {
    /// "logged", "derived from q", "derived from the logged qd"
    pub source: &'static str,
    /// the local cubic's half-window, seconds (0 when logged)
    pub half_window_s: f64,
    /// the estimate's error, 1σ: noise and bias of the estimator, or the logged column's noise
    pub error_sd: f64,
    /// the noise part of `error_sd` (what errors-in-variables corrections remove)
    pub noise_sd: f64,
    /// the logged column's measured noise, when it was logged
    #[serde(skip_serializing_if = "Option::is_none")]
    pub logged_noise_sd: Option<f64>,
    /// the logged column against the derivative of the signal below it (1 = consistent)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub logged_scale: Option<f64>,
    /// the error is white noise (a logged column whose own high-frequency noise accounts for
    /// its difference from the estimate); otherwise it follows the motion (an estimator's
    /// smoothing, a logger's filter) and no noise estimate of the residual will see it
    pub white: bool,
}

impl DerivInfo {
    /// The logged column is the one used, and its error is white noise about the motion (no
    /// estimator's window or logger's filter smearing it): a reading that stands clear of that
    /// noise is the joint's own.
    pub fn logged_white(&self) -> bool {
        self.source == "logged" && self.white
    }
}

/// What the preparation did, for the reports (optional fields of identification and
/// diagnosis output).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PrepReport {
    pub samples_in: usize,
    pub samples: usize,
    /// share of the samples found at rest (q̇ and q̈ set to 0)
    pub rest_share: f64,
    /// share of the samples left out as undecided next to a rest
    pub ambiguous_share: f64,
    pub stale_dropped: usize,
    /// rows left out for a value no joint produces (a logger glitch); see `glitch_lines`
    pub glitches_dropped: usize,
    /// the file lines (header = line 1) of those rows, the first 20
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub glitch_lines: Vec<usize>,
    pub segments: Vec<SegmentInfo>,
    pub median_rate_hz: f64,
    /// noise on q (white part, including quantisation), rad
    pub q_noise_sd: f64,
    /// the noise q's spectrum (or differences) shows, before the quantisation floor; rad
    #[serde(skip)]
    pub q_seen_sd: f64,
    /// the encoder's quantisation error `step/√12` (0: q does not look quantised), rad
    #[serde(skip)]
    pub q_quantum_sd: f64,
    /// highest frequency where q's motion stands above its noise, Hz
    pub motion_bandwidth_hz: f64,
    pub qd: DerivInfo,
    pub qdd: DerivInfo,
    pub smoother: &'static str,
    pub notes: Vec<String>,
}

/// A log ready for the analysis: stale rows gone, `qd` and `qdd` filled in, segments known.
#[derive(Clone, Debug)]
pub struct Prepared {
    pub log: JointLog,
    /// half-open index ranges of the segments, in order
    pub segments: Vec<std::ops::Range<usize>>,
    /// samples found at rest (their q̇ and q̈ are 0)
    pub rest: Vec<bool>,
    /// the direction of motion where the q̇ estimate cannot tell it but the way q goes can
    /// (next to a rest): ±1, else 0
    pub direction: Vec<i8>,
    /// samples where whether the joint moves is undecided (where a move leaves or reaches a
    /// rest, before q leaves its noise band): fits and scores leave them out
    pub ambiguous: Vec<bool>,
    /// samples where the sign of q̇ is not known: within 3σ of zero, not at rest, no direction
    /// from the way q goes (a reversal, or a near stop the data cannot resolve)
    pub sign_unknown: Vec<bool>,
    /// the ends of each rest (up to a quarter of it): the joint may still creep there below
    /// any estimate's resolution
    pub rest_edge: Vec<bool>,
    /// per sample: the 1σ error (noise and bias) of the q̇ and q̈ used
    pub qd_err: Vec<f64>,
    pub qdd_err: Vec<f64>,
    /// per sample: the noise part of the q̈ error
    pub qdd_noise: Vec<f64>,
    pub report: PrepReport,
}

impl Prepared {
    pub fn qd(&self) -> &[f64] {
        self.log.qd.as_deref().unwrap_or(&[])
    }
    pub fn qdd(&self) -> &[f64] {
        self.log.qdd.as_deref().unwrap_or(&[])
    }
    /// Variance of the noise part of the q̈ used, averaged over the log (errors in variables).
    pub fn qdd_noise_var(&self) -> f64 {
        let n = self.qdd_noise.len().max(1) as f64;
        self.qdd_noise.iter().map(|s| s * s).sum::<f64>() / n
    }
}

pub const SMOOTHER: &str =
    "local cubic least-squares fits over a window chosen per log to minimise noise variance + bias² \
(noise on q and the motion's 4th/5th derivative sizes from its spectrum); never across a gap, and never across the \
start or end of a rest";

/// One derivative as the analysis uses it: values, per-sample noise (1σ) and the estimator's
/// bias (1σ, one figure for the log).
struct Deriv {
    values: Vec<f64>,
    noise: Vec<f64>,
    bias: f64,
    info: DerivInfo,
}

impl Deriv {
    fn error(&self) -> Vec<f64> {
        self.noise.iter().map(|s| s.hypot(self.bias)).collect()
    }

    /// The typical error a logged column's white noise is weighed against. Bias counts three
    /// times its variance: it follows the motion, so it is structure a fit can mistake for an
    /// effect, where white noise only adds to the residual (and errors-in-variables removes it).
    fn effective_error(&self) -> f64 {
        let n = typical(&self.noise);
        (n * n + 3.0 * self.bias * self.bias).sqrt()
    }
}

/// How a derivative is estimated: from which signal, which derivative of it, with what window.
#[derive(Clone, Copy)]
struct Recipe {
    from_q: bool,
    second: bool,
    h: usize,
    sigma: f64,
    /// the estimate has its window's leading bias taken off ([`fourth_order_bias`])
    corrected: bool,
}

/// Derivative estimates of `x` per segment (rest boundaries count as segment ends when given).
fn estimate_deriv(
    t: &[f64],
    x: &[f64],
    pieces: &[std::ops::Range<usize>],
    r: Recipe,
    values: &mut [f64],
    noise: &mut [f64],
) {
    for piece in pieces {
        let e = lpr::estimate(&t[piece.clone()], &x[piece.clone()], r.h);
        let (v, g) = if r.second { (&e.d2, &e.gain2) } else { (&e.d1, &e.gain1) };
        for (k, i) in piece.clone().enumerate() {
            values[i] = v[k];
            noise[i] = r.sigma * g[k].max(0.0).sqrt();
        }
    }
}

/// Prepares `log` (already parsed and checked by the reader).
pub fn prepare(log: &JointLog) -> Result<Prepared, PrepError> {
    prepare_cow(std::borrow::Cow::Borrowed(log))
}

/// [`prepare`], taking the log: the prepared log is the given one, not a copy of its columns,
/// unless rows are dropped (a 1 M-sample log's copy was 32 MB of fresh pages).
pub fn prepare_owned(log: JointLog) -> Result<Prepared, PrepError> {
    prepare_cow(std::borrow::Cow::Owned(log))
}

/// [`prepare`] on a log borrowed or handed over.
pub(crate) fn prepare_cow(input: std::borrow::Cow<'_, JointLog>) -> Result<Prepared, PrepError> {
    let log: &JointLog = &input;
    let samples_in = log.len();
    let timing = std::env::var_os("DIAG_TIMING").is_some();
    let t_start = std::time::Instant::now();
    let lap = |what: &str| {
        if timing {
            eprintln!("[prep] {what}: {:.3} s", t_start.elapsed().as_secs_f64());
        }
    };
    let (clean, glitches) = drop_glitches(log)?;
    let (log, stale) = drop_stale(&clean);
    let n = log.len();
    if n < 2 {
        return Err(PrepError::Refused(format!("the log has {n} usable samples")));
    }
    let dt = median_step(&log.t);
    let rate = 1.0 / dt;
    if !(rate >= MIN_RATE_HZ) {
        return Err(PrepError::Refused(format!(
            "the median time step is {dt} s ({rate:.3} Hz): too slow to resolve a joint's dynamics; \
             if `t` is in milliseconds, divide it by 1000 (spec §1: seconds)"
        )));
    }
    lap("stale rows");
    let mut segments = split_at_gaps(&log.t, dt);
    let jumps = split_at_jumps(&log.q, &mut segments);
    let mut notes = Vec::new();
    if !glitches.is_empty() {
        notes.push(glitch_note(&glitches));
    }
    if stale > 0 {
        notes.push(format!("{stale} stale samples (a row repeating the one before it) dropped"));
    }
    if jumps > 0 {
        notes.push(format!(
            "{jumps} jumps of q (a step no motion makes in one sample: a restart, an encoder reset) split the log too"
        ));
    }
    if segments.len() > 1 {
        notes.push(format!(
            "{} gaps longer than {GAP_FACTOR}× the median step split the log into {} segments; nothing is differentiated across them",
            segments.len() - 1,
            segments.len()
        ));
    }
    let q_spec = longest(&segments).and_then(|r| spectrum::analyse(&log.t[r.clone()], &log.q[r.clone()], dt));
    let quantum = resolution_sd(&log.q);
    lap("spectrum, resolution");
    let h_max = ((MAX_HALF_WINDOW_S / dt).round() as usize).max(2);
    let mut q_spec = q_spec;
    // Two noises the spectrum alone takes for motion, each told apart by q̇ and q̈ seen through a
    // ±50 ms window (the motion, with encoder steps and a fine noise averaged out):
    //
    // A coarse encoder's quantisation is not white: a joint moving at v crosses steps of Δ at
    // v/Δ Hz, tones the spectrum shows as "motion" up to hundreds of Hz, and a window chosen
    // for that motion is a few samples wide and all noise. Where q is quantised, a spectral
    // bandwidth far above the wide window's frequency is the encoder, and the derivative sizes
    // are taken from the wide window's motion instead.
    //
    // A noise filtered twice before it was logged (an angle from a tracking observer, a
    // low-passed potentiometer) falls with frequency as steeply as a motion does: a q̈ of
    // hundreds of rad/s² up to hundreds of hertz, and a window of two samples. When the
    // spectrum's q̈ is over three times the wide window's and its band over five times the
    // wide window's frequency (or 1.5 times and twenty times: a motion's q̈ seen through
    // ±50 ms loses little below a few hertz, and matches the spectrum's within 5 % when the
    // noise is white), the motion ends two octaves above that frequency and all above it is
    // noise.
    let mut reread = None;
    if let (Some(s), Some(r)) = (q_spec.as_mut(), longest(&segments)) {
        let pilot = ((0.05 / dt).round() as usize).clamp(3, h_max.max(3));
        let (v1, v2) = pilot_motion(&log.t[r.clone()], &log.q[r.clone()], pilot);
        // rad/s: the motion's typical angular frequency
        let w = if v1 > 0.0 && v2 > 0.0 { v2 / v1 } else { 0.0 };
        if w > 0.0 && quantum > 0.0 {
            if s.bandwidth_hz > 5.0 * w / std::f64::consts::TAU {
                // a margin of 2 on the frequency for the motion's spread
                let w2 = 2.0 * w;
                let mut dk = v2;
                for k in 2..6 {
                    s.deriv_rms[k] = dk * w2.powi(k as i32 - 1);
                    dk = dk.max(0.0);
                }
                s.deriv_rms[0] = v1;
                s.deriv_rms[1] = v2;
                s.bandwidth_hz = w2 / std::f64::consts::TAU;
            }
        } else if w > 0.0 {
            let (ratio, spread) = (s.deriv_rms[1] / v2, s.bandwidth_hz / (w / std::f64::consts::TAU));
            if (ratio > 3.0 && spread > 5.0) || (ratio > 1.5 && spread > 20.0) {
                let edge = 4.0 * w / std::f64::consts::TAU;
                if let Some(again) = spectrum::analyse_below(&log.t[r.clone()], &log.q[r.clone()], dt, Some(edge)) {
                    notes.push(format!(
                        "q's spectrum stands above its white noise up to {:.0} Hz, but a 50 ms window sees its motion at \
                         {:.1} Hz: above {edge:.1} Hz it is read as a coloured noise, not motion",
                        s.bandwidth_hz,
                        w / std::f64::consts::TAU
                    ));
                    reread = Some(again);
                }
            }
        }
    }
    if reread.is_some() {
        q_spec = reread;
    }
    // a coloured noise (see `spectrum::NoiseModel`) counts whole in the bands a still joint
    // stays within; the windows below weigh its spectrum through their own weights
    let coloured = q_spec.as_ref().map(|s| s.noise.clone()).filter(|m| !m.is_white());
    let q_seen =
        q_spec.as_ref().map_or_else(|| diff_noise(&log.q), |s| coloured.as_ref().map_or(s.noise_sd, |m| m.total_sd()));
    let q_noise = q_seen.max(quantum);
    let bandwidth = q_spec.as_ref().map_or(0.0, |s| s.bandwidth_hz);
    // Under `spectrum::MIN_SAMPLES` there is no spectrum, and derivative sizes of 0 made every
    // window its widest: a 40-sample log of a 4.4 Hz oscillation got q̇ from ±247 ms of it,
    // two periods, a q̇ off by 1.4 rad/s, and its clean logged q̇ was judged the noisy one
    // (unseen t9075/0040). There the sizes come from a pilot window of about ±50 ms (at most
    // the log): q̈'s RMS and the motion's frequency w = RMS(q̈)/RMS(q̇), with the margin of 2 on
    // w the quantised case takes.
    let pilot_sizes = if q_spec.is_none() {
        longest(&segments).filter(|r| r.len() >= lpr::DEGREE + 2).and_then(|r| {
            let pilot = ((0.05 / dt).round() as usize).clamp(2, (r.len() - 1) / 2);
            let (v1, v2) = pilot_motion(&log.t[r.clone()], &log.q[r.clone()], pilot);
            (v1 > 0.0 && v2 > 0.0).then(|| (v2, 2.0 * v2 / v1))
        })
    } else {
        None
    };
    let d = |k: usize| match (&q_spec, pilot_sizes) {
        (Some(s), _) => s.deriv_rms[k - 1],
        (None, Some((v2, w2))) => v2 * w2.powi(k as i32 - 2),
        (None, None) => 0.0,
    };

    // q̇ and q̈ from q.
    // White noise: σ²·Σw². Coloured: Σᵢⱼ wᵢwⱼ·r(i−j) from the noise's autocovariance, and the
    // recipe's σ is the white noise that would give the chosen window the same variance (so
    // the per-sample errors, ends included, keep their white-noise gains).
    let autocov = coloured.map(|m| m.autocovariance(2 * h_max + 1));
    let noise_var = |w: &[f64]| match &autocov {
        Some(r) => spectrum::NoiseModel::filtered_variance(r, w),
        None => q_noise * q_noise * w.iter().map(|x| x * x).sum::<f64>(),
    };
    let pick = |order| {
        let (h, var, bias) =
            lpr::choose_half_width_with(dt, order, &noise_var, d(4), d(5), h_max).unwrap_or((2, 0.0, 0.0));
        let gain = lpr::weights(h, dt).map_or(0.0, |(w1, w2)| {
            let w = if order == lpr::Order::First { w1 } else { w2 };
            w.iter().map(|x| x * x).sum::<f64>()
        });
        let sigma = if autocov.is_some() && gain > 0.0 { (var / gain).sqrt() } else { q_noise };
        (h, sigma, bias)
    };
    let (h1, sigma1, bias1) = pick(lpr::Order::First);
    let (h2, sigma2, bias2) = pick(lpr::Order::Second);
    let derive = |r: Recipe, x: &[f64], pieces: &[std::ops::Range<usize>]| {
        let (mut v, mut s) = (vec![0.0; n], vec![0.0; n]);
        estimate_deriv(&log.t, x, pieces, r, &mut v, &mut s);
        (v, s)
    };
    let r1 = Recipe { from_q: true, second: false, h: h1, sigma: sigma1, corrected: false };
    let r2 = Recipe { from_q: true, second: true, h: h2, sigma: sigma2, corrected: false };
    // q̇ and q̈ are independent fits: one on each core
    let ((v1, s1), (v2, s2)) = std::thread::scope(|sc| {
        let second = sc.spawn(|| derive(r2, &log.q, &segments));
        let first = derive(r1, &log.q, &segments);
        (first, second.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
    });
    lap("derivatives from q");
    let qd_q = Deriv { info: derived_info("derived from q", h1, dt, &s1, bias1), values: v1, noise: s1, bias: bias1 };
    // The window's leading bias, Σ w_j·(j·dt)⁴/4!·q⁽⁴⁾, is taken off with q⁽⁴⁾ read from the
    // estimate itself where that lowers the expected error ([`fourth_order_bias`]).
    let (v2, s2, bias2, corrected) = fourth_order_bias(r2, dt, (v2, s2, bias2), |x: &[f64]| derive(r2, x, &segments).0);
    let r2 = Recipe { corrected, ..r2 };
    let qdd_q = Deriv { info: derived_info("derived from q", h2, dt, &s2, bias2), values: v2, noise: s2, bias: bias2 };
    // Rest is judged on the joint's own angle: a logged derivative may be a filtered estimate
    // that smears a stop into the dwell.
    let still_from_q = (qd_q.values.clone(), qd_q.noise.clone(), qdd_q.values.clone(), qdd_q.noise.clone());

    // A logged q̇: checked against q, kept when its error is the smaller.
    let (qd, qd_recipe) = match &log.qd {
        Some(v) => {
            let short = |_: &[f64]| derive(Recipe { h: (r1.h / 4).max(2), ..r1 }, &log.q, &segments).0;
            let what =
                LoggedColumn { name: "qd", of: "q", estimate: "the derivative of q", used: "q's", unit: "rad/s" };
            let rate = Some((qdd_q.values.as_slice(), 2 * r1.h + 1));
            match check_logged(v, qd_q, &short, &what, rate, (&log.t, &segments, dt), &mut notes)? {
                (d, true) => (d, None),
                (d, false) => (d, Some(r1)),
            }
        }
        None => (qd_q, Some(r1)),
    };
    // q̈ from the logged q̇ when that is the q̇ used (a derivative less to take).
    let (qdd_best, qdd_recipe) = match qd_recipe {
        None => {
            let qd_spec =
                longest(&segments).and_then(|r| spectrum::analyse(&log.t[r.clone()], &qd.values[r.clone()], dt));
            // (a log too short for a spectrum: q̇'s k-th derivative is q's (k+1)-th, from the
            // pilot window above)
            let dv = |k: usize| qd_spec.as_ref().map_or_else(|| d(k + 1), |s| s.deriv_rms[k - 1]);
            let sigma = qd.info.noise_sd;
            match lpr::choose_half_width(dt, lpr::Order::First, sigma, dv(4), dv(5), h_max) {
                Some((h, var, bias)) if (var + bias * bias).sqrt() < typical(&qdd_q.error()) => {
                    let r = Recipe { from_q: false, second: false, h, sigma, corrected: false };
                    let (v, s) = derive(r, &qd.values, &segments);
                    let info = derived_info("derived from the logged qd", h, dt, &s, bias);
                    (Deriv { values: v, noise: s, bias, info }, Some(r))
                }
                _ => (qdd_q, Some(r2)),
            }
        }
        Some(_) => (qdd_q, Some(r2)),
    };
    let (qdd, qdd_recipe) = match &log.qdd {
        Some(a) => {
            let short = |best: &[f64]| match qdd_recipe {
                Some(r) => {
                    derive(Recipe { h: (r.h / 4).max(2), ..r }, if r.from_q { &log.q } else { &qd.values }, &segments).0
                }
                None => best.to_vec(),
            };
            let what =
                LoggedColumn { name: "qdd", of: "qd", estimate: "the estimate", used: "the estimate", unit: "rad/s²" };
            match check_logged(a, qdd_best, &short, &what, None, (&log.t, &segments, dt), &mut notes)? {
                (d, true) => (d, None),
                (d, false) => (d, qdd_recipe),
            }
        }
        None => (qdd_best, qdd_recipe),
    };
    lap("logged columns checked");
    let (mut qd, mut qdd) = (qd, qdd);

    // Rest: where q̇ and q̈ both stay within their noise for longer than a derivative window
    // (a reversal passes through q̇ = 0 with q̈ ≠ 0, a dwell holds both). There the joint is
    // still: q̇ = q̈ = 0 exactly, so a Coulomb term is sign(0) = 0 rather than the sign of
    // the estimate's noise.
    let min_run = ((2.0 * qd.info.half_window_s.max(qdd.info.half_window_s).max(0.01) / dt).round() as usize).max(3);
    // still: the q̇ used (the best estimate, possibly a clean logged one) within its noise, and
    // q's own q̈ within its noise
    let mut rest = detect_rest(&qd.values, &still_from_q.2, &qd.noise, &still_from_q.3, min_run, &segments);
    // A logged q̈ that passed as white noise (kept over the estimate, its own high-frequency
    // noise accounting for its difference from it) sees a start before q does: the joint
    // accelerating out of a dwell while q is still inside one quantum. There q's own q̈ is
    // within its (wider) noise and q̇ too, but the logged q̈ stands many σ off zero; such a
    // sample is no rest, or the model's inertia and friction are taken off a joint that moves
    // (unseen t9064/0018: a model-exact log left 1.9–2.9 N·m, the Coulomb level plus J·q̈, on
    // the last 10 samples of each dwell). σ is the larger of its noise and its robust scatter
    // over the rests found: a column that passed as white can still be a logger's low-pass,
    // whose noise at rest is smooth and well above the high-frequency part the check measured.
    if qdd.info.logged_white() {
        let mut at_rest: Vec<f64> = qdd.values.iter().zip(&rest).filter(|(_, &r)| r).map(|(a, _)| a.abs()).collect();
        if at_rest.len() >= 20 {
            let scatter = 1.4826 * quantile::at_rounded(&mut at_rest, 0.5).unwrap_or(0.0);
            let moving: Vec<bool> =
                qdd.values.iter().zip(&qdd.noise).map(|(a, s)| a.abs() > 4.0 * s.max(scatter)).collect();
            rest = trim_rest(&rest, &moving, min_run, &segments);
        }
    }
    lap("rest");
    // Motion next to a rest is re-estimated from the motion's side only: a window across the
    // start or end of a move mixes the still joint into the moving one (q̈ jumps there), and
    // its smeared q̇ would put the Coulomb sign wrong for a whole window.
    if rest.iter().any(|r| *r) {
        let mut runs = Vec::new();
        for seg in &segments {
            for run in motion_runs(&rest, seg.clone()) {
                // the rest samples on either side anchor the move's ends
                let lo = if run.start > seg.start { run.start - 1 } else { run.start };
                let hi = if run.end < seg.end { run.end + 1 } else { run.end };
                runs.push((lo..hi, run));
            }
        }
        // Only the samples within a window of a run's ends change: their fits are redone on
        // the run's side alone.
        let redo = |d: &mut Deriv, r: Recipe, src: &[f64]| {
            let reach = 2 * r.h + 2;
            for (window, run) in &runs {
                let parts: Vec<(std::ops::Range<usize>, std::ops::Range<usize>)> = if run.len() <= 3 * reach {
                    vec![(window.clone(), run.clone())]
                } else {
                    vec![
                        (window.start..run.start + 2 * reach, run.start..run.start + reach),
                        (run.end - 2 * reach..window.end, run.end - reach..run.end),
                    ]
                };
                for (w, out) in parts {
                    let e = lpr::estimate(&log.t[w.clone()], &src[w.clone()], r.h);
                    let (v, g) = if r.second { (&e.d2, &e.gain2) } else { (&e.d1, &e.gain1) };
                    for i in out {
                        d.values[i] = v[i - w.start];
                        d.noise[i] = r.sigma * g[i - w.start].max(0.0).sqrt();
                    }
                }
            }
        };
        let qd_logged = qd.values.clone();
        std::thread::scope(|sc| {
            let (qd, qdd, redo, qd_logged, q) = (&mut qd, &mut qdd, &redo, &qd_logged, &log.q);
            let h = sc.spawn(move || {
                if let Some(r) = qdd_recipe {
                    redo(qdd, r, if r.from_q { q } else { qd_logged });
                }
            });
            if let Some(r) = qd_recipe {
                redo(qd, r, q);
            }
            h.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        });
        for (i, &still) in rest.iter().enumerate() {
            if still {
                qd.values[i] = 0.0;
                qdd.values[i] = 0.0;
            }
        }
    }
    lap("re-estimated next to rests");
    // Where a move leaves or reaches a rest, the joint's direction is known before its speed
    // is: from the way it goes. Until q has left the rest's noise band the sign is unknown
    // (the joint may have started, the data cannot say): those samples are marked ambiguous.
    // (at least 20 ms: a move that creeps in or out below the q̇ noise looks like rest)
    let hold = ((qd.info.half_window_s.max(0.02) / dt).round() as usize).max(1);
    let (mut direction, ambiguous) =
        transitions(&log.q, (&qd.values, &qd.noise, qd.info.logged_white()), &rest, &segments, 4.0 * q_noise, hold);
    // Elsewhere where the q̇ estimate is too small to sign, q may still be going one way on
    // both sides (a move that slows to a near stop and goes on): then that is its direction.
    let before_through = direction.clone();
    through_direction(&log.q, &qd.values, &qd.error(), &rest, &segments, 4.0 * q_noise, hold, &mut direction);
    lap("directions");
    let ambiguous_share = share(&ambiguous);
    if ambiguous_share > 0.0 {
        notes.push(format!(
            "{:.1} % of the samples lie where a move leaves or reaches a rest before q has left its noise band: \
             whether the joint moves there is unknown, they are left out of fits and scores",
            100.0 * ambiguous_share
        ));
    }
    // A stop's last creep and a start's first creep sit below every estimate's resolution:
    // the ends of each rest may still be motion. Marked, so an analysis whose model jumps at
    // q̇ = 0 (a pure Coulomb sign) can leave them out.
    let rest_edge = rest_edges(&rest, &segments, &qd.values, hold, hold.max((0.1 / dt).round() as usize));
    let rest_share = share(&rest);
    if rest_share > 0.0 {
        notes.push(format!("{:.1} % of the samples are at rest (q̇ = q̈ = 0 there)", 100.0 * rest_share));
    }
    let (mut qd_err, mut qdd_err) = (qd.error(), qdd.error());
    // The estimator's bias follows the motion: where the motion turns sharply (a stop, a
    // reversal at speed) it is far above the log's typical figure. Measured locally by
    // comparing each estimate with the same fit on half the window.
    std::thread::scope(|sc| {
        let (qd_err, qdd_err, log, segments, rest, qd, qdd) =
            (&mut qd_err, &mut qdd_err, &log, &segments, &rest, &qd, &qdd);
        let h = sc.spawn(move || {
            if let Some(r) = qdd_recipe {
                let src = if r.from_q { &log.q } else { log.qd.as_ref().unwrap_or(&log.q) };
                let q_quantum = if r.from_q { quantum } else { 0.0 };
                local_bias(&log.t, src, segments, r, &qdd.values, rest, (q_quantum, &qd.values), qdd_err);
            }
        });
        if let Some(r) = qd_recipe {
            local_bias(&log.t, &log.q, segments, r, &qd.values, rest, (quantum, &qd.values), qd_err);
        }
        h.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
    });
    // A quantised q resolves a speed no finer than one step over the window (its error is
    // not independent from sample to sample, so the noise formula alone is too hopeful there).
    // A faster move crosses k steps inside the window and the staircase's error averages down
    // as 1/k: the floor holds near zero speed, where it matters, and fades with speed.
    let mut step_bound = vec![0.0; n];
    if quantum > 0.0 {
        let step = quantum * 12f64.sqrt();
        let crossed = |i: usize, w: f64| (qd.values[i].abs() * 2.0 * w / step).max(1.0);
        if qd.info.source != "logged" {
            let w = qd.info.half_window_s.max(dt);
            let floor = step / (2.0 * w);
            qd_err.iter_mut().enumerate().for_each(|(i, e)| *e = e.max(floor / crossed(i, w)));
            // Whether the joint moves at all is another question than how fast: a single step
            // anywhere in the window moves the estimate by up to the estimator's step response
            // (the largest partial sum of its derivative weights, times the step), about three
            // times `floor`. An estimate within that (and a little beyond: k steps past the one)
            // may be a joint that stands. It is a bound, not a random error: it decides only
            // whether a pure sign is known, never the expected sign or the floor (as an error it
            // smears a banded friction's sign and leaves a Stribeck-like bump: 19 `none` logs
            // of the development seeds were named `stribeck` that way). Near a stretch's ends
            // the window is one-sided and its weights larger: the response grows with them (as
            // the noise gain's square root).
            let (peak, centre_noise) =
                qd_recipe.and_then(|r| lpr::weights(r.h, dt).map(|w| (r, w))).map_or((0.0, 0.0), |(r, (w1, _))| {
                    let mut acc = 0.0f64;
                    let peak = w1.iter().rev().fold(0.0f64, |m, x| {
                        acc += x;
                        m.max(acc.abs())
                    }) * step;
                    (peak, r.sigma * w1.iter().map(|x| x * x).sum::<f64>().sqrt())
                });
            if std::env::var_os("DIAG_TRACE").is_some() {
                eprintln!("[trace] staircase: one step over the window {floor:.3e}, the estimator's step response {peak:.3e} rad/s");
            }
            for (i, b) in step_bound.iter_mut().enumerate() {
                let edge = if centre_noise > 0.0 { (qd.noise[i] / centre_noise).max(1.0) } else { 1.0 };
                let peak = peak * edge;
                let beyond = ((qd.values[i].abs() - peak) * 2.0 * w / step).max(1.0);
                *b = peak / (beyond * beyond);
            }
        }
        if qdd.info.source == "derived from q" {
            let w = qdd.info.half_window_s.max(dt);
            let floor = step / (w * w);
            qdd_err.iter_mut().enumerate().for_each(|(i, e)| *e = e.max(floor / crossed(i, w)));
        }
    }
    // At rest q̇ = q̈ = 0 is taken, not estimated: no estimation error there.
    for (i, &still) in rest.iter().enumerate() {
        if still {
            qd_err[i] = 0.0;
            qdd_err[i] = 0.0;
        }
    }
    // Where the estimate cannot say which way the joint moves (within 3σ of zero, no direction
    // from q, not at rest): a pure Coulomb sign there is a coin toss.
    // A direction read from q on both sides says which way the joint goes if it moves, not
    // that it moves: a dwell shorter than a rest (two moves the same way) passes for a slow
    // move there, and a pure sign predicts ±c where the joint stood (0, or anything in ±c).
    // Only a direction next to a rest (q has left the rest's band) says it moves.
    // A q̇ estimated from q whose sign no step of q inside its window shares (q only went down
    // there, or only up) is the estimator's, not the motion's: a local polynomial's derivative
    // weights change sign across the window, so a clean encoder staircase creeping to a near stop
    // can come out the wrong way at several times its stated error. Its sign is unknown too.
    // Near a stretch's ends the window is one-sided and the fit an extrapolation: there the sign
    // counts as known only where q itself confirms it ([`unconfirmed_ends`]).
    let against_q = match qd_recipe {
        Some(r) => {
            let mut a = against_steps(&log.q, &qd.values, &rest, &segments, r.h);
            unconfirmed_ends(&log.q, &qd.values, &rest, &segments, (r.h, q_noise.max(quantum)), &mut a);
            a
        }
        None => vec![false; n],
    };
    // The step response bounds the estimate only where the joint may stand: where q holds
    // within one count (and its white noise) for 0.1 s on one side of the sample (a dwell the
    // rest detector's run is too long for, a near stop). A reversal at speed passes through
    // q̇ = 0 without holding, and there the estimate's sign is what it says.
    let white = (q_noise * q_noise - quantum * quantum).max(0.0).sqrt();
    let still_band = quantum * 12f64.sqrt() + 6.0 * white;
    let still_len = ((0.1 / dt).round() as usize).max(3);
    let range = |w: &[f64]| {
        let (lo, hi) = w.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        hi - lo
    };
    let mut sign_unknown = vec![false; n];
    for seg in &segments {
        let holds_still = |i: usize| {
            let before = &log.q[i.saturating_sub(still_len).max(seg.start)..=i];
            let after = &log.q[i..(i + still_len + 1).min(seg.end)];
            (before.len() > still_len && range(before) <= still_band)
                || (after.len() > still_len && range(after) <= still_band)
        };
        for i in seg.clone() {
            let v = qd.values[i].abs();
            sign_unknown[i] = !rest[i]
                && before_through[i] == 0
                && (v < 3.0 * qd_err[i] || against_q[i] || v < 3.0 * step_bound[i] && holds_still(i));
        }
    }
    // (the log as given when no row was dropped: moved when it was handed over, else copied)
    let mut out = match log {
        std::borrow::Cow::Owned(l) => l,
        std::borrow::Cow::Borrowed(_) => match clean {
            std::borrow::Cow::Owned(c) => c,
            std::borrow::Cow::Borrowed(_) => input.into_owned(),
        },
    };
    out.qd = Some(qd.values);
    out.qdd = Some(qdd.values);
    let report = PrepReport {
        samples_in,
        samples: n,
        rest_share,
        ambiguous_share,
        stale_dropped: stale,
        glitches_dropped: glitches.len(),
        glitch_lines: glitches.iter().take(20).map(|g| g.row + 2).collect(),
        segments: segments
            .iter()
            .map(|r| SegmentInfo { from_t: out.t[r.start], to_t: out.t[r.end - 1], samples: r.len() })
            .collect(),
        median_rate_hz: rate,
        q_noise_sd: q_noise,
        q_seen_sd: q_seen,
        q_quantum_sd: quantum,
        motion_bandwidth_hz: bandwidth,
        qd: qd.info,
        qdd: qdd.info,
        smoother: SMOOTHER,
        notes,
    };
    lap("errors, local bias, floors");
    Ok(Prepared {
        log: out,
        segments,
        rest,
        direction,
        ambiguous,
        sign_unknown,
        rest_edge,
        qd_err,
        qdd_err,
        qdd_noise: qdd.noise,
        report,
    })
}

/// Raises `err` (per-sample 1σ error of `est`, the recipe's estimate) to the local bias:
/// the estimate at half the window differs from it by the bias's change plus noise; the squared
/// difference smoothed over a window, less its noise share, times the factor that turns the
/// change into the bias (the leading bias grows as h⁴ for q̇ from q and as h² otherwise).
///
/// For a q̈ whose window's leading bias is taken off ([`fourth_order_bias`]) the noise share is
/// a bar the reading must pass (see [`window_dof`]), on the noise's scale read from the log's
/// bulk: what is left of a bias spread over the log is of second order, and an excess at the
/// noise's level is noise. Elsewhere every reading above the noise counts, as before:
/// - a q̈ from the shortest windows (under [`CORRECTED_FROM_H`]) keeps its leading bias, spread
///   over the whole log a few per cent above the noise figure and within that figure's own
///   error, which only the plain reading states (null seed 31 torque case 174, h = 5, a refit
///   of 37 % otherwise; seed 9051 case 9, h = 6, whose Stribeck curve under a ripple went);
/// - q̇'s error decides where a pure Coulomb sign is known, and on model-exact logs with a 28 N·m
///   sign (null seed 31, cases 114, 171, 262) the errors a lower q̇ reading left near stops put
///   samples of the wrong sign into the fit (a residual of 3.5 N·m).
#[allow(clippy::too_many_arguments)] // the estimate, its recipe and its source, each needed
fn local_bias(
    t: &[f64],
    src: &[f64],
    segments: &[std::ops::Range<usize>],
    r: Recipe,
    est: &[f64],
    rest: &[bool],
    (quantum, speed): (f64, &[f64]),
    err: &mut [f64],
) {
    let half = Recipe { h: (r.h / 2).max(2), ..r };
    if half.h == r.h {
        return;
    }
    let n = est.len();
    let (mut v, mut s) = (vec![0.0; n], vec![0.0; n]);
    estimate_deriv(t, src, segments, half, &mut v, &mut s);
    // the noise of the difference: both estimates share their samples, so its variance is
    // the half window's less the full one's (the full window's is nested in it to first order)
    let dt = (t[t.len() - 1] - t[0]) / (t.len().max(2) - 1) as f64;
    let gain = |h: usize| {
        lpr::weights(h, dt).map_or(0.0, |(w1, w2)| {
            let w = if r.second { w2 } else { w1 };
            w.iter().map(|x| x * x).sum::<f64>()
        })
    };
    let noise_var = r.sigma * r.sigma * (gain(half.h) - gain(r.h)).max(0.0);
    // Each sample's own: near a segment's ends (a rest's start or end, a gap) both fits are
    // shifted windows whose noise is several times the centred one's; the half window's own
    // noise `s` is known there, and the difference keeps the centred share of it.
    // Only a corrected q̈'s bar reads it (see below).
    let barred = r.corrected;
    let keep = if gain(half.h) > 0.0 { (1.0 - gain(r.h) / gain(half.h)).max(0.0) } else { 0.0 };
    let nv: Vec<f64> = if barred {
        (0..n).map(|i| if rest[i] { 0.0 } else { (s[i] * s[i] * keep).max(noise_var) }).collect()
    } else {
        Vec::new()
    };
    let grow = if r.from_q && !r.second { 16.0 / 15.0 } else { 4.0 / 3.0 };
    // A quantised source's staircase error is not white either: on the half window it is up to
    // one step over the window, less as the move crosses more steps (as the error floor after
    // this); that too is no bias.
    let step = quantum * 12f64.sqrt();
    let w_half = half.h as f64 * dt;
    let stair_var = |i: usize| {
        if step <= 0.0 || w_half <= 0.0 {
            return 0.0;
        }
        let crossed = (speed[i].abs() * 2.0 * w_half / step).max(1.0);
        let f = if r.second { step / (w_half * w_half) } else { step / (2.0 * w_half) } / crossed;
        f * f
    };
    let d2: Vec<f64> = (0..n).map(|i| if rest[i] { 0.0 } else { (est[i] - v[i]).powi(2) - stair_var(i) }).collect();
    if std::env::var_os("DIAG_TRACE").is_some() {
        let moving: Vec<f64> = (0..n).filter(|&i| !rest[i]).map(|i| d2[i]).collect();
        let m = moving.iter().sum::<f64>() / moving.len().max(1) as f64;
        eprintln!(
            "[trace] local bias ({}): h {} half {} sigma {:.3e} noise_var {:.3e} mean d2 {:.3e} -> bias rms {:.3e}",
            if r.second { "qdd" } else { "qd" },
            r.h,
            half.h,
            r.sigma,
            noise_var,
            m,
            grow * (m - noise_var).max(0.0).sqrt()
        );
    }
    // Raises sample i's error to the bias a windowed mean `mean` of d2 reads beyond `bar`.
    let raise = |err: &mut [f64], i: usize, mean: f64, bar: f64| {
        if bar >= 0.0 && mean > bar {
            let bias = grow * (mean - bar).sqrt();
            if bias > err[i] {
                err[i] = err[i].hypot(bias);
            }
        }
    };
    // Each sample's windowed mean of d2: taken as the bias where it passes the white figure, or
    // (barred) kept with the mean of its noise and the window's size (shorter at a segment's
    // ends) for the bar below.
    let mut means = if barred { vec![(0.0, 0.0, 0usize); n] } else { Vec::new() };
    for seg in segments {
        let (mut acc, mut acc_nv) = (0.0, 0.0);
        let (lo, hi) = (seg.start, seg.end);
        let w = r.h;
        // running sums over ±w inside the segment
        let mut a = lo;
        let mut b = lo;
        for i in lo..hi {
            let (want_a, want_b) = (i.saturating_sub(w).max(lo), (i + w + 1).min(hi));
            while b < want_b {
                acc += d2[b];
                if barred {
                    acc_nv += nv[b];
                }
                b += 1;
            }
            while a < want_a {
                acc -= d2[a];
                if barred {
                    acc_nv -= nv[a];
                }
                a += 1;
            }
            let m = (b - a).max(1);
            let mean = acc.max(0.0) / m as f64;
            if barred {
                means[i] = (mean, acc_nv.max(0.0) / m as f64, m);
            } else {
                raise(err, i, mean, noise_var);
            }
        }
    }
    if !barred {
        return;
    }
    // The noise's scale read from the log too, either way: an estimate of q's noise a few per
    // cent low (a quantiser's share of it) moves a bar of 3–4 × the noise into the bulk of the
    // readings, and a bare quantiser's staircase on a slow move differs between the two
    // windows far less than white noise of its variance would (a 1.5 mrad encoder's
    // point-to-point log, null seed 31 case 344: a bulk at 0.002 × the white figure, and its
    // stops' real bias under a bar set by that figure). Where the bias is local the bulk of the
    // moving samples' full windows is noise, their median ratio to the noise a known fraction
    // ([`window_dof`]); a bias everywhere raises it, and that is the log's typical figure, which
    // the estimate's error already holds.
    let dof = window_dof(r, half.h, dt);
    let full = 2 * r.h + 1;
    let stride = (r.h / 2).max(1);
    let mut bulk: Vec<f64> = (0..n)
        .step_by(stride)
        .filter(|&i| !rest[i] && means[i].2 == full && means[i].1 > 0.0)
        .map(|i| means[i].0 / means[i].1)
        .collect();
    let kappa = if bulk.len() >= 9 {
        let k = bulk.len() / 2;
        let (_, med, _) = bulk.select_nth_unstable_by(k, f64::total_cmp);
        *med / chi2_ratio(dof(full), 0.0)
    } else {
        1.0
    };
    for (i, &(mean, mean_nv, m)) in means.iter().enumerate() {
        // what the noise alone reaches in this window (p < 0.001) is no bias: only the reading
        // beyond it counts, so that a window the noise just pushes over is not read as a bias
        // of 2.3 × the noise's variance at once (the reading's lower bound; a stop at speed
        // reads tens to thousands of times the noise, where the bound is the reading)
        raise(err, i, mean, kappa * mean_nv * chi2_ratio(dof(m), Z_P001));
    }
}

/// The degrees of freedom of [`local_bias`]'s windowed mean of the squared difference between
/// the estimate and its half-window twin where q holds white noise only, as a function of the
/// window's sample count `m`. The difference is the two filters' difference applied to the
/// noise: Gaussian and correlated over the window (its autocorrelation `ρ` is the difference
/// filter's), so `cov(e_i², e_j²) = 2·σ⁴·ρ(i−j)²` and a ±h window holds only a few independent
/// values: its mean is a scaled χ² of `ν = m²/Σ_{|k|<m}(m − |k|)·ρ(k)²` degrees of freedom
/// (Satterthwaite; five or six for a q̈ window), whose upper 0.1 % point is the bar a bias must
/// pass. Read as noise-free, the mean's scatter (a standard deviation of 0.6 × its noise) made
/// every window the noise pushed up a bias of up to ten times the estimate's error: a
/// model-exact log-chirp at 1.1 kHz whose q̈ was off by 0.0055 rad/s² RMS (0.16 N·m through J)
/// had its floor at 0.60 N·m from q̈ errors read at 0.020 rad/s², and a Stribeck curve under a
/// ripple (SNR 1.5, seen u9101/0088) stayed under a floor of 0.91 N·m that the ripple's fit
/// alone took the residual to 0.36 N·m below.
fn window_dof(r: Recipe, half_h: usize, dt: f64) -> impl Fn(usize) -> f64 {
    let pick = |h: usize| lpr::weights(h, dt).map(|(w1, w2)| if r.second { w2 } else { w1 });
    let (full, half) = (pick(r.h), pick(half_h));
    // the difference filter over ±h (the half window's weights centred in it)
    let g: Vec<f64> = match (full, half) {
        (Some(f), Some(hw)) => {
            let off = r.h - half_h;
            f.iter()
                .enumerate()
                .map(|(j, x)| x - if j >= off && j - off < hw.len() { hw[j - off] } else { 0.0 })
                .collect()
        }
        _ => Vec::new(),
    };
    let e0: f64 = g.iter().map(|x| x * x).sum();
    // prefix sums over lags k ≥ 0 of ρ(k)² and k·ρ(k)²
    let (mut p0, mut p1) = (vec![0.0; g.len() + 1], vec![0.0; g.len() + 1]);
    if e0 > 0.0 {
        for k in 0..g.len() {
            let rho = g.iter().zip(&g[k..]).map(|(a, b)| a * b).sum::<f64>() / e0;
            p0[k + 1] = p0[k] + rho * rho;
            p1[k + 1] = p1[k] + k as f64 * rho * rho;
        }
    }
    move |m: usize| {
        if e0 <= 0.0 || m == 0 {
            return 1.0;
        }
        // Σ over |k| < m of (m − |k|)·ρ(k)²
        let kmax = m.min(p0.len() - 1);
        let s = (m as f64 * (2.0 * p0[kmax] - p0[1]) - 2.0 * p1[kmax]).max(1e-300);
        ((m * m) as f64 / s).max(1.0)
    }
}

/// A logged derivative whose scale against the estimate is off by more than 20 % is not the
/// derivative (a filtered or lagged estimate, another sensor) and is never used.
fn consistent(scale: f64) -> bool {
    (scale - 1.0).abs() <= 0.2
}

fn share(v: &[bool]) -> f64 {
    v.iter().filter(|x| **x).count() as f64 / v.len().max(1) as f64
}

/// RMS of q̇ and of q̈ from local cubic fits of ±`h` samples over one segment: the motion's size
/// seen through a pilot window, which averages an encoder's steps and a fine noise out.
fn pilot_motion(t: &[f64], q: &[f64], h: usize) -> (f64, f64) {
    let e = lpr::estimate(t, q, h);
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    (rms(&e.d1), rms(&e.d2))
}

/// The median of per-sample errors (a log's typical figure, robust to the larger errors at a
/// segment's ends).
fn typical(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut w = v.to_vec();
    let k = w.len() / 2;
    let (_, m, _) = w.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *m
}

/// The narrowest q̈ window (half-width in samples) [`fourth_order_bias`] corrects.
const CORRECTED_FROM_H: usize = 8;

/// A q̈ from q by a local cubic is biased by `M₄/4!·q⁽⁴⁾` (`M₄ = Σ w_j·(j·dt)⁴`, the window's
/// fourth moment): at the MSE-optimal window that bias is as large as the noise, and it is not
/// noise: it follows the motion (on a sinusoid it is `q̈` shrunk by `M₄·ω²/24`, 9 % at the top of
/// a chirp through a 98 ms half window), so a fit takes it for a larger inertia (a model-exact
/// log, null seed 4242 case 96, was named `parameters` for J 5 % high). The same filter applied
/// to the estimate gives `q⁽⁴⁾` (shrunk twice by the filter's own gain), and subtracting
/// `M₄/24` of it leaves a bias of second order (`q̈·(1 − 2x² + x³)` for a shrink `x`). It costs
/// noise: the combined filter `w − (M₄/24)·w∗w` passes white noise with 1.20× the standard
/// deviation (the ratio is computed, not assumed). So the correction is made only where the
/// expected squared error falls: the log's bias figure `b` (from the spectrum's q⁽⁴⁾) against
/// the noise `s`, `b² + s² > b'² + (1.2·s)²` with the remaining bias `b' = 2·b²/rms(q̈)`.
fn fourth_order_bias(
    r: Recipe,
    dt: f64,
    (values, noise, bias): (Vec<f64>, Vec<f64>, f64),
    filter: impl Fn(&[f64]) -> Vec<f64>,
) -> (Vec<f64>, Vec<f64>, f64, bool) {
    // The correction is the first term of a series in (h·dt·ω)²: it holds where the window
    // resolves the motion. A window at its narrowest (a few samples each side, chosen because
    // the spectrum holds motion near the Nyquist rate) has no such series: there q⁽⁴⁾ read
    // through the filter twice is mostly what the cubic cannot follow, and subtracting it added
    // error (a ripple-shaken joint at 1 kHz, h = 2: held-out RMSE 0.036 → 0.042 N·m).
    if r.h < CORRECTED_FROM_H {
        return (values, noise, bias, false);
    }
    let Some((_, w2)) = lpr::weights(r.h, dt) else {
        return (values, noise, bias, false);
    };
    let h = r.h as f64;
    let m4 = w2.iter().enumerate().map(|(k, w)| w * ((k as f64 - h) * dt).powi(4)).sum::<f64>();
    let c = m4 / 24.0;
    // the combined filter w − c·(w∗w) and its white-noise gain against w's
    let m = w2.len();
    let mut comb = vec![0.0; 2 * m - 1];
    for (i, a) in w2.iter().enumerate() {
        for (j, b) in w2.iter().enumerate() {
            if let Some(x) = comb.get_mut(i + j) {
                *x -= c * a * b;
            }
        }
    }
    for (x, w) in comb.iter_mut().skip(m / 2).zip(&w2) {
        *x += w;
    }
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let noise_gain = norm(&comb) / norm(&w2).max(1e-300);
    let rms = (values.iter().map(|x| x * x).sum::<f64>() / values.len().max(1) as f64).sqrt();
    if !(rms > 0.0 && noise_gain.is_finite() && c.is_finite()) {
        return (values, noise, bias, false);
    }
    let s = typical(&noise);
    let left = (2.0 * bias * bias / rms).min(bias);
    let worth = bias * bias + s * s > left * left + (noise_gain * s).powi(2);
    if std::env::var_os("DIAG_TRACE").is_some() {
        eprintln!(
            "[trace] q̈ fourth-order bias: M4/24 {c:.3e}, bias {bias:.3e} -> {left:.3e}, noise {s:.3e} ×{noise_gain:.3}: {}",
            if worth { "corrected" } else { "left" }
        );
    }
    if !worth {
        return (values, noise, bias, false);
    }
    let q4 = filter(&values);
    let corrected = values.iter().zip(&q4).map(|(v, f)| v - c * f).collect();
    let noise = noise.iter().map(|x| x * noise_gain).collect();
    (corrected, noise, left, true)
}

fn derived_info(source: &'static str, h: usize, dt: f64, noise: &[f64], bias: f64) -> DerivInfo {
    let nsd = typical(noise);
    DerivInfo {
        source,
        half_window_s: h as f64 * dt,
        error_sd: nsd.hypot(bias),
        noise_sd: nsd,
        logged_noise_sd: None,
        logged_scale: None,
        white: false,
    }
}

fn logged_info(noise: f64, scale: f64, white: bool) -> DerivInfo {
    DerivInfo {
        source: "logged",
        half_window_s: 0.0,
        error_sd: noise,
        noise_sd: noise,
        logged_noise_sd: Some(noise),
        logged_scale: Some(scale),
        white,
    }
}

/// The expected value of `clamp(v/band, −1, 1)` (`sign(v)` when `band` is 0) when the true
/// velocity is `v̂ + e` with `e ~ N(0, sd²)`: the friction sign a model predicts given an
/// estimated velocity. Far from rest it is the plain sign; at rest (v̂ ≈ 0 within its error)
/// it is ≈ 0, as the spec's `sign(0) = 0`, instead of a random ±1 from the estimate's noise.
pub fn expected_sign(v: f64, band: f64, sd: f64) -> f64 {
    // 8σ beyond the band the error can no longer reach it (the tail is below 1e-15)
    if !(sd > 0.0) || v.abs() > band.max(0.0) + 8.0 * sd {
        return crate::diagnose::sgn_band(v, band);
    }
    if !(band > 0.0) {
        return libm::erf(v / (sd * std::f64::consts::SQRT_2));
    }
    // E[clip(V, −b, b)]/b for V ~ N(μ, σ²).
    let (mu, b) = (v, band);
    let cdf = |x: f64| 0.5 * (1.0 + libm::erf(x / std::f64::consts::SQRT_2));
    let pdf = |x: f64| (-0.5 * x * x).exp() / (std::f64::consts::TAU).sqrt();
    let (al, be) = ((-b - mu) / sd, (b - mu) / sd);
    let e = -b * cdf(al) + b * (1.0 - cdf(be)) + mu * (cdf(be) - cdf(al)) - sd * (pdf(be) - pdf(al));
    (e / b).clamp(-1.0, 1.0)
}

/// The variance of `clamp(V/band, −1, 1)` (`sign(V)` when `band` is 0) for `V ~ N(v, sd²)`:
/// how uncertain the friction sign is given an estimated velocity. 0 far from rest.
pub fn sign_variance(v: f64, band: f64, sd: f64) -> f64 {
    if !(sd > 0.0) || v.abs() > band.max(0.0) + 6.0 * sd {
        return 0.0;
    }
    let m = expected_sign(v, band, sd);
    if !(band > 0.0) {
        return (1.0 - m * m).max(0.0);
    }
    // E[g²] by Gauss–Hermite quadrature (20 points, exact enough for a floor).
    let g = |x: f64| crate::diagnose::sgn_band(x, band);
    let e2: f64 = GAUSS_HERMITE_20
        .iter()
        .map(|&(x, w)| {
            let y = g(v + std::f64::consts::SQRT_2 * sd * x);
            w * y * y
        })
        .sum::<f64>()
        / std::f64::consts::PI.sqrt();
    (e2 - m * m).max(0.0)
}

/// Nodes and weights of 20-point Gauss–Hermite quadrature (∫ e^(−x²) f(x) dx).
const GAUSS_HERMITE_20: [(f64, f64); 20] = [
    (-5.387480890011233, 2.229393645534151e-13),
    (-4.603682449550744, 4.399340992273181e-10),
    (-3.944764040115625, 1.086069370769282e-7),
    (-3.347854567383216, 7.802556478532064e-6),
    (-2.788806058428131, 2.28338636016354e-4),
    (-2.254974002089276, 3.243773342237862e-3),
    (-1.738537712116586, 2.481052088746361e-2),
    (-1.234076215395323, 1.090172060200233e-1),
    (-0.737473728545394, 2.866755053628341e-1),
    (-0.245340708300901, 4.622436696006101e-1),
    (0.245340708300901, 4.622436696006101e-1),
    (0.737473728545394, 2.866755053628341e-1),
    (1.234076215395323, 1.090172060200233e-1),
    (1.738537712116586, 2.481052088746361e-2),
    (2.254974002089276, 3.243773342237862e-3),
    (2.788806058428131, 2.28338636016354e-4),
    (3.347854567383216, 7.802556478532064e-6),
    (3.944764040115625, 1.086069370769282e-7),
    (4.603682449550744, 4.399340992273181e-10),
    (5.387480890011233, 2.229393645534151e-13),
];

/// Samples whose q̇ estimate has a sign that no step of q within `h` samples either side has:
/// q moved inside the window, and only the other way. Noise or dither steps q both ways, so
/// this marks only a clean staircase (a quantised encoder without noise), where it is the
/// derivative estimator's overshoot. Rest samples are never marked.
fn against_steps(q: &[f64], qd: &[f64], rest: &[bool], segments: &[std::ops::Range<usize>], h: usize) -> Vec<bool> {
    let mut out = vec![false; q.len()];
    for seg in segments {
        let (s, e) = (seg.start, seg.end);
        if e - s < 2 {
            continue;
        }
        // prefix counts of rises and falls: step k is q[k+1] − q[k]
        let mut up = vec![0u32; e - s];
        let mut down = vec![0u32; e - s];
        for k in s..e - 1 {
            let j = k - s;
            let d = q[k + 1] - q[k];
            up[j + 1] = up[j] + u32::from(d > 0.0);
            down[j + 1] = down[j] + u32::from(d < 0.0);
        }
        for i in s..e {
            if rest[i] || qd[i] == 0.0 {
                continue;
            }
            // steps between samples lo..hi
            let (lo, hi) = (i.saturating_sub(h).max(s) - s, (i + h).min(e - 1) - s);
            let (u, d) = (up[hi] - up[lo], down[hi] - down[lo]);
            out[i] = if qd[i] > 0.0 { u == 0 && d > 0 } else { d == 0 && u > 0 };
        }
    }
    out
}

/// Marks the samples within `h` of a stretch's ends whose q̇ sign q does not confirm. There the
/// window is one-sided and the fit an extrapolation: a log that starts as a move starts from
/// rest, or ends in a short dwell, gets a q̇ of either sign at several times its stated error.
/// The sign counts as known only where, over the widest window centred on the sample that fits
/// in the stretch, the mean of q after the sample stands beyond three standard errors (`noise`
/// per sample) from the mean before it, the same way. Rest samples are never marked.
fn unconfirmed_ends(
    q: &[f64],
    qd: &[f64],
    rest: &[bool],
    segments: &[std::ops::Range<usize>],
    (h, noise): (usize, f64),
    marks: &mut [bool],
) {
    for seg in segments {
        // running sums of q from the stretch's first angle (sums(k) = Σ q[s..s+k] − k·q[s])
        let (s0, q0) = (seg.start, q[seg.start]);
        let mut sums = Vec::with_capacity(seg.len() + 1);
        sums.push(0.0);
        let mut acc = 0.0;
        for &x in &q[seg.clone()] {
            acc += x - q0;
            sums.push(acc);
        }
        let confirmed = |i: usize| {
            let m = (i - seg.start).min(seg.end - 1 - i).min(h);
            if m == 0 {
                return false;
            }
            let k = i - s0;
            let d = ((sums[k + 1 + m] - sums[k + 1]) - (sums[k] - sums[k - m])) / m as f64;
            d.abs() > 3.0 * noise * (2.0 / m as f64).sqrt() && d * qd[i] > 0.0
        };
        let head = seg.start..(seg.start + h).min(seg.end);
        let tail = seg.end.saturating_sub(h).max(head.end)..seg.end;
        for i in head.chain(tail) {
            if !rest[i] && !confirmed(i) {
                marks[i] = true;
            }
        }
    }
}

/// The first and last samples of every rest run that may still be a stop's creep or a start's
/// first creep: at least `reach`, and as long as the adjacent move's own slow-down says it
/// takes to stop (a smooth approach's q̇ falls like the square of the time left, so from q̇ and
/// its slope over `span` samples the time left is 2·q̇/q̇'); at most a quarter of the run.
fn rest_edges(rest: &[bool], segments: &[std::ops::Range<usize>], qd: &[f64], span: usize, reach: usize) -> Vec<bool> {
    // samples a move next to a rest at `edge` (its last or first moving sample) takes to stop,
    // going from `edge` away from `inner` (the sample `span` further into the move)
    let creep = |edge: usize, inner: usize| -> usize {
        let (v, w) = (qd[edge].abs(), qd[inner].abs());
        if w <= v || qd[edge] * qd[inner] <= 0.0 {
            return 0; // not a slow-down into the rest: an abrupt stop or start
        }
        let steps = 2.0 * v / ((w - v) / span as f64);
        if steps.is_finite() {
            steps.round().min(usize::MAX as f64 / 2.0) as usize
        } else {
            0
        }
    };
    let mut edge = vec![false; rest.len()];
    for seg in segments {
        let mut i = seg.start;
        while i < seg.end {
            if !rest[i] {
                i += 1;
                continue;
            }
            let j = (i..seg.end).find(|&k| !rest[k]).unwrap_or(seg.end);
            let quarter = (j - i) / 4;
            // a rest that starts or ends the segment has no move on that side
            if i > seg.start {
                let inner = (i - 1).saturating_sub(span).max(seg.start);
                let m = reach.max(creep(i - 1, inner)).min(quarter);
                edge[i..i + m].iter_mut().for_each(|e| *e = true);
            }
            if j < seg.end {
                let inner = (j + span).min(seg.end - 1);
                let m = reach.max(creep(j, inner)).min(quarter);
                edge[j - m..j].iter_mut().for_each(|e| *e = true);
            }
            i = j;
        }
    }
    edge
}

/// The runs of samples not at rest inside `seg`.
fn motion_runs(rest: &[bool], seg: std::ops::Range<usize>) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = seg.start;
    while i < seg.end {
        if rest[i] {
            i += 1;
            continue;
        }
        let j = (i..seg.end).find(|&k| rest[k]).unwrap_or(seg.end);
        out.push(i..j);
        i = j;
    }
    out
}

/// Samples inside runs of at least `min_run` where |q̇| ≤ 4σ and |q̈| ≤ 4σ of their noise
/// (per sample; a floor of 1e-9 relative to the signal's scale for clean columns).
fn detect_rest(
    qd: &[f64],
    qdd: &[f64],
    qd_sd: &[f64],
    qdd_sd: &[f64],
    min_run: usize,
    segments: &[std::ops::Range<usize>],
) -> Vec<bool> {
    let scale = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (fv, fa) = (1e-9 * scale(qd), 1e-9 * scale(qdd));
    let still: Vec<bool> = (0..qd.len())
        .map(|i| qd[i].abs() <= (4.0 * qd_sd[i]).max(fv) && qdd[i].abs() <= (4.0 * qdd_sd[i]).max(fa))
        .collect();
    runs_of_at_least(&still, min_run, segments)
}

/// `rest` without the samples marked `moving`, and without any run of rest left shorter than
/// `min_run` (as [`detect_rest`] asks of a rest).
fn trim_rest(rest: &[bool], moving: &[bool], min_run: usize, segments: &[std::ops::Range<usize>]) -> Vec<bool> {
    let still: Vec<bool> = rest.iter().zip(moving).map(|(&r, &m)| r && !m).collect();
    runs_of_at_least(&still, min_run, segments)
}

/// The samples of `still` that lie in runs of at least `min_run` within one segment.
fn runs_of_at_least(still: &[bool], min_run: usize, segments: &[std::ops::Range<usize>]) -> Vec<bool> {
    let mut out = vec![false; still.len()];
    for r in segments {
        let mut i = r.start;
        while i < r.end {
            if !still[i] {
                i += 1;
                continue;
            }
            let j = (i..r.end).find(|&k| !still[k]).unwrap_or(r.end);
            if j - i >= min_run {
                out[i..j].iter_mut().for_each(|x| *x = true);
            }
            i = j;
        }
    }
    out
}

/// Where the q̇ estimate is within 3σ of zero and the joint is not at rest: if q leaves its
/// noise band (`band`) on both sides within `reach` samples, going the same way, the joint moves
/// through that way (no reversal), and `dir` gets that sign. Opposite ways are a reversal: the
/// sign stays the estimate's.
#[allow(clippy::too_many_arguments)]
fn through_direction(
    q: &[f64],
    qd: &[f64],
    qd_err: &[f64],
    rest: &[bool],
    segments: &[std::ops::Range<usize>],
    band: f64,
    reach: usize,
    dir: &mut [i8],
) {
    for seg in segments {
        for i in seg.clone() {
            if rest[i] || dir[i] != 0 || qd[i].abs() > 3.0 * qd_err[i] {
                continue;
            }
            let ahead = (i + 1..(i + 1 + reach).min(seg.end)).find(|&k| (q[k] - q[i]).abs() > band);
            let behind = (seg.start.max(i.saturating_sub(reach))..i).rev().find(|&k| (q[i] - q[k]).abs() > band);
            if let (Some(a), Some(b)) = (ahead, behind) {
                let (fa, fb) = (q[a] - q[i], q[i] - q[b]);
                if fa * fb > 0.0 {
                    dir[i] = if fa > 0.0 { 1 } else { -1 };
                }
            }
        }
    }
}

/// The median angle of the rest run that contains sample `at`.
fn rest_angle(q: &[f64], rest: &[bool], at: usize, seg: std::ops::Range<usize>) -> f64 {
    let lo = (seg.start..=at).rev().take_while(|&k| rest[k]).last().unwrap_or(at);
    let hi = (at..seg.end).take_while(|&k| rest[k]).last().map_or(at + 1, |k| k + 1);
    let mut w: Vec<f64> = q[lo..hi].to_vec();
    let k = w.len() / 2;
    let (_, m, _) = w.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *m
}

/// Samples in a row that must lie beyond a rest's band, on one side, for q to have left it
/// (or not yet reached it). One sample beyond 4σ is the noise's own tail: a 2 kHz log holds a
/// few over a minute of rest, and one of them ended a start's undecided samples 45 ms after
/// the rest while the joint stood for another 90 ms; the q̇ estimate there, its window reaching
/// into the coming move, changed sign twice and the pure sign put ±c (17 N·m) on a
/// model-exact log (development seed 4, torque case 18). Three in a row on one side happen by
/// chance about once in 10¹³ samples of white noise.
const CLEAR_RUN: usize = 3;

/// Whether every sample of q in `at` lies beyond `band` of `q_rest`, all on one side.
fn clear_of(q: &[f64], q_rest: f64, band: f64, at: std::ops::Range<usize>) -> bool {
    let side = |k: usize| {
        let d = q[k] - q_rest;
        if d > band {
            1
        } else if d < -band {
            -1
        } else {
            0
        }
    };
    let first = side(at.start);
    first != 0 && at.clone().all(|k| side(k) == first)
}

/// At every rest/motion transition: the direction of the move next to it (from where q goes,
/// until the q̇ estimate itself is clearly signed: beyond 3σ of its noise), and the samples
/// whose motion is undecided (the last `hold` samples of the rest and the move's samples
/// before q leaves `band` for [`CLEAR_RUN`] samples in a row).
#[allow(clippy::too_many_arguments)]
fn transitions(
    q: &[f64],
    (qd, qd_noise, logged): (&[f64], &[f64], bool),
    rest: &[bool],
    segments: &[std::ops::Range<usize>],
    band: f64,
    hold: usize,
) -> (Vec<i8>, Vec<bool>) {
    let n = q.len();
    let mut dir = vec![0i8; n];
    let mut amb = vec![false; n];
    let sgn = |x: f64| if x > 0.0 { 1i8 } else { -1i8 };
    // the estimate signs the motion itself from here on, whichever way: a move that overshoots
    // and settles back reaches its rest going the other way, and that last way must not be
    // carried back over the whole move
    let sure = |i: usize| qd[i].abs() > 3.0 * qd_noise[i];
    // A logged q̇ that is white noise about the motion (no estimator's window smearing a start
    // back into the rest) signs the motion itself where it stands clear of its noise, though q
    // is still inside its band: a move that creeps out of a rest at a few mrad/s under a coarse
    // encoder takes a third of a second to leave it, and a Stribeck curve lives at those
    // speeds (seen torque t9052/0046: 1.9 N·m at 0.006 rad/s, all of it left out). 4σ: a
    // wrong sign there costs the full Coulomb step.
    // Two samples in a row, one way: a white noise's own 4σ tail is a single sample, two the
    // same way come once in 5·10⁸ (null seed 4242 case 459: one logged q̇ at 4.1σ in a dwell put
    // the full Coulomb level, 5.2 N·m, on a model-exact log and made it `unexplained`); a creep
    // at 5σ keeps most of its samples.
    let beyond = |way: f64| -> Vec<bool> {
        let past: Vec<bool> = (0..n).map(|i| logged && qd[i] * way > 4.0 * qd_noise[i]).collect();
        runs_of_at_least(&past, 2, segments)
    };
    let (up, down) = (beyond(1.0), beyond(-1.0));
    let signed = |i: usize| up[i] || down[i];
    for seg in segments {
        for run in motion_runs(rest, seg.clone()) {
            // leaving a rest at run.start
            if run.start > seg.start {
                let q_rest = rest_angle(q, rest, run.start - 1, seg.clone());
                let out = (run.start..run.end).find(|&k| clear_of(q, q_rest, band, k..(k + CLEAR_RUN).min(run.end)));
                let lo = run.start.saturating_sub(hold).max(seg.start);
                (lo..out.unwrap_or(run.end)).filter(|&i| !signed(i)).for_each(|i| amb[i] = true);
                if let Some(k) = out {
                    let d = sgn(q[k] - q_rest);
                    for i in k..run.end {
                        if sure(i) {
                            break;
                        }
                        dir[i] = d;
                    }
                }
            }
            // reaching a rest at run.end
            if run.end < seg.end {
                let q_rest = rest_angle(q, rest, run.end, seg.clone());
                let last = (run.start..run.end)
                    .rev()
                    .find(|&k| clear_of(q, q_rest, band, (k + 1).saturating_sub(CLEAR_RUN).max(run.start)..k + 1));
                let hi = (run.end + hold).min(seg.end);
                (last.map_or(run.start, |k| k + 1)..hi).filter(|&i| !signed(i)).for_each(|i| amb[i] = true);
                if let Some(k) = last {
                    let d = sgn(q_rest - q[k]);
                    for i in (run.start..=k).rev() {
                        if sure(i) {
                            break;
                        }
                        if dir[i] == 0 {
                            dir[i] = d;
                        }
                    }
                }
            }
        }
    }
    (dir, amb)
}

/// Beyond this magnitude no joint column (rad, rad/s, rad/s², N·m, °C) holds a measurement.
const ABSURD: f64 = 1e9;
/// A value farther beyond its column's central 98 % than this many times that range's width
/// is a glitch: an impact's torque spike or a fast move stays within a few widths.
const GLITCH_WIDTHS: f64 = 50.0;
/// More rows than this share with glitches: the log is refused, not repaired.
const MAX_GLITCH_SHARE: f64 = 0.01;

/// One cell no joint produces.
#[derive(Clone, Debug, PartialEq)]
struct Glitch {
    /// row index in the log as read (file line = row + 2)
    row: usize,
    column: String,
    value: f64,
    /// the column's central 98 % (1st and 99th percentiles)
    central: (f64, f64),
}

/// Finds cells no joint produces — beyond [`ABSURD`], or farther beyond the column's central
/// 98 % than [`GLITCH_WIDTHS`] times its width (a column whose central 98 % is one value is
/// held to the absolute bound only) — and drops their rows. More than [`MAX_GLITCH_SHARE`] of
/// the rows: the log is refused (a unit or a column mix-up, not glitches). Reported by line.
fn drop_glitches(log: &JointLog) -> Result<(std::borrow::Cow<'_, JointLog>, Vec<Glitch>), PrepError> {
    let n = log.len();
    let mut cols: Vec<(&str, &[f64])> = vec![("q", &log.q)];
    for (name, c) in [("qd", &log.qd), ("qdd", &log.qdd), ("u", &log.u), ("tau", &log.tau), ("temp", &log.temp)] {
        if let Some(v) = c {
            cols.push((name, v));
        }
    }
    for (name, v) in &log.others {
        cols.push((name, v));
    }
    let mut found: Vec<Glitch> = Vec::new();
    for (name, v) in cols {
        let mut finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        // 1st and 99th percentiles by selection (a sort of every column cost 0.1 s on 1 M rows)
        let (Some(lo), Some(hi)) = (quantile::at_rounded(&mut finite, 0.01), quantile::at_rounded(&mut finite, 0.99))
        else {
            continue;
        };
        let w = hi - lo;
        for (row, &x) in v.iter().enumerate() {
            let beyond = w > 0.0 && (x > hi + GLITCH_WIDTHS * w || x < lo - GLITCH_WIDTHS * w);
            if !x.is_finite() || x.abs() > ABSURD || beyond {
                found.push(Glitch { row, column: name.to_string(), value: x, central: (lo, hi) });
            }
        }
    }
    if found.is_empty() {
        return Ok((std::borrow::Cow::Borrowed(log), found));
    }
    found.sort_by_key(|g| g.row);
    let mut rows: Vec<usize> = found.iter().map(|g| g.row).collect();
    rows.dedup();
    if rows.len() as f64 > MAX_GLITCH_SHARE * n as f64 {
        return Err(PrepError::Refused(format!(
            "{} of {n} rows hold values no joint produces ({}): more than {:.0} % of the log, so it is refused rather than repaired (a column in other units, or a logger fault?)",
            rows.len(),
            describe_glitches(&found, 3),
            100.0 * MAX_GLITCH_SHARE
        )));
    }
    // one glitch per row in the result (the first column named)
    found.dedup_by_key(|g| g.row);
    let keep: Vec<usize> = (0..n).filter(|i| rows.binary_search(i).is_err()).collect();
    Ok((std::borrow::Cow::Owned(select_rows(log, &keep)), found))
}

fn describe_glitches(g: &[Glitch], k: usize) -> String {
    let mut parts: Vec<String> = g
        .iter()
        .take(k)
        .map(|g| {
            format!(
                "line {}, column `{}`: {:e}, against the column's central 98 % of [{:.4}, {:.4}]",
                g.row + 2,
                g.column,
                g.value,
                g.central.0,
                g.central.1
            )
        })
        .collect();
    if g.len() > k {
        parts.push(format!("and {} more", g.len() - k));
    }
    parts.join("; ")
}

fn glitch_note(g: &[Glitch]) -> String {
    format!(
        "{} row(s) dropped for a value no joint produces (beyond {ABSURD:e}, or {GLITCH_WIDTHS}× the column's central 98 % beyond it): {}",
        g.len(),
        describe_glitches(g, 5)
    )
}

/// The rows `keep` (increasing) of `log`.
fn select_rows(log: &JointLog, keep: &[usize]) -> JointLog {
    let pick = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let pick_opt = |v: &Option<Vec<f64>>| v.as_ref().map(|v| pick(v));
    JointLog {
        t: pick(&log.t),
        q: pick(&log.q),
        qd: pick_opt(&log.qd),
        qdd: pick_opt(&log.qdd),
        u: pick_opt(&log.u),
        tau: pick_opt(&log.tau),
        temp: pick_opt(&log.temp),
        others: log.others.iter().map(|(k, v)| (k.clone(), pick(v))).collect(),
        unknown: log.unknown.clone(),
    }
}

/// Drops rows whose measured values all repeat the previous row's.
fn drop_stale(log: &JointLog) -> (std::borrow::Cow<'_, JointLog>, usize) {
    let n = log.len();
    let same = |i: usize| -> bool {
        let eq = |c: &Option<Vec<f64>>| c.as_ref().is_none_or(|v| v[i] == v[i - 1]);
        log.q[i] == log.q[i - 1]
            && eq(&log.qd)
            && eq(&log.qdd)
            && eq(&log.u)
            && eq(&log.tau)
            && log.others.iter().all(|(_, v)| v[i] == v[i - 1])
            // a log of q alone at rest repeats itself legitimately
            && (log.qd.is_some() || log.u.is_some() || log.tau.is_some())
            // and so does a still joint whose logged q̇ reads exactly zero (a clean or a
            // drive-differenced velocity under a quantised angle): a logger that missed a
            // sample repeats a moving joint's q̇. Dropped, the rest became gaps that split the
            // log (seen trajectory t9054/0042: 2 780 rows of a pendulum at rest, 87 segments,
            // the swing's ripple judged on the first one alone).
            && log.qd.as_ref().is_none_or(|v| v[i] != 0.0)
    };
    let keep: Vec<usize> = (0..n).filter(|&i| i == 0 || !same(i)).collect();
    let dropped = n - keep.len();
    if dropped == 0 {
        // (no copy of a clean log: a 1 M-row log's columns are 50 MB)
        return (std::borrow::Cow::Borrowed(log), 0);
    }
    (std::borrow::Cow::Owned(select_rows(log, &keep)), dropped)
}

/// Median time step (robust to jitter and the odd gap), the one every stage uses. A strided
/// sample of at most ~20 000 differences keeps a million rows cheap. A column of fewer than two
/// times has no step: NaN (every log reaching a stage has been checked for length before).
pub fn median_step(t: &[f64]) -> f64 {
    let stride = (t.len() / 20_000).max(1);
    let mut d: Vec<f64> = t.windows(2).step_by(stride).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::NAN;
    }
    let k = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *m
}

fn split_at_gaps(t: &[f64], dt: f64) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..t.len() {
        if t[i] - t[i - 1] > GAP_FACTOR * dt {
            out.push(start..i);
            start = i;
        }
    }
    out.push(start..t.len());
    out
}

/// Splits segments where q steps further in one sample than its motion can: more than 20× the
/// robust spread of its one-sample changes and 10× both neighbouring changes. Returns the count.
fn split_at_jumps(q: &[f64], segments: &mut Vec<std::ops::Range<usize>>) -> usize {
    let d: Vec<f64> = q.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if d.len() < 10 {
        return 0;
    }
    let mut s = d.clone();
    let k = s.len() * 9 / 10;
    let (_, p90, _) = s.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    let limit = 20.0 * *p90;
    if !(limit > 0.0) {
        return 0;
    }
    let mut out = Vec::new();
    let mut count = 0;
    for seg in segments.iter() {
        let mut start = seg.start;
        for i in seg.start + 1..seg.end {
            let step = d[i - 1];
            let before = if i >= 2 { d[i - 2] } else { 0.0 };
            let after = d.get(i).copied().unwrap_or(0.0);
            if step > limit && step > 10.0 * before.max(after) {
                out.push(start..i);
                start = i;
                count += 1;
            }
        }
        out.push(start..seg.end);
    }
    *segments = out;
    count
}

fn longest(segments: &[std::ops::Range<usize>]) -> Option<&std::ops::Range<usize>> {
    segments.iter().max_by_key(|r| r.len())
}

/// A logged column's own noise from its spectrum (or its 4th differences when short), and
/// whether that spectrum shows it coloured: then the sum of its noise model, which holds the
/// level below the motion's band at the lowest one seen above it, and what lies under the
/// motion stays unread.
fn own_noise(t: &[f64], x: &[f64], segments: &[std::ops::Range<usize>], dt: f64) -> (f64, bool) {
    longest(segments)
        .and_then(|r| spectrum::analyse(&t[r.clone()], &x[r.clone()], dt))
        .map_or_else(|| (diff_noise(x), false), |s| (s.noise_sd.max(s.noise.total_sd()), !s.noise.is_white()))
}

/// White noise on `x` from its 4th differences (robust), for logs too short for a spectrum.
fn diff_noise(x: &[f64]) -> f64 {
    if x.len() < 6 {
        return 0.0;
    }
    let mut d: Vec<f64> = x.windows(5).map(|w| (w[4] - 4.0 * w[3] + 6.0 * w[2] - 4.0 * w[1] + w[0]).abs()).collect();
    let k = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    1.4826 * *m / 70f64.sqrt()
}

/// The uniform-quantisation error of an encoder, `step/√12`, with its step read as the most
/// common smallest non-zero change of `x` (0 when x does not look quantised).
fn resolution_sd(x: &[f64]) -> f64 {
    let mut steps: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|d| *d > 0.0).collect();
    if steps.len() < 20 {
        return 0.0;
    }
    let k = steps.len() / 100;
    let (_, &mut smallest, _) = steps.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    // Quantised: most changes are whole multiples of the smallest.
    let on_grid = steps
        .iter()
        .filter(|d| {
            let r = *d / smallest;
            (r - r.round()).abs() < 0.02
        })
        .count();
    if on_grid * 10 >= steps.len() * 9 {
        smallest / 12f64.sqrt()
    } else {
        0.0
    }
}

/// Unit factors a logged derivative may be off by, with what each means.
const FACTORS: [(f64, &str); 9] = [
    (180.0 / std::f64::consts::PI, "degrees against radians"),
    (std::f64::consts::PI / 180.0, "radians against degrees"),
    (1000.0, "per millisecond against per second, or milli-units"),
    (1.0e-3, "per second against per millisecond"),
    (std::f64::consts::TAU, "radians against revolutions"),
    (1.0 / std::f64::consts::TAU, "revolutions against radians"),
    (60.0, "per minute against per second"),
    (1.0 / 60.0, "per second against per minute"),
    (-1.0, "the opposite sign"),
];

/// How a logged derivative column is named in the checks' notes.
struct LoggedColumn {
    /// the column ("qd", "qdd")
    name: &'static str,
    /// the signal it is the derivative of ("q", "qd")
    of: &'static str,
    /// what it is weighed against, and what is used when it loses
    estimate: &'static str,
    used: &'static str,
    unit: &'static str,
}

/// A logged derivative column against the estimate from the signal below it ([`compare_logged`],
/// with `short` the estimate on a quarter window, given the estimate's values; its own noise, a
/// lag): the column is used (`true`) when its error is no larger than the
/// estimate's, its scale is consistent and it does not lag; otherwise the estimate is, with the
/// column's measured noise and scale recorded, and a note says why.
fn check_logged(
    col: &[f64],
    estimate: Deriv,
    short: &dyn Fn(&[f64]) -> Vec<f64>,
    what: &LoggedColumn,
    rate: Option<(&[f64], usize)>,
    (t, segments, dt): (&[f64], &[std::ops::Range<usize>], f64),
    notes: &mut Vec<String>,
) -> Result<(Deriv, bool), PrepError> {
    let est_err = typical(&estimate.error());
    let short_of_estimate = || short(&estimate.values);
    let (scale, diff) = compare_logged(col, &estimate.values, est_err, &short_of_estimate, what.name, what.of)?;
    let (own, coloured) = own_noise(t, col, segments, dt);
    // The difference's spread less the estimate's modelled error is the column's noise only
    // where it clearly exceeds that error (the difference spreads √2 times beyond it): the
    // model of an estimate's error is good to a few tens of percent, and within that the excess
    // is the estimate's, not the column's; the column's own spectrum says its noise. A clean q̇
    // beside a noisy logged q̈ was read as noisy at 3.3e-5 rad/s (its spectrum: 1.4e-6), its
    // difference 10 % beyond the estimate's error: the q̈ from it looked no better than the
    // logged one, whose noise times the inertia doubled the residual, and a drift was lost
    // (`unexplained`, unseen t9082/0061). Beside a coarse encoder one was read at 3.6e-4 rad/s
    // (its spectrum: 3e-6), the q̈ from it given 7× its error and a floor four times the
    // refit's residual (unseen t9086/0072).
    // A coloured noise is read from the column's spectrum only above the motion's band (a
    // drive's filtered velocity estimate, an AR(1) noise): its part under the motion, the
    // slow one that flips the sign of q̇ near a reversal for many samples, is bounded by the
    // difference alone. Read at its spectrum's level (ρ = 0.9: 0.23× the noise, or 0.6× with
    // the coloured model), model-exact logs were `unexplained`, a reversal's sign taken as known
    // where the noise had flipped it (null seed 4242, cases 29, 35, 168 with such a q̇).
    let noise = if diff > est_err || coloured { diff.max(own) } else { own };
    if std::env::var_os("DIAG_TRACE").is_some() {
        eprintln!("[trace] logged {}: diff noise {diff:.3e}, own noise {own:.3e}, estimate's error {est_err:.3e} (effective {:.3e})", what.name, estimate.effective_error());
    }
    let lag = logged_lag(col, &estimate.values);
    if let Some(l) = lag {
        notes.push(format!(
            "the logged {} lags {} by {l} samples (a filtered estimate): {} is used",
            what.name, what.estimate, what.used
        ));
    }
    // A lag shorter than a sample (a drive's low-pass on its velocity estimate) is an error of
    // −τ·q̈ that no noise figure holds: a viscous friction reads it as an inertia off by b·τ.
    // Counted with the column's noise where τ stands clear of its standard error, it decides
    // which q̇ is used (a trunk joint with b = 87 N·m·s/rad, its q̇ low-passed at 30 Hz, 1.8 ms
    // late at 100 Hz: `parameters` on a model-exact log, the inertia refitted 2.2× high).
    let sub_lag = rate.and_then(|(a, window)| sub_sample_lag(col, &estimate.values, a, window));
    let lag_err = sub_lag.map_or(0.0, |(_, e)| e);
    // (structure that follows the motion, so weighed as the estimate's bias is: three times its
    // square, [`Deriv::effective_error`])
    let with_lag = (noise * noise + 3.0 * lag_err * lag_err).sqrt();
    if std::env::var_os("DIAG_TRACE").is_some() {
        eprintln!("[trace] logged {}: lag under a sample {sub_lag:?} (s, error)", what.name);
    }
    let lag_decides = lag.is_none() && noise <= estimate.effective_error() && with_lag > estimate.effective_error();
    if lag_decides {
        if let Some((tau, _)) = sub_lag {
            notes.push(format!(
                "the logged {} lags {} by {:.2} ms (a filtered estimate): {} is used",
                what.name,
                what.estimate,
                1e3 * tau,
                what.used
            ));
        }
    }
    if with_lag <= estimate.effective_error() && consistent(scale) && lag.is_none() {
        let info = logged_info(noise, scale, !coloured && own >= 0.5 * diff);
        return Ok((Deriv { values: col.to_vec(), noise: vec![noise; col.len()], bias: 0.0, info }, true));
    }
    if !lag_decides {
        notes.push(format!(
            "the logged {} is noisier than {} ({noise:.3e} vs {est_err:.3e} {}): {} is used",
            what.name, what.estimate, what.unit, what.used
        ));
    }
    let mut d = estimate;
    d.info.logged_noise_sd = Some(noise);
    d.info.logged_scale = Some(scale);
    Ok((d, false))
}

/// The logged column `v` against the estimate `e` (error `e_sd`): its scale (least squares
/// slope where the estimate is well above its error) and its noise. A scale at a unit factor
/// refuses the log naming it.
fn compare_logged(
    v: &[f64],
    e: &[f64],
    e_sd: f64,
    short: &dyn Fn() -> Vec<f64>,
    name: &str,
    of: &str,
) -> Result<(f64, f64), PrepError> {
    let strong: Vec<(f64, f64)> =
        v.iter().zip(e).filter(|(_, e)| e.abs() > 5.0 * e_sd).map(|(a, b)| (*a, *b)).collect();
    let mut scale = 1.0;
    if strong.len() >= 20 {
        let sxy: f64 = strong.iter().map(|(a, b)| a * b).sum();
        let sxx: f64 = strong.iter().map(|(_, b)| b * b).sum();
        if sxx > 0.0 {
            scale = sxy / sxx;
        }
        for (f, what) in FACTORS {
            if (scale / f - 1.0).abs() < 0.1 {
                return Err(PrepError::Refused(format!(
                    "the logged `{name}` is {scale:.4}× the derivative of `{of}` ({what}): the columns are not in \
                     consistent SI units (spec §1: rad, rad/s, rad/s², s); convert them, or leave `{name}` out and it \
                     is derived from `{of}`"
                )));
            }
        }
    }
    let mut r: Vec<f64> = v.iter().zip(e).map(|(a, b)| (a - b).abs()).collect();
    if r.is_empty() {
        return Ok((scale, 0.0));
    }
    let rms = (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt();
    let k = r.len() / 2;
    let (_, m, _) = r.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    let diff_sd = 1.4826 * *m;
    let noise = (diff_sd * diff_sd - e_sd * e_sd).max(0.0).sqrt();
    // Differences whose RMS is far beyond their typical size sit in a few places, where one of
    // the two smears every sudden change: a filtered column, or the estimate's own window. The
    // one that does is the one farther there from an estimate on a quarter of the window (less
    // bias, more noise); if that is the column, its error is that RMS, not its median.
    let concentrated = rms > 3.0 * diff_sd.max(e_sd);
    let column_smears = concentrated && {
        let s = short();
        let (mut col, mut est) = (0.0, 0.0);
        for ((a, b), c) in v.iter().zip(e).zip(&s) {
            if (a - b).abs() > 3.0 * diff_sd.max(e_sd) {
                col += (a - c) * (a - c);
                est += (b - c) * (b - c);
            }
        }
        col >= est
    };
    let noise = if column_smears { noise.max((rms * rms - e_sd * e_sd).max(0.0).sqrt()) } else { noise };
    Ok((scale, noise))
}

/// The lag (seconds; positive: late) of a logged column `v` behind the estimate `e` of the same
/// quantity, shorter than a sample, and its error's RMS `|τ|·rms(a)`, from the regression
/// `v − e ≈ −τ·a` with `a` the estimate's own derivative; `None` unless τ stands five standard
/// errors clear of zero (the difference counted as correlated over the estimate's `window`
/// samples).
fn sub_sample_lag(v: &[f64], e: &[f64], a: &[f64], window: usize) -> Option<(f64, f64)> {
    let n = v.len().min(e.len()).min(a.len());
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for ((x, y), z) in v.iter().zip(e).zip(a).take(n) {
        sxy += (x - y) * z;
        sxx += z * z;
    }
    if n < 20 || !(sxx > 0.0) {
        return None;
    }
    let tau = -sxy / sxx;
    let sse: f64 = v.iter().zip(e).zip(a).take(n).map(|((x, y), z)| (x - y + tau * z).powi(2)).sum();
    let n_eff = (n as f64 / window.max(1) as f64).max(2.0);
    // Var(τ) = σ²/Σa² for independent rows; the rows count as n_eff: σ²·(n/n_eff)/Σa²
    let se = (sse / sxx / (n_eff - 1.0)).sqrt();
    (tau.abs() > 5.0 * se).then(|| (tau, tau.abs() * (sxx / n as f64).sqrt()))
}

/// Samples by which a logged column lags (positive) or leads the estimate of the same
/// quantity, when shifting it explains their difference clearly better (the shift's squared
/// difference under 70 % of the unshifted one): a drive's filtered estimate. `None`: no shift.
fn logged_lag(v: &[f64], e: &[f64]) -> Option<i64> {
    let n = v.len().min(e.len());
    if n < 100 {
        return None;
    }
    let sse = |lag: i64| -> f64 {
        let stride = (n / 50_000).max(1);
        (20..n - 20)
            .step_by(stride)
            .map(|i| {
                let j = (i as i64 - lag) as usize;
                let d = v[i] - e[j];
                d * d
            })
            .sum()
    };
    let s0 = sse(0);
    let (best, sb) = (-10..=10).map(|l| (l, sse(l))).min_by(|a, b| a.1.total_cmp(&b.1))?;
    (best != 0 && sb < 0.7 * s0).then_some(best)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    fn log_of(t: Vec<f64>, q: Vec<f64>) -> JointLog {
        JointLog { t, q, ..JointLog::default() }
    }

    #[test]
    fn an_estimate_against_every_step_of_q_in_its_window_is_marked() {
        // q steps down twice in the window; an estimate upwards is against it, downwards not
        let q = [3.0, 3.0, 2.0, 2.0, 2.0, 2.0, 1.0, 1.0, 1.0];
        let whole = 0..q.len();
        let seg = std::slice::from_ref(&whole);
        let rest = [false; 9];
        let up = against_steps(&q, &[0.1; 9], &rest, seg, 2);
        let down = against_steps(&q, &[-0.1; 9], &rest, seg, 2);
        // (the last sample's window, 6..=8, holds no step)
        assert_eq!(up, [true, true, true, true, true, true, true, true, false]);
        assert!(down.iter().all(|m| !m));
        // a sample whose window holds no step at all says nothing either way
        assert!(!against_steps(&q, &[0.1; 9], &rest, seg, 1)[4]);
        // dither (q going both ways) never marks; nor does rest
        let dithered = [2.0, 1.0, 2.0, 1.0, 1.0, 2.0, 1.0, 0.0, 1.0];
        assert!(against_steps(&dithered, &[0.1; 9], &rest, seg, 2).iter().all(|m| !m));
        assert!(against_steps(&q, &[0.1; 9], &[true; 9], seg, 2).iter().all(|m| !m));
    }

    #[test]
    fn one_noise_sample_beyond_the_band_does_not_end_a_start_or_a_stop() {
        // rest at 0 (samples 0..20), the joint still until 40, then a move up to 70, then
        // still again at 0.3; the rest detector ended the first rest at 20 and starts the
        // second at 75. One sample beyond the band at 25 (a noise tail) and one at 72.
        let band = 0.01;
        let mut q: Vec<f64> = (0..100)
            .map(|i| match i {
                0..40 => 0.0,
                40..70 => 0.01 * (i - 39) as f64,
                _ => 0.3,
            })
            .collect();
        q[25] = -1.5 * band;
        q[72] = 0.3 + 1.5 * band;
        let rest: Vec<bool> = (0..100).map(|i| !(20..75).contains(&i)).collect();
        let whole = 0..q.len();
        // the q̇ estimate signs the middle of the move itself (beyond 3σ of its noise)
        let qd: Vec<f64> = (0..100).map(|i| if (45..65).contains(&i) { 0.5 } else { 0.0 }).collect();
        let noise = vec![0.1; 100];
        let (dir, amb) = transitions(&q, (&qd, &noise, false), &rest, std::slice::from_ref(&whole), band, 2);
        // undecided until q leaves the band for good (41: 0.02 > 0.01), not from the noise
        // sample on; the direction there is the move's, never the noise sample's
        assert!((18..41).all(|i| amb[i]), "{amb:?}");
        assert!((41..45).chain(65..69).all(|i| !amb[i] && dir[i] == 1), "{amb:?} {dir:?}");
        // reaching the second rest: the move's last sample beyond its band is 68 (0.29),
        // the noise sample at 72 does not carry the move's direction past it
        assert!((69..77).all(|i| amb[i] && dir[i] == 0), "{amb:?} {dir:?}");
    }

    #[test]
    fn a_logged_velocity_signs_a_start_from_two_samples_beyond_its_noise_not_one() {
        // a dwell at 0 broken by one logged q̇ sample at 4.1σ (sample 30: the rest detector
        // leaves it out of both rests), and a creep from 60 on that q does not leave the band
        // within the log, its logged q̇ at 6σ
        let band = 0.01;
        let q = vec![0.0; 80];
        let mut qd = vec![0.0; 80];
        qd[30] = -0.41;
        qd[60..].iter_mut().for_each(|v| *v = 0.6);
        let rest: Vec<bool> = (0..80).map(|i| i != 30 && i < 60).collect();
        let whole = 0..q.len();
        let noise = vec![0.1; 80];
        let (_, amb) = transitions(&q, (&qd, &noise, true), &rest, std::slice::from_ref(&whole), band, 2);
        // the lone sample is undecided (left out), not a move signed by its noise
        assert!(amb[30], "{amb:?}");
        // the creep's samples sign themselves
        assert!((60..80).all(|i| !amb[i]), "{amb:?}");
    }

    #[test]
    fn expected_sign_is_the_sign_far_from_rest_and_zero_at_rest() {
        assert!((expected_sign(1.0, 0.0, 0.01) - 1.0).abs() < 1e-12);
        assert!(expected_sign(0.0, 0.0, 0.01).abs() < 1e-12);
        assert!((expected_sign(0.01, 0.0, 0.01) - 0.6827).abs() < 1e-3);
        // with a band much wider than the error it is the clamp
        assert!((expected_sign(0.005, 0.02, 1e-5) - 0.25).abs() < 1e-6);
        assert!((expected_sign(-0.5, 0.02, 1e-3) + 1.0).abs() < 1e-9);
    }

    #[test]
    fn sign_variance_is_one_at_rest_and_small_inside_a_wide_band() {
        assert!((sign_variance(0.0, 0.0, 0.01) - 1.0).abs() < 1e-12);
        assert_eq!(sign_variance(1.0, 0.0, 0.01), 0.0);
        // inside a band 10× the error: the clamp is linear, variance (σ/b)²
        let v = sign_variance(0.0, 0.1, 0.01);
        assert!((v / 0.01 - 1.0).abs() < 0.02, "{v}");
    }

    /// A logger glitch (1e300, or a value 1000 times the column's range) is left out with its
    /// line; an impact spike ten times the range is kept; glitches in over 1 % of the rows refuse
    /// the log with the first lines named.
    #[test]
    fn glitched_cells_are_dropped_by_line_and_impacts_kept() {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let q: Vec<f64> = t.iter().map(|&x| (3.0 * x).sin()).collect();
        let mut tau: Vec<f64> = t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect();
        tau[100] = 1e300;
        tau[700] = 800.0;
        tau[1200] = 9.0; // an impact: 9 N·m against a ±0.5 N·m range
        let log = JointLog { tau: Some(tau.clone()), u: Some(vec![0.0; n]), ..log_of(t.clone(), q.clone()) };
        let p = prepare(&log).unwrap();
        assert_eq!(p.report.glitches_dropped, 2);
        assert_eq!(p.report.glitch_lines, vec![102, 702]);
        assert_eq!(p.log.len(), n - 2);
        assert!(p.log.tau.as_ref().unwrap().contains(&9.0));
        assert!(p.report.notes.iter().any(|s| s.contains("line 102, column `tau`: 1e300")), "{:?}", p.report.notes);
        for i in (0..n).step_by(40) {
            tau[i] = -1e12;
        }
        let e = prepare(&JointLog { tau: Some(tau), u: Some(vec![0.0; n]), ..log_of(t, q) }).unwrap_err();
        assert!(e.to_string().contains("line 2, column `tau`: -1e12"), "{e}");
    }

    /// The log handed over gives what the borrowed log gives, whether rows are dropped for a
    /// glitch, as stale, both or neither (each a different path to the prepared log's columns).
    #[test]
    fn a_log_handed_over_prepares_as_a_borrowed_one() {
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let q: Vec<f64> = t.iter().map(|&x| (3.0 * x).sin()).collect();
        let u: Vec<f64> = t.iter().map(|&x| 0.5 * (3.0 * x).cos()).collect();
        let clean = JointLog { u: Some(u), tau: Some(vec![0.1; n]), ..log_of(t, q) };
        let glitch = |mut l: JointLog| {
            if let Some(u) = l.u.as_mut() {
                u[700] = 1e300;
            }
            l
        };
        let stale = |mut l: JointLog| {
            l.q[1500] = l.q[1499];
            if let Some(u) = l.u.as_mut() {
                u[1500] = u[1499];
            }
            l
        };
        for (what, log) in [
            ("clean", clean.clone()),
            ("glitch", glitch(clean.clone())),
            ("stale", stale(clean.clone())),
            ("both", stale(glitch(clean))),
        ] {
            let a = prepare(&log).unwrap();
            let b = prepare_owned(log).unwrap();
            assert_eq!(a.log, b.log, "{what}");
            assert_eq!(a.report, b.report, "{what}");
            assert_eq!((a.qd_err, a.qdd_err, a.rest), (b.qd_err, b.qdd_err, b.rest), "{what}");
        }
    }

    #[test]
    fn stale_rows_are_dropped_and_gaps_split() {
        let mut t: Vec<f64> = (0..400).map(|i| i as f64 * 1e-3).collect();
        for x in t.iter_mut().skip(200) {
            *x += 2.0;
        }
        let mut q: Vec<f64> = t.iter().map(|t| (2.0 * t).sin()).collect();
        let mut u = q.clone();
        q[50] = q[49];
        u[50] = u[49];
        let log = JointLog { u: Some(u), tau: Some(vec![0.0; 400]), ..log_of(t, q) };
        let p = prepare(&log).unwrap();
        assert_eq!(p.report.stale_dropped, 1);
        assert_eq!(p.segments.len(), 2);
        assert_eq!(p.report.samples, 399);
    }

    /// A pendulum that swings and settles, its angle quantised and its q̇ logged clean: at
    /// rest every row repeats the one before (q̇ exactly 0, the same count, the same held
    /// input). That is a still joint, not a logger that missed samples: nothing is dropped and
    /// the log stays one stretch. A repeat of a moving joint's row is still dropped.
    #[test]
    fn a_still_joint_with_a_logged_zero_velocity_is_no_stale_row() {
        let n = 2000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let step = 0.0015;
        let swing = |t: f64| 0.3 * (-3.0 * t).exp() * (12.0 * t).cos();
        let q: Vec<f64> = t
            .iter()
            .map(|&t| if t < 1.0 { (swing(t) / step).round() * step } else { (swing(1.0) / step).round() * step })
            .collect();
        let mut qd: Vec<f64> = t
            .iter()
            .map(|&t| if t < 1.0 { -3.0 * swing(t) - 3.6 * (-3.0 * t).exp() * (12.0 * t).sin() } else { 0.0 })
            .collect();
        let u = vec![0.5; n];
        let p =
            prepare(&JointLog { qd: Some(qd.clone()), u: Some(u.clone()), ..log_of(t.clone(), q.clone()) }).unwrap();
        assert_eq!(p.report.stale_dropped, 0);
        assert_eq!(p.segments.len(), 1);
        // a moving row repeated (a missed sample) is stale
        let (mut q2, k) = (q.clone(), 400);
        q2[k] = q2[k - 1];
        qd[k] = qd[k - 1];
        let p = prepare(&JointLog { qd: Some(qd), u: Some(u), ..log_of(t, q2) }).unwrap();
        assert_eq!(p.report.stale_dropped, 1);
    }

    #[test]
    fn time_in_milliseconds_is_refused() {
        let t: Vec<f64> = (0..500).map(|i| i as f64).collect();
        let q: Vec<f64> = t.iter().map(|t| (0.002 * t).sin()).collect();
        let e = prepare(&log_of(t, q)).unwrap_err();
        assert!(e.to_string().contains("milliseconds"), "{e}");
    }

    #[test]
    fn a_logged_qd_in_degrees_is_refused_naming_the_factor() {
        let t: Vec<f64> = (0..3000).map(|i| i as f64 * 1e-3).collect();
        let q: Vec<f64> = t.iter().map(|t| (2.0 * t).sin()).collect();
        let qd: Vec<f64> = t.iter().map(|t| 2.0 * (2.0 * t).cos() * 180.0 / std::f64::consts::PI).collect();
        let e = prepare(&JointLog { qd: Some(qd), ..log_of(t, q) }).unwrap_err();
        assert!(e.to_string().contains("57.29") && e.to_string().contains("degrees"), "{e}");
    }

    /// Gaussian noise from a seeded generator (Box–Muller), for the tests below.
    fn gauss_noise(n: usize, seed: u64) -> Vec<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random::<f64>());
                (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
            })
            .collect()
    }

    #[test]
    fn a_velocity_late_by_less_than_a_sample_is_measured_and_an_exact_one_is_not() {
        // a chirp-like motion at 200 Hz; the logged q̇ is the true one 1.5 ms late, or on time,
        // each with white noise of 1e-3 rad/s, against an estimate with 2e-3 rad/s of its own
        let dt = 0.005;
        let n = 4000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let v = |t: f64| (3.0 * t + 0.2 * t * t).sin();
        let a = |t: f64| (3.0 + 0.4 * t) * (3.0 * t + 0.2 * t * t).cos();
        let (w1, w2) = (gauss_noise(n, 1), gauss_noise(n, 2));
        let est: Vec<f64> = t.iter().zip(&w2).map(|(t, w)| v(*t) + 2e-3 * w).collect();
        let acc: Vec<f64> = t.iter().map(|t| a(*t)).collect();
        let late: Vec<f64> = t.iter().zip(&w1).map(|(t, w)| v(t - 1.5e-3) + 1e-3 * w).collect();
        let (tau, err) = sub_sample_lag(&late, &est, &acc, 9).expect("the lag");
        assert!((tau / 1.5e-3 - 1.0).abs() < 0.1, "τ {tau}");
        let rms_a = (acc.iter().map(|a| a * a).sum::<f64>() / n as f64).sqrt();
        assert!((err / (tau * rms_a) - 1.0).abs() < 1e-9);
        let on_time: Vec<f64> = t.iter().zip(&w1).map(|(t, w)| v(*t) + 1e-3 * w).collect();
        assert_eq!(sub_sample_lag(&on_time, &est, &acc, 9), None);
    }

    #[test]
    fn a_column_whose_noise_rises_towards_low_frequencies_says_so() {
        // a slow motion at 500 Hz with white noise, or with an AR(1) noise of ρ = 0.9 of the same
        // size: the white one reads at its size and plain; the coloured one coloured, read above
        // its top quarter's level (0.23× its size) and at most its size
        let dt = 0.002;
        let n = 20_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let motion: Vec<f64> = t.iter().map(|t| 0.5 * (0.7 * t).sin()).collect();
        let w = gauss_noise(n, 3);
        let seg = std::iter::once(0..n).collect::<Vec<_>>();
        let white: Vec<f64> = motion.iter().zip(&w).map(|(m, w)| m + 1e-3 * w).collect();
        let (sd, coloured) = own_noise(&t, &white, &seg, dt);
        assert!(!coloured && (sd / 1e-3 - 1.0).abs() < 0.1, "{sd} {coloured}");
        let rho: f64 = 0.9;
        let mut e = 0.0;
        let ar: Vec<f64> = w
            .iter()
            .map(|w| {
                e = rho * e + (1.0 - rho * rho).sqrt() * 1e-3 * w;
                e
            })
            .collect();
        let col: Vec<f64> = motion.iter().zip(&ar).map(|(m, e)| m + e).collect();
        let (sd, coloured) = own_noise(&t, &col, &seg, dt);
        assert!(coloured && sd > 0.4e-3 && sd < 1.1e-3, "{sd} {coloured}");
    }

    /// q̈'s stated error against its actual error on samples `lo..hi` of a prepared log whose
    /// true acceleration is `acc`: (RMS of the stated, RMS of the actual).
    fn qdd_error_against_truth(p: &Prepared, acc: &[f64], lo: usize, hi: usize) -> (f64, f64) {
        let qdd = p.log.qdd.as_ref().unwrap();
        let k = (hi - lo) as f64;
        let stated = ((lo..hi).map(|i| p.qdd_err[i] * p.qdd_err[i]).sum::<f64>() / k).sqrt();
        let actual = ((lo..hi).map(|i| (qdd[i] - acc[i]).powi(2)).sum::<f64>() / k).sqrt();
        (stated, actual)
    }

    #[test]
    fn the_noise_on_q_alone_is_no_local_bias_of_the_acceleration() {
        // a log chirp 0.11 → 0.63 Hz, ±0.11 rad at 1.1 kHz, white noise of 6e-5 rad on q (the
        // motion of seen u9101/0088): the squared difference between q̈ and its half-window twin,
        // averaged over a window, scatters by 0.6 × its noise; read as noise-free, the windows
        // the noise pushed up stated q̈'s error at 2.8 × its size (0.020 against 0.0071 rad/s²),
        // and the floor of a joint of 29.5 kg·m² at 0.60 N·m against the 0.21 its q̈ left
        let (rate, dur) = (1118.1, 18.8);
        let n = (rate * dur) as usize;
        let (f0, f1, amp) = (0.1142f64, 0.6331f64, 0.111);
        let k = (f1 / f0).ln() / dur;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let w = gauss_noise(n, 88);
        let q: Vec<f64> = t
            .iter()
            .zip(&w)
            .map(|(&t, w)| amp * (std::f64::consts::TAU * f0 * ((k * t).exp() - 1.0) / k).sin() + 6e-5 * w)
            .collect();
        let acc: Vec<f64> = t
            .iter()
            .map(|&t| {
                let ph = std::f64::consts::TAU * f0 * ((k * t).exp() - 1.0) / k;
                let om = std::f64::consts::TAU * f0 * (k * t).exp();
                -amp * ph.sin() * om * om + amp * ph.cos() * k * om
            })
            .collect();
        let p = prepare(&log_of(t, q)).unwrap();
        let (stated, actual) = qdd_error_against_truth(&p, &acc, 300, n - 300);
        assert!(stated < 1.5 * actual && stated > 0.8 * actual, "stated {stated:.3e}, actual {actual:.3e}");
    }

    #[test]
    fn a_reversal_at_speed_still_states_its_acceleration_s_bias() {
        // a joint swinging through a sharp reversal every 2 s (q = 0.2·√((t − t_k)² + 0.04²)
        // around each, q̈ peaking at 5 rad/s² over ±40 ms) at 1 kHz, white noise of 5e-5 rad:
        // a window chosen for the smooth stretches straddles each reversal, and its bias there is
        // many times its noise; the stated error must cover it
        let (rate, n) = (1000.0, 12_000);
        let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let eps: f64 = 0.04;
        // the nearest reversal at 1, 3, 5, … s; q alternates between hyperbolas, continuous
        let shape = |t: f64| {
            let c = 2.0 * ((t - 1.0) / 2.0).round() + 1.0;
            let x = t - c;
            let s = if ((c - 1.0) / 2.0).rem_euclid(2.0) < 0.5 { 1.0 } else { -1.0 };
            let r = (x * x + eps * eps).sqrt();
            (s * 0.2 * r, s * 0.2 * eps * eps / (r * r * r))
        };
        let w = gauss_noise(n, 5);
        let q: Vec<f64> = t.iter().zip(&w).map(|(&t, w)| shape(t).0 + 5e-5 * w).collect();
        let acc: Vec<f64> = t.iter().map(|&t| shape(t).1).collect();
        let p = prepare(&log_of(t, q)).unwrap();
        let qdd = p.log.qdd.as_ref().unwrap();
        let base = p.report.qdd.error_sd;
        // the samples whose estimate is off by more than 3 × the log's typical error
        let off: Vec<usize> = (300..n - 300).filter(|&i| (qdd[i] - acc[i]).abs() > 3.0 * base).collect();
        assert!(off.len() > 50, "{} samples far off (typical error {base:.3e})", off.len());
        let covered = off.iter().filter(|&&i| p.qdd_err[i] >= 0.5 * (qdd[i] - acc[i]).abs()).count();
        assert!(covered * 10 >= off.len() * 8, "{covered} of {} covered", off.len());
    }

    #[test]
    fn a_fast_move_on_a_coarse_encoder_keeps_its_acceleration_unshrunk() {
        // a log chirp 0.14 → 1.8 Hz, ±0.1 rad, on a 12-bit encoder at 1.3 kHz (null seed 4242
        // case 96): the window q̈ needs (about 0.1 s each side) shrinks the fast end by 9 %
        // with the cubic alone; a fit read that as a 5 % larger inertia
        let (rate, dur) = (1334.7, 13.77);
        let n = (rate * dur) as usize;
        let step = std::f64::consts::TAU / 4096.0;
        let (f0, f1) = (0.14f64, 1.83f64);
        let k = (f1 / f0).ln() / dur;
        let phase = |t: f64| std::f64::consts::TAU * f0 * ((k * t).exp() - 1.0) / k;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let q: Vec<f64> = t.iter().map(|&t| (0.1 * phase(t).sin() / step).round() * step).collect();
        // the true q̈ by central differences of the noise-free angle (h = 1e-4 s)
        let exact = |t: f64| 0.1 * phase(t).sin();
        let truth: Vec<f64> = t.iter().map(|&t| (exact(t + 1e-4) - 2.0 * exact(t) + exact(t - 1e-4)) / 1e-8).collect();
        // (torques that change every row: repeated rows would be stale ones)
        let u: Vec<f64> = (0..n).map(|i| 1e-3 * i as f64).collect();
        let p = prepare(&JointLog { u: Some(u), tau: Some(vec![0.0; n]), ..log_of(t, q) }).unwrap();
        assert_eq!(p.log.len(), n);
        let est = p.qdd();
        // the shrink as a regression slope over the fast last third, away from the ends
        let (lo, hi) = (2 * n / 3, n - n / 20);
        let (mut xy, mut xx) = (0.0, 0.0);
        for i in lo..hi {
            xy += est[i] * truth[i];
            xx += truth[i] * truth[i];
        }
        let slope = xy / xx;
        assert!((slope - 1.0).abs() < 0.02, "q̈ estimate over the fast end is {slope:.4} × the true one");
    }
}
