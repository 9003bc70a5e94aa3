//! Load balancing (the paper's sliding boundaries): load intervals reported
//! to the host and the low neighbour, and the decision on this node's high
//! boundary across the driving axis.

use link_proto::{LoadReport, Message, SlideOffer, SlidePolicy};

use crate::link::Port;
use crate::slide::{self, Side};

use super::Node;

impl<const S: usize, const R: usize, const C: usize, const P: usize, const O: usize> Node<S, R, C, P, O> {
    /// The axis whose boundaries slide (0 before an assignment).
    pub(super) fn driving_axis(&self) -> usize {
        self.assign.map_or(0, |a| usize::from(a.driving_axis))
    }

    /// The side a driving-axis port faces, `None` for other ports.
    pub(super) fn side_of(&self, port: Port) -> Option<Side> {
        let d = self.driving_axis();
        match port {
            p if p == Port::toward(d, true) => Some(Side::Hi),
            p if p == Port::toward(d, false) => Some(Side::Lo),
            _ => None,
        }
    }

    /// Whether the array has a node beyond `side` along the driving axis.
    fn has_neighbour(&self, side: Side) -> bool {
        let d = self.driving_axis();
        self.assign.is_some_and(|a| {
            let (c, n) = (a.coord.get(d).copied().unwrap_or(0), a.array.get(d).copied().unwrap_or(1));
            match side {
                Side::Lo => c > 0,
                Side::Hi => c + 1 < n,
            }
        })
    }

    /// Ends load intervals: reports them and decides this node's high boundary.
    pub(super) fn balance_tick(&mut self, now: u64) {
        let Some((k, load)) = self.intervals.due(now, &self.meter) else { return };
        self.slide.own_load = Some((k, load));
        let report = LoadReport {
            node: self.id,
            interval: k,
            running: load.running,
            waiting: load.waiting,
            rays: self.totals.rays,
            sphere_tests: self.totals.sphere_tests,
            cube_steps: self.totals.cube_steps,
            refused: self.totals.refused,
            busy_polls: self.totals.busy_polls,
            extent: {
                let (lo, hi) = self.extent_after_giving();
                hi.saturating_sub(lo)
            },
        };
        self.queue_control(Port::Host, Message::Load(report));
        if self.has_neighbour(Side::Lo) {
            self.queue_control(Port::toward(self.driving_axis(), false), Message::Load(report));
        }
        self.decide();
    }

    /// The paper's rule for the boundary on this node's high side: if one load is
    /// lower and under the threshold, the boundary slides one step toward the busier node.
    ///
    /// The paper compares the two loads "at intervals of the given time"; each
    /// decision pairs this node's latest interval with the high neighbour's
    /// latest report, each used once, whatever their indices. With clocks
    /// started together these are the same interval. Clocks that drift apart
    /// by more than an interval (an emulated board's virtual clock lags the
    /// host's by however long it was busy) would otherwise never meet on an
    /// index again, and the boundary would never move.
    pub(super) fn decide(&mut self) {
        let (Some(balance), Some((k, own))) = (self.balance, self.slide.own_load) else { return };
        let Some((theirs, their_extent)) = self.slide.neighbour_load[Side::Hi] else { return };
        if self.slide.busy(Side::Hi) || !self.has_neighbour(Side::Hi) {
            return;
        }
        self.slide.own_load = None;
        self.slide.neighbour_load[Side::Hi] = None;
        let d = self.driving_axis();
        let (lo, hi) = self.extent_after_giving();
        let own_extent = hi.saturating_sub(lo);
        let (take, give) = match balance.policy {
            SlidePolicy::Paper => {
                let step = balance.step.max(1);
                let take = own.lighter_than(&theirs) && own.under(balance.threshold);
                let give = theirs.lighter_than(&own) && theirs.under(balance.threshold);
                (take.then_some(step), give.then_some(step))
            }
            SlidePolicy::Proportional { gamma, deadband } => {
                // A boundary that just moved holds still while its slab is in
                // transit, then decides on both running times averaged over the
                // intervals since (see `slide::average`): one interval is a
                // handful of shaded hits, too noisy to act on alone.
                if self.slide.hold > 0 {
                    self.slide.hold -= 1;
                    return;
                }
                let n = (self.slide.samples + 1).min(slide::AVERAGE_WINDOW);
                let mine = slide::average(self.slide.smoothed.lo, own.running, n);
                let yours = slide::average(self.slide.smoothed.hi, theirs.running, n);
                self.slide.smoothed = slide::PerSide { lo: mine, hi: yours };
                self.slide.samples = n;
                if n < slide::MIN_SAMPLES {
                    return;
                }
                let take = slide::proportional_shift(mine, yours, own_extent, their_extent, gamma, deadband);
                let give = slide::proportional_shift(yours, mine, their_extent, own_extent, gamma, deadband);
                if take.is_some() || give.is_some() {
                    self.slide.hold = 2;
                    self.slide.samples = 0;
                }
                (take, give)
            }
        };
        if let Some(step) = take {
            let offer = SlideOffer { interval: k, boundary: hi.saturating_add(step) };
            self.slide.requested[Side::Hi] = true;
            self.queue_control(Port::toward(d, true), Message::SlideRequest(offer));
        } else if let Some(step) = give.filter(|&s| hi > lo + s) {
            self.start_giving(Side::Hi, hi - step);
        }
    }

    /// The node's extent along the driving axis once the slabs it is giving are gone.
    pub(super) fn extent_after_giving(&self) -> (u16, u16) {
        let d = self.driving_axis();
        let owned = self.region.owned();
        let lo = self.slide.outgoing[Side::Lo].map_or(owned.lo.get(d).copied().unwrap_or(0), |o| o.boundary);
        let hi = self.slide.outgoing[Side::Hi].map_or(owned.hi.get(d).copied().unwrap_or(0), |o| o.boundary);
        (lo, hi)
    }
}
