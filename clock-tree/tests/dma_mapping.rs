//! The neighbour links' DMA streams against RM0430's request mapping
//! tables and status register layout, typed here from the manual (not
//! through the crate's tables).

use clock_tree::dma::{self, Controller, Stream, UartStreams};
use clock_tree::nucleo_f413zh::{LINK_DMA, NEIGHBOUR_DMA};

/// Every request of the eight U(S)ARTs the board could use, as RM0430's
/// "DMA1 request mapping" and "DMA2 request mapping" tables give them for
/// the STM32F413: (controller, stream, channel, peripheral, receive).
/// UART10's are also embassy's and stm32f4xx-hal's maps for the F413.
const REQUESTS: [(u8, u8, u8, &str, bool); 24] = [
    (1, 0, 4, "UART5", true),
    (1, 1, 4, "USART3", true),
    (1, 1, 5, "UART7", false),
    (1, 2, 4, "UART4", true),
    (1, 3, 4, "USART3", false),
    (1, 3, 5, "UART7", true),
    (1, 4, 4, "UART4", false),
    (1, 4, 7, "USART3", false),
    (1, 5, 4, "USART2", true),
    (1, 6, 4, "USART2", false),
    (1, 7, 6, "USART2", true),
    (1, 7, 8, "UART5", false),
    (2, 1, 5, "USART6", true),
    (2, 2, 4, "USART1", true),
    (2, 2, 5, "USART6", true),
    (2, 5, 4, "USART1", true),
    (2, 6, 5, "USART6", false),
    (2, 7, 4, "USART1", false),
    (2, 7, 5, "USART6", false),
    (1, 0, 5, "UART8", false),
    (2, 0, 5, "UART10", true),
    (2, 3, 9, "UART10", true),
    (2, 5, 9, "UART10", false),
    (2, 7, 6, "UART10", false),
];

/// The links' U(S)ARTs in [`LINK_DMA`]'s order (the neighbours' in port
/// order, then the host's), and whether each is on APB1 (RM0430's memory
/// map: UART10 sits at 0x4001_1C00, on APB2).
const PORTS: [(&str, bool); 7] = [
    ("USART1", false),
    ("USART2", true),
    ("UART4", true),
    ("UART5", true),
    ("USART6", false),
    ("UART10", false),
    ("USART3", true),
];

fn request_of(s: Stream) -> Option<(&'static str, bool)> {
    let controller = match s.controller {
        Controller::Dma1 => 1,
        Controller::Dma2 => 2,
    };
    REQUESTS.iter().find(|r| (r.0, r.1, r.2) == (controller, s.stream, s.channel)).map(|r| (r.3, r.4))
}

#[test]
fn each_link_direction_has_its_uarts_request() {
    assert_eq!(LINK_DMA[..6], NEIGHBOUR_DMA);
    for (streams, (uart, _)) in LINK_DMA.iter().zip(PORTS) {
        assert_eq!(request_of(streams.rx), Some((uart, true)), "{uart} RX on {:?}", streams.rx);
        assert_eq!(request_of(streams.tx), Some((uart, false)), "{uart} TX on {:?}", streams.tx);
    }
}

#[test]
fn dma1_serves_only_apb1() {
    // RM0430, "DMA1 and DMA2": DMA1's peripheral port is on APB1 only.
    for (streams, (uart, apb1)) in LINK_DMA.iter().zip(PORTS) {
        for s in [streams.rx, streams.tx] {
            assert!(apb1 || s.controller == Controller::Dma2, "{uart} on APB2 but {:?}", s);
        }
    }
}

#[test]
fn no_two_directions_share_a_stream() {
    let mut seen = Vec::new();
    for s in LINK_DMA.iter().flat_map(|u| [u.rx, u.tx]) {
        let key = (s.controller == Controller::Dma1, s.stream);
        assert!(!seen.contains(&key), "{:?} twice", s);
        seen.push(key);
    }
    assert!(dma::distinct(&LINK_DMA));
    // And the check sees a clash: USART3 sending on the stream UART4 sends on.
    let clash = [NEIGHBOUR_DMA[2], UartStreams { rx: Stream::dma1(1, 4), tx: Stream::dma1(4, 7) }];
    assert!(!dma::distinct(&clash));
    // The same stream number on the other controller is no clash.
    let apart = [UartStreams { rx: Stream::dma1(1, 4), tx: Stream::dma2(1, 5) }];
    assert!(dma::distinct(&apart));
}

#[test]
fn the_channel_fits_chsel() {
    // RM0430, DMA_SxCR: CHSEL[3:0] (bits 28:25) on the F413, streams 0-7.
    for s in LINK_DMA.iter().flat_map(|u| [u.rx, u.tx]) {
        assert!(s.channel < 16 && s.stream < 8, "{:?}", s);
    }
}

#[test]
fn flags_sit_where_the_status_registers_put_them() {
    // RM0430, DMA_LISR: TCIF0 bit 5, TCIF1 bit 11, TCIF2 bit 21, TCIF3
    // bit 27; FEIF0 bit 0, DMEIF0 bit 2, TEIF0 bit 3, HTIF0 bit 4; bits 1,
    // 7, 12-15, 17, 23 and 28-31 reserved. DMA_HISR: the same for streams 4-7.
    let tcif = [5, 11, 21, 27];
    for stream in 0..8u8 {
        let s = Stream::dma1(stream, 0);
        assert_eq!(s.high(), stream >= 4);
        assert_eq!(s.transfer_complete(), 1 << tcif[usize::from(stream % 4)], "stream {stream}");
        let first = [0, 6, 16, 22][usize::from(stream % 4)];
        assert_eq!(s.all_flags(), 0b11_1101 << first, "stream {stream}");
    }
    let reserved = (1 << 1) | (1 << 7) | (0xF << 12) | (1 << 17) | (1 << 23) | (0xF << 28);
    let every = (0..4u8).fold(0, |acc, n| acc | Stream::dma2(n, 0).all_flags());
    assert_eq!(every & reserved, 0);
    assert_eq!(every.count_ones(), 20);
}
