//! SysTick as a cost meter. Under `qemu-system-arm -icount shift=N` virtual time advances
//! 2^N ns per executed instruction, and mps2-an386 clocks SysTick from its 25 MHz system
//! clock, so the count is a repeatable instruction counter (DWT CYCCNT reads 0 in QEMU).
//! At shift=7 one instruction is 128 ns = 3.2 SysTick ticks; the bench measures that
//! ratio itself with a loop of known length rather than trusting this arithmetic.

const SYST_CSR: *mut u32 = 0xE000_E010 as *mut u32;
const SYST_RVR: *mut u32 = 0xE000_E014 as *mut u32;
const SYST_CVR: *mut u32 = 0xE000_E018 as *mut u32;

/// The counter is 24 bits wide and counts down.
pub const MASK: u32 = 0x00FF_FFFF;

/// Free-running, processor clock, no interrupt.
pub fn start() {
    // SAFETY: SysTick registers exist on every Cortex-M4; nothing else in the image uses them.
    unsafe {
        core::ptr::write_volatile(SYST_CSR, 0);
        core::ptr::write_volatile(SYST_RVR, MASK);
        core::ptr::write_volatile(SYST_CVR, 0);
        core::ptr::write_volatile(SYST_CSR, 0b101);
    }
}

/// Current down-counter value.
#[inline(always)]
pub fn now() -> u32 {
    // SAFETY: read-only access to the SysTick current value register.
    unsafe { core::ptr::read_volatile(SYST_CVR) }
}

/// Ticks from `start` to `end` (down-counter, one wrap at most: keep spans < 2^24 ticks).
#[inline(always)]
pub fn elapsed(start: u32, end: u32) -> u32 {
    start.wrapping_sub(end) & MASK
}
