//! `jointctl eds`: the node's CiA 306 EDS, from the core's object dictionary.

use clap::Args;
use std::path::PathBuf;

/// Write the joint node's electronic data sheet (CiA 306), generated from the same parameter
/// table the firmware validates with. Load it in any CANopen master (python-canopen:
/// `network.add_node(5, "joint.eds")`).
#[derive(Debug, Args)]
pub struct EdsArgs {
    /// EDS file to write (stdout when absent)
    #[arg(long, value_name = "FILE.eds")]
    pub out: Option<PathBuf>,
}

pub fn run(a: &EdsArgs) -> anyhow::Result<()> {
    let text = joint_can::eds::generate();
    match &a.out {
        Some(p) => std::fs::write(p, text).map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", p.display()))?,
        None => print!("{text}"),
    }
    Ok(())
}
