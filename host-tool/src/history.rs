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
