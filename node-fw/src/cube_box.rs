//! A box of unit cubes `[lo, hi)`: the shape of every subregion.

use crate::limits::ONE;
use crate::sphere::Sphere;

/// A box of unit cubes `[lo, hi)`, with cubes numbered x fastest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CubeBox {
    /// Lower corner (inclusive).
    pub lo: [u16; 3],
    /// Upper corner (exclusive).
    pub hi: [u16; 3],
}

impl CubeBox {
    /// Number of cubes (0 for an empty box).
    pub fn volume(&self) -> u64 {
        (0..3).map(|a| u64::from(at(&self.hi, a).saturating_sub(at(&self.lo, a)))).product()
    }

    /// Index of `cell` within the box, or `None` outside it.
    pub fn index(&self, cell: [i32; 3]) -> Option<usize> {
        let mut index = 0usize;
        for axis in (0..3).rev() {
            let (lo, hi) = (i32::from(at(&self.lo, axis)), i32::from(at(&self.hi, axis)));
            let c = cell.get(axis).copied().unwrap_or(-1);
            if c < lo || c >= hi {
                return None;
            }
            index = index * (hi - lo) as usize + (c - lo) as usize;
        }
        Some(index)
    }

    /// Calls `f` with the index of every closed cube of the box that meets the
    /// sphere's surface.
    pub fn for_each_surface_cube(&self, sphere: &Sphere, mut f: impl FnMut(usize)) {
        let c = sphere.center().map(i64::from);
        let r = i64::from(sphere.radius().to_bits());
        let mut range = [(0i64, 0i64); 3];
        for (axis, out) in range.iter_mut().enumerate() {
            let ca = c.get(axis).copied().unwrap_or(0);
            // Closed cubes k with k <= c + r and k + 1 >= c - r.
            let first = (ca - r).div_euclid(ONE) - i64::from((ca - r).rem_euclid(ONE) == 0);
            let last = (ca + r).div_euclid(ONE);
            let lo = i64::from(at(&self.lo, axis));
            let hi = i64::from(at(&self.hi, axis)) - 1;
            *out = (first.max(lo), last.min(hi));
        }
        let [(x0, x1), (y0, y1), (z0, z1)] = range;
        for z in z0..=z1 {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let cell = [x, y, z];
                    if !surface_meets_cube(c, r * r, cell) {
                        continue;
                    }
                    if let Some(k) = self.index(cell.map(|v| v as i32)) {
                        f(k);
                    }
                }
            }
        }
    }
}

/// Whether the sphere surface (centre `c`, squared radius `r2`, raw) meets the
/// closed unit cube `cell`. The distance from the centre to points of the
/// (connected) cube ranges over `[d_min, d_max]`, so the surface meets it iff
/// `d_min^2 <= r^2 <= d_max^2`; exact in i64.
pub fn surface_meets_cube(c: [i64; 3], r2: i64, cell: [i64; 3]) -> bool {
    let mut near = 0i64;
    let mut far = 0i64;
    for (&ca, &k) in c.iter().zip(&cell) {
        let (lo, hi) = (k * ONE, (k + 1) * ONE);
        let gap = if ca < lo {
            lo - ca
        } else if ca > hi {
            ca - hi
        } else {
            0
        };
        let reach = (ca - lo).abs().max((hi - ca).abs());
        near += gap * gap;
        far += reach * reach;
    }
    near <= r2 && r2 <= far
}

fn at(a: &[u16; 3], i: usize) -> u16 {
    a.get(i).copied().unwrap_or(0)
}
