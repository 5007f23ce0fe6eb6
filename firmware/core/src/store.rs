//! Power-loss-safe parameter store: two flash slots holding CRC'd records, sans-IO.
//!
//! The firmware's parameter task is the only owner of the flash; it hands its HAL's
//! `embedded-storage` [`NorFlash`] (a [`Region`] of the parameter pages) to a [`Store`],
//! calls [`Store::load`] at boot and drives a save with [`Store::begin_save`] and one
//! [`Store::poll`] per tick, each poll doing exactly one flash operation.
//!
//! # Why two slots (A/B) and not a log
//! A record (header + every scalar parameter + the full gravity table) is 2 568 bytes, more
//! than one 2 KiB page of the STM32G431, so a log could hold only one or two records per erase
//! anyway; an A/B pair gives the same safety with far simpler recovery. Each slot is the
//! smallest whole number of pages that holds a record (2 pages = 4 KiB on the G431, 8 KiB for
//! both, the region `memory.x` reserves). A save always goes to the slot that does **not** hold
//! the newest intact record, so until the new record is complete the old one is never touched.
//!
//! # Record format (little-endian)
//! ```text
//!  0  magic "JPRM"          4  format version u16    6  header length u16 (= 24)
//!  8  sequence u32         12  payload length u32   16  CRC-32 u32    20  reserved u32 (0)
//! 24  payload (version 1):
//!       u16 parameter count N, u16 entry size (8), u32 model-block length E (0 = none)
//!       N × { u32 name id = CRC-32 of the parameter's name, f32 value }
//!       table: u8 n_axes, u8 has_sigma, u8 A, u8 M, u16 C, u16 reserved,
//!              axis_source[A] u8, points[A] u8, grid A×M f32, torque C f32, sigma C f32
//!       (A, M, C = AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX of the firmware that wrote it)
//!       model block, only when E > 0 (E = 4 + 12·T):
//!              u8 series terms n, u8 T, u8 term size (12), u8 flags (bit 0: table is residual),
//!              T × { f32 amplitude, f32 phase, 4 × i8 multipliers }
//!       (T = series::TERMS_MAX of the writer)
//!       communication block, only when the record is longer than the above:
//!              u8 kind (1), u8 reserved (0), u16 length L (≤ COMM_MAX), L opaque bytes
//!              (the node's LSS configuration and PDO mappings: canopen::storage::CommSettings)
//! ```
//! The model block (arm gravity: the analytic series and the residual flag) was added inside
//! version 1 in the word that read 0 before: a set without a series and without a residual
//! table is written byte for byte as before, and an older firmware meets a record with the
//! block as a length mismatch ([`LayoutError::Length`]) and refuses it rather than running a
//! residual table as a torque of its own.
//! The communication block came the same way: a record without one (no stored LSS configuration
//! and default PDO mappings) is byte for byte what the store wrote before; an older firmware
//! refuses a record with one as a length mismatch. It is outside the set's CRC ([`set_crc`],
//! which names the parameter set on the bus): remapping a PDO does not rename the set.
//! The CRC (CRC-32/ISO-HDLC) covers the payload followed by header bytes 0..16; the reserved
//! word must read 0.
//!
//! # The save sequence and why a power cut cannot mix sets
//! 1. erase every page of the target slot (one page per poll);
//! 2. program the payload, 8 bytes per poll (the G4 programs double-words), in address order;
//! 3. program header bytes 16..24 (CRC), then 8..16 (sequence, length), and **last** bytes
//!    0..8 (magic, version): the record exists only once its magic is programmed.
//!
//! A cut anywhere before the last byte of step 3 leaves a slot without a complete header or
//! with a CRC that does not match: [`Store::load`] ignores it and returns the other slot's
//! record, i.e. the old set. The newer of two intact records wins by sequence number (serial
//! arithmetic, so wrap-around is harmless). A cut during an erase only damages the slot being
//! written. Known limit, as for every NOR-flash store: a cell whose programming or erase was
//! cut may read differently on a later boot; the CRC still keeps such a record out, but a
//! record that read as valid once could read as damaged later (then the older set loads, and
//! a fault is reported).
//!
//! # Firmware updates and format changes
//! Scalar values are stored with the CRC-32 of the parameter's *name*, not its index, so a
//! firmware that adds, removes or reorders parameters still reads the calibration: known names
//! are taken, new parameters get their defaults ([`LoadInfo::defaulted`]), unknown stored ones
//! are dropped ([`LoadInfo::unknown`]). **Rule for developers: a parameter whose unit or meaning
//! changes must get a new name.** The table stores its own dimensions and is copied into
//! different compile-time maxima when its used part fits. A record of a newer (or unknown)
//! format version is refused with [`LoadError::UnsupportedVersion`] and left untouched, never
//! guessed at; a later format adds a `decode_v2` and keeps `decode_v1` as its migration path.
//! Whatever was read must then pass [`params::check`] before [`Store::load`] returns it.
//!
//! # Cost per operation (STM32G431, RM0440 / DS12589)
//! A page erase takes 22 ms typical (40 ms max), a double-word program 82 µs typical (91 µs
//! max); a full save is 2 erases + 321 programs ≈ 70 ms of flash busy time. The G431 has a
//! single flash bank: **while an erase or program runs, every instruction fetch from flash
//! stalls**, so the control loop does not stall only if its interrupt handler, vector table
//! and everything it calls run from RAM (CCM SRAM); otherwise save only while the torque is
//! off (pre-operational). [`Store::poll`] itself adds a few µs of CPU work per call;
//! `begin_save` computes the CRC of the whole record once (≈ 0.1 ms). Endurance: 10 000 erase
//! cycles per page; the slots alternate, so ≈ 20 000 saves.
//!
//! RAM: the store keeps no copy of the record (≈ 50 bytes of state). `poll` re-serializes the
//! next 8 bytes from the `ParamSet` it is given; the caller passes the same set every time,
//! and if it changed the running CRC no longer matches the one computed by `begin_save`, so
//! the record is never committed ([`SaveError::SourceChanged`]) and the old set stays.

use crate::params::{self, ParamError, ParamSet, RawParams, PARAMS, PARAM_COUNT};
use crate::safety::Faults;
use crate::series::{TERMS_MAX, TERM_BYTES};
use crate::table::{AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};

// ---------------------------------------------------------------------------------------
// CRC-32/ISO-HDLC (the zlib/Ethernet CRC): reflected polynomial 0xEDB88320, init and xorout
// 0xFFFFFFFF. Nibble table: 64 bytes of flash instead of 1 KiB, speed is irrelevant here.

const CRC_POLY: u32 = 0xEDB8_8320;

// Only ever evaluated at compile time (it builds a `const`): an out-of-bounds index would be a
// build error, not a panic.
#[allow(clippy::indexing_slicing)]
const fn crc_nibble_table() -> [u32; 16] {
    let mut t = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = if c & 1 != 0 { (c >> 1) ^ CRC_POLY } else { c >> 1 };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}

const CRC_TABLE: [u32; 16] = crc_nibble_table();

/// Streaming CRC-32/ISO-HDLC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc32(u32);

impl Crc32 {
    pub const fn new() -> Self {
        Crc32(0xFFFF_FFFF)
    }

    pub fn update(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.update_byte(b);
        }
    }

    #[inline]
    fn update_byte(&mut self, b: u8) {
        let mut c = self.0 ^ u32::from(b);
        // The index is masked to 0..=15: it can never be out of bounds.
        c = (c >> 4) ^ CRC_TABLE.get((c & 0xF) as usize).copied().unwrap_or(0);
        c = (c >> 4) ^ CRC_TABLE.get((c & 0xF) as usize).copied().unwrap_or(0);
        self.0 = c;
    }

    pub const fn finish(self) -> u32 {
        !self.0
    }
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

/// CRC-32/ISO-HDLC of `bytes` (check value: `crc32(b"123456789") == 0xCBF4_3926`).
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

// ---------------------------------------------------------------------------------------
// Flash abstraction

use embedded_storage::nor_flash::ErrorType;
pub use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// What the store takes: any `embedded-storage` [`NorFlash`] (every HAL's flash driver
/// implements it): erased bytes read `0xFF`; `erase(from, to)` takes page-aligned bounds;
/// `write` takes `WRITE_SIZE`-aligned offset and length and may only program erased bytes;
/// reads are of any byte (`READ_SIZE` 1). The store owns the whole flash it is given, addressed
/// from 0; a chip's driver covers the whole chip, so the firmware hands it a [`Region`] of its
/// parameter pages.
pub trait Flash: NorFlash {}
impl<F: NorFlash> Flash for F {}

#[cfg(feature = "mock-flash")]
#[path = "store_mock.rs"]
pub mod mock;

/// A window `[base, base + len)` of a [`NorFlash`], itself a `NorFlash` addressed from 0: the
/// parameter pages of a chip's flash (memory.x's region) with no board adapter. An access
/// outside the window is refused with [`RegionError::OutOfBounds`] and touches nothing.
pub struct Region<F> {
    flash: F,
    base: u32,
    len: u32,
}

impl<F: NorFlash> Region<F> {
    /// The window of `flash` at `base`, `len` bytes (clamped to the flash's capacity).
    pub fn new(flash: F, base: u32, len: u32) -> Self {
        let cap = u32::try_from(flash.capacity()).unwrap_or(u32::MAX);
        let len = len.min(cap.saturating_sub(base));
        Region { flash, base, len }
    }

    /// Where the window sits in the flash: (base, len).
    pub fn window(&self) -> (u32, u32) {
        (self.base, self.len)
    }

    pub fn into_inner(self) -> F {
        self.flash
    }

    fn span(&self, offset: u32, len: usize) -> Result<u32, RegionError<F::Error>> {
        let len = u32::try_from(len).map_err(|_| RegionError::OutOfBounds)?;
        match offset.checked_add(len) {
            Some(end) if end <= self.len => Ok(self.base + offset),
            _ => Err(RegionError::OutOfBounds),
        }
    }
}

/// A [`Region`]'s error: outside the window, or the flash's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegionError<E> {
    OutOfBounds,
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for RegionError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RegionError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RegionError::Flash(e) => e.kind(),
        }
    }
}

impl<F: NorFlash> ErrorType for Region<F> {
    type Error = RegionError<F::Error>;
}

impl<F: NorFlash> ReadNorFlash for Region<F> {
    const READ_SIZE: usize = F::READ_SIZE;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let at = self.span(offset, bytes.len())?;
        self.flash.read(at, bytes).map_err(RegionError::Flash)
    }
    fn capacity(&self) -> usize {
        self.len as usize
    }
}

impl<F: NorFlash> NorFlash for Region<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let a = self.span(from, 0)?;
        let b = self.span(to, 0)?;
        self.flash.erase(a, b).map_err(RegionError::Flash)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let at = self.span(offset, bytes.len())?;
        self.flash.write(at, bytes).map_err(RegionError::Flash)
    }
}

// ---------------------------------------------------------------------------------------
// Record layout

/// Record magic, the first bytes of every committed record.
pub const MAGIC: [u8; 4] = *b"JPRM";
/// Payload format this firmware writes and reads.
pub const FORMAT_VERSION: u16 = 1;
/// Header bytes in front of the payload.
pub const HEADER_LEN: usize = 24;
/// Bytes of one scalar entry (name id + value).
const ENTRY_LEN: usize = 8;
/// Program unit of the store.
const UNIT: usize = 8;

const PARAMS_OFF: usize = 8;
const TABLE_OFF: usize = PARAMS_OFF + PARAM_COUNT * ENTRY_LEN;
const TABLE_HDR: usize = 8;
const SOURCE_OFF: usize = TABLE_OFF + TABLE_HDR;
const POINTS_OFF: usize = SOURCE_OFF + AXES_MAX;
const GRID_OFF: usize = POINTS_OFF + AXES_MAX;
const TORQUE_OFF: usize = GRID_OFF + 4 * AXES_MAX * AXIS_POINTS_MAX;
const SIGMA_OFF: usize = TORQUE_OFF + 4 * CELLS_MAX;

/// Payload bytes this firmware writes for a set without a model block.
pub const PAYLOAD_LEN: usize = SIGMA_OFF + 4 * CELLS_MAX;
/// Record bytes (header + payload) without a model block, rounded up to the program unit.
pub const RECORD_LEN: usize = (HEADER_LEN + PAYLOAD_LEN).div_ceil(UNIT) * UNIT;
/// Bytes of the model block (series and residual flag) when present.
pub const MODEL_BLOCK_LEN: usize = 4 + TERM_BYTES * TERMS_MAX;
/// Most bytes of a communication block's contents.
pub const COMM_MAX: usize = 512;
/// The communication block's own header (kind, reserved, length).
const COMM_HDR: usize = 4;
/// The longest record (with the model and communication blocks): what a slot must hold.
pub const RECORD_MAX_LEN: usize =
    (HEADER_LEN + PAYLOAD_LEN + MODEL_BLOCK_LEN + COMM_HDR + COMM_MAX).div_ceil(UNIT) * UNIT;

/// Byte `j` of the communication block holding `comm` (header, then the bytes).
fn comm_byte(comm: &[u8], j: usize) -> u8 {
    let l = comm.len() as u16;
    match j {
        0 => 1,
        1 => 0,
        2 => (l & 0xFF) as u8,
        3 => (l >> 8) as u8,
        _ => comm.get(j - COMM_HDR).copied().unwrap_or(0xFF),
    }
}

/// Bytes of the communication block holding `comm` (none when `comm` is empty).
fn comm_block_len(comm: &[u8]) -> usize {
    if comm.is_empty() {
        0
    } else {
        COMM_HDR + comm.len()
    }
}

/// Byte `i` of the record payload of `raw` followed by the communication block of `comm`.
fn record_byte(raw: &RawParams, comm: &[u8], i: usize) -> u8 {
    let set = payload_len(raw);
    if i < set {
        payload_byte(raw, i)
    } else {
        comm_byte(comm, i - set)
    }
}

/// The communication block given to [`Store::set_comm`] is longer than [`COMM_MAX`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CommTooLong;

/// Model-block bytes of `raw`: present only when it has a series or a residual table.
fn model_block_len(raw: &RawParams) -> usize {
    if raw.series.n_terms > 0 || raw.table.residual {
        MODEL_BLOCK_LEN
    } else {
        0
    }
}

/// Payload bytes of `raw`'s record.
fn payload_len(raw: &RawParams) -> usize {
    PAYLOAD_LEN + model_block_len(raw)
}

/// CRC-32 of a parameter set: over its record payload (the bytes a save writes), so the host
/// and the joint compute the same number from the same set. Names a set on the bus (0x2204)
/// and in a commit (0x2205).
pub fn set_crc(raw: &RawParams) -> u32 {
    let mut c = Crc32::new();
    for i in 0..payload_len(raw) {
        c.update(&[payload_byte(raw, i)]);
    }
    c.finish()
}

/// The id a parameter is stored under: CRC-32 of its name.
pub fn name_id(name: &str) -> u32 {
    crc32(name.as_bytes())
}

fn le_byte(word: u32, i: usize) -> u8 {
    word.to_le_bytes().get(i).copied().unwrap_or(0xFF)
}

/// Byte `i` of the version-1 payload of `raw`. Computed on demand, so a save needs no buffer.
fn payload_byte(raw: &RawParams, i: usize) -> u8 {
    let t = &raw.table;
    if i < PARAMS_OFF {
        let e = model_block_len(raw) as u16;
        let head: [u8; 8] = [
            (PARAM_COUNT & 0xFF) as u8,
            (PARAM_COUNT >> 8) as u8,
            ENTRY_LEN as u8,
            0,
            (e & 0xFF) as u8,
            (e >> 8) as u8,
            0,
            0,
        ];
        head.get(i).copied().unwrap_or(0)
    } else if i < TABLE_OFF {
        let e = (i - PARAMS_OFF) / ENTRY_LEN;
        let b = (i - PARAMS_OFF) % ENTRY_LEN;
        if b < 4 {
            let id = PARAMS.get(e).map(|d| name_id(d.name)).unwrap_or(0);
            le_byte(id, b)
        } else {
            let v = raw.values.get(e).copied().unwrap_or(f32::NAN);
            le_byte(v.to_bits(), b - 4)
        }
    } else if i < SOURCE_OFF {
        let head: [u8; 8] = [
            t.n_axes,
            u8::from(t.has_sigma),
            AXES_MAX as u8,
            AXIS_POINTS_MAX as u8,
            (CELLS_MAX & 0xFF) as u8,
            (CELLS_MAX >> 8) as u8,
            0,
            0,
        ];
        head.get(i - TABLE_OFF).copied().unwrap_or(0)
    } else if i < POINTS_OFF {
        t.axis_source.get(i - SOURCE_OFF).copied().unwrap_or(0)
    } else if i < GRID_OFF {
        t.points.get(i - POINTS_OFF).copied().unwrap_or(0)
    } else if i < TORQUE_OFF {
        let k = (i - GRID_OFF) / 4;
        let v = t.grid.get(k / AXIS_POINTS_MAX).and_then(|row| row.get(k % AXIS_POINTS_MAX)).copied().unwrap_or(0.0);
        le_byte(v.to_bits(), (i - GRID_OFF) % 4)
    } else if i < SIGMA_OFF {
        let v = t.torque.get((i - TORQUE_OFF) / 4).copied().unwrap_or(0.0);
        le_byte(v.to_bits(), (i - TORQUE_OFF) % 4)
    } else if i < PAYLOAD_LEN {
        let v = t.sigma.get((i - SIGMA_OFF) / 4).copied().unwrap_or(0.0);
        le_byte(v.to_bits(), (i - SIGMA_OFF) % 4)
    } else if i < payload_len(raw) {
        let j = i - PAYLOAD_LEN;
        match j {
            0 => raw.series.n_terms,
            1 => TERMS_MAX as u8,
            2 => TERM_BYTES as u8,
            3 => u8::from(t.residual),
            _ => raw.series.term_bytes((j - 4) / TERM_BYTES).get((j - 4) % TERM_BYTES).copied().unwrap_or(0),
        }
    } else {
        // Padding up to the program unit: left erased.
        0xFF
    }
}

/// Header bytes 0..16 (the part the CRC covers) for `seq` and a payload of `len` bytes.
fn header16(seq: u32, len: usize) -> [u8; 16] {
    let mut h = [0u8; 16];
    let fields: [(usize, &[u8]); 5] = [
        (0, &MAGIC),
        (4, &FORMAT_VERSION.to_le_bytes()),
        (6, &(HEADER_LEN as u16).to_le_bytes()),
        (8, &seq.to_le_bytes()),
        (12, &(len as u32).to_le_bytes()),
    ];
    for (off, bytes) in fields {
        if let Some(dst) = h.get_mut(off..off + bytes.len()) {
            dst.copy_from_slice(bytes);
        }
    }
    h
}

/// `a` is newer than `b` in serial-number arithmetic (RFC 1982).
fn seq_newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

// ---------------------------------------------------------------------------------------
// Results and errors

/// What a slot holds, as found by a scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SlotState {
    /// Every byte erased.
    Blank,
    /// An intact record (CRC matches). Its payload may still be of a format this firmware
    /// refuses.
    Valid { seq: u32, version: u16 },
    /// Not blank, but no record was ever committed here: an interrupted save (or foreign data
    /// that does not start with the magic).
    Uncommitted,
    /// Starts with the magic but the header or CRC is wrong: a committed record was damaged
    /// (or the cut hit the final commit write).
    Damaged,
}

/// Why a stored record's payload could not be read, though its CRC matched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LayoutError {
    /// The payload is shorter than its own structure says.
    Truncated { len: u32 },
    /// Scalar entries of an unknown size.
    EntrySize { found: u16 },
    /// The same parameter stored twice (entry index given).
    DuplicateParam { entry: u16 },
    /// `has_sigma` is neither 0 nor 1.
    BadFlag { value: u8 },
    /// The payload length does not match the stored table dimensions.
    Length { expected: u32, found: u32 },
    /// The table's used part exceeds its own stored dimensions.
    TableInconsistent,
    /// The stored table does not fit this firmware's table limits.
    TableTooLarge { n_axes: u8, points: u8, cells: u32 },
    /// The model block's own sizes disagree with its length, or it holds more series terms
    /// than it has room for.
    ModelBlock,
    /// The stored series has more terms than this firmware's series can hold.
    SeriesTooLarge { n_terms: u8 },
}

/// Why [`Store::load`] returned no parameter set. The firmware then runs on defaults and
/// raises [`LoadError::fault`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoadError<E> {
    /// The flash driver failed.
    Flash(E),
    /// Both slots erased: a fresh board, nothing saved yet. Not a fault.
    Blank,
    /// No intact record, and the region is not blank (foreign data, damage, or a first save
    /// that was cut).
    Corrupt { a: SlotState, b: SlotState },
    /// An intact record of a format version this firmware cannot read (written by a newer
    /// firmware). It is left in place, so going back to that firmware finds it again.
    UnsupportedVersion { found: u16, supported: u16, seq: u32 },
    /// An intact record whose payload structure cannot be read into this firmware's types.
    Layout { error: LayoutError, seq: u32 },
    /// The stored set was read but fails `params::check()`.
    Rejected { error: ParamError, seq: u32 },
}

impl<E> LoadError<E> {
    /// The fault to latch for this outcome ([`Faults::NONE`] for a blank store).
    pub fn fault(&self) -> Faults {
        match self {
            LoadError::Blank => Faults::NONE,
            LoadError::Flash(_) | LoadError::Corrupt { .. } => Faults::PARAMS_CORRUPT,
            LoadError::UnsupportedVersion { .. } | LoadError::Layout { .. } => Faults::PARAMS_VERSION,
            LoadError::Rejected { .. } => Faults::PARAMS_REJECTED,
        }
    }
}

/// Details of a successful load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadInfo {
    /// Slot the set came from (0 = A, 1 = B).
    pub slot: u8,
    pub seq: u32,
    pub version: u16,
    /// Parameters this firmware has but the record lacked: set to their defaults.
    pub defaulted: u8,
    /// Parameters in the record this firmware does not know: dropped.
    pub unknown: u8,
    /// The table was copied from different compile-time dimensions.
    pub table_migrated: bool,
    /// State of the other slot.
    pub other: SlotState,
}

impl LoadInfo {
    /// [`Faults::PARAMS_CORRUPT`] when the other slot holds a damaged committed record (flash
    /// going bad, or the set loaded may be older than the newest one saved); otherwise none.
    /// An uncommitted other slot is the normal trace of a cut save and is not a fault.
    pub fn fault(&self) -> Faults {
        if self.other == SlotState::Damaged {
            Faults::PARAMS_CORRUPT
        } else {
            Faults::NONE
        }
    }
}

/// A loaded, checked parameter set.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    pub params: ParamSet,
    pub info: LoadInfo,
}

/// Why a store could not be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeometryError {
    /// `WRITE_SIZE` does not divide 8 or `ERASE_SIZE` is not a multiple of 8.
    Granularity { write_size: u32, erase_size: u32 },
    /// The region cannot hold two slots.
    RegionTooSmall { need: u32, have: u32 },
}

/// Why a save stopped. In every case the previously stored set is intact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SaveError<E> {
    /// The flash driver failed; the save is abandoned.
    Flash(E),
    /// The `RawParams` passed to `poll` differ from the one given to `begin_save`; the record
    /// was not committed.
    SourceChanged,
}

/// Progress of a save.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SaveProgress {
    /// No save in progress.
    Idle,
    /// `done` of `total` flash operations finished.
    Working { done: u16, total: u16 },
    /// The record is committed.
    Done { slot: u8, seq: u32 },
}

// ---------------------------------------------------------------------------------------
// The store

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Newest {
    /// Not scanned yet.
    Unknown,
    /// Scanned: no intact record.
    None,
    Some {
        slot: u8,
        seq: u32,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Idle,
    Erase {
        page: u32,
    },
    Payload {
        off: u32,
    },
    /// Header units left to program: 2 → bytes 16..24, 1 → 8..16, 0 → 0..8 (commit).
    Header {
        unit: u8,
    },
}

#[derive(Clone, Copy, Debug)]
struct Job {
    slot: u8,
    seq: u32,
    crc: u32,
    running: Crc32,
    done: u16,
    /// payload bytes of the record being saved (the set's, then the communication block)
    payload: u32,
}

/// The parameter store over a flash region.
pub struct Store<F: Flash> {
    flash: F,
    slot_len: u32,
    pages_per_slot: u32,
    newest: Newest,
    phase: Phase,
    job: Job,
    /// the communication block: of the newest record after [`Store::load`], written with
    /// every save (see [`Store::set_comm`])
    comm: [u8; COMM_MAX],
    comm_len: u16,
}

/// Bytes read per flash read while scanning.
const SCAN_CHUNK: usize = 64;

impl<F: Flash> Store<F> {
    /// A store over the whole region `flash` exposes. Slot A is the first half of the region,
    /// slot B the second: the layout depends on the region (memory.x), never on this build's
    /// record size, so a firmware update with a different record length still finds both
    /// slots where the old build wrote them. A save erases only the pages its record needs.
    pub fn new(flash: F) -> Result<Self, GeometryError> {
        let ws = F::WRITE_SIZE;
        let es = F::ERASE_SIZE;
        // `%` rather than `is_multiple_of` (Rust 1.87): the workspace declares 1.85.
        #[allow(clippy::manual_is_multiple_of)]
        // Records are read at any byte (READ_SIZE 1, as every MCU's flash reads).
        let bad = F::READ_SIZE != 1 || ws == 0 || UNIT % ws != 0 || es == 0 || es % UNIT != 0;
        if bad {
            return Err(GeometryError::Granularity { write_size: ws as u32, erase_size: es as u32 });
        }
        let pages = RECORD_MAX_LEN.div_ceil(es);
        let have = flash.capacity();
        let slot_len = have / 2 / es * es;
        if slot_len < pages * es {
            return Err(GeometryError::RegionTooSmall {
                need: (2 * pages * es) as u32,
                have: u32::try_from(have).unwrap_or(u32::MAX),
            });
        }
        Ok(Store {
            flash,
            slot_len: slot_len as u32,
            pages_per_slot: pages as u32,
            newest: Newest::Unknown,
            phase: Phase::Idle,
            job: Job { slot: 0, seq: 0, crc: 0, running: Crc32::new(), done: 0, payload: PAYLOAD_LEN as u32 },
            comm: [0xFF; COMM_MAX],
            comm_len: 0,
        })
    }

    /// The communication block every following save writes with its set (empty: none, and
    /// the record is byte for byte a set-only one). Not part of the set's CRC.
    pub fn set_comm(&mut self, bytes: &[u8]) -> Result<(), CommTooLong> {
        let dst = self.comm.get_mut(..bytes.len()).ok_or(CommTooLong)?;
        dst.copy_from_slice(bytes);
        self.comm_len = bytes.len() as u16;
        Ok(())
    }

    /// The communication block: the newest record's after [`Store::load`], or what
    /// [`Store::set_comm`] gave since.
    pub fn comm(&self) -> &[u8] {
        self.comm.get(..usize::from(self.comm_len)).unwrap_or(&[])
    }

    /// Bytes of flash the two slots use (the region may be larger).
    pub fn used_len(&self) -> u32 {
        2 * self.slot_len
    }

    /// Give the flash back (e.g. to simulate a reboot in tests).
    pub fn into_flash(self) -> F {
        self.flash
    }

    fn base(&self, slot: u8) -> u32 {
        u32::from(slot) * self.slot_len
    }

    /// Classify one slot.
    fn scan_slot(&mut self, slot: u8) -> Result<SlotState, F::Error> {
        let base = self.base(slot);
        let mut h = [0u8; HEADER_LEN];
        self.flash.read(base, &mut h)?;
        let magic_ok = h.get(0..4) == Some(&MAGIC[..]);
        if !magic_ok {
            return Ok(if self.slot_blank(base)? { SlotState::Blank } else { SlotState::Uncommitted });
        }
        let u16_at = |o: usize| u16::from_le_bytes([byte(&h, o), byte(&h, o + 1)]);
        let u32_at = |o: usize| u32::from_le_bytes([byte(&h, o), byte(&h, o + 1), byte(&h, o + 2), byte(&h, o + 3)]);
        let version = u16_at(4);
        let header_len = u16_at(6);
        let seq = u32_at(8);
        let len = u32_at(12);
        let crc = u32_at(16);
        let reserved = u32_at(20);
        if usize::from(header_len) != HEADER_LEN || reserved != 0 || len > self.slot_len - HEADER_LEN as u32 {
            return Ok(SlotState::Damaged);
        }
        let mut c = Crc32::new();
        let mut buf = [0u8; SCAN_CHUNK];
        let mut off = 0u32;
        while off < len {
            let n = (len - off).min(SCAN_CHUNK as u32) as usize;
            let part = buf.get_mut(..n).unwrap_or(&mut []);
            self.flash.read(base + HEADER_LEN as u32 + off, part)?;
            c.update(part);
            off += n as u32;
        }
        c.update(h.get(..16).unwrap_or(&[]));
        Ok(if c.finish() == crc { SlotState::Valid { seq, version } } else { SlotState::Damaged })
    }

    fn slot_blank(&mut self, base: u32) -> Result<bool, F::Error> {
        let mut buf = [0u8; SCAN_CHUNK];
        let mut off = 0;
        while off < self.slot_len {
            let n = (self.slot_len - off).min(SCAN_CHUNK as u32) as usize;
            let part = buf.get_mut(..n).unwrap_or(&mut []);
            self.flash.read(base + off, part)?;
            if part.iter().any(|&b| b != 0xFF) {
                return Ok(false);
            }
            off += n as u32;
        }
        Ok(true)
    }

    /// Scan both slots: their states and the newest intact one.
    pub fn scan(&mut self) -> Result<[SlotState; 2], F::Error> {
        let a = self.scan_slot(0)?;
        let b = self.scan_slot(1)?;
        self.newest = match (a, b) {
            (SlotState::Valid { seq: sa, .. }, SlotState::Valid { seq: sb, .. }) => {
                if seq_newer(sb, sa) {
                    Newest::Some { slot: 1, seq: sb }
                } else {
                    Newest::Some { slot: 0, seq: sa }
                }
            }
            (SlotState::Valid { seq, .. }, _) => Newest::Some { slot: 0, seq },
            (_, SlotState::Valid { seq, .. }) => Newest::Some { slot: 1, seq },
            _ => Newest::None,
        };
        Ok([a, b])
    }

    /// Read the newest intact record, decode it (migrating if needed) and check it. Call once
    /// at boot, before any save. On `Err`, run on `ParamSet::defaults()` and latch
    /// `err.fault()`; on `Ok`, also latch `info.fault()`. See also [`Store::load_or_defaults`].
    pub fn load(&mut self) -> Result<Loaded, LoadError<F::Error>> {
        let states = self.scan().map_err(LoadError::Flash)?;
        let (slot, seq) = match self.newest {
            Newest::Some { slot, seq } => (slot, seq),
            _ => {
                let [a, b] = states;
                return Err(if a == SlotState::Blank && b == SlotState::Blank {
                    LoadError::Blank
                } else {
                    LoadError::Corrupt { a, b }
                });
            }
        };
        let version = match states.get(usize::from(slot)) {
            Some(SlotState::Valid { version, .. }) => *version,
            _ => 0,
        };
        let other = states.get(usize::from(1 - slot)).copied().unwrap_or(SlotState::Blank);
        let decoded = match version {
            1 => self.decode_v1(self.base(slot) + HEADER_LEN as u32)?,
            found => return Err(LoadError::UnsupportedVersion { found, supported: FORMAT_VERSION, seq }),
        };
        let (raw, defaulted, unknown, table_migrated) = match decoded {
            Ok(d) => d,
            Err(error) => return Err(LoadError::Layout { error, seq }),
        };
        let params = params::check(&raw).map_err(|error| LoadError::Rejected { error, seq })?;
        Ok(Loaded { params, info: LoadInfo { slot, seq, version, defaulted, unknown, table_migrated, other } })
    }

    /// [`Store::load`] for the common boot path: the set to run and the faults to latch.
    pub fn load_or_defaults(&mut self) -> (ParamSet, Faults) {
        match self.load() {
            Ok(l) => {
                let f = l.info.fault();
                (l.params, f)
            }
            Err(e) => (ParamSet::defaults(), e.fault()),
        }
    }

    fn read_bytes<const N: usize>(&mut self, at: u32) -> Result<[u8; N], LoadError<F::Error>> {
        let mut b = [0u8; N];
        self.flash.read(at, &mut b).map_err(LoadError::Flash)?;
        Ok(b)
    }

    fn read_f32(&mut self, at: u32) -> Result<f32, LoadError<F::Error>> {
        Ok(f32::from_le_bytes(self.read_bytes::<4>(at)?))
    }

    /// Decode a version-1 payload starting at `p` (its CRC already matched). Outer `Err`:
    /// flash failure; inner `Err`: structure that cannot be read into this firmware's types.
    #[allow(clippy::type_complexity)]
    fn decode_v1(&mut self, p: u32) -> Result<Result<(RawParams, u8, u8, bool), LayoutError>, LoadError<F::Error>> {
        let len = u32::from_le_bytes(self.read_bytes::<4>(p - HEADER_LEN as u32 + 12)?);
        let head = self.read_bytes::<8>(p)?;
        let n = usize::from(u16::from_le_bytes([byte(&head, 0), byte(&head, 1)]));
        let entry = u16::from_le_bytes([byte(&head, 2), byte(&head, 3)]);
        let block = u32::from_le_bytes([byte(&head, 4), byte(&head, 5), byte(&head, 6), byte(&head, 7)]) as usize;
        if usize::from(entry) != ENTRY_LEN {
            return Ok(Err(LayoutError::EntrySize { found: entry }));
        }
        let table_off = PARAMS_OFF + n * ENTRY_LEN;
        if (table_off + TABLE_HDR) as u32 > len {
            return Ok(Err(LayoutError::Truncated { len }));
        }

        let mut ids = [0u32; PARAM_COUNT];
        for (id, d) in ids.iter_mut().zip(PARAMS.iter()) {
            *id = name_id(d.name);
        }
        let mut raw = RawParams::defaults();
        let mut seen = [false; PARAM_COUNT];
        let mut unknown: u8 = 0;
        for e in 0..n {
            let ent = self.read_bytes::<8>(p + (PARAMS_OFF + e * ENTRY_LEN) as u32)?;
            let id = u32::from_le_bytes([byte(&ent, 0), byte(&ent, 1), byte(&ent, 2), byte(&ent, 3)]);
            let v = f32::from_le_bytes([byte(&ent, 4), byte(&ent, 5), byte(&ent, 6), byte(&ent, 7)]);
            match ids.iter().position(|&x| x == id) {
                Some(j) => {
                    if seen.get(j).copied().unwrap_or(true) {
                        return Ok(Err(LayoutError::DuplicateParam { entry: e as u16 }));
                    }
                    if let (Some(s), Some(slot)) = (seen.get_mut(j), raw.values.get_mut(j)) {
                        *s = true;
                        *slot = v;
                    }
                }
                None => unknown = unknown.saturating_add(1),
            }
        }
        let defaulted = seen.iter().filter(|s| !**s).count() as u8;

        // Table with the writer's dimensions A, M, C.
        let th = self.read_bytes::<8>(p + table_off as u32)?;
        let n_axes = byte(&th, 0);
        let has_sigma = match byte(&th, 1) {
            0 => false,
            1 => true,
            value => return Ok(Err(LayoutError::BadFlag { value })),
        };
        let a_max = usize::from(byte(&th, 2));
        let m_max = usize::from(byte(&th, 3));
        let c_max = usize::from(u16::from_le_bytes([byte(&th, 4), byte(&th, 5)]));
        let src_off = table_off + TABLE_HDR;
        let pts_off = src_off + a_max;
        let grid_off = pts_off + a_max;
        let torque_off = grid_off + 4 * a_max * m_max;
        let sigma_off = torque_off + 4 * c_max;
        let block_off = sigma_off + 4 * c_max;
        let expected = block_off.saturating_add(block);
        // A communication block after the set: its own header says how long it is.
        let mut comm_len = 0usize;
        if (expected + COMM_HDR) as u32 <= len {
            let h = self.read_bytes::<4>(p + expected as u32)?;
            let l = usize::from(u16::from_le_bytes([byte(&h, 2), byte(&h, 3)]));
            if byte(&h, 0) == 1 && l <= COMM_MAX && (expected + COMM_HDR + l) as u32 == len {
                comm_len = l;
            }
        }
        let full = expected + if comm_len > 0 { COMM_HDR + comm_len } else { 0 };
        if full as u32 != len {
            return Ok(Err(LayoutError::Length { expected: expected as u32, found: len }));
        }
        if comm_len > 0 {
            let at = p + (expected + COMM_HDR) as u32;
            let dst = self.comm.get_mut(..comm_len).unwrap_or(&mut []);
            self.flash.read(at, dst).map_err(LoadError::Flash)?;
        }
        self.comm_len = comm_len as u16;
        let mut stored_points = [0u8; 256];
        let mut src = [0u8; 256];
        for a in 0..a_max {
            if let Some(s) = src.get_mut(a) {
                let [v] = self.read_bytes::<1>(p + (src_off + a) as u32)?;
                *s = v;
            }
            if let Some(s) = stored_points.get_mut(a) {
                let [v] = self.read_bytes::<1>(p + (pts_off + a) as u32)?;
                *s = v;
            }
        }
        // Used part, in the writer's own terms.
        let used_axes = usize::from(n_axes);
        let mut cells: u32 = if used_axes == 0 { 0 } else { 1 };
        let mut max_points = 0u8;
        if used_axes > a_max {
            return Ok(Err(LayoutError::TableInconsistent));
        }
        for &pts in stored_points.iter().take(used_axes) {
            if usize::from(pts) > m_max {
                return Ok(Err(LayoutError::TableInconsistent));
            }
            cells = cells.saturating_mul(u32::from(pts));
            max_points = max_points.max(pts);
        }
        if cells as usize > c_max {
            return Ok(Err(LayoutError::TableInconsistent));
        }
        if used_axes > AXES_MAX || usize::from(max_points) > AXIS_POINTS_MAX || cells as usize > CELLS_MAX {
            return Ok(Err(LayoutError::TableTooLarge { n_axes, points: max_points, cells }));
        }
        // Copy the overlap of the writer's and this firmware's dimensions: all of it when they
        // agree (exact round trip), at least the used part otherwise (checked just above).
        let t = &mut raw.table;
        t.n_axes = n_axes;
        t.has_sigma = has_sigma;
        for a in 0..a_max.min(AXES_MAX) {
            if let (Some(d), Some(s)) = (t.axis_source.get_mut(a), src.get(a)) {
                *d = *s;
            }
            if let (Some(d), Some(s)) = (t.points.get_mut(a), stored_points.get(a)) {
                *d = *s;
            }
        }
        for a in 0..a_max.min(AXES_MAX) {
            for i in 0..m_max.min(AXIS_POINTS_MAX) {
                let v = self.read_f32(p + (grid_off + 4 * (a * m_max + i)) as u32)?;
                if let Some(d) = t.grid.get_mut(a).and_then(|r| r.get_mut(i)) {
                    *d = v;
                }
            }
        }
        for c in 0..c_max.min(CELLS_MAX) {
            let tq = self.read_f32(p + (torque_off + 4 * c) as u32)?;
            let sg = self.read_f32(p + (sigma_off + 4 * c) as u32)?;
            if let (Some(dt), Some(ds)) = (t.torque.get_mut(c), t.sigma.get_mut(c)) {
                *dt = tq;
                *ds = sg;
            }
        }
        if block > 0 {
            let h = self.read_bytes::<4>(p + block_off as u32)?;
            let (n_terms, t_max, size, flags) = (byte(&h, 0), usize::from(byte(&h, 1)), byte(&h, 2), byte(&h, 3));
            if usize::from(size) != TERM_BYTES
                || block != 4 + TERM_BYTES * t_max
                || usize::from(n_terms) > t_max
                || flags > 1
            {
                return Ok(Err(LayoutError::ModelBlock));
            }
            if usize::from(n_terms) > TERMS_MAX {
                return Ok(Err(LayoutError::SeriesTooLarge { n_terms }));
            }
            raw.table.residual = flags == 1;
            raw.series.n_terms = n_terms;
            for k in 0..t_max.min(TERMS_MAX) {
                let b = self.read_bytes::<TERM_BYTES>(p + (block_off + 4 + TERM_BYTES * k) as u32)?;
                raw.series.set_term_bytes(k, &b);
            }
        }
        let migrated = (a_max, m_max, c_max) != (AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX);
        Ok(Ok((raw, defaulted, unknown, migrated)))
    }

    /// Start saving `set` (normally the set just put in force: only validated sets are ever
    /// persisted). Picks the slot not holding the newest intact record (scanning first if
    /// `load` was not called), computes the record's CRC, and restarts any save in progress.
    /// Then call [`Store::poll`] with the same set until it returns `Done`.
    pub fn begin_save(&mut self, set: &ParamSet) -> Result<(), SaveError<F::Error>> {
        let raw = set.raw();
        self.phase = Phase::Idle;
        if self.newest == Newest::Unknown {
            self.scan().map_err(SaveError::Flash)?;
        }
        let (slot, seq) = match self.newest {
            Newest::Some { slot, seq } => (1 - slot, seq.wrapping_add(1)),
            _ => (0, 1),
        };
        let comm = self.comm();
        let len = payload_len(raw) + comm_block_len(comm);
        let mut c = Crc32::new();
        for i in 0..len {
            c.update_byte(record_byte(raw, comm, i));
        }
        c.update(&header16(seq, len));
        self.job = Job { slot, seq, crc: c.finish(), running: Crc32::new(), done: 0, payload: len as u32 };
        self.phase = Phase::Erase { page: 0 };
        Ok(())
    }

    /// Pages the save in progress erases: those its record needs (a slot has room for the
    /// longest record; what lies past a shorter one is never read).
    fn job_pages(&self) -> u32 {
        let record = HEADER_LEN + self.job.payload as usize;
        (record.div_ceil(F::ERASE_SIZE) as u32).clamp(1, self.pages_per_slot)
    }

    /// A save is in progress.
    pub fn is_saving(&self) -> bool {
        self.phase != Phase::Idle
    }

    /// Abandon a save in progress; the stored sets stay as they are (the target slot may be
    /// left uncommitted, which `load` ignores).
    pub fn abort_save(&mut self) {
        self.phase = Phase::Idle;
    }

    /// Flash operations in one save (erases + programs): of the save in progress, else of a
    /// record without a model block.
    pub fn ops_per_save(&self) -> u16 {
        let record = (HEADER_LEN + self.job.payload as usize).div_ceil(UNIT) * UNIT;
        (self.job_pages() as usize + record / UNIT) as u16
    }

    /// Do the next flash operation of the save started by `begin_save` (one page erase or one
    /// 8-byte program). `set` must be the set given to `begin_save`.
    pub fn poll(&mut self, set: &ParamSet) -> Result<SaveProgress, SaveError<F::Error>> {
        let raw = set.raw();
        let base = self.base(self.job.slot);
        let total = self.ops_per_save();
        let r = self.step(raw, base);
        match r {
            Ok(Some(done)) => Ok(done),
            Ok(None) => {
                self.job.done = self.job.done.saturating_add(1);
                Ok(SaveProgress::Working { done: self.job.done, total })
            }
            Err(e) => {
                // The target slot is not the newest intact one, so abandoning is always safe.
                self.phase = Phase::Idle;
                Err(e)
            }
        }
    }

    fn step(&mut self, raw: &RawParams, base: u32) -> Result<Option<SaveProgress>, SaveError<F::Error>> {
        match self.phase {
            Phase::Idle => Ok(Some(SaveProgress::Idle)),
            Phase::Erase { page } => {
                let es = F::ERASE_SIZE as u32;
                let from = base + page * es;
                self.flash.erase(from, from + es).map_err(SaveError::Flash)?;
                self.phase = if page + 1 < self.job_pages() {
                    Phase::Erase { page: page + 1 }
                } else {
                    Phase::Payload { off: 0 }
                };
                Ok(None)
            }
            Phase::Payload { off } => {
                let mut unit = [0xFFu8; UNIT];
                let len = self.job.payload as usize;
                for (k, b) in unit.iter_mut().enumerate() {
                    let i = off as usize + k;
                    // Past the job's length: padding, left erased (a set that grew a model
                    // block since begin_save fails the CRC check below anyway).
                    let comm = self.comm.get(..usize::from(self.comm_len)).unwrap_or(&[]);
                    *b = if i < len { record_byte(raw, comm, i) } else { 0xFF };
                    if i < len {
                        self.job.running.update_byte(*b);
                    }
                }
                self.program(base + HEADER_LEN as u32 + off, &unit)?;
                let next = off + UNIT as u32;
                let record = (HEADER_LEN + len).div_ceil(UNIT) * UNIT;
                self.phase = if (next as usize) < record - HEADER_LEN {
                    Phase::Payload { off: next }
                } else {
                    Phase::Header { unit: 2 }
                };
                Ok(None)
            }
            Phase::Header { unit } => {
                let h = header16(self.job.seq, self.job.payload as usize);
                let mut w = [0u8; UNIT];
                match unit {
                    2 => {
                        // Last chance to notice a source that changed under us: nothing of
                        // the header is programmed yet, so the record stays uncommitted.
                        let mut c = self.job.running;
                        c.update(&h);
                        if c.finish() != self.job.crc {
                            self.phase = Phase::Idle;
                            return Err(SaveError::SourceChanged);
                        }
                        if let Some(d) = w.get_mut(..4) {
                            d.copy_from_slice(&self.job.crc.to_le_bytes());
                        }
                        self.program(base + 16, &w)?;
                        self.phase = Phase::Header { unit: 1 };
                        Ok(None)
                    }
                    1 => {
                        w.copy_from_slice(h.get(8..16).unwrap_or(&[0; 8]));
                        self.program(base + 8, &w)?;
                        self.phase = Phase::Header { unit: 0 };
                        Ok(None)
                    }
                    _ => {
                        w.copy_from_slice(h.get(0..8).unwrap_or(&[0; 8]));
                        self.program(base, &w)?;
                        self.phase = Phase::Idle;
                        self.newest = Newest::Some { slot: self.job.slot, seq: self.job.seq };
                        Ok(Some(SaveProgress::Done { slot: self.job.slot, seq: self.job.seq }))
                    }
                }
            }
        }
    }

    /// Program one 8-byte unit in `WRITE_SIZE` pieces.
    fn program(&mut self, at: u32, unit: &[u8; UNIT]) -> Result<(), SaveError<F::Error>> {
        for (k, piece) in unit.chunks(F::WRITE_SIZE).enumerate() {
            self.flash.write(at + (k * F::WRITE_SIZE) as u32, piece).map_err(SaveError::Flash)?;
        }
        Ok(())
    }

    /// Run a whole save at once (boot-time or test use; blocks for ~70 ms of flash time on the
    /// G431).
    pub fn save_blocking(&mut self, set: &ParamSet) -> Result<(u8, u32), SaveError<F::Error>> {
        self.begin_save(set)?;
        loop {
            if let SaveProgress::Done { slot, seq } = self.poll(set)? {
                return Ok((slot, seq));
            }
            if !self.is_saving() {
                // Cannot happen (poll only goes idle through Done or an error), but never spin.
                return Err(SaveError::SourceChanged);
            }
        }
    }
}

fn byte(b: &[u8], i: usize) -> u8 {
    b.get(i).copied().unwrap_or(0)
}
