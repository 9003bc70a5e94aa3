//! A ray's wire form: fixed little-endian fields, packed and unpacked by
//! hand, carried in a frame as one postcard byte string.
//!
//! Rays are most of the traffic between nodes, and postcard's field-by-field
//! walk (a varint per integer, a tag per option and enum) was about half of
//! what a ray's frame cost to encode and decode on the Cortex-M3 (see
//! `scripts/firmware.sh`'s `ray_frame_*` kernels). Here a ray is a flags
//! byte, then its fields at fixed offsets; the optional ones follow only when
//! present, and two common cases take fewer bytes: weights that fit 16 bits
//! and credit under 2^40 (a primary ray's 2^32 and every share of it). Any
//! [`RayMsg`] round-trips; bytes that are not one are refused, never read as
//! something else.
//!
//! Layout, after the flags and the depth byte: origin (3 x i32), direction
//! (3 x i32), cell (3 x u16), pixel (u32), weights (3 x u16 or 3 x u32),
//! credit (5 or 8 bytes), class (u16), tag (u16), then `ignore` (u16),
//! `t_max` (i32) and `best` (t as i32, then the sphere) when present.

use serde::de::{Error as _, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::message::{HitMsg, MaterialMsg, RayKind, RayMsg, SphereMsg};

const HAS_IGNORE: u8 = 1 << 0;
const HAS_BEST: u8 = 1 << 1;
const HAS_T_MAX: u8 = 1 << 2;
const SHORT_WEIGHTS: u8 = 1 << 3;
const SHORT_CREDIT: u8 = 1 << 4;
const KIND_SHIFT: u32 = 5;
const KIND_MASK: u8 = 0b11 << KIND_SHIFT;
const KNOWN: u8 = HAS_IGNORE | HAS_BEST | HAS_T_MAX | SHORT_WEIGHTS | SHORT_CREDIT | KIND_MASK;

/// A sphere's bytes: id, centre, radius, colour, four coefficients and the exponent.
const SPHERE_LEN: usize = 2 + 12 + 4 + 6 + 8 + 1;
/// The longest ray: every option present, long weights and credit.
pub const RAY_MAX_LEN: usize = 2 + 12 + 12 + 6 + 4 + 12 + 8 + 2 + 2 + 2 + 4 + 4 + SPHERE_LEN;

/// Writes fields one after another into a buffer.
struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) -> Option<()> {
        let end = self.at.checked_add(bytes.len())?;
        self.out.get_mut(self.at..end)?.copy_from_slice(bytes);
        self.at = end;
        Some(())
    }
}

/// Reads fields one after another from a buffer.
struct Reader<'a> {
    bytes: &'a [u8],
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, rest) = self.bytes.split_at_checked(N)?;
        self.bytes = rest;
        head.try_into().ok()
    }
    fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|[b]| b)
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    fn i32x3(&mut self) -> Option<[i32; 3]> {
        Some([self.i32()?, self.i32()?, self.i32()?])
    }
}

fn kind_bits(kind: RayKind) -> u8 {
    let k = match kind {
        RayKind::Primary => 0,
        RayKind::Reflected => 1,
        RayKind::Shadow => 2,
    };
    k << KIND_SHIFT
}

fn kind_of(flags: u8) -> Option<RayKind> {
    match (flags & KIND_MASK) >> KIND_SHIFT {
        0 => Some(RayKind::Primary),
        1 => Some(RayKind::Reflected),
        2 => Some(RayKind::Shadow),
        _ => None,
    }
}

/// Packs `ray` into `out`; the length written, or `None` if `out` is shorter
/// than the ray needs ([`RAY_MAX_LEN`] always suffices).
pub fn encode_ray(ray: &RayMsg, out: &mut [u8]) -> Option<usize> {
    let short_weights = ray.weight.iter().all(|&w| w <= u32::from(u16::MAX));
    let short_credit = ray.credit < 1 << 40;
    let mut flags = kind_bits(ray.kind);
    for (set, bit) in [
        (ray.ignore.is_some(), HAS_IGNORE),
        (ray.best.is_some(), HAS_BEST),
        (ray.t_max.is_some(), HAS_T_MAX),
        (short_weights, SHORT_WEIGHTS),
        (short_credit, SHORT_CREDIT),
    ] {
        if set {
            flags |= bit;
        }
    }
    let mut w = Writer { out, at: 0 };
    w.put(&[flags, ray.depth])?;
    for v in ray.origin.iter().chain(&ray.dir) {
        w.put(&v.to_le_bytes())?;
    }
    for c in ray.cell {
        w.put(&c.to_le_bytes())?;
    }
    w.put(&ray.pixel.to_le_bytes())?;
    for v in ray.weight {
        if short_weights {
            w.put(&(v as u16).to_le_bytes())?;
        } else {
            w.put(&v.to_le_bytes())?;
        }
    }
    let credit = ray.credit.to_le_bytes();
    w.put(credit.get(..if short_credit { 5 } else { 8 })?)?;
    w.put(&ray.class.to_le_bytes())?;
    w.put(&ray.tag.to_le_bytes())?;
    if let Some(ignore) = ray.ignore {
        w.put(&ignore.to_le_bytes())?;
    }
    if let Some(t_max) = ray.t_max {
        w.put(&t_max.to_le_bytes())?;
    }
    if let Some(best) = ray.best {
        w.put(&best.t.to_le_bytes())?;
        put_sphere(&mut w, &best.sphere)?;
    }
    Some(w.at)
}

fn put_sphere(w: &mut Writer<'_>, s: &SphereMsg) -> Option<()> {
    w.put(&s.id.to_le_bytes())?;
    for v in s.center {
        w.put(&v.to_le_bytes())?;
    }
    w.put(&s.radius.to_le_bytes())?;
    let m = &s.material;
    for v in m.color.iter().chain(&[m.ambient, m.diffuse, m.specular, m.reflect]) {
        w.put(&v.to_le_bytes())?;
    }
    w.put(&[m.shininess])
}

/// Unpacks a ray; `None` unless `bytes` are exactly one ray's wire form.
pub fn decode_ray(bytes: &[u8]) -> Option<RayMsg> {
    let mut r = Reader { bytes };
    let flags = r.u8()?;
    if flags & !KNOWN != 0 {
        return None;
    }
    let kind = kind_of(flags)?;
    let depth = r.u8()?;
    let origin = r.i32x3()?;
    let dir = r.i32x3()?;
    let cell = [r.u16()?, r.u16()?, r.u16()?];
    let pixel = r.u32()?;
    let mut weight = [0u32; 3];
    for v in &mut weight {
        *v = if flags & SHORT_WEIGHTS != 0 { u32::from(r.u16()?) } else { r.u32()? };
    }
    let mut credit = [0u8; 8];
    let credit_len = if flags & SHORT_CREDIT != 0 { 5 } else { 8 };
    credit.get_mut(..credit_len)?.copy_from_slice(r.bytes.get(..credit_len)?);
    r.bytes = r.bytes.get(credit_len..)?;
    let credit = u64::from_le_bytes(credit);
    // A short form must be the one the encoder chose: one ray, one encoding.
    let long_weights_fit = flags & SHORT_WEIGHTS == 0 && weight.iter().all(|&w| w <= u32::from(u16::MAX));
    if long_weights_fit || (credit_len == 8 && credit < 1 << 40) {
        return None;
    }
    let class = r.u16()?;
    let tag = r.u16()?;
    let ignore = if flags & HAS_IGNORE != 0 { Some(r.u16()?) } else { None };
    let t_max = if flags & HAS_T_MAX != 0 { Some(r.i32()?) } else { None };
    let best =
        if flags & HAS_BEST != 0 { Some(HitMsg { t: r.i32()?, sphere: take_sphere(&mut r)? }) } else { None };
    if !r.bytes.is_empty() {
        return None;
    }
    Some(RayMsg { origin, dir, cell, pixel, weight, credit, kind, depth, ignore, best, t_max, class, tag })
}

fn take_sphere(r: &mut Reader<'_>) -> Option<SphereMsg> {
    let id = r.u16()?;
    let center = r.i32x3()?;
    let radius = r.i32()?;
    let color = [r.u16()?, r.u16()?, r.u16()?];
    let (ambient, diffuse, specular, reflect) = (r.u16()?, r.u16()?, r.u16()?, r.u16()?);
    let shininess = r.u8()?;
    let material = MaterialMsg { color, ambient, diffuse, specular, shininess, reflect };
    Some(SphereMsg { id, center, radius, material })
}

impl Serialize for RayMsg {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut buf = [0u8; RAY_MAX_LEN];
        let len = encode_ray(self, &mut buf).unwrap_or(0);
        serializer.serialize_bytes(buf.get(..len).unwrap_or_default())
    }
}

impl<'de> Deserialize<'de> for RayMsg {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct RayBytes;
        impl Visitor<'_> for RayBytes {
            type Value = RayMsg;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("a ray's wire form")
            }
            fn visit_bytes<E: serde::de::Error>(self, bytes: &[u8]) -> Result<RayMsg, E> {
                decode_ray(bytes).ok_or_else(|| E::custom("not a ray"))
            }
        }
        deserializer.deserialize_bytes(RayBytes).map_err(D::Error::custom)
    }
}

impl postcard::experimental::max_size::MaxSize for RayMsg {
    // The byte string's length (one varint byte: RAY_MAX_LEN < 128) and its bytes.
    const POSTCARD_MAX_SIZE: usize = 1 + RAY_MAX_LEN;
}

const _: () = assert!(RAY_MAX_LEN < 128);

#[cfg(test)]
mod tests {
    use super::*;

    fn ray() -> RayMsg {
        RayMsg {
            origin: [-5 << 16, 3, i32::MAX],
            dir: [1 << 30, -7, 0],
            cell: [1, 2, 65535],
            pixel: 4_000_000,
            weight: [32768, 0, 65535],
            credit: 1 << 32,
            kind: RayKind::Shadow,
            depth: 2,
            ignore: Some(9),
            best: None,
            t_max: Some(123_456),
            class: 17,
            tag: 300,
        }
    }

    #[test]
    fn a_primary_share_of_credit_takes_the_short_forms() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = RayMsg { ignore: None, t_max: None, ..ray() };
        // Flags, depth, 24 of line, 6 of cell, 4 of pixel, 6 of weights, 5 of credit, 4 of class and tag.
        assert_eq!(encode_ray(&r, &mut buf), Some(2 + 24 + 6 + 4 + 6 + 5 + 4));
        assert_eq!(decode_ray(buf.get(..51).unwrap()), Some(r));
    }

    #[test]
    fn a_second_encoding_of_the_same_ray_is_refused() {
        // The ray above with its weights written long although they fit short.
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = RayMsg { ignore: None, t_max: None, ..ray() };
        let n = encode_ray(&r, &mut buf).unwrap();
        let mut long = buf[..2 + 24 + 6 + 4].to_vec();
        long[0] &= !SHORT_WEIGHTS;
        for w in r.weight {
            long.extend_from_slice(&w.to_le_bytes());
        }
        long.extend_from_slice(&buf[2 + 24 + 6 + 4 + 6..n]);
        assert_eq!(decode_ray(&long), None);
    }

    proptest::proptest! {
        /// Weights and credit on both sides of the short forms' limits.
        #[test]
        fn rays_round_trip_across_the_short_forms(
            weight in proptest::array::uniform3(0u32..70_000),
            credit in (1u64 << 40) - 1000..(1u64 << 40) + 1000,
            low_credit in proptest::bool::ANY,
            t_max in proptest::option::of(proptest::num::i32::ANY),
        ) {
            let credit = if low_credit { credit >> 9 } else { credit };
            let r = RayMsg { weight, credit, t_max, ..ray() };
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_ray(&r, &mut buf).unwrap();
            proptest::prop_assert_eq!(decode_ray(&buf[..n]), Some(r));
        }
    }

    #[test]
    fn short_buffers_and_stray_bytes_are_refused() {
        let mut buf = [0u8; RAY_MAX_LEN + 1];
        let n = encode_ray(&ray(), &mut buf).unwrap();
        assert_eq!(encode_ray(&ray(), &mut [0u8; 20]), None);
        assert_eq!(decode_ray(&buf[..n - 1]), None);
        assert_eq!(decode_ray(&buf[..n + 1]), None);
        let mut bad = buf;
        bad[0] |= 3 << KIND_SHIFT;
        assert_eq!(decode_ray(&bad[..n]), None, "kind 3 is no kind");
    }
}
