//! The static partition: subregion boxes, sub-image tiles, the eye's node, and a
//! capacity check before anything is sent.

use link_proto::{Assign, Capacity};
use node_fw::{CubeBox, Grid, Sphere};

use crate::error::{HostError, input};
use crate::scene::Scene;

/// How the grid is split over an X x Y x Z array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Partition {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Cut positions per axis: `cuts[a][i]..cuts[a][i + 1]` is node row `i`.
    pub cuts: [Vec<u16>; 3],
    /// Driving axis of the sliding boundaries.
    pub driving_axis: u8,
    /// Per node row (index over the two other axes, the first fastest), cuts
    /// along the driving axis that replace `cuts[driving_axis]` (staggered
    /// boundaries, as after sliding or from an oracle).
    pub row_cuts: Option<Vec<Vec<u16>>>,
}

impl Partition {
    /// Even cuts of `grid` over `array`.
    pub fn even(grid: [u16; 3], array: [u16; 3], driving_axis: u8) -> Result<Self, HostError> {
        for a in 0..3 {
            if array[a] == 0 {
                return Err(input(format!("array {array:?} needs at least one node per axis")));
            }
            if array[a] > grid[a] {
                return Err(HostError::ArrayTooLarge(format!(
                    "array {}x{}x{} is larger than the grid {}x{}x{}: each node needs at least one cube per axis",
                    array[0], array[1], array[2], grid[0], grid[1], grid[2]
                )));
            }
        }
        let cuts = std::array::from_fn(|a| {
            (0..=array[a]).map(|i| (u32::from(i) * u32::from(grid[a]) / u32::from(array[a])) as u16).collect()
        });
        Ok(Self { array, cuts, driving_axis, row_cuts: None })
    }

    /// The oracle static partition: even cuts across the driving axis, and in
    /// every row the driving axis cut where the measured compute cost (one value
    /// per unit cube, x fastest) splits evenly.
    pub fn oracle(
        grid: [u16; 3],
        array: [u16; 3],
        driving_axis: u8,
        cost: &[u64],
    ) -> Result<Self, HostError> {
        let mut p = Self::even(grid, array, driving_axis)?;
        p.cut_rows(grid, cost);
        Ok(p)
    }

    /// Cuts every row along the driving axis where its cost splits evenly.
    fn cut_rows(&mut self, grid: [u16; 3], cost: &[u64]) {
        let parts = usize::from(self.array[usize::from(self.driving_axis)]);
        let rows = self.row_layers(grid, cost).iter().map(|layer| equal_cost_cuts(layer, parts)).collect();
        self.row_cuts = Some(rows);
    }

    /// A partition fitted to a per-cube cost map (x fastest). The planes across
    /// the driving axis stay whole (routing needs nothing but a node's own
    /// box), placed so the rows of nodes along the driving axis carry costs as
    /// even as whole planes allow: rectilinear partitioning after Nicol (1994),
    /// each axis in turn cut to minimise the busiest row given the other's
    /// cuts. Each row is then cut along the driving axis where its cost splits
    /// evenly. From the true cost map this is an oracle; from a preview
    /// render's, a start the host can afford.
    pub fn fitted(
        grid: [u16; 3],
        array: [u16; 3],
        driving_axis: u8,
        cost: &[u64],
    ) -> Result<Self, HostError> {
        let mut p = Self::even(grid, array, driving_axis)?;
        let d = usize::from(driving_axis);
        let [a, b] = [(d + 1) % 3, (d + 2) % 3];
        let mut best = p.busiest_row(grid, cost);
        // A few alternations settle it; keep the best seen, as a pass may not improve.
        for _ in 0..4 {
            let mut next = p.clone();
            for (cut, other) in [(a, b), (b, a)] {
                let planes = plane_costs(grid, cost, cut, other, &next.cuts[other]);
                next.cuts[cut] = bottleneck_cuts(&planes, usize::from(array[cut]));
            }
            let busiest = next.busiest_row(grid, cost);
            if busiest >= best {
                break;
            }
            (p, best) = (next, busiest);
        }
        p.cut_rows(grid, cost);
        Ok(p)
    }

    /// The cost of the busiest row of nodes along the driving axis.
    fn busiest_row(&self, grid: [u16; 3], cost: &[u64]) -> u64 {
        self.row_layers(grid, cost).iter().map(|l| l.iter().sum::<u64>()).max().unwrap_or(0)
    }

    /// Per row of nodes along the driving axis (in [`Self::row_of`] order),
    /// the cost of each layer of cubes across it, from a per-cube cost map.
    /// Uses the even cuts across the driving axis.
    pub fn row_layers(&self, grid: [u16; 3], cost: &[u64]) -> Vec<Vec<u64>> {
        let d = usize::from(self.driving_axis);
        let others: Vec<usize> = (0..3).filter(|&a| a != d).collect();
        let (a0, a1) = (others[0], others[1]);
        let mut rows = Vec::new();
        for r1 in 0..usize::from(self.array[a1]) {
            for r0 in 0..usize::from(self.array[a0]) {
                let mut layer = vec![0u64; usize::from(grid[d])];
                for c1 in self.cuts[a1][r1]..self.cuts[a1][r1 + 1] {
                    for c0 in self.cuts[a0][r0]..self.cuts[a0][r0 + 1] {
                        for (k, l) in layer.iter_mut().enumerate() {
                            let mut cell = [0usize; 3];
                            cell[d] = k;
                            cell[a0] = usize::from(c0);
                            cell[a1] = usize::from(c1);
                            let i =
                                cell[0] + usize::from(grid[0]) * (cell[1] + usize::from(grid[1]) * cell[2]);
                            *l += cost.get(i).copied().unwrap_or(0);
                        }
                    }
                }
                rows.push(layer);
            }
        }
        rows
    }

    /// The row of node coordinate `c` (index over the non-driving axes).
    fn row_of(&self, c: [u16; 3]) -> usize {
        let d = usize::from(self.driving_axis);
        let others: Vec<usize> = (0..3).filter(|&a| a != d).collect();
        usize::from(c[others[0]]) + usize::from(self.array[others[0]]) * usize::from(c[others[1]])
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.array.iter().map(|&n| usize::from(n)).product()
    }

    /// Whether the partition has no node.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Array coordinate of node `id` (x fastest).
    pub fn coord(&self, id: usize) -> [u16; 3] {
        node_fw::wiring::coord_of(id, self.array)
    }

    /// The box of node `id`.
    pub fn bounds(&self, id: usize) -> CubeBox {
        let c = self.coord(id);
        let d = usize::from(self.driving_axis);
        let cuts = |a: usize| match &self.row_cuts {
            Some(rows) if a == d => &rows[self.row_of(c)],
            _ => &self.cuts[a],
        };
        CubeBox {
            lo: std::array::from_fn(|a| cuts(a)[usize::from(c[a])]),
            hi: std::array::from_fn(|a| cuts(a)[usize::from(c[a]) + 1]),
        }
    }

    /// The assignment message of node `id`.
    pub fn assign(&self, id: usize) -> Assign {
        let b = self.bounds(id);
        Assign {
            array: self.array,
            coord: self.coord(id),
            lo: b.lo,
            hi: b.hi,
            driving_axis: self.driving_axis,
            staggered: self.row_cuts.is_some(),
        }
    }

    /// The node whose box holds `p` (clamped into the grid first).
    pub fn owner_of(&self, p: [f64; 3], grid: [u16; 3]) -> usize {
        let cell: [u16; 3] = std::array::from_fn(|a| p[a].floor().clamp(0.0, f64::from(grid[a] - 1)) as u16);
        let idx: [usize; 3] = std::array::from_fn(|a| {
            self.cuts[a].windows(2).position(|w| cell[a] >= w[0] && cell[a] < w[1]).unwrap_or(0)
        });
        idx[0] + usize::from(self.array[0]) * (idx[1] + usize::from(self.array[1]) * idx[2])
    }

    /// Checks that every node can hold its part of the scene; the error names
    /// the first node that cannot, and by how much.
    pub fn check_capacity(&self, scene: &Scene, capacity: Capacity) -> Result<(), HostError> {
        let grid = Grid::new(scene.grid).map_err(|e| input(format!("grid: {e:?}")))?;
        let spheres: Vec<Sphere> = scene
            .sphere_msgs()
            .iter()
            .map(|m| Sphere::from_msg(m, &grid).map_err(|e| input(format!("sphere {}: {e:?}", m.id))))
            .collect::<Result<_, _>>()?;
        for id in 0..self.len() {
            let b = self.bounds(id);
            let cubes = b.volume();
            let (mut kept, mut refs) = (0u64, 0u64);
            for s in &spheres {
                let mut n = 0u64;
                b.for_each_surface_cube(s, |_| n += 1);
                if n > 0 {
                    kept += 1;
                }
                refs += n;
            }
            let c = self.coord(id);
            let name = format!("node {id} ({},{},{})", c[0], c[1], c[2]);
            if cubes > u64::from(capacity.cubes) {
                return Err(HostError::Capacity(format!(
                    "{name} would span {cubes} cubes; a node holds {}",
                    capacity.cubes
                )));
            }
            if kept > u64::from(capacity.spheres) {
                return Err(HostError::Capacity(format!(
                    "{name} would hold {kept} spheres; a node holds {}",
                    capacity.spheres
                )));
            }
            if refs > u64::from(capacity.refs) {
                return Err(HostError::Capacity(format!(
                    "{name} would hold {refs} sphere references; a node holds {}",
                    capacity.refs
                )));
            }
        }
        Ok(())
    }
}

/// Cuts `0 = c_0 < c_1 < ... < c_parts = layers.len()` splitting the layer
/// costs as evenly as prefix sums allow, every part at least one layer.
pub fn equal_cost_cuts(layers: &[u64], parts: usize) -> Vec<u16> {
    let n = layers.len();
    let total: u64 = layers.iter().sum();
    let mut cuts = vec![0u16];
    let mut prefix = 0u64;
    let mut k = 0usize;
    for i in 1..parts {
        let target = total as u128 * i as u128 / parts as u128;
        // Leave room for the parts still to come; take at least one layer.
        let min = usize::from(*cuts.last().unwrap_or(&0)) + 1;
        let max = n - (parts - i);
        while k < max && (k < min || u128::from(prefix + layers[k] / 2) < target) {
            prefix += layers[k];
            k += 1;
        }
        cuts.push(k as u16);
    }
    cuts.push(n as u16);
    cuts
}

/// Per plane of cubes across axis `cut`, its cost within each part of axis
/// `other` (cut at `other_cuts`), summed over the third axis.
fn plane_costs(grid: [u16; 3], cost: &[u64], cut: usize, other: usize, other_cuts: &[u16]) -> Vec<Vec<u64>> {
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

/// The paper's driving axis: the one along which the sphere counts of the
/// node layers vary most (coefficient of variation; ties to the lowest axis).
pub fn driving_axis(scene: &Scene, array: [u16; 3]) -> Result<u8, HostError> {
    let mut best = (0u8, f64::NEG_INFINITY);
    for axis in 0..3u8 {
        let even = Partition::even(scene.grid, array, axis)?;
        let layers = usize::from(array[usize::from(axis)]);
        let mut counts = vec![0f64; layers];
        for s in &scene.spheres {
            // A sphere counts in every layer its bounding interval reaches.
            let a = usize::from(axis);
            for (i, w) in even.cuts[a].windows(2).enumerate() {
                if s.center[a] + s.radius >= f64::from(w[0]) && s.center[a] - s.radius <= f64::from(w[1]) {
                    counts[i] += 1.0;
                }
            }
        }
        let mean = counts.iter().sum::<f64>() / layers as f64;
        let var = counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / layers as f64;
        let cv = if mean > 0.0 { var.sqrt() / mean } else { 0.0 };
        if cv > best.1 + 1e-12 {
            best = (axis, cv);
        }
    }
    Ok(best.0)
}

/// The axis most aligned with the camera's view direction: rays enter on the
/// face toward the eye, so work falls off along it even when sphere counts are
/// alike on every axis (a refinement beyond the paper).
pub fn view_axis(scene: &Scene) -> u8 {
    let c = scene.camera();
    let f = crate::scene::sub(c.look_at, c.eye);
    (0..3u8).max_by(|&a, &b| f[usize::from(a)].abs().total_cmp(&f[usize::from(b)].abs())).unwrap_or(0)
}

/// Splits a `width` x `height` image into `n` tiles `[x0, y0, x1, y1)`, one per
/// node: a grid of tiles as close to square as `n` allows.
pub fn tiles(width: u16, height: u16, n: usize) -> Vec<[u16; 4]> {
    let aspect = f64::from(width) / f64::from(height);
    let cols = (1..=n)
        .filter(|&c| n.is_multiple_of(c))
        .min_by(|&a, &b| {
            let score = |c: usize| ((c as f64 / (n / c) as f64) / aspect).ln().abs();
            score(a).total_cmp(&score(b))
        })
        .unwrap_or(1);
    let rows = n / cols;
    let split = |len: u16, parts: usize, i: usize| (u32::from(len) * i as u32 / parts as u32) as u16;
    (0..n)
        .map(|i| {
            let (cx, cy) = (i % cols, i / cols);
            [
                split(width, cols, cx),
                split(height, rows, cy),
                split(width, cols, cx + 1),
                split(height, rows, cy + 1),
            ]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{Partition, bottleneck_cuts, equal_cost_cuts};
    use proptest::prelude::*;

    /// The largest per-component sum of any part.
    fn worst(planes: &[Vec<u64>], cuts: &[u16]) -> u64 {
        cuts.windows(2)
            .flat_map(|w| {
                let part = &planes[usize::from(w[0])..usize::from(w[1])];
                (0..planes[0].len()).map(move |j| part.iter().map(|p| p[j]).sum::<u64>())
            })
            .max()
            .unwrap_or(0)
    }

    /// Every way to cut `n` planes into `parts` non-empty parts.
    fn all_cuts(n: usize, parts: usize) -> Vec<Vec<u16>> {
        if parts == 1 {
            return vec![vec![0, n as u16]];
        }
        (parts - 1..n)
            .flat_map(|last| {
                all_cuts(last, parts - 1).into_iter().map(move |mut c| {
                    c.push(n as u16);
                    c
                })
            })
            .collect()
    }

    proptest! {
        #[test]
        fn bottleneck_cuts_are_optimal_against_every_cut(
            planes in (1usize..=3).prop_flat_map(|k| prop::collection::vec(prop::collection::vec(0u64..50, k), 1..=9)),
            parts in 1usize..=4,
        ) {
            prop_assume!(parts <= planes.len());
            let cuts = bottleneck_cuts(&planes, parts);
            prop_assert_eq!(cuts.len(), parts + 1);
            prop_assert_eq!(cuts[0], 0);
            prop_assert_eq!(usize::from(cuts[parts]), planes.len());
            prop_assert!(cuts.windows(2).all(|w| w[0] < w[1]), "{:?}", cuts);
            let best = all_cuts(planes.len(), parts).iter().map(|c| worst(&planes, c)).min().unwrap();
            prop_assert_eq!(worst(&planes, &cuts), best);
        }
    }

    #[test]
    fn fitted_partition_evens_out_rows_of_a_concentrated_cost() {
        // Nearly all the cost in an 8^3 block off-centre in a 16^3 grid, as
        // when the spheres fill part of the space.
        let grid = [16u16; 3];
        let mut cost = vec![1u64; 16 * 16 * 16];
        for z in 2..10 {
            for y in 6..14 {
                for x in 3..11 {
                    cost[x + 16 * (y + 16 * z)] = 1000;
                }
            }
        }
        let even = Partition::even(grid, [4; 3], 2).unwrap();
        let fitted = Partition::fitted(grid, [4; 3], 2, &cost).unwrap();
        let rows = |p: &Partition| -> Vec<u64> {
            p.row_layers(grid, &cost).iter().map(|l| l.iter().sum()).collect()
        };
        let (e, f) = (rows(&even), rows(&fitted));
        let mean = e.iter().sum::<u64>() as f64 / e.len() as f64;
        assert_eq!(e.iter().sum::<u64>(), f.iter().sum::<u64>());
        let (emax, fmax) = (*e.iter().max().unwrap() as f64 / mean, *f.iter().max().unwrap() as f64 / mean);
        assert!(emax > 2.0 && fmax < 1.1, "busiest row / mean: even {emax:.2}, fitted {fmax:.2}");
        // Whole planes across the driving axis; every node keeps a cube per axis.
        for a in 0..3 {
            assert!(fitted.cuts[a].windows(2).all(|w| w[0] < w[1]) && fitted.cuts[a][4] == 16);
        }
        for row in fitted.row_cuts.as_ref().unwrap() {
            assert!(row.windows(2).all(|w| w[0] < w[1]) && row[0] == 0 && row[4] == 16, "{row:?}");
        }
    }

    #[test]
    fn equal_cost_cuts_split_evenly_and_keep_a_layer_each() {
        assert_eq!(equal_cost_cuts(&[1; 8], 4), vec![0, 2, 4, 6, 8]);
        // All the cost in the first two layers: each part still gets one layer.
        assert_eq!(equal_cost_cuts(&[100, 100, 0, 0, 0, 0], 3), vec![0, 1, 2, 6]);
        assert_eq!(equal_cost_cuts(&[0, 0, 0, 0, 50, 50], 2), vec![0, 5, 6]);
        assert_eq!(equal_cost_cuts(&[7], 1), vec![0, 1]);
    }
}
