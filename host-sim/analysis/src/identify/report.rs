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
//! Plots are plain SVG written here (no plotting crate): dots for measurements, lines for the
//! model.

use std::fmt::Write as _;
use std::path::Path;

use super::segments::SegKind;
use super::{friction_torque, inertia, spring, Data, Identified, IdentifyError, Options, Quiet};

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

/// One series of a plot.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: Vec<(f64, f64)>,
    pub line: bool,
    pub color: &'a str,
}

fn nice_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).max(1e-12);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| span / s <= 6.0).unwrap_or(10.0 * mag);
    let mut v = Vec::new();
    let mut x = (lo / step).ceil() * step;
    while x <= hi + 1e-9 * step {
        v.push(x);
        x += step;
    }
    v
}

/// An SVG plot of the series (640×400).
pub fn svg_plot(title: &str, xlabel: &str, ylabel: &str, series: &[Series<'_>]) -> String {
    let (w, h, ml, mr, mt, mb) = (640.0, 400.0, 70.0, 20.0, 40.0, 50.0);
    let all = series.iter().flat_map(|s| s.points.iter()).filter(|(x, y)| x.is_finite() && y.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for (x, y) in all {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 - x0 < 1e-12 {
        x1 = x0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0).max(1e-9);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let sx = |x: f64| ml + (x - x0) / (x1 - x0) * (w - ml - mr);
    let sy = |y: f64| h - mb - (y - y0) / (y1 - y0) * (h - mt - mb);
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = write!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = write!(s, r#"<text x="{}" y="22" text-anchor="middle" font-size="14">{}</text>"#, w / 2.0, esc(title));
    let _ = write!(
        s,
        r##"<rect x="{ml}" y="{mt}" width="{}" height="{}" fill="none" stroke="#444"/>"##,
        w - ml - mr,
        h - mt - mb
    );
    for t in nice_ticks(x0, x1) {
        let _ = write!(
            s,
            r##"<line x1="{0:.1}" x2="{0:.1}" y1="{1}" y2="{2}" stroke="#ddd"/><text x="{0:.1}" y="{3}" text-anchor="middle">{4}</text>"##,
            sx(t),
            mt,
            h - mb,
            h - mb + 16.0,
            fmt_tick(t)
        );
    }
    for t in nice_ticks(y0, y1) {
        let _ = write!(
            s,
            r##"<line x1="{0}" x2="{1}" y1="{2:.1}" y2="{2:.1}" stroke="#ddd"/><text x="{3}" y="{4:.1}" text-anchor="end">{5}</text>"##,
            ml,
            w - mr,
            sy(t),
            ml - 6.0,
            sy(t) + 4.0,
            fmt_tick(t)
        );
    }
    let _ =
        write!(s, r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#, (ml + w - mr) / 2.0, h - 12.0, esc(xlabel));
    let _ = write!(
        s,
        r#"<text x="16" y="{0}" text-anchor="middle" transform="rotate(-90 16 {0})">{1}</text>"#,
        (mt + h - mb) / 2.0,
        esc(ylabel)
    );
    for (k, se) in series.iter().enumerate() {
        if se.line {
            let mut d = String::new();
            for (i, (x, y)) in se.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()).enumerate() {
                let _ = write!(d, "{}{:.1},{:.1} ", if i == 0 { "M" } else { "L" }, sx(*x), sy(*y));
            }
            let _ = write!(s, r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.5"/>"#, se.color);
        } else {
            for (x, y) in se.points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()) {
                let _ = write!(s, r#"<circle cx="{:.1}" cy="{:.1}" r="2.2" fill="{}"/>"#, sx(*x), sy(*y), se.color);
            }
        }
        let ly = mt + 14.0 + 16.0 * k as f64;
        let _ = write!(
            s,
            r#"<rect x="{}" y="{}" width="10" height="10" fill="{}"/><text x="{}" y="{}">{}</text>"#,
            ml + 10.0,
            ly - 9.0,
            se.color,
            ml + 26.0,
            ly,
            esc(se.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn fmt_tick(t: f64) -> String {
    let s = format!("{t:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

fn subsample<T: Copy>(v: &[T], max: usize) -> Vec<T> {
    let stride = (v.len() / max.max(1)).max(1);
    v.iter().step_by(stride).copied().collect()
}

/// Writes report.md, report.json and the SVG plots into `dir` (created if needed).
pub fn write_dir(dir: &Path, rep: &Report, id: &Identified, data: &Data) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut plots: Vec<(&str, String)> = Vec::new();
    plots.extend(friction_plot(id));
    plots.extend(static_plot(id));
    plots.extend(overall_plots(id, data));
    plots.extend(table_plot(id));
    plots.extend(spring_plots(id, data));
    let mut md = report_md(rep, id);
    for (name, svg) in &plots {
        std::fs::write(dir.join(name), svg)?;
        let _ = writeln!(md, "![{name}]({name})\n");
    }
    std::fs::write(dir.join("report.md"), md)?;
    let json = serde_json::json!({ "report": rep, "identified": id, "segments": data.segments.iter().map(|s| s.iter().filter(|s| s.kind != SegKind::Motion).count()).collect::<Vec<_>>() });
    std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(&json).unwrap_or_default())
}

/// Friction points of the matched plateaus, kept and rejected, with the fitted polynomial.
fn friction_plot(id: &Identified) -> Option<(&'static str, String)> {
    let f = id.friction.as_ref()?;
    let vmax = f.points.iter().fold(0.0f64, |m, p| m.max(p.v)) * 1.05;
    let curve: Vec<(f64, f64)> = (0..=100).map(|k| k as f64 * vmax / 100.0).map(|v| (v, f.eval(v))).collect();
    let (kept, rej): (Vec<_>, Vec<_>) = f.points.iter().zip(&f.weights).partition(|(_, w)| **w > 0.0);
    Some((
        "friction.svg",
        svg_plot(
            "Friction: (d₊ − d₋)/2 on matched plateaus",
            "speed |q̇| (rad/s)",
            "friction torque (N·m)",
            &[
                Series {
                    name: "plateau points",
                    points: kept.iter().map(|(p, _)| (p.v, p.f)).collect(),
                    line: false,
                    color: "#1f77b4",
                },
                Series {
                    name: "rejected (bisquare weight 0)",
                    points: rej.iter().map(|(p, _)| (p.v, p.f)).collect(),
                    line: false,
                    color: "#d62728",
                },
                Series { name: "a·v² + b·v + c", points: curve, line: true, color: "#111" },
            ],
        ),
    ))
}

/// The static poses with the fitted weight and offset.
fn static_plot(id: &Identified) -> Option<(&'static str, String)> {
    let w = id.weight.as_ref()?;
    let (q0, q1) = id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
    let curve: Vec<(f64, f64)> =
        (0..=100).map(|k| q0 + (q1 - q0) * k as f64 / 100.0).map(|q| (q, w.curve(q))).collect();
    Some((
        "static.svg",
        svg_plot(
            "Static poses: weight + offset",
            "q (rad)",
            "torque (N·m)",
            &[
                Series {
                    name: "poses",
                    points: id.poses.iter().map(|p| (p.q, p.d)).collect(),
                    line: false,
                    color: "#1f77b4",
                },
                Series { name: "C_w0·sin(s·q + φ) + C_0", points: curve, line: true, color: "#111" },
            ],
        ),
    ))
}

/// Measured d and the full model's prediction over the first torque log, and the inertia fit.
fn overall_plots(id: &Identified, data: &Data) -> Vec<(&'static str, String)> {
    let mut plots = Vec::new();
    if let Some((li, p)) = data.prepared.iter().enumerate().find(|(_, p)| p.d.is_some()) {
        if let Some(d) = &p.d {
            let fr = id.friction.clone();
            let w = id.weight.clone();
            let c0s = id.weight.as_ref().map_or(id.c0.unwrap_or(0.0), |w| w.c0);
            let band = id.v_band;
            let model = |q: f64, v: f64| {
                fr.as_ref().map_or(0.0, |f| friction_torque(f, v, band)) + w.as_ref().map_or(c0s, |w| w.curve(q))
            };
            let cutoff = id.inertia.as_ref().map_or(5.0, |i| i.cutoff_hz);
            let dat = inertia::data(&data.pairs(), &model, cutoff, 0.05);
            let idx: Vec<usize> = subsample(&(0..p.len()).collect::<Vec<_>>(), 4000);
            let meas: Vec<(f64, f64)> = idx.iter().map(|&i| (p.t[i], d[i])).collect();
            let written = Written::of(id);
            let pred: Vec<(f64, f64)> =
                idx.iter().map(|&i| (p.t[i], predict(&written, data, Some(&dat.acc), li, i))).collect();
            plots.push((
                "overall.svg",
                svg_plot(
                    "Disturbance d = u − tau: measured and model",
                    "t (s)",
                    "d (N·m)",
                    &[
                        Series { name: "measured", points: meas, line: true, color: "#9ecae1" },
                        Series { name: "model", points: pred, line: true, color: "#111" },
                    ],
                ),
            ));
            if let Some(inr) = &id.inertia {
                let idx: Vec<usize> = (0..p.len()).filter(|&i| dat.mask[li][i]).collect();
                let idx = subsample(&idx, 3000);
                let pts: Vec<(f64, f64)> = idx.iter().map(|&i| (dat.acc[li][i], dat.y[li][i])).collect();
                let (a0, a1) =
                    pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| (a.min(*x), b.max(*x)));
                plots.push((
                    "inertia.svg",
                    svg_plot(
                        "Inertia: d − friction − weight against q̈ (filtered)",
                        "q̈ (rad/s²)",
                        "torque (N·m)",
                        &[
                            Series { name: "moving samples", points: pts, line: false, color: "#1f77b4" },
                            Series {
                                name: "J·q̈ + ΔC_0",
                                points: vec![(a0, inr.j * a0 + inr.dc0), (a1, inr.j * a1 + inr.dc0)],
                                line: true,
                                color: "#111",
                            },
                        ],
                    ),
                ));
            }
        }
    }
    plots
}

/// The gravity table: one line per grid value of the second axis (the first four).
fn table_plot(id: &Identified) -> Option<(&'static str, String)> {
    let t = id.table.as_ref()?;
    let colors = ["#111", "#d62728", "#2ca02c", "#9467bd"];
    let second: Vec<f64> = t.grid.get(1).cloned().unwrap_or_else(|| vec![0.0]);
    let pick: Vec<f64> =
        if second.len() <= 4 { second.clone() } else { (0..4).map(|k| second[k * (second.len() - 1) / 3]).collect() };
    let (q0, q1) = (t.grid[0][0], t.grid[0][t.grid[0].len() - 1]);
    let names: Vec<String> =
        pick.iter().map(|v| format!("{} = {v:.3}", t.axes.get(1).map_or("", String::as_str))).collect();
    let mut series = Vec::new();
    for (k, v) in pick.iter().enumerate() {
        let pts = (0..=100)
            .map(|i| q0 + (q1 - q0) * i as f64 / 100.0)
            .map(|q| {
                let mut x = vec![q, *v];
                x.truncate(t.axes.len());
                x.resize(t.axes.len(), *v);
                (q, t.eval(&x).0)
            })
            .collect();
        series.push(Series {
            name: if t.axes.len() > 1 { &names[k] } else { "table" },
            points: pts,
            line: true,
            color: colors[k % 4],
        });
    }
    Some((
        "gravity_table.svg",
        svg_plot("Gravity table (whole static gravity, N·m)", "q (rad)", "torque (N·m)", &series),
    ))
}

/// The spring's static curve over the poses and its free oscillation against the log.
fn spring_plots(id: &Identified, data: &Data) -> Vec<(&'static str, String)> {
    let mut plots = Vec::new();
    let Some(sp) = &id.spring else { return plots };
    if let Some(st) = &sp.stat {
        let (q0, q1) = id.poses.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.q), b.max(p.q)));
        let h = 0.5 * st.dead_zone;
        let curve: Vec<(f64, f64)> = (0..=200)
            .map(|k| q0 + (q1 - q0) * k as f64 / 200.0)
            .map(|q| {
                let x = q - st.q0;
                (
                    q,
                    st.k * if x > h {
                        x - h
                    } else if x < -h {
                        x + h
                    } else {
                        0.0
                    },
                )
            })
            .collect();
        plots.push((
            "spring_static.svg",
            svg_plot(
                "Spring: static torque against angle",
                "q (rad)",
                "torque (N·m)",
                &[
                    Series {
                        name: "poses",
                        points: id.poses.iter().map(|p| (p.q, p.d)).collect(),
                        line: false,
                        color: "#1f77b4",
                    },
                    Series { name: "K·dz(q − q0)", points: curve, line: true, color: "#111" },
                ],
            ),
        ));
    }
    if let Some(f) = &sp.free {
        if let Some((p, (s, e))) = free_stretch(data, &Options::default(), f) {
            let tt: Vec<f64> = p.t[s..e].iter().map(|t| t - f.t0).collect();
            let mut sim = vec![0.0; e - s];
            let w = sp.stat.as_ref().map_or(0.0, |s| s.dead_zone);
            spring::simulate(&tt, f.k_over_j, f.b_over_j, f.q0, w, f.q_start, f.qd_start, &mut sim);
            let idx = subsample(&(0..e - s).collect::<Vec<_>>(), 3000);
            plots.push((
                "spring_free.svg",
                svg_plot(
                    "Free oscillation: logged and simulated angle",
                    "t (s)",
                    "q (rad)",
                    &[
                        Series {
                            name: "logged",
                            points: idx.iter().map(|&i| (p.t[s + i], p.q[s + i])).collect(),
                            line: false,
                            color: "#1f77b4",
                        },
                        Series {
                            name: "fitted model",
                            points: idx.iter().map(|&i| (p.t[s + i], sim[i])).collect(),
                            line: true,
                            color: "#111",
                        },
                    ],
                ),
            ));
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
