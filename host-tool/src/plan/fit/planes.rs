//! Rectilinear partitioning (Nicol 1994): the planes across the driving
//! axis, each axis cut to minimise the busiest row of nodes.

use crate::plan::partition::Partition;

impl Partition {
    /// The cubes' cost (`cells`, x fastest) of the busiest row of nodes
    /// along the driving axis.
    pub(super) fn busiest_row(&self, grid: [u16; 3], cells: &[u64]) -> u64 {
        let [a, b] = self.row_axes();
        let planes = plane_costs(grid, cells, a, b, &self.cuts[b]);
        let row = |lo: u16, hi: u16, part: usize| -> u64 {
            planes[usize::from(lo)..usize::from(hi)].iter().map(|p| p[part]).sum()
        };
        let parts = self.cuts[b].len() - 1;
        self.cuts[a].windows(2).flat_map(|w| (0..parts).map(move |j| row(w[0], w[1], j))).max().unwrap_or(0)
    }
}

/// Per plane of cubes across axis `cut`, its cost within each part of axis
/// `other` (cut at `other_cuts`), summed over the third axis.
pub(super) fn plane_costs(
    grid: [u16; 3],
    cost: &[u64],
    cut: usize,
    other: usize,
    other_cuts: &[u16],
) -> Vec<Vec<u64>> {
    let part_of: Vec<usize> = (0..grid[other])
        .map(|c| other_cuts.windows(2).position(|w| c >= w[0] && c < w[1]).unwrap_or(0))
        .collect();
    let mut planes = vec![vec![0u64; other_cuts.len().saturating_sub(1)]; usize::from(grid[cut])];
    let (nx, ny) = (usize::from(grid[0]), usize::from(grid[1]));
    for (i, &c) in cost.iter().enumerate() {
        let cell = [i % nx, (i / nx) % ny, i / (nx * ny)];
        if let Some(part) = planes.get_mut(cell[cut]).and_then(|p| p.get_mut(part_of[cell[other]])) {
            *part += c;
        }
    }
    planes
}

/// Cuts `0 = c_0 < ... < c_parts = planes.len()` minimising the largest
/// per-component sum of any part (each plane a vector of costs, one per row
/// it crosses): the least feasible bound by bisection, then a greedy cut.
pub fn bottleneck_cuts(planes: &[Vec<u64>], parts: usize) -> Vec<u16> {
    let fallback = || (0..=parts).map(|i| (i * planes.len() / parts.max(1)) as u16).collect();
    if parts == 0 || planes.len() < parts {
        return fallback();
    }
    let (mut lo, mut hi) = (0u64, planes.iter().flatten().sum::<u64>());
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if greedy_cuts(planes, parts, mid).is_some() { hi = mid } else { lo = mid + 1 }
    }
    greedy_cuts(planes, parts, lo).unwrap_or_else(fallback)
}

/// Cuts with no part over `bound` in any component, exactly `parts` parts of
/// at least one plane each, or `None` if that takes more parts.
fn greedy_cuts(planes: &[Vec<u64>], parts: usize, bound: u64) -> Option<Vec<u16>> {
    let n = planes.len();
    let mut cuts = vec![0u16];
    let mut acc = vec![0u64; planes.first().map_or(0, Vec::len)];
    for (i, plane) in planes.iter().enumerate() {
        let started = usize::from(*cuts.last().unwrap_or(&0)) < i;
        let over = acc.iter().zip(plane).any(|(a, p)| a + p > bound);
        // Cut when this part is full, or when every part still to come needs a plane.
        if started && (over || n - i == parts - cuts.len()) {
            if cuts.len() == parts {
                return None;
            }
            cuts.push(i as u16);
            acc.iter_mut().for_each(|a| *a = 0);
        }
        if plane.iter().any(|&p| p > bound) {
            return None;
        }
        acc.iter_mut().zip(plane).for_each(|(a, p)| *a += p);
    }
    cuts.push(n as u16);
    (cuts.len() == parts + 1).then_some(cuts)
}
