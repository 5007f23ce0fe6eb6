//! `jointctl log`: record a joint's TPDOs into a joint-log CSV (spec §1).

use super::bus_args::{open_master, BusArgs};
use super::num;
use clap::Args;
use joint_core::canopen::node::{NMT_START, TPDO1_BASE};
use joint_core::canopen::pdo::{Tpdo1, Tpdo2};
use joint_formats::output::Plan;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Record a joint's telemetry (TPDO1: q, q̇, τ; TPDO2: q̈, measured τ, temperature) as a
/// joint-log CSV: one row per TPDO1, t from the bus clock, u = the commanded output torque.
/// The measured torque is written as `tau` only with --load-cell (a joint without one sends 0).
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
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub bus: BusArgs,
}

pub fn run(a: &LogArgs) -> anyhow::Result<()> {
    let mut plan = Plan::new();
    let out = plan.file("--out", &a.out);
    if a.json {
        plan.stdout("--json");
    }
    let outs = plan.check()?;
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    m.keep_other = true;
    if a.start {
        m.nmt(a.node, NMT_START)?;
    }
    let t0 = m.bus.now_us();
    let end = t0 + (a.seconds * 1e6) as u64;
    let mut rows: Vec<(f64, Tpdo1, Tpdo2, u8)> = Vec::new();
    // q̈, the measured torque and the temperature come in TPDO2: no row before the first one
    // (a placeholder would read as data: q̈ = 0, 0 °C)
    let mut last2: Option<Tpdo2> = None;
    let mut before_tpdo2 = 0usize;
    let id1 = TPDO1_BASE + u16::from(a.node);
    let id2 = id1 + 0x100;
    while m.bus.now_us() < end {
        let left = end - m.bus.now_us();
        m.recv(Duration::from_micros(left))?;
        let nmt = m.seen.get(&a.node).and_then(|s| s.state).map_or(0, |s| s.heartbeat_byte());
        for (t, f) in m.other.drain(..) {
            if f.id() == id2 {
                if let Some(p) = Tpdo2::decode(f.data()) {
                    last2 = Some(p);
                }
            } else if f.id() == id1 {
                if let Some(p) = Tpdo1::decode(f.data()) {
                    match last2 {
                        Some(p2) => rows.push(((t - t0) as f64 * 1e-6, p, p2, nmt)),
                        None => before_tpdo2 += 1,
                    }
                }
            }
        }
    }
    if rows.is_empty() {
        anyhow::bail!(
            "node {}: no TPDO in {:.1} s on {} (is it operational? use --start)",
            a.node,
            a.seconds,
            m.bus.describe()
        );
    }
    // `faults` (the TPDO's fault bits) and `nmt` (the heartbeat's state byte) are optional
    // columns of the spec's reader: kept aside, so a faulted stretch is visible in the log
    let mut text =
        String::from(if a.load_cell { "t,q,qd,qdd,u,tau,temp,faults,nmt\n" } else { "t,q,qd,qdd,u,temp,faults,nmt\n" });
    let mut last_t = f64::NEG_INFINITY;
    for (t, p1, p2, nmt) in &rows {
        // the spec needs strictly increasing time: two TPDOs in the same µs keep the first
        if *t <= last_t {
            continue;
        }
        last_t = *t;
        if a.load_cell {
            text.push_str(&format!(
                "{t:.6},{},{},{},{},{},{},{},{nmt}\n",
                p1.q, p1.qd, p2.qdd, p1.tau_cmd, p2.tau_measured, p2.temperature, p1.faults
            ));
        } else {
            text.push_str(&format!(
                "{t:.6},{},{},{},{},{},{},{nmt}\n",
                p1.q, p1.qd, p2.qdd, p1.tau_cmd, p2.temperature, p1.faults
            ));
        }
    }
    outs.write(out, text.as_bytes())?;
    let mut o = outs.human();
    if a.json {
        say!(
            o,
            "{}",
            serde_json::json!({"node": a.node, "rows": rows.len(), "out": a.out.display().to_string(),
                "simulated": a.bus.is_sim(), "tpdo1_before_first_tpdo2": before_tpdo2})
        );
    } else {
        say!(
            o,
            "node {}: {} samples in {:.1} s → {}{}{}",
            a.node,
            rows.len(),
            a.seconds,
            a.out.display(),
            if before_tpdo2 > 0 {
                format!(" ({before_tpdo2} TPDO1 before the first TPDO2 not logged: no q̈ or temperature yet)")
            } else {
                String::new()
            },
            a.bus.sim_note()
        );
    }
    Ok(())
}
