//! The joint core on another HAL: an STM32F405 (e.g. an Olimex STM32-E407 or any F405 board
//! with a CAN transceiver on PB8/PB9) through `stm32f4xx-hal`, which none of the project's
//! boards use. It is the example of docs/porting.md, everything a board supplies and nothing
//! else, in one super-loop (no executor):
//!
//! 1. CAN: bxCAN through `bxcan`, whose frames are `embedded_can::Frame`s, so the core's
//!    `canopen::hal` converts them (no conversion code here);
//! 2. flash: the HAL's `UnlockedFlash` is an `embedded-storage` `NorFlash`; the core's
//!    `Region` windows sectors 10–11 for the parameter store (memory.x keeps them out of the
//!    image);
//! 3. the control loop: the core's `ControlLoop` at the committed rate, the angle from TIM3 in
//!    quadrature mode, the motor command as a duty on TIM1 CH1 (an H-bridge's input);
//! 4. time: the cycle counter at 168 MHz.
//!
//! Built in `scripts/test.sh` for thumbv7em-none-eabihf; it has not run on hardware.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("port-f4 is a firmware image: cargo build --release --target thumbv7em-none-eabihf");
}

#[cfg(target_os = "none")]
mod image {
    use bxcan::filter::Mask32;
    use bxcan::Fifo;
    use cortex_m_rt::entry;
    use joint_core::canopen::hal::{to_core, to_hal};
    use joint_core::canopen::outbox::Outbox;
    use joint_core::canopen::storage::FlashStorage;
    use joint_core::canopen::{Node, NodeConfig};
    use joint_core::control::Controller;
    use joint_core::control_loop::ControlLoop;
    use joint_core::store::{Region, Store};
    use panic_halt as _;
    use stm32f4xx_hal::flash::{FlashExt, LockedFlash};
    use stm32f4xx_hal::rcc::Config;
    use stm32f4xx_hal::{pac, prelude::*, qei::Qei};

    const NODE_ID: u8 = 7;
    /// The parameter store: sectors 10 and 11, as offsets from the flash base (memory.x).
    const PARAM_OFFSET: u32 = 0x000C_0000;
    const PARAM_LEN: u32 = 0x0004_0000;
    /// Encoder counts per joint radian (a 1000-line encoder in x4 mode behind a 1:50 gear).
    const COUNTS_PER_RAD: f32 = 4000.0 * 50.0 / core::f32::consts::TAU;
    /// Motor torque for a full duty swing (the H-bridge's ±1 at its full scale), N·m.
    const FULL_SCALE_NM: f32 = 2.0;
    const SYSCLK_HZ: u32 = 168_000_000;

    /// µs since boot from the cycle counter, extended past its 25.6 s wrap.
    struct Clock {
        last: u32,
        high: u64,
    }

    impl Clock {
        fn now_us(&mut self) -> u64 {
            let c = cortex_m::peripheral::DWT::cycle_count();
            if c < self.last {
                self.high += 1 << 32;
            }
            self.last = c;
            (self.high + u64::from(c)) / u64::from(SYSCLK_HZ / 1_000_000)
        }
    }

    #[entry]
    fn main() -> ! {
        let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
            loop {
                cortex_m::asm::wfi();
            }
        };
        let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
        let mut clock = Clock { last: 0, high: 0 };

        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiob = dp.GPIOB.split(&mut rcc);

        // 1. CAN1 on PB8 (RX) / PB9 (TX), 1 Mbit/s from PCLK1 = 42 MHz: BRP 3, 1 + 11 + 2 tq
        let can = dp.CAN1.can((gpiob.pb9, gpiob.pb8), &mut rcc);
        let mut can = bxcan::Can::builder(can).set_bit_timing(0x001a_0002).enable();
        can.modify_filters().enable_bank(0, Fifo::Fifo0, Mask32::accept_all());

        // 3. the angle (TIM3 on PA6/PA7 in quadrature mode) and the drive (TIM1 CH1 on PA8)
        let qei = Qei::new(dp.TIM3, (gpioa.pa6, gpioa.pa7), &mut rcc);
        let (_, (ch1, ..)) = dp.TIM1.pwm_us(50.micros(), &mut rcc);
        let mut pwm = ch1.with(gpioa.pa8);
        let max_duty = pwm.get_max_duty();
        pwm.set_duty(max_duty / 2);
        pwm.enable();

        // 2. the parameter store in its flash window, the node on it
        let mut flash = LockedFlash::new(dp.FLASH);
        let mut unlocked = flash.unlocked();
        let Ok(store) = Store::new(Region::new(&mut unlocked, PARAM_OFFSET, PARAM_LEN)) else {
            loop {
                cortex_m::asm::wfi();
            }
        };
        let now = clock.now_us();
        let mut node: Node<_, Controller> = Node::with_step(NodeConfig::new(NODE_ID), FlashStorage::new(store), now);
        let mut control = ControlLoop::new(node.params());
        let mut outbox: Outbox<16> = Outbox::new();
        let mut next_tick = now;
        let (mut last_count, mut turns) = (qei.count(), 0i64);

        loop {
            let now = clock.now_us();
            // CAN in: what the node does not serve is dropped (to_core says why)
            if let Ok(rx) = can.receive() {
                if let Ok(f) = to_core(&rx) {
                    node.process(now, Some(&f), &mut |out| outbox.push(out));
                }
            }
            node.poll(now, &mut |out| outbox.push(out));
            // CAN out, outside any lock; a full mailbox drops the frame (counted by the node's
            // peer as a missing one, as on a busy bus)
            for f in outbox.frames() {
                if let Some(hw) = to_hal::<bxcan::Frame>(f) {
                    let _ = can.transmit(&hw);
                }
            }
            outbox.clear();

            if now >= next_tick {
                next_tick = now + control.nominal_period_us();
                // the 16-bit counter unwrapped into a joint angle
                let c = qei.count();
                let d = i64::from(c.wrapping_sub(last_count) as i16);
                last_count = c;
                turns += d;
                let q = turns as f32 / COUNTS_PER_RAD;
                let t = control.tick(&mut node, now, Ok::<f32, ()>(q));
                let x = if t.drive { (t.out.u_motor / FULL_SCALE_NM).clamp(-1.0, 1.0) } else { 0.0 };
                let duty = ((0.5 + 0.5 * x) * f32::from(max_duty)) as u16;
                pwm.set_duty(duty);
            }
        }
    }
}
