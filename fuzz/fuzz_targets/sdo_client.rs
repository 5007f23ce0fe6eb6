//! Fuzz the host's SDO client (`joint_can::master`) against a node that answers anything: the
//! input scripts the frames the bus returns (id, data, delay) and the operations the client
//! runs (upload, download of a chosen length, a whole parameter pull). The client must never
//! panic, allocate without bound or loop forever: every operation ends in a value or an error,
//! and an upload never returns more than its 1 MiB bound.
#![no_main]

use std::collections::VecDeque;
use std::time::Duration;

use joint_can::master::Master;
use joint_can::{transfer, Bus};
use joint_core::canopen::CanFrame;
use libfuzzer_sys::fuzz_target;

const NODE: u8 = 5;

/// A bus whose answers come from the script; time moves by each frame's delay, or by the
/// whole timeout when the script is spent.
struct Script {
    frames: VecDeque<(u64, CanFrame)>,
    now: u64,
}

impl Bus for Script {
    fn send(&mut self, _f: &CanFrame) -> std::io::Result<()> {
        self.now += 100;
        Ok(())
    }
    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        match self.frames.pop_front() {
            Some((dt, f)) if dt <= timeout.as_micros() as u64 => {
                self.now += dt;
                Ok(Some(f))
            }
            Some((dt, f)) => {
                self.now += timeout.as_micros() as u64;
                self.frames.push_front((dt - timeout.as_micros() as u64, f));
                Ok(None)
            }
            None => {
                self.now += timeout.as_micros() as u64;
                Ok(None)
            }
        }
    }
    fn now_us(&self) -> u64 {
        self.now
    }
    fn describe(&self) -> String {
        "fuzz script".into()
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&ops, rest)) = data.split_first() else { return };
    // frames: [delay, id selector, len, data…]
    let mut frames = VecDeque::new();
    let mut r = rest;
    while r.len() >= 3 {
        let (h, t) = r.split_at(3);
        let len = usize::from(h[2] % 9).min(t.len());
        let (d, t) = t.split_at(len);
        r = t;
        let id = match h[1] % 4 {
            0 | 1 => 0x580 + u16::from(NODE),
            2 => 0x700 + u16::from(h[1] >> 2),
            _ => (u16::from(h[1]) << 3 | u16::from(h[2])) & 0x7FF,
        };
        if let Some(f) = CanFrame::new(id, d) {
            frames.push_back((u64::from(h[0]) * 50, f));
        }
    }
    let mut m = Master::new(Box::new(Script { frames, now: 0 }));
    m.sdo_timeout = Duration::from_millis(5);
    for k in 0..4 {
        match (ops >> (2 * k)) & 3 {
            0 => {
                if let Ok(v) = m.read(NODE, 0x2000 + k, 0) {
                    assert!(v.len() <= (1 << 20) + 7);
                }
            }
            1 => {
                let payload: Vec<u8> = (0..usize::from(ops) * 3).map(|i| i as u8).collect();
                let _ = m.write(NODE, 0x2100, 1, &payload);
            }
            2 => {
                let _ = transfer::pull(&mut m, NODE);
            }
            _ => {
                let _ = m.read_string(NODE, 0x1008, 0);
            }
        }
    }
});
