//! The node's parameter storage on the board: a handoff, not a flash driver.
//!
//! The CANopen node calls [`ParamStorage::save`] (object 0x1010) and
//! [`ParamStorage::restore_defaults`] (0x1011) from inside the CAN task's critical section,
//! where nothing may wait, let alone stall 40 ms on a page erase. So [`BoardStorage`] only
//! records the request and wakes the params task, the one owner of the flash, which takes it
//! with [`BoardStorage::take_job`], does the flash work with the core's incremental store
//! (only while no torque is commanded: the single-bank G431 stalls every instruction fetch
//! during an erase), and reports back with [`BoardStorage::finish`]. While a job is queued or
//! running, further requests get [`StorageError::Busy`] (SDO abort 0x08000020), so the master
//! knows to retry.
//!
//! [`ParamStorage::load`] answers from a mirror of what the flash holds (or will hold once
//! the job in flight completes): the set read at boot, replaced by every accepted save,
//! cleared by restore. When a job fails, the params task re-reads the flash and puts what it
//! really holds back into the mirror, and latches `STORE_WRITE`.
//!
//! The node's communication settings (the LSS configuration, the PDO mappings) ride in the
//! set's record ([`CommSettings`], the store's communication block): mirrored here like the
//! set, handed to the params task with every save. An LSS "store configuration" is a save of
//! the stored set with the new configuration.
//!
//! "Restore defaults" erases the two record slots ([`EraseOrder`]); the slot holding the
//! older record goes first, so a power cut during the erase boots either the stored set
//! (first slot cut) or the defaults (second slot cut), never an older calibration.

use joint_core::canopen::lss::LssConfig;
use joint_core::canopen::pdo_map::PDO_MAPS_BYTES;
use joint_core::canopen::storage::CommSettings;
use joint_core::canopen::{ParamStorage, StorageError};
use joint_core::params::{ParamSet, RawParams};
use joint_core::safety::Faults;
use joint_core::store::SlotState;

/// Work for the params task. (No `Box` without an allocator: the set travels by value,
/// once per job, from the node's lock to the params task's stack.)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Job {
    /// Persist this (committed, validated) set, with these communication settings.
    Save(RawParams, CommSettings),
    /// Erase the stored set: the next boot runs the table defaults.
    Erase,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    SaveQueued,
    EraseQueued,
    Running,
}

/// The board's [`ParamStorage`]; lives inside the node, shared with the params task through
/// the node's lock.
pub struct BoardStorage {
    /// What `load` returns: the flash's set as of the last completed or accepted job.
    mirror: Option<RawParams>,
    /// The communication settings the flash holds (or will once the job in flight completes).
    comm: CommSettings,
    /// What reading the flash found (boot, or the re-read after a failed job): the node
    /// latches it again after every NMT reset-node.
    load_fault: Faults,
    state: State,
    /// Wakes the params task (a `Signal` on the board, a counter in tests). Called inside
    /// the node's critical section, so it must only set a flag.
    wake: fn(),
}

impl BoardStorage {
    /// `boot`: the set the store read at boot (`None` when blank, corrupt or refused) and
    /// the fault that read found.
    pub fn new(boot: Option<RawParams>, comm: CommSettings, load_fault: Faults, wake: fn()) -> Self {
        BoardStorage { mirror: boot, comm, load_fault, state: State::Idle, wake }
    }

    /// The params task takes the queued job (a copy of the set to save), marking it running.
    pub fn take_job(&mut self) -> Option<Job> {
        let job = match self.state {
            State::SaveQueued => Job::Save(self.mirror.clone()?, self.comm),
            State::EraseQueued => Job::Erase,
            State::Idle | State::Running => return None,
        };
        self.state = State::Running;
        Some(job)
    }

    /// The running job ended. `Ok`: the flash now holds what the mirror says (and whatever
    /// was wrong with it before is gone). `Err((actual, fault))`: it failed; `actual` is what
    /// a re-read of the flash found (`None`: nothing usable) and `fault` what that read found.
    pub fn finish(&mut self, result: Result<(), (Option<RawParams>, CommSettings, Faults)>) {
        match result {
            Ok(()) => self.load_fault = Faults::NONE,
            Err((actual, comm, fault)) => {
                self.mirror = actual;
                self.comm = comm;
                self.load_fault = fault;
            }
        }
        self.state = State::Idle;
    }

    /// A job is queued or running.
    pub fn busy(&self) -> bool {
        self.state != State::Idle
    }

    fn request(&mut self, next: State) -> Result<(), StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        self.state = next;
        (self.wake)();
        Ok(())
    }
}

impl ParamStorage for BoardStorage {
    fn save(&mut self, set: &ParamSet) -> Result<(), StorageError> {
        self.request(State::SaveQueued)?;
        self.mirror = Some(set.raw().clone());
        Ok(())
    }

    fn load(&mut self) -> Option<RawParams> {
        self.mirror.clone()
    }

    fn load_fault(&self) -> Faults {
        self.load_fault
    }

    /// Erase: the defaults and the default PDO mappings at the next boot. A stored LSS
    /// configuration stays (it is CiA 305's, not the application's): then a record of the
    /// defaults carrying it is saved instead of the erase.
    fn restore_defaults(&mut self) -> Result<(), StorageError> {
        if let Some(lss) = self.comm.lss {
            self.request(State::SaveQueued)?;
            self.mirror = Some(RawParams::defaults());
            self.comm = CommSettings { lss: Some(lss), pdo: None };
            return Ok(());
        }
        self.request(State::EraseQueued)?;
        self.mirror = None;
        self.comm = CommSettings::default();
        Ok(())
    }

    /// Kept for the save of the set that follows (the node saves the mappings first).
    fn save_pdo(&mut self, maps: &[u8; PDO_MAPS_BYTES]) -> Result<(), StorageError> {
        if self.busy() {
            return Err(StorageError::Busy);
        }
        self.comm.pdo = Some(*maps);
        Ok(())
    }

    fn load_pdo(&mut self) -> Option<[u8; PDO_MAPS_BYTES]> {
        self.comm.pdo
    }

    fn load_lss(&mut self) -> Option<LssConfig> {
        self.comm.lss
    }

    /// LSS store configuration: the stored set saved again with it (the defaults when none is
    /// stored: what the node runs then anyway).
    fn save_lss(&mut self, c: LssConfig) -> Result<(), StorageError> {
        self.request(State::SaveQueued)?;
        if self.mirror.is_none() {
            self.mirror = Some(RawParams::defaults());
        }
        self.comm.lss = Some(c);
        Ok(())
    }
}

/// The pages to erase for "restore defaults", in a power-cut-safe order: the slot without
/// the newest intact record first, then the newest. `slot_len` and `page` in bytes; slot A
/// starts at 0 and slot B at `slot_len` (the core store's layout).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EraseOrder {
    slots: [u32; 2],
    slot_len: u32,
    page: u32,
    next: u32,
}

impl EraseOrder {
    pub fn new(states: [SlotState; 2], slot_len: u32, page: u32) -> Self {
        let seq = |s: SlotState| match s {
            SlotState::Valid { seq, .. } => Some(seq),
            _ => None,
        };
        // Serial-number comparison as the store does: B is newest when it is valid and A is
        // not, or both are and B's sequence is ahead.
        let [a, b] = states;
        let b_newest = match (seq(a), seq(b)) {
            (Some(a), Some(b)) => (b.wrapping_sub(a) as i32) > 0,
            (None, Some(_)) => true,
            _ => false,
        };
        let slots = if b_newest { [0, 1] } else { [1, 0] };
        EraseOrder { slots, slot_len, page: page.max(1), next: 0 }
    }

    /// The next page to erase as `(from, to)`, or `None` when all are done.
    pub fn next_page(&mut self) -> Option<(u32, u32)> {
        let per_slot = self.slot_len.div_ceil(self.page);
        let k = self.next;
        let slot = *self.slots.get((k / per_slot.max(1)) as usize)?;
        let from = slot * self.slot_len + (k % per_slot) * self.page;
        self.next += 1;
        Some((from, from + self.page))
    }

    pub fn pages(&self) -> u32 {
        2 * self.slot_len.div_ceil(self.page)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use joint_core::params::ParamId;
    use std::sync::atomic::{AtomicU32, Ordering};

    static WAKES: AtomicU32 = AtomicU32::new(0);
    fn wake() {
        WAKES.fetch_add(1, Ordering::Relaxed);
    }

    fn set(fraction: f32) -> RawParams {
        let mut r = RawParams::defaults();
        r.set(ParamId::Fraction, fraction);
        r
    }

    fn checked(fraction: f32) -> ParamSet {
        joint_core::params::check(&set(fraction)).unwrap()
    }

    #[test]
    fn save_hands_the_set_to_the_params_task_once_and_refuses_while_busy() {
        let mut s = BoardStorage::new(Some(set(0.5)), CommSettings::default(), Faults::NONE, wake);
        assert_eq!(s.load(), Some(set(0.5)));
        assert_eq!(s.take_job(), None, "nothing asked yet");
        let w = WAKES.load(Ordering::Relaxed);
        s.save(&checked(0.7)).unwrap();
        assert!(WAKES.load(Ordering::Relaxed) > w, "the params task is woken");
        assert_eq!(s.save(&checked(0.8)), Err(StorageError::Busy));
        assert_eq!(s.restore_defaults(), Err(StorageError::Busy));
        assert_eq!(s.load(), Some(set(0.7)), "a refused request changes nothing");
        assert_eq!(s.take_job(), Some(Job::Save(set(0.7), CommSettings::default())));
        assert_eq!(s.take_job(), None, "a job is handed out once");
        assert_eq!(s.save(&checked(0.8)), Err(StorageError::Busy), "busy while running");
        s.finish(Ok(()));
        assert!(!s.busy());
        assert_eq!(s.load(), Some(set(0.7)));
    }

    #[test]
    fn a_failed_save_puts_what_the_flash_holds_back() {
        let mut s = BoardStorage::new(Some(set(0.5)), CommSettings::default(), Faults::NONE, wake);
        s.save(&checked(0.7)).unwrap();
        assert!(matches!(s.take_job(), Some(Job::Save(..))));
        s.finish(Err((Some(set(0.5)), CommSettings::default(), Faults::NONE)));
        assert_eq!(s.load(), Some(set(0.5)));
        s.save(&checked(0.9)).unwrap();
        s.take_job();
        s.finish(Err((None, CommSettings::default(), Faults::PARAMS_CORRUPT)));
        assert_eq!(s.load(), None);
        assert_eq!(s.load_fault(), Faults::PARAMS_CORRUPT);
    }

    /// The communication settings travel with the set: mappings saved with it, an LSS store
    /// saves the stored set again with the new configuration, and a restore keeps the LSS
    /// configuration in a record of the defaults instead of erasing it.
    #[test]
    fn mappings_and_lss_ride_with_the_set_to_the_params_task() {
        use joint_core::canopen::lss::LssConfig;
        let mut s = BoardStorage::new(Some(set(0.5)), CommSettings::default(), Faults::NONE, wake);
        let maps = [7u8; PDO_MAPS_BYTES];
        s.save_pdo(&maps).unwrap();
        s.save(&checked(0.6)).unwrap();
        assert_eq!(s.take_job(), Some(Job::Save(set(0.6), CommSettings { lss: None, pdo: Some(maps) })));
        assert_eq!(s.save_pdo(&maps), Err(StorageError::Busy), "nothing changes while a job runs");
        s.finish(Ok(()));
        let id = LssConfig { node_id: 21, bit_timing: 0 };
        s.save_lss(id).unwrap();
        assert_eq!(s.take_job(), Some(Job::Save(set(0.6), CommSettings { lss: Some(id), pdo: Some(maps) })));
        s.finish(Ok(()));
        assert_eq!((s.load_lss(), s.load_pdo()), (Some(id), Some(maps)));
        s.restore_defaults().unwrap();
        assert_eq!(s.take_job(), Some(Job::Save(RawParams::defaults(), CommSettings { lss: Some(id), pdo: None })));
        s.finish(Ok(()));
        // without an LSS configuration, a restore is the erase it always was
        let mut s = BoardStorage::new(Some(set(0.5)), CommSettings::default(), Faults::NONE, wake);
        s.restore_defaults().unwrap();
        assert_eq!(s.take_job(), Some(Job::Erase));
    }

    #[test]
    fn restore_empties_the_mirror_and_queues_an_erase() {
        let mut s = BoardStorage::new(Some(set(0.5)), CommSettings::default(), Faults::NONE, wake);
        s.restore_defaults().unwrap();
        assert_eq!(s.load(), None);
        assert_eq!(s.take_job(), Some(Job::Erase));
        s.finish(Ok(()));
        assert_eq!(s.load(), None);
    }

    /// Through the node: 0x1010 "save" queues the committed set (not the staged one), a
    /// second store while the first is in flight is refused with 0x08000020 and changes
    /// nothing; a boot fault is latched again after NMT reset-node; 0x1011 queues an erase.
    #[test]
    fn the_node_hands_store_and_restore_to_the_params_task() {
        use joint_core::canopen::{od, Node, NodeConfig};
        let mut n = Node::new(
            NodeConfig::new(5),
            BoardStorage::new(None, CommSettings::default(), Faults::PARAMS_CORRUPT, wake),
            0,
        );
        assert!(n.safety().faults().contains(Faults::PARAMS_CORRUPT));
        n.process(0, None, &mut |_| {});
        let fraction = 0x2000 + ParamId::Fraction.index() as u16;
        n.write(fraction, 0, &0.6f32.to_le_bytes()).unwrap();
        let crc = joint_core::store::set_crc(n.staged()); // commit by naming the set (0x2205)
        n.write(0x2205, 0, &crc.to_le_bytes()).unwrap();
        n.write(fraction, 0, &0.3f32.to_le_bytes()).unwrap(); // staged, not committed
        n.write(0x1010, 1, &od::SAVE_SIGNATURE.to_le_bytes()).unwrap();
        let again = n.write(0x1010, 1, &od::SAVE_SIGNATURE.to_le_bytes());
        assert_eq!(again.map_err(|a| a.code()), Err(0x0800_0020));
        let Some(Job::Save(raw, _)) = n.storage_mut().take_job() else { panic!("no save job") };
        assert_eq!(raw.get(ParamId::Fraction), 0.6);
        n.storage_mut().finish(Ok(()));
        // NMT reset-node: the committed-and-stored set comes back, the boot fault is gone.
        n.process(1000, Some(&joint_core::canopen::CanFrame::new(0, &[0x81, 5]).unwrap()), &mut |_| {});
        assert_eq!(n.params().get(ParamId::Fraction), 0.6);
        assert!(!n.safety().faults().contains(Faults::PARAMS_CORRUPT));
        n.write(0x1011, 1, &od::LOAD_SIGNATURE.to_le_bytes()).unwrap();
        assert_eq!(n.storage_mut().take_job(), Some(Job::Erase));
    }

    fn pages(mut e: EraseOrder) -> Vec<(u32, u32)> {
        let n = e.pages();
        let v: Vec<_> = core::iter::from_fn(|| e.next_page()).collect();
        assert_eq!(v.len() as u32, n);
        v
    }

    #[test]
    fn erase_starts_with_the_slot_not_holding_the_newest_record() {
        let valid = |seq| SlotState::Valid { seq, version: 1 };
        // A newest: B's two pages first.
        let e = EraseOrder::new([valid(7), valid(6)], 4096, 2048);
        assert_eq!(pages(e), [(4096, 6144), (6144, 8192), (0, 2048), (2048, 4096)]);
        // B newest, across the sequence wrap.
        let e = EraseOrder::new([valid(u32::MAX), valid(0)], 4096, 2048);
        assert_eq!(pages(e).first(), Some(&(0, 2048)));
        // Only B intact.
        let e = EraseOrder::new([SlotState::Damaged, valid(3)], 4096, 2048);
        assert_eq!(pages(e).first(), Some(&(0, 2048)));
        // Nothing intact: every page still goes.
        let e = EraseOrder::new([SlotState::Uncommitted, SlotState::Blank], 4096, 2048);
        assert_eq!(pages(e).len(), 4);
    }

    // The shared NOR-flash double (the core's `mock-flash` feature).
    use joint_core::store::mock::MemFlash;

    /// Restore defaults as the params task does it (scan, erase in [`EraseOrder`], one page
    /// at a time), with the power cut at every page and inside pages: the next boot finds the
    /// newest stored set or nothing, never the older calibration.
    #[test]
    fn restore_cut_at_any_point_never_boots_an_older_set() {
        use joint_core::store::Store;
        let old = joint_core::params::check(&set(0.4)).unwrap();
        let new = joint_core::params::check(&set(0.8)).unwrap();
        let mut store = Store::new(MemFlash::blank(8192)).unwrap();
        store.save_blocking(&old).unwrap();
        store.save_blocking(&new).unwrap();
        let states = store.scan().unwrap();
        let slot_len = store.used_len() / 2;
        let image = store.into_flash().mem;

        let mut order = EraseOrder::new(states, slot_len, 2048);
        let pages: Vec<(u32, u32)> = core::iter::from_fn(|| order.next_page()).collect();
        let mut outcomes = std::collections::BTreeSet::new();
        for cut in 0..pages.len() {
            for partial in [0usize, 8, 1024, 2047] {
                let mut mem = image.clone();
                for &(a, b) in &pages[..cut] {
                    mem[a as usize..b as usize].fill(0xFF);
                }
                let (a, _) = pages[cut];
                mem[a as usize..a as usize + partial].fill(0xFF);
                let mut st = Store::new(MemFlash::from_mem(mem)).unwrap();
                match st.load() {
                    Ok(l) => {
                        assert_eq!(
                            l.params.raw(),
                            new.raw(),
                            "cut before page {cut} (+{partial} B) booted an older set"
                        );
                        outcomes.insert("newest");
                    }
                    Err(_) => {
                        outcomes.insert("defaults");
                    }
                }
            }
        }
        assert_eq!(outcomes.len(), 2, "both outcomes occur over the cut points: {outcomes:?}");
        // Uncut, the region is blank: a fresh board, no fault.
        let mut mem = image.clone();
        for &(a, b) in &pages {
            mem[a as usize..b as usize].fill(0xFF);
        }
        let mut st = Store::new(MemFlash::from_mem(mem)).unwrap();
        assert!(matches!(st.load(), Err(joint_core::store::LoadError::Blank)));
    }
}
