//! `jointctl closed-loop`: assistance tracking with the firmware core in the loop, its
//! parameters pushed over the simulated CAN bus, and an operator moving the trunk rod (trunk
//! paper §4); `--sweep-fraction` scans the compensated fraction F; `--workflow` runs the
//! before → log → diagnose → push → after loop of docs/closed-loop.md.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use serde_json::json;

use super::num;
use crate::closed_loop::{self, svg, workflow, LoopConfig, Setup};
use host_sim::plant::PlantFile;
use joint_core::params::ParamId;
use joint_formats::model_file::ModelFile;
use joint_formats::output::{FileSlot, FolderKind, FolderSlot, Outputs, Plan};

/// What `--workflow DIR` writes; an existing folder holding only these is a previous run's and
/// is replaced as a whole, anything else in it makes the run refuse.
pub const WORKFLOW: FolderKind = FolderKind {
    what: "a closed-loop workflow (run.csv, diagnosis.json, emitted.toml)",
    owns: |name| matches!(name, "run.csv" | "diagnosis.json" | "emitted.toml"),
};

/// Run closed-loop assistance trials: the joint node gets MODEL by SDO push on a simulated
/// CAN bus, runs u = (K·β + F·C_c)/(N − 1) at 1 kHz against PLANT (its effects, sensors and
/// [delay]), while an operator moves the trunk rod at random. Reports the RMSE between the
/// desired support torque K·β and the delivered torque (what the user feels), per trial and
/// mean ± sd, and whether the loop stayed stable.
///
/// Examples:
///   jointctl closed-loop --plant examples/plants/trunk-right.toml \
///       --model examples/models/trunk-right.toml --fraction 0.7 --json right.json
///   jointctl closed-loop --plant examples/plants/trunk-right.toml \
///       --model examples/models/trunk-right.toml --sweep-fraction --delay 0.01 --svg sweep.svg
///   jointctl closed-loop --plant examples/plants/trunk-right-stribeck.toml \
///       --model examples/models/trunk-right.toml --log run.csv
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ClosedLoopArgs {
    /// Plant TOML: the simulated joint (model, effects, [sensors], [delay], [joint_range])
    #[arg(long, value_name = "PLANT.toml")]
    pub plant: PathBuf,
    /// Model TOML pushed to the joint (its [compensation] section, with the flags below)
    #[arg(long, value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Compensated fraction F of C_c, 0 ≤ F ≤ 1 [default: the model's compensation.fraction]
    #[arg(long, value_name = "F", value_parser = num::param(ParamId::Fraction))]
    pub fraction: Option<f64>,
    /// Support stiffness K of the desired torque K·β, N·m/rad, −1000 ≤ K ≤ 1000 [default: the
    /// model's assist_k]
    #[arg(long, value_name = "K", allow_hyphen_values = true, value_parser = num::param(ParamId::AssistK))]
    pub assist_k: Option<f64>,
    /// Number of trials (seeds SEED, SEED+1, …), 1..=1000
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = num::count(1, 1000))]
    pub trials: usize,
    /// Scored seconds per trial, 1 ≤ S ≤ 3600
    #[arg(long, value_name = "S", default_value_t = 20.0, value_parser = num::within(1.0, 3600.0, "s"))]
    pub seconds: f64,
    /// Random seed of the first trial
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// Sensor delay in seconds, replacing the plant's [delay] (0 = none; 0 ≤ S ≤ 0.2)
    #[arg(long, value_name = "S", value_parser = num::within(0.0, 0.2, "s"))]
    pub delay: Option<f64>,
    /// Operator (hand) stiffness K_h, N·m/rad, 0 < K_h ≤ 1e5 [default: the plant's
    /// [operator], else a human grip on the rod, 60 N·m/rad with 2 N·m·s/rad
    /// (docs/closed-loop.md)]
    #[arg(long, value_name = "N·m/rad", requires = "operator_damping", value_parser = num::positive(1.0e5, "N·m/rad"))]
    pub operator_stiffness: Option<f64>,
    /// Operator (hand) damping B_h, N·m·s/rad, 0 ≤ B_h ≤ 1e4 (with --operator-stiffness)
    #[arg(long, value_name = "N·m·s/rad", requires = "operator_stiffness", value_parser = num::within(0.0, 1.0e4, "N·m·s/rad"))]
    pub operator_damping: Option<f64>,
    /// Write the JSON result here (- for stdout)
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Write the trials' joint log (CSV, spec §1; trials back to back) here (- for stdout;
    /// trials × seconds × 1 kHz ≤ 1e7 samples)
    #[arg(long, value_name = "LOG.csv")]
    pub log: Option<PathBuf>,
    /// Sweep the fraction F over 0, 0.1, …, 1 instead of one F
    #[arg(long)]
    pub sweep_fraction: bool,
    /// Step of the sweep, 0.01 ≤ STEP ≤ 1
    #[arg(long, value_name = "STEP", default_value_t = 0.1, value_parser = num::within(0.01, 1.0, ""))]
    pub sweep_step: f64,
    /// Write the sweep plot (SVG) here (- for stdout)
    #[arg(long, value_name = "OUT.svg")]
    pub svg: Option<PathBuf>,
    /// Run the fix workflow (trials → log → diagnose --emit-model → push → trials) and write
    /// its files (run.csv, diagnosis.json, emitted.toml) into this directory, built aside and
    /// moved into place whole (an existing DIR is replaced only if it holds a previous run's)
    #[arg(long, value_name = "DIR")]
    pub workflow: Option<PathBuf>,
}

/// The checked outputs of a run.
struct Outs {
    outs: Outputs,
    json: Option<FileSlot>,
    log: Option<FileSlot>,
    svg: Option<FileSlot>,
    workflow: Option<FolderSlot>,
}

impl Outs {
    /// Which option combinations write what, refused before any work: an output the mode would
    /// not write is an error, not silently ignored.
    fn check(a: &ClosedLoopArgs) -> anyhow::Result<Outs> {
        if a.svg.is_some() && !a.sweep_fraction {
            anyhow::bail!("--svg plots the fraction sweep: add --sweep-fraction");
        }
        if a.log.is_some() && a.sweep_fraction {
            anyhow::bail!("--log records one fraction's trials: leave it out of --sweep-fraction");
        }
        if a.workflow.is_some() && (a.log.is_some() || a.svg.is_some() || a.sweep_fraction) {
            anyhow::bail!(
                "--workflow writes its own run.csv and runs one fraction: leave out --log, --svg and --sweep-fraction"
            );
        }
        if a.log.is_some() {
            let terms = [("--trials", a.trials as f64), ("--seconds", a.seconds), ("1 kHz", 1000.0)];
            num::budget("log samples", &terms, num::MAX_LOG_SAMPLES)?;
        }
        let mut plan = Plan::new();
        plan.input("--plant", &a.plant).input("--model", &a.model);
        let json = plan.file_opt("--json", a.json.as_deref());
        let log = plan.file_opt("--log", a.log.as_deref());
        let svg = plan.file_opt("--svg", a.svg.as_deref());
        let workflow = plan.folder_opt("--workflow", a.workflow.as_deref(), WORKFLOW);
        Ok(Outs { outs: plan.check()?, json, log, svg, workflow })
    }

    fn write(&self, slot: Option<FileSlot>, text: &str) -> anyhow::Result<()> {
        if let Some(s) = slot {
            self.outs.write(s, text.as_bytes())?;
        }
        Ok(())
    }
}

fn paper_json(model: &str) -> serde_json::Value {
    let this = closed_loop::paper_for(model).map(|(j, _)| j);
    json!({
        "source": "trunk paper §4, ten hand-moved trials per joint at F = 0.7",
        "fraction": 0.7,
        "right": {"tracking_rmse_mean": closed_loop::PAPER_RIGHT.0, "tracking_rmse_sd": closed_loop::PAPER_RIGHT.1},
        "left": {"tracking_rmse_mean": closed_loop::PAPER_LEFT.0, "tracking_rmse_sd": closed_loop::PAPER_LEFT.1},
        "this_joint": this,
    })
}

fn bar(total: usize, what: &str) -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::new(total as u64);
    b.set_style(
        indicatif::ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    b.set_prefix(what.to_string());
    b
}

pub fn run(a: &ClosedLoopArgs) -> anyhow::Result<()> {
    let outs = Outs::check(a)?;
    let plant = PlantFile::read_file(&a.plant)?;
    let model = ModelFile::read_file(&a.model)?;
    let (pn, mn) = (a.plant.display().to_string(), a.model.display().to_string());
    let cfg = LoopConfig {
        fraction: a.fraction,
        assist_k: a.assist_k,
        trials: a.trials,
        seconds: a.seconds,
        seed: a.seed,
        delay: a.delay,
        keep_log: a.log.is_some(),
        operator: a.operator_stiffness.zip(a.operator_damping),
    };
    let mut o = outs.outs.human();
    if let Some(dir) = outs.workflow {
        return run_workflow(a, &outs, dir, (&plant, &model, &cfg), &mut o);
    }
    if a.sweep_fraction {
        let fr = closed_loop::sweep_fractions(a.sweep_step);
        let b = bar(fr.len(), "fractions");
        let pts = closed_loop::sweep(&plant, &model, &cfg, &fr, (&pn, &mn), &mut |d, _| b.set_position(d as u64))?;
        b.finish_and_clear();
        let setup = Setup::new(&plant, &model, &LoopConfig { fraction: Some(0.0), ..cfg.clone() }, &pn, &mn)?;
        let onset = closed_loop::instability_onset(&pts);
        say!(
            o,
            "fraction sweep on {pn} (sensor delay {:.1} ms, {} trials × {} s per point):",
            1e3 * setup.delay,
            a.trials,
            a.seconds
        );
        say!(o, "  {:>5}  {:>16}  {:>8}  {:>12}", "F", "RMSE N·m", "stable", "osc N·m RMS");
        for p in &pts {
            say!(
                o,
                "  {:>5.2}  {:>7.3} ± {:<6.3}  {:>8}  {:>12.3}",
                p.fraction,
                p.tracking_rmse_mean,
                p.tracking_rmse_sd,
                if p.stable { "yes" } else { "NO" },
                p.osc_torque_rms_max
            );
        }
        match onset {
            Some(f) => say!(o, "unstable from F = {f:.2} on"),
            None => say!(o, "no instability up to F = 1 with these settings"),
        }
        if outs.svg.is_some() {
            let title = format!(
                "{} — sensor delay {:.1} ms, {} × {} s trials per F",
                pn,
                1e3 * setup.delay,
                a.trials,
                a.seconds
            );
            outs.write(outs.svg, &svg::render(&pts, &title))?;
        }
        if outs.json.is_some() {
            let j = json!({
                "plant": pn, "model": mn, "sensor_delay_s": setup.delay, "trials_per_point": a.trials,
                "seconds": a.seconds, "seed": a.seed, "assist_k": setup.assist_k,
                "operator_stiffness": setup.k_h, "operator_damping": setup.b_h,
                "instability_onset_fraction": onset,
                "stability_criterion": criterion_text(),
                "sweep": pts,
                "paper": paper_json(&mn),
            });
            outs.write(outs.json, &serde_json::to_string_pretty(&j)?)?;
        }
        return Ok(());
    }
    let setup = Setup::new(&plant, &model, &cfg, &pn, &mn)?;
    let b = bar(cfg.trials, "trials");
    let r = closed_loop::run(&setup, &cfg, &mut |d, _| b.set_position(d as u64))?;
    b.finish_and_clear();
    say!(
            o,
        "{} trials of {} s on {pn}, model {mn} pushed by SDO ({} transfers, {:.1} ms), F = {:.2}, K = {:.2} N·m/rad, delay {:.1} ms",
        r.trials.len(),
        r.seconds,
        r.push.sdo_transfers,
        r.push.elapsed_us as f64 / 1e3,
        r.fraction,
        r.assist_k,
        1e3 * r.sensor_delay_s
    );
    for (i, t) in r.trials.iter().enumerate() {
        say!(
            o,
            "  trial {:>2} (seed {}): RMSE {:.3} N·m  {}",
            i + 1,
            t.seed,
            t.rmse,
            if t.stable { "stable".to_string() } else { format!("UNSTABLE: {}", t.stability.why.join("; ")) }
        );
    }
    say!(
        o,
        "tracking RMSE {:.3} ± {:.3} N·m, {}",
        r.tracking_rmse_mean,
        r.tracking_rmse_sd,
        if r.stable { "stable" } else { "NOT stable" }
    );
    if let Some((j, (m, s))) = closed_loop::paper_for(&mn) {
        say!(o, "paper ({j} joint, F = 0.7): {m:.2} ± {s:.2} N·m");
    }
    // Both outputs are written to their temporary files before either is committed.
    let log_sink = match (outs.log, &r.log) {
        (Some(slot), Some(l)) => {
            let mut s = outs.outs.open(slot)?;
            l.write_csv(&mut s).with_context(|| format!("{}: cannot write", s.named()))?;
            Some(s)
        }
        _ => None,
    };
    if outs.json.is_some() {
        let mut j = serde_json::to_value(&r)?;
        if let Some(obj) = j.as_object_mut() {
            obj.insert("paper".into(), paper_json(&mn));
            obj.insert("stability_criterion".into(), json!(criterion_text()));
        }
        outs.write(outs.json, &serde_json::to_string_pretty(&j)?)?;
    }
    if let Some(s) = log_sink {
        s.commit()?;
    }
    Ok(())
}

fn criterion_text() -> String {
    use closed_loop::limits::*;
    format!(
        "stable = no divergence (finite state), q within the joint range ± {RANGE_MARGIN} rad, |q̇| ≤ {QD_MAX} rad/s, and no sustained oscillation: \
         the delivered torque minus its {OSC_WINDOW} s centred moving average (what lies above the hand-motion band) stays ≤ {OSC_TORQUE_RMS} N·m RMS \
         in every 1 s window of the trial's second half"
    )
}

fn run_workflow(
    a: &ClosedLoopArgs,
    outs: &Outs,
    dir: FolderSlot,
    (plant, model, cfg): (&PlantFile, &ModelFile, &LoopConfig),
    out: &mut dyn Write,
) -> anyhow::Result<()> {
    let (pn, mn) = (a.plant.display().to_string(), a.model.display().to_string());
    let o = workflow::run_workflow(plant, model, cfg, (&pn, &mn))?;
    let ceiling = workflow::ceiling(plant, model, cfg, (&pn, &mn))?;
    let st = outs.outs.stage(dir)?;
    let files = || -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(st.path().join("run.csv"))?);
        o.log.write_csv(&mut f)?;
        f.flush()?;
        std::fs::write(st.path().join("diagnosis.json"), &o.diagnosis_json)?;
        std::fs::write(st.path().join("emitted.toml"), &o.emitted_model)
    };
    files().with_context(|| format!("{}: cannot write", st.named()))?;
    say!(out, "plant effects: {}", if o.plant_effects.is_empty() { "none".into() } else { o.plant_effects.join(", ") });
    say!(
        out,
        "before: tracking {:.3} ± {:.3} N·m, model error {:.3} ± {:.3} N·m",
        o.before.tracking_rmse_mean,
        o.before.tracking_rmse_sd,
        o.before.model_error_rmse_mean,
        o.before.model_error_rmse_sd
    );
    say!(out, "diagnose verdict: {} (selected: {})", o.verdict, o.selected.join(" → "));
    if !o.dropped_effects.is_empty() {
        say!(
            out,
            "the emitted model needs {}, which the firmware cannot compensate: not pushed, the old model stays (the refit was made together with that term)",
            o.dropped_effects.join(", ")
        );
    }
    say!(
        out,
        "after:  tracking {:.3} ± {:.3} N·m ({:.0} % of before), model error {:.3} ± {:.3} N·m ({:.0} % of before)",
        o.after.tracking_rmse_mean,
        o.after.tracking_rmse_sd,
        100.0 * o.ratio,
        o.after.model_error_rmse_mean,
        o.after.model_error_rmse_sd,
        100.0 * o.model_error_ratio
    );
    if let Some(c) = &ceiling {
        say!(
            out,
            "ceiling (true effect parameters, no diagnosis): tracking {:.3} ± {:.3} N·m, model error {:.3} ± {:.3} N·m",
            c.tracking_rmse_mean,
            c.tracking_rmse_sd,
            c.model_error_rmse_mean,
            c.model_error_rmse_sd
        );
    }
    let json = match outs.json {
        Some(slot) => {
            let j = json!({"plant": pn, "model": mn, "workflow": o, "ceiling_true_parameters": ceiling});
            let mut s = outs.outs.open(slot)?;
            s.write_all(serde_json::to_string_pretty(&j)?.as_bytes())
                .with_context(|| format!("{}: cannot write", s.named()))?;
            Some(s)
        }
        None => None,
    };
    st.commit()?;
    if let Some(s) = json {
        s.commit()?;
    }
    Ok(())
}
