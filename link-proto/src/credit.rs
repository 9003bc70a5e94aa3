//! A share of credit in one byte: `m * 2^e`, `m` odd and at most 7.
//!
//! The host gives every pixel a credit and knows its frame is complete when
//! all of it is back (Mattern's weights, the paper's frame end without a
//! global view). A hit splits its ray's credit among its children and
//! itself, by powers of two (`node_fw::credit`), so every ray carries a
//! power of two and every record returns a power of two or a small odd
//! multiple of one, or a sum of a few such. One byte holds those: the
//! exponent in the low six bits, `(m - 1) / 2` in the top two. Four bytes
//! each went to a ray's credit and a record's: about a fifth of what the
//! busiest host links carried (1000 spheres, 4x4x4, 921 600 baud).

use crate::pack::{Reader, Writer};
use crate::ray_wire::PIXEL_CREDIT;

/// The exponent's bits.
const EXPONENT_MASK: u8 = 0x3f;
/// Where the odd multiplier's index starts.
const MULTIPLIER_SHIFT: u32 = 6;

/// `credit` in one byte, if it is an odd multiple up to 7 of a power of two.
pub fn to_byte(credit: u64) -> Option<u8> {
    if credit == 0 {
        return None;
    }
    let e = credit.trailing_zeros();
    let m = credit >> e;
    (m <= 7).then(|| e as u8 | ((m as u8 - 1) / 2) << MULTIPLIER_SHIFT)
}

/// The credit a byte stands for; `None` where it does not fit 64 bits.
pub fn from_byte(b: u8) -> Option<u64> {
    let e = u32::from(b & EXPONENT_MASK);
    let m = 2 * u64::from(b >> MULTIPLIER_SHIFT) + 1;
    let credit = m.checked_shl(e)?;
    (credit >> e == m).then_some(credit)
}

/// The shortest form of a credit on the wire, in a ray or a record: what
/// the two bits of its flags say (the code), and the bytes that follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Form {
    /// A primary ray's whole credit ([`PIXEL_CREDIT`]): no bytes.
    Pixel,
    /// Any other under 2^32 without a byte of its own: four bytes.
    Short,
    /// Any other: eight.
    Long,
    /// A share as a hit splits them, its byte ([`to_byte`]).
    Scaled(u8),
}

impl Form {
    /// The form the encoder chooses for `credit`.
    pub(crate) fn of(credit: u64) -> Self {
        if credit == PIXEL_CREDIT {
            return Self::Pixel;
        }
        match to_byte(credit) {
            Some(b) => Self::Scaled(b),
            None if credit <= u64::from(u32::MAX) => Self::Short,
            None => Self::Long,
        }
    }

    /// The form's two-bit code.
    pub(crate) fn code(self) -> u8 {
        match self {
            Self::Pixel => 0,
            Self::Short => 1,
            Self::Long => 2,
            Self::Scaled(_) => 3,
        }
    }

    /// Writes the bytes of `credit` in this form (its own form, [`Form::of`]).
    pub(crate) fn write(self, credit: u64, w: &mut Writer<'_>) -> Option<()> {
        match self {
            Self::Pixel => Some(()),
            Self::Short => w.put(&(credit as u32).to_le_bytes()),
            Self::Long => w.put(&credit.to_le_bytes()),
            Self::Scaled(b) => w.put(&[b]),
        }
    }

    /// How many bytes the form `code` names takes (as [`Form::read`] reads it).
    pub(crate) fn wire_len(code: u8) -> usize {
        match code {
            0 => 0,
            1 => 4,
            2 => 8,
            _ => 1,
        }
    }

    /// Reads a credit written in the form `code` names; `None` for bytes
    /// that are not the encoder's choice (each credit has one encoding).
    pub(crate) fn read(code: u8, r: &mut Reader<'_>) -> Option<u64> {
        let scaled = |c: u64| to_byte(c).is_some();
        match code {
            0 => Some(PIXEL_CREDIT),
            1 => Some(u64::from(r.u32()?)).filter(|&c| !scaled(c)),
            2 => Some(u64::from_le_bytes(r.take()?))
                .filter(|&c| c > u64::from(u32::MAX) && c != PIXEL_CREDIT && !scaled(c)),
            _ => from_byte(r.u8()?).filter(|&c| c != PIXEL_CREDIT),
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::{from_byte, to_byte};
    use std::vec;

    /// Every byte that stands for a credit stands for a different one, and
    /// the credit goes back to that byte.
    #[test]
    fn every_byte_round_trips() {
        let mut seen = std::collections::BTreeSet::new();
        for b in 0..=u8::MAX {
            match from_byte(b) {
                Some(c) => {
                    assert_eq!(to_byte(c), Some(b), "{c}");
                    assert!(seen.insert(c));
                }
                // Only the largest exponents overflow, with m = 3, 5 or 7.
                None => assert!(b >> 6 > 0 && b & 0x3f >= 62, "{b:#x}"),
            }
        }
    }

    /// Against the definition, by search: an odd m up to 7 and an e with m 2^e = c.
    #[test]
    fn the_credits_with_a_byte_are_the_small_odd_multiples_of_powers_of_two() {
        let fits = |c: u64| (0..64).any(|e| [1u128, 3, 5, 7].iter().any(|&m| m << e == u128::from(c)));
        let mut cases =
            vec![0, 1, 2, 3, 9, 11, 13, 14, 15, 1 << 32, (1 << 32) - 1, 7 << 61, u64::MAX, 1 << 63];
        cases.extend((0..64).flat_map(|e| [1u64 << e, (1u64 << e) + 1, (1u64 << e).wrapping_mul(3)]));
        for c in cases {
            assert_eq!(to_byte(c).is_some(), fits(c), "{c}");
        }
    }
}
