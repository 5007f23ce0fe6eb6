//! A bus that records every frame that passes, both ways, with the bus clock's time: what
//! `candump -l` on the same wire would have written (our own frames included, as a SocketCAN
//! socket with loopback sees them).

use super::Bus;
use joint_core::canopen::CanFrame;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The frames a [`TapBus`] saw: (bus time µs, frame), in the order they passed.
pub type Tape = Arc<Mutex<Vec<(u64, CanFrame)>>>;

/// See the module documentation.
pub struct TapBus {
    inner: Box<dyn Bus>,
    tape: Tape,
}

impl TapBus {
    pub fn new(inner: Box<dyn Bus>, tape: Tape) -> TapBus {
        TapBus { inner, tape }
    }

    fn record(&self, f: &CanFrame) {
        let now = self.inner.now_us();
        if let Ok(mut t) = self.tape.lock() {
            t.push((now, *f));
        }
    }
}

impl Bus for TapBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        self.inner.send(f)?;
        self.record(f);
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        let f = self.inner.recv(timeout)?;
        if let Some(f) = &f {
            self.record(f);
        }
        Ok(f)
    }

    fn now_us(&self) -> u64 {
        self.inner.now_us()
    }

    fn describe(&self) -> String {
        self.inner.describe()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::script_bus::ScriptBus;

    #[test]
    fn both_directions_are_recorded_in_order() {
        let tape = Tape::default();
        let mut b = TapBus::new(Box::new(ScriptBus::new([])), tape.clone());
        let f = CanFrame::new(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap();
        b.send(&f).unwrap();
        assert_eq!(tape.lock().unwrap().len(), 1);
        assert_eq!(tape.lock().unwrap()[0].1, f);
    }
}
