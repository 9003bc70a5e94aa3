//! Exact reference for the ray/sphere decision on the quantised ray.
//!
//! Uses the classic discriminant `b^2 - a c` in big integers (the firmware uses
//! Lagrange's form in i128), and the roots in f64 from the exact big-integer
//! coefficients by the stable formula, accurate to about 1e-11 cube.

use num_bigint::BigInt;
use num_traits::{Signed, ToPrimitive, Zero};

/// The exact answer for one ray and one sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExactHit {
    /// Ray parameter of the hit, in cubes along a unit direction.
    pub t: f64,
    /// Origin inside the sphere.
    pub inside: bool,
}

/// Exact decision and near-exact depth, on raw inputs (Q16.16 origin, centre and
/// radius; Q2.30 direction). Same conventions as the firmware: the hit at
/// `t >= 0`, the exit point from inside, an origin on the surface counts as
/// outside.
pub fn exact_hit(origin: [i32; 3], dir: [i32; 3], center: [i32; 3], radius: i32) -> Option<ExactHit> {
    let f: Vec<BigInt> = (0..3).map(|i| BigInt::from(origin[i] as i64 - center[i] as i64)).collect();
    let d: Vec<BigInt> = dir.iter().map(|&v| BigInt::from(v)).collect();
    let a: BigInt = d.iter().map(|x| x * x).sum();
    let b: BigInt = f.iter().zip(&d).map(|(x, y)| x * y).sum();
    let r2 = BigInt::from(radius as i64 * radius as i64);
    let c: BigInt = f.iter().map(|x| x * x).sum::<BigInt>() - r2;
    // Units: a 2^-60, b 2^-46, c 2^-32; b^2 and a c both 2^-92.
    let disc = &b * &b - &a * &c;
    if disc.is_negative() {
        return None;
    }
    let af = a.to_f64().unwrap() / 2f64.powi(60);
    let bf = b.to_f64().unwrap() / 2f64.powi(46);
    let cf = c.to_f64().unwrap() / 2f64.powi(32);
    let s = disc.to_f64().unwrap().sqrt() / 2f64.powi(46);
    let b_neg = b.is_negative();
    if c.is_positive() || c.is_zero() {
        if !b_neg {
            return None;
        }
        let t = if c.is_zero() { 0.0 } else { cf / (s - bf) };
        return Some(ExactHit { t, inside: false });
    }
    let t = if b_neg { (s - bf) / af } else { cf / -(bf + s) };
    Some(ExactHit { t, inside: true })
}
