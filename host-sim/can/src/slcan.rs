//! Lawicel / slcan: CAN frames as ASCII lines over a serial port, as spoken by CANable,
//! CANtact, USBtin and most USB–CAN adapters (and by python-can's `slcan` interface).
//!
//! `tIIILDD…\r` is a standard data frame (3 hex digits id, 1 digit length, 2 hex digits per
//! byte); `T` extended, `r`/`R` remote frames (ignored: the node serves none). Commands
//! (`S8\r` 1 Mbit/s, `O\r` open, `C\r` close, `V\r` version …) are answered with `\r` by an
//! adapter; when the other end is another program on a `socat` pty pair the commands it sends
//! are simply ignored here, and adapter acknowledgements (`z\r`, `\r`, BEL) are skipped when
//! reading. A reader thread turns lines into frames, so `recv` can wait with a timeout.
//!
//! CAN FD: the extension of the CANable 2.0 slcan firmware (normaldotcom/canable2-fw, also
//! WeAct's and candleLight-derived slcan firmwares, and python-can's `slcan` interface since
//! 4.x): `dIIIL…` an FD frame without bit-rate switch, `bIIIL…` with it (`D`/`B` extended),
//! `L` the DLC as one hex digit 0..F (9 = 12 bytes … F = 64); `Yn` before `O` sets the data
//! bit rate (Y1 1, Y2 2, Y4 4, Y5 5, Y8 8 Mbit/s).

use super::Bus;
use joint_core::canopen::frame::{fd_len_of_dlc, FD_MAX_LEN};
use joint_core::canopen::CanFrame;
use std::io::{Read, Write};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// `S` code of a bitrate.
pub fn bitrate_code(bitrate: u32) -> Option<u8> {
    match bitrate {
        10_000 => Some(0),
        20_000 => Some(1),
        50_000 => Some(2),
        100_000 => Some(3),
        125_000 => Some(4),
        250_000 => Some(5),
        500_000 => Some(6),
        800_000 => Some(7),
        1_000_000 => Some(8),
        _ => None,
    }
}

/// `Y` code of a CAN FD data bit rate.
pub fn data_bitrate_code(bitrate: u32) -> Option<u8> {
    match bitrate {
        1_000_000 => Some(1),
        2_000_000 => Some(2),
        4_000_000 => Some(4),
        5_000_000 => Some(5),
        8_000_000 => Some(8),
        _ => None,
    }
}

/// The slcan line of a frame, `\r` included: `t` classic, `b` FD with bit-rate switch, `d`
/// FD without.
pub fn encode(f: &CanFrame) -> String {
    let kind = match (f.is_fd(), f.brs()) {
        (false, _) => 't',
        (true, true) => 'b',
        (true, false) => 'd',
    };
    let mut s = format!("{kind}{:03X}{:X}", f.id(), f.dlc());
    for b in f.data() {
        s.push_str(&format!("{b:02X}"));
    }
    s.push('\r');
    s
}

/// A frame from one received line (without its `\r`); `None` for anything that is not a
/// well-formed standard data frame, classic or FD (commands, acknowledgements, extended or
/// remote frames, garbage). Trailing timestamp digits (`Z1` mode) are ignored.
pub fn decode(line: &str) -> Option<CanFrame> {
    let b = line.as_bytes();
    let kind = *b.first()?;
    if !matches!(kind, b't' | b'b' | b'd') || b.len() < 5 {
        return None;
    }
    let id = u16::from_str_radix(line.get(1..4)?, 16).ok()?;
    let code = (*b.get(4)? as char).to_digit(16)? as u8;
    let len = match kind {
        b't' if code <= 8 => usize::from(code),
        b't' => return None,
        _ => fd_len_of_dlc(code)?,
    };
    let mut data = [0u8; FD_MAX_LEN];
    for (k, d) in data.iter_mut().enumerate().take(len) {
        *d = u8::from_str_radix(line.get(5 + 2 * k..7 + 2 * k)?, 16).ok()?;
    }
    let data = data.get(..len)?;
    match kind {
        b't' => CanFrame::new(id, data),
        _ => CanFrame::new_fd(id, data, kind == b'b'),
    }
}

/// An slcan adapter (or pty) as a [`Bus`].
pub struct SlcanBus {
    port: Box<dyn serialport::SerialPort>,
    rx: Receiver<CanFrame>,
    t0: Instant,
    path: String,
    /// tells the reader thread to stop (it checks at every read timeout, 50 ms)
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Drop for SlcanBus {
    /// Close the CAN channel and wait for the reader thread, so the port (and its exclusive
    /// lock) is free when the bus is gone: a command run right after can open it.
    fn drop(&mut self) {
        let _ = self.port.write_all(b"C\r");
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(h) = self.reader.take() {
            let _ = h.join();
        }
    }
}

impl SlcanBus {
    pub fn open(path: &str, bitrate: u32) -> anyhow::Result<SlcanBus> {
        Self::open_with(path, bitrate, None)
    }

    /// A CAN FD adapter: nominal `bitrate`, data phase at `data_bitrate` (`Yn`).
    pub fn open_fd(path: &str, bitrate: u32, data_bitrate: u32) -> anyhow::Result<SlcanBus> {
        Self::open_with(path, bitrate, Some(data_bitrate))
    }

    fn open_with(path: &str, bitrate: u32, data_bitrate: Option<u32>) -> anyhow::Result<SlcanBus> {
        let code = bitrate_code(bitrate).ok_or_else(|| anyhow::anyhow!("slcan: unsupported bitrate {bitrate}"))?;
        let fd = match data_bitrate {
            Some(d) => {
                let y = data_bitrate_code(d)
                    .ok_or_else(|| anyhow::anyhow!("slcan: unsupported data bitrate {d} (1, 2, 4, 5, 8 Mbit/s)"))?;
                format!("Y{y}\r")
            }
            None => String::new(),
        };
        let mut port = serialport::new(path, 115_200)
            .timeout(Duration::from_millis(50))
            .open()
            .map_err(|e| anyhow::anyhow!("slcan: cannot open {path}: {e}"))?;
        // Close (in case it was open), set the bitrate, open. An adapter answers each with \r;
        // a peer program ignores them.
        port.write_all(format!("C\rS{code}\r{fd}O\r").as_bytes()).map_err(|e| anyhow::anyhow!("slcan: {path}: {e}"))?;
        let mut reader = port.try_clone().map_err(|e| anyhow::anyhow!("slcan: {path}: {e}"))?;
        let (tx, rx) = mpsc::channel();
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stopped = stop.clone();
        let reader = std::thread::spawn(move || {
            let mut line = Vec::with_capacity(32);
            let mut buf = [0u8; 256];
            loop {
                if stopped.load(std::sync::atomic::Ordering::Relaxed) {
                    return;
                }
                match reader.read(&mut buf) {
                    Ok(0) => std::thread::sleep(Duration::from_millis(1)),
                    Ok(n) => {
                        for &c in buf.iter().take(n) {
                            if c == b'\r' || c == b'\n' || c == 0x07 {
                                if let Some(f) = std::str::from_utf8(&line).ok().and_then(decode) {
                                    if tx.send(f).is_err() {
                                        return;
                                    }
                                }
                                line.clear();
                            } else if line.len() < 160 {
                                line.push(c);
                            } else {
                                // an endless line is garbage: drop it
                                line.clear();
                            }
                        }
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(_) => return,
                }
            }
        });
        Ok(SlcanBus { port, rx, t0: Instant::now(), path: path.to_string(), stop, reader: Some(reader) })
    }
}

impl Bus for SlcanBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        self.port.write_all(encode(f).as_bytes())
    }

    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        match self.rx.recv_timeout(timeout) {
            Ok(f) => Ok(Some(f)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(std::io::Error::new(std::io::ErrorKind::BrokenPipe, format!("slcan: {} closed", self.path)))
            }
        }
    }

    fn now_us(&self) -> u64 {
        self.t0.elapsed().as_micros() as u64
    }

    fn describe(&self) -> String {
        format!("slcan on {}", self.path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip() {
        let f = CanFrame::new(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]).unwrap();
        let s = encode(&f);
        assert_eq!(s, "t60584018100100000000\r");
        assert_eq!(decode(s.trim_end_matches('\r')), Some(f));
        assert_eq!(decode("t7050"), CanFrame::new(0x705, &[]));
        assert_eq!(decode("t70517F"), CanFrame::new(0x705, &[0x7F]));
    }

    #[test]
    fn garbage_lines_are_not_frames() {
        for l in ["", "z", "S8", "O", "T12345678100", "r1230", "t12", "t1239", "t123200", "tXYZ0", "t12320G00", "t123A"]
        {
            assert_eq!(decode(l), None, "{l:?}");
        }
        // trailing timestamp is ignored
        assert_eq!(decode("t12310012AB"), CanFrame::new(0x123, &[0x00]));
    }

    #[test]
    fn fd_lines_carry_the_dlc_as_one_hex_digit() {
        // the lines python-can's slcan interface writes: b/d, 3-digit id, DLC 0..F
        let d: Vec<u8> = (0..32).collect();
        let f = CanFrame::new_fd(0x385, &d, true).unwrap();
        let s = encode(&f);
        assert_eq!(&s[..5], "b385D");
        assert_eq!(s.len(), 5 + 64 + 1);
        assert_eq!(decode(s.trim_end_matches('\r')), Some(f));
        let slow = CanFrame::new_fd(0x200, &[0x10, 0, 0x20, 0, 0x30, 0, 0, 0, 0, 0, 0, 0], false).unwrap();
        assert_eq!(encode(&slow), "d2009100020003000000000000000\r");
        assert_eq!(decode("d2009100020003000000000000000"), Some(slow));
        assert_eq!(decode(&format!("b7FFF{}", "AB".repeat(64))), CanFrame::new_fd(0x7FF, &[0xAB; 64], true));
        // an FD frame of ≤ 8 bytes keeps its digit
        assert_eq!(encode(&CanFrame::new(0x605, &[1, 2]).unwrap().into_fd(true)), "b60520102\r");
        // short data, bad digits
        for l in ["b385D00", "b385G", "d12", &format!("b385F{}", "0".repeat(126))] {
            assert_eq!(decode(l), None, "{l:?}");
        }
        assert_eq!(data_bitrate_code(5_000_000), Some(5));
        assert_eq!(data_bitrate_code(3_000_000), None);
    }
}
