//! `jointctl sim`: serve simulated joints (the core's CANopen node + host-sim's plant) on a
//! real bus, so any CANopen master can talk to them.

use super::num;
use crate::sim_joint::{JointSim, SimStorage};
use clap::Args;
use host_sim::plant::PlantFile;
use joint_can::BusSpec;
use joint_core::canopen::lss::UNCONFIGURED;
use joint_core::canopen::node::{MemoryStorage, NodeConfig};
use joint_core::canopen::CanFrame;
use joint_formats::output::Plan;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Serve simulated joints on a CAN bus until stopped (Ctrl-C, SIGTERM or --seconds).
///
/// Each joint runs the firmware core's CANopen node, controller and watchdog at 1 kHz on the
/// wall clock; with --plant the joint moves as that plant (else it is held at rest).
///
/// Example (a python-canopen master on the other end of a pty pair):
///   socat -d -d pty,raw,echo=0,link=/tmp/canA pty,raw,echo=0,link=/tmp/canB &
///   jointctl sim --bus slcan:/tmp/canB --node 5 --plant examples/plants/trunk-right.toml
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct SimArgs {
    /// slcan:PATH[@BITRATE] or socketcan:IFACE
    #[arg(long, value_name = "BUS")]
    pub bus: BusSpec,
    /// Node id of a simulated joint (1..=127); repeat for several
    #[arg(long = "node", required = true, value_parser = num::node_id())]
    pub nodes: Vec<u8>,
    /// Plant TOML the joints move as (default: held at rest)
    #[arg(long, value_name = "PLANT.toml")]
    pub plant: Option<PathBuf>,
    /// Stop after this many seconds (0 < S ≤ 1e7)
    #[arg(long, value_name = "S", value_parser = num::positive(1.0e7, "s"))]
    pub seconds: Option<f64>,
    /// Existing directory for the joints' stored parameters (node-N.toml, each replaced
    /// atomically on save), the stand-in for flash; default: in memory
    #[arg(long, value_name = "DIR")]
    pub store_dir: Option<PathBuf>,
    /// Start the joints unconfigured (node id 0xFF), silent until an LSS master (CiA 305:
    /// fast scan, configure node id) gives each its id; each --node is then the joint's
    /// serial number (0x1018 sub 4), not its id. A joint whose --store-dir holds a stored
    /// LSS configuration boots with that id.
    #[arg(long)]
    pub lss_unconfigured: bool,
    /// Print a JSON summary at the end
    #[arg(long)]
    pub json: bool,
    /// CAN FD: the joints are FD nodes (TPDO3, the state in 32 bytes of REAL32 but the assist gain and command, FD
    /// frames with bit-rate switch; RPDO1 from the host's shared command frame 0x200), and an
    /// slcan adapter is opened with its data bit rate (`Yn`; frames `b`/`d`)
    #[arg(long)]
    pub fd: bool,
    /// Data-phase bit rate with --fd, bit/s (10000..=8000000; slcan adapters take 1, 2, 4, 5
    /// or 8 Mbit/s; default 5000000)
    #[arg(long, value_name = "BIT/S", value_parser = num::bitrate(num::CAN_FD_DATA_BITRATE))]
    pub data_bitrate: Option<u32>,
}

pub fn run(a: &SimArgs) -> anyhow::Result<()> {
    for &n in &a.nodes {
        super::bus_args::check_node(n)?;
        if a.nodes.iter().filter(|&&m| m == n).count() > 1 {
            anyhow::bail!("node id {n} given twice");
        }
    }
    if a.bus == BusSpec::Sim {
        anyhow::bail!("`jointctl sim` serves joints to other programs: give a real bus (slcan:PATH or socketcan:IFACE); the in-process bus is what push/pull/scan use with --bus sim");
    }
    // The store's files are written while serving (each save replaces one atomically);
    // checked here so a node file is never the plant file, a folder or read-only.
    let mut plan = Plan::new();
    if let Some(p) = &a.plant {
        plan.input("--plant", p);
    }
    if let Some(d) = &a.store_dir {
        for &n in &a.nodes {
            plan.file("--store-dir", &store_file(d, n));
        }
    }
    plan.check()?;
    let plant = a.plant.as_ref().map(|p| PlantFile::read_file(p)).transpose()?;
    if a.data_bitrate.is_some() && !a.fd {
        anyhow::bail!("--data-bitrate is the CAN FD data phase: give --fd too");
    }
    let mut bus =
        if a.fd { joint_can::open_fd(&a.bus, a.data_bitrate.unwrap_or(5_000_000))? } else { joint_can::open(&a.bus)? };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))?;
    }
    let now0 = bus.now_us();
    let mut joints: Vec<JointSim> = a
        .nodes
        .iter()
        .map(|&n| {
            let storage = match &a.store_dir {
                Some(d) => SimStorage::file(store_file(d, n)),
                None => SimStorage::Memory(MemoryStorage::default()),
            };
            if a.lss_unconfigured {
                let mut cfg = NodeConfig::new(UNCONFIGURED).with_fd(a.fd);
                cfg.identity.serial = u32::from(n);
                JointSim::with_config(cfg, plant.as_ref(), storage, now0)
            } else {
                JointSim::with_config(NodeConfig::new(n).with_fd(a.fd), plant.as_ref(), storage, now0)
            }
        })
        .collect();
    if a.lss_unconfigured {
        let ids: Vec<u8> = joints.iter().map(|j| j.node.node_id()).collect();
        eprintln!(
            "serving joints with serial(s) {:?}, node ids {ids:?} (255: unconfigured, LSS) on {} (Ctrl-C to stop)",
            a.nodes,
            bus.describe()
        );
    } else {
        eprintln!("serving joint node(s) {:?} on {} (Ctrl-C to stop)", a.nodes, bus.describe());
    }
    let end_us = a.seconds.map(|s| now0 + (s * 1e6) as u64);
    let mut next_tick = now0;
    let (mut rx_frames, mut tx_frames, mut dropped) = (0u64, 0u64, 0u64);
    let mut out: Vec<(usize, CanFrame)> = Vec::new();
    let mut buf = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        let now = bus.now_us();
        if end_us.is_some_and(|e| now >= e) {
            break;
        }
        if now >= next_tick {
            for (i, j) in joints.iter_mut().enumerate() {
                j.step(now, &mut buf);
                out.extend(buf.drain(..).map(|f| (i, f)));
            }
            // the period of the committed controller_rate_hz (the joints' loops; 1 ms by default)
            let period = joints.iter().map(|j| j.control_period_us()).min().unwrap_or(1000);
            next_tick += period;
            if next_tick + 100_000 < now {
                // fell far behind (suspended?): do not replay the backlog
                next_tick = now + period;
            }
        } else if let Some(f) = bus.recv(Duration::from_micros(next_tick - now))? {
            rx_frames += 1;
            let t = bus.now_us();
            for (i, j) in joints.iter_mut().enumerate() {
                j.receive(t, &f, &mut buf);
                out.extend(buf.drain(..).map(|f| (i, f)));
            }
        }
        // Send, and let the other local joints hear it as they would on a wire. A bus that
        // takes nothing (a master that stopped reading the pty, a full adapter queue) costs the
        // frames of this round, counted, as a node that loses arbitration or goes error-passive
        // loses them: the joints keep running and the next round tries again.
        let mut stalled = false;
        while !out.is_empty() {
            let batch: Vec<(usize, CanFrame)> = std::mem::take(&mut out);
            for (src, f) in batch {
                if stalled {
                    dropped += 1;
                    continue;
                }
                match bus.send(&f) {
                    Ok(()) => tx_frames += 1,
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::TimedOut
                                | std::io::ErrorKind::WouldBlock
                                | std::io::ErrorKind::Interrupted
                        ) =>
                    {
                        stalled = true;
                        dropped += 1;
                        continue;
                    }
                    Err(e) => return Err(e.into()),
                }
                let t = bus.now_us();
                for (i, j) in joints.iter_mut().enumerate() {
                    if i != src {
                        j.receive(t, &f, &mut buf);
                        out.extend(buf.drain(..).map(|f| (i, f)));
                    }
                }
            }
        }
    }
    let secs = (bus.now_us() - now0) as f64 * 1e-6;
    if a.json {
        println!(
            "{}",
            serde_json::json!({"nodes": a.nodes, "seconds": secs, "frames_received": rx_frames, "frames_sent": tx_frames,
                "frames_dropped": dropped})
        );
    } else {
        eprintln!(
            "stopped after {secs:.1} s: {rx_frames} frames received, {tx_frames} sent, {dropped} dropped (the bus took none)"
        );
    }
    Ok(())
}

/// Where node `n`'s parameters are stored under `--store-dir`.
fn store_file(dir: &std::path::Path, n: u8) -> PathBuf {
    dir.join(format!("node-{n}.toml"))
}
