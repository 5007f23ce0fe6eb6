//! Joint-board firmware for the STM32G431CB (B-G431B-ESC1): a CANopen joint node.
//!
//! The board runs the core's sans-IO CANopen node ([`joint_core::canopen::Node`]: NMT,
//! heartbeat producer and consumer, SDO, EMCY, TPDOs, RPDOs, staged/committed parameters),
//! which lives in one blocking mutex (`NODE`, a critical section) shared by the tasks; every
//! lock is held for one call into the node and no I/O happens inside it. `main` only
//! initialises the chip, reads the parameter store, creates the node and spawns the tasks:
//! - `control`: fixed-rate loop (Ticker at the committed `controller_rate_hz`, 1 kHz
//!   default, up to 10 kHz): encoder → differentiators → `node.control` (controller with the
//!   committed set, NMT mode, the host's RPDO commands, heartbeat watchdog with torque fade)
//!   → PWM; pets the independent watchdog (IWDG), so a stuck loop resets the chip;
//! - `can`: FDCAN1, classic CAN at 1 Mbit/s: every received frame goes to
//!   `node.process(now, Some(&frame), tx)` (extended-id, remote and over-long frames are
//!   counted and dropped), a 1 ms tick calls `node.poll` (heartbeat, TPDO event timers, SDO
//!   timeouts, EMCY); what the node emits is collected during the lock and written to the
//!   controller afterwards. Automatic bus-off recovery (128 × 11 recessive bits, done by the
//!   controller) latches `CAN_BUS_OFF` in the node (EMCY 0x8140); error counters, bus-off
//!   episodes and dropped frames are in `BUS_STATS` and logged over defmt (the node's object
//!   dictionary has no object for them yet);
//! - `params`: the only owner of the flash: loads the stored set at boot (defaults plus a
//!   latched fault when the region is corrupt, foreign or refused), then serves the node's
//!   0x1010 store and 0x1011 restore requests handed over by [`firmware::storage`], with the
//!   core's incremental power-loss-safe A/B store, one flash operation at a time and only
//!   while no torque is commanded (the single-bank G431 stalls on erase).
//!
//! Not here: node id and bit rate are compile-time constants (no LSS, no DIP switches);
//! CAN FD is not enabled; the torque stage is an open-loop H-bridge for a brushed motor
//! (see `board.rs`); the bus counters have no object in the node's dictionary (defmt only).
//!
//! # Memory (not run on a board yet)
//! - **Stack**: the G431 has 32 KiB of RAM; static data takes 9.6 KiB (`scripts/fw-size.sh`).
//!   Building the node with a stored set peaks at 16.6 KiB of stack on a Cortex-M4F,
//!   measured by stack painting in the `qemu-canopen` image and checked (≤ 20 KiB) by
//!   `scripts/qemu-test.sh`. The core puts parameter sets in force in place and a gravity table
//!   holds at most 128 values, which is what brought this down from 33 KiB.
//! - **Flash**: 63.0 KiB of the 64 KiB budget; the node's commit-error text avoids float
//!   formatting (≈ 13 KiB of `core::fmt`) for that reason.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod app;
#[cfg(target_os = "none")]
mod board;

/// What `app.rs` and `board.rs` take from this board: its timers and its control step.
#[cfg(target_os = "none")]
mod hal {
    pub type EncoderTimer = embassy_stm32::peripherals::TIM4;
    pub type PwmTimer = embassy_stm32::peripherals::TIM1;
    /// Erase granularity of the G431's flash (memory.x's `__param_page_size`).
    pub const PARAM_PAGE: usize = 2048;
    /// The G431 has an FPU: f32 unless built with `--features q16`.
    #[cfg(not(feature = "q16"))]
    pub type Step = joint_core::control::Controller;
    #[cfg(feature = "q16")]
    pub type Step = joint_core::fixed::ControllerFx;
}

#[cfg(target_os = "none")]
mod fw {
    use embassy_executor::Spawner;
    use embassy_stm32::can;
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

    use crate::app::{self, CAN_BITRATE, ENCODER_COUNTS_PER_REV, IWDG_TIMEOUT_US, MOTOR_FULL_SCALE_NM};
    use crate::board::{HBridgeTorque, QeiEncoder};

    // the FD image's nominal rate is the classic image's: 170 MHz / 170 tq
    #[cfg(feature = "fd")]
    const _: () = assert!(170_000_000 / (1 + 135 + 34) == CAN_BITRATE);

    bind_interrupts!(struct Irqs {
        FDCAN1_IT0 => can::IT0InterruptHandler<peripherals::FDCAN1>;
        FDCAN1_IT1 => can::IT1InterruptHandler<peripherals::FDCAN1>;
    });

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
        // Parameters first: the node must start on the stored calibration.
        let (store, ratio) = app::boot(Flash::new_blocking(p.FLASH));

        let qei = Qei::new(
            p.TIM4,
            p.PB6,
            p.PB7,
            qei::Config { ch1_pull: Pull::Up, ch2_pull: Pull::Up, ..Default::default() },
        );
        let encoder = QeiEncoder::new(qei, ENCODER_COUNTS_PER_REV, ratio);
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
        #[cfg(not(feature = "fd"))]
        can_cfg.set_bitrate(CAN_BITRATE);
        #[cfg(feature = "fd")]
        can_cfg.set_config(crate::fd::timing(can_cfg.config()));
        can_cfg.set_config(can_cfg.config().set_automatic_bus_off_recovery(true));
        let can = can_cfg.into_normal_mode();
        #[cfg(feature = "fd")]
        crate::fd::enable_delay_compensation();

        app::spawn(spawner, encoder, torque, wdg, can, store);
    }
}

/// CAN FD bit timing of the G431 image (feature `fd`). The FDCAN kernel clock is PCLK1 =
/// 170 MHz (fdcansel above; APB1 undivided), one time quantum 5.88 ns with prescaler 1 in both
/// phases — CiA 601-3 recommends the same quantum for both, so the phases' edges line up:
///
/// | phase | rate | tq/bit | sync + TSEG1 + TSEG2 | sample point | SJW |
/// |---|---|---|---|---|---|
/// | nominal (arbitration) | 1 Mbit/s | 170 | 1 + 135 + 34 | 80.0 % | 34 |
/// | data (BRS) | 5 Mbit/s | 34 | 1 + 25 + 8 | 76.5 % | 8 |
///
/// Register ranges (RM0440 FDCAN_NBTP/DBTP): NTSEG1 ≤ 256, NTSEG2 ≤ 128, DTSEG1 ≤ 32,
/// DTSEG2 ≤ 16, DSJW ≤ 16; embassy writes value − 1. At 5 Mbit/s a bit is 200 ns, shorter
/// than the transceiver loop delay (TX→bus→RX, ≈ 100–250 ns for a TCAN/MCP2562FD-class
/// part), so the transmitter samples its own bits at a secondary sample point: transceiver
/// delay compensation (DBTP.TDC) with offset TDCO = DBRP × DTSEG1 = 25 mtq after the measured
/// delay (ST's HAL examples and AN5348), filter window TDCF 0 (off). embassy-stm32 0.6 does
/// not write TDCR, so [`enable_delay_compensation`] does it through the PAC.
#[cfg(all(target_os = "none", feature = "fd"))]
mod fd {
    use core::num::{NonZeroU16, NonZeroU8};
    use embassy_stm32::can::config::{DataBitTiming, FdCanConfig, FrameTransmissionConfig, NominalBitTiming};

    const fn nz8(v: u8) -> NonZeroU8 {
        match NonZeroU8::new(v) {
            Some(n) => n,
            None => NonZeroU8::MIN,
        }
    }

    /// Nominal 1 Mbit/s, data 5 Mbit/s, FD frames with bit-rate switch allowed.
    pub fn timing(c: FdCanConfig) -> FdCanConfig {
        let nominal =
            NominalBitTiming { prescaler: NonZeroU16::MIN, seg1: nz8(135), seg2: nz8(34), sync_jump_width: nz8(34) };
        let data = DataBitTiming {
            transceiver_delay_compensation: true,
            prescaler: NonZeroU16::MIN,
            seg1: nz8(25),
            seg2: nz8(8),
            sync_jump_width: nz8(8),
        };
        c.set_nominal_bit_timing(nominal)
            .set_data_bit_timing(data)
            .set_frame_transmit(FrameTransmissionConfig::AllowFdCanAndBRS)
    }

    /// TDCO/TDCF and DBTP.TDC, which are writable only in configuration mode (CCCR.INIT and
    /// CCE): enter it, write, leave (the controller then waits for 11 recessive bits to join
    /// the bus again). Called once, right after the controller started.
    pub fn enable_delay_compensation() {
        let r = embassy_stm32::pac::FDCAN1;
        r.cccr().modify(|w| w.set_init(true));
        while !r.cccr().read().init() {}
        r.cccr().modify(|w| w.set_cce(true));
        r.tdcr().write(|w| {
            w.set_tdco(25);
            w.set_tdcf(0);
        });
        r.dbtp().modify(|w| w.set_tdc(true));
        r.cccr().modify(|w| w.set_cce(false));
        r.cccr().modify(|w| w.set_init(false));
        while r.cccr().read().init() {}
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the joint firmware runs on the STM32G431: cargo fw-build (thumbv7em-none-eabihf)");
    std::process::exit(2);
}
