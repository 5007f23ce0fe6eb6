//! `jointctl eds`: the node's CiA 306 EDS, from the core's object dictionary.

use clap::Args;
use joint_formats::output::{Plan, STDOUT};
use std::path::{Path, PathBuf};

/// Write the joint node's electronic data sheet (CiA 306), generated from the same parameter
/// table the firmware validates with. Load it in any CANopen master (python-canopen:
/// `network.add_node(5, "joint.eds")`).
#[derive(Debug, Args)]
pub struct EdsArgs {
    /// EDS file to write (stdout when absent or -)
    #[arg(long, value_name = "FILE.eds")]
    pub out: Option<PathBuf>,
}

pub fn run(a: &EdsArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let out = plan.file("--out", a.out.as_deref().unwrap_or(Path::new(STDOUT)));
    let outs = plan.check()?;
    outs.write(out, joint_can::eds::generate().as_bytes())?;
    Ok(())
}
