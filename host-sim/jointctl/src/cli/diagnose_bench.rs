//! `jointctl diagnose-bench`: how often `diagnose` names the effect that was withheld from the
//! model (see `host_sim::diagnose::bench` for how cases are drawn and scored).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::bench;
use joint_formats::log::write_atomic;

/// Generate logs with a known effect withheld from the model, diagnose them blind, and print the
/// confusion matrix, the accuracy, the over-claim rate on `none` cases and the mean shrink.
///
/// Example:
///   jointctl diagnose-bench --cases 26 --seed 1 --json bench.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct DiagnoseBenchArgs {
    /// Number of cases (kinds cycle: none, each effect, parameters, a pair, none; 13 cover all)
    #[arg(long, default_value_t = 26)]
    pub cases: usize,
    /// Random seed for plants, effect sizes, noise and scenarios
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seconds per scenario (three scenarios per log, at 1 kHz; torque mode only: a free
    /// response lasts 2–4 s)
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Which mode the logs are diagnosed in: `torque` (sweeps, holds, hand motion with u and
    /// tau logged) or `trajectory` (free responses of an elastic joint, angles only)
    #[arg(long, default_value = "torque", value_parser = ["torque", "trajectory"])]
    pub mode: String,
    /// Write the full bench report (every case, the confusion matrix) as JSON here
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Also write each case's log and model (case-N.csv, case-N.toml) into this directory, to
    /// re-run `jointctl diagnose` on one case by hand
    #[arg(long, value_name = "DIR")]
    pub dump: Option<PathBuf>,
}

pub fn run(a: &DiagnoseBenchArgs) -> anyhow::Result<()> {
    if a.cases == 0 || !(a.seconds.is_finite() && a.seconds >= 3.0) {
        anyhow::bail!("--cases must be ≥ 1 and --seconds ≥ 3");
    }
    if let Some(d) = &a.dump {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create", d.display()))?;
    }
    let mode = if a.mode == "trajectory" { bench::Mode::Trajectory } else { bench::Mode::Torque };
    let rep = bench::run_mode(mode, a.cases, a.seed, a.seconds, a.dump.as_deref(), |r| {
        eprintln!(
            "case {:>3}: {:<8} truth {:<40} → {:<40} {} ({:.2} s)",
            r.case,
            r.joint,
            r.truth,
            r.predicted,
            if r.correct { "ok" } else { "WRONG" },
            r.seconds
        );
    })
    .map_err(|e| anyhow::anyhow!(e))?;
    if let Some(p) = &a.json {
        let s = serde_json::to_string_pretty(&rep)?;
        write_atomic(p, |f| std::io::Write::write_all(f, s.as_bytes()))
            .with_context(|| format!("{}: cannot write", p.display()))?;
    }
    let mut preds: Vec<String> = rep.confusion.values().flat_map(|m| m.keys().cloned()).collect();
    preds.sort();
    preds.dedup();
    println!("confusion matrix (rows: withheld effect, columns: diagnosed):");
    print!("{:<45}", "");
    for (k, _) in preds.iter().enumerate() {
        print!(" {:>4}", format!("[{k}]"));
    }
    println!();
    for (truth, row) in &rep.confusion {
        print!("{truth:<45}");
        for p in &preds {
            print!(" {:>4}", row.get(p).copied().unwrap_or(0));
        }
        println!();
    }
    for (k, p) in preds.iter().enumerate() {
        println!("  [{k}] = {p}");
    }
    let correct = rep.cases.iter().filter(|c| c.correct).count();
    println!("accuracy        {:.1} % ({correct}/{})", 100.0 * rep.accuracy, rep.cases.len());
    println!(
        "over-claims     {} of {} none cases ({:.1} %)",
        rep.overclaims,
        rep.none_cases,
        100.0 * rep.overclaim_rate
    );
    println!(
        "mean shrink     {:.1} % diagnosed vs {:.1} % of the true effect's candidate (single-effect cases)",
        100.0 * rep.mean_shrink,
        100.0 * rep.mean_true_shrink
    );
    Ok(())
}
