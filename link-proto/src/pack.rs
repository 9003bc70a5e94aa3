//! Fields packed by hand: a writer and a reader over byte buffers, and
//! canonical varints. The wire forms of rays and retirements are built from
//! these; every read and write is checked, none panics.

/// A varint writer of one unsigned type, with its attributes: the same loop
/// for each, so that a `u32` needs no 64-bit shifts.
macro_rules! varint_writer {
    ($(#[$attr:meta])* $name:ident($ty:ty)) => {
        $(#[$attr])*
        pub(crate) fn $name(&mut self, mut v: $ty) -> Option<()> {
            let room = self.out.get_mut(self.at..)?;
            for (n, slot) in room.iter_mut().enumerate() {
                if v < 0x80 {
                    *slot = v as u8;
                    self.at += n + 1;
                    return Some(());
                }
                *slot = (v as u8) | 0x80;
                v >>= 7;
            }
            None
        }
    };
}

/// Writes fields one after another into a buffer.
pub(crate) struct Writer<'a> {
    out: &'a mut [u8],
    /// Bytes written so far.
    pub(crate) at: usize,
}

impl<'a> Writer<'a> {
    /// A writer at the start of `out`.
    pub(crate) fn new(out: &'a mut [u8]) -> Self {
        Self { out, at: 0 }
    }

    /// Appends `bytes`; `None` when they do not fit.
    pub(crate) fn put(&mut self, bytes: &[u8]) -> Option<()> {
        let end = self.at.checked_add(bytes.len())?;
        self.out.get_mut(self.at..end)?.copy_from_slice(bytes);
        self.at = end;
        Some(())
    }

    varint_writer! {
        /// Appends `v` as a varint: seven bits a byte, low first, the high
        /// bit set on every byte but the last (as postcard writes them). Not
        /// inlined: a record has four, and flash is short on small boards.
        ///
        /// Into the room left by walking it, one check for all the bytes: a
        /// bounds-checked `put` a byte cost a record's four varints about 27
        /// instructions each on a Cortex-M3. Its own loop, not `varint64`'s:
        /// 64-bit shifts cost a six-record retirement 240 more instructions.
        #[inline(never)]
        varint(u32)
    }

    varint_writer! {
        /// [`Self::varint`] of a `u64`: up to ten bytes (postcard's `u64`),
        /// inlined where the one credit of a retirement is written.
        varint64(u64)
    }
}

/// Reads fields one after another from a buffer.
#[derive(Debug, Clone)]
pub(crate) struct Reader<'a> {
    pub(crate) bytes: &'a [u8],
}

impl Reader<'_> {
    pub(crate) fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.bytes.split_at_checked(N)?;
        self.bytes = rest;
        head.try_into().ok()
    }
    pub(crate) fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|[b]| b)
    }
    pub(crate) fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    /// Three little-endian bytes, widened.
    pub(crate) fn u24(&mut self) -> Option<u32> {
        self.take().map(|[a, b, c]| u32::from_le_bytes([a, b, c, 0]))
    }
    pub(crate) fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    pub(crate) fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    pub(crate) fn i32x3(&mut self) -> Option<[i32; 3]> {
        Some([self.i32()?, self.i32()?, self.i32()?])
    }

    /// A varint as [`Writer::varint64`] writes it, and only so: a longer
    /// form of the same value (a last byte of zero) or one beyond `u64` is
    /// refused.
    pub(crate) fn varint64(&mut self) -> Option<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8()?;
            let bits = u64::from(b & 0x7f);
            if shift == 63 && bits > 1 {
                return None;
            }
            v |= bits << shift;
            if b & 0x80 == 0 {
                // Canonical: only the value 0 ends on a zero byte, and it is one byte long.
                return (b != 0 || shift == 0).then_some(v);
            }
        }
        None
    }

    /// [`Self::varint64`] of a `u32`: one beyond it is refused.
    pub(crate) fn varint(&mut self) -> Option<u32> {
        self.varint64().and_then(|v| u32::try_from(v).ok())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #[test]
        fn varints_round_trip_as_postcard_writes_them(v in proptest::num::u32::ANY) {
            let mut buf = [0u8; 5];
            let mut w = Writer::new(&mut buf);
            w.varint(v).unwrap();
            let n = w.at;
            let mut theirs = [0u8; 5];
            proptest::prop_assert_eq!(&buf[..n], postcard::to_slice(&v, &mut theirs).unwrap());
            let mut r = Reader { bytes: &buf[..n] };
            proptest::prop_assert_eq!(r.varint(), Some(v));
            proptest::prop_assert!(r.bytes.is_empty());
        }

        #[test]
        fn long_varints_round_trip_as_postcard_writes_them(v in proptest::num::u64::ANY) {
            let mut buf = [0u8; 10];
            let mut w = Writer::new(&mut buf);
            proptest::prop_assert!(w.varint64(v).is_some());
            let n = w.at;
            let mut theirs = [0u8; 10];
            proptest::prop_assert_eq!(Some(&buf[..n]), postcard::to_slice(&v, &mut theirs).ok().map(|b| &*b));
            let mut r = Reader { bytes: &buf[..n] };
            proptest::prop_assert_eq!(r.varint64(), Some(v));
            proptest::prop_assert!(r.bytes.is_empty());
        }
    }

    #[test]
    fn a_varint_that_does_not_fit_is_not_written() {
        // 2^14 takes three bytes: two do not hold it, three do.
        let mut buf = [0u8; 3];
        let mut w = Writer::new(&mut buf[..2]);
        assert_eq!(w.varint(1 << 14), None);
        assert_eq!(w.at, 0);
        let mut w = Writer::new(&mut buf);
        assert_eq!(w.varint(1 << 14), Some(()));
        assert_eq!((w.at, buf), (3, [0x80, 0x80, 0x01]));
    }

    #[test]
    fn longer_forms_and_overflows_are_refused() {
        assert_eq!(Reader { bytes: &[0x81, 0x00] }.varint(), None, "1 written in two bytes");
        assert_eq!(Reader { bytes: &[0x80, 0x80, 0x80, 0x80, 0x10] }.varint(), None, "2^32");
        assert_eq!(Reader { bytes: &[0x81, 0x00] }.varint64(), None, "1 written in two bytes");
        let two_to_64 = [0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x02];
        assert_eq!(Reader { bytes: &two_to_64 }.varint64(), None, "2^64");
        let mut max = [0xff; 10];
        max[9] = 0x01;
        assert_eq!(Reader { bytes: &max }.varint64(), Some(u64::MAX));
        assert_eq!(Reader { bytes: &[0xff, 0xff, 0xff, 0xff, 0x0f] }.varint(), Some(u32::MAX));
        assert_eq!(Reader { bytes: &[0x80] }.varint(), None, "cut short");
        assert_eq!(Reader { bytes: &[0x00] }.varint(), Some(0));
    }
}
