//! What a board does when the firmware has a bug: a panic or a hard fault.
//!
//! node-fw reports bad input to the host as error messages, so neither should
//! ever happen; when one does, its place must reach someone. On a real board
//! panic-probe prints the panic over defmt's RTT channel, which probe-rs shows
//! with a backtrace, and the board stops. On an emulated board the place goes
//! to QEMU's standard output through semihosting (host-tool passes what an
//! emulator said on into its error), and the emulation ends, so the host
//! hears at once that the link closed.

use cortex_m_rt::{ExceptionFrame, exception};

#[cfg(feature = "stm32f413")]
use panic_probe as _;

/// Tells the host (QEMU's standard output) where the firmware failed.
#[cfg(not(feature = "stm32f413"))]
fn say(parts: &[&[u8]]) {
    if let Ok(mut out) = cortex_m_semihosting::hio::hstdout() {
        for part in parts {
            let _ = out.write_all(part);
        }
    }
}

/// `n` in decimal, in `buf`'s tail (no formatting machinery: the small
/// image has no room for it).
#[cfg(not(feature = "stm32f413"))]
fn decimal(mut n: u32, buf: &mut [u8; 10]) -> &[u8] {
    let mut start = buf.len();
    for slot in buf.iter_mut().rev() {
        *slot = b'0' + (n % 10) as u8;
        start -= 1;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    buf.get(start..).unwrap_or_default()
}

/// `n` as eight hex digits.
#[cfg(not(feature = "stm32f413"))]
fn hex(n: u32) -> [u8; 8] {
    let mut out = [0u8; 8];
    for (i, digit) in out.iter_mut().enumerate() {
        let nibble = (n >> (28 - 4 * i)) & 0xF;
        *digit = b"0123456789abcdef".get(nibble as usize).copied().unwrap_or(b'?');
    }
    out
}

#[cfg(not(feature = "stm32f413"))]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let mut line = [0u8; 10];
    match info.location() {
        Some(at) => say(&[
            b"node firmware panicked at ",
            at.file().as_bytes(),
            b":",
            decimal(at.line(), &mut line),
            b"\n",
        ]),
        None => say(&[b"node firmware panicked\n"]),
    }
    crate::board::active::exit(false)
}

/// A hard fault: the program counter where it struck goes out as a panic's
/// place does.
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    #[cfg(feature = "stm32f413")]
    {
        defmt::error!("hard fault at pc {=u32:#010x}", frame.pc());
        crate::board::active::exit(false)
    }
    #[cfg(not(feature = "stm32f413"))]
    {
        say(&[b"node firmware hard fault at pc 0x", &hex(frame.pc()), b"\n"]);
        crate::board::active::exit(false)
    }
}
