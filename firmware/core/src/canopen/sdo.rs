//! SDO protocol pieces shared by the node (server) and host tools (client): abort codes,
//! command specifiers and the frame layouts of CiA 301 §7.2.4.3.
//!
//! Expedited, segmented and block transfers (with CRC) are served; the block protocol itself
//! lives with the node (`node/block.rs`), its frame constants and the CRC here.

/// SDO abort codes used by the node (CiA 301 table 22).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Abort {
    /// 0x05030000 toggle bit not alternated
    Toggle,
    /// 0x05040000 SDO protocol timed out
    Timeout,
    /// 0x05040001 client/server command specifier not valid or unknown
    Command,
    /// 0x05040002 invalid block size (block mode only)
    BlockSize,
    /// 0x05040003 invalid sequence number (block mode only)
    SeqNo,
    /// 0x05040004 CRC error (block mode only)
    Crc,
    /// 0x06010000 unsupported access to an object
    Unsupported,
    /// 0x06010001 attempt to read a write-only object
    WriteOnly,
    /// 0x06010002 attempt to write a read-only object
    ReadOnly,
    /// 0x06020000 object does not exist in the object dictionary
    NoObject,
    /// 0x06070010 data type does not match, length of service parameter does not match
    TypeLength,
    /// 0x06070012 data type does not match, length of service parameter too high
    TooLong,
    /// 0x06070013 data type does not match, length of service parameter too low
    TooShort,
    /// 0x06040041 object cannot be mapped to the PDO
    CannotMap,
    /// 0x06040042 the number and length of the objects to be mapped would exceed the PDO length
    MapLength,
    /// 0x06090011 sub-index does not exist
    NoSubIndex,
    /// 0x06090030 invalid value for parameter (download only)
    InvalidValue,
    /// 0x06090031 value of parameter written too high
    TooHigh,
    /// 0x06090032 value of parameter written too low
    TooLow,
    /// 0x08000000 general error
    General,
    /// 0x08000020 data cannot be transferred or stored to the application
    CannotStore,
    /// 0x08000022 ... because of the present device state
    DeviceState,
}

impl Abort {
    pub const fn code(self) -> u32 {
        match self {
            Abort::Toggle => 0x0503_0000,
            Abort::Timeout => 0x0504_0000,
            Abort::Command => 0x0504_0001,
            Abort::BlockSize => 0x0504_0002,
            Abort::SeqNo => 0x0504_0003,
            Abort::Crc => 0x0504_0004,
            Abort::Unsupported => 0x0601_0000,
            Abort::WriteOnly => 0x0601_0001,
            Abort::ReadOnly => 0x0601_0002,
            Abort::NoObject => 0x0602_0000,
            Abort::TypeLength => 0x0607_0010,
            Abort::TooLong => 0x0607_0012,
            Abort::TooShort => 0x0607_0013,
            Abort::CannotMap => 0x0604_0041,
            Abort::MapLength => 0x0604_0042,
            Abort::NoSubIndex => 0x0609_0011,
            Abort::InvalidValue => 0x0609_0030,
            Abort::TooHigh => 0x0609_0031,
            Abort::TooLow => 0x0609_0032,
            Abort::General => 0x0800_0000,
            Abort::CannotStore => 0x0800_0020,
            Abort::DeviceState => 0x0800_0022,
        }
    }

    /// The abort for a code, if it is one of ours.
    pub fn from_code(code: u32) -> Option<Abort> {
        const ALL: [Abort; 22] = [
            Abort::Toggle,
            Abort::Timeout,
            Abort::Command,
            Abort::BlockSize,
            Abort::SeqNo,
            Abort::Crc,
            Abort::WriteOnly,
            Abort::ReadOnly,
            Abort::NoObject,
            Abort::TypeLength,
            Abort::TooLong,
            Abort::TooShort,
            Abort::Unsupported,
            Abort::CannotMap,
            Abort::MapLength,
            Abort::NoSubIndex,
            Abort::InvalidValue,
            Abort::TooHigh,
            Abort::TooLow,
            Abort::General,
            Abort::CannotStore,
            Abort::DeviceState,
        ];
        ALL.into_iter().find(|a| a.code() == code)
    }

    /// Short English description (CiA 301 wording).
    pub const fn describe(self) -> &'static str {
        match self {
            Abort::Toggle => "toggle bit not alternated",
            Abort::Timeout => "SDO protocol timed out",
            Abort::Command => "command specifier not valid or unknown",
            Abort::BlockSize => "invalid block size (block mode)",
            Abort::SeqNo => "invalid sequence number (block mode)",
            Abort::Crc => "CRC error (block mode)",
            Abort::WriteOnly => "attempt to read a write-only object",
            Abort::ReadOnly => "attempt to write a read-only object",
            Abort::NoObject => "object does not exist in the object dictionary",
            Abort::TypeLength => "data type does not match, length of service parameter does not match",
            Abort::TooLong => "data type does not match, length of service parameter too high",
            Abort::TooShort => "data type does not match, length of service parameter too low",
            Abort::Unsupported => "unsupported access to an object",
            Abort::CannotMap => "object cannot be mapped to the PDO",
            Abort::MapLength => "the number and length of the objects to be mapped would exceed the PDO length",
            Abort::NoSubIndex => "sub-index does not exist",
            Abort::InvalidValue => "invalid value for parameter",
            Abort::TooHigh => "value of parameter written too high",
            Abort::TooLow => "value of parameter written too low",
            Abort::General => "general error",
            Abort::CannotStore => "data cannot be transferred or stored to the application",
            Abort::DeviceState => "data cannot be transferred or stored because of the present device state",
        }
    }
}

/// COB-ID base of SDO requests (client → server): `0x600 + node`.
pub const RX_BASE: u16 = 0x600;
/// COB-ID base of SDO responses (server → client): `0x580 + node`.
pub const TX_BASE: u16 = 0x580;

/// Client command specifiers (bits 7..5 of byte 0 of a request).
pub const CCS_DOWNLOAD_SEGMENT: u8 = 0;
pub const CCS_INITIATE_DOWNLOAD: u8 = 1;
pub const CCS_INITIATE_UPLOAD: u8 = 2;
pub const CCS_UPLOAD_SEGMENT: u8 = 3;
pub const CCS_ABORT: u8 = 4;
/// Block upload (client: initiate, start, acknowledge, end by its low two bits).
pub const CCS_BLOCK_UPLOAD: u8 = 5;
/// Block download (client: initiate, end by bit 0; the segments carry no specifier).
pub const CCS_BLOCK_DOWNLOAD: u8 = 6;
/// Largest number of segments in one block (CiA 301: 1..=127).
pub const BLOCK_SEGMENTS_MAX: u8 = 127;

/// CRC-16 of block transfers (CiA 301 §7.2.4.3.16): CCITT polynomial x¹⁶+x¹²+x⁵+1 (0x1021),
/// initial value 0, no reflection, no final XOR (the "XMODEM" variant), fed one byte at a
/// time so the node can run it over an object it never copies. Bitwise: 512 bytes take ~4 k
/// steps once per transfer, and a table would cost 512 bytes of flash.
pub fn crc16_byte(crc: u16, byte: u8) -> u16 {
    let mut c = crc ^ (u16::from(byte) << 8);
    for _ in 0..8 {
        c = if c & 0x8000 != 0 { (c << 1) ^ 0x1021 } else { c << 1 };
    }
    c
}

/// [`crc16_byte`] over a slice, from 0.
pub fn crc16(data: &[u8]) -> u16 {
    data.iter().fold(0, |c, &b| crc16_byte(c, b))
}

/// An abort frame payload.
pub fn abort_payload(index: u16, sub: u8, abort: Abort) -> [u8; 8] {
    let i = index.to_le_bytes();
    let c = abort.code().to_le_bytes();
    [0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}

/// Payload of an expedited initiate-download request carrying `data` (1..=4 bytes).
pub fn expedited_download(index: u16, sub: u8, data: &[u8]) -> [u8; 8] {
    let n = data.len().clamp(1, 4);
    let i = index.to_le_bytes();
    let mut p = [0x23 | (((4 - n) as u8) << 2), i[0], i[1], sub, 0, 0, 0, 0];
    for (dst, src) in p.iter_mut().skip(4).zip(data.iter().take(4)) {
        *dst = *src;
    }
    p
}

/// Payload of an initiate-upload request.
pub fn upload_request(index: u16, sub: u8) -> [u8; 8] {
    let i = index.to_le_bytes();
    [0x40, i[0], i[1], sub, 0, 0, 0, 0]
}

/// Payload of a segmented initiate-download request announcing `size` bytes.
pub fn segmented_download(index: u16, sub: u8, size: u32) -> [u8; 8] {
    let i = index.to_le_bytes();
    let s = size.to_le_bytes();
    [0x21, i[0], i[1], sub, s[0], s[1], s[2], s[3]]
}
