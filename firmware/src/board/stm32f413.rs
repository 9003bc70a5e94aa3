//! NUCLEO-F413ZH: a Cortex-M4F with ten U(S)ARTs, enough for the host and all
//! six neighbours, so every node of any array is cabled the same way.
//!
//! | port | peripheral | TX | RX | AF |
//! |---|---|---|---|---|
//! | host | USART3 (ST-LINK virtual COM port) | PD8 | PD9 | 7 |
//! | +X | USART1 | PB6 | PB7 | 7 |
//! | -X | USART2 | PD5 | PD6 | 7 |
//! | +Y | UART4 | PA0 | PA1 | 8 |
//! | -Y | UART5 | PC12 | PD2 | 8 |
//! | +Z | USART6 | PC6 | PC7 | 8 |
//! | -Z | UART7 | PE8 | PE7 | 8 |
//!
//! Cable each board's +X TX to its +X neighbour's -X RX and back (crossed),
//! and likewise for Y and Z. The core runs on the 16 MHz HSI after reset;
//! every UART runs at [`BAUD`]. The clock is the DWT cycle counter.

use core::convert::Infallible;

use embedded_io::{ErrorType, Read, ReadReady, Write, WriteReady};

use super::mmio::Reg;
use crate::clock::{Clock, Widen};

/// Baud rate of every UART.
pub const BAUD: u32 = 115_200;
/// Core and peripheral clock after reset (HSI).
const CLOCK_HZ: u32 = 16_000_000;
/// Neighbour UARTs.
pub const NEIGHBOUR_UARTS: usize = 6;

const RCC: usize = 0x4002_3800;
const AHB1ENR: usize = 0x30;
const APB1ENR: usize = 0x40;
const APB2ENR: usize = 0x44;
const GPIO: usize = 0x4002_0000;
const GPIO_STRIDE: usize = 0x400;
const MODER: usize = 0x00;
const AFRL: usize = 0x20;
const AFRH: usize = 0x24;

const SR: usize = 0x00;
const DR: usize = 0x04;
const BRR: usize = 0x08;
const CR1: usize = 0x0C;
const SR_ORE: u32 = 1 << 3;
const SR_RXNE: u32 = 1 << 5;
const SR_TXE: u32 = 1 << 7;
/// Enabled, TX, RX, RX interrupt (it only pends: see [`super::wake`]).
const CR1_UE_TE_RE: u32 = (1 << 13) | (1 << 5) | (1 << 3) | (1 << 2);

/// A GPIO pin: port (0 = A) and number.
#[derive(Debug, Clone, Copy)]
struct Pin(usize, usize);

/// One U(S)ART: base, clock-enable register and bit, pins, alternate function.
#[derive(Debug, Clone, Copy)]
struct UartDef {
    base: usize,
    enable: (usize, u32),
    tx: Pin,
    rx: Pin,
    af: u32,
}

const A: usize = 0;
const B: usize = 1;
const C: usize = 2;
const D: usize = 3;
const E: usize = 4;

/// Host, then +X, -X, +Y, -Y, +Z, -Z (the table above).
const UARTS: [UartDef; 7] = [
    UartDef { base: 0x4000_4800, enable: (APB1ENR, 18), tx: Pin(D, 8), rx: Pin(D, 9), af: 7 },
    UartDef { base: 0x4001_1000, enable: (APB2ENR, 4), tx: Pin(B, 6), rx: Pin(B, 7), af: 7 },
    UartDef { base: 0x4000_4400, enable: (APB1ENR, 17), tx: Pin(D, 5), rx: Pin(D, 6), af: 7 },
    UartDef { base: 0x4000_4C00, enable: (APB1ENR, 19), tx: Pin(A, 0), rx: Pin(A, 1), af: 8 },
    UartDef { base: 0x4000_5000, enable: (APB1ENR, 20), tx: Pin(C, 12), rx: Pin(D, 2), af: 8 },
    UartDef { base: 0x4001_1400, enable: (APB2ENR, 5), tx: Pin(C, 6), rx: Pin(C, 7), af: 8 },
    UartDef { base: 0x4000_7800, enable: (APB1ENR, 30), tx: Pin(E, 8), rx: Pin(E, 7), af: 8 },
];

fn alternate(pin: Pin, af: u32) {
    let Pin(port, n) = pin;
    Reg::at(RCC, AHB1ENR).modify(1 << port, 1 << port);
    let gpio = GPIO + port * GPIO_STRIDE;
    Reg::at(gpio, MODER).modify(0b11 << (2 * n), 0b10 << (2 * n));
    let (afr, shift) = if n < 8 { (AFRL, 4 * n) } else { (AFRH, 4 * (n - 8)) };
    Reg::at(gpio, afr).modify(0xF << shift, af << shift);
}

/// A polled STM32F4 U(S)ART.
#[derive(Debug)]
pub struct Uart {
    base: usize,
    /// Receive overruns seen (bytes lost in hardware; the reliable channel resends).
    pub overruns: u32,
}

impl Uart {
    fn new(def: UartDef) -> Self {
        let (reg, bit) = def.enable;
        Reg::at(RCC, reg).modify(1 << bit, 1 << bit);
        alternate(def.tx, def.af);
        alternate(def.rx, def.af);
        Reg::at(def.base, BRR).write((CLOCK_HZ + BAUD / 2) / BAUD);
        Reg::at(def.base, CR1).write(CR1_UE_TE_RE);
        Self { base: def.base, overruns: 0 }
    }

    fn status(&self) -> u32 {
        Reg::at(self.base, SR).read()
    }
}

impl ErrorType for Uart {
    type Error = Infallible;
}

impl ReadReady for Uart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.status() & SR_RXNE != 0)
    }
}

impl Read for Uart {
    /// Blocks until a byte arrives (embedded-io's contract); reads one.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else { return Ok(0) };
        let mut sr = self.status();
        while sr & SR_RXNE == 0 {
            sr = self.status();
        }
        // An overrun keeps the byte in DR and loses the next; reading SR then
        // DR delivers the kept byte and clears the overrun.
        if sr & SR_ORE != 0 {
            self.overruns = self.overruns.wrapping_add(1);
        }
        *first = Reg::at(self.base, DR).read() as u8;
        Ok(1)
    }
}

impl WriteReady for Uart {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(Reg::at(self.base, SR).read() & SR_TXE != 0)
    }
}

impl Write for Uart {
    /// Blocks until there is room (embedded-io's contract); writes one byte.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let Some(&first) = buf.first() else { return Ok(0) };
        while Reg::at(self.base, SR).read() & SR_TXE == 0 {}
        Reg::at(self.base, DR).write(u32::from(first));
        Ok(1)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while Reg::at(self.base, SR).read() & SR_TXE == 0 {}
        Ok(())
    }
}

/// The host UART and the six neighbour UARTs, in port order.
pub fn uarts() -> (Uart, [Uart; NEIGHBOUR_UARTS]) {
    let [host, px, nx, py, ny, pz, nz] = UARTS.map(Uart::new);
    (host, [px, nx, py, ny, pz, nz])
}

/// The DWT cycle counter as the clock.
#[derive(Debug)]
pub struct Timer {
    widen: Widen,
}

impl Timer {
    /// Enables the cycle counter.
    pub fn start(mut core: cortex_m::Peripherals) -> Self {
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
        Self { widen: Widen::new(cortex_m::peripheral::DWT::cycle_count()) }
    }
}

impl Clock for Timer {
    fn now(&mut self) -> u64 {
        self.widen.up(cortex_m::peripheral::DWT::cycle_count())
    }
}

/// The host UART, the neighbour UARTs and the clock.
pub fn init() -> (Uart, [Uart; NEIGHBOUR_UARTS], Timer) {
    let Some(core) = cortex_m::Peripherals::take() else { exit(false) };
    let (host, neighbours) = uarts();
    (host, neighbours, Timer::start(core))
}

/// SysTick period while idle: 2 ms at 16 MHz.
pub const WAKE_PERIOD: u32 = 32_000;

/// Clears what pended (NVIC, SysTick) before a poll; a UART's receive
/// interrupt clears itself when its byte is read.
pub fn clear_wakeups() {
    super::wake::clear();
}

/// Nothing to exit to on a real board: stop.
pub fn exit(_success: bool) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}
