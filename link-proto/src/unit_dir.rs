//! A unit direction in nine bytes rather than twelve: its largest
//! component left out, since the other two fix it to within a few units.
//!
//! A node's directions are unit vectors in Q2.30 (`Direction::normalize`
//! in node-fw: the vector over the integer square root of its squared
//! length, each component truncated toward zero), so `d.d` lies within
//! about 2^32 of 2^60. The largest component `c` is at least 2^30 /
//! sqrt(3), so its magnitude is `isqrt(2^60 - a^2 - b^2) - k` for a `k`
//! from -1 to 2 (over 600 000 normalised directions of every scale and
//! near every axis: -1 where the square root's truncation leaves `c` at
//! 2^30 and a small `b` beside it, 2 seldom; a test in node-fw holds every
//! normalised direction to the compact form). The wire carries `a` and `b`
//! (31 bits each, offset by 2^30), which component `c` is, its sign and
//! `k + 1` (two bits): 67 bits, in nine bytes whose other five bits are
//! zero. A direction that is not so (no node accepts it as a ray's anyway)
//! goes whole, in twelve.
//!
//! Each direction has one form: [`expand`] takes only bytes [`compact`]
//! writes, so a ray still has exactly one encoding.
//!
//! Layout, little-endian: bits 0..31 `a + 2^30`, 31..62 `b + 2^30`, 62..64
//! the index of `c`; then a byte of `c`'s sign (bit 0) and `k + 1` (bits 1..3).

/// The compact form's length.
pub const COMPACT_LEN: usize = 9;

/// The other two components lie in `[-OFFSET, OFFSET)`: 31 bits.
const OFFSET: i64 = 1 << 30;
const LOW31: u64 = (1 << 31) - 1;
/// A unit vector's `d.d` in Q2.30 squared.
const ONE_SQUARED: u64 = 1 << 60;
/// `k` runs from `-K_BIAS` to `3 - K_BIAS`, written plus `K_BIAS`.
const K_BIAS: i64 = 1;

/// `d`'s compact form, if it has one.
pub fn compact(d: [i32; 3]) -> Option<[u8; COMPACT_LEN]> {
    let (m, c, a, b) = split(d);
    let k = root_offset(rest(a, b)?, c.unsigned_abs())?;
    let low = ((i64::from(a) + OFFSET) as u64 & LOW31)
        | (((i64::from(b) + OFFSET) as u64 & LOW31) << 31)
        | ((m as u64) << 62);
    let last = u8::from(c < 0) | k << 1;
    let mut out = [0u8; COMPACT_LEN];
    let (head, tail) = out.split_at_mut(8);
    head.copy_from_slice(&low.to_le_bytes());
    tail.copy_from_slice(&[last]);
    Some(out)
}

/// The direction whose compact form is `bytes`; `None` unless [`compact`]
/// writes them for it.
pub fn expand(bytes: &[u8; COMPACT_LEN]) -> Option<[i32; 3]> {
    let (head, tail) = bytes.split_at(8);
    let low = u64::from_le_bytes(head.try_into().ok()?);
    let last = *tail.first()?;
    if last >> 3 != 0 {
        return None;
    }
    let a = ((low & LOW31) as i64 - OFFSET) as i32;
    let b = (((low >> 31) & LOW31) as i64 - OFFSET) as i32;
    let m = (low >> 62) as usize;
    let c = isqrt(rest(a, b)?) as i64 + K_BIAS - i64::from(last >> 1);
    let c = i32::try_from(c).ok().filter(|&c| c >= 0)?;
    let c = if last & 1 != 0 { -c } else { c };
    let d = match m {
        0 => [c, a, b],
        1 => [a, c, b],
        2 => [a, b, c],
        _ => return None,
    };
    // The encoder chose `m` as the first largest: any other choice, or a
    // sign on a zero, was never written.
    (largest(d) == m && (c != 0 || last & 1 == 0)).then_some(d)
}

/// The index of the first component of the largest magnitude.
fn largest(d: [i32; 3]) -> usize {
    let [x, y, z] = d.map(i32::unsigned_abs);
    if x >= y && x >= z {
        0
    } else if y >= z {
        1
    } else {
        2
    }
}

/// `d` as the encoder splits it: the index of its first largest
/// component, that component, and the other two in order.
fn split(d: [i32; 3]) -> (usize, i32, i32, i32) {
    let [x, y, z] = d;
    match largest(d) {
        0 => (0, x, y, z),
        1 => (1, y, x, z),
        _ => (2, z, x, y),
    }
}

/// `2^60 - a^2 - b^2`, if `a` and `b` fit 31 bits and it is at least zero.
fn rest(a: i32, b: i32) -> Option<u64> {
    let fits = |v: i32| (-OFFSET..OFFSET).contains(&i64::from(v));
    if !fits(a) || !fits(b) {
        return None;
    }
    let square = |v: i32| u64::from(v.unsigned_abs()).pow(2);
    // Each square is at most 2^60: the sum fits.
    ONE_SQUARED.checked_sub(square(a) + square(b))
}

/// `isqrt(rest) - c + K_BIAS`, if it is 0 to 3, found without a square
/// root (the sender's half of the work): `isqrt(rest) = c + k` exactly when
/// `(c + k)^2 <= rest < (c + k + 1)^2`, that is when `2ck + k^2 <= rest -
/// c^2 < 2c(k + 1) + (k + 1)^2`; with `t = 2c + 1` the bounds for `k` from
/// -1 to 3 are `2 - t`, 0, `t`, `2t + 2` and `3t + 6`.
fn root_offset(rest: u64, c: u32) -> Option<u8> {
    let (c, t) = (i64::from(c), 2 * i64::from(c) + 1);
    // rest <= 2^60 and c^2 < 2^62: the difference fits.
    let diff = rest as i64 - c * c;
    let k = if diff < 0 {
        (diff >= 2 - t).then_some(0)?
    } else if diff < t {
        1
    } else if diff < 2 * t + 2 {
        2
    } else {
        (diff < 3 * t + 6).then_some(3)?
    };
    Some(k)
}

/// `floor(sqrt(n))`, for `n` up to 2^60, in 32-bit steps (the receiver's
/// half of the work): `u64::isqrt` divides in 64 bits, which a Cortex-M3
/// does in software, about a hundred instructions a root.
///
/// The top 31 or 32 bits' root `r` scaled by `2^h` is under the root by
/// less than `2^h`; one Newton step from below, `x + floor((n - x^2) / 2x)`,
/// lands at most `2^(2h) / (2x) = 2^h / 2r <= 1/2` over it, so one
/// comparison finishes.
fn isqrt(n: u64) -> u64 {
    if (1 << 58..1 << 60).contains(&n) {
        // Every unit direction's rest: h = 14 (as below), in constant shifts.
        let r = isqrt_top((n >> 28) as u32);
        let x = r << 14;
        let square = u64::from(x) * u64::from(x);
        let x = x + (((n - square) >> 15) as u32) / r;
        let square = u64::from(x) * u64::from(x);
        return u64::from(x) - u64::from(square > n);
    }
    let Ok(small) = u32::try_from(n) else {
        // n >> 2h is in [2^30, 2^32), its root `r` in [2^15, 2^16), h <= 15.
        let h = (64 - n.leading_zeros() - 31) / 2;
        let r = isqrt_top((n >> (2 * h)) as u32);
        let x = u64::from(r) << h;
        // 0 <= n - x^2 < 2^(h+1) x + 2^(2h), so this quotient's dividend is
        // under 2^31 and (floors nest) its floor that of (n - x^2) / 2x.
        let step = (((n - x * x) >> (h + 1)) as u32) / r;
        let x = x + u64::from(step);
        return if x * x > n { x - 1 } else { x };
    };
    u64::from(small.isqrt())
}

/// `floor(sqrt(t))` for `t` in `[2^30, 2^32)`: from the tangent at `2^31`,
/// `(t / 2^16 + 2^15) / sqrt(2)`, at most 6.1% over the root, two Newton
/// steps (with floors they never go under it: `floor((r + t / r) / 2)` is at
/// least the root's floor by the means' inequality) bring it within one,
/// and a comparison the rest of the way. `u32::isqrt` took twice as long.
fn isqrt_top(t: u32) -> u32 {
    // (t >> 16) + 2^15 < 3 2^15, times 23171 (2^15 / sqrt 2, rounded up) under 2^32.
    let r = ((t >> 16) + (1 << 15)) * 23_171 >> 15;
    let r = (r + t / r) / 2;
    let r = (r + t / r) / 2;
    if u64::from(r) * u64::from(r) > u64::from(t) { r - 1 } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The unit vector nearest `v`'s direction, each component truncated
    /// toward zero as the nodes' normalisation does, in f64 then checked in
    /// integers: an oracle apart from node-fw's.
    fn truncated_unit(v: [f64; 3]) -> Option<[i32; 3]> {
        let len = v.iter().map(|c| c * c).sum::<f64>().sqrt();
        if len == 0.0 || !len.is_finite() {
            return None;
        }
        let d = v.map(|c| (c / len * (1u64 << 30) as f64).trunc() as i32);
        let len2: i128 = d.iter().map(|&c| i128::from(c).pow(2)).sum();
        (0..=1 << 33).contains(&((1i128 << 60) - len2)).then_some(d)
    }

    proptest! {
        #[test]
        fn directions_near_unit_length_take_the_compact_form_and_come_back(
            v in proptest::array::uniform3(-1e6f64..1e6),
        ) {
            if let Some(d) = truncated_unit(v) {
                let bytes = compact(d);
                prop_assert!(bytes.is_some(), "{:?}", d);
                prop_assert_eq!(bytes.and_then(|b| expand(&b)), Some(d));
            }
        }

        /// Whatever nine bytes arrive, what expands compacts to them again:
        /// no direction has two forms.
        #[test]
        fn any_bytes_that_expand_are_the_compact_form_of_what_they_expand_to(
            bytes in proptest::array::uniform9(any::<u8>()),
        ) {
            if let Some(d) = expand(&bytes) {
                prop_assert_eq!(compact(d), Some(bytes));
            }
        }

        #[test]
        fn any_direction_with_a_compact_form_comes_back(d in proptest::array::uniform3(any::<i32>())) {
            if let Some(bytes) = compact(d) {
                prop_assert_eq!(expand(&bytes), Some(d));
            }
        }
    }

    proptest! {
        #[test]
        fn the_square_root_is_the_floor_of_the_exact_one(n in 0u64..=1 << 60, shift in 0u32..60) {
            for n in [n, n >> shift] {
                let r = isqrt(n);
                prop_assert!(r * r <= n && (r + 1) * (r + 1) > n, "n = {}, r = {}", n, r);
            }
        }
    }

    proptest! {
        #[test]
        fn the_top_bits_root_is_the_floor_of_the_exact_one(t in 1u32 << 30..=u32::MAX) {
            prop_assert_eq!(isqrt_top(t), t.isqrt());
        }

        #[test]
        fn the_senders_offset_is_the_receivers_root_less_the_component(
            rest in 0u64..=1 << 60,
            c in 0u32..1 << 31,
            near in -3i64..5,
        ) {
            // The component at the root or a few off it, and anywhere.
            let at_root = (rest.isqrt() as i64 + near).clamp(0, (1 << 31) - 1) as u32;
            for c in [c, at_root] {
                let k = rest.isqrt() as i64 - i64::from(c) + K_BIAS;
                prop_assert_eq!(root_offset(rest, c), u8::try_from(k).ok().filter(|&k| k <= 3));
            }
        }
    }

    #[test]
    fn the_square_root_at_the_edges_of_its_steps() {
        for t in [1u32 << 30, (1 << 30) + 1, (1 << 31) - 1, 1 << 31, u32::MAX, 0xFFFE_0001, 0xFFFE_0000] {
            assert_eq!(isqrt_top(t), t.isqrt(), "{t}");
        }
        for e in 0..=60u32 {
            for n in [1u64 << e, (1 << e) - 1, (1 << e) + 1] {
                let r = isqrt(n);
                assert!(
                    u128::from(r).pow(2) <= u128::from(n) && u128::from(r + 1).pow(2) > u128::from(n),
                    "{n}"
                );
            }
        }
        for r in [1u64 << 30, (1 << 30) - 1, 65_535, 65_536, 3] {
            for n in [r * r - 1, r * r, r * r + 2 * r] {
                assert_eq!(isqrt(n), if n < r * r { r - 1 } else { r }, "{n}");
            }
        }
    }

    #[test]
    fn the_axes_and_ties_take_the_compact_form() {
        let one = 1 << 30;
        for d in [[one, 0, 0], [0, -one, 0], [0, 0, one], [0, 0, -one]] {
            let bytes = compact(d).unwrap();
            assert_eq!(expand(&bytes), Some(d));
        }
        // Equal magnitudes: the first is left out, whatever the signs.
        let t = 619_925_131; // 2^30 / sqrt(3), truncated
        for d in [[t, t, t], [-t, t, -t], [t, -t, -t]] {
            let bytes = compact(d).unwrap();
            assert_eq!(bytes[7] >> 6, 0, "index 0");
            assert_eq!(expand(&bytes), Some(d));
        }
    }

    #[test]
    fn bytes_no_encoder_writes_are_refused() {
        let c = ((1u64 << 60) - (1 << 58) - (1 << 56)).isqrt() as i32;
        let d = [1 << 29, -(1 << 28), c];
        let bytes = compact(d).unwrap();
        assert_eq!(bytes[7] >> 6, 2);
        // A component left out that is not the largest: `a` near one, so
        // `c` near zero.
        let a = (1u64 << 30) - 1;
        let low = (a + (1 << 30)) | (1 << 30) << 31;
        let mut small = [0u8; COMPACT_LEN];
        small[..8].copy_from_slice(&low.to_le_bytes());
        assert_eq!(expand(&small), None);
        // Of equal magnitudes, the second left out.
        let t = 619_925_131;
        let mut second = compact([t, t, t]).unwrap();
        second[7] |= 0x40;
        assert_eq!(expand(&second), None);
        // Index 3 is no component.
        let mut three = bytes;
        three[7] |= 0xc0;
        assert_eq!(expand(&three), None);
        // Stray high bits in the last byte.
        let mut stray = bytes;
        stray[8] |= 0x08;
        assert_eq!(expand(&stray), None);
        // Far from unit length: no compact form, and a 31-bit overflow none either.
        assert_eq!(compact([1 << 29, 1 << 29, 1 << 29]), None);
        assert_eq!(compact([i32::MIN, 0, 0]), None);
        assert_eq!(compact([i32::MAX, 1 << 30, 0]), None);
    }
}
