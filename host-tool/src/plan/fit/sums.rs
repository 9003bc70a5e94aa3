//! A cost map's running sums, so that the fit prices a box of cubes, or a
//! face of one, in a handful of additions instead of a walk over its cubes.
//!
//! The local search prices thousands of candidate partitions of one map; each
//! used to walk every cube and every face of the grid. With the sums a
//! candidate costs a few lookups a node, and the rays leaving a face a few
//! more for each node they pass (`Partition::node_costs`). The sums are exact
//! integers, so every price is the same as the walk's.

use crate::plan::cost_map::CostMap;

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
    /// Per axis: [`CostMap::face`], both ways.
    pub faces: [BoxSums; 3],
}

impl MapSums {
    /// The sums of `map`.
    pub fn new(map: &CostMap) -> Self {
        let g = map.grid;
        let sums = |v: &[u64]| BoxSums::new(g, v);
        Self {
            cells: sums(&map.cells()),
            up: std::array::from_fn(|a| sums(&map.up[a])),
            down: std::array::from_fn(|a| sums(&map.down[a])),
            faces: std::array::from_fn(|a| {
                sums(&map.up[a].iter().zip(&map.down[a]).map(|(u, d)| u + d).collect::<Vec<_>>())
            }),
        }
    }
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
