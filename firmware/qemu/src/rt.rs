//! What the images add to cortex-m-rt (which starts them as it starts the boards: vector table,
//! .bss/.data, the FPU enabled on thumbv7em-none-eabihf before `main`): fault and stray
//! interrupt handlers that report through semihosting and exit instead of locking up QEMU, and
//! a panic handler that does the same (panic-probe would hang QEMU).

use core::panic::PanicInfo;
use cortex_m_rt::{exception, ExceptionFrame};

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    semihosting::eprintln!("fault: HardFault at pc {:#010x}", ef.pc());
    semihosting::process::exit(crate::EXIT_FAULT)
}

#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    // every other exception or interrupt: the images poll SysTick with its interrupt off, so
    // anything taken here is a fault of the image
    semihosting::eprintln!("fault: exception {irqn}");
    semihosting::process::exit(crate::EXIT_FAULT)
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    semihosting::eprintln!("panicked: {}", info);
    semihosting::process::exit(1)
}
