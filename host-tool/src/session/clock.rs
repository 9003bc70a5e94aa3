//! The clocks a run's times are counted on, one type per unit, so that a
//! time can be compared, added or plotted only with times of its own clock.
//!
//! The in-memory board keeps virtual time: cycles of its modelled core,
//! deterministic. Boards, emulated or real, are timed by the host's clock as
//! their messages arrive. Their own load reports count their core's clock
//! ticks (instructions under QEMU); those stay plain numbers of the
//! [`link_proto::LoadReport`] the node sent.

use std::fmt;

/// A clock that stamps what the host receives during a run.
pub trait Clock: Copy + Ord + Default + fmt::Debug + fmt::Display {
    /// The unit, as summaries and plots name it.
    const UNIT: &'static str;
    /// The unit of the nodes' own running and waiting counts on the
    /// transports that keep this clock.
    const NODE_UNIT: &'static str;
    /// The count of units since the run began.
    fn ticks(self) -> u64;
    /// The time in the in-memory board's virtual cycles, if this clock counts them.
    fn cycles(self) -> Option<u64>;
}

/// Virtual cycles of the in-memory board's modelled core.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Cycles(pub u64);

/// Microseconds of the host's clock since the run began.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct HostMicros(pub u64);

impl Clock for Cycles {
    const UNIT: &'static str = "cycles (virtual)";
    const NODE_UNIT: &'static str = "cycles (virtual)";

    fn ticks(self) -> u64 {
        self.0
    }

    fn cycles(self) -> Option<u64> {
        Some(self.0)
    }
}

impl Clock for HostMicros {
    const UNIT: &'static str = "us (host clock)";
    const NODE_UNIT: &'static str = "board clock ticks (core cycles; instructions under QEMU)";

    fn ticks(self) -> u64 {
        self.0
    }

    fn cycles(self) -> Option<u64> {
        None
    }
}

impl fmt::Display for Cycles {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} cycles", self.0)
    }
}

impl fmt::Display for HostMicros {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} us of host time", self.0)
    }
}
