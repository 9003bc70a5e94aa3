//! The three-dimensional digital line: the unit cubes pierced by a ray.
//!
//! The paper (after Fujimoto et al.) runs two 2-D DDAs and compares their error
//! terms. This is the exact equivalent with integer additions only: let `N_i` be
//! the raw distance along axis `i` from the origin to the next cube boundary in
//! the direction of travel, so the boundary is crossed at `t_i = N_i / |D_i|`.
//! Axis `i` is crossed before axis `j` iff `N_i |D_j| < N_j |D_i|`. The walk
//! keeps the three differences `e_ij = N_i |D_j| - N_j |D_i|` (i < j), less
//! one so that "no later" is a sign test; a step along axis `i` adds
//! `ONE |D_j|` to `e_ij` or subtracts `ONE |D_j|` from `e_ji`, so a step is two
//! additions and three sign tests. No division, no rounding, no drift over any
//! length. `N` itself is not kept: the cell and the origin give it when a hit
//! must be placed in the cube.
//!
//! **Tie rule.** When boundaries are crossed at the same `t` (the ray passes
//! through a cube edge or corner), the lowest axis (x, then y, then z) steps
//! first, one axis per step. The extra cube visited meets the ray in a single
//! point, which keeps the walk conservative: every cube the ray crosses with
//! positive length is visited, and every visited closed cube touches the ray.
//!
//! **Zero components.** An axis with `D_i = 0` never steps. A ray lying in a
//! cube face plane (`D_i = 0`, origin on a boundary) walks the cubes on the
//! upper side of the plane; closed registration of spheres (see
//! [`crate::subregion`]) makes that sufficient.
//!
//! The state is entirely `(origin, direction, cell)`: [`DigitalLine::resume`]
//! rebuilds the differences from the cell, so a ray passed to another node
//! continues bit-identically.

use crate::error::{Error, Field};
use crate::geometry::{Grid, Line, zip3};
use crate::limits::{
    DIR_FRAC, MAX_BOUNDARY_RAW, MAX_COORD_RAW, MAX_GRID, MIN_COORD_RAW, ONE, POS_FRAC, Scalar,
};

/// Exact integer walk of the unit cubes along a [`Line`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DigitalLine {
    cell: [i32; 3],
    /// +1, -1 or 0 per axis.
    step: [i32; 3],
    /// `ONE |D_i|`: what a step along another axis adds to a difference.
    inc: [i64; 3],
    /// `e01 - 1, e02 - 1, e12 - 1` with `e_ij = N_i |D_j| - N_j |D_i|`: axis
    /// `i` goes no later than `j` iff its entry is negative. A pair with an
    /// axis that does not move holds a constant that orders that axis last.
    e: [i64; 3],
    /// Axis whose boundary comes first (tie: lowest axis).
    next: usize,
}

/// A parameter `t = num / den * 2^14` (num raw Q16.16 distance, den raw Q2.30).
#[derive(Clone, Copy)]
struct Ratio {
    num: i64,
    den: i64,
}

impl Ratio {
    fn lt(self, other: Ratio) -> bool {
        i128::from(self.num) * i128::from(other.den) < i128::from(other.num) * i128::from(self.den)
    }
}

// Boundary distances fit `u32` (so their products with direction components fit `u64`).
const _: () = assert!(MAX_BOUNDARY_RAW < u32::MAX as i64);

impl DigitalLine {
    /// Starts the walk where the line enters the grid, at `t >= 0`.
    ///
    /// Returns `None` if the line does not cross the grid with positive length.
    pub fn enter(line: &Line, grid: &Grid) -> Option<Self> {
        if let Some(cell) = origin_cell_inside(line, grid) {
            return Self::resume(line, cell).ok();
        }
        let (t_in, _) = entry_interval(line, grid)?;
        let o = line.origin();
        let d = line.dir();
        let mut cell = [0i32; 3];
        for (axis, out) in cell.iter_mut().enumerate() {
            let (oj, dj) = (i64::from(get32(&o, axis)), i64::from(get32(&d, axis)));
            let size = i64::from(grid.size().get(axis).copied().unwrap_or(1));
            // Entry point coordinate in raw units: (O den + num D) / den, exact.
            let num = i128::from(oj) * i128::from(t_in.den) + i128::from(t_in.num) * i128::from(dj);
            let den = t_in.den * ONE;
            *out = entry_index(num, den, dj.signum(), oj, size);
        }
        Self::resume(line, cell).ok()
    }

    /// Continues the walk of `line` from `cell`, as a node does with a received ray.
    ///
    /// Fails if the line does not pass through the closed cube `cell` ahead of
    /// its origin, or if `cell` lies more than 2^14 cubes from the grid's
    /// corner along an axis: such a state cannot come from a real walk.
    pub fn resume(line: &Line, cell: [i32; 3]) -> Result<Self, Error> {
        // Straight-line code over the three axes, the walk built once at the
        // end: this runs for every ray a node receives, and a loop over
        // indexed arrays and a zeroed walk filled in field by field cost half
        // of it again on a Cortex-M3.
        let (origin, d) = (line.origin(), line.dir());
        let [n0, n1, n2] = zip3(zip3(origin, d, |o, d| (o, d)), cell, |(o, d), c| boundary_distance(o, d, c));
        let n = [n0?, n1?, n2?];
        // Some axis moves: a `Line`'s direction is a checked unit vector
        // (every `Direction` passes `Direction::from_bits`).
        let abs_d = d.map(i32::unsigned_abs);
        let e = [difference(n, abs_d, 0, 1), difference(n, abs_d, 0, 2), difference(n, abs_d, 1, 2)];
        let next = first_axis(e);
        let inc = abs_d.map(|d| ONE * i64::from(d));
        if !entered_before_exit(e, inc, next) {
            return Err(Error::OutOfRange(Field::Cell));
        }
        let step = d.map(i32::signum);
        Ok(DigitalLine { cell, step, inc, e, next })
    }

    /// The current unit cube.
    #[inline]
    pub fn cell(&self) -> [i32; 3] {
        self.cell
    }

    /// The axis along which the walk leaves the current cube.
    pub fn exit_axis(&self) -> usize {
        self.next
    }

    /// Moves to the next cube; returns the axis stepped along. Inlined: it is
    /// the inner loop of every walk.
    #[inline]
    pub fn step(&mut self) -> usize {
        let axis = self.next;
        let [e01, e02, e12] = &mut self.e;
        let [i0, i1, i2] = self.inc;
        match axis {
            0 => {
                *e01 += i1;
                *e02 += i2;
            }
            1 => {
                *e01 -= i0;
                *e12 += i2;
            }
            _ => {
                *e02 -= i0;
                *e12 -= i1;
            }
        }
        if let (Some(c), Some(s)) = (self.cell.get_mut(axis), self.step.get(axis)) {
            *c += *s;
        }
        self.next = self.first_axis();
        axis
    }

    /// Whether `t <= t_exit`, the parameter at which the walk of `line`
    /// leaves the current cube. Exact: `t |D_a| <= N_a 2^30`. The walk keeps
    /// neither the line's origin nor `|D|`: a smaller walk is set up faster
    /// for every ray a node receives, and its line is at hand where this is asked.
    pub fn exits_at_or_after(&self, line: &Line, t: Scalar) -> bool {
        let a = self.next;
        let abs_d = i64::from(line.dir().get(a).copied().unwrap_or(0).unsigned_abs());
        i64::from(t.to_bits()) * abs_d <= self.boundary(line.origin(), a) << DIR_FRAC
    }

    /// `N_a`: raw distance from `origin` to the current cube's boundary ahead
    /// along moving axis `a`.
    fn boundary(&self, origin: [i32; 3], a: usize) -> i64 {
        let (c, o) = (i64::from(get32(&self.cell, a)), i64::from(get32(&origin, a)));
        if get32(&self.step, a) > 0 { (c + 1) * ONE - o } else { o - c * ONE }
    }

    /// Lowest axis among those whose boundary is crossed first: axis `i` goes
    /// no later than `j > i` iff `e_ij <= 0`, that is, iff its entry is negative.
    #[inline]
    fn first_axis(&self) -> usize {
        first_axis(self.e)
    }
}

/// A received ray's cube from its wire form ([`link_proto::RayMsg::cell`]),
/// for [`DigitalLine::resume`]. Written out per axis: `map` over the array
/// compiles to a loop on a Cortex-M3, which cost a received ray's set-up 17
/// instructions.
#[inline]
pub fn wire_cell([x, y, z]: [u16; 3]) -> [i32; 3] {
    [i32::from(x), i32::from(y), i32::from(z)]
}

/// Lowest axis among those whose boundary is crossed first, from the
/// differences `e_ij - 1`: axis `i` goes no later than `j > i` iff `e_ij <= 0`,
/// that is, iff its entry is negative.
#[inline]
fn first_axis([e01, e02, e12]: [i64; 3]) -> usize {
    match (e01 < 0, e02 < 0, e12 < 0) {
        (true, true, _) => 0,
        (true, false, _) | (false, _, false) => 2,
        (false, _, true) => 1,
    }
}

/// `e_ij - 1` (i < j) for boundary distances `n`; a moving axis always
/// goes before one that does not move (whose pairs never change, as its
/// `ONE |D|` is 0).
#[inline]
fn difference(n: [u32; 3], abs_d: [u32; 3], i: usize, j: usize) -> i64 {
    let (ni, nj) = (n.get(i).copied().unwrap_or(0), n.get(j).copied().unwrap_or(0));
    let (di, dj) = (abs_d.get(i).copied().unwrap_or(0), abs_d.get(j).copied().unwrap_or(0));
    match (di != 0, dj != 0) {
        // Each product is under 2^63: their difference fits `i64`.
        (true, true) => (u64::from(ni) * u64::from(dj)) as i64 - (u64::from(nj) * u64::from(di)) as i64 - 1,
        (true, false) => i64::MIN,
        _ => i64::MAX,
    }
}

/// Whether the line enters the cube no later than it leaves it through
/// axis `next`'s boundary, from the walk's differences.
///
/// Moving axis `i` enters its slab at `t = (N_i - ONE) / |D_i|` (at or before
/// 0 when its slab holds the origin), and the cube is entered when the last
/// moving axis enters; it is left at `N_a / |D_a|`, `a = next`. So the test
/// is `(N_i - ONE) |D_a| <= N_a |D_i|` for every moving `i != a` (for
/// `i = a` it always holds), that is `N_i |D_a| - N_a |D_i| <= ONE |D_a|`,
/// whose left side is `e_ia + 1` for `i < a` and `-(e_ai + 1)` for `i > a`:
/// no product beyond those the walk keeps. An axis that does not move
/// (`ONE |D| = 0`) never bounds the entry (its pairs hold constants, not
/// differences).
#[inline]
fn entered_before_exit([e01, e02, e12]: [i64; 3], inc: [i64; 3], next: usize) -> bool {
    let [i0, i1, i2] = inc;
    // `e_ia + 1 <= inc_a` and `-(e_ai + 1) <= inc_a`; an `e` of a moving pair
    // is under 2^62 in magnitude and `inc` under 2^47, so neither side wraps.
    let before = |e: i64, inc: i64| e < inc;
    let after = |e: i64, inc: i64| e + inc >= -1;
    match next {
        0 => (i1 == 0 || after(e01, i0)) && (i2 == 0 || after(e02, i0)),
        1 => (i0 == 0 || before(e01, i1)) && (i2 == 0 || after(e12, i1)),
        _ => (i0 == 0 || before(e02, i2)) && (i1 == 0 || before(e12, i2)),
    }
}

/// `N`: the raw distance along one axis from the origin `o` to the boundary
/// of cell `c` ahead in the direction of travel `d`; 0 for an axis that does
/// not move, whose origin must then lie in the cell's closed slab. Fails for
/// a cell behind the origin or farther than any walk reaches.
///
/// In `i32`, which a Cortex-M3 does in one instruction where `i64` takes two
/// or three: a cell within [`MAX_CELL`] cubes of the grid's corner has
/// `|c ONE| <= 2^30`, an accepted origin `|o| < 2^29.4`, so `c ONE + ONE - o`
/// and `o - c ONE` fit (asserted below). A cell farther out is no cube a
/// walk visits (walks stay in the grid), and is rejected first.
#[inline]
fn boundary_distance(o: i32, d: i32, c: i32) -> Result<u32, Error> {
    if c.unsigned_abs() > MAX_CELL {
        return Err(Error::OutOfRange(Field::Cell));
    }
    let lower = c << POS_FRAC;
    let n = if d > 0 {
        lower + ONE32 - o
    } else if d < 0 {
        o - lower
    } else if o >= lower && o - lower <= ONE32 {
        return Ok(0);
    } else {
        return Err(Error::OutOfRange(Field::Cell));
    };
    match u32::try_from(n) {
        Ok(n) if i64::from(n) <= MAX_BOUNDARY_RAW => Ok(n),
        _ => Err(Error::OutOfRange(Field::Cell)),
    }
}

/// The farthest cell from the grid's corner, per axis, that a received ray may name.
const MAX_CELL: u32 = 1 << 14;
/// [`ONE`] as `i32`.
const ONE32: i32 = ONE as i32;

// The bounds `boundary_distance` relies on.
const _: () = {
    let lower = (MAX_CELL as i64) * ONE;
    assert!(lower <= 1 << 30);
    let o = if MAX_COORD_RAW > -MIN_COORD_RAW { MAX_COORD_RAW } else { -MIN_COORD_RAW };
    assert!(lower + ONE + o <= i32::MAX as i64);
    assert!(MAX_CELL > MAX_GRID as u32);
};

/// The parameter interval `(t_in, t_out)` over which the line is inside the grid
/// box, with `0 <= t_in < t_out`; `None` if there is no positive-length overlap.
fn entry_interval(line: &Line, grid: &Grid) -> Option<(Ratio, Ratio)> {
    let o = line.origin();
    let d = line.dir();
    let mut t_in = Ratio { num: 0, den: 1 };
    let mut t_out: Option<Ratio> = None;
    for axis in 0..3 {
        let (oi, di) = (i64::from(get32(&o, axis)), i64::from(get32(&d, axis)));
        let size = i64::from(grid.size().get(axis).copied().unwrap_or(0)) * ONE;
        let (near, far) = match di.signum() {
            1 => (-oi, size - oi),
            -1 => (oi - size, oi),
            _ if oi >= 0 && oi <= size => continue,
            _ => return None,
        };
        let den = di.abs();
        let (near, far) = (Ratio { num: near, den }, Ratio { num: far, den });
        if t_in.lt(near) {
            t_in = near;
        }
        if t_out.is_none_or(|t| far.lt(t)) {
            t_out = Some(far);
        }
    }
    let t_out = t_out?;
    t_in.lt(t_out).then_some((t_in, t_out))
}

/// The cube a line starts in when its origin lies strictly inside the grid
/// on every axis, or `None`.
///
/// Such a line enters at `t = 0` with a positive length inside, and its
/// entry cube is the one [`entry_index`] finds for the origin itself: the
/// cube below a boundary the origin lies on when moving down, else the cube
/// at or above it. Every shadow ray and reflection from a sphere inside the
/// grid starts so; found here without [`entry_interval`]'s 128-bit
/// comparisons and products, which a Cortex-M3 builds from 32-bit ones
/// (each child ray's entry took 900 instructions; see `scripts/profile-kernel.sh shade`).
fn origin_cell_inside(line: &Line, grid: &Grid) -> Option<[i32; 3]> {
    let ([o0, o1, o2], [d0, d1, d2], [n0, n1, n2]) = (line.origin(), line.dir(), grid.size());
    // Axis by axis, so that a line from outside (every initial ray from an
    // eye outside the grid) stops at its first axis outside.
    let cube = |o: i32, d: i32, size: u16| {
        let inside = o > 0 && i64::from(o) < i64::from(size) * ONE;
        // o > 0, so the shift is floor(o / ONE), and ceil(o / ONE) - 1
        // moving down.
        inside.then(|| (if d < 0 { o - 1 } else { o }) >> POS_FRAC)
    };
    Some([cube(o0, d0, n0)?, cube(o1, d1, n1)?, cube(o2, d2, n2)?])
}

/// The cube index along one axis of the entry point `num / den` (raw units,
/// `den > 0`), on the lower side of a boundary when moving down (`sign < 0`),
/// clamped into the grid's `size` cubes; `origin`'s cube when not moving.
///
/// Outside `(0, den size]` the clamp decides; inside, `num < 2^56`, so one
/// 64-bit division does what a 128-bit one did (a Cortex-M divides 128-bit
/// integers in software, bit by bit).
fn entry_index(num: i128, den: i64, sign: i64, origin: i64, size: i64) -> i32 {
    let index = if sign == 0 {
        origin.div_euclid(ONE)
    } else if num <= 0 {
        0
    } else if num > i128::from(den) * i128::from(size) {
        size - 1
    } else {
        let (n, d) = (num as u64, den as u64);
        // floor(num / den) moving up; ceil(num / den) - 1 moving down.
        let n = if sign > 0 { n } else { n - 1 };
        n.checked_div(d).unwrap_or(0) as i64
    };
    index.clamp(0, size - 1) as i32
}

fn get32(a: &[i32; 3], i: usize) -> i32 {
    a.get(i).copied().unwrap_or(0)
}
