//! The CANopen master side `jointctl` uses: SDO client (expedited and segmented), NMT,
//! its own heartbeat (the joints' watchdogs need it), and a record of what it overheard
//! (heartbeats, EMCYs, TPDOs) while waiting for answers.
//!
//! SDO frames carry no client address, so two masters on one server channel have one's
//! segments acknowledged into the other's transfer. The joint serves a second channel
//! (0x1201) for that: [`Master::use_second_channel`] configures it through the default one, as
//! CiA 301 has it, and runs every later transfer with that node on it.

use super::{timing, Bus};
use joint_core::canopen::node::{NmtState, DEFAULT_HOST_ID, EMCY_BASE, HEARTBEAT_BASE};
use joint_core::canopen::od;
use joint_core::canopen::sdo::{self, Abort};
use joint_core::canopen::CanFrame;
use std::collections::BTreeMap;
use std::time::Duration;

/// Why an SDO transfer failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SdoError {
    #[error("node {node}: {index:04X}:{sub} aborted with 0x{code:08X} ({text})")]
    Abort { node: u8, index: u16, sub: u8, code: u32, text: &'static str },
    #[error("node {node}: {index:04X}:{sub}: no answer within {ms} ms")]
    Timeout { node: u8, index: u16, sub: u8, ms: u64 },
    #[error("node {node}: {index:04X}:{sub}: protocol error: {what}")]
    Protocol { node: u8, index: u16, sub: u8, what: String },
    #[error("bus: {0}")]
    Io(String),
}

impl SdoError {
    pub fn abort_code(&self) -> Option<u32> {
        match self {
            SdoError::Abort { code, .. } => Some(*code),
            _ => None,
        }
    }
}

/// Our heartbeat period unless a node consumes it faster ([`Master::match_consumer`]).
pub const DEFAULT_HEARTBEAT_US: u64 = 100_000;

/// COB-IDs of an SDO server channel: `rx` client → server (requests), `tx` server → client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoCobs {
    pub rx: u16,
    pub tx: u16,
}

/// "Not valid" bit of a COB-ID entry (CiA 301).
const COB_INVALID: u32 = 0x8000_0000;

impl SdoCobs {
    /// The default channel of `node` (0x1200): 0x600 + id, 0x580 + id.
    pub fn default_for(node: u8) -> SdoCobs {
        SdoCobs { rx: sdo::RX_BASE + u16::from(node), tx: sdo::TX_BASE + u16::from(node) }
    }

    /// The second channel's COB-IDs by our convention: the default channel's of node id + 64
    /// (0x640 + id, 0x5C0 + id), free on a bus whose node ids stay below 64. `None` for a node
    /// id of 64 or more, whose + 64 is no node id: such a node needs COB-IDs named for it.
    pub fn second_for(node: u8) -> Option<SdoCobs> {
        (1..64).contains(&node).then(|| SdoCobs::default_for(node + 64))
    }

    /// Whether these COB-IDs can be a second channel of `node`: 11-bit ids, not 0 (NMT), two
    /// different ones, neither one of the node's default channel (the node refuses those too).
    pub fn check_for(self, node: u8) -> Result<(), String> {
        let d = SdoCobs::default_for(node);
        for id in [self.rx, self.tx] {
            if id == 0 || id > 0x7FF {
                return Err(format!("COB-ID 0x{id:X} is not an 11-bit CAN id (1..=0x7FF)"));
            }
            if id == d.rx || id == d.tx {
                return Err(format!("COB-ID 0x{id:X} is node {node}'s default SDO channel"));
            }
        }
        if self.rx == self.tx {
            return Err(format!("request and response need two COB-IDs, not 0x{:X} twice", self.rx));
        }
        Ok(())
    }
}

/// What the master last heard from a node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seen {
    pub state: Option<NmtState>,
    pub last_us: u64,
    pub heartbeats: u64,
    /// boot-up messages heard (the node started or reset)
    pub boots: u64,
}

/// See the module documentation.
pub struct Master {
    pub bus: Box<dyn Bus>,
    pub host_id: u8,
    /// own heartbeat period, µs (0 = none)
    pub heartbeat_us: u64,
    next_heartbeat_us: u64,
    pub sdo_timeout: Duration,
    pub seen: BTreeMap<u8, Seen>,
    /// EMCYs overheard: (node, time µs, payload)
    pub emcy: Vec<(u8, u64, Vec<u8>)>,
    /// other frames overheard (TPDOs …), kept only when `keep_other`
    pub other: Vec<(u64, CanFrame)>,
    pub keep_other: bool,
    /// SDO frames exchanged (requests and responses) and their bits on the wire
    pub sdo_frames: u64,
    pub sdo_bits: u64,
    /// nodes served on their second SDO channel: its COB-IDs and the boot-ups heard when it was
    /// configured (a reset communication makes it "not valid" again: it is configured anew)
    second: BTreeMap<u8, (SdoCobs, u64)>,
}

impl Master {
    pub fn new(bus: Box<dyn Bus>) -> Master {
        Master {
            bus,
            host_id: DEFAULT_HOST_ID,
            heartbeat_us: DEFAULT_HEARTBEAT_US,
            next_heartbeat_us: 0,
            sdo_timeout: Duration::from_millis(1000),
            seen: BTreeMap::new(),
            emcy: Vec::new(),
            other: Vec::new(),
            keep_other: false,
            sdo_frames: 0,
            sdo_bits: 0,
            second: BTreeMap::new(),
        }
    }

    /// The SDO channel this master uses with `node`.
    pub fn sdo_cobs(&self, node: u8) -> SdoCobs {
        self.second.get(&node).map_or(SdoCobs::default_for(node), |(c, _)| *c)
    }

    fn boots(&self, node: u8) -> u64 {
        self.seen.get(&node).map_or(0, |s| s.boots)
    }

    /// Run every later SDO transfer with `node` on its second server channel (0x1201) at
    /// `cobs`, so this master never shares a transfer with one on the default channel (a
    /// controller). The channel is configured as CiA 301 has it, through the default channel:
    /// 0x1201 sub 1 and 2 the COB-IDs (valid), sub 3 our node id: three expedited writes, the
    /// only transfers this master makes on the default channel. When the node already serves
    /// `cobs` there (an earlier command configured it), nothing is written. Refused, changing
    /// nothing, when the node's second channel is in use with other COB-IDs.
    pub fn use_second_channel(&mut self, node: u8, cobs: SdoCobs) -> Result<(), SdoError> {
        let proto = |what: String| SdoError::Protocol { node, index: od::SDO_SERVER2, sub: 1, what };
        cobs.check_for(node).map_err(proto)?;
        // already served there? A request left unanswered changes nothing on the node; it
        // costs one SDO timeout, once (a shorter wait, taken for "not configured" on a loaded
        // host or adapter, would write on channel 1 beside the controller again)
        self.second.insert(node, (cobs, self.boots(node)));
        let there = self.read_u32(node, od::SDO_SERVER2, 1);
        if there == Ok(u32::from(cobs.rx)) {
            return Ok(());
        }
        self.second.remove(&node);
        self.configure_second(node, cobs)
    }

    /// An expedited write of the channel configuration, tried again when its answer is lost
    /// or is another master's (a controller's transfer on the default channel: its answers,
    /// or the abort of its transfer that ours ended, which carry no client address): the write
    /// leaves no transfer open on the node, so trying it again is harmless, and no abort is
    /// sent (it would end the other master's transfer).
    fn write_config(&mut self, node: u8, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        let out_of_step = [Abort::Toggle.code(), Abort::Command.code(), Abort::Timeout.code()];
        let mut tries = 1;
        loop {
            match self.write(node, od::SDO_SERVER2, sub, data) {
                Err(SdoError::Timeout { .. } | SdoError::Protocol { .. }) if tries < 4 => tries += 1,
                Err(SdoError::Abort { code, .. }) if tries < 4 && out_of_step.contains(&code) => tries += 1,
                r => return r,
            }
        }
    }

    /// Write 0x1201 through the default channel, then use it.
    fn configure_second(&mut self, node: u8, cobs: SdoCobs) -> Result<(), SdoError> {
        let written = self
            .write_config(node, 1, &u32::from(cobs.rx).to_le_bytes())
            .and_then(|()| self.write_config(node, 2, &u32::from(cobs.tx).to_le_bytes()));
        if let Err(e) = written {
            if e.abort_code() == Some(Abort::InvalidValue.code()) {
                // a valid COB-ID's id cannot change: another master uses the channel
                let rx = self.read_u32(node, od::SDO_SERVER2, 1)?;
                let tx = self.read_u32(node, od::SDO_SERVER2, 2)?;
                if (rx | tx) & COB_INVALID == 0 {
                    return Err(SdoError::Protocol {
                        node,
                        index: od::SDO_SERVER2,
                        sub: 1,
                        what: format!(
                            "the second SDO channel is in use with COB-IDs 0x{:X}/0x{:X} (another master's?), not \
                             0x{:X}/0x{:X}",
                            rx & 0x7FF,
                            tx & 0x7FF,
                            cobs.rx,
                            cobs.tx
                        ),
                    });
                }
            }
            return Err(e);
        }
        self.write_config(node, 3, &[self.host_id])?;
        self.second.insert(node, (cobs, self.boots(node)));
        Ok(())
    }

    /// Before a transfer on a second channel: the node reset since it was configured (its
    /// boot-up heard), so the channel is "not valid" again: configure it anew.
    fn second_still_valid(&mut self, node: u8) -> Result<(), SdoError> {
        if let Some((cobs, boots)) = self.second.get(&node).copied() {
            if self.boots(node) > boots {
                self.second.remove(&node);
                self.configure_second(node, cobs)?;
            }
        }
        Ok(())
    }

    fn io(e: std::io::Error) -> SdoError {
        SdoError::Io(e.to_string())
    }

    /// Send our heartbeat when due.
    pub fn pump(&mut self) -> Result<(), SdoError> {
        if self.heartbeat_us == 0 {
            return Ok(());
        }
        let now = self.bus.now_us();
        if now >= self.next_heartbeat_us {
            if let Some(f) = CanFrame::new(HEARTBEAT_BASE + u16::from(self.host_id), &[0x05]) {
                self.bus.send(&f).map_err(Self::io)?;
            }
            self.next_heartbeat_us = now + self.heartbeat_us;
        }
        Ok(())
    }

    /// Receive one frame (our heartbeat kept going meanwhile), recording what it says.
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, SdoError> {
        self.pump()?;
        // Wait at most until our next heartbeat is due, so it keeps its period.
        let slice = if self.heartbeat_us == 0 {
            timeout
        } else {
            let left = self.next_heartbeat_us.saturating_sub(self.bus.now_us()).max(1);
            timeout.min(Duration::from_micros(left))
        };
        let f = self.bus.recv(slice).map_err(Self::io)?;
        if let Some(f) = &f {
            self.observe(f);
        }
        Ok(f)
    }

    fn observe(&mut self, f: &CanFrame) {
        let now = self.bus.now_us();
        let id = f.id();
        if (HEARTBEAT_BASE + 1..=HEARTBEAT_BASE + 127).contains(&id) && f.dlc() == 1 {
            let node = (id - HEARTBEAT_BASE) as u8;
            if node != self.host_id {
                let e = self.seen.entry(node).or_insert(Seen { state: None, last_us: now, heartbeats: 0, boots: 0 });
                e.state = f.data().first().and_then(|&b| NmtState::from_heartbeat_byte(b));
                if f.data().first() == Some(&0x00) {
                    e.boots += 1;
                }
                e.last_us = now;
                e.heartbeats += 1;
            }
        } else if (EMCY_BASE + 1..=EMCY_BASE + 127).contains(&id) {
            self.emcy.push(((id - EMCY_BASE) as u8, now, f.data().to_vec()));
        } else if self.keep_other {
            self.other.push((now, *f));
        }
    }

    /// Matches our heartbeat to what `node` consumes: reads its consumer heartbeat times
    /// (0x1016, each `node id << 16 | time ms`) and, for the entry that names us, produces at
    /// half that time (CiA 301 leaves the margin to the master; half keeps one lost frame from
    /// faulting the joint), never slower than the default 100 ms and never faster than 10 ms.
    /// Returns the consumer time found (ms), `None` when the node does not watch us.
    pub fn match_consumer(&mut self, node: u8) -> Result<Option<u64>, SdoError> {
        let n = self.read(node, 0x1016, 0)?.first().copied().unwrap_or(0);
        for sub in 1..=n {
            let v = self.read_u32(node, 0x1016, sub)?;
            let (id, ms) = ((v >> 16) & 0x7F, u64::from(v & 0xFFFF));
            if id == u32::from(self.host_id) && ms > 0 {
                let us = (ms * 1000 / 2).clamp(10_000, DEFAULT_HEARTBEAT_US);
                if us < self.heartbeat_us || self.heartbeat_us == 0 {
                    self.heartbeat_us = us;
                    self.next_heartbeat_us = self.next_heartbeat_us.min(self.bus.now_us() + us);
                }
                return Ok(Some(ms));
            }
        }
        Ok(None)
    }

    /// Listen for `d` (keeping our heartbeat going), recording what is heard.
    pub fn listen(&mut self, d: Duration) -> Result<(), SdoError> {
        let end = self.bus.now_us() + d.as_micros() as u64;
        loop {
            let now = self.bus.now_us();
            if now >= end {
                return Ok(());
            }
            self.recv(Duration::from_micros(end - now))?;
        }
    }

    pub fn nmt(&mut self, node: u8, cs: u8) -> Result<(), SdoError> {
        if let Some(f) = CanFrame::new(0, &[cs, node]) {
            self.bus.send(&f).map_err(Self::io)?;
        }
        Ok(())
    }

    fn count(&mut self, f: &CanFrame) {
        self.sdo_frames += 1;
        self.sdo_bits += u64::from(timing::classic_bits(f.id(), f.data()));
    }

    /// One request, one response, on the channel this master uses with `node`.
    fn transact(&mut self, node: u8, index: u16, sub: u8, req: [u8; 8]) -> Result<[u8; 8], SdoError> {
        self.second_still_valid(node)?;
        let cobs = self.sdo_cobs(node);
        let f = CanFrame::new(cobs.rx, &req).ok_or_else(|| SdoError::Protocol {
            node,
            index,
            sub,
            what: "node id out of range".into(),
        })?;
        self.pump()?;
        self.bus.send(&f).map_err(Self::io)?;
        self.count(&f);
        let start = self.bus.now_us();
        let limit = self.sdo_timeout.as_micros() as u64;
        let want = cobs.tx;
        loop {
            let waited = self.bus.now_us().saturating_sub(start);
            if waited >= limit {
                return Err(SdoError::Timeout { node, index, sub, ms: limit / 1000 });
            }
            if let Some(r) = self.recv(Duration::from_micros(limit - waited))? {
                if r.id() == want {
                    self.count(&r);
                    let mut d = [0u8; 8];
                    for (x, y) in d.iter_mut().zip(r.data()) {
                        *x = *y;
                    }
                    if d[0] == 0x80 {
                        let code = u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
                        let text = Abort::from_code(code).map_or("unknown abort code", |a| a.describe());
                        return Err(SdoError::Abort { node, index, sub, code, text });
                    }
                    return Ok(d);
                }
            }
        }
    }

    /// Abort whatever SDO transfer `node` may still hold for `index:sub` (before a retry, so the
    /// server starts the next one clean).
    pub fn abort_transfer(&mut self, node: u8, index: u16, sub: u8) {
        self.abort(node, index, sub, Abort::Timeout);
    }

    fn abort(&mut self, node: u8, index: u16, sub: u8, a: Abort) {
        if let Some(f) = CanFrame::new(self.sdo_cobs(node).rx, &sdo::abort_payload(index, sub, a)) {
            let _ = self.bus.send(&f);
        }
    }

    /// SDO upload (read) of any length.
    pub fn read(&mut self, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
        let r = self.transact(node, index, sub, sdo::upload_request(index, sub))?;
        let proto = |what: &str| SdoError::Protocol { node, index, sub, what: what.to_string() };
        if r[0] >> 5 != 2 || u16::from_le_bytes([r[1], r[2]]) != index || r[3] != sub {
            return Err(proto("unexpected response to upload request"));
        }
        if r[0] & 0x02 != 0 {
            let n = if r[0] & 0x01 != 0 { 4 - ((r[0] >> 2) & 3) as usize } else { 4 };
            return Ok(r.get(4..4 + n).unwrap_or(&[]).to_vec());
        }
        let total = if r[0] & 0x01 != 0 { Some(u32::from_le_bytes([r[4], r[5], r[6], r[7]]) as usize) } else { None };
        // the announced size is the node's word: reserve no more than 64 KiB before the data come
        let mut out = Vec::with_capacity(total.unwrap_or(64).min(1 << 16));
        let mut toggle = 0u8;
        loop {
            let s = self.transact(node, index, sub, [0x60 | (toggle << 4), 0, 0, 0, 0, 0, 0, 0])?;
            if s[0] >> 5 != 0 || (s[0] >> 4) & 1 != toggle {
                self.abort(node, index, sub, Abort::Toggle);
                return Err(proto("bad upload segment (toggle or command)"));
            }
            let n = 7 - ((s[0] >> 1) & 7) as usize;
            out.extend_from_slice(s.get(1..1 + n).unwrap_or(&[]));
            if s[0] & 1 != 0 {
                break;
            }
            if out.len() > 1 << 20 {
                self.abort(node, index, sub, Abort::TooLong);
                return Err(proto("upload longer than 1 MiB"));
            }
            toggle ^= 1;
        }
        if total.is_some_and(|t| t != out.len()) {
            return Err(proto("segmented upload length differs from the announced size"));
        }
        Ok(out)
    }

    /// SDO download (write): expedited up to 4 bytes, segmented above.
    pub fn write(&mut self, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        let proto = |what: &str| SdoError::Protocol { node, index, sub, what: what.to_string() };
        if !data.is_empty() && data.len() <= 4 {
            let r = self.transact(node, index, sub, sdo::expedited_download(index, sub, data))?;
            if r[0] != 0x60 {
                return Err(proto("unexpected response to download"));
            }
            return Ok(());
        }
        let r = self.transact(node, index, sub, sdo::segmented_download(index, sub, data.len() as u32))?;
        if r[0] != 0x60 {
            return Err(proto("unexpected response to download"));
        }
        let mut toggle = 0u8;
        let chunks: Vec<&[u8]> = if data.is_empty() { vec![&[][..]] } else { data.chunks(7).collect() };
        for (i, c) in chunks.iter().enumerate() {
            let last = i + 1 == chunks.len();
            let mut d = [0u8; 8];
            d[0] = (toggle << 4) | (((7 - c.len()) as u8) << 1) | u8::from(last);
            for (x, y) in d.iter_mut().skip(1).zip(c.iter()) {
                *x = *y;
            }
            let r = self.transact(node, index, sub, d)?;
            if r[0] != 0x20 | (toggle << 4) {
                self.abort(node, index, sub, Abort::Toggle);
                return Err(proto("bad download segment response"));
            }
            toggle ^= 1;
        }
        Ok(())
    }

    pub fn read_u32(&mut self, node: u8, index: u16, sub: u8) -> Result<u32, SdoError> {
        let v = self.read(node, index, sub)?;
        let mut b = [0u8; 4];
        for (x, y) in b.iter_mut().zip(&v) {
            *x = *y;
        }
        Ok(u32::from_le_bytes(b))
    }

    pub fn read_string(&mut self, node: u8, index: u16, sub: u8) -> Result<String, SdoError> {
        Ok(String::from_utf8_lossy(&self.read(node, index, sub)?).into_owned())
    }
}
