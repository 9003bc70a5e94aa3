//! Boundary positions over time, rebuilt from the slides the nodes reported.

use crate::partition::Partition;

/// One boundary position: at `time`, boundary `index` (between node rows
/// `index` and `index + 1` along the driving axis) of node row `row` is at `position`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryAt {
    /// Virtual time.
    pub time: u64,
    /// Row of nodes along the driving axis (index over the other two axes).
    pub row: usize,
    /// Boundary index within the row.
    pub index: usize,
    /// Position in cubes along the driving axis.
    pub position: u16,
}

/// Every boundary's initial position at time 0, then one entry per slide.
pub fn boundary_history(partition: &Partition, slides: &[(u64, u16, u16)]) -> Vec<BoundaryAt> {
    let d = usize::from(partition.driving_axis);
    let nodes = partition.len();
    let mut lo: Vec<u16> = (0..nodes).map(|n| partition.bounds(n).lo[d]).collect();
    let mut hi: Vec<u16> = (0..nodes).map(|n| partition.bounds(n).hi[d]).collect();
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
    for (n, &position) in hi.iter().enumerate() {
        let c = usize::from(partition.coord(n)[d]);
        if c + 1 < usize::from(partition.array[d]) {
            out.push(BoundaryAt { time: 0, row: row_of(n), index: c, position });
        }
    }
    for &(time, node, boundary) in slides {
        let n = usize::from(node);
        let c = usize::from(partition.coord(n)[d]);
        if boundary > hi[n] && n + stride < nodes {
            hi[n] = boundary;
            lo[n + stride] = boundary;
            out.push(BoundaryAt { time, row: row_of(n), index: c, position: boundary });
        } else if boundary < lo[n] && n >= stride {
            lo[n] = boundary;
            hi[n - stride] = boundary;
            out.push(BoundaryAt { time, row: row_of(n), index: c - 1, position: boundary });
        }
    }
    out
}

/// How much boundaries moved within a window of virtual time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Churn {
    /// Boundary moves in the window.
    pub moves: usize,
    /// Moves opposite to the same boundary's previous move (back and forth:
    /// thrashing proper).
    pub reversals: usize,
}

/// Moves and reversals of `history` ([`boundary_history`]) in `[from, to)`.
pub fn churn(history: &[BoundaryAt], from: u64, to: u64) -> Churn {
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

    fn at(time: u64, index: usize, position: u16) -> BoundaryAt {
        BoundaryAt { time, row: 0, index, position }
    }

    #[test]
    fn churn_counts_moves_in_the_window_and_reversals() {
        // Boundary 0 starts at 8, goes up, up, back down; boundary 1 moves once.
        let h = [at(0, 0, 8), at(0, 1, 16), at(10, 0, 9), at(20, 0, 10), at(30, 0, 9), at(40, 1, 15)];
        assert_eq!(churn(&h, 0, 100), Churn { moves: 4, reversals: 1 });
        // Only the moves at 20 and 30 fall in [15, 35): one of them reverses.
        assert_eq!(churn(&h, 15, 35), Churn { moves: 2, reversals: 1 });
        assert_eq!(churn(&h, 50, 60), Churn::default());
    }
}
