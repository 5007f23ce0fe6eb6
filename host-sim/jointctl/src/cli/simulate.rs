//! `jointctl simulate`: run the firmware core against a simulated joint and write a joint log.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{self, SimConfig};
use joint_core::params::ParamId;
use joint_formats::model_file::ModelFile;
use joint_formats::output::Plan;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Simulate a joint running the firmware's control core and write a joint log (CSV).
///
/// The plant file is the "true" joint (a model TOML plus optional unmodelled effects and
/// sensor noise); the controller file is the model the firmware core compensates with. When
/// both hold the same model, the residual `u − tau − model` is sensor noise only.
///
/// Example:
///   jointctl simulate --plant examples/plants/trunk-right.toml \
///       --controller examples/models/trunk-right.toml --scenario sweep,poses,hand \
///       --seconds 20 --out out/trunk.csv
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct SimulateArgs {
    /// Plant TOML: the simulated joint's true dynamics, effects and sensors
    #[arg(long, value_name = "PLANT.toml")]
    pub plant: PathBuf,
    /// Model TOML the controller (the firmware core) runs with
    #[arg(long, value_name = "MODEL.toml")]
    pub controller: PathBuf,
    /// What happens to the joint, comma-separated to run several back to back in one log:
    /// sweep = velocity-controlled back-and-forth strokes at 5…90 deg/s;
    /// poses = position holds in 10° steps; free = held, then released (free oscillation);
    /// hand = an operator moves the joint at random while the core assists
    #[arg(long, value_name = "LIST", default_value = "sweep", value_parser = parse_scenarios)]
    pub scenario: ScenarioList,
    /// Duration of EACH scenario in the list, seconds (0 < S ≤ 86400; the whole log at most
    /// 1e7 samples and 1e9 plant steps)
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = num::positive(86_400.0, "s"))]
    pub seconds: f64,
    /// Output joint log (CSV), or - for stdout; written only if the whole run succeeds
    #[arg(long, value_name = "LOG.csv")]
    pub out: PathBuf,
    /// Random seed: the same seed gives the same log, byte for byte
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control (and log) rate in Hz, 100 ≤ HZ ≤ 10000 (the core's controller.rate_hz range)
    /// [default: the controller model's controller.rate_hz, 1000]
    #[arg(long, value_name = "HZ", value_parser = num::param(ParamId::ControlRateHz))]
    pub rate: Option<f64>,
    /// Plant integration rate in Hz (RK4; an integer multiple ≥ 10× of the control rate;
    /// 1000 ≤ HZ ≤ 1e6)
    #[arg(long, value_name = "HZ", default_value_t = 10_000.0, value_parser = num::within(1_000.0, 1.0e6, "Hz"))]
    pub plant_rate: f64,
    /// Joint range in degrees, "MIN,MAX" (−360 ≤ MIN < MAX ≤ 360) [default: the plant's
    /// [joint_range], else 0,116.5]
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_range, allow_hyphen_values = true)]
    pub range: Option<(f64, f64)>,
    /// Angle in degrees where `free` releases the joint (−360 ≤ DEG ≤ 360) [default: 75 % of
    /// the range]
    #[arg(long, value_name = "DEG", allow_hyphen_values = true, value_parser = num::within(-360.0, 360.0, "deg"))]
    pub free_start: Option<f64>,
    /// Leave out u and tau: write a trajectory-mode log (t, q, qd, qdd)
    #[arg(long)]
    pub no_torque: bool,
    /// Print the summary as one JSON object on stdout
    #[arg(long)]
    pub json: bool,
}

/// A comma-separated scenario list (a newtype so clap takes the list as one value).
#[derive(Clone, Debug)]
pub struct ScenarioList(pub Vec<ScenarioKind>);

fn parse_scenarios(s: &str) -> Result<ScenarioList, String> {
    ScenarioKind::parse_list(s).map(ScenarioList)
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("`{s}`: expected MIN,MAX in degrees"))?;
    let p = |x: &str| x.trim().parse::<f64>().map_err(|_| format!("`{x}` is not a number"));
    let (lo, hi) = (p(a)?, p(b)?);
    if !(lo.is_finite() && hi.is_finite() && hi > lo && lo >= -360.0 && hi <= 360.0) {
        return Err(format!("`{s}`: allowed: -360 ≤ MIN < MAX ≤ 360 degrees"));
    }
    Ok((lo, hi))
}

pub fn run(a: &SimulateArgs) -> anyhow::Result<()> {
    let scenarios: Vec<ScenarioKind> = a.scenario.0.clone();
    let n = scenarios.len() as f64;
    let steps = [("--plant-rate", a.plant_rate), ("--seconds", a.seconds), ("scenarios", n)];
    num::budget("plant steps", &steps, num::MAX_PLANT_STEPS)?;
    if let Some(r) = a.rate {
        num::budget("log samples", &[("--rate", r), ("--seconds", a.seconds), ("scenarios", n)], num::MAX_LOG_SAMPLES)?;
    }
    let mut plan = Plan::new();
    plan.input("--plant", &a.plant).input("--controller", &a.controller);
    let out = plan.file("--out", &a.out);
    if a.json {
        plan.stdout("--json");
    }
    let outs = plan.check()?;
    let plant = PlantFile::read_file(&a.plant)?;
    let model = ModelFile::read_file(&a.controller)?;
    let params = model.param_set()?;
    if a.rate.is_none() {
        let r = f64::from(params.get(ParamId::ControlRateHz));
        let terms = [("controller.rate_hz", r), ("--seconds", a.seconds), ("scenarios", n)];
        num::budget("log samples", &terms, num::MAX_LOG_SAMPLES)?;
    }
    let cfg = SimConfig {
        scenarios: scenarios.clone(),
        seconds: a.seconds,
        seed: a.seed,
        rate: a.rate,
        plant_rate: a.plant_rate,
        range: a.range.map(|(lo, hi)| (lo * DEG, hi * DEG)),
        free_start: a.free_start.map(|d| d * DEG),
        torque_columns: !a.no_torque,
    };
    eprintln!(
        "simulating {} s of {:?} on plant {} with controller {}",
        a.seconds * scenarios.len() as f64,
        scenarios,
        a.plant.display(),
        a.controller.display()
    );
    let (log, info) = sim::simulate(&plant, &params, &cfg)?;
    let mut sink = outs.open(out)?;
    log.write_csv(&mut sink).with_context(|| format!("--out {}: cannot write the log", a.out.display()))?;
    sink.commit()?;
    let s = sim::summarize(&log, &params, &model.other_columns(), Some((&plant.sensors, a.seed)));
    let mut o = outs.human();
    if a.json {
        let v = serde_json::json!({ "out": a.out.display().to_string(), "summary": s, "run": info });
        say!(o, "{v}");
    } else {
        say!(
            o,
            "wrote {} ({} samples, {:.3} s, {} mode)",
            a.out.display(),
            s.samples,
            s.duration_s,
            match s.mode {
                joint_formats::log::LogMode::Torque => "torque",
                joint_formats::log::LogMode::Trajectory => "trajectory",
            }
        );
        say!(o, "  columns          {}", s.columns.join(","));
        say!(
            o,
            "  q range          {:.4} … {:.4} rad ({:.1} … {:.1}°)",
            s.q_min,
            s.q_max,
            s.q_min / DEG,
            s.q_max / DEG
        );
        if let (Some(u), Some(t)) = (s.rms_u, s.rms_tau) {
            say!(o, "  RMS u, tau       {u:.3}, {t:.3} N·m");
        }
        if let Some(r) = s.rms_residual {
            say!(o, "  RMS residual     {r:.3} N·m  (d = u − tau minus the controller model's prediction)");
        }
        if let Some(f) = s.noise_floor {
            say!(o, "  noise floor      {f:.3} N·m  (expected from the plant's sensor noise)");
        }
    }
    Ok(())
}
