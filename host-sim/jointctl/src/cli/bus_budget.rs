//! `jointctl bus-budget`: bus load of joint telemetry from the real frame layout.

use super::num;
use clap::Args;
use joint_can::timing;

/// Bus load of J joints streaming telemetry at R Hz, from the frames' real bit length (bit
/// stuffing included: worst case, and typical = mean over random payloads).
///
/// Traffic per joint per period: classic CAN — TPDO1 (8 B: q, q̇, τ, faults), TPDO2 (8 B: q̈,
/// τ measured, temperature, gain) and the host's RPDO1 (2 B: assist command); CAN FD (with
/// --data-bitrate, bit-rate switch) — TPDO1+TPDO2 in one 16-byte frame and the 2-byte RPDO.
/// Plus heartbeats: every joint and the host at 10 Hz (classic, 1 byte). The FD figures are a
/// projection: the node implemented today speaks classic CAN.
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
            frame(0x180 + j, 16, true, rate);
            frame(0x200 + j, 2, true, rate);
        } else {
            frame(0x180 + j, 8, false, rate);
            frame(0x280 + j, 8, false, rate);
            frame(0x200 + j, 2, false, rate);
        }
        frame(0x700 + j, 1, false, 10.0);
    }
    frame(0x77F, 1, false, 10.0);
    (worst / 1e9, typical / 1e9)
}

/// Most joints whose worst-case load stays at or below `limit`.
pub fn max_joints(rate: f64, bitrate: u32, data_bitrate: Option<u32>, limit: f64) -> u32 {
    (0..=127).rev().find(|&j| load(j, rate, bitrate, data_bitrate).0 <= limit).unwrap_or(0)
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
    Ok(())
}
