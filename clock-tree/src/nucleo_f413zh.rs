//! The clocks of the node firmware on a NUCLEO-F413ZH.
//!
//! The core runs at the F413's full 100 MHz from the PLL, fed by the 8 MHz
//! clock the on-board ST-LINK drives into OSC_IN (HSE bypass), or by the HSI
//! when that clock is absent (the board's solder bridges choose).
//! APB1 then runs at 50 MHz and APB2 at 100 MHz.
//!
//! The neighbour links cross both buses (a board's +X USART1 on APB2 meets
//! its neighbour's -X USART2 on APB1), so both ends must divide to the same
//! rate. 3 Mbaud cannot be: APB1 divides to 2.94 or 3.125 Mbaud, APB2 to
//! 3.03. Both of those are exact on both buses (50 MHz / 17 and 100 MHz /
//! 34; 50 MHz / 16 and 100 MHz / 32); the links run at the faster,
//! 3.125 Mbaud.

use crate::dma::{Stream, UartStreams};
use crate::pll::{ClockPlan, Limits, PllSource};
use crate::usart::Brr;

/// The ST-LINK's clock on OSC_IN, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock, Hz.
pub const SYSCLK: u32 = 100_000_000;
/// Rate of every neighbour link, baud.
pub const NEIGHBOUR_BAUD: u32 = 3_125_000;
/// Rate of the host link (USART3 to the ST-LINK's virtual COM port), baud.
pub const HOST_BAUD: u32 = 921_600;

/// The plan from the ST-LINK's clock.
pub const FROM_HSE: ClockPlan = plan(PllSource::Hse(HSE_HZ));
/// The plan from the internal oscillator.
pub const FROM_HSI: ClockPlan = plan(PllSource::Hsi);

const fn plan(source: PllSource) -> ClockPlan {
    match ClockPlan::new(source, SYSCLK, Limits::STM32F413) {
        Ok(plan) => plan,
        Err(_) => panic!("no PLL plan for the core clock"),
    }
}

const fn brr(pclk: u32, baud: u32) -> Brr {
    match Brr::new(pclk, baud) {
        Ok(brr) => brr,
        Err(_) => panic!("the bus clock does not divide to the baud rate"),
    }
}

/// Neighbour U(S)ARTs on APB1 (USART2, UART4, UART5).
pub const NEIGHBOUR_APB1: Brr = brr(FROM_HSE.pclk1(), NEIGHBOUR_BAUD);
/// Neighbour U(S)ARTs on APB2 (USART1, USART6, UART10).
pub const NEIGHBOUR_APB2: Brr = brr(FROM_HSE.pclk2(), NEIGHBOUR_BAUD);
/// The host USART3 (APB1).
pub const HOST_APB1: Brr = brr(FROM_HSE.pclk1(), HOST_BAUD);

/// The DMA streams of the neighbour U(S)ARTs, in port order (+X USART1, -X
/// USART2, +Y UART4, -Y UART5, +Z USART6, -Z UART10), from RM0430's request
/// mapping. The three on APB1 take six of DMA1's streams; USART1, USART6
/// and UART10, on APB2, six of DMA2's.
///
/// -Z is UART10 rather than UART7 for the host's sake: USART3's requests
/// reach only DMA1's streams 1, 3 and 4, and UART7's reach only streams 1
/// and 3, so with UART7 on the board the host link could have no stream.
pub const NEIGHBOUR_DMA: [UartStreams; 6] = [
    UartStreams { rx: Stream::dma2(2, 4), tx: Stream::dma2(7, 4) },
    UartStreams { rx: Stream::dma1(5, 4), tx: Stream::dma1(6, 4) },
    UartStreams { rx: Stream::dma1(2, 4), tx: Stream::dma1(4, 4) },
    UartStreams { rx: Stream::dma1(0, 4), tx: Stream::dma1(7, 8) },
    UartStreams { rx: Stream::dma2(1, 5), tx: Stream::dma2(6, 5) },
    UartStreams { rx: Stream::dma2(0, 5), tx: Stream::dma2(5, 9) },
];

/// The host USART3's DMA streams (DMA1 streams 1 and 3, channel 4).
pub const HOST_DMA: UartStreams = UartStreams { rx: Stream::dma1(1, 4), tx: Stream::dma1(3, 4) };

/// Every link's DMA streams: the neighbours' in port order, then the host's.
pub const LINK_DMA: [UartStreams; 7] = [
    NEIGHBOUR_DMA[0],
    NEIGHBOUR_DMA[1],
    NEIGHBOUR_DMA[2],
    NEIGHBOUR_DMA[3],
    NEIGHBOUR_DMA[4],
    NEIGHBOUR_DMA[5],
    HOST_DMA,
];

const _: () = assert!(crate::dma::distinct(&LINK_DMA), "two directions share a DMA stream");
