//! The board image's tasks and glue, shared by every board: each board's `main.rs` includes
//! this file (the G0B1 crate by path) next to `board.rs`, and gives it a `hal` module (its
//! timers and its control step) and a `main` that sets up the chip's clocks and pins. The
//! tasks only use embassy-stm32 APIs that are the same on the STM32G4 and G0 families, so
//! what differs between boards is the HAL set-up and nothing else.
//!
//! The tasks are described in the G431 crate's `main.rs`.

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use defmt::{error, info, warn};
use embassy_executor::Spawner;
use embassy_futures::select::{select, Either};
use embassy_stm32::can;
use embassy_stm32::flash::Flash;
use embassy_stm32::peripherals;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use firmware::can_link::{self, BusMode, BusStats, Outbox};
use firmware::control_loop::ControlLoop;
use firmware::io::{Encoder, TorqueOutput};
use firmware::storage::{BoardStorage, EraseOrder, Job};
use joint_core::canopen::storage::CommSettings;
use joint_core::canopen::{CanFrame, Node, NodeConfig};
use joint_core::params::{check, ParamId, ParamSet, RawParams};
use joint_core::safety::Faults;
use joint_core::store::{NorFlash as _, SaveProgress, Store};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

use crate::board::{HBridgeTorque, ParamFlash, QeiEncoder};

/// This node's CANopen id (no LSS: a compile-time constant).
pub const NODE_ID: u8 = 5;
pub const CAN_BITRATE: u32 = 1_000_000;
/// The node's timers (heartbeat, TPDO event timer, SDO timeout) want a poll at least
/// every millisecond.
const NODE_POLL: Duration = Duration::from_millis(1);
/// Bus counters are logged this often while they change.
const STATS_LOG: Duration = Duration::from_secs(10);
/// Encoder edges per motor revolution (x4 decoding of a 1024-line encoder).
pub const ENCODER_COUNTS_PER_REV: u32 = 4096;
/// Motor torque at 100 % duty, N·m (see board::HBridgeTorque).
pub const MOTOR_FULL_SCALE_NM: f32 = 0.5;
/// IWDG timeout: long enough for a flash page erase (40 ms max, the CPU stalls on the
/// single-bank G431), short enough that a stuck loop is caught within 0.1 s.
pub const IWDG_TIMEOUT_US: u32 = 100_000;

type Cs = CriticalSectionRawMutex;
type JointNode = Node<BoardStorage, crate::hal::Step>;

/// The CANopen node, shared by the control, CAN and params tasks. Every lock is one call
/// into the node (a control step, one frame, one poll, a storage handoff): a few µs, an
/// SDO commit (the whole-set check) the longest. Never locked while waiting on I/O.
/// The node itself (≈ 9 KiB) lives in `NODE_CELL`, uninitialised RAM (.bss) until
/// `main` builds it in place: an `Option<Node>` static would be initialised data, i.e.
/// 9 KiB of flash too.
static NODE: Mutex<Cs, RefCell<Option<&'static mut JointNode>>> = Mutex::new(RefCell::new(None));
static NODE_CELL: StaticCell<JointNode> = StaticCell::new();
/// The node queued a store/restore job for the params task.
static STORE_WAKE: Signal<Cs, ()> = Signal::new();
/// The loop commands a non-zero torque: the params task does not touch the flash.
static TORQUE_ACTIVE: AtomicBool = AtomicBool::new(false);
/// Flash operations done so far: a change tells the loop a gap was a flash stall.
static FLASH_OPS: AtomicU32 = AtomicU32::new(0);
pub static BUS_STATS: Mutex<Cs, Cell<BusStats>> = Mutex::new(Cell::new(BusStats {
    mode: BusMode::ErrorActive,
    rec: 0,
    tec: 0,
    rx_frames: 0,
    tx_frames: 0,
    rx_rejected: 0,
    tx_dropped: 0,
    bus_errors: 0,
    error_passive_events: 0,
    bus_off_events: 0,
    recoveries: 0,
}));

/// One more flash operation. A load and a store, not `fetch_add`: the Cortex-M0+ has no
/// read-modify-write atomics, and the params task is the only writer.
fn count_flash_op() {
    FLASH_OPS.store(FLASH_OPS.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
}

fn now_us() -> u64 {
    Instant::now().as_micros()
}

fn wake_params() {
    STORE_WAKE.signal(());
}

/// `f` on the node inside its lock (`None` only before `main` created it).
fn with_node<R>(f: impl FnOnce(&mut JointNode) -> R) -> Option<R> {
    NODE.lock(|n| n.borrow_mut().as_deref_mut().map(f))
}

/// The stored set as the store reads it at boot, its communication settings (LSS
/// configuration, PDO mappings) and the fault to latch.
fn boot_params(store: Option<&mut Store<ParamFlash>>) -> (Option<RawParams>, CommSettings, Faults) {
    let Some(store) = store else {
        error!("parameter region too small for two slots: defaults, nothing can be saved");
        return (None, CommSettings::default(), Faults::PARAMS_CORRUPT);
    };
    match store.load() {
        Ok(l) => {
            info!(
                "parameters: slot {=u8} seq {=u32} ({=u8} defaulted, {=u8} unknown)",
                l.info.slot, l.info.seq, l.info.defaulted, l.info.unknown
            );
            let comm = CommSettings::decode(store.comm()).unwrap_or_default();
            (Some(l.params.raw().clone()), comm, l.info.fault())
        }
        Err(e) => {
            let f = e.fault();
            if f.is_empty() {
                info!("parameters: nothing stored, table defaults");
            } else {
                warn!("parameter store unreadable: defaults, fault {=u16:#x}", f.bits());
            }
            (None, CommSettings::default(), f)
        }
    }
}

/// The node, built into its static cell, then reset there (its stored set, LSS configuration
/// and PDO mappings read): the stack holds either the node being moved in or the reset's
/// parameter-set temporaries, never both (`Node::with_step_cold`). Out of line so that
/// neither is part of `main`'s frame.
#[inline(never)]
fn create_node(boot: Option<RawParams>, comm: CommSettings, fault: Faults) -> &'static mut JointNode {
    let node = NODE_CELL.init_with(|| {
        let cfg = NodeConfig::new(NODE_ID).with_fd(cfg!(feature = "fd"));
        Node::with_step_cold(cfg, BoardStorage::new(boot, comm, fault, wake_params), now_us())
    });
    node.reset_in_place(now_us());
    node
}

/// Reads the parameter store and builds the node (the first thing `main` does after the
/// clocks: the node must start on the stored calibration). Returns the store for the params
/// task and the committed transmission ratio for the encoder.
pub fn boot(flash: Flash<'static, embassy_stm32::flash::Blocking>) -> (Option<Store<ParamFlash>>, f32) {
    info!(
        "joint firmware {} ({} step) starting, CANopen node {=u8}",
        env!("CARGO_PKG_VERSION"),
        <crate::hal::Step as joint_core::canopen::ControlStep>::ARITHMETIC.name(),
        NODE_ID
    );
    let flash = crate::board::param_flash(flash);
    let (base, len) = flash.window();
    info!("parameter region {=u32:#x}, {=u32} bytes", crate::board::FLASH_BASE + base, len);
    let mut store = Store::new(flash).ok();
    let (boot, comm, fault) = boot_params(store.as_mut());
    // The node latches `fault` (the storage's load fault) itself, and again after every
    // NMT reset-node.
    let node = create_node(boot, comm, fault);
    let ratio = node.params().get(ParamId::Ratio);
    NODE.lock(|n| *n.borrow_mut() = Some(node));
    (store, ratio)
}

/// Spawns the three tasks on the board's peripherals.
pub fn spawn(
    spawner: Spawner,
    encoder: QeiEncoder,
    torque: HBridgeTorque,
    wdg: IndependentWatchdog<'static, peripherals::IWDG>,
    can: can::Can<'static>,
    store: Option<Store<ParamFlash>>,
) {
    // A failed spawn is a build-time sizing error (task pool); it is logged, and the
    // IWDG, started only by the control task, then never runs: no torque either way.
    match control(encoder, torque, wdg) {
        Ok(t) => spawner.spawn(t),
        Err(_) => error!("spawning the control task failed"),
    }
    match can_task(can) {
        Ok(t) => spawner.spawn(t),
        Err(_) => error!("spawning the CAN task failed"),
    }
    match params_task(store) {
        Ok(t) => spawner.spawn(t),
        Err(_) => error!("spawning the parameter task failed"),
    }
}

#[embassy_executor::task]
async fn control(
    mut enc: QeiEncoder,
    mut out: HBridgeTorque,
    mut wdg: IndependentWatchdog<'static, peripherals::IWDG>,
) {
    let Some((mut lp, mut ratio_bits)) =
        with_node(|n| (ControlLoop::new(n.params()), n.params().get(ParamId::Ratio).to_bits()))
    else {
        error!("control: no node");
        return;
    };
    let mut period = lp.nominal_period_us();
    let mut ticker = Ticker::every(Duration::from_micros(period));
    let mut flash_ops = FLASH_OPS.load(Ordering::Relaxed);
    let mut faults = Faults::NONE;
    wdg.unleash();
    info!("control loop at {=u64} us", period);
    loop {
        ticker.next().await;
        wdg.pet();
        let position = enc.position();
        let ops = FLASH_OPS.load(Ordering::Relaxed);
        // A gap since the last tick that a flash operation explains (made while the
        // torque was off) is not a stuck loop.
        let excuse = ops != flash_ops;
        flash_ops = ops;
        let now = now_us();
        let Some((r, ratio)) = with_node(|n| {
            if excuse {
                lp.excuse_gap();
            }
            (lp.tick(n, now, position), n.params().get(ParamId::Ratio))
        }) else {
            out.disable();
            continue;
        };
        if r.drive {
            out.set_motor_torque(r.out.u_motor);
        } else {
            out.disable();
        }
        TORQUE_ACTIVE.store(r.out.tau_out != 0.0, Ordering::Relaxed);
        if ratio.to_bits() != ratio_bits {
            // Committed in pre-operational only (safety parameter), so never under torque.
            ratio_bits = ratio.to_bits();
            enc.set_ratio(ENCODER_COUNTS_PER_REV, ratio);
        }
        if lp.nominal_period_us() != period {
            period = lp.nominal_period_us();
            ticker = Ticker::every(Duration::from_micros(period));
            info!("control loop at {=u64} us", period);
        }
        if r.faults != faults {
            if !r.faults.is_empty() {
                warn!("faults {=u16:#x}", r.faults.bits());
            }
            faults = r.faults;
        }
    }
}

/// The next received frame as the node's (or why it is not one). Classic image: the HAL's
/// classic frames; FD image: its FD frames, whose header says FD and BRS.
#[cfg(not(feature = "fd"))]
async fn rx_frame(rx: &mut can::CanRx<'_>) -> Result<Result<CanFrame, can_link::Rejected>, can::enums::BusError> {
    rx.read().await.map(|env| can_link::to_core(&env.frame))
}
#[cfg(feature = "fd")]
async fn rx_frame(rx: &mut can::CanRx<'_>) -> Result<Result<CanFrame, can_link::Rejected>, can::enums::BusError> {
    rx.read_fd().await.map(|env| {
        let h = env.frame.header();
        can_link::to_core_fd(&env.frame, h.fdcan(), h.bit_rate_switching())
    })
}

#[cfg(not(feature = "fd"))]
type HalFrame = can::Frame;
#[cfg(feature = "fd")]
type HalFrame = can::frame::FdFrame;

/// The node's frame as the HAL's: FD frames (with their BRS) only in the FD image.
#[cfg(not(feature = "fd"))]
fn to_hal(f: &CanFrame) -> Option<HalFrame> {
    can_link::to_hal::<can::Frame>(f)
}
#[cfg(feature = "fd")]
fn to_hal(f: &CanFrame) -> Option<HalFrame> {
    use can::frame::Header;
    let id = embedded_can::StandardId::new(f.id())?.into();
    let h = if f.is_fd() {
        Header::new_fd(id, f.len() as u8, false, f.brs())
    } else {
        Header::new(id, f.len() as u8, false)
    };
    can::frame::FdFrame::new(h, f.data()).ok()
}

#[cfg(not(feature = "fd"))]
async fn tx_frame(tx: &mut can::CanTx<'_>, f: &HalFrame) -> Option<HalFrame> {
    tx.write(f).await
}
#[cfg(feature = "fd")]
async fn tx_frame(tx: &mut can::CanTx<'_>, f: &HalFrame) -> Option<HalFrame> {
    tx.write_fd(f).await
}

#[embassy_executor::task]
async fn can_task(can: can::Can<'static>) {
    let (mut tx, mut rx, props) = can.split();
    let mut stats = BUS_STATS.lock(|s| s.get());
    // Frames the node emits inside one lock: boot-up + SDO answer + heartbeat + EMCYs +
    // 4 TPDOs is the most one call sends.
    let mut outbox: Outbox<16> = Outbox::new();
    let mut poll = Ticker::every(NODE_POLL);
    let mut logged = stats;
    let mut next_log = Instant::now() + STATS_LOG;
    loop {
        match select(rx_frame(&mut rx), poll.next()).await {
            Either::First(Ok(f)) => {
                stats.count_rx();
                match f {
                    Ok(f) => {
                        let now = now_us();
                        with_node(|n| n.process(now, Some(&f), &mut outbox.sink()));
                    }
                    Err(_) => stats.count_rx_rejected(),
                }
            }
            Either::First(Err(_)) => stats.count_bus_error(),
            Either::Second(()) => {
                let now = now_us();
                with_node(|n| n.poll(now, &mut outbox.sink()));
            }
        }
        for f in outbox.frames() {
            let hal = to_hal(f);
            match hal {
                Some(frame) if stats.mode != BusMode::BusOff => {
                    // write() waits for a free TX buffer; bounded so a dead bus cannot
                    // park the task (and with it the node's timers).
                    match embassy_time::with_timeout(Duration::from_millis(5), tx_frame(&mut tx, &frame)).await {
                        Ok(None) => stats.count_tx(),
                        // A queued lower-priority frame was pushed out to make room.
                        Ok(Some(_)) => {
                            stats.count_tx();
                            stats.count_tx_dropped();
                        }
                        Err(_) => stats.count_tx_dropped(),
                    }
                }
                _ => stats.count_tx_dropped(),
            }
        }
        outbox.clear();
        for _ in 0..outbox.take_overflow() {
            stats.count_tx_dropped();
        }

        let mode = match props.bus_error_mode() {
            can::enums::BusErrorMode::ErrorActive => BusMode::ErrorActive,
            can::enums::BusErrorMode::ErrorPassive => BusMode::ErrorPassive,
            can::enums::BusErrorMode::BusOff => BusMode::BusOff,
        };
        match stats.observe(mode, props.rx_error_count(), props.tx_error_count()) {
            Some(can_link::BusEvent::EnteredBusOff) => {
                warn!("CAN bus-off (tec {=u8}); controller recovers automatically", stats.tec);
                with_node(|n| n.safety_mut().raise(Faults::CAN_BUS_OFF));
            }
            Some(can_link::BusEvent::Recovered) => info!("CAN recovered from bus-off"),
            Some(can_link::BusEvent::EnteredErrorPassive) => {
                warn!("CAN error-passive (rec {=u8}, tec {=u8})", stats.rec, stats.tec)
            }
            None => {}
        }
        BUS_STATS.lock(|s| s.set(stats));
        if Instant::now() >= next_log {
            next_log = Instant::now() + STATS_LOG;
            if stats != logged {
                logged = stats;
                let node_dropped = with_node(|n| n.dropped).unwrap_or(0);
                info!(
                    "CAN rx {=u32} tx {=u32} rejected {=u32} tx-dropped {=u32} bus-errors {=u32} rec {=u8} tec {=u8} bus-off {=u32} node-dropped {=u32}",
                    stats.rx_frames, stats.tx_frames, stats.rx_rejected, stats.tx_dropped, stats.bus_errors,
                    stats.rec, stats.tec, stats.bus_off_events, node_dropped
                );
            }
        }
    }
}

/// Waits until the loop commands no torque: the single-bank flash stalls every
/// instruction fetch during an operation, so it never happens under load.
async fn torque_off() {
    while TORQUE_ACTIVE.load(Ordering::Relaxed) {
        Timer::after_millis(20).await;
    }
}

/// Saves `set`, one flash operation per millisecond; torque coming back mid-save
/// abandons the attempt (the old record is intact) and starts over once it is off again.
async fn save(store: &mut Store<ParamFlash>, set: &ParamSet) -> Result<(), ()> {
    'attempt: loop {
        torque_off().await;
        store.begin_save(set).map_err(|_| ())?;
        loop {
            if TORQUE_ACTIVE.load(Ordering::Relaxed) {
                store.abort_save();
                warn!("parameter save paused: torque active");
                continue 'attempt;
            }
            let r = store.poll(set);
            count_flash_op();
            match r {
                Ok(SaveProgress::Done { .. }) => return Ok(()),
                Ok(_) => Timer::after_millis(1).await,
                Err(_) => return Err(()),
            }
        }
    }
}

/// Erases both record slots, the one without the newest record first (see
/// `firmware::storage::EraseOrder`), one page per step.
async fn erase(slot: &mut Option<Store<ParamFlash>>) -> Result<(), ()> {
    let mut store = slot.take().ok_or(())?;
    let states = match store.scan() {
        Ok(s) => s,
        Err(_) => {
            *slot = Some(store);
            return Err(());
        }
    };
    let slot_len = store.used_len() / 2;
    let mut flash = store.into_flash();
    let mut order = EraseOrder::new(states, slot_len, ParamFlash::ERASE_SIZE as u32);
    let mut result = Ok(());
    while let Some((from, to)) = order.next_page() {
        torque_off().await;
        let r = flash.erase(from, to);
        count_flash_op();
        if r.is_err() {
            result = Err(());
            break;
        }
        Timer::after_millis(1).await;
    }
    // The geometry was accepted at boot, so this succeeds; the store rescans before its
    // next save.
    *slot = Store::new(flash).ok();
    result
}

/// What the params task does for a job. The set is kept across the save's awaits in the
/// task's own storage; there is no allocator to box it into.
#[allow(clippy::large_enum_variant)]
enum Work {
    Save(ParamSet, CommSettings),
    Erase,
}

/// Takes the node's queued job. Out of line, like the two helpers below, so that the
/// parameter-set temporaries are not part of the task's poll frame (the stack is shared
/// by every task and tight: see the module doc).
#[inline(never)]
fn take_work() -> Option<Work> {
    let job = with_node(|n| n.storage_mut().take_job()).flatten()?;
    // Only committed sets reach the storage, so the check passes; a set that did not
    // would be a core bug, reported as a failed write rather than stored.
    match job {
        Job::Save(raw, comm) => match check(&raw) {
            Ok(set) => Some(Work::Save(set, comm)),
            Err(_) => {
                job_done(Err(()), None);
                None
            }
        },
        Job::Erase => Some(Work::Erase),
    }
}

/// Reports the end of a job to the node; on failure, re-reads what the flash holds.
#[inline(never)]
fn job_done(result: Result<(), ()>, store: Option<&mut Store<ParamFlash>>) {
    match result {
        Ok(()) => {
            info!("parameter store updated");
            with_node(|n| n.storage_mut().finish(Ok(())));
        }
        Err(()) => {
            error!("parameter store write failed; re-reading what the flash holds");
            let actual = boot_params(store);
            with_node(|n| {
                n.storage_mut().finish(Err(actual));
                n.safety_mut().raise(Faults::STORE_WRITE);
            });
        }
    }
}

#[embassy_executor::task]
async fn params_task(mut store: Option<Store<ParamFlash>>) {
    loop {
        STORE_WAKE.wait().await;
        let Some(work) = take_work() else {
            continue;
        };
        let result = match (work, store.as_mut()) {
            (Work::Save(set, comm), Some(s)) => match comm.stage(s) {
                Ok(()) => save(s, &set).await,
                Err(_) => Err(()),
            },
            (Work::Erase, Some(_)) => erase(&mut store).await,
            _ => Err(()),
        };
        job_done(result, store.as_mut());
    }
}
