//! Boundary positions over time, rebuilt from the slides the nodes reported.

use crate::plan::partition::Partition;
use crate::session::clock::Clock;
use crate::session::frame::SlideSeen;

/// One boundary position: at `time`, boundary `index` (between node rows
/// `index` and `index + 1` along the driving axis) of node row `row` is at `position`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryAt<T> {
    /// When it got there (the start of the run for initial positions).
    pub time: T,
    /// Row of nodes along the driving axis (index over the other two axes).
    pub row: usize,
    /// Boundary index within the row.
    pub index: usize,
    /// Position in cubes along the driving axis.
    pub position: u16,
}

/// Every boundary's initial position at time 0, then one entry per slide,
/// in time order. Each boundary's slides are put in the order they happened
/// by their count (the two nodes of a boundary report over different host
/// links, so arrival order can differ); a note that arrives before an
/// earlier slide's is dated when that one arrived.
pub fn boundary_history<T: Clock>(partition: &Partition, slides: &[SlideSeen<T>]) -> Vec<BoundaryAt<T>> {
    let d = usize::from(partition.driving_axis);
    let nodes = partition.len();
    let stride = match d {
        0 => 1,
        1 => usize::from(partition.array[0]),
        _ => usize::from(partition.array[0]) * usize::from(partition.array[1]),
    };
    let row_of = |n: usize| {
        let c = partition.coord(n);
        let others: Vec<usize> = (0..3).filter(|&a| a != d).map(|a| usize::from(c[a])).collect();
        let width = (0..3).filter(|&a| a != d).map(|a| usize::from(partition.array[a])).next().unwrap_or(1);
        others[0] + width * others[1]
    };
    let mut out = Vec::new();
    for n in 0..nodes {
        let c = usize::from(partition.coord(n)[d]);
        if c + 1 < usize::from(partition.array[d]) {
            out.push(BoundaryAt {
                time: T::default(),
                row: row_of(n),
                index: c,
                position: partition.bounds(n).hi[d],
            });
        }
    }
    // Each note, under the node on the boundary's low side.
    let mut moves: Vec<(usize, u16, T, u16)> = slides
        .iter()
        .filter_map(|s| {
            let n = usize::from(s.node);
            let low = if s.note.high_side { n } else { n.checked_sub(stride)? };
            (low + stride < nodes).then_some((low, s.note.count, s.at, s.note.boundary))
        })
        .collect();
    moves.sort_unstable_by_key(|&(low, count, at, _)| (low, count, at));
    let mut dated = Vec::with_capacity(moves.len());
    let mut last = (usize::MAX, T::default());
    for (low, _, at, position) in moves {
        let time = if last.0 == low { at.max(last.1) } else { at };
        last = (low, time);
        let c = usize::from(partition.coord(low)[d]);
        dated.push(BoundaryAt { time, row: row_of(low), index: c, position });
    }
    // Stable: each boundary's moves keep their order among equal times.
    dated.sort_by_key(|b| b.time);
    out.extend(dated);
    out
}

/// The partition once `slides` are done: every boundary where its last
/// slide left it (the subregions the nodes hold when the frame has ended).
pub fn after_slides<T: Clock>(partition: &Partition, slides: &[SlideSeen<T>]) -> Partition {
    let d = usize::from(partition.driving_axis);
    let [a0, a1] = partition.row_axes();
    let width = usize::from(partition.array[a0]);
    let rows = width * usize::from(partition.array[a1]);
    let row_coord = |r: usize| {
        let mut c = [0u16; 3];
        c[a0] = (r % width) as u16;
        c[a1] = (r / width) as u16;
        c
    };
    let mut row_cuts: Vec<Vec<u16>> =
        (0..rows).map(|r| partition.cuts_at(d, row_coord(r)).to_vec()).collect();
    for b in boundary_history(partition, slides) {
        if let Some(cut) = row_cuts.get_mut(b.row).and_then(|cuts| cuts.get_mut(b.index + 1)) {
            *cut = b.position;
        }
    }
    // Rows that all line up again need no cuts of their own.
    let whole = row_cuts.iter().all(|cuts| *cuts == partition.cuts[d]);
    Partition { row_cuts: (!whole).then_some(row_cuts), ..partition.clone() }
}

/// How much boundaries moved within a window of time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Churn {
    /// Boundary moves in the window.
    pub moves: usize,
    /// Moves opposite to the same boundary's previous move (back and forth:
    /// thrashing proper).
    pub reversals: usize,
}

/// Moves and reversals of `history` ([`boundary_history`]) in `[from, to)`.
pub fn churn<T: Clock>(history: &[BoundaryAt<T>], from: T, to: T) -> Churn {
    let mut last: std::collections::BTreeMap<(usize, usize), (u16, i8)> = Default::default();
    let mut out = Churn::default();
    for b in history {
        let key = (b.row, b.index);
        let Some(&(position, direction)) = last.get(&key) else {
            last.insert(key, (b.position, 0));
            continue;
        };
        let now = match b.position.cmp(&position) {
            std::cmp::Ordering::Greater => 1,
            std::cmp::Ordering::Less => -1,
            std::cmp::Ordering::Equal => 0,
        };
        if (from..to).contains(&b.time) && now != 0 {
            out.moves += 1;
            if now == -direction {
                out.reversals += 1;
            }
        }
        last.insert(key, (b.position, if now == 0 { direction } else { now }));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::clock::Cycles;

    fn at(time: u64, index: usize, position: u16) -> BoundaryAt<Cycles> {
        BoundaryAt { time: Cycles(time), row: 0, index, position }
    }

    #[test]
    fn churn_counts_moves_in_the_window_and_reversals() {
        // Boundary 0 starts at 8, goes up, up, back down; boundary 1 moves once.
        let h = [at(0, 0, 8), at(0, 1, 16), at(10, 0, 9), at(20, 0, 10), at(30, 0, 9), at(40, 1, 15)];
        assert_eq!(churn(&h, Cycles(0), Cycles(100)), Churn { moves: 4, reversals: 1 });
        // Only the moves at 20 and 30 fall in [15, 35): one of them reverses.
        assert_eq!(churn(&h, Cycles(15), Cycles(35)), Churn { moves: 2, reversals: 1 });
        assert_eq!(churn(&h, Cycles(50), Cycles(60)), Churn::default());
    }

    #[test]
    fn notes_that_arrive_out_of_order_are_put_back_in_order() {
        use link_proto::SlideNote;
        // Two nodes along x on a 16-cube grid, cut at 8. The boundary moves
        // to 9 (node 0 took a slab), then back to 8 (node 1 took it back);
        // node 1's note reaches the host first.
        let p = Partition::even([16, 4, 4], [2, 1, 1], 0).unwrap();
        let seen = |at, node, boundary, high_side, count| SlideSeen {
            at: Cycles(at),
            node,
            note: SlideNote { boundary, high_side, count },
        };
        let notes = [seen(50, 1, 8, false, 2), seen(70, 0, 9, true, 1)];
        let h = boundary_history(&p, &notes);
        let moves: Vec<(u64, u16)> = h.iter().map(|b| (b.time.0, b.position)).collect();
        assert_eq!(moves, [(0, 8), (70, 9), (70, 8)]);
        // Back where it started: the partition lines up as before.
        assert_eq!(after_slides(&p, &notes), p);
    }

    #[test]
    fn after_slides_moves_each_rows_boundary_to_its_last_position() {
        use link_proto::SlideNote;
        // 2x2x1 along x on 16x8x4: rows y = 0 and y = 1, each cut at 8.
        let p = Partition::even([16, 8, 4], [2, 2, 1], 0).unwrap();
        let seen = |node, boundary, count| SlideSeen {
            at: Cycles(10 * u64::from(count)),
            node,
            note: SlideNote { boundary, high_side: true, count },
        };
        // Row 1 (nodes 2 and 3): node 2 takes two slabs, to 9 then 10.
        let slid = after_slides(&p, &[seen(2, 9, 1), seen(2, 10, 2)]);
        assert_eq!(slid.row_cuts, Some(vec![vec![0, 8, 16], vec![0, 10, 16]]));
        assert_eq!(slid.bounds(2).hi[0], 10);
        assert_eq!(slid.bounds(3).lo[0], 10);
        assert_eq!(slid.bounds(0).hi[0], 8);
    }
}
