//! The validation report (trunk paper §3.5): how well the identified model predicts torque it
//! was not fitted to.
//!
//! The data are cut into blocks of [`BLOCK_S`] seconds (an eighth of the log when that is
//! shorter, so a short log still has held-out blocks); every fourth block is held out, the
//! model is identified again on the other three quarters, and that refit is scored on the
//! held-out blocks: RMSE and Pearson r² per term (friction points, static poses, the filtered
//! inertia equation) and overall (the measured disturbance `d = u − tau` of every held-out
//! sample against the model's prediction). The model written to the TOML is the fit on all
//! data; the refit exists only to be scored honestly. The spring's free oscillation is one
//! stretch: it is scored in-sample, and held out by fitting its first 70 % and letting the
//! fitted model run on through the last 30 %.
//!
//! Plots come from [`crate::plot`] (plotters): dots for measurements, lines for the model, long
//! time series as their per-pixel envelope; `report.html` shows them with those series zoomable.

use std::fmt::Write as _;
use std::path::Path;

use super::segments::SegKind;
use super::{friction_torque, inertia, spring, Data, Identified, IdentifyError, Options, Quiet};
use crate::plot::{colour, interactive, Plot};

/// Length of a hold-out block, s.
pub const BLOCK_S: f64 = 4.0;

/// One score.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    pub what: String,
    pub n: usize,
    pub rmse: f64,
    /// squared Pearson correlation of measured and predicted (blind to bias and scale)
    pub r2: f64,
    /// coefficient of determination on these samples, 1 − SSE/SST about their own mean: the
    /// share of their variance the model explains (≤ 0 when it explains nothing); the quality
    /// gate reads this one
    pub skill: f64,
    pub unit: &'static str,
    /// true when scored on held-out data
    pub held_out: bool,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Report {
    pub block_s: f64,
    /// why the hold-out refit failed, if it did (scores are then absent)
    pub refit_error: Option<String>,
    pub scores: Vec<Score>,
    /// the held-out quality the write decision reads
    pub quality: Quality,
}

/// Below this held-out R² (share of the held-out variance explained) a model is not written
/// without `--force`.
pub const MIN_HELDOUT_R2: f64 = 0.5;

/// The held-out quality of a fit: which score, its value, and whether it passes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Quality {
    /// what was measured
    pub metric: String,
    /// held-out R² (1 − SSE/SST), when measured
    pub value: Option<f64>,
    pub threshold: f64,
    /// None when nothing could be held out
    pub passed: Option<bool>,
    pub why: String,
}

impl Quality {
    fn not_measured(why: impl Into<String>) -> Quality {
        Quality { metric: "none".into(), value: None, threshold: MIN_HELDOUT_R2, passed: None, why: why.into() }
    }

    fn of(metric: &str, skill: f64, why: impl Into<String>) -> Quality {
        let passed = skill >= MIN_HELDOUT_R2;
        Quality {
            metric: metric.into(),
            value: Some(skill),
            threshold: MIN_HELDOUT_R2,
            passed: Some(passed),
            why: why.into(),
        }
    }
}

fn held_out(data: &Data, log: usize, t: f64) -> bool {
    let (t0, t1) = data.prepared.get(log).and_then(|p| Some((*p.t.first()?, *p.t.last()?))).unwrap_or((0.0, 0.0));
    let block = BLOCK_S.min((t1 - t0) / 8.0).max(1e-9);
    ((t - t0) / block).floor() as i64 % 4 == 3
}

/// RMSE of `pred − meas` and the squared Pearson correlation.
pub fn rmse_r2(meas: &[f64], pred: &[f64]) -> (f64, f64) {
    let n = meas.len().min(pred.len());
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let nf = n as f64;
    let (mut se, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        se += (pred[i] - meas[i]).powi(2);
        sx += meas[i];
        sy += pred[i];
    }
    let (mx, my) = (sx / nf, sy / nf);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (dx, dy) = (meas[i] - mx, pred[i] - my);
        sxy += dx * dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    let r2 = if sxx > 0.0 && syy > 0.0 { sxy * sxy / (sxx * syy) } else { f64::NAN };
    ((se / nf).sqrt(), r2)
}

fn push_score(v: &mut Vec<Score>, what: &str, meas: &[f64], pred: &[f64], unit: &'static str, held_out: bool) {
    if !meas.is_empty() {
        v.push(score(what, meas, pred, unit, held_out));
    }
}

fn score(what: &str, meas: &[f64], pred: &[f64], unit: &'static str, held_out: bool) -> Score {
    let (rmse, r2) = rmse_r2(meas, pred);
    Score { what: what.to_string(), n: meas.len(), rmse, r2, skill: skill(meas, pred), unit, held_out }
}

/// 1 − SSE/SST of `pred` against `meas` about the mean of `meas`.
pub fn skill(meas: &[f64], pred: &[f64]) -> f64 {
    let n = meas.len().min(pred.len());
    if n == 0 {
        return f64::NAN;
    }
    let m = meas[..n].iter().sum::<f64>() / n as f64;
    let sst: f64 = meas[..n].iter().map(|x| (x - m).powi(2)).sum();
    let sse: f64 = meas[..n].iter().zip(&pred[..n]).map(|(a, b)| (a - b).powi(2)).sum();
    if sst > 0.0 {
        1.0 - sse / sst
    } else {
        f64::NAN
    }
}

/// Model prediction of d at sample i of log `li` (friction at the filtered velocity, q̈ from
/// the inertia data's filtered acceleration).
/// The model that would be written: the determined parameters of an identification, looked up
/// once (the prediction runs per sample).
struct Written<'a> {
    id: &'a Identified,
    friction: [f64; 3],
    c0: f64,
    weight: Option<&'a super::weight::WeightFit>,
    table: Option<&'a super::gravity_table::TableFit>,
    j: Option<f64>,
    spring_k: Option<(f64, f64, f64)>,
    spring_b: Option<f64>,
}

impl<'a> Written<'a> {
    fn of(id: &'a Identified) -> Written<'a> {
        let det = |t: &str, k: &str| id.determined(t, k);
        let f = id.friction.as_ref();
        let coef = |k: usize, v: f64| if det("friction", ["a", "b", "c"][k]) { v } else { 0.0 };
        let spring = id.spring.as_ref();
        Written {
            id,
            friction: f.map_or([0.0; 3], |f| [coef(0, f.a), coef(1, f.b), coef(2, f.c)]),
            c0: id.c0.filter(|_| det("offset", "c0")).unwrap_or(0.0),
            weight: id.weight.as_ref().filter(|_| det("weight", "amplitude")),
            table: id.table.as_ref().filter(|_| det("gravity_table", "torque")),
            j: id.inertia.as_ref().filter(|_| det("inertia", "j")).map(|i| i.j),
            spring_k: spring.and_then(|s| {
                let st = s.stat.as_ref()?;
                s.k.filter(|_| det("spring", "k")).map(|k| (k, st.q0, 0.5 * st.dead_zone))
            }),
            spring_b: spring.and_then(|s| s.b).filter(|_| det("spring", "b")),
        }
    }
}

/// The written model's prediction of d at sample i of log `li` (friction at the filtered
/// velocity, q̈ from the inertia data's filtered acceleration).
fn predict(w: &Written, data: &Data, acc: Option<&[Vec<f64>]>, li: usize, i: usize) -> f64 {
    let p = &data.prepared[li];
    let (q, v) = (p.q[i], p.qd_f[i]);
    let [a, b, c] = w.friction;
    let mut d = w.c0 + a * v * v.abs() + b * v + c * super::sign_band(v, w.id.v_band);
    let wq = w.weight.map_or(0.0, |wf| wf.weight(q));
    match w.table {
        Some(t) => {
            let x: Vec<f64> = t
                .axes
                .iter()
                .map(|a| if a == "q" { q } else { p.others.iter().find(|(n, _)| n == a).map_or(0.0, |(_, c)| c[i]) })
                .collect();
            d += t.gravity(wq, &x, w.id.table_clamp_k);
        }
        None => d += wq,
    }
    if let (Some(j), Some(acc)) = (w.j, acc) {
        d += j * acc[li][i];
    }
    if let Some((k, q0, h)) = w.spring_k {
        let x = q - q0;
        d += k * if x > h {
            x - h
        } else if x < -h {
            x + h
        } else {
            0.0
        };
    }
    if let Some(b) = w.spring_b {
        d += b * p.qd[i];
    }
    d
}

/// Refits on the training blocks and scores the refit on the held-out blocks.
pub fn validate(data: &Data, opts: &Options, full: &Identified) -> Result<Report, IdentifyError> {
    let mut rep =
        Report { block_s: BLOCK_S, refit_error: None, scores: Vec::new(), quality: Quality::not_measured("") };
    let train = |li: usize, t: f64| !held_out(data, li, t);
    // The refit runs the method the full fit ran (auto resolved), on the same terms.
    let refit_opts = Options { terms: full.terms.clone(), method: full.method, ..opts.clone() };
    let refit = match super::identify_data(data, &refit_opts, &train, &Quiet) {
        Ok(r) => Some(r),
        Err(e) => {
            rep.refit_error = Some(e.to_string());
            None
        }
    };
    if let Some(r) = &refit {
        if let (Some(f), Some(ff)) = (&r.friction, &full.friction) {
            let pts: Vec<_> = ff.points.iter().filter(|p| held_out(data, p.log, p.t)).collect();
            let meas: Vec<f64> = pts.iter().map(|p| p.f).collect();
            let pred: Vec<f64> = pts.iter().map(|p| f.eval(p.v)).collect();
            push_score(&mut rep.scores, "friction (± plateau points)", &meas, &pred, "N·m", true);
        }
        if let Some(w) = &r.weight {
            let poses: Vec<_> = full.poses.iter().filter(|p| held_out(data, p.log, p.t)).collect();
            let meas: Vec<f64> = poses.iter().map(|p| p.d).collect();
            let pred: Vec<f64> = poses.iter().map(|p| w.curve(p.q)).collect();
            push_score(&mut rep.scores, "static (weight + offset, poses)", &meas, &pred, "N·m", true);
        }
        let w = r.weight.clone();
        let fr = r.friction.clone();
        let c0s = r.weight.as_ref().map_or(r.c0.unwrap_or(0.0), |w| w.c0);
        let band = r.v_band;
        let model = |q: f64, v: f64| {
            fr.as_ref().map_or(0.0, |f| friction_torque(f, v, band)) + w.as_ref().map_or(c0s, |w| w.curve(q))
        };
        let dat = inertia::data(&data.pairs(), &model, opts.accel_cutoff, opts.v_min_inertia);
        if let Some(inr) = r.inertia.as_ref().filter(|_| full.method == super::Method::Papers) {
            let (mut meas, mut pred) = (Vec::new(), Vec::new());
            for (li, ((acc, y), mask)) in dat.acc.iter().zip(&dat.y).zip(&dat.mask).enumerate() {
                let p = &data.prepared[li];
                for i in 0..acc.len() {
                    if mask[i] && held_out(data, li, p.t[i]) {
                        meas.push(y[i]);
                        pred.push(inr.j * acc[i] + inr.dc0);
                    }
                }
            }
            push_score(&mut rep.scores, "inertia (filtered eq. 5 residual torque)", &meas, &pred, "N·m", true);
        }
        if data.has_torque() {
            let written = Written::of(r);
            let (mut meas, mut pred) = (Vec::new(), Vec::new());
            for (li, p) in data.prepared.iter().enumerate() {
                let Some(d) = &p.d else { continue };
                for i in 0..p.len() {
                    if held_out(data, li, p.t[i]) {
                        meas.push(d[i]);
                        pred.push(predict(&written, data, Some(&dat.acc), li, i));
                    }
                }
            }
            push_score(&mut rep.scores, "overall (d = u − tau, every held-out sample)", &meas, &pred, "N·m", true);
            // The same, with measured and predicted d low-passed at the fit's cut-off: what the
            // model can explain, without the sensor noise and chatter above it.
            let (mut meas_f, mut pred_f) = (Vec::new(), Vec::new());
            for (li, p) in data.prepared.iter().enumerate() {
                let Some(d) = &p.d else { continue };
                let df = p.lowpass(d, opts.accel_cutoff);
                let pr: Vec<f64> = (0..p.len()).map(|i| predict(&written, data, Some(&dat.acc), li, i)).collect();
                let pf = p.lowpass(&pr, opts.accel_cutoff);
                for i in 0..p.len() {
                    if held_out(data, li, p.t[i]) {
                        meas_f.push(df[i]);
                        pred_f.push(pf[i]);
                    }
                }
            }
            let what = format!("overall low-passed at {} Hz (held-out samples)", opts.accel_cutoff);
            push_score(&mut rep.scores, &what, &meas_f, &pred_f, "N·m", true);
        }
    }
    if let Some(s) = &full.spring {
        if let Some(f) = &s.free {
            if let Some((p, seg)) = free_stretch(data, opts, f) {
                let mut sim = vec![0.0; seg.1 - seg.0];
                let tt: Vec<f64> = p.t[seg.0..seg.1].iter().map(|t| t - f.t0).collect();
                let w = s.stat.as_ref().map_or(0.0, |s| s.dead_zone);
                spring::simulate(&tt, f.k_over_j, f.b_over_j, f.q0, w, f.q_start, f.qd_start, &mut sim);
                push_score(
                    &mut rep.scores,
                    "spring free oscillation (angle, in-sample)",
                    &p.q[seg.0..seg.1],
                    &sim,
                    "rad",
                    false,
                );
                // Held out: fit the first 70 % of the stretch, let the fitted model run on and
                // score it on the last 30 % it never saw.
                let cut = seg.0 + (seg.1 - seg.0) * 7 / 10;
                let part = super::segments::Segment { kind: SegKind::Free, start: seg.0, end: cut };
                let q0 = s.stat.as_ref().map(|st| st.q0);
                if let Some(g) = spring::free_fit(p, f.log, &part, q0, w) {
                    let tt: Vec<f64> = p.t[seg.0..seg.1].iter().map(|t| t - g.t0).collect();
                    let mut sim = vec![0.0; tt.len()];
                    spring::simulate(&tt, g.k_over_j, g.b_over_j, g.q0, w, g.q_start, g.qd_start, &mut sim);
                    let k = cut - seg.0;
                    push_score(
                        &mut rep.scores,
                        "spring free oscillation (angle, last 30 % held out)",
                        &p.q[cut..seg.1],
                        &sim[k..],
                        "rad",
                        true,
                    );
                }
            }
        }
    }
    rep.quality = quality(data, opts, full, refit.as_ref(), &rep.scores);
    Ok(rep)
}

fn determined_set(id: &Identified) -> Vec<String> {
    id.status.iter().filter(|p| p.determined()).map(|p| p.name()).collect()
}

/// The held-out figure the write decision reads (see [`Quality`]):
/// - torque mode: the share of the variance of d (low-passed at the fit's cut-off) on the
///   held-out blocks that the refit on the other blocks explains (for the papers' procedures:
///   when the refit determines the same parameters as the full fit);
/// - when the blocks take a whole test away (the refit determines other parameters, or fails):
///   the friction curve from plateaus scored on every fourth friction point, refitted on the rest;
/// - trajectory mode: the free oscillation's last 30 %, predicted from a fit of the first 70 %.
fn quality(data: &Data, opts: &Options, full: &Identified, refit: Option<&Identified>, scores: &[Score]) -> Quality {
    let det = determined_set(full);
    let lp = scores.iter().find(|s| s.what.starts_with("overall low-passed"));
    // The regression's refit is the same procedure on less data, whatever it then determines;
    // the papers' refit is only comparable when the held-out blocks left it every test.
    let same = refit.is_some_and(|r| full.method == super::Method::JointLs || determined_set(r) == det);
    if let (Some(s), true, true) = (lp, same, data.has_torque()) {
        return Quality::of(
            &format!("held-out R² of d low-passed at {} Hz", opts.accel_cutoff),
            s.skill,
            format!(
                "{} held-out samples (every fourth block of {} s), predicted by a refit on the other blocks: RMSE {:.4} \
                 N·m, Pearson r² {:.4}",
                s.n,
                BLOCK_S,
                s.rmse,
                s.r2
            ),
        );
    }
    let why_blocks = match refit {
        None => "the hold-out refit failed".to_string(),
        Some(r) => format!(
            "the refit on the training blocks determines {{{}}} instead of {{{}}} (the held-out blocks take a whole test \
             away)",
            determined_set(r).join(", "),
            det.join(", ")
        ),
    };
    if let Some(f) = full.friction.as_ref().filter(|f| f.points.len() >= 8) {
        if let Some(sk) = friction_points_cv(f) {
            return Quality::of(
                "held-out R² of the friction points (every fourth point held out)",
                sk,
                format!("{why_blocks}; the friction curve is scored on its own points instead"),
            );
        }
    }
    if let Some(s) = scores.iter().find(|s| s.what.contains("last 30 % held out")) {
        return Quality::of(
            "held-out R² of the free oscillation's angle (last 30 %, from a fit of the first 70 %)",
            s.skill,
            format!("RMSE {:.4} rad, Pearson r² {:.4}", s.rmse, s.r2),
        );
    }
    if det.is_empty() {
        return Quality::not_measured("nothing determined to score");
    }
    Quality::not_measured(why_blocks)
}

/// The friction curve refitted on three quarters of its points (the coefficients the full
/// fit has) and scored on the fourth quarter, pooled over the four folds.
fn friction_points_cv(f: &super::friction::FrictionFit) -> Option<f64> {
    let (mut meas, mut pred) = (Vec::new(), Vec::new());
    for fold in 0..4 {
        let train: Vec<_> = f.points.iter().enumerate().filter(|(i, _)| i % 4 != fold).map(|(_, p)| *p).collect();
        let g = super::friction::fit_with(&train, f.free)?;
        for p in f.points.iter().skip(fold).step_by(4) {
            meas.push(p.f);
            pred.push(g.eval(p.v));
        }
    }
    Some(skill(&meas, &pred))
}

fn free_stretch<'a>(
    data: &'a Data,
    _opts: &Options,
    f: &spring::FreeFit,
) -> Option<(&'a super::segments::Prepared, (usize, usize))> {
    let p = data.prepared.get(f.log)?;
    let s = p.t.partition_point(|&t| t < f.t0);
    let e = p.t.partition_point(|&t| t <= f.t1);
    (e > s).then_some((p, (s, e)))
}

/// How each log's q̇ and q̈ were obtained, in a line or two per log.
pub fn preparation_text(id: &Identified, cutoff_hz: f64) -> String {
    let mut s = String::new();
    for (k, p) in id.preparation.iter().enumerate() {
        let _ = writeln!(s, "log {}: {}", k + 1, p.summary());
        for n in &p.notes {
            let _ = writeln!(s, "       {n}");
        }
        if p.rest_share > 0.0 || p.ambiguous_share > 0.0 {
            let _ = writeln!(
                s,
                "       identification evaluates the local cubic over whole stretches and keeps every sample (a \
                 swing's turning points can pass the rest test; q̈ = 0 there would bias J)"
            );
        }
    }
    if let Some(p) = id.preparation.first() {
        let _ = writeln!(
            s,
            "smoother: {} (joint_analysis::prep); the fits then low-pass both sides of their equations with \
             the same zero-phase 2nd-order Butterworth at {cutoff_hz} Hz",
            p.smoother
        );
    }
    s
}

/// Human summary of the identified terms (and the scores).
pub fn summary_text(id: &Identified, rep: Option<&Report>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "method: {} — {}", id.method.name(), id.method_why);
    let mut basis = Vec::new();
    if let Some(f) = id.friction.as_ref().filter(|f| !f.points.is_empty()) {
        let rej = f.weights.iter().filter(|w| **w == 0.0).count();
        basis.push(format!("friction from {} plateau points ({rej} rejected as outliers)", f.points.len()));
    }
    if let Some(w) = id.weight.as_ref().filter(|_| !id.poses.is_empty()) {
        basis.push(format!("weight from {} static poses (curve RMS {:.4} N·m)", id.poses.len(), w.rms));
    }
    if let Some(i) = id.inertia.as_ref().filter(|_| id.joint_ls.is_none()) {
        basis.push(format!("inertia from {} moving samples ({} Hz zero-phase)", i.n, i.cutoff_hz));
    }
    if !basis.is_empty() {
        let _ = writeln!(s, "from: {}", basis.join("; "));
    }
    s.push_str(&super::status::text(&id.status));
    if let Some(sp) = &id.spring {
        if let Some(st) = &sp.stat {
            let _ = writeln!(
                s,
                "spring     k = {:.4} N·m/rad (branches {:.4}/{:.4}), q0 = {:.4} rad, dead zone {:.4} rad",
                st.k, st.k_pos, st.k_neg, st.q0, st.dead_zone
            );
        }
        if let Some(f) = &sp.free {
            let _ = writeln!(
                s,
                "free       ω_n = {:.4} rad/s, ζ = {:.4}, angle RMS {:.5} rad over {} samples",
                f.omega_n, f.zeta, f.rms, f.n
            );
        }
        if let (Some(j), Some(b)) = (sp.j, sp.b) {
            let _ = writeln!(s, "           j = {j:.5} kg·m², b = {b:.5} N·m·s/rad");
        }
    }
    if let Some(t) = &id.table {
        let dims: Vec<String> = t.grid.iter().map(|g| g.len().to_string()).collect();
        let _ = writeln!(
            s,
            "table      axes [{}], grid {}, {} samples, RMS {:.4} N·m, {} cells without data, σ_m {}",
            t.axes.join(", "),
            dims.join("×"),
            t.samples,
            t.rms,
            t.empty_cells,
            t.sigma_model.map_or("— (no weight term)".to_string(), |s| format!("{s:.4} N·m"))
        );
    }
    for n in &id.notes {
        let _ = writeln!(s, "note: {n}");
    }
    if let Some(r) = rep {
        if let Some(e) = &r.refit_error {
            let _ = writeln!(s, "validation: the hold-out refit failed ({e})");
        }
        for sc in &r.scores {
            let _ = writeln!(
                s,
                "validation {}: RMSE {:.4} {}, R² {:.4}, Pearson r² {:.4} ({} {})",
                sc.what,
                sc.rmse,
                sc.unit,
                sc.skill,
                sc.r2,
                sc.n,
                if sc.held_out { "held-out" } else { "in-sample" }
            );
        }
        let q = &r.quality;
        let _ = match (q.value, q.passed) {
            (Some(v), Some(p)) => writeln!(
                s,
                "quality: {} = {v:.4} ({} the threshold {}); {}",
                q.metric,
                if p { "meets" } else { "below" },
                q.threshold,
                q.why
            ),
            _ => writeln!(s, "quality: not measured ({})", q.why),
        };
    }
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// One plot of the report: its file name, the plot, and whether the HTML report makes it
/// zoomable (the long time series).
struct Figure {
    file: &'static str,
    plot: Plot,
    zoom: bool,
}

impl Figure {
    fn new(file: &'static str, plot: Plot) -> Figure {
        Figure { file, plot, zoom: false }
    }
}

/// Writes report.md, report.html, report.json and the SVG plots into `dir` (created if
/// needed). report.html holds the same plots inline, with the long time series zoomable.
pub fn write_dir(dir: &Path, rep: &Report, id: &Identified, data: &Data) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut figs: Vec<Figure> = Vec::new();
    figs.extend(friction_plot(id));
    figs.extend(static_plot(id));
    figs.extend(overall_plots(id, data));
    figs.extend(table_plot(id));
    figs.extend(spring_plots(id, data));
    let mut md = report_md(rep, id);
    let mut html = report_html_head(rep, id);
    for f in &figs {
        let svg = f.plot.svg();
        std::fs::write(dir.join(f.file), &svg)?;
        let _ = writeln!(md, "![{0}]({0})\n", f.file);
        if f.zoom {
            html.push_str(&interactive::figure(&f.plot));
        } else {
            let _ = writeln!(html, "<figure>{svg}</figure>");
        }
    }
    html.push_str(interactive::SCRIPT);
    html.push_str("</body></html>\n");
    std::fs::write(dir.join("report.md"), md)?;
    std::fs::write(dir.join("report.html"), html)?;
    let json = serde_json::json!({ "report": rep, "identified": id, "segments": data.segments.iter().map(|s| s.iter().filter(|s| s.kind != SegKind::Motion).count()).collect::<Vec<_>>() });
    std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(&json).unwrap_or_default())
}

/// report.html up to the plots: the summary and the score table, self-contained.
fn report_html_head(rep: &Report, id: &Identified) -> String {
    let mut h = String::from(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>jointctl identify</title><style>\
         body{font-family:sans-serif;max-width:1200px;margin:1em auto;color:#222}pre{background:#f6f6f6;padding:8px;\
         overflow-x:auto;font-size:12px}figure{display:inline-block;margin:6px;vertical-align:top}table{border-collapse:\
         collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#eee}td:first-child{text-align:\
         left}.iv-help,.hint{font-size:12px;color:#555}</style></head><body>\n<h1>Identification report</h1>\n<pre id=\"summary\">",
    );
    let cutoff = id.inertia.as_ref().map_or(5.0, |i| i.cutoff_hz);
    h.push_str(&esc(&preparation_text(id, cutoff)));
    h.push_str(&esc(&summary_text(id, Some(rep))));
    let _ = write!(
        h,
        "</pre>\n<p>Hold-out: every 4th block of {BLOCK_S} s (or an eighth of a shorter log) is left out of a refit and used to score it.</p>\n\
         <table id=\"scores\"><tr><th>score</th><th>n</th><th>RMSE</th><th>R²</th><th>Pearson r²</th><th>data</th></tr>"
    );
    for s in &rep.scores {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.4} {}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td></tr>",
            esc(&s.what),
            s.n,
            s.rmse,
            s.unit,
            s.skill,
            s.r2,
            if s.held_out { "held-out" } else { "in-sample" }
        );
    }
    h.push_str("</table>\n<h2>Plots</h2>\n<p class=\"hint\">Time plots are zoomable: wheel to zoom in time, drag to pan, shift-drag to zoom to a box, double-click for the whole log.</p>\n");
    h
}

/// `n + 1` values evenly spread over `[a, b]`.
fn grid(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| a + (b - a) * k as f64 / n as f64).collect()
}

/// Friction points of the matched plateaus, kept and rejected, with the fitted polynomial.
fn friction_plot(id: &Identified) -> Option<Figure> {
    let f = id.friction.as_ref()?;
    let vmax = f.points.iter().fold(0.0f64, |m, p| m.max(p.v)) * 1.05;
    let v = grid(0.0, vmax, 100);
    let curve: Vec<f64> = v.iter().map(|&v| f.eval(v)).collect();
    let (kept, rej): (Vec<_>, Vec<_>) = f.points.iter().zip(&f.weights).partition(|(_, w)| **w > 0.0);
    let xy = |s: &[(&super::friction::FrictionPoint, &f64)]| -> (Vec<f64>, Vec<f64>) {
        s.iter().map(|(p, _)| (p.v, p.f)).unzip()
    };
    let ((kx, ky), (rx, ry)) = (xy(&kept), xy(&rej));
    let mut plot = Plot::new(
        "friction",
        "Friction: (d₊ − d₋)/2 on matched plateaus",
        "speed |q̇| (rad/s)",
        "friction torque (N·m)",
    )
    .points("plateau points", colour::BLUE, &kx, &ky)
    .points("rejected (bisquare weight 0)", colour::RED, &rx, &ry)
    .line("a·v² + b·v + c", colour::BLACK, &v, &curve);
    plot.y_zero = true;
    plot.legend_left = true;
    Some(Figure::new("friction.svg", plot))
}

/// The static poses with the fitted weight and offset.
fn static_plot(id: &Identified) -> Option<Figure> {
    let w = id.weight.as_ref()?;
    let (q0, q1) = id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
    let q = grid(q0, q1, 100);
    let curve: Vec<f64> = q.iter().map(|&q| w.curve(q)).collect();
    let (px, py): (Vec<f64>, Vec<f64>) = id.poses.iter().map(|p| (p.q, p.d)).unzip();
    let mut plot = Plot::new("static", "Static poses: weight + offset", "q (rad)", "torque (N·m)")
        .points("poses", colour::BLUE, &px, &py)
        .line("C_w0·sin(s·q + φ) + C_0", colour::BLACK, &q, &curve);
    plot.legend_left = true;
    Some(Figure::new("static.svg", plot))
}

/// Measured d and the full model's prediction over the first torque log (every sample: the
/// plot draws it as its envelope, the HTML report zooms into it), and the inertia fit.
fn overall_plots(id: &Identified, data: &Data) -> Vec<Figure> {
    let mut plots = Vec::new();
    let Some((li, p)) = data.prepared.iter().enumerate().find(|(_, p)| p.d.is_some()) else { return plots };
    let Some(d) = &p.d else { return plots };
    let fr = id.friction.clone();
    let w = id.weight.clone();
    let c0s = id.weight.as_ref().map_or(id.c0.unwrap_or(0.0), |w| w.c0);
    let band = id.v_band;
    let model = |q: f64, v: f64| {
        fr.as_ref().map_or(0.0, |f| friction_torque(f, v, band)) + w.as_ref().map_or(c0s, |w| w.curve(q))
    };
    let cutoff = id.inertia.as_ref().map_or(5.0, |i| i.cutoff_hz);
    let dat = inertia::data(&data.pairs(), &model, cutoff, 0.05);
    let written = Written::of(id);
    let pred: Vec<f64> = (0..p.len()).map(|i| predict(&written, data, Some(&dat.acc), li, i)).collect();
    let overall = Plot::new("overall", "Disturbance d = u − tau: measured and model", "t (s)", "d (N·m)")
        .size(1100, 380)
        .line("measured", "#9ecae1", &p.t, d)
        .line("model", colour::BLACK, &p.t, &pred);
    plots.push(Figure { file: "overall.svg", plot: overall, zoom: true });
    if let Some(inr) = &id.inertia {
        let idx: Vec<usize> = (0..p.len()).filter(|&i| dat.mask[li][i]).collect();
        let (ax, ay): (Vec<f64>, Vec<f64>) = idx.iter().map(|&i| (dat.acc[li][i], dat.y[li][i])).unzip();
        let (a0, a1) = ax.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
        let mut plot =
            Plot::new("inertia", "Inertia: d − friction − weight against q̈ (filtered)", "q̈ (rad/s²)", "torque (N·m)")
                .points("moving samples", colour::BLUE, &ax, &ay)
                .line("J·q̈ + ΔC_0", colour::BLACK, &[a0, a1], &[inr.j * a0 + inr.dc0, inr.j * a1 + inr.dc0]);
        plot.legend_left = true;
        plots.push(Figure::new("inertia.svg", plot));
    }
    plots
}

/// The gravity table: one line per grid value of the second axis (the first four).
fn table_plot(id: &Identified) -> Option<Figure> {
    let t = id.table.as_ref()?;
    let colours = [colour::BLACK, colour::RED, colour::GREEN, colour::PURPLE];
    let second: Vec<f64> = t.grid.get(1).cloned().unwrap_or_else(|| vec![0.0]);
    let pick: Vec<f64> =
        if second.len() <= 4 { second.clone() } else { (0..4).map(|k| second[k * (second.len() - 1) / 3]).collect() };
    let first = t.grid.first()?;
    let q = grid(*first.first()?, *first.last()?, 100);
    let mut plot = Plot::new("gravity_table", "Gravity table (whole static gravity)", "q (rad)", "torque (N·m)");
    for (k, v) in pick.iter().enumerate() {
        let y: Vec<f64> = q
            .iter()
            .map(|&q| {
                let mut x = vec![q, *v];
                x.truncate(t.axes.len());
                x.resize(t.axes.len(), *v);
                t.eval(&x).0
            })
            .collect();
        let name = match t.axes.get(1) {
            Some(a) => format!("{a} = {v:.3}"),
            None => "table".to_string(),
        };
        plot = plot.line(&name, colours[k % 4], &q, &y);
    }
    Some(Figure::new("gravity_table.svg", plot))
}

/// The spring's static curve over the poses and its free oscillation against the log.
fn spring_plots(id: &Identified, data: &Data) -> Vec<Figure> {
    let mut plots = Vec::new();
    let Some(sp) = &id.spring else { return plots };
    if let Some(st) = &sp.stat {
        let (q0, q1) = id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
        let h = 0.5 * st.dead_zone;
        let q = grid(q0, q1, 200);
        let curve: Vec<f64> = q
            .iter()
            .map(|&q| {
                let x = q - st.q0;
                st.k * if x > h {
                    x - h
                } else if x < -h {
                    x + h
                } else {
                    0.0
                }
            })
            .collect();
        let (px, py): (Vec<f64>, Vec<f64>) = id.poses.iter().map(|p| (p.q, p.d)).unzip();
        plots.push(Figure::new(
            "spring_static.svg",
            Plot::new("spring_static", "Spring: static torque against angle", "q (rad)", "torque (N·m)")
                .points("poses", colour::BLUE, &px, &py)
                .line("K·dz(q − q0)", colour::BLACK, &q, &curve),
        ));
    }
    if let Some(f) = &sp.free {
        if let Some((p, (s, e))) = free_stretch(data, &Options::default(), f) {
            let tt: Vec<f64> = p.t[s..e].iter().map(|t| t - f.t0).collect();
            let mut sim = vec![0.0; e - s];
            let w = sp.stat.as_ref().map_or(0.0, |s| s.dead_zone);
            spring::simulate(&tt, f.k_over_j, f.b_over_j, f.q0, w, f.q_start, f.qd_start, &mut sim);
            let plot = Plot::new("spring_free", "Free oscillation: logged and simulated angle", "t (s)", "q (rad)")
                .size(1100, 380)
                .line("logged", colour::BLUE, &p.t[s..e], &p.q[s..e])
                .line("fitted model", colour::BLACK, &p.t[s..e], &sim);
            plots.push(Figure { file: "spring_free.svg", plot, zoom: true });
        }
    }
    plots
}

/// report.md up to the plots: the summary and the score table.
fn report_md(rep: &Report, id: &Identified) -> String {
    let mut md = String::from("# Identification report\n\n```\n");
    let cutoff = id.inertia.as_ref().map_or(5.0, |i| i.cutoff_hz);
    md.push_str(&preparation_text(id, cutoff));
    md.push_str(&summary_text(id, Some(rep)));
    md.push_str("```\n\n");
    let _ = writeln!(md, "Hold-out: every 4th block of {BLOCK_S} s (or an eighth of a shorter log) is left out of a refit and used to score it.\n");
    md.push_str("| score | n | RMSE | R² | Pearson r² | data |\n|---|---|---|---|---|---|\n");
    for s in &rep.scores {
        let _ = writeln!(
            md,
            "| {} | {} | {:.4} {} | {:.4} | {:.4} | {} |",
            s.what,
            s.n,
            s.rmse,
            s.unit,
            s.skill,
            s.r2,
            if s.held_out { "held-out" } else { "in-sample" }
        );
    }
    md.push('\n');
    md
}
