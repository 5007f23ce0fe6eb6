//! The classic CAN data frame the node speaks: 11-bit identifier, 0..=8 data bytes.
//!
//! The core has no CAN driver dependency. Firmware converts to and from its HAL's frame type
//! through `embedded_can::Frame` (embassy-stm32's `can::Frame` implements it):
//!
//! ```ignore
//! use embedded_can::{Frame as _, Id, StandardId};
//! // HAL → core: extended ids and remote frames are not CANopen traffic we serve; drop them.
//! fn to_core(f: &impl embedded_can::Frame) -> Option<CanFrame> {
//!     match f.id() {
//!         Id::Standard(id) if !f.is_remote_frame() => CanFrame::new(id.as_raw(), f.data()),
//!         _ => None,
//!     }
//! }
//! // core → HAL: the id is ≤ 0x7FF and the length ≤ 8 by construction, so both succeed.
//! fn to_hal<F: embedded_can::Frame>(f: &CanFrame) -> Option<F> {
//!     F::new(StandardId::new(f.id())?, f.data())
//! }
//! ```

/// Largest 11-bit identifier.
pub const ID_MAX: u16 = 0x7FF;

/// A classic CAN data frame with a standard (11-bit) identifier. Its fields are private so
/// that every value is valid: `id ≤ 0x7FF`, `len ≤ 8`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CanFrame {
    id: u16,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A frame, or `None` when `id > 0x7FF` or `data` is longer than 8 bytes.
    pub fn new(id: u16, data: &[u8]) -> Option<CanFrame> {
        if id > ID_MAX || data.len() > 8 {
            return None;
        }
        let mut d = [0u8; 8];
        d.get_mut(..data.len())?.copy_from_slice(data);
        Some(CanFrame { id, len: data.len() as u8, data: d })
    }

    /// A frame from a fixed 8-byte payload of which the first `len` bytes count (`len` and `id`
    /// are clamped into range, so this cannot fail; the node uses it for its own replies).
    pub fn from_parts(id: u16, data: [u8; 8], len: u8) -> CanFrame {
        CanFrame { id: id & ID_MAX, len: len.min(8), data }
    }

    /// The 11-bit identifier (COB-ID).
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The data length code, 0..=8.
    pub fn dlc(&self) -> u8 {
        self.len
    }

    /// The payload, `dlc` bytes.
    pub fn data(&self) -> &[u8] {
        self.data.get(..self.len as usize).unwrap_or(&[])
    }

    /// All eight data bytes (those past `dlc` are zero for frames made by [`CanFrame::new`]).
    pub fn raw_data(&self) -> &[u8; 8] {
        &self.data
    }
}
