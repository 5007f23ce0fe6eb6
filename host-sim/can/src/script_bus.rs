//! A bus whose answers come from a script: each `recv` hands out the next scripted frame once
//! its delay has passed on the bus clock, or lets the whole timeout pass when the script is
//! spent; `send` takes 100 µs and goes nowhere. For driving the master against a node that
//! answers anything (the SDO client's fuzz target and property test), and for replaying a bus
//! capture as if it were the bus (`--bus replay:FILE`: sends take no time and go nowhere).

use super::Bus;
use joint_core::canopen::CanFrame;
use std::collections::VecDeque;
use std::time::Duration;

/// See the module documentation.
pub struct ScriptBus {
    /// (delay µs after the previous event, frame), in order
    frames: VecDeque<(u64, CanFrame)>,
    now: u64,
    /// bus time one `send` takes, µs
    send_us: u64,
    name: String,
}

impl ScriptBus {
    pub fn new(frames: impl IntoIterator<Item = (u64, CanFrame)>) -> ScriptBus {
        ScriptBus { frames: frames.into_iter().collect(), now: 0, send_us: 100, name: "scripted bus".into() }
    }

    /// A capture played back: the clock starts at `start_us`, sends take no time, `name` is
    /// what messages call the bus.
    pub fn replay(start_us: u64, frames: impl IntoIterator<Item = (u64, CanFrame)>, name: String) -> ScriptBus {
        ScriptBus { frames: frames.into_iter().collect(), now: start_us, send_us: 0, name }
    }
}

impl Bus for ScriptBus {
    fn send(&mut self, _f: &CanFrame) -> std::io::Result<()> {
        self.now += self.send_us;
        Ok(())
    }
    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        let limit = timeout.as_micros() as u64;
        match self.frames.pop_front() {
            Some((dt, f)) if dt <= limit => {
                self.now += dt;
                Ok(Some(f))
            }
            Some((dt, f)) => {
                self.now += limit;
                self.frames.push_front((dt - limit, f));
                Ok(None)
            }
            None => {
                self.now += limit;
                Ok(None)
            }
        }
    }
    fn now_us(&self) -> u64 {
        self.now
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}
