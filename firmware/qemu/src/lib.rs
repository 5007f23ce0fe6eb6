//! Support for the joint core's test and benchmark images on QEMU's `mps2-an386`.
//!
//! These images run the real `joint_core` code on an emulated Cortex-M4F and talk to the
//! host only through semihosting: text on stdout, an exact exit status, nothing else. The
//! pieces here are what every image needs besides cortex-m-rt (which starts them as it starts
//! the boards): fault handlers and a panic handler that exit through semihosting instead of
//! spinning on `udf` like panic-probe does ([`rt`]), and the SysTick counter the benchmark reads.
//! [`canopen_session`] is the scripted CANopen session of the `qemu-canopen` image; it is
//! plain `joint_core` code and also builds on the host (the parity test includes the same
//! file). Everything else is empty on the host, so a host `cargo check` of this workspace stays green.
#![cfg_attr(target_os = "none", no_std)]

#[cfg(target_os = "none")]
pub mod canopen_image;
pub mod canopen_session;
#[cfg(target_os = "none")]
pub mod rt;
#[cfg(target_os = "none")]
pub mod systick;

#[cfg(target_os = "none")]
pub use semihosting;

/// `core::fmt::Write` to semihosting stdout, one SYS_WRITE per line instead of one per
/// `write_str` (a semihosting call is a trap into QEMU; thousands of lines add up).
#[cfg(target_os = "none")]
pub struct LineOut {
    out: semihosting::io::Stdout,
    buf: [u8; 160],
    len: usize,
}

#[cfg(target_os = "none")]
impl LineOut {
    pub fn stdout() -> Option<Self> {
        semihosting::io::stdout().ok().map(|out| LineOut { out, buf: [0; 160], len: 0 })
    }

    pub fn flush(&mut self) -> core::fmt::Result {
        use semihosting::io::Write as _;
        let pending = self.buf.get(..self.len).ok_or(core::fmt::Error)?;
        self.out.write_all(pending).map_err(|_| core::fmt::Error)?;
        self.len = 0;
        Ok(())
    }
}

#[cfg(target_os = "none")]
impl core::fmt::Write for LineOut {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for &b in s.as_bytes() {
            if self.len == self.buf.len() {
                self.flush()?;
            }
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
            if b == b'\n' {
                self.flush()?;
            }
        }
        Ok(())
    }
}

#[cfg(target_os = "none")]
impl Drop for LineOut {
    fn drop(&mut self) {
        let _ = self.flush();
    }
}

/// Exit status of an image whose checks failed (as opposed to a panic, which is 1, and a
/// CPU fault, which is 3): scripts tell the three apart.
pub const EXIT_CHECK_FAILED: i32 = 2;
/// Exit status after a HardFault or another fault exception.
pub const EXIT_FAULT: i32 = 3;

/// Declares the image's entry point: `firmware_qemu::entry!(main);` with `fn main() -> i32`.
/// The returned value becomes QEMU's exit status through semihosting's SYS_EXIT_EXTENDED.
#[macro_export]
macro_rules! entry {
    ($main:path) => {
        // cortex-m-rt's reset handler calls `main` (what its #[entry] attribute exports)
        #[export_name = "main"]
        pub extern "C" fn __qemu_entry() -> ! {
            let f: fn() -> i32 = $main;
            let code = f();
            $crate::semihosting::process::exit(code)
        }
    };
}

/// Host build of an image: says where it belongs instead of pretending to run.
#[cfg(not(target_os = "none"))]
pub fn host_main(name: &str) {
    eprintln!(
        "{name} is a test image for qemu-system-arm -M mps2-an386 (thumbv7em-none-eabihf, \
         scripts/qemu-test.sh) or -M mps2-an385 (thumbv6m-none-eabi, scripts/qemu-test-m0.sh)"
    );
    std::process::exit(2);
}
