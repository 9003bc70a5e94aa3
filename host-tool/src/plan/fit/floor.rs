//! The least busiest node a partition of the routed family can have, found
//! exactly by dynamic programming over every box a row of nodes can take.
//!
//! The family is the one the nodes route ([`Partition::routed_axes`]):
//! planes across the slab axis whole, each slab cutting its own columns,
//! each row along the driving axis cutting its own nodes. Every node pays its
//! cubes and the crossings of its faces inside the grid
//! ([`CostMap::node_cost`]); rays forwarded through a node on their way to a
//! non-neighbour are left out. So the value is a floor under the busiest
//! node of any partition of the family ([`Partition::node_costs`] only adds
//! to it), and the partition reaching it is a start for the local search.
//!
//! Every row is a rectangle across the slab and column axes; its best cut
//! along the driving axis is a small dynamic program ([`least_busiest`]).
//! Tabled for every rectangle, the columns of each slab and then the slabs
//! are each one more such program over the table.

use std::num::NonZeroUsize;

use crate::error::HostError;
use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

use super::sums::LayerSums;

/// Work (rectangles times their row program's steps) above which [`floor`]
/// declines: a few seconds on this machine's two cores. A 32^3 grid on 8x8x8
/// nodes takes 1.1e9.
pub const WORK_BUDGET: u64 = 3_000_000_000;

/// Table entries (one per pair of spans across the slab and column axes)
/// above which [`floor`] declines: 128 MiB. A 32^3 grid takes 1.2e6.
pub const TABLE_BUDGET: u64 = 1 << 24;

/// The floor and a partition of the family whose nodes' own costs reach it.
#[derive(Debug, Clone)]
pub struct Floor {
    /// The least busiest node's cost over the family.
    pub cost: u64,
    /// A partition whose busiest node, priced by [`CostMap::node_cost`],
    /// pays exactly that.
    pub partition: Partition,
}

/// The family's floor for `map` over `array` along `driving_axis`, or
/// `None` where tabling every rectangle would cost more time than
/// [`WORK_BUDGET`] or more memory than [`TABLE_BUDGET`].
pub fn floor(map: &CostMap, array: [u16; 3], driving_axis: u8) -> Result<Option<Floor>, HostError> {
    floor_under(map, array, driving_axis, None)
}

/// [`floor`], told a partition of the family (`member`, over the same grid,
/// array and driving axis), whose rows cut on their own bound the floor from
/// above: a rectangle whose row must cost more than that can be in no
/// partition that reaches the floor, so its row is searched only below that
/// cost, or not at all where its layers alone say so. The floor and its partition are
/// [`floor`]'s. On the paper's scene over 8x8x8 (a preview's map, 256x256)
/// this took the table from 7.8e9 to 4.1e9 instructions (callgrind): a wide
/// rectangle holds several rows' work.
pub fn floor_under(
    map: &CostMap,
    array: [u16; 3],
    driving_axis: u8,
    member: Option<&Partition>,
) -> Result<Option<Floor>, HostError> {
    let mut partition = Partition::even(map.grid, array, driving_axis)?;
    let [s, c] = partition.routed_axes();
    let d = usize::from(driving_axis);
    let g = map.grid.map(u64::from);
    let spans = |a: usize| g[a] * (g[a] + 1) / 2;
    let steps = u64::from(array[d]) * g[d] * g[d] / 2 + g[d];
    let entries = ((g[s] + 1) * (g[c] + 1)).saturating_mul((g[s] + 1) * (g[c] + 1));
    if spans(s).saturating_mul(spans(c)).saturating_mul(steps) > WORK_BUDGET || entries > TABLE_BUDGET {
        return Ok(None);
    }
    let g = map.grid.map(usize::from);
    let n = array.map(usize::from);
    let sums = LayerSums::new(map, driving_axis);
    let cap = member.map_or(u64::MAX, |m| sums.rows_least(m, n[d]));
    let table = RowTable::new(&sums, n[d], cap);
    // Per slab, its best columns; over the slabs, the best cut.
    let slabs: Vec<Vec<(u64, Vec<u16>)>> = (0..=g[s])
        .map(|s0| {
            let columns = |s1| least_busiest(g[c], n[c], |c0, c1| table.get(s0, s1, c0, c1));
            (0..=g[s]).map(|s1| if s0 < s1 { columns(s1) } else { (0, Vec::new()) }).collect()
        })
        .collect();
    let (cost, slab_cuts) = least_busiest(g[s], n[s], |s0, s1| slabs[s0][s1].0);
    let columns: Vec<Vec<u16>> =
        slab_cuts.windows(2).map(|w| slabs[usize::from(w[0])][usize::from(w[1])].1.clone()).collect();
    partition.cuts[s] = slab_cuts;
    partition.slab_cuts = Some(columns);
    // Each row's own cuts, row by row in the partition's order.
    let rows = (0..partition.len() / n[d]).map(|row| {
        let ((s0, s1), (c0, c1)) = (partition.row_span(row, s), partition.row_span(row, c));
        sums.row(n[d], [s0, s1, c0, c1].map(usize::from)).1
    });
    partition.row_cuts = Some(rows.collect());
    Ok(Some(Floor { cost, partition }))
}

/// Cuts `0 = k_0 < ... < k_parts = len` minimising the largest
/// `cost(k_i, k_i+1)`: that largest cost and the cuts (exact, dynamic
/// programming; every part keeps at least one unit).
pub fn least_busiest(len: usize, parts: usize, cost: impl Fn(usize, usize) -> u64) -> (u64, Vec<u16>) {
    let parts = parts.clamp(1, len.max(1));
    let mut best = vec![vec![u64::MAX; len + 1]; parts + 1];
    let mut from = vec![vec![0usize; len + 1]; parts + 1];
    best[0][0] = 0;
    for p in 1..=parts {
        for j in p..=len - (parts - p) {
            for i in p - 1..j {
                if best[p - 1][i] != u64::MAX {
                    let v = best[p - 1][i].max(cost(i, j));
                    if v < best[p][j] {
                        (best[p][j], from[p][j]) = (v, i);
                    }
                }
            }
        }
    }
    let mut cuts = vec![len];
    for p in (1..=parts).rev() {
        cuts.push(from[p][cuts[cuts.len() - 1]]);
    }
    cuts.reverse();
    (best[parts][len], cuts.into_iter().map(|k| k as u16).collect())
}

/// [`least_busiest`]'s cost alone, for parts that cost `prefix[j] -
/// prefix[i] + plane[i] + plane[j]` (`prefix` running sums, so not
/// decreasing; `plane` at least zero): a part can cost no less than its
/// layers, so the search for a part's start stops once its layers alone
/// cost as much as the best found. The floor tables this for every
/// rectangle, and only the cost; the cuts come from [`least_busiest`].
///
/// Exact when it is at most `cap`; otherwise some value above `cap`: no
/// start is searched whose layers alone cost more.
pub fn least_busiest_cost(prefix: &[u64], plane: &[u64], parts: usize, cap: u64) -> u64 {
    let len = prefix.len().saturating_sub(1);
    let parts = parts.clamp(1, len.max(1));
    let cost = |i: usize, j: usize| prefix[j] - prefix[i] + plane[i] + plane[j];
    // last[j]: the least busiest part of layers 0..j cut into p parts; one
    // part starts at layer 0.
    let mut last: Vec<u64> = (0..=len).map(|j| if j == 0 { u64::MAX } else { cost(0, j) }).collect();
    let mut next = vec![u64::MAX; len + 1];
    for p in 2..=parts {
        next.fill(u64::MAX);
        // Each part leaves a layer for every part after it; the last ends the row.
        let ends = if p == parts { len..=len } else { p..=len - (parts - p) };
        for j in ends {
            let mut best = cap.saturating_add(1);
            let (layers_to_j, plane_j) = (prefix[j], plane[j]);
            // The starts from the nearest, their layers, planes and best
            // cuts before them side by side: this loop is most of the floor.
            let starts = prefix[p - 1..j].iter().zip(&plane[p - 1..j]).zip(&last[p - 1..j]);
            for ((&layers_to_i, &plane_i), &before) in starts.rev() {
                let layers = layers_to_j - layers_to_i;
                if layers >= best {
                    break;
                }
                best = best.min(before.max(layers + plane_i + plane_j));
            }
            next[j] = best;
        }
        std::mem::swap(&mut last, &mut next);
    }
    last[len]
}

/// For every rectangle across the slab and column axes, the least busiest
/// node of a row of nodes over it, its cut along the driving axis free.
struct RowTable {
    /// Cubes along the slab and column axes.
    sides: [usize; 2],
    /// Indexed by [`Self::key`].
    least: Vec<u64>,
}

impl RowTable {
    /// Tables every rectangle for rows of `parts` nodes, on every core:
    /// exactly where that is at most `cap`, else a value above `cap`.
    fn new(sums: &LayerSums, parts: usize, cap: u64) -> Self {
        let [gs, gc] = [sums.g[0], sums.g[1]];
        let block = (gs + 1) * (gc + 1) * (gc + 1);
        let mut least = vec![0u64; (gs + 1) * block];
        let threads = std::thread::available_parallelism().map_or(1, NonZeroUsize::get);
        let mut jobs: Vec<Vec<(usize, &mut [u64])>> = (0..threads).map(|_| Vec::new()).collect();
        for (s0, rows) in least.chunks_mut(block).enumerate().take(gs) {
            jobs[s0 % threads].push((s0, rows));
        }
        std::thread::scope(|scope| {
            for job in jobs {
                scope.spawn(move || {
                    for (s0, rows) in job {
                        sums.table_from(s0, parts, cap, rows);
                    }
                });
            }
        });
        Self { sides: [gs, gc], least }
    }

    /// Position of rectangle `[s0, s1) x [c0, c1)` in the table.
    fn key(sides: [usize; 2], s0: usize, s1: usize, c0: usize, c1: usize) -> usize {
        let [gs, gc] = sides;
        ((s0 * (gs + 1) + s1) * (gc + 1) + c0) * (gc + 1) + c1
    }

    fn get(&self, s0: usize, s1: usize, c0: usize, c1: usize) -> u64 {
        self.least[Self::key(self.sides, s0, s1, c0, c1)]
    }
}

impl LayerSums {
    /// Fills `rows` (the table's block for rectangles starting at `s0`),
    /// exactly where a row's least busiest node costs at most `cap`. Above
    /// it, a rectangle whose layers hold more than `parts` nodes of `cap`
    /// each is given what they hold a node, without a search: its row has
    /// a node that pays at least that.
    fn table_from(&self, s0: usize, parts: usize, cap: u64, rows: &mut [u64]) {
        let [gs, gc, _] = self.g;
        let most = u128::from(cap) * parts as u128;
        let (mut prefix, mut plane) = (vec![0u64; self.g[2] + 1], vec![0u64; self.g[2] + 1]);
        for s1 in s0 + 1..=gs {
            for c0 in 0..gc {
                for c1 in c0 + 1..=gc {
                    let r = [s0, s1, c0, c1];
                    let held = self.held(r);
                    rows[RowTable::key([gs, gc], 0, s1, c0, c1)] = if u128::from(held) > most {
                        held.div_ceil(parts as u64)
                    } else {
                        self.profile_into(r, &mut prefix, &mut plane);
                        least_busiest_cost(&prefix, &plane, parts, cap)
                    };
                }
            }
        }
    }

    /// The busiest of `member`'s rows, each cut on its own into `parts`
    /// nodes: a partition of the family that reaches it, so the floor is no
    /// higher.
    fn rows_least(&self, member: &Partition, parts: usize) -> u64 {
        let [s, c] = member.routed_axes();
        (0..member.len() / parts.max(1))
            .map(|row| {
                let ((s0, s1), (c0, c1)) = (member.row_span(row, s), member.row_span(row, c));
                self.row(parts, [s0, s1, c0, c1].map(usize::from)).0
            })
            .max()
            .unwrap_or(u64::MAX)
    }

    /// The least busiest node of a row of `parts` nodes over rectangle `r`,
    /// and the row's cuts along the driving axis.
    fn row(&self, parts: usize, r: [usize; 4]) -> (u64, Vec<u16>) {
        let (prefix, plane) = self.profile(r);
        least_busiest(self.g[2], parts, |i, j| prefix[j] - prefix[i] + plane[i] + plane[j])
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{map_of, partition_of};
    use super::{floor, floor_under, least_busiest, least_busiest_cost};
    use crate::plan::cost_map::CostMap;
    use crate::plan::partition::Partition;
    use proptest::prelude::*;

    /// Every way to cut `len` units into `parts` non-empty parts.
    fn all_cuts(len: u16, parts: u16) -> Vec<Vec<u16>> {
        if parts == 1 {
            return vec![vec![0, len]];
        }
        (parts - 1..len)
            .flat_map(|last| {
                all_cuts(last, parts - 1).into_iter().map(move |mut c| {
                    c.push(len);
                    c
                })
            })
            .collect()
    }

    /// Every combination of one choice from each list.
    fn product(lists: &[Vec<Vec<u16>>]) -> Vec<Vec<Vec<u16>>> {
        lists.iter().fold(vec![Vec::new()], |acc, list| {
            acc.iter()
                .flat_map(|pre| {
                    list.iter().map(move |x| {
                        let mut v = pre.clone();
                        v.push(x.clone());
                        v
                    })
                })
                .collect()
        })
    }

    /// The busiest node of every partition of the family, each node priced
    /// on its own box: the least of them.
    fn brute_force(map: &CostMap, array: [u16; 3], d: u8) -> u64 {
        let p = Partition::even(map.grid, array, d).unwrap();
        let [s, c] = p.routed_axes();
        let (g, n) = (map.grid, array);
        let rows = usize::from(n[0]) * usize::from(n[1]) * usize::from(n[2]) / usize::from(n[usize::from(d)]);
        let mut least = u64::MAX;
        for slabs in all_cuts(g[s], n[s]) {
            let columns = vec![all_cuts(g[c], n[c]); usize::from(n[s])];
            for columns in product(&columns) {
                let along = vec![all_cuts(g[usize::from(d)], n[usize::from(d)]); rows];
                for row_cuts in product(&along) {
                    let mut q = p.clone();
                    q.cuts[s] = slabs.clone();
                    q.slab_cuts = Some(columns.clone());
                    q.row_cuts = Some(row_cuts);
                    let busiest = (0..q.len()).map(|id| map.node_cost(&q.bounds(id))).max().unwrap();
                    least = least.min(busiest);
                }
            }
        }
        least
    }

    #[test]
    fn floor_declines_grids_too_large_to_table() {
        // Few steps per row, but 200^4 table entries: declined for memory.
        assert!(floor(&CostMap::new([200, 200, 2]), [1, 1, 1], 2).unwrap().is_none());
        // A small table, but too many steps per rectangle.
        assert!(floor(&CostMap::new([64, 64, 64]), [8, 8, 8], 2).unwrap().is_none());
        assert!(floor(&CostMap::new([16, 16, 16]), [4, 4, 4], 2).unwrap().is_some());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn floor_is_the_least_busiest_node_of_every_partition_of_the_family(
            grid in prop::array::uniform3(2u16..=4),
            array in prop::array::uniform3(1u16..=2),
            d in 0u8..3,
            values in prop::collection::vec(0u64..100, 1..=97),
        ) {
            let map = map_of(grid, &values);
            let found = floor(&map, array, d).unwrap().unwrap();
            prop_assert_eq!(found.cost, brute_force(&map, array, d));
            // Its partition reaches it, and tiles the grid.
            let p = &found.partition;
            let busiest = (0..p.len()).map(|id| map.node_cost(&p.bounds(id))).max().unwrap();
            prop_assert_eq!(busiest, found.cost);
            let volume: u64 = (0..p.len()).map(|id| p.bounds(id).volume()).sum();
            prop_assert_eq!(volume, grid.iter().map(|&g| u64::from(g)).product::<u64>());
        }

        #[test]
        fn a_member_of_the_family_leaves_the_floor_and_its_partition_as_they_were(
            grid in prop::array::uniform3(2u16..=5),
            array in prop::array::uniform3(1u16..=3),
            d in 0u8..3,
            values in prop::collection::vec(0u64..100, 1..=97),
            seeds in prop::collection::vec(prop::collection::vec(0u16..100, 4), 40),
            slabs in any::<bool>(),
        ) {
            prop_assume!((0..3).all(|a| array[a] <= grid[a]));
            let map = map_of(grid, &values);
            let member = partition_of(grid, array, d, &seeds, (slabs, true));
            let exact = floor(&map, array, d).unwrap().unwrap();
            let told = floor_under(&map, array, d, Some(&member)).unwrap().unwrap();
            prop_assert_eq!(told.cost, exact.cost);
            prop_assert_eq!(told.partition, exact.partition);
        }

        #[test]
        fn least_busiest_cost_is_least_busiests_cost(
            layers in prop::collection::vec(0u64..1000, 1..=12),
            planes in prop::collection::vec(0u64..800, 13),
            parts in 1usize..=5,
        ) {
            let len = layers.len();
            let prefix: Vec<u64> = std::iter::once(0).chain(layers.iter().scan(0, |s, &l| { *s += l; Some(*s) })).collect();
            let plane: Vec<u64> = (0..=len).map(|k| if k == 0 || k == len { 0 } else { planes[k] }).collect();
            let cost = |i: usize, j: usize| prefix[j] - prefix[i] + plane[i] + plane[j];
            prop_assert_eq!(least_busiest_cost(&prefix, &plane, parts, u64::MAX), least_busiest(len, parts, cost).0);
        }

        #[test]
        fn least_busiest_is_optimal_against_every_cut(
            costs in prop::collection::vec(0u64..1000, 1..=81),
            len in 1u16..=8,
            parts in 1u16..=4,
        ) {
            prop_assume!(parts <= len);
            let cost = |i: usize, j: usize| costs[(i * 9 + j) % costs.len()];
            let (least, cuts) = least_busiest(usize::from(len), usize::from(parts), cost);
            let worst = |c: &[u16]| c.windows(2).map(|w| cost(usize::from(w[0]), usize::from(w[1]))).max().unwrap();
            prop_assert_eq!(worst(&cuts), least);
            prop_assert_eq!(cuts.len(), usize::from(parts) + 1);
            prop_assert!(cuts.windows(2).all(|w| w[0] < w[1]) && cuts[0] == 0 && cuts[usize::from(parts)] == len);
            prop_assert_eq!(all_cuts(len, parts).iter().map(|c| worst(c)).min().unwrap(), least);
        }
    }
}
