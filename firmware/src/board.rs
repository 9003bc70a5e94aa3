//! Boards: UART drivers and clocks, one module per board.

pub mod boot_count;
#[cfg(any(feature = "stm32f413", feature = "netduinoplus2"))]
pub mod byte_ring;
#[cfg(dma_links)]
pub mod dma_link;
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

/// What the firmware needs of a board's UART besides moving bytes.
pub trait LostBytes {
    /// Received bytes lost since the last call: an overrun in the
    /// peripheral (the board read too late) or a full receive ring. A byte a
    /// bad cable damages still arrives; these never did. Counted since the
    /// last call, not in all, so that a UART that comes to serve another
    /// port (the wires are mapped once a node knows its place) brings none
    /// of its past to it.
    ///
    /// The loop calls it once a pass, after reading the UART: a UART may
    /// forget there what it learnt of its receiver during the pass (a DMA
    /// link forgets how many bytes it knows to wait).
    fn take_lost(&mut self) -> u32;
}

/// The board's parts the node firmware uses: its UARTs `U` (the host's and
/// `N` neighbours'), its clock `C`, what it is, and its lights on pins `L`.
pub struct Parts<U, C, L, const N: usize> {
    /// The host's UART.
    pub host: U,
    /// The neighbours' UARTs.
    pub neighbours: [U; N],
    /// The clock.
    pub clock: C,
    /// What the board is, for its hellos.
    pub info: link_proto::BoardInfo,
    /// The working light and the fault light.
    pub lights: crate::lights::Lights<L, L>,
}
