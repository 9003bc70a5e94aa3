//! A cost map's running sums, so that the fit prices a box of cubes, or a
//! face of one, in a handful of additions instead of a walk over its cubes.
//!
//! The local search prices thousands of candidate partitions of one map; each
//! used to walk every cube and every face of the grid. With the sums a
//! candidate costs a few lookups a node, and the rays leaving a face a few
//! more for each node they pass (`Partition::node_costs`). The sums are exact
//! integers, so every price is the same as the walk's.

use crate::plan::cost_map::{CostMap, WireCycles};
#[cfg(doc)]
use crate::plan::partition::Partition;

/// Running sums of one value per cube over every box from the grid's origin:
/// `at[(x, y, z)]` is the sum over the cubes below `x`, `y` and `z`.
#[derive(Debug, Clone)]
pub struct BoxSums {
    /// Cubes per axis, plus one.
    side: [usize; 3],
    at: Vec<u64>,
}

impl BoxSums {
    /// The running sums of `values` (x fastest) over a grid of `grid` cubes.
    pub fn new(grid: [u16; 3], values: &[u64]) -> Self {
        let n = grid.map(usize::from);
        let side = n.map(|k| k + 1);
        let mut at = vec![0u64; side.iter().product()];
        let index = |x: usize, y: usize, z: usize| x + side[0] * (y + side[1] * z);
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let v = values[x + n[0] * (y + n[1] * z)];
                    // Inclusion-exclusion; wrapping, because a partial sum of
                    // the terms may dip below zero although the result cannot.
                    let s = v
                        .wrapping_add(at[index(x, y + 1, z + 1)])
                        .wrapping_add(at[index(x + 1, y, z + 1)])
                        .wrapping_add(at[index(x + 1, y + 1, z)])
                        .wrapping_sub(at[index(x, y, z + 1)])
                        .wrapping_sub(at[index(x, y + 1, z)])
                        .wrapping_sub(at[index(x + 1, y, z)])
                        .wrapping_add(at[index(x, y, z)]);
                    at[index(x + 1, y + 1, z + 1)] = s;
                }
            }
        }
        Self { side, at }
    }

    fn get(&self, [x, y, z]: [usize; 3]) -> u64 {
        self.at[x + self.side[0] * (y + self.side[1] * z)]
    }

    /// The sum over the cubes `lo <= c < hi` (empty if any `hi <= lo`).
    pub fn sum(&self, lo: [usize; 3], hi: [usize; 3]) -> u64 {
        if (0..3).any(|a| hi[a] <= lo[a]) {
            return 0;
        }
        let corner = |pick: [bool; 3]| self.get(std::array::from_fn(|a| if pick[a] { hi[a] } else { lo[a] }));
        corner([true, true, true])
            .wrapping_sub(corner([false, true, true]))
            .wrapping_sub(corner([true, false, true]))
            .wrapping_sub(corner([true, true, false]))
            .wrapping_add(corner([false, false, true]))
            .wrapping_add(corner([false, true, false]))
            .wrapping_add(corner([true, false, false]))
            .wrapping_sub(corner([false, false, false]))
    }
}

/// The running sums of everything a [`CostMap`] charges.
#[derive(Debug, Clone)]
pub struct MapSums {
    /// Per cube: [`CostMap::cell`].
    pub cells: BoxSums,
    /// Per axis: [`CostMap::up`].
    pub up: [BoxSums; 3],
    /// Per axis: [`CostMap::down`].
    pub down: [BoxSums; 3],
    /// The wires' bytes, where they are priced.
    pub wire: Option<WireSums>,
}

/// The running sums of a [`crate::plan::cost_map::WireMap`]'s bytes.
#[derive(Debug, Clone)]
pub struct WireSums {
    /// Per cube: bytes to the host.
    pub host: BoxSums,
    /// Per axis: bytes crossing upward.
    pub up: [BoxSums; 3],
    /// Per axis: bytes crossing downward.
    pub down: [BoxSums; 3],
    /// What a byte takes on each wire.
    pub cycles: WireCycles,
}

impl MapSums {
    /// The sums of `map`.
    pub fn new(map: &CostMap) -> Self {
        let g = map.grid;
        let sums = |v: &[u64]| BoxSums::new(g, v);
        let w = &map.wire;
        let wire = w.cycles.priced().then(|| WireSums {
            host: sums(&w.host),
            up: std::array::from_fn(|a| sums(&w.up[a])),
            down: std::array::from_fn(|a| sums(&w.down[a])),
            cycles: w.cycles,
        });
        Self {
            cells: sums(&map.cells()),
            up: std::array::from_fn(|a| sums(&map.up[a])),
            down: std::array::from_fn(|a| sums(&map.down[a])),
            wire,
        }
    }
}

/// Per layer across the driving axis, running sums over the slab and column
/// axes ([`Partition::routed_axes`]) of what cubes cost and of what rays
/// crossing each face cost a side: what a row of nodes over any rectangle
/// of them pays, layer by layer. The floor tables every rectangle from them,
/// and the local search profiles its candidates' rows.
pub(super) struct LayerSums {
    /// Cubes along the slab, column and driving axes.
    pub(super) g: [usize; 3],
    /// Per layer, 2-D running sums of the cubes' costs: `[c][s]`, one
    /// past each, `g[0] + 1` wide.
    cubes: Vec<Vec<u64>>,
    /// Per layer, 2-D running sums of the faces to the next layer.
    ahead: Vec<Vec<u64>>,
    /// Per layer and plane across the slab axis (between `s` and `s + 1`),
    /// running sums along the column axis.
    across_slab: Vec<Vec<Vec<u64>>>,
    /// Per layer and plane across the column axis, running sums along the
    /// slab axis.
    across_column: Vec<Vec<Vec<u64>>>,
}

impl LayerSums {
    /// The sums of `map` for rows along `driving_axis`.
    pub(super) fn new(map: &CostMap, driving_axis: u8) -> Self {
        let d = usize::from(driving_axis);
        let [s, c] = [(d + 1) % 3, (d + 2) % 3];
        let grid = map.grid.map(usize::from);
        let g = [grid[s], grid[c], grid[d]];
        let index = |is: usize, ic: usize, k: usize| {
            let mut cell = [0usize; 3];
            (cell[s], cell[c], cell[d]) = (is, ic, k);
            cell[0] + grid[0] * (cell[1] + grid[1] * cell[2])
        };
        let face = |axis: usize, at: usize, limit: usize, i: usize| {
            if at + 1 < limit { map.face(axis, i) } else { 0 }
        };
        let plane = |f: &dyn Fn(usize, usize) -> u64| {
            let w = g[0] + 1;
            let mut p = vec![0u64; w * (g[1] + 1)];
            for ic in 0..g[1] {
                for is in 0..g[0] {
                    p[(ic + 1) * w + is + 1] =
                        f(is, ic) + p[ic * w + is + 1] + p[(ic + 1) * w + is] - p[ic * w + is];
                }
            }
            p
        };
        let run = |len: usize, f: &dyn Fn(usize) -> u64| {
            std::iter::once(0)
                .chain((0..len).scan(0u64, |sum, i| {
                    *sum += f(i);
                    Some(*sum)
                }))
                .collect::<Vec<u64>>()
        };
        let layers = 0..g[2];
        Self {
            g,
            cubes: layers.clone().map(|k| plane(&|is, ic| map.cell(index(is, ic, k)))).collect(),
            ahead: layers.clone().map(|k| plane(&|is, ic| face(d, k, g[2], index(is, ic, k)))).collect(),
            across_slab: layers
                .clone()
                .map(|k| (0..g[0]).map(|is| run(g[1], &|ic| face(s, is, g[0], index(is, ic, k)))).collect())
                .collect(),
            across_column: layers
                .map(|k| (0..g[1]).map(|ic| run(g[0], &|is| face(c, ic, g[1], index(is, ic, k)))).collect())
                .collect(),
        }
    }

    /// A row over rectangle `r` (`[s0, s1, c0, c1]`): `prefix[k]`, what layers `0..k` cost;
    /// `plane[k]`, what each side of a cut at `k` pays (none at the ends).
    pub(super) fn profile(&self, r: [usize; 4]) -> (Vec<u64>, Vec<u64>) {
        let gd = self.g[2];
        let (mut prefix, mut plane) = (vec![0u64; gd + 1], vec![0u64; gd + 1]);
        self.profile_into(r, &mut prefix, &mut plane);
        (prefix, plane)
    }

    /// [`Self::profile`] written into `prefix` and `plane` (as long as the
    /// driving axis has planes, one more than its layers), for a caller that
    /// profiles many rectangles: the floor's table, 279 000 of them.
    pub(super) fn profile_into(&self, r: [usize; 4], prefix: &mut [u64], plane: &mut [u64]) {
        let [gs, _, gd] = self.g;
        (prefix[0], plane[0], plane[gd]) = (0, 0, 0);
        for k in 0..gd {
            prefix[k + 1] = prefix[k] + self.layer(k, r);
            if k + 1 < gd {
                plane[k + 1] = rectangle(&self.ahead[k], gs + 1, r);
            }
        }
    }

    /// What layer `k` of a row over rectangle `r` costs its holder: its cubes
    /// and the crossings of the row's side faces inside the grid.
    fn layer(&self, k: usize, r: [usize; 4]) -> u64 {
        let [gs, gc, _] = self.g;
        let [s0, s1, c0, c1] = r;
        let mut sum = rectangle(&self.cubes[k], gs + 1, r);
        let along = |run: &Vec<u64>, lo: usize, hi: usize| run[hi] - run[lo];
        if s0 > 0 {
            sum += along(&self.across_slab[k][s0 - 1], c0, c1);
        }
        if s1 < gs {
            sum += along(&self.across_slab[k][s1 - 1], c0, c1);
        }
        if c0 > 0 {
            sum += along(&self.across_column[k][c0 - 1], s0, s1);
        }
        if c1 < gc {
            sum += along(&self.across_column[k][c1 - 1], s0, s1);
        }
        sum
    }
}

/// The sum over rectangle `[s0, s1) x [c0, c1)` from 2-D running sums `p`
/// of row width `w`.
fn rectangle(p: &[u64], w: usize, [s0, s1, c0, c1]: [usize; 4]) -> u64 {
    p[c1 * w + s1] + p[c0 * w + s0] - p[c0 * w + s1] - p[c1 * w + s0]
}

#[cfg(test)]
mod tests {
    use super::BoxSums;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn a_box_sums_what_its_cubes_hold(
            (grid, values, lo, hi) in (1u16..=5, 1u16..=5, 1u16..=5).prop_flat_map(|(x, y, z)| {
                let n = usize::from(x * y * z);
                (
                    Just([x, y, z]),
                    prop::collection::vec(0u64..1 << 40, n),
                    (0..=x, 0..=y, 0..=z),
                    (0..=x, 0..=y, 0..=z),
                )
            })
        ) {
            let (lo, hi) = ([lo.0, lo.1, lo.2].map(usize::from), [hi.0, hi.1, hi.2].map(usize::from));
            let n = grid.map(usize::from);
            let mut walked = 0u64;
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        walked += values[x + n[0] * (y + n[1] * z)];
                    }
                }
            }
            prop_assert_eq!(BoxSums::new(grid, &values).sum(lo, hi), walked);
        }
    }
}
