//! Linux SocketCAN (`socketcan:can0`, `socketcan:vcan0`) as a [`Bus`], classic and CAN FD.
//!
//! The socket is the `socketcan` crate's `CanFdSocket` (a raw CAN socket with
//! `CAN_RAW_FD_FRAMES` set), so it receives classic frames (`struct can_frame`, `CAN_MTU` 16
//! bytes) and FD frames (`struct canfd_frame`, `CANFD_MTU` 72 bytes) alike; a read returns one
//! whole struct and its length says which. We read and write those structs as bytes
//! ([`encode`], [`decode`], `linux/can.h`) rather than through the crate's frame types, so the
//! layout the kernel sees is the one the unit tests check byte for byte. Sending FD frames
//! needs an interface whose MTU is 72 (`ip link set can0 mtu 72` / `type can ... fd on`).

use super::Bus;
use joint_core::canopen::frame::fd_dlc_of_len;
use joint_core::canopen::CanFrame;
use socketcan::{CanFdSocket, Socket};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// `sizeof(struct can_frame)`.
pub const CAN_MTU: usize = 16;
/// `sizeof(struct canfd_frame)`.
pub const CANFD_MTU: usize = 72;
/// `canfd_frame.flags`: bit-rate switch, error state indicator, FD frame (set by the kernel
/// on FD frames it receives since Linux 5.14; ignored on send).
const CANFD_BRS: u8 = 0x01;
const CANFD_FDF: u8 = 0x04;
/// `can_id` flags: extended, remote, error frame.
const CAN_EFF_FLAG: u32 = 0x8000_0000;
const CAN_RTR_FLAG: u32 = 0x4000_0000;
const CAN_ERR_FLAG: u32 = 0x2000_0000;

/// The nominal bit rate a SocketCAN interface reports through netlink (`ip -details link show`:
/// `bitrate`), `None` when it has no bit timing (a `vcan`, which moves frames between sockets
/// at memory speed) or cannot be asked.
pub fn interface_bitrate(iface: &str) -> Option<u32> {
    socketcan::CanInterface::open(iface).ok()?.bit_rate().ok().flatten().filter(|&b| b > 0)
}

/// A frame as the kernel's struct: `can_frame` (16 bytes) for classic frames, `canfd_frame`
/// (72 bytes) for FD frames. `can_id` is in host byte order, as the kernel keeps it.
pub fn encode(f: &CanFrame) -> Vec<u8> {
    let mtu = if f.is_fd() { CANFD_MTU } else { CAN_MTU };
    let flags = if f.is_fd() { CANFD_FDF | if f.brs() { CANFD_BRS } else { 0 } } else { 0 };
    let mut b = Vec::with_capacity(CANFD_MTU);
    b.extend_from_slice(&u32::from(f.id()).to_ne_bytes());
    // len, flags (classic: __pad), res0, res1 (classic: len8_dlc, unused for len ≤ 8)
    b.extend_from_slice(&[f.len() as u8, flags, 0, 0]);
    b.extend_from_slice(f.data());
    b.resize(mtu, 0);
    b
}

/// A frame from one struct the socket returned; `None` for extended, remote and error
/// frames (not CANopen traffic this node serves), a wrong size or an invalid length.
pub fn decode(b: &[u8]) -> Option<CanFrame> {
    let id = u32::from_ne_bytes(b.get(..4)?.try_into().ok()?);
    if id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG) != 0 || id > 0x7FF {
        return None;
    }
    let len = usize::from(*b.get(4)?);
    let data = b.get(8..8 + len)?;
    match b.len() {
        CAN_MTU => CanFrame::new(id as u16, data),
        CANFD_MTU => {
            fd_dlc_of_len(len)?;
            CanFrame::new_fd(id as u16, data, b.get(5)? & CANFD_BRS != 0)
        }
        _ => None,
    }
}

pub struct SocketCanBus {
    sock: CanFdSocket,
    iface: String,
    t0: Instant,
}

impl SocketCanBus {
    pub fn open(iface: &str) -> anyhow::Result<SocketCanBus> {
        let sock = CanFdSocket::open(iface).map_err(|e| anyhow::anyhow!("socketcan: cannot open {iface}: {e}"))?;
        Ok(SocketCanBus { sock, iface: iface.to_string(), t0: Instant::now() })
    }
}

impl Bus for SocketCanBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        let b = encode(f);
        let n = self.sock.write(&b)?;
        if n != b.len() {
            return Err(std::io::Error::other(format!("socketcan: short write {n} of {}", b.len())));
        }
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        let end = Instant::now() + timeout;
        let mut buf = [0u8; CANFD_MTU];
        loop {
            let left = end.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(None);
            }
            self.sock.set_read_timeout(left)?;
            match self.sock.read(&mut buf) {
                Ok(n) => {
                    if let Some(c) = buf.get(..n).and_then(decode) {
                        return Ok(Some(c));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classic_frames_are_can_frame_structs() {
        let f = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 1]).unwrap();
        let b = encode(&f);
        let id = 0x605u32.to_ne_bytes();
        assert_eq!(b, [id[0], id[1], id[2], id[3], 4, 0, 0, 0, 0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        assert_eq!(decode(&b), Some(f));
    }

    #[test]
    fn fd_frames_are_canfd_frame_structs_of_72_bytes() {
        let d: Vec<u8> = (0..32).collect();
        let f = CanFrame::new_fd(0x385, &d, true).unwrap();
        let b = encode(&f);
        assert_eq!(b.len(), 72);
        assert_eq!(&b[..4], &0x385u32.to_ne_bytes());
        assert_eq!((b[4], b[5], b[6], b[7]), (32, CANFD_FDF | CANFD_BRS, 0, 0));
        assert_eq!(&b[8..40], &d[..]);
        assert!(b[40..].iter().all(|&x| x == 0));
        assert_eq!(decode(&b), Some(f));
        // without BRS; and a kernel before 5.14 leaves FDF clear: the size says FD
        let slow = CanFrame::new_fd(0x385, &d[..12], false).unwrap();
        let mut b = encode(&slow);
        assert_eq!(b[5], CANFD_FDF);
        b[5] = 0;
        assert_eq!(decode(&b), Some(slow));
        // an 8-byte FD frame stays FD
        let short = CanFrame::new(0x605, &[1; 8]).unwrap().into_fd(true);
        assert_eq!(decode(&encode(&short)), Some(short));
    }

    #[test]
    fn what_the_node_does_not_serve_is_not_a_frame() {
        let mut b = encode(&CanFrame::new(0x123, &[1]).unwrap());
        b[..4].copy_from_slice(&(0x123 | CAN_EFF_FLAG).to_ne_bytes());
        assert_eq!(decode(&b), None, "extended");
        b[..4].copy_from_slice(&(0x123 | CAN_RTR_FLAG).to_ne_bytes());
        assert_eq!(decode(&b), None, "remote");
        b[..4].copy_from_slice(&(0x123 | CAN_ERR_FLAG).to_ne_bytes());
        assert_eq!(decode(&b), None, "error frame");
        let mut fd = encode(&CanFrame::new_fd(0x123, &[0; 12], true).unwrap());
        fd[4] = 13; // not an FD length
        assert_eq!(decode(&fd), None);
        fd[4] = 65;
        assert_eq!(decode(&fd), None);
        let mut c = encode(&CanFrame::new(0x123, &[0; 8]).unwrap());
        c[4] = 9; // a classic struct holds 8
        assert_eq!(decode(&c), None);
        assert_eq!(decode(&c[..10]), None, "wrong size");
    }
}
