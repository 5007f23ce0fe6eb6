//! The trajectory-mode report (spec §3), the model `--emit-model` writes, and the plot data,
//! from the fits and the judgement.

use joint_formats::vocab::Effect as Vocab;
use std::collections::BTreeMap;

use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;

use super::fits::{Fitted, Prior};
use super::judge::{self, Judged, Outcome};
use super::terms::{refit_values, Kind, Layout};
use super::Skipped;
use crate::diagnose::regimes::Regimes;
use crate::diagnose::select::{Scored, ALPHA, AT_FLOOR, MIN_GAIN};
use crate::diagnose::{
    separating_test, Alternative, Diagnosis, EffectOut, Gap, NotApplicable, PlotData, RegimeOut, RegimeShrink, Report,
    RestTail, SplitInfo, Step, TestInfo, Verdict,
};

/// What the report reads besides the fits.
pub struct Ctx<'a> {
    pub model: &'a ModelFile,
    pub lay: &'a Layout,
    pub log: &'a JointLog,
    pub t: &'a [f64],
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub split: &'a super::split::Split,
    pub regimes: &'a Regimes,
    pub rest_tail: Option<RestTail>,
    /// a rest tail read at every m-th sample: (from t, samples in the tail, m)
    pub thinned: Option<(f64, usize, usize)>,
    pub skipped: Skipped,
    pub has_u: bool,
    pub prior: Prior,
}

pub fn build(ctx: &Ctx, fits: &[Fitted], j: &Judged) -> Diagnosis {
    let (r0, s) = (&fits[0], &fits[1]);
    let f = j.f(r0, s);
    let final_fit: &Fitted = match (j.chosen.last(), j.verdict) {
        (Some(o), _) => &fits[o.fit],
        (None, Vocab::Parameters) => &fits[2],
        (None, Vocab::InitialState) => &fits[1],
        _ => f,
    };
    let before = f.scored.rmse();
    let vafter = final_fit.scored.rmse();
    let mut effects =
        vec![effect_out(ctx, fits, j, &j.params, &f.scored), effect_out(ctx, fits, j, &j.initial, &r0.scored)];
    effects.extend(j.effects.iter().map(|o| effect_out(ctx, fits, j, o, &f.scored)));
    effects.sort_by(|a, b| a.holdout_rmse_after.total_cmp(&b.holdout_rmse_after));
    let selected: Vec<Step> = j
        .chosen
        .iter()
        .enumerate()
        .map(|(k, o)| Step {
            effect: o.name.name().into(),
            params: effect_params(ctx, &fits[o.fit], k, j),
            holdout_rmse_after: fits[o.fit].scored.rmse(),
            shrink: crate::diagnose::shrink(before, fits[o.fit].scored.rmse()),
            p_value: o.p,
        })
        .collect();
    let (alts, closest) = judge::company(j, fits, &f.scored, ctx.lay, ctx.split.n_train());
    let verdict_name = j.verdict.to_string();
    let verdict = Verdict {
        effect: verdict_name.clone(),
        holdout_rmse_before: before,
        holdout_rmse_after: vafter,
        shrink: crate::diagnose::shrink(before, vafter),
        effects: if j.chosen.is_empty() {
            vec![verdict_name]
        } else {
            j.chosen.iter().map(|o| o.name.to_string()).collect()
        },
        alternatives: alts
            .into_iter()
            .map(|a| Alternative { effect: a.name().into(), test: separating_test(j.verdict, a) })
            .collect(),
        closest: closest.into_iter().map(|e| e.name().to_string()).collect(),
    };
    let r0v: Vec<f64> = ctx.q.iter().zip(&f.sim).map(|(a, b)| a - b).collect();
    let ra: Vec<f64> = ctx.q.iter().zip(&final_fit.sim).map(|(a, b)| a - b).collect();
    let (total, regimes) = regimes_out(ctx.regimes, &r0v);
    let n = ctx.q.len();
    let refit_used = j.verdict == Vocab::Parameters || !j.chosen.is_empty();
    let refit_base = if refit_used { final_fit.base(ctx.lay) } else { &ctx.lay.beta0 };
    let mut warnings = crate::diagnose::refit_warnings(&effects);
    if let Some((from_t, k, m)) = ctx.thinned {
        warnings.push(format!(
            "the rest from t = {from_t:.3} s ({k} samples) is scored at one sample in {m} (and fitted in full): \
             the log rests elsewhere than the file's model there, and scored in full it would outweigh the motion \
             before it"
        ));
    }
    if let Some(d) = j.floor_dof {
        warnings.push(format!(
            "short log ({n} samples, {} held out): the noise floor is read from the fits' training residual ({d} \
             degrees of freedom), so a model error the refit absorbs there counts as noise; a `none` here means \
             this log cannot tell, not that the model is confirmed",
            f.scored.n
        ));
    }
    let report = Report {
        mode: "trajectory",
        samples: n,
        split: SplitInfo {
            method: "interleaved_blocks",
            train: ctx.split.n_train(),
            holdout: ctx.split.n_held(),
            blocks: ctx.split.blocks,
            held_blocks: ctx.split.held_blocks.clone(),
            guard_samples: 0,
            test_units: ctx.split.units,
            rest_tail: ctx.rest_tail.clone(),
            cross_fitted: (!f.scored.folds.is_empty()).then_some(1 + f.scored.folds.len()),
            holdout_scored: (!f.scored.folds.is_empty()).then_some(f.scored.n),
        },
        gap: Gap {
            rmse: (total / n.max(1) as f64).sqrt(),
            holdout_rmse: before,
            noise_floor: j.floor,
            unit: "rad",
            at_noise_floor: vafter <= AT_FLOOR * j.floor,
            qdd_noise_sd: None,
            scored_samples: None,
            rest_creep_samples: None,
        },
        regimes,
        effects,
        verdict,
        selected,
        refit: nest(refit_values(ctx.model, ctx.lay, refit_base)),
        test: TestInfo {
            method: "one-sided t-test on the per-unit log ratio of held-out MSE and a projection test of the held-out MSE difference \
                     (its variance from the units, Satterthwaite degrees of freedom; six interleaved held-out blocks of 20, up to four \
                     units each, or one per sample when fewer; windows up to 3 000 samples cross-fitted over three such folds, \
                     every inner block held out once; p = 2·min), Bonferroni over everything tested, a 2 % minimum gain, \
                     nothing tested once the file's model is within 10 % of the noise floor; initial_state only when the \
                     freed start differs from the log's estimate beyond its uncertainty (χ², 2 dof, p < 0.001)",
            alpha: ALPHA,
            alpha_each: j.alpha_each,
            min_gain: MIN_GAIN,
        },
        resid: Some(resid(ctx, &r0v, &ra)),
        unknown_columns: ctx.log.unknown.clone(),
        not_applicable: not_applicable(ctx),
        not_determined: Vec::new(),
        warnings,
        prep: None,
    };
    let emitted_model = emitted_model(ctx, final_fit, j);
    let plots = plots(ctx, &r0v, &ra);
    Diagnosis { report, emitted_model, plots }
}

fn effect_out(ctx: &Ctx, fits: &[Fitted], j: &Judged, o: &Outcome, reference: &Scored) -> EffectOut {
    let fit = &fits[o.fit];
    let before = reference.rmse();
    let k = fit.effects.len().saturating_sub(1);
    EffectOut {
        effect: o.name.name().into(),
        holdout_rmse_before: before,
        holdout_rmse_after: fit.scored.rmse(),
        shrink: crate::diagnose::shrink(before, fit.scored.rmse()),
        significant: o.significant,
        params: effect_params(ctx, fit, k, j),
        reference: match o.name {
            Vocab::Parameters | Vocab::InitialState => "model",
            _ => "parameters",
        },
        t_stat: o.t.clamp(-1e9, 1e9),
        p_value: o.p,
        gain: o.gain,
        implausible: o.implausible,
        regimes: regime_shrinks(ctx.regimes, reference, &fit.scored),
    }
}

/// A fit's values as the report names them: the model's terms for `parameters`, the start for
/// `initial_state`, effect `k`'s own values otherwise.
fn effect_params(ctx: &Ctx, f: &Fitted, k: usize, j: &Judged) -> BTreeMap<String, f64> {
    let mut p = BTreeMap::new();
    let mut put = |key: &str, v: f64| {
        p.insert(key.to_string(), v);
    };
    if f.effects.is_empty() {
        if f.free == super::fits::Free::Start {
            put("q", f.theta[0]);
            put("qd", f.theta[1]);
            put("q_estimate", ctx.prior.q);
            put("qd_estimate", ctx.prior.v);
            put("q_estimate_sd", ctx.prior.sd_q);
            put("qd_estimate_sd", ctx.prior.sd_v);
            put("chi2", j.start_chi2);
            if let Some((c, sd)) = j.start_chi2_noise {
                // the start was judged off against the first angle's noise, not the estimate's
                // width: that χ² and the width it used, beside the wide one
                put("chi2_angle_noise", c);
                put("q_noise_sd", sd);
            }
        } else {
            for (key, v) in refit_values(ctx.model, ctx.lay, f.base(ctx.lay)) {
                put(&key, v);
            }
        }
        return p;
    }
    let e = f.effect_values(ctx.lay, k);
    let g = |i: usize| e.get(i).copied().unwrap_or(0.0);
    let c = ctx.lay.coulomb(f.base(ctx.lay));
    match f.effects[k] {
        Kind::Stribeck => {
            put("level", g(0));
            put("speed", g(1).exp());
            put("exponent", g(2));
        }
        Kind::Asymmetric => put("delta", g(0)),
        Kind::Ripple | Kind::Ripple2 => {
            put("amplitude", g(0).hypot(g(1)));
            put("phase", g(1).atan2(g(0)));
            put("period", g(2).exp());
            if f.effects[k] == Kind::Ripple2 {
                put("amplitude_2", g(3).hypot(g(4)));
                put("phase_2", g(4).atan2(g(3)));
                put("period_2", g(5).exp());
            }
        }
        Kind::CableAbove | Kind::CableBelow => {
            put("k", g(0));
            put("engage", g(1));
            put("width", g(2).exp());
            put("side", if f.effects[k] == Kind::CableAbove { 1.0 } else { -1.0 });
        }
        Kind::CableCubic if ctx.lay.has(crate::diagnose::candidates::Col::Q) => {
            put("k3", g(0));
            put("center", g(1));
        }
        Kind::CableCubic => {
            put("k1", g(0));
            put("k3", g(1));
            put("center", g(2));
        }
        Kind::CableBump => {
            put("amplitude", g(0));
            put("center", g(1));
            put("width", g(2).exp());
        }
        Kind::Backlash => {
            put("width", g(0).exp());
            put("center", g(1));
            put("offset", g(1) - ctx.lay.q_rest);
        }
        Kind::Dry => put("c", g(0)),
        Kind::DryBand => {
            put("c", g(0));
            put("v_band", g(1).exp());
        }
        Kind::Presliding => {
            let x = g(0).exp();
            put("distance", x);
            put("sigma", c.max(0.0) / x);
            put("c", c);
        }
        Kind::Delay => put("seconds", g(0)),
    }
    p
}

fn regime_shrinks(regimes: &Regimes, m0: &Scored, s: &Scored) -> Vec<RegimeShrink> {
    regimes
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

/// Where the file's model's residual lies over the whole window, per regime.
fn regimes_out(regimes: &Regimes, r0: &[f64]) -> (f64, Vec<RegimeOut>) {
    let total: f64 = r0.iter().map(|r| r * r).sum();
    let nreg = regimes.defs.len();
    let mut sse = vec![0.0; nreg];
    let mut cnt = vec![0usize; nreg];
    for (i, r) in r0.iter().enumerate() {
        let mut b = regimes.bits[i];
        while b != 0 {
            let k = b.trailing_zeros() as usize;
            sse[k] += r * r;
            cnt[k] += 1;
            b &= b - 1;
        }
    }
    let out = regimes
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

/// MATLAB-`resid`-style evidence on the held-out part: before and after.
fn resid(ctx: &Ctx, r0: &[f64], ra: &[f64]) -> crate::diagnose::Resid {
    let dt = crate::prep::median_step(ctx.t);
    let lag = ((0.1 / dt).round() as usize).clamp(10, 100);
    let held =
        |x: &[f64]| -> Vec<f64> { x.iter().zip(&ctx.split.held).filter(|(_, h)| **h).map(|(v, _)| *v).collect() };
    let (b, a, qd) = (held(r0), held(ra), held(ctx.qd));
    let (b, a, qd) = (b.as_slice(), a.as_slice(), qd.as_slice());
    crate::diagnose::Resid {
        input: vec!["qd"],
        autocorrelation_before: crate::diagnose::resid::xcorr(b, b, lag, true),
        autocorrelation_after: crate::diagnose::resid::xcorr(a, a, lag, true),
        xcorr_before: vec![crate::diagnose::resid::xcorr(b, qd, lag, false)],
        xcorr_after: vec![crate::diagnose::resid::xcorr(a, qd, lag, false)],
    }
}

fn not_applicable(ctx: &Ctx) -> Vec<NotApplicable> {
    // the terms a free response cannot show, with the reason the kinds' table gives
    let mut v: Vec<NotApplicable> =
        Vocab::terms().filter_map(|e| Kind::of(e).err().map(|why| NotApplicable { effect: e.name(), why })).collect();
    for &(effect, why) in &ctx.skipped {
        v.push(NotApplicable { effect, why });
    }
    let _ = ctx.has_u;
    v
}

/// The emitted model: the file's model with the refitted values (clamped into the parameter
/// table's ranges) plus the verdict's effect sections; what the core's sections cannot state
/// (a Stribeck exponent other than 2, a second ripple harmonic, a cable below its angle or a
/// progressive one, a dead zone off-centre) is written as comments.
fn emitted_model(ctx: &Ctx, final_fit: &Fitted, j: &Judged) -> String {
    let mut mf = ctx.model.clone();
    let refit_used = j.verdict == Vocab::Parameters || !j.chosen.is_empty();
    if refit_used {
        for (k, v) in refit_values(ctx.model, ctx.lay, final_fit.base(ctx.lay)) {
            if let Some((sec, key)) = k.split_once('.') {
                if let Some(d) = joint_core::params::param_at(sec, key) {
                    mf.set(d.id, v.clamp(f64::from(d.min), f64::from(d.max)), None);
                }
            }
        }
    }
    let mut sections = String::new();
    let mut table_taken = mf.table.is_some();
    for (k, kind) in final_fit.effects.iter().enumerate() {
        let p = effect_params(ctx, final_fit, k, j);
        if *kind == Kind::CableBump && !table_taken {
            // Padding is a torque of the angle alone: written as the gravity table the joint adds
            // to the weight (no model section holds it), over its centre ± 3 widths.
            let g = |k: &str| p.get(k).copied().unwrap_or(0.0);
            let (a, c, w) = (g("amplitude"), g("center"), g("width").abs());
            let bump = super::sim::Cable::Bump { a, qb: c, w };
            mf.table = Some(crate::diagnose::position_table(c - 3.0 * w, c + 3.0 * w, |q| bump.torque(q)));
            table_taken = true;
            sections.push_str(&format!(
                "\n# cable_spring, padding: {a:?}·exp(−½((q − {c:?})/{w:?})²) N·m, written as the [gravity_table] above\n"
            ));
            continue;
        }
        // the band is the friction law's (`[friction] v_band`, which the plant's dry friction
        // reads too)
        if *kind == Kind::DryBand {
            if let Some(&band) = p.get("v_band") {
                mf.set(joint_core::params::ParamId::FrictionVBand, band, None);
            }
        }
        if *kind == Kind::Presliding {
            if let Some(&sigma) = p.get("sigma") {
                mf.set(joint_core::params::ParamId::PreslidingSigma, sigma, None);
            }
            continue;
        }
        sections.push_str(&effect_section(&p, *kind));
    }
    let mut out = String::from("# written by `jointctl diagnose --emit-model` (trajectory mode)\n");
    out.push_str(&mf.to_toml_string());
    out.push_str(&sections);
    if j.verdict == Vocab::InitialState {
        out.push_str(&format!(
            "\n# initial_state: the run starts at q = {:?} rad, qd = {:?} rad/s (not a model section)\n",
            final_fit.theta[0], final_fit.theta[1]
        ));
    }
    out
}

fn effect_section(p: &BTreeMap<String, f64>, kind: Kind) -> String {
    let g = |k: &str| p.get(k).copied().unwrap_or(0.0);
    match kind {
        Kind::Stribeck => format!(
            "\n[stribeck]\nlevel = {:?}\nspeed = {:?}\n# fitted exponent {:.3} (the core's curve is exp(−(q̇/speed)²))\n",
            g("level"),
            g("speed"),
            g("exponent")
        ),
        Kind::Asymmetric => format!("\n[asymmetric_friction]\ndelta = {:?}\n", g("delta")),
        Kind::Ripple => format!(
            "\n[position_ripple]\namplitude = {:?}\nperiod = {:?}\nphase = {:?}\n",
            g("amplitude"),
            g("period"),
            g("phase")
        ),
        Kind::Ripple2 => format!(
            "\n[position_ripple]\namplitude = {:?}\nperiod = {:?}\nphase = {:?}\n# second harmonic: amplitude = {:?}, period = {:?}, phase = {:?}\n",
            g("amplitude"),
            g("period"),
            g("phase"),
            g("amplitude_2"),
            g("period_2"),
            g("phase_2")
        ),
        Kind::CableAbove => {
            format!("\n[cable_spring]\nk = {:?}\nengage = {:?}\nwidth = {:?}\n", g("k").max(0.0), g("engage"), g("width"))
        }
        Kind::CableBelow => format!(
            "\n# cable_spring taut below its angle (the core's section engages above): k = {:?}, engage = {:?}, width = {:?}\n",
            g("k"),
            g("engage"),
            g("width")
        ),
        Kind::CableCubic => format!(
            "\n# cable_spring, progressive k1·x + k3·x³ with x = q − {:?}: k1 = {:?}, k3 = {:?} (no core section)\n",
            g("center"),
            g("k1"),
            g("k3")
        ),
        Kind::CableBump => format!(
            "\n# cable_spring, padding: {:?}·exp(−½((q − {:?})/{:?})²) N·m (no core section)\n",
            g("amplitude"),
            g("center"),
            g("width")
        ),
        Kind::Backlash => format!(
            "\n[backlash]\nwidth = {:?}\n# dead zone centred {:?} rad from the spring's rest angle\n",
            g("width"),
            g("offset")
        ),
        Kind::Dry | Kind::DryBand => format!("\n[dry_friction]\nc = {:?}\n", g("c").max(0.0)),
        Kind::Delay if g("seconds") >= 0.0 => format!("\n[delay]\nseconds = {:?}\n", g("seconds")),
        Kind::Delay => format!(
            "\n# delay: the logged u is {:?} s late against the motion (the [delay] section takes the other sign only)\n",
            -g("seconds")
        ),
        Kind::Presliding => String::new(),
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

/// Every thinned sample for the HTML report: before (the file's model) and after.
fn plots(ctx: &Ctx, r0: &[f64], ra: &[f64]) -> PlotData {
    let n = ctx.q.len();
    // every sample up to 400 000: the plots draw long series as their envelope
    let stride = (n / 400_000).max(1);
    let mut p = PlotData { unit: "rad", measured_label: "q (rad)", ..PlotData::default() };
    for i in (0..n).step_by(stride) {
        p.t.push(ctx.t[i]);
        p.q.push(ctx.q[i]);
        p.qd.push(ctx.qd[i]);
        p.measured.push(ctx.q[i]);
        p.before.push(r0[i]);
        p.after.push(ra[i]);
        let b = ctx.regimes.bits[i];
        p.speed_regime.push(if b & 1 != 0 {
            0
        } else if b & 2 != 0 {
            1
        } else {
            2
        });
        p.held.push(ctx.split.held[i]);
    }
    p
}
