//! Where a frame's work falls: per unit cube, and per face between two cubes.
//!
//! On the array most of a node's time goes to messages, not to walking cubes:
//! a ray crossing a node boundary costs each side tens of cube steps. So a
//! partition fitted to compute alone balances the small part of the load. The
//! map keeps both: what a cube costs whoever holds it, and what the rays
//! crossing each face would cost the two nodes if a boundary lay there.

use node_fw::CubeBox;

/// Cycles of one frame under the board's cost model, by place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CostMap {
    /// Cubes per axis.
    pub grid: [u16; 3],
    /// Per cube (x fastest): walking, sphere tests, shading and ray creation.
    pub compute: Vec<u64>,
    /// Per cube: messages its holder handles whatever the partition (the
    /// retirement of each ray ending there; an initial ray received there).
    pub messages: Vec<u64>,
    /// Per axis, per cube: what each side pays for the rays crossing the face
    /// to the cube's upper neighbour along that axis upward, were a boundary
    /// there.
    pub up: [Vec<u64>; 3],
    /// The same for the rays crossing that face downward. The directions are
    /// kept apart because a ray forwarded to its owner passes through nodes
    /// that depend on where it comes from.
    pub down: [Vec<u64>; 3],
}

impl CostMap {
    /// An empty map of `grid`.
    pub fn new(grid: [u16; 3]) -> Self {
        let cubes = grid.iter().map(|&n| usize::from(n)).product();
        let zeros = || std::array::from_fn(|_| vec![0; cubes]);
        Self { grid, compute: vec![0; cubes], messages: vec![0; cubes], up: zeros(), down: zeros() }
    }

    /// The index of `cell`, or `None` outside the grid.
    pub fn index(&self, cell: [i32; 3]) -> Option<usize> {
        let inside = (0..3).all(|a| cell[a] >= 0 && cell[a] < i32::from(self.grid[a]));
        let [nx, ny, _] = self.grid.map(usize::from);
        inside.then(|| cell[0] as usize + nx * (cell[1] as usize + ny * cell[2] as usize))
    }

    /// Charges `cycles` of compute to `cell` (nothing outside the grid).
    pub fn add_compute(&mut self, cell: [i32; 3], cycles: u64) {
        if let Some(i) = self.index(cell) {
            self.compute[i] += cycles;
        }
    }

    /// Charges `cycles` of messages to `cell` (nothing outside the grid).
    pub fn add_message(&mut self, cell: [i32; 3], cycles: u64) {
        if let Some(i) = self.index(cell) {
            self.messages[i] += cycles;
        }
    }

    /// Charges `cycles` per side to the face a ray crosses stepping from
    /// `from` to the face-adjacent `to`.
    pub fn add_crossing(&mut self, from: [i32; 3], to: [i32; 3], cycles: u64) {
        let Some(axis) = (0..3).find(|&a| from[a] != to[a]) else { return };
        let upward = from[axis] < to[axis];
        let Some(i) = self.index(if upward { from } else { to }) else { return };
        let faces = if upward { &mut self.up } else { &mut self.down };
        faces[axis][i] += cycles;
    }

    /// What each side pays for the rays crossing, either way, the face
    /// between cube `i` and its upper neighbour along `axis`.
    pub fn face(&self, axis: usize, i: usize) -> u64 {
        self.up[axis][i] + self.down[axis][i]
    }

    /// What a cube costs its holder before any boundary: compute and messages.
    pub fn cell(&self, i: usize) -> u64 {
        self.compute[i] + self.messages[i]
    }

    /// Every cube's [`Self::cell`] cost (x fastest).
    pub fn cells(&self) -> Vec<u64> {
        (0..self.compute.len()).map(|i| self.cell(i)).collect()
    }

    /// What the node holding `b` would pay if each face of `b` bordered one
    /// node (no ray forwarded through it): its cubes, and the crossings of
    /// every face of `b` inside the grid.
    pub fn node_cost(&self, b: &CubeBox) -> u64 {
        let mut sum = 0u64;
        for z in b.lo[2]..b.hi[2] {
            for y in b.lo[1]..b.hi[1] {
                for x in b.lo[0]..b.hi[0] {
                    let cell = [x, y, z].map(i32::from);
                    let Some(i) = self.index(cell) else { continue };
                    sum += self.cell(i);
                    for a in 0..3 {
                        // The face below this cube, if it is b's and not the grid's.
                        if cell[a] == i32::from(b.lo[a]) && b.lo[a] > 0 {
                            let mut below = cell;
                            below[a] -= 1;
                            sum += self.index(below).map_or(0, |j| self.face(a, j));
                        }
                        if cell[a] + 1 == i32::from(b.hi[a]) && b.hi[a] < self.grid[a] {
                            sum += self.face(a, i);
                        }
                    }
                }
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_pays_its_cubes_and_the_crossings_of_its_inner_faces() {
        let mut m = CostMap::new([4, 4, 4]);
        m.add_compute([1, 1, 1], 10);
        m.add_message([1, 1, 1], 5);
        m.add_compute([3, 3, 3], 7);
        // A ray stepping +x from (1,1,1) into (2,1,1), and one stepping back.
        m.add_crossing([1, 1, 1], [2, 1, 1], 100);
        m.add_crossing([2, 1, 1], [1, 1, 1], 100);
        // A crossing between two cubes inside the box costs the node nothing.
        m.add_crossing([0, 1, 1], [1, 1, 1], 1000);
        // Outside the grid: ignored.
        m.add_compute([4, 0, 0], 1);
        let b = CubeBox { lo: [0, 0, 0], hi: [2, 2, 2] };
        assert_eq!(m.node_cost(&b), 15 + 200);
        let right = CubeBox { lo: [2, 0, 0], hi: [4, 4, 4] };
        assert_eq!(m.node_cost(&right), 7 + 200);
        // The whole grid has no inner face.
        assert_eq!(m.node_cost(&CubeBox { lo: [0; 3], hi: [4; 3] }), 22);
    }
}
