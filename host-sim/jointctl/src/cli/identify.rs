//! `jointctl identify`: logged characterisation tests → model TOML (+ validation report).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use joint_analysis::identify::segments::Window;
use joint_analysis::identify::{self, Method, Options, Progress, Term};
use joint_formats::log::JointLog;
use joint_formats::output::{FolderKind, Plan};

/// What `--report DIR` writes; an existing folder holding only these is a previous report and
/// is replaced as a whole, anything else in it makes the run refuse.
pub const REPORT: FolderKind = FolderKind {
    what: "an identification report (report.md, report.html, report.json, *.svg)",
    owns: |name| name == "report.md" || name == "report.html" || name == "report.json" || name.ends_with(".svg"),
};

/// Identify the joint model from logged tests and write the model TOML (ready for `push`).
///
/// Procedures (the papers'): friction from ± constant-velocity plateaus (robust bisquare fit
/// of a·v² + b·v + c, 95 % CIs); weight C_w0·sin(s·q + φ) from static poses; inertia and
/// offset from moving samples (zero-phase filtered, eq. 5); spring K from the static
/// torque–angle slope, J and B from a free oscillation; a gravity table over q and the other
/// joints' angles from static samples. Segments are found from the data; --window overrides.
/// A log without plateaus or poses gets the whole-log regression (--method auto).
///
/// Every parameter is reported with its 95 % CI and a status (determined, weakly determined,
/// not excited, with the test that would pin it); only determined ones are written, and only
/// when the held-out R² is at least 0.5 and the model passes the plausibility gate (--force
/// overrides those two). Otherwise nothing is written and the exit status is 1.
///
/// Example:
///   jointctl simulate --plant examples/plants/trunk-right.toml \
///       --controller examples/models/trunk-right.toml --scenario sweep,poses,hand \
///       --seconds 40 --out trunk.csv
///   jointctl identify --log trunk.csv --out trunk-identified.toml --report report/
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct IdentifyArgs {
    /// Joint log(s) (CSV, spec §1); repeat for several
    #[arg(long = "log", value_name = "FILE", required = true)]
    pub logs: Vec<PathBuf>,
    /// Terms to identify, comma-separated: friction, weight, inertia, offset, spring,
    /// gravity_table (over q and every q_<name> column; fused with the weight term when both)
    /// [default: friction,weight,inertia,offset with torque logs, spring with trajectory logs]
    #[arg(long, value_name = "LIST")]
    pub terms: Option<String>,
    /// Output model TOML, or - for stdout; written only when identification succeeds
    #[arg(long, value_name = "MODEL.toml")]
    pub out: PathBuf,
    /// Directory for the validation report (report.md, report.html, report.json, SVG plots); built aside and
    /// moved into place whole; an existing DIR is replaced only if it holds a previous report
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Use START..END seconds as a segment of KIND (plateau, static, motion, free) instead of
    /// the automatic search for that kind (0 ≤ START < END, finite); repeatable
    #[arg(long = "window", value_name = "START:END:KIND", value_parser = parse_window)]
    pub windows: Vec<Window>,
    /// auto = the papers' procedures where the log holds their tests (± plateaus, static poses,
    /// a free oscillation), the whole-log regression where it holds none; papers = the papers'
    /// procedures only; joint-ls = one least-squares fit of all rigid terms on every sample
    #[arg(long, value_parser = super::choice::described(&Method::NAMES), default_value = "auto")]
    pub method: Method,
    /// Write the model even when its held-out R² is below 0.5 or it fails the plausibility
    /// gate (it still holds the determined parameters only, and must pass the joint's check)
    #[arg(long)]
    pub force: bool,
    /// Zero-phase low-pass cut-off of the inertia (and joint-ls) fit, Hz (0 < HZ ≤ 10000; at or
    /// above the log's Nyquist frequency the filter passes everything)
    #[arg(long, value_name = "HZ", default_value_t = 5.0, value_parser = num::positive(10_000.0, "Hz"))]
    pub accel_cutoff: f64,
    /// Model name written to the TOML
    #[arg(long)]
    pub name: Option<String>,
    /// Print the results as one JSON object on stdout
    #[arg(long)]
    pub json: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
}

struct Bar(Option<indicatif::ProgressBar>);

impl Progress for Bar {
    fn stage(&self, msg: &str, done: u64, total: u64) {
        if let Some(b) = &self.0 {
            b.set_length(total);
            b.set_position(done);
            b.set_message(msg.to_string());
        }
    }
}

/// The analysis's own parse (finite, START < END) plus a window that starts before the log.
fn parse_window(s: &str) -> Result<Window, String> {
    let w: Window = s.parse()?;
    if w.start < 0.0 {
        return Err(format!("`{s}`: allowed: 0 ≤ START < END (seconds from the log's start)"));
    }
    Ok(w)
}

pub fn run(a: &IdentifyArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    for p in &a.logs {
        plan.input("--log", p);
    }
    let model_out = plan.file("--out", &a.out);
    let report_out = plan.folder_opt("--report", a.report.as_deref(), REPORT);
    if a.json {
        plan.stdout("--json");
    }
    let outs = plan.check()?;
    let mut logs = Vec::with_capacity(a.logs.len());
    for path in &a.logs {
        // Errors name the file, line and column; nothing is written on error.
        logs.push(JointLog::read_file(path)?);
    }
    let terms = match &a.terms {
        Some(t) => Term::parse_list(t).map_err(|e| anyhow::anyhow!("--terms: {e}"))?,
        None => Vec::new(),
    };
    let opts = Options {
        method: a.method,
        terms,
        windows: a.windows.clone(),
        accel_cutoff: a.accel_cutoff,
        name: a.name.clone(),
        ..Options::default()
    };
    let n: usize = logs.iter().map(JointLog::len).sum();
    let bar = (!a.quiet && n > 200_000).then(|| {
        let b = indicatif::ProgressBar::new(3);
        b.set_style(
            indicatif::ProgressStyle::with_template("{spinner} identify [{bar:20}] {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let progress = Bar(bar);
    let (data, id) = identify::identify(&logs, &opts, &progress)?;
    let name = a.name.clone().or_else(|| a.out.file_stem().map(|s| s.to_string_lossy().into_owned()));
    // The held-out refit always runs: the decision to write reads its quality.
    let rep = identify::report::validate(&data, &opts, &id)?;
    let decision = identify::decide::decide(&data, &id, &rep.quality, name.as_deref(), a.force)?;
    if let Some(b) = &progress.0 {
        b.finish_and_clear();
    }
    if let Some(mf) = &decision.model {
        // The report is built in a folder beside DIR; the model and the report are committed
        // only when both were written.
        let staged = match report_out {
            Some(slot) => {
                let st = outs.stage(slot)?;
                identify::report::write_dir(st.path(), &rep, &id, &data)
                    .with_context(|| format!("{}: cannot write the report", st.named()))?;
                Some(st)
            }
            None => None,
        };
        let mut sink = outs.open(model_out)?;
        sink.write_all(mf.to_toml_string().as_bytes()).with_context(|| format!("{}: cannot write", sink.named()))?;
        if let Some(st) = staged {
            st.commit()?;
        }
        sink.commit()?;
    }
    let mut o = outs.human();
    if a.json {
        let v = serde_json::json!({
            "model": a.out.display().to_string(),
            "written": decision.written,
            "decision": decision,
            "identified": id,
            "report": rep,
        });
        say!(o, "{}", serde_json::to_string_pretty(&v)?);
    } else {
        say_raw!(o, "{}", identify::report::preparation_text(&id, opts.accel_cutoff));
        say_raw!(o, "{}", identify::report::summary_text(&id, Some(&rep)));
        for c in &decision.plausibility.checked {
            say!(o, "plausibility: {c}");
        }
        for w in &decision.warnings {
            say!(o, "warning: {w}");
        }
        for f in &decision.overridden {
            say!(o, "forced past: {f}");
        }
        if decision.written {
            say!(o, "wrote {} ({})", a.out.display(), decision.params.join(", "));
            if let Some(d) = &a.report {
                say!(o, "report in {}", d.display());
            }
        }
    }
    if !decision.written {
        let force = if decision.params.is_empty() { "" } else { " (--force writes it anyway)" };
        anyhow::bail!("nothing written to {}: {}{force}", a.out.display(), decision.refused.join("; "));
    }
    Ok(())
}
