//! Sleeping until there is something to do (any Cortex-M).
//!
//! On the mps2-an385 interrupts stay masked (PRIMASK, [`arm`]): a UART's
//! receive interrupt or the SysTick only pends, which is enough to end a
//! `wfi`, and nothing runs behind the main loop's back. (The STM32 image
//! runs its receive interrupts' handlers instead and uses [`start_tick`]
//! only: see its module.) The loop clears what is pending before it
//! polls, so a byte that arrives after the poll still ends the next `wfi`:
//! no wake-up is lost. Under QEMU an idle node then costs the host no CPU,
//! which matters with eight emulated boards on two cores.

use super::mmio::Reg;

const NVIC_ISER: usize = 0xE000_E100;
const NVIC_ICPR: usize = 0xE000_E280;
const SCB_ICSR: usize = 0xE000_ED04;
const ICSR_PENDSTCLR: u32 = 1 << 25;
const SYST: usize = 0xE000_E010;
const SYST_CSR: usize = 0x0;
const SYST_RVR: usize = 0x4;
const SYST_CVR: usize = 0x8;
/// Enable, interrupt, core clock.
const SYST_ON: u32 = 0b111;
/// Interrupt lines covered (the boards here have fewer than 96).
const BANKS: usize = 3;

/// Masks interrupts, lets every interrupt line pend, and starts the SysTick
/// pending every `period` core cycles, so timers (resends, load intervals)
/// are served while idle.
pub fn arm(period: u32) {
    cortex_m::interrupt::disable();
    for bank in 0..BANKS {
        Reg::at(NVIC_ISER, 4 * bank).write(u32::MAX);
    }
    start_tick(period);
}

/// Starts the SysTick interrupting every `period` core cycles.
pub fn start_tick(period: u32) {
    Reg::at(SYST, SYST_RVR).write(period.clamp(1, 0x00FF_FFFF));
    Reg::at(SYST, SYST_CVR).write(0);
    Reg::at(SYST, SYST_CSR).write(SYST_ON);
}

/// Forgets what pended so far (call before polling).
pub fn clear() {
    for bank in 0..BANKS {
        Reg::at(NVIC_ICPR, 4 * bank).write(u32::MAX);
    }
    Reg::at(SCB_ICSR, 0).write(ICSR_PENDSTCLR);
}

/// Waits for an interrupt to pend (returns at once if one already has).
pub fn sleep() {
    cortex_m::asm::wfi();
}
