//! `MemFlash`: a NOR flash in RAM with the STM32G4's geometry (2 KiB pages, 8-byte programming
//! of erased double-words only) and power-cut injection, the one test double of every crate that
//! stores parameters (feature `mock-flash`; never in firmware).
//!
//! `budget` bytes may still be erased or programmed; when it runs out the power is cut: the
//! operation stops mid-way and every later call fails until the "reboot" (a new `MemFlash` over
//! the same bytes, [`MemFlash::from_mem`]). With `scramble`, the rest of a page whose erase was
//! cut holds garbage instead of its old contents (cells in an undefined state).

extern crate std;
use std::vec::Vec;

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash};

/// Page size of the mock (the G431's).
pub const PAGE: usize = 2048;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemFlashError {
    PowerCut,
    Misaligned,
    /// programming a double-word that is not erased (the G4's PROGERR)
    NotErased,
    OutOfBounds,
}

impl NorFlashError for MemFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            MemFlashError::Misaligned => NorFlashErrorKind::NotAligned,
            MemFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            MemFlashError::PowerCut | MemFlashError::NotErased => NorFlashErrorKind::Other,
        }
    }
}

#[derive(Clone, Debug)]
pub struct MemFlash {
    /// the cells
    pub mem: Vec<u8>,
    budget: Option<u64>,
    dead: bool,
    scramble: bool,
    /// bytes erased or programmed so far
    pub used: u64,
}

impl MemFlash {
    /// `len` erased bytes.
    pub fn blank(len: usize) -> Self {
        Self::from_mem(std::vec![0xFF; len])
    }

    /// A flash holding `mem` (after a reboot: no cut pending).
    pub fn from_mem(mem: Vec<u8>) -> Self {
        MemFlash { mem, budget: None, dead: false, scramble: false, used: 0 }
    }

    /// Cut the power after `budget` more bytes erased or programmed.
    pub fn with_cut(mut self, budget: u64, scramble: bool) -> Self {
        self.budget = Some(budget);
        self.scramble = scramble;
        self
    }

    /// Whether the power has been cut.
    pub fn dead(&self) -> bool {
        self.dead
    }

    /// Consume one byte of budget; false = the power is gone.
    fn tick(&mut self) -> bool {
        if let Some(b) = self.budget.as_mut() {
            if *b == 0 {
                self.dead = true;
                return false;
            }
            *b -= 1;
        }
        self.used += 1;
        true
    }

    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, MemFlashError> {
        let o = offset as usize;
        let end = o.checked_add(len).ok_or(MemFlashError::OutOfBounds)?;
        if end > self.mem.len() {
            return Err(MemFlashError::OutOfBounds);
        }
        Ok(o..end)
    }
}

impl ErrorType for MemFlash {
    type Error = MemFlashError;
}

impl ReadNorFlash for MemFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), MemFlashError> {
        if self.dead {
            return Err(MemFlashError::PowerCut);
        }
        let r = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(self.mem.get(r).ok_or(MemFlashError::OutOfBounds)?);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for MemFlash {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = PAGE;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), MemFlashError> {
        if self.dead {
            return Err(MemFlashError::PowerCut);
        }
        let (f, t) = (from as usize, to as usize);
        // `%` rather than `is_multiple_of` (Rust 1.87): the workspace declares 1.85.
        #[allow(clippy::manual_is_multiple_of)]
        let misaligned = f % PAGE != 0 || t % PAGE != 0 || f > t;
        if misaligned {
            return Err(MemFlashError::Misaligned);
        }
        if t > self.mem.len() {
            return Err(MemFlashError::OutOfBounds);
        }
        for i in f..t {
            if !self.tick() {
                if self.scramble {
                    let page_end = (i / PAGE + 1) * PAGE;
                    let mut x = (i as u32).wrapping_mul(2_654_435_761) | 1;
                    for b in self.mem.get_mut(i..page_end).unwrap_or(&mut []) {
                        x ^= x << 13;
                        x ^= x >> 17;
                        x ^= x << 5;
                        *b = x as u8;
                    }
                }
                return Err(MemFlashError::PowerCut);
            }
            if let Some(b) = self.mem.get_mut(i) {
                *b = 0xFF;
            }
        }
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), MemFlashError> {
        if self.dead {
            return Err(MemFlashError::PowerCut);
        }
        #[allow(clippy::manual_is_multiple_of)]
        let misaligned = offset as usize % 8 != 0 || bytes.len() % 8 != 0;
        if misaligned {
            return Err(MemFlashError::Misaligned);
        }
        let r = self.range(offset, bytes.len())?;
        // STM32G4: programming a double-word that is not erased is an error (PROGERR).
        if self.mem.get(r.clone()).is_some_and(|d| d.iter().any(|&b| b != 0xFF)) {
            return Err(MemFlashError::NotErased);
        }
        for (i, &b) in r.zip(bytes) {
            if !self.tick() {
                return Err(MemFlashError::PowerCut);
            }
            if let Some(c) = self.mem.get_mut(i) {
                *c &= b;
            }
        }
        Ok(())
    }
}
