//! Who this board is: its unique id, and the hello that names it.
//!
//! An STM32 has a 96-bit unique device id in its system memory. The emulated
//! boards have none, so the host that launches them writes one into the last
//! 16 bytes of RAM before the core starts (QEMU's `-device loader`), which
//! each emulated board's `memory.x` keeps below the stack, out of reach of the
//! start-up code. No mark there means no id: the host then cannot check the
//! cabling.

use link_proto::board::version_part;
use link_proto::{BoardId, FirmwareVersion};

use super::mmio::Reg;

/// This firmware's version.
pub const FIRMWARE: FirmwareVersion = FirmwareVersion {
    major: version_part(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: version_part(env!("CARGO_PKG_VERSION_MINOR")),
    patch: version_part(env!("CARGO_PKG_VERSION_PATCH")),
};

/// Marks an id the host wrote (word 1 of the cell; the id is word 0).
/// host-tool's `qemu` module writes the same.
pub const EMULATED_MARK: u32 = 0x1D5E_7B0A;

/// The id the host wrote at `cell` for an emulated board, if it wrote one.
#[cfg(any(feature = "mps2-an385", feature = "netduinoplus2"))]
pub fn emulated(cell: usize) -> BoardId {
    let (id, mark) = (Reg::at(cell, 0).read(), Reg::at(cell, 4).read());
    if mark == EMULATED_MARK { BoardId([id, 0, 0]) } else { BoardId::NONE }
}

/// An STM32F4's unique device id (RM0430 31.2: three words at 0x1FFF_7A10,
/// least significant first).
#[cfg(feature = "stm32f413")]
pub fn stm32_uid() -> BoardId {
    const UID: usize = 0x1FFF_7A10;
    BoardId([Reg::at(UID, 0).read(), Reg::at(UID, 4).read(), Reg::at(UID, 8).read()])
}
