//! An independent f64 renderer (glam): the same Whitted model, brute-force over
//! all spheres, no grid walk, no fixed point. Only surfaces inside the grid box
//! exist, as for the array.

use glam::DVec3;

use crate::camera::PixelBasis;
use crate::frame::to_srgb8;
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
    /// Primary rays that miss every sphere but pass within `margin` of one's silhouette.
    pub near_miss: Vec<f64>,
}

impl RefImage {
    /// 8-bit sRGB, through the same mapping as the array's frame buffer.
    pub fn rgb8(&self) -> Vec<u8> {
        self.color
            .iter()
            .flat_map(|c| c.to_array().map(|v| to_srgb8((v * 32768.0).max(0.0).round() as u64)))
            .collect()
    }
}

struct World<'a> {
    scene: &'a Scene,
    grid: DVec3,
}

impl World<'_> {
    /// Nearest hit at t > 0 whose point lies in the grid box, skipping `ignore`.
    /// Returns (t, sphere index, origin inside).
    fn hit(&self, o: DVec3, d: DVec3, ignore: Option<usize>, t_max: f64) -> Option<(f64, usize, bool)> {
        let mut best: Option<(f64, usize, bool)> = None;
        for (i, s) in self.scene.spheres.iter().enumerate() {
            if Some(i) == ignore {
                continue;
            }
            let Some((t, inside)) = intersect(o, d, s) else { continue };
            let p = o + d * t;
            let in_grid = p.cmpge(DVec3::ZERO).all() && p.cmple(self.grid).all();
            if t < t_max && in_grid && best.is_none_or(|b| t < b.0) {
                best = Some((t, i, inside));
            }
        }
        best
    }

    fn trace(&self, o: DVec3, d: DVec3, weight: DVec3, depth: u8, ignore: Option<usize>) -> DVec3 {
        let Some((t, i, inside)) = self.hit(o, d, ignore, f64::INFINITY) else {
            return weight * v3(self.scene.background);
        };
        let s = &self.scene.spheres[i];
        let p = o + d * t;
        let mut n = (p - v3(s.center)).normalize();
        if inside {
            n = -n;
        }
        let color = v3(s.color);
        let mut out = weight * s.ambient * color * v3(self.scene.ambient);
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
            if self.hit(p, ldir, Some(i), dist).is_some() {
                continue;
            }
            let r = 2.0 * ndl * n - ldir;
            let spec = if s.specular > 0.0 {
                s.specular * r.dot(-d).max(0.0).powi(i32::from(s.shininess))
            } else {
                0.0
            };
            out += weight * (s.diffuse * ndl * color + DVec3::splat(spec)) * v3(l.color);
        }
        if s.reflect > 0.0 && depth < self.scene.max_depth {
            let r = (d - 2.0 * d.dot(n) * n).normalize();
            out += self.trace(p, r, weight * s.reflect, depth + 1, Some(i));
        }
        out
    }
}

/// Renders `scene` at `width` x `height` in f64.
pub fn render(scene: &Scene, width: u16, height: u16) -> RefImage {
    let world = World { scene, grid: DVec3::from_array(scene.grid.map(f64::from)) };
    let basis = PixelBasis::new(&scene.camera(), width, height);
    let eye = v3(basis.eye);
    let pixels = usize::from(width) * usize::from(height);
    let mut img = RefImage {
        color: Vec::with_capacity(pixels),
        hits: Vec::with_capacity(pixels),
        near_miss: Vec::new(),
    };
    for y in 0..height {
        for x in 0..width {
            let d =
                (v3(basis.corner) + f64::from(x) * v3(basis.du) + f64::from(y) * v3(basis.dv)).normalize();
            img.color.push(world.trace(eye, d, DVec3::ONE, 0, None));
            let hit = world.hit(eye, d, None, f64::INFINITY).map(|(t, i, _)| {
                let s = &scene.spheres[i];
                let gap = scene
                    .spheres
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .filter_map(|(_, o)| intersect(eye, d, o).map(|(u, _)| (u - t).abs()))
                    .fold(f64::INFINITY, f64::min);
                RefHit { sphere: i as u16, t, margin: silhouette_margin(eye, d, s), gap }
            });
            img.hits.push(hit);
        }
    }
    img
}

/// `r - distance from the centre to the line` (positive inside the silhouette).
pub fn silhouette_margin(o: DVec3, d: DVec3, s: &SphereDesc) -> f64 {
    let f = o - v3(s.center);
    s.radius - f.cross(d).length()
}

/// Hit at t >= 0 (entry from outside, exit from inside), as the firmware defines it.
fn intersect(o: DVec3, d: DVec3, s: &SphereDesc) -> Option<(f64, bool)> {
    let f = o - v3(s.center);
    let (a, b, c) = (d.dot(d), f.dot(d), f.dot(f) - s.radius * s.radius);
    let disc = s.radius * s.radius * a - f.cross(d).length_squared();
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

fn v3(a: [f64; 3]) -> DVec3 {
    DVec3::from_array(a)
}
