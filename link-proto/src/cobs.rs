//! Consistent Overhead Byte Stuffing (Cheshire and Baker, 1999), without
//! the delimiters.
//!
//! Every zero byte of the input becomes a *code* byte giving the distance to
//! the next one, so the encoded bytes hold no zero and a zero can delimit
//! frames. A code of 0xFF marks a run of 254 non-zero bytes with no zero
//! after it. Hand-written rather than taken from the `cobs` crate: that
//! crate's per-byte state machine cost three times as many instructions per
//! frame on a Cortex-M3, and a node encodes or decodes a frame for every
//! message. The tests hold this code to the crate's output.

/// Largest encoding of `n` input bytes: one code byte per started run of 254.
pub const fn max_encoding_length(n: usize) -> usize {
    n + n / 254 + 1
}

/// Encodes `src` into `out`; the encoded length, or `None` when `out` is
/// too short (then `out` holds a partial encoding).
pub fn encode(src: &[u8], out: &mut [u8]) -> Option<usize> {
    // `code_at` holds the current run's code byte, written once the run ends.
    let (mut code_at, mut w, mut code) = (0usize, 1usize, 1u8);
    for &b in src {
        if code == 0xFF {
            // A full run, and more input: the next run starts (the full run
            // itself implies no zero).
            *out.get_mut(code_at)? = code;
            (code_at, w, code) = (w, w + 1, 1);
        }
        if b == 0 {
            *out.get_mut(code_at)? = code;
            (code_at, w, code) = (w, w + 1, 1);
        } else {
            *out.get_mut(w)? = b;
            w += 1;
            code += 1;
        }
    }
    *out.get_mut(code_at)? = code;
    Some(w)
}

/// Encodes in place: `buf[0]` is a free slot for the first code byte and
/// `buf[1..]` the input. Each zero (and the slot) becomes the distance to the
/// next zero or the end, so the encoding is `buf` itself. Only for inputs of
/// at most 253 bytes, where no run reaches the 254 that would need a code
/// byte inserted; `None` (and `buf` untouched) for longer ones. A frame is far
/// shorter, and this spares the copy and the scratch buffer of [`encode`].
///
/// A word at a time: the zero bytes of each word are found at once
/// (`zero_bytes`) and each is turned into its run's code, so a run costs
/// a few instructions however short (a ray's frame has a zero every few
/// bytes) and a word without a zero a few more. A byte at a time cost a
/// ray's frame seven instructions a byte on a Cortex-M3.
pub fn encode_in_place(buf: &mut [u8]) -> Option<()> {
    let n = buf.len();
    if n == 0 || n > 254 {
        return None;
    }
    // The code byte waiting for its run's end: the slot, then each zero.
    let mut code_at = 0usize;
    let mut at = 1usize;
    while let Some(word) = buf.get(at..at + 4) {
        let mut zeros = zero_bytes(u32::from_le_bytes(word.try_into().unwrap_or([1; 4])));
        while zeros != 0 {
            let zero = at + (zeros.trailing_zeros() / 8) as usize;
            // Fewer than 255 bytes: every distance fits a code byte.
            *buf.get_mut(code_at)? = (zero - code_at) as u8;
            code_at = zero;
            zeros &= zeros - 1;
        }
        at += 4;
    }
    for i in at..n {
        if buf.get(i) == Some(&0) {
            *buf.get_mut(code_at)? = (i - code_at) as u8;
            code_at = i;
        }
    }
    *buf.get_mut(code_at)? = (n - code_at) as u8;
    Some(())
}

/// The top bit of each zero byte of `w`, exactly: `(b & 0x7F) + 0x7F` has
/// its top bit set when `b`'s low bits are not all zero, and never carries
/// into the next byte.
#[inline(always)]
pub(crate) fn zero_bytes(w: u32) -> u32 {
    !(((w & 0x7F7F_7F7F) + 0x7F7F_7F7F) | w) & 0x8080_8080
}

/// The index of the first zero byte of `bytes`. Four bytes at a time: in
/// `m = (w - 0x0101_0101) & !w & 0x8080_8080` the lowest set bit is the top
/// bit of the word's first zero byte (little-endian: the first in memory),
/// and `m` is zero when no byte is (a borrow can set bits only above a zero
/// byte). On a Cortex-M3 a word costs about what a byte does searched one
/// by one; every frame's bytes pass through this twice, stuffed by the
/// sender and searched for the delimiter by the receiver.
pub fn first_zero(bytes: &[u8]) -> Option<usize> {
    let mut words = bytes.chunks_exact(4);
    let mut at = 0;
    for word in &mut words {
        let w = u32::from_le_bytes(word.try_into().unwrap_or([0; 4]));
        let zeros = w.wrapping_sub(0x0101_0101) & !w & 0x8080_8080;
        if zeros != 0 {
            return Some(at + (zeros.trailing_zeros() / 8) as usize);
        }
        at += 4;
    }
    words.remainder().iter().position(|&b| b == 0).map(|k| at + k)
}

/// Decodes `buf` in place and returns the decoded bytes; `None` when `buf`
/// is empty (no encoding is) or a code byte is zero or points past the end.
///
/// When no run is a full one (code 0xFF), as in every frame shorter than 255
/// bytes, each code byte after the first stands where a zero was: the codes
/// are zeroed along their chain and the decoded bytes are `buf[1..]`, so
/// decoding touches a byte per zero, not every byte (moving the data down
/// over the first code cost a ray's frame a fifth of its decoding on a
/// Cortex-M3). Otherwise runs are moved down to `buf[0..]`.
pub fn decode_slice(buf: &mut [u8]) -> Option<&[u8]> {
    let (start, len) = decode_in_place(buf)?;
    buf.get(start..start + len)
}

/// [`decode_slice`], telling where in `buf` the decoded bytes are: their
/// start (0 or 1) and length.
pub fn decode_in_place(buf: &mut [u8]) -> Option<(usize, usize)> {
    if buf.is_empty() {
        return None;
    }
    if chain_without_full_runs(buf)? {
        let mut at = usize::from(*buf.first()?);
        while at < buf.len() {
            let code = core::mem::replace(buf.get_mut(at)?, 0);
            at += usize::from(code);
        }
        Some((1, buf.len() - 1))
    } else {
        Some((0, decode_runs(buf)?))
    }
}

/// Walks the code chain: `Some(true)` if it ends exactly at the end with no
/// full run on the way, `Some(false)` if it meets a full run (the general
/// decoder then handles it), `None` if a code is zero or points past the end.
fn chain_without_full_runs(buf: &[u8]) -> Option<bool> {
    let mut at = 0usize;
    while let Some(&code) = buf.get(at) {
        match code {
            0 => return None,
            0xFF => return Some(false),
            _ => at += usize::from(code),
        }
    }
    (at == buf.len()).then_some(true)
}

/// Decodes run by run (the general case).
fn decode_runs(buf: &mut [u8]) -> Option<usize> {
    let (mut r, mut w) = (0usize, 0usize);
    while let Some(&code) = buf.get(r) {
        let end = r + usize::from(code);
        if code == 0 || end > buf.len() {
            return None;
        }
        // The decoded bytes never overtake the encoded ones (w <= r).
        for i in r + 1..end {
            let b = *buf.get(i)?;
            *buf.get_mut(w)? = b;
            w += 1;
        }
        r = end;
        // A run short of 254 ends in a zero, except the last one.
        if code != 0xFF && r < buf.len() {
            *buf.get_mut(w)? = 0;
            w += 1;
        }
    }
    Some(w)
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    /// Inputs with many zeros, few zeros, and long non-zero runs. Not empty:
    /// a frame always holds its CRC, and the crate encodes nothing as nothing,
    /// which is not COBS (the `known_vectors` test has the empty input).
    fn input() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            proptest::collection::vec(0u8..4, 1..600),
            proptest::collection::vec(any::<u8>(), 1..600),
            proptest::collection::vec(1u8..=255, 1..600),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]

        /// The same bytes as the `cobs` crate, and back again.
        #[test]
        fn matches_the_cobs_crate(src in input()) {
            let mut ours = [0u8; 700];
            let mut theirs = [0u8; 700];
            let n = encode(&src, &mut ours).unwrap();
            let m = ::cobs::encode(&src, &mut theirs);
            prop_assert_eq!(&ours[..n], &theirs[..m]);
            prop_assert!(n <= max_encoding_length(src.len()));
            prop_assert!(!ours[..n].contains(&0));
            prop_assert_eq!(decode_slice(&mut ours[..n]), Some(&src[..]));
        }

        /// Arbitrary bytes decode as the crate decodes them, or fail where it does.
        #[test]
        fn decodes_like_the_cobs_crate(enc in proptest::collection::vec(1u8..=255, 0..300)) {
            let (mut ours, mut theirs) = (enc.clone(), enc);
            let a = decode_slice(&mut ours).map(<[u8]>::to_vec);
            let b = ::cobs::decode_in_place(&mut theirs).ok().map(|n| theirs[..n].to_vec());
            prop_assert_eq!(a, b);
        }

        /// In place, the same bytes as `encode`, up to the 253-byte limit.
        #[test]
        fn encodes_in_place_as_encode_does(src in input()) {
            let mut out = [0u8; 700];
            let n = encode(&src, &mut out).unwrap();
            let mut buf = [&[0x5A][..], &src].concat();
            if src.len() <= 253 {
                prop_assert_eq!(encode_in_place(&mut buf), Some(()));
                prop_assert_eq!(&buf[..], &out[..n]);
            } else {
                let before = buf.clone();
                prop_assert_eq!(encode_in_place(&mut buf), None);
                prop_assert_eq!(buf, before);
            }
        }

        /// A buffer one byte short is refused, never overrun.
        #[test]
        fn short_buffer_is_refused(src in input()) {
            let mut out = [0u8; 700];
            let n = encode(&src, &mut out).unwrap();
            prop_assert_eq!(encode(&src, &mut out[..n - 1]), None);
        }
    }

    /// Bytes with zeros sparse or dense, at every offset from a word's start.
    fn sparse_zeros() -> impl Strategy<Value = Vec<u8>> {
        (proptest::collection::vec(any::<u8>(), 0..40), 0u8..=255)
            .prop_map(|(v, keep)| v.into_iter().map(|b| if b < keep { b | 1 } else { 0 }).collect())
    }

    proptest! {
        #[test]
        fn the_first_zero_is_the_first_zero_byte(bytes in sparse_zeros(), skip in 0usize..4) {
            let bytes = bytes.get(skip.min(bytes.len())..).unwrap_or_default();
            prop_assert_eq!(first_zero(bytes), bytes.iter().position(|&b| b == 0));
        }
    }

    #[test]
    fn a_zero_in_each_byte_of_a_word_is_found() {
        for at in 0..9 {
            let mut bytes = [0x80u8; 9];
            bytes[at] = 0;
            assert_eq!(first_zero(&bytes), Some(at));
            // 0x01 below and above it: the masks' borrow cases.
            bytes[..at].fill(0x01);
            assert_eq!(first_zero(&bytes), Some(at));
            bytes[at + 1..].fill(0x01);
            assert_eq!(first_zero(&bytes), Some(at));
            bytes[..at].fill(0x80);
            assert_eq!(first_zero(&bytes), Some(at));
        }
        assert_eq!(first_zero(&[0xFF; 11]), None);
        assert_eq!(first_zero(&[]), None);
    }

    #[test]
    fn the_zero_bytes_of_a_word_are_exactly_its_zero_bytes() {
        // Every byte value in every position, beside zeros and 0x01s.
        for b in 0..=255u8 {
            for pos in 0..4 {
                for fill in [0x00u8, 0x01, 0x80, 0xFF] {
                    let mut bytes = [fill; 4];
                    bytes[pos] = b;
                    let want = bytes
                        .iter()
                        .enumerate()
                        .fold(0u32, |m, (i, &x)| m | (u32::from(x == 0) << (8 * i + 7)));
                    assert_eq!(zero_bytes(u32::from_le_bytes(bytes)), want, "{bytes:02x?}");
                }
            }
        }
    }

    #[test]
    fn known_vectors() {
        // From the COBS paper and Wikipedia's table.
        let cases: [(&[u8], &[u8]); 5] = [
            (&[], &[1]),
            (&[0], &[1, 1]),
            (&[0, 0], &[1, 1, 1]),
            (&[0x11, 0x22, 0x00, 0x33], &[3, 0x11, 0x22, 2, 0x33]),
            (&[0x11, 0x00, 0x00, 0x00], &[2, 0x11, 1, 1, 1]),
        ];
        for (src, want) in cases {
            let mut out = [0u8; 16];
            let n = encode(src, &mut out).unwrap();
            assert_eq!(&out[..n], want);
        }
    }
}
