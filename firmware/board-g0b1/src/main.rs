//! Joint-board firmware for the STM32G0B1 (Cortex-M0+ at 64 MHz, no FPU, two FDCAN; e.g. the
//! NUCLEO-G0B1RE with a CAN transceiver and an H-bridge wired to it): the same CANopen joint
//! node, tasks, parameter store and watchdogs as the G431 image, whose `app.rs` (the tasks)
//! and `board.rs` (encoder, H-bridge, parameter flash) this crate includes unchanged. Only
//! the HAL set-up is here: clocks, pins, interrupts, the memory map (`memory.x`).
//!
//! The control step is Q16.16 by default (cargo feature `q16`): on a part without an FPU every
//! f32 operation is a library call, and the Q16.16 full step takes 0.40x the instructions of
//! the soft-float one, 0.26–0.51x with a gravity table or series (scripts/fw-bench.sh). Both steps
//! have every term; `--no-default-features` builds the f32 one. The node names its step in its
//! identity (0x1018 product code 0x4A4E0002, 0x1008 "joint-node q16.16").
//!
//! Pins (NUCLEO-G0B1RE morpho headers; PA11/PA12 are the Nucleo's USB): FDCAN1 RX PD0,
//! TX PD1; encoder TIM3 CH1/CH2 on PB4/PB5; H-bridge TIM1 CH1/CH1N PA8/PB13 and CH2/CH2N
//! PA9/PB14. FDCAN1's interrupt lines are shared with TIM16/TIM17 on this part.
//!
//! Not run on a board yet (no G0B1 here): it builds, links, and its size is checked
//! (scripts/fw-size.sh g0b1). What runs under QEMU is the core and the node on the same
//! instruction set (scripts/qemu-test.sh m0). The FDCAN filter set-up is embassy's default
//! (accept all standard and extended ids into FIFO 0); an open report says a G0B1 drops
//! standard-id frames with some filter configurations, which this default does not use:
//! check it on the first board.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[path = "../../board/src/app.rs"]
mod app;
#[cfg(target_os = "none")]
#[path = "../../board/src/board.rs"]
mod board;

/// What `app.rs` and `board.rs` take from this board: its timers, flash page and control step.
#[cfg(target_os = "none")]
mod hal {
    pub type EncoderTimer = embassy_stm32::peripherals::TIM3;
    pub type PwmTimer = embassy_stm32::peripherals::TIM1;
    /// Erase granularity of the G0B1's flash (memory.x's `__param_page_size`).
    pub const PARAM_PAGE: usize = 2048;
    #[cfg(feature = "q16")]
    pub type Step = joint_core::fixed::ControllerFx;
    #[cfg(not(feature = "q16"))]
    pub type Step = joint_core::control::Controller;
}

#[cfg(feature = "fd")]
compile_error!("CAN FD is not built for the G0B1 yet: 64 MHz gives no exact 5 Mbit/s data phase (see Cargo.toml)");

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

    bind_interrupts!(struct Irqs {
        TIM16_FDCAN_IT0 => can::IT0InterruptHandler<peripherals::FDCAN1>;
        TIM17_FDCAN_IT1 => can::IT1InterruptHandler<peripherals::FDCAN1>;
    });

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let mut config = Config::default();
        {
            use embassy_stm32::rcc::*;
            // 64 MHz from HSI16 (no dependence on a crystal): 16·8/2, VCO at 128 MHz.
            config.rcc.pll = Some(Pll {
                source: PllSource::HSI,
                prediv: PllPreDiv::DIV1,
                mul: PllMul::MUL8,
                divp: None,
                divq: None,
                divr: Some(PllRDiv::DIV2),
            });
            config.rcc.sys = Sysclk::PLL1_R;
            config.rcc.mux.fdcansel = mux::Fdcansel::PCLK1;
        }
        let p = embassy_stm32::init(config);
        // Parameters first: the node must start on the stored calibration.
        let (store, ratio) = app::boot(Flash::new_blocking(p.FLASH));

        let qei = Qei::new(
            p.TIM3,
            p.PB4,
            p.PB5,
            qei::Config { ch1_pull: Pull::Up, ch2_pull: Pull::Up, ..Default::default() },
        );
        let encoder = QeiEncoder::new(qei, ENCODER_COUNTS_PER_REV, ratio);
        let pwm = ComplementaryPwm::new(
            p.TIM1,
            Some(PwmPin::new(p.PA8, OutputType::PushPull)),
            Some(ComplementaryPwmPin::new(p.PB13, OutputType::PushPull)),
            Some(PwmPin::new(p.PA9, OutputType::PushPull)),
            Some(ComplementaryPwmPin::new(p.PB14, OutputType::PushPull)),
            None,
            None,
            None,
            None,
            Hertz(20_000),
            CountingMode::CenterAlignedBothInterrupts,
        );
        let torque = HBridgeTorque::new(pwm, MOTOR_FULL_SCALE_NM);
        let wdg = IndependentWatchdog::new(p.IWDG, IWDG_TIMEOUT_US);

        let mut can_cfg = can::CanConfigurator::new(p.FDCAN1, p.PD0, p.PD1, Irqs);
        can_cfg.set_bitrate(CAN_BITRATE);
        can_cfg.set_config(can_cfg.config().set_automatic_bus_off_recovery(true));
        let can = can_cfg.into_normal_mode();

        app::spawn(spawner, encoder, torque, wdg, can, store);
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the G0B1 joint firmware runs on the STM32G0B1: cargo fw-build-g0 (thumbv6m-none-eabi)");
    std::process::exit(2);
}
