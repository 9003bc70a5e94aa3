//! Load: the paper's running time / waiting time, measured over intervals.

/// Running and waiting time, attributed from one poll to the next: the time
/// between two polls counts as running if the earlier poll did work.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoadMeter {
    last: u64,
    busy: bool,
    /// Time spent processing.
    pub running: u64,
    /// Time spent with nothing to process.
    pub waiting: u64,
}

impl LoadMeter {
    /// A meter at time 0.
    pub const fn new() -> Self {
        Self { last: 0, busy: false, running: 0, waiting: 0 }
    }

    /// Attributes the time since the last poll.
    pub fn tick(&mut self, now: u64) {
        let dt = now.saturating_sub(self.last);
        if self.busy {
            self.running += dt;
        } else {
            self.waiting += dt;
        }
        self.last = now;
    }

    /// Records whether the poll that just ran did work.
    pub fn set_busy(&mut self, busy: bool) {
        self.busy = busy;
    }

    /// Starts counting afresh at `now`.
    pub fn restart(&mut self, now: u64) {
        *self = LoadMeter { last: now, ..LoadMeter::default() };
    }

    /// Time of the last poll.
    pub fn last(&self) -> u64 {
        self.last
    }
}

/// The load of one interval: `running / waiting`. Zero waiting with some
/// running is an infinite load (the node never waited); an interval with
/// neither has load zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Load {
    /// Running time.
    pub running: u64,
    /// Waiting time.
    pub waiting: u64,
}

impl Load {
    /// `self < other`, exactly (cross-multiplied in u128).
    pub fn lighter_than(&self, other: &Load) -> bool {
        u128::from(self.running) * u128::from(other.waiting)
            < u128::from(other.running) * u128::from(self.waiting)
            || (self.waiting > 0 && other.waiting == 0 && other.running > 0)
    }

    /// `self < threshold`, with the threshold in Q16.16, exactly.
    pub fn under(&self, threshold: u32) -> bool {
        (u128::from(self.running) << 16) < u128::from(threshold) * u128::from(self.waiting)
    }
}

/// Splits time into intervals of `length` ticks and yields each interval's load.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IntervalClock {
    length: u64,
    next_end: u64,
    index: u32,
    at_start: Load,
}

impl IntervalClock {
    /// A clock that never ends an interval (no balancing).
    pub const fn idle() -> Self {
        Self { length: 0, next_end: u64::MAX, index: 0, at_start: Load { running: 0, waiting: 0 } }
    }

    /// Intervals of `length` ticks from `now`.
    pub fn new(now: u64, length: u64) -> Self {
        let length = length.max(1);
        Self { length, next_end: now + length, index: 0, at_start: Load::default() }
    }

    /// If an interval ended by `now`, its index and load (running and waiting
    /// totals since the previous one ended).
    pub fn due(&mut self, now: u64, meter: &LoadMeter) -> Option<(u32, Load)> {
        if self.length == 0 || now < self.next_end {
            return None;
        }
        let load = Load {
            running: meter.running - self.at_start.running,
            waiting: meter.waiting - self.at_start.waiting,
        };
        let index = self.index;
        self.at_start = Load { running: meter.running, waiting: meter.waiting };
        self.index += 1;
        // Skip whole intervals the node slept through.
        self.next_end += self.length * ((now - self.next_end) / self.length + 1);
        Some((index, load))
    }
}
