//! Links moved by DMA: the NUCLEO-F413ZH image's seven U(S)ARTs, the six
//! neighbours' and the host's ([`clock_tree::nucleo_f413zh::LINK_DMA`] says
//! which streams).
//!
//! An interrupt a byte costs a board about 51 cycles at each end of a link,
//! more than a frame's own handling of that byte (docs/scaling.md). A DMA
//! stream moves the bytes with none:
//! - receiving, a circular transfer writes a ring of [`RX_LEN`] bytes and
//!   never stops. The loop reads behind it. Where the stream is follows
//!   from its laps (counted by its transfer-complete interrupt, once every
//!   [`RX_LEN`] bytes) and its NDTR (the bytes left in the lap);
//! - sending, the loop queues bytes in a ring of [`TX_LEN`]; the stream
//!   sends the oldest run of them that lies in one piece, and its
//!   transfer-complete interrupt starts the next. An interrupt a run, not a
//!   byte.
//!
//! A receive ring the loop falls more than half behind is taken to be
//! overrun: what it had not read is dropped and counted as lost, and the
//! reliable channel resends the frames it belonged to, as it does for a
//! full byte ring.
//!
//! QEMU models no STM32 DMA, so this runs on real boards only; the emulated
//! STM32 (`netduinoplus2`) image moves every byte by interrupt. The streams,
//! channels and flags are held to RM0430 by clock-tree's tests.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering, compiler_fence};

use clock_tree::dma::{Controller, Stream, UartStreams, circular_position, flags, next_run};
use stm32f4::stm32f413::{self as pac, dma1};

/// Bytes of a receive ring: 327 680 core cycles of a link at 3.125 Mbaud,
/// eight times the longest pass of the loop.
pub const RX_LEN: usize = 1024;
/// Bytes of a send ring: a longest frame and a half. The port's transmit
/// ring ([`crate::tx_ring`]) holds the frames waiting; this one only keeps
/// the stream fed.
pub const TX_LEN: usize = 256;

/// Behind by more than this, the loop may be reading bytes the stream is
/// writing over: it drops them.
const OVERRUN: u32 = RX_LEN as u32 / 2;

/// A link's memory, shared by the loop, the streams' handlers and the DMA.
pub struct DmaLink {
    /// Written by the receive stream only.
    rx: UnsafeCell<[u8; RX_LEN]>,
    /// Receive laps completed: written by the receive stream's handler.
    laps: AtomicU32,
    /// Bytes the loop has read in all, wrapping: written by the loop.
    read: AtomicU32,
    /// Read by the send stream while a run is in flight.
    tx: UnsafeCell<[u8; TX_LEN]>,
    /// Bytes queued in all: written by the loop.
    queued: AtomicU32,
    /// Bytes sent in all: written by the send handler, or by the loop
    /// inside a critical section.
    sent: AtomicU32,
    /// Bytes of the run in flight; 0 when the send stream is idle. Written
    /// where `sent` is.
    in_flight: AtomicU32,
}

// SAFETY: the loop writes `tx` only at positions from `queued` on, which no
// run in flight covers (a run lies between `sent` and `queued`), and reads
// `rx` only behind the stream (checked against its position each time).
// The indices have one writer each, or are written with interrupts off.
// Everything runs on one core (see `byte_ring`'s note on ordering).
unsafe impl Sync for DmaLink {}

impl DmaLink {
    /// An idle link.
    pub const fn new() -> Self {
        Self {
            rx: UnsafeCell::new([0; RX_LEN]),
            laps: AtomicU32::new(0),
            read: AtomicU32::new(0),
            tx: UnsafeCell::new([0; TX_LEN]),
            queued: AtomicU32::new(0),
            sent: AtomicU32::new(0),
            in_flight: AtomicU32::new(0),
        }
    }

    /// Where the receive stream is, in bytes written in all
    /// ([`circular_position`], the loop's `read` less than a lap behind).
    fn written(&self, rx: Dma, read: u32) -> u32 {
        loop {
            let laps = self.laps.load(Ordering::Relaxed);
            let left = rx.stream.ndtr().read().ndt().bits();
            // A lap counted between the two reads: look again.
            if self.laps.load(Ordering::Relaxed) == laps {
                break circular_position(laps, left, RX_LEN as u32, read);
            }
        }
    }

    /// Whether the loop has read all that the stream wrote (a stream past
    /// 7 writes nothing).
    pub fn caught_up(&self, rx: Stream) -> bool {
        let read = self.read.load(Ordering::Relaxed);
        Dma::of(rx).is_none_or(|rx| self.written(rx, read) == read)
    }

    /// Starts the send stream on the oldest run of queued bytes, if any and
    /// it is idle. With interrupts off, or from the send handler.
    #[inline(always)]
    fn send_next(&self, tx: Dma) {
        if self.in_flight.load(Ordering::Relaxed) != 0 {
            return;
        }
        let (sent, queued) = (self.sent.load(Ordering::Relaxed), self.queued.load(Ordering::Relaxed));
        let Some((at, run)) = next_run(sent, queued, TX_LEN as u32) else { return };
        self.in_flight.store(run, Ordering::Relaxed);
        let start = self.tx.get().cast::<u8>().wrapping_add(at as usize) as u32;
        tx.clear();
        let st = tx.stream;
        // SAFETY: the address is inside `tx`, which lives for ever, and the
        // run lies in it (`run <= TX_LEN - at`).
        st.m0ar().write(|w| unsafe { w.m0a().bits(start) });
        // A run is at most TX_LEN bytes: it fits NDTR.
        st.ndtr().write(|w| w.ndt().set(run as u16));
        // The bytes in memory before the stream reads them.
        cortex_m::asm::dmb();
        st.cr().modify(|_, w| w.en().enabled());
    }

    /// The send stream's interrupt: the run is out (or failed, and the
    /// reliable channel resends it); the next starts.
    #[inline(always)]
    pub fn on_sent(&self, tx: Dma) {
        let done = tx.take_flags();
        if done & (flags::TRANSFER_COMPLETE | flags::TRANSFER_ERROR) == 0 {
            return;
        }
        // Only this handler, and the loop with interrupts off, write it.
        let run = self.in_flight.load(Ordering::Relaxed);
        self.in_flight.store(0, Ordering::Relaxed);
        self.sent.store(self.sent.load(Ordering::Relaxed).wrapping_add(run), Ordering::Relaxed);
        self.send_next(tx);
    }

    /// The receive stream's interrupt: a lap is done. A transfer error stops
    /// the stream; it starts again at the ring's start, a lap on (what the
    /// lap had left to write is stale, and the frames' CRC refuses it).
    #[inline(always)]
    pub fn on_received(&self, rx: Dma) {
        let got = rx.take_flags();
        if got & (flags::TRANSFER_COMPLETE | flags::TRANSFER_ERROR) != 0 {
            self.laps.store(self.laps.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
        }
        let st = rx.stream;
        if st.cr().read().en().is_disabled() {
            st.ndtr().write(|w| w.ndt().set(RX_LEN as u16));
            st.cr().modify(|_, w| w.en().enabled());
        }
    }
}

impl core::fmt::Debug for DmaLink {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DmaLink").field("laps", &self.laps).field("read", &self.read).finish()
    }
}

impl Default for DmaLink {
    fn default() -> Self {
        Self::new()
    }
}

/// One stream's registers.
#[derive(Debug, Clone, Copy)]
pub struct Dma {
    block: &'static dma1::RegisterBlock,
    stream: &'static dma1::ST,
    plan: Stream,
}

impl Dma {
    /// The registers of `plan`'s stream; `None` for a stream past 7.
    /// Inlined, so that a handler's stream is a constant.
    #[inline(always)]
    pub fn of(plan: Stream) -> Option<Self> {
        let block = match plan.controller {
            Controller::Dma1 => pac::DMA1::ptr(),
            Controller::Dma2 => pac::DMA2::ptr(),
        };
        // SAFETY: the controllers' fixed addresses, valid for ever. Each
        // stream is driven by one link (the plan gives every direction its
        // own), and its flags are cleared through write-one registers that
        // touch no other stream's.
        let block: &'static dma1::RegisterBlock = unsafe { &*block };
        let stream = block.st_iter().nth(usize::from(plan.stream))?;
        Some(Self { block, stream, plan })
    }

    /// Reads and clears the stream's flags; returns them at shift 0.
    #[inline(always)]
    fn take_flags(&self) -> u32 {
        let isr =
            if self.plan.high() { self.block.hisr().read().bits() } else { self.block.lisr().read().bits() };
        self.clear();
        (isr >> self.plan.flag_shift()) & flags::ALL
    }

    #[inline(always)]
    fn clear(&self) {
        let bits = self.plan.all_flags();
        // SAFETY: write-one-to-clear bits of this stream's flags only.
        if self.plan.high() {
            self.block.hifcr().write(|w| unsafe { w.bits(bits) });
        } else {
            self.block.lifcr().write(|w| unsafe { w.bits(bits) });
        }
    }

    /// Stops the stream and waits until it has (RM0430: EN reads 0 before
    /// the stream may be configured).
    fn stop(&self) {
        self.stream.cr().modify(|_, w| w.en().disabled());
        while self.stream.cr().read().en().is_enabled() {}
        self.clear();
    }
}

/// The loop's side of a link: its streams, and what it knows waits.
#[derive(Debug)]
pub struct DmaPort {
    link: &'static DmaLink,
    rx: Dma,
    tx: Dma,
    /// Bytes known to wait since the stream was last looked at, so that a
    /// byte read costs no look at the stream. Dropped once a pass
    /// ([`DmaPort::lost`]).
    ready: u32,
    /// Bytes dropped to overruns.
    lost: u32,
}

impl DmaPort {
    /// Configures `streams` for the U(S)ART whose data register is at `dr`
    /// and starts receiving; the U(S)ART's DMA requests are then to be
    /// turned on (CR3's DMAR and DMAT). The DMA controllers' clocks must be on.
    pub fn start(link: &'static DmaLink, streams: UartStreams, dr: u32) -> Option<Self> {
        let (rx, tx) = (Dma::of(streams.rx)?, Dma::of(streams.tx)?);
        for (dma, channel) in [(rx, streams.rx.channel), (tx, streams.tx.channel)] {
            dma.stop();
            // SAFETY: the data register of a U(S)ART, a fixed address.
            dma.stream.par().write(|w| unsafe { w.pa().bits(dr) });
            dma.stream.cr().write(|w| {
                let w = w.chsel().set(channel).msize().bits8().psize().bits8().minc().incremented();
                w.tcie().enabled().teie().enabled()
            });
        }
        let ring = link.rx.get().cast::<u8>() as u32;
        let st = rx.stream;
        // SAFETY: `rx` is the link's for ever, RX_LEN bytes.
        st.m0ar().write(|w| unsafe { w.m0a().bits(ring) });
        st.ndtr().write(|w| w.ndt().set(RX_LEN as u16));
        // Receiving must not fall behind the line: high priority.
        st.cr().modify(|_, w| w.pl().high().circ().enabled().dir().peripheral_to_memory());
        st.cr().modify(|_, w| w.en().enabled());
        tx.stream.cr().modify(|_, w| w.pl().medium().dir().memory_to_peripheral());
        Some(Self { link, rx, tx, ready: 0, lost: 0 })
    }

    /// Bytes the stream wrote that the loop has not read: those known, or
    /// else as the stream says, after dropping them all if there are too
    /// many to be trusted.
    fn waiting(&mut self) -> u32 {
        if self.ready > 0 {
            return self.ready;
        }
        let read = self.link.read.load(Ordering::Relaxed);
        let written = self.link.written(self.rx, read);
        let waiting = written.wrapping_sub(read);
        if waiting > OVERRUN {
            self.lost = self.lost.wrapping_add(waiting);
            self.link.read.store(written, Ordering::Relaxed);
            return 0;
        }
        self.ready = waiting;
        waiting
    }

    /// Whether a byte waits.
    pub fn read_ready(&mut self) -> bool {
        self.waiting() > 0
    }

    /// The oldest byte not read, if one waits.
    pub fn read_byte(&mut self) -> Option<u8> {
        if self.waiting() == 0 {
            return None;
        }
        self.ready -= 1;
        let read = self.link.read.load(Ordering::Relaxed);
        // SAFETY: inside the ring (`% RX_LEN`); the stream is at most
        // OVERRUN bytes ahead, so it is not writing this byte. Volatile: the
        // DMA writes the ring behind the compiler's back.
        let byte = unsafe { self.link.rx.get().cast::<u8>().add(read as usize % RX_LEN).read_volatile() };
        compiler_fence(Ordering::Release);
        self.link.read.store(read.wrapping_add(1), Ordering::Relaxed);
        Some(byte)
    }

    /// Whether the send ring has room.
    pub fn write_ready(&self) -> bool {
        self.room() > 0
    }

    fn room(&self) -> usize {
        let l = self.link;
        TX_LEN - l.queued.load(Ordering::Relaxed).wrapping_sub(l.sent.load(Ordering::Relaxed)) as usize
    }

    /// Queues what fits of `buf` and starts the stream if it is idle; the
    /// bytes queued.
    pub fn write(&mut self, buf: &[u8]) -> usize {
        let n = buf.len().min(self.room());
        let queued = self.link.queued.load(Ordering::Relaxed);
        let ring = self.link.tx.get().cast::<u8>();
        for (i, &b) in buf.iter().take(n).enumerate() {
            let at = (queued as usize).wrapping_add(i) % TX_LEN;
            // SAFETY: inside the ring; past `queued`, where no run in flight
            // reads (there is room for these `n`).
            unsafe { ring.add(at).write(b) };
        }
        compiler_fence(Ordering::Release);
        self.link.queued.store(queued.wrapping_add(n as u32), Ordering::Relaxed);
        let (link, tx) = (self.link, self.tx);
        cortex_m::interrupt::free(|_| link.send_next(tx));
        n
    }

    /// Whether every queued byte has been handed to the U(S)ART.
    pub fn sent_all(&self) -> bool {
        let l = self.link;
        l.queued.load(Ordering::Relaxed) == l.sent.load(Ordering::Relaxed)
    }

    /// Bytes dropped to overruns so far. The loop asks once a pass, after
    /// reading, and the count of bytes known to wait goes with it: no pass
    /// reads on a count an earlier one made. Within a pass the stream
    /// cannot reach a byte so counted: it was at most [`OVERRUN`] bytes
    /// behind the stream, which must write [`RX_LEN`] - [`OVERRUN`] more
    /// (164 000 cycles at 3.125 Mbaud) to come round to it, four times the
    /// longest pass.
    pub fn lost(&mut self) -> u32 {
        self.ready = 0;
        self.lost
    }
}
