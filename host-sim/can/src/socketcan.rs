//! Linux SocketCAN (`socketcan:can0`, `socketcan:vcan0`) as a [`Bus`], through the
//! `socketcan` crate; frames convert through `embedded_can::Frame`, as on the MCU.

use super::Bus;
use embedded_can::{Frame as _, Id, StandardId};
use joint_core::canopen::CanFrame;
use socketcan::{CanSocket, Socket};
use std::time::{Duration, Instant};

pub struct SocketCanBus {
    sock: CanSocket,
    iface: String,
    t0: Instant,
}

impl SocketCanBus {
    pub fn open(iface: &str) -> anyhow::Result<SocketCanBus> {
        let sock = CanSocket::open(iface).map_err(|e| anyhow::anyhow!("socketcan: cannot open {iface}: {e}"))?;
        Ok(SocketCanBus { sock, iface: iface.to_string(), t0: Instant::now() })
    }
}

impl Bus for SocketCanBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        let id = StandardId::new(f.id()).ok_or_else(|| std::io::Error::other("id > 0x7FF"))?;
        let frame = socketcan::CanFrame::new(id, f.data()).ok_or_else(|| std::io::Error::other("frame"))?;
        self.sock.write_frame(&frame)
    }

    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        let end = Instant::now() + timeout;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            self.sock.set_read_timeout(left)?;
            match self.sock.read_frame() {
                Ok(f) => {
                    if let (Id::Standard(id), false) = (f.id(), f.is_remote_frame()) {
                        if let Some(c) = CanFrame::new(id.as_raw(), f.data()) {
                            return Ok(Some(c));
                        }
                    }
                }
                Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                    return Ok(None)
                }
                Err(e) => return Err(e),
            }
        }
    }

    fn now_us(&self) -> u64 {
        self.t0.elapsed().as_micros() as u64
    }

    fn describe(&self) -> String {
        format!("socketcan {}", self.iface)
    }
}
