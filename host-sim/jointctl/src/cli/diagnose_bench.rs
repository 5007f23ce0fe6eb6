//! `jointctl diagnose-bench`: how often `diagnose` names the effect that was withheld from the
//! model (see `host_sim::diagnose::bench` for how cases are drawn and scored).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use crate::bench;
use joint_formats::output::{FolderKind, Plan};

/// What `--dump DIR` writes; an existing folder holding only these is a previous dump and is
/// replaced as a whole, anything else in it makes the run refuse.
pub const DUMP: FolderKind =
    FolderKind { what: "a bench dump (case-N.csv, case-N.toml)", owns: |name| is_case_file(name) };

fn is_case_file(name: &str) -> bool {
    let stem = name.strip_suffix(".csv").or_else(|| name.strip_suffix(".toml"));
    stem.and_then(|s| s.strip_prefix("case-")).is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// Generate logs with a known effect withheld from the model, diagnose them blind, and print the
/// confusion matrix, the accuracy, the over-claim rate on `none` cases and the mean shrink.
///
/// Example:
///   jointctl diagnose-bench --cases 26 --seed 1 --json bench.json
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct DiagnoseBenchArgs {
    /// Number of cases (kinds cycle: none, each effect, parameters, a pair, none; 13 cover
    /// all), 1..=10000
    #[arg(long, default_value_t = 26, value_parser = num::count(1, 10_000))]
    pub cases: usize,
    /// Random seed for plants, effect sizes, noise and scenarios
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seconds per scenario (three scenarios per log, at 1 kHz; torque mode only: a free
    /// response lasts 2–4 s), 3 ≤ S ≤ 600
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = num::within(3.0, 600.0, "s"))]
    pub seconds: f64,
    /// Which mode the logs are diagnosed in: `torque` (sweeps, holds, hand motion with u and
    /// tau logged) or `trajectory` (free responses of an elastic joint, angles only)
    #[arg(long, default_value = "torque", value_parser = ["torque", "trajectory"])]
    pub mode: String,
    /// Write the full bench report (every case, the confusion matrix) as JSON here (- for
    /// stdout)
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Also write each case's log and model (case-N.csv, case-N.toml) into this directory, to
    /// re-run `jointctl diagnose` on one case by hand; built aside and moved into place whole
    /// (an existing DIR is replaced only if it holds a previous dump)
    #[arg(long, value_name = "DIR")]
    pub dump: Option<PathBuf>,
}

pub fn run(a: &DiagnoseBenchArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let json_out = plan.file_opt("--json", a.json.as_deref());
    let dump_out = plan.folder_opt("--dump", a.dump.as_deref(), DUMP);
    let outs = plan.check()?;
    let staged = dump_out.map(|s| outs.stage(s)).transpose()?;
    let mode = if a.mode == "trajectory" { bench::Mode::Trajectory } else { bench::Mode::Torque };
    let rep = bench::run_mode(mode, a.cases, a.seed, a.seconds, staged.as_ref().map(|s| s.path()), |r| {
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
    let json = match json_out {
        Some(slot) => {
            let mut s = outs.open(slot)?;
            s.write_all(serde_json::to_string_pretty(&rep)?.as_bytes())
                .with_context(|| format!("{}: cannot write", s.named()))?;
            Some(s)
        }
        None => None,
    };
    if let Some(st) = staged {
        st.commit()?;
    }
    if let Some(s) = json {
        s.commit()?;
    }
    let mut o = outs.human();
    let mut preds: Vec<String> = rep.confusion.values().flat_map(|m| m.keys().cloned()).collect();
    preds.sort();
    preds.dedup();
    say!(o, "confusion matrix (rows: withheld effect, columns: diagnosed):");
    say_raw!(o, "{:<45}", "");
    for (k, _) in preds.iter().enumerate() {
        say_raw!(o, " {:>4}", format!("[{k}]"));
    }
    say!(o);
    for (truth, row) in &rep.confusion {
        say_raw!(o, "{truth:<45}");
        for p in &preds {
            say_raw!(o, " {:>4}", row.get(p).copied().unwrap_or(0));
        }
        say!(o);
    }
    for (k, p) in preds.iter().enumerate() {
        say!(o, "  [{k}] = {p}");
    }
    let correct = rep.cases.iter().filter(|c| c.correct).count();
    say!(o, "accuracy        {:.1} % ({correct}/{})", 100.0 * rep.accuracy, rep.cases.len());
    say!(
        o,
        "over-claims     {} of {} none cases ({:.1} %)",
        rep.overclaims,
        rep.none_cases,
        100.0 * rep.overclaim_rate
    );
    say!(
        o,
        "mean shrink     {:.1} % diagnosed vs {:.1} % of the true effect's candidate (single-effect cases)",
        100.0 * rep.mean_shrink,
        100.0 * rep.mean_true_shrink
    );
    Ok(())
}
