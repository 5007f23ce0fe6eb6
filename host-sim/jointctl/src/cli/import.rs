//! `jointctl import`: convert a logger's file, a bus capture or a ROS 2 bag into the joint-log
//! CSV (spec §1). Every importer's page: docs/import.md.

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use super::num;
use joint_formats::import::candump::{self, DecodeOpts};
use joint_formats::import::csv_map::{CsvOpts, Decimal, Delimiter};
use joint_formats::import::eds::PdoMap;
use joint_formats::import::mcap::{Axis, McapOpts};
use joint_formats::import::{self, Format, ImportOpts};
use joint_formats::log::JointLog;
use joint_formats::output::Plan;

/// Convert a file into a joint log (CSV, spec §1). Format pages: docs/import.md.
///
/// Formats:
///   csv        any delimited file through a column map (--map; docs/import.md#csv)
///   candump    a can-utils bus capture (candump -l) decoded through the node's EDS (--eds,
///              --node; docs/import.md#candump)
///   mcap       a ROS 2 bag: sensor_msgs/JointState (--topic, --joint-name) and an optional
///              torque topic (--tau-topic; docs/import.md#mcap)
///   dfki-pendulum, dfki-double-pendulum (--joint 1..2), jensen-free-swing, panda-gaz (--joint
///   1..7), ur5e-friction (--joint 0..5): the data sets in shared/data/real
///   (docs/import.md#data-sets)
///
/// Examples:
///   jointctl import --format csv --input run.csv --out log.csv \
///       --map t=time_s,q=angle_deg:deg,u=motor_current_A:*0.75*160,tau=0
///   jointctl import --format candump --input bus.log --eds joint.eds --node 5 --out log.csv
///   jointctl import --format mcap --input run.mcap --topic /joint_states --joint-name knee --out log.csv
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
    /// csv: COLUMN=SOURCE[:UNIT|*X|/X|+X|-X…], comma-separated (docs/import.md#csv); candump:
    /// COLUMN=OBJECT_NAME[:…] over the EDS's mapped objects (default: the joint's own EDS)
    #[arg(long, value_name = "MAP")]
    pub map: Option<String>,
    /// csv: the delimiter (default: detected)
    #[arg(long, value_parser = super::choice::named(&Delimiter::NAMES))]
    pub delimiter: Option<Delimiter>,
    /// csv: the decimal mark, point or comma (default: detected)
    #[arg(long, value_parser = super::choice::named(&[("point", Decimal::Point), ("comma", Decimal::Comma)]))]
    pub decimal: Option<Decimal>,
    /// candump: the node's EDS or DCF (its TPDO mapping decodes the capture)
    #[arg(long, value_name = "FILE.eds")]
    pub eds: Option<PathBuf>,
    /// candump: node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: Option<u8>,
    /// candump with the joint's EDS: the joint has a load cell, its torque is `tau`
    #[arg(long)]
    pub load_cell: bool,
    /// mcap: the sensor_msgs/JointState topic
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// mcap: the joint's name in JointState.name
    #[arg(long, value_name = "NAME")]
    pub joint_name: Option<String>,
    /// mcap: topic of the measured external torque (std_msgs/Float64, geometry_msgs/WrenchStamped
    /// or JointState effort of the same joint)
    #[arg(long, value_name = "TOPIC")]
    pub tau_topic: Option<String>,
    /// mcap: the WrenchStamped torque axis
    #[arg(long, default_value = "z", value_parser = super::choice::named(&Axis::NAMES))]
    pub tau_axis: Axis,
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

/// The options a format needs and the ones it does not take, checked before any file is read.
fn check_options(a: &ImportArgs) -> anyhow::Result<()> {
    let page = |anchor: &str| format!("see docs/import.md#{anchor}");
    let given = |name: &str, set: bool, formats: &str| -> anyhow::Result<()> {
        if set {
            anyhow::bail!("{name} applies to --format {formats} only");
        }
        Ok(())
    };
    let csv = a.format == Format::Csv;
    let can = a.format == Format::Candump;
    let bag = a.format == Format::Mcap;
    given("--delimiter", a.delimiter.is_some() && !csv, "csv")?;
    given("--decimal", a.decimal.is_some() && !csv, "csv")?;
    given("--map", a.map.is_some() && !csv && !can, "csv or candump")?;
    given("--eds", a.eds.is_some() && !can, "candump")?;
    given("--node", a.node.is_some() && !can, "candump")?;
    given("--load-cell", a.load_cell && !can, "candump")?;
    for (n, set) in [
        ("--topic", a.topic.is_some()),
        ("--joint-name", a.joint_name.is_some()),
        ("--tau-topic", a.tau_topic.is_some()),
    ] {
        given(n, set && !bag, "mcap")?;
    }
    match a.format {
        Format::Csv if a.map.is_none() => {
            anyhow::bail!("--format csv needs --map (e.g. --map t=time,q=angle:deg; {})", page("csv"))
        }
        Format::Candump if a.eds.is_none() || a.node.is_none() => {
            anyhow::bail!("--format candump needs --eds FILE and --node ID ({})", page("candump"))
        }
        Format::Candump if a.load_cell && a.map.is_some() => {
            anyhow::bail!("--load-cell sets the default map; with --map, map tau yourself ({})", page("candump"))
        }
        Format::Mcap if a.topic.is_none() || a.joint_name.is_none() => {
            anyhow::bail!("--format mcap needs --topic TOPIC and --joint-name NAME ({})", page("mcap"))
        }
        _ => Ok(()),
    }
}

/// The docs/import.md section of a format, named in every error of its reader.
fn page(f: Format) -> &'static str {
    match f {
        Format::Csv => "docs/import.md#csv",
        Format::Candump => "docs/import.md#candump",
        Format::Mcap => "docs/import.md#mcap",
        _ => "docs/import.md#data-sets",
    }
}

pub fn run(a: &ImportArgs) -> anyhow::Result<()> {
    check_options(a)?;
    convert_and_write(a).map_err(|e| anyhow::anyhow!("{e:#}\n(the format: {})", page(a.format)))
}

fn convert_and_write(a: &ImportArgs) -> anyhow::Result<()> {
    if a.format == Format::Ur5eFriction {
        num::budget("samples per table row", &[("--hold", a.hold), ("--rate", a.rate)], MAX_HOLD_SAMPLES)?;
    }
    let mut plan = Plan::new();
    plan.input("--input", &a.input);
    if let Some(e) = &a.eds {
        plan.input("--eds", e);
    }
    let out = plan.file("--out", &a.out);
    let outs = plan.check()?;
    let file = a.input.display().to_string();
    let read_text = |p: &PathBuf| -> anyhow::Result<String> {
        std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))
    };
    // what the format gives: a log, or (candump) CSV text with the fault and NMT columns
    let (text, rows, mode, notes) = match a.format {
        Format::Candump => {
            let eds_path = a.eds.as_ref().context("--eds")?;
            let eds_file = eds_path.display().to_string();
            let node = a.node.context("--node")?;
            let pdos = PdoMap::from_eds(&read_text(eds_path)?, &eds_file, node).map_err(anyhow::Error::msg)?;
            let (records, errors) = candump::parse_capture(&read_text(&a.input)?, &file).map_err(anyhow::Error::msg)?;
            let o = DecodeOpts { node, map: a.map.clone().unwrap_or_default(), load_cell: a.load_cell };
            let d = candump::decode(records.iter().map(candump::Record::view), &pdos, &o)
                .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
            // the decoded text is a joint log: the spec's reader must take it
            let log = JointLog::parse(d.csv.as_bytes(), &file).context("decoded capture")?;
            let mut notes = d.notes;
            if errors > 0 {
                notes.push(format!("{errors} error frames in the capture: skipped"));
            }
            (d.csv.into_bytes(), log.len(), log.mode(), notes)
        }
        _ => {
            let (log, notes) = if a.format == Format::Mcap {
                let bytes = std::fs::read(&a.input).with_context(|| format!("cannot read {file}"))?;
                let o = McapOpts {
                    topic: a.topic.clone().unwrap_or_default(),
                    joint: a.joint_name.clone().unwrap_or_default(),
                    tau_topic: a.tau_topic.clone(),
                    tau_axis: a.tau_axis,
                };
                import::mcap::convert(&bytes, &file, &o).map_err(anyhow::Error::msg)?
            } else {
                let o = ImportOpts {
                    joint: a.joint,
                    gear_ratio: a.gear_ratio,
                    hold: a.hold,
                    rate: a.rate,
                    csv: CsvOpts { map: a.map.clone().unwrap_or_default(), delimiter: a.delimiter, decimal: a.decimal },
                };
                let im = import::convert(a.format, &read_text(&a.input)?, &file, &o).map_err(anyhow::Error::msg)?;
                (im.log, im.notes)
            };
            let mut bytes = Vec::new();
            log.write_csv(&mut bytes).context("cannot format the log")?;
            (bytes, log.len(), log.mode(), notes)
        }
    };
    let mut sink = outs.open(out)?;
    sink.write_all(&text).with_context(|| format!("{}: cannot write", sink.named()))?;
    sink.commit()?;
    for n in &notes {
        eprintln!("note: {n}");
    }
    say!(
        outs.human(),
        "wrote {} ({} samples, {} mode)",
        a.out.display(),
        rows,
        match mode {
            joint_formats::log::LogMode::Torque => "torque",
            joint_formats::log::LogMode::Trajectory => "trajectory",
        }
    );
    Ok(())
}
