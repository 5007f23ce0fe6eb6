//! The CAN data frame the node speaks: 11-bit identifier, classic (0..=8 data bytes) or CAN FD
//! (ISO 11898-1:2015: 0..=8, 12, 16, 20, 24, 32, 48 or 64 bytes, with or without bit-rate
//! switch).
//!
//! The core has no CAN driver dependency. Its `hal` module (feature `embedded-can`) converts
//! to and from any HAL's `embedded_can::Frame` (embassy-stm32's `can::Frame` implements it; the
//! FD flags, which `embedded_can` does not carry, come from the HAL's frame header:
//! `hal::to_core_fd`).
//!
//! One type for both formats keeps every queue and callback of the node as it was; the price
//! is RAM: a frame is 68 bytes instead of 12 (an outbox of 16 frames: 1088 B instead of 192).

/// Largest 11-bit identifier.
pub const ID_MAX: u16 = 0x7FF;

/// Largest CAN FD payload.
pub const FD_MAX_LEN: usize = 64;

/// Payload length of each data length code (ISO 11898-1:2015 table 5): codes 0..=8 are the
/// length itself, 9..=15 the FD lengths 12..=64.
pub const FD_LENGTHS: [u8; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// The payload length of DLC `code` in an FD frame (`None` above 15).
pub fn fd_len_of_dlc(code: u8) -> Option<usize> {
    FD_LENGTHS.get(usize::from(code)).map(|&l| usize::from(l))
}

/// The DLC of an FD payload of exactly `len` bytes (`None` if `len` is not a valid FD length).
pub fn fd_dlc_of_len(len: usize) -> Option<u8> {
    FD_LENGTHS.iter().position(|&l| usize::from(l) == len).map(|p| p as u8)
}

/// The smallest valid FD length that holds `len` bytes (`None` above 64).
pub fn fd_padded_len(len: usize) -> Option<usize> {
    FD_LENGTHS.iter().map(|&l| usize::from(l)).find(|&l| l >= len)
}

const FLAG_FD: u8 = 1;
const FLAG_BRS: u8 = 2;

/// A CAN data frame with a standard (11-bit) identifier. Its fields are private so that every
/// value is valid: `id ≤ 0x7FF`; a classic frame has `len ≤ 8`, an FD frame a valid FD length;
/// bytes past `len` are zero for frames made by [`CanFrame::new`] and [`CanFrame::new_fd`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CanFrame {
    id: u16,
    len: u8,
    flags: u8,
    data: [u8; FD_MAX_LEN],
}

impl Default for CanFrame {
    fn default() -> Self {
        CanFrame { id: 0, len: 0, flags: 0, data: [0; FD_MAX_LEN] }
    }
}

impl CanFrame {
    /// A classic frame, or `None` when `id > 0x7FF` or `data` is longer than 8 bytes.
    pub fn new(id: u16, data: &[u8]) -> Option<CanFrame> {
        if data.len() > 8 {
            return None;
        }
        Self::build(id, data, data.len(), 0)
    }

    /// An FD frame (with bit-rate switch if `brs`), or `None` when `id > 0x7FF` or `data` is
    /// longer than 64 bytes. A length between the valid FD lengths is padded with 0x00 up to
    /// the next one (ISO 11898-1 has no length 10: 10 bytes go as 12).
    pub fn new_fd(id: u16, data: &[u8], brs: bool) -> Option<CanFrame> {
        let len = fd_padded_len(data.len())?;
        Self::build(id, data, len, FLAG_FD | if brs { FLAG_BRS } else { 0 })
    }

    fn build(id: u16, data: &[u8], len: usize, flags: u8) -> Option<CanFrame> {
        if id > ID_MAX {
            return None;
        }
        let mut d = [0u8; FD_MAX_LEN];
        d.get_mut(..data.len())?.copy_from_slice(data);
        Some(CanFrame { id, len: len as u8, flags, data: d })
    }

    /// A classic frame from a fixed 8-byte payload of which the first `len` bytes count
    /// (`len` and `id` are clamped into range, so this cannot fail; the node uses it for its
    /// own replies).
    pub fn from_parts(id: u16, data: [u8; 8], len: u8) -> CanFrame {
        let mut d = [0u8; FD_MAX_LEN];
        for (dst, src) in d.iter_mut().zip(data) {
            *dst = src;
        }
        CanFrame { id: id & ID_MAX, len: len.min(8), flags: 0, data: d }
    }

    /// The same payload as an FD frame (classic frames of ≤ 8 bytes keep their length: every
    /// length 0..=8 is a valid FD length).
    pub fn into_fd(self, brs: bool) -> CanFrame {
        CanFrame { flags: FLAG_FD | if brs { FLAG_BRS } else { 0 }, ..self }
    }

    /// The 11-bit identifier (COB-ID).
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The data length code: the length for 0..=8 bytes (so for every classic frame), 9..=15
    /// for the FD lengths 12..=64.
    pub fn dlc(&self) -> u8 {
        fd_dlc_of_len(usize::from(self.len)).unwrap_or(15)
    }

    /// Payload length in bytes.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// No payload.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// An FD frame (FDF bit recessive).
    pub fn is_fd(&self) -> bool {
        self.flags & FLAG_FD != 0
    }

    /// An FD frame whose data phase runs at the data bit rate.
    pub fn brs(&self) -> bool {
        self.flags & FLAG_BRS != 0
    }

    /// The payload, `len` bytes.
    pub fn data(&self) -> &[u8] {
        self.data.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// The first eight data bytes (those past `len` are zero for frames made by
    /// [`CanFrame::new`]).
    pub fn raw_data(&self) -> &[u8; 8] {
        self.data.first_chunk::<8>().unwrap_or(&[0; 8])
    }
}
