//! The static partition: subregion boxes, sub-image tiles, the eye's node, and a
//! capacity check before anything is sent.

use link_proto::{Assign, Boundaries, Capacity, SphereMsg};
use node_fw::{CubeBox, Grid, Sphere};

use crate::error::{HostError, input};
use crate::scene::Scene;

/// How the grid is split over an X x Y x Z array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Partition {
    /// Nodes per axis.
    pub array: [u16; 3],
    /// Cut positions per axis: `cuts[a][i]..cuts[a][i + 1]` is node row `i`.
    pub cuts: [Vec<u16>; 3],
    /// Driving axis of the sliding boundaries.
    pub driving_axis: u8,
    /// Per node row (index over the two other axes, the first fastest), cuts
    /// along the driving axis that replace `cuts[driving_axis]` (staggered
    /// boundaries, as after sliding or from an oracle).
    pub row_cuts: Option<Vec<Vec<u16>>>,
    /// Per slab of nodes across the first routed axis ([`Self::routed_axes`]),
    /// cuts along the second that replace its `cuts` (beyond the paper: the
    /// columns of a fitted partition need not line up from slab to slab).
    pub slab_cuts: Option<Vec<Vec<u16>>>,
}

impl Partition {
    /// Even cuts of `grid` over `array`.
    pub fn even(grid: [u16; 3], array: [u16; 3], driving_axis: u8) -> Result<Self, HostError> {
        for a in 0..3 {
            if array[a] == 0 {
                return Err(input(format!("array {array:?} needs at least one node per axis")));
            }
            if array[a] > grid[a] {
                return Err(HostError::ArrayTooLarge(format!(
                    "array {}x{}x{} is larger than the grid {}x{}x{}: each node needs at least one cube per axis",
                    array[0], array[1], array[2], grid[0], grid[1], grid[2]
                )));
            }
        }
        let cuts = std::array::from_fn(|a| {
            (0..=array[a]).map(|i| (u32::from(i) * u32::from(grid[a]) / u32::from(array[a])) as u16).collect()
        });
        Ok(Self { array, cuts, driving_axis, row_cuts: None, slab_cuts: None })
    }

    /// The row of node coordinate `c` (index over the non-driving axes).
    pub fn row_of(&self, c: [u16; 3]) -> usize {
        let [a0, a1] = self.row_axes();
        usize::from(c[a0]) + usize::from(self.array[a0]) * usize::from(c[a1])
    }

    /// The two axes across the driving axis, lower first: a row's index runs
    /// over the first fastest.
    pub fn row_axes(&self) -> [usize; 2] {
        let d = usize::from(self.driving_axis);
        if d == 0 {
            [1, 2]
        } else if d == 1 {
            [0, 2]
        } else {
            [0, 1]
        }
    }

    /// The two axes across the driving axis in the order the nodes route
    /// rays along them ([`node_fw::route`]): planes across the first are
    /// whole; across the second, whole within each slab of the first.
    pub fn routed_axes(&self) -> [usize; 2] {
        let d = usize::from(self.driving_axis);
        [(d + 1) % 3, (d + 2) % 3]
    }

    /// The cuts along `axis` of the nodes sharing node coordinate `c`'s slab
    /// (across the first routed axis) and row (along the driving axis).
    pub fn cuts_at(&self, axis: usize, c: [u16; 3]) -> &[u16] {
        let d = usize::from(self.driving_axis);
        let [slab_axis, column_axis] = self.routed_axes();
        match (&self.row_cuts, &self.slab_cuts) {
            (Some(rows), _) if axis == d => &rows[self.row_of(c)],
            (_, Some(slabs)) if axis == column_axis => &slabs[usize::from(c[slab_axis])],
            _ => &self.cuts[axis],
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.array.iter().map(|&n| usize::from(n)).product()
    }

    /// Whether the partition has no node.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Array coordinate of node `id` (x fastest).
    pub fn coord(&self, id: usize) -> [u16; 3] {
        node_fw::wiring::coord_of(id, self.array)
    }

    /// How many neighbours node `id` has in the array.
    pub fn neighbours(&self, id: usize) -> usize {
        let c = self.coord(id);
        (0..3).map(|a| usize::from(c[a] > 0) + usize::from(c[a] + 1 < self.array[a])).sum()
    }

    /// The box of node `id`.
    pub fn bounds(&self, id: usize) -> CubeBox {
        let c = self.coord(id);
        let span = |a: usize| {
            let (cuts, i) = (self.cuts_at(a, c), usize::from(c[a]));
            (cuts[i], cuts[i + 1])
        };
        let spans: [(u16, u16); 3] = std::array::from_fn(span);
        CubeBox { lo: spans.map(|s| s.0), hi: spans.map(|s| s.1) }
    }

    /// Whether node `id` needs `sphere` sent: the node keeps it (its surface
    /// meets a cube of the node's box, by the node's own test), or the node
    /// must see it to refuse it (it is not a valid sphere of `grid`). Sending
    /// a node only these leaves it holding exactly what the whole scene would
    /// leave it, for a fraction of the messages on a large array.
    pub fn needs(&self, id: usize, sphere: &SphereMsg, grid: &Grid) -> bool {
        match Sphere::from_msg(sphere, grid) {
            Ok(s) if s.within(grid) => {
                let mut meets = false;
                self.bounds(id).for_each_surface_cube(&s, |_| meets = true);
                meets
            }
            _ => true,
        }
    }

    /// How many of `scene`'s spheres node `id` is sent ([`Self::needs`]).
    pub fn spheres_sent(&self, id: usize, scene: &Scene) -> usize {
        let Ok(grid) = Grid::new(scene.grid) else { return scene.spheres.len() };
        scene.sphere_msgs().iter().filter(|s| self.needs(id, s, &grid)).count()
    }

    /// The assignment message of node `id`.
    pub fn assign(&self, id: usize) -> Assign {
        let b = self.bounds(id);
        Assign {
            array: self.array,
            coord: self.coord(id),
            lo: b.lo,
            hi: b.hi,
            driving_axis: self.driving_axis,
            boundaries: self.boundaries(),
        }
    }

    /// How far the boxes' boundaries line up: the least kind this partition
    /// needs.
    pub fn boundaries(&self) -> Boundaries {
        if self.slab_cuts.is_some() {
            Boundaries::StaggeredColumns
        } else if self.row_cuts.is_some() {
            Boundaries::StaggeredRows
        } else {
            Boundaries::Whole
        }
    }

    /// The node whose box holds `p` (clamped into the grid first): found in
    /// routing order, each axis's cuts known once the earlier ones are.
    pub fn owner_of(&self, p: [f64; 3], grid: [u16; 3]) -> usize {
        let cell: [u16; 3] = std::array::from_fn(|a| p[a].floor().clamp(0.0, f64::from(grid[a] - 1)) as u16);
        let [slab_axis, column_axis] = self.routed_axes();
        let mut c = [0u16; 3];
        for a in [slab_axis, column_axis, usize::from(self.driving_axis)] {
            let at = self.cuts_at(a, c).windows(2).position(|w| cell[a] >= w[0] && cell[a] < w[1]);
            c[a] = at.unwrap_or(0) as u16;
        }
        usize::from(c[0])
            + usize::from(self.array[0])
                * (usize::from(c[1]) + usize::from(self.array[1]) * usize::from(c[2]))
    }

    /// Checks that every node can hold its part of the scene; the error names
    /// the first node that cannot, and by how much.
    pub fn check_capacity(&self, scene: &Scene, capacity: Capacity) -> Result<(), HostError> {
        let grid = Grid::new(scene.grid).map_err(|e| input(format!("grid: {e:?}")))?;
        let spheres: Vec<Sphere> = scene
            .sphere_msgs()
            .iter()
            .map(|m| Sphere::from_msg(m, &grid).map_err(|e| input(format!("sphere {}: {e:?}", m.id))))
            .collect::<Result<_, _>>()?;
        for id in 0..self.len() {
            let b = self.bounds(id);
            let cubes = b.volume();
            let (mut kept, mut refs) = (0u64, 0u64);
            for s in &spheres {
                let mut n = 0u64;
                b.for_each_surface_cube(s, |_| n += 1);
                if n > 0 {
                    kept += 1;
                }
                refs += n;
            }
            let c = self.coord(id);
            let name = format!("node {id} ({},{},{})", c[0], c[1], c[2]);
            if cubes > u64::from(capacity.cubes) {
                return Err(HostError::Capacity(format!(
                    "{name} would span {cubes} cubes; a node holds {}: use more nodes (--array) or fewer \
                     cubes (--grid)",
                    capacity.cubes
                )));
            }
            if kept > u64::from(capacity.spheres) {
                return Err(HostError::Capacity(format!(
                    "{name} would hold {kept} spheres; a node holds {}: use more nodes (--array)",
                    capacity.spheres
                )));
            }
            if refs > u64::from(capacity.refs) {
                return Err(HostError::Capacity(format!(
                    "{name} would hold {refs} sphere references; a node holds {}: use more nodes (--array) \
                     or larger cubes (a coarser --grid)",
                    capacity.refs
                )));
            }
        }
        Ok(())
    }
}

/// The paper's driving axis: the one along which the sphere counts of the
/// node layers vary most (coefficient of variation; ties to the lowest axis).
pub fn driving_axis(scene: &Scene, array: [u16; 3]) -> Result<u8, HostError> {
    let mut best = (0u8, f64::NEG_INFINITY);
    for axis in 0..3u8 {
        let even = Partition::even(scene.grid, array, axis)?;
        let layers = usize::from(array[usize::from(axis)]);
        let mut counts = vec![0f64; layers];
        for s in &scene.spheres {
            // A sphere counts in every layer its bounding interval reaches.
            let a = usize::from(axis);
            for (i, w) in even.cuts[a].windows(2).enumerate() {
                if s.center[a] + s.radius >= f64::from(w[0]) && s.center[a] - s.radius <= f64::from(w[1]) {
                    counts[i] += 1.0;
                }
            }
        }
        let mean = counts.iter().sum::<f64>() / layers as f64;
        let var = counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / layers as f64;
        let cv = if mean > 0.0 { var.sqrt() / mean } else { 0.0 };
        if cv > best.1 + 1e-12 {
            best = (axis, cv);
        }
    }
    Ok(best.0)
}

/// The axis most aligned with the camera's view direction: rays enter on the
/// face toward the eye, so work falls off along it even when sphere counts are
/// alike on every axis (a refinement beyond the paper).
pub fn view_axis(scene: &Scene) -> u8 {
    let c = scene.camera();
    let f = crate::scene::sub(c.look_at, c.eye);
    (0..3u8).max_by(|&a, &b| f[usize::from(a)].abs().total_cmp(&f[usize::from(b)].abs())).unwrap_or(0)
}

/// Splits a `width` x `height` image into `n` tiles `[x0, y0, x1, y1)`, one per
/// node: a grid of tiles as close to square as `n` allows.
pub fn tiles(width: u16, height: u16, n: usize) -> Vec<[u16; 4]> {
    let aspect = f64::from(width) / f64::from(height);
    let cols = (1..=n)
        .filter(|&c| n.is_multiple_of(c))
        .min_by(|&a, &b| {
            let score = |c: usize| ((c as f64 / (n / c) as f64) / aspect).ln().abs();
            score(a).total_cmp(&score(b))
        })
        .unwrap_or(1);
    let rows = n / cols;
    let split = |len: u16, parts: usize, i: usize| (u32::from(len) * i as u32 / parts as u32) as u16;
    (0..n)
        .map(|i| {
            let (cx, cy) = (i % cols, i / cols);
            [
                split(width, cols, cx),
                split(height, rows, cy),
                split(width, cols, cx + 1),
                split(height, rows, cy + 1),
            ]
        })
        .collect()
}
