//! [`ParamStorage`] over the core's power-loss-safe flash store ([`crate::store::Store`]), so
//! `save` (0x1010) writes a CRC'd A/B record and a reset (or power cycle) loads it back; the
//! node's communication settings (the LSS configuration, the PDO mappings: [`CommSettings`])
//! ride in the same record as its communication block, so they are saved and lost together
//! with the set, never half.
//!
//! The save here is blocking: ≈ 70 ms of flash busy time on the STM32G431, during which the
//! single-bank flash stalls instruction fetches (see the store's module doc). Use it where
//! saving happens with the torque off (pre-operational) or the control loop runs from RAM;
//! a firmware that saves while operational drives [`Store::begin_save`]/[`Store::poll`] from
//! its flash task instead and implements [`ParamStorage`] itself.

use super::lss::LssConfig;
use super::node::{ParamStorage, StorageError};
use super::pdo_map::PDO_MAPS_BYTES;
use crate::params::{ParamSet, RawParams};
use crate::safety::Faults;
use crate::store::{Flash, LoadError, Store};

/// What a node keeps besides its parameter set: the LSS configuration (CiA 305 store
/// configuration) and the PDO mappings (0x1010 with the set). Stored as the store's
/// communication block: `u8 version (1), u8 flags (bit 0 LSS, bit 1 PDO), u8 node id,
/// u8 bit-timing index`, then, with bit 1, the mappings (`PdoMaps::to_bytes`). Nothing stored
/// is no block at all (the record is then byte for byte a set-only one).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct CommSettings {
    pub lss: Option<LssConfig>,
    pub pdo: Option<[u8; PDO_MAPS_BYTES]>,
}

impl CommSettings {
    /// The longest block.
    pub const MAX_BYTES: usize = 4 + PDO_MAPS_BYTES;

    /// The block's bytes into `out`; its length (0: nothing to store).
    pub fn encode(&self, out: &mut [u8; Self::MAX_BYTES]) -> usize {
        if self.lss.is_none() && self.pdo.is_none() {
            return 0;
        }
        let flags = u8::from(self.lss.is_some()) | (u8::from(self.pdo.is_some()) << 1);
        let l = self.lss.unwrap_or(LssConfig { node_id: 0, bit_timing: 0 });
        let (head, rest) = out.split_at_mut(4);
        head.copy_from_slice(&[1, flags, l.node_id, l.bit_timing]);
        match (&self.pdo, rest.get_mut(..PDO_MAPS_BYTES)) {
            (Some(m), Some(dst)) => {
                dst.copy_from_slice(m);
                Self::MAX_BYTES
            }
            _ => 4,
        }
    }

    /// Hands the block to `store` for its next save (`Store::set_comm`). Out of line: the
    /// encoded block is on the stack only during this call.
    #[inline(never)]
    pub fn stage<F: Flash>(&self, store: &mut Store<F>) -> Result<(), crate::store::CommTooLong> {
        let mut b = [0u8; Self::MAX_BYTES];
        let n = self.encode(&mut b);
        store.set_comm(b.get(..n).unwrap_or(&[]))
    }

    /// A block as [`CommSettings::encode`] wrote it; `None` for anything else (another
    /// version, a wrong length), which the node then treats as nothing stored.
    pub fn decode(b: &[u8]) -> Option<CommSettings> {
        let (&[version, flags, node_id, bit_timing], rest) = b.split_first_chunk::<4>()?;
        if version != 1 || flags & !0b11 != 0 {
            return None;
        }
        let lss = (flags & 1 != 0).then_some(LssConfig { node_id, bit_timing });
        let pdo = if flags & 2 != 0 {
            Some(<[u8; PDO_MAPS_BYTES]>::try_from(rest).ok()?)
        } else if rest.is_empty() {
            None
        } else {
            return None;
        };
        Some(CommSettings { lss, pdo })
    }
}

/// See the module documentation.
pub struct FlashStorage<F: Flash> {
    store: Option<Store<F>>,
    fault: Faults,
    /// the communication settings of the newest record (read at the first load), and what
    /// `save_pdo`/`save_lss` changed since: written with every save
    comm: CommSettings,
    /// the stored set, for an LSS store that rewrites the record without a new set
    stored: Option<RawParams>,
    scanned: bool,
}

impl<F: Flash> FlashStorage<F> {
    /// Over a store (its geometry already checked by [`Store::new`]).
    pub fn new(store: Store<F>) -> Self {
        FlashStorage {
            store: Some(store),
            fault: Faults::NONE,
            comm: CommSettings::default(),
            stored: None,
            scanned: false,
        }
    }

    /// Give the flash back (a power cycle in tests).
    pub fn into_flash(self) -> Option<F> {
        self.store.map(Store::into_flash)
    }
}

impl<F: Flash> FlashStorage<F> {
    /// Reads the newest record: its set (returned), its communication settings and its fault.
    fn scan(&mut self) -> Option<RawParams> {
        self.scanned = true;
        let store = self.store.as_mut()?;
        match store.load() {
            Ok(l) => {
                self.fault = l.info.fault();
                self.comm = CommSettings::decode(store.comm()).unwrap_or_default();
                self.stored = Some(l.params.raw().clone());
                self.stored.clone()
            }
            Err(e) => {
                self.fault = e.fault();
                if let LoadError::Blank = e {
                    self.fault = Faults::NONE;
                }
                self.comm = CommSettings::default();
                self.stored = None;
                None
            }
        }
    }

    fn scanned(&mut self) {
        if !self.scanned {
            self.scan();
        }
    }

    /// One record: `set` with the communication settings in force here.
    fn write(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        let store = self.store.as_mut().ok_or(StorageError::Failed)?;
        self.comm.stage(store).map_err(|_| StorageError::Failed)?;
        store.save_blocking(set).map_err(|_| StorageError::Failed)?;
        self.stored = Some(set.raw().clone());
        Ok(())
    }
}

impl<F: Flash> ParamStorage for FlashStorage<F> {
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        self.scanned();
        self.write(set)
    }

    fn load(&mut self) -> Option<RawParams> {
        self.scan()
    }

    /// Kept here and written by the save of the set that follows (the node saves the mappings
    /// first, then the set: one record holds both).
    fn save_pdo(&mut self, maps: &[u8; PDO_MAPS_BYTES]) -> Result<(), StorageError> {
        self.scanned();
        self.comm.pdo = Some(*maps);
        Ok(())
    }

    fn load_pdo(&mut self) -> Option<[u8; PDO_MAPS_BYTES]> {
        self.scanned();
        self.comm.pdo
    }

    fn load_lss(&mut self) -> Option<LssConfig> {
        self.scanned();
        self.comm.lss
    }

    /// LSS store configuration: the stored set's record again, with the new configuration
    /// (the table defaults' when nothing is stored: what such a node runs anyway).
    fn save_lss(&mut self, c: LssConfig) -> Result<(), StorageError> {
        self.scanned();
        let raw = self.stored.clone().unwrap_or_default();
        let set = crate::params::check(&raw).map_err(|_| StorageError::Failed)?;
        let before = self.comm;
        self.comm.lss = Some(c);
        self.write(&set).inspect_err(|_| self.comm = before)
    }

    fn load_fault(&self) -> Faults {
        self.fault
    }

    /// Erase both slots: the next reset runs the table defaults and the default PDO mappings.
    /// A stored LSS configuration stays (CiA 301's restore is of the application's and the
    /// communication profile's parameters, not of the LSS node id): it is written again in a
    /// record of the defaults.
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        self.scanned();
        if let Some(lss) = self.comm.lss {
            self.comm = CommSettings { lss: Some(lss), pdo: None };
            return self.write(&ParamSet::defaults());
        }
        let store = self.store.take().ok_or(StorageError::Failed)?;
        let len = store.used_len();
        let mut flash = store.into_flash();
        let erased = flash.erase(0, len).is_ok();
        // Same flash, same geometry: rebuilding cannot fail; if it did, saves report Failed.
        self.store = Store::new(flash).ok();
        // what the mirrors said is gone (or, after a failed erase, unknown): read it again
        self.scanned = false;
        if erased {
            Ok(())
        } else {
            Err(StorageError::Failed)
        }
    }
}
