//! A ray's wire form: fixed little-endian fields, packed and unpacked by
//! hand, carried in a frame as its bare bytes (to postcard, a tuple of
//! them): its flag bytes say how long it is, so it needs no length.
//!
//! Rays are most of the traffic between nodes, and every byte of a ray is
//! paid three times: on the wire, and by the CRC and COBS at both ends. So a
//! ray carries only what its exact continuation needs, in the shortest of a
//! few fixed forms that two flag bytes choose:
//! - a primary ray's origin is the eye, which every node knows: a node
//!   sends [`ORIGIN_AT_EYE`] in its place and it takes no bytes;
//! - weights at full strength (every primary ray) take none, weights under
//!   2^16 two bytes each, else four;
//! - credit of exactly 2^32 (a primary ray's) takes none; an odd multiple
//!   up to 7 of a power of two (every other ray's: a hit splits its ray's
//!   credit among its children by powers of two) one byte
//!   ([`crate::credit`]); any other under 2^32 four bytes, else eight;
//! - any other origin inside the grid's first 256 cubes (every reflected or
//!   shadow ray's: it starts on a sphere the grid holds) three bytes a
//!   component, else four;
//! - cells under 256 (every grid cell) one byte each and a pixel under 2^24
//!   (every pixel of an image up to 4096x4096) three bytes, else two and four;
//! - a class under 256 one byte, else two; a zero tag (every ray passed on a
//!   grant) none; depth under 3 rides in the flags.
//!
//! Any [`RayMsg`] round-trips, and each has exactly one encoding: bytes that
//! are not the encoder's choice for some ray are refused, never read as
//! something else.
//!
//! Layout: flags, forms, \[depth\], \[origin\], direction (3 x i32), cell,
//! pixel, \[weights\], \[credit\], class, \[tag\], then `ignore`
//! (u16), `t_max` (i32) and `best` (t as i32, then the sphere) when present.

use serde::de::{Error as _, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::credit;
use crate::message::{HitMsg, MaterialMsg, Message, RayKind, RayMsg, SphereMsg};
use crate::pack::{Reader, Writer};

/// The origin a node writes for a primary ray that starts at the eye: the
/// wire leaves it out, and the receiver puts its own eye back. Far outside
/// every accepted coordinate range, so a ray that keeps it is refused.
pub const ORIGIN_AT_EYE: [i32; 3] = [i32::MIN; 3];

// The first flag byte: what is present.
const HAS_IGNORE: u8 = 1 << 0;
const HAS_BEST: u8 = 1 << 1;
const HAS_T_MAX: u8 = 1 << 2;
const KIND_SHIFT: u32 = 3;
const KIND_MASK: u8 = 0b11 << KIND_SHIFT;
const HAS_TAG: u8 = 1 << 5;
const WIDE_CLASS: u8 = 1 << 6;
const AT_EYE: u8 = 1 << 7;

// The second: how long the variable fields are, and the depth.
const WEIGHTS_MASK: u8 = 0b11;
const WEIGHTS_FULL: u8 = 0;
const WEIGHTS_SHORT: u8 = 1;
const WEIGHTS_LONG: u8 = 2;
/// The credit's form ([`credit::Form`]), its code in two bits.
const CREDIT_SHIFT: u32 = 2;
const CREDIT_MASK: u8 = 0b11 << CREDIT_SHIFT;
/// Cells two bytes each and the pixel four, for a cell or a pixel out of the short forms.
const WIDE: u8 = 1 << 4;
/// The origin in three bytes a component.
const SHORT_ORIGIN: u8 = 1 << 5;
const DEPTH_SHIFT: u32 = 6;
/// A depth this large or larger follows in a byte of its own. Depths 0 to
/// 2 (a primary ray, its shadow rays, one reflection and its shadow rays)
/// are most of the traffic.
const DEPTH_ESCAPE: u8 = 3;

/// Short origin components and pixels are under this: three bytes.
const SHORT_LIMIT: u32 = 1 << 24;

/// Full strength, Q1.15.
const FULL_WEIGHT: u32 = 32768;
/// A primary ray's credit: the share of its pixel that the host accounts
/// for (every ray a primary spawns splits its credit).
pub const PIXEL_CREDIT: u64 = 1 << 32;

/// A sphere's bytes: id, centre, radius, colour, four coefficients and the exponent.
const SPHERE_LEN: usize = 2 + 12 + 4 + 6 + 8 + 1;
/// The longest ray: every option present, every field in its long form.
pub const RAY_MAX_LEN: usize = 3 + 12 + 12 + 6 + 4 + 12 + 8 + 2 + 2 + 2 + 4 + 4 + SPHERE_LEN;

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

/// Whether `origin` is [`ORIGIN_AT_EYE`], compared a component at a time:
/// an array's `==` is a `memcmp` call on a Cortex-M3, and this runs twice a ray.
pub fn at_eye(origin: [i32; 3]) -> bool {
    origin.iter().all(|&c| c == i32::MIN)
}

/// A ray on its way to a neighbour: the ray as the node keeps it, and
/// beside it what the hop changes (its class, its tag, the eye in place of
/// its origin) and whether it goes on a grant, so that it is packed from
/// where it lies. Copied into a [`Message`] first, a ray cost each end of a
/// hop about 40 instructions on a Cortex-M3 (a `RayMsg` is 120 bytes).
#[derive(Debug, Clone, Copy)]
pub struct OutgoingRay<'a> {
    /// The ray's state.
    pub ray: &'a RayMsg,
    /// Its class on the wire.
    pub class: u16,
    /// Its tag on the wire (0 on a grant).
    pub tag: u16,
    /// The origin goes as [`ORIGIN_AT_EYE`] (the receiver puts its eye back).
    pub origin_at_eye: bool,
    /// A [`Message::GrantedRay`] rather than a [`Message::Ray`].
    pub granted: bool,
}

impl<'a> OutgoingRay<'a> {
    /// `ray` as it is, on a grant or not.
    pub fn of(ray: &'a RayMsg, granted: bool) -> Self {
        Self { ray, class: ray.class, tag: ray.tag, origin_at_eye: false, granted }
    }

    /// The origin it goes with.
    fn origin(&self) -> [i32; 3] {
        if self.origin_at_eye { ORIGIN_AT_EYE } else { self.ray.origin }
    }

    /// The message it stands for: the same bytes on the wire.
    pub fn message(&self) -> Message {
        let ray = RayMsg { origin: self.origin(), class: self.class, tag: self.tag, ..*self.ray };
        if self.granted { Message::GrantedRay(ray) } else { Message::Ray(ray) }
    }
}

/// The flag bytes the encoder chooses for `out`, going with `origin`, whose
/// credit takes `credit`.
fn flags_of(out: &OutgoingRay<'_>, origin: [i32; 3], credit: credit::Form) -> [u8; 2] {
    let ray = out.ray;
    let mut flags = kind_bits(ray.kind);
    for (set, bit) in [
        (ray.ignore.is_some(), HAS_IGNORE),
        (ray.best.is_some(), HAS_BEST),
        (ray.t_max.is_some(), HAS_T_MAX),
        (out.tag != 0, HAS_TAG),
        (out.class > 0xff, WIDE_CLASS),
        (at_eye(origin), AT_EYE),
    ] {
        if set {
            flags |= bit;
        }
    }
    let weights = if ray.weight.iter().all(|&w| w == FULL_WEIGHT) {
        WEIGHTS_FULL
    } else if ray.weight.iter().all(|&w| w <= 0xffff) {
        WEIGHTS_SHORT
    } else {
        WEIGHTS_LONG
    };
    let credit = credit.code() << CREDIT_SHIFT;
    let wide = if ray.cell.iter().any(|&c| c > 0xff) || ray.pixel >= SHORT_LIMIT { WIDE } else { 0 };
    let origin = if short_origin(origin) { SHORT_ORIGIN } else { 0 };
    [flags, weights | credit | wide | origin | (ray.depth.min(DEPTH_ESCAPE) << DEPTH_SHIFT)]
}

/// Whether every component of `origin` fits three bytes (the eye's do not).
fn short_origin(origin: [i32; 3]) -> bool {
    origin.iter().all(|&c| (c as u32) < SHORT_LIMIT)
}

/// The low three bytes of `v`.
fn three_bytes(v: u32) -> [u8; 3] {
    let [a, b, c, _] = v.to_le_bytes();
    [a, b, c]
}

/// Packs `ray` into `out`; the length written, or `None` if `out` is shorter
/// than the ray needs ([`RAY_MAX_LEN`] always suffices).
#[inline(always)]
pub fn encode_ray(ray: &RayMsg, out: &mut [u8]) -> Option<usize> {
    encode_outgoing(&OutgoingRay::of(ray, false), out)
}

/// Packs the ray `o` sends into `out`, as [`encode_ray`] packs the ray it
/// stands for ([`OutgoingRay::message`]).
#[inline(always)]
pub fn encode_outgoing(o: &OutgoingRay<'_>, out: &mut [u8]) -> Option<usize> {
    let ray = o.ray;
    let origin = o.origin();
    let credit = credit::Form::of(ray.credit);
    let [flags, forms] = flags_of(o, origin, credit);
    let mut w = Writer::new(out);
    w.put(&[flags, forms])?;
    if ray.depth >= DEPTH_ESCAPE {
        w.put(&[ray.depth])?;
    }
    if forms & SHORT_ORIGIN != 0 {
        for v in origin {
            w.put(&three_bytes(v as u32))?;
        }
    } else if flags & AT_EYE == 0 {
        for v in origin {
            w.put(&v.to_le_bytes())?;
        }
    }
    for v in ray.dir {
        w.put(&v.to_le_bytes())?;
    }
    if forms & WIDE != 0 {
        for c in ray.cell {
            w.put(&c.to_le_bytes())?;
        }
        w.put(&ray.pixel.to_le_bytes())?;
    } else {
        w.put(&ray.cell.map(|c| c as u8))?;
        w.put(&three_bytes(ray.pixel))?;
    }
    for v in ray.weight {
        match forms & WEIGHTS_MASK {
            WEIGHTS_SHORT => w.put(&(v as u16).to_le_bytes())?,
            WEIGHTS_LONG => w.put(&v.to_le_bytes())?,
            _ => {}
        }
    }
    credit.write(ray.credit, &mut w)?;
    if flags & WIDE_CLASS != 0 {
        w.put(&o.class.to_le_bytes())?;
    } else {
        w.put(&[o.class as u8])?;
    }
    if o.tag != 0 {
        w.put(&o.tag.to_le_bytes())?;
    }
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

/// Unpacks a ray; `None` unless `bytes` are exactly one ray's wire form:
/// the one [`encode_ray`] writes. Each form is checked as it is read (a
/// field written longer than its value needs is refused), which costs a
/// fraction of choosing the flags again and comparing them.
#[inline(always)]
pub fn decode_ray(bytes: &[u8]) -> Option<RayMsg> {
    read_ray(bytes, |ray, rest| rest.is_empty().then_some(ray))
}

/// The ray at the start of `bytes` as the message of a ray's frame, on a
/// grant or not, written into `out` if `after` takes the bytes that follow
/// it (a frame gives a ray no length: its flags say how long it is); what
/// `after` made of them. `out` is untouched unless both are good. Each
/// variant is built where it goes: a ray unpacked and then moved into the
/// message cost each received frame a copy of its 120 bytes.
#[inline(always)]
pub fn decode_ray_into<T>(
    bytes: &[u8],
    granted: bool,
    out: &mut Message,
    after: impl FnOnce(&[u8]) -> Option<T>,
) -> Option<T> {
    read_ray(bytes, |ray, rest| {
        let made = after(rest)?;
        *out = if granted { Message::GrantedRay(ray) } else { Message::Ray(ray) };
        Some(made)
    })
}

/// Unpacks the ray at the start of `bytes` as [`decode_ray`] says and hands
/// it to `finish`, with the bytes after it, once every field is read and
/// checked.
#[inline(always)]
fn read_ray<T>(bytes: &[u8], finish: impl FnOnce(RayMsg, &[u8]) -> Option<T>) -> Option<T> {
    let mut r = Reader { bytes };
    let flags = r.u8()?;
    let forms = r.u8()?;
    let kind = kind_of(flags)?;
    let depth = match forms >> DEPTH_SHIFT {
        DEPTH_ESCAPE => r.u8().filter(|&d| d >= DEPTH_ESCAPE)?,
        d => d,
    };
    let origin = match (flags & AT_EYE != 0, forms & SHORT_ORIGIN != 0) {
        (true, false) => ORIGIN_AT_EYE,
        (false, true) => [r.u24()? as i32, r.u24()? as i32, r.u24()? as i32],
        (false, false) => r.i32x3().filter(|&o| !at_eye(o) && !short_origin(o))?,
        (true, true) => return None,
    };
    let dir = r.i32x3()?;
    let (cell, pixel) = if forms & WIDE != 0 {
        Some(([r.u16()?, r.u16()?, r.u16()?], r.u32()?))
            .filter(|(c, p)| c.iter().any(|&c| c > 0xff) || *p >= SHORT_LIMIT)?
    } else {
        ([u16::from(r.u8()?), u16::from(r.u8()?), u16::from(r.u8()?)], r.u24()?)
    };
    let weight = match forms & WEIGHTS_MASK {
        WEIGHTS_FULL => [FULL_WEIGHT; 3],
        WEIGHTS_SHORT => Some([u32::from(r.u16()?), u32::from(r.u16()?), u32::from(r.u16()?)])
            .filter(|w| w.iter().any(|&w| w != FULL_WEIGHT))?,
        WEIGHTS_LONG => Some([r.u32()?, r.u32()?, r.u32()?]).filter(|w| w.iter().any(|&w| w > 0xffff))?,
        _ => return None,
    };
    let credit = credit::Form::read((forms & CREDIT_MASK) >> CREDIT_SHIFT, &mut r)?;
    let class = if flags & WIDE_CLASS != 0 { r.u16().filter(|&c| c > 0xff)? } else { u16::from(r.u8()?) };
    let tag = if flags & HAS_TAG != 0 { r.u16().filter(|&t| t != 0)? } else { 0 };
    let ignore = if flags & HAS_IGNORE != 0 { Some(r.u16()?) } else { None };
    let t_max = if flags & HAS_T_MAX != 0 { Some(r.i32()?) } else { None };
    let best =
        if flags & HAS_BEST != 0 { Some(HitMsg { t: r.i32()?, sphere: take_sphere(&mut r)? }) } else { None };
    finish(
        RayMsg { origin, dir, cell, pixel, weight, credit, kind, depth, ignore, best, t_max, class, tag },
        r.bytes,
    )
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

/// How long the ray whose flag bytes are `flags` and `forms` is on the
/// wire, all of it: what a reader that cannot see the whole frame (serde's)
/// must take. Flags no encoder writes give some length; the ray's decoder
/// refuses them.
fn wire_len(flags: u8, forms: u8) -> usize {
    let has = |bit: u8, len: usize| if flags & bit != 0 { len } else { 0 };
    let depth = usize::from(forms >> DEPTH_SHIFT == DEPTH_ESCAPE);
    let origin = match (flags & AT_EYE != 0, forms & SHORT_ORIGIN != 0) {
        (_, true) => 9,
        (true, false) => 0,
        (false, false) => 12,
    };
    let cell_pixel = if forms & WIDE != 0 { 6 + 4 } else { 3 + 3 };
    let weights = match forms & WEIGHTS_MASK {
        WEIGHTS_SHORT => 6,
        WEIGHTS_LONG => 12,
        _ => 0,
    };
    let credit = credit::Form::wire_len((forms & CREDIT_MASK) >> CREDIT_SHIFT);
    let class = if flags & WIDE_CLASS != 0 { 2 } else { 1 };
    2 + depth
        + origin
        + 12
        + cell_pixel
        + weights
        + credit
        + class
        + has(HAS_TAG, 2)
        + has(HAS_IGNORE, 2)
        + has(HAS_T_MAX, 4)
        + has(HAS_BEST, 4 + SPHERE_LEN)
}

/// A ray is its wire form's bytes, one after another with no length before
/// them (as a tuple, which postcard writes so): its flags say how many.
impl Serialize for RayMsg {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut buf = [0u8; RAY_MAX_LEN];
        let len = encode_ray(self, &mut buf).unwrap_or(0);
        let mut tuple = serializer.serialize_tuple(len)?;
        for byte in buf.get(..len).unwrap_or_default() {
            tuple.serialize_element(byte)?;
        }
        tuple.end()
    }
}

impl<'de> Deserialize<'de> for RayMsg {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct RayBytes;
        impl<'de> Visitor<'de> for RayBytes {
            type Value = RayMsg;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str("a ray's wire form")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<RayMsg, A::Error> {
                let mut buf = [0u8; RAY_MAX_LEN];
                let mut next =
                    || seq.next_element::<u8>()?.ok_or_else(|| A::Error::custom("a ray cut short"));
                let (flags, forms) = (next()?, next()?);
                let len = wire_len(flags, forms);
                let bytes = buf.get_mut(..len).ok_or_else(|| A::Error::custom("not a ray"))?;
                let (head, tail) =
                    bytes.split_at_mut_checked(2).ok_or_else(|| A::Error::custom("not a ray"))?;
                head.copy_from_slice(&[flags, forms]);
                for byte in tail {
                    *byte = next()?;
                }
                decode_ray(bytes).ok_or_else(|| A::Error::custom("not a ray"))
            }
        }
        deserializer.deserialize_tuple(RAY_MAX_LEN, RayBytes)
    }
}

impl postcard::experimental::max_size::MaxSize for RayMsg {
    // Its bytes, with no length before them.
    const POSTCARD_MAX_SIZE: usize = RAY_MAX_LEN;
}

const _: () = assert!(RAY_MAX_LEN < 128);

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec;
    use std::vec::Vec;

    use super::*;

    // The credit forms as the layout documents them: the oracle's own codes.
    const CREDIT_PRIMARY: u8 = 0;
    const CREDIT_SHORT: u8 = 1 << CREDIT_SHIFT;
    const CREDIT_LONG: u8 = 2 << CREDIT_SHIFT;
    const CREDIT_SCALED: u8 = 3 << CREDIT_SHIFT;

    fn ray() -> RayMsg {
        RayMsg {
            origin: [-5 << 16, 3, i32::MAX],
            dir: [1 << 30, -7, 0],
            cell: [1, 2, 65535],
            pixel: 4_000_000,
            weight: [32768, 0, 65535],
            credit: 1 << 33,
            kind: RayKind::Shadow,
            depth: 2,
            ignore: Some(9),
            best: None,
            t_max: Some(123_456),
            class: 17,
            tag: 300,
        }
    }

    fn primary() -> RayMsg {
        RayMsg {
            origin: ORIGIN_AT_EYE,
            cell: [3, 200, 255],
            weight: [FULL_WEIGHT; 3],
            credit: PIXEL_CREDIT,
            kind: RayKind::Primary,
            depth: 0,
            ignore: None,
            t_max: None,
            tag: 0,
            ..ray()
        }
    }

    #[test]
    fn a_primary_ray_on_a_grant_takes_21_bytes() {
        let mut buf = [0u8; RAY_MAX_LEN];
        // Two flag bytes, 12 of direction, 3 of cell, 3 of pixel, 1 of class.
        assert_eq!(encode_ray(&primary(), &mut buf), Some(2 + 12 + 3 + 3 + 1));
        assert_eq!(decode_ray(&buf[..21]), Some(primary()));
    }

    #[test]
    fn a_shadow_ray_from_a_sphere_in_the_grid_takes_three_bytes_an_origin_component() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = RayMsg {
            origin: [0, (1 << 24) - 1, 5 << 16],
            cell: [0, 255, 5],
            credit: PIXEL_CREDIT / 3,
            tag: 0,
            ..ray()
        };
        // Flags, forms, origin 9, direction 12, cell 3, pixel 3, weights 6
        // (one is over 2^15 but under 2^16), credit 4, class, ignore 2, t_max 4.
        let n = encode_ray(&r, &mut buf).unwrap();
        assert_eq!(n, 2 + 9 + 12 + 3 + 3 + 6 + 4 + 1 + 2 + 4);
        assert_eq!(buf[2..11], [0, 0, 0, 0xff, 0xff, 0xff, 0, 0, 5]);
        assert_eq!(decode_ray(&buf[..n]), Some(r));
        // One component at 2^24 or below zero, and the origin takes four bytes each.
        for far in [1 << 24, -1] {
            let r = RayMsg { origin: [0, far, 5 << 16], ..r };
            assert_eq!(encode_ray(&r, &mut buf), Some(n + 3));
        }
    }

    #[test]
    fn a_second_encoding_of_the_same_ray_is_refused() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = RayMsg { cell: [1, 2, 3], ..ray() };
        let n = encode_ray(&r, &mut buf).unwrap();
        // The same ray with its cells and pixel written wide although they fit.
        let mut wide = buf[..2 + 24].to_vec();
        wide[1] |= WIDE;
        for c in r.cell {
            wide.extend_from_slice(&c.to_le_bytes());
        }
        wide.extend_from_slice(&r.pixel.to_le_bytes());
        wide.extend_from_slice(&buf[2 + 24 + 3 + 3..n]);
        assert_eq!(decode_ray(&wide), None);
        // An origin in the grid written long.
        let g = RayMsg { origin: [1, 2, 3], ..r };
        let n = encode_ray(&g, &mut buf).unwrap();
        let mut long = buf[..2].to_vec();
        long[1] &= !SHORT_ORIGIN;
        for v in g.origin {
            long.extend_from_slice(&v.to_le_bytes());
        }
        long.extend_from_slice(&buf[2 + 9..n]);
        assert_eq!(decode_ray(&long), None);
        // Both at the eye and short.
        let mut both = buf[..n].to_vec();
        both[0] |= AT_EYE;
        assert_eq!(decode_ray(&both), None);
        both.drain(2..11);
        assert_eq!(decode_ray(&both), None);
        // A full-strength primary ray with its weights written out.
        let p = primary();
        let n = encode_ray(&p, &mut buf).unwrap();
        let mut long = buf[..n].to_vec();
        long[1] |= WEIGHTS_SHORT;
        let at = 2 + 12 + 3 + 3;
        for _ in 0..3 {
            long.splice(at..at, 32768u16.to_le_bytes());
        }
        assert_eq!(decode_ray(&long), None);
    }

    /// Rays with every field on both sides of its forms' limits.
    fn arb_ray() -> impl proptest::strategy::Strategy<Value = RayMsg> {
        use proptest::prelude::*;
        let sphere = SphereMsg {
            id: 7,
            center: [1, -2, 3],
            radius: 9,
            material: MaterialMsg {
                color: [1, 2, 3],
                ambient: 4,
                diffuse: 5,
                specular: 6,
                shininess: 7,
                reflect: 8,
            },
        };
        // Shares a hit splits off (powers of two, small odd multiples of them),
        // and any other.
        let scaled = (0u32..64, 0u64..4).prop_map(|(e, i)| (2 * i + 1).checked_shl(e).unwrap_or(1));
        let credit = prop_oneof![
            Just(PIXEL_CREDIT),
            scaled,
            (1u64 << 32) - 2..(1u64 << 32) + 3,
            0u64..1 << 33,
            any::<u64>()
        ];
        let origin = prop_oneof![
            Just(ORIGIN_AT_EYE),
            proptest::array::uniform3(prop_oneof![Just(i32::MIN), any::<i32>()]),
            // Short components, and some just out of the short form.
            proptest::array::uniform3(prop_oneof![0i32..1 << 24, (1 << 24) - 2..(1 << 24) + 2, -2i32..2])
        ];
        let pixel = prop_oneof![0u32..1 << 24, (1u32 << 24) - 2..(1 << 24) + 2, any::<u32>()];
        (
            proptest::array::uniform3(prop_oneof_weights()),
            credit,
            proptest::array::uniform3(prop_oneof![250u16..260, any::<u16>()]),
            prop_oneof![250u16..260, any::<u16>()],
            prop_oneof![Just(0u16), any::<u16>()],
            prop_oneof![1u8..5, any::<u8>()],
            origin,
            proptest::option::of(any::<i32>()),
            any::<bool>(),
            pixel,
        )
            .prop_map(
                move |(weight, credit, cell, class, tag, depth, origin, t_max, best, pixel)| {
                    let best = best.then_some(HitMsg { t: -11, sphere });
                    RayMsg { weight, credit, cell, class, tag, depth, origin, t_max, best, pixel, ..ray() }
                },
            )
    }

    proptest::proptest! {
        #[test]
        fn rays_round_trip_across_the_forms(r in arb_ray()) {
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_ray(&r, &mut buf).unwrap();
            proptest::prop_assert_eq!(decode_ray(&buf[..n]), Some(r));
            proptest::prop_assert_eq!(wire_len(buf[0], buf[1]), n);
        }

        /// Through serde (postcard), a ray is its bytes with no length
        /// before them, and reads back from them whatever follows.
        #[test]
        fn rays_go_through_postcard_as_their_bare_bytes(r in arb_ray(), tail in proptest::num::u8::ANY) {
            let fail = |why: &'static str| proptest::test_runner::TestCaseError::fail(why);
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_ray(&r, &mut buf).ok_or_else(|| fail("RAY_MAX_LEN holds any ray"))?;
            let mut out = [0u8; RAY_MAX_LEN + 8];
            let through = postcard::to_slice(&r, &mut out).map_err(|_| fail("postcard wrote no ray"))?.to_vec();
            proptest::prop_assert_eq!(&through[..], &buf[..n]);
            let mut with_tail = through.clone();
            with_tail.push(tail);
            let (back, rest) =
                postcard::take_from_bytes::<RayMsg>(&with_tail).map_err(|_| fail("postcard read no ray"))?;
            proptest::prop_assert_eq!(back, r);
            proptest::prop_assert_eq!(rest, &[tail][..]);
            proptest::prop_assert!(postcard::from_bytes::<RayMsg>(&through[..n - 1]).is_err());
        }
    }

    /// One choice of form for each field that has more than one.
    #[derive(Debug, Clone, Copy)]
    struct Forms {
        escaped_depth: bool,
        origin: Origin,
        wide: bool,
        weights: u8,
        credit: u8,
        wide_class: bool,
        tag: bool,
    }

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Origin {
        AtEye,
        Short,
        Long,
    }

    /// Every choice of forms whose fields `r`'s values fit, canonical or not.
    fn forms_fitting(r: &RayMsg) -> Vec<Forms> {
        let fits = |v: &[u32], max: u32| v.iter().all(|&x| x <= max);
        let cells = r.cell.map(u32::from);
        let (weights, credits) = (
            [WEIGHTS_FULL, WEIGHTS_SHORT, WEIGHTS_LONG],
            [CREDIT_PRIMARY, CREDIT_SHORT, CREDIT_LONG, CREDIT_SCALED],
        );
        let origins = [Origin::AtEye, Origin::Short, Origin::Long];
        // Two ways for four fields, three for two, four for one: 576 choices,
        // by mixed radix.
        (0..2 * 3 * 2 * 3 * 4 * 2 * 2)
            .map(|i: usize| Forms {
                escaped_depth: i % 2 == 1,
                origin: origins[i / 2 % 3],
                wide: i / 6 % 2 == 1,
                weights: weights[i / 12 % 3],
                credit: credits[i / 36 % 4],
                wide_class: i / 144 % 2 == 1,
                tag: i / 288 % 2 == 1,
            })
            .filter(|f| f.escaped_depth || r.depth < DEPTH_ESCAPE)
            .filter(|f| match f.origin {
                Origin::AtEye => r.origin == ORIGIN_AT_EYE,
                Origin::Short => r.origin.iter().all(|&c| (0..1 << 24).contains(&c)),
                Origin::Long => true,
            })
            .filter(|f| f.wide || (fits(&cells, 0xff) && r.pixel < 1 << 24))
            .filter(|f| match f.weights {
                WEIGHTS_FULL => r.weight == [FULL_WEIGHT; 3],
                WEIGHTS_SHORT => fits(&r.weight, 0xffff),
                _ => true,
            })
            .filter(|f| match f.credit {
                CREDIT_PRIMARY => r.credit == PIXEL_CREDIT,
                CREDIT_SHORT => r.credit < 1 << 32,
                CREDIT_SCALED => scaled_byte(r.credit).is_some(),
                _ => true,
            })
            .filter(|f| f.wide_class || r.class <= 0xff)
            .filter(|f| f.tag || r.tag == 0)
            .collect()
    }

    /// The scaled byte of `credit`, found by search: `m 2^e` with `m` odd
    /// and at most 7, as `e | (m - 1) / 2 << 6`.
    fn scaled_byte(credit: u64) -> Option<u8> {
        (0..64u32).find_map(|e| {
            [1u8, 3, 5, 7]
                .into_iter()
                .find(|&m| u128::from(m) << e == u128::from(credit))
                .map(|m| e as u8 | (((m - 1) / 2) << 6))
        })
    }

    /// `r` written in the layout the module documents, in forms `f`: the
    /// decoder's oracle, built apart from the encoder's choice of forms.
    fn write_in(r: &RayMsg, f: Forms) -> Vec<u8> {
        let le =
            |v: &[u32], n: usize| v.iter().flat_map(|x| x.to_le_bytes()[..n].to_vec()).collect::<Vec<u8>>();
        let mut flags = kind_bits(r.kind);
        for (set, bit) in [
            (r.ignore.is_some(), HAS_IGNORE),
            (r.best.is_some(), HAS_BEST),
            (r.t_max.is_some(), HAS_T_MAX),
            (f.tag, HAS_TAG),
            (f.wide_class, WIDE_CLASS),
            (f.origin == Origin::AtEye, AT_EYE),
        ] {
            flags |= if set { bit } else { 0 };
        }
        let depth = if f.escaped_depth { DEPTH_ESCAPE } else { r.depth };
        let wide = if f.wide { WIDE } else { 0 };
        let short = if f.origin == Origin::Short { SHORT_ORIGIN } else { 0 };
        let mut b = vec![flags, f.weights | f.credit | wide | short | depth << DEPTH_SHIFT];
        if f.escaped_depth {
            b.push(r.depth);
        }
        match f.origin {
            Origin::AtEye => {}
            Origin::Short => b.extend(le(&r.origin.map(|v| v as u32), 3)),
            Origin::Long => b.extend(le(&r.origin.map(|v| v as u32), 4)),
        }
        b.extend(le(&r.dir.map(|v| v as u32), 4));
        b.extend(le(&r.cell.map(u32::from), if f.wide { 2 } else { 1 }));
        b.extend(le(&[r.pixel], if f.wide { 4 } else { 3 }));
        match f.weights {
            WEIGHTS_SHORT => b.extend(le(&r.weight, 2)),
            WEIGHTS_LONG => b.extend(le(&r.weight, 4)),
            _ => {}
        }
        match f.credit {
            CREDIT_SCALED => b.extend(scaled_byte(r.credit)),
            CREDIT_SHORT => b.extend(&r.credit.to_le_bytes()[..4]),
            CREDIT_LONG => b.extend(r.credit.to_le_bytes()),
            _ => {}
        }
        b.extend(le(&[u32::from(r.class)], if f.wide_class { 2 } else { 1 }));
        if f.tag {
            b.extend(r.tag.to_le_bytes());
        }
        if let Some(i) = r.ignore {
            b.extend(i.to_le_bytes());
        }
        if let Some(t) = r.t_max {
            b.extend(t.to_le_bytes());
        }
        if let Some(h) = r.best {
            let (s, m) = (h.sphere, h.sphere.material);
            b.extend(h.t.to_le_bytes());
            b.extend(s.id.to_le_bytes());
            b.extend(le(&s.center.map(|v| v as u32), 4));
            b.extend(s.radius.to_le_bytes());
            let [c0, c1, c2] = m.color;
            b.extend(le(&[c0, c1, c2, m.ambient, m.diffuse, m.specular, m.reflect].map(u32::from), 2));
            b.push(m.shininess);
        }
        b
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config::with_cases(128))]
        /// Of all the ways to write a ray, the decoder takes exactly one,
        /// the encoder's.
        #[test]
        fn a_ray_decodes_from_exactly_one_writing(r in arb_ray()) {
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_ray(&r, &mut buf).unwrap();
            let writings = forms_fitting(&r).into_iter().map(|f| write_in(&r, f));
            let taken: Vec<Vec<u8>> = writings.filter(|w| decode_ray(w).is_some()).collect();
            proptest::prop_assert_eq!(taken, vec![buf[..n].to_vec()]);
        }
    }

    fn prop_oneof_weights() -> impl proptest::strategy::Strategy<Value = u32> {
        proptest::prop_oneof![
            proptest::strategy::Just(FULL_WEIGHT),
            65000u32..70_000,
            proptest::num::u32::ANY
        ]
    }

    #[test]
    fn a_ray_unpacked_into_its_message_is_the_ray_and_a_bad_one_leaves_it_be() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let n = encode_ray(&ray(), &mut buf).unwrap();
        buf[n..n + 2].copy_from_slice(&[7, 9]);
        let mut out = Message::Space;
        let rest = |after: &[u8]| Some(after.to_vec());
        assert_eq!(decode_ray_into(&buf[..n + 2], true, &mut out, rest), Some(vec![7, 9]));
        assert_eq!(out, Message::GrantedRay(ray()));
        assert_eq!(decode_ray_into(&buf[..n], false, &mut out, rest), Some(vec![]));
        assert_eq!(out, Message::Ray(ray()));
        // Cut short: refused, and the message is what it was.
        assert_eq!(decode_ray_into(&buf[..n - 1], true, &mut out, rest), None);
        assert_eq!(out, Message::Ray(ray()));
        // What follows refused: so is the ray.
        assert_eq!(decode_ray_into(&buf[..n + 2], true, &mut out, |_| None::<()>), None);
        assert_eq!(out, Message::Ray(ray()));
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
        let mut bad = buf;
        bad[1] |= 3;
        assert_eq!(decode_ray(&bad[..n]), None, "weight form 3 is no form");
    }
}
