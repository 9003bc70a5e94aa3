//! Memory-mapped registers: with the boot counter, the only unsafe code of
//! the firmware.
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
