//! QEMU's mps2-an385: a Cortex-M3 with five CMSDK APB UARTs and APB timers.
//!
//! UART 0 is the host link; UARTs 1-4 serve the neighbour ports that exist
//! (see [`node_fw::wiring::uart_ports`]). QEMU binds them to its `-serial`
//! arguments in order. Timer 0 free-runs on the 25 MHz peripheral clock.

use core::convert::Infallible;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_io::{ErrorType, Read, ReadReady, Write, WriteReady};
use link_proto::{BoardInfo, BoardKind, ClockSource};

use super::identity;
use super::mmio::Reg;
use crate::clock::{Clock, Widen};
use crate::lights::Lights;

/// Base addresses of UART 0-4.
pub const UARTS: [usize; 5] = [0x4000_4000, 0x4000_5000, 0x4000_6000, 0x4000_7000, 0x4000_9000];
/// Neighbour UARTs (all but the host's).
pub const NEIGHBOUR_UARTS: usize = 4;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
/// A byte arrived while the last was unread, and was lost; write 1 to clear
/// (ARM CMSDK TRM, DDI 0479, APB UART STATE).
const STATE_RX_OVERRUN: u32 = 1 << 3;
/// TX and RX enabled, RX interrupt (it only pends: see [`super::wake`]).
const CTRL_TX_RX: u32 = 0b1011;
const INTCLEAR: usize = 0x0C;

/// A CMSDK APB UART, polled.
#[derive(Debug)]
pub struct Uart {
    base: usize,
    /// Receive overruns seen since they were last taken: at least a byte
    /// lost each (QEMU holds bytes back until they are read, so its UARTs
    /// never overrun).
    overruns: u32,
}

impl Uart {
    /// Enables the UART at `base` (115200 baud from 25 MHz; QEMU ignores the rate).
    pub fn new(base: usize) -> Self {
        Reg::at(base, BAUDDIV).write(25_000_000 / BAUD);
        Reg::at(base, CTRL).write(CTRL_TX_RX);
        Self { base, overruns: 0 }
    }

    #[inline]
    fn state(&self) -> u32 {
        Reg::at(self.base, STATE).read()
    }
}

impl ErrorType for Uart {
    type Error = Infallible;
}

impl ReadReady for Uart {
    #[inline]
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        let state = self.state();
        if state & STATE_RX_OVERRUN != 0 {
            self.overruns = self.overruns.wrapping_add(1);
            Reg::at(self.base, STATE).write(STATE_RX_OVERRUN);
        }
        Ok(state & STATE_RX_FULL != 0)
    }
}

impl super::LostBytes for Uart {
    /// An overrun flag says a byte or more was lost: counted as one.
    fn take_lost(&mut self) -> u32 {
        core::mem::take(&mut self.overruns)
    }
}

impl Read for Uart {
    /// Blocks until a byte arrives (embedded-io's contract); reads one.
    #[inline]
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let Some(first) = buf.first_mut() else { return Ok(0) };
        while self.state() & STATE_RX_FULL == 0 {}
        *first = Reg::at(self.base, DATA).read() as u8;
        Ok(1)
    }
}

impl WriteReady for Uart {
    #[inline]
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.state() & STATE_TX_FULL == 0)
    }
}

impl Write for Uart {
    /// Blocks until there is room (embedded-io's contract); writes one byte.
    #[inline]
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let Some(&first) = buf.first() else { return Ok(0) };
        while self.state() & STATE_TX_FULL != 0 {}
        Reg::at(self.base, DATA).write(u32::from(first));
        Ok(1)
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        while self.state() & STATE_TX_FULL != 0 {}
        Ok(())
    }
}

const TIMER0: usize = 0x4000_0000;
const TIMER_CTRL: usize = 0x00;
const TIMER_VALUE: usize = 0x04;
const TIMER_RELOAD: usize = 0x08;
/// Nanoseconds per tick of the 25 MHz timer.
const NS_PER_TICK: u64 = 40;

/// Timer 0 as a clock in nanoseconds (instructions under `-icount shift=0`).
#[derive(Debug)]
pub struct Timer {
    widen: Widen,
}

impl Timer {
    /// Starts timer 0 counting down from 2^32 - 1.
    pub fn start() -> Self {
        Reg::at(TIMER0, TIMER_RELOAD).write(u32::MAX);
        Reg::at(TIMER0, TIMER_VALUE).write(u32::MAX);
        Reg::at(TIMER0, TIMER_CTRL).write(1);
        Self { widen: Widen::new(0) }
    }

    /// Ticks since start (up-counting).
    pub fn ticks(&mut self) -> u64 {
        self.widen.up(u32::MAX - Reg::at(TIMER0, TIMER_VALUE).read())
    }
}

impl Clock for Timer {
    fn now(&mut self) -> u64 {
        self.ticks() * NS_PER_TICK
    }

    fn ticks_per_second(&self) -> u64 {
        1_000_000_000
    }
}

/// The host UART and the four neighbour UARTs.
pub fn uarts() -> (Uart, [Uart; NEIGHBOUR_UARTS]) {
    let [host, a, b, c, d] = UARTS.map(Uart::new);
    (host, [a, b, c, d])
}

/// Where the host puts this board's id: the last 16 bytes of the 64 KiB of
/// RAM that `memory/mps2-an385.x` claims.
pub const ID_CELL: usize = 0x2000_FFF0;

/// The UARTs' rate (QEMU ignores it).
const BAUD: u32 = 115_200;

/// This board's parts: the user LEDs are LED0 lit while working, LED1 once failed.
pub type Parts = super::Parts<Uart, Timer, Led, NEIGHBOUR_UARTS>;

/// Brings the board up.
pub fn init() -> Parts {
    let (host, neighbours) = uarts();
    let info = BoardInfo {
        id: identity::emulated(ID_CELL),
        kind: BoardKind::Mps2An385,
        firmware: identity::FIRMWARE,
        clock_hz: 25_000_000,
        clock_source: ClockSource::Virtual,
        link_baud: BAUD,
        host_baud: BAUD,
    };
    let lights = Lights::new(Led { bit: 0 }, Led { bit: 1 });
    Parts { host, neighbours, clock: Timer::start(), info, lights }
}

/// The FPGA's system control registers (AN385: LED0 drives the two user LEDs).
const FPGAIO: usize = 0x4002_8000;
const LED0: usize = 0x000;

/// One user LED, a bit of FPGAIO's LED0 register.
#[derive(Debug)]
pub struct Led {
    bit: u32,
}

impl PinErrorType for Led {
    type Error = Infallible;
}

impl OutputPin for Led {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Reg::at(FPGAIO, LED0).modify(1 << self.bit, 0);
        Ok(())
    }

    fn set_high(&mut self) -> Result<(), Infallible> {
        Reg::at(FPGAIO, LED0).modify(1 << self.bit, 1 << self.bit);
        Ok(())
    }
}

/// SysTick period while idle: 2 ms at 25 MHz (resends and load intervals
/// are served at least this often; a busy node polls continuously).
pub const WAKE_PERIOD: u32 = 50_000;

/// Lets the UARTs' receive interrupts and the SysTick pend, masked.
pub fn arm_wakeups() {
    super::wake::arm(WAKE_PERIOD);
}

/// Waits for an interrupt to pend.
pub fn sleep() {
    super::wake::sleep();
}

/// Clears what pended (UARTs, NVIC, SysTick) before a poll.
pub fn clear_wakeups() {
    for base in UARTS {
        Reg::at(base, INTCLEAR).write(0b11);
    }
    super::wake::clear();
}

/// Ends the emulation (semihosting exit), with success or failure.
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {
        cortex_m::asm::wfi();
    }
}
