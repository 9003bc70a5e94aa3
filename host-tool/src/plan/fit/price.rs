//! What each node pays under a cost map, every boundary crossing charged
//! hop by hop as the nodes route it.

use node_fw::CubeBox;
use node_fw::link::Port;

use super::sums::MapSums;
use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

/// Which face of a node's box, across an axis: the ray crossing it leaves
/// the box upward or downward.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Upper,
    Lower,
}

impl Partition {
    /// Every node's cost under `map`, rays routed as the nodes route them
    /// ([`node_fw::route`]): a ray leaving a node across a non-driving axis
    /// goes to the neighbour at the same place along the driving axis, which
    /// forwards it along that axis to the owner, every node on the way paying
    /// both sides of a hop.
    pub fn node_costs(&self, map: &CostMap) -> Vec<u64> {
        self.node_costs_summed(map, &MapSums::new(map))
    }

    /// [`Self::node_costs`] with `map`'s sums made once for many partitions.
    ///
    /// Every crossing lies on one face of the box it leaves: a node pays its
    /// cubes, and each face of its box inside the grid charges the rays
    /// leaving through it. Where the neighbour across the face holds the cube
    /// beyond, a ray takes one hop ([`node_fw::route::toward`] sends it
    /// across the face, as the cube is inside the box on the other two axes),
    /// so that part of the face is one sum; only the rest is routed a cube
    /// at a time.
    pub(super) fn node_costs_summed(&self, map: &CostMap, sums: &MapSums) -> Vec<u64> {
        let boxes: Vec<CubeBox> = (0..self.len()).map(|id| self.bounds(id)).collect();
        let mut cost: Vec<u64> = boxes.iter().map(|b| sums.cells.sum(lo(b), hi(b))).collect();
        for id in 0..boxes.len() {
            for axis in 0..3 {
                for side in [Side::Upper, Side::Lower] {
                    self.charge_face(map, sums, &boxes, &mut cost, (id, axis, side));
                }
            }
        }
        cost
    }

    /// Charges the rays leaving node `id`'s box across its `side` face along
    /// `axis`: upward, each face cube's [`CostMap::up`]; downward, the cube
    /// beyond's [`CostMap::down`] (both are kept at the lower cube).
    fn charge_face(
        &self,
        map: &CostMap,
        sums: &MapSums,
        boxes: &[CubeBox],
        cost: &mut [u64],
        (id, axis, side): (usize, usize, Side),
    ) {
        let b = &boxes[id];
        let (lo, hi) = (lo(b), hi(b));
        let upward = side == Side::Upper;
        if (upward && hi[axis] >= usize::from(map.grid[axis])) || (!upward && lo[axis] == 0) {
            return;
        }
        // The layer of cubes whose entries the face charges: the lower side.
        let layer = if upward { hi[axis] - 1 } else { lo[axis] - 1 };
        let charges = if upward { &map.up[axis] } else { &map.down[axis] };
        let mut one_hop = ([0; 3], [0; 3]);
        if let Some(n) = self.face_neighbour(id, axis, upward) {
            let m = &boxes[n];
            let meets = if upward { m.lo[axis] == b.hi[axis] } else { m.hi[axis] == b.lo[axis] };
            if meets {
                let (mut l, mut h) = (lo, hi);
                for a in (0..3).filter(|&a| a != axis) {
                    (l[a], h[a]) = (lo[a].max(usize::from(m.lo[a])), hi[a].min(usize::from(m.hi[a])));
                }
                (l[axis], h[axis]) = (layer, layer + 1);
                let sum = if upward { sums.up[axis].sum(l, h) } else { sums.down[axis].sum(l, h) };
                cost[id] += sum;
                cost[n] += sum;
                one_hop = (l, h);
            }
        }
        let whole = (0..3).all(|a| a == axis || (one_hop.0[a] == lo[a] && one_hop.1[a] == hi[a]));
        if whole {
            return;
        }
        let [e1, e2] = [(axis + 1) % 3, (axis + 2) % 3];
        let n = map.grid.map(usize::from);
        for u in lo[e1]..hi[e1] {
            for v in lo[e2]..hi[e2] {
                let mut at = [0usize; 3];
                (at[axis], at[e1], at[e2]) = (layer, u, v);
                if (0..3).all(|a| at[a] >= one_hop.0[a] && at[a] < one_hop.1[a]) {
                    continue;
                }
                let i = at[0] + n[0] * (at[1] + n[1] * at[2]);
                let mut beyond = at.map(|c| c as i32);
                if upward {
                    beyond[axis] += 1;
                }
                self.charge_route(boxes, cost, id, beyond, charges[i]);
            }
        }
    }

    /// The node across node `id`'s `upward` (or lower) face along `axis`.
    fn face_neighbour(&self, id: usize, axis: usize, upward: bool) -> Option<usize> {
        let mut c = self.coord(id);
        c[axis] = if upward { c[axis].checked_add(1)? } else { c[axis].checked_sub(1)? };
        node_fw::wiring::index_of(c, self.array).map(usize::from)
    }

    /// Charges `per_side` to both ends of every hop of a ray leaving node
    /// `from` for `cell`, each hop where that node's box sends it
    /// ([`node_fw::route::toward`], the nodes' own rule).
    fn charge_route(&self, boxes: &[CubeBox], cost: &mut [u64], from: usize, cell: [i32; 3], per_side: u64) {
        let d = usize::from(self.driving_axis);
        let [ax, ay, _] = self.array.map(usize::from);
        let stride = [1, ax, ax * ay];
        let mut at = from;
        // Every hop moves toward the owner, so a route is shorter than the array;
        // and `cell` is in the grid, so there is a neighbour that way.
        for _ in 0..self.len() {
            let Some(port) = node_fw::route::toward(&boxes[at], cell, d) else { break };
            let axis = port.axis().unwrap_or(0);
            let id = if port == Port::toward(axis, true) { at + stride[axis] } else { at - stride[axis] };
            cost[at] += per_side;
            cost[id] += per_side;
            at = id;
        }
    }
}

fn lo(b: &CubeBox) -> [usize; 3] {
    b.lo.map(usize::from)
}

fn hi(b: &CubeBox) -> [usize; 3] {
    b.hi.map(usize::from)
}

#[cfg(test)]
mod tests {
    use node_fw::CubeBox;
    use proptest::prelude::*;

    use crate::plan::cost_map::CostMap;
    use crate::plan::partition::Partition;

    /// Every node's cost found the plain way: each pair of neighbouring
    /// cubes of two owners charged hop by hop, with owners, boxes and routes
    /// worked out here ([`node_fw::route::toward`], the nodes' rule).
    fn walked(p: &Partition, map: &CostMap) -> Vec<u64> {
        let n = map.grid.map(usize::from);
        let boxes: Vec<CubeBox> = (0..p.len()).map(|id| p.bounds(id)).collect();
        let owner = |c: [usize; 3]| {
            let cell = c.map(|v| v as i32);
            boxes.iter().position(|b| node_fw::route::toward(b, cell, 0).is_none()).unwrap()
        };
        let a = p.array.map(usize::from);
        let route = |cost: &mut Vec<u64>, from: usize, cell: [usize; 3], per_side: u64| {
            let mut at = from;
            let target = owner(cell);
            while at != target {
                let port =
                    node_fw::route::toward(&boxes[at], cell.map(|v| v as i32), usize::from(p.driving_axis))
                        .unwrap();
                let axis = port.axis().unwrap();
                let mut c = node_fw::wiring::coord_of(at, p.array).map(usize::from);
                if port == node_fw::link::Port::toward(axis, true) {
                    c[axis] += 1
                } else {
                    c[axis] -= 1
                }
                let next = c[0] + a[0] * (c[1] + a[1] * c[2]);
                cost[at] += per_side;
                cost[next] += per_side;
                at = next;
            }
        };
        let mut cost = vec![0u64; p.len()];
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let i = x + n[0] * (y + n[1] * z);
                    let here = owner([x, y, z]);
                    cost[here] += map.cell(i);
                    for ax in 0..3 {
                        let mut up = [x, y, z];
                        up[ax] += 1;
                        if up[ax] < n[ax] && owner(up) != here {
                            route(&mut cost, here, up, map.up[ax][i]);
                            route(&mut cost, owner(up), [x, y, z], map.down[ax][i]);
                        }
                    }
                }
            }
        }
        cost
    }

    /// Cuts of `len` cubes into `parts` non-empty parts, from `seed`.
    fn cuts(len: u16, parts: u16, seed: &[u16]) -> Vec<u16> {
        let mut c = vec![0u16];
        for i in 1..parts {
            let least = c[usize::from(i) - 1] + 1;
            let most = len - (parts - i);
            let pick = seed.get(usize::from(i)).copied().unwrap_or(0) % (most - least + 1);
            c.push(least + pick);
        }
        c.push(len);
        c
    }

    proptest! {
        #[test]
        fn node_costs_by_sums_agree_with_walking_every_face(
            grid in prop::array::uniform3(2u16..=6),
            array in prop::array::uniform3(1u16..=3),
            d in 0u8..3,
            seeds in prop::collection::vec(prop::collection::vec(0u16..100, 4), 40),
            values in prop::collection::vec(0u64..1000, 1..=200),
            staggered in (any::<bool>(), any::<bool>()),
        ) {
            prop_assume!((0..3).all(|a| array[a] <= grid[a]));
            let mut p = Partition::even(grid, array, d).unwrap();
            let mut seed = seeds.iter().cycle();
            for a in 0..3 {
                p.cuts[a] = cuts(grid[a], array[a], seed.next().unwrap());
            }
            let [s, c] = p.routed_axes();
            if staggered.0 {
                p.slab_cuts = Some((0..array[s]).map(|_| cuts(grid[c], array[c], seed.next().unwrap())).collect());
            }
            let du = usize::from(d);
            if staggered.1 {
                let rows = p.len() / usize::from(array[du]);
                p.row_cuts = Some((0..rows).map(|_| cuts(grid[du], array[du], seed.next().unwrap())).collect());
            }
            let mut map = CostMap::new(grid);
            let mut v = values.iter().cycle().copied();
            for i in 0..map.compute.len() {
                map.compute[i] = v.next().unwrap();
                map.messages[i] = v.next().unwrap() / 3;
                for a in 0..3 {
                    map.up[a][i] = v.next().unwrap();
                    map.down[a][i] = v.next().unwrap() / 2;
                }
            }
            prop_assert_eq!(p.node_costs(&map), walked(&p, &map));
        }
    }
}
