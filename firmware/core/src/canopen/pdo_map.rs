//! The PDO mappings in force (0x1600.., 0x1A00..), writable the CiA 301 way, and the PDO
//! configuration that 0x1010 "save" stores with the parameters.
//!
//! CiA 301 §7.5.2.36/38: to change a mapping a master makes the PDO invalid (COB-ID bit 31),
//! writes 0 to sub 0, writes the entries, then writes their number to sub 0 and makes the PDO
//! valid again. Here an entry is refused with 0x06040041 unless its object is PDO-mappable in
//! the direction (readable for a TPDO, writable for an RPDO; RPDOs may also map the CiA 301
//! dummy types 0x0002..0x0007) and the entry's length is the object's; sub 0 is refused with
//! 0x06040042 when the entries would not fit a frame (8 bytes on a classic node, 64 on an FD
//! node) or one of them is empty; writes while the PDO is valid, or to an entry while sub 0
//! is not 0, are refused with 0x06010000. A refused write changes nothing.

use super::od::{self, DataType, MAP_MAX, RPDO_COUNT, TPDO_COUNT};
use super::sdo::Abort;

const N: usize = (RPDO_COUNT + TPDO_COUNT) as usize;

/// Every PDO's mapping: RPDO `n` at `n`, TPDO `n` at `RPDO_COUNT + n`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoMaps {
    entries: [[u32; MAP_MAX]; N],
    count: [u8; N],
}

fn slot(tx: bool, n: u8) -> usize {
    usize::from(n) + if tx { usize::from(RPDO_COUNT) } else { 0 }
}

/// Bits of a mapping entry.
pub fn entry_bits(e: u32) -> usize {
    (e & 0xFF) as usize
}

/// A CiA 301 dummy entry (a data type index, sub 0): skips its bits of a received PDO.
pub fn is_dummy(e: u32) -> bool {
    (0x0002..=0x0007).contains(&(e >> 16)) && (e >> 8) & 0xFF == 0
}

impl PdoMaps {
    /// The dictionary's defaults for a node with `node_id` (RPDO1 of an FD node: its slot of
    /// the shared command frame, [`od::shared_cmd_mapping`]).
    pub fn defaults(node_id: u8, fd: bool) -> PdoMaps {
        let mut m = EMPTY;
        m.reset(node_id, fd);
        m
    }

    /// No entries anywhere (a node's mappings before its first reset of communication).
    pub const EMPTY: PdoMaps = EMPTY;

    /// Back to [`PdoMaps::defaults`], in place (the node lives in a static: a temporary
    /// copy would cost the stack its 460 bytes).
    #[inline(never)]
    pub fn reset(&mut self, node_id: u8, fd: bool) {
        self.clone_from(&DEFAULTS);
        if fd {
            if let (Some(e), Some(c)) = (self.entries.first_mut(), self.count.first_mut()) {
                if let Some(k) = od::shared_cmd_mapping(node_id, e) {
                    *c = k as u8;
                }
            }
        }
    }

    /// The entries in force of a PDO.
    pub fn get(&self, tx: bool, n: u8) -> &[u32] {
        let i = slot(tx, n);
        match (self.entries.get(i), self.count.get(i)) {
            (Some(e), Some(&c)) => e.get(..usize::from(c)).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Sub `sub` of the mapping object: sub 0 the number of entries, else the entry (also one
    /// past sub 0: written, not in force).
    pub fn read(&self, tx: bool, n: u8, sub: u8) -> u32 {
        let i = slot(tx, n);
        if sub == 0 {
            return u32::from(self.count.get(i).copied().unwrap_or(0));
        }
        self.entries.get(i).and_then(|e| e.get(usize::from(sub) - 1)).copied().unwrap_or(0)
    }

    /// Bytes the PDO's entries in force fill.
    pub fn bytes(&self, tx: bool, n: u8) -> usize {
        self.get(tx, n).iter().map(|&e| entry_bits(e)).sum::<usize>() / 8
    }

    /// A master's write to sub `sub` of PDO `n`'s mapping; `valid`: the PDO's COB-ID has bit
    /// 31 clear; `max_bytes`: what a frame holds on this bus. See the module documentation.
    pub fn write(&mut self, tx: bool, n: u8, sub: u8, v: u32, valid: bool, max_bytes: usize) -> Result<(), Abort> {
        let i = slot(tx, n);
        if valid {
            return Err(Abort::Unsupported);
        }
        let entries = self.entries.get_mut(i).ok_or(Abort::NoObject)?;
        let count = self.count.get_mut(i).ok_or(Abort::NoObject)?;
        if sub == 0 {
            let k = v as usize;
            let new = entries.get(..k).ok_or(Abort::MapLength)?;
            let bits: usize = new.iter().map(|&e| entry_bits(e)).sum();
            if bits > 8 * max_bytes || new.contains(&0) {
                return Err(Abort::MapLength);
            }
            *count = k as u8;
            return Ok(());
        }
        if *count != 0 {
            return Err(Abort::Unsupported);
        }
        // 0 clears an entry; anything else must be mappable
        if v != 0 {
            check_entry(tx, v)?;
        }
        *entries.get_mut(usize::from(sub) - 1).ok_or(Abort::NoSubIndex)? = v;
        Ok(())
    }

    /// The mapping as bytes for the store: per PDO its count, then its entries (LE).
    pub fn to_bytes(&self, out: &mut [u8; PDO_MAPS_BYTES]) {
        let mut k = 0;
        for (e, &c) in self.entries.iter().zip(&self.count) {
            for b in core::iter::once(c).chain(e.iter().flat_map(|x| x.to_le_bytes())) {
                if let Some(o) = out.get_mut(k) {
                    *o = b;
                }
                k += 1;
            }
        }
    }

    /// Take a mapping stored by [`PdoMaps::to_bytes`], in place; `false` (and nothing
    /// changed) if an entry would not be accepted now (a firmware whose dictionary changed
    /// keeps its defaults rather than map the unknown) or a PDO would exceed 64 bytes. (A
    /// mapping longer than 8 bytes is kept on a classic node as its defaults are: such a TPDO
    /// cannot be validated there.)
    #[inline(never)]
    pub fn load(&mut self, b: &[u8; PDO_MAPS_BYTES]) -> bool {
        const STRIDE: usize = 1 + 4 * MAP_MAX;
        let entry = |c: &[u8], k: usize| -> u32 {
            let mut w = [0u8; 4];
            for (d, s) in w.iter_mut().zip(c.iter().skip(1 + 4 * k)) {
                *d = *s;
            }
            u32::from_le_bytes(w)
        };
        // check everything first: a stored image is taken whole or not at all
        for (i, c) in b.chunks_exact(STRIDE).enumerate() {
            let k = usize::from(c.first().copied().unwrap_or(0));
            let tx = i >= usize::from(RPDO_COUNT);
            let bits: usize = (0..k).map(|j| entry_bits(entry(c, j))).sum();
            if k > MAP_MAX || bits > 512 || (0..k).any(|j| check_entry(tx, entry(c, j)).is_err()) {
                return false;
            }
        }
        for ((c, e), n) in b.chunks_exact(STRIDE).zip(self.entries.iter_mut()).zip(self.count.iter_mut()) {
            *n = c.first().copied().unwrap_or(0);
            for (j, d) in e.iter_mut().enumerate() {
                *d = entry(c, j);
            }
        }
        true
    }
}

const EMPTY: PdoMaps = PdoMaps { entries: [[0; MAP_MAX]; N], count: [0; N] };

/// The dictionary's mappings, built at compile time (one copy in flash): copying them costs
/// less flash than code that assembles them.
// Indexing in a const: an index out of range fails the build, never the firmware.
#[allow(clippy::indexing_slicing)]
static DEFAULTS: PdoMaps = {
    let mut m = EMPTY;
    let mut i = 0;
    while i < N {
        let fixed: &[u32] =
            if i < RPDO_COUNT as usize { od::RPDO_DEFAULTS[i] } else { od::TPDO_DEFAULTS[i - RPDO_COUNT as usize] };
        let mut k = 0;
        while k < fixed.len() && k < MAP_MAX {
            m.entries[i][k] = fixed[k];
            k += 1;
        }
        m.count[i] = k as u8;
        i += 1;
    }
    m
};

/// Bytes of [`PdoMaps::to_bytes`].
pub const PDO_MAPS_BYTES: usize = N * (1 + 4 * MAP_MAX);

/// Whether `e` may be mapped into a TPDO (`tx`) or an RPDO.
fn check_entry(tx: bool, e: u32) -> Result<(), Abort> {
    let bits = entry_bits(e);
    if !tx && is_dummy(e) {
        let size = match e >> 16 {
            0x0002 | 0x0005 => 8,
            0x0003 | 0x0006 => 16,
            _ => 32,
        };
        return if bits == size { Ok(()) } else { Err(Abort::CannotMap) };
    }
    let info = od::sub_info((e >> 16) as u16, ((e >> 8) & 0xFF) as u8).map_err(|_| Abort::CannotMap)?;
    let dir = if tx { info.access.readable() } else { info.access.writable() };
    let size = match info.dtype {
        DataType::VisibleString | DataType::Domain => None,
        t => t.size(),
    };
    if !info.pdo || !dir || size.map(|s| s * 8) != Some(bits) {
        return Err(Abort::CannotMap);
    }
    Ok(())
}
