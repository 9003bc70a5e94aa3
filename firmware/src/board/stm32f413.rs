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
//! | -Z | UART7 | APB1 | PE8 | PE7 | 8 |
//!
//! Cable each board's +X TX to its +X neighbour's -X RX and back (crossed),
//! and likewise for Y and Z. The core runs at 100 MHz from the PLL and the
//! links at the rates of [`clock_tree::nucleo_f413zh`]; the clock is TIM2,
//! a 32-bit timer at the core clock.
//!
//! Under QEMU the RCC is a stub whose ready flags never rise: every wait for
//! one is bounded, the core stays on its reset clock, and the emulator
//! ignores baud rates anyway. TIM2 there counts virtual nanoseconds, which
//! `-icount shift=0` makes instructions, the in-memory board's unit.

use core::convert::Infallible;

use clock_tree::nucleo_f413zh::{
    FROM_HSE, FROM_HSI, HOST_APB1, HOST_BAUD, NEIGHBOUR_APB1, NEIGHBOUR_APB2, NEIGHBOUR_BAUD,
};
use clock_tree::{Brr, ClockPlan};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_io::{ErrorType, Read, ReadReady, Write, WriteReady};
use link_proto::{BoardId, BoardInfo, BoardKind, ClockSource};

use super::identity;
use super::mmio::Reg;
use crate::clock::{Clock, Widen};
use crate::lights::Lights;

/// Neighbour UARTs.
pub const NEIGHBOUR_UARTS: usize = 6;

const RCC: usize = 0x4002_3800;
const RCC_CR: usize = 0x00;
const RCC_PLLCFGR: usize = 0x04;
const RCC_CFGR: usize = 0x08;
const AHB1ENR: usize = 0x30;
const APB1ENR: usize = 0x40;
const APB2ENR: usize = 0x44;
const CR_HSEON: u32 = 1 << 16;
const CR_HSERDY: u32 = 1 << 17;
const CR_HSEBYP: u32 = 1 << 18;
const CR_PLLON: u32 = 1 << 24;
const CR_PLLRDY: u32 = 1 << 25;
const CFGR_SWS_PLL: u32 = 0b10 << 2;
const CFGR_SWS: u32 = 0b11 << 2;
const APB1ENR_TIM2: u32 = 1 << 0;
const APB1ENR_PWR: u32 = 1 << 28;
const PWR_CR: usize = 0x4000_7000;
/// Voltage scale 1 (VOS = 11), needed above 84 MHz.
const PWR_CR_VOS1: u32 = 0b11 << 14;
const FLASH_ACR: usize = 0x4002_3C00;
/// Polls of a ready flag before giving up on it (some milliseconds at 16 MHz;
/// the HSE and the PLL lock within hundreds of microseconds).
const READY_POLLS: u32 = 100_000;

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

const TIM2: usize = 0x4000_0000;
const TIM_CR1: usize = 0x00;
const TIM_EGR: usize = 0x14;
const TIM_CNT: usize = 0x24;
const TIM_PSC: usize = 0x28;
const TIM_ARR: usize = 0x2C;

/// A GPIO pin: port (0 = A) and number.
#[derive(Debug, Clone, Copy)]
struct Pin(usize, usize);

/// One U(S)ART: base, clock-enable register and bit, pins, alternate
/// function, baud-rate register.
#[derive(Debug, Clone, Copy)]
struct UartDef {
    base: usize,
    enable: (usize, u32),
    tx: Pin,
    rx: Pin,
    af: u32,
    brr: Brr,
}

const A: usize = 0;
const B: usize = 1;
const C: usize = 2;
const D: usize = 3;
const E: usize = 4;

const NA1: Brr = NEIGHBOUR_APB1;
const NA2: Brr = NEIGHBOUR_APB2;

/// Host, then +X, -X, +Y, -Y, +Z, -Z (the table above).
#[rustfmt::skip]
const UARTS: [UartDef; 7] = [
    UartDef { base: 0x4000_4800, enable: (APB1ENR, 18), tx: Pin(D, 8), rx: Pin(D, 9), af: 7, brr: HOST_APB1 },
    UartDef { base: 0x4001_1000, enable: (APB2ENR, 4), tx: Pin(B, 6), rx: Pin(B, 7), af: 7, brr: NA2 },
    UartDef { base: 0x4000_4400, enable: (APB1ENR, 17), tx: Pin(D, 5), rx: Pin(D, 6), af: 7, brr: NA1 },
    UartDef { base: 0x4000_4C00, enable: (APB1ENR, 19), tx: Pin(A, 0), rx: Pin(A, 1), af: 8, brr: NA1 },
    UartDef { base: 0x4000_5000, enable: (APB1ENR, 20), tx: Pin(C, 12), rx: Pin(D, 2), af: 8, brr: NA1 },
    UartDef { base: 0x4001_1400, enable: (APB2ENR, 5), tx: Pin(C, 6), rx: Pin(C, 7), af: 8, brr: NA2 },
    UartDef { base: 0x4000_7800, enable: (APB1ENR, 30), tx: Pin(E, 8), rx: Pin(E, 7), af: 8, brr: NA1 },
];

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

/// Polls `reg` until `mask` reads `want`, at most [`READY_POLLS`] times.
fn wait_for(reg: Reg, mask: u32, want: u32) -> bool {
    (0..READY_POLLS).any(|_| reg.read() & mask == want)
}

/// Runs the core from the PLL: the ST-LINK's clock if it is there, else the
/// HSI. Voltage scale and flash wait states go up before the clock does.
fn start_clocks() -> CoreClock {
    let cr = Reg::at(RCC, RCC_CR);
    cr.modify(CR_HSEON | CR_HSEBYP, CR_HSEON | CR_HSEBYP);
    let (plan, source): (ClockPlan, CoreClock) = if wait_for(cr, CR_HSERDY, CR_HSERDY) {
        (FROM_HSE, CoreClock::PllFromHse)
    } else {
        cr.modify(CR_HSEON | CR_HSEBYP, 0);
        (FROM_HSI, CoreClock::PllFromHsi)
    };
    Reg::at(RCC, APB1ENR).modify(APB1ENR_PWR, APB1ENR_PWR);
    Reg::at(PWR_CR, 0).modify(PWR_CR_VOS1, PWR_CR_VOS1);
    Reg::at(RCC, RCC_PLLCFGR).write(plan.pllcfgr());
    cr.modify(CR_PLLON, CR_PLLON);
    if !wait_for(cr, CR_PLLRDY, CR_PLLRDY) {
        cr.modify(CR_PLLON, 0);
        return CoreClock::Hsi;
    }
    Reg::at(FLASH_ACR, 0).write(plan.flash_acr());
    Reg::at(RCC, RCC_CFGR).write(plan.cfgr());
    if wait_for(Reg::at(RCC, RCC_CFGR), CFGR_SWS, CFGR_SWS_PLL) { source } else { CoreClock::Hsi }
}

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
        Reg::at(def.base, BRR).write(u32::from(def.brr.value));
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
        Ok(self.status() & SR_TXE != 0)
    }
}

impl Write for Uart {
    /// Blocks until there is room (embedded-io's contract); writes one byte.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let Some(&first) = buf.first() else { return Ok(0) };
        while self.status() & SR_TXE == 0 {}
        Reg::at(self.base, DR).write(u32::from(first));
        Ok(1)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while self.status() & SR_TXE == 0 {}
        Ok(())
    }
}

/// The host UART and the six neighbour UARTs, in port order.
pub fn uarts() -> (Uart, [Uart; NEIGHBOUR_UARTS]) {
    let [host, px, nx, py, ny, pz, nz] = UARTS.map(Uart::new);
    (host, [px, nx, py, ny, pz, nz])
}

/// TIM2, free-running up over 32 bits at the core clock (its APB1 is
/// divided by two, so the timer clock is twice the bus's).
#[derive(Debug)]
pub struct Timer {
    widen: Widen,
}

impl Timer {
    /// Starts TIM2 from zero, undivided.
    pub fn start() -> Self {
        Reg::at(RCC, APB1ENR).modify(APB1ENR_TIM2, APB1ENR_TIM2);
        Reg::at(TIM2, TIM_PSC).write(0);
        Reg::at(TIM2, TIM_ARR).write(u32::MAX);
        // Update event: loads the prescaler and clears the counter.
        Reg::at(TIM2, TIM_EGR).write(1);
        Reg::at(TIM2, TIM_CR1).write(1);
        Self { widen: Widen::new(Reg::at(TIM2, TIM_CNT).read()) }
    }
}

impl Clock for Timer {
    fn now(&mut self) -> u64 {
        self.widen.up(Reg::at(TIM2, TIM_CNT).read())
    }
}

/// The board's parts the node firmware uses.
pub struct Parts {
    /// The host's UART.
    pub host: Uart,
    /// The neighbours' UARTs.
    pub neighbours: [Uart; NEIGHBOUR_UARTS],
    /// The clock.
    pub clock: Timer,
    /// What the board is, for its hellos.
    pub info: BoardInfo,
    /// The user LEDs: LD1 (green) lit while working, LD3 (red) once failed.
    pub lights: Lights<Led, Led>,
}

/// Brings the board up: the core clock first, then the UARTs at their rates.
pub fn init() -> Parts {
    let core = start_clocks();
    let (host, neighbours) = uarts();
    let lights = Lights::new(Led::new(LD1_GREEN), Led::new(LD3_RED));
    Parts { host, neighbours, clock: Timer::start(), info: board_info(core), lights }
}

/// The NUCLEO-F413ZH's user LEDs (UM1974: LD1 green on PB0, LD2 blue on
/// PB7, LD3 red on PB14). LD2's pin is USART1's RX (+X), so it stays dark.
const LD1_GREEN: Pin = Pin(B, 0);
const LD3_RED: Pin = Pin(B, 14);
const BSRR: usize = 0x18;

/// A push-pull GPIO output driving an LED, set and reset through BSRR
/// (RM0430 7.4.7: bit n sets pin n, bit n + 16 resets it, atomically).
#[derive(Debug)]
pub struct Led {
    pin: Pin,
}

impl Led {
    fn new(pin: Pin) -> Self {
        let Pin(port, n) = pin;
        Reg::at(RCC, AHB1ENR).modify(1 << port, 1 << port);
        Reg::at(GPIO + port * GPIO_STRIDE, MODER).modify(0b11 << (2 * n), 0b01 << (2 * n));
        Self { pin }
    }

    fn bsrr(&self, value: u32) {
        let Pin(port, _) = self.pin;
        Reg::at(GPIO + port * GPIO_STRIDE, BSRR).write(value);
    }
}

impl PinErrorType for Led {
    type Error = Infallible;
}

impl OutputPin for Led {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.bsrr(1 << (self.pin.1 + 16));
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        self.bsrr(1 << self.pin.1);
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

/// Clears what pended (NVIC, SysTick) before a poll; a UART's receive
/// interrupt clears itself when its byte is read.
pub fn clear_wakeups() {
    super::wake::clear();
}

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
