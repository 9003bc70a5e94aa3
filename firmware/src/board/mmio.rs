//! Memory-mapped registers where no peripheral-access crate fits: the
//! mps2-an385's CMSDK UARTs, timer and FPGA registers, the Cortex-M core's
//! NVIC and SysTick, an STM32's unique id and the emulated boards' id cell.
//! With the boot counter and the STM32 module's register handles, the only
//! unsafe code of the firmware.
#![allow(unsafe_code)]

/// One 32-bit peripheral register at a fixed address.
#[derive(Debug, Clone, Copy)]
pub struct Reg(usize);

impl Reg {
    /// The register at `base + offset`.
    ///
    /// Board modules only build these from their datasheet's peripheral
    /// addresses, which are valid, aligned and not aliased by Rust objects.
    pub const fn at(base: usize, offset: usize) -> Self {
        Self(base + offset)
    }

    /// Reads the register.
    pub fn read(self) -> u32 {
        // SAFETY: a peripheral register address from the datasheet (see `at`);
        // volatile, because the hardware changes it.
        unsafe { core::ptr::read_volatile(self.0 as *const u32) }
    }

    /// Writes the register.
    pub fn write(self, value: u32) {
        // SAFETY: as in `read`.
        unsafe { core::ptr::write_volatile(self.0 as *mut u32, value) }
    }

    /// Sets bits `mask` to `value` (read-modify-write).
    pub fn modify(self, mask: u32, value: u32) {
        self.write((self.read() & !mask) | (value & mask));
    }
}
