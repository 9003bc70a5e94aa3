//! Whitted shading in integer arithmetic: ambient, point lights through shadow
//! rays, and mirror reflection, each child ray carrying its share of the pixel.
//!
//! Colours, weights and coefficients are Q1.15 (32768 = 1.0). Every product is
//! rounded down the same way on every node, and pixel contributions are integers
//! the host sums, so the image does not depend on which node shades what, nor
//! on the order contributions arrive in.
//!
//! A scene pays only for what it has: no shadow ray toward a light behind the
//! surface or when there is no light, no reflection ray off a surface with
//! `reflect = 0`, beyond the depth limit, or with a zero weight.

use link_proto::{LightMsg, RayKind, RayMsg, SceneHeader};

use crate::digital_line::DigitalLine;
use crate::geometry::{Direction, Grid, Line, Point, zip3};
use crate::limits::{DIR_FRAC, ONE, Scalar};
use crate::sphere::Sphere;

/// One Q1.15 unit.
pub const Q15_ONE: u32 = 1 << 15;

/// A child ray candidate, evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Child {
    /// A ray to trace, starting in its entry cube.
    Ray(RayMsg),
    /// Resolved at once (it never enters the grid): its contribution.
    Done([u32; 3]),
}

/// The surface at a hit: point, unit normal facing the ray, inside flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Surface {
    /// Hit point, raw Q16.16.
    pub point: [i32; 3],
    /// Unit normal (flipped toward the ray for a hit from inside), raw Q2.30.
    pub normal: [i32; 3],
    /// The ray started inside the sphere.
    pub inside: bool,
}

impl Surface {
    /// The surface where `line` hits `sphere` at `t`.
    pub fn at(line: &Line, t: Scalar, sphere: &Sphere) -> Option<Surface> {
        let point = line.at(t);
        let c = sphere.center();
        let outward = zip3(point, c, |p, c| i64::from(p) - i64::from(c));
        let normal = Direction::normalize(outward).ok()?.bits();
        let o = line.origin();
        let f2: i128 = zip3(o, c, |o, c| sq(i64::from(o) - i64::from(c))).iter().sum();
        let inside = f2 < sq(i64::from(sphere.radius().to_bits()));
        let normal = if inside { normal.map(|n| -n) } else { normal };
        Some(Surface { point, normal, inside })
    }
}

fn sq(x: i64) -> i128 {
    i128::from(x) * i128::from(x)
}

/// `a b` in Q1.15, rounded down.
pub fn mul15(a: u32, b: u32) -> u32 {
    u32::try_from((u64::from(a) * u64::from(b)) >> 15).unwrap_or(u32::MAX)
}

/// `x^n` in Q1.15 for `x <= 1`, by repeated squaring.
fn pow15(x: u32, mut n: u8) -> u32 {
    let (mut base, mut acc) = (x.min(Q15_ONE), Q15_ONE);
    while n > 0 {
        if n & 1 == 1 {
            acc = mul15(acc, base);
        }
        base = mul15(base, base);
        n >>= 1;
    }
    acc
}

/// Dot product of two Q2.30 vectors, Q2.30.
fn dot30(a: &[i32; 3], b: &[i32; 3]) -> i64 {
    a.iter().zip(b).map(|(&x, &y)| i64::from(x) * i64::from(y)).sum::<i64>() >> DIR_FRAC
}

/// Q2.30 (clamped at 0) to Q1.15.
fn to15(x: i64) -> u32 {
    u32::try_from((x.max(0) >> 15).min(i64::from(u32::MAX))).unwrap_or(u32::MAX)
}

/// What a hit sees: the scene-wide settings and the lights.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// Grid, ambient light, background, depth limit.
    pub header: &'a SceneHeader,
    /// The grid.
    pub grid: &'a Grid,
    /// Point lights.
    pub lights: &'a [LightMsg],
}

impl Scene<'_> {
    /// The background colour, Q1.15: what a ray at full strength that leaves
    /// the grid contributes.
    pub fn background_colour(&self) -> [u32; 3] {
        self.header.background.map(u32::from)
    }

    /// Contribution of a ray that leaves the grid: background times weight.
    pub fn background(&self, ray: &RayMsg) -> [u32; 3] {
        zip3(ray.weight, self.header.background, |w, b| mul15(w, u32::from(b)))
    }

    /// Ambient contribution of a hit.
    pub fn ambient(&self, ray: &RayMsg, sphere: &Sphere) -> [u32; 3] {
        let m = sphere.material();
        let lit = self.header.ambient.map(|a| mul15(u32::from(m.ambient), u32::from(a)));
        let reflected = zip3(lit, m.color, |l, c| mul15(l, u32::from(c)));
        zip3(ray.weight, reflected, mul15)
    }

    /// Child candidates of a hit: one per light, then the reflection.
    pub fn candidates(&self) -> u8 {
        self.lights.len() as u8 + 1
    }

    /// Evaluates child candidate `k` of `ray` hitting `sphere` at `surface`.
    pub fn child(
        &self,
        ray: &RayMsg,
        line: &Line,
        surface: &Surface,
        sphere: &Sphere,
        k: u8,
    ) -> Option<Child> {
        if surface.inside {
            return None;
        }
        match self.lights.get(usize::from(k)) {
            Some(light) => self.shadow_ray(ray, line, surface, sphere, light),
            None if usize::from(k) == self.lights.len() => self.reflection(ray, line, surface, sphere),
            None => None,
        }
    }

    fn shadow_ray(
        &self,
        ray: &RayMsg,
        line: &Line,
        surface: &Surface,
        sphere: &Sphere,
        light: &LightMsg,
    ) -> Option<Child> {
        let to_light = zip3(light.position, surface.point, |l, p| i64::from(l) - i64::from(p));
        let dist: u128 = to_light.iter().map(|&x| crate::wide::square(x.unsigned_abs())).sum();
        let dist = i32::try_from(crate::wide::isqrt(dist)).ok().filter(|&d| d > 0)?;
        let l = Direction::normalize(to_light).ok()?.bits();
        let ndl = dot30(&surface.normal, &l);
        if ndl <= 0 {
            return None;
        }
        let m = sphere.material();
        let diffuse = mul15(u32::from(m.diffuse), to15(ndl));
        // Phong highlight: R = 2 (N.L) N - L against the view direction V = -D.
        let specular = if m.specular > 0 {
            let r = zip3(surface.normal, l, |n, l| {
                (((2 * ndl * i64::from(n)) >> DIR_FRAC) - i64::from(l)) as i32
            });
            let v = line.dir().map(|d| -d);
            mul15(u32::from(m.specular), pow15(to15(dot30(&r, &v)), m.shininess))
        } else {
            0
        };
        let surface_term = m.color.map(|c| mul15(diffuse, u32::from(c)).saturating_add(specular));
        let lit = zip3(surface_term, light.color, |s, l| mul15(s, u32::from(l)));
        let weight = zip3(ray.weight, lit, mul15);
        if weight == [0; 3] {
            return None;
        }
        let shadow = RayMsg {
            kind: RayKind::Shadow,
            weight,
            t_max: (!self.beyond_the_grid(light.position)).then_some(dist),
            ..self.spawn(ray, surface, sphere, l)
        };
        Some(self.enter(shadow, weight))
    }

    /// Whether `p` lies a cube or more outside the grid's closed box on some
    /// axis: a light there is beyond every sphere, so a shadow ray toward it
    /// needs no `t_max`, and without one it is four bytes shorter on every
    /// hop.
    ///
    /// Spheres lie in the grid's box (a node refuses any other), so a ray
    /// meets one only before it leaves the box, at `t_exit`, and every cube
    /// it walks ends by then too. `t_max` is the light's distance, rounded
    /// down by under 2^-16, along a direction rounded by 2^-30 a component:
    /// the point at `t_max` lies within 2^-13 of the light (lights are under
    /// 2^15 cubes away), so outside the box, and `t_max > t_exit + 0.99`,
    /// far more than any rounding of a hit's `t`. No test against `t_max`
    /// (a hit at or beyond it, a cube ending at or beyond it) could succeed,
    /// and the ray retires when it leaves the grid as it would have there.
    fn beyond_the_grid(&self, p: [i32; 3]) -> bool {
        p.iter().zip(self.grid.size()).any(|(&x, s)| {
            let x = i64::from(x);
            x <= -ONE || x >= (i64::from(s) + 1) * ONE
        })
    }

    fn reflection(&self, ray: &RayMsg, line: &Line, surface: &Surface, sphere: &Sphere) -> Option<Child> {
        let m = sphere.material();
        if m.reflect == 0 || ray.depth >= self.header.max_depth || ray.kind == RayKind::Shadow {
            return None;
        }
        let weight = ray.weight.map(|w| mul15(w, u32::from(m.reflect)));
        if weight == [0; 3] {
            return None;
        }
        let d = line.dir();
        let ddn = dot30(&d, &surface.normal);
        let r = zip3(d, surface.normal, |d, n| i64::from(d) - ((2 * ddn * i64::from(n)) >> DIR_FRAC));
        let r = Direction::normalize(r).ok()?.bits();
        let reflected = RayMsg {
            kind: RayKind::Reflected,
            weight,
            depth: ray.depth + 1,
            ..self.spawn(ray, surface, sphere, r)
        };
        let background = self.background(&reflected);
        Some(self.enter(reflected, background))
    }

    /// A child leaving the surface along `dir`, not yet placed in a cube.
    fn spawn(&self, parent: &RayMsg, surface: &Surface, sphere: &Sphere, dir: [i32; 3]) -> RayMsg {
        RayMsg {
            origin: surface.point,
            dir,
            cell: [0; 3],
            credit: 0,
            ignore: Some(sphere.id()),
            best: None,
            t_max: None,
            class: parent.class.saturating_add(1),
            tag: 0,
            ..*parent
        }
    }

    /// Places `ray` in its entry cube, or resolves it with `outside` if it never
    /// enters the grid.
    fn enter(&self, mut ray: RayMsg, outside: [u32; 3]) -> Child {
        let walk = Point::from_bits(ray.origin)
            .ok()
            .zip(Direction::from_bits(ray.dir).ok())
            .and_then(|(o, d)| DigitalLine::enter(&Line::new(o, d), self.grid));
        match walk {
            Some(walk) => {
                ray.cell = walk.cell().map(|c| c as u16);
                Child::Ray(ray)
            }
            None => Child::Done(outside),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_is_beyond_the_grid_from_one_cube_out() {
        let Ok(grid) = Grid::new([8, 6, 4]) else { panic!("a valid grid") };
        let header = SceneHeader {
            grid: [8, 6, 4],
            ambient: [0; 3],
            background: [0; 3],
            max_depth: 1,
            map: link_proto::MapLoad::Sent,
        };
        let scene = Scene { header: &header, grid: &grid, lights: &[] };
        let at = |p: [f64; 3]| p.map(|x| (x * ONE as f64) as i32);
        for far in [[-1.0, 3.0, 2.0], [9.0, 3.0, 2.0], [4.0, 7.0, 2.0], [4.0, -1.5, 2.0], [4.0, 3.0, 5.0]] {
            assert!(scene.beyond_the_grid(at(far)), "{far:?}");
        }
        for near in [[-0.99, 3.0, 2.0], [8.99, 6.99, 4.99], [4.0, 3.0, 2.0], [-0.5, -0.5, -0.5]] {
            assert!(!scene.beyond_the_grid(at(near)), "{near:?}");
        }
    }
}
