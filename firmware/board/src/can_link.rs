//! CAN frame plumbing that does not need the peripheral: which received frames are the
//! host's heartbeat, the node's own heartbeat frame, and the bookkeeping of bus health
//! (error counters, error-passive and bus-off episodes) that the CAN task exposes.
//!
//! The CANopen protocol itself (NMT, SDO, PDO, EMCY) is the core's job (issue 4); this
//! module only knows the two COB-IDs the firmware must handle before that exists: the
//! host's heartbeat, which feeds the heartbeat watchdog, and the node's own heartbeat.
//! Everything is generic over `embedded_can::Frame`, so it is unit-tested on the host
//! with a plain frame type and used on the board with embassy-stm32's `can::Frame`.

use embedded_can::{Frame, Id, StandardId};

/// CANopen heartbeat/NMT-error-control COB-ID base (CiA 301): heartbeat of node n is 0x700 + n.
pub const HEARTBEAT_BASE: u16 = 0x700;

/// A CANopen node id, 1..=127.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeId(u8);

/// A node id outside 1..=127.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BadNodeId(pub u8);

impl NodeId {
    /// Checks the CiA 301 range; 0 is the NMT broadcast address and 128.. do not exist.
    pub const fn new(id: u8) -> Result<Self, BadNodeId> {
        if id >= 1 && id <= 127 {
            Ok(Self(id))
        } else {
            Err(BadNodeId(id))
        }
    }

    pub const fn get(self) -> u8 {
        self.0
    }

    /// COB-ID of this node's heartbeat.
    pub fn heartbeat_id(self) -> StandardId {
        // 0x700 + 127 = 0x77F < 0x800: always a valid 11-bit id, so `new` cannot return None;
        // ZERO is there only to avoid an unwrap the lints forbid.
        StandardId::new(HEARTBEAT_BASE + u16::from(self.0)).unwrap_or(StandardId::ZERO)
    }
}

/// CANopen NMT state byte carried by a heartbeat (CiA 301 table 50).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum NmtState {
    BootUp = 0x00,
    Stopped = 0x04,
    Operational = 0x05,
    PreOperational = 0x7F,
}

impl NmtState {
    pub fn from_byte(b: u8) -> Option<Self> {
        match b & 0x7F {
            0x00 => Some(Self::BootUp),
            0x04 => Some(Self::Stopped),
            0x05 => Some(Self::Operational),
            0x7F => Some(Self::PreOperational),
            _ => None,
        }
    }
}

/// What a received frame means to the firmware's plumbing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inbound {
    /// The host's heartbeat: feeds the heartbeat watchdog. Carries the host's NMT state.
    HostHeartbeat(NmtState),
    /// Anything else: handed on to the protocol layer unchanged.
    Other,
}

/// Classifies a received frame. A frame on the host's heartbeat id that is not a valid
/// heartbeat (remote frame, wrong length, unknown state byte) does NOT feed the watchdog:
/// a babbling or broken host must not keep the joint powered.
pub fn classify<F: Frame>(frame: &F, host: NodeId) -> Inbound {
    let is_host_hb = matches!(frame.id(), Id::Standard(id) if id == host.heartbeat_id());
    if !is_host_hb || frame.is_remote_frame() || frame.dlc() != 1 {
        return Inbound::Other;
    }
    match frame.data().first().copied().and_then(NmtState::from_byte) {
        Some(state) => Inbound::HostHeartbeat(state),
        None => Inbound::Other,
    }
}

/// The node's own heartbeat frame (one byte, the NMT state).
pub fn heartbeat_frame<F: Frame>(node: NodeId, state: NmtState) -> Option<F> {
    F::new(node.heartbeat_id(), &[state as u8])
}

/// Error state of the controller as the FDCAN reports it (PSR.EP / PSR.BO).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BusMode {
    #[default]
    ErrorActive,
    ErrorPassive,
    BusOff,
}

/// Counters the CAN task exposes (to defmt logs now, to the CANopen error register and
/// EMCY later). All counters saturate instead of wrapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BusStats {
    pub mode: BusMode,
    /// Receive and transmit error counters as last read from the controller (ECR).
    pub rec: u8,
    pub tec: u8,
    pub rx_frames: u32,
    pub tx_frames: u32,
    /// Received frames dropped because the protocol side's queue was full.
    pub rx_dropped: u32,
    /// Frames the firmware wanted to send but had to drop (queue full, bus off).
    pub tx_dropped: u32,
    /// Receive errors the driver reported (stuff, form, CRC, ...).
    pub bus_errors: u32,
    /// Entries into error-passive and into bus-off.
    pub error_passive_events: u32,
    pub bus_off_events: u32,
    /// Times the controller came back from bus-off to error-active/passive.
    pub recoveries: u32,
}

/// A change of bus mode worth reporting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusEvent {
    EnteredErrorPassive,
    EnteredBusOff,
    /// Left bus-off: the controller saw 128 × 11 recessive bits and rejoined.
    Recovered,
}

impl BusStats {
    /// Feeds a fresh reading of the controller's state; returns the transition, if any.
    pub fn observe(&mut self, mode: BusMode, rec: u8, tec: u8) -> Option<BusEvent> {
        let before = self.mode;
        self.mode = mode;
        self.rec = rec;
        self.tec = tec;
        match (before, mode) {
            (BusMode::BusOff, BusMode::BusOff) => None,
            (_, BusMode::BusOff) => {
                self.bus_off_events = self.bus_off_events.saturating_add(1);
                Some(BusEvent::EnteredBusOff)
            }
            (BusMode::BusOff, _) => {
                self.recoveries = self.recoveries.saturating_add(1);
                Some(BusEvent::Recovered)
            }
            (BusMode::ErrorActive, BusMode::ErrorPassive) => {
                self.error_passive_events = self.error_passive_events.saturating_add(1);
                Some(BusEvent::EnteredErrorPassive)
            }
            _ => None,
        }
    }

    pub fn count_rx(&mut self) {
        self.rx_frames = self.rx_frames.saturating_add(1);
    }
    pub fn count_tx(&mut self) {
        self.tx_frames = self.tx_frames.saturating_add(1);
    }
    pub fn count_rx_dropped(&mut self) {
        self.rx_dropped = self.rx_dropped.saturating_add(1);
    }
    pub fn count_tx_dropped(&mut self) {
        self.tx_dropped = self.tx_dropped.saturating_add(1);
    }
    pub fn count_bus_error(&mut self) {
        self.bus_errors = self.bus_errors.saturating_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::ExtendedId;

    /// A plain classic frame for host tests.
    #[derive(Debug, Clone, PartialEq)]
    struct TestFrame {
        id: Id,
        remote: bool,
        dlc: usize,
        data: [u8; 8],
    }

    impl Frame for TestFrame {
        fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
            if data.len() > 8 {
                return None;
            }
            let mut d = [0; 8];
            d.get_mut(..data.len())?.copy_from_slice(data);
            Some(Self { id: id.into(), remote: false, dlc: data.len(), data: d })
        }
        fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
            (dlc <= 8).then(|| Self { id: id.into(), remote: true, dlc, data: [0; 8] })
        }
        fn is_extended(&self) -> bool {
            matches!(self.id, Id::Extended(_))
        }
        fn is_remote_frame(&self) -> bool {
            self.remote
        }
        fn id(&self) -> Id {
            self.id
        }
        fn dlc(&self) -> usize {
            self.dlc
        }
        fn data(&self) -> &[u8] {
            if self.remote {
                &[]
            } else {
                &self.data[..self.dlc]
            }
        }
    }

    fn sid(raw: u16) -> StandardId {
        StandardId::new(raw).unwrap()
    }

    #[test]
    fn node_id_range() {
        assert_eq!(NodeId::new(0), Err(BadNodeId(0)));
        assert_eq!(NodeId::new(128), Err(BadNodeId(128)));
        assert_eq!(NodeId::new(127).unwrap().heartbeat_id(), sid(0x77F));
        assert_eq!(NodeId::new(1).unwrap().heartbeat_id(), sid(0x701));
    }

    #[test]
    fn host_heartbeat_is_recognised_only_when_well_formed() {
        let host = NodeId::new(0x7F).unwrap();
        let ok = TestFrame::new(sid(0x77F), &[0x05]).unwrap();
        assert_eq!(classify(&ok, host), Inbound::HostHeartbeat(NmtState::Operational));
        // Toggle bit (bit 7) as sent by node-guarding-era masters is ignored.
        let toggled = TestFrame::new(sid(0x77F), &[0x85]).unwrap();
        assert_eq!(classify(&toggled, host), Inbound::HostHeartbeat(NmtState::Operational));
        let wrong_node = TestFrame::new(sid(0x77E), &[0x05]).unwrap();
        assert_eq!(classify(&wrong_node, host), Inbound::Other);
        let long = TestFrame::new(sid(0x77F), &[0x05, 0]).unwrap();
        assert_eq!(classify(&long, host), Inbound::Other);
        let empty = TestFrame::new(sid(0x77F), &[]).unwrap();
        assert_eq!(classify(&empty, host), Inbound::Other);
        let remote = TestFrame::new_remote(sid(0x77F), 1).unwrap();
        assert_eq!(classify(&remote, host), Inbound::Other);
        let bad_state = TestFrame::new(sid(0x77F), &[0x33]).unwrap();
        assert_eq!(classify(&bad_state, host), Inbound::Other);
        let ext = TestFrame::new(ExtendedId::new(0x77F).unwrap(), &[0x05]).unwrap();
        assert_eq!(classify(&ext, host), Inbound::Other);
    }

    #[test]
    fn own_heartbeat_frame() {
        let f: TestFrame = heartbeat_frame(NodeId::new(5).unwrap(), NmtState::PreOperational).unwrap();
        assert_eq!(f.id(), Id::Standard(sid(0x705)));
        assert_eq!(f.data(), &[0x7F]);
    }

    #[test]
    fn bus_off_episode_is_counted_once_and_recovery_noticed() {
        let mut s = BusStats::default();
        assert_eq!(s.observe(BusMode::ErrorActive, 0, 10), None);
        assert_eq!(s.observe(BusMode::ErrorPassive, 0, 130), Some(BusEvent::EnteredErrorPassive));
        assert_eq!(s.observe(BusMode::BusOff, 0, 255), Some(BusEvent::EnteredBusOff));
        assert_eq!(s.observe(BusMode::BusOff, 0, 255), None);
        assert_eq!(s.observe(BusMode::ErrorActive, 0, 0), Some(BusEvent::Recovered));
        assert_eq!((s.error_passive_events, s.bus_off_events, s.recoveries), (1, 1, 1));
        assert_eq!((s.rec, s.tec), (0, 0));
    }

    #[test]
    fn counters_saturate() {
        let mut s = BusStats { rx_frames: u32::MAX, ..BusStats::default() };
        s.count_rx();
        assert_eq!(s.rx_frames, u32::MAX);
    }
}
