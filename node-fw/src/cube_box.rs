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
            let (first, last) = surface_range(c.get(axis).copied().unwrap_or(0), r);
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

/// The cubes along one axis whose closed cubes a sphere of centre `c` and
/// radius `r` (raw) may meet: `k` from `first` to `last`, those with
/// `k <= c + r` and `k + 1 >= c - r`. No cube outside them lists it.
fn surface_range(c: i64, r: i64) -> (i64, i64) {
    let first = (c - r).div_euclid(ONE) - i64::from((c - r).rem_euclid(ONE) == 0);
    (first, (c + r).div_euclid(ONE))
}

/// Whether a walk from `cell` along `dir` has every cube that lists `sphere`
/// behind it: on some axis `cell` lies past the cubes from `first` to `last`
/// that [`CubeBox::for_each_surface_cube`] searches for the sphere (those
/// with `k <= c + r` and `k + 1 >= c - r`), and the walk moves that way or not at all along it,
/// as a digital line's cell moves along each axis only in its direction's
/// sign. Then no node's cube the walk goes on to lists the sphere, so a ray
/// leaving it need not name it to be ignored: every test it meets is the same.
///
/// Past the range is `k > last`, that is `k ONE > c + r`, or `k < first`,
/// that is `(k + 1) ONE < c - r`: compared so, with no division (a look
/// costs each leaving ray that ignores a sphere).
pub fn leaves_behind(sphere: &Sphere, cell: [i32; 3], dir: [i32; 3]) -> bool {
    let r = i64::from(sphere.radius().to_bits());
    let axes = sphere.center().into_iter().zip(cell).zip(dir);
    axes.into_iter().any(|((c, k), d)| {
        let (c, k) = (i64::from(c), i64::from(k));
        (d >= 0 && k * ONE > c + r) || (d <= 0 && (k + 1) * ONE < c - r)
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Grid;
    use link_proto::{MaterialMsg, SphereMsg};
    use proptest::prelude::*;

    fn sphere(center: [i32; 3], radius: i32) -> Sphere {
        let material =
            MaterialMsg { color: [1; 3], ambient: 0, diffuse: 0, specular: 0, shininess: 1, reflect: 0 };
        let grid = Grid::new([32; 3]).unwrap();
        Sphere::from_msg(&SphereMsg { id: 1, center, radius, material }, &grid).unwrap()
    }

    #[test]
    fn a_sphere_two_cubes_behind_is_left_behind_and_one_ahead_is_not() {
        // Centre (5.5, 5.5, 5.5), radius 0.75: its cubes are 4 to 6 on each axis.
        let s = sphere([5 << 16 | 1 << 15; 3], 3 << 14);
        assert!(leaves_behind(&s, [7, 5, 5], [1 << 30, 0, 0]));
        assert!(leaves_behind(&s, [7, 5, 5], [0, 1 << 30, 0]), "x never changes");
        assert!(!leaves_behind(&s, [7, 5, 5], [-(1 << 30), 0, 0]), "coming back");
        assert!(!leaves_behind(&s, [6, 5, 5], [1 << 30, 0, 0]), "cube 6 meets it");
        assert!(leaves_behind(&s, [3, 9, 5], [-1, -1, 0]));
        assert!(!leaves_behind(&s, [3, 5, 5], [1, 0, 0]));
        // Radius 0.5: the surface touches the closed cubes 4 and 6 at a point
        // of their faces (x = 5 and x = 6), which lists it there.
        let s = sphere([5 << 16 | 1 << 15; 3], 1 << 15);
        assert!(!leaves_behind(&s, [6, 5, 5], [1, 0, 0]));
        assert!(leaves_behind(&s, [7, 5, 5], [1, 0, 0]));
        assert!(!leaves_behind(&s, [4, 5, 5], [-1, 0, 0]));
        assert!(leaves_behind(&s, [3, 5, 5], [-1, 0, 0]));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2_000))]

        /// Left behind, the sphere is listed in no cube a walk from `cell`
        /// along `dir` can reach: every cube on or past `cell` in each
        /// axis's direction (only `cell`'s own coordinate where a component
        /// is zero), against the cubes `for_each_surface_cube` lists it in.
        #[test]
        fn a_sphere_left_behind_is_listed_in_no_cube_ahead(
            center in proptest::array::uniform3(2i32 << 16..10 << 16),
            radius in 1i32 << 12..3 << 16,
            cell in proptest::array::uniform3(-1i32..14),
            dir in proptest::array::uniform3(prop_oneof![Just(0i32), Just(1), Just(-1)]),
        ) {
            let s = sphere(center, radius);
            prop_assume!(leaves_behind(&s, cell, dir));
            let region = CubeBox { lo: [0; 3], hi: [16; 3] };
            let mut listed = 0;
            region.for_each_surface_cube(&s, |k| {
                listed += 1;
                let k = k as i32;
                let m = [k % 16, k / 16 % 16, k / 256];
                let ahead = (0..3).all(|a| match dir[a].signum() {
                    1 => m[a] >= cell[a],
                    -1 => m[a] <= cell[a],
                    _ => m[a] == cell[a],
                });
                assert!(!ahead, "cube {m:?} lists the sphere, ahead of {cell:?} along {dir:?}");
            });
            prop_assert!(listed > 0);
        }
    }
}
