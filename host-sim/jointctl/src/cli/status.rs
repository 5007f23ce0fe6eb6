//! `jointctl status`: which parameter set runs on a joint, whether another is staged, its NMT
//! state and faults; `jointctl discard`: drop a staged set.

use super::bus_args::{check_node, open_master, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_can::master::{Master, SdoError};
use joint_core::canopen::od;
use joint_core::safety::Faults;
use joint_formats::model_file::ModelFile;
use std::path::PathBuf;
use std::time::Duration;

/// Show what runs on a joint: the CRC-32 of its set in force and of its staged set (object
/// 0x2204, the same CRC `push` names in its commit), whether they differ (a staged set waiting
/// for a commit), its NMT state and fault bits. With --model, whether that model is the one in
/// force.
///
/// Example:
///   jointctl status --node 5 --bus slcan:/dev/ttyACM0 --model examples/models/trunk-right.toml
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct StatusArgs {
    /// Node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: u8,
    /// A model TOML to compare with the set in force
    #[arg(long, value_name = "MODEL.toml")]
    pub model: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

/// Drop a joint's staged parameter set (changes written but not committed, e.g. by a push that
/// was interrupted): the set in force stays and becomes the staged one again.
///
/// Example:
///   jointctl discard --node 5 --bus slcan:/dev/ttyACM0
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct DiscardArgs {
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

/// (set in force, staged set) CRCs.
fn crcs(m: &mut Master, node: u8) -> Result<(u32, u32), SdoError> {
    let a = m.read_u32(node, od::PARAMS_CRC, 1)?;
    let s = m.read_u32(node, od::PARAMS_CRC, 2)?;
    Ok((a, s))
}

pub fn run_status(a: &StatusArgs) -> anyhow::Result<()> {
    check_node(a.node)?;
    let want = match &a.model {
        Some(p) => {
            let mf = ModelFile::read_file(p)?;
            mf.param_set()?;
            Some(joint_core::store::set_crc(&mf.raw_params()?))
        }
        None => None,
    };
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    a.sdo.apply(&mut m, a.node)?;
    // a heartbeat tells the NMT state
    m.listen(Duration::from_millis(300))?;
    let (active, staged) = crcs(&mut m, a.node)?;
    let faults = Faults::from_bits_truncate(m.read_u32(a.node, od::JOINT_STATE, od::JS_FAULTS)? as u16);
    let state = m.seen.get(&a.node).and_then(|s| s.state).map(|s| s.name());
    let fault_names: Vec<&str> = faults.names().collect();
    let is_model = want.map(|w| w == active);
    if a.json {
        println!(
            "{}",
            serde_json::json!({
                "node": a.node, "simulated": a.bus.is_sim(), "nmt": state, "faults": fault_names,
                "active_crc": format!("{active:08x}"), "staged_crc": format!("{staged:08x}"),
                "staged_pending": staged != active, "model_in_force": is_model,
            })
        );
    } else {
        println!(
            "node {}: {}, faults {}{}",
            a.node,
            state.unwrap_or("no heartbeat heard"),
            if fault_names.is_empty() { "none".to_string() } else { fault_names.join(", ") },
            a.bus.sim_note()
        );
        println!("  set in force: crc {active:08x}");
        if staged == active {
            println!("  nothing staged");
        } else {
            println!("  staged, not committed: crc {staged:08x} (`jointctl discard` drops it; a push replaces it)");
        }
        if let (Some(w), Some(p)) = (want, &a.model) {
            println!(
                "  {}: crc {w:08x}, {}",
                p.display(),
                if w == active { "the set in force" } else { "not the set in force" }
            );
        }
    }
    Ok(())
}

pub fn run_discard(a: &DiscardArgs) -> anyhow::Result<()> {
    check_node(a.node)?;
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    a.sdo.apply(&mut m, a.node)?;
    let (_, before) = crcs(&mut m, a.node)?;
    m.write(a.node, od::COMMIT, 0, &[0])?;
    let (active, staged) = crcs(&mut m, a.node)?;
    if staged != active {
        anyhow::bail!(
            "node {}: the staged set is still {staged:08x} after discarding (set in force {active:08x})",
            a.node
        );
    }
    let dropped = before != active;
    if a.json {
        println!(
            "{}",
            serde_json::json!({"node": a.node, "simulated": a.bus.is_sim(), "dropped": dropped,
                "active_crc": format!("{active:08x}")})
        );
    } else {
        println!(
            "node {}: {}; set in force crc {active:08x}{}",
            a.node,
            if dropped { format!("staged set {before:08x} dropped") } else { "nothing was staged".to_string() },
            a.bus.sim_note()
        );
    }
    Ok(())
}
