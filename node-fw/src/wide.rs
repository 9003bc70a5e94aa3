//! Exact wide-integer steps for a 32-bit core: square roots, squares and
//! quotients of values up to about 2^90, computed with 64-bit operations.
//!
//! A Cortex-M divides and takes roots of 128-bit integers in software, bit by
//! bit: thousands of instructions each. The kernels' operands are narrower
//! than 128 bits, so these functions reach the same exact results through a
//! 64-bit estimate and one correction. They are exact on every input; the
//! narrow paths are only faster, never different.

/// `a b` as a 128-bit value, from four 32 x 32-bit products.
#[inline]
pub fn mul_wide(a: u64, b: u64) -> u128 {
    const LOW: u64 = 0xffff_ffff;
    let (a1, a0, b1, b0) = (a >> 32, a & LOW, b >> 32, b & LOW);
    let mid = u128::from(a0 * b1) + u128::from(a1 * b0);
    (u128::from(a1 * b1) << 64) + (mid << 32) + u128::from(a0 * b0)
}

/// `a^2` as a 128-bit value.
#[inline]
pub fn square(a: u64) -> u128 {
    mul_wide(a, a)
}

/// `floor(sqrt(n))`.
pub fn isqrt(n: u128) -> u128 {
    match u64::try_from(n) {
        Ok(n) => u128::from(isqrt64(n)),
        Err(_) if n >> 92 == 0 => u128::from(isqrt_by_tangent(n)),
        Err(_) => u128::from(isqrt_beyond_92(n)),
    }
}

/// `floor(sqrt(n))` of a 64-bit value.
fn isqrt64(n: u64) -> u64 {
    match u32::try_from(n) {
        Ok(n) => u64::from(n.isqrt()),
        Err(_) => {
            // The root of the top 31 or 32 bits, then the tangent there: with
            // k <= 16 its error is under one (see `tangent_step`).
            let k = (64 - n.leading_zeros()).saturating_sub(31) / 2;
            let s = u64::from(((n >> (2 * k)) as u32).isqrt());
            tangent_step(u128::from(n), s << k)
        }
    }
}

/// `floor(sqrt(n))` for `2^64 <= n < 2^92`.
fn isqrt_by_tangent(n: u128) -> u64 {
    // The top 63 or 64 bits have a root s >= 2^31; k <= 14.
    let k = (128 - n.leading_zeros()).saturating_sub(63) / 2;
    let s = isqrt64((n >> (2 * k)) as u64);
    tangent_step(n, s << k)
}

/// `floor(sqrt(n))` for `n >= 2^92` (a sphere test's discriminant reaches
/// 2^106 with the largest radii).
///
/// The root of `n / 4^j`, cut to 91 or 92 bits, is `s >= 2^45`, and `a = s
/// 2^j` (`j <= 18`) is under the root by less than `2^j`: the tangent at `a`
/// overshoots it by under `2^(j-46)`, less than one, as in [`tangent_step`].
/// Its step `(n - a^2) / 2a` (up to 2^83 over at least 2^46) is taken from
/// both shifted right by 20, which leaves it at most two under; the root is
/// then found from squares, a step or two either way.
fn isqrt_beyond_92(n: u128) -> u64 {
    let bits = 128 - n.leading_zeros();
    let j = (bits - 91) / 2;
    let a = isqrt_by_tangent(n >> (2 * j)) << j;
    let step = ((n - square(a)) >> 20) as u64 / ((u128::from(a) >> 19) as u64 + 1);
    let mut y = a + step;
    while square(y) > n {
        y -= 1;
    }
    while y < u64::MAX && square(y + 1) <= n {
        y += 1;
    }
    y
}

/// `floor(sqrt(n))` from `a = s 2^k`, `s = floor(sqrt(n / 4^k)) >= 2^15` (or
/// `>= 2^31` with `k <= 14`).
///
/// `0 <= sqrt(n) - a < 2^k`, so the tangent at `a`, `y = a + (n - a^2) / 2a`,
/// lies above the root by `(sqrt(n) - a)^2 / 2a < 2^(k-16)` (`2^(k-32)`), under
/// one: `floor(y)` is the root or one more, which one multiplication decides.
/// `n - a^2 < 2^(k+1) a + 4^k` and `(y - a)(y + a)` fit in 64 bits.
#[inline]
fn tangent_step(n: u128, a: u64) -> u64 {
    let d = (n - square(a)) as u64;
    let y = a + d / (2 * a);
    if (y - a) * (y + a) > d { y - 1 } else { y }
}

/// `floor(n 2^30 / d)`, or `None` if that is `2^31` or more or `d` is 0:
/// a ray's depth in Q16.16 from a sphere test's numerator and denominator
/// (up to 2^63 each, in units whose ratio needs the 2^30).
///
/// In 128-bit arithmetic this is a software division of a 94-bit value,
/// thousands of instructions on a Cortex-M3. Here: the quotient is under
/// 2^31 exactly when `n < 2 d`. For `d < 2^33`, `n 2^30 < 2^64` and one
/// 64-bit division is exact. Otherwise both are shifted right by `e` so that
/// `d >> e` has 32 bits, and dividing by `(d >> e) + 1` gives an estimate at
/// or under the quotient by at most 2 (`(x + y) / (y (y + 1)) < 1 + 2^-31`
/// for `x / y < 2`, `y >= 2^31`); the exact remainder, a 64 x 64-bit product
/// taken from `n 2^30`, corrects it.
#[inline]
pub fn div_shl30(n: u64, d: u64) -> Option<u32> {
    if d == 0 || n >> 1 >= d {
        return None;
    }
    if d >> 33 == 0 {
        // n < 2 d < 2^34, so n 2^30 < 2^64.
        return u32::try_from((n << 30) / d).ok();
    }
    let e = 32 - d.leading_zeros();
    let wide = u128::from(n) << 30;
    // wide < 2 d 2^30 < 2^(63 + e): the shifted value fits 64 bits.
    let mut q = ((wide >> e) as u64) / ((d >> e) + 1);
    let mut rem = wide - mul_wide(q, d);
    while rem >= u128::from(d) {
        q += 1;
        rem -= u128::from(d);
    }
    u32::try_from(q).ok()
}

/// Division of `c 2^30` by a fixed `d` in `[2^40, 2^42]` for `c <= d`, by
/// a reciprocal: two 64-bit divisions once, then a multiplication and one
/// correction per quotient (a unit direction divides three components by
/// its length).
#[derive(Debug, Clone, Copy)]
pub struct Divisor30 {
    d: u64,
    /// `floor(2^72 / d)`, in `[2^30, 2^32]`.
    inv: u64,
}

impl Divisor30 {
    /// The divisor `d`, or `None` outside `[2^40, 2^42]`.
    pub fn new(d: u64) -> Option<Self> {
        if !(1 << 40..=1 << 42).contains(&d) {
            return None;
        }
        // 2^72 = 2^51 2^21, one long-division step each: r1 2^21 < 2^63.
        let (q1, r1) = ((1u64 << 51) / d, (1u64 << 51) % d);
        Some(Self { d, inv: (q1 << 21) + (r1 << 21) / d })
    }

    /// `floor(c 2^30 / d)`, or `None` if `c > d`.
    ///
    /// `inv` is below `2^72 / d` by less than one, so `c inv / 2^42` is below
    /// `c 2^30 / d` by less than `c / 2^42 <= 1`: the estimate is the quotient
    /// or one less. The remainder, under `2 d < 2^43`, is exact in wrapping
    /// 64-bit arithmetic and tells which.
    #[inline]
    pub fn div_shl30(&self, c: u64) -> Option<u64> {
        if c > self.d {
            return None;
        }
        let q = (mul_wide(c, self.inv) >> 42) as u64;
        let rem = (c << 30).wrapping_sub(q.wrapping_mul(self.d));
        Some(if rem >= self.d { q + 1 } else { q })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn is_root(n: u128, r: u128) -> bool {
        r * r <= n && (r + 1).checked_mul(r + 1).is_none_or(|s| s > n)
    }

    #[test]
    fn roots_at_the_edges_of_every_path() {
        for bits in 0..127u32 {
            let p = 1u128 << bits;
            for n in [p - 1, p, p + 1, p.saturating_mul(3) / 2] {
                assert!(is_root(n, isqrt(n)), "n = {n}");
            }
        }
        for r in [(1u128 << 32) - 1, 1 << 32, (1 << 46) - 1, 1 << 46, (1 << 47) - 3] {
            for n in [r * r - 1, r * r, r * r + 2 * r] {
                assert!(is_root(n, isqrt(n)), "n = {n}");
            }
        }
        assert_eq!(isqrt(u128::MAX), u128::from(u64::MAX));
    }

    #[test]
    fn depth_quotients_at_the_edges() {
        let want = |n: u64, d: u64| {
            u32::try_from((u128::from(n) << 30) / u128::from(d)).ok().filter(|&q| q < 1 << 31)
        };
        for bits in 0..64u32 {
            let d = 1u64 << bits;
            for d in [d - 1, d, d + 1, d.saturating_mul(3) / 2, u64::MAX >> (63 - bits)] {
                if d == 0 {
                    assert_eq!(div_shl30(5, 0), None);
                    continue;
                }
                for n in [
                    0,
                    1,
                    d / 3,
                    d - 1,
                    d,
                    d.saturating_add(1),
                    (2 * u128::from(d) - 1).min(u128::from(u64::MAX)) as u64,
                ] {
                    assert_eq!(div_shl30(n, d), want(n, d), "n = {n}, d = {d}");
                }
                assert_eq!(div_shl30(d.saturating_mul(2), d), want(d.saturating_mul(2), d), "d = {d}");
            }
        }
        assert_eq!(div_shl30(u64::MAX, u64::MAX), Some(1 << 30));
    }

    #[test]
    fn quotients_at_the_edges() {
        for d in [1u64 << 40, (1 << 40) + 1, (1 << 42) - 1, 1 << 42, 3 << 40] {
            let v = Divisor30::new(d).unwrap();
            for c in [0, 1, d / 3, d - 1, d] {
                assert_eq!(v.div_shl30(c).map(u128::from), Some((u128::from(c) << 30) / u128::from(d)));
            }
            assert_eq!(v.div_shl30(d + 1), None);
        }
        assert!(Divisor30::new((1 << 40) - 1).is_none() && Divisor30::new((1 << 42) + 1).is_none());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn roots_are_exact(n in any::<u128>(), shift in 0u32..128) {
            let n = n >> shift;
            prop_assert!(is_root(n, isqrt(n)), "n = {}", n);
        }

        #[test]
        fn reciprocal_quotients_are_exact(d in (1u64 << 40)..=(1 << 42), c in any::<u64>(), near in any::<bool>()) {
            // Numerators near d as often as anywhere below it.
            let c = if near { d - (c % 1024).min(d) } else { c % (d + 1) };
            let want = (u128::from(c) << 30) / u128::from(d);
            prop_assert_eq!(Divisor30::new(d).and_then(|v| v.div_shl30(c)).map(u128::from), Some(want));
        }

        #[test]
        fn depth_quotients_are_exact(n in any::<u64>(), d in any::<u64>(), shift in 0u32..64, near in any::<bool>()) {
            // Divisors of every length, and numerators near the 2^31 limit as
            // often as anywhere below it.
            let d = d >> shift;
            let n = if near { (2 * u128::from(d)).saturating_sub(u128::from(n % 4096)) as u64 } else { n >> (shift / 2) };
            let want = if d == 0 { None } else { u32::try_from((u128::from(n) << 30) / u128::from(d)).ok() };
            prop_assert_eq!(div_shl30(n, d), want.filter(|&q| q < 1 << 31));
        }

        #[test]
        fn wide_products_are_exact(a in any::<u64>(), b in any::<u64>()) {
            prop_assert_eq!(mul_wide(a, b), u128::from(a) * u128::from(b));
        }

        #[test]
        fn squares_are_exact(a in any::<u64>(), shift in 0u32..64) {
            let a = a >> shift;
            prop_assert_eq!(square(a), u128::from(a) * u128::from(a));
        }
    }
}
