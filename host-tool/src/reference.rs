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

impl RefImage {}

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
                    let mut best: Option<($f, usize, bool)> = None;
                    for (i, s) in self.scene.spheres.iter().enumerate() {
                        if Some(i) == ignore {
                            continue;
                        }
                        let Some((t, inside)) = intersect(o, d, s) else { continue };
                        let p = o + d * t;
                        let in_grid = p.cmpge(<$v>::ZERO).all() && p.cmple(self.grid).all();
                        if t < t_max && in_grid && best.is_none_or(|b| t < b.0) {
                            best = Some((t, i, inside));
                        }
                    }
                    best
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

            /// Renders `scene` at `width` x `height`.
            pub(super) fn render(scene: &Scene, width: u16, height: u16) -> RefImage {
                let grid = v3(scene.grid.map(f64::from));
                let world = World { scene, grid, rays: Cell::new(0) };
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
    in_f64::render(scene, width, height)
}

/// Renders `scene` at `width` x `height` in f32: the floating-point baseline.
pub fn render_f32(scene: &Scene, width: u16, height: u16) -> RefImage {
    in_f32::render(scene, width, height)
}

/// `r - distance from the centre to the line` (positive inside the silhouette).
pub fn silhouette_margin(o: DVec3, d: DVec3, s: &SphereDesc) -> f64 {
    let f = o - DVec3::from_array(s.center);
    s.radius - f.cross(d).length()
}
