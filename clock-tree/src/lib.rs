//! The STM32F4 clock tree of the node boards, and the DMA streams of their
//! links, as register values.
//!
//! The firmware runs the core from the main PLL at the chip's full speed and
//! its U(S)ARTs at fixed rates. Which PLL factors, bus prescalers, flash wait
//! states and baud-rate divisors that takes follows from a few rules of the
//! reference manual (RM0430 for the STM32F413: "RCC PLL
//! configuration register", "Relation between CPU clock frequency and
//! flash memory read time", "Fractional baud rate generation"). This
//! crate applies them in `const fn`s, so the firmware's register values are
//! computed, checked against the chip's limits at compile time, and
//! unit-tested on the host against the manual's formulas.
#![no_std]
#![forbid(unsafe_code)]

pub mod dma;
pub mod nucleo_f413zh;
pub mod pll;
pub mod usart;

pub use pll::{ClockError, ClockPlan, Limits, PllSource};
pub use usart::{BaudError, Brr};
