//! LSS slave (CiA 305): how a fresh board with no node id is found and given one on the bus.
//!
//! Master → slave on 0x7E5, slave → master on 0x7E4, 8-byte frames. This module is the
//! protocol's state machine over the node's identity (0x1018); what needs the node (the node
//! id going live, storing, the bit timing) comes back as an [`Action`] for
//! [`super::node::Node`] to carry out.
//!
//! Served: switch state global and selective, configure node id (1..=127, or 0xFF:
//! unconfigured after the next reset communication), configure bit timing (CiA table 0; only
//! the rates the node runs, [`BIT_TIMINGS`], others answer error 1), activate bit timing
//! (recorded in [`Lss::activate_ms`]; a node with one rate has nothing to switch),
//! store configuration (node id and bit timing through the node's storage; error 1 where it
//! cannot store), inquire identity and node id, identify remote slave, identify non-configured
//! remote slave, and fast scan (only an unconfigured slave in the waiting state takes part,
//! as in CiA 305 §8.4.1).

use super::node::Identity;

/// Whether this build's node serves LSS (the `lss` feature).
pub const SERVED: bool = cfg!(feature = "lss");

/// COB-ID of LSS requests (master → slave).
pub const LSS_MASTER: u16 = 0x7E5;
/// COB-ID of LSS responses (slave → master).
pub const LSS_SLAVE: u16 = 0x7E4;
/// The node id of an unconfigured node.
pub const UNCONFIGURED: u8 = 0xFF;
/// Bit timings of CiA 305 table 0 the node runs, as a bit mask over the table index
/// (0 = 1000 kbit/s, 1 = 800, 2 = 500, 3 = 250, 4 = 125, 6 = 50, 7 = 20, 8 = 10): the
/// boards run 1 Mbit/s only (the EDS's BaudRate_1000).
pub const BIT_TIMINGS: u16 = 1 << 0;

/// What the LSS slave keeps in non-volatile storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LssConfig {
    /// 1..=127, or [`UNCONFIGURED`]
    pub node_id: u8,
    /// index into CiA 305 table 0
    pub bit_timing: u8,
}

/// The LSS state (CiA 305 §6.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LssMode {
    Waiting,
    Configuration,
}

/// What a frame asks of the node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    None,
    /// send this response
    Respond([u8; 8]),
    /// store [`Lss::pending`] and answer 0x17 with the outcome
    Store,
    /// the unconfigured node has a pending id: reset communication, which makes it active
    ResetCommunication,
}

/// The LSS slave's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lss {
    pub mode: LssMode,
    /// the node id and bit timing configured, in force after the next reset communication
    pub pending: LssConfig,
    /// switch state selective: how many of vendor, product, revision, serial matched in turn
    selective: u8,
    /// identify remote slave: everything so far matched
    remote: bool,
    /// identify remote slave: the low bound of the range being checked
    low: u32,
    /// fast scan: the identity part being scanned, `None` while not taking part
    scan: Option<u8>,
    /// the switch delay (ms) of the last activate bit timing: a board with more than one rate
    /// switches to `pending.bit_timing` after it; ours run one, so nothing changes on the bus
    pub activate_ms: Option<u16>,
}

fn word(d: &[u8]) -> u32 {
    u32::from_le_bytes([
        d.get(1).copied().unwrap_or(0),
        d.get(2).copied().unwrap_or(0),
        d.get(3).copied().unwrap_or(0),
        d.get(4).copied().unwrap_or(0),
    ])
}

fn part(id: &Identity, k: u8) -> u32 {
    match k {
        0 => id.vendor_id,
        1 => id.product_code,
        2 => id.revision,
        _ => id.serial,
    }
}

fn reply(cs: u8, b: [u8; 4]) -> Action {
    Action::Respond([cs, b[0], b[1], b[2], b[3], 0, 0, 0])
}

impl Lss {
    pub const fn new(pending: LssConfig) -> Lss {
        Lss { mode: LssMode::Waiting, pending, selective: 0, remote: false, low: 0, scan: None, activate_ms: None }
    }

    /// One LSS request (8 bytes: shorter ones are the caller's to drop). `active` is the node
    /// id in force.
    pub fn on_request(&mut self, d: &[u8], id: &Identity, active: u8) -> Action {
        let cs = d.first().copied().unwrap_or(0);
        let b1 = d.get(1).copied().unwrap_or(0);
        let unconfigured = active == UNCONFIGURED;
        let config = self.mode == LssMode::Configuration;
        match cs {
            0x04 => {
                self.selective = 0;
                if b1 == 1 {
                    self.mode = LssMode::Configuration;
                } else if b1 == 0 {
                    let was = self.mode;
                    self.mode = LssMode::Waiting;
                    if was == LssMode::Configuration && unconfigured && self.pending.node_id != UNCONFIGURED {
                        return Action::ResetCommunication;
                    }
                }
                Action::None
            }
            0x40..=0x43 if !config => {
                let k = cs - 0x40;
                // each part in turn; a mismatch (or a part out of order) starts again
                self.selective = if k == self.selective && word(d) == part(id, k) { k + 1 } else { 0 };
                if self.selective == 4 {
                    self.selective = 0;
                    self.mode = LssMode::Configuration;
                    return reply(0x44, [0; 4]);
                }
                Action::None
            }
            0x11 if config => {
                let ok = (1..=127).contains(&b1) || b1 == UNCONFIGURED;
                if ok {
                    self.pending.node_id = b1;
                }
                reply(0x11, [u8::from(!ok), 0, 0, 0])
            }
            0x13 if config => {
                let index = d.get(2).copied().unwrap_or(0xFF);
                let ok = b1 == 0 && index < 16 && BIT_TIMINGS & (1 << index) != 0;
                if ok {
                    self.pending.bit_timing = index;
                }
                reply(0x13, [u8::from(!ok), 0, 0, 0])
            }
            0x15 if config => {
                self.activate_ms = Some(u16::from_le_bytes([b1, d.get(2).copied().unwrap_or(0)]));
                Action::None
            }
            0x17 if config => Action::Store,
            0x5A..=0x5D if config => reply(cs, part(id, cs - 0x5A).to_le_bytes()),
            0x5E if config => reply(0x5E, [active, 0, 0, 0]),
            0x46..=0x4B => self.identify(cs, word(d), id),
            0x4C if unconfigured => reply(0x50, [0; 4]),
            0x51 if unconfigured && !config => self.fast_scan(d, id),
            _ => Action::None,
        }
    }

    /// Identify remote slave: vendor and product equal, revision and serial in [low, high].
    fn identify(&mut self, cs: u8, v: u32, id: &Identity) -> Action {
        match cs {
            0x46 => self.remote = v == id.vendor_id,
            0x47 => self.remote &= v == id.product_code,
            0x48 | 0x4A => self.low = v,
            0x49 => self.remote &= (self.low..=v).contains(&id.revision),
            _ => {
                let hit = self.remote && (self.low..=v).contains(&id.serial);
                self.remote = false;
                if hit {
                    return reply(0x4F, [0; 4]);
                }
            }
        }
        Action::None
    }

    /// Fast scan (CiA 305 §8.4.1): bit 0x80 starts it; then the master names the bits from
    /// `bit_checked` up of one identity part, and the slave answers while they are its own.
    /// A whole part confirmed moves to the next; the last one confirmed puts the slave in
    /// the configuration state.
    fn fast_scan(&mut self, d: &[u8], id: &Identity) -> Action {
        let bit = d.get(5).copied().unwrap_or(0);
        let sub = d.get(6).copied().unwrap_or(0);
        let next = d.get(7).copied().unwrap_or(0);
        if bit == 0x80 {
            self.scan = Some(0);
            return reply(0x4F, [0; 4]);
        }
        if bit > 31 || sub > 3 || next > 3 || self.scan != Some(sub) {
            return Action::None;
        }
        let mask = u32::MAX << bit;
        if (word(d) ^ part(id, sub)) & mask != 0 {
            return Action::None;
        }
        if bit == 0 {
            // `next` = `sub` is the master checking the last bit; a `next` below it, the wrap
            // after the serial: the whole identity is this slave's
            if next < sub {
                self.scan = None;
                self.mode = LssMode::Configuration;
            } else {
                self.scan = Some(next);
            }
        }
        reply(0x4F, [0; 4])
    }
}
