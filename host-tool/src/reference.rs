//! An independent floating-point renderer (glam): the same Whitted model,
//! brute-force over all spheres, no grid walk, no fixed point. Only surfaces
//! inside the grid box exist, as for the array. The f64 instance is the
//! reference; the f32 instance is the floating-point baseline of `report numerics`.

use std::cell::Cell;

use glam::{DVec3, Vec3};

use crate::plan::camera::PixelBasis;
use crate::results::image::to_srgb8;
use crate::scene::{Scene, SphereDesc};

/// A pixel's first hit in the reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefHit {
    /// Sphere id.
    pub sphere: u16,
    /// Distance along the unit primary direction.
    pub t: f64,
    /// How far the primary ray passes from the hit sphere's silhouette
    /// (`r - closest approach`, cubes): small means a grazing hit.
    pub margin: f64,
    /// Depth gap to the next sphere along the ray (infinite if none).
    pub gap: f64,
}

/// A reference render.
#[derive(Debug, Clone)]
pub struct RefImage {
    /// Linear colour per pixel (1.0 = full).
    pub color: Vec<DVec3>,
    /// Primary hit per pixel.
    pub hits: Vec<Option<RefHit>>,
    /// Rays traced (primary, shadow and reflection).
    pub rays: u64,
}

impl RefImage {
    /// 8-bit sRGB, through the same mapping as the array's frame buffer.
    pub fn rgb8(&self) -> Vec<u8> {
        rgb8_of(&self.color)
    }
}

/// Linear colours as 8-bit sRGB, through the same mapping as the array's
/// frame buffer.
pub fn rgb8_of(colors: &[DVec3]) -> Vec<u8> {
    colors
        .iter()
        .flat_map(|c| c.to_array().map(|v| to_srgb8((v * 32768.0).max(0.0).round() as u64)))
        .collect()
}

/// The reference image of `scene` at `size` with `side` x `side` samples a
/// pixel on the array's regular grid, as linear colours (each pixel the mean
/// of its samples).
pub fn render_sampled(scene: &Scene, size: [u16; 2], side: u16) -> Vec<DVec3> {
    let [w, h] = size.map(|n| n * side);
    let img = render(scene, w, h);
    crate::results::image::block_means(&img.color, w, h, side)
}

/// The renderer for one float type (`$v` a glam vector of `$f`).
macro_rules! renderer {
    ($name:ident, $v:ty, $f:ty) => {
        mod $name {
            use super::*;

            fn v3(a: [f64; 3]) -> $v {
                <$v>::new(a[0] as $f, a[1] as $f, a[2] as $f)
            }

            pub(super) struct World<'a> {
                pub(super) scene: &'a Scene,
                pub(super) grid: $v,
                pub(super) rays: Cell<u64>,
                /// Per unit cube (x fastest), the spheres whose bounding
                /// box meets it: a grid walk; `None`: every sphere per ray.
                pub(super) cells: Option<Vec<Vec<u16>>>,
            }

            /// Each cube's spheres, by bounding box.
            pub(super) fn cells(scene: &Scene) -> Vec<Vec<u16>> {
                let [gx, gy, gz] = scene.grid.map(usize::from);
                let mut cells = vec![Vec::new(); gx * gy * gz];
                for (i, s) in scene.spheres.iter().enumerate() {
                    let range = |a: usize, n: usize| {
                        let lo = (s.center[a] - s.radius).floor().max(0.0) as usize;
                        let hi = ((s.center[a] + s.radius).floor().max(0.0) as usize).min(n - 1);
                        lo.min(n - 1)..=hi
                    };
                    for z in range(2, gz) {
                        for y in range(1, gy) {
                            for x in range(0, gx) {
                                cells[(z * gy + y) * gx + x].push(i as u16);
                            }
                        }
                    }
                }
                cells
            }

            /// Hit at t >= 0 (entry from outside, exit from inside), as the firmware defines it.
            pub(super) fn intersect(o: $v, d: $v, s: &SphereDesc) -> Option<($f, bool)> {
                let r = s.radius as $f;
                let f = o - v3(s.center);
                let (a, b, c) = (d.dot(d), f.dot(d), f.dot(f) - r * r);
                let disc = r * r * a - f.cross(d).length_squared();
                if disc < 0.0 {
                    return None;
                }
                let sq = disc.sqrt();
                if c > 0.0 {
                    (b < 0.0).then(|| (c / (sq - b), false))
                } else if c == 0.0 {
                    (b < 0.0).then_some((0.0, false))
                } else if b < 0.0 {
                    Some(((sq - b) / a, true))
                } else {
                    Some((c / -(b + sq), true))
                }
            }

            impl World<'_> {
                /// Nearest hit at t > 0 whose point lies in the grid box, skipping `ignore`.
                pub(super) fn hit(
                    &self,
                    o: $v,
                    d: $v,
                    ignore: Option<usize>,
                    t_max: $f,
                ) -> Option<($f, usize, bool)> {
                    match &self.cells {
                        None => {
                            self.nearest(o, d, ignore, t_max, 0..self.scene.spheres.len(), <$f>::INFINITY)
                        }
                        Some(cells) => self.walk(cells, o, d, ignore, t_max),
                    }
                }

                /// Nearest hit among `spheres` at t < min(`t_max`, `until`)
                /// whose point lies in the grid box.
                fn nearest(
                    &self,
                    o: $v,
                    d: $v,
                    ignore: Option<usize>,
                    t_max: $f,
                    spheres: impl Iterator<Item = usize>,
                    until: $f,
                ) -> Option<($f, usize, bool)> {
                    let mut best: Option<($f, usize, bool)> = None;
                    for i in spheres {
                        if Some(i) == ignore {
                            continue;
                        }
                        let Some((t, inside)) = intersect(o, d, &self.scene.spheres[i]) else { continue };
                        let p = o + d * t;
                        let in_grid = p.cmpge(<$v>::ZERO).all() && p.cmple(self.grid).all();
                        if t < t_max && t <= until && in_grid && best.is_none_or(|b| t < b.0) {
                            best = Some((t, i, inside));
                        }
                    }
                    best
                }

                /// The nearest hit by walking the cubes along the ray
                /// (Amanatides and Woo), testing each cube's spheres: the
                /// traversal the nodes do, in floating point.
                fn walk(
                    &self,
                    cells: &[Vec<u16>],
                    o: $v,
                    d: $v,
                    ignore: Option<usize>,
                    t_max: $f,
                ) -> Option<($f, usize, bool)> {
                    let g = self.grid.to_array();
                    let (o, d) = (o.to_array(), d.to_array());
                    let (mut t0, mut t1): ($f, $f) = (0.0, <$f>::INFINITY);
                    for a in 0..3 {
                        if d[a] == 0.0 {
                            if o[a] < 0.0 || o[a] > g[a] {
                                return None;
                            }
                            continue;
                        }
                        let (ta, tb) = ((0.0 - o[a]) / d[a], (g[a] - o[a]) / d[a]);
                        t0 = t0.max(ta.min(tb));
                        t1 = t1.min(ta.max(tb));
                    }
                    if t0 > t1 || t0 >= t_max {
                        return None;
                    }
                    let dims = self.scene.grid.map(i64::from);
                    let mut cell = [0i64; 3];
                    let (mut next, mut delta, mut step) =
                        ([<$f>::INFINITY; 3], [<$f>::INFINITY; 3], [0i64; 3]);
                    for a in 0..3 {
                        let p = o[a] + d[a] * t0;
                        cell[a] = (p.floor() as i64).clamp(0, dims[a] - 1);
                        if d[a] > 0.0 {
                            step[a] = 1;
                            delta[a] = 1.0 / d[a];
                            next[a] = ((cell[a] + 1) as $f - o[a]) / d[a];
                        } else if d[a] < 0.0 {
                            step[a] = -1;
                            delta[a] = -1.0 / d[a];
                            next[a] = (cell[a] as $f - o[a]) / d[a];
                        }
                    }
                    let (ov, dv) = (<$v>::from_array(o), <$v>::from_array(d));
                    loop {
                        let exit = next[0].min(next[1]).min(next[2]);
                        let index = ((cell[2] * dims[1] + cell[1]) * dims[0] + cell[0]) as usize;
                        let spheres = cells.get(index).map_or(&[][..], |c| c.as_slice());
                        let here = spheres.iter().map(|&i| usize::from(i));
                        if let Some(hit) = self.nearest(ov, dv, ignore, t_max, here, exit) {
                            return Some(hit);
                        }
                        if exit >= t_max || exit > t1 {
                            return None;
                        }
                        let a = if next[0] <= next[1] && next[0] <= next[2] {
                            0
                        } else if next[1] <= next[2] {
                            1
                        } else {
                            2
                        };
                        cell[a] += step[a];
                        if cell[a] < 0 || cell[a] >= dims[a] {
                            return None;
                        }
                        next[a] += delta[a];
                    }
                }

                pub(super) fn trace(&self, o: $v, d: $v, weight: $v, depth: u8, ignore: Option<usize>) -> $v {
                    self.rays.set(self.rays.get() + 1);
                    let Some((t, i, inside)) = self.hit(o, d, ignore, <$f>::INFINITY) else {
                        return weight * v3(self.scene.background);
                    };
                    let s = &self.scene.spheres[i];
                    let p = o + d * t;
                    let mut n = (p - v3(s.center)).normalize();
                    if inside {
                        n = -n;
                    }
                    let color = v3(s.color);
                    let mut out = weight * s.ambient as $f * color * v3(self.scene.ambient);
                    if inside {
                        return out;
                    }
                    for l in &self.scene.lights {
                        let to = v3(l.position) - p;
                        let dist = to.length();
                        let ldir = to / dist;
                        let ndl = n.dot(ldir);
                        if ndl <= 0.0 {
                            continue;
                        }
                        self.rays.set(self.rays.get() + 1);
                        if self.hit(p, ldir, Some(i), dist).is_some() {
                            continue;
                        }
                        let r = 2.0 * ndl * n - ldir;
                        let spec = if s.specular > 0.0 {
                            s.specular as $f * r.dot(-d).max(0.0).powi(i32::from(s.shininess))
                        } else {
                            0.0
                        };
                        out += weight * (s.diffuse as $f * ndl * color + <$v>::splat(spec)) * v3(l.color);
                    }
                    if s.reflect > 0.0 && depth < self.scene.max_depth {
                        let r = (d - 2.0 * d.dot(n) * n).normalize();
                        out += self.trace(p, r, weight * s.reflect as $f, depth + 1, Some(i));
                    }
                    out
                }
            }

            /// Renders `scene` at `width` x `height`, walking the grid's
            /// cubes with `walk`, else testing every sphere per ray.
            pub(super) fn render(scene: &Scene, width: u16, height: u16, walk: bool) -> RefImage {
                let grid = v3(scene.grid.map(f64::from));
                let world = World { scene, grid, rays: Cell::new(0), cells: walk.then(|| cells(scene)) };
                let basis = PixelBasis::new(&scene.camera(), width, height);
                let eye = v3(basis.eye);
                let pixels = usize::from(width) * usize::from(height);
                let mut img =
                    RefImage { color: Vec::with_capacity(pixels), hits: Vec::with_capacity(pixels), rays: 0 };
                for y in 0..height {
                    for x in 0..width {
                        let (fx, fy) = (x as $f, y as $f);
                        let d = (v3(basis.corner) + fx * v3(basis.du) + fy * v3(basis.dv)).normalize();
                        let c = world.trace(eye, d, <$v>::ONE, 0, None);
                        img.color.push(DVec3::new(f64::from(c.x), f64::from(c.y), f64::from(c.z)));
                        let hit = world.hit(eye, d, None, <$f>::INFINITY).map(|(t, i, _)| {
                            let gap = scene
                                .spheres
                                .iter()
                                .enumerate()
                                .filter(|(j, _)| *j != i)
                                .filter_map(|(_, o)| {
                                    intersect(eye, d, o).map(|(u, _)| f64::from((u - t).abs()))
                                })
                                .fold(f64::INFINITY, f64::min);
                            let f = eye - v3(scene.spheres[i].center);
                            let margin = scene.spheres[i].radius - f64::from(f.cross(d).length());
                            RefHit { sphere: i as u16, t: f64::from(t), margin, gap }
                        });
                        img.hits.push(hit);
                    }
                }
                img.rays = world.rays.get();
                img
            }
        }
    };
}

renderer!(in_f64, DVec3, f64);
renderer!(in_f32, Vec3, f32);

/// Renders `scene` at `width` x `height` in f64: the reference.
pub fn render(scene: &Scene, width: u16, height: u16) -> RefImage {
    in_f64::render(scene, width, height, false)
}

/// Renders `scene` at `width` x `height` in f32, every sphere tested per ray.
pub fn render_f32(scene: &Scene, width: u16, height: u16) -> RefImage {
    in_f32::render(scene, width, height, false)
}

/// Renders `scene` at `width` x `height` in f32 walking the grid's cubes, as
/// the nodes do: the floating-point baseline on equal terms.
pub fn render_f32_walked(scene: &Scene, width: u16, height: u16) -> RefImage {
    in_f32::render(scene, width, height, true)
}

/// [`render_f32_walked`] in f64, for checking the walk against [`render`].
pub fn render_walked(scene: &Scene, width: u16, height: u16) -> RefImage {
    in_f64::render(scene, width, height, true)
}

/// `r - distance from the centre to the line` (positive inside the silhouette).
pub fn silhouette_margin(o: DVec3, d: DVec3, s: &SphereDesc) -> f64 {
    let f = o - DVec3::from_array(s.center);
    s.radius - f.cross(d).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walking_the_cubes_finds_what_testing_every_sphere_finds() {
        for (seed, grid) in [(1, [12, 12, 12]), (2, [16, 9, 7])] {
            let scene = Scene::random(60, seed, 0.5, grid).unwrap();
            let (all, walked) = (render(&scene, 40, 32), render_walked(&scene, 40, 32));
            let same_hit =
                all.hits.iter().zip(&walked.hits).filter(|(a, b)| a.map(|h| h.sphere) == b.map(|h| h.sphere));
            assert_eq!(same_hit.count(), all.hits.len(), "seed {seed}: a primary hit differs");
            let near =
                all.color.iter().zip(&walked.color).filter(|(a, b)| (**a - **b).abs().max_element() < 1e-9);
            assert_eq!(near.count(), all.color.len(), "seed {seed}: a colour differs");
            // The same ray tree.
            assert_eq!(all.rays, walked.rays);
        }
    }
}
