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
    /// The board's control step: f32 (the G431 image) or q16 (the G0B1 image's default);
    /// named in the EDS's product number and name
    #[arg(long, value_enum, default_value = "f32")]
    pub step: Step,
    /// A node on a CAN FD bus: TPDO3 (the state in REAL32 but the assist gain and command, 32 bytes) valid by default,
    /// the classic TPDO1/2 invalid
    #[arg(long)]
    pub fd: bool,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Step {
    F32,
    Q16,
}

pub fn run(a: &EdsArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let out = plan.file("--out", a.out.as_deref().unwrap_or(Path::new(STDOUT)));
    let outs = plan.check()?;
    let fd = a.fd;
    let a = match a.step {
        Step::F32 => joint_core::fixed::Arithmetic::F32,
        Step::Q16 => joint_core::fixed::Arithmetic::Q16,
    };
    outs.write(out, joint_can::eds::generate_for_bus(a, fd).as_bytes())?;
    Ok(())
}
