//! A boot counter in RAM that a reset leaves alone: each start of the node
//! gets a new incarnation for its links, so its peers notice a restart.
//!
//! The counter lives in `.uninit` (cortex-m-rt does not zero or load it). A
//! warm reset (watchdog, reset pin, debugger) keeps it and the count goes on;
//! at power-up the RAM holds no valid mark and the count starts from whatever
//! the cells hold, which on real SRAM differs from one power-up to the next.
//! An emulator that zeroes RAM at launch starts from 1 every time, so a
//! relaunched QEMU node is caught by the host's time-out instead.
#![allow(unsafe_code)]

use core::mem::MaybeUninit;

/// Marks the counter as written by this firmware.
const MARK: u32 = 0x1D0C_B007;

#[unsafe(link_section = ".uninit.BOOT_COUNT")]
static mut BOOT_COUNT: MaybeUninit<[u32; 2]> = MaybeUninit::uninit();

/// Counts this start and returns its incarnation (never the previous one).
/// Call once, before the links first transmit.
pub fn next_incarnation() -> u32 {
    let cell = (&raw mut BOOT_COUNT).cast::<u32>();
    // SAFETY: `BOOT_COUNT` is 8 aligned bytes that only this function touches,
    // once at start-up, before interrupts or anything else could. Volatile
    // reads take the cells as they are, written or not: any bit pattern is a
    // valid `u32`.
    let (mark, count) = unsafe { (cell.read_volatile(), cell.add(1).read_volatile()) };
    let next = if mark == MARK { count.wrapping_add(1) } else { count ^ mark ^ 1 };
    // SAFETY: as above.
    unsafe {
        cell.write_volatile(MARK);
        cell.add(1).write_volatile(next);
    }
    next
}
