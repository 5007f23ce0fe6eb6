//! `jointctl scan`: find the nodes on a bus by their heartbeats.

use super::bus_args::{open_master, BusArgs};
use super::num;
use clap::Args;
use joint_core::canopen::od;
use std::time::Duration;

/// List the CANopen nodes on the bus (by heartbeat), with their NMT state, device name and
/// identity.
#[derive(Debug, Args)]
pub struct ScanArgs {
    /// How long to listen, seconds, 0 < S ≤ 3600 (heartbeats come every 0.1 s from our joints;
    /// other devices often use 1 s)
    #[arg(long, value_name = "S", default_value_t = 1.5, value_parser = num::positive(3600.0, "s"))]
    pub seconds: f64,
    /// Node ids of the simulated joints on --bus sim (1..=127)
    #[arg(long = "sim-node", default_values_t = [1u8, 2], value_parser = num::node_id())]
    pub sim_nodes: Vec<u8>,
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
}

pub fn run(a: &ScanArgs) -> anyhow::Result<()> {
    let (mut m, _sim) = open_master(&a.bus, &a.sim_nodes)?;
    m.listen(Duration::from_secs_f64(a.seconds))?;
    let mut rows = Vec::new();
    let seen: Vec<(u8, _)> = m.seen.iter().map(|(k, v)| (*k, *v)).collect();
    for (node, s) in seen {
        let name = m.read_string(node, od::DEVICE_NAME, 0).ok();
        let mut ident = [None; 4];
        for (k, x) in ident.iter_mut().enumerate() {
            *x = m.read_u32(node, od::IDENTITY, k as u8 + 1).ok();
        }
        rows.push(serde_json::json!({
            "node": node,
            "state": s.state.map(|x| x.name()),
            "heartbeats": s.heartbeats,
            "device_name": name,
            "vendor_id": ident[0], "product_code": ident[1], "revision": ident[2], "serial": ident[3],
        }));
    }
    if a.json {
        println!("{}", serde_json::json!({"bus": m.bus.describe(), "simulated": a.bus.is_sim(), "nodes": rows}));
    } else {
        println!("on {}{}", m.bus.describe(), a.bus.sim_note());
        println!("{:>4}  {:<16} {:<20} {:>10} {:>10}", "node", "state", "name", "product", "revision");
        for r in &rows {
            let s = |k: &str| r[k].as_str().unwrap_or("?").to_string();
            let h = |k: &str| r[k].as_u64().map_or("?".to_string(), |v| format!("0x{v:08X}"));
            println!(
                "{:>4}  {:<16} {:<20} {:>10} {:>10}",
                r["node"].as_u64().unwrap_or(0),
                s("state"),
                s("device_name"),
                h("product_code"),
                h("revision")
            );
        }
        if rows.is_empty() {
            println!("no node heard on {} in {:.1} s", m.bus.describe(), a.seconds);
        }
    }
    Ok(())
}
