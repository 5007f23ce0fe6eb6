//! Fuzz the host's SDO client (`joint_can::master`) against a node that answers anything: the
//! input scripts the frames the bus returns (id, data, delay) and the operations the client
//! runs (upload, download of a chosen length, a whole parameter pull). The client must never
//! panic, allocate without bound or loop forever: every operation ends in a value or an error,
//! and an upload never returns more than its 1 MiB bound.
#![no_main]

use std::time::Duration;

use joint_can::master::Master;
use joint_can::script_bus::ScriptBus;
use joint_can::transfer;
use joint_core::canopen::CanFrame;
use libfuzzer_sys::fuzz_target;

const NODE: u8 = 5;

fuzz_target!(|data: &[u8]| {
    let Some((&ops, rest)) = data.split_first() else { return };
    // frames: [delay, id selector, len, data…]
    let mut frames = Vec::new();
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
            frames.push((u64::from(h[0]) * 50, f));
        }
    }
    let mut m = Master::new(Box::new(ScriptBus::new(frames)));
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
