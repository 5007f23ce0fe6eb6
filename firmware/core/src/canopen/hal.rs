//! The core's frame and any HAL's `embedded_can::Frame` (feature `embedded-can`): what a board
//! needs between its CAN driver and the node, written once. embassy-stm32's FDCAN `Frame`,
//! bxcan's, socketcan's and most HALs' frames implement `embedded_can::Frame`.
//!
//! ```ignore
//! // receive: a frame the node does not serve is counted, never handed on
//! match joint_core::canopen::hal::to_core(&rx) {
//!     Ok(f) => node.process(now_us, Some(&f), &mut |out| outbox.push(out)),
//!     Err(_why) => stats.count_rx_rejected(),
//! }
//! // send
//! let hal_frame: MyHalFrame = joint_core::canopen::hal::to_hal(&out).ok_or(Error)?;
//! ```

use super::CanFrame;
use embedded_can::{Frame, Id, StandardId};

/// Why a received frame was not handed to the node. None of these is CANopen traffic the
/// node serves; they are counted ([`BusStats::rx_rejected`]), never a panic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rejected {
    /// 29-bit identifier: CANopen (CiA 301) uses 11-bit ids only.
    Extended,
    /// Remote frame: the node implements no RTR services (node guarding is not served).
    Remote,
    /// More than 8 data bytes (an FD frame on a classic node).
    TooLong,
}

/// A received HAL frame as the node's frame.
pub fn to_core<F: Frame>(f: &F) -> Result<CanFrame, Rejected> {
    let Id::Standard(id) = f.id() else {
        return Err(Rejected::Extended);
    };
    if f.is_remote_frame() {
        return Err(Rejected::Remote);
    }
    CanFrame::new(id.as_raw(), f.data()).ok_or(Rejected::TooLong)
}

/// A received frame of a controller in CAN FD mode as the node's frame: `fd` and `brs` are
/// what the HAL's header says (embassy-stm32's `FdFrame::header()`), which `embedded_can`
/// does not carry.
pub fn to_core_fd<F: Frame>(f: &F, fd: bool, brs: bool) -> Result<CanFrame, Rejected> {
    let Id::Standard(id) = f.id() else {
        return Err(Rejected::Extended);
    };
    if f.is_remote_frame() {
        return Err(Rejected::Remote);
    }
    if fd {
        CanFrame::new_fd(id.as_raw(), f.data(), brs).ok_or(Rejected::TooLong)
    } else {
        CanFrame::new(id.as_raw(), f.data()).ok_or(Rejected::TooLong)
    }
}

/// A frame of the node as the HAL's frame. The node only makes frames with an 11-bit id, so
/// `None` means the HAL refused the frame (an FD frame on a classic HAL frame type).
pub fn to_hal<F: Frame>(f: &CanFrame) -> Option<F> {
    F::new(StandardId::new(f.id())?, f.data())
}
