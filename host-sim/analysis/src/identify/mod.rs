//! Identification: from logged characterisation tests to the model TOML the joint runs.
//!
//! The procedures are the papers': friction from constant-velocity plateaus (trunk paper §3.2,
//! [`friction`]), the weight from static poses (§3.3, [`weight`]), inertia and offset from
//! moving samples with friction and weight known (§3.4, [`inertia`]), the elastic joint's
//! spring from the static torque–angle slope and its inertia and damping from the free
//! oscillation (elastic-joint paper, [`spring`]). Segments are found from the data
//! ([`segments`]). Friction comes first, then the weight, then the inertia; a second round
//! repeats friction and weight with `J·q̈` taken off the plateaus and poses, which removes
//! the bias of plateaus whose velocity still drifts.
//!
//! [`identify`] returns the fitted terms and the [`ModelFile`] to write; [`report`] scores a
//! refit on held-out blocks of the data and draws the plots.

#![allow(clippy::indexing_slicing)] // numerical kernels: every index is bounded by the loop range or a length checked just before

pub mod decide;
pub mod filter;
pub mod friction;
pub mod gravity_table;
pub mod inertia;
pub mod joint_ls;
mod judge;
pub mod nls;
pub mod report;
pub mod robust;
pub mod segments;
pub mod spring;
pub mod status;
pub mod weight;

use joint_core::params::ParamId;

use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use judge::{
    acc_excitation, friction_status, friction_weight_known, inertia_status, offset_papers, spring_status,
    weight_status, FRICTION_KEYS,
};
use segments::{Prepared, SegKind, Segment, SegmentCfg, Window};
use status::{ParamStatus, Status};

/// A model term identification can produce.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Term {
    Friction,
    Weight,
    Inertia,
    Offset,
    Spring,
    GravityTable,
}

impl Term {
    pub fn parse_list(s: &str) -> Result<Vec<Term>, String> {
        let mut v = Vec::new();
        for p in s.split(',') {
            let t = match p.trim() {
                "friction" => Term::Friction,
                "weight" => Term::Weight,
                "inertia" => Term::Inertia,
                "offset" => Term::Offset,
                "spring" => Term::Spring,
                "gravity_table" => Term::GravityTable,
                other => {
                    return Err(format!(
                        "unknown term `{other}` (known: friction, weight, inertia, offset, spring, gravity_table)"
                    ))
                }
            };
            if !v.contains(&t) {
                v.push(t);
            }
        }
        Ok(v)
    }
}

/// The rigid joint's terms (torque mode), found by the papers' procedures or the regression.
pub const RIGID_TERMS: [Term; 4] = [Term::Friction, Term::Weight, Term::Inertia, Term::Offset];

/// How the rigid-joint terms are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// the papers' procedures where the log holds their tests (± constant-velocity plateaus,
    /// static poses, a free oscillation), the whole-log regression where it holds none
    #[default]
    Auto,
    /// the papers' procedures: friction from plateaus, weight from poses, inertia and offset
    /// from motion with both known
    Papers,
    /// one least-squares fit of all rigid terms on every sample (for logs without plateaus or
    /// poses, e.g. a swing-up run); the weight's s is fixed at 1
    JointLs,
}

impl Method {
    /// Every method with its name (as in the JSON) and a line saying what it does.
    pub const NAMES: [(&'static str, Method, &'static str); 3] = [
        (
            "auto",
            Method::Auto,
            "the papers' procedures where the log holds their tests (plateaus, poses, a free oscillation), the whole-log regression (joint-ls) where it holds none; the choice and its reason are reported",
        ),
        (
            "papers",
            Method::Papers,
            "the papers' procedures: friction from plateaus, weight from poses, inertia and offset from motion with both known",
        ),
        (
            "joint-ls",
            Method::JointLs,
            "one least-squares fit of all rigid terms on every sample (for logs without plateaus or poses, e.g. a swing-up run); the weight's s is fixed at 1",
        ),
    ];

    pub fn name(self) -> &'static str {
        Method::NAMES.iter().find(|(_, m, _)| *m == self).map_or("?", |(n, _, _)| n)
    }
}

/// Settings of a run.
#[derive(Clone, Debug)]
pub struct Options {
    pub method: Method,
    /// terms to identify (empty: friction, weight, inertia, offset for torque-mode logs,
    /// spring for trajectory-only logs)
    pub terms: Vec<Term>,
    pub windows: Vec<Window>,
    pub segments: SegmentCfg,
    /// zero-phase low-pass of the inertia fit, Hz
    pub accel_cutoff: f64,
    /// friction sign band written to the model (and used to remove the creep's friction), rad/s
    pub v_band: f64,
    /// |q̇| below which samples are left out of the inertia fit, rad/s
    pub v_min_inertia: f64,
    pub name: Option<String>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Auto,
            terms: Vec::new(),
            windows: Vec::new(),
            segments: SegmentCfg::default(),
            accel_cutoff: 5.0,
            // The f32 default as its shortest decimal (0.01, not 0.009999999776…).
            v_band: format!("{}", ParamId::FrictionVBand.desc().default).parse().unwrap_or(0.01),
            v_min_inertia: 0.05,
            name: None,
        }
    }
}

/// Why identification could not produce a model.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IdentifyError {
    #[error("no log given")]
    NoLog,
    #[error("{term}: {msg}")]
    Term { term: &'static str, msg: String },
    #[error("the identified model is not a valid parameter set: {0}")]
    Invalid(String),
    /// the shared preparation stage refused a log (units, rate, too few samples)
    #[error("log {log}: {msg}")]
    Prep { log: usize, msg: String },
}

fn term_err(term: &'static str, msg: impl Into<String>) -> IdentifyError {
    IdentifyError::Term { term, msg: msg.into() }
}

/// Spring results: static slope, free oscillation, and the resulting J and B.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SpringResult {
    pub stat: Option<spring::StaticSpring>,
    pub free: Option<spring::FreeFit>,
    pub k: Option<f64>,
    pub j: Option<f64>,
    pub b: Option<f64>,
}

/// Everything a run found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Identified {
    pub terms: Vec<Term>,
    /// the method that ran (`auto` resolved to `papers` or `joint-ls`) and why
    pub method: Method,
    pub method_why: String,
    pub friction: Option<friction::FrictionFit>,
    pub weight: Option<weight::WeightFit>,
    pub poses: Vec<weight::Pose>,
    pub inertia: Option<inertia::InertiaFit>,
    /// the whole-log regression, when it ran
    pub joint_ls: Option<inertia::JointLsFit>,
    pub spring: Option<SpringResult>,
    pub table: Option<gravity_table::TableFit>,
    /// fusion clamp k written with a table that has σ_m
    pub table_clamp_k: f64,
    /// the offset C_0 found (written when determined)
    pub c0: Option<f64>,
    pub v_band: f64,
    /// every parameter with its CI and status; only the determined ones are written
    pub status: Vec<status::ParamStatus>,
    /// segments found per log
    pub segments: Vec<Vec<Segment>>,
    /// what the shared preparation stage did to each log (the smoother, its windows, stale
    /// rows, gaps)
    pub preparation: Vec<crate::prep::PrepReport>,
    pub notes: Vec<String>,
}

impl Identified {
    /// The status of `term.param`, if identification judged it.
    pub fn status_of(&self, term: &str, param: &str) -> Option<&status::ParamStatus> {
        self.status.iter().find(|p| p.term == term && p.param == param)
    }

    /// True when `term.param` is determined (and so written).
    pub fn determined(&self, term: &str, param: &str) -> bool {
        self.status_of(term, param).is_some_and(|p| p.determined())
    }
}

/// Progress events for a front end (the CLI draws a bar from them).
pub trait Progress {
    fn stage(&self, _msg: &str, _done: u64, _total: u64) {}
}

/// No progress output.
pub struct Quiet;
impl Progress for Quiet {}

#[derive(Debug)]
/// The logs prepared and segmented once, shared by the full fit and the hold-out refit.
pub struct Data {
    pub prepared: Vec<Prepared>,
    pub segments: Vec<Vec<Segment>>,
}

impl Data {
    /// Prepares and segments every log; a log the preparation stage refuses (units, rate) is
    /// refused here with its reason.
    pub fn new(logs: &[JointLog], opts: &Options) -> Result<Data, IdentifyError> {
        let mut prepared = Vec::with_capacity(logs.len());
        for (li, l) in logs.iter().enumerate() {
            let p = Prepared::new(l, &opts.segments)
                .map_err(|e| IdentifyError::Prep { log: li + 1, msg: e.to_string() })?;
            prepared.push(p);
        }
        let segments = prepared.iter().map(|p| segments::find(p, &opts.segments, &opts.windows)).collect();
        Ok(Data { prepared, segments })
    }

    /// Each prepared log with its segments.
    pub fn pairs(&self) -> Vec<(&Prepared, &[Segment])> {
        self.prepared.iter().zip(&self.segments).map(|(p, s)| (p, s.as_slice())).collect()
    }

    pub fn has_torque(&self) -> bool {
        self.prepared.iter().any(|p| p.d.is_some())
    }
}

/// Fusion clamp written with an identified table: the fused gravity stays within
/// τ_model ± 3·σ_m. σ_m is a mean absolute residual, not a bound, so the arm paper's k = 1
/// would clip corrections the data support; 3 keeps the clamp a guard against a wrong table.
pub const TABLE_CLAMP_K: f64 = 3.0;

/// Smoothed sign as the core computes it (`clamp(v/band, −1, 1)`; sign(0) = 0 without a band):
/// the core's own rule in f64, the one the diagnosis and the plant use too.
pub use joint_core::math::sign_smooth_f64 as sign_band;

/// Friction torque of a fitted curve at a signed velocity, as the model evaluates it.
pub fn friction_torque(f: &friction::FrictionFit, v: f64, band: f64) -> f64 {
    f.a * v * v.abs() + f.b * v + f.c * sign_band(v, band)
}

/// Identifies the terms from all logs. `keep(log, t)` selects the data a fit may use (the
/// full run keeps everything; the report's refit keeps the training blocks).
///
/// A term the log holds no test for is not an error: it gets the status `not excited` with the
/// test that would pin it, and is not written. Errors are left for what no log could fix here:
/// no log, torque terms asked of a log without torque, a log the preparation refuses.
pub fn identify_data(
    data: &Data,
    opts: &Options,
    keep: &dyn Fn(usize, f64) -> bool,
    progress: &dyn Progress,
) -> Result<Identified, IdentifyError> {
    if data.prepared.is_empty() {
        return Err(IdentifyError::NoLog);
    }
    let terms = if opts.terms.is_empty() {
        if data.has_torque() {
            vec![Term::Friction, Term::Weight, Term::Inertia, Term::Offset]
        } else {
            vec![Term::Spring]
        }
    } else {
        opts.terms.clone()
    };
    let rigid = terms.iter().any(|t| RIGID_TERMS.contains(t));
    if rigid && !data.has_torque() {
        return Err(term_err("friction/weight/inertia/offset", "need a torque-mode log (columns u and tau)"));
    }
    // Segments filtered by `keep` (by their start time).
    let kept: Vec<Vec<Segment>> = data
        .prepared
        .iter()
        .zip(&data.segments)
        .enumerate()
        .map(|(li, (p, segs))| segs.iter().filter(|s| keep(li, p.t[s.start])).copied().collect())
        .collect();
    let kept_pairs: Vec<(&Prepared, &[Segment])> =
        data.prepared.iter().zip(&kept).map(|(p, s)| (p, s.as_slice())).collect();
    let mut out = Identified {
        terms: terms.clone(),
        method: Method::Papers,
        method_why: String::new(),
        friction: None,
        weight: None,
        poses: Vec::new(),
        inertia: None,
        joint_ls: None,
        spring: None,
        table: None,
        table_clamp_k: TABLE_CLAMP_K,
        c0: None,
        v_band: opts.v_band,
        status: Vec::new(),
        segments: data.segments.clone(),
        preparation: data.prepared.iter().map(|p| p.prep.clone()).collect(),
        notes: Vec::new(),
    };
    let total = 2 + u64::from(terms.contains(&Term::Spring));
    if rigid {
        let (method, why) = resolve_method(opts, &terms, &kept_pairs);
        out.method = method;
        out.method_why = why;
        match method {
            Method::JointLs => joint_ls_terms(data, opts, keep, &mut out)?,
            _ => papers_terms(data, &kept_pairs, opts, keep, progress, &mut out),
        }
        // `auto` took the papers' tests, and they pinned nothing: the regression may still.
        if opts.method == Method::Auto && method == Method::Papers && !out.status.iter().any(|p| p.determined()) {
            // The Coulomb level's reason says most (it is the coefficient every friction has).
            let mut found: Vec<&ParamStatus> = out.status.iter().collect();
            found.sort_by_key(|p| !(p.term == "friction" && p.param == "c"));
            let found: Vec<String> = found.iter().map(|p| format!("{}: {}", p.name(), p.why)).collect();
            out.status.clear();
            out.friction = None;
            out.weight = None;
            out.inertia = None;
            out.c0 = None;
            out.poses.clear();
            out.method = Method::JointLs;
            out.method_why = format!(
                "the papers' tests in this log determine nothing ({}): the whole-log regression (joint-ls) instead",
                found.first().map_or("", String::as_str)
            );
            joint_ls_terms(data, opts, keep, &mut out)?;
        }
    } else {
        out.method_why = "the papers' procedures (elastic joint: static slope and free oscillation)".into();
    }
    if terms.contains(&Term::GravityTable) {
        table_term(data, &kept_pairs, &mut out);
    }
    if terms.contains(&Term::Spring) {
        progress.stage("spring", 2, total);
        spring_terms(data, &kept_pairs, opts, &mut out);
    }
    progress.stage("done", total, total);
    Ok(out)
}

/// Static poses needed for the weight fit (one more than its unknowns).
fn poses_needed(terms: &[Term]) -> usize {
    if terms.contains(&Term::Offset) {
        5
    } else {
        4
    }
}

/// `auto` → the papers' procedures when the log holds the tests of the friction and weight
/// asked for (at least one of them: the missing one is then `not excited`), the whole-log
/// regression when it holds neither. A forced method is taken as it is.
fn resolve_method(opts: &Options, terms: &[Term], pairs: &[(&Prepared, &[Segment])]) -> (Method, String) {
    let strict = (opts.segments.a_strict, opts.segments.a_strict_rel);
    let want_f = terms.contains(&Term::Friction);
    let want_w = terms.contains(&Term::Weight);
    let points = if want_f { friction::points(pairs, None, strict).len() } else { 0 };
    let poses = if want_w { weight::poses(pairs, &|_| 0.0).len() } else { 0 };
    let need = poses_needed(terms);
    let (f_ok, w_ok) = (points >= 4, poses >= need);
    let found = format!(
        "{points} friction points from matched ± constant-velocity plateaus (4 needed), {poses} static poses ({need} needed)"
    );
    match opts.method {
        Method::JointLs => {
            (Method::JointLs, "asked for (--method joint-ls): one least-squares fit on every sample".into())
        }
        Method::Papers => (Method::Papers, format!("asked for (--method papers); the log holds {found}")),
        Method::Auto => {
            let any_test = (want_f && f_ok) || (want_w && w_ok);
            let all_tests = (!want_f || f_ok) && (!want_w || w_ok);
            if all_tests && (want_f || want_w) || any_test {
                let mut why = format!("the log holds the papers' tests: {found}");
                if !all_tests {
                    why.push_str(
                        "; the term without its test is not identified (`--method joint-ls` fits every term from the \
                         whole log instead, as well as the log's motion allows)",
                    );
                }
                (Method::Papers, why)
            } else if !want_f && !want_w {
                (Method::Papers, "inertia and offset from motion (trunk §3.4)".into())
            } else {
                (
                    Method::JointLs,
                    format!(
                        "no test of the papers' procedures in the log ({found}): the whole-log regression (joint-ls)"
                    ),
                )
            }
        }
    }
}

/// The papers' procedures: friction (§3.2), weight (§3.3), inertia and offset (§3.4), then a
/// second round with `J·q̈` taken off the plateaus and poses. Every term gets its status.
fn papers_terms(
    data: &Data,
    kept_pairs: &[(&Prepared, &[Segment])],
    opts: &Options,
    keep: &dyn Fn(usize, f64) -> bool,
    progress: &dyn Progress,
    out: &mut Identified,
) {
    let terms = out.terms.clone();
    let has = |t: Term| terms.contains(&t);
    let band = opts.v_band;
    let pairs = data.pairs();
    let total = 2 + u64::from(has(Term::Spring));
    let mut inertia_acc: Option<(Vec<Vec<f64>>, f64)> = None;
    let mut f_status = Vec::new();
    let mut inertia_data = None;
    for round in 0..2u64 {
        progress.stage(
            if round == 0 { "friction, weight, inertia" } else { "second round (J·q̈ removed)" },
            round,
            total,
        );
        if has(Term::Friction) {
            let accel = inertia_acc.as_ref().map(|(a, j)| (a.as_slice(), *j));
            let pts = friction::points(kept_pairs, accel, (opts.segments.a_strict, opts.segments.a_strict_rel));
            out.friction = friction::fit(&pts);
            f_status = friction_status(out.friction.as_ref(), pts.len());
        }
        let fr = out.friction.clone();
        let ffun = |v: f64| fr.as_ref().map_or(0.0, |f| friction_torque(f, v, band));
        if has(Term::Weight) || (has(Term::Offset) && !has(Term::Inertia)) {
            let mut poses = weight::poses(kept_pairs, &ffun);
            if let Some((acc, j)) = &inertia_acc {
                // Take J·q̈ off too (a pose still settling accelerates a little).
                for pose in &mut poses {
                    let (p, segs) = kept_pairs[pose.log];
                    if let Some(s) = segs.iter().find(|s| s.kind == SegKind::Static && p.t[s.start] == pose.t) {
                        let m = acc[pose.log][s.start..s.end].iter().sum::<f64>() / s.len() as f64;
                        pose.d -= j * m;
                    }
                }
            }
            if has(Term::Weight) {
                out.weight = weight::fit(&poses, has(Term::Offset));
            } else if !poses.is_empty() {
                out.c0 = Some(poses.iter().map(|p| p.d).sum::<f64>() / poses.len() as f64);
            }
            out.poses = poses;
        }
        // §3.4 subtracts friction and weight: without them (asked for, not found) J would
        // absorb their torque.
        let known = friction_weight_known(out, &terms);
        if has(Term::Inertia) && known {
            let w = out.weight.clone();
            let c0s = out.c0.unwrap_or(0.0);
            let model = |q: f64, v: f64| ffun(v) + w.as_ref().map_or(c0s, |w| w.curve(q));
            let dat = inertia::data(&pairs, &model, opts.accel_cutoff, opts.v_min_inertia);
            let fs = data.prepared.first().map_or(1000.0, |p| p.fs);
            let keep_i = |li: usize, i: usize| keep(li, data.prepared[li].t[i]);
            out.inertia = inertia::fit(&dat, fs, opts.accel_cutoff, &keep_i);
            if let Some(fit) = out.inertia.as_ref().filter(|f| f.j > 0.0) {
                inertia_acc = Some((dat.acc.clone(), fit.j));
            }
            inertia_data = Some(dat);
        }
        if !(has(Term::Inertia) && has(Term::Friction) && inertia_acc.is_some()) {
            break;
        }
    }
    if has(Term::Friction) {
        out.status.extend(f_status);
    }
    if has(Term::Weight) {
        let st = weight_status(out.weight.as_ref(), &out.poses, poses_needed(&terms));
        out.status.extend(st);
    }
    if has(Term::Inertia) {
        let known = friction_weight_known(out, &terms);
        let exc = inertia_data.as_ref().map(|d| acc_excitation(data, d, opts.accel_cutoff, keep));
        out.status.push(inertia_status(out.inertia.as_ref(), known, exc));
    }
    if has(Term::Offset) {
        let (c0, s) = offset_papers(out, has(Term::Inertia));
        out.c0 = c0;
        out.status.push(s);
    }
}

/// The whole-log regression and its statuses (the determined terms keep the full fit's values).
fn joint_ls_terms(
    data: &Data,
    opts: &Options,
    keep: &dyn Fn(usize, f64) -> bool,
    out: &mut Identified,
) -> Result<(), IdentifyError> {
    let logs: Vec<&Prepared> = data.prepared.iter().collect();
    let keep_i = |li: usize, i: usize| keep(li, data.prepared[li].t[i]);
    let f = inertia::joint_ls(&logs, opts.v_band, opts.accel_cutoff, &keep_i)
        .ok_or_else(|| term_err("joint-ls", "too few torque-mode samples (or a singular regression)"))?;
    let fs = data.prepared[0].fs;
    out.status.extend(joint_ls::statuses(&f, fs, &out.terms));
    out.notes.extend(joint_ls::ratio_note(&f));
    let has = |t: Term| out.terms.contains(&t);
    let ci = |k: usize, v: f64| joint_ls::ci(&f, fs, k, v);
    if has(Term::Friction) {
        out.friction = Some(friction::FrictionFit {
            a: f.a,
            b: f.b,
            c: f.c,
            se: [f.se[1], f.se[2], f.se[3]],
            ci95: [ci(1, f.a), ci(2, f.b), ci(3, f.c)],
            sigma: f.rms,
            points: Vec::new(),
            weights: Vec::new(),
            free: [f.free[1], f.free[2], f.free[3]],
            negative: [f.negative[1], f.negative[2], f.negative[3]],
            cov: [1, 2, 3].map(|i| [1, 2, 3].map(|j| f.cov[i][j])),
        });
    }
    if has(Term::Weight) {
        let (amp, phi, se_amp, se_phi) = joint_ls::amplitude_phase(&f);
        out.weight = Some(weight::WeightFit {
            amplitude: amp,
            s: 1.0,
            phi,
            c0: 0.0,
            fitted_offset: false,
            se: vec![se_amp, 0.0, se_phi],
            rms: f.rms,
            s_fixed: true,
        });
    }
    if has(Term::Inertia) {
        out.inertia = Some(inertia::InertiaFit {
            j: f.j,
            dc0: 0.0,
            se: [f.se[0], f.se[6]],
            ci95: [ci(0, f.j), ci(6, f.c0)],
            rms: f.rms,
            n: f.n,
            cutoff_hz: f.cutoff_hz,
        });
    }
    if has(Term::Offset) {
        out.c0 = Some(f.c0);
    }
    out.notes.push(format!(
        "joint least squares on {} filtered samples ({} Hz): RMS {:.4} N·m, r² {:.4}",
        f.n, f.cutoff_hz, f.rms, f.r2
    ));
    out.joint_ls = Some(f);
    Ok(())
}

fn ffun_none(_: f64) -> f64 {
    0.0
}

/// The gravity table over q and the other joints' angles from static samples.
fn table_term(data: &Data, kept_pairs: &[(&Prepared, &[Segment])], out: &mut Identified) {
    let fr = out.friction.clone();
    let band = out.v_band;
    let c0 = out.c0.unwrap_or(0.0);
    let w = out.weight.clone();
    let st = |li: usize, i: usize| {
        let p = &data.prepared[li];
        let d = p.d.as_ref().map_or(0.0, |d| d[i]);
        d - fr.as_ref().map_or(0.0, |f| friction_torque(f, p.qd_f[i], band)) - c0
    };
    let model = |li: usize, i: usize| w.as_ref().map_or(0.0, |w| w.weight(data.prepared[li].q[i]));
    let m: Option<&dyn Fn(usize, usize) -> f64> = if out.weight.is_some() { Some(&model) } else { None };
    match gravity_table::fit(kept_pairs, &st, m) {
        Ok(fit) => {
            out.status.push(ParamStatus {
                term: "gravity_table",
                param: "torque",
                value: None,
                ci95: None,
                status: Status::Determined,
                why: format!(
                    "{} static samples, RMS {:.4} N·m, {} cells without data (filled smoothly)",
                    fit.samples, fit.rms, fit.empty_cells
                ),
                test: None,
            });
            out.table = Some(fit);
        }
        Err(e) => out.status.push(ParamStatus::not_excited("gravity_table", "torque", e, status::TEST_TABLE)),
    }
}

/// The elastic joint: K from static poses, J and B from the free oscillation with K.
fn spring_terms(data: &Data, kept_pairs: &[(&Prepared, &[Segment])], opts: &Options, out: &mut Identified) {
    let poses = weight::poses(kept_pairs, &ffun_none);
    let stat = spring::static_fit(&poses);
    // The free oscillation: trajectory-mode logs, or any log with a `free` window.
    let has_free_window = opts.windows.iter().any(|w| w.kind == SegKind::Free);
    let mut free = None;
    for (li, p) in data.prepared.iter().enumerate() {
        if p.d.is_some() && !has_free_window {
            continue;
        }
        if let Some(seg) = segments::free_segment(p, &opts.windows) {
            let (q0, w) = stat.as_ref().map_or((None, 0.0), |s| (Some(s.q0), s.dead_zone));
            free = spring::free_fit(p, li, &seg, q0, w);
            if free.is_some() {
                break;
            }
        }
    }
    let k = stat.as_ref().map(|s| s.k);
    let (j, b) = match (k, &free) {
        (Some(k), Some(f)) => {
            let j = k / f.k_over_j;
            (Some(j), Some(f.b_over_j * j))
        }
        _ => (None, None),
    };
    out.status.extend(spring_status(stat.as_ref(), free.as_ref(), poses.len(), j, b));
    if let Some(f) = &free {
        out.notes.push(format!(
            "free oscillation: ω_n = {:.4} rad/s, ζ = {:.4} (J = K/ω_n², B = 2ζω_n·J need K)",
            f.omega_n, f.zeta
        ));
    }
    out.spring = Some(SpringResult { stat, free, k, j, b });
    out.poses = poses;
}

/// The model file for the identified terms: only the determined parameters are written (a
/// missing key or section is a term the model does not have, spec §2).
pub fn model_file(id: &Identified, name: Option<&str>) -> Result<ModelFile, IdentifyError> {
    let mut mf = ModelFile::empty("(identified)");
    mf.name = name.map(str::to_string);
    let det = |t: &str, p: &str| id.determined(t, p);
    if let Some(f) = &id.friction {
        let ids = [ParamId::FrictionA, ParamId::FrictionB, ParamId::FrictionC];
        let mut any = false;
        for (k, (pid, v)) in ids.iter().zip([f.a, f.b, f.c]).enumerate() {
            if det("friction", FRICTION_KEYS[k]) {
                mf.set(*pid, v, None);
                any = true;
            }
        }
        if any {
            mf.set(ParamId::FrictionVBand, id.v_band, None);
        }
    }
    if let Some(w) = id.weight.as_ref().filter(|_| det("weight", "amplitude")) {
        mf.set(ParamId::WeightAmplitude, w.amplitude, None);
        mf.set(ParamId::WeightS, w.s, None);
        mf.set(ParamId::WeightPhi, w.phi, None);
    }
    if let Some(i) = id.inertia.as_ref().filter(|_| det("inertia", "j")) {
        mf.set(ParamId::InertiaJ, i.j, None);
    }
    if let Some(c0) = id.c0.filter(|_| det("offset", "c0")) {
        mf.set(ParamId::OffsetC0, c0, None);
    }
    if let Some(t) = id.table.as_ref().filter(|_| det("gravity_table", "torque")) {
        mf.table = Some(t.spec());
        match t.sigma_model {
            Some(sm) if sm > 0.0 => {
                mf.set(ParamId::TableSigmaModel, sm, None);
                mf.set(ParamId::TableClampK, id.table_clamp_k, None);
            }
            _ => mf.set(ParamId::TableSigmaModel, 0.0, None),
        }
    }
    if let Some(s) = &id.spring {
        if let Some(k) = s.k.filter(|_| det("spring", "k")) {
            mf.set(ParamId::SpringK, k, None);
            mf.set(ParamId::SpringQ0, s.stat.as_ref().map_or(0.0, |s| s.q0), None);
        }
        if let Some(b) = s.b.filter(|_| det("spring", "b")) {
            mf.set(ParamId::SpringB, b, None);
        }
        if let Some(j) = s.j.filter(|_| det("inertia", "j")) {
            mf.set(ParamId::InertiaJ, j, None);
        }
    }
    mf.param_set().map_err(|e| IdentifyError::Invalid(e.to_string()))?;
    Ok(mf)
}

/// Identifies from logs with every sample available to the fit.
pub fn identify(
    logs: &[JointLog],
    opts: &Options,
    progress: &dyn Progress,
) -> Result<(Data, Identified), IdentifyError> {
    let data = Data::new(logs, opts)?;
    let id = identify_data(&data, opts, &|_, _| true, progress)?;
    Ok((data, id))
}
