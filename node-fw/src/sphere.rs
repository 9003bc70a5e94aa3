//! Spheres and the exact ray/sphere hit.
//!
//! With `f = o - c`, `a = d.d`, `b = f.d` and `c = f.f - r^2`, the line meets the
//! sphere iff the discriminant `b^2 - a c` is non-negative. It is computed in
//! Lagrange's form `a r^2 - |f x d|^2` (Ray Tracing Gems, ch. 7), which has no
//! cancellation, and in `i128` from raw integers, where every product is exact:
//! the hit/miss decision, whether the origin is inside (`sign c`), and whether
//! the sphere lies ahead (`sign b`) are exact for the quantised ray. Only the
//! depth `t` is rounded, once, by the stable root formula `q = -(b + sign(b)
//! sqrt(disc))`, `t0 = c / q`, `t1 = q / a`, which avoids `-b + sqrt(disc)`
//! cancelling for a far small sphere or an origin near the surface.

use link_proto::{MaterialMsg, SphereMsg};

use crate::error::{Error, Field};
use crate::geometry::{Grid, Line, Point};
use crate::limits::{DIR_FRAC, MAX_RADIUS_RAW, MIN_RADIUS_RAW, Scalar};

/// Surface parameters after Whitted: all coefficients Q1.15 (32768 = 1.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Material {
    /// Surface colour.
    pub color: [u16; 3],
    /// Ambient coefficient.
    pub ambient: u16,
    /// Diffuse coefficient.
    pub diffuse: u16,
    /// Specular coefficient.
    pub specular: u16,
    /// Phong exponent of the highlight.
    pub shininess: u8,
    /// Mirror reflection coefficient; 0 means no reflection rays.
    pub reflect: u16,
}

impl From<&MaterialMsg> for Material {
    fn from(m: &MaterialMsg) -> Self {
        Material {
            color: m.color,
            ambient: m.ambient,
            diffuse: m.diffuse,
            specular: m.specular,
            shininess: m.shininess,
            reflect: m.reflect,
        }
    }
}

impl From<&Material> for MaterialMsg {
    fn from(m: &Material) -> Self {
        MaterialMsg {
            color: m.color,
            ambient: m.ambient,
            diffuse: m.diffuse,
            specular: m.specular,
            shininess: m.shininess,
            reflect: m.reflect,
        }
    }
}

/// A sphere, validated against the grid and the radius limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sphere {
    id: u16,
    center: [i32; 3],
    radius: i32,
    /// `r^2`, raw in units of 2^-32.
    r2: i64,
    material: Material,
}

/// Where a line meets a sphere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Root {
    /// Ray parameter of the hit, rounded down to Q16.16.
    pub t: Scalar,
    /// The origin is inside the sphere (the hit is the exit point).
    pub inside: bool,
}

/// The nearest hit of a ray so far. Ordered by `t`, then by sphere id, so equal
/// depths resolve the same way on every node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Hit {
    /// Ray parameter, Q16.16.
    pub t: Scalar,
    /// Sphere id.
    pub sphere: u16,
}

impl Sphere {
    /// A sphere with centre inside the closed grid box and radius in 1/256..=64 cubes.
    pub fn new(
        id: u16,
        center: Point,
        radius: Scalar,
        material: Material,
        grid: &Grid,
    ) -> Result<Self, Error> {
        let center = center.bits();
        if !grid.contains_point(center) {
            return Err(Error::OutOfRange(Field::Center));
        }
        let radius = radius.to_bits();
        if !(MIN_RADIUS_RAW..=MAX_RADIUS_RAW).contains(&radius) {
            return Err(Error::OutOfRange(Field::Radius));
        }
        Ok(Self { id, center, radius, r2: i64::from(radius) * i64::from(radius), material })
    }

    /// A sphere from its wire form, validated as [`Sphere::new`] does.
    pub fn from_msg(m: &SphereMsg, grid: &Grid) -> Result<Self, Error> {
        let center = Point::from_bits(m.center)?;
        Sphere::new(m.id, center, Scalar::from_bits(m.radius), Material::from(&m.material), grid)
    }

    /// The sphere's wire form.
    pub fn to_msg(&self) -> SphereMsg {
        SphereMsg {
            id: self.id,
            center: self.center,
            radius: self.radius,
            material: MaterialMsg::from(&self.material),
        }
    }

    /// Whether the whole sphere lies in the closed box of `grid` (the scene is
    /// the grid: a node rejects a sphere that sticks out of it).
    pub fn within(&self, grid: &Grid) -> bool {
        let r = i64::from(self.radius);
        self.center.iter().zip(grid.size()).all(|(&c, s)| {
            let c = i64::from(c);
            c - r >= 0 && c + r <= i64::from(s) * crate::limits::ONE
        })
    }

    /// Scene-wide id.
    pub fn id(&self) -> u16 {
        self.id
    }

    /// Raw Q16.16 centre.
    pub fn center(&self) -> [i32; 3] {
        self.center
    }

    /// Radius.
    pub fn radius(&self) -> Scalar {
        Scalar::from_bits(self.radius)
    }

    /// Surface parameters.
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// Where `line` meets the sphere at `t >= 0`: the entry point from outside,
    /// the exit point from inside. `None` if it does not.
    ///
    /// An origin exactly on the surface counts as outside: the ray hits at `t = 0`
    /// if it heads inward, and misses otherwise.
    pub fn intersect(&self, line: &Line) -> Option<Root> {
        let o = line.origin();
        let d = line.dir();
        let f = [
            i64::from(o[0]) - i64::from(self.center[0]),
            i64::from(o[1]) - i64::from(self.center[1]),
            i64::from(o[2]) - i64::from(self.center[2]),
        ];
        let d = [i64::from(d[0]), i64::from(d[1]), i64::from(d[2])];
        // f x d: each term below 2^61, exact in i64 (see crate::limits).
        let cross = [f[1] * d[2] - f[2] * d[1], f[2] * d[0] - f[0] * d[2], f[0] * d[1] - f[1] * d[0]];
        let a = line.dir_len2();
        let disc =
            a * i128::from(self.r2) - cross.iter().map(|&x| i128::from(x) * i128::from(x)).sum::<i128>();
        if disc < 0 {
            return None;
        }
        let b: i128 = f.iter().zip(&d).map(|(&x, &y)| i128::from(x) * i128::from(y)).sum();
        let c: i128 = f.iter().map(|&x| i128::from(x) * i128::from(x)).sum::<i128>() - i128::from(self.r2);
        // The root only where a depth needs it: a sphere behind the origin
        // is missed whatever it is.
        let s = || crate::wide::isqrt(disc.unsigned_abs()) as i128;
        let (t, inside) = match (c.signum(), b < 0) {
            // Outside, sphere ahead: near root t0 = c / q with q = s - b > 0.
            (1, true) => (depth(c, s() - b)?, false),
            (1, false) => return None,
            // On the surface: enters at t = 0 if heading inward.
            (0, true) => (0, false),
            (0, false) => return None,
            // Inside: far root. With b < 0, t1 = q / a (q = s - b > 0); with
            // b >= 0, t1 = c / q (q = -(b + s) < 0), both free of cancellation.
            (_, true) => (depth(s() - b, a)?, true),
            (_, false) => (depth(-c, b + s())?, true),
        };
        Some(Root { t: Scalar::from_bits(t), inside })
    }
}

/// `num / den` scaled to a raw Q16.16 parameter, rounded toward zero; `None`
/// where it does not fit one (or `den` is 0). Both are positive here.
///
/// Both roots have the form (units 2^-32 over 2^-46) or (2^-46 over 2^-60),
/// so the Q16.16 value is `num 2^30 / den`. Within the documented ranges
/// both are under 2^63 ([`crate::limits`]) and a 64-bit quotient path
/// ([`crate::wide::div_shl30`]) gives it; the 128-bit division stays for
/// anything wider.
fn depth(num: i128, den: i128) -> Option<i32> {
    match (u64::try_from(num), u64::try_from(den)) {
        (Ok(n), Ok(d)) => crate::wide::div_shl30(n, d).map(|t| t as i32),
        _ if den == 0 => None,
        _ => i32::try_from((num << DIR_FRAC) / den).ok(),
    }
}
