//! `jointctl push`: stage a model's parameters on a joint by SDO, read them back, commit.

use super::bus_args::{check_node, open_master, BusArgs, SdoArgs};
use super::num;
use clap::Args;
use joint_can::transfer::{self, PushOptions};
use joint_formats::model_file::ModelFile;
use std::path::PathBuf;

/// Push a model TOML to a joint node: every parameter is staged by SDO, read back, and the
/// set is committed as a whole (the joint checks it and keeps its old set if it fails). Then
/// the joint's set is read back: the command succeeds only when the new set runs, and says
/// which set runs when it fails (the previous one, or unknown when the joint stops
/// answering). Lost frames are retried; a joint that resets mid-push is pushed again. A model
/// that fails the plausibility gate (an [inertia] j ≤ 0, negative friction or spring terms) is
/// refused before any CAN traffic unless --force.
///
/// Example:
///   jointctl push examples/models/trunk-right.toml --node 5 --bus slcan:/dev/ttyACM0 --save
#[derive(Debug, Args)]
#[command(verbatim_doc_comment)]
pub struct PushArgs {
    /// Model TOML to push
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Node id of the joint (1..=127)
    #[arg(long, value_parser = num::node_id())]
    pub node: u8,
    /// Persist the committed set on the joint (object 0x1010 "save")
    #[arg(long)]
    pub save: bool,
    /// Put the node in pre-operational first (torque off): needed when safety-relevant
    /// parameters (ratio, fraction, limits, rates, timeouts) change
    #[arg(long)]
    pub pre_operational: bool,
    /// Print one JSON object instead of the human summary
    #[arg(long)]
    pub json: bool,
    /// Push a model that fails the plausibility gate (non-positive inertia, negative friction
    /// or stiffness); the joint's own check still applies
    #[arg(long)]
    pub force: bool,
    /// The slcan PATH is an adapter on a real CAN bus running at its @BITRATE: the push's time
    /// is then compared with the wire minimum of its frames at that rate. Without it an slcan
    /// push reports host/transport time only (a pty or a socat link has no bit timing). The
    /// simulated bus is always compared (its bit-timing model), SocketCAN when the interface
    /// reports its bit timing (a vcan does not)
    #[arg(long)]
    pub real_bus: bool,
    #[command(flatten)]
    pub bus: BusArgs,
    #[command(flatten)]
    pub sdo: SdoArgs,
}

pub fn run(a: &PushArgs) -> anyhow::Result<()> {
    check_node(a.node)?;
    if a.real_bus && !matches!(a.bus.spec()?, joint_can::BusSpec::Slcan { .. }) {
        anyhow::bail!(
            "--real-bus is for slcan adapters: the simulated bus is always timed, and SocketCAN reads the \
             interface's bit timing"
        );
    }
    let mf = ModelFile::read_file(&a.model)?;
    // Refuse locally what the joint would refuse, with the file's key and line named.
    mf.param_set()?;
    // And what it would accept but no physical joint has; both before any CAN traffic.
    let gate = joint_analysis::plausible::check(&mf, &[]);
    if !gate.plausible() {
        let why = gate.reasons().join("; ");
        if !a.force {
            anyhow::bail!("{}: implausible model, not pushed: {why} (--force pushes it anyway)", a.model.display());
        }
        eprintln!("warning: {}: implausible model pushed (--force): {why}", a.model.display());
    }
    let raw = mf.raw_params()?;
    let (mut m, _sim) = open_master(&a.bus, &[a.node])?;
    a.sdo.apply(&mut m, a.node)?;
    let bar = indicatif::ProgressBar::new(1);
    if a.json {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_prefix(format!("node {}", a.node));
    let opts = PushOptions { pre_operational: a.pre_operational, save: a.save };
    // Ctrl-C stops the push before its next transfer; what it staged is then discarded and the
    // set in force read back, so nothing half-pushed is left waiting for a commit
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let cancel = cancel.clone();
        ctrlc::set_handler(move || cancel.store(true, std::sync::atomic::Ordering::SeqCst))?;
    }
    let v = transfer::push_verified_until(
        &mut m,
        a.node,
        &raw,
        opts,
        &mut |p| {
            bar.set_length(p.total as u64);
            bar.set_position(p.done as u64);
            bar.set_message(p.what.clone());
        },
        &cancel,
    );
    bar.finish_and_clear();
    let in_force = match &v.in_force {
        transfer::InForce::New => "new".to_string(),
        transfer::InForce::Previous => "previous".to_string(),
        transfer::InForce::Unknown(_) => "unknown".to_string(),
    };
    if !v.ok() {
        let what = match &v.in_force {
            transfer::InForce::New => format!("the new set runs on node {} (read back whole), but", a.node),
            transfer::InForce::Previous => {
                format!(
                    "node {} runs its previous set, not the pushed one (read back whole; commits are all or nothing):",
                    a.node
                )
            }
            transfer::InForce::Unknown(why) => format!("which set runs on node {} is not known ({why}):", a.node),
        };
        if a.json {
            let j = serde_json::json!({
                "node": a.node, "model": a.model.display().to_string(), "bus": m.bus.describe(), "ok": false,
                "simulated": a.bus.is_sim(),
                "in_force": in_force, "attempts": v.attempts, "retries": v.retries, "error": v.error,
            });
            println!("{j}");
        }
        anyhow::bail!("{what} {}", v.error.as_deref().unwrap_or("the push did not complete"));
    }
    let Some(r) = v.report else {
        // the commit's confirmation was lost but the read-back shows the new set whole
        println!(
            "pushed {} to node {}: the commit's confirmation was lost, the read-back shows the new set running ({} retries)",
            a.model.display(),
            a.node,
            v.retries
        );
        return Ok(());
    };
    let basis =
        transfer::TimeBasis::of(&a.bus.spec()?, a.real_bus, a.bus.bitrate, joint_can::socketcan::interface_bitrate);
    if a.json {
        let (time_basis, wire, ratio, bitrate, note) = match &basis {
            transfer::TimeBasis::Wire { bitrate, how } => {
                let wire = transfer::wire_minimum_us(&r, *bitrate);
                ("bus", Some(wire), Some(r.elapsed_us as f64 / wire), Some(*bitrate), how.to_string())
            }
            transfer::TimeBasis::Host { why } => ("host", None, None, None, why.clone()),
        };
        let j = serde_json::json!({
            "node": a.node, "model": a.model.display().to_string(), "bus": m.bus.describe(), "ok": true,
            "simulated": a.bus.is_sim(),
            "sdo_transfers": r.sdo_transfers, "frames": r.frames, "bits": r.bits,
            "elapsed_us": r.elapsed_us, "time_basis": time_basis, "time_note": note, "bitrate": bitrate,
            "wire_minimum_us": wire, "ratio": ratio, "saved": r.saved,
            "in_force": in_force, "attempts": v.attempts, "retries": v.retries,
        });
        println!("{j}");
    } else {
        let time = match &basis {
            transfer::TimeBasis::Wire { bitrate, .. } => {
                let wire = transfer::wire_minimum_us(&r, *bitrate);
                format!(
                    "{:.2} ms (wire minimum of those frames at {} kbit/s: {:.2} ms, ratio {:.3})",
                    r.elapsed_us as f64 / 1000.0,
                    bitrate / 1000,
                    wire / 1000.0,
                    r.elapsed_us as f64 / wire
                )
            }
            transfer::TimeBasis::Host { why } => format!(
                "{:.2} ms of host/transport time, not bus time (no wire minimum: {why})",
                r.elapsed_us as f64 / 1000.0
            ),
        };
        println!(
            "pushed {} to node {} on {}: {} SDO transfers, {} frames, {}{}{}; read back: the new set runs{}",
            a.model.display(),
            a.node,
            m.bus.describe(),
            r.sdo_transfers,
            r.frames,
            time,
            if r.saved { ", saved" } else { "" },
            a.bus.sim_note(),
            if v.retries > 0 || v.attempts > 1 {
                format!(" ({} transfers retried, {} pushes)", v.retries, v.attempts)
            } else {
                String::new()
            }
        );
    }
    Ok(())
}
