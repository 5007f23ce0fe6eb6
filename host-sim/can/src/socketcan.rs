//! Linux SocketCAN (`socketcan:can0`, `socketcan:vcan0`) as a [`Bus`], classic and CAN FD.
//!
//! The socket is the `socketcan` crate's `CanFdSocket` (a raw CAN socket with
//! `CAN_RAW_FD_FRAMES` set), so it receives classic frames (`struct can_frame`, `CAN_MTU` 16
//! bytes) and FD frames (`struct canfd_frame`, `CANFD_MTU` 72 bytes) alike; the crate tells them
//! apart by the size the kernel returned (so an FD frame from a kernel before 5.14, which leaves
//! `CANFD_FDF` clear, is still FD). Its frame types implement `embedded_can::Frame`, so the
//! conversion to and from the node's frame is the core's (`joint_core::canopen::hal`, what the
//! boards use), not one of our own: [`from_socket`] and [`to_socket`] only add what
//! `embedded_can` does not carry, the FD frame type and its bit-rate switch. The unit tests check
//! the structs the kernel sees byte for byte. Sending FD frames needs an interface whose MTU is
//! 72 (`ip link set can0 mtu 72` / `type can ... fd on`).

use super::Bus;
use joint_core::canopen::hal::{self, Rejected};
use joint_core::canopen::CanFrame;
use socketcan::{CanAnyFrame, CanDataFrame, CanFdFrame, CanFdSocket, Socket};
use std::time::{Duration, Instant};

/// The nominal bit rate a SocketCAN interface reports through netlink (`ip -details link show`:
/// `bitrate`), `None` when it has no bit timing (a `vcan`, which moves frames between sockets
/// at memory speed) or cannot be asked.
pub fn interface_bitrate(iface: &str) -> Option<u32> {
    socketcan::CanInterface::open(iface).ok()?.bit_rate().ok().flatten().filter(|&b| b > 0)
}

/// A frame the socket returned as the node's frame, through the core's conversion: classic
/// frames by [`hal::to_core`], FD frames by [`hal::to_core_fd`] with the struct's bit-rate
/// switch. Extended and remote frames are refused with the core's reason; error frames (which
/// the socket only delivers when asked to) as remote ones, no CANopen traffic either.
pub fn from_socket(f: &CanAnyFrame) -> Result<CanFrame, Rejected> {
    match f {
        CanAnyFrame::Normal(d) => hal::to_core(d),
        CanAnyFrame::Fd(d) => hal::to_core_fd(d, true, d.is_brs()),
        CanAnyFrame::Remote(r) => hal::to_core(r),
        CanAnyFrame::Error(_) => Err(Rejected::Remote),
    }
}

/// The node's frame as the socket's, through the core's [`hal::to_hal`]: a classic frame as a
/// `can_frame`, an FD frame (of any length, 8 bytes and fewer included) as a `canfd_frame`
/// with its bit-rate switch. `None` only for a frame the crate refuses (none the node makes).
pub fn to_socket(f: &CanFrame) -> Option<CanAnyFrame> {
    if f.is_fd() {
        let mut fd: CanFdFrame = hal::to_hal(f)?;
        fd.set_brs(f.brs());
        Some(fd.into())
    } else {
        hal::to_hal::<CanDataFrame>(f).map(CanAnyFrame::from)
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
        let out = to_socket(f).ok_or_else(|| std::io::Error::other(format!("socketcan: cannot send {f:?}")))?;
        self.sock.write_frame(&out)
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
                // a frame the node does not serve is skipped, as on the boards
                Ok(f) => {
                    if let Ok(c) = from_socket(&f) {
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
    use socketcan::frame::{AsPtr, FdFlags};
    use socketcan::{CanRemoteFrame, EmbeddedFrame, ExtendedId, StandardId};

    /// `canfd_frame.flags`: bit-rate switch, FD frame.
    const CANFD_BRS: u8 = 0x01;
    const CANFD_FDF: u8 = 0x04;

    /// The frame the kernel would return for these bytes (what `CanFdSocket::read_frame` makes of
    /// a read of that size).
    fn received(b: &[u8]) -> CanAnyFrame {
        if b.len() == 16 {
            let mut f = CanDataFrame::new(StandardId::ZERO, &[]).unwrap();
            f.as_bytes_mut().copy_from_slice(b);
            f.into()
        } else {
            let mut f = CanFdFrame::default();
            f.as_bytes_mut().copy_from_slice(b);
            f.into()
        }
    }

    #[test]
    fn classic_frames_are_can_frame_structs() {
        let f = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 1]).unwrap();
        let s = to_socket(&f).unwrap();
        let id = 0x605u32.to_ne_bytes();
        assert_eq!(s.as_bytes(), [id[0], id[1], id[2], id[3], 4, 0, 0, 0, 0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
        assert_eq!(from_socket(&s), Ok(f));
        assert_eq!(from_socket(&received(s.as_bytes())), Ok(f));
    }

    #[test]
    fn fd_frames_are_canfd_frame_structs_of_72_bytes() {
        let d: Vec<u8> = (0..32).collect();
        let f = CanFrame::new_fd(0x385, &d, true).unwrap();
        let s = to_socket(&f).unwrap();
        let b = s.as_bytes();
        assert_eq!(b.len(), 72);
        assert_eq!(&b[..4], &0x385u32.to_ne_bytes());
        assert_eq!((b[4], b[5], b[6], b[7]), (32, CANFD_FDF | CANFD_BRS, 0, 0));
        assert_eq!(&b[8..40], &d[..]);
        assert!(b[40..].iter().all(|&x| x == 0));
        assert_eq!(from_socket(&received(b)), Ok(f));
        // without BRS; and a kernel before 5.14 leaves FDF clear: the size says FD
        let slow = CanFrame::new_fd(0x385, &d[..12], false).unwrap();
        let mut b = to_socket(&slow).unwrap().as_bytes().to_vec();
        assert_eq!(b[5], CANFD_FDF);
        b[5] = 0;
        assert_eq!(from_socket(&received(&b)), Ok(slow));
        // an 8-byte FD frame stays FD
        let short = CanFrame::new(0x605, &[1; 8]).unwrap().into_fd(true);
        let s = to_socket(&short).unwrap();
        assert_eq!(s.as_bytes().len(), 72);
        assert_eq!(from_socket(&received(s.as_bytes())), Ok(short));
    }

    #[test]
    fn what_the_node_does_not_serve_is_not_a_frame() {
        let ext = CanDataFrame::new(ExtendedId::new(0x123).unwrap(), &[1]).unwrap();
        assert_eq!(from_socket(&ext.into()), Err(Rejected::Extended));
        let remote = CanRemoteFrame::new_remote(StandardId::new(0x123).unwrap(), 1).unwrap();
        assert_eq!(from_socket(&remote.into()), Err(Rejected::Remote));
        let err = socketcan::CanErrorFrame::new_error(0x004, &[0; 8]).unwrap();
        assert_eq!(from_socket(&err.into()), Err(Rejected::Remote), "error frame");
        let fd_ext = CanFdFrame::with_flags(ExtendedId::new(0x123).unwrap(), &[0; 12], FdFlags::BRS).unwrap();
        assert_eq!(from_socket(&fd_ext.into()), Err(Rejected::Extended));
    }
}
