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
    /// The bytes the same rays put on the wires, and what a byte takes there.
    pub wire: WireMap,
}

/// What a frame puts on the wires, by place: a node's CPU may sit idle
/// while its links carry its bytes, so where a byte takes long on the wire
/// a node's time is the longest of its CPU's and each of its wires'.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WireMap {
    /// Per cube: bytes its holder sends the host (the retirements of the
    /// rays ending there).
    pub host: Vec<u64>,
    /// Per axis, per cube: bytes of the rays crossing the face to the cube's
    /// upper neighbour along that axis upward, a hop's.
    pub up: [Vec<u64>; 3],
    /// The same downward.
    pub down: [Vec<u64>; 3],
    /// Cycles a byte takes on each wire: none leaves the wires unpriced.
    pub cycles: WireCycles,
}

/// Cycles a byte takes on the wire (ten bits at the baud rate), on a
/// neighbour link and on the host link; zero where it is not priced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WireCycles {
    /// On a link between neighbours.
    pub neighbour: u64,
    /// On a node's link to the host.
    pub host: u64,
}

impl WireCycles {
    /// The wires the in-memory board models as `link` and `host`.
    pub fn of(link: &sim_board::LinkSpec, host: &sim_board::LinkSpec) -> Self {
        Self { neighbour: link.model().byte, host: host.model().byte }
    }

    /// Whether any wire is priced.
    pub fn priced(&self) -> bool {
        self.neighbour > 0 || self.host > 0
    }
}

impl CostMap {
    /// An empty map of `grid`.
    pub fn new(grid: [u16; 3]) -> Self {
        let cubes = grid.iter().map(|&n| usize::from(n)).product();
        let zeros = || std::array::from_fn(|_| vec![0; cubes]);
        let wire =
            WireMap { host: vec![0; cubes], up: zeros(), down: zeros(), cycles: WireCycles::default() };
        Self { grid, compute: vec![0; cubes], messages: vec![0; cubes], up: zeros(), down: zeros(), wire }
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

    /// Charges `bytes` on the host link to `cell`'s holder (nothing outside the grid).
    pub fn add_host_bytes(&mut self, cell: [i32; 3], bytes: u64) {
        if let Some(i) = self.index(cell) {
            self.wire.host[i] += bytes;
        }
    }

    /// Charges `cycles` per side, and `bytes` on the wire, to the face a ray
    /// crosses stepping from `from` to the face-adjacent `to`.
    pub fn add_crossing(&mut self, from: [i32; 3], to: [i32; 3], cycles: u64, bytes: u64) {
        let Some(axis) = (0..3).find(|&a| from[a] != to[a]) else { return };
        let upward = from[axis] < to[axis];
        let Some(i) = self.index(if upward { from } else { to }) else { return };
        let (faces, wires) =
            if upward { (&mut self.up, &mut self.wire.up) } else { (&mut self.down, &mut self.wire.down) };
        faces[axis][i] += cycles;
        wires[axis][i] += bytes;
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
        m.add_crossing([1, 1, 1], [2, 1, 1], 100, 40);
        m.add_crossing([2, 1, 1], [1, 1, 1], 100, 30);
        // A crossing between two cubes inside the box costs the node nothing.
        m.add_crossing([0, 1, 1], [1, 1, 1], 1000, 40);
        // Outside the grid: ignored.
        m.add_compute([4, 0, 0], 1);
        let b = CubeBox { lo: [0, 0, 0], hi: [2, 2, 2] };
        assert_eq!(m.node_cost(&b), 15 + 200);
        let right = CubeBox { lo: [2, 0, 0], hi: [4, 4, 4] };
        assert_eq!(m.node_cost(&right), 7 + 200);
        // The whole grid has no inner face.
        assert_eq!(m.node_cost(&CubeBox { lo: [0; 3], hi: [4; 3] }), 22);
    }

    #[test]
    fn a_crossing_puts_its_bytes_on_the_face_it_crosses_each_way_apart() {
        let mut m = CostMap::new([4, 4, 4]);
        m.add_crossing([1, 1, 1], [2, 1, 1], 100, 40);
        m.add_crossing([2, 1, 1], [1, 1, 1], 100, 30);
        m.add_crossing([1, 2, 1], [1, 1, 1], 100, 7);
        m.add_host_bytes([3, 0, 0], 12);
        m.add_host_bytes([4, 0, 0], 99);
        let at = |c: [i32; 3]| m.index(c).unwrap();
        assert_eq!(m.wire.up[0][at([1, 1, 1])], 40);
        assert_eq!(m.wire.down[0][at([1, 1, 1])], 30);
        // Kept at the lower cube of the face, downward.
        assert_eq!(m.wire.down[1][at([1, 1, 1])], 7);
        assert_eq!(m.wire.host[at([3, 0, 0])], 12);
        let total = |v: &[u64]| v.iter().sum::<u64>();
        assert_eq!(total(&m.wire.host), 12, "outside the grid: nothing");
        assert_eq!((0..3).map(|a| total(&m.wire.up[a]) + total(&m.wire.down[a])).sum::<u64>(), 77);
    }
}
