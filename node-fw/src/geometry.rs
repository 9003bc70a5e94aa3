//! Checked geometric values: grid, points, unit directions, quantised lines.
//!
//! Constructors validate against [`crate::limits`] and return an [`Error`]
//! instead of wrapping; once built, a value is inside the ranges the kernels are
//! proven for.

use crate::error::{Error, Field};
use crate::limits::{DIR_FRAC, DIR_ONE, MAX_GRID, MAX_UNIT_ERROR_RAW, ONE, Scalar, Unit, coord_in_range};
use crate::wide;

/// The scene's grid of unit cubes, `[0, size)` on each axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grid {
    size: [u16; 3],
}

impl Grid {
    /// A one-cube grid, the placeholder of an unassigned subregion.
    pub const UNIT: Grid = Grid { size: [1; 3] };

    /// A grid of `size` cubes per axis, each in `1..=256`.
    pub fn new(size: [u16; 3]) -> Result<Self, Error> {
        if size.iter().all(|&s| (1..=MAX_GRID).contains(&s)) {
            Ok(Self { size })
        } else {
            Err(Error::OutOfRange(Field::Grid))
        }
    }

    /// Cubes per axis.
    pub fn size(&self) -> [u16; 3] {
        self.size
    }

    /// Whether `cell` is a cube of the grid.
    #[inline]
    pub fn contains(&self, cell: [i32; 3]) -> bool {
        cell.iter().zip(self.size).all(|(&c, s)| c >= 0 && c < i32::from(s))
    }

    /// Whether the raw point lies in the closed grid box.
    pub fn contains_point(&self, raw: [i32; 3]) -> bool {
        raw.iter().zip(self.size).all(|(&x, s)| x >= 0 && i64::from(x) <= i64::from(s) * ONE)
    }
}

/// A point in Q16.16 cubes, within the accepted range of origins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Point {
    raw: [i32; 3],
}

impl Point {
    /// A point from raw Q16.16 coordinates.
    pub fn from_bits(raw: [i32; 3]) -> Result<Self, Error> {
        if raw.iter().all(|&x| coord_in_range(x)) {
            Ok(Self { raw })
        } else {
            Err(Error::OutOfRange(Field::Origin))
        }
    }

    /// A point from fixed-point coordinates.
    pub fn new(p: [Scalar; 3]) -> Result<Self, Error> {
        Self::from_bits(p.map(Scalar::to_bits))
    }

    /// Raw Q16.16 coordinates.
    pub fn bits(&self) -> [i32; 3] {
        self.raw
    }
}

/// `d.d` of raw components, exact: each square is at most 2^62, so the sum
/// fits `u64` and needs no 128-bit arithmetic, which a Cortex-M3 calls a
/// library for (this runs for every ray a node receives).
fn squared_length(d: [i32; 3]) -> u64 {
    d.iter().map(|&c| i64::from(c).unsigned_abs().pow(2)).sum()
}

/// A unit direction in Q2.30, `|d.d - 1| <= 2^-20`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Direction {
    raw: [i32; 3],
}

impl Direction {
    /// A direction from raw Q2.30 components, which must form a unit vector.
    pub fn from_bits(raw: [i32; 3]) -> Result<Self, Error> {
        Self::with_len2(raw).map(|(dir, _)| dir)
    }

    /// The direction of raw components and its `d.d`, which the check
    /// computes anyway and a line keeps.
    fn with_len2(raw: [i32; 3]) -> Result<(Self, u64), Error> {
        const LEAST: u64 = DIR_ONE.unsigned_abs().pow(2) - MAX_UNIT_ERROR_RAW;
        let len2 = squared_length(raw);
        // `|len2 - 1| <= MAX_UNIT_ERROR_RAW` as one unsigned comparison: below
        // `LEAST` the subtraction wraps past the bound.
        if len2.wrapping_sub(LEAST) <= 2 * MAX_UNIT_ERROR_RAW {
            Ok((Self { raw }, len2))
        } else {
            Err(Error::OutOfRange(Field::Direction))
        }
    }

    /// A direction from fixed-point components, which must form a unit vector.
    pub fn new(d: [Unit; 3]) -> Result<Self, Error> {
        Self::from_bits(d.map(Unit::to_bits))
    }

    /// The unit direction of `v` (any scale, nonzero), rounded to Q2.30.
    ///
    /// Deterministic integer arithmetic: every node computes the same bits.
    pub fn normalize(v: [i64; 3]) -> Result<Self, Error> {
        let largest = v.iter().map(|c| c.unsigned_abs()).max().unwrap_or(0);
        if largest == 0 {
            return Err(Error::OutOfRange(Field::Direction));
        }
        // Rescale so the largest component lies in [2^40, 2^41): the square root
        // is then exact to 2^-41 whatever the input's scale. (The shift right
        // rounds toward minus infinity, as it always has: the bits are part of
        // every image.)
        let top = 63 - largest.leading_zeros() as i32;
        let v = v.map(|c| if top < 40 { c << (40 - top) } else { c >> (top - 40) });
        // |c| < 2^41: squares below 2^82, their sum below 2^84, its root below 2^42.
        let len2: u128 = v.iter().map(|&c| wide::square(c.unsigned_abs())).sum();
        let len = u64::try_from(wide::isqrt(len2)).map_err(|_| Error::OutOfRange(Field::Direction))?;
        // len is in [2^40, 2^42) and |c| <= len, so the reciprocal applies
        // and every quotient is at most 2^30.
        let by_len = wide::Divisor30::new(len).ok_or(Error::OutOfRange(Field::Direction))?;
        let mut raw = [0i32; 3];
        for (out, &c) in raw.iter_mut().zip(&v) {
            // c 2^30 / len, truncated toward zero.
            let q = by_len.div_shl30(c.unsigned_abs()).and_then(|q| i32::try_from(q).ok());
            let q = q.ok_or(Error::OutOfRange(Field::Direction))?;
            *out = if c < 0 { -q } else { q };
        }
        Self::from_bits(raw)
    }

    /// Raw Q2.30 components.
    pub fn bits(&self) -> [i32; 3] {
        self.raw
    }
}

/// A quantised ray: origin and unit direction, with `d.d` cached for the sphere test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Line {
    origin: [i32; 3],
    dir: [i32; 3],
    /// `d.d` in raw units of 2^-60 (about 2^60: the direction is a unit vector).
    a: u64,
}

impl Line {
    /// The line through `origin` along `dir`.
    pub fn new(origin: Point, dir: Direction) -> Self {
        let d = dir.bits();
        Self { origin: origin.bits(), dir: d, a: squared_length(d) }
    }

    /// A received ray's line from raw coordinates, checked as
    /// [`Point::from_bits`] and [`Direction::from_bits`] check them (the
    /// origin first), with `d.d` computed once: this runs for every ray a
    /// node receives.
    pub fn from_bits(origin: [i32; 3], dir: [i32; 3]) -> Result<Self, Error> {
        let origin = Point::from_bits(origin)?;
        let (dir, a) = Direction::with_len2(dir)?;
        Ok(Self { origin: origin.bits(), dir: dir.bits(), a })
    }

    /// Raw Q16.16 origin.
    pub fn origin(&self) -> [i32; 3] {
        self.origin
    }

    /// Raw Q2.30 direction.
    pub fn dir(&self) -> [i32; 3] {
        self.dir
    }

    /// `d.d`, raw in units of 2^-60.
    pub fn dir_len2(&self) -> i128 {
        i128::from(self.a)
    }

    /// The point at parameter `t`, rounded to the nearest Q16.16 value.
    pub fn at(&self, t: Scalar) -> [i32; 3] {
        let t = i64::from(t.to_bits());
        let half = 1i64 << (DIR_FRAC - 1);
        let mut p = [0i32; 3];
        for ((out, &o), &d) in p.iter_mut().zip(&self.origin).zip(&self.dir) {
            let step = (t * i64::from(d) + half) >> DIR_FRAC;
            // |o| < 2^30 and |t d| < 2^31 within the limits: the sum fits i64, and
            // saturating to i32 keeps a hit point inside the accepted range.
            *out = (i64::from(o) + step).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        }
        p
    }
}

/// Component-wise `f(a_i, b_i)` of two 3-vectors (no indexing, no panic path).
pub fn zip3<A: Copy, B: Copy, T>(a: [A; 3], b: [B; 3], f: impl Fn(A, B) -> T) -> [T; 3] {
    let ([a0, a1, a2], [b0, b1, b2]) = (a, b);
    [f(a0, b0), f(a1, b1), f(a2, b2)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The plain 128-bit normalisation the firmware shipped first: the bits
    /// of every image rest on it, so the fast one must agree everywhere.
    fn normalize_i128(v: [i64; 3]) -> Option<[i32; 3]> {
        let largest = v.iter().map(|c| c.unsigned_abs()).max()?;
        if largest == 0 {
            return None;
        }
        let top = 63 - largest.leading_zeros() as i32;
        let v = v.map(|c| {
            let c = i128::from(c);
            if top < 40 { c << (40 - top) } else { c >> (top - 40) }
        });
        let len = v.iter().map(|&c| c * c).sum::<i128>().isqrt();
        let raw = v.map(|c| i32::try_from((c << DIR_FRAC) / len).ok());
        Some([raw[0]?, raw[1]?, raw[2]?]).filter(|r| Direction::from_bits(*r).is_ok())
    }

    fn agrees(v: [i64; 3]) -> Result<(), TestCaseError> {
        let fast = Direction::normalize(v).ok().map(|d| d.bits());
        prop_assert_eq!(fast, normalize_i128(v), "v = {:?}", v);
        Ok(())
    }

    #[test]
    fn normalize_matches_the_128_bit_reference_at_the_extremes() {
        let edges = [0, 1, -1, 2, 3, (1 << 40) - 1, 1 << 40, -(1 << 41), i64::MAX, i64::MIN, i64::MIN + 1];
        for &x in &edges {
            for &y in &edges {
                for &z in &edges {
                    agrees([x, y, z]).unwrap();
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn normalize_matches_the_128_bit_reference(v in any::<[i64; 3]>(), shifts in any::<[u8; 3]>()) {
            agrees(core::array::from_fn(|i| v[i] >> (shifts[i] % 64)))?;
        }
    }
}
