//! Rays that ended, several to a message: what a node tells the host.
//!
//! A node's host link carries what every ray that ends leaves behind: on
//! real boards (921 600 baud) it is busy most of the frame. So a message
//! carries two things apart:
//! - [`Totals`]: the credit the rays hand back, how many they are and how
//!   many they spawned. The host only ever sums these (the frame is
//!   complete when its credit is all back), so a message carries their sum
//!   once;
//! - [`Contribution`]s: what the rays add to their pixels, a pixel's rays
//!   that end one after another summed into one (contributions are
//!   integers, so the host's sums do not change). A ray that adds nothing
//!   (a blocked shadow ray) has none.
//!
//! Records travel together when the link is behind: as many to a message as
//! fit a ray's size packed (about ten). A node holds a message with room
//! only while it has work of its own (see `node_fw`'s `transmit`), so the
//! last records of a frame never wait.

use postcard::experimental::max_size::MaxSize;
use serde::de::Visitor;
use serde::ser::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::pack::{Reader, Writer};

/// A ray that ended, or rays of one pixel: what a node hands the host.
/// Contributions are integers, so their sum is independent of order and of
/// how records are merged.
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

/// What rays that ended add to one pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Contribution {
    /// Pixel index `y * width + x`.
    pub pixel: u32,
    /// Per channel, Q1.15, beside the background.
    pub rgb: [u32; 3],
    /// Rays that left the scene at full strength: each adds the background.
    pub background: u8,
}

impl Contribution {
    /// What `r` adds to its pixel; `None` if nothing (a blocked shadow ray).
    pub fn of(r: &Retire) -> Option<Self> {
        let c = Self { pixel: r.pixel, rgb: r.rgb, background: r.background };
        c.adds_something().then_some(c)
    }

    /// Whether it changes its pixel (no record is written of one that does not).
    fn adds_something(&self) -> bool {
        // Component by component: an array's `==` is a `memcmp` call on a Cortex-M3.
        let [red, green, blue] = self.rgb;
        red | green | blue != 0 || self.background != 0
    }

    /// Adds `other` into this one; hands it back when it is another pixel's
    /// or a sum would overflow.
    // Handing it back is the point: the caller keeps it for another record.
    #[allow(clippy::result_large_err)]
    pub fn merge(&mut self, other: Contribution) -> Result<(), Contribution> {
        let ([r0, g0, b0], [r1, g1, b1]) = (self.rgb, other.rgb);
        match (
            other.pixel == self.pixel,
            [r0.checked_add(r1), g0.checked_add(g1), b0.checked_add(b1)],
            self.background.checked_add(other.background),
        ) {
            (true, [Some(r), Some(g), Some(b)], Some(background)) => {
                *self = Contribution { pixel: self.pixel, rgb: [r, g, b], background };
                Ok(())
            }
            _ => Err(other),
        }
    }
}

/// What the rays of a message account for, summed: the host adds these up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Totals {
    /// Credit handed back.
    pub credit: u64,
    /// Rays the ending rays spawned.
    pub spawned: u16,
    /// Rays that ended.
    pub rays: u16,
}

impl Totals {
    /// These and `r`'s; `None` if a sum would overflow.
    fn plus(&self, r: &Retire) -> Option<Self> {
        Some(Self {
            credit: self.credit.checked_add(r.credit)?,
            spawned: self.spawned.checked_add(u16::from(r.spawned))?,
            rays: self.rays.checked_add(u16::from(r.rays))?,
        })
    }
}

/// The totals of the rays that ended and their contributions in the order
/// they were added: the last unpacked, so that a pixel's next ray (most
/// merges) is summed into it, and those before it packed in their wire
/// form. A node moves every message whole, so a message is kept to a ray's
/// size (a larger one made every message, rays too, dearer on a
/// Cortex-M3): about ten of the usual records fit it packed, and at least
/// three of any.
#[derive(Debug, Clone, Copy)]
pub struct Retirements {
    /// The sums of every ray added.
    totals: Totals,
    /// The last contribution, open to the next ray of its pixel.
    last: Option<Contribution>,
    /// The contributions before it, in their wire form.
    packed: [u8; PACKED_MAX],
    /// Bytes of `packed` in use.
    packed_len: u8,
    /// Contributions in all, the last included.
    len: u8,
    /// The pixel of the last packed record (when there is one), which the
    /// next record's pixel is written against.
    packed_pixel: u32,
}

/// Room for the packed records: with the totals and the last one, a
/// message stays within a ray's size (a test holds it), and it holds two
/// records of the longest form, so that any three fit.
const PACKED_MAX: usize = 74;
const _: () = assert!(PACKED_MAX >= 2 * RECORD_MAX_LEN && PACKED_MAX < 256);

impl Retirements {
    /// One ray that ended, or a pixel's rays summed. Its totals overflow nothing.
    pub fn new(first: Retire) -> Self {
        let totals =
            Totals { credit: first.credit, spawned: u16::from(first.spawned), rays: u16::from(first.rays) };
        let last = Contribution::of(&first);
        Self {
            totals,
            last,
            packed: [0; PACKED_MAX],
            packed_len: 0,
            len: u8::from(last.is_some()),
            packed_pixel: 0,
        }
    }

    /// How many contributions there are.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether the rays added nothing to any pixel (blocked shadow rays).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The sums of the rays' credit and counts.
    pub fn totals(&self) -> Totals {
        self.totals
    }

    /// The contributions, in the order they were added.
    pub fn iter(&self) -> Contributions<'_> {
        Contributions { packed: Reader { bytes: self.packed_bytes() }, last: self.last, before: None }
    }

    /// The pixel the last record's is written against: the last packed
    /// record's, if any.
    fn before_last(&self) -> Option<u32> {
        (self.packed_len > 0).then_some(self.packed_pixel)
    }

    /// The packed records' bytes.
    fn packed_bytes(&self) -> &[u8] {
        self.packed.get(..usize::from(self.packed_len)).unwrap_or_default()
    }

    /// Whether a ray of another pixel would be refused: the last
    /// contribution no longer fits among the packed ones (a ray of its
    /// pixel may still merge, and one that adds nothing still joins).
    pub fn is_full(&self) -> bool {
        let Some(last) = &self.last else { return false };
        let mut scratch = [0u8; RECORD_MAX_LEN];
        let mut w = Writer::new(&mut scratch);
        encode_record(last, self.before_last(), &mut w)
            .is_none_or(|()| usize::from(self.packed_len) + w.at > PACKED_MAX)
    }

    /// Adds `r`: its credit and counts to the totals, and what it adds to
    /// its pixel into the last contribution if it is of the same pixel (and
    /// the sums fit), else as a new one after it. Hands `r` back when a
    /// total would overflow or there is no room; then nothing changed.
    #[allow(clippy::result_large_err)]
    pub fn push(&mut self, r: Retire) -> Result<(), Retire> {
        let Some(totals) = self.totals.plus(&r) else { return Err(r) };
        if let Some(c) = Contribution::of(&r) {
            self.add(c).map_err(|_| r)?;
        }
        self.totals = totals;
        Ok(())
    }

    /// Adds `c` after the contributions, into the last where it merges.
    fn add(&mut self, c: Contribution) -> Result<(), Contribution> {
        let Some(mut last) = self.last else {
            self.last = Some(c);
            self.len = 1;
            return Ok(());
        };
        let c = match last.merge(c) {
            Ok(()) => {
                self.last = Some(last);
                return Ok(());
            }
            Err(c) => c,
        };
        let (at, before) = (usize::from(self.packed_len), self.before_last());
        let Some(room) = self.packed.get_mut(at..) else { return Err(c) };
        let mut w = Writer::new(room);
        if encode_record(&last, before, &mut w).is_none() {
            // A partial record past `packed_len` is not one: nothing changed.
            return Err(c);
        }
        // At most PACKED_MAX (< 256) bytes, and a record per two of them.
        self.packed_len += w.at as u8;
        self.len += 1;
        self.packed_pixel = last.pixel;
        self.last = Some(c);
        Ok(())
    }
}

/// The contributions of a [`Retirements`], in order.
#[derive(Debug, Clone)]
pub struct Contributions<'a> {
    packed: Reader<'a>,
    last: Option<Contribution>,
    /// The pixel of the record before the next one.
    before: Option<u32>,
}

impl Iterator for Contributions<'_> {
    type Item = Contribution;

    fn next(&mut self) -> Option<Contribution> {
        if self.packed.bytes.is_empty() {
            return self.last.take();
        }
        // Packed by `add` or checked by the decoder: every record reads
        // back. Were one not to, the iterator would end, not panic.
        let record = decode_record(&mut self.packed, self.before);
        match record {
            Some(c) => self.before = Some(c.pixel),
            None => {
                self.packed.bytes = &[];
                self.last = None;
            }
        }
        record
    }
}

/// Equal when they hold the same totals and contributions: each record has
/// one wire form, so the packed bytes are equal too (what lies beyond them
/// is not theirs).
impl PartialEq for Retirements {
    fn eq(&self, other: &Self) -> bool {
        self.totals == other.totals
            && self.len == other.len
            && self.last == other.last
            && self.packed_bytes() == other.packed_bytes()
    }
}

impl Eq for Retirements {}

// The wire form: hand-packed. A retirement is most of what a host link
// carries: postcard's form took 14.5 bytes a record (1000 spheres, 4x4x4,
// 921 600 baud), most of them a primary ray's whole credit (a five-byte
// varint) and counts of one ray; a record of its own for each ray's credit
// and counts took 8.7 bytes of the 10.5 a record cost (4x8x2, 256x256).
//
// Layout: the totals (credit as an exponent byte and an odd varint,
// spawned and rays as varints), then the
// contributions, each: flags, pixel, [rgb (3 varints)], [background
// count]. The first record's pixel is a varint; each later one's is its
// difference from the record's before it, zigzagged (0, -1, 1, -2, ...)
// into a varint: a node's rays come by tiles and rows, so neighbours in a
// message are mostly near, two bytes where a 256x256 image's pixels take
// three. Each message has exactly one encoding: bytes that
// are not the encoder's choice are refused.
//
// A primary ray that met nothing (behind a sparse scene, most of what the
// nodes at the back of the array retire) contributes the background colour
// itself: its record is the flags and the pixel, about four bytes.

/// No colour beside the background: no rgb bytes.
const RGB_ZERO: u8 = 1 << 0;
const BACKGROUND_SHIFT: u32 = 1;
const BACKGROUND_MASK: u8 = 0b11 << BACKGROUND_SHIFT;
/// No ray at full strength left the scene: no byte.
const BACKGROUND_NONE: u8 = 0;
/// One did: no byte.
const BACKGROUND_ONE: u8 = 1 << BACKGROUND_SHIFT;
/// Two or more did: their count in a byte.
const BACKGROUND_COUNT: u8 = 2 << BACKGROUND_SHIFT;
const KNOWN_FLAGS: u8 = RGB_ZERO | BACKGROUND_MASK;

/// The longest record: flags, four five-byte varints (a difference of
/// pixels takes 33 bits zigzagged) and the count.
const RECORD_MAX_LEN: usize = 1 + 5 + 15 + 1;
/// The longest totals: the credit's exponent and ten-byte varint, and two
/// three-byte varints.
const TOTALS_MAX_LEN: usize = 1 + 10 + 3 + 3;
/// The longest wire form of a message's retirements.
pub(crate) const WIRE_MAX_LEN: usize = TOTALS_MAX_LEN + PACKED_MAX + RECORD_MAX_LEN;
const _: () = assert!(WIRE_MAX_LEN < 128, "the byte string's length must stay one varint byte");

fn flags_of(c: &Contribution) -> u8 {
    // Component by component: an array's `==` is a `memcmp` call on a Cortex-M3.
    let [red, green, blue] = c.rgb;
    let rgb = if red | green | blue == 0 { RGB_ZERO } else { 0 };
    rgb | match c.background {
        0 => BACKGROUND_NONE,
        1 => BACKGROUND_ONE,
        _ => BACKGROUND_COUNT,
    }
}

/// `d` zigzagged: 0, -1, 1, -2, ... as 0, 1, 2, 3, ...
fn zigzag(d: i64) -> u64 {
    ((d << 1) ^ (d >> 63)) as u64
}

/// The difference `zigzag` made `z` of.
fn unzigzag(z: u64) -> i64 {
    ((z >> 1) as i64) ^ -((z & 1) as i64)
}

/// Packs `c` after what `w` holds, its pixel against `before`'s.
fn encode_record(c: &Contribution, before: Option<u32>, w: &mut Writer<'_>) -> Option<()> {
    let flags = flags_of(c);
    w.put(&[flags])?;
    match before {
        None => w.varint(c.pixel)?,
        Some(b) => w.varint64(zigzag(i64::from(c.pixel) - i64::from(b)))?,
    }
    if flags & RGB_ZERO == 0 {
        for v in c.rgb {
            w.varint(v)?;
        }
    }
    if flags & BACKGROUND_MASK == BACKGROUND_COUNT {
        w.put(&[c.background])?;
    }
    Some(())
}

/// Unpacks the record at the front of `r`'s bytes, its pixel written
/// against `before`'s.
fn decode_record(r: &mut Reader<'_>, before: Option<u32>) -> Option<Contribution> {
    let flags = r.u8()?;
    if flags & !KNOWN_FLAGS != 0 {
        return None;
    }
    let pixel = match before {
        None => r.varint()?,
        // A difference no two pixels have is no record's.
        Some(b) => u32::try_from(i64::from(b).checked_add(unzigzag(r.varint64()?))?).ok()?,
    };
    let rgb = if flags & RGB_ZERO != 0 { [0; 3] } else { [r.varint()?, r.varint()?, r.varint()?] };
    let background = match flags & BACKGROUND_MASK {
        BACKGROUND_NONE => 0,
        BACKGROUND_ONE => 1,
        BACKGROUND_COUNT => r.u8()?,
        _ => return None,
    };
    let record = Contribution { pixel, rgb, background };
    // One record, one encoding: the forms must be the ones the encoder
    // chose, and a record that adds nothing is never written.
    (flags_of(&record) == flags && record.adds_something()).then_some(record)
}

fn encode_totals(t: &Totals, w: &mut Writer<'_>) -> Option<()> {
    // Credit as an odd multiple of a power of two (0 as 0 of 2^0): a pixel's
    // is 2^32 and a hit splits a ray's by powers of two, so a message's sum
    // is a small odd number of a large power: two bytes where a varint of
    // the sum took five.
    let exponent = if t.credit == 0 { 0 } else { t.credit.trailing_zeros() };
    w.put(&[exponent as u8])?;
    w.varint64(t.credit >> exponent)?;
    w.varint(u32::from(t.spawned))?;
    w.varint(u32::from(t.rays))
}

fn decode_totals(r: &mut Reader<'_>) -> Option<Totals> {
    let exponent = u32::from(r.u8()?);
    let odd = r.varint64()?;
    // One encoding: an odd multiple, or 0 of 2^0; and no bit shifted out.
    let canonical = if odd == 0 { exponent == 0 } else { odd % 2 == 1 && exponent < 64 };
    let credit = odd.checked_shl(exponent).filter(|c| canonical && c >> exponent == odd)?;
    let spawned = u16::try_from(r.varint()?).ok()?;
    let rays = u16::try_from(r.varint()?).ok()?;
    Some(Totals { credit, spawned, rays })
}

impl Retirements {
    /// Writes the wire form at the start of `out` (the totals, the packed
    /// records, then the last); its length, at most [`WIRE_MAX_LEN`], or
    /// `None` when `out` is shorter.
    pub(crate) fn encode_wire(&self, out: &mut [u8]) -> Option<usize> {
        let mut w = Writer::new(out);
        encode_totals(&self.totals, &mut w)?;
        w.put(self.packed_bytes())?;
        if let Some(last) = &self.last {
            encode_record(last, self.before_last(), &mut w)?;
        }
        Some(w.at)
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
                let totals = decode_totals(&mut r).ok_or_else(not_a_record)?;
                let records = r.bytes;
                let (mut last, mut last_at, mut len) = (None::<Contribution>, 0usize, 0u8);
                let mut packed_pixel = 0;
                while !r.bytes.is_empty() {
                    last_at = records.len() - r.bytes.len();
                    let before = last.map(|c| c.pixel);
                    packed_pixel = before.unwrap_or(0);
                    last = Some(decode_record(&mut r, before).ok_or_else(not_a_record)?);
                    len = len.checked_add(1).ok_or_else(|| E::custom("too many records"))?;
                }
                // The records before the last must fit where a node packs them.
                let before = records.get(..last_at).filter(|b| b.len() <= PACKED_MAX);
                let before = before.ok_or_else(|| E::custom("too many records"))?;
                let packed_len = last_at as u8;
                let mut all =
                    Retirements { totals, last, packed: [0; PACKED_MAX], packed_len, len, packed_pixel };
                all.packed.get_mut(..last_at).ok_or_else(not_a_record)?.copy_from_slice(before);
                Ok(all)
            }
        }
        deserializer.deserialize_bytes(Records)
    }
}

impl MaxSize for Retirements {
    // The byte string's length (one varint byte) and the wire form.
    const POSTCARD_MAX_SIZE: usize = 1 + WIRE_MAX_LEN;
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    use crate::ray_wire::PIXEL_CREDIT;

    fn r(pixel: u32, c: u32) -> Retire {
        Retire { pixel, rgb: [c, 2 * c, 3], credit: u64::from(c) << 20, spawned: 1, rays: 1, background: 0 }
    }

    fn c(pixel: u32, rgb: [u32; 3], background: u8) -> Contribution {
        Contribution { pixel, rgb, background }
    }

    /// The contributions, as a list.
    fn listed(all: &Retirements) -> std::vec::Vec<Contribution> {
        all.iter().collect()
    }

    /// The totals of `rays`, summed here in 128 bits.
    fn summed(rays: &[Retire]) -> (u128, u32, u32) {
        rays.iter().fold((0, 0, 0), |(c, s, n), r| {
            (c + u128::from(r.credit), s + u32::from(r.spawned), n + u32::from(r.rays))
        })
    }

    fn totals_of(all: &Retirements) -> (u128, u32, u32) {
        let t = all.totals();
        (u128::from(t.credit), u32::from(t.spawned), u32::from(t.rays))
    }

    #[test]
    fn a_pixel_s_next_ray_is_summed_and_others_take_records_until_full() {
        let mut all = Retirements::new(r(7, 10));
        assert_eq!(all.push(r(7, 5)), Ok(()));
        assert_eq!(listed(&all), [c(7, [15, 30, 6], 0)]);
        assert_eq!(all.push(r(1, 1)), Ok(()));
        assert_eq!(all.push(r(7, 1)), Ok(()), "a pixel not last takes a record of its own");
        assert_eq!(listed(&all), [c(7, [15, 30, 6], 0), c(1, [1, 2, 3], 0), c(7, [1, 2, 3], 0)]);
        assert_eq!(totals_of(&all), summed(&[r(7, 10), r(7, 5), r(1, 1), r(7, 1)]));
        // A lit shadow ray's record in a 256x256 image: flags, three bytes
        // of pixel (one against a neighbour's), two of each colour.
        let lit = |pixel| Retire {
            pixel,
            rgb: [3000, 2000, 1000],
            credit: PIXEL_CREDIT >> 3,
            spawned: 0,
            rays: 1,
            background: 0,
        };
        let mut all = Retirements::new(lit(20_000));
        let mut pushed = std::vec![lit(20_000)];
        let mut pixel = 20_001;
        while !all.is_full() {
            assert_eq!(all.push(lit(pixel)), Ok(()));
            pushed.push(lit(pixel));
            pixel += 1;
        }
        assert_eq!(all.push(r(pixel, 1)), Err(r(pixel, 1)), "full: another pixel has no room");
        assert_eq!(all.push(lit(pixel - 1)), Ok(()), "the last pixel still merges");
        pushed.push(lit(pixel - 1));
        let blocked = Retire { rgb: [0; 3], ..lit(pixel) };
        assert_eq!(all.push(blocked), Ok(()), "a ray that adds nothing still joins");
        pushed.push(blocked);
        let mut expected: std::vec::Vec<Contribution> =
            (20_000..pixel).map(|p| c(p, [3000, 2000, 1000], 0)).collect();
        let Some(last) = expected.last_mut() else { panic!("records were pushed") };
        last.rgb = [6000, 4000, 2000];
        assert_eq!(listed(&all), expected);
        assert_eq!(totals_of(&all), summed(&pushed));
        // Ten bytes the first, eight each after it (a pixel one on from the
        // one before: a byte): ten records, where three fitted unpacked.
        assert_eq!(all.len(), 10);
    }

    #[test]
    fn rays_that_add_nothing_take_no_record() {
        let blocked = Retire { rgb: [0; 3], background: 0, ..r(9, 0) };
        let mut all = Retirements::new(blocked);
        assert!(all.is_empty() && !all.is_full());
        assert_eq!(all.push(Retire { pixel: 12, ..blocked }), Ok(()));
        assert_eq!(listed(&all), []);
        assert_eq!(all.push(r(3, 2)), Ok(()));
        assert_eq!(listed(&all), [c(3, [2, 4, 3], 0)]);
        let rays = [blocked, Retire { pixel: 12, ..blocked }, r(3, 2)];
        assert_eq!(totals_of(&all), summed(&rays));
        // On the wire: the totals alone, then one record.
        let only = Retirements::new(blocked);
        let bytes = to_wire(&only);
        assert_eq!(bytes, [4, 0, 0, 1, 1], "length, credit 0 (of 2^0), one spawned, one ray");
        assert_eq!(from_wire(&bytes), Some(only));
    }

    #[test]
    fn any_three_records_fit_and_a_message_stays_within_a_ray_s_size() {
        let longest = |p| Retire {
            pixel: u32::MAX - p,
            rgb: [u32::MAX; 3],
            credit: u64::MAX / 4,
            spawned: 9,
            rays: 9,
            background: 9,
        };
        let mut all = Retirements::new(longest(0));
        for p in [1, 2] {
            assert_eq!(all.push(longest(p)), Ok(()));
        }
        let want: std::vec::Vec<_> = (0..3).map(|p| c(u32::MAX - p, [u32::MAX; 3], 9)).collect();
        assert_eq!(listed(&all), want);
        assert!(core::mem::size_of::<Retirements>() <= core::mem::size_of::<crate::RayMsg>());
        assert_eq!(from_wire(&to_wire(&all)), Some(all));
    }

    #[test]
    fn a_sum_that_would_overflow_is_refused_and_changes_nothing() {
        let mut a = c(1, [u32::MAX, 0, 0], 0);
        assert_eq!(a.merge(c(1, [1, 0, 0], 0)), Err(c(1, [1, 0, 0], 0)));
        let mut a = c(1, [1, 0, 0], 255);
        assert_eq!(a.merge(c(1, [1, 0, 0], 1)), Err(c(1, [1, 0, 0], 1)));
        let mut a = c(1, [1, 0, 0], 0);
        assert_eq!(a.merge(c(2, [1, 0, 0], 0)), Err(c(2, [1, 0, 0], 0)), "another pixel");
        // The totals: credit, and 65 535 rays.
        for (first, next) in [
            (Retire { credit: u64::MAX, ..r(1, 1) }, r(1, 1)),
            (Retire { rays: 255, ..r(1, 1) }, Retire { rays: 1, ..r(1, 1) }),
        ] {
            let mut all = Retirements::new(first);
            let mut more = 0;
            while all.push(Retire { credit: 0, ..first }).is_ok() && more < 1000 {
                more += 1;
            }
            let before = all;
            assert_eq!(all.push(next), Err(next));
            assert_eq!(all, before);
        }
    }

    /// `all`'s postcard form.
    fn to_wire(all: &Retirements) -> std::vec::Vec<u8> {
        let mut buf = [0u8; Retirements::POSTCARD_MAX_SIZE];
        match postcard::to_slice(all, &mut buf) {
            Ok(bytes) => bytes.to_vec(),
            Err(e) => panic!("{all:?} does not encode: {e}"),
        }
    }

    /// The retirements `bytes` are the postcard form of, if any.
    fn from_wire(bytes: &[u8]) -> Option<Retirements> {
        postcard::from_bytes(bytes).ok()
    }

    /// A wire form: the totals' bytes, then the records', each pixel
    /// against the one before as the encoder writes it.
    fn wire(totals: &[u8], records: &[Contribution]) -> std::vec::Vec<u8> {
        let mut buf = [0u8; 255];
        let mut w = Writer::new(&mut buf[1..]);
        let mut before = None;
        let fits = w.put(totals).is_some()
            && records.iter().all(|r| {
                let written = encode_record(r, before, &mut w).is_some();
                before = Some(r.pixel);
                written
            });
        assert!(fits, "a test's records fit 254 bytes");
        let n = w.at;
        buf[0] = n as u8;
        buf[..=n].to_vec()
    }

    #[test]
    fn records_round_trip_and_more_than_a_node_packs_are_refused() {
        let mut all = Retirements::new(r(1, 1));
        for p in 2..=10 {
            assert_eq!(all.push(r(p, p)), Ok(()));
        }
        assert_eq!(from_wire(&to_wire(&all)), Some(all));
        // Records before the last beyond what a node packs: 74 bytes.
        let wide = c(0, [1 << 30; 3], 0);
        let records: std::vec::Vec<_> = (0..7).map(|p| Contribution { pixel: 1 << 28 | p, ..wide }).collect();
        assert_eq!(wire(&[], &records[..1]).len() - 1, 21);
        assert_eq!(wire(&[], &records[..2]).len() - 1, 21 + 17, "a pixel one on: a byte");
        assert!(from_wire(&wire(&[0, 0, 0, 0], &records[..5])).is_some(), "72 before the last");
        assert!(from_wire(&wire(&[0, 0, 0, 0], &records[..6])).is_none(), "89 before the last");
        assert!(from_wire(&[0]).is_none(), "no totals");
        assert!(from_wire(&[2, 0, 0]).is_none(), "totals cut short");
    }

    #[test]
    fn a_pixel_is_written_against_the_one_before_both_ways_and_to_the_ends() {
        let one = |pixel| c(pixel, [5, 6, 7], 0);
        let pixels = [70_000, 70_001, 69_990, 0, u32::MAX, 1, u32::MAX - 1, 70_000, 70_000];
        let records: std::vec::Vec<_> = pixels.iter().map(|&p| one(p)).collect();
        let bytes = wire(&[0, 0, 0, 1], &records);
        // 70 000 takes three bytes alone; +1 and -11 one each.
        assert_eq!(wire(&[], &records[..3]).len() - 1, (1 + 3 + 3) + (1 + 1 + 3) + (1 + 1 + 3));
        assert_eq!(from_wire(&bytes).map(|all| listed(&all)), Some(records.clone()));
        // A difference that leaves the pixels' range is no record's.
        let mut below = wire(&[0, 0, 0, 1], &records[..1]);
        below.extend_from_slice(&[0, 0xff, 0xff, 0xff, 0xff, 0x0f, 5, 6, 7]);
        below[0] += 9;
        assert!(from_wire(&below).is_none());
    }

    #[test]
    fn a_primary_ray_that_missed_takes_its_flags_and_pixel() {
        let miss =
            Retire { pixel: 300, rgb: [0; 3], credit: PIXEL_CREDIT, spawned: 0, rays: 1, background: 1 };
        // The string's length; the totals: the pixel's credit (1 of 2^32,
        // two bytes), none spawned, one ray; then flags and a two-byte pixel.
        assert_eq!(to_wire(&Retirements::new(miss)), [7, 32, 1, 0, 1, BACKGROUND_ONE | RGB_ZERO, 172, 2]);
        // Under the full strength, its colour: two, two and three bytes.
        let dim = c(300, [1000, 2000, 30000], 0);
        assert_eq!(wire(&[], &[dim]).len(), 1 + 1 + 2 + 2 + 2 + 3);
        // Merged with another such ray of its pixel: the background count.
        let Some(mut two) = Contribution::of(&miss) else { panic!("a miss adds the background") };
        assert_eq!(two.merge(two), Ok(()));
        assert_eq!(two.background, 2);
        assert_eq!(wire(&[], &[two]).len(), 1 + 1 + 2 + 1);
    }

    #[test]
    fn a_second_encoding_of_the_same_message_is_refused() {
        let ok = |bytes: &[u8]| from_wire(bytes).is_some();
        let one = c(5, [0; 3], 1);
        assert!(ok(&wire(&[0, 0, 0, 1], &[one])));
        // A varint of the totals written longer than it needs.
        assert!(!ok(&wire(&[0, 0x80, 0x00, 0, 1], &[one])));
        // Credit 12 only as 3 of 2^2: not 6 of 2^1, nor 0 of 2^5, nor past 64 bits.
        assert!(ok(&wire(&[2, 3, 0, 1], &[one])));
        assert!(!ok(&wire(&[1, 6, 0, 1], &[one])));
        assert!(!ok(&wire(&[5, 0, 0, 1], &[one])));
        assert!(!ok(&wire(&[63, 3, 0, 1], &[one])));
        assert!(!ok(&wire(&[64, 1, 0, 1], &[one])));
        // Colour written out though it is none.
        let mut zero_rgb = wire(&[0, 0, 0, 1], &[one]);
        zero_rgb[5] &= !RGB_ZERO;
        zero_rgb.extend_from_slice(&[0, 0, 0]);
        zero_rgb[0] += 3;
        assert!(!ok(&zero_rgb));
        // A flag no encoder sets.
        let mut odd = wire(&[0, 0, 0, 1], &[one]);
        odd[5] |= 1 << 7;
        assert!(!ok(&odd));
        // One background ray written as a count, or the count's form unused.
        let mut counted = wire(&[0, 0, 0, 1], &[one]);
        counted[5] = (counted[5] & !BACKGROUND_MASK) | BACKGROUND_COUNT;
        counted.push(1);
        counted[0] += 1;
        assert!(!ok(&counted));
        let mut form3 = wire(&[0, 0, 0, 1], &[one]);
        form3[5] |= BACKGROUND_MASK;
        assert!(!ok(&form3));
        // A record that adds nothing, which no encoder writes.
        let mut nothing = wire(&[0, 0, 0, 1], &[one]);
        nothing[5] &= !BACKGROUND_MASK;
        assert!(!ok(&nothing));
        // Counts past their 16 bits.
        assert!(!ok(&wire(&[0, 0, 0x80, 0x80, 0x04, 1], &[one])));
    }

    proptest::proptest! {
        /// Every field on both sides of its forms' limits, rays pushed
        /// until one is refused: the contributions read back are what went
        /// in, and the totals are the rays' sums.
        #[test]
        fn retirements_round_trip_across_the_forms(
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
                let adds = Contribution::of(r).is_some();
                match all.push(*r) {
                    Ok(()) => taken += 1,
                    Err(back) => {
                        let t = all.totals();
                        let overflow = t.credit.checked_add(r.credit).is_none();
                        proptest::prop_assert!(overflow || (adds && full && all.len() >= 3));
                        proptest::prop_assert_eq!(back, *r);
                        break;
                    }
                }
                proptest::prop_assert!(!(full && adds));
            }
            let want: std::vec::Vec<_> = records[..taken].iter().filter_map(Contribution::of).collect();
            proptest::prop_assert_eq!(listed(&all), want);
            proptest::prop_assert_eq!(totals_of(&all), summed(&records[..taken]));
            proptest::prop_assert_eq!(from_wire(&to_wire(&all)), Some(all));
        }
    }
}
