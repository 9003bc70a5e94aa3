//! NUCLEO-F413ZH: a Cortex-M4F with ten U(S)ARTs, enough for the host and all
//! six neighbours, so every node of any array is cabled the same way. The
//! same code runs on QEMU's `netduinoplus2` (an STM32F405 model with the
//! same seven U(S)ARTs at the same addresses, and TIM2).
//!
//! | port | peripheral | bus | TX | RX | AF |
//! |---|---|---|---|---|---|
//! | host | USART3 (ST-LINK virtual COM port) | APB1 | PD8 | PD9 | 7 |
//! | +X | USART1 | APB2 | PB6 | PB7 | 7 |
//! | -X | USART2 | APB1 | PD5 | PD6 | 7 |
//! | +Y | UART4 | APB1 | PA0 | PA1 | 8 |
//! | -Y | UART5 | APB1 | PC12 | PD2 | 8 |
//! | +Z | USART6 | APB2 | PC6 | PC7 | 8 |
//! | -Z | UART10 | APB2 | PE3 | PE2 | 11 |
//!
//! -Z is UART10 so that every link, the host's too, has DMA streams of its
//! own ([`clock_tree::nucleo_f413zh::NEIGHBOUR_DMA`] says why). QEMU's
//! SoC has no UART10: the `netduinoplus2` image serves -Z with UART7 (PE8
//! TX, PE7 RX, AF 8), where its model has one.
//!
//! Cable each board's +X TX to its +X neighbour's -X RX and back (crossed),
//! and likewise for Y and Z. The core runs at 100 MHz from the PLL and the
//! links at the rates of [`clock_tree::nucleo_f413zh`]; the clock is TIM2,
//! a 32-bit timer at the core clock.
//!
//! On the real board every link's bytes move by DMA (`dma_link.rs`), the
//! host's as well as the neighbours'. With the `interrupt-links` feature,
//! and on QEMU, which models no DMA, they move by interrupt instead, a byte
//! at a time, through rings (`byte_ring.rs`).
//!
//! Under QEMU the RCC is a stub whose ready flags never rise: every wait for
//! one is bounded, the core stays on its reset clock, and the emulator
//! ignores baud rates anyway. TIM2 there counts virtual nanoseconds, which
//! `-icount shift=0` makes instructions, the in-memory board's unit.
//!
//! Registers go through the `stm32f4` peripheral-access crate: typed fields
//! where the reference manual names them, whole-register values only where
//! [`clock_tree`] computes them (and its tests decode them field by field).

use core::convert::Infallible;
#[cfg(not(dma_links))]
use core::sync::atomic::{AtomicBool, Ordering};

use clock_tree::nucleo_f413zh::{
    FROM_HSE, FROM_HSI, HOST_APB1, HOST_BAUD, NEIGHBOUR_APB1, NEIGHBOUR_APB2, NEIGHBOUR_BAUD,
};
use clock_tree::{Brr, ClockPlan};
use cortex_m::peripheral::NVIC;
use cortex_m_rt::exception;
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_io::{ErrorType, Read, ReadReady, Write, WriteReady};
use link_proto::{BoardId, BoardInfo, BoardKind, ClockSource};
use stm32f4::Periph;
use stm32f4::stm32f413::{self as pac, Interrupt, gpiob, interrupt, tim2, uart4, usart1};

#[cfg(not(dma_links))]
use super::byte_ring::ByteRing;
#[cfg(dma_links)]
use super::dma_link::{Dma, DmaLink, DmaPort};
#[cfg(dma_links)]
use clock_tree::nucleo_f413zh::LINK_DMA;

use super::identity;
use crate::clock::{Clock, Widen};
use crate::lights::Lights;

/// Neighbour UARTs.
pub const NEIGHBOUR_UARTS: usize = 6;

/// Polls of a ready flag before giving up on it (some milliseconds at 16 MHz;
/// the HSE and the PLL lock within hundreds of microseconds).
const READY_POLLS: u32 = 100_000;

/// The register block of a peripheral taken from `Peripherals`, for the
/// rest of the program.
fn keep<RB, const A: usize>(_owned: Periph<RB, A>) -> &'static RB {
    // SAFETY: `Peripherals::take` hands each peripheral out once, and its
    // only handle is given up here: this reference is the only way left to
    // the block, which lives at its fixed address for ever.
    unsafe { &*Periph::<RB, A>::ptr() }
}

/// Where the core clock came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoreClock {
    /// The PLL from the ST-LINK's clock: 100 MHz.
    PllFromHse,
    /// The PLL from the internal oscillator: 100 MHz.
    PllFromHsi,
    /// No PLL locked (an emulator's stub RCC): the 16 MHz reset clock, and
    /// the baud rates are wrong by the same factor.
    Hsi,
}

/// Polls until `ready` holds, at most [`READY_POLLS`] times.
fn wait_for(ready: impl Fn() -> bool) -> bool {
    (0..READY_POLLS).any(|_| ready())
}

/// Runs the core from the PLL: the ST-LINK's clock if it is there, else the
/// HSI. Voltage scale and flash wait states go up before the clock does.
fn start_clocks(
    rcc: &pac::rcc::RegisterBlock,
    pwr: &pac::pwr::RegisterBlock,
    flash: &pac::flash::RegisterBlock,
) -> CoreClock {
    rcc.cr().modify(|_, w| w.hseon().set_bit().hsebyp().set_bit());
    let (plan, source): (ClockPlan, CoreClock) = if wait_for(|| rcc.cr().read().hserdy().bit_is_set()) {
        (FROM_HSE, CoreClock::PllFromHse)
    } else {
        rcc.cr().modify(|_, w| w.hseon().clear_bit().hsebyp().clear_bit());
        (FROM_HSI, CoreClock::PllFromHsi)
    };
    rcc.apb1enr().modify(|_, w| w.pwren().set_bit());
    // Voltage scale 1, needed above 84 MHz.
    pwr.cr().modify(|_, w| w.vos().scale1());
    // SAFETY (all three writes): every value comes from `ClockPlan`, whose
    // tests decode it field by field against RM0430 and whose constructor
    // fails the build on a factor out of the chip's range.
    rcc.pllcfgr().write(|w| unsafe { w.bits(plan.pllcfgr()) });
    rcc.cr().modify(|_, w| w.pllon().set_bit());
    if !wait_for(|| rcc.cr().read().pllrdy().bit_is_set()) {
        rcc.cr().modify(|_, w| w.pllon().clear_bit());
        return CoreClock::Hsi;
    }
    flash.acr().write(|w| unsafe { w.bits(plan.flash_acr()) });
    rcc.cfgr().write(|w| unsafe { w.bits(plan.cfgr()) });
    if wait_for(|| rcc.cfgr().read().sws().is_pll()) { source } else { CoreClock::Hsi }
}

/// Puts pins `n...` of `gpio` on alternate function `af`.
macro_rules! alternate {
    ($gpio:expr, $af:expr, $($n:expr),+) => {{
        let gpio = $gpio;
        $(
            gpio.moder().modify(|_, w| w.moder($n).alternate());
            if $n < 8 {
                gpio.afrl().modify(|_, w| w.afr($n).set($af));
            } else {
                gpio.afrh().modify(|_, w| w.afr($n % 8).set($af));
            }
        )+
    }};
}

/// A U(S)ART's registers: USART1-3 and 6 have the full block, UART4, 5 and 7
/// the asynchronous one, alike in the four registers used here (RM0430
/// 26.6: SR, DR, BRR, CR1).
#[derive(Debug, Clone, Copy)]
enum Regs {
    Usart(&'static usart1::RegisterBlock),
    Uart(&'static uart4::RegisterBlock),
}

/// Runs `$body` with `$r` bound to whichever block `$regs` holds.
macro_rules! with_regs {
    ($regs:expr, $r:ident => $body:expr) => {
        match $regs {
            Regs::Usart($r) => $body,
            Regs::Uart($r) => $body,
        }
    };
}

/// Bytes each of a UART's rings holds: 82 000 core cycles of a neighbour
/// link at 3.125 Mbaud, about twice the longest pass of the loop (a poll's
/// six pieces of work, `node_fw::node::PIECES_PER_POLL`, all shaded hits
/// at 7 000 instructions). A byte lost to a full ring costs a resend, not
/// the frame.
#[cfg(not(dma_links))]
const RING: usize = 256;

/// A UART's bytes on their way between its interrupt handler and the loop.
#[cfg(not(dma_links))]
struct Rings {
    /// Received: the handler pushes, the loop pops.
    rx: ByteRing<RING>,
    /// To send: the loop pushes, the handler pops.
    tx: ByteRing<RING>,
    /// Whether the transmit interrupt is on, as CR1's TXEIE says: a flag in
    /// memory, so that a received byte's interrupt reads no register to
    /// learn that there is nothing to send. Written only where TXEIE is,
    /// with it (inside a critical section, or by the handler).
    sending: AtomicBool,
}

/// Each U(S)ART's rings, in the order of [`IRQS`]: the host's, then +X,
/// -X, +Y, -Y, +Z, -Z.
#[cfg(not(dma_links))]
static RINGS: [Rings; 7] =
    [const { Rings { rx: ByteRing::new(), tx: ByteRing::new(), sending: AtomicBool::new(false) } }; 7];

/// Each link's DMA rings, in [`LINK_DMA`]'s order: the neighbours' in port
/// order (+X, -X, +Y, -Y, +Z, -Z), then the host's.
#[cfg(dma_links)]
static DMA_LINKS: [DmaLink; 7] = [const { DmaLink::new() }; 7];

/// The host link's index in [`DMA_LINKS`] and [`LINK_DMA`].
#[cfg(dma_links)]
const HOST_LINK: usize = NEIGHBOUR_UARTS;

/// A U(S)ART: its registers, and how its bytes reach memory.
#[derive(Debug)]
pub struct Uart {
    regs: Regs,
    bytes: Bytes,
    /// The count of lost bytes when last taken (the count only grows, so
    /// the difference is taken here).
    lost_taken: u32,
}

/// How a U(S)ART's bytes move between it and memory.
#[derive(Debug)]
enum Bytes {
    /// By its interrupt: the handler moves received bytes into one ring and
    /// bytes to send out of another (see [`super::byte_ring`]).
    #[cfg(not(dma_links))]
    Interrupt(&'static Rings),
    /// By two DMA streams (see [`super::dma_link`]).
    #[cfg(dma_links)]
    Dma(DmaPort),
}

#[cfg(not(dma_links))]
impl core::fmt::Debug for Rings {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Rings").field("rx", &self.rx).field("tx", &self.tx).finish()
    }
}

impl Uart {
    /// Sets the rate and enables transmitter, receiver and the receive
    /// interrupt; the transmit interrupt is enabled while bytes wait. The
    /// bus clock must be on.
    #[cfg(not(dma_links))]
    fn new(regs: Regs, brr: Brr, rings: &'static Rings) -> Self {
        set_rate(regs, brr);
        with_regs!(regs, r => {
            r.cr1().write(|w| w.ue().set_bit().te().set_bit().re().set_bit().rxneie().set_bit());
        });
        Self { regs, bytes: Bytes::Interrupt(rings), lost_taken: 0 }
    }

    /// Neighbour link `link`'s U(S)ART: moved by DMA where the image has
    /// it, else by interrupt through the link's rings.
    fn neighbour(regs: Regs, brr: Brr, link: usize) -> Self {
        #[cfg(dma_links)]
        return Self::with_dma(regs, brr, link);
        #[cfg(not(dma_links))]
        {
            let Some(rings) = RINGS.get(link + 1) else { exit(false) };
            Self::new(regs, brr, rings)
        }
    }

    /// The host link's U(S)ART, moved as the neighbours' are.
    fn host(regs: Regs, brr: Brr) -> Self {
        #[cfg(dma_links)]
        return Self::with_dma(regs, brr, HOST_LINK);
        #[cfg(not(dma_links))]
        Self::new(regs, brr, &RINGS[0])
    }

    /// Sets the rate, starts the DMA streams of link `link` ([`LINK_DMA`]) and
    /// turns on the U(S)ART's DMA requests, transmitter and receiver. Its
    /// receive interrupt is on only while the loop sleeps ([`sleep`]). The
    /// bus clock and the DMA controllers' must be on.
    #[cfg(dma_links)]
    fn with_dma(regs: Regs, brr: Brr, link: usize) -> Self {
        set_rate(regs, brr);
        let (Some(ring), Some(&streams)) = (DMA_LINKS.get(link), LINK_DMA.get(link)) else { exit(false) };
        let dr = with_regs!(regs, r => r.dr().as_ptr() as u32);
        let Some(port) = DmaPort::start(ring, streams, dr) else { exit(false) };
        with_regs!(regs, r => {
            r.cr3().write(|w| w.dmar().set_bit().dmat().set_bit());
            r.cr1().write(|w| w.ue().set_bit().te().set_bit().re().set_bit());
        });
        Self { regs, bytes: Bytes::Dma(port), lost_taken: 0 }
    }
}

/// Clears TC in a U(S)ART's SR, which a DMA stream's writes to DR leave
/// set (RM0430, "Transmission using DMA"), so that [`Uart::flush`] waits for
/// the bytes queued now. SR's other clearable flags (RXNE, LBD and, on a
/// USART, CTS) are written 1, which leaves them as they are: a 0 would take
/// a received byte from under its stream.
#[cfg(dma_links)]
fn clear_transmission_complete(regs: Regs) {
    const RXNE: u16 = 1 << 5;
    const LBD: u16 = 1 << 8;
    const CTS: u16 = 1 << 9;
    // SAFETY: SR's writable bits are all clear-by-zero; the bits written 1
    // are the ones it has, and TC alone is written 0.
    match regs {
        Regs::Usart(r) => r.sr().write(|w| unsafe { w.bits(RXNE | LBD | CTS) }),
        Regs::Uart(r) => r.sr().write(|w| unsafe { w.bits(RXNE | LBD) }),
    };
}

/// Sets a U(S)ART's baud-rate register.
fn set_rate(regs: Regs, brr: Brr) {
    let (mantissa, fraction) = (brr.value >> 4, (brr.value & 0xF) as u8);
    with_regs!(regs, r => r.brr().write(|w| w.div_mantissa().set(mantissa).div_fraction().set(fraction)));
}

/// A UART's interrupt, one byte each way at most: the byte received, and
/// the next byte to send while the transmit interrupt is on. Every byte a
/// link moves costs one of these, so it is kept short (the CPU cycles a
/// byte of `sim_board::link_spec::Transfer::Interrupt` count its path):
/// - one read of SR for both directions;
/// - no second look for another byte: the UART holds one each way, and a
///   flag still set raises the interrupt again at once (tail-chained);
/// - whether to send is a flag in memory ([`Rings::sending`]), not a read
///   of CR1;
/// - inlined into each UART's handler, so its registers' address is a
///   constant and the block's kind is known.
///
/// Reading SR then DR takes the byte and clears an overrun; an overrun
/// means a byte was lost before this ran.
#[cfg(not(dma_links))]
#[inline(always)]
fn service(regs: Regs, rings: &Rings) {
    let (received, overrun, empty) = with_regs!(regs, r => {
        let sr = r.sr().read();
        (sr.rxne().bit_is_set(), sr.ore().bit_is_set(), sr.txe().bit_is_set())
    });
    if received {
        if overrun {
            rings.rx.note_lost();
        }
        if !rings.rx.push(with_regs!(regs, r => r.dr().read().dr().bits()) as u8) {
            rings.rx.note_lost();
        }
    }
    if empty && rings.sending.load(Ordering::Relaxed) {
        match rings.tx.pop() {
            Some(byte) => {
                with_regs!(regs, r => r.dr().write(|w| w.dr().set(u16::from(byte))));
            }
            None => stop_sending(regs, rings),
        }
    }
}

/// Turns the transmit interrupt off (TXE stays set while the line is idle),
/// with nothing left to send. No byte is stranded with it off: the loop
/// turns it on again with every byte it queues ([`Uart::write`]).
#[cfg(not(dma_links))]
fn stop_sending(regs: Regs, rings: &Rings) {
    with_regs!(regs, r => r.cr1().modify(|_, w| w.txeie().clear_bit()));
    rings.sending.store(false, Ordering::Relaxed);
}

/// Writes while the UART takes bytes and any wait; with none left, turns
/// the transmit interrupt off. The loop's start of the line, inside a
/// critical section.
#[cfg(not(dma_links))]
fn transmit(regs: Regs, rings: &Rings) {
    while with_regs!(regs, r => r.sr().read().txe().bit_is_set()) {
        let Some(byte) = rings.tx.pop() else {
            stop_sending(regs, rings);
            return;
        };
        with_regs!(regs, r => r.dr().write(|w| w.dr().set(u16::from(byte))));
    }
}

/// The registers of the U(S)ART at `block`, for its interrupt handler.
fn regs_at<RB>(block: *const RB) -> &'static RB {
    // SAFETY: `block` is a PAC peripheral's fixed address, valid for ever.
    // The loop writes the registers only inside a critical section
    // (starting the transmitter), so it and the handler never interleave
    // on them; outside one it only reads SR (for TC, in a flush).
    unsafe { &*block }
}

/// Each U(S)ART's interrupt handler, and [`IRQS`], from one list: the
/// index of its rings in [`RINGS`], its name (interrupt and peripheral
/// alike) and its register block's kind.
#[cfg(not(dma_links))]
macro_rules! uart_interrupts {
    ($($ring:literal: $name:ident $kind:ident),+ $(,)?) => {
        /// The interrupts of the U(S)ARTs that move bytes by interrupt.
        const IRQS: &[Interrupt] = &[$(Interrupt::$name),+];
        $(
            #[interrupt]
            fn $name() {
                service(Regs::$kind(regs_at(pac::$name::ptr())), &RINGS[$ring]);
            }
        )+
    };
}

#[cfg(all(not(dma_links), feature = "netduinoplus2"))]
uart_interrupts! {
    0: USART3 Usart,
    1: USART1 Usart,
    2: USART2 Usart,
    3: UART4 Uart,
    4: UART5 Uart,
    5: USART6 Usart,
    6: UART7 Uart,
}

#[cfg(all(not(dma_links), not(feature = "netduinoplus2")))]
uart_interrupts! {
    0: USART3 Usart,
    1: USART1 Usart,
    2: USART2 Usart,
    3: UART4 Uart,
    4: UART5 Uart,
    5: USART6 Usart,
    6: UART10 Uart,
}

/// No U(S)ART moves bytes by interrupt.
#[cfg(dma_links)]
const IRQS: &[Interrupt] = &[];

/// The U(S)ARTs' interrupts when their bytes move by DMA: raised by a byte
/// received while the loop sleeps ([`sleep`] turns them on), they only turn
/// themselves off again. Their registers in [`LINK_DMA`]'s order
/// ([`link_regs`]) and their lines ([`WAKE_IRQS`]) from one list.
#[cfg(dma_links)]
macro_rules! wake_interrupts {
    ($($name:ident $kind:ident),+ $(,)?) => {
        /// The U(S)ARTs' lines.
        const WAKE_IRQS: &[Interrupt] = &[$(Interrupt::$name),+];

        /// The U(S)ARTs' registers, in [`LINK_DMA`]'s order.
        fn link_regs() -> [Regs; 7] {
            [$(Regs::$kind(regs_at(pac::$name::ptr()))),+]
        }

        $(
            #[interrupt]
            fn $name() {
                let regs = Regs::$kind(regs_at(pac::$name::ptr()));
                with_regs!(regs, r => r.cr1().modify(|_, w| w.rxneie().clear_bit()));
            }
        )+
    };
}

#[cfg(dma_links)]
wake_interrupts! {
    USART1 Usart,
    USART2 Usart,
    UART4 Uart,
    UART5 Uart,
    USART6 Usart,
    UART10 Uart,
    USART3 Usart,
}

/// The DMA streams' interrupts of each link (receive, then send), and
/// [`DMA_IRQS`], from one list. Each interrupt is checked against the
/// link's streams in [`LINK_DMA`] when the firmware builds.
#[cfg(dma_links)]
macro_rules! dma_interrupts {
    ($($link:literal: $rx:ident $tx:ident),+ $(,)?) => {
        /// The DMA streams' lines.
        const DMA_IRQS: &[Interrupt] = &[$(Interrupt::$rx, Interrupt::$tx),+];
        $(
            const _: () = assert!(
                matches!(stream_irq(LINK_DMA[$link].rx), Some(Interrupt::$rx))
                    && matches!(stream_irq(LINK_DMA[$link].tx), Some(Interrupt::$tx)),
                "a DMA interrupt that is not its link's stream"
            );

            #[interrupt]
            fn $rx() {
                let link = DMA_LINKS.get($link);
                if let (Some(link), Some(rx)) = (link, LINK_DMA.get($link).and_then(|s| Dma::of(s.rx))) {
                    link.on_received(rx);
                }
            }

            #[interrupt]
            fn $tx() {
                let link = DMA_LINKS.get($link);
                if let (Some(link), Some(tx)) = (link, LINK_DMA.get($link).and_then(|s| Dma::of(s.tx))) {
                    link.on_sent(tx);
                }
            }
        )+
    };
}

#[cfg(dma_links)]
dma_interrupts! {
    0: DMA2_STREAM2 DMA2_STREAM7,
    1: DMA1_STREAM5 DMA1_STREAM6,
    2: DMA1_STREAM2 DMA1_STREAM4,
    3: DMA1_STREAM0 DMA1_STREAM7,
    4: DMA2_STREAM1 DMA2_STREAM6,
    5: DMA2_STREAM0 DMA2_STREAM5,
    6: DMA1_STREAM1 DMA1_STREAM3,
}

/// A stream's interrupt line.
#[cfg(dma_links)]
const fn stream_irq(s: clock_tree::dma::Stream) -> Option<Interrupt> {
    use Interrupt as I;
    use clock_tree::dma::Controller::{Dma1, Dma2};
    Some(match (s.controller, s.stream) {
        (Dma1, 0) => I::DMA1_STREAM0,
        (Dma1, 1) => I::DMA1_STREAM1,
        (Dma1, 2) => I::DMA1_STREAM2,
        (Dma1, 3) => I::DMA1_STREAM3,
        (Dma1, 4) => I::DMA1_STREAM4,
        (Dma1, 5) => I::DMA1_STREAM5,
        (Dma1, 6) => I::DMA1_STREAM6,
        (Dma1, 7) => I::DMA1_STREAM7,
        (Dma2, 0) => I::DMA2_STREAM0,
        (Dma2, 1) => I::DMA2_STREAM1,
        (Dma2, 2) => I::DMA2_STREAM2,
        (Dma2, 3) => I::DMA2_STREAM3,
        (Dma2, 4) => I::DMA2_STREAM4,
        (Dma2, 5) => I::DMA2_STREAM5,
        (Dma2, 6) => I::DMA2_STREAM6,
        (Dma2, 7) => I::DMA2_STREAM7,
        _ => return None,
    })
}

impl ErrorType for Uart {
    type Error = Infallible;
}

impl super::LostBytes for Uart {
    fn take_lost(&mut self) -> u32 {
        let lost = match &mut self.bytes {
            #[cfg(not(dma_links))]
            Bytes::Interrupt(rings) => rings.rx.lost(),
            // An overrun in the U(S)ART (the stream late) counts one byte;
            // reading SR here and the stream's next read of DR clear it.
            #[cfg(dma_links)]
            Bytes::Dma(port) => {
                let overrun = with_regs!(self.regs, r => r.sr().read().ore().bit_is_set());
                port.lost().wrapping_add(u32::from(overrun))
            }
        };
        lost.wrapping_sub(core::mem::replace(&mut self.lost_taken, lost))
    }
}

impl ReadReady for Uart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(match &mut self.bytes {
            #[cfg(not(dma_links))]
            Bytes::Interrupt(rings) => !rings.rx.is_empty(),
            #[cfg(dma_links)]
            Bytes::Dma(port) => port.read_ready(),
        })
    }
}

impl Read for Uart {
    /// Blocks until a byte arrives (embedded-io's contract); reads one.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else { return Ok(0) };
        *first = loop {
            let byte = match &mut self.bytes {
                #[cfg(not(dma_links))]
                Bytes::Interrupt(rings) => rings.rx.pop(),
                #[cfg(dma_links)]
                Bytes::Dma(port) => port.read_byte(),
            };
            if let Some(byte) = byte {
                break byte;
            }
        };
        Ok(1)
    }
}

impl WriteReady for Uart {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(match &self.bytes {
            #[cfg(not(dma_links))]
            Bytes::Interrupt(rings) => !rings.tx.is_full(),
            #[cfg(dma_links)]
            Bytes::Dma(port) => port.write_ready(),
        })
    }
}

impl Write for Uart {
    /// Blocks until there is room (embedded-io's contract); queues what
    /// fits of `buf`, starts the transmitter and lets the handler go on.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        while !self.write_ready()? {}
        match &mut self.bytes {
            #[cfg(not(dma_links))]
            Bytes::Interrupt(rings) => Ok(write_by_interrupt(self.regs, rings, buf)),
            #[cfg(dma_links)]
            Bytes::Dma(port) => {
                clear_transmission_complete(self.regs);
                Ok(port.write(buf))
            }
        }
    }

    /// Waits until every queued byte has left the UART.
    fn flush(&mut self) -> Result<(), Infallible> {
        let queued = |bytes: &Bytes| match bytes {
            #[cfg(not(dma_links))]
            Bytes::Interrupt(rings) => !rings.tx.is_empty(),
            #[cfg(dma_links)]
            Bytes::Dma(port) => !port.sent_all(),
        };
        while queued(&self.bytes) || !with_regs!(self.regs, r => r.sr().read().tc().bit_is_set()) {}
        Ok(())
    }
}

/// Queues what fits of `buf` in `rings`, starts the transmitter and lets
/// the handler go on; how many bytes it queued.
#[cfg(not(dma_links))]
fn write_by_interrupt(regs: Regs, rings: &Rings, buf: &[u8]) -> usize {
    let queued = buf.iter().take_while(|&&b| rings.tx.push(b)).count();
    // Start the line now rather than at the interrupt's next turn; the
    // interrupt goes on while the loop is busy elsewhere. (QEMU 7.2's
    // USART model raises no transmit interrupt: there this start sends
    // everything, the model taking each byte at once.)
    cortex_m::interrupt::free(|_| {
        with_regs!(regs, r => r.cr1().modify(|_, w| w.txeie().set_bit()));
        rings.sending.store(true, Ordering::Relaxed);
        transmit(regs, rings);
    });
    queued
}

/// TIM2, free-running up over 32 bits at the core clock (its APB1 is
/// divided by two, so the timer clock is twice the bus's).
#[derive(Debug)]
pub struct Timer {
    tim: &'static tim2::RegisterBlock,
    widen: Widen,
    hz: u64,
}

impl Timer {
    /// Starts TIM2 from zero, undivided, counting at `hz`. Its bus clock must be on.
    fn start(tim: &'static tim2::RegisterBlock, hz: u64) -> Self {
        tim.psc().write(|w| w.psc().set(0));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // Update event: loads the prescaler and clears the counter.
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().write(|w| w.cen().set_bit());
        Self { tim, widen: Widen::new(tim.cnt().read().bits()), hz }
    }
}

impl Clock for Timer {
    fn now(&mut self) -> u64 {
        self.widen.up(self.tim.cnt().read().bits())
    }

    fn ticks_per_second(&self) -> u64 {
        self.hz
    }
}

/// This board's parts: the user LEDs are LD1 (green) lit while working, LD3 (red) once failed.
pub type Parts = super::Parts<Uart, Timer, Led, NEIGHBOUR_UARTS>;

/// Brings the board up: the core clock first, then the UARTs at their rates.
pub fn init() -> Parts {
    // `init` runs once, first: the peripherals are there to take.
    let Some(dp) = pac::Peripherals::take() else { exit(false) };
    let rcc = keep(dp.RCC);
    let core = start_clocks(rcc, keep(dp.PWR), keep(dp.FLASH));
    rcc.ahb1enr().modify(|_, w| {
        w.gpioaen().set_bit().gpioben().set_bit().gpiocen().set_bit().gpioden().set_bit().gpioeen().set_bit()
    });
    rcc.apb1enr().modify(|_, w| {
        let w = w.tim2en().set_bit().usart2en().set_bit().usart3en().set_bit();
        w.uart4en().set_bit().uart5en().set_bit()
    });
    rcc.apb2enr().modify(|_, w| w.usart1en().set_bit().usart6en().set_bit());
    let (a, b, c, d, e) = (keep(dp.GPIOA), keep(dp.GPIOB), keep(dp.GPIOC), keep(dp.GPIOD), keep(dp.GPIOE));
    alternate!(d, 7, 8, 9); // USART3: host
    alternate!(b, 7, 6, 7); // USART1: +X
    alternate!(d, 7, 5, 6); // USART2: -X
    alternate!(a, 8, 0, 1); // UART4: +Y
    alternate!(c, 8, 12); // UART5 TX: -Y
    alternate!(d, 8, 2); // UART5 RX
    alternate!(c, 8, 6, 7); // USART6: +Z
    // -Z: UART10 on the NUCLEO, UART7 on QEMU's SoC, which has no UART10.
    #[cfg(not(feature = "netduinoplus2"))]
    let minus_z = {
        rcc.apb2enr().modify(|_, w| w.uart10en().set_bit());
        alternate!(e, 11, 2, 3);
        (Regs::Uart(keep(dp.UART10)), NEIGHBOUR_APB2)
    };
    #[cfg(feature = "netduinoplus2")]
    let minus_z = {
        rcc.apb1enr().modify(|_, w| w.uart7en().set_bit());
        alternate!(e, 8, 7, 8);
        (Regs::Uart(keep(dp.UART7)), NEIGHBOUR_APB1)
    };
    let host = Regs::Usart(keep(dp.USART3));
    let regs = [
        (Regs::Usart(keep(dp.USART1)), NEIGHBOUR_APB2),
        (Regs::Usart(keep(dp.USART2)), NEIGHBOUR_APB1),
        (Regs::Uart(keep(dp.UART4)), NEIGHBOUR_APB1),
        (Regs::Uart(keep(dp.UART5)), NEIGHBOUR_APB1),
        (Regs::Usart(keep(dp.USART6)), NEIGHBOUR_APB2),
        minus_z,
    ];
    #[cfg(dma_links)]
    {
        // The streams are DMA1's and DMA2's, which are taken here for good.
        let (_dma1, _dma2) = (keep(dp.DMA1), keep(dp.DMA2));
        rcc.ahb1enr().modify(|_, w| w.dma1en().set_bit().dma2en().set_bit());
    }
    let mut link = 0;
    let neighbours = regs.map(|(r, brr)| {
        link += 1;
        Uart::neighbour(r, brr, link - 1)
    });
    let host = Uart::host(host, HOST_APB1);
    let lights = Lights::new(Led::new(b, LD1_GREEN), Led::new(b, LD3_RED));
    let info = board_info(core);
    Parts { host, neighbours, clock: Timer::start(keep(dp.TIM2), timer_hz(&info)), info, lights }
}

/// TIM2's rate: the core clock on a real board; under QEMU it counts
/// virtual nanoseconds whatever the (stub) clock tree says.
fn timer_hz(info: &BoardInfo) -> u64 {
    if cfg!(feature = "netduinoplus2") { 1_000_000_000 } else { u64::from(info.clock_hz) }
}

/// The NUCLEO-F413ZH's user LEDs on port B (UM1974: LD1 green on PB0, LD2
/// blue on PB7, LD3 red on PB14). LD2's pin is USART1's RX (+X), so it stays
/// dark.
const LD1_GREEN: u8 = 0;
const LD3_RED: u8 = 14;

/// A push-pull GPIO output on port B driving an LED, set and reset through
/// BSRR (RM0430 7.4.7: atomic, no read-modify-write).
#[derive(Debug)]
pub struct Led {
    gpio: &'static gpiob::RegisterBlock,
    pin: u8,
}

impl Led {
    fn new(gpio: &'static gpiob::RegisterBlock, pin: u8) -> Self {
        gpio.moder().modify(|_, w| w.moder(pin).output());
        Self { gpio, pin }
    }
}

impl PinErrorType for Led {
    type Error = Infallible;
}

impl OutputPin for Led {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.gpio.bsrr().write(|w| w.br(self.pin).set_bit());
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.gpio.bsrr().write(|w| w.bs(self.pin).set_bit());
        Ok(())
    }
}

/// Where the host puts an emulated board's id: the last 16 bytes of the
/// 192 KiB of RAM that `memory/netduinoplus2.x` claims (QEMU's SoC has no
/// unique id).
#[cfg(feature = "netduinoplus2")]
pub const ID_CELL: usize = 0x2002_FFF0;

#[cfg(feature = "netduinoplus2")]
const KIND: BoardKind = BoardKind::Netduinoplus2;
#[cfg(not(feature = "netduinoplus2"))]
const KIND: BoardKind = BoardKind::NucleoF413zh;

#[cfg(feature = "netduinoplus2")]
fn board_id() -> BoardId {
    identity::emulated(ID_CELL)
}
#[cfg(not(feature = "netduinoplus2"))]
fn board_id() -> BoardId {
    identity::stm32_uid()
}

/// The board as its hello names it. On the reset clock the baud rates are
/// not the ones set, so none is claimed.
fn board_info(core: CoreClock) -> BoardInfo {
    let (clock_hz, clock_source, link_baud, host_baud) = match core {
        CoreClock::PllFromHse => (FROM_HSE.sysclk(), ClockSource::PllFromExternal, NEIGHBOUR_BAUD, HOST_BAUD),
        CoreClock::PllFromHsi => (FROM_HSI.sysclk(), ClockSource::PllFromInternal, NEIGHBOUR_BAUD, HOST_BAUD),
        CoreClock::Hsi => (16_000_000, ClockSource::Reset, 0, 0),
    };
    BoardInfo {
        id: board_id(),
        kind: KIND,
        firmware: identity::FIRMWARE,
        clock_hz,
        clock_source,
        link_baud,
        host_baud,
    }
}

/// SysTick period while idle: 2 ms at 100 MHz.
pub const WAKE_PERIOD: u32 = 200_000;

/// Starts the wake-up tick and lets the U(S)ARTs' receive interrupts run:
/// theirs are the only lines enabled, and their handlers only move bytes
/// into the rings.
pub fn arm_wakeups() {
    super::wake::start_tick(WAKE_PERIOD);
    for &irq in IRQS {
        // SAFETY: each of these lines has its handler above, which touches
        // nothing but its UART's SR and DR and its ring's producer side.
        unsafe { NVIC::unmask(irq) };
    }
    #[cfg(dma_links)]
    for &irq in WAKE_IRQS.iter().chain(DMA_IRQS) {
        // SAFETY: each has its handler above: a U(S)ART's clears its own
        // receive interrupt enable; a stream's touches its flags, its link's
        // handler-side indices and (to start a run) its own registers.
        unsafe { NVIC::unmask(irq) };
    }
    // SAFETY: called once at boot, outside any critical section.
    unsafe { cortex_m::interrupt::enable() };
}

/// Sleeps unless a byte is waiting. The check and the `wfi` run with
/// interrupts masked, so a byte that arrives between them still ends the
/// `wfi` (a pending interrupt wakes a masked core) and is taken by its
/// handler once they are unmasked again.
///
/// Bytes a DMA stream receives raise no interrupt, so before sleeping the
/// U(S)ARTs' receive interrupts are turned on (each handler
/// turns its own off again), and the streams are looked at once more: a
/// byte that came before the interrupt was on raised none.
pub fn sleep() {
    cortex_m::interrupt::free(|_| {
        if !nothing_waits() {
            return;
        }
        #[cfg(dma_links)]
        {
            for regs in link_regs() {
                with_regs!(regs, r => r.cr1().modify(|_, w| w.rxneie().set_bit()));
            }
            if !nothing_waits() {
                return;
            }
        }
        cortex_m::asm::wfi();
    });
}

/// Whether no received byte waits for the loop.
fn nothing_waits() -> bool {
    #[cfg(not(dma_links))]
    return RINGS.iter().all(|r| r.rx.is_empty());
    #[cfg(dma_links)]
    DMA_LINKS.iter().zip(LINK_DMA).all(|(link, s)| link.caught_up(s.rx))
}

/// Nothing to forget: the handlers take what pends.
pub fn clear_wakeups() {}

/// The wake-up tick's only work is to end a `wfi`.
#[exception]
fn SysTick() {}

/// Under QEMU the emulation ends (semihosting); a real board has nothing
/// to exit to: it stops.
pub fn exit(success: bool) -> ! {
    #[cfg(feature = "netduinoplus2")]
    {
        use cortex_m_semihosting::debug;
        debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    }
    let _ = success;
    loop {
        cortex_m::asm::wfi();
    }
}
