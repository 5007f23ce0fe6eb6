//! CAN on the host: one [`Bus`] trait over the in-process simulated bus (virtual time, with a
//! bit-timing model), Lawicel `slcan` serial adapters and Linux SocketCAN; the SDO master that
//! `jointctl` uses; and the EDS generator.
//!
//! Bus names on the command line: `sim` (in-process), `slcan:PATH[@BITRATE]` (a CANable or any
//! Lawicel adapter, or one end of a `socat` pty pair), `socketcan:IFACE`.

pub mod eds;
pub mod master;
pub mod script_bus;
pub mod sim_bus;
pub mod slcan;
pub mod socketcan;
pub mod tap;
pub mod timing;
pub mod transfer;

use joint_core::canopen::CanFrame;
use std::time::Duration;

/// A CAN bus as the host sees it: send frames, receive frames with a timeout, and a clock.
/// Real buses use the wall clock; the simulated bus has a virtual clock that only moves while
/// someone waits on it, so tests and timing figures do not depend on the machine's speed.
pub trait Bus: Send {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()>;
    /// The next frame from the bus, or `None` when `timeout` passes first.
    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>>;
    /// Microseconds on this bus's clock.
    fn now_us(&self) -> u64;
    /// What this bus is, for messages.
    fn describe(&self) -> String;
}

/// A parsed `--bus` argument.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusSpec {
    Sim,
    Slcan {
        path: String,
        bitrate: u32,
    },
    SocketCan {
        iface: String,
    },
    /// a can-utils capture played back as the bus (read-only: what is sent goes nowhere)
    Replay {
        path: String,
    },
}

impl std::str::FromStr for BusSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "sim" {
            return Ok(BusSpec::Sim);
        }
        if let Some(rest) = s.strip_prefix("slcan:") {
            let (path, bitrate) = match rest.rsplit_once('@') {
                Some((p, b)) => (p, b.parse::<u32>().map_err(|_| format!("bus `{s}`: bitrate `{b}` is not a number"))?),
                None => (rest, 1_000_000),
            };
            if path.is_empty() {
                return Err(format!("bus `{s}`: slcan needs a serial port path, e.g. slcan:/dev/ttyACM0"));
            }
            if slcan::bitrate_code(bitrate).is_none() {
                return Err(format!("bus `{s}`: slcan bitrates are 10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k, 1M"));
            }
            return Ok(BusSpec::Slcan { path: path.to_string(), bitrate });
        }
        if let Some(iface) = s.strip_prefix("socketcan:") {
            if iface.is_empty() {
                return Err(format!("bus `{s}`: socketcan needs an interface, e.g. socketcan:can0"));
            }
            return Ok(BusSpec::SocketCan { iface: iface.to_string() });
        }
        if let Some(path) = s.strip_prefix("replay:") {
            if path.is_empty() {
                return Err(format!("bus `{s}`: replay needs a capture file, e.g. replay:bus.log"));
            }
            return Ok(BusSpec::Replay { path: path.to_string() });
        }
        Err(format!("unknown bus `{s}`: use sim, slcan:PATH[@BITRATE], socketcan:IFACE or replay:CAPTURE.log"))
    }
}

/// Open a real bus for CAN FD: an slcan adapter with its data phase at `data_bitrate`
/// (`Yn`); a SocketCAN socket receives FD frames in any case (the interface's own data bit
/// rate is set with `ip link`).
pub fn open_fd(spec: &BusSpec, data_bitrate: u32) -> anyhow::Result<Box<dyn Bus>> {
    match spec {
        BusSpec::Slcan { path, bitrate } => Ok(Box::new(slcan::SlcanBus::open_fd(path, *bitrate, data_bitrate)?)),
        other => open(other),
    }
}

/// Open a real bus (`slcan`, `socketcan`). The simulated bus is built by its owner, which
/// also attaches the simulated joints, so it is not opened here.
pub fn open(spec: &BusSpec) -> anyhow::Result<Box<dyn Bus>> {
    match spec {
        BusSpec::Sim => anyhow::bail!("the simulated bus exists only inside one process: use `jointctl sim` with --bus slcan:PATH to serve joints to another program"),
        BusSpec::Slcan { path, bitrate } => Ok(Box::new(slcan::SlcanBus::open(path, *bitrate)?)),
        BusSpec::SocketCan { iface } => Ok(Box::new(socketcan::SocketCanBus::open(iface)?)),
        BusSpec::Replay { .. } => anyhow::bail!("a capture is replayed by its reader (jointctl's --bus replay:FILE)"),
    }
}
