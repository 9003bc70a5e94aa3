//! Entry tiles: the sub-images that let initial rays start where they enter.
//!
//! In the paper's parallel mode every node creates the rays of a regular
//! sub-image and passes each one across the array to the node where it
//! enters the scene, so every initial ray costs a message per hop and the
//! nodes on the face toward the eye receive all of them. Beyond the paper,
//! the host can instead give each node on that face the sub-image that
//! enters through its part of the face: rays then start (nearly always) on
//! the node that traces them first. Seen at an angle, the grid also shows
//! the eye a side face or two: the nodes on one of them ([`side_face`]) are
//! given the sub-images that enter through their parts of it, so those rays
//! too start where they enter rather than on the front face, a hop per node
//! between. Which node creates a ray changes nothing in the image; a ray
//! that enters elsewhere (through the other side face, or across a tile's
//! rounded edge) is passed on as in the parallel mode.

use link_proto::CameraMsg;
use node_fw::camera::primary_line;
use node_fw::{DigitalLine, Grid};

use crate::plan::camera::PixelBasis;
use crate::plan::partition::{Partition, tiles};

/// A tile `[x0, y0, x1, y1)` per node for a `size` image: the nodes whose
/// coordinate along `view_axis` is on the eye's side, and those on the side
/// face that creates its own rays ([`side_face`]), get the
/// pixels whose rays enter through their part of the grid's faces, the
/// others none. The tiles cover every pixel once: a column's tile is that of
/// the rays of most of the column, and pixels whose rays miss the grid go
/// with their nearest neighbours. With the eye inside the grid, or no ray
/// entering it, the regular tiles of the parallel mode are returned.
pub fn entry_tiles(
    basis: &PixelBasis,
    grid: [u16; 3],
    partition: &Partition,
    view_axis: usize,
    size: [u16; 2],
) -> Vec<[u16; 4]> {
    let regular = || tiles(size[0], size[1], partition.len());
    let Ok(cubes) = Grid::new(grid) else { return regular() };
    let Some(low) = eye_on_low_side(basis.eye, grid, view_axis) else { return regular() };
    let [w, h] = size.map(usize::from);
    let cells = entry_cells(&basis.msg(), &cubes, size);
    let across = across_axis(basis, view_axis);
    let side = side_face(&cells, basis.eye, grid, view_axis, across);
    // The array coordinate of each pixel's entry node, or None for a miss.
    let coords: Vec<Option<[u16; 3]>> = cells
        .into_iter()
        .map(|cell| Some(partition.coord(partition.owner_of(cell?.map(|c| f64::from(c) + 0.5), grid))))
        .collect();
    if coords.iter().all(Option::is_none) {
        return regular();
    }
    let places = Places::new(partition.array, view_axis, low, across, side);
    let at = |x: usize, y: usize| coords.get(y * w + x).copied().flatten();
    // Bands of image columns by their place across the image, counting rows
    // y0..y1; bands of image rows by their place down it, counting columns x0..x1.
    let col_bands = |y0: usize, y1: usize| {
        bands(w, places.count[0], |x| (y0..y1).filter_map(move |y| at(x, y)).map(|c| places.of_ray(c)[0]))
    };
    let row_bands = |x0: usize, x1: usize| {
        bands(h, places.count[1], |y| (x0..x1).filter_map(move |x| at(x, y)).map(|c| places.of_ray(c)[1]))
    };
    let (cols, rows) = (col_bands(0, h), row_bands(0, w));
    let tiling = |order: Order| {
        let rows_per_col = (order == Order::RowsPerColumn)
            .then(|| cols.iter().map(|&(x0, x1)| row_bands(x0, x1)).collect::<Vec<_>>());
        let cols_per_row = (order == Order::ColumnsPerRow)
            .then(|| rows.iter().map(|&(y0, y1)| col_bands(y0, y1)).collect::<Vec<_>>());
        (0..partition.len())
            .map(|id| {
                let Some([i, j]) = places.of_node(partition.coord(id)) else { return [0; 4] };
                let col = cols_per_row.as_ref().map_or(cols[i], |per| per[j][i]);
                let row = rows_per_col.as_ref().map_or(rows[j], |per| per[i][j]);
                if col.0 == col.1 || row.0 == row.1 {
                    return [0; 4];
                }
                [col.0, row.0, col.1, row.1].map(|v| v as u16)
            })
            .collect::<Vec<_>>()
    };
    // Columns cut per slab: each slab's band of image lines is cut on its own.
    let slab_axis = partition.slab_cuts.as_ref().map(|_| partition.routed_axes()[0]);
    let slab_axis = slab_axis.filter(|_| usize::from(partition.driving_axis) == view_axis);
    let order = match slab_axis {
        Some(a) if a == across => Order::RowsPerColumn,
        Some(a) if a == 3 - view_axis - across => Order::ColumnsPerRow,
        _ => Order::Whole,
    };
    if side.is_none() {
        return tiling(order);
    }
    // Seen at an angle, a node's part of a face is no rectangle in the
    // image, and rows along the view axis may be cut each on its own: of
    // the ways to cut, the one that leaves the most rays at home.
    let mut best = tiling(order);
    let mut most = at_home(&best, partition, &coords, w);
    for other in
        [Order::Whole, Order::RowsPerColumn, Order::ColumnsPerRow].into_iter().filter(|&o| o != order)
    {
        let tiles = tiling(other);
        let home = at_home(&tiles, partition, &coords, w);
        if home > most {
            (best, most) = (tiles, home);
        }
    }
    best
}

/// How many pixels of an image `w` wide `tiles` give to the node their ray
/// enters (`coords`, per pixel, the entry node's array coordinate).
fn at_home(tiles: &[[u16; 4]], partition: &Partition, coords: &[Option<[u16; 3]>], w: usize) -> usize {
    let home = |id: usize, t: &[u16; 4]| {
        let c = Some(partition.coord(id));
        let (xs, ys) = (usize::from(t[0])..usize::from(t[2]), usize::from(t[1])..usize::from(t[3]));
        ys.flat_map(|y| xs.clone().map(move |x| y * w + x))
            .filter(|&i| coords.get(i).copied().flatten() == c)
            .count()
    };
    tiles.iter().enumerate().map(|(id, t)| home(id, t)).sum()
}

/// How entry tiles cut the image: columns and rows each once, or the rows
/// of each band of columns on their own, or the columns of each band of rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Order {
    Whole,
    RowsPerColumn,
    ColumnsPerRow,
}

/// Where each node that creates rays sits in the image: a place across it
/// (a band of columns) and a place down it (a band of rows). One of the two
/// follows the grid's outline ([`Outline`]) along the axis of the side face
/// that creates its own rays, if any; the other is the node's coordinate.
struct Places {
    outline: Outline,
    /// Whether the outline runs down the image (the side face is its top or
    /// bottom) rather than across it.
    down: bool,
    /// The other image axis's array axis.
    plain: usize,
    /// Places across and down.
    count: [u16; 2],
}

impl Places {
    fn new(array: [u16; 3], view_axis: usize, low: bool, across: usize, side: Option<(usize, bool)>) -> Self {
        let other = 3 - view_axis - across;
        let down = side.is_some_and(|(axis, _)| axis == other);
        let (axis, plain) = if down { (other, across) } else { (across, other) };
        let outline = Outline::new(array, view_axis, low, axis, side.map(|(_, low)| low));
        let count = if down { [array[plain], outline.places()] } else { [outline.places(), array[plain]] };
        Self { outline, down, plain, count }
    }

    /// The places of the node that creates the rays entering node `c`.
    fn of_ray(&self, c: [u16; 3]) -> [u16; 2] {
        let (on, plain) = (self.outline.place_of_ray(c), c[self.plain]);
        if self.down { [plain, on] } else { [on, plain] }
    }

    /// The places of node `c`, if it creates rays.
    fn of_node(&self, c: [u16; 3]) -> Option<[usize; 2]> {
        self.outline.place_of_node(c)?;
        Some(self.of_ray(c).map(usize::from))
    }
}

/// The grid's outline along one image axis as the eye sees it, a place per
/// node that creates rays: the nodes of the face toward the eye along the
/// view axis, in order along `axis`, and beyond one end of them the nodes of
/// the side face across `axis` toward the eye, deeper ones further out.
struct Outline {
    array: [u16; 3],
    view_axis: usize,
    /// The front layer's coordinate along the view axis.
    front: u16,
    axis: usize,
    /// Whether the side face toward the eye is the low one along `axis`, if
    /// it creates its own rays.
    side: Option<bool>,
}

impl Outline {
    fn new(array: [u16; 3], view_axis: usize, low: bool, axis: usize, side: Option<bool>) -> Self {
        let front = if low { 0 } else { array[view_axis] - 1 };
        Self { array, view_axis, front, axis, side }
    }

    /// Nodes behind the front layer on the side face: places beyond the front's.
    fn deep(&self) -> u16 {
        if self.side.is_some() { self.array[self.view_axis] - 1 } else { 0 }
    }

    /// How many places.
    fn places(&self) -> u16 {
        self.array[self.axis] + self.deep()
    }

    /// The place of node `c` on the side face toward the eye, counted from
    /// the front, if it lies there behind the front layer.
    fn side_place(&self, c: [u16; 3]) -> Option<usize> {
        let depth = c[self.view_axis].abs_diff(self.front);
        let edge = if self.side? { 0 } else { self.array[self.axis] - 1 };
        (depth > 0 && c[self.axis] == edge).then_some(usize::from(depth))
    }

    /// The place of the node that creates the rays entering node `c`: its
    /// own on the side face, else that of the front node in its line of
    /// nodes along the view axis.
    fn place_of_ray(&self, c: [u16; 3]) -> u16 {
        let front = c[self.axis] + if self.side == Some(true) { self.deep() } else { 0 };
        match (self.side, self.side_place(c)) {
            (Some(true), Some(depth)) => self.deep() - depth as u16,
            (Some(false), Some(depth)) => self.array[self.axis] - 1 + depth as u16,
            _ => front,
        }
    }

    /// The place of node `c`, if it creates rays.
    fn place_of_node(&self, c: [u16; 3]) -> Option<usize> {
        (c[self.view_axis] == self.front || self.side_place(c).is_some())
            .then(|| usize::from(self.place_of_ray(c)))
    }
}

/// The array axis, other than `view_axis`, that runs across `basis`'s image
/// (the one its step to the right moves along more).
pub fn across_axis(basis: &PixelBasis, view_axis: usize) -> usize {
    let others = [(view_axis + 1) % 3, (view_axis + 2) % 3];
    let (a, b) = (others[0].min(others[1]), others[0].max(others[1]));
    if basis.du[b].abs() > basis.du[a].abs() { b } else { a }
}

/// The side face whose nodes entry tiles let create the rays entering it
/// (its axis, and whether it is the low one), for the eye at `eye` looking
/// along `view_axis` with `across` running across the image, and each
/// pixel's entry cube `cells`: the face across `across` toward the eye if
/// any ray enters it, else the one across the third axis (the top or the
/// bottom). A side face runs along one image axis, so only one can be given
/// its own tiles; the cost map asks the same. Where rays enter both, the
/// face across the image is the one to take, though fewer may enter it: on
/// the sphereflake of `lab report tradeoff`, seen from above a corner, its
/// frame took 3.21e6 cycles on 4x4x4 with the side across the image and
/// 3.56e6 with the top, which more rays enter (3.67e6 with neither).
pub fn side_face(
    cells: &[Option<[i32; 3]>],
    eye: [f64; 3],
    grid: [u16; 3],
    view_axis: usize,
    across: usize,
) -> Option<(usize, bool)> {
    let low = eye_on_low_side(eye, grid, view_axis)?;
    let front = layer_of_face(grid, view_axis, low);
    let entered = |axis: usize| {
        let side_low = side_toward_eye(eye, grid, axis)?;
        let edge = layer_of_face(grid, axis, side_low);
        cells.iter().flatten().any(|c| c[axis] == edge && c[view_axis] != front).then_some((axis, side_low))
    };
    entered(across).or_else(|| entered(3 - view_axis - across))
}

/// The layer of cubes along `axis` on the grid's low face, or its high one.
pub fn layer_of_face(grid: [u16; 3], axis: usize, low: bool) -> i32 {
    if low { 0 } else { i32::from(grid[axis]) - 1 }
}

/// Whether the grid's face across `axis` that the eye sees is the low one,
/// or `None` if the eye lies within the grid's extent along `axis` (then no
/// ray enters through either).
fn side_toward_eye(eye: [f64; 3], grid: [u16; 3], axis: usize) -> Option<bool> {
    let g = f64::from(grid[axis]);
    if eye[axis] < 0.0 {
        Some(true)
    } else if eye[axis] > g {
        Some(false)
    } else {
        None
    }
}

/// Where entry tiles create the rays for an eye at `eye`: `None` with the
/// eye inside the grid (the tiles are the regular ones), else whether the
/// grid's face toward the eye along `view_axis` is its low one.
pub fn eye_on_low_side(eye: [f64; 3], grid: [u16; 3], view_axis: usize) -> Option<bool> {
    let g = grid.map(f64::from);
    if (0..3).all(|a| eye[a] > 0.0 && eye[a] < g[a]) {
        return None;
    }
    Some(eye[view_axis] < g[view_axis] / 2.0)
}

/// Per pixel of a `size` image (row by row), the cube where its initial ray
/// enters `grid`, or `None` if it misses: the cube the creating node itself
/// computes, with the same exact arithmetic.
pub fn entry_cells(camera: &CameraMsg, grid: &Grid, size: [u16; 2]) -> Vec<Option<[i32; 3]>> {
    let [w, h] = size.map(usize::from);
    (0..w * h)
        .map(|i| {
            let line = primary_line(camera, (i % w) as u16, (i / w) as u16).ok()?;
            Some(DigitalLine::enter(&line, grid)?.cell())
        })
        .collect()
}

/// Splits `len` image lines (columns or rows) into `n` contiguous bands, one
/// per array coordinate: a line goes to the median coordinate of its rays
/// (`line(i)`), lines without rays to their neighbours' band, and the
/// sequence is made monotone so that every band is one interval.
fn bands<I: Iterator<Item = u16>>(len: usize, n: u16, line: impl Fn(usize) -> I) -> Vec<(usize, usize)> {
    let median = |i: usize| {
        let mut v: Vec<u16> = line(i).collect();
        v.sort_unstable();
        v.get(v.len() / 2).copied()
    };
    let mut class: Vec<Option<u16>> = (0..len).map(median).collect();
    // Lines that see no grid take the class of the nearest line before, or after.
    let mut last = None;
    for c in class.iter_mut() {
        *c = c.or(last);
        last = *c;
    }
    let mut next = None;
    for c in class.iter_mut().rev() {
        *c = c.or(next);
        next = *c;
    }
    let mut class: Vec<u16> = class.into_iter().map(|c| c.unwrap_or(0)).collect();
    let falling = class.first() > class.last();
    if falling {
        class.reverse();
    }
    // Monotone: a line never goes back to an earlier band.
    let mut top = 0;
    for c in class.iter_mut() {
        top = top.max(*c);
        *c = top;
    }
    let mut bands = vec![(0usize, 0usize); usize::from(n)];
    for k in 0..n {
        let start = class.iter().position(|&c| c >= k).unwrap_or(len);
        let end = class.iter().position(|&c| c > k).unwrap_or(len);
        bands[usize::from(k)] = (start, end);
    }
    if falling {
        for b in bands.iter_mut() {
            *b = (len - b.1, len - b.0);
        }
    }
    bands
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// The independent reference: where the f64 ray from `eye` along `d`
    /// enters the box `[0, g]`, nudged inside (slab test).
    fn entry_point(eye: [f64; 3], d: [f64; 3], g: [f64; 3]) -> Option<[f64; 3]> {
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            if d[a] == 0.0 {
                if eye[a] < 0.0 || eye[a] > g[a] {
                    return None;
                }
                continue;
            }
            let (ta, tb) = (-eye[a] / d[a], (g[a] - eye[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        if t0 >= t1 {
            return None;
        }
        let t = t0 + (t1 - t0).min(1e-3) / 2.0;
        Some(std::array::from_fn(|k| eye[k] + t * d[k]))
    }

    /// Every pixel in exactly one tile.
    fn covers_once(tiles: &[[u16; 4]], size: [u16; 2]) -> bool {
        let mut hits = vec![0u8; usize::from(size[0]) * usize::from(size[1])];
        for t in tiles {
            for y in t[1]..t[3] {
                for x in t[0]..t[2] {
                    hits[usize::from(y) * usize::from(size[0]) + usize::from(x)] += 1;
                }
            }
        }
        hits.iter().all(|&n| n == 1)
    }

    /// Columns (along y) cut per slab (along x), none lined up with the next.
    fn jagged(mut p: Partition) -> Partition {
        let (slabs, columns) = (usize::from(p.array[0]), usize::from(p.array[1]));
        let n = *p.cuts[1].last().unwrap();
        let shifted = |s: usize| {
            let mut cuts = p.cuts[1].clone();
            for (i, c) in cuts.iter_mut().enumerate().take(columns).skip(1) {
                *c = (*c + (s + i) as u16 % 3).min(n - (columns - i) as u16);
            }
            cuts
        };
        p.slab_cuts = Some((0..slabs).map(shifted).collect());
        p
    }

    /// Even boxes over a few arrays, and two with columns cut per slab.
    fn even_and_jagged(grid: [u16; 3]) -> Vec<Partition> {
        let even = [[4, 4, 4], [2, 3, 1], [1, 1, 5], [3, 2, 2]].map(|a| Partition::even(grid, a, 2).unwrap());
        let jagged = [[4, 4, 4], [3, 2, 2]].map(|a| jagged(Partition::even(grid, a, 2).unwrap()));
        assert!(jagged.iter().all(|p| p.slab_cuts.as_ref().is_some_and(|s| s[0] != s[1])));
        even.into_iter().chain(jagged).collect()
    }

    #[test]
    fn front_nodes_share_the_image_and_rays_start_on_their_entry_node() {
        let mut scene = Scene::random(10, 1, 1.0, [16; 3]).unwrap();
        let size = [64, 48];
        let partitions = even_and_jagged(scene.grid);
        // Upright, and turned a quarter so that the image's rows run along x.
        for up in [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]] {
            let mut cam = scene.camera();
            cam.up = up;
            scene.camera = Some(cam);
            let basis = PixelBasis::new(&scene.camera(), size[0], size[1]);
            for p in &partitions {
                front_tiles_hold(&scene, &basis, p, size);
            }
        }
    }

    #[test]
    fn seen_at_an_angle_the_side_face_toward_the_eye_creates_its_own_rays() {
        let mut scene = Scene::random(10, 1, 1.0, [16; 3]).unwrap();
        let size = [64, 48];
        let mut staggered = Partition::even(scene.grid, [3, 2, 4], 2).unwrap();
        staggered.row_cuts = Some((0..6).map(|r| vec![0, 2 + r, 6 + r, 9 + r, 16]).collect());
        let partitions: Vec<_> = even_and_jagged(scene.grid).into_iter().chain([staggered]).collect();
        // The default view turned about the vertical through the grid's
        // centre, far enough that the eye is beyond the face x = 0 or x = 16
        // but still looks mostly along z.
        let straight = scene.camera();
        for degrees in [-40.0f64, 35.0] {
            let (s, c) = degrees.to_radians().sin_cos();
            let mut cam = straight;
            let [dx, dz] = [straight.eye[0] - 8.0, straight.eye[2] - 8.0];
            cam.eye = [8.0 + c * dx + s * dz, straight.eye[1], 8.0 - s * dx + c * dz];
            assert!(cam.eye[0] < 0.0 || cam.eye[0] > 16.0, "{:?}", cam.eye);
            scene.camera = Some(cam);
            let basis = PixelBasis::new(&scene.camera(), size[0], size[1]);
            for p in &partitions {
                front_tiles_hold(&scene, &basis, p, size);
            }
        }
    }

    #[test]
    fn seen_from_above_the_top_face_creates_its_own_rays() {
        let mut scene = Scene::random(10, 1, 1.0, [16; 3]).unwrap();
        let size = [48, 64];
        let partitions =
            [[4, 4, 4], [2, 3, 1], [1, 4, 3], [3, 2, 2]].map(|a| Partition::even(scene.grid, a, 2).unwrap());
        // Above the grid (y = 16), still looking mostly along z; and below
        // it, turned a quarter, so that the bottom face runs across the image.
        for (eye, up) in [([8.0, 27.0, -18.0], [0.0, 1.0, 0.0]), ([8.0, -11.0, -18.0], [1.0, 0.0, 0.0])] {
            let mut cam = scene.camera();
            (cam.eye, cam.up) = (eye, up);
            scene.camera = Some(cam);
            let basis = PixelBasis::new(&scene.camera(), size[0], size[1]);
            let cells = entry_cells(&basis.msg(), &Grid::new(scene.grid).unwrap(), size);
            assert_eq!(
                side_face(&cells, basis.eye, scene.grid, 2, across_axis(&basis, 2)),
                Some((1, eye[1] < 0.0))
            );
            for p in &partitions {
                front_tiles_hold(&scene, &basis, p, size);
            }
        }
    }

    /// Every pixel in one tile, only the front layer (z = 0: the eye is at
    /// negative z) and the side face toward the eye creating rays, and most
    /// rays created by the node whose box they enter.
    fn front_tiles_hold(scene: &Scene, basis: &PixelBasis, p: &Partition, size: [u16; 2]) {
        let array = p.array;
        let t = entry_tiles(basis, scene.grid, p, 2, size);
        assert!(covers_once(&t, size), "{array:?}: {t:?}");
        let side = |c: [u16; 3]| {
            (0..2).any(|a| (basis.eye[a] < 0.0 && c[a] == 0) || (basis.eye[a] > 16.0 && c[a] == array[a] - 1))
        };
        for (id, tile) in t.iter().enumerate() {
            let c = p.coord(id);
            if c[2] != 0 && !side(c) {
                assert_eq!(*tile, [0; 4], "{array:?}: node {id}");
            }
        }
        // Independent check: most rays that enter the grid are created by
        // the node whose box they enter.
        let g = scene.grid.map(f64::from);
        let (mut entering, mut at_home) = (0, 0);
        for (id, tile) in t.iter().enumerate() {
            for y in tile[1]..tile[3] {
                for x in tile[0]..tile[2] {
                    let d = std::array::from_fn(|a| {
                        basis.corner[a] + f64::from(x) * basis.du[a] + f64::from(y) * basis.dv[a]
                    });
                    if let Some(e) = entry_point(basis.eye, d, g) {
                        let b = p.bounds(id);
                        let inside = (0..3).all(|a| e[a] >= f64::from(b.lo[a]) && e[a] < f64::from(b.hi[a]));
                        entering += 1;
                        at_home += usize::from(inside);
                    }
                }
            }
        }
        assert!(entering > 0);
        assert!(at_home * 100 >= entering * 95, "{array:?}: {at_home} of {entering} at home");
    }

    #[test]
    fn eye_inside_the_grid_falls_back_to_regular_tiles() {
        let mut scene = Scene::random(10, 1, 1.0, [16; 3]).unwrap();
        let mut cam = scene.camera();
        cam.eye = [8.0, 8.0, 1.0];
        cam.look_at = [8.0, 8.0, 12.0];
        scene.camera = Some(cam);
        let size = [32, 32];
        let basis = PixelBasis::new(&scene.camera(), size[0], size[1]);
        let p = Partition::even(scene.grid, [2, 2, 2], 2).unwrap();
        assert_eq!(entry_tiles(&basis, scene.grid, &p, 2, size), tiles(32, 32, 8));
    }

    #[test]
    fn bands_are_intervals_in_either_direction() {
        let rising = [None, Some(0), Some(0), Some(1), Some(0), Some(2), None];
        let b = bands(7, 3, |i| rising[i].into_iter());
        assert_eq!(b, vec![(0, 3), (3, 5), (5, 7)]);
        let falling = [Some(2), Some(2), Some(1), None, Some(0)];
        let b = bands(5, 3, |i| falling[i].into_iter());
        assert_eq!(b, vec![(4, 5), (2, 4), (0, 2)]);
        // A coordinate no line sees gets an empty band.
        let gap = [Some(0), Some(2)];
        assert_eq!(bands(2, 3, |i| gap[i].into_iter()), vec![(0, 1), (1, 1), (1, 2)]);
    }
}
