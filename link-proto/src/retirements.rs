//! Rays that ended, several to a message: what a node tells the host.
//!
//! A node's host link carries one record for every ray that ends: on real
//! boards (921 600 baud) it is busy most of the frame, and every message and
//! every byte costs the node's CPU (an interrupt a byte). So records travel
//! together when the link is behind: as many to a message as fit a ray's
//! size packed (about ten), and a pixel's rays that end one after another
//! are summed into one record
//! (contributions are integers, so the host's sums do not change). A node
//! holds a message with room only while it has work of its own (see
//! `node_fw`'s `transmit`), so the last records of a frame never wait.

use postcard::experimental::max_size::MaxSize;
use serde::de::Visitor;
use serde::ser::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::credit;
use crate::pack::{Reader, Writer};

/// Rays of one pixel that ended. Contributions are integers, so their sum is
/// independent of order and of how records are merged. It travels only
/// inside [`Retirements`], in their packed form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Retire {
    /// Pixel index `y * width + x`.
    pub pixel: u32,
    /// Contribution to the pixel per channel, Q1.15.
    pub rgb: [u32; 3],
    /// Credit returned to the host. The frame is complete when the host has back
    /// the credit of every initial ray.
    pub credit: u64,
    /// Rays spawned by the ending rays (shadow and reflection rays).
    pub spawned: u8,
    /// Rays this record stands for (at least one).
    pub rays: u8,
    /// Rays among them that left the scene at full strength (a primary ray
    /// that met nothing): each adds the scene's background colour, which
    /// the host holds, so the record carries a count and not the colour.
    /// `rgb` is the rest of the contribution.
    pub background: u8,
}

impl Retire {
    /// Adds `other`'s rays into this record; hands `other` back when it is
    /// another pixel's or a count would overflow.
    // Handing it back is the point: the caller keeps it for another record.
    #[allow(clippy::result_large_err)]
    pub fn merge(&mut self, other: Retire) -> Result<(), Retire> {
        let ([r0, g0, b0], [r1, g1, b1]) = (self.rgb, other.rgb);
        match (
            other.pixel == self.pixel,
            [r0.checked_add(r1), g0.checked_add(g1), b0.checked_add(b1)],
            self.credit.checked_add(other.credit),
            self.spawned.checked_add(other.spawned),
            self.rays.checked_add(other.rays),
            self.background.checked_add(other.background),
        ) {
            (
                true,
                [Some(r), Some(g), Some(b)],
                Some(credit),
                Some(spawned),
                Some(rays),
                Some(background),
            ) => {
                *self = Retire { pixel: self.pixel, rgb: [r, g, b], credit, spawned, rays, background };
                Ok(())
            }
            _ => Err(other),
        }
    }
}

/// Records in the order they were added, at least one: the last unpacked,
/// so that a pixel's next ray (most merges) is summed into it, and those
/// before it packed in their wire form. A node moves every message whole,
/// so a message is kept to a ray's size (a larger one made every message,
/// rays too, dearer on a Cortex-M3): three records fitted it unpacked,
/// about ten of the usual forms fit it packed, and at least three of any.
#[derive(Debug, Clone, Copy)]
pub struct Retirements {
    /// The last record, open to the next ray of its pixel.
    last: Retire,
    /// The records before it, in their wire form.
    packed: [u8; PACKED_MAX],
    /// Bytes of `packed` in use.
    packed_len: u8,
    /// Records in all, the last included.
    len: u8,
}

/// Room for the packed records: with the last one, a message stays within
/// a ray's size (a test holds it), and it holds two records of the longest
/// form, so that any three fit.
const PACKED_MAX: usize = 86;
const _: () = assert!(PACKED_MAX >= 2 * RECORD_MAX_LEN && PACKED_MAX < 256);

impl Retirements {
    /// One record, of one ray or summed over a pixel's.
    pub fn new(first: Retire) -> Self {
        Self { last: first, packed: [0; PACKED_MAX], packed_len: 0, len: 1 }
    }

    /// How many records there are.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Never: a message holds at least one record (for clippy's sake).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The records, in the order they were added.
    pub fn iter(&self) -> Records<'_> {
        Records { packed: Reader { bytes: self.packed_bytes() }, last: Some(self.last) }
    }

    /// The packed records' bytes.
    fn packed_bytes(&self) -> &[u8] {
        self.packed.get(..usize::from(self.packed_len)).unwrap_or_default()
    }

    /// Whether a record of another pixel would be refused: the last one no
    /// longer fits among the packed ones (a ray of its pixel may still merge).
    pub fn is_full(&self) -> bool {
        let mut scratch = [0u8; RECORD_MAX_LEN];
        let mut w = Writer::new(&mut scratch);
        encode_record(&self.last, &mut w).is_none_or(|()| usize::from(self.packed_len) + w.at > PACKED_MAX)
    }

    /// Adds `r`: into the last record if it is of the same pixel (and the
    /// sums fit), else as a new record after it. Hands `r` back when there
    /// is no room.
    #[allow(clippy::result_large_err)]
    pub fn push(&mut self, r: Retire) -> Result<(), Retire> {
        let r = match self.last.merge(r) {
            Ok(()) => return Ok(()),
            Err(r) => r,
        };
        let at = usize::from(self.packed_len);
        let Some(room) = self.packed.get_mut(at..) else { return Err(r) };
        let mut w = Writer::new(room);
        if encode_record(&self.last, &mut w).is_none() {
            // A partial record past `packed_len` is not one: nothing changed.
            return Err(r);
        }
        // At most PACKED_MAX (< 256) bytes, and a record per two of them.
        self.packed_len += w.at as u8;
        self.len += 1;
        self.last = r;
        Ok(())
    }
}

/// The records of a [`Retirements`], in order.
#[derive(Debug, Clone)]
pub struct Records<'a> {
    packed: Reader<'a>,
    last: Option<Retire>,
}

impl Iterator for Records<'_> {
    type Item = Retire;

    fn next(&mut self) -> Option<Retire> {
        if self.packed.bytes.is_empty() {
            return self.last.take();
        }
        // Packed by `push` or checked by the decoder: every record reads
        // back. Were one not to, the iterator would end, not panic.
        let record = decode_record(&mut self.packed);
        if record.is_none() {
            self.packed.bytes = &[];
            self.last = None;
        }
        record
    }
}

/// Equal when they hold the same records: each record has one wire form,
/// so the packed bytes are equal too (what lies beyond them is not theirs).
impl PartialEq for Retirements {
    fn eq(&self, other: &Self) -> bool {
        self.len == other.len && self.last == other.last && self.packed_bytes() == other.packed_bytes()
    }
}

impl Eq for Retirements {}

// The wire form of the records: hand-packed, one flag byte a record choosing
// the shortest form of each field. A retirement is most of what a host link
// carries, and on real boards each byte costs an interrupt: postcard's form took
// 14.5 bytes a record (1000 spheres, 4x4x4, 921 600 baud), most of them a
// primary ray's whole credit (a five-byte varint) and counts of one ray.
//
// Layout of a record: flags, pixel (varint), [rgb (3 varints)], [credit
// (a byte, or u32 or u64 little-endian)], [spawned, rays], [background]. A
// ray's share of its pixel's credit is a power of two, and a parent's what
// its children left, so most credits take the byte. Each record
// has exactly one encoding: bytes that are not the encoder's choice are
// refused.
//
// A primary ray that met nothing (behind a sparse scene, most of what the
// nodes at the back of the array retire) contributes the background colour
// itself: its record is the flags and the pixel, about four bytes where the
// colour took six more.

/// No contribution (a blocked shadow ray): no rgb bytes.
const RGB_ZERO: u8 = 1 << 0;
/// One ray that spawned none: no count bytes.
const ONE_RAY: u8 = 1 << 1;
/// The credit's form ([`credit::Form`]), its code in two bits.
const CREDIT_SHIFT: u32 = 2;
const CREDIT_MASK: u8 = 0b11 << CREDIT_SHIFT;
const BACKGROUND_SHIFT: u32 = 4;
const BACKGROUND_MASK: u8 = 0b11 << BACKGROUND_SHIFT;
/// No ray at full strength left the scene: no byte.
const BACKGROUND_NONE: u8 = 0;
/// One did: no byte.
const BACKGROUND_ONE: u8 = 1 << BACKGROUND_SHIFT;
/// Two or more did: their count in a byte.
const BACKGROUND_COUNT: u8 = 2 << BACKGROUND_SHIFT;
const KNOWN_FLAGS: u8 = RGB_ZERO | ONE_RAY | CREDIT_MASK | BACKGROUND_MASK;

/// The longest record: flags, four five-byte varints, a long credit and the counts.
const RECORD_MAX_LEN: usize = 1 + 5 + 15 + 8 + 2 + 1;
/// The longest wire form of a message's records.
pub(crate) const WIRE_MAX_LEN: usize = PACKED_MAX + RECORD_MAX_LEN;
const _: () = assert!(WIRE_MAX_LEN < 128, "the byte string's length must stay one varint byte");

fn flags_of(r: &Retire) -> u8 {
    flags_with(r, credit::Form::of(r.credit))
}

fn flags_with(r: &Retire, credit: credit::Form) -> u8 {
    let mut flags = credit.code() << CREDIT_SHIFT;
    // Component by component: an array's `==` is a `memcmp` call on a Cortex-M3.
    let [red, green, blue] = r.rgb;
    if red | green | blue == 0 {
        flags |= RGB_ZERO;
    }
    if r.spawned == 0 && r.rays == 1 {
        flags |= ONE_RAY;
    }
    flags
        | match r.background {
            0 => BACKGROUND_NONE,
            1 => BACKGROUND_ONE,
            _ => BACKGROUND_COUNT,
        }
}

/// Packs `r` after what `w` holds.
fn encode_record(r: &Retire, w: &mut Writer<'_>) -> Option<()> {
    let form = credit::Form::of(r.credit);
    let flags = flags_with(r, form);
    w.put(&[flags])?;
    w.varint(r.pixel)?;
    if flags & RGB_ZERO == 0 {
        for c in r.rgb {
            w.varint(c)?;
        }
    }
    form.write(r.credit, w)?;
    if flags & ONE_RAY == 0 {
        w.put(&[r.spawned, r.rays])?;
    }
    if flags & BACKGROUND_MASK == BACKGROUND_COUNT {
        w.put(&[r.background])?;
    }
    Some(())
}

/// Unpacks the record at the front of `r`'s bytes.
fn decode_record(r: &mut Reader<'_>) -> Option<Retire> {
    let flags = r.u8()?;
    if flags & !KNOWN_FLAGS != 0 {
        return None;
    }
    let pixel = r.varint()?;
    let rgb = if flags & RGB_ZERO != 0 { [0; 3] } else { [r.varint()?, r.varint()?, r.varint()?] };
    let credit = credit::Form::read((flags & CREDIT_MASK) >> CREDIT_SHIFT, r)?;
    let (spawned, rays) = if flags & ONE_RAY != 0 { (0, 1) } else { (r.u8()?, r.u8()?) };
    let background = match flags & BACKGROUND_MASK {
        BACKGROUND_NONE => 0,
        BACKGROUND_ONE => 1,
        BACKGROUND_COUNT => r.u8()?,
        _ => return None,
    };
    let record = Retire { pixel, rgb, credit, spawned, rays, background };
    // One record, one encoding: the forms must be the ones the encoder chose.
    (flags_of(&record) == flags).then_some(record)
}

impl Retirements {
    /// Writes the records' wire form at the start of `out` (the packed
    /// records, then the last); its length, at most [`WIRE_MAX_LEN`], or
    /// `None` when `out` is shorter.
    pub(crate) fn encode_wire(&self, out: &mut [u8]) -> Option<usize> {
        let packed = self.packed_bytes();
        out.get_mut(..packed.len())?.copy_from_slice(packed);
        let mut w = Writer::new(out.get_mut(packed.len()..)?);
        encode_record(&self.last, &mut w)?;
        Some(packed.len() + w.at)
    }
}

impl Serialize for Retirements {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut buf = [0u8; WIRE_MAX_LEN];
        let len = self.encode_wire(&mut buf).ok_or_else(|| S::Error::custom("records too long"))?;
        serializer.serialize_bytes(buf.get(..len).unwrap_or_default())
    }
}

impl<'de> Deserialize<'de> for Retirements {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Records;
        impl Visitor<'_> for Records {
            type Value = Retirements;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("retirement records")
            }
            fn visit_bytes<E: serde::de::Error>(self, bytes: &[u8]) -> Result<Retirements, E> {
                let not_a_record = || E::custom("not a record");
                let mut r = Reader { bytes };
                let mut last = decode_record(&mut r).ok_or_else(not_a_record)?;
                let (mut last_at, mut len) = (0usize, 1u8);
                while !r.bytes.is_empty() {
                    last_at = bytes.len() - r.bytes.len();
                    last = decode_record(&mut r).ok_or_else(not_a_record)?;
                    len = len.checked_add(1).ok_or_else(|| E::custom("too many records"))?;
                }
                // The records before the last must fit where a node packs them.
                let before = bytes.get(..last_at).filter(|b| b.len() <= PACKED_MAX);
                let before = before.ok_or_else(|| E::custom("too many records"))?;
                let mut all = Retirements { last, packed: [0; PACKED_MAX], packed_len: last_at as u8, len };
                all.packed.get_mut(..last_at).ok_or_else(not_a_record)?.copy_from_slice(before);
                Ok(all)
            }
        }
        deserializer.deserialize_bytes(Records)
    }
}

impl MaxSize for Retirements {
    // The byte string's length (one varint byte) and the records.
    const POSTCARD_MAX_SIZE: usize = 1 + WIRE_MAX_LEN;
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    use crate::ray_wire::PIXEL_CREDIT;

    // The credit forms as the layout documents them.
    const CREDIT_SHORT: u8 = 1 << CREDIT_SHIFT;
    const CREDIT_LONG: u8 = 2 << CREDIT_SHIFT;
    const CREDIT_SCALED: u8 = 3 << CREDIT_SHIFT;

    fn r(pixel: u32, c: u32) -> Retire {
        Retire { pixel, rgb: [c, 2 * c, 3], credit: u64::from(c) << 20, spawned: 1, rays: 1, background: 0 }
    }

    /// The records, as a list.
    fn listed(all: &Retirements) -> std::vec::Vec<Retire> {
        all.iter().collect()
    }

    #[test]
    fn a_pixel_s_next_ray_is_summed_and_others_take_records_until_full() {
        let mut all = Retirements::new(r(7, 10));
        assert_eq!(all.push(r(7, 5)), Ok(()));
        let summed =
            Retire { pixel: 7, rgb: [15, 30, 6], credit: 15 << 20, spawned: 2, rays: 2, background: 0 };
        assert_eq!(listed(&all), [summed]);
        assert_eq!(all.push(r(1, 1)), Ok(()));
        assert_eq!(all.push(r(7, 1)), Ok(()), "a pixel not last takes a record of its own");
        assert_eq!(listed(&all), [summed, r(1, 1), r(7, 1)]);
        // A lit shadow ray's record in a 256x256 image: flags, three bytes
        // of pixel, two of each colour, a byte of credit.
        let lit = |pixel| Retire {
            pixel,
            rgb: [3000, 2000, 1000],
            credit: PIXEL_CREDIT >> 3,
            spawned: 0,
            rays: 1,
            background: 0,
        };
        let mut all = Retirements::new(lit(20_000));
        let mut expected = listed(&all);
        let mut pixel = 20_001;
        while !all.is_full() {
            assert_eq!(all.push(lit(pixel)), Ok(()));
            expected.push(lit(pixel));
            pixel += 1;
        }
        assert_eq!(all.push(r(pixel, 1)), Err(r(pixel, 1)), "full: another pixel has no room");
        assert_eq!(all.push(lit(pixel - 1)), Ok(()), "the last pixel still merges");
        expected.last_mut().unwrap().merge(lit(pixel - 1)).unwrap();
        assert_eq!(listed(&all), expected);
        assert_eq!(all.len(), expected.len());
        // Eleven bytes each: eight, where three fitted unpacked.
        assert_eq!(all.len(), 8);
    }

    #[test]
    fn any_three_records_fit_and_a_message_stays_within_a_ray_s_size() {
        let longest = |p| Retire {
            pixel: u32::MAX - p,
            rgb: [u32::MAX; 3],
            credit: u64::MAX,
            spawned: 9,
            rays: 9,
            background: 9,
        };
        let mut all = Retirements::new(longest(0));
        for p in [1, 2] {
            assert_eq!(all.push(longest(p)), Ok(()));
        }
        assert_eq!(listed(&all), [longest(0), longest(1), longest(2)]);
        assert!(core::mem::size_of::<Retirements>() <= core::mem::size_of::<crate::RayMsg>());
    }

    #[test]
    fn a_merge_that_would_overflow_is_refused() {
        let mut a = Retire { rays: 255, ..r(1, 1) };
        assert_eq!(a.merge(r(1, 1)), Err(r(1, 1)));
        let mut a = Retire { rgb: [u32::MAX, 0, 0], ..r(1, 1) };
        assert_eq!(a.merge(r(1, 1)), Err(r(1, 1)));
        let mut a = Retire { background: 255, ..r(1, 1) };
        let b = Retire { background: 1, ..r(1, 1) };
        assert_eq!(a.merge(b), Err(b));
        let mut a = r(1, 1);
        assert_eq!(a.merge(r(2, 1)), Err(r(2, 1)), "another pixel");
    }

    /// The records' wire form as a postcard byte string.
    fn wire(records: &[Retire]) -> std::vec::Vec<u8> {
        let mut buf = [0u8; 255];
        let mut w = Writer::new(&mut buf[1..]);
        for r in records {
            encode_record(r, &mut w).unwrap();
        }
        let n = w.at;
        buf[0] = n as u8;
        buf[..=n].to_vec()
    }

    #[test]
    fn records_round_trip_and_more_than_a_node_packs_are_refused() {
        let mut all = Retirements::new(r(1, 1));
        for p in 2..=10 {
            all.push(r(p, p)).unwrap();
        }
        let mut buf = [0u8; Retirements::POSTCARD_MAX_SIZE];
        let bytes = postcard::to_slice(&all, &mut buf).unwrap();
        assert_eq!(postcard::from_bytes::<Retirements>(bytes), Ok(all));
        // Records before the last beyond what a node packs: 86 bytes.
        let wide = Retire { rgb: [1 << 30; 3], ..r(0, 0) };
        let records: std::vec::Vec<_> = (0..7).map(|p| Retire { pixel: 1 << 28 | p, ..wide }).collect();
        assert_eq!(wire(&records[..1]).len() - 1, 27);
        assert!(
            postcard::from_bytes::<Retirements>(&wire(&records[..4])).is_ok(),
            "81 bytes before the last"
        );
        assert!(postcard::from_bytes::<Retirements>(&wire(&records[..5])).is_err(), "108 before the last");
        assert!(postcard::from_bytes::<Retirements>(&[0]).is_err(), "no record");
    }

    #[test]
    fn a_primary_ray_that_missed_takes_its_flags_and_pixel() {
        let miss =
            Retire { pixel: 300, rgb: [0; 3], credit: PIXEL_CREDIT, spawned: 0, rays: 1, background: 1 };
        // The string's length, flags and a two-byte pixel.
        assert_eq!(wire(&[miss]).len(), 1 + 1 + 2);
        // Under the full strength, its colour: two, two and three bytes.
        let dim = Retire { rgb: [1000, 2000, 30000], background: 0, ..miss };
        assert_eq!(wire(&[dim]).len(), 1 + 1 + 2 + 2 + 2 + 3);
        // Merged with another such ray of its pixel: two pixels' credit
        // (2^33, a byte), the counts and the background count.
        let mut two = miss;
        assert_eq!(two.merge(miss), Ok(()));
        assert_eq!(two.background, 2);
        assert_eq!(wire(&[two]).len(), 1 + 1 + 2 + 1 + 2 + 1);
        let blocked = Retire { rgb: [0; 3], credit: PIXEL_CREDIT / 3, ..miss };
        // Flags, pixel, four bytes of credit.
        assert_eq!(wire(&[blocked]).len(), 1 + 1 + 2 + 4);
        // A shadow ray's share, a power of two, or a parent's, three of one: a byte.
        for credit in [PIXEL_CREDIT / 16, 3 * PIXEL_CREDIT / 32] {
            let shadow = Retire { credit, ..blocked };
            assert_eq!(wire(&[shadow]).len(), 1 + 1 + 2 + 1, "{credit}");
        }
    }

    #[test]
    fn a_second_encoding_of_the_same_record_is_refused() {
        let one = Retire { pixel: 5, rgb: [0; 3], credit: 7, spawned: 0, rays: 1, background: 0 };
        let mut longer = wire(&[one]);
        // Counts written out though they are the one-ray form's.
        longer[1] &= !ONE_RAY;
        longer.extend_from_slice(&[0, 1]);
        longer[0] += 2;
        assert!(postcard::from_bytes::<Retirements>(&longer).is_err());
        // A one-byte credit written in four or eight.
        let mut short = wire(&[one]);
        short[1] = (short[1] & !CREDIT_MASK) | CREDIT_SHORT;
        short.pop();
        short.extend_from_slice(&7u32.to_le_bytes());
        short[0] += 3;
        assert!(postcard::from_bytes::<Retirements>(&short).is_err());
        let nine = Retire { credit: 9, ..one };
        let mut long = wire(&[nine]);
        long[1] = (long[1] & !CREDIT_MASK) | CREDIT_LONG;
        long.extend_from_slice(&[0; 4]);
        long[0] += 4;
        assert!(postcard::from_bytes::<Retirements>(&long).is_err());
        // The whole credit written as its byte (2^32: exponent 32).
        let mut whole = wire(&[Retire { credit: PIXEL_CREDIT, ..one }]);
        whole[1] = (whole[1] & !CREDIT_MASK) | CREDIT_SCALED;
        whole.push(32);
        whole[0] += 1;
        assert!(postcard::from_bytes::<Retirements>(&whole).is_err());
        // A flag no encoder sets.
        let mut odd = wire(&[one]);
        odd[1] |= 1 << 7;
        assert!(postcard::from_bytes::<Retirements>(&odd).is_err());
        // One background ray written as a count, or no background form at all.
        let mut counted = wire(&[Retire { background: 1, ..one }]);
        counted[1] = (counted[1] & !BACKGROUND_MASK) | BACKGROUND_COUNT;
        counted.push(1);
        counted[0] += 1;
        assert!(postcard::from_bytes::<Retirements>(&counted).is_err());
        let mut zero = wire(&[one]);
        zero[1] |= BACKGROUND_COUNT;
        zero.push(0);
        zero[0] += 1;
        assert!(postcard::from_bytes::<Retirements>(&zero).is_err());
        let mut form3 = wire(&[one]);
        form3[1] |= BACKGROUND_MASK;
        assert!(postcard::from_bytes::<Retirements>(&form3).is_err());
    }

    proptest::proptest! {
        /// Every field on both sides of its forms' limits, records pushed
        /// until one is refused: the list read back is what went in.
        #[test]
        fn records_round_trip_across_the_forms(
            records in proptest::collection::vec(
                (
                    proptest::num::u32::ANY,
                    proptest::prop_oneof![
                        proptest::strategy::Just([0u32; 3]),
                        proptest::array::uniform3(proptest::num::u32::ANY),
                    ],
                    proptest::prop_oneof![
                        proptest::strategy::Just(PIXEL_CREDIT),
                        proptest::strategy::Strategy::prop_map((0u32..64, 0u64..4), |(e, i)| (2 * i + 1) << e),
                        0u64..=u64::from(u32::MAX),
                        proptest::num::u64::ANY,
                    ],
                    proptest::prop_oneof![proptest::strategy::Just((0u8, 1u8)), (0u8..4, 1u8..4), (proptest::num::u8::ANY, proptest::num::u8::ANY)],
                    proptest::prop_oneof![0u8..3, proptest::num::u8::ANY],
                ),
                1..=16,
            ),
        ) {
            let records: std::vec::Vec<Retire> = records
                .into_iter()
                .enumerate()
                // Distinct pixels, so that none merge.
                .map(|(k, (pixel, rgb, credit, (spawned, rays), background))| {
                    Retire { pixel: pixel / 4 * 4 + k as u32, rgb, credit, spawned, rays, background }
                })
                .collect();
            let mut all = Retirements::new(records[0]);
            let mut taken = 1;
            for r in &records[1..] {
                let full = all.is_full();
                match all.push(*r) {
                    Ok(()) => taken += 1,
                    Err(back) => {
                        proptest::prop_assert!(full && taken >= 3);
                        proptest::prop_assert_eq!(back, *r);
                        break;
                    }
                }
                proptest::prop_assert!(!full);
            }
            proptest::prop_assert_eq!(listed(&all), &records[..taken]);
            let mut buf = [0u8; Retirements::POSTCARD_MAX_SIZE];
            let bytes = postcard::to_slice(&all, &mut buf).unwrap();
            proptest::prop_assert_eq!(postcard::from_bytes::<Retirements>(bytes), Ok(all));
        }
    }
}
