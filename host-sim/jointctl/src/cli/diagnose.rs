//! `jointctl diagnose`: where the sim-to-real gap lies, which effect causes it, how far it
//! shrinks. The outputs are checked against the inputs before anything is read, rendered after
//! the whole diagnosis succeeded, and committed only when all of them were written (see
//! `joint_formats::output`), so a refused input never leaves a report behind.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use super::num;
use joint_analysis::diagnose::candidates::Kind;
use joint_analysis::diagnose::{self, Options};
use joint_formats::log::JointLog;
use joint_formats::model_file::ModelFile;
use joint_formats::output::Plan;

/// Compare a joint log with a model: split the residual by regime, test every effect of the
/// vocabulary on held-out data, and report how far the best one shrinks the gap.
///
/// Torque mode (log with u and tau): the residual is u − tau − model disturbance, sample by
/// sample. Trajectory mode (no torques): the model is simulated and compared with q.
/// Fits use the training blocks only; every "holdout" figure comes from held-out blocks.
///
/// Example:
///   jointctl diagnose --log run.csv --model trunk-right.toml --json gap.json \
///       --report gap.html --emit-model trunk-right-fixed.toml
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct DiagnoseArgs {
    /// Joint log (CSV, spec §1)
    #[arg(long, value_name = "LOG.csv")]
    pub log: PathBuf,
    /// Model TOML (spec §2)
    #[arg(long, value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Write the diagnosis JSON (spec §3) here (- for stdout)
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML report (inline SVG plots) here (- for stdout)
    #[arg(long, value_name = "OUT.html")]
    pub report: Option<PathBuf>,
    /// Write the refitted model plus the selected effects' sections (plant TOML) here (- for
    /// stdout)
    #[arg(long, value_name = "OUT.toml")]
    pub emit_model: Option<PathBuf>,
    /// At most this many effects in the forward selection (1 ≤ N ≤ the vocabulary's 9)
    #[arg(long, default_value_t = 3, value_parser = num::count(1, Kind::ALL.len() as u64))]
    pub max_effects: usize,
    /// Write the --emit-model even when it fails the plausibility gate (non-positive inertia,
    /// negative friction or stiffness, a weight the log's static samples contradict)
    #[arg(long)]
    pub force: bool,
    /// Score every candidate on one training/held-out split even for a torque log of at most
    /// 250 000 samples or a trajectory window of at most 3 000, which are otherwise
    /// cross-fitted over three folds (every inner sample held out once). A third of the
    /// selection's time in torque mode, about three quarters in trajectory mode; the tests have
    /// less power
    #[arg(long)]
    pub single_split: bool,
}

pub fn run(a: &DiagnoseArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    plan.input("--log", &a.log).input("--model", &a.model);
    let json_out = plan.file_opt("--json", a.json.as_deref());
    let report_out = plan.file_opt("--report", a.report.as_deref());
    let model_out = plan.file_opt("--emit-model", a.emit_model.as_deref());
    let outs = plan.check()?;
    let log = JointLog::read_file(&a.log)?;
    let model = ModelFile::read_file(&a.model)?;
    let t0 = std::time::Instant::now();
    let opts = Options { max_effects: a.max_effects, cross_fit: !a.single_split };
    // The emitted model's gate reads the log again; without it the diagnosis takes the log's
    // columns instead of copying them.
    let (d, gate_log) = if model_out.is_some() {
        (diagnose::diagnose(&log, &model, &opts), Some(log))
    } else {
        (diagnose::diagnose_owned(log, &model, &opts), None)
    };
    let d = d.map_err(|e| anyhow::anyhow!("{}: {e}", a.log.display()))?;
    let elapsed = t0.elapsed().as_secs_f64();
    if let Some(log) = &gate_log {
        gate_emitted(&d.emitted_model, log, a.force)?;
    }
    // Render everything first, write every output to its temporary file, then commit them:
    // a failure on any one leaves none of them behind.
    let json = serde_json::to_string_pretty(&d.report)?;
    let html = report_out.map(|_| diagnose::report_html::render(&d));
    let mut sinks = Vec::new();
    for (slot, text) in [(json_out, Some(&json)), (report_out, html.as_ref()), (model_out, Some(&d.emitted_model))] {
        if let (Some(slot), Some(text)) = (slot, text) {
            let mut s = outs.open(slot)?;
            s.write_all(text.as_bytes()).map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", s.named()))?;
            sinks.push(s);
        }
    }
    for s in sinks {
        s.commit()?;
    }
    print_summary(&mut outs.human(), &d.report, elapsed);
    Ok(())
}

/// The plausibility gate on the emitted model, with the diagnosed log as the static evidence.
/// The emitted text is a plant file (the model plus effect sections), so it is read as one;
/// refused, nothing at all is written (the outputs are all or nothing).
fn gate_emitted(text: &str, log: &JointLog, force: bool) -> anyhow::Result<()> {
    let model = match host_sim::plant::PlantFile::parse(text, "--emit-model") {
        Ok(p) => p.model,
        Err(_) => ModelFile::parse(text, "--emit-model")?,
    };
    let gate = joint_analysis::plausible::check(&model, std::slice::from_ref(log));
    if gate.plausible() {
        return Ok(());
    }
    let why = gate.reasons().join("; ");
    if force {
        eprintln!("warning: --emit-model: implausible model written (--force): {why}");
        return Ok(());
    }
    anyhow::bail!("--emit-model: the emitted model is implausible, nothing written: {why} (--force writes it anyway)")
}

fn print_summary(o: &mut dyn Write, r: &diagnose::Report, secs: f64) {
    let u = r.gap.unit;
    match r.split.cross_fitted.zip(r.split.holdout_scored) {
        Some((k, scored)) => say!(
            o,
            "{} mode, {} samples ({} held out once each over {k} cross-fitted folds, {}), {:.2} s",
            r.mode,
            r.samples,
            scored,
            r.split.method,
            secs
        ),
        None => say!(
            o,
            "{} mode, {} samples ({} train / {} held out, {}), {:.2} s",
            r.mode,
            r.samples,
            r.split.train,
            r.split.holdout,
            r.split.method,
            secs
        ),
    }
    if let Some(p) = &r.prep {
        say!(o, "preparation: {}", p.summary());
        for n in &p.notes {
            say!(o, "  {n}");
        }
    }
    if let Some(rt) = &r.split.rest_tail {
        say!(
            o,
            "  the last {} samples (from t = {:.3} s) left out: the log and the model are both at rest there",
            rt.samples,
            rt.from_t
        );
    }
    say!(
        o,
        "gap: RMSE {:.4} {u} (held out {:.4}), noise floor ≈ {:.4} {u}",
        r.gap.rmse,
        r.gap.holdout_rmse,
        r.gap.noise_floor
    );
    if let Some(k) = r.gap.scored_samples {
        say!(o, "  (RMSE and regimes on the {k} samples scored; the others say nothing about the model: their direction of motion is unknown)");
    }
    if let Some(k) = r.gap.rest_creep_samples {
        say!(
            o,
            "  {k} samples inside rests step by the model's ±c: a creep below the q̇ resolution (direction unknown, left out)"
        );
    }
    if let Some(sd) = r.gap.qdd_noise_sd {
        say!(o, "  the log's q̈ carries white noise of ≈ {sd:.3} rad/s²: removed from the inertia's fit (errors in variables)");
    }
    say!(o, "where (share of squared residual, RMSE):");
    for g in &r.regimes {
        say!(o, "  {:<16} {:>6.1} %  {:.4} {u}   {}", g.name, 100.0 * g.share, g.rmse, g.where_);
    }
    say!(o, "effects (held-out RMSE after, shrink, p):");
    for e in &r.effects {
        say!(
            o,
            "  {:<24} {:.4} {u}  {:>6.1} %  p={:.2e} {}",
            e.effect,
            e.holdout_rmse_after,
            100.0 * e.shrink,
            e.p_value,
            if e.significant {
                "significant"
            } else if e.implausible.is_some() {
                "ruled out"
            } else {
                ""
            }
        );
    }
    for e in r.effects.iter().filter(|e| !e.significant) {
        if let Some(why) = &e.implausible {
            say!(o, "  ({} ruled out: {why})", e.effect);
        }
    }
    say!(
        o,
        "verdict: {} (held-out RMSE {:.4} → {:.4} {u}, shrink {:.1} %){}",
        r.verdict.effect,
        r.verdict.holdout_rmse_before,
        r.verdict.holdout_rmse_after,
        100.0 * r.verdict.shrink,
        if r.verdict.effects.len() > 1 {
            format!("; forward selection: {}", r.verdict.effects.join(" → "))
        } else {
            String::new()
        }
    );
    if !r.verdict.alternatives.is_empty() {
        say!(o, "this log cannot tell the verdict from:");
        for a in &r.verdict.alternatives {
            say!(o, "  {}: to tell them apart, {}", a.effect, a.test);
        }
    }
    if !r.verdict.closest.is_empty() {
        say!(o, "closest candidates (none explains the gap): {}", r.verdict.closest.join(", "));
    }
    if !r.not_determined.is_empty() {
        say!(o, "not determined by this log (the emitted model keeps the file's values):");
        for u in &r.not_determined {
            say!(o, "  {}: {}", u.params.join(", "), u.why);
            say!(o, "    to pin it: {}", u.test);
        }
    }
    for w in &r.warnings {
        say!(o, "warning: {w}");
    }
}
