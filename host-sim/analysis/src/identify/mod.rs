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

pub mod filter;
pub mod friction;
pub mod gravity_table;
pub mod inertia;
pub mod nls;
pub mod report;
pub mod robust;
pub mod segments;
pub mod spring;
pub mod weight;

use joint_core::params::ParamId;

use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use segments::{Prepared, SegKind, Segment, SegmentCfg, Window};

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

/// How the rigid-joint terms are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// the papers' procedures: friction from plateaus, weight from poses, inertia and offset
    /// from motion with both known
    #[default]
    Papers,
    /// one least-squares fit of all rigid terms on every sample (for logs without plateaus or
    /// poses, e.g. a swing-up run); the weight's s is fixed at 1
    JointLs,
}

impl Method {
    /// Every method with its name (as in the JSON) and a line saying what it does.
    pub const NAMES: [(&'static str, Method, &'static str); 2] = [
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
            method: Method::Papers,
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
    pub friction: Option<friction::FrictionFit>,
    pub weight: Option<weight::WeightFit>,
    pub poses: Vec<weight::Pose>,
    pub inertia: Option<inertia::InertiaFit>,
    pub spring: Option<SpringResult>,
    pub table: Option<gravity_table::TableFit>,
    /// fusion clamp k written with a table that has σ_m
    pub table_clamp_k: f64,
    /// final offset C_0 written to the model
    pub c0: Option<f64>,
    pub v_band: f64,
    /// segments found per log
    pub segments: Vec<Vec<Segment>>,
    /// what the shared preparation stage did to each log (the smoother, its windows, stale
    /// rows, gaps)
    pub preparation: Vec<crate::prep::PrepReport>,
    pub notes: Vec<String>,
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

    fn pairs(&self) -> Vec<(&Prepared, &[Segment])> {
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

/// Smoothed sign as the core computes it (`clamp(v/band, −1, 1)`).
pub fn sign_band(v: f64, band: f64) -> f64 {
    if band > 0.0 {
        (v / band).clamp(-1.0, 1.0)
    } else {
        v.signum()
    }
}

/// Friction torque of a fitted curve at a signed velocity, as the model evaluates it.
pub fn friction_torque(f: &friction::FrictionFit, v: f64, band: f64) -> f64 {
    f.a * v * v.abs() + f.b * v + f.c * sign_band(v, band)
}

/// Identifies the terms from all logs. `keep(log, t)` selects the data a fit may use (the
/// full run keeps everything; the report's refit keeps the training blocks).
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
    let has = |t: Term| terms.contains(&t);
    let pairs = data.pairs();
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
    let band = opts.v_band;
    let mut out = Identified {
        terms: terms.clone(),
        friction: None,
        weight: None,
        poses: Vec::new(),
        inertia: None,
        spring: None,
        table: None,
        table_clamp_k: TABLE_CLAMP_K,
        c0: None,
        v_band: band,
        segments: data.segments.clone(),
        preparation: data.prepared.iter().map(|p| p.prep.clone()).collect(),
        notes: Vec::new(),
    };
    let torque_terms = [Term::Friction, Term::Weight, Term::Inertia, Term::Offset];
    if terms.iter().any(|t| torque_terms.contains(t)) && !data.has_torque() {
        return Err(term_err("friction/weight/inertia/offset", "need a torque-mode log (columns u and tau)"));
    }
    if opts.method == Method::JointLs && terms.iter().any(|t| torque_terms.contains(t)) {
        joint_ls_terms(data, opts, keep, &mut out)?;
    }
    let total = 2 + u64::from(has(Term::Spring));
    let papers = opts.method == Method::Papers;
    let has = |t: Term| terms.contains(&t) && (papers || t == Term::Spring);
    let mut inertia_acc: Option<(Vec<Vec<f64>>, f64)> = None;
    for round in 0..2u64 {
        progress.stage(
            if round == 0 { "friction, weight, inertia" } else { "second round (J·q̈ removed)" },
            round,
            total,
        );
        if has(Term::Friction) {
            let accel = inertia_acc.as_ref().map(|(a, j)| (a.as_slice(), *j));
            let pts = friction::points(&kept_pairs, accel, (opts.segments.a_strict, opts.segments.a_strict_rel));
            let fit = friction::fit(&pts).ok_or_else(|| {
                term_err(
                    "friction",
                    format!(
                        "{} friction points from matched ± constant-velocity plateaus; at least 4 needed \
                         (run a speed sweep, or give --window START:END:plateau)",
                        pts.len()
                    ),
                )
            })?;
            out.friction = Some(fit);
        }
        let fr = out.friction.clone();
        let ffun = |v: f64| fr.as_ref().map_or(0.0, |f| friction_torque(f, v, band));
        if has(Term::Weight) || (has(Term::Offset) && !has(Term::Inertia)) {
            let mut poses = weight::poses(&kept_pairs, &ffun);
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
                let fit = weight::fit(&poses, has(Term::Offset)).ok_or_else(|| {
                    term_err(
                        "weight",
                        format!(
                            "{} static poses found; at least {} needed (hold the joint still at several angles, \
                             or give --window START:END:static)",
                            poses.len(),
                            if has(Term::Offset) { 5 } else { 4 }
                        ),
                    )
                })?;
                out.weight = Some(fit);
            } else if !poses.is_empty() {
                let c0 = poses.iter().map(|p| p.d).sum::<f64>() / poses.len() as f64;
                out.c0 = Some(c0);
            }
            out.poses = poses;
        }
        if has(Term::Inertia) {
            let w = out.weight.clone();
            let c0s = out.c0.unwrap_or(0.0);
            let model = |q: f64, v: f64| ffun(v) + w.as_ref().map_or(c0s, |w| w.curve(q));
            let dat = inertia::data(&pairs, &model, opts.accel_cutoff, opts.v_min_inertia);
            let fs = data.prepared.first().map_or(1000.0, |p| p.fs);
            let keep_i = |li: usize, i: usize| keep(li, data.prepared[li].t[i]);
            let fit = inertia::fit(&dat, fs, opts.accel_cutoff, &keep_i).ok_or_else(|| {
                term_err("inertia", "too few moving samples (|q̇| above the threshold, not static) in torque-mode logs")
            })?;
            if !(fit.j > 0.0) {
                return Err(term_err(
                    "inertia",
                    format!("the fit gives J = {:.4} kg·m² (not positive): the log has too little acceleration", fit.j),
                ));
            }
            inertia_acc = Some((dat.acc, fit.j));
            out.inertia = Some(fit);
        }
        if !(has(Term::Inertia) && has(Term::Friction)) {
            break;
        }
    }
    if has(Term::Offset) {
        let stat = out.weight.as_ref().filter(|w| w.fitted_offset).map(|w| w.c0).or(out.c0);
        let dyn_c0 = out.inertia.as_ref().map(|i| i.dc0);
        out.c0 = match (stat, dyn_c0) {
            (Some(s), Some(d)) => Some(s + d),
            (Some(s), None) => Some(s),
            (None, Some(d)) => Some(d),
            (None, None) => return Err(term_err("offset", "needs static poses or moving samples with torque")),
        };
    }
    if terms.contains(&Term::GravityTable) {
        let fr = out.friction.clone();
        let c0 = out.c0.unwrap_or(0.0);
        let w = out.weight.clone();
        let st = |li: usize, i: usize| {
            let p = &data.prepared[li];
            let d = p.d.as_ref().map_or(0.0, |d| d[i]);
            d - fr.as_ref().map_or(0.0, |f| friction_torque(f, p.qd_f[i], band)) - c0
        };
        let model = |li: usize, i: usize| w.as_ref().map_or(0.0, |w| w.weight(data.prepared[li].q[i]));
        let m: Option<&dyn Fn(usize, usize) -> f64> = if out.weight.is_some() { Some(&model) } else { None };
        let fit = gravity_table::fit(&kept_pairs, &st, m).map_err(|e| term_err("gravity_table", e))?;
        out.table = Some(fit);
    }
    if has(Term::Spring) {
        progress.stage("spring", 2, total);
        out.spring = Some(identify_spring(data, &kept_pairs, &ffun_none, opts, &mut out.notes)?);
        out.poses = weight::poses(&kept_pairs, &ffun_none);
    }
    progress.stage("done", total, total);
    Ok(out)
}

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
    let has = |t: Term| out.terms.contains(&t);
    let tq = robust::t_quantile_975(f.n as f64 * (2.0 * f.cutoff_hz / data.prepared[0].fs).min(1.0) - 7.0);
    let ci = |k: usize, v: f64| (v - tq * f.se[k], v + tq * f.se[k]);
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
        });
    }
    if has(Term::Weight) {
        let amp = f.alpha.hypot(f.beta);
        out.weight = Some(weight::WeightFit {
            amplitude: amp,
            s: 1.0,
            phi: f.beta.atan2(f.alpha),
            c0: 0.0,
            fitted_offset: false,
            se: vec![f.se[4].hypot(f.se[5]), 0.0, f.se[4].hypot(f.se[5]) / amp.max(1e-12)],
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
    Ok(())
}

fn ffun_none(_: f64) -> f64 {
    0.0
}

fn identify_spring(
    data: &Data,
    kept_pairs: &[(&Prepared, &[Segment])],
    friction: &dyn Fn(f64) -> f64,
    opts: &Options,
    notes: &mut Vec<String>,
) -> Result<SpringResult, IdentifyError> {
    let poses = weight::poses(kept_pairs, friction);
    let stat = spring::static_fit(&poses);
    if stat.is_none() {
        notes.push(format!(
            "spring: {} static poses with torque, no torque–angle branch with 2 poses: K not identified",
            poses.len()
        ));
    }
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
    if free.is_none() {
        notes.push("spring: no free oscillation found (a trajectory-mode log, or --window START:END:free): J and B not identified".into());
    }
    let k = stat.as_ref().map(|s| s.k);
    let (j, b) = match (k, &free) {
        (Some(k), Some(f)) => {
            let j = k / f.k_over_j;
            (Some(j), Some(f.b_over_j * j))
        }
        _ => (None, None),
    };
    if k.is_none() && free.is_none() {
        return Err(term_err("spring", "neither static torque–angle poses nor a free oscillation found"));
    }
    if k.is_none() {
        notes.push(
            "spring: without K only ω_n and ζ of the free oscillation are known (J = K/ω_n², B = 2ζω_n·J)".into(),
        );
    }
    Ok(SpringResult { stat, free, k, j, b })
}

/// The model file for the identified terms (only identified sections are written).
pub fn model_file(id: &Identified, name: Option<&str>) -> Result<ModelFile, IdentifyError> {
    let mut mf = ModelFile::empty("(identified)");
    mf.name = name.map(str::to_string);
    if let Some(f) = &id.friction {
        mf.set(ParamId::FrictionA, f.a, None);
        mf.set(ParamId::FrictionB, f.b, None);
        mf.set(ParamId::FrictionC, f.c, None);
        mf.set(ParamId::FrictionVBand, id.v_band, None);
    }
    if let Some(w) = &id.weight {
        mf.set(ParamId::WeightAmplitude, w.amplitude, None);
        mf.set(ParamId::WeightS, w.s, None);
        mf.set(ParamId::WeightPhi, w.phi, None);
    }
    if let Some(i) = &id.inertia {
        mf.set(ParamId::InertiaJ, i.j, None);
    }
    if let Some(c0) = id.c0 {
        mf.set(ParamId::OffsetC0, c0, None);
    }
    if let Some(t) = &id.table {
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
        if let Some(k) = s.k {
            mf.set(ParamId::SpringK, k, None);
            mf.set(ParamId::SpringQ0, s.stat.as_ref().map_or(0.0, |s| s.q0), None);
        }
        if let Some(b) = s.b {
            mf.set(ParamId::SpringB, b, None);
        }
        if let Some(j) = s.j {
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
