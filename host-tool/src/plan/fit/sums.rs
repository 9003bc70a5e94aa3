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

/// Running sums of two values per cube over every box from the grid's
/// origin: `at[(x, y, z)]` is the sum over the cubes below `x`, `y` and `z`.
/// Two, because the fit prices each box twice over, in cycles and in bytes:
/// side by side, one box's eight corners are read once for both.
#[derive(Debug, Clone)]
pub struct BoxSums {
    /// Cubes per axis, plus one.
    side: [usize; 3],
    at: Vec<[u64; 2]>,
}

impl BoxSums {
    /// The running sums of `first` and `second` (each x fastest; `second`
    /// zero where it is empty) over a grid of `grid` cubes.
    pub fn new(grid: [u16; 3], first: &[u64], second: &[u64]) -> Self {
        let n = grid.map(usize::from);
        let side = n.map(|k| k + 1);
        let mut at = vec![[0u64; 2]; side.iter().product()];
        let index = |x: usize, y: usize, z: usize| x + side[0] * (y + side[1] * z);
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let i = x + n[0] * (y + n[1] * z);
                    let v = [first[i], second.get(i).copied().unwrap_or(0)];
                    let s = std::array::from_fn(|k| {
                        // Inclusion-exclusion; wrapping, because a partial sum
                        // of the terms may dip below zero although the result
                        // cannot.
                        v[k].wrapping_add(at[index(x, y + 1, z + 1)][k])
                            .wrapping_add(at[index(x + 1, y, z + 1)][k])
                            .wrapping_add(at[index(x + 1, y + 1, z)][k])
                            .wrapping_sub(at[index(x, y, z + 1)][k])
                            .wrapping_sub(at[index(x, y + 1, z)][k])
                            .wrapping_sub(at[index(x + 1, y, z)][k])
                            .wrapping_add(at[index(x, y, z)][k])
                    });
                    at[index(x + 1, y + 1, z + 1)] = s;
                }
            }
        }
        Self { side, at }
    }

    /// The sums over the cubes `lo <= c < hi` (empty if any `hi <= lo`).
    pub fn sum(&self, lo: [usize; 3], hi: [usize; 3]) -> [u64; 2] {
        if (0..3).any(|a| hi[a] <= lo[a]) {
            return [0; 2];
        }
        let (sy, sz) = (self.side[0], self.side[0] * self.side[1]);
        let (x, y, z) = ([lo[0], hi[0]], [lo[1] * sy, hi[1] * sy], [lo[2] * sz, hi[2] * sz]);
        let at = |i: usize, j: usize, k: usize| self.at[x[i] + y[j] + z[k]];
        let ([a, b, c, d], [e, f, g, h]) = (
            [at(1, 1, 1), at(0, 0, 1), at(0, 1, 0), at(1, 0, 0)],
            [at(0, 1, 1), at(1, 0, 1), at(1, 1, 0), at(0, 0, 0)],
        );
        std::array::from_fn(|k| {
            a[k].wrapping_add(b[k])
                .wrapping_add(c[k])
                .wrapping_add(d[k])
                .wrapping_sub(e[k])
                .wrapping_sub(f[k])
                .wrapping_sub(g[k])
                .wrapping_sub(h[k])
        })
    }
}

/// The running sums of everything a [`CostMap`] charges, each beside the
/// bytes it puts on a wire ([`crate::plan::cost_map::WireMap`]).
#[derive(Debug, Clone)]
pub struct MapSums {
    /// Per cube: [`CostMap::cell`], and the bytes to the host.
    pub cells: BoxSums,
    /// Per axis: [`CostMap::up`], and the bytes crossing upward.
    pub up: [BoxSums; 3],
    /// Per axis: [`CostMap::down`], and the bytes crossing downward.
    pub down: [BoxSums; 3],
    /// What a byte takes on each wire, where the wires are priced (else
    /// the bytes are left out: zero).
    pub wire: Option<WireCycles>,
}

impl MapSums {
    /// The sums of `map`.
    pub fn new(map: &CostMap) -> Self {
        let g = map.grid;
        let w = &map.wire;
        let wire = w.cycles.priced().then_some(w.cycles);
        let sums = |v: &[u64], b: &[u64]| BoxSums::new(g, v, if wire.is_some() { b } else { &[] });
        Self {
            cells: sums(&map.cells(), &w.host),
            up: std::array::from_fn(|a| sums(&map.up[a], &w.up[a])),
            down: std::array::from_fn(|a| sums(&map.down[a], &w.down[a])),
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
    /// What each layer's cubes and side faces cost, the layers innermost:
    /// a rectangle's profile reads a run of layers at each of its corners
    /// (the floor profiles 279 000 rectangles; a layer at a time, its reads
    /// were scattered over every layer's table).
    layers: Planes,
    /// The layers' sums added up: what a whole row holds.
    all: Planes,
    /// Per layer, 2-D running sums of the faces to the next layer, as
    /// [`Planes::cubes`].
    ahead: Vec<u64>,
}

/// Running sums over the slab and column axes, `depth` values an entry:
/// one a layer, or one for all the layers added up (every sum is linear in
/// the costs).
struct Planes {
    depth: usize,
    /// 2-D running sums of the cubes' costs: entry `c * (g[0] + 1) + s`,
    /// one past each.
    cubes: Vec<u64>,
    /// Per plane across the slab axis (between `s` and `s + 1`), running
    /// sums along the column axis: entry `s * (g[1] + 1) + c`.
    across_slab: Vec<u64>,
    /// Per plane across the column axis, running sums along the slab axis:
    /// entry `c * (g[0] + 1) + s`.
    across_column: Vec<u64>,
}

impl Planes {
    /// Writes into `out` (`depth` long) what a row over rectangle `r` pays
    /// at each depth: its cubes and the crossings of the row's side faces
    /// inside the grid (`gs` and `gc` cubes across).
    fn cost_into(&self, [gs, gc]: [usize; 2], r: [usize; 4], out: &mut [u64]) {
        let [s0, s1, c0, c1] = r;
        rectangle_into(&self.cubes, self.depth, gs + 1, r, out);
        let mut along = |table: &[u64], lo: usize, hi: usize| {
            let (lo, hi) = (&table[lo * self.depth..], &table[hi * self.depth..]);
            for ((o, &h), &l) in out.iter_mut().zip(hi).zip(lo) {
                *o += h - l;
            }
        };
        let (slab, column) = (gc + 1, gs + 1);
        if s0 > 0 {
            along(&self.across_slab, (s0 - 1) * slab + c0, (s0 - 1) * slab + c1);
        }
        if s1 < gs {
            along(&self.across_slab, (s1 - 1) * slab + c0, (s1 - 1) * slab + c1);
        }
        if c0 > 0 {
            along(&self.across_column, (c0 - 1) * column + s0, (c0 - 1) * column + s1);
        }
        if c1 < gc {
            along(&self.across_column, (c1 - 1) * column + s0, (c1 - 1) * column + s1);
        }
    }

    /// The same sums with every entry's values added up.
    fn added_up(&self) -> Self {
        let add = |t: &[u64]| t.chunks(self.depth.max(1)).map(|c| c.iter().sum()).collect();
        Self {
            depth: 1,
            cubes: add(&self.cubes),
            across_slab: add(&self.across_slab),
            across_column: add(&self.across_column),
        }
    }
}

impl LayerSums {
    /// The sums of `map` for rows along `driving_axis`.
    pub(super) fn new(map: &CostMap, driving_axis: u8) -> Self {
        let d = usize::from(driving_axis);
        let [s, c] = [(d + 1) % 3, (d + 2) % 3];
        let grid = map.grid.map(usize::from);
        let g = [grid[s], grid[c], grid[d]];
        let (w, gd) = (g[0] + 1, g[2]);
        let index = |is: usize, ic: usize, k: usize| {
            let mut cell = [0usize; 3];
            (cell[s], cell[c], cell[d]) = (is, ic, k);
            cell[0] + grid[0] * (cell[1] + grid[1] * cell[2])
        };
        let face = |axis: usize, at: usize, limit: usize, i: usize| {
            if at + 1 < limit { map.face(axis, i) } else { 0 }
        };
        // 2-D running sums, every layer's at once.
        let plane = |f: &dyn Fn(usize, usize, usize) -> u64| {
            let mut p = vec![0u64; w * (g[1] + 1) * gd];
            for ic in 0..g[1] {
                for is in 0..g[0] {
                    for k in 0..gd {
                        let at = |c: usize, s: usize| (c * w + s) * gd + k;
                        p[at(ic + 1, is + 1)] =
                            f(is, ic, k) + p[at(ic, is + 1)] + p[at(ic + 1, is)] - p[at(ic, is)];
                    }
                }
            }
            p
        };
        // Per plane `i` of `planes`, running sums of `len` faces, every layer's.
        let runs = |planes: usize, len: usize, f: &dyn Fn(usize, usize, usize) -> u64| {
            let mut r = vec![0u64; planes * (len + 1) * gd];
            for i in 0..planes {
                for j in 0..len {
                    for k in 0..gd {
                        let at = |j: usize| (i * (len + 1) + j) * gd + k;
                        r[at(j + 1)] = r[at(j)] + f(i, j, k);
                    }
                }
            }
            r
        };
        let layers = Planes {
            depth: gd,
            cubes: plane(&|is, ic, k| map.cell(index(is, ic, k))),
            across_slab: runs(g[0], g[1], &|is, ic, k| face(s, is, g[0], index(is, ic, k))),
            across_column: runs(g[1], g[0], &|ic, is, k| face(c, ic, g[1], index(is, ic, k))),
        };
        Self {
            g,
            all: layers.added_up(),
            layers,
            ahead: plane(&|is, ic, k| face(d, k, gd, index(is, ic, k))),
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
        let [gs, gc, gd] = self.g;
        // Each layer's cost, then their running sum.
        prefix[0] = 0;
        self.layers.cost_into([gs, gc], r, &mut prefix[1..=gd]);
        for k in 1..=gd {
            prefix[k] += prefix[k - 1];
        }
        // The faces ahead of the last layer leave the grid: none.
        rectangle_into(&self.ahead, gd, gs + 1, r, &mut plane[1..=gd]);
        (plane[0], plane[gd]) = (0, 0);
    }

    /// What a row over rectangle `r` holds in all its layers: the last of
    /// [`Self::profile`]'s prefix, in a few additions instead of a pass
    /// over the layers.
    pub(super) fn held(&self, r: [usize; 4]) -> u64 {
        let mut held = [0];
        self.all.cost_into([self.g[0], self.g[1]], r, &mut held);
        held[0]
    }
}

/// Writes into `out` the sums over rectangle `[s0, s1) x [c0, c1)` from 2-D
/// running sums `p` of row width `w`, `depth` values an entry.
fn rectangle_into(p: &[u64], depth: usize, w: usize, [s0, s1, c0, c1]: [usize; 4], out: &mut [u64]) {
    let at = |c: usize, s: usize| &p[(c * w + s) * depth..(c * w + s + 1) * depth];
    let (a, b, c, d) = (at(c1, s1), at(c0, s0), at(c0, s1), at(c1, s0));
    for (k, o) in out.iter_mut().enumerate() {
        *o = a[k] + b[k] - c[k] - d[k];
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
            let doubled: Vec<u64> = values.iter().map(|v| v * 2).collect();
            prop_assert_eq!(BoxSums::new(grid, &values, &doubled).sum(lo, hi), [walked, 2 * walked]);
            prop_assert_eq!(BoxSums::new(grid, &values, &[]).sum(lo, hi), [walked, 0]);
        }
    }
}
