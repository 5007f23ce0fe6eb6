//! `jointctl import`: convert a real logger's file into the joint-log CSV (spec §1).

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use joint_formats::import::{self, Format, ImportOpts};

/// Convert a data set's file into a joint log (CSV, spec §1).
///
/// Formats: dfki-pendulum (time,position,velocity,torque), jensen-free-swing
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
    /// Joint log to write
    #[arg(long, value_name = "LOG.csv")]
    pub out: PathBuf,
    /// Joint to extract (panda-gaz: 1..7, ur5e-friction: 0..5)
    #[arg(long)]
    pub joint: Option<usize>,
    /// ur5e-friction: motor-to-joint torque ratio
    #[arg(long, default_value_t = 101.0)]
    pub gear_ratio: f64,
    /// ur5e-friction: seconds each table row is held
    #[arg(long, default_value_t = 1.0)]
    pub hold: f64,
    /// ur5e-friction: sample rate of the written log, Hz
    #[arg(long, default_value_t = 1000.0)]
    pub rate: f64,
}

pub fn run(a: &ImportArgs) -> anyhow::Result<()> {
    let file = a.input.display().to_string();
    let text = std::fs::read_to_string(&a.input).with_context(|| format!("cannot read {file}"))?;
    let o = ImportOpts { joint: a.joint, gear_ratio: a.gear_ratio, hold: a.hold, rate: a.rate };
    let im = import::convert(a.format, &text, &file, &o).map_err(anyhow::Error::msg)?;
    im.log.write_file(&a.out).with_context(|| format!("writing {}", a.out.display()))?;
    for n in &im.notes {
        eprintln!("note: {n}");
    }
    println!(
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
