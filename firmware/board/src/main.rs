//! Joint-board firmware for the STM32G431CB (B-G431B-ESC1).
//!
//! `main` only initialises the chip and spawns the tasks:
//! - `control`: fixed-rate loop (Ticker at `controller_rate_hz`, 1 kHz default, up to
//!   10 kHz): encoder → differentiators → `Controller::step` → safety layer → PWM; pets the
//!   independent watchdog (IWDG), so a stuck loop resets the chip;
//! - `can`: FDCAN1, classic CAN at 1 Mbit/s: received frames go to the `CAN_RX` channel
//!   for the protocol layer (the host's heartbeat 0x700 + host id is taken out here and
//!   feeds the heartbeat watchdog), frames in `CAN_TX` go out; automatic bus-off recovery
//!   (128 × 11 recessive bits, done by the controller), error counters and bus-off
//!   episodes in `BUS_STATS`;
//! - `heartbeat`: the node's own heartbeat 0x700 + node id every 100 ms;
//! - `params`: the only owner of the flash: loads the stored set at boot (defaults plus a
//!   latched fault when the region is corrupt or foreign), saves on request with the
//!   core's power-loss-safe A/B store.
//!
//! The CANopen protocol (SDO, PDO, NMT) is not here yet: nothing consumes `CAN_RX` and
//! nothing sends `PARAM_CMD` until it is.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod fw {
    use core::cell::{Cell, RefCell};
    use core::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, Ordering};

    use defmt::{error, info, warn};
    use embassy_executor::Spawner;
    use embassy_futures::select::{select3, Either3};
    use embassy_stm32::can::{self, Frame};
    use embassy_stm32::flash::Flash;
    use embassy_stm32::gpio::{OutputType, Pull};
    use embassy_stm32::peripherals;
    use embassy_stm32::time::Hertz;
    use embassy_stm32::timer::complementary_pwm::{ComplementaryPwm, ComplementaryPwmPin};
    use embassy_stm32::timer::low_level::CountingMode;
    use embassy_stm32::timer::qei::{self, Qei};
    use embassy_stm32::timer::simple_pwm::PwmPin;
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{bind_interrupts, Config};
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::blocking_mutex::Mutex;
    use embassy_sync::channel::Channel;
    use embassy_sync::signal::Signal;
    use embassy_time::{Duration, Instant, Ticker, Timer};
    use firmware::can_link::{self, BusMode, BusStats, Inbound, NmtState, NodeId};
    use firmware::control_loop::{Command, ControlLoop};
    use firmware::io::{Encoder, TorqueOutput};
    use joint_core::control::Mode;
    use joint_core::params::{ParamId, ParamSet};
    use joint_core::safety::Faults;
    use joint_core::store::{SaveProgress, Store};
    use {defmt_rtt as _, panic_probe as _};

    use crate::board::{HBridgeTorque, ParamFlash, QeiEncoder};

    /// This node's CANopen id (until the protocol layer makes it a parameter).
    const NODE_ID: u8 = 5;
    /// The host (CANopen master) whose heartbeat feeds the watchdog.
    const HOST_NODE_ID: u8 = 0x7F;
    const CAN_BITRATE: u32 = 1_000_000;
    const HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);
    /// Encoder edges per motor revolution (x4 decoding of a 1024-line encoder).
    const ENCODER_COUNTS_PER_REV: u32 = 4096;
    /// Motor torque at 100 % duty, N·m (see board::HBridgeTorque).
    const MOTOR_FULL_SCALE_NM: f32 = 0.5;
    /// IWDG timeout: long enough for a flash page erase (40 ms max, the CPU stalls on the
    /// single-bank G431), short enough that a stuck loop is caught within 0.1 s.
    const IWDG_TIMEOUT_US: u32 = 100_000;

    bind_interrupts!(struct Irqs {
        FDCAN1_IT0 => can::IT0InterruptHandler<peripherals::FDCAN1>;
        FDCAN1_IT1 => can::IT1InterruptHandler<peripherals::FDCAN1>;
    });

    type Cs = CriticalSectionRawMutex;

    /// The parameter set in force; written only by the params task, copied by the loop
    /// when `PARAMS_CHANGED` fires (one copy, inside a short critical section).
    static PARAMS: Mutex<Cs, RefCell<Option<ParamSet>>> = Mutex::new(RefCell::new(None));
    static PARAMS_CHANGED: Signal<Cs, ()> = Signal::new();
    /// Time (µs) of the latest valid host heartbeat.
    static HOST_HEARTBEAT: Signal<Cs, u64> = Signal::new();
    /// What the host asks for; set by the protocol layer.
    static COMMAND: Mutex<Cs, Cell<Command>> = Mutex::new(Cell::new(Command {
        mode: Mode::Assist,
        assist_cmd: 0.0,
        others: [0.0; 3],
    }));
    /// Faults found outside the loop (boot store, bus-off), OR-ed in, taken by the loop.
    static PENDING_FAULTS: AtomicU16 = AtomicU16::new(0);
    /// Latched faults and torque state as the loop last saw them, for reports.
    static LOOP_FAULTS: AtomicU16 = AtomicU16::new(0);
    static TORQUE_ACTIVE: AtomicBool = AtomicBool::new(false);
    /// Flash operations done so far: a change tells the loop a gap was a flash stall.
    static FLASH_OPS: AtomicU32 = AtomicU32::new(0);
    /// Frames for the protocol layer and from it.
    pub static CAN_RX: Channel<Cs, Frame, 16> = Channel::new();
    pub static CAN_TX: Channel<Cs, Frame, 16> = Channel::new();
    pub static BUS_STATS: Mutex<Cs, Cell<BusStats>> = Mutex::new(Cell::new(BusStats {
        mode: BusMode::ErrorActive,
        rec: 0,
        tec: 0,
        rx_frames: 0,
        tx_frames: 0,
        rx_dropped: 0,
        tx_dropped: 0,
        bus_errors: 0,
        error_passive_events: 0,
        bus_off_events: 0,
        recoveries: 0,
    }));

    /// Requests to the params task. Sent by the protocol layer (CANopen 0x1010 store /
    /// 0x1011 restore, issue 4), which does not exist in this image yet.
    #[allow(dead_code)]
    #[derive(Clone, Copy, defmt::Format)]
    pub enum ParamCommand {
        /// Persist the set in force.
        Save,
        /// Put the table defaults in force (not persisted until `Save`).
        RestoreDefaults,
    }
    pub static PARAM_CMD: Channel<Cs, ParamCommand, 2> = Channel::new();

    fn now_us() -> u64 {
        Instant::now().as_micros()
    }

    fn raise(f: Faults) {
        PENDING_FAULTS.fetch_or(f.bits(), Ordering::Relaxed);
    }

    fn publish(set: ParamSet) {
        PARAMS.lock(|p| *p.borrow_mut() = Some(set));
        PARAMS_CHANGED.signal(());
    }

    fn current_params() -> ParamSet {
        PARAMS.lock(|p| p.borrow().clone()).unwrap_or_default()
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let mut config = Config::default();
        {
            use embassy_stm32::rcc::*;
            // 170 MHz from HSI16 (no dependence on the board's crystal): 16/4·85/2.
            config.rcc.pll = Some(Pll {
                source: PllSource::HSI,
                prediv: PllPreDiv::DIV4,
                mul: PllMul::MUL85,
                divp: None,
                divq: None,
                divr: Some(PllRDiv::DIV2),
            });
            config.rcc.sys = Sysclk::PLL1_R;
            config.rcc.boost = true;
            config.rcc.mux.fdcansel = mux::Fdcansel::PCLK1;
        }
        let p = embassy_stm32::init(config);
        info!("joint firmware {} starting", env!("CARGO_PKG_VERSION"));

        // Parameters first: the loop must start on the stored calibration.
        let flash = ParamFlash::new(Flash::new_blocking(p.FLASH));
        let (base, len) = flash.region();
        info!("parameter region {=u32:#x}, {=u32} bytes", base, len);
        let store = match Store::new(flash) {
            Ok(mut store) => {
                let (set, fault) = store.load_or_defaults();
                if !fault.is_empty() {
                    warn!("parameter store: running on defaults or an older set, fault {=u16:#x}", fault.bits());
                    raise(fault);
                }
                publish(set);
                Some(store)
            }
            Err(_) => {
                error!("parameter region too small for two slots: defaults, nothing will be saved");
                raise(Faults::PARAMS_CORRUPT);
                publish(ParamSet::defaults());
                None
            }
        };
        let params = current_params();

        let qei = Qei::new(p.TIM4, p.PB6, p.PB7, qei::Config { ch1_pull: Pull::Up, ch2_pull: Pull::Up, ..Default::default() });
        let encoder = QeiEncoder::new(qei, ENCODER_COUNTS_PER_REV, params.get(ParamId::Ratio));
        let pwm = ComplementaryPwm::new(
            p.TIM1,
            Some(PwmPin::new(p.PA8, OutputType::PushPull)),
            Some(ComplementaryPwmPin::new(p.PC13, OutputType::PushPull)),
            Some(PwmPin::new(p.PA9, OutputType::PushPull)),
            Some(ComplementaryPwmPin::new(p.PA12, OutputType::PushPull)),
            None,
            None,
            None,
            None,
            Hertz(20_000),
            CountingMode::CenterAlignedBothInterrupts,
        );
        let torque = HBridgeTorque::new(pwm, MOTOR_FULL_SCALE_NM);
        let wdg = IndependentWatchdog::new(p.IWDG, IWDG_TIMEOUT_US);

        let mut can_cfg = can::CanConfigurator::new(p.FDCAN1, p.PA11, p.PB9, Irqs);
        can_cfg.set_bitrate(CAN_BITRATE);
        can_cfg.set_config(can_cfg.config().set_automatic_bus_off_recovery(true));
        let can = can_cfg.into_normal_mode();

        let (Ok(node), Ok(host)) = (NodeId::new(NODE_ID), NodeId::new(HOST_NODE_ID)) else {
            error!("node ids out of range");
            return;
        };
        // A failed spawn is a build-time sizing error (task pool); it is logged, and the
        // IWDG, started only by the control task, then never runs: no torque either way.
        match control(encoder, torque, wdg) {
            Ok(t) => spawner.spawn(t),
            Err(_) => error!("spawning the control task failed"),
        }
        match can_task(can, host) {
            Ok(t) => spawner.spawn(t),
            Err(_) => error!("spawning the CAN task failed"),
        }
        match heartbeat(node) {
            Ok(t) => spawner.spawn(t),
            Err(_) => error!("spawning the heartbeat task failed"),
        }
        if let Some(store) = store {
            match params_task(store) {
                Ok(t) => spawner.spawn(t),
                Err(_) => error!("spawning the parameter task failed"),
            }
        }
    }

    #[embassy_executor::task]
    async fn control(mut enc: QeiEncoder, mut out: HBridgeTorque, mut wdg: IndependentWatchdog<'static, peripherals::IWDG>) {
        let mut params = current_params();
        let mut lp = ControlLoop::new(&params, now_us());
        let mut ticker = Ticker::every(Duration::from_micros(lp.nominal_period_us()));
        let mut flash_ops = FLASH_OPS.load(Ordering::Relaxed);
        wdg.unleash();
        info!("control loop at {=u64} us", lp.nominal_period_us());
        loop {
            ticker.next().await;
            wdg.pet();
            if PARAMS_CHANGED.signaled() {
                PARAMS_CHANGED.reset();
                params = current_params();
                let old = lp.nominal_period_us();
                lp.apply_params(&params);
                if lp.nominal_period_us() != old {
                    ticker = Ticker::every(Duration::from_micros(lp.nominal_period_us()));
                }
            }
            let now = now_us();
            if let Some(t) = HOST_HEARTBEAT.try_take() {
                lp.on_heartbeat(t);
            }
            let pending = PENDING_FAULTS.swap(0, Ordering::Relaxed);
            if pending != 0 {
                lp.raise(Faults::from_bits_truncate(pending));
            }
            let ops = FLASH_OPS.load(Ordering::Relaxed);
            if ops != flash_ops {
                // The gap since the last tick was a flash stall the params task chose to
                // make while the torque was off, not a stuck loop.
                flash_ops = ops;
                lp.excuse_gap();
            }
            let cmd = COMMAND.lock(|c| c.get());
            let r = lp.tick(&params, now, enc.position(), &cmd);
            if r.gain > 0.0 {
                out.set_motor_torque(r.u_motor);
            } else {
                out.disable();
            }
            TORQUE_ACTIVE.store(r.gain > 0.0 && r.tau != 0.0, Ordering::Relaxed);
            LOOP_FAULTS.store(r.faults.bits(), Ordering::Relaxed);
            let new = lp.take_new_faults();
            if !new.is_empty() {
                warn!("fault latched: {=u16:#x}", new.bits());
            }
        }
    }

    #[embassy_executor::task]
    async fn can_task(can: can::Can<'static>, host: NodeId) {
        let (mut tx, mut rx, props) = can.split();
        let mut stats = BUS_STATS.lock(|s| s.get());
        loop {
            match select3(rx.read(), CAN_TX.receive(), Timer::after_millis(10)).await {
                Either3::First(Ok(env)) => {
                    stats.count_rx();
                    match can_link::classify(&env.frame, host) {
                        Inbound::HostHeartbeat(_) => HOST_HEARTBEAT.signal(now_us()),
                        Inbound::Other => {
                            if CAN_RX.try_send(env.frame).is_err() {
                                stats.count_rx_dropped();
                            }
                        }
                    }
                }
                Either3::First(Err(_)) => stats.count_bus_error(),
                Either3::Second(frame) => {
                    if stats.mode == BusMode::BusOff {
                        stats.count_tx_dropped();
                    } else {
                        // write() waits for a free TX buffer; bounded so a dead bus cannot
                        // park the task.
                        match embassy_time::with_timeout(Duration::from_millis(5), tx.write(&frame)).await {
                            Ok(_) => stats.count_tx(),
                            Err(_) => stats.count_tx_dropped(),
                        }
                    }
                }
                Either3::Third(()) => {}
            }
            let mode = match props.bus_error_mode() {
                can::enums::BusErrorMode::ErrorActive => BusMode::ErrorActive,
                can::enums::BusErrorMode::ErrorPassive => BusMode::ErrorPassive,
                can::enums::BusErrorMode::BusOff => BusMode::BusOff,
            };
            match stats.observe(mode, props.rx_error_count(), props.tx_error_count()) {
                Some(can_link::BusEvent::EnteredBusOff) => {
                    warn!("CAN bus-off (tec {=u8}); controller recovers automatically", stats.tec);
                    raise(Faults::CAN_BUS_OFF);
                }
                Some(can_link::BusEvent::Recovered) => info!("CAN recovered from bus-off"),
                Some(can_link::BusEvent::EnteredErrorPassive) => warn!("CAN error-passive (rec {=u8}, tec {=u8})", stats.rec, stats.tec),
                None => {}
            }
            BUS_STATS.lock(|s| s.set(stats));
        }
    }

    #[embassy_executor::task]
    async fn heartbeat(node: NodeId) {
        // CiA 301: boot-up message once, then the node is pre-operational.
        let mut state = NmtState::BootUp;
        let mut ticker = Ticker::every(HEARTBEAT_PERIOD);
        loop {
            if let Some(f) = can_link::heartbeat_frame::<Frame>(node, state) {
                if CAN_TX.try_send(f).is_err() {
                    BUS_STATS.lock(|s| {
                        let mut v = s.get();
                        v.count_tx_dropped();
                        s.set(v);
                    });
                }
            }
            state = NmtState::PreOperational;
            ticker.next().await;
        }
    }

    #[embassy_executor::task]
    async fn params_task(mut store: Store<ParamFlash>) {
        loop {
            match PARAM_CMD.receive().await {
                ParamCommand::RestoreDefaults => {
                    info!("parameters: defaults in force");
                    publish(ParamSet::defaults());
                }
                ParamCommand::Save => {
                    // The G431 has one flash bank: an erase stalls every instruction fetch
                    // for up to 40 ms. Save only while no torque is commanded, so the
                    // stall never hits a joint under load.
                    while TORQUE_ACTIVE.load(Ordering::Relaxed) {
                        Timer::after_millis(20).await;
                    }
                    let set = current_params();
                    if store.begin_save(&set).is_err() {
                        error!("parameter save could not start");
                        raise(Faults::STORE_WRITE);
                        continue;
                    }
                    loop {
                        if TORQUE_ACTIVE.load(Ordering::Relaxed) {
                            // Torque came back mid-save: stop; the old record is intact.
                            store.abort_save();
                            warn!("parameter save aborted: torque active");
                            break;
                        }
                        let r = store.poll(&set);
                        FLASH_OPS.fetch_add(1, Ordering::Relaxed);
                        match r {
                            Ok(SaveProgress::Done { .. }) => {
                                info!("parameters saved");
                                break;
                            }
                            Ok(_) => Timer::after_millis(1).await,
                            Err(_) => {
                                error!("parameter save failed; the previous set is intact");
                                raise(Faults::STORE_WRITE);
                                break;
                            }
                        }
                    }
                }
            }
        }
    }

    /// Latched faults as the loop last saw them (for status reports of the protocol layer,
    /// issue 4).
    #[allow(dead_code)]
    pub fn loop_faults() -> Faults {
        Faults::from_bits_truncate(LOOP_FAULTS.load(Ordering::Relaxed))
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the joint firmware runs on the STM32G431: cargo fw-build (thumbv7em-none-eabihf)");
    std::process::exit(2);
}
