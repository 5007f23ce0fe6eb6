//! Bus selection shared by the CAN subcommands (`--bus`, `--bitrate`), and opening a master
//! on it. `--bus sim` builds the in-process simulated bus with simulated joints at the node
//! ids the command addresses, so every command can be tried (and timed) without hardware.

use crate::sim_joint::{JointSim, SimStorage};
use clap::Args;
use joint_can::master::Master;
use joint_can::sim_bus::{SharedSimBus, SimBus};
use joint_can::BusSpec;
use joint_core::canopen::node::MemoryStorage;
use std::sync::{Arc, Mutex};

#[derive(Debug, Clone, Args)]
pub struct BusArgs {
    /// CAN bus: sim (in-process simulated bus with simulated joints), slcan:PATH[@BITRATE]
    /// (Lawicel serial adapter or pty), socketcan:IFACE
    #[arg(long, value_name = "BUS", default_value = "sim")]
    pub bus: BusSpec,
    /// Bitrate of the simulated bus, bit/s (10000..=1000000, classic CAN; slcan takes it after
    /// @, socketcan from the interface)
    #[arg(long, value_name = "BIT/S", default_value_t = 1_000_000, value_parser = super::num::bitrate(super::num::CAN_BITRATE))]
    pub bitrate: u32,
}

/// A master on the chosen bus. On `sim`, `nodes` get simulated joints (in memory, table
/// defaults), and the shared bus handle is returned too.
pub fn open_master(args: &BusArgs, nodes: &[u8]) -> anyhow::Result<(Master, Option<SharedSimBus>)> {
    match &args.bus {
        BusSpec::Sim => {
            let mut bus = SimBus::new(args.bitrate);
            for &n in nodes {
                check_node(n)?;
                bus.attach(Arc::new(Mutex::new(JointSim::new(
                    n,
                    None,
                    SimStorage::Memory(MemoryStorage::default()),
                    0,
                ))));
            }
            let shared = SharedSimBus(Arc::new(Mutex::new(bus)));
            // let the joints boot
            let mut m = Master::new(Box::new(shared.clone()));
            m.listen(std::time::Duration::from_millis(5))?;
            Ok((m, Some(shared)))
        }
        spec => Ok((Master::new(joint_can::open(spec)?), None)),
    }
}

pub fn check_node(n: u8) -> anyhow::Result<()> {
    if !(1..=127).contains(&n) {
        anyhow::bail!("node id {n} is outside 1..=127");
    }
    Ok(())
}
