//! Exact rational reference for the digital line.
//!
//! Lists every boundary plane the ray crosses inside the grid with its exact
//! parameter, sorts the crossings by `(t, axis)` and applies them in order. This
//! is the same specification as the firmware's (start cube by direction, lowest
//! axis first on ties), computed a different way.

// Reference code reads best as per-axis formulas indexed by axis.
#![allow(clippy::needless_range_loop)]

use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{One, Signed, Zero};

/// Exact rational number.
pub type Q = BigRational;

fn q(n: i64, d: i64) -> Q {
    Q::new(BigInt::from(n), BigInt::from(d))
}

/// A quantised ray in exact rational cube units.
#[derive(Clone, Debug)]
pub struct RationalRay {
    /// Origin in cubes.
    pub o: [Q; 3],
    /// Direction in cubes per unit t.
    pub d: [Q; 3],
}

impl RationalRay {
    /// From raw Q16.16 origin and Q2.30 direction.
    pub fn from_raw(origin: [i32; 3], dir: [i32; 3]) -> Self {
        Self { o: origin.map(|v| q(v as i64, 1 << 16)), d: dir.map(|v| q(v as i64, 1 << 30)) }
    }

    /// The point at `t`.
    pub fn at(&self, t: &Q) -> [Q; 3] {
        [0, 1, 2].map(|i| &self.o[i] + t * &self.d[i])
    }
}

/// The parameter interval where the ray is inside the box `[lo, hi]`, if non-empty.
pub fn slab(ray: &RationalRay, lo: [i64; 3], hi: [i64; 3]) -> Option<(Q, Q)> {
    let mut t_in: Option<Q> = None;
    let mut t_out: Option<Q> = None;
    for i in 0..3 {
        if ray.d[i].is_zero() {
            if ray.o[i] < q(lo[i], 1) || ray.o[i] > q(hi[i], 1) {
                return None;
            }
            continue;
        }
        let a = (q(lo[i], 1) - &ray.o[i]) / &ray.d[i];
        let b = (q(hi[i], 1) - &ray.o[i]) / &ray.d[i];
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        t_in = Some(t_in.map_or(near.clone(), |t: Q| t.max(near)));
        t_out = Some(t_out.map_or(far.clone(), |t: Q| t.min(far)));
    }
    Some((t_in?, t_out?))
}

/// The grid interval `[t_in, t_out]` with `t >= 0`, if it has positive length.
pub fn grid_interval(ray: &RationalRay, grid: [u16; 3]) -> Option<(Q, Q)> {
    let hi = grid.map(i64::from);
    let (t_in, t_out) = slab(ray, [0; 3], hi)?;
    let t_in = t_in.max(Q::zero());
    (t_in < t_out).then_some((t_in, t_out))
}

/// The cubes the reference walk visits inside the grid, in order.
pub fn walk(origin: [i32; 3], dir: [i32; 3], grid: [u16; 3]) -> Vec<[i32; 3]> {
    let ray = RationalRay::from_raw(origin, dir);
    let Some((t_in, _)) = grid_interval(&ray, grid) else {
        return Vec::new();
    };
    let p = ray.at(&t_in);
    let mut cell = [0i64; 3];
    for i in 0..3 {
        let v = if ray.d[i].is_positive() {
            p[i].floor()
        } else if ray.d[i].is_negative() {
            p[i].ceil() - Q::one()
        } else {
            ray.o[i].floor()
        };
        let v: i64 = v.to_integer().try_into().unwrap();
        cell[i] = v.clamp(0, grid[i] as i64 - 1);
    }
    // Every plane crossing ahead of the start cube, up to the grid's far side.
    let mut events: Vec<(Q, usize, i64)> = Vec::new();
    for i in 0..3 {
        let size = grid[i] as i64;
        let planes: Vec<i64> = if ray.d[i].is_positive() {
            (cell[i] + 1..=size).collect()
        } else if ray.d[i].is_negative() {
            (0..=cell[i]).rev().collect()
        } else {
            Vec::new()
        };
        let step = if ray.d[i].is_positive() { 1 } else { -1 };
        for plane in planes {
            events.push(((q(plane, 1) - &ray.o[i]) / &ray.d[i], i, step));
        }
    }
    events.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut cells = vec![cell.map(|v| v as i32)];
    for (_, axis, step) in events {
        cell[axis] += step;
        if cell[axis] < 0 || cell[axis] >= grid[axis] as i64 {
            break;
        }
        cells.push(cell.map(|v| v as i32));
    }
    cells
}

/// Geometric checks of a walk that do not depend on the tie rule: every cube
/// touches the ray inside the grid, the cubes chain without a gap from `t_in`
/// to `t_out`, and every cube whose interior the ray crosses with positive
/// length is visited. Returns a description of the first violation.
pub fn check_walk(origin: [i32; 3], dir: [i32; 3], grid: [u16; 3], cells: &[[i32; 3]]) -> Result<(), String> {
    let ray = RationalRay::from_raw(origin, dir);
    let Some((t_in, t_out)) = grid_interval(&ray, grid) else {
        return if cells.is_empty() { Ok(()) } else { Err("walk of a ray that misses the grid".into()) };
    };
    if cells.is_empty() {
        return Err("ray crosses the grid but walk is empty".into());
    }
    let mut reach = t_in.clone();
    for c in cells {
        let lo = c.map(i64::from);
        let hi = lo.map(|v| v + 1);
        let Some((a, b)) = slab(&ray, lo, hi) else {
            return Err(format!("cube {c:?} does not touch the ray"));
        };
        if a > b || b < t_in || a > t_out {
            return Err(format!("cube {c:?} does not touch the ray inside the grid"));
        }
        if a > reach {
            return Err(format!("gap before cube {c:?}"));
        }
        reach = reach.max(b);
    }
    if reach < t_out {
        return Err("walk ends before the ray leaves the grid".into());
    }
    // Positive-length crossings: between consecutive distinct plane crossings the
    // ray is inside one cube; if no coordinate is an integer there, it must be visited.
    let mut ts = vec![t_in.clone(), t_out.clone()];
    for i in 0..3 {
        if ray.d[i].is_zero() {
            continue;
        }
        for plane in 0..=grid[i] as i64 {
            let t = (q(plane, 1) - &ray.o[i]) / &ray.d[i];
            if t > t_in && t < t_out {
                ts.push(t);
            }
        }
    }
    ts.sort();
    ts.dedup();
    for w in ts.windows(2) {
        let mid = (&w[0] + &w[1]) / q(2, 1);
        let p = ray.at(&mid);
        if p.iter().any(|x| x.is_integer()) {
            continue;
        }
        let cell: [i32; 3] = p.map(|x| i32::try_from(x.floor().to_integer()).unwrap());
        if !cells.contains(&cell) {
            return Err(format!("cube {cell:?} crossed with positive length but not visited"));
        }
    }
    Ok(())
}
