//! Rays that ended, several to a message: what a node tells the host.
//!
//! A node's host link carries one record for every ray that ends, and on real
//! boards (921 600 baud) that link bounds the frame. So records travel
//! together when the link is behind: up to [`Retirements::CAPACITY`] to a
//! message, and a pixel's rays that end together are summed into one record
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

/// One to [`Retirements::CAPACITY`] records, in the order they were added.
#[derive(Debug, Clone, Copy)]
pub struct Retirements {
    records: [Retire; Retirements::CAPACITY],
    len: u8,
}

impl Retirements {
    /// Records a message holds: as many as keep [`crate::Message`] no larger
    /// than a ray makes it, since a node moves every message whole (four
    /// made every message, rays too, about 2% dearer on a Cortex-M3).
    pub const CAPACITY: usize = 3;

    /// Records of one ray each, or summed per pixel.
    pub fn new(first: Retire) -> Self {
        let mut records = [Retire::default(); Self::CAPACITY];
        if let Some(slot) = records.first_mut() {
            *slot = first;
        }
        Self { records, len: 1 }
    }

    /// The records.
    pub fn records(&self) -> &[Retire] {
        self.records.get(..usize::from(self.len)).unwrap_or_default()
    }

    /// Whether no further record fits (one of a pixel already held may).
    pub fn is_full(&self) -> bool {
        usize::from(self.len) >= Self::CAPACITY
    }

    /// Adds `r`: into the record of its pixel if there is one, else as a new
    /// record. Hands it back when neither has room.
    #[allow(clippy::result_large_err)]
    pub fn push(&mut self, r: Retire) -> Result<(), Retire> {
        let len = usize::from(self.len);
        let r = match self.records.get_mut(..len).and_then(|rs| rs.iter_mut().find(|x| x.pixel == r.pixel)) {
            Some(record) => match record.merge(r) {
                Ok(()) => return Ok(()),
                Err(r) => r,
            },
            None => r,
        };
        match self.records.get_mut(len) {
            Some(slot) => {
                *slot = r;
                self.len += 1;
                Ok(())
            }
            None => Err(r),
        }
    }
}

/// Equal when they hold the same records (what lies beyond them is not theirs).
impl PartialEq for Retirements {
    fn eq(&self, other: &Self) -> bool {
        self.records() == other.records()
    }
}

impl Eq for Retirements {}

// The wire form of the records: hand-packed, one flag byte a record choosing
// the shortest form of each field. On real boards the host link bounds the
// frame, and a retirement is most of what it carries: postcard's form took
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
const WIRE_MAX_LEN: usize = Retirements::CAPACITY * RECORD_MAX_LEN;
const _: () = assert!(WIRE_MAX_LEN < 128, "the byte string's length must stay one varint byte");

fn flags_of(r: &Retire) -> u8 {
    flags_with(r, credit::Form::of(r.credit))
}

fn flags_with(r: &Retire, credit: credit::Form) -> u8 {
    let mut flags = credit.code() << CREDIT_SHIFT;
    if r.rgb == [0; 3] {
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

impl Serialize for Retirements {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut buf = [0u8; WIRE_MAX_LEN];
        let mut w = Writer::new(&mut buf);
        for r in self.records() {
            encode_record(r, &mut w).ok_or_else(|| S::Error::custom("records too long"))?;
        }
        let len = w.at;
        serializer.serialize_bytes(buf.get(..len).unwrap_or_default())
    }
}

impl<'de> Deserialize<'de> for Retirements {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Records;
        impl Visitor<'_> for Records {
            type Value = Retirements;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("one to three retirement records")
            }
            fn visit_bytes<E: serde::de::Error>(self, bytes: &[u8]) -> Result<Retirements, E> {
                let mut r = Reader { bytes };
                let first = decode_record(&mut r).ok_or_else(|| E::custom("not a record"))?;
                let mut all = Retirements::new(first);
                while !r.bytes.is_empty() {
                    let record = decode_record(&mut r).ok_or_else(|| E::custom("not a record"))?;
                    let len = usize::from(all.len);
                    let slot = all.records.get_mut(len).ok_or_else(|| E::custom("too many records"))?;
                    *slot = record;
                    all.len += 1;
                }
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

    #[test]
    fn a_pixel_s_rays_are_summed_and_others_take_records_until_full() {
        let mut all = Retirements::new(r(7, 10));
        assert_eq!(all.push(r(7, 5)), Ok(()));
        assert_eq!(
            all.records(),
            &[Retire { pixel: 7, rgb: [15, 30, 6], credit: 15 << 20, spawned: 2, rays: 2, background: 0 }]
        );
        for p in [1, 2] {
            assert_eq!(all.push(r(p, 1)), Ok(()));
        }
        assert!(all.is_full());
        assert_eq!(all.push(r(9, 1)), Err(r(9, 1)), "a fourth pixel has no room");
        assert_eq!(all.push(r(2, 4)), Ok(()), "a pixel held still merges");
        assert_eq!(all.records().len(), 3);
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
    fn records_round_trip_and_more_than_three_are_refused() {
        let mut all = Retirements::new(r(1, 1));
        for p in [2, 3] {
            all.push(r(p, p)).unwrap();
        }
        let mut buf = [0u8; Retirements::POSTCARD_MAX_SIZE];
        let bytes = postcard::to_slice(&all, &mut buf).unwrap();
        assert_eq!(postcard::from_bytes::<Retirements>(bytes), Ok(all));
        assert!(postcard::from_bytes::<Retirements>(&wire(&[r(1, 1); 4])).is_err());
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
        /// Every field on both sides of its forms' limits, up to three records.
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
                1..=3,
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
            for r in &records[1..] {
                all.push(*r).unwrap();
            }
            let mut buf = [0u8; Retirements::POSTCARD_MAX_SIZE];
            let bytes = postcard::to_slice(&all, &mut buf).unwrap();
            proptest::prop_assert_eq!(postcard::from_bytes::<Retirements>(bytes), Ok(all));
        }
    }
}
