//! `jointctl pull`: read a joint's parameter set into a model TOML.

use super::bus_args::{open_master, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_can::transfer;
use joint_formats::model_file::ModelFile;
use joint_formats::output::Plan;
use std::io::Write as _;
use std::path::PathBuf;

/// Read a joint node's parameters (scalars and gravity table) into a model TOML.
///
/// Example:
///   jointctl pull --node 5 --bus slcan:/dev/ttyACM0 --out joint5.toml
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct PullArgs {
    /// Node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: u8,
    /// Model TOML to write, or - for stdout
    #[arg(long, value_name = "MODEL.toml")]
    pub out: PathBuf,
    /// `name` written into the model
    #[arg(long)]
    pub name: Option<String>,
    /// Names of the other joints' angle columns for gravity-table axes 1..=3 (`q_hip,q_knee`)
    #[arg(long, value_delimiter = ',')]
    pub others: Vec<String>,
    /// Print one JSON object (the values) instead of the human summary
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

pub fn run(a: &PullArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let out = plan.file("--out", &a.out);
    if a.json {
        plan.stdout("--json");
    }
    let outs = plan.check()?;
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    a.sdo.apply(&mut m, a.node)?;
    let (raw, pending) = transfer::pull(&mut m, a.node)?;
    if pending {
        eprintln!("warning: node {} has staged changes not committed; the file holds the staged values", a.node);
    }
    let mf = ModelFile::from_raw(&raw, a.name.as_deref(), &a.others);
    outs.write(out, mf.to_toml_string().as_bytes())?;
    if a.json {
        let values: serde_json::Map<String, serde_json::Value> = joint_core::params::PARAMS
            .iter()
            .map(|d| {
                // the f32's shortest decimal, not its f64 widening (0.2, not 0.20000000298…)
                let v: f64 = raw.get(d.id).to_string().parse().unwrap_or(f64::NAN);
                (d.name.to_string(), serde_json::json!(v))
            })
            .collect();
        say!(
            outs.human(),
            "{}",
            serde_json::json!({"node": a.node, "out": a.out.display().to_string(), "pending": pending,
                "simulated": a.bus.is_sim(),
                "table_axes": raw.table.n_axes, "values": values})
        );
    } else {
        say!(
            outs.human(),
            "pulled node {} into {}{}{}",
            a.node,
            a.out.display(),
            a.bus.sim_note(),
            if pending { " (staged values)" } else { "" }
        );
    }
    Ok(())
}
