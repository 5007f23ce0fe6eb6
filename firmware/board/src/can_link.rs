//! CAN frame plumbing that does not need the peripheral: conversion between the HAL's
//! frames and the core's [`CanFrame`], the outbox the node's frames wait in while the node's
//! lock is held, and the bookkeeping of bus health (error counters, error-passive and
//! bus-off episodes) that the CAN task exposes.
//!
//! The CANopen protocol itself (NMT, heartbeat, SDO, PDO, EMCY) is the core's
//! [`joint_core::canopen::Node`]; this module only moves frames to and from it. Everything
//! is generic over `embedded_can::Frame`, so it is unit-tested on the host with a plain
//! frame type and used on the board with embassy-stm32's `can::Frame`.

// The conversion between any HAL's `embedded_can::Frame` and the core's frame is the core's
// (feature `embedded-can`), so another board or a host driver takes it as is.
pub use joint_core::canopen::hal::{to_core, to_core_fd, to_hal, Rejected};

// The outbox the node's frames wait in is the core's: one loop body for every firmware.
pub use joint_core::canopen::outbox::Outbox;

/// Error state of the controller as the FDCAN reports it (PSR.EP / PSR.BO).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BusMode {
    #[default]
    ErrorActive,
    ErrorPassive,
    BusOff,
}

/// Counters the CAN task exposes (defmt log on every change of bus mode and every 10 s while
/// they change; the node's object dictionary has no object for them yet). All counters
/// saturate instead of wrapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BusStats {
    pub mode: BusMode,
    /// Receive and transmit error counters as last read from the controller (ECR).
    pub rec: u8,
    pub tec: u8,
    pub rx_frames: u32,
    pub tx_frames: u32,
    /// Received frames the node does not serve (extended id, remote, over 8 bytes).
    pub rx_rejected: u32,
    /// Frames the node sent that did not go out (outbox full, TX buffer timeout, bus off).
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
    pub fn count_rx_rejected(&mut self) {
        self.rx_rejected = self.rx_rejected.saturating_add(1);
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
    use embedded_can::{Frame, Id, StandardId};
    use joint_core::canopen::CanFrame;

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
    fn standard_data_frames_convert_both_ways_unchanged() {
        for (id, data) in [(0x000u16, &[0x01u8, 0x05][..]), (0x605, &[0x2F, 0x00, 0x20, 0, 1, 2, 3, 4]), (0x7FF, &[])] {
            let hal = TestFrame::new(sid(id), data).unwrap();
            let core = to_core(&hal).unwrap();
            assert_eq!((core.id(), core.data()), (id, data));
            let back: TestFrame = to_hal(&core).unwrap();
            assert_eq!(back, hal);
        }
    }

    #[test]
    fn frames_the_node_does_not_serve_are_rejected_with_the_reason() {
        let ext = TestFrame::new(ExtendedId::new(0x605).unwrap(), &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap();
        assert_eq!(to_core(&ext), Err(Rejected::Extended));
        let remote = TestFrame::new_remote(sid(0x705), 1).unwrap();
        assert_eq!(to_core(&remote), Err(Rejected::Remote));
        // An FD-sized payload cannot become a classic frame.
        let long = TestFrame { id: Id::Standard(sid(0x605)), remote: false, dlc: 12, data: [0; 8] };
        let long = LongFrame(long);
        assert_eq!(to_core(&long), Err(Rejected::TooLong));
    }

    /// A frame type whose `data()` is longer than 8 bytes, as an FD frame's can be.
    struct LongFrame(TestFrame);
    impl Frame for LongFrame {
        fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
            TestFrame::new(id, data).map(LongFrame)
        }
        fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
            TestFrame::new_remote(id, dlc).map(LongFrame)
        }
        fn is_extended(&self) -> bool {
            false
        }
        fn is_remote_frame(&self) -> bool {
            false
        }
        fn id(&self) -> Id {
            self.0.id
        }
        fn dlc(&self) -> usize {
            12
        }
        fn data(&self) -> &[u8] {
            &[0; 12]
        }
    }

    #[test]
    fn fd_frames_keep_their_format_and_bit_rate_switch() {
        let long = LongFrame(TestFrame { id: Id::Standard(sid(0x605)), remote: false, dlc: 12, data: [0; 8] });
        let f = to_core_fd(&long, true, true).unwrap();
        assert!(f.is_fd() && f.brs() && f.len() == 12);
        let f = to_core_fd(&long, true, false).unwrap();
        assert!(f.is_fd() && !f.brs());
        // a classic frame received in FD mode stays classic; a long one claimed classic is refused
        let short = TestFrame::new(sid(0x605), &[1, 2]).unwrap();
        let c = to_core_fd(&short, false, false).unwrap();
        assert!(!c.is_fd() && c.data() == [1, 2]);
        assert_eq!(to_core_fd(&long, false, false), Err(Rejected::TooLong));
        let ext = TestFrame::new(ExtendedId::new(0x605).unwrap(), &[0]).unwrap();
        assert_eq!(to_core_fd(&ext, true, true), Err(Rejected::Extended));
        let remote = TestFrame::new_remote(sid(0x705), 1).unwrap();
        assert_eq!(to_core_fd(&remote, true, true), Err(Rejected::Remote));
    }

    #[test]
    fn outbox_keeps_order_and_counts_what_does_not_fit() {
        let mut o = Outbox::<2>::new();
        for id in [0x705u16, 0x185, 0x085] {
            o.push(CanFrame::new(id, &[1]).unwrap());
        }
        let ids: Vec<u16> = o.frames().iter().map(|f| f.id()).collect();
        assert_eq!(ids, [0x705, 0x185]);
        assert_eq!(o.take_overflow(), 1);
        assert_eq!(o.take_overflow(), 0);
        o.clear();
        assert!(o.frames().is_empty());
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
