//! `jointctl bus-budget`: bus load of joint telemetry from the real frame layout, and
//! (`--measured`) as measured on the simulated bus with the joints' real CANopen nodes.

use super::num;
use crate::sim_joint::{JointSim, SimStorage};
use clap::Args;
use joint_can::sim_bus::SimBus;
use joint_can::{timing, Bus};
use joint_core::canopen::node::{MemoryStorage, NodeConfig};
use joint_core::canopen::{od, CanFrame};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Bus load of J joints streaming telemetry at R Hz, from the frames' real bit length (bit
/// stuffing included: worst case, and typical = mean over random payloads).
///
/// Traffic per joint per period: classic CAN — TPDO1 (8 B: q, q̇, τ, faults), TPDO2 (8 B: q̈,
/// τ measured, temperature, gain) and the host's RPDO1 (2 B: assist command); CAN FD (with
/// --data-bitrate, bit-rate switch) — the FD node's TPDO3 (32 B: the state in REAL32 but the assist gain and command)
/// and the host's shared command frame (COB-ID 0x200, 2 B per joint, FD with BRS, once per
/// period for all joints). Plus heartbeats: every joint and the host at 10 Hz (classic, 1 B).
///
/// --measured runs 1, 2, 4, 6 and 8 simulated joints (the firmware's CANopen node, started,
/// TPDO event timer at the period) on the simulated bus, classic 1 Mbit/s and FD 1/5 Mbit/s,
/// the host sending the joints' commands every period (classic: one RPDO per joint; FD: the
/// shared command frame) and its heartbeat, and reports the share
/// of time the bus was busy (real bits of every frame, stuffing included) over 200 ms.
///
/// Example:
///   jointctl bus-budget --joints 6 --rate 1000 --bitrate 1000000 --data-bitrate 5000000
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct BusBudgetArgs {
    /// Number of joints on the bus (1..=127, the CANopen node ids)
    #[arg(long, value_parser = num::int::<u32>(1, 127))]
    pub joints: u32,
    /// Telemetry rate per joint, Hz (0 < HZ ≤ 10000)
    #[arg(long, value_name = "HZ", value_parser = num::positive(10_000.0, "Hz"))]
    pub rate: f64,
    /// Nominal (arbitration) bitrate, bit/s (10000..=1000000)
    #[arg(long, value_name = "BIT/S", default_value_t = 1_000_000, value_parser = num::bitrate(num::CAN_BITRATE))]
    pub bitrate: u32,
    /// CAN FD data-phase bitrate, bit/s (--bitrate ≤ BIT/S ≤ 8000000; omit for classic CAN)
    #[arg(long, value_name = "BIT/S", value_parser = num::bitrate(num::CAN_FD_DATA_BITRATE))]
    pub data_bitrate: Option<u32>,
    /// Also print the joints × rate table for classic 1 Mbit/s and FD 1/5 Mbit/s
    #[arg(long)]
    pub table: bool,
    /// Also measure 1, 2, 4, 6, 8 joints at --rate on the simulated bus, classic and FD side
    /// by side (--rate must be 1000/k Hz: the TPDO event timer counts whole ms)
    #[arg(long)]
    pub measured: bool,
    #[arg(long)]
    pub json: bool,
}

/// Bus time per second (ns per s = load × 1e9) of the traffic, (worst, typical).
pub fn load(joints: u32, rate: f64, bitrate: u32, data_bitrate: Option<u32>) -> (f64, f64) {
    let mut worst = 0.0;
    let mut typical = 0.0;
    let mut rng: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut payload = |n: usize| -> Vec<u8> {
        (0..n)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                (rng >> 24) as u8
            })
            .collect()
    };
    const SAMPLES: usize = 64;
    let mut frame = |id: u16, n: usize, fd: bool, hz: f64| {
        let (w, t) = match (fd, data_bitrate) {
            (true, Some(d)) => {
                let w = timing::fd_time_ns(id, &vec![0u8; n], bitrate, d, true) as f64;
                let t =
                    (0..SAMPLES).map(|_| timing::fd_time_ns(id, &payload(n), bitrate, d, false) as f64).sum::<f64>()
                        / SAMPLES as f64;
                (w, t)
            }
            _ => {
                let w = f64::from(timing::classic_bits_worst(n)) * 1e9 / f64::from(bitrate);
                let t = (0..SAMPLES).map(|_| timing::classic_time_ns(id, &payload(n), bitrate) as f64).sum::<f64>()
                    / SAMPLES as f64;
                (w, t)
            }
        };
        worst += w * hz;
        typical += t * hz;
    };
    for j in 1..=joints.min(127) as u16 {
        if data_bitrate.is_some() {
            frame(0x380 + j, 32, true, rate);
        } else {
            frame(0x180 + j, 8, false, rate);
            frame(0x280 + j, 8, false, rate);
            frame(0x200 + j, 2, false, rate);
        }
        frame(0x700 + j, 1, false, 10.0);
    }
    frame(0x77F, 1, false, 10.0);
    if data_bitrate.is_some() && joints > 0 {
        frame(0x200, 2 * joints.min(31) as usize, true, rate);
    }
    (worst / 1e9, typical / 1e9)
}

/// Most joints whose worst-case load stays at or below `limit`.
pub fn max_joints(rate: f64, bitrate: u32, data_bitrate: Option<u32>, limit: f64) -> u32 {
    (0..=127).rev().find(|&j| load(j, rate, bitrate, data_bitrate).0 <= limit).unwrap_or(0)
}

/// What [`measure`] saw on the simulated bus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// share of the measurement window the bus was busy
    pub load: f64,
    /// frames per second, and of them CAN FD frames
    pub frames_per_s: f64,
    pub fd_frames_per_s: f64,
    /// frames still waiting at the end: more than the joints' count means the bus saturated
    pub backlog: usize,
}

/// Joints counts the measured table covers.
pub const MEASURED_JOINTS: [u32; 5] = [1, 2, 4, 6, 8];

/// Run `joints` simulated joints (node ids 1..) with their TPDOs every `period_ms` on the
/// simulated bus — classic at `bitrate`, or FD with BRS at `bitrate`/`data_bitrate` (FD nodes:
/// TPDO3) — with the host's RPDO1 to each joint every period and its heartbeat at 10 Hz;
/// the load is measured over 200 ms after 50 ms of settling.
pub fn measure(joints: u32, period_ms: u16, bitrate: u32, data_bitrate: Option<u32>) -> anyhow::Result<Measured> {
    let mut bus = match data_bitrate {
        Some(d) => SimBus::new_fd(bitrate, d),
        None => SimBus::new(bitrate),
    };
    let fd = data_bitrate.is_some();
    let tpdos: &[u8] = if fd { &[od::TPDO_FD] } else { &[0, 1] };
    for j in 1..=joints.min(127) as u8 {
        let js = JointSim::with_config(
            NodeConfig::new(j).with_fd(fd),
            None,
            SimStorage::Memory(MemoryStorage::default()),
            0,
        );
        let js = Arc::new(Mutex::new(js));
        if let Ok(mut s) = js.lock() {
            for &n in tpdos {
                s.node
                    .write(od::TPDO_COMM + u16::from(n), 5, &period_ms.to_le_bytes())
                    .map_err(|e| anyhow::anyhow!("TPDO{} event timer: {}", n + 1, e.describe()))?;
            }
        }
        bus.attach(js);
    }
    let hb = |b: &mut SimBus| -> anyhow::Result<()> { Ok(b.send(&frame(0x77F, &[5])?)?) };
    bus.run_for(Duration::from_millis(2));
    hb(&mut bus)?;
    bus.send(&frame(0, &[1, 0])?)?; // NMT start all
    let period = Duration::from_millis(u64::from(period_ms));
    let settle = 50 / u64::from(period_ms.max(1));
    let window = 200 / u64::from(period_ms.max(1));
    let mut start = (0, 0, 0, 0);
    for k in 0..settle + window {
        if k == settle {
            start = (bus.now_ns(), bus.stats.busy_ns, bus.stats.frames, bus.stats.fd_frames);
        }
        if k * u64::from(period_ms) % 100 == 0 {
            hb(&mut bus)?;
        }
        if fd {
            // one FD frame with every joint's command (0.16 N·m assist), joint j at 2(j − 1)
            let cmd: Vec<u8> = (0..joints.min(31)).flat_map(|_| [0x10, 0x00]).collect();
            let f = CanFrame::new_fd(od::SHARED_CMD_COB, &cmd, true).ok_or_else(|| anyhow::anyhow!("shared frame"))?;
            bus.send(&f)?;
        } else {
            for j in 1..=joints.min(127) as u16 {
                bus.send(&frame(0x200 + j, &[0x10, 0x00])?)?;
            }
        }
        bus.run_for(period);
        bus.drain_inbox();
    }
    let t = (bus.now_ns() - start.0) as f64;
    Ok(Measured {
        load: (bus.stats.busy_ns - start.1) as f64 / t,
        frames_per_s: (bus.stats.frames - start.2) as f64 * 1e9 / t,
        fd_frames_per_s: (bus.stats.fd_frames - start.3) as f64 * 1e9 / t,
        backlog: bus.backlog(),
    })
}

fn frame(id: u16, d: &[u8]) -> anyhow::Result<CanFrame> {
    CanFrame::new(id, d).ok_or_else(|| anyhow::anyhow!("frame {id:03X}"))
}

/// The TPDO period for `rate`, whole ms.
fn period_ms(rate: f64) -> anyhow::Result<u16> {
    let p = 1000.0 / rate;
    if (p - p.round()).abs() > 1e-9 || !(1.0..=1000.0).contains(&p.round()) {
        anyhow::bail!("--measured needs a rate of 1000/k Hz (k = 1..1000): the TPDO event timer counts whole ms");
    }
    Ok(p.round() as u16)
}

/// The measured table: per joints count, classic 1 Mbit/s and FD 1/5 Mbit/s.
pub fn measured_table(rate: f64) -> anyhow::Result<Vec<(u32, Measured, Measured)>> {
    let p = period_ms(rate)?;
    MEASURED_JOINTS
        .iter()
        .map(|&j| Ok((j, measure(j, p, 1_000_000, None)?, measure(j, p, 1_000_000, Some(5_000_000))?)))
        .collect()
}

fn print_measured(rate: f64, json: bool) -> anyhow::Result<()> {
    let rows = measured_table(rate)?;
    if json {
        let cells: Vec<serde_json::Value> = rows
            .iter()
            .map(|(j, c, f)| {
                let m = |m: &Measured| {
                    serde_json::json!({"load": m.load, "frames_per_s": m.frames_per_s,
                        "fd_frames_per_s": m.fd_frames_per_s, "backlog": m.backlog})
                };
                serde_json::json!({"joints": j, "classic_1M": m(c), "fd_1M_5M": m(f)})
            })
            .collect();
        println!("{}", serde_json::json!({"measured": {"rate_hz": rate, "rows": cells}}));
        return Ok(());
    }
    println!(
        "
measured on the simulated bus, {rate} Hz per joint (joints' CANopen nodes, 200 ms):"
    );
    println!("{:>8} | {:>24} | {:>24}", "joints", "classic 1 Mbit/s", "CAN FD 1/5 Mbit/s");
    for (j, c, f) in rows {
        let cell = |m: &Measured| {
            // more than two periods' frames waiting: the bus cannot keep up
            let sat = if m.backlog > 6 * j as usize + 2 { " SATURATED" } else { "" };
            format!("{:.1} %{sat}", 100.0 * m.load)
        };
        println!("{j:>8} | {:>24} | {:>24}", cell(&c), cell(&f));
    }
    Ok(())
}

pub fn run(a: &BusBudgetArgs) -> anyhow::Result<()> {
    if let Some(d) = a.data_bitrate.filter(|&d| d < a.bitrate) {
        anyhow::bail!(
            "--data-bitrate {d} is below --bitrate {}: the data phase is at least the nominal rate",
            a.bitrate
        );
    }
    let (w, t) = load(a.joints, a.rate, a.bitrate, a.data_bitrate);
    let fit = max_joints(a.rate, a.bitrate, a.data_bitrate, 0.8);
    let kind = match a.data_bitrate {
        Some(d) => format!("CAN FD {}/{} kbit/s", a.bitrate / 1000, d / 1000),
        None => format!("classic CAN {} kbit/s", a.bitrate / 1000),
    };
    let rates = [100.0, 200.0, 500.0, 1000.0];
    let joints = [1u32, 2, 4, 6, 8, 12];
    let configs: [(&str, u32, Option<u32>); 2] =
        [("classic CAN 1 Mbit/s", 1_000_000, None), ("CAN FD 1/5 Mbit/s", 1_000_000, Some(5_000_000))];
    if a.json {
        let table: Vec<serde_json::Value> = if a.table {
            configs
                .iter()
                .map(|(name, b, d)| {
                    let cells: Vec<serde_json::Value> = joints
                        .iter()
                        .flat_map(|&j| rates.iter().map(move |&r| (j, r)))
                        .map(|(j, r)| {
                            let (w, t) = load(j, r, *b, *d);
                            serde_json::json!({"joints": j, "rate_hz": r, "worst": w, "typical": t})
                        })
                        .collect();
                    let max: Vec<serde_json::Value> = rates
                        .iter()
                        .map(|&r| serde_json::json!({"rate_hz": r, "max_joints_80pct": max_joints(r, *b, *d, 0.8)}))
                        .collect();
                    serde_json::json!({"bus": name, "cells": cells, "max": max})
                })
                .collect()
        } else {
            Vec::new()
        };
        println!(
            "{}",
            serde_json::json!({"bus": kind, "joints": a.joints, "rate_hz": a.rate, "load_worst": w, "load_typical": t,
                "max_joints_at_80pct_worst": fit, "table": table})
        );
        if a.measured {
            print_measured(a.rate, true)?;
        }
        return Ok(());
    }
    println!(
        "{kind}: {} joints at {} Hz → bus load {:.1} % worst case, {:.1} % typical; at most {fit} joints at this rate stay ≤ 80 % worst case",
        a.joints,
        a.rate,
        100.0 * w,
        100.0 * t
    );
    if a.table {
        for (name, b, d) in configs {
            println!("\n{name}: worst-case bus load (typical in parentheses)");
            print!("{:>8}", "joints");
            for r in rates {
                print!(" | {:>16}", format!("{r} Hz"));
            }
            println!();
            for j in joints {
                print!("{j:>8}");
                for r in rates {
                    let (w, t) = load(j, r, b, d);
                    print!(" | {:>16}", format!("{:.1} % ({:.1} %)", 100.0 * w, 100.0 * t));
                }
                println!();
            }
            print!("{:>8}", "max ≤80%");
            for r in rates {
                print!(" | {:>16}", max_joints(r, b, d, 0.8));
            }
            println!();
        }
    }
    if a.measured {
        print_measured(a.rate, false)?;
    }
    Ok(())
}
