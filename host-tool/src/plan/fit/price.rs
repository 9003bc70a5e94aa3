//! What each node pays under a cost map, every boundary crossing charged
//! hop by hop as the nodes route it.

use node_fw::CubeBox;
use node_fw::link::Port;

use crate::plan::cost_map::CostMap;
use crate::plan::partition::Partition;

impl Partition {
    /// Every node's cost under `map`, rays routed as the nodes route them
    /// ([`node_fw::route`]): a ray leaving a node across a non-driving axis
    /// goes to the neighbour at the same place along the driving axis, which
    /// forwards it along that axis to the owner, every node on the way paying
    /// both sides of a hop.
    pub fn node_costs(&self, map: &CostMap) -> Vec<u64> {
        let owner = self.owners(map.grid);
        let boxes: Vec<_> = (0..self.len()).map(|id| self.bounds(id)).collect();
        let mut cost = vec![0u64; self.len()];
        for (i, &o) in owner.iter().enumerate() {
            cost[o] += map.cell(i);
        }
        let n = map.grid.map(usize::from);
        let stride = [1, n[0], n[0] * n[1]];
        let mut i = 0;
        for z in 0..n[2] {
            for y in 0..n[1] {
                for x in 0..n[0] {
                    let cell = [x, y, z];
                    let lo = owner[i];
                    for a in (0..3).filter(|&a| cell[a] + 1 < n[a]) {
                        let hi = owner[i + stride[a]];
                        if lo != hi {
                            let mut above = cell.map(|c| c as i32);
                            above[a] += 1;
                            self.charge_route(&boxes, &mut cost, lo, above, map.up[a][i]);
                            self.charge_route(&boxes, &mut cost, hi, cell.map(|c| c as i32), map.down[a][i]);
                        }
                    }
                    i += 1;
                }
            }
        }
        cost
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

    /// The node holding each cube (x fastest).
    fn owners(&self, grid: [u16; 3]) -> Vec<usize> {
        let [nx, ny, _] = grid.map(usize::from);
        let mut owner = vec![0; grid.iter().map(|&n| usize::from(n)).product()];
        for id in 0..self.len() {
            let b = self.bounds(id);
            for z in b.lo[2]..b.hi[2] {
                for y in b.lo[1]..b.hi[1] {
                    for x in b.lo[0]..b.hi[0] {
                        owner[usize::from(x) + nx * (usize::from(y) + ny * usize::from(z))] = id;
                    }
                }
            }
        }
        owner
    }
}
