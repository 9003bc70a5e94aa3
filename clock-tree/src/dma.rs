//! STM32F4 DMA streams for U(S)ARTs: which stream and channel serve a
//! direction, where a stream's flags sit, and the ring arithmetic of a
//! circular receive stream and of a send stream's runs (tested against a
//! model of the streams in `tests/dma_rings.rs`).
//!
//! Each of the two DMA controllers has eight streams; a peripheral's request
//! reaches a stream through one of its channels, fixed by the chip's request
//! mapping (RM0430, "DMA1 request mapping" and "DMA2 request mapping"). A
//! stream serves one request at a time, so the plan of a board must give
//! every direction it moves by DMA a stream of its own: [`distinct`] checks
//! that at compile time. DMA1's peripheral port reaches APB1 only, so a
//! U(S)ART on APB2 must use DMA2.

/// A DMA controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Controller {
    /// DMA1: APB1 peripherals.
    Dma1,
    /// DMA2: APB2 peripherals (and memory to memory).
    Dma2,
}

/// One stream of a controller, and the channel that selects its request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stream {
    /// The controller.
    pub controller: Controller,
    /// Stream 0 to 7.
    pub stream: u8,
    /// The request channel (the CHSEL field of the stream's CR).
    pub channel: u8,
}

impl Stream {
    /// Stream `stream` of DMA1 on `channel`.
    pub const fn dma1(stream: u8, channel: u8) -> Self {
        Self { controller: Controller::Dma1, stream, channel }
    }

    /// Stream `stream` of DMA2 on `channel`.
    pub const fn dma2(stream: u8, channel: u8) -> Self {
        Self { controller: Controller::Dma2, stream, channel }
    }

    /// Whether the stream's flags are in the high registers (HISR, HIFCR):
    /// streams 4 to 7.
    pub const fn high(&self) -> bool {
        self.stream >= 4
    }

    /// The shift of the stream's five flags in its LISR/HISR (and their
    /// clear bits in LIFCR/HIFCR): 0, 6, 16 and 22 for the four streams of
    /// each register.
    pub const fn flag_shift(&self) -> u32 {
        [0, 6, 16, 22][(self.stream % 4) as usize]
    }

    /// The stream's transfer-complete flag (TCIF), in place.
    pub const fn transfer_complete(&self) -> u32 {
        flags::TRANSFER_COMPLETE << self.flag_shift()
    }

    /// All five of the stream's flags, in place: what a clear writes.
    pub const fn all_flags(&self) -> u32 {
        flags::ALL << self.flag_shift()
    }
}

/// A stream's flags at shift 0 (RM0430, "DMA low interrupt status register").
pub mod flags {
    /// FIFO error.
    pub const FIFO_ERROR: u32 = 1 << 0;
    /// Direct mode error.
    pub const DIRECT_MODE_ERROR: u32 = 1 << 2;
    /// Transfer error.
    pub const TRANSFER_ERROR: u32 = 1 << 3;
    /// Half transfer.
    pub const HALF_TRANSFER: u32 = 1 << 4;
    /// Transfer complete.
    pub const TRANSFER_COMPLETE: u32 = 1 << 5;
    /// All five.
    pub const ALL: u32 = FIFO_ERROR | DIRECT_MODE_ERROR | TRANSFER_ERROR | HALF_TRANSFER | TRANSFER_COMPLETE;
}

/// The streams of one U(S)ART: receiving and sending.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UartStreams {
    /// Peripheral to memory.
    pub rx: Stream,
    /// Memory to peripheral.
    pub tx: Stream,
}

/// Whether no stream of `plan` serves two directions.
pub const fn distinct(plan: &[UartStreams]) -> bool {
    let mut i = 0;
    while i < 2 * plan.len() {
        let mut j = i + 1;
        while j < 2 * plan.len() {
            let (a, b) = (nth(plan, i), nth(plan, j));
            if a.stream == b.stream && same_controller(a.controller, b.controller) {
                return false;
            }
            j += 1;
        }
        i += 1;
    }
    true
}

const fn nth(plan: &[UartStreams], i: usize) -> Stream {
    let u = &plan[i / 2];
    if i.is_multiple_of(2) { u.rx } else { u.tx }
}

const fn same_controller(a: Controller, b: Controller) -> bool {
    matches!((a, b), (Controller::Dma1, Controller::Dma1) | (Controller::Dma2, Controller::Dma2))
}

/// Where a circular receive stream of a `len`-byte ring is, in bytes
/// written in all (wrapping), from its `laps` counted by its
/// transfer-complete interrupt and `ndtr`, the bytes left in the lap, given
/// a position `behind` it by less than a lap (the reader's: a reader a lap
/// behind has lost bytes anyway).
///
/// NDTR reloads the moment a lap ends, before the interrupt that counts
/// the lap has run: a position before `behind` is such a lap, not yet
/// counted, and one lap more is added. (`len` divides 2^32, so positions
/// wrap with the laps.)
pub const fn circular_position(laps: u32, ndtr: u16, len: u32, behind: u32) -> u32 {
    let left = if (ndtr as u32) < len { ndtr as u32 } else { len };
    let at = laps.wrapping_mul(len).wrapping_add(len - left);
    if (at.wrapping_sub(behind) as i32) < 0 { at.wrapping_add(len) } else { at }
}

/// The next run a send stream takes from a `len`-byte ring: where it starts
/// in the ring and how long it is, given the bytes `sent` and `queued` in
/// all; `None` when nothing waits. A run never wraps: what lies past the
/// ring's end goes in the next.
pub const fn next_run(sent: u32, queued: u32, len: u32) -> Option<(u32, u32)> {
    let waiting = queued.wrapping_sub(sent);
    if waiting == 0 {
        return None;
    }
    let at = sent % len;
    let to_end = len - at;
    Some((at, if waiting < to_end { waiting } else { to_end }))
}
