//! Fixed-point formats and the documented ranges inside which nothing overflows.
//!
//! | quantity                         | format  | storage | range accepted                      |
//! |----------------------------------|---------|---------|-------------------------------------|
//! | grid size                        | integer | `u16`   | 1..=256 cubes per axis              |
//! | origin, eye, light               | Q16.16  | `i32`   | up to 10^4 cubes outside the grid   |
//! | sphere centre                    | Q16.16  | `i32`   | inside the closed grid box          |
//! | sphere radius                    | Q16.16  | `i32`   | 1/256 ..= 64 cubes                  |
//! | direction component              | Q2.30   | `i32`   | unit vector, length within 2^-20    |
//! | ray parameter `t`                | Q16.16  | `i32`   | 0 ..= 32767 (distance along a ray)  |
//!
//! Why these formats: Q16.16 holds every coordinate up to 10^4 cubes outside a
//! 256-cube grid (|x| < 2^14 cubes) with a resolution of 1.5e-5 cube, and Q2.30
//! directions shift a ray sideways by under 1e-9 cube per cube travelled, so
//! direction quantisation never dominates origin quantisation. The product of a
//! position and a direction is exact in `i64`; the sphere discriminant
//! `a r^2 - |f x d|^2` is exact in `i128` (see [`crate::sphere`]). The worst-case
//! magnitudes of every intermediate are asserted at compile time below.

use fixed::types::{I2F30, I16F16};

/// Positions, radii and ray parameters: Q16.16 in cubes.
pub type Scalar = I16F16;
/// Direction components: Q2.30.
pub type Unit = I2F30;

/// Fraction bits of [`Scalar`].
pub const POS_FRAC: u32 = 16;
/// Fraction bits of [`Unit`].
pub const DIR_FRAC: u32 = 30;
/// One cube in raw [`Scalar`] units.
pub const ONE: i64 = 1 << POS_FRAC;
/// Raw value of a unit direction component.
pub const DIR_ONE: i64 = 1 << DIR_FRAC;

/// Largest grid size per axis.
pub const MAX_GRID: u16 = 256;
/// How far outside the grid (per axis, in cubes) an origin, eye or light may lie.
pub const MAX_OUTSIDE: i64 = 10_000;
/// Smallest radius, raw (1/256 cube).
pub const MIN_RADIUS_RAW: i32 = (ONE / 256) as i32;
/// Largest radius, raw (64 cubes).
pub const MAX_RADIUS_RAW: i32 = (64 * ONE) as i32;
/// Largest accepted deviation of `d.d` from 1, raw in units of 2^-60 (that is, 2^-20).
pub const MAX_UNIT_ERROR_RAW: u64 = 1 << 40;

/// Smallest raw coordinate of an origin.
pub const MIN_COORD_RAW: i64 = -MAX_OUTSIDE * ONE;
/// Largest raw coordinate of an origin.
pub const MAX_COORD_RAW: i64 = (MAX_GRID as i64 + MAX_OUTSIDE) * ONE;

/// Largest |f| = |origin - centre| per axis, raw.
pub const MAX_OFFSET_RAW: i64 = MAX_COORD_RAW - MIN_COORD_RAW;
/// Largest distance from an origin to the next cube boundary along an axis, raw.
pub const MAX_BOUNDARY_RAW: i64 = MAX_OFFSET_RAW + ONE;

// Compile-time proofs of the overflow-freedom claimed in the module docs.
const _: () = {
    // Coordinates fit i32 (Q16.16).
    assert!(MAX_COORD_RAW < i32::MAX as i64 && MIN_COORD_RAW > i32::MIN as i64);
    // Digital line: N_i |D_j| and t |D| compared in i64, with one cube of headroom
    // per step: N <= MAX_BOUNDARY_RAW + 256 cubes.
    let n_max = MAX_BOUNDARY_RAW + MAX_GRID as i64 * ONE;
    assert!((n_max as i128) * (DIR_ONE as i128) < i64::MAX as i128 / 4);
    assert!((i32::MAX as i128) * (DIR_ONE as i128) < i64::MAX as i128);
    assert!((n_max as i128) << DIR_FRAC < i64::MAX as i128);
    // Sphere test: |f x d|^2 summed over three axes, and a r^2, fit i128.
    let cross = 2 * (MAX_OFFSET_RAW as i128) * (DIR_ONE as i128);
    assert!(cross.checked_mul(cross).is_some());
    assert!(cross * cross < i128::MAX / 4);
    let a = 3 * (DIR_ONE as i128) * (DIR_ONE as i128);
    let r2 = (MAX_RADIUS_RAW as i128) * (MAX_RADIUS_RAW as i128);
    assert!(a * r2 < i128::MAX / 4);
    // t = c 2^30 / q with c <= 3 |f|^2.
    let c = 3 * (MAX_OFFSET_RAW as i128) * (MAX_OFFSET_RAW as i128);
    assert!(c < i128::MAX >> 31);
};

/// Checks that a raw coordinate lies within the accepted range of origins.
pub const fn coord_in_range(raw: i32) -> bool {
    raw as i64 >= MIN_COORD_RAW && raw as i64 <= MAX_COORD_RAW
}
