//! CRC-32C (Castagnoli), the frame check, four bytes at a time.
//!
//! Every frame is checked at both ends of every link, so the CRC is paid per
//! byte of every message a node handles. The usual table method (the `crc`
//! crate's) takes one table lookup per byte, about 7.6 Cortex-M3
//! instructions a byte of a ray's frame. "Slicing by 4" (Kounavis and Berry,
//! 2005) folds a whole little-endian word into the register with four
//! lookups in four tables: one load of the word, four table loads and four
//! exclusive ors per four bytes. Four tables take 4 KiB of flash; slicing
//! by 8 would double that for no gain on a core without a cache.
//!
//! The tests hold it to the `crc` crate's `CRC_32_ISCSI` for every length
//! and alignment.

/// The CRC-32C polynomial 0x1EDC6F41, bit-reversed (the CRC is reflected).
const POLY: u32 = 0x82F6_3B78;

/// `TABLES[0][b]` is the CRC of byte `b`; `TABLES[k][b]` is that CRC carried
/// through `k` more zero bytes, so a byte `k` places before the word's end
/// enters through table `k`.
static TABLES: [[u32; 256]; 4] = tables();

// Evaluated by the compiler: an index out of range would fail the build.
#[allow(clippy::indexing_slicing)]
const fn tables() -> [[u32; 256]; 4] {
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 256 {
        let mut c = b as u32;
        let mut bit = 0;
        while bit < 8 {
            c = if c & 1 == 1 { (c >> 1) ^ POLY } else { c >> 1 };
            bit += 1;
        }
        t[0][b] = c;
        b += 1;
    }
    let mut k = 1;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            let prev = t[k - 1][b];
            t[k][b] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            b += 1;
        }
        k += 1;
    }
    t
}

/// The entry of `table` for the low byte of `x`.
#[inline(always)]
#[allow(clippy::indexing_slicing)] // The mask keeps the index below 256.
fn lookup(table: &[u32; 256], x: u32) -> u32 {
    table[(x & 0xFF) as usize]
}

/// CRC-32C of `bytes` (initial value and final xor all ones, reflected).
pub fn checksum(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    let mut words = bytes.chunks_exact(4);
    for word in &mut words {
        crc = fold_word(crc, u32::from_le_bytes(word.try_into().unwrap_or([0; 4])));
    }
    for &b in words.remainder() {
        crc = fold_byte(crc, b);
    }
    !crc
}

/// `crc` with the byte `b` folded in.
#[inline(always)]
fn fold_byte(crc: u32, b: u8) -> u32 {
    lookup(&TABLES[0], crc ^ u32::from(b)) ^ (crc >> 8)
}

/// `crc` with the four bytes of the little-endian word `w` folded in.
#[inline(always)]
fn fold_word(crc: u32, w: u32) -> u32 {
    let [t0, t1, t2, t3] = &TABLES;
    let x = crc ^ w;
    lookup(t3, x) ^ lookup(t2, x >> 8) ^ lookup(t1, x >> 16) ^ lookup(t0, x >> 24)
}

/// [`checksum`] of `bytes`, which are XORed with `mask` in place in the
/// same pass: byte `i` with byte `i % 4` of `mask`, little-endian. Also
/// whether any byte is zero once masked (the frame's stuffing then has work
/// to do, see [`crate::frame`]).
pub fn checksum_then_mask(bytes: &mut [u8], mask: u32) -> (u32, bool) {
    let (mut crc, mut zeros) = (!0u32, 0u32);
    let mut words = bytes.chunks_exact_mut(4);
    for word in &mut words {
        let w = u32::from_le_bytes((&*word).try_into().unwrap_or([0; 4]));
        crc = fold_word(crc, w);
        let masked = w ^ mask;
        zeros |= crate::cobs::zero_bytes(masked);
        word.copy_from_slice(&masked.to_le_bytes());
    }
    for (b, k) in words.into_remainder().iter_mut().zip(mask.to_le_bytes()) {
        crc = fold_byte(crc, *b);
        *b ^= k;
        zeros |= u32::from(*b == 0);
    }
    (!crc, zeros != 0)
}

/// [`checksum`] of `bytes` as they were before [`checksum_then_mask`]
/// masked them with `mask`, which this undoes in place in the same pass.
pub fn unmask_then_checksum(bytes: &mut [u8], mask: u32) -> u32 {
    let mut crc = !0u32;
    let mut words = bytes.chunks_exact_mut(4);
    for word in &mut words {
        let w = u32::from_le_bytes((&*word).try_into().unwrap_or([0; 4])) ^ mask;
        crc = fold_word(crc, w);
        word.copy_from_slice(&w.to_le_bytes());
    }
    for (b, k) in words.into_remainder().iter_mut().zip(mask.to_le_bytes()) {
        *b ^= k;
        crc = fold_byte(crc, *b);
    }
    !crc
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::{checksum, checksum_then_mask, unmask_then_checksum};
    use proptest::prelude::*;
    use std::vec::Vec;

    const REFERENCE: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

    #[test]
    fn the_check_value_is_crc32cs() {
        // The catalogue's check value: CRC-32/ISCSI of "123456789".
        assert_eq!(checksum(b"123456789"), 0xE306_9283);
        assert_eq!(checksum(&[]), 0);
    }

    proptest! {
        #[test]
        fn it_is_the_crc_crates_crc32c(bytes in proptest::collection::vec(any::<u8>(), 0..300), skip in 0usize..4) {
            // Every length, and every alignment of the start.
            let bytes: Vec<u8> = bytes;
            let bytes = bytes.get(skip.min(bytes.len())..).unwrap_or_default();
            prop_assert_eq!(checksum(bytes), REFERENCE.checksum(bytes));
        }

        /// Masking in the CRC's pass gives the CRC of the bytes as they were,
        /// each byte XORed with the mask's byte at its place, and whether a
        /// masked byte is zero; unmasking gives both back.
        #[test]
        fn masking_in_the_same_pass_changes_nothing_else(
            bytes in proptest::collection::vec(any::<u8>(), 0..300),
            skip in 0usize..4,
            mask in any::<u32>(),
        ) {
            let mut bytes: Vec<u8> = bytes;
            let skip = skip.min(bytes.len());
            let bytes = &mut bytes[skip..];
            let original = bytes.to_vec();
            let masked: Vec<u8> =
                original.iter().enumerate().map(|(i, b)| b ^ mask.to_le_bytes()[i % 4]).collect();
            let (crc, zeros) = checksum_then_mask(bytes, mask);
            prop_assert_eq!(crc, REFERENCE.checksum(&original));
            prop_assert_eq!(&bytes[..], &masked[..]);
            prop_assert_eq!(zeros, masked.contains(&0));
            prop_assert_eq!(unmask_then_checksum(bytes, mask), REFERENCE.checksum(&original));
            prop_assert_eq!(&bytes[..], &original[..]);
        }
    }
}
