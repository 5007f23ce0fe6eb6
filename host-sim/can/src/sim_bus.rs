//! The in-process simulated CAN bus: virtual time, arbitration by identifier, and the real
//! frame length (bit stuffing of the actual bits, [`super::timing`]) for every transfer.
//!
//! Participants are the master (the [`Bus`] side: `jointctl`'s code) and any number of
//! [`SimDevice`]s (simulated joints). Time moves only while the master waits in
//! [`Bus::recv`] (or [`SimBus::run_for`]): the bus then plays out transmissions, device ticks
//! and device replies in time order. A frame occupies the bus for its bit length at the
//! configured bitrate, intermission included; when the bus falls idle the pending frame with
//! the lowest identifier wins (CAN arbitration). A device's reply to a frame becomes ready
//! `turnaround` after the frame ended — its processing and controller latency.
//!
//! A CAN FD bus ([`SimBus::new_fd`]) has a data bit rate too: an FD frame with bit-rate
//! switch runs its data phase at it ([`timing::frame_time_ns`], ISO 11898-1:2015 layout);
//! classic frames and FD frames without BRS run wholly at the nominal rate. On a classic bus
//! (no data rate) an FD frame is timed as if it had no BRS: a classic controller would destroy
//! it with an error frame, which the simulation does not model.

use super::timing;
use super::Bus;
use joint_core::canopen::CanFrame;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A simulated participant.
pub trait SimDevice: Send {
    /// A frame from someone else finished at `t_us`; replies go to `out`.
    fn on_frame(&mut self, t_us: u64, f: &CanFrame, out: &mut Vec<CanFrame>);
    /// Periodic work at `t_us` (control step, timers).
    fn tick(&mut self, t_us: u64, out: &mut Vec<CanFrame>);
    /// Tick period, µs (≥ 1).
    fn period_us(&self) -> u64;
}

/// Counters of what crossed the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusStats {
    pub frames: u64,
    /// of which CAN FD frames
    pub fd_frames: u64,
    /// bits on the wire, stuffing and intermission included (nominal and data phase)
    pub bits: u64,
    /// time the bus was busy, ns
    pub busy_ns: u64,
}

/// Who sent a frame: the master or device `i`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Src {
    Master,
    Device(usize),
}

struct Pending {
    ready_ns: u64,
    seq: u64,
    src: Src,
    frame: CanFrame,
}

/// Faults the bus injects (issue 16): frames lost on the wire, alone or in bursts, a device
/// that resets when the master sends a given frame, an adapter that goes away.
#[derive(Default)]
pub struct Faults {
    /// chance that a frame, once it has crossed the wire, reaches nobody (EMI past the
    /// controller's retransmissions, a receive overrun); applies to every sender
    pub loss: f64,
    /// a lost frame takes this many following frames with it (0: single losses)
    pub burst: u32,
    /// seed of the loss draws (xorshift64*; 0 is taken as 1)
    pub seed: u64,
    /// reset a device (a brown-out: its RAM state lost, parameters from its storage, boot-up)
    /// when the master sends a frame that `when` picks
    pub reset: Option<ResetOn>,
    /// the adapter stops answering after this many more master frames: `send` fails with an
    /// I/O error and nothing is received
    pub adapter_dies_after: Option<u64>,
    /// frames lost so far
    pub lost: u64,
    burst_left: u32,
}

/// See [`Faults::reset`].
pub struct ResetOn {
    pub device: usize,
    /// picks the master frame; returns true once per reset wanted
    pub when: Box<dyn FnMut(&CanFrame) -> bool + Send>,
    /// the reset comes before the device sees that frame (lost with the power), else right after
    /// the device handled it (its reply is lost)
    pub before: bool,
    /// resets done
    pub done: u32,
}

impl Faults {
    /// Lose frames at `loss` (bursts of `burst` more), drawn from `seed`.
    pub fn lossy(loss: f64, burst: u32, seed: u64) -> Faults {
        Faults { loss, burst, seed: seed.max(1), ..Faults::default() }
    }

    fn draw(&mut self) -> f64 {
        // xorshift64*: deterministic per seed, no dependency
        let mut x = self.seed.max(1);
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.seed = x;
        (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Whether the frame that just crossed the wire is lost.
    fn lose(&mut self) -> bool {
        if self.burst_left > 0 {
            self.burst_left -= 1;
            self.lost += 1;
            return true;
        }
        if self.loss > 0.0 && self.draw() < self.loss {
            self.burst_left = self.burst;
            self.lost += 1;
            return true;
        }
        false
    }
}

/// See the module documentation.
pub struct SimBus {
    bitrate: u32,
    /// CAN FD data-phase rate; `None` on a classic bus
    data_bitrate: Option<u32>,
    now_ns: u64,
    devices: Vec<(Arc<Mutex<dyn SimDevice>>, u64)>,
    pending: Vec<Pending>,
    in_flight: Option<(u64, Src, CanFrame)>,
    inbox: VecDeque<CanFrame>,
    seq: u64,
    /// delay from the end of a frame to a device's reply being ready, ns
    pub turnaround_ns: u64,
    pub stats: BusStats,
    /// the master's frames after this many are lost (a cable pulled mid-transfer)
    pub cut_master_after: Option<u64>,
    master_sent: u64,
    /// frames the master sent that were lost to `cut_master_after`
    pub master_lost: u64,
    /// injected faults (none by default)
    pub faults: Faults,
}

/// Default device turnaround: 20 µs, the order of an SDO reply on a 170 MHz Cortex-M4 (a few
/// µs of node code plus the FDCAN's transmit latency).
pub const DEFAULT_TURNAROUND_NS: u64 = 20_000;

impl SimBus {
    pub fn new(bitrate: u32) -> SimBus {
        SimBus {
            bitrate: bitrate.max(1),
            data_bitrate: None,
            now_ns: 0,
            devices: Vec::new(),
            pending: Vec::new(),
            in_flight: None,
            inbox: VecDeque::new(),
            seq: 0,
            turnaround_ns: DEFAULT_TURNAROUND_NS,
            stats: BusStats::default(),
            cut_master_after: None,
            master_sent: 0,
            master_lost: 0,
            faults: Faults::default(),
        }
    }

    /// Lose every master frame after the next `n` (a cable pulled mid-transfer).
    pub fn cut_master_after_more(&mut self, n: u64) {
        self.cut_master_after = Some(self.master_sent + n);
    }

    /// A CAN FD bus: arbitration at `nominal`, the data phase of BRS frames at `data`.
    pub fn new_fd(nominal: u32, data: u32) -> SimBus {
        let mut b = SimBus::new(nominal);
        b.data_bitrate = Some(data.max(1));
        b
    }

    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// The data-phase rate of a CAN FD bus.
    pub fn data_bitrate(&self) -> Option<u32> {
        self.data_bitrate
    }

    /// Attach a device; its first tick is now.
    pub fn attach(&mut self, dev: Arc<Mutex<dyn SimDevice>>) {
        self.devices.push((dev, self.now_ns));
    }

    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Let the bus run for `d` without the master waiting for anything; frames for the master
    /// stay queued for [`Bus::recv`].
    pub fn run_for(&mut self, d: Duration) {
        let limit = self.now_ns.saturating_add(d.as_nanos() as u64);
        while self.now_ns < limit {
            self.advance(limit, false);
        }
    }

    /// Frames waiting for the bus (a backlog that grows: the bus is saturated).
    pub fn backlog(&self) -> usize {
        self.pending.len()
    }

    /// Drop every frame queued for the master.
    pub fn drain_inbox(&mut self) -> Vec<CanFrame> {
        self.inbox.drain(..).collect()
    }

    fn queue(&mut self, ready_ns: u64, src: Src, frame: CanFrame) {
        self.seq += 1;
        self.pending.push(Pending { ready_ns, seq: self.seq, src, frame });
    }

    fn start_next(&mut self) {
        if self.in_flight.is_some() {
            return;
        }
        let now = self.now_ns;
        let winner = self
            .pending
            .iter()
            .enumerate()
            .filter(|(_, p)| p.ready_ns <= now)
            .min_by_key(|(_, p)| (p.frame.id(), p.seq))
            .map(|(i, _)| i);
        if let Some(i) = winner {
            let p = self.pending.swap_remove(i);
            let (n, d) = timing::frame_bits(&p.frame);
            let dur = timing::frame_time_ns(&p.frame, self.bitrate, self.data_bitrate.unwrap_or(self.bitrate));
            self.stats.frames += 1;
            self.stats.fd_frames += u64::from(p.frame.is_fd());
            self.stats.bits += u64::from(n + d);
            self.stats.busy_ns += dur;
            self.in_flight = Some((now + dur, p.src, p.frame));
        }
    }

    /// Play events up to `limit_ns`; returns early once the master has a frame when
    /// `stop_on_inbox`.
    fn advance(&mut self, limit_ns: u64, stop_on_inbox: bool) {
        let mut out = Vec::new();
        loop {
            self.start_next();
            let mut next = limit_ns;
            if let Some((end, _, _)) = self.in_flight {
                next = next.min(end);
            } else if let Some(r) = self.pending.iter().map(|p| p.ready_ns).filter(|&r| r > self.now_ns).min() {
                next = next.min(r);
            }
            for (_, t) in &self.devices {
                next = next.min(*t);
            }
            self.now_ns = self.now_ns.max(next);
            let now = self.now_ns;
            if let Some((end, src, f)) = self.in_flight {
                if end <= now {
                    self.in_flight = None;
                    if self.faults.lose() {
                        continue;
                    }
                    let mut reset = None;
                    if let (Some(r), Src::Master) = (self.faults.reset.as_mut(), src) {
                        if (r.when)(&f) {
                            r.done += 1;
                            reset = Some((r.device, r.before));
                        }
                    }
                    for (i, (dev, _)) in self.devices.iter().enumerate() {
                        if src == Src::Device(i) {
                            continue;
                        }
                        let reset_here = reset.filter(|(d, _)| *d == i);
                        if let Ok(mut d) = dev.lock() {
                            if reset_here.is_some_and(|(_, before)| before) {
                                // the power goes with the frame: an NMT reset-node is the same
                                // restart (parameters from storage, boot-up)
                                if let Some(nmt) = CanFrame::new(0, &[RESET_NODE, 0]) {
                                    d.on_frame(now / 1000, &nmt, &mut out);
                                }
                            } else {
                                d.on_frame(now / 1000, &f, &mut out);
                                if reset_here.is_some() {
                                    out.clear();
                                    if let Some(nmt) = CanFrame::new(0, &[RESET_NODE, 0]) {
                                        d.on_frame(now / 1000, &nmt, &mut out);
                                    }
                                }
                            }
                        }
                        for r in out.drain(..) {
                            self.seq += 1;
                            self.pending.push(Pending {
                                ready_ns: now + self.turnaround_ns,
                                seq: self.seq,
                                src: Src::Device(i),
                                frame: r,
                            });
                        }
                    }
                    if src != Src::Master {
                        self.inbox.push_back(f);
                    }
                }
            }
            for i in 0..self.devices.len() {
                let due = self.devices.get(i).map(|(_, t)| *t).unwrap_or(u64::MAX);
                if due <= now {
                    let mut period = 1000;
                    if let Some((dev, _)) = self.devices.get(i) {
                        if let Ok(mut d) = dev.lock() {
                            d.tick(now / 1000, &mut out);
                            period = d.period_us().max(1);
                        }
                    }
                    for r in out.drain(..) {
                        self.queue(now, Src::Device(i), r);
                    }
                    if let Some((_, t)) = self.devices.get_mut(i) {
                        *t = due + period * 1000;
                    }
                }
            }
            if (stop_on_inbox && !self.inbox.is_empty()) || now >= limit_ns {
                return;
            }
        }
    }
}

/// NMT command "reset node" (CiA 301).
const RESET_NODE: u8 = 0x81;

impl Bus for SimBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        if let Some(n) = self.faults.adapter_dies_after.as_mut() {
            if *n == 0 {
                return Err(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "the CAN adapter stopped answering"));
            }
            *n -= 1;
        }
        self.master_sent += 1;
        if self.cut_master_after.is_some_and(|n| self.master_sent > n) {
            self.master_lost += 1;
            return Ok(());
        }
        self.queue(self.now_ns, Src::Master, *f);
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        if self.faults.adapter_dies_after == Some(0) {
            return Err(std::io::Error::new(std::io::ErrorKind::BrokenPipe, "the CAN adapter stopped answering"));
        }
        if let Some(f) = self.inbox.pop_front() {
            return Ok(Some(f));
        }
        let limit = self.now_ns.saturating_add(timeout.as_nanos() as u64);
        self.advance(limit, true);
        Ok(self.inbox.pop_front())
    }

    fn now_us(&self) -> u64 {
        self.now_ns / 1000
    }

    fn describe(&self) -> String {
        match self.data_bitrate {
            Some(d) => format!("simulated CAN FD bus at {}/{} kbit/s", self.bitrate / 1000, d / 1000),
            None => format!("simulated bus at {} kbit/s", self.bitrate / 1000),
        }
    }
}

/// A shared handle, so a test can keep the bus (and its devices) while a master owns a `Box<dyn Bus>`.
#[derive(Clone)]
pub struct SharedSimBus(pub Arc<Mutex<SimBus>>);

impl Bus for SharedSimBus {
    fn send(&mut self, f: &CanFrame) -> std::io::Result<()> {
        self.0.lock().map_err(|_| std::io::Error::other("simulated bus poisoned"))?.send(f)
    }
    fn recv(&mut self, timeout: Duration) -> std::io::Result<Option<CanFrame>> {
        self.0.lock().map_err(|_| std::io::Error::other("simulated bus poisoned"))?.recv(timeout)
    }
    fn now_us(&self) -> u64 {
        self.0.lock().map(|b| b.now_us()).unwrap_or(0)
    }
    fn describe(&self) -> String {
        self.0.lock().map(|b| b.describe()).unwrap_or_default()
    }
}
