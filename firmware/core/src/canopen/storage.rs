//! [`ParamStorage`] over the core's power-loss-safe flash store ([`crate::store::Store`]), so
//! `save` (0x1010) writes a CRC'd A/B record and a reset (or power cycle) loads it back.
//!
//! The save here is blocking: ≈ 70 ms of flash busy time on the STM32G431, during which the
//! single-bank flash stalls instruction fetches (see the store's module doc). Use it where
//! saving happens with the torque off (pre-operational) or the control loop runs from RAM;
//! a firmware that saves while operational drives [`Store::begin_save`]/[`Store::poll`] from
//! its flash task instead and implements [`ParamStorage`] itself.

use super::node::{ParamStorage, StorageError};
use crate::params::{ParamSet, RawParams};
use crate::safety::Faults;
use crate::store::{Flash, LoadError, Store};

/// See the module documentation.
pub struct FlashStorage<F: Flash> {
    store: Option<Store<F>>,
    fault: Faults,
}

impl<F: Flash> FlashStorage<F> {
    /// Over a store (its geometry already checked by [`Store::new`]).
    pub fn new(store: Store<F>) -> Self {
        FlashStorage { store: Some(store), fault: Faults::NONE }
    }

    /// Give the flash back (a power cycle in tests).
    pub fn into_flash(self) -> Option<F> {
        self.store.map(Store::into_flash)
    }
}

impl<F: Flash> ParamStorage for FlashStorage<F> {
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        let store = self.store.as_mut().ok_or(StorageError::Failed)?;
        store.save_blocking(set).map(|_| ()).map_err(|_| StorageError::Failed)
    }

    fn load(&mut self) -> Option<RawParams> {
        let store = self.store.as_mut()?;
        match store.load() {
            Ok(l) => {
                self.fault = l.info.fault();
                Some(l.params.raw().clone())
            }
            Err(e) => {
                self.fault = e.fault();
                if let LoadError::Blank = e {
                    self.fault = Faults::NONE;
                }
                None
            }
        }
    }

    fn load_fault(&self) -> Faults {
        self.fault
    }

    /// Erase both slots: the next reset runs the table defaults.
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        let store = self.store.take().ok_or(StorageError::Failed)?;
        let len = store.used_len();
        let mut flash = store.into_flash();
        let erased = flash.erase(0, len).is_ok();
        // Same flash, same geometry: rebuilding cannot fail; if it did, saves report Failed.
        self.store = Store::new(flash).ok();
        if erased {
            Ok(())
        } else {
            Err(StorageError::Failed)
        }
    }
}
