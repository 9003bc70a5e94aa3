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
pub fn encode_in_place(buf: &mut [u8]) -> Option<()> {
    if buf.is_empty() || buf.len() > 254 {
        return None;
    }
    let mut next = buf.len();
    for (i, b) in buf.iter_mut().enumerate().skip(1).rev() {
        if *b == 0 {
            // Fewer than 255 bytes: the distance fits a code byte.
            *b = (next - i) as u8;
            next = i;
        }
    }
    *buf.first_mut()? = next as u8;
    Some(())
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
    if buf.is_empty() {
        return None;
    }
    if chain_without_full_runs(buf)? {
        let mut at = usize::from(*buf.first()?);
        while at < buf.len() {
            let code = core::mem::replace(buf.get_mut(at)?, 0);
            at += usize::from(code);
        }
        buf.get(1..)
    } else {
        let n = decode_runs(buf)?;
        buf.get(..n)
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
