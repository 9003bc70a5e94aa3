//! Sliding boundary surfaces: moving a slab of cubes between two nodes that
//! share a boundary perpendicular to the driving axis.
//!
//! The node on the low side of a boundary decides for it, from both nodes'
//! loads of the same interval. The busier node gives: it streams every sphere
//! touching the slab, then `SlideDone`. The receiver grows its *storage* box
//! first and takes ownership of the slab only once it holds all of them; the
//! giver drops the slab when the receiver's acceptance arrives. In between,
//! both own the slab and both hold all of its spheres, so a ray is traced
//! correctly wherever it is. A receiver that cannot hold the slab shrinks
//! back and refuses: nothing is half done.

use crate::cube_box::CubeBox;
use crate::error::Error;
use crate::load::Load;

/// Which side of the node along the driving axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// Toward lower coordinates.
    Lo = 0,
    /// Toward higher coordinates.
    Hi = 1,
}

impl Side {
    /// Index 0 or 1.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// One value per side, indexed by [`Side`] (no panic path).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PerSide<T> {
    /// The low side.
    pub lo: T,
    /// The high side.
    pub hi: T,
}

impl<T> core::ops::Index<Side> for PerSide<T> {
    type Output = T;
    fn index(&self, side: Side) -> &T {
        match side {
            Side::Lo => &self.lo,
            Side::Hi => &self.hi,
        }
    }
}

impl<T> core::ops::IndexMut<Side> for PerSide<T> {
    fn index_mut(&mut self, side: Side) -> &mut T {
        match side {
            Side::Lo => &mut self.lo,
            Side::Hi => &mut self.hi,
        }
    }
}

/// A slab this node is giving away.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outgoing {
    /// New position of the boundary.
    pub boundary: u16,
    /// `SlideOffer` sent.
    pub offered: bool,
    /// Next sphere id to consider sending.
    pub next_id: u32,
    /// Spheres sent.
    pub sent: u32,
    /// `SlideDone` sent; waiting for the receiver's reply.
    pub done: bool,
}

/// A slab this node is receiving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Incoming {
    /// New position of the boundary.
    pub boundary: u16,
    /// Storage box before the slide, restored on refusal.
    pub old_storage: CubeBox,
    /// Spheres received.
    pub received: u32,
    /// Why the slab cannot be taken, once known.
    pub failed: Option<Error>,
}

/// Slide state of both sides of a node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SlideState {
    /// Slabs being given, per side.
    pub outgoing: PerSide<Option<Outgoing>>,
    /// Slabs being received, per side.
    pub incoming: PerSide<Option<Incoming>>,
    /// A request sent to the neighbour on this side, not yet answered.
    pub requested: PerSide<bool>,
    /// The neighbour's latest load report per side, until a decision uses
    /// it: (load, extent).
    pub neighbour_load: PerSide<Option<(Load, u16)>>,
    /// This node's latest interval load, until a decision uses it.
    pub own_load: Option<(u32, Load)>,
    /// Average running time per interval of this node and of the high-side
    /// neighbour since the high boundary last moved (proportional policy).
    pub smoothed: PerSide<u64>,
    /// Intervals in `smoothed` (capped at [`AVERAGE_WINDOW`]).
    pub samples: u32,
    /// Intervals the high boundary stays put after it moved (proportional policy).
    pub hold: u32,
    /// Slides committed as receiver this frame.
    pub committed: u32,
    /// Slides of the boundary on each side this frame, given or taken (the
    /// neighbour across counts the same: see `link_proto::SlideNote`).
    pub moves: PerSide<u16>,
    /// Slides refused as receiver (capacity) this frame.
    pub refused: u32,
}

impl SlideState {
    /// No slide in progress, no loads known.
    pub const fn new() -> Self {
        Self {
            outgoing: PerSide { lo: None, hi: None },
            incoming: PerSide { lo: None, hi: None },
            requested: PerSide { lo: false, hi: false },
            neighbour_load: PerSide { lo: None, hi: None },
            own_load: None,
            smoothed: PerSide { lo: 0, hi: 0 },
            samples: 0,
            hold: 0,
            committed: 0,
            moves: PerSide { lo: 0, hi: 0 },
            refused: 0,
        }
    }

    /// Whether a slide is in progress on `side`.
    pub fn busy(&self, side: Side) -> bool {
        self.outgoing[side].is_some() || self.incoming[side].is_some() || self.requested[side]
    }
}

/// `b` with its face on `side` of `axis` moved to `position`.
pub fn with_face(b: CubeBox, axis: usize, side: Side, position: u16) -> CubeBox {
    let mut out = b;
    let face = match side {
        Side::Lo => out.lo.get_mut(axis),
        Side::Hi => out.hi.get_mut(axis),
    };
    if let Some(f) = face {
        *f = position;
    }
    out
}

/// The slab between a box's face on `side` and `boundary` (the cubes that move).
pub fn slab(owned: CubeBox, axis: usize, side: Side, boundary: u16) -> CubeBox {
    let face = match side {
        Side::Lo => owned.lo.get(axis),
        Side::Hi => owned.hi.get(axis),
    }
    .copied()
    .unwrap_or(0);
    let (a, b) = if face < boundary { (face, boundary) } else { (boundary, face) };
    let mut out = owned;
    if let (Some(lo), Some(hi)) = (out.lo.get_mut(axis), out.hi.get_mut(axis)) {
        *lo = a;
        *hi = b;
    }
    out
}

/// Intervals over which the proportional policy averages running times at most.
pub const AVERAGE_WINDOW: u32 = 16;

/// Intervals averaged before the proportional policy moves a boundary.
pub const MIN_SAMPLES: u32 = 2;

/// Adds the `n`-th sample `x` to `mean`: the running mean of the samples
/// since the boundary moved, which becomes an exponential average of weight
/// `1 / n` once `n` stops at [`AVERAGE_WINDOW`]. The noise of the estimate
/// falls as the boundary stays put, so a boundary in the right place stops
/// moving (no thrashing), while a real shift of the work still shows within
/// a window.
pub fn average(mean: u64, x: u64, n: u32) -> u64 {
    let n = u64::from(n.max(1));
    if x >= mean { mean + (x - mean) / n } else { mean - (mean - x) / n }
}

/// Cubes the boundary should move toward the busier node under the
/// proportional policy: `(W_b - W_l) / (W_b + W_l) * (d_b + d_l) / (2 gamma)`,
/// rounded to nearest, at least 1 when above the dead band, at most 0.49 of the
/// busier node's extent. `None` below the dead band.
pub fn proportional_shift(
    light: u64,
    busy: u64,
    d_light: u16,
    d_busy: u16,
    gamma: u32,
    deadband: u32,
) -> Option<u16> {
    let (wl, wb) = (u128::from(light), u128::from(busy));
    let total = wl + wb;
    if total == 0 || wb <= wl {
        return None;
    }
    // (wb - wl) / total < deadband / 2^16 -> no move.
    if ((wb - wl) << 16) < u128::from(deadband) * total {
        return None;
    }
    let span = u128::from(d_light) + u128::from(d_busy);
    let num = ((wb - wl) * span) << 16;
    let den = total * 2 * u128::from(gamma.max(1));
    let shift = ((num + den / 2) / den).max(1);
    let cap = (u128::from(d_busy) * 49) / 100;
    let shift = shift.min(cap);
    (shift > 0).then(|| u16::try_from(shift).unwrap_or(u16::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE: u32 = 1 << 16;

    #[test]
    fn average_is_the_running_mean_then_an_exponential_one() {
        let mut m = 0;
        for (n, x) in [(1, 100), (2, 200), (3, 600)] {
            m = average(m, x, n);
        }
        assert_eq!(m, 300);
        // At the window's cap each sample moves the mean by 1/16 of the gap.
        assert_eq!(average(1600, 0, AVERAGE_WINDOW), 1500);
        assert_eq!(average(1600, 3200, AVERAGE_WINDOW), 1700);
    }

    #[test]
    fn proportional_shift_follows_the_formula() {
        // (300 - 100) / 400 * (8 + 8) / (2 * 4) = 1.0 cube.
        assert_eq!(proportional_shift(100, 300, 8, 8, 4 * ONE, ONE / 10), Some(1));
        // Twice the spread: 2 cubes; gamma 1: 8 * 0.5 = 4 cubes... capped at 0.49 * 8 = 3.
        assert_eq!(proportional_shift(100, 300, 16, 16, 4 * ONE, ONE / 10), Some(2));
        assert_eq!(proportional_shift(100, 300, 8, 8, ONE, ONE / 10), Some(3));
        // Inside the dead band, or the light node is not lighter: no move.
        assert_eq!(proportional_shift(100, 105, 8, 8, 4 * ONE, ONE / 10), None);
        assert_eq!(proportional_shift(300, 100, 8, 8, 4 * ONE, ONE / 10), None);
        // A busy node of one layer cannot give anything.
        assert_eq!(proportional_shift(0, 300, 8, 1, 4 * ONE, ONE / 10), None);
    }
}
