//! `jointctl watch`: a live table of every node's state from heartbeats and TPDOs.

use super::bus_args::{open_master, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_core::canopen::node::{NMT_START, TPDO1_BASE};
use joint_core::canopen::pdo::Tpdo1;
use joint_core::safety::Faults;
use std::collections::BTreeMap;
use std::time::Duration;

/// Show every node's NMT state and joint state (q, q̇, τ, faults from TPDO1), refreshed twice
/// a second, until Ctrl-C or --seconds.
#[derive(Debug, Args)]
pub struct WatchArgs {
    /// Stop after this many seconds (0 < S ≤ 1e7) [default: until Ctrl-C]
    #[arg(long, value_name = "S", value_parser = num::positive(1.0e7, "s"))]
    pub seconds: Option<f64>,
    /// Send NMT start to all nodes first (TPDOs flow only in operational)
    #[arg(long)]
    pub start: bool,
    /// Node ids of the simulated joints on --bus sim (1..=127)
    #[arg(long = "sim-node", default_values_t = [1u8, 2], value_parser = num::node_id())]
    pub sim_nodes: Vec<u8>,
    /// One JSON object per refresh (JSON lines)
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

pub fn run(a: &WatchArgs) -> anyhow::Result<()> {
    let (mut m, _sim) = open_master(&a.bus, &a.sim_nodes)?;
    m.keep_other = true;
    if a.start {
        // every joint heard so far gets our heartbeat at the rate its 0x1016 consumes it
        let nodes: Vec<u8> = m.seen.keys().copied().collect();
        if !matches!(a.bus.spec()?, joint_can::BusSpec::Replay { .. }) {
            if a.sdo.sdo_cob_ids.is_some() && nodes.len() > 1 {
                anyhow::bail!("--sdo-cob-ids names one node's channel 2, and {} nodes answer", nodes.len());
            }
            for n in nodes {
                a.sdo.apply(&mut m, n)?;
                m.match_consumer(n)?;
            }
        }
        m.nmt(0, NMT_START)?;
    }
    let t0 = m.bus.now_us();
    let mut pdo: BTreeMap<u8, Tpdo1> = BTreeMap::new();
    loop {
        m.listen(Duration::from_millis(500))?;
        for (_, f) in m.other.drain(..) {
            if (TPDO1_BASE + 1..=TPDO1_BASE + 127).contains(&f.id()) {
                if let Some(p) = Tpdo1::decode(f.data()) {
                    pdo.insert((f.id() - TPDO1_BASE) as u8, p);
                }
            }
        }
        let now = m.bus.now_us();
        let rows: Vec<serde_json::Value> = m
            .seen
            .iter()
            .map(|(n, s)| {
                let p = pdo.get(n);
                serde_json::json!({
                    "node": n, "state": s.state.map(|x| x.name()),
                    "heartbeat_age_ms": (now.saturating_sub(s.last_us)) / 1000,
                    "q": p.map(|p| p.q), "qd": p.map(|p| p.qd), "tau": p.map(|p| p.tau_cmd),
                    "faults": p.map(|p| Faults::from_bits_truncate(p.faults).names().collect::<Vec<_>>()),
                })
            })
            .collect();
        let t = (now - t0) as f64 * 1e-6;
        if a.json {
            println!("{}", serde_json::json!({"t": t, "simulated": a.bus.is_sim(), "nodes": rows}));
        } else {
            println!("t = {t:.1} s{}", a.bus.sim_note());
            println!(
                "{:>4}  {:<16} {:>8} {:>9} {:>9} {:>9}  faults",
                "node", "state", "hb ms", "q rad", "qd rad/s", "tau N·m"
            );
            for r in &rows {
                let f = |k: &str| r[k].as_f64().map_or("-".to_string(), |v| format!("{v:.4}"));
                let faults = r["faults"].as_array().map_or("-".to_string(), |v| {
                    if v.is_empty() {
                        "none".into()
                    } else {
                        v.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(",")
                    }
                });
                println!(
                    "{:>4}  {:<16} {:>8} {:>9} {:>9} {:>9}  {}",
                    r["node"].as_u64().unwrap_or(0),
                    r["state"].as_str().unwrap_or("?"),
                    r["heartbeat_age_ms"].as_u64().unwrap_or(0),
                    f("q"),
                    f("qd"),
                    f("tau"),
                    faults
                );
            }
        }
        if a.seconds.is_some_and(|s| t >= s) {
            return Ok(());
        }
    }
}
