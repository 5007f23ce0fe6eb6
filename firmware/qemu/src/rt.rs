//! The smallest runtime that runs Rust on QEMU's mps2-an386 (no cortex-m-rt; see qemu.x
//! for why): a vector table, a reset handler that enables the FPU before any float code,
//! zeroes .bss and copies .data, then jumps to the image's `__qemu_entry`, and fault
//! handlers that report through semihosting and exit instead of locking up QEMU.

use core::panic::PanicInfo;

// Reset is written in assembly so that nothing touches an FPU register (or the .bss/.data
// the compiler may assume initialised) before CPACR grants access to CP10/CP11.
#[cfg(not(armv6m))]
core::arch::global_asm!(
    ".section .text.Reset,\"ax\",%progbits",
    ".global Reset",
    ".type Reset,%function",
    ".thumb_func",
    "Reset:",
    // CPACR (0xE000_ED88): full access to CP10 and CP11 (the FPU).
    "    ldr r0, =0xE000ED88",
    "    ldr r1, [r0]",
    "    orr r1, r1, #0x00F00000",
    "    str r1, [r0]",
    "    dsb",
    "    isb",
    "    ldr r0, =__sbss",
    "    ldr r1, =__ebss",
    "    movs r2, #0",
    "1:  cmp r0, r1",
    "    bhs 2f",
    "    str r2, [r0], #4",
    "    b 1b",
    "2:  ldr r0, =__sdata",
    "    ldr r1, =__edata",
    "    ldr r2, =__sidata",
    "3:  cmp r0, r1",
    "    bhs 4f",
    "    ldr r3, [r2], #4",
    "    str r3, [r0], #4",
    "    b 3b",
    "4:  bl __qemu_entry",
    "    b 4b",
    ".ltorg",
    ".size Reset, . - Reset",
);

// The thumbv6m images (Cortex-M0+ instruction set, run on mps2-an385's Cortex-M3): no FPU to
// enable, and Thumb-1 has no post-indexed stores, so the pointers are advanced by hand.
#[cfg(armv6m)]
core::arch::global_asm!(
    ".section .text.Reset,\"ax\",%progbits",
    ".global Reset",
    ".type Reset,%function",
    ".thumb_func",
    "Reset:",
    "    ldr r0, =__sbss",
    "    ldr r1, =__ebss",
    "    movs r2, #0",
    "1:  cmp r0, r1",
    "    bhs 2f",
    "    str r2, [r0]",
    "    adds r0, #4",
    "    b 1b",
    "2:  ldr r0, =__sdata",
    "    ldr r1, =__edata",
    "    ldr r2, =__sidata",
    "3:  cmp r0, r1",
    "    bhs 4f",
    "    ldr r3, [r2]",
    "    str r3, [r0]",
    "    adds r0, #4",
    "    adds r2, #4",
    "    b 3b",
    "4:  bl __qemu_entry",
    "    b 4b",
    ".ltorg",
    ".size Reset, . - Reset",
);

extern "C" {
    fn Reset() -> !;
}

/// Exception vectors 1..=15 (the initial stack pointer is word 0, written by qemu.x).
#[link_section = ".vector_table.exceptions"]
#[no_mangle]
#[used]
pub static __VECTORS: [unsafe extern "C" fn() -> !; 15] = [
    Reset, // 1 reset
    fault, // 2 NMI
    fault, // 3 HardFault
    fault, // 4 MemManage
    fault, // 5 BusFault
    fault, // 6 UsageFault
    fault, // 7..=10 reserved: never taken, but a valid address is cheaper than a hole
    fault, fault, fault, fault, // 11 SVCall
    fault, // 12 DebugMonitor
    fault, // 13 reserved
    fault, // 14 PendSV
    fault, // 15 SysTick (the images poll SysTick with its interrupt disabled)
];

unsafe extern "C" fn fault() -> ! {
    // ICSR.VECTACTIVE names the exception, enough to tell a HardFault from a stray IRQ.
    // SAFETY: ICSR is an always-readable System Control Block register.
    let icsr = unsafe { core::ptr::read_volatile(0xE000_ED04 as *const u32) };
    semihosting::eprintln!("fault: exception {} (ICSR {:#010x})", icsr & 0x1FF, icsr);
    semihosting::process::exit(crate::EXIT_FAULT)
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    semihosting::eprintln!("panicked: {}", info);
    semihosting::process::exit(1)
}
