//! `jointctl import`: convert a real logger's file into the joint-log CSV (spec §1).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use joint_formats::import::{self, Format, ImportOpts};
use joint_formats::output::Plan;

/// Convert a data set's file into a joint log (CSV, spec §1).
///
/// Formats: dfki-pendulum (time,position,velocity,torque), dfki-double-pendulum (one joint
/// of the DFKI double pendulum's sys-id record; --joint 1..2), jensen-free-swing
/// (time_s_nominal,angle_deg), panda-gaz (one joint of the Panda exciting trajectory; --joint
/// 1..7), ur5e-friction (one joint of the UR5e friction table as held constant-velocity
/// stretches; --joint 0..5).
///
/// Example:
///   jointctl import --format dfki-pendulum \
///       --input shared/data/real/dfki_simple_pendulum/sysid_pd_swingup_measured.csv --out pendulum.csv
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct ImportArgs {
    #[arg(long, value_parser = super::choice::named(&Format::NAMES))]
    pub format: Format,
    /// Upstream file
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Joint log to write, or - for stdout
    #[arg(long, value_name = "LOG.csv")]
    pub out: PathBuf,
    /// Joint to extract (panda-gaz: 1..7, ur5e-friction: 0..5, dfki-double-pendulum: 1..2)
    #[arg(long, value_parser = num::count(0, 7))]
    pub joint: Option<usize>,
    /// ur5e-friction: motor-to-joint torque ratio (0 < N ≤ 1000)
    #[arg(long, default_value_t = 101.0, value_parser = num::positive(1000.0, ""))]
    pub gear_ratio: f64,
    /// ur5e-friction: seconds each table row is held (0 < S ≤ 3600; hold × rate ≤ 1e6 samples)
    #[arg(long, default_value_t = 1.0, value_parser = num::positive(3600.0, "s"))]
    pub hold: f64,
    /// ur5e-friction: sample rate of the written log, Hz (0 < HZ ≤ 100000)
    #[arg(long, default_value_t = 1000.0, value_parser = num::positive(100_000.0, "Hz"))]
    pub rate: f64,
}

/// Samples one held table row of ur5e-friction may take (the table has tens of rows).
const MAX_HOLD_SAMPLES: f64 = 1.0e6;

pub fn run(a: &ImportArgs) -> anyhow::Result<()> {
    if a.format == Format::Ur5eFriction {
        num::budget("samples per table row", &[("--hold", a.hold), ("--rate", a.rate)], MAX_HOLD_SAMPLES)?;
    }
    let mut plan = Plan::new();
    plan.input("--input", &a.input);
    let out = plan.file("--out", &a.out);
    let outs = plan.check()?;
    let file = a.input.display().to_string();
    let text = std::fs::read_to_string(&a.input).with_context(|| format!("cannot read {file}"))?;
    let o = ImportOpts { joint: a.joint, gear_ratio: a.gear_ratio, hold: a.hold, rate: a.rate };
    let im = import::convert(a.format, &text, &file, &o).map_err(anyhow::Error::msg)?;
    let mut sink = outs.open(out)?;
    im.log.write_csv(&mut sink).with_context(|| format!("{}: cannot write", sink.named()))?;
    sink.commit()?;
    for n in &im.notes {
        eprintln!("note: {n}");
    }
    say!(
        outs.human(),
        "wrote {} ({} samples, {} mode)",
        a.out.display(),
        im.log.len(),
        match im.log.mode() {
            joint_formats::log::LogMode::Torque => "torque",
            joint_formats::log::LogMode::Trajectory => "trajectory",
        }
    );
    Ok(())
}
