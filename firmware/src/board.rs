//! Boards: UART drivers and clocks, one module per board.

pub mod boot_count;
pub mod identity;
pub mod mmio;
pub mod wake;

#[cfg(feature = "mps2-an385")]
pub mod mps2_an385;
#[cfg(feature = "mps2-an385")]
pub use mps2_an385 as active;

#[cfg(any(feature = "stm32f413", feature = "netduinoplus2"))]
pub mod stm32f413;
#[cfg(all(any(feature = "stm32f413", feature = "netduinoplus2"), not(feature = "mps2-an385")))]
pub use stm32f413 as active;
