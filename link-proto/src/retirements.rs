//! Rays that ended, several to a message: what a node tells the host.
//!
//! A node's host link carries one record for every ray that ends, and on real
//! boards (921 600 baud) that link bounds the frame. So records travel
//! together when the link is behind: up to [`Retirements::CAPACITY`] to a
//! message, and a pixel's rays that end together are summed into one record
//! (contributions are integers, so the host's sums do not change). Nothing
//! waits for company: whatever is ready when the link takes a message goes.

use postcard::experimental::max_size::MaxSize;
use serde::de::{Error as _, SeqAccess, Visitor};
use serde::ser::SerializeSeq;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Rays of one pixel that ended. Contributions are integers, so their sum is
/// independent of order and of how records are merged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, MaxSize)]
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
        ) {
            (true, [Some(r), Some(g), Some(b)], Some(credit), Some(spawned), Some(rays)) => {
                *self = Retire { pixel: self.pixel, rgb: [r, g, b], credit, spawned, rays };
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

impl Serialize for Retirements {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut seq = serializer.serialize_seq(Some(self.records().len()))?;
        for r in self.records() {
            seq.serialize_element(r)?;
        }
        seq.end()
    }
}

impl<'de> Deserialize<'de> for Retirements {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Records;
        impl<'de> Visitor<'de> for Records {
            type Value = Retirements;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("one to three retirement records")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Retirements, A::Error> {
                let first = seq.next_element()?.ok_or_else(|| A::Error::custom("no record"))?;
                let mut all = Retirements::new(first);
                while let Some(r) = seq.next_element::<Retire>()? {
                    let len = usize::from(all.len);
                    let slot =
                        all.records.get_mut(len).ok_or_else(|| A::Error::custom("too many records"))?;
                    *slot = r;
                    all.len += 1;
                }
                Ok(all)
            }
        }
        deserializer.deserialize_seq(Records)
    }
}

impl MaxSize for Retirements {
    // The count (one varint byte) and the records.
    const POSTCARD_MAX_SIZE: usize = 1 + Retirements::CAPACITY * Retire::POSTCARD_MAX_SIZE;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn r(pixel: u32, c: u32) -> Retire {
        Retire { pixel, rgb: [c, 2 * c, 3], credit: u64::from(c) << 20, spawned: 1, rays: 1 }
    }

    #[test]
    fn a_pixel_s_rays_are_summed_and_others_take_records_until_full() {
        let mut all = Retirements::new(r(7, 10));
        assert_eq!(all.push(r(7, 5)), Ok(()));
        assert_eq!(
            all.records(),
            &[Retire { pixel: 7, rgb: [15, 30, 6], credit: 15 << 20, spawned: 2, rays: 2 }]
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
        let mut a = r(1, 1);
        assert_eq!(a.merge(r(2, 1)), Err(r(2, 1)), "another pixel");
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
        let four = [r(1, 1); 4];
        let mut buf = [0u8; 256];
        let bytes = postcard::to_slice(&four.as_slice(), &mut buf).unwrap();
        assert!(postcard::from_bytes::<Retirements>(bytes).is_err());
        assert!(postcard::from_bytes::<Retirements>(&[0]).is_err(), "no record");
    }
}
