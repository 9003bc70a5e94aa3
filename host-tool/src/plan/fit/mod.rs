//! Fitting a partition to a cost map ([`crate::plan::cost_map`]): the planes
//! across the driving axis by rectilinear partitioning and a local search,
//! then each slab's own columns, each row along the driving axis exactly,
//! and every node's cost with rays routed as the nodes route them; the
//! family's exact floor ([`floor`]) is one more start.

pub mod floor;
mod planes;
mod price;
mod rows;
mod sums;
#[cfg(test)]
mod testing;

pub use planes::bottleneck_cuts;
use planes::plane_costs;
pub use rows::{RowProfile, row_cuts};

use link_proto::Boundaries;

use crate::error::{HostError, input};
use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;
use crate::threads::join;
use price::{Pricing, Score};

/// How far ahead of the even boxes a fit's longest node time must be
/// priced, where a wire's time is the longest of either, for the fit to be
/// kept: a fraction (numerator, denominator) of the even boxes' time. The
/// wires' prices err by different amounts on different partitions of one
/// frame: on 4x4x4 at 1 Mbaud (1000 spheres, seed 1986, 128x128, rows along
/// the paper's driving axis) the even boxes' busiest wire was priced 13%
/// above what the board carried and a fit's within 1%, and that fit, priced
/// 8% ahead, ran 4% behind. (Each ray is priced at its share of a full batch,
/// the fewest bytes it can take, so the excess is the preview's: its rays,
/// at half the resolution, stand for the frame's only roughly.) Where the CPUs
/// bound both, the fit is kept if it is priced ahead at all: a margin there
/// gave up fits 13% faster than even boxes (8x8x1 on ideal links, 256x256,
/// seed 7).
const WIRE_MARGIN: (u128, u128) = (1, 8);
impl Partition {
    /// A partition fitted to a cost map: the one whose busiest node pays
    /// least, as far as a local search finds it. The planes across the
    /// driving axis are first placed whole by rectilinear partitioning after
    /// Nicol (1994), each axis in turn cut to minimise the busiest row's cubes
    /// given the other's cuts; then moved a cube at a time while that lowers
    /// the busiest node, every boundary's crossings counted and rays routed as
    /// the nodes route them ([`Self::node_costs`]). Then each slab across the
    /// first routed axis may cut its own columns, searched the same way, and
    /// also from the family's exact floor ([`floor::floor`], which leaves out
    /// forwarding); the nodes' dimension-order routing still needs nothing
    /// but their own box. Rows are cut along the driving axis exactly
    /// ([`row_cuts`]). From the true cost map this is an oracle; from a
    /// preview render's, a start the host can afford. Its boundaries line up at least as far as `most`
    /// allows (the nodes' pools size for the forwarding that staggered
    /// boundaries bring).
    pub fn fitted(
        grid: [u16; 3],
        array: [u16; 3],
        driving_axis: u8,
        map: &CostMap,
        most: Boundaries,
    ) -> Result<Self, HostError> {
        if map.grid != grid {
            return Err(input(format!("a cost map of grid {:?} cannot fit grid {grid:?}", map.grid)));
        }
        let mut p = Self::even(grid, array, driving_axis)?;
        let cells = map.cells();
        let [a, b] = p.row_axes();
        let mut best = p.busiest_row(grid, &cells);
        // A few alternations settle it; keep the best seen, as a pass may not improve.
        for _ in 0..4 {
            let mut next = p.clone();
            for (cut, other) in [(a, b), (b, a)] {
                let planes = plane_costs(grid, &cells, cut, other, &next.cuts[other]);
                next.cuts[cut] = bottleneck_cuts(&planes, usize::from(array[cut]));
            }
            let busiest = next.busiest_row(grid, &cells);
            if busiest >= best {
                break;
            }
            (p, best) = (next, busiest);
        }
        let even = Self::even(grid, array, driving_axis)?;
        let mut pricing = Pricing::new(map, driving_axis);
        let whole = p.refine(&mut pricing, most);
        if most < Boundaries::StaggeredColumns {
            return Ok(p.or_even(even, &pricing));
        }
        // Beyond whole planes: each slab across the first routed axis cuts its
        // own columns, from the whole cuts, from its own cubes' costs, or as
        // the family's floor cuts them. The starts are searched each on its
        // own core (a row's price depends on nothing but its rectangle, so
        // each search keeps its own rows), and the best is taken in this
        // order, the first of equals.
        let refined = |mut start: Self, pricing: &mut Pricing<'_>| (start.refine(pricing, most), start);
        let (alike, own, exact) = std::thread::scope(|scope| {
            let alike = scope.spawn(|| refined(p.slabs_alike(), &mut Pricing::new(map, driving_axis)));
            let own =
                scope.spawn(|| refined(p.slabs_on_their_own(&cells), &mut Pricing::new(map, driving_axis)));
            let exact = floor::floor_under(map, array, driving_axis, Some(&p))
                .map(|f| f.map(|f| refined(f.partition, &mut pricing)));
            (join(alike), join(own), exact)
        });
        let mut best = (whole, p);
        for (s, jagged) in [Some(alike), Some(own), exact?].into_iter().flatten() {
            if s < best.0 {
                best = (s, jagged);
            }
        }
        Ok(best.1.or_even(even, &pricing))
    }

    /// This partition, unless the even boxes are priced ahead of it, or
    /// within [`WIRE_MARGIN`] of it where a wire bounds either: then the even
    /// boxes. The search starts from cuts that balance the CPU alone, and
    /// where the wires bound a frame nothing it reaches may beat the even
    /// boxes.
    fn or_even(self, even: Self, pricing: &Pricing<'_>) -> Self {
        let [fit, even_score] = [&self, &even].map(|p| pricing.score(p));
        // The longest node time above the busiest CPU: a wire's.
        let wire_bound = fit.0 > fit.1 || even_score.0 > even_score.1;
        let (ahead, of) = if wire_bound { WIRE_MARGIN } else { (0, 1) };
        let [fit, even_time] = [fit.0, even_score.0].map(u128::from);
        if fit * of < even_time * (of - ahead) { self } else { even }
    }

    /// This partition with every slab cut into the columns all share now.
    fn slabs_alike(&self) -> Self {
        let [slab_axis, column_axis] = self.routed_axes();
        let cuts = vec![self.cuts[column_axis].clone(); usize::from(self.array[slab_axis])];
        Self { slab_cuts: Some(cuts), ..self.clone() }
    }

    /// This partition with each slab cut into columns of even cost (`cells`,
    /// x fastest), on its own.
    fn slabs_on_their_own(&self, cells: &[u64]) -> Self {
        let [slab_axis, column_axis] = self.routed_axes();
        let grid = self.grid();
        let [nx, ny, _] = grid.map(usize::from);
        let slabs = self.cuts[slab_axis].windows(2).map(|w| {
            let mut planes = vec![vec![0u64]; usize::from(grid[column_axis])];
            for (i, &c) in cells.iter().enumerate() {
                let cell = [i % nx, i / nx % ny, i / (nx * ny)];
                if (usize::from(w[0])..usize::from(w[1])).contains(&cell[slab_axis]) {
                    planes[cell[column_axis]][0] += c;
                }
            }
            bottleneck_cuts(&planes, usize::from(self.array[column_axis]))
        });
        Self { slab_cuts: Some(slabs.collect()), ..self.clone() }
    }

    /// Cubes per axis: the last cut along each.
    fn grid(&self) -> [u16; 3] {
        std::array::from_fn(|a| self.cuts[a].last().copied().unwrap_or(0))
    }

    /// Moves single planes across the driving axis by a cube (a slab's own
    /// where slabs cut their columns), rows re-cut, while that lowers the
    /// busiest node's cost (ties: the sum of squares); returns the score.
    fn refine(&mut self, pricing: &mut Pricing<'_>, most: Boundaries) -> Score {
        let mut best = self.cut_rows(pricing, most, None).unwrap_or(price::WORST);
        // Each accepted move lowers the score, so this ends; the cap bounds the time.
        for _ in 0..4 * usize::from(pricing.grid().iter().copied().max().unwrap_or(1)) {
            let mut improved = false;
            for plane in self.movable_planes() {
                for step in [-1, 1] {
                    let mut next = self.clone();
                    if next.move_plane(plane, step)
                        && let Some(s) = next.cut_rows(pricing, most, Some(best))
                        && s < best
                    {
                        (*self, best) = (next, s);
                        improved = true;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        best
    }

    /// Every inner plane across a non-driving axis: (axis, slab, index), the
    /// slab `None` where the planes are whole.
    fn movable_planes(&self) -> Vec<(usize, Option<usize>, usize)> {
        let column_axis = self.routed_axes()[1];
        let slabs = self.slab_cuts.as_ref().map_or(0, Vec::len);
        let mut planes = Vec::new();
        for a in self.row_axes() {
            let inner = 1..usize::from(self.array[a]);
            if a == column_axis && slabs > 0 {
                planes.extend((0..slabs).flat_map(|s| inner.clone().map(move |i| (a, Some(s), i))));
            } else {
                planes.extend(inner.map(|i| (a, None, i)));
            }
        }
        planes
    }

    /// Moves a plane by `step` cubes if every node keeps a cube on each side.
    fn move_plane(&mut self, (axis, slab, i): (usize, Option<usize>, usize), step: i32) -> bool {
        let cuts = match (slab, self.slab_cuts.as_mut()) {
            (Some(s), Some(slabs)) => &mut slabs[s],
            _ => &mut self.cuts[axis],
        };
        let at = i32::from(cuts[i]) + step;
        if at <= i32::from(cuts[i - 1]) || at >= i32::from(cuts[i + 1]) {
            return false;
        }
        cuts[i] = at as u16;
        true
    }

    /// Cuts the rows along the driving axis, each on its own (staggered, as
    /// sliding leaves them, if `most` allows) or all alike (no ray forwarded),
    /// whichever leaves the busiest node paying less; returns that score.
    /// `None` if both score worse than `beat`: a candidate of the local
    /// search is priced only as far as it could still win.
    fn cut_rows(
        &mut self,
        pricing: &mut Pricing<'_>,
        most: Boundaries,
        beat: Option<Score>,
    ) -> Option<Score> {
        let d = usize::from(self.driving_axis);
        let parts = usize::from(self.array[d]);
        let (rows, own) = pricing.rows(self);
        let mut alike = Self { row_cuts: None, ..self.clone() };
        alike.cuts[d] = row_cuts(&rows, parts);
        let staggered = Self { row_cuts: Some(own), ..self.clone() };
        // A node past the longest time of `beat` scores worse than it.
        let limit = beat.map_or(u64::MAX, |b| b.0);
        let a = pricing.score_within(&alike, limit);
        if most == Boundaries::Whole {
            *self = alike;
            return a;
        }
        // Staggered rows are taken only if they score below the alike rows.
        let s = pricing.score_within(&staggered, a.map_or(limit, |a| a.0));
        match (a, s) {
            (Some(a), Some(s)) if a <= s => {
                *self = alike;
                Some(a)
            }
            (_, Some(s)) => {
                *self = staggered;
                Some(s)
            }
            (a, None) => {
                *self = alike;
                a
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{RowProfile, bottleneck_cuts, row_cuts};
    use crate::plan::cost_map::{CostMap, WireCycles};
    use crate::plan::partition::Partition;
    use link_proto::Boundaries;
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
        let map = CostMap { compute: cost, ..CostMap::new(grid) };
        let even = Partition::even(grid, [4; 3], 2).unwrap();
        let fitted = Partition::fitted(grid, [4; 3], 2, &map, Boundaries::StaggeredColumns).unwrap();
        let rows = |p: &Partition| p.row_loads(&map);
        let (e, f) = (rows(&even), rows(&fitted));
        let mean = e.iter().sum::<u64>() as f64 / e.len() as f64;
        assert_eq!(e.iter().sum::<u64>(), f.iter().sum::<u64>());
        let (emax, fmax) = (*e.iter().max().unwrap() as f64 / mean, *f.iter().max().unwrap() as f64 / mean);
        assert!(emax > 2.0 && fmax < 1.1, "busiest row / mean: even {emax:.2}, fitted {fmax:.2}");
        // Whole planes across the driving axis; every node keeps a cube per axis.
        for a in 0..3 {
            assert!(fitted.cuts[a].windows(2).all(|w| w[0] < w[1]) && fitted.cuts[a][4] == 16);
        }
        for row in fitted.row_cuts.iter().flatten() {
            assert!(row.windows(2).all(|w| w[0] < w[1]) && row[0] == 0 && row[4] == 16, "{row:?}");
        }
        // The boxes tile the grid.
        let volume: u64 = (0..fitted.len()).map(|id| fitted.bounds(id).volume()).sum();
        assert_eq!(volume, 16 * 16 * 16);
    }

    #[test]
    fn a_fit_a_little_ahead_of_even_boxes_is_kept_unless_a_wire_bounds_it() {
        // Two nodes along x: even boxes pay 80 and 96, the cut after nine
        // cubes 90 and 84, 6% ahead.
        let grid = [16u16, 1, 1];
        let compute = (0..16).map(|x| if x < 8 { 10 } else { 12 }).collect();
        let mut map = CostMap { compute, ..CostMap::new(grid) };
        let cut = |map: &CostMap| {
            let p = Partition::fitted(grid, [2, 1, 1], 0, map, Boundaries::StaggeredColumns).unwrap();
            p.bounds(0).hi[0]
        };
        assert_eq!(cut(&map), 9, "the CPUs bound both: the fit is ahead");
        // The first cube's holder sends the host 95 cycles of bytes whatever
        // the cut: its wire bounds both, and the fit is not 1/8 ahead.
        map.wire.host[0] = 19;
        map.wire.cycles = WireCycles { neighbour: 0, host: 5 };
        assert_eq!(cut(&map), 8, "a wire bounds the fit: the even boxes");
        // With the wire at 85 cycles the CPUs bound both again.
        map.wire.host[0] = 17;
        assert_eq!(cut(&map), 9);
    }

    #[test]
    fn fitted_partition_cuts_where_few_rays_cross() {
        // Even compute; rays crossing the planes z = 4, 8 and 12 heavily, the
        // even partition's cuts along the driving axis z.
        let grid = [16u16; 3];
        let mut map = CostMap { compute: vec![10; 16 * 16 * 16], ..CostMap::new(grid) };
        for (i, f) in map.up[2].iter_mut().enumerate() {
            *f = if [3, 7, 11].contains(&(i / 256)) { 1000 } else { 1 };
        }
        for (i, f) in map.down[2].iter_mut().enumerate() {
            *f = if i / 256 == 7 { 500 } else { 0 };
        }
        let max_node = |p: &Partition| (0..p.len()).map(|id| map.node_cost(&p.bounds(id))).max().unwrap();
        let even = Partition::even(grid, [2, 2, 4], 2).unwrap();
        let fitted = Partition::fitted(grid, [2, 2, 4], 2, &map, Boundaries::StaggeredColumns).unwrap();
        // A row is 64 cubes across: 640 a layer, 64 a plane's side, 64 000
        // at the heavy planes (96 000 at z = 8, crossed both ways).
        assert_eq!(max_node(&even), 4 * 640 + 64_000 + 96_000);
        assert_eq!(max_node(&fitted), 5 * 640 + 64, "{:?} {:?}", fitted.cuts, fitted.row_cuts);
        // No ray is forwarded here: the routed account agrees with the boxes'.
        for p in [&even, &fitted] {
            let routed = p.node_costs(&map);
            assert!((0..p.len()).all(|id| routed[id] == map.node_cost(&p.bounds(id))));
        }
    }

    #[test]
    fn fitted_partition_cuts_each_slab_into_its_own_columns() {
        // The cost sits low in y where x < 8 and high in y where x >= 8: whole
        // planes across y cannot split both slabs' work evenly.
        let grid = [16u16; 3];
        let mut cost = vec![1u64; 16 * 16 * 16];
        for (i, c) in cost.iter_mut().enumerate() {
            let (x, y) = (i % 16, i / 16 % 16);
            if (x < 8 && y < 4) || (x >= 8 && y >= 12) {
                *c = 100;
            }
        }
        let map = CostMap { compute: cost, ..CostMap::new(grid) };
        let fitted = Partition::fitted(grid, [2, 2, 2], 2, &map, Boundaries::StaggeredColumns).unwrap();
        let max = |p: &Partition| *p.node_costs(&map).iter().max().unwrap();
        // The best whole planes, by trying every pair of cuts across x and y.
        let mut whole = u64::MAX;
        for x in 1..16 {
            for y in 1..16 {
                let mut p = Partition::even(grid, [2, 2, 2], 2).unwrap();
                (p.cuts[0][1], p.cuts[1][1]) = (x, y);
                let mut pricing = super::Pricing::new(&map, 2);
                whole = whole.min(p.cut_rows(&mut pricing, Boundaries::StaggeredRows, None).unwrap().0);
            }
        }
        let slabs = fitted.slab_cuts.as_ref().expect("columns cut per slab");
        assert!(slabs[0][1] < 8 && slabs[1][1] > 8, "{slabs:?}");
        assert!(max(&fitted) * 10 < whole * 8, "fitted {} against whole planes {whole}", max(&fitted));
        // Within 10% of an eighth of the cost per node.
        let total: u64 = map.compute.iter().sum();
        assert!(max(&fitted) * 8 <= total * 11 / 10, "{} of {total}", max(&fitted));
        let volume: u64 = (0..fitted.len()).map(|id| fitted.bounds(id).volume()).sum();
        assert_eq!(volume, 16 * 16 * 16);
    }

    /// The busiest part of any row under `cuts`, priced from scratch.
    fn busiest_part(rows: &[(Vec<u64>, Vec<u64>)], cuts: &[u16]) -> u64 {
        let mut worst = 0;
        for (layers, planes) in rows {
            let n = layers.len();
            let plane = |k: usize| if k == 0 || k == n { 0 } else { planes[k] };
            for w in cuts.windows(2) {
                let (i, j) = (usize::from(w[0]), usize::from(w[1]));
                worst = worst.max(layers[i..j].iter().sum::<u64>() + plane(i) + plane(j));
            }
        }
        worst
    }

    proptest! {
        #[test]
        fn row_cuts_are_optimal_against_every_cut(
            rows in (1usize..=9).prop_flat_map(|n| prop::collection::vec((
                prop::collection::vec(0u64..50, n),
                prop::collection::vec(0u64..80, n + 1),
            ), 1..=3)),
            parts in 1usize..=4,
        ) {
            let n = rows[0].0.len();
            prop_assume!(parts <= n);
            let profiles: Vec<RowProfile> =
                rows.iter().map(|(l, p)| RowProfile { layers: l.clone(), planes: p.clone() }).collect();
            let cuts = row_cuts(&profiles, parts);
            prop_assert_eq!(cuts.len(), parts + 1);
            prop_assert_eq!(cuts[0], 0);
            prop_assert_eq!(usize::from(cuts[parts]), n);
            prop_assert!(cuts.windows(2).all(|w| w[0] < w[1]), "{:?}", cuts);
            let best = all_cuts(n, parts).iter().map(|c| busiest_part(&rows, c)).min().unwrap();
            prop_assert_eq!(busiest_part(&rows, &cuts), best);
        }
    }
}
