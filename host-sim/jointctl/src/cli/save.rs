//! `jointctl save`: persist a joint's committed parameter set (0x1010 "save").

use super::bus_args::{check_node, open_master, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_core::canopen::od;

/// Make the joint store its committed parameter set in flash (CiA 301 object 0x1010).
#[derive(Debug, Args)]
pub struct SaveArgs {
    /// Node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: u8,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

pub fn run(a: &SaveArgs) -> anyhow::Result<()> {
    check_node(a.node)?;
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    a.sdo.apply(&mut m, a.node)?;
    m.write(a.node, od::STORE_PARAMETERS, 1, &od::SAVE_SIGNATURE.to_le_bytes())?;
    if a.json {
        println!("{}", serde_json::json!({"node": a.node, "saved": true, "simulated": a.bus.is_sim()}));
    } else {
        println!("node {}: parameters saved{}", a.node, a.bus.sim_note());
    }
    Ok(())
}
