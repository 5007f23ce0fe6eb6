//! Bus selection shared by the CAN subcommands (`--bus`, `--bitrate`), and opening a master
//! on it. `--bus sim` builds the in-process simulated bus with simulated joints at the node
//! ids the command addresses, so every command can be tried (and timed) without hardware.

use crate::sim_joint::{JointSim, SimStorage};
use anyhow::Context as _;
use clap::Args;
use joint_can::master::{Master, SdoCobs};
use joint_can::script_bus::ScriptBus;
use joint_can::sim_bus::{SharedSimBus, SimBus};
use joint_can::tap::{TapBus, Tape};
use joint_can::Bus;
use joint_can::BusSpec;
use joint_core::canopen::node::MemoryStorage;
use joint_core::canopen::CanFrame;
use joint_formats::import::candump;
use std::sync::{Arc, Mutex};

/// The environment variable that may name the bus when `--bus` is not given.
pub const BUS_ENV: &str = "JOINTCTL_BUS";

#[derive(Debug, Clone, Args)]
pub struct BusArgs {
    /// CAN bus (required: no command talks to a simulation unless told to): slcan:PATH[@BITRATE]
    /// (Lawicel serial adapter or pty), socketcan:IFACE, sim (in-process simulated bus with
    /// simulated joints), or replay:CAPTURE.log (a candump -l capture played back, read-only).
    /// Without --bus, the environment variable JOINTCTL_BUS may name a real bus (never sim)
    #[arg(long, value_name = "BUS")]
    pub bus: Option<BusSpec>,
    /// Bitrate of the simulated bus, bit/s (10000..=1000000, classic CAN; slcan takes it after
    /// @, socketcan from the interface)
    #[arg(long, value_name = "BIT/S", default_value_t = 1_000_000, value_parser = super::num::bitrate(super::num::CAN_BITRATE))]
    pub bitrate: u32,
}

/// Which of a joint's SDO server channels a command uses (`--sdo-channel`, `--sdo-cob-ids`).
#[derive(Debug, Clone, Args)]
pub struct SdoArgs {
    /// SDO server channel of the joint: 1 the default (0x1200: 0x600 + id / 0x580 + id), 2 the
    /// second (0x1201), so this command and a controller on channel 1 never share a transfer
    /// (SDO frames carry no client address). Channel 2 is configured first through channel 1,
    /// as CiA 301 has it (0x1201: its two COB-IDs and our node id, three expedited writes,
    /// skipped when the joint already serves it with those COB-IDs), and again after the joint
    /// resets
    #[arg(long, value_name = "1|2", default_value_t = 1, value_parser = super::num::int::<u8>(1, 2))]
    pub sdo_channel: u8,
    /// COB-IDs of channel 2, request,response (0x… hex or decimal). Default 0x640 + id,
    /// 0x5C0 + id: the default channel of node id + 64, free on a bus whose node ids are all
    /// below 64; a node id of 64 or more needs them named
    #[arg(long, value_name = "RX,TX", value_parser = parse_cob_pair)]
    pub sdo_cob_ids: Option<SdoCobs>,
}

/// Two 11-bit CAN ids, `RX,TX`, different. Whether they suit the node (not its default
/// channel) is checked against its id before any traffic ([`SdoCobs::check_for`]).
fn parse_cob_pair(s: &str) -> Result<SdoCobs, String> {
    const ALLOWED: &str = "allowed: two different COB-IDs RX,TX, each 1..=0x7FF (0x… hex or decimal)";
    let one = |t: &str| {
        let t = t.trim();
        let v = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
            Some(h) => u16::from_str_radix(h, 16),
            None => t.parse::<u16>(),
        }
        .map_err(|_| format!("`{t}` is not a COB-ID; {ALLOWED}"))?;
        if !(1..=0x7FF).contains(&v) {
            return Err(format!("`{t}` is not an 11-bit CAN id; {ALLOWED}"));
        }
        Ok(v)
    };
    let (rx, tx) = s.split_once(',').ok_or_else(|| format!("one value; {ALLOWED}"))?;
    let c = SdoCobs { rx: one(rx)?, tx: one(tx)? };
    if c.rx == c.tx {
        return Err(format!("the same COB-ID twice; {ALLOWED}"));
    }
    Ok(c)
}

impl SdoArgs {
    /// Put `m`'s SDO transfers with `node` on the channel asked for: channel 2 is configured
    /// on the joint first (through channel 1), so nothing else of the command runs there.
    pub fn apply(&self, m: &mut Master, node: u8) -> anyhow::Result<()> {
        if self.sdo_channel == 1 {
            if self.sdo_cob_ids.is_some() {
                anyhow::bail!("--sdo-cob-ids names channel 2's COB-IDs: give it with --sdo-channel 2");
            }
            return Ok(());
        }
        let cobs = match self.sdo_cob_ids {
            Some(c) => c,
            None => SdoCobs::second_for(node).ok_or_else(|| {
                anyhow::anyhow!(
                    "node {node}: channel 2's default COB-IDs (node id + 64's default channel) exist only for node \
                     ids below 64: name them with --sdo-cob-ids RX,TX"
                )
            })?,
        };
        cobs.check_for(node).map_err(|e| anyhow::anyhow!("--sdo-cob-ids: {e}"))?;
        m.use_second_channel(node, cobs)
            .map_err(|e| anyhow::anyhow!("configuring SDO channel 2 (0x1201) at 0x{:X}/0x{:X}: {e}", cobs.rx, cobs.tx))
    }
}

/// A master on the chosen bus. On `sim`, `nodes` get simulated joints (in memory, table
/// defaults), and the shared bus handle is returned too.
pub fn open_master(args: &BusArgs, nodes: &[u8]) -> anyhow::Result<(Master, Option<SharedSimBus>)> {
    open_master_tapped(args, nodes, None)
}

/// [`open_master`], with every frame on the bus recorded on `tape` when given (from the
/// simulated joints' boot-up on).
pub fn open_master_tapped(
    args: &BusArgs,
    nodes: &[u8],
    tape: Option<Tape>,
) -> anyhow::Result<(Master, Option<SharedSimBus>)> {
    let tapped = |b: Box<dyn Bus>| -> Box<dyn Bus> {
        match &tape {
            Some(t) => Box::new(TapBus::new(b, t.clone())),
            None => b,
        }
    };
    match &args.spec()? {
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
            let mut m = Master::new(tapped(Box::new(shared.clone())));
            m.listen(std::time::Duration::from_millis(5))?;
            Ok((m, Some(shared)))
        }
        BusSpec::Replay { path } => Ok((Master::new(tapped(Box::new(replay_bus(path)?))), None)),
        spec => Ok((Master::new(tapped(joint_can::open(spec)?)), None)),
    }
}

impl BusArgs {
    /// The bus asked for: `--bus`, else `JOINTCTL_BUS` when it names a real bus. Forgetting
    /// `--bus` used to run the command on the simulation and print "pushed … saved".
    pub fn spec(&self) -> anyhow::Result<BusSpec> {
        if let Some(b) = &self.bus {
            return Ok(b.clone());
        }
        match std::env::var(BUS_ENV) {
            Ok(v) if !v.trim().is_empty() => match v.trim().parse::<BusSpec>() {
                Ok(BusSpec::Sim) => anyhow::bail!(
                    "{BUS_ENV}=sim: a configured default must name a real bus (slcan:PATH, socketcan:IFACE); pass \
                     --bus sim to use the simulated joints"
                ),
                Ok(b) => Ok(b),
                Err(e) => anyhow::bail!("{BUS_ENV}={v}: {e}"),
            },
            _ => anyhow::bail!(
                "no bus given: pass --bus slcan:PATH[@BITRATE], --bus socketcan:IFACE, or --bus sim for the in-process \
                 simulated joints (or set {BUS_ENV} to a real bus)"
            ),
        }
    }

    /// What a human output appends on the simulated bus or a replayed capture, so no result
    /// reads as a live joint's.
    pub fn sim_note(&self) -> &'static str {
        match self.spec() {
            Ok(BusSpec::Sim) => " [simulated bus: in-process joints, not hardware]",
            Ok(BusSpec::Replay { .. }) => " [replayed capture: not a live bus]",
            _ => "",
        }
    }

    /// Whether the command runs on the simulated bus (every output says so).
    pub fn is_sim(&self) -> bool {
        matches!(self.spec(), Ok(BusSpec::Sim))
    }
}

/// A capture played back as the bus: its classic frames with standard ids at their recorded
/// times (extended and CAN FD frames are not this node's protocol and are left out).
fn replay_bus(path: &str) -> anyhow::Result<ScriptBus> {
    let text = std::fs::read_to_string(path).with_context(|| format!("bus replay:{path}: cannot read the capture"))?;
    let (records, _) = candump::parse_capture(&text, path).map_err(anyhow::Error::msg)?;
    let start = records.first().map_or(0, |r| r.t_ns / 1000);
    let mut prev = start;
    let mut frames = Vec::with_capacity(records.len());
    for r in records.iter().filter(|r| !r.extended && !r.remote && r.fd_flags.is_none()) {
        let Some(f) = u16::try_from(r.id).ok().and_then(|id| CanFrame::new(id, &r.data)) else { continue };
        let t = r.t_ns / 1000;
        frames.push((t.saturating_sub(prev), f));
        prev = prev.max(t);
    }
    Ok(ScriptBus::replay(start, frames, format!("replayed capture {path}")))
}

pub fn check_node(n: u8) -> anyhow::Result<()> {
    if !(1..=127).contains(&n) {
        anyhow::bail!("node id {n} is outside 1..=127");
    }
    Ok(())
}
