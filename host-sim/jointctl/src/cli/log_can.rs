//! `jointctl log`: record a joint's TPDOs into a joint-log CSV (spec §1).

use super::bus_args::{open_master_tapped, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_can::tap::Tape;
use joint_can::BusSpec;
use joint_core::canopen::node::NMT_START;
use joint_formats::import::candump::{self, DecodeOpts, FrameRef};
use joint_formats::import::eds::PdoMap;
use joint_formats::output::Plan;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Record a joint's telemetry (TPDO1: q, q̇, τ; TPDO2: q̈, measured τ, temperature) as a
/// joint-log CSV: one row per TPDO1 once a TPDO2 has arrived, t from the bus clock since the
/// first frame, u = the commanded output torque, plus the fault bits and the NMT state. The
/// measured torque is written as `tau` only with --load-cell (a joint without one sends 0).
/// --candump also writes the raw traffic as a can-utils capture, which `import --format
/// candump` decodes back into the same CSV (docs/import.md#candump).
#[derive(Debug, Args)]
pub struct LogArgs {
    /// Node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: u8,
    /// How long to record, seconds (0 < S ≤ 3600: 3.6 M rows at 1 kHz)
    #[arg(long, value_name = "S", value_parser = num::positive(3600.0, "s"))]
    pub seconds: f64,
    /// Joint log to write, or - for stdout
    #[arg(long, value_name = "LOG.csv")]
    pub out: PathBuf,
    /// The joint has a load cell: write its torque as the `tau` column
    #[arg(long)]
    pub load_cell: bool,
    /// Send NMT start to the node first (TPDOs flow only in operational)
    #[arg(long)]
    pub start: bool,
    /// Also write every frame on the bus as a can-utils capture (candump -l format)
    #[arg(long, value_name = "CAPTURE.log")]
    pub candump: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

pub fn run(a: &LogArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let out = plan.file("--out", &a.out);
    let cap_out = plan.file_opt("--candump", a.candump.as_deref());
    if a.json {
        plan.stdout("--json");
    }
    let outs = plan.check()?;
    let tape = Tape::default();
    let (mut m, _sim) = open_master_tapped(&a.bus, &[a.node], Some(tape.clone()))?;
    if a.start {
        // the joint faults (heartbeat_lost) when our heartbeat is slower than its 0x1016 says
        if !matches!(a.bus.spec()?, BusSpec::Replay { .. }) {
            a.sdo.apply(&mut m, a.node)?;
            m.match_consumer(a.node)?;
        }
        m.nmt(a.node, NMT_START)?;
    }
    // everything on the bus for the time asked (our heartbeat kept going), then decoded as a
    // capture would be: the CSV is what `import --format candump` makes of the --candump file
    m.listen(Duration::from_secs_f64(a.seconds))?;
    let iface = match a.bus.spec()? {
        BusSpec::Sim => "sim0".to_string(),
        BusSpec::SocketCan { iface } => iface,
        BusSpec::Slcan { .. } => "slcan0".to_string(),
        BusSpec::Replay { .. } => "replay0".to_string(),
    };
    let tape = tape.lock().map_err(|_| anyhow::anyhow!("capture lock poisoned"))?;
    // the tape's frames as the decoder and the capture writer read them, without a copy
    let frames = || {
        tape.iter().map(|(t, f)| FrameRef {
            t_ns: t * 1000,
            id: u32::from(f.id()),
            extended: false,
            remote: false,
            data: f.data(),
        })
    };
    let pdos = PdoMap::from_eds(&joint_can::eds::generate(), "the joint's EDS", a.node).map_err(anyhow::Error::msg)?;
    let decoded =
        candump::decode(frames(), &pdos, &DecodeOpts { node: a.node, map: String::new(), load_cell: a.load_cell })
            .map_err(|e| {
                anyhow::anyhow!("{e} on {} in {:.1} s (is it operational? use --start)", m.bus.describe(), a.seconds)
            })?;
    if let Some(slot) = cap_out {
        outs.write(slot, candump::write_capture(frames(), &iface).as_bytes())?;
    }
    outs.write(out, decoded.csv.as_bytes())?;
    let mut o = outs.human();
    if a.json {
        say!(
            o,
            "{}",
            serde_json::json!({"node": a.node, "rows": decoded.rows, "out": a.out.display().to_string(),
                "frames": tape.len(), "candump": a.candump.as_ref().map(|p| p.display().to_string()),
                "simulated": a.bus.is_sim(), "tpdo1_before_first_tpdo2": decoded.early, "notes": decoded.notes})
        );
    } else {
        say!(
            o,
            "node {}: {} samples in {:.1} s → {}{}{}",
            a.node,
            decoded.rows,
            a.seconds,
            a.out.display(),
            a.candump
                .as_ref()
                .map(|p| format!(" (capture of {} frames → {})", tape.len(), p.display()))
                .unwrap_or_default(),
            a.bus.sim_note()
        );
        for n in &decoded.notes {
            say!(o, "note: {n}");
        }
    }
    Ok(())
}
