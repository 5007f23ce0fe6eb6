//! `jointctl identify`: logged characterisation tests → model TOML (+ validation report).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use joint_analysis::identify::segments::Window;
use joint_analysis::identify::{self, Method, Options, Progress, Term};
use joint_formats::log::{self, JointLog};

/// Identify the joint model from logged tests and write the model TOML (ready for `push`).
///
/// Procedures (the papers'): friction from ± constant-velocity plateaus (robust bisquare fit
/// of a·v² + b·v + c, 95 % CIs); weight C_w0·sin(s·q + φ) from static poses; inertia and
/// offset from moving samples (zero-phase filtered, eq. 5); spring K from the static
/// torque–angle slope, J and B from a free oscillation; a gravity table over q and the other
/// joints' angles from static samples. Segments are found from the data; --window overrides.
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
    /// Output model TOML; written only when identification succeeds
    #[arg(long, value_name = "MODEL.toml")]
    pub out: PathBuf,
    /// Directory for the validation report (report.md, report.json, SVG plots)
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Use START..END seconds as a segment of KIND (plateau, static, motion, free) instead of
    /// the automatic search for that kind; repeatable
    #[arg(long = "window", value_name = "START:END:KIND")]
    pub windows: Vec<Window>,
    /// papers = the papers' procedures (plateaus, poses, motion); joint-ls = one least-squares
    /// fit of all rigid terms on every sample, for logs without plateaus or poses
    #[arg(long, value_parser = super::choice::described(&Method::NAMES), default_value = "papers")]
    pub method: Method,
    /// Zero-phase low-pass cut-off of the inertia (and joint-ls) fit, Hz
    #[arg(long, value_name = "HZ", default_value_t = 5.0)]
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

pub fn run(a: &IdentifyArgs) -> anyhow::Result<()> {
    if !(a.accel_cutoff.is_finite() && a.accel_cutoff > 0.0) {
        anyhow::bail!("--accel-cutoff {} must be a positive frequency in Hz", a.accel_cutoff);
    }
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
    let mf = identify::model_file(&id, name.as_deref())?;
    let rep = match &a.report {
        Some(dir) => {
            let r = identify::report::validate(&data, &opts, &id)?;
            identify::report::write_dir(dir, &r, &id, &data)
                .with_context(|| format!("writing the report to {}", dir.display()))?;
            Some(r)
        }
        None => None,
    };
    if let Some(b) = &progress.0 {
        b.finish_and_clear();
    }
    let text = mf.to_toml_string();
    log::write_atomic(&a.out, |w| std::io::Write::write_all(w, text.as_bytes()))
        .with_context(|| format!("writing {}", a.out.display()))?;
    if a.json {
        let v = serde_json::json!({ "model": a.out.display().to_string(), "identified": id, "report": rep });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{}", identify::report::summary_text(&id, rep.as_ref()));
        println!("wrote {}", a.out.display());
        if let Some(d) = &a.report {
            println!("report in {}", d.display());
        }
    }
    Ok(())
}
