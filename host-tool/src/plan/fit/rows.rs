//! Rows of nodes along the driving axis: what each layer of cubes and each
//! cut costs a row, and the exact cut of rows by dynamic programming.

use std::collections::HashMap;

use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

use super::floor;
use super::sums::LayerSums;

impl Partition {
    /// Per row of nodes along the driving axis, what it pays before it is cut
    /// along that axis: its cubes and the crossings of its side faces. Any
    /// cut only adds to it.
    pub fn row_loads(&self, map: &CostMap) -> Vec<u64> {
        let parts = usize::from(self.array[usize::from(self.driving_axis)]);
        let sums = LayerSums::new(map, self.driving_axis);
        (0..self.len() / parts).map(|row| self.row_profile(&sums, row).layers.iter().sum()).collect()
    }

    /// The cubes along `axis` (one across the driving axis) that row `row`
    /// (in [`Self::row_of`] order) spans.
    pub fn row_span(&self, row: usize, axis: usize) -> (u16, u16) {
        let [a0, a1] = self.row_axes();
        let mut node = [0u16; 3];
        node[a0] = (row % usize::from(self.array[a0])) as u16;
        node[a1] = (row / usize::from(self.array[a0])) as u16;
        let cuts = self.cuts_at(axis, node);
        (cuts[usize::from(node[axis])], cuts[usize::from(node[axis]) + 1])
    }

    /// One row of nodes (in [`Self::row_of`] order) as the map sees it, with
    /// the planes across the driving axis whole: per layer of cubes across
    /// the driving axis, its cubes and its crossings of the row's side faces;
    /// per plane `k` between layers `k - 1` and `k`, what each side of a cut
    /// there pays (`0` at the row's ends).
    pub(super) fn row_profile(&self, sums: &LayerSums, row: usize) -> RowProfile {
        let [s, c] = self.routed_axes();
        let ((s0, s1), (c0, c1)) = (self.row_span(row, s), self.row_span(row, c));
        let (prefix, planes) = sums.profile([s0, s1, c0, c1].map(usize::from));
        RowProfile { layers: prefix.windows(2).map(|w| w[1] - w[0]).collect(), planes }
    }
}

/// Rows already profiled and cut on their own, by the rectangle they span
/// across the driving axis: a row's profile and its own cuts depend on
/// nothing else, and the local search moves one plane at a time, so most
/// rows of a candidate were met before.
#[derive(Debug, Default)]
pub(super) struct RowCache {
    rows: HashMap<[u16; 4], (RowProfile, Vec<u16>)>,
}

impl RowCache {
    /// Every row of `p` in [`Partition::row_of`] order: its profile under
    /// `sums` (along `p`'s driving axis), and its own cuts.
    pub(super) fn rows(&mut self, p: &Partition, sums: &LayerSums) -> (Vec<RowProfile>, Vec<Vec<u16>>) {
        let parts = usize::from(p.array[usize::from(p.driving_axis)]);
        let [a0, a1] = p.row_axes();
        (0..p.len() / parts.max(1))
            .map(|row| {
                let ((lo0, hi0), (lo1, hi1)) = (p.row_span(row, a0), p.row_span(row, a1));
                let (profile, cuts) = self.rows.entry([lo0, hi0, lo1, hi1]).or_insert_with(|| {
                    let profile = p.row_profile(sums, row);
                    let cuts = row_cuts(std::slice::from_ref(&profile), parts);
                    (profile, cuts)
                });
                (profile.clone(), cuts.clone())
            })
            .unzip()
    }
}

/// One row of nodes along the driving axis, as a cost map sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RowProfile {
    /// Per layer of cubes across the driving axis, what its holder pays.
    pub layers: Vec<u64>,
    /// Per plane `k` between layers `k - 1` and `k`, what each side of a cut
    /// there pays; the row's ends (`0` and `layers.len()`) are never charged.
    pub planes: Vec<u64>,
}

impl RowProfile {
    /// What each side of a cut at plane `k` pays (nothing at the row's ends).
    fn plane(&self, k: usize) -> u64 {
        if k == 0 || k == self.layers.len() { 0 } else { self.planes.get(k).copied().unwrap_or(0) }
    }
}

/// Cuts `0 = c_0 < ... < c_parts = n` shared by `rows` (of `n` layers each)
/// minimising the busiest part of any row: exact, by dynamic programming over
/// (parts, end layer). Every part keeps at least one layer.
pub fn row_cuts(rows: &[RowProfile], parts: usize) -> Vec<u16> {
    let n = rows.first().map_or(0, |r| r.layers.len());
    let parts = parts.clamp(1, n.max(1));
    // cost[i * (n + 1) + j]: what the part of layers i..j pays in the
    // busiest row, by running sums, tabled once (the search asks for each
    // span many times), a row at a time into buffers made once: the local
    // search tables this for every candidate, and the inner loop over j
    // then runs along contiguous memory.
    let mut cost = vec![0u64; (n + 1) * (n + 1)];
    let (mut sums, mut plane) = (vec![0u64; n + 1], vec![0u64; n + 1]);
    for r in rows {
        for k in 0..n {
            sums[k + 1] = sums[k] + r.layers[k];
        }
        for (k, p) in plane.iter_mut().enumerate() {
            *p = r.plane(k);
        }
        for i in 0..n {
            let (start, from) = (sums[i], plane[i]);
            let row = &mut cost[i * (n + 1) + i + 1..(i + 1) * (n + 1)];
            for ((c, &s), &p) in row.iter_mut().zip(&sums[i + 1..]).zip(&plane[i + 1..]) {
                *c = (*c).max(s - start + from + p);
            }
        }
    }
    floor::least_busiest(n, parts, |i, j| cost[i * (n + 1) + j]).1
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::super::sums::LayerSums;
    use super::super::testing::partitions_and_maps;
    use super::RowProfile;
    use crate::plan::cost_map::CostMap;
    use crate::plan::partition::Partition;

    /// A row's profile found the plain way, a cube at a time.
    fn walked(p: &Partition, map: &CostMap, row: usize) -> RowProfile {
        let d = usize::from(p.driving_axis);
        let [a0, a1] = p.row_axes();
        let n = usize::from(map.grid[d]);
        let (mut layers, mut planes) = (vec![0u64; n], vec![0u64; n + 1]);
        let ((lo0, hi0), (lo1, hi1)) = (p.row_span(row, a0), p.row_span(row, a1));
        let at = |c0: u16, c1: u16, k: usize| {
            let mut cell = [0i32; 3];
            (cell[a0], cell[a1], cell[d]) = (i32::from(c0), i32::from(c1), k as i32);
            map.index(cell)
        };
        let face = |a: usize, i: Option<usize>| i.map_or(0, |i| map.face(a, i));
        for c1 in lo1..hi1 {
            for c0 in lo0..hi0 {
                for k in 0..n {
                    let i = at(c0, c1, k);
                    let mut sum = i.map_or(0, |i| map.cell(i));
                    if c0 == lo0 && lo0 > 0 {
                        sum += face(a0, at(c0 - 1, c1, k));
                    }
                    if c0 + 1 == hi0 && hi0 < map.grid[a0] {
                        sum += face(a0, i);
                    }
                    if c1 == lo1 && lo1 > 0 {
                        sum += face(a1, at(c0, c1 - 1, k));
                    }
                    if c1 + 1 == hi1 && hi1 < map.grid[a1] {
                        sum += face(a1, i);
                    }
                    layers[k] += sum;
                    if k + 1 < n {
                        planes[k + 1] += face(d, i);
                    }
                }
            }
        }
        RowProfile { layers, planes }
    }

    proptest! {
        #[test]
        fn row_profiles_by_sums_agree_with_walking_every_cube((p, map) in partitions_and_maps(false)) {
            let sums = LayerSums::new(&map, p.driving_axis);
            let rows = p.len() / usize::from(p.array[usize::from(p.driving_axis)]);
            for row in 0..rows {
                let expected = walked(&p, &map, row);
                prop_assert_eq!(p.row_profile(&sums, row), expected.clone());
                // What the whole row holds, from the layers' sums added up.
                let [s, c] = p.routed_axes();
                let ((s0, s1), (c0, c1)) = (p.row_span(row, s), p.row_span(row, c));
                let held = sums.held([s0, s1, c0, c1].map(usize::from));
                prop_assert_eq!(held, expected.layers.iter().sum::<u64>());
            }
        }
    }
}
