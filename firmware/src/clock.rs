//! The board's clock, in cycles.
//!
//! The node only uses time to split running from waiting and to time
//! resends, so a free-running counter is enough. On QEMU with `-icount
//! shift=0` every instruction takes 1 ns of virtual time; the mps2 clock
//! reports nanoseconds, which then count instructions exactly (to the timer's
//! 40-instruction resolution), the unit of the in-memory board's cost model.

/// A monotonic cycle counter.
pub trait Clock {
    /// Cycles since start.
    fn now(&mut self) -> u64;

    /// How many of [`Clock::now`]'s units make a second, so that waits
    /// meant in time (a resend's) come out the same on every board.
    fn ticks_per_second(&self) -> u64;
}

/// Extends a wrapping 32-bit counter to 64 bits; it must be read at least
/// once per wrap.
#[derive(Debug, Default, Clone, Copy)]
pub struct Widen {
    last: u32,
    high: u64,
}

impl Widen {
    /// A widener whose first reading is `first`.
    pub const fn new(first: u32) -> Self {
        Self { last: first, high: 0 }
    }

    /// The 64-bit count for an up-counter reading.
    pub fn up(&mut self, reading: u32) -> u64 {
        if reading < self.last {
            self.high += 1 << 32;
        }
        self.last = reading;
        self.high | u64::from(reading)
    }
}
