//! `jointctl diagnose`: where the sim-to-real gap lies, which effect causes it, how far it
//! shrinks. Output files are written through a temporary file and a rename, and only after the
//! whole diagnosis succeeded, so a refused input never leaves a report behind.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use joint_analysis::diagnose::{self, Options};
use joint_formats::log::{write_atomic, JointLog};
use joint_formats::model_file::ModelFile;

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
    /// Write the diagnosis JSON (spec §3) here
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML report (inline SVG plots) here
    #[arg(long, value_name = "OUT.html")]
    pub report: Option<PathBuf>,
    /// Write the refitted model plus the selected effects' sections (plant TOML) here
    #[arg(long, value_name = "OUT.toml")]
    pub emit_model: Option<PathBuf>,
    /// At most this many effects in the forward selection
    #[arg(long, default_value_t = 3)]
    pub max_effects: usize,
}

pub fn run(a: &DiagnoseArgs) -> anyhow::Result<()> {
    let log = JointLog::read_file(&a.log)?;
    let model = ModelFile::read_file(&a.model)?;
    let t0 = std::time::Instant::now();
    let d = diagnose::diagnose(&log, &model, &Options { max_effects: a.max_effects.max(1) })
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.log.display()))?;
    let elapsed = t0.elapsed().as_secs_f64();
    // Render everything first, then write: nothing is written unless everything succeeded.
    let json = serde_json::to_string_pretty(&d.report)?;
    let html = a.report.as_ref().map(|_| diagnose::report_html::render(&d));
    if let Some(p) = &a.json {
        write_atomic(p, |f| std::io::Write::write_all(f, json.as_bytes()))
            .with_context(|| format!("{}: cannot write", p.display()))?;
    }
    if let (Some(p), Some(h)) = (&a.report, &html) {
        write_atomic(p, |f| std::io::Write::write_all(f, h.as_bytes()))
            .with_context(|| format!("{}: cannot write", p.display()))?;
    }
    if let Some(p) = &a.emit_model {
        write_atomic(p, |f| std::io::Write::write_all(f, d.emitted_model.as_bytes()))
            .with_context(|| format!("{}: cannot write", p.display()))?;
    }
    print_summary(&d.report, elapsed);
    Ok(())
}

fn print_summary(r: &diagnose::Report, secs: f64) {
    let u = r.gap.unit;
    println!(
        "{} mode, {} samples ({} train / {} held out, {}), {:.2} s",
        r.mode, r.samples, r.split.train, r.split.holdout, r.split.method, secs
    );
    if let Some(rt) = &r.split.rest_tail {
        println!(
            "  the last {} samples (from t = {:.3} s) left out: the log and the model are both at rest there",
            rt.samples, rt.from_t
        );
    }
    println!(
        "gap: RMSE {:.4} {u} (held out {:.4}), noise floor ≈ {:.4} {u}",
        r.gap.rmse, r.gap.holdout_rmse, r.gap.noise_floor
    );
    if let Some(sd) = r.gap.qdd_noise_sd {
        println!("  the log's q̈ carries white noise of ≈ {sd:.3} rad/s²: removed from the inertia's fit (errors in variables)");
    }
    println!("where (share of squared residual, RMSE):");
    for g in &r.regimes {
        println!("  {:<16} {:>6.1} %  {:.4} {u}   {}", g.name, 100.0 * g.share, g.rmse, g.where_);
    }
    println!("effects (held-out RMSE after, shrink, p):");
    for e in &r.effects {
        println!(
            "  {:<24} {:.4} {u}  {:>6.1} %  p={:.2e} {}",
            e.effect,
            e.holdout_rmse_after,
            100.0 * e.shrink,
            e.p_value,
            if e.significant {
                "significant"
            } else if e.implausible.is_some() {
                "implausible sign"
            } else {
                ""
            }
        );
    }
    println!(
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
    for w in &r.warnings {
        println!("warning: {w}");
    }
}
